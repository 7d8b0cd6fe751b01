//! Where Structured Text comes from: TwinCAT's `.TcPOU`, `.TcDUT`, `.TcGVL` and `.TcIO` files as
//! programs and library files, and `[st] library` folders, through the real `plcd` binary.

mod harness;

use std::fs;
use std::path::Path;

use harness::tempdir::TempDir;

use harness::daemon::plcd_in as plcd;

fn write(dir: &Path, name: &str, text: &str) {
    let path = dir.join(name);
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    fs::write(path, text).unwrap();
}

/// A TwinCAT file as TwinCAT 3 writes it: a byte order mark, the XML header, CDATA sections.
fn tc(object: &str) -> String {
    format!(
        "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n<TcPlcObject Version=\"1.1.0.1\" ProductVersion=\"3.1.4024.9\">\r\n{object}\r\n</TcPlcObject>"
    )
}

fn pou(name: &str, declaration: &str, body: &str) -> String {
    tc(&format!(
        "  <POU Name=\"{name}\" Id=\"{{55bec0fa-53f4-4d28-bb23-ca23c3b1566f}}\" SpecialFunc=\"None\">\r\n    <Declaration><![CDATA[{declaration}]]></Declaration>\r\n    <Implementation>\r\n      <ST><![CDATA[{body}]]></ST>\r\n    </Implementation>\r\n    <LineIds Name=\"{name}\">\r\n      <LineId Id=\"3\" Count=\"2\" />\r\n    </LineIds>\r\n  </POU>"
    ))
}

/// The last value of each watched variable in a `--trace -` output.
fn last(trace: &str, name: &str) -> Option<String> {
    let key = format!("\"dev\":\"{name}\",\"value\":");
    trace
        .lines()
        .rev()
        .find_map(|l| l.split_once(&key))
        .map(|(_, v)| v.trim_end_matches('}').to_string())
}

/// The first value the trace gives `name` (at RUN start, for a device a binding writes then).
fn first(trace: &str, name: &str) -> Option<String> {
    let key = format!("\"dev\":\"{name}\",\"value\":");
    trace.lines().find_map(|l| l.split_once(&key)).map(|(_, v)| v.trim_end_matches('}').to_string())
}

/// `plcd check` of the project in `dir` passes; the lines of its report holding `marker`
/// (`": VAR_CONFIG "`, `"[iec.variables]"`: what each binding was mapped to).
fn check_lines(dir: &Path, marker: &str) -> Vec<String> {
    let out = plcd(dir, &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    stdout.lines().filter(|l| l.contains(marker)).map(str::to_string).collect()
}

/// `plcd check` of the project in `dir` passes, then `plcd sim --for <duration> --watch
/// <watch> --trace -`: its trace.
fn checked_trace(dir: &Path, duration: &str, watch: &str) -> String {
    let out = plcd(dir, &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let args =
        ["sim", "--config", "plcd.toml", "--for", duration, "--watch", watch, "--trace", "-"];
    let out = plcd(dir, &args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A project directory named `name` whose program `main` is `MAIN.TcPOU`, with the library
/// folder `lib/`, a scan every millisecond.
fn twincat_project(name: &str) -> TempDir {
    let dir = TempDir::new(name);
    let d = dir.path();
    write(
        d,
        "plcd.toml",
        "[plc]\nscan_period_ms = 1\n\n[[program]]\nname = \"main\"\nfile = \"MAIN.TcPOU\"\n\n[st]\nlibrary = [\"lib/\"]\n",
    );
    dir
}

fn project() -> TempDir {
    let dir = twincat_project("st-sources");
    let d = dir.path();
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\tc : Counter;\r\n\tp : Point;\r\n\tn : INT;\r\nEND_VAR",
            "c(step := Constants.STEP);\r\np.x := c.total;\r\nIF p.x > 4 THEN\r\n\tn := n + 1;\r\nEND_IF",
        ),
    );
    write(
        d,
        "lib/blocks/Counter.TcPOU",
        &pou(
            "Counter",
            "FUNCTION_BLOCK Counter\r\nVAR_INPUT\r\n\tstep : INT;\r\nEND_VAR\r\nVAR_OUTPUT\r\n\ttotal : INT;\r\nEND_VAR",
            "total := total + step;",
        ),
    );
    write(
        d,
        "lib/types/Point.TcDUT",
        &tc("  <DUT Name=\"Point\" Id=\"{1}\">\r\n    <Declaration><![CDATA[TYPE Point :\r\nSTRUCT\r\n\tx : INT;\r\n\ty : INT;\r\nEND_STRUCT\r\nEND_TYPE\r\n]]></Declaration>\r\n  </DUT>"),
    );
    write(
        d,
        "lib/Constants.TcGVL",
        &tc("  <GVL Name=\"Constants\" Id=\"{2}\">\r\n    <Declaration><![CDATA[{attribute 'qualified_only'}\r\nVAR_GLOBAL CONSTANT\r\n\tSTEP : INT := 2;\r\nEND_VAR\r\n]]></Declaration>\r\n  </GVL>"),
    );
    write(d, "lib/notes.txt", "not a source: skipped\n");
    dir
}

#[test]
fn a_twincat_program_runs_on_a_library_folder_of_twincat_files() {
    let dir = project();
    let trace = checked_trace(dir.path(), "3500us", "main.c.total,main.p.x,main.n");
    // a scan every 1 ms: 4 scans in 3.5 ms (t = 0, 1, 2, 3 ms), 2 each
    assert_eq!(last(&trace, "main.c.total").as_deref(), Some("8"), "{trace}");
    assert_eq!(last(&trace, "main.p.x").as_deref(), Some("8"));
    // p.x > 4 from the third scan (6, then 8)
    assert_eq!(last(&trace, "main.n").as_deref(), Some("2"));
}

#[test]
fn an_error_in_a_twincat_file_is_reported_at_its_line_and_column() {
    let dir = project();
    let broken = pou(
        "Counter",
        "FUNCTION_BLOCK Counter\r\nVAR_INPUT\r\n\tstep : INT;\r\nEND_VAR\r\nVAR_OUTPUT\r\n\ttotal : INT;\r\nEND_VAR",
        "total := total + stepp;",
    );
    write(dir.path(), "lib/blocks/Counter.TcPOU", &broken);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    // line 12 of the file: `      <ST><![CDATA[total := total + stepp;`, `stepp` at column 37
    assert!(
        stderr.starts_with("lib/blocks/Counter.TcPOU:12:37: error: `stepp` is not declared"),
        "{stderr}"
    );
}

/// A TwinCAT 3 `.TcPOU` of a function block with a `<Method>` and a `<Property>` (with `<Get>`
/// and `<Set>`, the `<Set>` declared `PUBLIC` as TwinCAT writes an accessor's access
/// specifier), as TwinCAT writes them after the body, and a `.TcIO` interface.
fn twincat_oop_project() -> TempDir {
    let dir = twincat_project("st-sources-oop");
    let d = dir.path();
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\tfbAxis : FB_Axis;\r\n\tiAxis : I_Axis;\r\n\tnPos : INT;\r\n\tbDone : BOOL;\r\nEND_VAR",
            "iAxis := fbAxis;\r\nbDone := iAxis.M_Move(nTarget := 5);\r\nfbAxis.P_Speed := fbAxis.P_Speed + 1;\r\nnPos := fbAxis.nPosition;",
        ),
    );
    let axis = "  <POU Name=\"FB_Axis\" Id=\"{1}\" SpecialFunc=\"None\">\r\n    <Declaration><![CDATA[FUNCTION_BLOCK FB_Axis IMPLEMENTS I_Axis\r\nVAR\r\n\tnPosition : INT;\r\n\tnSpeed : INT := 1;\r\nEND_VAR]]></Declaration>\r\n    <Implementation>\r\n      <ST><![CDATA[]]></ST>\r\n    </Implementation>\r\n    <Method Name=\"M_Move\" Id=\"{2}\">\r\n      <Declaration><![CDATA[METHOD PUBLIC M_Move : BOOL\r\nVAR_INPUT\r\n\tnTarget : INT;\r\nEND_VAR]]></Declaration>\r\n      <Implementation>\r\n        <ST><![CDATA[IF nPosition < nTarget THEN\r\n\tnPosition := nPosition + nSpeed;\r\nEND_IF\r\nM_Move := nPosition >= nTarget;]]></ST>\r\n      </Implementation>\r\n    </Method>\r\n    <Property Name=\"P_Speed\" Id=\"{3}\">\r\n      <Declaration><![CDATA[PROPERTY PUBLIC P_Speed : INT]]></Declaration>\r\n      <Get Name=\"Get\" Id=\"{4}\">\r\n        <Declaration><![CDATA[VAR\r\nEND_VAR]]></Declaration>\r\n        <Implementation>\r\n          <ST><![CDATA[P_Speed := nSpeed;]]></ST>\r\n        </Implementation>\r\n      </Get>\r\n      <Set Name=\"Set\" Id=\"{5}\">\r\n        <Declaration><![CDATA[PUBLIC\r\nVAR\r\nEND_VAR]]></Declaration>\r\n        <Implementation>\r\n          <ST><![CDATA[nSpeed := P_Speed;]]></ST>\r\n        </Implementation>\r\n      </Set>\r\n    </Property>\r\n  </POU>";
    write(d, "lib/FB_Axis.TcPOU", &tc(axis));
    let itf = "  <Itf Name=\"I_Axis\" Id=\"{6}\">\r\n    <Declaration><![CDATA[INTERFACE I_Axis EXTENDS __System.IQueryInterface]]></Declaration>\r\n    <Method Name=\"M_Move\" Id=\"{7}\">\r\n      <Declaration><![CDATA[METHOD M_Move : BOOL\r\nVAR_INPUT\r\n\tnTarget : INT;\r\nEND_VAR]]></Declaration>\r\n    </Method>\r\n  </Itf>";
    write(d, "lib/I_Axis.TcIO", &tc(itf));
    dir
}

#[test]
fn a_twincat_function_block_with_methods_properties_and_an_interface_runs() {
    let dir = twincat_oop_project();
    let trace = checked_trace(dir.path(), "2500us", "main.nPos,main.bDone");
    // 3 scans (t = 0, 1, 2 ms): each moves by the speed, then the property adds 1 to it:
    // speeds 1, 2, 3, positions 1, 3, 6, capped by nothing but the target 5 (>= 5 at 6)
    assert_eq!(last(&trace, "main.nPos").as_deref(), Some("6"), "{trace}");
    assert_eq!(last(&trace, "main.bDone").as_deref(), Some("1"), "{trace}");
}

/// A file as OpenPLC Editor generates it: its programs, then a CONFIGURATION whose resource
/// runs one program every 20 ms and another every 5 ms.
const OPENPLC: &str = "PROGRAM prog0
  VAR
    count : INT;
  END_VAR
  count := count + 1;
END_PROGRAM

PROGRAM fast
  VAR
    n : DINT;
  END_VAR
  n := n + 1;
END_PROGRAM


