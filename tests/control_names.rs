//! `plcctl get`, `set`, `watch`, `force` and `unforce` by Structured Text variable name, against
//! a real daemon on the sim backend: every kind of value read and written back, located
//! variables as their devices, the refusals (CONSTANT, out of range, bad syntax, a structure, an
//! unknown name, a variable that is no I/O bit), the writes of one `set` at one END, and names
//! resolved against a project loaded online; dates as literals, and the real-time clock of
//! `plcd run` reading the system's.
//!
//! Real time is only waited on, never asserted: `set` answers once its writes are applied and
//! `get` from a capture taken after the request, so a value written is read back at once; only
//! what the program itself does (a forced input copied to an output) is waited for.

mod harness;

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::process::Output;
use std::time::Duration;

use harness::daemon::{Daemon, Project};
use serde_json::{json, Value};

const PATIENCE: Duration = Duration::from_secs(10);

const CONFIG: &str = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
    [[program]]\nname = \"main\"\nfile = \"main.st\"\n\
    [st]\nlibrary = [\"types.st\"]\n\
    [control]\nsocket = \"plcd.sock\"\n";

const TYPES: &str = "\
TYPE
    Mode : (Idle, Running := 5, Fault);
    Axis : STRUCT
        pos : REAL;
        homed : BOOL;
    END_STRUCT;
END_TYPE
VAR_GLOBAL
    Total_Parts : DINT := 12;
END_VAR
";

/// `lamp` copies the input `inp`; `scans` counts; `torn` counts the scans that saw the twenty
/// elements of `same` differ (the writes of one `set` split over two ENDs).
const MAIN: &str = "\
PROGRAM Main
VAR
    Speed : INT := 7;
    big : LINT;
    u : ULINT;
    r : REAL := 1.5;
    lr : LREAL;
    flag : BOOL := TRUE;
    t : TIME := T#1s500ms;
    s : STRING[20] := 'hi';
    w : WSTRING[10] := \"Grüße €\";
    mode : Mode := Running;
    buf : ARRAY [1..4] OF INT := [10, 20, 30, 40];
    m : ARRAY [1..2, 1..2] OF DINT;
    axis : Axis;
    t1 : TON;
    lamp AT %QX4.0 : BOOL; (* byte 4 of the %QX image, from P064: P0660 *)
    inp AT %IX0.1 : BOOL;
    pos AT %D00200 : DINT;
    same : ARRAY [1..20] OF INT;
    scans : DINT;
    torn : DINT;
    i : INT;
    at_pos : POINTER TO DINT;
    at_speed : REF_TO INT;
END_VAR
VAR CONSTANT
    kmax : INT := 10;
END_VAR
    scans := scans + 1;
    at_pos := ADR(pos);
    at_speed := REF(Speed);
    lamp := inp;
    FOR i := 2 TO 20 DO
        IF same[i] <> same[1] THEN
            torn := torn + 1;
        END_IF;
    END_FOR;
END_PROGRAM
";

struct Plc {
    daemon: Daemon,
    project: Project,
}

impl Plc {
    fn start(name: &str) -> Plc {
        let project = Project::new(
            &format!("names-{name}"),
            &[("plcd.toml", CONFIG), ("types.st", TYPES), ("main.st", MAIN)],
        );
        let daemon = project.start().with_patience(PATIENCE);
        let plc = Plc { daemon, project };
        plc.daemon.wait_for("control socket");
        plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");
        plc
    }

    fn ctl(&self, args: &[&str]) -> Output {
        self.project.plcctl(args)
    }

