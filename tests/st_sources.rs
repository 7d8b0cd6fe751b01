//! Where Structured Text comes from: TwinCAT's `.TcPOU`, `.TcDUT` and `.TcGVL` files as
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

fn project() -> TempDir {
    let dir = TempDir::new("st-sources");
    let d = dir.path();
    write(
        d,
        "plcd.toml",
        "[plc]\nscan_period_ms = 1\n\n[[program]]\nname = \"main\"\nfile = \"MAIN.TcPOU\"\n\n[st]\nlibrary = [\"lib/\"]\n",
    );
    write(
        d,
        "MAIN.TcPOU",
        &pou(
            "MAIN",
            "PROGRAM MAIN\r\nVAR\r\n\tc : Counter;\r\n\tp : Point;\r\n\tn : INT;\r\nEND_VAR",
            "c(step := STEP);\r\np.x := c.total;\r\nIF p.x > 4 THEN\r\n\tn := n + 1;\r\nEND_IF",
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
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let out = plcd(
        dir.path(),
        &[
            "sim",
            "--config",
            "plcd.toml",
            "--for",
            "3500us",
            "--watch",
            "main.c.total,main.p.x,main.n",
            "--trace",
            "-",
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
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