CONFIGURATION Config0

  RESOURCE Res0 ON PLC
    VAR_GLOBAL
      limit : INT := 5;
    END_VAR
    TASK task0(INTERVAL := T#20ms,PRIORITY := 1);
    TASK task1(INTERVAL := T#5ms,PRIORITY := 0);
    PROGRAM instance0 WITH task0 : prog0;
    PROGRAM instance1 WITH task1 : fast;
  END_RESOURCE
END_CONFIGURATION
";

/// `REF()` and `ADR()` as the initial value of a CONFIGURATION's `VAR_GLOBAL` (docs/ST.md,
/// "References and pointers"): set as any global's, at the start of the first program that
/// runs; the program reads through them from its first scan.
#[test]
fn a_configuration_global_may_be_initialised_with_a_reference() {
    let dir = TempDir::new("st-configuration-ref");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let source = "PROGRAM prog0\n  VAR\n    seen : INT;\n    second : INT;\n  END_VAR\n\
        seen := r^;\n  second := pair[2]^;\nEND_PROGRAM\n\
        CONFIGURATION Config0\n  VAR_GLOBAL\n    target : INT := 42;\n    other : INT := 7;\n\
        r : REF_TO INT := REF(target);\n    pair : ARRAY [1..2] OF POINTER TO INT := [ADR(target), ADR(other)];\n\
        END_VAR\n  RESOURCE Res0 ON PLC\n    TASK task0(INTERVAL := T#10ms, PRIORITY := 1);\n\
        PROGRAM instance0 WITH task0 : prog0;\n  END_RESOURCE\nEND_CONFIGURATION\n";
    write(dir.path(), "plc.st", source);
    let trace = checked_trace(dir.path(), "25ms", "instance0.seen,instance0.second");
    // the first scan already reads 42 through r and 7 through pair[2]
    assert_eq!(last(&trace, "instance0.seen").as_deref(), Some("42"), "{trace}");
    assert_eq!(last(&trace, "instance0.second").as_deref(), Some("7"), "{trace}");
}

#[test]
fn an_openplc_configuration_maps_onto_the_scan_and_a_cycle_task() {
    let dir = TempDir::new("st-configuration");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    write(dir.path(), "plc.st", OPENPLC);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary = stdout.lines().next().unwrap_or_default();
    assert!(
        summary.starts_with("plcd.toml: ok: 2 program(s), ") && summary.ends_with(" 1 task(s)")
    );
    assert_eq!(
        stdout.lines().skip(1).collect::<Vec<_>>(),
        [
            "  configuration Config0: TASK task0 → the scan, every 20 ms (the lowest-priority task)",
            "  configuration Config0: TASK task1 → cycle task 0, every 5 ms, priority 2",
            "  configuration Config0: PROGRAM instance0 : prog0 → program \"instance0\" in the scan",
            "  configuration Config0: PROGRAM instance1 : fast → program \"instance1\" in task \"task1\"",
        ]
    );
    let watch = "instance0.count,instance1.n,limit";
    let out = plcd(
        dir.path(),
        &["sim", "--config", "plcd.toml", "--for", "99ms", "--watch", watch, "--trace", "-"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    // the scan every 20 ms: at 0, 20, 40, 60, 80 ms
    assert_eq!(last(&trace, "instance0.count").as_deref(), Some("5"), "{trace}");
    // task1 every 5 ms: 5, 10, … 95 ms
    assert_eq!(last(&trace, "instance1.n").as_deref(), Some("19"));
}

#[test]
fn a_task_no_program_runs_in_is_not_scheduled() {
    // matiec's test programs declare such a task; `plcd sim` once panicked on it (an engine
    // task with no program to run).
    let dir = TempDir::new("st-configuration-empty-task");
    write(
        dir.path(),
        "plcd.toml",
        "[plc]\nscan_period_ms = 10\n\n[[program]]\nfile = \"plc.st\"\n",
    );
    let source = "PROGRAM p\n  VAR n : INT; END_VAR\n  n := n + 1;\nEND_PROGRAM\n\
        CONFIGURATION c\n  RESOURCE r ON PLC\n    TASK t(INTERVAL := t#100ms, PRIORITY := 0);\n\
        PROGRAM i : p;\n  END_RESOURCE\nEND_CONFIGURATION\n";
    write(dir.path(), "plc.st", source);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("  configuration c: TASK t → no PROGRAM runs in it: not scheduled"));
    assert!(stdout.lines().next().unwrap_or_default().ends_with(" 0 task(s)"), "{stdout}");
    let out = plcd(
        dir.path(),
        &["sim", "--config", "plcd.toml", "--for", "95ms", "--watch", "i.n", "--trace", "-"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    // the scan every 10 ms: at 0, 10, … 90 ms
    let trace = String::from_utf8_lossy(&out.stdout);
    assert_eq!(last(&trace, "i.n").as_deref(), Some("10"), "{trace}");
}

/// A configuration in the form Beremiz and OpenPLC Editor write, with an event task
/// (`SINGLE`) and program instances given arguments: inputs from a constant and a global,
/// outputs to a global located at a P bit and to a direct address.
const EVENTS_AND_ARGUMENTS: &str = "PROGRAM prog0
  VAR_INPUT
    speed : INT;
  END_VAR
  VAR_OUTPUT
    done : BOOL;
  END_VAR
  VAR
    total : INT;
  END_VAR
  total := total + speed;
  done := total >= 30;
  IF done THEN
    RETURN;
  END_IF;
END_PROGRAM

PROGRAM counter
  VAR_INPUT
    step : INT;
  END_VAR
  VAR_OUTPUT
    n : INT;
    many : BOOL;
    low : BYTE;
  END_VAR
  n := n + step;
  many := n > 7;
  low := INT_TO_BYTE(n);
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    VAR_GLOBAL
      start_btn AT %IX0.1 : BOOL;
      lamp AT %QX0.2 : BOOL;
      limit : INT := 5;
    END_VAR
    TASK task0(INTERVAL := T#20ms,PRIORITY := 0);
    TASK trig(SINGLE := start_btn, PRIORITY := 1);
    PROGRAM instance0 WITH task0 : prog0 (speed := 10, done => lamp);
    PROGRAM presses WITH trig : counter (step := limit, many => %QX0.5, low => %QB1);
  END_RESOURCE
END_CONFIGURATION
";

#[test]
fn a_single_task_runs_on_each_rising_edge_and_instances_copy_their_arguments() {
    let dir = TempDir::new("st-configuration-events");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    write(dir.path(), "plc.st", EVENTS_AND_ARGUMENTS);
    // start_btn (P0001) rises at 30 ms and again at 70 ms, falling between
    write(dir.path(), "inputs.csv", "30ms, P0001, 1\n50ms, P0001, 0\n70ms, P0001, 1\n");
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        stdout.lines().skip(1).filter(|l| !l.starts_with("  iec:")).collect::<Vec<_>>(),
        [
            "  configuration Config0: TASK task0 → the scan, every 20 ms (the lowest-priority task)",
            "  configuration Config0: TASK trig → device task 16, on each rising edge of P0001 (`start_btn`), priority 3",
            "  configuration Config0: PROGRAM instance0 : prog0 → program \"instance0\" in the scan",
            "  configuration Config0: PROGRAM presses : counter → program \"presses\" in task \"trig\"",
        ]
    );
    // lamp (%QX0.2) and many (%QX0.5): bits 2 and 5 of the %QX image's first byte, P064
    // plcd check shows where the configuration's direct addresses land, arguments included
    let iec: Vec<&str> = stdout.lines().filter(|l| l.starts_with("  iec: plc.st:")).collect();
    assert!(iec.iter().any(|l| l.ends_with(": start_btn AT %IX0.1 → P0001")), "{iec:?}");
    assert!(iec.iter().any(|l| l.ends_with(": presses.many => %QX0.5 → P0645")), "{iec:?}");
    assert!(iec.iter().any(|l| l.ends_with(": presses.low => %QB1 → D13024 (high byte)")));
    let watch = "instance0.total,instance0.speed,presses.n,P0642,P0645,D13024";
    let out = plcd(
        dir.path(),
        &[
            "sim",
            "--config",
            "plcd.toml",
            "--for",
            "99ms",
            "--inputs",
            "inputs.csv",
            "--watch",
            watch,
            "--trace",
            "-",
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    // the scan at 0, 20, 40, 60 and 80 ms, speed 10 from the configuration each time
    assert_eq!(last(&trace, "instance0.speed").as_deref(), Some("10"), "{trace}");
    assert_eq!(last(&trace, "instance0.total").as_deref(), Some("50"));
    // done from the third scan on, when the body RETURNs: copied to lamp all the same
    assert_eq!(last(&trace, "P0642").as_deref(), Some("1"));
    // the edges are read at the scans of 40 and 80 ms: two runs of 5 (limit)
    assert_eq!(last(&trace, "presses.n").as_deref(), Some("10"));
    assert_eq!(last(&trace, "P0645").as_deref(), Some("1"));
    // low (10) copied to %QB1, the high byte of D13024 (openplc's %QB area): 10 * 256
    assert_eq!(last(&trace, "D13024").as_deref(), Some("2560"));
    // the copies are ordinary code: the interpreter gives the native code's trace
    let out = plcd(
        dir.path(),
        &[
            "sim",
            "--config",
            "plcd.toml",
            "--for",
            "99ms",
            "--inputs",
            "inputs.csv",
            "--watch",
            watch,
            "--trace",
            "-",
            "--interpreter",
        ],
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout), trace);
}

#[test]
fn every_wrong_argument_of_a_program_instance_is_reported_at_once() {
    let dir = TempDir::new("st-configuration-arguments");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "PROGRAM prog0
  VAR_INPUT speed : INT; END_VAR
  VAR_OUTPUT done : BOOL; END_VAR
  VAR count : INT; END_VAR
  count := count + speed;
  done := count > 100;
END_PROGRAM

CONFIGURATION Config0
  VAR_GLOBAL small : SINT; END_VAR
  VAR_GLOBAL CONSTANT c : BOOL := TRUE; END_VAR
  PROGRAM a : prog0 (speed := TRUE, done => small, count := 1);
  PROGRAM b : prog0 (speed := T#1s, done => c, speed => small, sped := 1);
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "plc.st:12:31: error: type mismatch: `BOOL` cannot be assigned to `INT` (use BOOL_TO_INT)
plc.st:12:45: error: type mismatch: `BOOL` cannot be assigned to `SINT`
plc.st:12:52: error: `count` is not a VAR_INPUT of `prog0`: `:=` gives an input its value before each run
plc.st:13:31: error: type mismatch: `TIME` cannot be assigned to `INT` (use TIME_TO_INT)
plc.st:13:45: error: `c` is CONSTANT: it cannot be written
plc.st:13:48: error: `speed` is not a VAR_OUTPUT of `prog0`: `=>` copies an output out after each run
plc.st:13:64: error: `prog0` has no VAR_INPUT or VAR_OUTPUT `sped` (did you mean `speed`?)
plcd.toml: 7 error(s)
"
    );
}

/// Variables declared at partly specified addresses, bound to devices by the configuration's
/// `VAR_CONFIG` (its paths as IEC writes them, from the resource, and as CODESYS does, from the
/// instance): the program reads and writes the devices, and an entry's initial value is the
/// device's at RUN start. Entries without an address give the instance's variables, its
/// function block's and its struct's members, their initial values.
const VAR_CONFIG: &str = "TYPE Limits : STRUCT lo : INT; hi : INT := 9; END_STRUCT END_TYPE

FUNCTION_BLOCK Step
  VAR_INPUT stride : INT := 1; END_VAR
  VAR_OUTPUT total : INT; END_VAR
  total := total + stride;
END_FUNCTION_BLOCK

PROGRAM blink
  VAR
    lamp AT %Q* : BOOL;
    level AT %MW* : INT := 7;
    seen AT %IX* : BOOL;
    code AT %QB* : BYTE;
    n : INT;
    copies : INT;
    counter : Step;
    lim : Limits;
    gain : INT := 1;
    acc : INT;
    span : INT;
  END_VAR
  n := n + 1;
  lamp := n MOD 2 = 1;
  code := code + 1;
  level := level + 1;
  IF seen THEN
    copies := copies + 1;
  END_IF;
  counter();
  acc := acc + gain;
  span := lim.hi - lim.lo;
END_PROGRAM

CONFIGURATION Config0
  RESOURCE Res0 ON PLC
    TASK main_task(INTERVAL := T#10ms, PRIORITY := 0);
    PROGRAM inst WITH main_task : blink;
  END_RESOURCE
  VAR_CONFIG
    Res0.inst.lamp AT %QX0.3 : BOOL;
    inst.level AT %MW5 : INT := 100;
    inst.seen AT %IX0.1 : BOOL;
    inst.code AT %QB1 : BYTE := 16#F0;
    inst.gain : INT := 3;
    Res0.inst.counter.stride : INT := 5;
    inst.lim : Limits := (lo := -1);
    inst.lim.hi : INT := 50;
  END_VAR
END_CONFIGURATION
";

/// `plcd check` shows the `[iec]` layout in effect and the device each variable located at an
/// IEC direct address lands on, in every declaration the project's ST files hold.
#[test]
fn check_shows_the_iec_layout_and_where_each_located_variable_lands() {
    let dir = TempDir::new("st-iec-layout-check");
    let text = "VAR_GLOBAL estop AT %IX0.2 : BOOL; END_VAR
PROGRAM Main
VAR
  button AT %IX0.0 : BOOL;
  lamp AT %QX0.0 : BOOL;
  level AT %IW3 : INT;
  code AT %QB1 : BYTE;
  raw AT %D00100 : INT;
END_VAR
  lamp := button AND NOT estop;
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    write(
        dir.path(),
        "plcd.toml",
        "[[program]]\nfile = \"plc.st\"\n\n[iec]\npreset = \"codesys\"\n",
    );
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    // CODESYS's byte images: %I from P000, %Q from P064, %M from M000; %IW3 is bytes 6 and 7,
    // word P003; %QB1 the high half of P064; a plcd device (`raw`) is no IEC address and is
    // not listed
    assert_eq!(
        stdout.lines().skip(1).collect::<Vec<_>>(),
        [
            "  iec: the codesys layout ([iec] preset), docs/ST.md \"Direct addresses\":",
            "  iec:   %IX0.0..%IX127.7, %IB0..%IB127, %IW0..%IW63, %ID0..%ID31, %IL0..%IL15 → P000..P063 (iec.input)",
            "  iec:   %QX0.0..%QX127.7, %QB0..%QB127, %QW0..%QW63, %QD0..%QD31, %QL0..%QL15 → P064..P127 (iec.output)",
            "  iec:   %MX0.0..%MX511.7, %MB0..%MB511, %MW0..%MW255, %MD0..%MD127, %ML0..%ML63 → M000..M255 (iec.memory)",
            "  iec: plc.st:1: estop AT %IX0.2 → P0002",
            "  iec: plc.st:4: Main.button AT %IX0.0 → P0000",
            "  iec: plc.st:5: Main.lamp AT %QX0.0 → P0640",
            "  iec: plc.st:6: Main.level AT %IW3 → P003",
            "  iec: plc.st:7: Main.code AT %QB1 → P064 (high byte)",
        ]
    );
    // without an IEC address, nothing of the layout
    write(
        dir.path(),
        "plc.st",
        "PROGRAM Main VAR raw AT %D00100 : INT; END_VAR raw := 1; END_PROGRAM\n",
    );
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
}

#[test]
fn var_config_binds_partly_specified_variables_to_devices() {
    let dir = TempDir::new("st-configuration-var-config");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    write(dir.path(), "plc.st", VAR_CONFIG);
    // the input of `seen` on from 15 ms: read by the scans of 20 ms on
    write(dir.path(), "inputs.csv", "15ms, P0001, 1\n");
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        stdout.lines().skip(3).filter(|l| !l.starts_with("  iec:")).collect::<Vec<_>>(),
        [
            "  configuration Config0: VAR_CONFIG Res0.inst.lamp AT %QX0.3 → P0643",
            "  configuration Config0: VAR_CONFIG inst.level AT %MW5 → D14005",
            "  configuration Config0: VAR_CONFIG inst.seen AT %IX0.1 → P0001",
            "  configuration Config0: VAR_CONFIG inst.code AT %QB1 → D13024 (high byte)",
        ]
    );
    let watch = "inst.n,inst.copies,inst.level,P0643,D14005,inst.acc,inst.counter.total,inst.span,\
                 inst.code,D13024,P064";
    let out = plcd(
        dir.path(),
        &[
            "sim",
            "--config",
            "plcd.toml",
            "--for",
            "25ms",
            "--inputs",
            "inputs.csv",
            "--watch",
            watch,
            "--trace",
            "-",
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    // three scans, at 0, 10 and 20 ms: n = 3, the lamp on (3 is odd) at P0643 (%QX0.3)
    assert_eq!(last(&trace, "inst.n").as_deref(), Some("3"), "{trace}");
    assert_eq!(last(&trace, "P0643").as_deref(), Some("1"));
    // code at %QB1, the high byte of D13024 (openplc's %QB area), from VAR_CONFIG's 16#F0, one
    // more a scan: 16#F3, D13024 = 16#F300, -3328 as the trace shows a word; the lamp's word
    // P064 holds its bit 3 alone
    assert_eq!(last(&trace, "inst.code").as_deref(), Some("243"));
    assert_eq!(last(&trace, "D13024").as_deref(), Some("-3328"));
    assert_eq!(last(&trace, "P064").as_deref(), Some("8"));
    // level at D14005 (%MW5, OpenPLC's %MW area from D14000) from VAR_CONFIG's 100 (not the
    // declaration's 7), one more a scan
    assert_eq!(last(&trace, "D14005").as_deref(), Some("103"));
    assert_eq!(last(&trace, "inst.level").as_deref(), Some("103"));
    // seen (P0001) read at the scan of 20 ms only
    assert_eq!(last(&trace, "inst.copies").as_deref(), Some("1"));
    // initial values for the instance: 3 a scan, 5 a call of its counter
    assert_eq!(last(&trace, "inst.acc").as_deref(), Some("9"));
    assert_eq!(last(&trace, "inst.counter.total").as_deref(), Some("15"));
    // lim from VAR_CONFIG's (lo := -1) and its hi := 50, not the type's 0 and 9
    assert_eq!(last(&trace, "inst.span").as_deref(), Some("51"));
}

#[test]
fn single_takes_a_direct_address_iec_or_plcd() {
    let dir = TempDir::new("st-configuration-single-direct");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "PROGRAM p
  VAR n : INT; END_VAR
  n := n + 1;
END_PROGRAM

CONFIGURATION c
  TASK iec(SINGLE := %MX1.2, PRIORITY := 0);
  TASK plcd(SINGLE := %D00010.3, PRIORITY := 9);
  PROGRAM a WITH iec : p;
  PROGRAM b WITH plcd : p;
  PROGRAM s : p;
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        stdout.lines().skip(1).take(2).collect::<Vec<_>>(),
        [
            "  configuration c: TASK iec → device task 16, on each rising edge of M000A (%MX1.2), priority 2",
            // PRIORITY past 5 is plcd's lowest, 7
            "  configuration c: TASK plcd → device task 17, on each rising edge of D00010.3 (%D00010.3), priority 7",
        ]
    );
}

#[test]
fn var_config_binds_each_instance_of_a_program_to_its_own_device() {
    // Two instances of one PROGRAM, each lamp bound to its own output, a third left in
    // variable memory; the instances count at different steps.
    let dir = TempDir::new("st-configuration-var-config-instances");
    write(
        dir.path(),
        "plcd.toml",
        "[plc]\nscan_period_ms = 10\n\n[[program]]\nfile = \"plc.st\"\n",
    );
    let text = "PROGRAM blink
  VAR_INPUT step : INT; END_VAR
  VAR
    lamp AT %QX* : BOOL;
    n : INT;
  END_VAR
  VAR_STAT runs : INT; END_VAR
  n := n + step;
  lamp := n >= 4;
  runs := runs + 1;
END_PROGRAM

CONFIGURATION c
  PROGRAM a : blink (step := 1);
  PROGRAM b : blink (step := 2);
  PROGRAM free : blink (step := 3);
  VAR_CONFIG
    a.lamp AT %QX0.1 : BOOL;
    b.lamp AT %QX0.2 : BOOL := TRUE;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    // a.lamp at %QX0.1 (P0641), b.lamp at %QX0.2 (P0642)
    let watch = "a.n,b.n,free.n,P0641,P0642,free.lamp,blink.runs";
    let out = plcd(
        dir.path(),
        &["sim", "--config", "plcd.toml", "--for", "25ms", "--watch", watch, "--trace", "-"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    // three scans: a.n = 3 (lamp off), b.n = 6 (on), free.n = 9 (on, in variable memory)
    assert_eq!(last(&trace, "a.n").as_deref(), Some("3"), "{trace}");
    assert_eq!(last(&trace, "b.n").as_deref(), Some("6"));
    assert_eq!(last(&trace, "free.n").as_deref(), Some("9"));
    assert_eq!(last(&trace, "P0641"), None, "a's lamp never on: P0641 never set");
    // b's lamp TRUE at RUN start (VAR_CONFIG's), FALSE at the first scan (n = 2), then TRUE
    assert_eq!(last(&trace, "P0642").as_deref(), Some("1"));
    assert!(trace.contains("\"dev\":\"P0642\",\"value\":0"), "{trace}");
    assert_eq!(last(&trace, "free.lamp").as_deref(), Some("1"));
    // VAR_STAT is the PROGRAM's one copy, whatever copy of its code an instance runs
    assert_eq!(last(&trace, "blink.runs").as_deref(), Some("9"));
}

/// IEC 61131-3's configuration example: `VAR_CONFIG` binds variables inside a FUNCTION_BLOCK
/// instance of a program instance (`STATION_2.P4.FB1.C2 AT %QB25`), declared at partly
/// specified addresses in the block. The instance gets a copy of the block of its own; the
/// block's other instances (`P4.FB2`, and `P5.FB1` in the PROGRAM's other instance) keep
/// variable memory.
const VAR_CONFIG_INSIDE_A_BLOCK: &str = "FUNCTION_BLOCK G
  VAR_INPUT step : INT; END_VAR
  VAR C2 AT %Q* : BYTE; END_VAR
  VAR_OUTPUT C3 AT %Q* : INT; END_VAR
  C2 := C2 + 1;
  C3 := C3 + step;
END_FUNCTION_BLOCK

PROGRAM F
  VAR COUNT : INT; END_VAR
  COUNT := COUNT + 1;
END_PROGRAM

PROGRAM H
  VAR FB1 : G; FB2 : G; seen : INT; END_VAR
  FB1(step := 10);
  FB2(step := 1);
  seen := FB1.C3;
END_PROGRAM

CONFIGURATION CELL_1
  RESOURCE STATION_1 ON PROCESSOR_TYPE_1
    TASK PER_1(INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM P1 WITH PER_1 : F;
  END_RESOURCE
  RESOURCE STATION_2 ON PROCESSOR_TYPE_2
    TASK PER_2(INTERVAL := T#10ms, PRIORITY := 2);
    PROGRAM P4 WITH PER_2 : H;
    PROGRAM P5 WITH PER_2 : H;
  END_RESOURCE
  VAR_CONFIG
    STATION_1.P1.COUNT : INT := 1;
    STATION_2.P4.FB1.C2 AT %QB25 : BYTE := 16#10;
    STATION_2.P4.FB1.C3 AT %QW3 : INT;
  END_VAR
END_CONFIGURATION
";

#[test]
fn var_config_binds_variables_inside_a_function_block_instance() {
    let dir = TempDir::new("st-configuration-var-config-inside-a-block");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    write(dir.path(), "plc.st", VAR_CONFIG_INSIDE_A_BLOCK);
    let bindings = check_lines(dir.path(), ": VAR_CONFIG ");
    assert_eq!(
        bindings,
        [
            "  configuration CELL_1: VAR_CONFIG STATION_2.P4.FB1.C2 AT %QB25 → D13036 (high byte)",
            "  configuration CELL_1: VAR_CONFIG STATION_2.P4.FB1.C3 AT %QW3 → D12003",
        ]
    );
    let watch = "P4.seen,P5.seen,D12003,D13036,P4.FB1.C3,P4.FB2.C2,P4.FB2.C3,P5.FB1.C2,P5.FB1.C3";
    let run = |engine: &[&str]| sim_trace(dir.path(), "25ms", watch, engine);
    let trace = run(&[]);
    // three scans: P4.FB1's C3 at %QW3 (D12003), 10 a call, read back by the program; C2 at
    // %QB25, the high byte of D13036, from VAR_CONFIG's 16#10, one more a call: 16#13
    assert_eq!(last(&trace, "D12003").as_deref(), Some("30"), "{trace}");
    assert_eq!(last(&trace, "P4.seen").as_deref(), Some("30"));
    assert_eq!(last(&trace, "D13036").as_deref(), Some("4864"));
    // the trace names the bound variable by its path, as any other
    assert_eq!(last(&trace, "P4.FB1.C3").as_deref(), Some("30"));
    // the block's other instances keep their variables in memory: P4.FB2 counts by 1, and
    // P5.FB1 (the PROGRAM's other instance) by 10, apart from the devices
    assert_eq!(last(&trace, "P4.FB2.C2").as_deref(), Some("3"));
    assert_eq!(last(&trace, "P4.FB2.C3").as_deref(), Some("3"));
    assert_eq!(last(&trace, "P5.FB1.C2").as_deref(), Some("3"));
    assert_eq!(last(&trace, "P5.FB1.C3").as_deref(), Some("30"));
    assert_eq!(last(&trace, "P5.seen").as_deref(), Some("30"));
    // the copies are ordinary code: the interpreter gives the native code's trace
    assert_eq!(run(&["--interpreter"]), trace);
}

/// IEC 61131-3 ed3's structured type with members at partly specified addresses: `VAR_CONFIG`
/// binds the members of each variable of it (`R.main.hw.IN`, `main.fb.hw.OUT_VAR`), the
/// variable given a copy of its type with the member at the address. Members not bound, and
/// the variables no entry names, stay in variable memory.
const VAR_CONFIG_STRUCT_MEMBERS: &str = "TYPE HW_COMP : STRUCT
    IN      AT %I*  : BOOL;
    OUT_VAR AT %Q*  : WORD := 200;
    ITNL    : REAL;
END_STRUCT; END_TYPE

FUNCTION_BLOCK Unit
  VAR hw : HW_COMP; END_VAR
  hw.OUT_VAR := hw.OUT_VAR + 2;
END_FUNCTION_BLOCK

PROGRAM Main
  VAR hw : HW_COMP; spare : HW_COMP; fb : Unit; seen : INT; END_VAR
  IF hw.IN THEN seen := seen + 1; END_IF;
  hw.OUT_VAR := hw.OUT_VAR + 1;
  hw.ITNL := hw.ITNL + 0.5;
  spare.OUT_VAR := spare.OUT_VAR + 1;
  fb();
END_PROGRAM

CONFIGURATION C
  RESOURCE R ON PLC
    TASK t(INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM main WITH t : Main;
    PROGRAM other WITH t : Main;
  END_RESOURCE
  VAR_CONFIG
    R.main.hw.IN AT %IX0.1 : BOOL;
    main.hw.OUT_VAR AT %QW5 : WORD;
    main.fb.hw.OUT_VAR AT %QW6 : WORD := 7;
  END_VAR
END_CONFIGURATION
";

#[test]
fn var_config_binds_struct_members_at_partly_specified_addresses() {
    let dir = TempDir::new("st-configuration-var-config-struct-members");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    write(dir.path(), "plc.st", VAR_CONFIG_STRUCT_MEMBERS);
    // the input of `main.hw.IN` (%IX0.1, P0001) on from 15 ms: read by the scan of 20 ms
    write(dir.path(), "inputs.csv", "15ms, P0001, 1\n");
    let bindings = check_lines(dir.path(), ": VAR_CONFIG ");
    assert_eq!(
        bindings,
        [
            "  configuration C: VAR_CONFIG R.main.hw.IN AT %IX0.1 → P0001",
            "  configuration C: VAR_CONFIG main.hw.OUT_VAR AT %QW5 → D12005",
            "  configuration C: VAR_CONFIG main.fb.hw.OUT_VAR AT %QW6 → D12006",
        ]
    );
    let watch = "D12005,D12006,main.hw.IN,main.hw.OUT_VAR,main.hw.ITNL,main.seen,\
                 main.spare.OUT_VAR,main.fb.hw.OUT_VAR,other.hw.OUT_VAR,other.fb.hw.OUT_VAR,\
                 other.seen";
    let run = |engine: &[&str]| {
        sim_trace(dir.path(), "25ms", watch, &[&["--inputs", "inputs.csv"], engine].concat())
    };
    let trace = run(&[]);
    // three scans: main.hw.OUT_VAR at %QW5 (D12005) from the member's 200, one more a scan;
    // main.fb.hw.OUT_VAR at %QW6 (D12006) from VAR_CONFIG's 7, two more a call
    assert_eq!(last(&trace, "D12005").as_deref(), Some("203"), "{trace}");
    assert_eq!(last(&trace, "D12006").as_deref(), Some("13"));
    // the trace names a bound member by its path: its device
    assert_eq!(last(&trace, "main.hw.OUT_VAR").as_deref(), Some("203"));
    assert_eq!(last(&trace, "main.fb.hw.OUT_VAR").as_deref(), Some("13"));
    // main.hw.IN at %IX0.1 (P0001), on for the scan of 20 ms only
    assert_eq!(last(&trace, "main.hw.IN").as_deref(), Some("1"));
    assert_eq!(last(&trace, "main.seen").as_deref(), Some("1"));
    // the member no entry binds, the variable no entry names, and the PROGRAM's other
    // instance keep variable memory: 200 and 7 their starts, no input seen
    assert_eq!(last(&trace, "main.hw.ITNL").as_deref(), Some("1.5"));
    assert_eq!(last(&trace, "main.spare.OUT_VAR").as_deref(), Some("203"));
    assert_eq!(last(&trace, "other.hw.OUT_VAR").as_deref(), Some("203"));
    assert_eq!(last(&trace, "other.fb.hw.OUT_VAR").as_deref(), Some("206"));
    assert_eq!(last(&trace, "other.seen"), None);
    // the copies are ordinary code: the interpreter gives the native code's trace
    assert_eq!(run(&["--interpreter"]), trace);
}

#[test]
fn var_config_gives_bound_struct_members_their_initial_values() {
    // members declared together (`A, B, C AT %Q*`), bound one by one: the entry's initial value
    // (77) before the variable's own (`(A := 5, C := 9)`), before the type's (200); a PROGRAM's
    // action and a FUNCTION_BLOCK's VAR_OUTPUT read from outside reach the devices too
    let dir = TempDir::new("st-configuration-var-config-struct-member-values");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "TYPE HW_COMP : STRUCT
    A, B, C AT %Q* : WORD := 200;
    ITNL : REAL;
END_STRUCT; END_TYPE
FUNCTION_BLOCK Unit
  VAR_OUTPUT hw : HW_COMP; END_VAR
  hw.B := hw.B + 2;
END_FUNCTION_BLOCK
PROGRAM Main
  VAR hw : HW_COMP := (A := 5, B := 6, C := 9); fb : Unit; seen, rest : WORD; END_VAR
  hw.A := hw.A + 1;
  rest := hw.B * 1000 + fb.hw.A;
  fb();
  seen := fb.hw.B;
  act();
END_PROGRAM
ACTION Main.act:
  hw.C := hw.C + 10;
END_ACTION
CONFIGURATION C
  RESOURCE R ON PLC
    TASK t(INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM main WITH t : Main;
  END_RESOURCE
  VAR_CONFIG
    main.hw.A AT %QW5 : WORD := 77;
    main.hw.C AT %QW7 : WORD;
    main.fb.hw.B AT %QW6 : WORD;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let watch = "D12005,D12006,D12007,main.seen,main.rest";
    let run = |engine: &[&str]| sim_trace(dir.path(), "25ms", watch, engine);
    let trace = run(&[]);
    // at RUN start, before the first scan
    assert_eq!(first(&trace, "D12005").as_deref(), Some("77"), "{trace}");
    assert_eq!(first(&trace, "D12007").as_deref(), Some("9"));
    assert_eq!(first(&trace, "D12006").as_deref(), Some("200"));
    // three scans: one more, ten more, two more
    assert_eq!(last(&trace, "D12005").as_deref(), Some("80"));
    assert_eq!(last(&trace, "D12007").as_deref(), Some("39"));
    assert_eq!(last(&trace, "D12006").as_deref(), Some("206"));
    assert_eq!(last(&trace, "main.seen").as_deref(), Some("206"));
    // B of main.hw, A of main.fb.hw: not bound, in memory with their initial values
    assert_eq!(last(&trace, "main.rest").as_deref(), Some("6200"));
    assert_eq!(run(&["--interpreter"]), trace);
}

#[test]
fn var_config_binds_members_of_members_at_any_depth() {
    // `main.cell.axis.hw.OUT_VAR`: a member of a member of a member, each struct on the way
    // copied for the variable (`Cell$main.cell`, `Axis$main.cell.axis`, …); a sibling bound by
    // a second entry shares those copies; the other variable of the type and the other axis
    // keep variable memory. Initial values: the entry's (40) before the variable's nested one
    // (`(axis := (hw := (OUT_VAR := 30, IN_VAR := 31)))`, which gives IN_VAR its 31) before the
    // type's (200); the spare axis' OUT_VAR keeps the type's 200.
    let dir = TempDir::new("st-configuration-var-config-members-of-members");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "TYPE HW_COMP : STRUCT OUT_VAR, IN_VAR AT %Q* : WORD := 200; END_STRUCT; END_TYPE
TYPE Axis : STRUCT hw : HW_COMP; pos : INT; END_STRUCT; END_TYPE
TYPE Cell : STRUCT axis, spare : Axis; END_STRUCT; END_TYPE
PROGRAM Main
  VAR
    cell : Cell := (axis := (hw := (OUT_VAR := 30, IN_VAR := 31)));
    other : Cell;
    sum : WORD;
  END_VAR
  cell.axis.hw.OUT_VAR := cell.axis.hw.OUT_VAR + 1;
  cell.axis.hw.IN_VAR := cell.axis.hw.IN_VAR + 2;
  cell.spare.hw.OUT_VAR := cell.spare.hw.OUT_VAR + 3;
  other.axis.hw.OUT_VAR := other.axis.hw.OUT_VAR + 4;
  sum := cell.axis.hw.OUT_VAR + cell.spare.hw.OUT_VAR;
END_PROGRAM
CONFIGURATION C
  RESOURCE R ON PLC
    TASK t(INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM main WITH t : Main;
  END_RESOURCE
  VAR_CONFIG
    main.cell.axis.hw.OUT_VAR AT %QW5 : WORD := 40;
    R.main.cell.axis.hw.IN_VAR AT %QW6 : WORD;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let bindings = check_lines(dir.path(), ": VAR_CONFIG ");
    assert_eq!(
        bindings,
        [
            "  configuration C: VAR_CONFIG main.cell.axis.hw.OUT_VAR AT %QW5 → D12005",
            "  configuration C: VAR_CONFIG R.main.cell.axis.hw.IN_VAR AT %QW6 → D12006",
        ]
    );
    let watch = "D12005,D12006,main.cell.axis.hw.OUT_VAR,main.cell.spare.hw.OUT_VAR,\
                 main.other.axis.hw.OUT_VAR,main.sum";
    let run = |engine: &[&str]| sim_trace(dir.path(), "25ms", watch, engine);
    let trace = run(&[]);
    // at RUN start, before the first scan
    assert_eq!(first(&trace, "D12005").as_deref(), Some("40"), "{trace}");
    assert_eq!(first(&trace, "D12006").as_deref(), Some("31"));
    // three scans: one more, two more a scan at the devices, the trace naming them by path
    assert_eq!(last(&trace, "D12005").as_deref(), Some("43"));
    assert_eq!(last(&trace, "D12006").as_deref(), Some("37"));
    assert_eq!(last(&trace, "main.cell.axis.hw.OUT_VAR").as_deref(), Some("43"));
    // not bound: in variable memory from the type's 200
    assert_eq!(last(&trace, "main.cell.spare.hw.OUT_VAR").as_deref(), Some("209"));
    assert_eq!(last(&trace, "main.other.axis.hw.OUT_VAR").as_deref(), Some("212"));
    assert_eq!(last(&trace, "main.sum").as_deref(), Some("252"));
    assert_eq!(run(&["--interpreter"]), trace);
}

#[test]
fn iec_variables_bind_a_member_of_a_member_to_a_device() {
    let dir = TempDir::new("st-configuration-iec-variables-member-of-member");
    let toml = "[[program]]\nfile = \"plc.st\"\nname = \"main\"\n\n[iec.variables]\n\
                \"main.axis.hw.OUT_VAR\" = \"D00300\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "TYPE HW_COMP : STRUCT OUT_VAR AT %Q* : WORD; END_STRUCT; END_TYPE
TYPE Axis : STRUCT hw : HW_COMP; END_STRUCT; END_TYPE
PROGRAM Main
  VAR axis : Axis; END_VAR
  axis.hw.OUT_VAR := axis.hw.OUT_VAR + 1;
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    let trace = sim_trace(dir.path(), "3ms", "D00300", &[]);
    let scans = trace.matches("\"ev\":\"scan_end\"").count().to_string();
    assert_eq!(last(&trace, "D00300").as_deref(), Some(scans.as_str()), "{trace}");
}

#[test]
fn a_struct_holding_a_bound_member_of_a_member_is_used_member_by_member() {
    // the variable and every struct member on the way to the bound member are refused whole,
    // each naming the member (was "`Cell` cannot be assigned to `Cell`": the copies' names)
    let dir = TempDir::new("st-configuration-member-of-member-whole");
    let toml = "[[program]]\nfile = \"plc.st\"\nname = \"main\"\n\n[iec.variables]\n\
                \"main.cell.axis.hw.OUT_VAR\" = \"D00300\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "TYPE HW_COMP : STRUCT OUT_VAR AT %Q* : WORD; END_STRUCT; END_TYPE
TYPE Axis : STRUCT hw : HW_COMP; END_STRUCT; END_TYPE
TYPE Cell : STRUCT axis : Axis; END_STRUCT; END_TYPE
PROGRAM Main
  VAR cell, c2 : Cell; a : Axis; h : HW_COMP; END_VAR
  c2 := cell;
  a := cell.axis;
  h := cell.axis.hw;
  c2.axis := a;
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let bound = "`cell.axis.hw.OUT_VAR` is bound to a device (VAR_CONFIG, [iec.variables])";
    let expected = [
        format!("plc.st:6:9: error: {bound}: `cell` can be used only member by member"),
        format!("plc.st:7:8: error: {bound}: `cell.axis` can be used only member by member"),
        format!("plc.st:8:8: error: {bound}: `cell.axis.hw` can be used only member by member"),
        "plcd.toml: 3 error(s)".to_string(),
    ];
    assert_eq!(stderr.lines().collect::<Vec<_>>(), expected, "{stderr}");
}

#[test]
fn iec_variables_bind_struct_members_to_iec_addresses_and_devices() {
    let dir = TempDir::new("st-configuration-iec-variables-struct-members");
    let toml = "[[program]]\nfile = \"plc.st\"\nname = \"main\"\n\n[iec.variables]\n\
                \"main.hw.IN\" = \"%IX0.1\"\n\"main.hw.OUT_VAR\" = \"D00300\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "TYPE HW_COMP : STRUCT IN AT %I* : BOOL; OUT_VAR AT %Q* : WORD; END_STRUCT; END_TYPE
PROGRAM Main
  VAR hw : HW_COMP; seen : INT; END_VAR
  IF hw.IN THEN seen := seen + 1; END_IF;
  hw.OUT_VAR := hw.OUT_VAR + 1;
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    write(dir.path(), "inputs.csv", "15ms, P0001, 1\n");
    let bindings = check_lines(dir.path(), "[iec.variables]");
    assert_eq!(
        bindings,
        [
            "  config: [iec.variables] main.hw.IN AT %IX0.1 → P0001",
            "  config: [iec.variables] main.hw.OUT_VAR AT %D00300 → D00300",
        ]
    );
    let watch = "D00300,main.hw.IN,main.hw.OUT_VAR,main.seen";
    let run = |engine: &[&str]| {
        sim_trace(dir.path(), "3ms", watch, &[&["--inputs", "inputs.csv"], engine].concat())
    };
    let trace = run(&[]);
    let scans = trace.matches("\"ev\":\"scan_end\"").count().to_string();
    // OUT_VAR at the plcd device D00300, one more a scan; IN at P0001, never on in 3 ms
    assert_eq!(last(&trace, "D00300").as_deref(), Some(scans.as_str()), "{trace}");
    assert_eq!(last(&trace, "main.hw.OUT_VAR").as_deref(), Some(scans.as_str()));
    assert_eq!(last(&trace, "main.seen"), None);
    assert_eq!(run(&["--interpreter"]), trace);
}

#[test]
fn iec_variables_bind_members_of_types_named_with_their_namespace() {
    // `Lib.HW_COMP` and `Lib.Valve` are the project's HW_COMP and Valve (`[st] namespaces`):
    // a binding of a member or of a block's variable goes through the qualified name as
    // through the plain one (it was refused as "does not fit")
    let dir = TempDir::new("st-configuration-iec-variables-qualified-types");
    let toml =
        "[[program]]\nfile = \"plc.st\"\nname = \"main\"\n\n[st]\nnamespaces = [\"Lib\"]\n\n\
                [iec.variables]\n\"main.hw.IN\" = \"%IX0.1\"\n\"main.hw.OUT_VAR\" = \"%QW2\"\n\
                \"main.valve.open\" = \"%QX0.3\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "TYPE HW_COMP : STRUCT IN AT %I* : BOOL; OUT_VAR AT %Q* : WORD; END_STRUCT; END_TYPE
FUNCTION_BLOCK Valve
  VAR_INPUT cmd : BOOL; END_VAR
  VAR open AT %Q* : BOOL; END_VAR
  open := cmd;
END_FUNCTION_BLOCK
PROGRAM Main
  VAR hw : Lib.HW_COMP; valve : Lib.Valve; END_VAR
  hw.OUT_VAR := hw.OUT_VAR + 1;
  valve(cmd := TRUE);
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    let bindings = check_lines(dir.path(), "[iec.variables]");
    assert_eq!(
        bindings,
        [
            "  config: [iec.variables] main.hw.IN AT %IX0.1 → P0001",
            "  config: [iec.variables] main.hw.OUT_VAR AT %QW2 → D12002",
            "  config: [iec.variables] main.valve.open AT %QX0.3 → P0643",
        ]
    );
    let watch = "D12002,P0643,main.hw.OUT_VAR";
    let run = |engine: &[&str]| sim_trace(dir.path(), "3ms", watch, engine);
    let trace = run(&[]);
    let scans = trace.matches("\"ev\":\"scan_end\"").count().to_string();
    // OUT_VAR at %QW2, one more a scan; the valve's output at %QX0.3
    assert_eq!(last(&trace, "D12002").as_deref(), Some(scans.as_str()), "{trace}");
    assert_eq!(last(&trace, "P0643").as_deref(), Some("1"));
    assert_eq!(run(&["--interpreter"]), trace);
}

#[test]
fn a_struct_with_members_on_devices_is_used_member_by_member() {
    // every whole use of `hw` is refused at its place, and none of `spare`'s (no member of it
    // bound): its bytes in memory do not hold the bound member
    let dir = TempDir::new("st-configuration-struct-members-whole-uses");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "TYPE HW_COMP : STRUCT IN AT %I* : BOOL; level : INT; END_STRUCT; END_TYPE
FUNCTION take : BOOL VAR_IN_OUT x : INT; END_VAR take := TRUE; END_FUNCTION
PROGRAM Main
  VAR hw : HW_COMP; spare : HW_COMP; n : UDINT; p : POINTER TO HW_COMP;
    r : REF_TO HW_COMP; END_VAR
  spare := hw;
  hw := spare;
  n := SIZEOF(hw);
  p := ADR(hw);
  IF hw = spare THEN n := 1; END_IF;
  r := REF(hw);
  spare := spare;
  take(hw.level);
  n := SIZEOF(spare);
END_PROGRAM
CONFIGURATION C
  PROGRAM main : Main;
  VAR_CONFIG
    main.hw.IN AT %IX0.1 : BOOL;
    main.hw : HW_COMP := (level := 3, IN := TRUE);
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let msg = "`hw.IN` is bound to a device (VAR_CONFIG, [iec.variables]): `hw` can be used only \
               member by member";
    let mut lines: Vec<String> = ["6:12", "7:3", "8:15", "9:12", "10:6", "11:12"]
        .iter()
        .map(|at| format!("plc.st:{at}: error: {msg}"))
        .collect();
    // an initial value of the whole struct would go to the member's bytes in memory
    lines.push(
        "plc.st:20:39: error: `main.hw.IN` is bound to a device (VAR_CONFIG, [iec.variables]): \
         give its initial value in its binding or in the declaration of `main.hw`"
            .to_string(),
    );
    let mut expected: Vec<&str> = lines.iter().map(String::as_str).collect();
    expected.push("plcd.toml: 7 error(s)");
    assert_eq!(stderr.lines().collect::<Vec<_>>(), expected, "{stderr}");
}

#[test]
fn var_config_checks_each_struct_member_entry() {
    // each entry that binds no member is reported at its place, and binds nothing: the
    // program compiles as without it
    let dir = TempDir::new("st-configuration-var-config-struct-member-errors");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "TYPE HW_COMP : STRUCT IN AT %I* : BOOL; OUT AT %QW* : WORD; level : INT; END_STRUCT; END_TYPE
PROGRAM Main
  VAR hw : HW_COMP; END_VAR
  VAR CONSTANT k : HW_COMP; END_VAR
  VAR_STAT st : HW_COMP; END_VAR
  hw.OUT := hw.OUT + 1;
END_PROGRAM
CONFIGURATION C
  PROGRAM main : Main;
  VAR_CONFIG
    main.hw.OUT AT %QX0.1 : WORD;
    main.hw.level AT %MW1 : INT;
    main.hw.NOPE AT %MW1 : INT;
    main.hw.IN AT %IX0.1 : INT;
    main.k.IN AT %IX0.1 : BOOL;
    main.st.IN AT %IX0.1 : BOOL;
    main.hw.IN AT %IX0.2 : BOOL;
    main.hw.IN AT %IX0.3 : BOOL;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let not_partial = "is not declared at a partly specified address (`AT %I*`, `%Q*`, `%M*`): \
                       VAR_CONFIG binds only such a variable";
    let expected = [
        "plc.st:11:20: error: `%QX0.1` does not fit `OUT`, declared at `%QW*`".to_string(),
        format!("plc.st:12:13: error: `main.hw.level` {not_partial}"),
        "plc.st:13:13: error: `HW_COMP` has no member `NOPE`".to_string(),
        "plc.st:14:13: error: `main.hw.IN` is `BOOL`, not `INT`".to_string(),
        "plc.st:15:10: error: `k` is CONSTANT: it cannot be written".to_string(),
        format!("plc.st:16:13: error: `main.st.IN` {not_partial}"),
        // the entry of line 14 binds `main.hw.IN`, its type reported
        "plc.st:17:5: error: `main.hw.IN` is already bound by VAR_CONFIG (line 14)".to_string(),
        "plc.st:18:5: error: `main.hw.IN` is already bound by VAR_CONFIG (line 14)".to_string(),
        "plcd.toml: 8 error(s)".to_string(),
    ];
    assert_eq!(stderr.lines().collect::<Vec<_>>(), expected, "{stderr}");
}

#[test]
fn var_config_checks_each_entry_of_a_member_of_a_member() {
    // the checks of a member's binding hold at any depth, each error at its place: a member
    // missing on the way (with the near name), a CONSTANT variable (named, not its member), a
    // member at no partly specified address, a type the entry gets wrong, an address that does
    // not fit, a member of an array's element
    let dir = TempDir::new("st-configuration-var-config-member-of-member-errors");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "TYPE HW_COMP : STRUCT IN AT %I* : BOOL; OUT AT %QW* : WORD; level : INT; END_STRUCT; END_TYPE
TYPE Axis : STRUCT hw : HW_COMP; axes : ARRAY [1..2] OF HW_COMP; END_STRUCT; END_TYPE
PROGRAM Main
  VAR axis : Axis; END_VAR
  VAR CONSTANT k : Axis; END_VAR
  axis.hw.OUT := axis.hw.OUT + 1;
END_PROGRAM
CONFIGURATION C
  PROGRAM main : Main;
  VAR_CONFIG
    main.axis.hx.IN AT %IX0.1 : BOOL;
    main.k.hw.IN AT %IX0.1 : BOOL;
    main.axis.hw.level AT %MW1 : INT;
    main.axis.hw.IN AT %IX0.1 : INT;
    main.axis.hw.OUT AT %QX0.1 : WORD;
    main.axis.axes.IN AT %IX0.2 : BOOL;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let not_partial = "is not declared at a partly specified address (`AT %I*`, `%Q*`, `%M*`): \
                       VAR_CONFIG binds only such a variable";
    let expected = [
        "plc.st:11:15: error: `Axis` has no member `hx` (did you mean `hw`?)".to_string(),
        "plc.st:12:10: error: `k` is CONSTANT: it cannot be written".to_string(),
        format!("plc.st:13:18: error: `main.axis.hw.level` {not_partial}"),
        "plc.st:14:18: error: `main.axis.hw.IN` is `BOOL`, not `INT`".to_string(),
        "plc.st:15:25: error: `%QX0.1` does not fit `OUT`, declared at `%QW*`".to_string(),
        "plc.st:16:20: error: `main.axis.axes` is `ARRAY [1..2] OF HW_COMP`: VAR_CONFIG binds a \
         variable of a program instance or of a FUNCTION_BLOCK instance inside it, or a member \
         of a struct variable of one at any depth, not an element of an array"
            .to_string(),
        "plcd.toml: 6 error(s)".to_string(),
    ];
    assert_eq!(stderr.lines().collect::<Vec<_>>(), expected, "{stderr}");
}

#[test]
fn a_struct_with_partly_specified_members_is_no_input_in_out_or_temp() {
    // IEC 61131-3 ed3: only a variable of an instance's own has members a configuration binds;
    // a VAR, a VAR_OUTPUT and a FUNCTION's VAR are accepted, their members in memory
    let dir = TempDir::new("st-struct-partly-specified-members-kinds");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    let text = "TYPE HW_COMP : STRUCT level : INT; OUT AT %QW* : WORD; END_STRUCT; END_TYPE
TYPE Board : STRUCT n : INT; hw : HW_COMP; END_STRUCT; END_TYPE
FUNCTION f : BOOL
  VAR_INPUT a : HW_COMP; END_VAR
  VAR_IN_OUT b : HW_COMP; END_VAR
  VAR c : HW_COMP; END_VAR
  f := TRUE;
END_FUNCTION
FUNCTION_BLOCK g
  VAR_OUTPUT d : HW_COMP; END_VAR
  VAR_TEMP e : HW_COMP; END_VAR
  VAR h : HW_COMP; END_VAR
  VAR_INPUT inside : Board; END_VAR
  VAR_IN_OUT many : ARRAY [1..2] OF HW_COMP; END_VAR
END_FUNCTION_BLOCK
PROGRAM Main VAR n : INT; END_VAR n := n + 1; END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let message = |at: &str, block: &str| {
        format!(
            "plc.st:{at}: error: `HW_COMP` has its member `OUT` at a partly specified address: a \
             {block} cannot be of it (IEC 61131-3): declare the variable in VAR or VAR_OUTPUT"
        )
    };
    // a struct or an array holding it too
    let expected = [
        message("4:13", "VAR_INPUT"),
        message("5:14", "VAR_IN_OUT"),
        message("11:12", "VAR_TEMP"),
        message("13:13", "VAR_INPUT"),
        message("14:14", "VAR_IN_OUT"),
        "plcd.toml: 5 error(s)".to_string(),
    ];
    assert_eq!(stderr.lines().collect::<Vec<_>>(), expected, "{stderr}");
}

#[test]
fn var_config_binds_a_variable_of_a_nested_instance_and_checks_each_entry() {
    // the PROGRAM's one instance: its code rewritten, `o.inner` given a copy of `Inner` inside
    // a copy of `Outer`; `o2` keeps the blocks
    let dir = TempDir::new("st-configuration-var-config-nested");
    let toml = "[plc]\nscan_period_ms = 10\n\n[[program]]\nfile = \"plc.st\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "FUNCTION_BLOCK Inner
  VAR x AT %MW* : INT; plain : INT; END_VAR
  x := x + 1;
END_FUNCTION_BLOCK

FUNCTION_BLOCK Outer
  VAR inner : Inner; END_VAR
  inner();
END_FUNCTION_BLOCK

PROGRAM p
  VAR o : Outer; o2 : Outer; END_VAR
  o();
  o2();
END_PROGRAM

CONFIGURATION c
  PROGRAM i : p;
  VAR_CONFIG
    i.o.inner.x AT %MW7 : INT := 4;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let watch = "D14007,i.o.inner.x,i.o2.inner.x";
    let out = plcd(
        dir.path(),
        &["sim", "--config", "plcd.toml", "--for", "25ms", "--watch", watch, "--trace", "-"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    // %MW7 is D14007: 4 at RUN start, one more at each of the three scans
    assert_eq!(last(&trace, "D14007").as_deref(), Some("7"), "{trace}");
    assert_eq!(last(&trace, "i.o.inner.x").as_deref(), Some("7"));
    assert_eq!(last(&trace, "i.o2.inner.x").as_deref(), Some("3"));
    // each wrong entry reported at its place
    let wrong = text.replace(
        "    i.o.inner.x AT %MW7 : INT := 4;\n",
        "    i.o.inner.x AT %MW7 : INT := 4;
    i.o.inner.x AT %MW8 : INT;
    i.o.inner.plain AT %MW9 : INT;
    i.o2.inner.x AT %IX0.1 : INT;
    i.o2.inner.x AT %MW10 : BOOL;
",
    );
    write(dir.path(), "plc.st", &wrong);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.lines().collect::<Vec<_>>(),
        [
            "plc.st:21:5: error: `i.o.inner.x` is already bound by VAR_CONFIG (line 20)",
            "plc.st:22:15: error: `i.o.inner.plain` is not declared at a partly specified address (`AT %I*`, `%Q*`, `%M*`): VAR_CONFIG binds only such a variable",
            "plc.st:23:21: error: `%IX0.1` does not fit `x`, declared at `%MW*`",
            "plc.st:24:16: error: `i.o2.inner.x` is `INT`, not `BOOL`",
            "plcd.toml: 4 error(s)",
        ]
    );
}

#[test]
fn var_config_copies_a_bound_blocks_methods_and_actions_with_it() {
    // the block's method and action write the device in the bound instance's copy; the
    // PROGRAM's two instances and its action: P4 runs a copy of it with its action
    let dir = TempDir::new("st-configuration-var-config-methods");
    let toml = "[plc]\nscan_period_ms = 10\n\n[[program]]\nfile = \"plc.st\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "FUNCTION_BLOCK G
  VAR_OUTPUT C3 AT %Q* : INT; END_VAR
  METHOD Bump : INT
    C3 := C3 + 100;
    Bump := C3;
  END_METHOD
END_FUNCTION_BLOCK

ACTION G.Step:
  C3 := C3 + 1;
END_ACTION

PROGRAM H
  VAR FB1 : G; got : INT; END_VAR
  FB1.Step();
  got := FB1.Bump();
END_PROGRAM

ACTION H.Twice:
  FB1.Step();
END_ACTION

CONFIGURATION c
  PROGRAM P4 : H;
  PROGRAM P5 : H;
  VAR_CONFIG
    P4.FB1.C3 AT %QW3 : INT;
  END_VAR
END_CONFIGURATION
";
    write(dir.path(), "plc.st", text);
    let watch = "D12003,P4.got,P5.got,P5.FB1.C3";
    let run = |engine: &[&str]| sim_trace(dir.path(), "25ms", watch, engine);
    let trace = run(&[]);
    // three scans of 101: on the device for P4, in memory for P5
    assert_eq!(last(&trace, "D12003").as_deref(), Some("303"), "{trace}");
    assert_eq!(last(&trace, "P4.got").as_deref(), Some("303"));
    assert_eq!(last(&trace, "P5.got").as_deref(), Some("303"));
    assert_eq!(last(&trace, "P5.FB1.C3").as_deref(), Some("303"));
    assert_eq!(run(&["--interpreter"]), trace);
}

/// The CODESYS forms TwinCAT code and TcUnit use (docs/ST.md, "CODESYS and TwinCAT habits"), in
/// TwinCAT files. Test data modelled on TcUnit (github.com/tcunit/TcUnit, MIT licence,
/// Copyright (c) 2018 Jakob Sagatowski and contributors): `U_ExpectedOrActual.TcDUT`'s UNION of
/// every elementary type (without its `BIT` member, a type plcd has not, and its `T_MaxString`
/// member, whose end its `WSTRING(255)` overlaps: plcd refuses such a string) and the
/// `AND_THEN` of `FB_TestResults.TcPOU` that guards a pointer read
/// (`… = NumberOfInitializedTestSuites AND_THEN TestSuiteAddresses[…]^.AreAllTestsFinished() AND …`),
/// with a JMP loop.
fn twincat_codesys_forms_project() -> TempDir {
    let dir = twincat_project("st-sources-codesys-forms");
    let d = dir.path();
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\tuValue : U_ExpectedOrActual;\r\n\tnBits : LWORD;\r\n\tnLow : DWORD;\r\n\tfbResults : FB_Results;\r\nEND_VAR",
            "uValue.lrealExpectedOrActual := 1.0;\r\nnBits := uValue.lwordExpectedOrActual;\r\nuValue.wordExpectedOrActual := 16#1234;\r\nnLow := uValue.dwordExpectedOrActual;\r\nfbResults();",
        ),
    );
    let members = [
        "boolExpectedOrActual : BOOL",
        "byteExpectedOrActual : BYTE",
        "dwordExpectedOrActual : DWORD",
        "lwordExpectedOrActual : LWORD",
        "udintExpectedOrActual : UDINT",
        "uintExpectedOrActual : UINT",
        "usintExpectedOrActual : USINT",
        "sintExpectedOrActual : SINT",
        "intExpectedOrActual : INT",
        "wordExpectedOrActual : WORD",
        "dintExpectedOrActual : DINT",
        "lintExpectedOrActual : LINT",
        "ulintExpectedOrActual : ULINT",
        "realExpectedOrActual : REAL",
        "lrealExpectedOrActual : LREAL",
        "wstringExpectedOrActual : WSTRING(255)",
        "timeExpectedOrActual : TIME",
        "ltimeExpectedOrActual : LTIME",
        "dateExpectedOrActual : DATE",
        "dateandtimeExpectedOrActual : DATE_AND_TIME",
        "timeofdayExpectedOrActual : TIME_OF_DAY",
    ];
    let union = format!(
        "TYPE U_ExpectedOrActual :\r\nUNION\r\n{}END_UNION\r\nEND_TYPE",
        members.iter().map(|m| format!("    {m};\r\n")).collect::<String>()
    );
    let dut = format!(
        "  <DUT Name=\"U_ExpectedOrActual\" Id=\"{{1}}\">\r\n    <Declaration><![CDATA[{union}]]></Declaration>\r\n  </DUT>"
    );
    write(d, "lib/DUTs/U_ExpectedOrActual.TcDUT", &tc(&dut));
    let suite = "  <DUT Name=\"ST_Suite\" Id=\"{2}\">\r\n    <Declaration><![CDATA[TYPE ST_Suite :\r\nSTRUCT\r\n    bFinished : BOOL;\r\nEND_STRUCT\r\nEND_TYPE]]></Declaration>\r\n  </DUT>";
    write(d, "lib/DUTs/ST_Suite.TcDUT", &tc(suite));
    write(
        d,
        "lib/POUs/FB_Results.TcPOU",
        &pou(
            "FB_Results",
            "FUNCTION_BLOCK FB_Results\r\nVAR\r\n\taSuites : ARRAY [1..3] OF POINTER TO ST_Suite;\r\n\tstLast : ST_Suite;\r\n\tnScan : INT;\r\n\tnSuites : INT := 3;\r\n\tbGeneral : BOOL;\r\n\tnAt : INT;\r\n\tnWalk : INT;\r\n\tnSum : INT;\r\nEND_VAR",
            "nScan := nScan + 1;\r\n// the last suite's pointer is NULL until scan 3\r\nIF nScan = 3 THEN\r\n\taSuites[nSuites] := ADR(stLast);\r\n\tstLast.bFinished := TRUE;\r\nEND_IF\r\nIF nSuites = 0 AND (NOT bGeneral) THEN\r\n\tbGeneral := TRUE;\r\nELSIF nScan >= nSuites AND_THEN\r\n\taSuites[nSuites]^.bFinished AND (NOT bGeneral) THEN\r\n\tbGeneral := TRUE;\r\n\tnAt := nScan;\r\nEND_IF\r\nnWalk := 0;\r\nnSum := 0;\r\nlblNext:\r\nnWalk := nWalk + 1;\r\nIF nWalk > 3 THEN\r\n\tJMP lblDone;\r\nEND_IF\r\nnSum := nSum + nWalk;\r\nJMP lblNext;\r\nlblDone:\r\n",
        ),
    );
    dir
}

#[test]
fn twincat_files_with_union_and_then_and_jumps_run() {
    let dir = twincat_codesys_forms_project();
    let watch =
        "main.nBits,main.nLow,main.fbResults.bGeneral,main.fbResults.nAt,main.fbResults.nSum";
    let trace = checked_trace(dir.path(), "3500us", watch);
    // LREAL 1.0 is 16#3FF0000000000000; its low double word is 0, then the WORD member
    // writes 16#1234 over its low two bytes
    assert_eq!(last(&trace, "main.nBits").as_deref(), Some("4607182418800017408"), "{trace}");
    assert_eq!(last(&trace, "main.nLow").as_deref(), Some("4660"), "{trace}");
    // 4 scans (t = 0 … 3 ms): nScan >= 3 from the third, when the pointer is set; before it
    // AND_THEN never read through the NULL pointer (no 2822H)
    assert_eq!(last(&trace, "main.fbResults.bGeneral").as_deref(), Some("1"), "{trace}");
    assert_eq!(last(&trace, "main.fbResults.nAt").as_deref(), Some("3"), "{trace}");
    assert!(!trace.contains("2822"), "{trace}");
    // the JMP loop adds 1 + 2 + 3
    assert_eq!(last(&trace, "main.fbResults.nSum").as_deref(), Some("6"), "{trace}");
}

/// A `]]>` in the ST of a `.TcPOU`: TwinCAT writes it over two CDATA sections (`']]]]><![CDATA[>'`,
/// as OSCAT NETWORK's XML_READER has it), which are one text: the string is the 3 characters
/// `]]>`, and an error after it on its line is reported 12 columns further left (the join's
/// length), every other line at its place.
#[test]
fn a_cdata_end_split_by_twincat_is_one_string() {
    let dir = TempDir::new("st-sources-cdata");
    let d = dir.path();
    let config =
        "[plc]\nscan_period_ms = 1\n\n[[program]]\nname = \"main\"\nfile = \"MAIN.TcPOU\"\n";
    write(d, "plcd.toml", config);
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\ts : STRING;\r\n\tn : INT;\r\nEND_VAR",
            "s := ']]]]><![CDATA[>'; n := LEN(s);\r\nIF s = CONCAT(']]', '>') THEN n := n + 10; END_IF",
        ),
    );
    let trace = checked_trace(d, "1500us", "main.s,main.n");
    assert_eq!(last(&trace, "main.s").as_deref(), Some("\"]]>\""), "{trace}");
    // LEN is 3, and the string equals `]]` and `>`
    assert_eq!(last(&trace, "main.n").as_deref(), Some("13"), "{trace}");
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\ts : STRING;\r\nEND_VAR",
            "s := ']]]]><![CDATA[>'; x := 1;\r\ny := 2;",
        ),
    );
    let out = plcd(d, &["check", "--config", "plcd.toml"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    // `      <ST><![CDATA[` is 19 columns: `x` at 32 of the text (44 of the file, before the
    // 12 characters of the join left out)
    assert!(stderr.contains("MAIN.TcPOU:9:32: error: `x` is not declared"), "{stderr}");
    assert!(stderr.contains("MAIN.TcPOU:10:1: error: `y` is not declared"), "{stderr}");
}

/// A `.TcGVL`'s `<GVL Name>` qualifies its variables (`{attribute 'qualified_only'}` lists, as
/// TcUnit's `GVL_Param_TcUnit`), whatever its file is called, in an array bound, an initial
/// value and statements; `[st] namespaces` names the library the sources are (`TcUnit.…`).
#[test]
fn a_twincat_gvl_name_and_a_library_namespace_qualify_names() {
    let dir = TempDir::new("st-sources-qualified");
    let d = dir.path();
    write(
        d,
        "plcd.toml",
        "[plc]\nscan_period_ms = 1\n\n[[program]]\nname = \"main\"\nfile = \"MAIN.TcPOU\"\n\n[st]\nlibrary = [\"lib/\"]\nnamespaces = [\"TcUnit\"]\n",
    );
    let gvl = "  <GVL Name=\"GVL_Param\" Id=\"{8}\" ParameterList=\"True\">\r\n    <Declaration><![CDATA[{attribute 'qualified_only'}\r\nVAR_GLOBAL CONSTANT\r\n\tBufferSize : UDINT := 4;\r\nEND_VAR\r\nVAR_GLOBAL\r\n\tnCalls : INT;\r\nEND_VAR]]></Declaration>\r\n  </GVL>";
    write(d, "lib/lib000_params.TcGVL", &tc(gvl));
    write(
        d,
        "lib/FB_Suite.TcPOU",
        &pou(
            "FB_Suite",
            "FUNCTION_BLOCK FB_Suite\r\nVAR\r\n\taBuffer : ARRAY[0..GVL_Param.BufferSize - 1] OF INT;\r\n\tnNext : UDINT := GVL_Param.BufferSize - 1;\r\nEND_VAR",
            "aBuffer[nNext] := aBuffer[nNext] + 1;\r\nTcUnit.GVL_Param.nCalls := GVL_Param.nCalls + 1;",
        ),
    );
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\tfbSuite : FB_Test;\r\n\tnLast : INT;\r\n\tnSeen : INT;\r\nEND_VAR",
            "fbSuite();\r\nnLast := fbSuite.aBuffer[3];\r\nnSeen := GVL_Param.nCalls;",
        ),
    );
    let test = pou(
        "FB_Test",
        "FUNCTION_BLOCK FB_Test EXTENDS TcUnit.FB_Suite\r\nVAR\r\nEND_VAR",
        "SUPER^();",
    );
    write(d, "lib/FB_Test.TcPOU", &test);
    let trace = checked_trace(d, "2500us", "main.nLast,main.nSeen");
    // 3 scans: each adds 1 to aBuffer[BufferSize - 1] = aBuffer[3] and counts the call
    assert_eq!(last(&trace, "main.nLast").as_deref(), Some("3"), "{trace}");
    assert_eq!(last(&trace, "main.nSeen").as_deref(), Some("3"), "{trace}");
}

/// `tests/twincat/plcproj` (its README): a TcUnit-shaped tree whose config lists no `[st]
/// namespaces`; the library's `.plcproj` (in its `[st] library` folder) and the program's
/// (the nearest one above `App/App/POUs/MAIN.TcPOU`) name `MyLib`, `Tc2_Standard`,
/// `IBaseLibrary` and `App`, which `plcd check` shows with their places, and the program runs
/// on `MyLib.FB_X`, `MyLib.GVL_Param_MyLib.nStep`, `Tc2_Standard.TON` and
/// `IBaseLibrary.TypeClass`, with plcd's `Tc2_Standard` compiled (`plcd-tc2.toml`) or not: the
/// same values either way.
#[test]
fn a_twincat_trees_plcproj_files_name_its_namespaces() {
    let dir = Path::new("tests/twincat/plcproj");
    for (config, hint) in [
        (
            "plcd.toml",
            " (a library plcd ships: `[st] system_libraries = [\"Tc2_Standard\"]` compiles it)",
        ),
        ("plcd-tc2.toml", ""),
    ] {
        let out = plcd(dir, &["check", "--config", config]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{config}: {stderr}");
        assert_eq!(stderr, "", "{config}");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let notes: Vec<&str> = stdout.lines().skip(1).collect();
        assert_eq!(
            notes,
            [
                "  namespace MyLib, from MyLib/MyLib/MyLib.plcproj:8 <DefaultNamespace>, App/App/App.plcproj:20 <PlaceholderReference Include=\"MyLib\">".to_string(),
                format!("  namespace Tc2_Standard, from MyLib/MyLib/MyLib.plcproj:28 <PlaceholderReference Include=\"Tc2_Standard\">, App/App/App.plcproj:24 <PlaceholderReference Include=\"Tc2_Standard\">{hint}"),
                "  namespace IBaseLibrary, from MyLib/MyLib/MyLib.plcproj:33 <LibraryReference Include=\"Base Interfaces,newest,System\">".to_string(),
                "  namespace App, from App/App/App.plcproj:7 <DefaultNamespace>".to_string(),
            ],
            "{config}"
        );
        let watch = "main.nScans,main.nCount,main.nTestCount,main.nCalls,main.bDone,main.bIntClass";
        let args = ["sim", "--config", config, "--for", "3500us", "--watch", watch, "--trace", "-"];
        let out = plcd(dir, &args);
        assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
        let trace = String::from_utf8_lossy(&out.stdout);
        // 4 scans (t = 0, 1, 2, 3 ms), each adding nLibStep / MyLib.GVL_Param_MyLib.nStep,
        // 3 / 3 (nLibStep's initial value is the library's constant too)
        assert_eq!(last(&trace, "main.nScans").as_deref(), Some("4"), "{config}: {trace}");
        // fbX counts by 3 in each of the 4 scans
        assert_eq!(last(&trace, "main.nCount").as_deref(), Some("12"), "{config}");
        // Tc2_Standard.TON with PT 2 ms: Q from its call at t = 2 ms, after fbTest's call, so
        // fbTest (FB_X_Test EXTENDS MyLib.FB_X) counts in the scans at 0, 1 and 2 ms, and is
        // called in all 4
        assert_eq!(last(&trace, "main.bDone").as_deref(), Some("1"), "{config}");
        assert_eq!(last(&trace, "main.nTestCount").as_deref(), Some("9"), "{config}");
        assert_eq!(last(&trace, "main.nCalls").as_deref(), Some("4"), "{config}");
        // IBaseLibrary.TypeClass.TYPE_INT, also where IBaseLibrary is a namespace
        assert_eq!(last(&trace, "main.bIntClass").as_deref(), Some("1"), "{config}");
    }
}

/// A `.plcproj` naming a library plcd ships (`Tc2_System`) leaves its meaning as it was
/// (docs/ST.md, "TwinCAT project files"): with `[st] system_libraries` naming it,
/// `Tc2_System.T_MaxString` is the library's type even where the project declares its own
/// `T_MaxString`; without, `Tc2_System` is one more namespace of the project, so it names the
/// project's.
#[test]
fn a_shipped_librarys_name_from_a_plcproj_keeps_its_meaning() {
    let dir = TempDir::new("st-sources-plcproj-shipped");
    let d = dir.path();
    write(
        d,
        "App.plcproj",
        "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n<Project DefaultTargets=\"Build\" xmlns=\"http://schemas.microsoft.com/developer/msbuild/2003\">\r\n  <ItemGroup>\r\n    <PlaceholderReference Include=\"Tc2_System\">\r\n      <DefaultResolution>Tc2_System, * (Beckhoff Automation GmbH)</DefaultResolution>\r\n      <Namespace>Tc2_System</Namespace>\r\n    </PlaceholderReference>\r\n  </ItemGroup>\r\n</Project>\r\n",
    );
    write(
        d,
        "lib/T_MaxString.TcDUT",
        &tc("  <DUT Name=\"T_MaxString\" Id=\"{1}\">\r\n    <Declaration><![CDATA[TYPE T_MaxString : STRING(10); END_TYPE\r\n]]></Declaration>\r\n  </DUT>"),
    );
    write(
        d,
        "POUs/MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\town : T_MaxString;\r\n\tqualified : Tc2_System.T_MaxString;\r\n\tnOwn : INT;\r\n\tnQualified : INT;\r\nEND_VAR",
            "own := 'abcdefghijklmnop';\r\nqualified := 'abcdefghijklmnop';\r\nnOwn := LEN(own);\r\nnQualified := LEN(qualified);",
        ),
    );
    let base = "[plc]\nscan_period_ms = 1\n\n[[program]]\nname = \"main\"\nfile = \"POUs/MAIN.TcPOU\"\n\n[st]\nlibrary = [\"lib/\"]\n";
    // the project's T_MaxString holds 10 characters of the 16, the library's 255
    for (system, qualified) in [(true, "16"), (false, "10")] {
        let shipped = if system { "system_libraries = [\"Tc2_System\"]\n" } else { "" };
        write(d, "plcd.toml", &format!("{base}{shipped}"));
        let trace = checked_trace(d, "500us", "main.nOwn,main.nQualified");
        assert_eq!(last(&trace, "main.nOwn").as_deref(), Some("10"), "{system}: {trace}");
        assert_eq!(
            last(&trace, "main.nQualified").as_deref(),
            Some(qualified),
            "{system}: {trace}"
        );
    }
}

/// `--watch main.r^` follows the reference at every look (docs/ST.md, "Tools"): it shows
/// what `a` holds while `r` points to `a`, then `b` once the program moves it there; a `NULL`
/// reference shows 0.
#[test]
fn a_watch_through_a_reference_follows_it() {
    let dir = TempDir::new("st-watch-through");
    write(
        dir.path(),
        "plcd.toml",
        "[plc]\nscan_period_ms = 10\n\n[[program]]\nname = \"main\"\nfile = \"main.st\"\n",
    );
    let source = "PROGRAM main\nVAR\n    n : INT;\n    a : INT;\n    b : INT := 200;\n\
        r : REF_TO INT;\n    nothing : REF_TO INT;\nEND_VAR\n    n := n + 1;\n    a := n;\n\
        IF n < 5 THEN\n        r := REF(a);\n    ELSE\n        r := REF(b);\n    END_IF;\nEND_PROGRAM\n";
    write(dir.path(), "main.st", source);
    let trace = checked_trace(dir.path(), "95ms", "main.r^,main.nothing^");
    // scans at 0, 10, … 90 ms: r^ is a (1, 2, 3, 4), then b from the fifth scan on
    let seen: Vec<&str> = trace
        .lines()
        .filter_map(|l| l.split_once("\"dev\":\"main.r^\",\"value\":"))
        .map(|(_, v)| v.trim_end_matches('}'))
        .collect();
    assert_eq!(seen, ["1", "2", "3", "4", "200"], "{trace}");
    assert!(last(&trace, "main.nothing^").is_none_or(|v| v == "0"), "{trace}");
}

/// `--watch main.p^.next^.value` follows both references at every look (docs/ST.md,
/// "Tools"): `b.value` while `a.next` points to `b`, then `c.value` once the program moves it;
/// a chain with a NULL reference shows 0.
#[test]
fn a_watch_through_two_references_follows_both() {
    let dir = TempDir::new("st-watch-chain");
    write(
        dir.path(),
        "plcd.toml",
        "[plc]\nscan_period_ms = 10\n\n[[program]]\nname = \"main\"\nfile = \"main.st\"\n",
    );
    let source = "TYPE Node : STRUCT value : INT; next : REF_TO Node; END_STRUCT END_TYPE\n\
        PROGRAM main\nVAR\n    n : INT;\n    a : Node;\n    b : Node;\n    c : Node := (value := 300);\n\
        p : REF_TO Node;\nEND_VAR\n    n := n + 1;\n    b.value := n;\n    p := REF(a);\n\
        IF n < 5 THEN\n        a.next := REF(b);\n    ELSE\n        a.next := REF(c);\n    END_IF;\nEND_PROGRAM\n";
    write(dir.path(), "main.st", source);
    let trace = checked_trace(dir.path(), "95ms", "main.p^.next^.value,main.p^.next^.next^.value");
    // scans at 0, 10, … 90 ms: p^.next^ is b (1, 2, 3, 4), then c from the fifth scan on
    let seen: Vec<&str> = trace
        .lines()
        .filter_map(|l| l.split_once("\"dev\":\"main.p^.next^.value\",\"value\":"))
        .map(|(_, v)| v.trim_end_matches('}'))
        .collect();
    assert_eq!(seen, ["1", "2", "3", "4", "300"], "{trace}");
    assert!(last(&trace, "main.p^.next^.next^.value").is_none_or(|v| v == "0"), "{trace}");
}

/// `{attribute 'qualified_only'}` before a `.TcGVL`'s `VAR_GLOBAL` makes `Gvl.x` the only name
/// of its variables outside the list, as TwinCAT enforces it: the plain name is an error at its
/// place naming the qualified form (docs/ST.md, "Qualified names").
#[test]
fn a_qualified_only_gvl_refuses_the_plain_name() {
    let dir = project();
    let main = pou(
        "MAIN",
        "PROGRAM MAIN\r\nVAR\r\n\tc : Counter;\r\n\tp : Point;\r\n\tn : INT;\r\nEND_VAR",
        "c(step := STEP);",
    );
    write(dir.path(), "MAIN.TcPOU", &main);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    // line 11 of the file: `      <ST><![CDATA[c(step := STEP);`, `STEP` at column 30
    assert!(
        stderr.contains(
            "MAIN.TcPOU:11:30: error: `STEP` is a global of the list `Constants`, which is \
             {attribute 'qualified_only'}: name it `Constants.STEP`"
        ),
        "{stderr}"
    );
}

/// Two global variable lists may declare the same name, as TwinCAT allows: each is its list's
/// own global, named `GVL_A.x` in the code, in `--watch` and in the trace (docs/ST.md,
/// "Qualified names"); a list's own declarations name its own plainly; a global no other list
/// declares keeps its plain name. The plain `x` elsewhere is an error naming both forms.
#[test]
fn two_global_variable_lists_may_declare_the_same_name() {
    let dir = TempDir::new("st-sources-two-lists");
    let d = dir.path();
    write(
        d,
        "plcd.toml",
        "[plc]\nscan_period_ms = 10\n\n[[program]]\nname = \"main\"\nfile = \"main.st\"\n\n\
         [st]\nlibrary = [\"GVL_A.st\", \"GVL_B.st\"]\n",
    );
    write(
        d,
        "GVL_A.st",
        "VAR_GLOBAL CONSTANT\n    k : INT := 2;\nEND_VAR\n\
         VAR_GLOBAL\n    x : INT := 1;\n    twice : INT := k * 2;\nEND_VAR\n",
    );
    write(
        d,
        "GVL_B.st",
        "VAR_GLOBAL CONSTANT\n    k : INT := 5;\nEND_VAR\n\
         VAR_GLOBAL\n    x : INT := 10;\n    total : INT;\nEND_VAR\n",
    );
    let main = "PROGRAM main\nVAR\n    sum : INT;\nEND_VAR\n    GVL_A.x := GVL_A.x + 1;\n\
        GVL_B.x := GVL_B.x + 10;\n    sum := GVL_A.x + GVL_B.x + GVL_A.twice;\n\
        total := sum;\nEND_PROGRAM\n";
    write(d, "main.st", main);
    let trace = checked_trace(d, "25ms", "GVL_A.x,gvl_b.x,total,GVL_A");
    // scans at 0, 10, 20 ms: A.x 1 → 4, B.x 10 → 40; twice = 4 (GVL_A's own k, 2, times 2)
    assert_eq!(last(&trace, "GVL_A.x").as_deref(), Some("4"), "{trace}");
    assert_eq!(last(&trace, "GVL_B.x").as_deref(), Some("40"), "{trace}");
    assert_eq!(last(&trace, "total").as_deref(), Some("48"), "{trace}");

    write(d, "main.st", &main.replace("total := sum;", "total := x;"));
    let out = plcd(d, &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(
            "main.st:8:10: error: `x` is ambiguous: 2 global variable lists declare it; name \
             one, `GVL_A.x` or `GVL_B.x`"
        ),
        "{stderr}"
    );
    assert!(stderr.contains("plcd.toml: 1 error(s)"), "one message for one mistake: {stderr}");
}

/// A configuration as Beremiz and OpenPLC Editor write one, with the access paths of IEC
/// 61131-3's example (§6.8.2): to a direct address through the resource, to a program
/// instance's variable and to a global; the sim's `--watch` names them by their own names.
const ACCESS_PATHS: &str = "PROGRAM P1
  VAR
    x : UINT;
    start AT %IX1.1 : BOOL;
  END_VAR
  VAR_ACCESS
    runs : x : UINT;   (* a PROGRAM's own access path, IEC 61131-3 2nd ed. *)
  END_VAR
  x := x + 1;
END_PROGRAM

CONFIGURATION Config0
  VAR_GLOBAL
    limit : INT := 5;
  END_VAR
  RESOURCE STATION_1 ON PLC
    TASK task0(INTERVAL := T#10ms, PRIORITY := 1);
    PROGRAM instance0 WITH task0 : P1;
  END_RESOURCE
  VAR_ACCESS
    ABLE : STATION_1.%IX1.1 : BOOL READ_ONLY;
    BAKER : STATION_1.instance0.x : UINT READ_WRITE;
    CHARLIE : limit : INT;
  END_VAR
END_CONFIGURATION
";

#[test]
fn a_configurations_access_paths_name_its_variables() {
    let dir = TempDir::new("st-access-paths");
    write(dir.path(), "plcd.toml", "[[program]]\nfile = \"plc.st\"\n");
    write(dir.path(), "plc.st", ACCESS_PATHS);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let listed: Vec<&str> = stdout.lines().filter(|l| l.contains("access path")).collect();
    assert_eq!(
        listed,
        [
            "  access path ABLE → P0009, read only",
            "  access path BAKER → instance0.x, read and write",
            "  access path CHARLIE → limit, read only",
            "  access path runs → instance0.x, read only",
        ],
        "{stdout}"
    );
    let trace = checked_trace(dir.path(), "49ms", "BAKER,runs,CHARLIE,ABLE");
    // the scan every 10 ms: at 0, 10, 20, 30, 40 ms
    assert_eq!(last(&trace, "BAKER").as_deref(), Some("5"), "{trace}");
    assert_eq!(last(&trace, "runs").as_deref(), Some("5"), "{trace}");
    // a value that never changes is not traced: `CHARLIE` and `ABLE` are only resolved
    assert_eq!(last(&trace, "CHARLIE"), None, "{trace}");
}

/// `[iec.variables]` binds the partly specified variables of `[[program]]`s without a
/// CONFIGURATION, as VAR_CONFIG binds a configuration's: two instances of one PROGRAM, one
/// bound (it runs a copy of the PROGRAM's code of its own, with its function block's copy),
/// the other keeping variable memory; `plcd check` notes each binding.
#[test]
fn iec_variables_bind_the_instances_of_programs_without_a_configuration() {
    let dir = TempDir::new("st-iec-variables");
    let toml = "[plc]\nscan_period_ms = 10\n\n[[program]]\nname = \"a\"\nfile = \"plc.st\"\n\n\
                [[program]]\nname = \"b\"\nfile = \"plc.st\"\n\n[iec.variables]\n\
                \"a.lamp\" = \"%QX0.3\"\n\"a.tank.level\" = \"%MW5\"\n\"a.alarm\" = \"%M0003\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "FUNCTION_BLOCK Tank
  VAR level AT %MW* : INT := 7; END_VAR
  level := level + 1;
END_FUNCTION_BLOCK

PROGRAM blink
  VAR
    lamp AT %Q* : BOOL;
    alarm AT %M* : BOOL;
    tank : Tank;
    n : INT;
  END_VAR
  n := n + 1;
  lamp := n MOD 2 = 1;
  alarm := tank.level > 8;
  tank();
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        stdout.lines().filter(|l| l.starts_with("  config:")).collect::<Vec<_>>(),
        [
            "  config: [iec.variables] a.lamp AT %QX0.3 → P0643",
            "  config: [iec.variables] a.tank.level AT %MW5 → D14005",
            "  config: [iec.variables] a.alarm AT %M0003 → M0003",
        ]
    );
    let watch = "a.n,P0643,D14005,a.tank.level,b.tank.level,a.lamp,b.lamp,M0003,a.alarm";
    let run = |engine: &[&str]| sim_trace(dir.path(), "25ms", watch, engine);
    let trace = run(&[]);
    // three scans: a's lamp at P0643 (n = 3, odd), its tank's level at D14005 from the
    // declaration's 7, written at RUN start, one more a scan
    assert_eq!(last(&trace, "a.n").as_deref(), Some("3"), "{trace}");
    assert_eq!(last(&trace, "P0643").as_deref(), Some("1"));
    assert_eq!(last(&trace, "D14005").as_deref(), Some("10"));
    // the tools name the bound variables by their paths and reach the devices
    assert_eq!(last(&trace, "a.tank.level").as_deref(), Some("10"));
    assert_eq!(last(&trace, "a.lamp").as_deref(), Some("1"));
    assert_eq!(last(&trace, "a.alarm").as_deref(), Some("1"));
    assert_eq!(last(&trace, "M0003").as_deref(), Some("1"));
    // b keeps its variables in memory, apart from the devices
    assert_eq!(last(&trace, "b.tank.level").as_deref(), Some("10"));
    assert_eq!(last(&trace, "b.lamp").as_deref(), Some("1"));
    // the copies are ordinary code: the interpreter gives the native code's trace
    assert_eq!(run(&["--interpreter"]), trace);
}

/// `[iec.variables]` next to a configuration's VAR_CONFIG: it binds what VAR_CONFIG leaves
/// partly specified, its paths written from the resource or from the instance.
#[test]
fn iec_variables_bind_what_a_configuration_leaves_partly_specified() {
    let dir = TempDir::new("st-iec-variables-configuration");
    let toml =
        "[[program]]\nfile = \"plc.st\"\n\n[iec.variables]\n\"Res0.inst.seen\" = \"%IX0.1\"\n";
    write(dir.path(), "plcd.toml", toml);
    write(dir.path(), "plc.st", VAR_CONFIG);
    write(dir.path(), "inputs.csv", "15ms, P0001, 1\n");
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(1), "VAR_CONFIG binds inst.seen already");
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "plcd.toml:5:1: error: iec.variables \"Res0.inst.seen\": `Res0.inst.seen` is already \
         bound by VAR_CONFIG (plc.st:43)\nplcd.toml: 1 error(s)\n"
    );
    // without VAR_CONFIG's entry, the config's binds it
    write(dir.path(), "plc.st", &VAR_CONFIG.replace("    inst.seen AT %IX0.1 : BOOL;\n", ""));
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("\n  config: [iec.variables] Res0.inst.seen AT %IX0.1 → P0001\n"));
    let args = ["sim", "--config", "plcd.toml", "--for", "25ms", "--inputs", "inputs.csv"];
    let mut args = args.to_vec();
    args.extend(["--watch", "inst.copies", "--trace", "-"]);
    let out = plcd(dir.path(), &args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    // seen (P0001) read at the scan of 20 ms only
    assert_eq!(last(&String::from_utf8_lossy(&out.stdout), "inst.copies").as_deref(), Some("1"));
}

/// Beremiz's multi-level addresses placed by `[iec.addresses]`: a declaration at one is a
/// located variable at the entry's device, checked by the key's size letter as any address;
/// `plcd check` notes each entry used and warns of one nothing names.
#[test]
fn iec_addresses_place_beremiz_multi_level_addresses() {
    let dir = TempDir::new("st-iec-addresses");
    let toml = "[[program]]\nfile = \"plc.st\"\n\n[iec.addresses]\n\
                \"%IX100.0.0\" = \"%IX4.0\"\n\"%IW100.0.1\" = \"%D00100\"\n\
                \"%QX100.1.0\" = \"%P0050\"\n\"%QW2.1\" = \"%QW7\"\n";
    write(dir.path(), "plcd.toml", toml);
    let text = "PROGRAM main
  VAR
    button AT %IX100.0.0 : BOOL;
    speed AT %IW100.0.1 : INT;
    lamp AT %QX100.1.0 : BOOL;
    copy : INT;
  END_VAR
  lamp := button;
  copy := speed;
END_PROGRAM
";
    write(dir.path(), "plc.st", text);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> =
        stdout.lines().filter(|l| l.starts_with("  config:") || l.contains(": main.")).collect();
    assert_eq!(
        lines,
        [
            "  iec: plc.st:3: main.button AT %IX100.0.0 → P0020",
            "  iec: plc.st:4: main.speed AT %IW100.0.1 → D00100",
            "  iec: plc.st:5: main.lamp AT %QX100.1.0 → P0050",
            "  config: [iec.addresses] %IX100.0.0 → %IX4.0 → P0020",
            "  config: [iec.addresses] %IW100.0.1 → D00100",
            "  config: [iec.addresses] %QX100.1.0 → P0050",
        ]
    );
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "plcd.toml:8:1: warning: iec.addresses \"%QW2.1\": no declaration, VAR_CONFIG, \
         configuration, access path or [iec.variables] entry of the project names `%QW2.1`\n"
    );
    write(dir.path(), "inputs.csv", "5ms, P0020, 1\n5ms, D00100, 1234\n");
    let args = ["sim", "--config", "plcd.toml", "--for", "10ms", "--inputs", "inputs.csv"];
    let mut args = args.to_vec();
    args.extend(["--watch", "P0050,plc.copy,plc.lamp", "--trace", "-"]);
    let out = plcd(dir.path(), &args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    assert_eq!(last(&trace, "P0050").as_deref(), Some("1"), "{trace}");
    assert_eq!(last(&trace, "plc.lamp").as_deref(), Some("1"));
    assert_eq!(last(&trace, "plc.copy").as_deref(), Some("1234"));
}

/// `[iec.variables]` inside a function block instance of a configuration's program instance,
/// beside VAR_CONFIG's bindings in the same block's other instance: `P5.FB1` (the PROGRAM's
/// other instance) gets a copy of the block of its own, as `P4.FB1` got for VAR_CONFIG; a
/// variable VAR_CONFIG binds already is refused at the config's key, naming VAR_CONFIG's line.
#[test]
fn iec_variables_bind_inside_a_block_beside_var_config() {
    let dir = TempDir::new("st-iec-variables-inside-a-block");
    let toml = "[[program]]\nfile = \"plc.st\"\n\n[iec.variables]\n\
                \"STATION_2.P5.FB1.C3\" = \"%QW5\"\n\"P4.FB1.C3\" = \"%QW6\"\n";
    write(dir.path(), "plcd.toml", toml);
    write(dir.path(), "plc.st", VAR_CONFIG_INSIDE_A_BLOCK);
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "plcd.toml:6:1: error: iec.variables \"P4.FB1.C3\": `P4.FB1.C3` is already bound by \
         VAR_CONFIG (plc.st:34)\nplcd.toml: 1 error(s)\n"
    );
    write(dir.path(), "plcd.toml", &toml.replace("\"P4.FB1.C3\" = \"%QW6\"\n", ""));
    let watch = "D12003,D12005,P4.FB1.C3,P5.FB1.C3,P5.FB2.C3,P5.seen";
    let args = ["sim", "--config", "plcd.toml", "--for", "25ms", "--watch", watch, "--trace", "-"];
    let out = plcd(dir.path(), &args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    // three scans, 10 a call: P4's C3 at %QW3 (D12003) by VAR_CONFIG, P5's at %QW5 (D12005)
    // by the config, each instance's own; P5.FB2 keeps variable memory
    assert_eq!(last(&trace, "D12003").as_deref(), Some("30"), "{trace}");
    assert_eq!(last(&trace, "D12005").as_deref(), Some("30"));
    assert_eq!(last(&trace, "P5.FB1.C3").as_deref(), Some("30"));
    assert_eq!(last(&trace, "P5.seen").as_deref(), Some("30"));
    assert_eq!(last(&trace, "P5.FB2.C3").as_deref(), Some("3"));
}

/// The trace (JSON Lines) of `plcd sim` on the project in `dir` for `run_for` of virtual time,
/// watching `watch`, with the options `more` (`--interpreter`, `--inputs`); the run must
/// succeed.
fn sim_trace(dir: &Path, run_for: &str, watch: &str, more: &[&str]) -> String {
    let mut args = vec!["sim", "--config", "plcd.toml", "--for", run_for, "--watch", watch];
    args.extend(["--trace", "-"]);
    args.extend(more);
    let out = plcd(dir, &args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}