    fn ok(&self, args: &[&str]) -> String {
        let out = self.ctl(args);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert_eq!(
            out.status.code(),
            Some(0),
            "plcctl {args:?}: {text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        text
    }

    fn json(&self, args: &[&str]) -> Value {
        let mut all = vec!["--json"];
        all.extend_from_slice(args);
        serde_json::from_str(&self.ok(&all)).unwrap()
    }

    /// `get` of names: the `values` array.
    fn values(&self, names: &[&str]) -> Vec<Value> {
        let mut args = vec!["get"];
        args.extend_from_slice(names);
        self.json(&args)["values"].as_array().unwrap().clone()
    }

    /// The value of one name.
    fn get(&self, name: &str) -> Value {
        self.values(&[name])[0]["value"].clone()
    }

    /// `plcctl ARGS` that must fail with the daemon's error; its message.
    fn refused(&self, args: &[&str]) -> String {
        let out = self.ctl(args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(1), "plcctl {args:?} must fail: {err}");
        err
    }

    /// One raw request line; its answer.
    fn raw(&self, request: &Value) -> Value {
        let mut stream = UnixStream::connect(self.project.socket()).unwrap();
        stream.set_read_timeout(Some(PATIENCE)).unwrap();
        stream.write_all(format!("{request}\n").as_bytes()).unwrap();
        let mut line = String::new();
        BufReader::new(stream).read_line(&mut line).unwrap();
        serde_json::from_str(&line).unwrap()
    }

    fn stop(self) {
        let (code, log) = self.daemon.stop();
        assert_eq!(code, 0, "clean stop:\n{}", log.join("\n"));
    }
}

#[test]
fn get_and_set_every_kind_of_variable_by_name() {
    let plc = Plc::start("types");

    // Initial values, typed as the trace writes them; names case-insensitive, answered with the
    // declaration's spelling.
    let values = plc.values(&[
        "MAIN.speed",
        "main.r",
        "main.flag",
        "main.t",
        "main.s",
        "main.mode",
        "main.buf[3]",
        "main.m[1,2]",
        "total_parts",
        "D00000",
    ]);
    let pairs: Vec<(String, Value, Value)> = values
        .iter()
        .map(|v| (v["dev"].as_str().unwrap().to_string(), v["value"].clone(), v["type"].clone()))
        .collect();
    let expected = [
        ("main.Speed", json!(7), json!("INT")),
        ("main.r", json!(1.5), json!("REAL")),
        ("main.flag", json!(1), json!("BOOL")),
        ("main.t", json!("T#1s500ms"), json!("TIME")),
        ("main.s", json!("hi"), json!("STRING[20]")),
        ("main.mode", json!("Running"), json!("Mode")),
        ("main.buf[3]", json!(30), json!("INT")),
        ("main.m[1,2]", json!(0), json!("DINT")),
        ("Total_Parts", json!(12), json!("DINT")),
        ("D00000", json!(0), Value::Null),
    ];
    for (got, (dev, value, ty)) in pairs.iter().zip(expected) {
        assert_eq!(got, &(dev.to_string(), value, ty), "{values:?}");
    }
    // A prefix stands for every variable under it, in place.
    let axis = plc.values(&["main.axis", "main.speed"]);
    let names: Vec<&str> = axis.iter().map(|v| v["dev"].as_str().unwrap()).collect();
    assert_eq!(names, ["main.axis.pos", "main.axis.homed", "main.Speed"]);
    let timer = plc.values(&["main.t1"]);
    assert!(timer.iter().any(|v| v["dev"] == "main.t1.ET" && v["value"] == "T#0s"), "{timer:?}");
    assert!(timer.iter().all(|v| v["dev"].as_str().unwrap().starts_with("main.t1.")));
    // A comma list, split outside brackets.
    assert_eq!(plc.values(&["main.m[1,2],main.buf[1]"]).len(), 2);

    // Every type written in one request, at one END, read back.
    let written = plc.ok(&[
        "set",
        "main.speed",
        "-5",
        "main.big=-9223372036854775808",
        "main.u",
        "18446744073709551615",
        "main.r",
        "0.1",
        "main.lr=1e300",
        "main.flag",
        "FALSE",
        "main.t",
        "T#2s",
        "main.s",
        "'it$'s'",
        "main.mode",
        "fault",
        "main.buf[2]",
        "99",
        "main.m[2,1]=-3",
        "main.axis.pos",
        "2.5",
        "total_parts",
        "16#10",
    ]);
    assert!(written.starts_with("13 writes applied at the END of scan "), "{written}");
    let got: Vec<Value> = plc
        .values(&[
            "main.speed",
            "main.big",
            "main.u",
            "main.r",
            "main.lr",
            "main.flag",
            "main.t",
            "main.s",
            "main.mode",
            "main.buf[2]",
            "main.m[2,1]",
            "main.axis.pos",
            "total_parts",
        ])
        .iter()
        .map(|v| v["value"].clone())
        .collect();
    assert_eq!(
        got,
        [
            json!(-5),
            json!(i64::MIN),
            json!(u64::MAX),
            json!(0.1),
            json!(1e300),
            json!(0),
            json!("T#2s"),
            json!("it's"),
            json!("Fault"),
            json!(99),
            json!(-3),
            json!(2.5),
            json!(16),
        ]
    );
    // The human form: a STRING as a literal, the type beside the value.
    let human = plc.ok(&["get", "main.s", "main.t", "D00000"]);
    let lines: Vec<&str> = human.lines().collect();
    assert_eq!(
        lines[0].split_whitespace().collect::<Vec<_>>(),
        ["main.s", "'it$'s'", "STRING[20]"]
    );
    assert_eq!(lines[1].split_whitespace().collect::<Vec<_>>(), ["main.t", "T#2s", "TIME"]);
    assert_eq!(lines[2].split_whitespace().next(), Some("D00000"));

    // A WSTRING: its characters, as a literal in double quotes for a human; set as one.
    assert_eq!(plc.values(&["main.w"])[0]["value"], json!("Grüße €"));
    assert_eq!(plc.values(&["main.w"])[0]["type"], json!("WSTRING[10]"));
    plc.ok(&["set", "main.w", "\"Ω $\"1$\" $20AC\""]);
    assert_eq!(plc.get("main.w"), json!("Ω \"1\" €"));
    let human = plc.ok(&["get", "main.w"]);
    assert_eq!(
        human.split_whitespace().collect::<Vec<_>>(),
        ["main.w", "\"Ω", "$\"1$\"", "€\"", "WSTRING[10]"]
    );
    let err = plc.refused(&["set", "main.w", "12345678901"]);
    assert!(err.contains("11 characters do not fit in a WSTRING[10]"), "{err}");
    let watched = plc.ok(&["watch", "--count", "1", "--interval", "10ms", "main.w"]);
    assert!(watched.contains("main.w=\"Ω $\"1$\" €\""), "{watched}");

    // JSON numbers and strings from a client other than plcctl; a non-finite real.
    let answer = plc.raw(&json!({"v": 1, "cmd": "set", "writes": [
        {"dev": "main.r", "value": 2.25}, {"dev": "main.speed", "value": -4},
        {"dev": "main.lr", "value": "-inf"}, {"dev": "D00010", "value": 9}]}));
    assert_eq!(answer["ok"]["count"], 4, "{answer}");
    assert_eq!(plc.get("main.r"), json!(2.25));
    assert_eq!(plc.get("main.speed"), json!(-4));
    assert_eq!(plc.get("main.lr"), json!("-inf"));
    assert_eq!(plc.get("D00010"), json!(9));

    // A located DINT is its two D words, low word first.
    plc.ok(&["set", "main.pos", "16#12345678"]);
    assert_eq!(
        plc.values(&["D00200", "D00201"]).iter().map(|v| v["value"].clone()).collect::<Vec<_>>(),
        [json!(0x5678), json!(0x1234)]
    );
    plc.ok(&["set", "D00200=1", "D00201=0"]);
    assert_eq!(plc.get("main.pos"), json!(1));

    // `watch` by name.
    let watched = plc.ok(&["watch", "--count", "2", "--interval", "10ms", "main.t", "main.s"]);
    assert_eq!(watched.lines().count(), 2, "{watched}");
    assert!(watched.lines().all(|l| l.contains("main.t=T#2s") && l.contains("main.s='it$'s'")));

    // Refusals: nothing of a refused request is written.
    let before = plc.get("main.speed");
    let err = plc.refused(&["set", "main.speed", "1", "main.kmax", "1"]);
    assert!(err.contains("main.kmax is CONSTANT (INT): it cannot be written"), "{err}");
    assert_eq!(plc.get("main.speed"), before);
    let err = plc.refused(&["set", "main.speed", "70000"]);
    assert!(err.contains("main.Speed (INT): `70000` is out of range for INT"), "{err}");
    let err = plc.refused(&["set", "main.t", "5"]);
    assert!(err.contains("main.t (TIME)") && err.contains("is not a TIME"), "{err}");
    let err = plc.refused(&["set", "main.mode", "Walking"]);
    assert!(err.contains("is not a value of Mode (Idle, Running, Fault)"), "{err}");
    let err = plc.refused(&["set", "main.s", "123456789012345678901"]);
    assert!(err.contains("21 characters do not fit in a STRING[20]"), "{err}");
    let err = plc.refused(&["set", "main.axis", "1"]);
    assert!(err.contains("`main.axis` holds 2 variables"), "{err}");
    let err = plc.refused(&["set", "main.buf[5]", "1"]);
    assert!(err.contains("no device or variable `main.buf[5]`"), "{err}");
    let err = plc.refused(&["get", "main.spede"]);
    assert!(
        err.contains("no device or variable `main.spede` (did you mean `main.Speed`?)"),
        "{err}"
    );
    let err = plc.refused(&["get", "D99999"]);
    assert!(err.contains("out of range"), "{err}");
    // A reference is shown as what it points to, and never written.
    let at_pos = plc.values(&["main.at_pos"]);
    assert_eq!(
        (&at_pos[0]["value"], &at_pos[0]["type"]),
        (&json!("D00200"), &json!("POINTER TO DINT"))
    );
    assert_eq!(plc.get("main.at_speed"), json!("main.Speed"));
    let err = plc.refused(&["set", "main.at_pos", "5"]);
    assert!(
        err.contains("main.at_pos (POINTER TO DINT): a POINTER TO DINT cannot be written"),
        "{err}"
    );
    let out = plc.ctl(&["set", "main.speed"]);
    assert_eq!(out.status.code(), Some(2), "a name without its value is a usage error");
    plc.stop();
}

#[test]
fn the_writes_of_one_set_land_at_one_end() {
    let plc = Plc::start("one-end");
    // Twenty elements (two commands of writes) and a STRING between them, twenty times over;
    // a scan that saw them differ counts in `torn`.
    for round in 1..=20 {
        let mut args: Vec<String> = vec!["set".into()];
        for i in 1..=20 {
            args.push(format!("main.same[{i}]={round}"));
            if i == 10 {
                args.push(format!("main.s=round {round}"));
            }
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert!(plc.ok(&args).starts_with("21 writes"));
    }
    assert_eq!(plc.get("main.same[20]"), json!(20));
    assert_eq!(plc.get("main.s"), json!("round 20"));
    assert_eq!(plc.get("main.torn"), json!(0), "every set applied at one END");
    // The check itself sees a partial write.
    plc.ok(&["set", "main.same[1]=99"]);
    plc.daemon.wait("a scan that sees the elements differ", || plc.get("main.torn") != json!(0));
    plc.stop();
}

#[test]
fn force_by_name_and_names_of_a_new_project() {
    let plc = Plc::start("force");
    // A BOOL located at a P bit is that bit.
    let forced = plc.json(&["force", "main.inp", "1"]);
    assert_eq!(forced["forces"], json!([{"dev": "P0001", "value": 1}]));
    plc.daemon.wait("the forced input copied to the lamp", || plc.get("main.lamp") == json!(1));
    assert_eq!(plc.get("P0660"), json!(1));
    assert_eq!(plc.get("main.inp"), json!(1));
    plc.ok(&["unforce", "MAIN.INP"]);
    let err = plc.refused(&["unforce", "main.inp"]);
    assert!(err.contains("main.inp (P0001) is not forced"), "{err}");
    // Forcing the output itself by its name.
    plc.ok(&["force", "main.lamp=0"]);
    plc.ok(&["force", "main.inp=1"]);
    assert_eq!(
        plc.json(&["forces"])["forces"],
        json!([{"dev": "P0001", "value": 1}, {"dev": "P0660", "value": 0}])
    );
    plc.ok(&["unforce", "--all"]);

    for (name, shown) in
        [("main.flag", "main.flag"), ("main.pos", "main.pos"), ("main.axis", "main.axis")]
    {
        let err = plc.refused(&["force", name, "1"]);
        assert!(
            err.contains(&format!(
                "{shown} is not an I/O bit: only P bits, or BOOL variables located at one, can be forced"
            )),
            "{err}"
        );
    }
    let err = plc.refused(&["force", "main.lampp", "1"]);
    assert!(
        err.contains("no device or variable `main.lampp` (did you mean `main.lamp`?)"),
        "{err}"
    );

    // An online change: names resolve against the new project, kept variables keep their
    // values, a new one starts from its initial value.
    plc.ok(&["set", "main.speed", "42"]);
    let dir = plc.project.dir.path().to_path_buf();
    let changed = MAIN
        .replace("    i : INT;\n", "    i : INT;\n    extra : INT := 5;\n")
        .replace("    Speed : INT := 7;\n", "    Speed : INT := 7;\n    gone_soon : BOOL;\n");
    std::fs::write(dir.join("main2.st"), changed).unwrap();
    std::fs::write(dir.join("new.toml"), CONFIG.replace("main.st", "main2.st")).unwrap();
    let new = dir.join("new.toml");
    plc.ok(&["load", "--config", new.to_str().unwrap(), "--online"]);
    assert_eq!(plc.get("main.extra"), json!(5));
    assert_eq!(plc.get("main.speed"), json!(42));
    assert_eq!(plc.get("main.gone_soon"), json!(0));
    let err = plc.refused(&["get", "main.extraa"]);
    assert!(err.contains("did you mean `main.extra`?"), "{err}");
    plc.stop();
}

/// The real-time clock of `plcd run` is the system's, in UTC; a date is read and written as
/// its literal.
#[test]
fn dates_are_read_and_written_as_literals_and_the_clock_is_the_systems() {
    const CLOCK: &str = "PROGRAM Main\nVAR\n    now : DT;\n    day : DATE;\nEND_VAR\n\
        now := SysRtcGetTime(TRUE);\nEND_PROGRAM\n";
    let config = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
        [[program]]\nname = \"main\"\nfile = \"main.st\"\n[control]\nsocket = \"plcd.sock\"\n";
    let project = Project::new("names-clock", &[("plcd.toml", config), ("main.st", CLOCK)]);
    let daemon = project.start().with_patience(PATIENCE);
    let plc = Plc { daemon, project };
    plc.daemon.wait_for("control socket");
    plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");

    let dt = plcd::value::ValueType::Calendar(plcd::value::Calendar::Dt);
    let text = plc.get("main.now");
    let read = plcd::value::parse(&dt, text.as_str().unwrap()).unwrap();
    let system = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap();
    assert!(system.as_secs().abs_diff(read) < 60, "{text} is not now ({})", system.as_secs());

    plc.ok(&["set", "main.day", "D#2024-03-01"]);
    assert_eq!(plc.get("main.day"), json!("D#2024-03-01"));
    let err = plc.refused(&["set", "main.day", "D#2024-02-30"]);
    assert!(err.contains("day 30 is not a day of 2024-02"), "{err}");
    plc.stop();
}

/// The new constructs by name (issue 29): a variable of an FB instance that has methods and a
/// method's `VAR_INST` (`main.c.Add.calls`), a UNION's members (the same bytes), a TOD and a DT
/// read and written as literals, a CHAR, a reference shown as the variable it points to, and a
/// chart's step flags `X` and `T` (read, never written); then an online change that keeps the
/// chart's active step, the method's `VAR_INST` and the union.
#[test]
fn methods_unions_dates_references_and_chart_steps_by_name() {
    const NEW: &str = "\
TYPE U : UNION dw : DWORD; b : ARRAY [0..3] OF BYTE; END_UNION END_TYPE
INTERFACE ICount
METHOD Add : INT
VAR_INPUT delta : INT; END_VAR
END_METHOD
END_INTERFACE
FUNCTION_BLOCK Counter IMPLEMENTS ICount
VAR n : INT; END_VAR
METHOD Add : INT
VAR_INPUT delta : INT; END_VAR
VAR_INST calls : DINT; END_VAR
    calls := calls + 1;
    n := n + delta;
    Add := n;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR
    c : Counter;
    i : ICount;
    u : U;
    shift : TOD := TOD#06:00:00;
    stamp : DT;
    ch : CHAR := 'a';
    r : REF_TO DINT;
    hits : DINT;
    go : BOOL;
    lamp : BOOL;
END_VAR
INITIAL_STEP Idle:
    Work(N);
END_STEP
STEP Fill:
    lamp(N);
    Work(N);
END_STEP
TRANSITION FROM Idle TO Fill := go; END_TRANSITION
TRANSITION FROM Fill TO Idle := NOT go; END_TRANSITION
ACTION Work:
    i := c;
    i.Add(1);
    hits := hits + 1;
    r := REF(hits);
END_ACTION
END_PROGRAM
";
    let config = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
        [[program]]\nname = \"main\"\nfile = \"main.st\"\n[control]\nsocket = \"plcd.sock\"\n";
    let project = Project::new("names-new", &[("plcd.toml", config), ("main.st", NEW)]);
    let daemon = project.start().with_patience(PATIENCE);
    let plc = Plc { daemon, project };
    plc.daemon.wait_for("control socket");
    plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");

    // The instance's own variable and its method's VAR_INST, counted by the call through the
    // interface; the instance as a prefix shows both.
    plc.daemon.wait("the method called", || plc.get("main.c.n").as_i64() > Some(2));
    let calls = plc.values(&["main.c.Add.calls"]);
    assert_eq!(calls[0]["type"], json!("DINT"));
    assert!(calls[0]["value"].as_i64() > Some(2), "{calls:?}");
    let names: Vec<String> =
        plc.values(&["main.c"]).iter().map(|v| v["dev"].as_str().unwrap().to_string()).collect();
    assert!(names.contains(&"main.c.n".to_string()), "{names:?}");
    assert!(names.contains(&"main.c.Add.calls".to_string()), "{names:?}");
    // Written by name, counted on from there.
    plc.ok(&["set", "main.c.n", "-1000"]);
    plc.daemon.wait("n counts on from -1000", || plc.get("main.c.n").as_i64() < Some(0));

    // A reference: what it points to.
    assert_eq!(plc.values(&["main.r"])[0]["value"], json!("main.hits"));
    assert_eq!(plc.values(&["main.r"])[0]["type"], json!("REF_TO DINT"));

    // A union: one member written, the other reads the same bytes.
    plc.ok(&["set", "main.u.dw", "16#11223344"]);
    assert_eq!(plc.get("main.u.b[0]"), json!(0x44));
    assert_eq!(plc.get("main.u.b[3]"), json!(0x11));
    plc.ok(&["set", "main.u.b[3]", "16#7F"]);
    assert_eq!(plc.get("main.u.dw"), json!(0x7F22_3344));

    // TOD, DT and CHAR: shown and written as literals.
    assert_eq!(plc.get("main.shift"), json!("TOD#06:00:00"));
    plc.ok(&["set", "main.shift", "TOD#12:30:15.5", "main.stamp", "DT#2024-03-01-12:30:15"]);
    assert_eq!(plc.get("main.shift"), json!("TOD#12:30:15.5"));
    assert_eq!(plc.get("main.stamp"), json!("DT#2024-03-01-12:30:15"));
    plc.ok(&["set", "main.stamp", "2024-12-31-23:59:59"]);
    assert_eq!(plc.get("main.stamp"), json!("DT#2024-12-31-23:59:59"));
    let err = plc.refused(&["set", "main.shift", "TOD#25:00:00"]);
    assert!(err.contains("main.shift (TOD)"), "{err}");
    assert_eq!(plc.get("main.ch"), json!("'a'"));
    plc.ok(&["set", "main.ch", "'z'"]);
    assert_eq!(plc.get("main.ch"), json!("'z'"));

    // The chart: Idle active, then Fill once go is set, its T counting, lamp its action.
    assert_eq!(plc.values(&["main.Idle.X"])[0]["type"], json!("BOOL"));
    assert_eq!(plc.get("main.Idle.X"), json!(1));
    assert_eq!(plc.get("main.Fill.X"), json!(0));
    plc.ok(&["set", "main.go", "TRUE"]);
    plc.daemon.wait("Fill active", || plc.get("main.Fill.X") == json!(1));
    assert_eq!(plc.get("main.Idle.X"), json!(0));
    plc.daemon.wait("lamp on", || plc.get("main.lamp") == json!(1));
    assert_eq!(plc.get("main.sfc$lamp.Q"), json!(1), "the action's control, by its tool name");
    assert_eq!(plc.get("main.sfc$Work.A"), json!(1), "Work's body runs in every step");
    plc.daemon.wait("Fill's time counts", || plc.get("main.Fill.T") != json!("T#0s"));
    assert_eq!(plc.values(&["main.Fill.T"])[0]["type"], json!("TIME"));
    let watched = plc.ok(&["watch", "--count", "1", "--interval", "10ms", "main.Fill.X"]);
    assert!(watched.contains("main.Fill.X=1"), "{watched}");

    // An online change: the chart stays in Fill, the VAR_INST and the union keep their values.
    let before = plc.get("main.c.Add.calls").as_i64().unwrap();
    let dir = plc.project.dir.path().to_path_buf();
    let changed = NEW.replace("    go : BOOL;\n", "    go : BOOL;\n    added : INT := 3;\n");
    std::fs::write(dir.join("main2.st"), changed).unwrap();
    std::fs::write(dir.join("new.toml"), config.replace("main.st", "main2.st")).unwrap();
    let new = dir.join("new.toml");
    plc.ok(&["load", "--config", new.to_str().unwrap(), "--online"]);
    assert_eq!(plc.get("main.added"), json!(3));
    assert_eq!(plc.get("main.Fill.X"), json!(1), "the active step kept");
    assert_eq!(plc.get("main.Idle.X"), json!(0));
    assert!(plc.get("main.c.Add.calls").as_i64() >= Some(before), "the VAR_INST kept");
    assert_eq!(plc.get("main.u.dw"), json!(0x7F22_3344), "the union kept");
    assert_eq!(plc.get("main.stamp"), json!("DT#2024-12-31-23:59:59"));
    plc.daemon.wait("the reference taken again", || plc.get("main.r") != json!("NULL"));

    // A step's X is the chart's state, as any variable a client may write it (docs/ST.md,
    // "Debugging"): the chart goes on from the steps so set, no transition cleared.
    plc.ok(&["set", "main.Fill.X", "FALSE", "main.Idle.X", "TRUE", "main.go", "FALSE"]);
    assert_eq!(plc.get("main.Idle.X"), json!(1), "moved back to Idle by hand");
    assert_eq!(plc.get("main.Fill.X"), json!(0));
    plc.daemon.wait("lamp off", || plc.get("main.lamp") == json!(0));
    plc.ok(&["set", "main.go", "TRUE"]);
    plc.daemon.wait("Fill entered again by its transition", || plc.get("main.Fill.X") == json!(1));
    plc.stop();
}

/// `main.r^` names what `main.r` points to (docs/ST.md "### plcctl"): read and written where
/// the reference points when the request is served, a struct's every member for `main.p^`,
/// an element of an array of references; a NULL reference, a name that is no reference and
/// a member the target has not are refused naming them. Nothing the program does moves the
/// references after its first scan, so every value read is the one written.
#[test]
fn names_through_a_reference_read_and_write_what_it_points_to() {
    const THROUGH: &str = "\
TYPE Axis : STRUCT pos : REAL; homed : BOOL; END_STRUCT END_TYPE
PROGRAM Main
VAR
    hits : DINT := 7;
    count : INT := 3;
    axis : Axis;
    text : STRING[10] := 'abc';
    r : REF_TO DINT;
    p : POINTER TO Axis;
    refs : ARRAY [1..2] OF REF_TO INT;
    rs : REF_TO STRING[10];
    nothing : REF_TO INT;
END_VAR
    r := REF(hits);
    p := ADR(axis);
    refs[2] := REF(count);
    rs := REF(text);
END_PROGRAM
";
    let config = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
        [[program]]\nname = \"main\"\nfile = \"main.st\"\n[control]\nsocket = \"plcd.sock\"\n";
    let project = Project::new("names-through", &[("plcd.toml", config), ("main.st", THROUGH)]);
    let daemon = project.start().with_patience(PATIENCE);
    let plc = Plc { daemon, project };
    plc.daemon.wait_for("control socket");
    plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");
    plc.daemon.wait("the references taken", || plc.get("main.rs") == json!("main.text"));

    let hits = plc.values(&["main.r^"]);
    assert_eq!(
        (&hits[0]["dev"], &hits[0]["value"], &hits[0]["type"]),
        (&json!("main.r^"), &json!(7), &json!("DINT"))
    );
    plc.ok(&["set", "main.r^", "100"]);
    assert_eq!(plc.get("main.hits"), json!(100), "written where r points");

    let axis = plc.values(&["main.p^"]);
    let names: Vec<&str> = axis.iter().map(|v| v["dev"].as_str().unwrap()).collect();
    assert_eq!(names, ["main.p^.pos", "main.p^.homed"]);
    plc.ok(&["set", "main.p^.pos", "2.5", "main.P^.HOMED", "TRUE"]);
    assert_eq!(plc.values(&["main.axis.pos", "main.axis.homed"])[1]["value"], json!(1));
    assert_eq!(plc.get("main.p^.pos"), json!(2.5));

    assert_eq!(plc.get("main.refs[2]^"), json!(3));
    assert_eq!(plc.get("main.rs^"), json!("abc"));
    plc.ok(&["set", "main.rs^", "'xyz'"]);
    assert_eq!(plc.get("main.text"), json!("xyz"));
    let watched = plc.ok(&["watch", "--count", "1", "--interval", "10ms", "main.r^"]);
    assert!(watched.contains("main.r^=100"), "{watched}");

    let err = plc.refused(&["get", "main.nothing^"]);
    assert!(err.contains("`main.nothing^`: `main.nothing` is NULL"), "{err}");
    let err = plc.refused(&["set", "main.refs[1]^", "1"]);
    assert!(err.contains("`main.refs[1]^`: `main.refs[1]` is NULL"), "{err}");
    let err = plc.refused(&["get", "main.hits^"]);
    assert!(err.contains("`main.hits` is not a reference (DINT)"), "{err}");
    let err = plc.refused(&["get", "main.p^.speed"]);
    assert!(
        err.contains("no variable `main.p^.speed`: a POINTER TO Axis points to no `.speed`"),
        "{err}"
    );
    let err = plc.refused(&["set", "main.p^", "1"]);
    assert!(err.contains("`main.p^` holds 2 variables"), "{err}");
    plc.stop();
}

/// A name through two references, `main.p^.next^.value` (docs/ST.md "### plcctl"): each
/// reference followed where it points when the request is served, one capture each; read,
/// written and watched; a NULL reference inside the chain is refused naming it. Nothing the
/// program does moves the references after its first scan.
#[test]
fn names_through_two_references_read_and_write_what_the_last_points_to() {
    const CHAIN: &str = "\
TYPE Node : STRUCT value : INT; next : REF_TO Node; END_STRUCT END_TYPE
PROGRAM Main
VAR
    a : Node := (value := 1);
    b : Node := (value := 2);
    p : REF_TO Node;
END_VAR
    a.next := REF(b);
    p := REF(a);
END_PROGRAM
";
    let config = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
        [[program]]\nname = \"main\"\nfile = \"main.st\"\n[control]\nsocket = \"plcd.sock\"\n";
    let project = Project::new("names-chain", &[("plcd.toml", config), ("main.st", CHAIN)]);
    let daemon = project.start().with_patience(PATIENCE);
    let plc = Plc { daemon, project };
    plc.daemon.wait_for("control socket");
    plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");
    plc.daemon.wait("the references taken", || plc.get("main.p") != json!("NULL"));

    let value = plc.values(&["main.p^.next^.value"]);
    assert_eq!(
        (&value[0]["dev"], &value[0]["value"], &value[0]["type"]),
        (&json!("main.p^.next^.value"), &json!(2), &json!("INT"))
    );
    assert_eq!(plc.get("main.a.next^.value"), json!(2), "a reference inside a struct");
    let node = plc.values(&["main.P^.Next^"]);
    let names: Vec<&str> = node.iter().map(|v| v["dev"].as_str().unwrap()).collect();
    assert_eq!(names, ["main.p^.next^.value", "main.p^.next^.next"]);
    plc.ok(&["set", "main.p^.next^.value", "20", "main.a.value", "10"]);
    assert_eq!(plc.get("main.b.value"), json!(20), "written where a.next points");
    assert_eq!(plc.get("main.p^.value"), json!(10));
    let watched = plc.ok(&["watch", "--count", "1", "--interval", "10ms", "main.p^.next^.value"]);
    assert!(watched.contains("main.p^.next^.value=20"), "{watched}");

    let err = plc.refused(&["get", "main.p^.next^.next^.value"]);
    assert!(err.contains("`main.p^.next^.next^.value`: `main.p^.next^.next` is NULL"), "{err}");
    let err = plc.refused(&["set", "main.p^.next^.next^.value", "1"]);
    assert!(err.contains("`main.p^.next^.next` is NULL"), "{err}");
    let err = plc.refused(&["get", "main.p^.value^"]);
    assert!(err.contains("`main.p^.value` is not a reference (INT)"), "{err}");
    plc.stop();
}

/// A global two lists declare is named `GVL_A.x` by clients too (docs/ST.md, "Qualified
/// names"): read, written, and the list as a prefix; a global one list declares keeps its plain
/// name.
#[test]
fn globals_two_lists_declare_are_named_by_their_list() {
    let config = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
        [[program]]\nname = \"main\"\nfile = \"main.st\"\n\
        [st]\nlibrary = [\"GVL_A.st\", \"GVL_B.st\"]\n[control]\nsocket = \"plcd.sock\"\n";
    let files = [
        ("plcd.toml", config),
        ("GVL_A.st", "VAR_GLOBAL\n    x : INT := 1;\nEND_VAR\n"),
        ("GVL_B.st", "VAR_GLOBAL\n    x : INT := 2;\n    only_b : INT := 3;\nEND_VAR\n"),
        ("main.st", "PROGRAM main\nVAR\n    sum : INT;\nEND_VAR\n    sum := GVL_A.x + GVL_B.x;\nEND_PROGRAM\n"),
    ];
    let project = Project::new("names-lists", &files);
    let daemon = project.start().with_patience(PATIENCE);
    let plc = Plc { daemon, project };
    plc.daemon.wait_for("control socket");
    plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");

    let values = plc.values(&["GVL_A.x", "gvl_b.X", "only_b"]);
    let shown: Vec<(&str, &Value)> =
        values.iter().map(|v| (v["dev"].as_str().unwrap(), &v["value"])).collect();
    assert_eq!(shown, [("GVL_A.x", &json!(1)), ("GVL_B.x", &json!(2)), ("only_b", &json!(3))]);
    plc.ok(&["set", "GVL_B.x", "40"]);
    plc.daemon.wait("the sum of both", || plc.get("main.sum") == json!(41));
    let names: Vec<String> =
        plc.values(&["GVL_B"]).iter().map(|v| v["dev"].as_str().unwrap().to_string()).collect();
    assert_eq!(names, ["GVL_B.x"], "the list's shared global; only_b is named plainly");
    let err = plc.refused(&["get", "x"]);
    assert!(err.contains("no device or variable `x`"), "{err}");
    plc.stop();
}

/// Access paths (`VAR_ACCESS`, docs/ST.md "Access paths"): read by their bare name, shown under
/// it (an FB instance's leaves as `timer.PT`, …), written through a `READ_WRITE` one, and a
/// write or a force through a `READ_ONLY` one refused naming the path.
#[test]
fn access_paths_are_read_by_their_name_and_written_only_when_read_write() {
    let config = "[plc]\nscan_period_ms = 1\nwatchdog_ms = 100\n\
        [[program]]\nname = \"main\"\nfile = \"main.st\"\n[control]\nsocket = \"plcd.sock\"\n";
    let main = "\
PROGRAM main
VAR
    n : DINT;
    limit : INT := 7;
    t : TON;
    lamp AT %QX0.1 : BOOL;
END_VAR
VAR_ACCESS
    count : main.n : DINT READ_ONLY;
    setpoint : limit : INT READ_WRITE;
    timer : t : TON READ_WRITE;
    output : lamp : BOOL;
END_VAR
    n := n + 1;
    t(IN := TRUE);
END_PROGRAM
";
    let project = Project::new("names-access", &[("plcd.toml", config), ("main.st", main)]);
    let daemon = project.start().with_patience(PATIENCE);
    let plc = Plc { daemon, project };
    plc.daemon.wait_for("control socket");
    plc.daemon.wait("RUN", || plc.json(&["status"])["mode"] == "RUN");

    let values = plc.values(&["count", "SETPOINT"]);
    assert_eq!(values[0]["dev"], "count", "shown under the path's name: {values:?}");
    assert_eq!(values[1]["dev"], "setpoint");
    assert_eq!(values[1]["value"], json!(7));
    plc.daemon.wait("the scans counted", || plc.get("count").as_i64().unwrap_or(0) > 1);

    plc.ok(&["set", "setpoint", "42"]);
    assert_eq!(plc.get("main.limit"), json!(42), "a READ_WRITE path writes its variable");
    plc.ok(&["set", "timer.PT", "T#2h"]);
    assert_eq!(plc.get("main.t.PT"), json!("T#2h"));
    let timer: Vec<String> =
        plc.values(&["timer"]).iter().map(|v| v["dev"].as_str().unwrap().to_string()).collect();
    assert!(timer.contains(&"timer.PT".to_string()), "{timer:?}");

    let err = plc.refused(&["set", "count", "0"]);
    assert!(
        err.contains("`count` is a READ_ONLY access path (to `main.n`)"),
        "a READ_ONLY path refuses writes: {err}"
    );
    let err = plc.refused(&["force", "output=1"]);
    assert!(err.contains("`output` is a READ_ONLY access path"), "{err}");
    let err = plc.refused(&["get", "timer.nothing"]);
    assert!(err.contains("the access path `timer` names `main.t`"), "{err}");
    plc.ok(&["set", "main.n", "0"]);
    plc.stop();
}
