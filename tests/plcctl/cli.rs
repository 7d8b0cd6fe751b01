//! `plcctl` end to end: the built binary against a fake daemon, a Unix listener on a thread
//! that records every request line and answers from a script. Each test checks the exact
//! request sent, the output (human and `--json`) and the exit status.
//!
//! Synchronisation is by the connection itself: the test waits for the process to exit, then
//! for the fake server's thread, which ends when the script is done or the client is gone.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

use plcctl::client::{Client, ClientError};
use plcd_ipc::{self as protocol, ModeName, Reply, Request};
use serde_json::{json, Value};

// The parts of the suite's harness (tests/harness) that need nothing of plcd: this package
// builds without the daemon, so its test includes those files alone. Each is only partly used
// here (the rest serves the root package's tests), hence the allowances.
#[allow(dead_code)]
#[path = "../harness/nobody.rs"]
mod nobody;
#[allow(dead_code)]
#[path = "../harness/runner.rs"]
mod runner;
#[allow(dead_code)]
#[path = "../harness/skip.rs"]
mod skip;
#[allow(dead_code)]
#[path = "../harness/tempdir.rs"]
mod tempdir;

use tempdir::TempDir;

/// What the fake daemon does next.
#[derive(Debug, Clone)]
enum Step {
    /// Read a request line and answer with this line (a newline is added).
    Answer(String),
    /// Read a request line and write these bytes as they are, then close.
    Raw(&'static str),
    /// Read a request line and close without answering.
    CloseAfterRead,
    /// Close the connection without reading (an idle timeout) and accept the next one.
    CloseIdle,
    /// Read a request line and keep the connection open, unanswered, until the test ends.
    Hang,
}

/// A fake daemon serving one script.
struct Fake {
    dir: TempDir,
    path: PathBuf,
    thread: Option<JoinHandle<Vec<String>>>,
    /// Dropped to release a [`Step::Hang`].
    release: Option<mpsc::Sender<()>>,
    /// Every request line, as it arrives.
    seen: mpsc::Receiver<String>,
}

impl Fake {
    fn start(name: &str, steps: Vec<Step>) -> Fake {
        let dir = TempDir::new(name);
        let path = dir.path().join("plcd.sock");
        let listener = UnixListener::bind(&path).unwrap();
        Fake::serve(dir, path, listener, steps)
    }

    fn serve(dir: TempDir, path: PathBuf, listener: UnixListener, steps: Vec<Step>) -> Fake {
        let (release, released) = mpsc::channel::<()>();
        let (seen_tx, seen) = mpsc::channel();
        let thread = std::thread::spawn(move || {
            let mut requests = Vec::new();
            let mut conn: Option<BufReader<UnixStream>> = None;
            for step in steps {
                let reader = match conn.as_mut() {
                    Some(reader) => reader,
                    None => conn.insert(BufReader::new(listener.accept().unwrap().0)),
                };
                if let Step::CloseIdle = step {
                    conn = None;
                    continue;
                }
                let mut line = String::new();
                if reader.read_line(&mut line).unwrap_or(0) == 0 {
                    break; // the client is gone
                }
                let line = line.strip_suffix('\n').unwrap_or(&line).to_string();
                requests.push(line.clone());
                let _ = seen_tx.send(line);
                match step {
                    Step::Answer(answer) => {
                        let _ = reader.get_mut().write_all(format!("{answer}\n").as_bytes());
                    }
                    Step::Raw(bytes) => {
                        let _ = reader.get_mut().write_all(bytes.as_bytes());
                        conn = None;
                    }
                    Step::CloseAfterRead => conn = None,
                    Step::Hang => {
                        let _ = released.recv();
                    }
                    Step::CloseIdle => unreachable!(),
                }
            }
            requests
        });
        Fake { dir, path, thread: Some(thread), release: Some(release), seen }
    }

    fn socket(&self) -> &str {
        self.path.to_str().unwrap()
    }

    /// The request lines received. Call once the client has exited.
    fn requests(mut self) -> Vec<String> {
        drop(self.release.take());
        // Unblocks an accept() the client never came to; harmless otherwise.
        let _ = UnixStream::connect(&self.path);
        self.thread.take().unwrap().join().unwrap()
    }
}

/// The outcome of one plcctl run.
#[derive(Debug)]
struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn plcctl_in(dir: &Path, args: &[&str], env: &[(&str, &str)]) -> Run {
    let mut command = runner::command(env!("CARGO_BIN_EXE_plcctl"));
    command.args(args).current_dir(dir).env_remove("PLCD_SOCKET").stdin(Stdio::null());
    for (key, value) in env {
        command.env(key, value);
    }
    let Output { status, stdout, stderr } = command.output().unwrap();
    Run {
        code: status.code().expect("plcctl exits, it is not killed"),
        stdout: String::from_utf8(stdout).unwrap(),
        stderr: String::from_utf8(stderr).unwrap(),
    }
}

/// plcctl `args` with `--socket` of `fake`.
fn plcctl(fake: &Fake, args: &[&str]) -> Run {
    let mut all = vec!["--socket", fake.socket()];
    all.extend_from_slice(args);
    plcctl_in(fake.dir.path(), &all, &[])
}

fn ok_line(ok: &Value) -> String {
    json!({"v": 1, "ok": ok}).to_string()
}

fn error_line(error: &Value) -> String {
    json!({"v": 1, "error": error}).to_string()
}

/// Runs `args` twice against a fake answering `ok`, once for a human and once with `--json`:
/// both send `request`, exit 0; the JSON output is `ok`; the human output is returned.
fn exchange(name: &str, args: &[&str], request: &str, ok: Value) -> String {
    let fake = Fake::start(name, vec![Step::Answer(ok_line(&ok))]);
    let human = plcctl(&fake, args);
    assert_eq!(fake.requests(), [request], "{args:?}");
    assert_eq!(human.code, 0, "{args:?}: {human:?}");
    assert_eq!(human.stderr, "", "{args:?}");

    let fake = Fake::start(name, vec![Step::Answer(ok_line(&ok))]);
    let mut json_args = vec!["--json"];
    json_args.extend_from_slice(args);
    let machine = plcctl(&fake, &json_args);
    assert_eq!(fake.requests(), [request], "{args:?} --json");
    assert_eq!(machine.code, 0, "{args:?} --json: {machine:?}");
    assert_eq!(machine.stdout.lines().count(), 1, "one line: {:?}", machine.stdout);
    let printed: Value = serde_json::from_str(&machine.stdout).unwrap();
    assert_eq!(printed, ok, "{args:?} --json prints the ok object");
    human.stdout
}

fn status_ok() -> Value {
    json!({
        "kind": "status",
        "version": "0.1.0",
        "config": "/etc/plcd/plcd.toml",
        "backend": "sim",
        "uptime_ms": 3_723_000,
        "mode": "ERROR",
        "error": {"code": "3405H", "detail": "division by zero at main:12"},
        "switch": "STOP",
        "remote_allowed": true,
        "scan": {"count": 12345, "cur_ns": 1_200_000, "min_ns": 950_000, "max_ns": 3_401_000,
                 "p50_ns": 1_100_000, "p99_ns": 2_000_000},
        "tasks": [
            {"name": "main", "kind": "scan", "runs": 12345, "ignored": 0, "overruns": 0,
             "latency": {"p50_ns": 6_500, "p99_ns": 18_000, "p999_ns": 40_100, "max_ns": 52_000},
             "exec": {"p50_ns": 900_000, "p99_ns": 1_500_000, "p999_ns": 1_600_000,
                      "max_ns": 1_700_000}},
            {"name": "blink_250ms", "kind": "cycle", "runs": 7, "ignored": 2, "overruns": 1,
             "latency": {"p50_ns": 51_200, "p99_ns": 79_100, "p999_ns": 79_100, "max_ns": 79_100},
             "exec": {"p50_ns": 5_600, "p99_ns": 9_600, "p999_ns": 9_600, "max_ns": 9_600}}
        ],
        "lost_edges": 3,
        "missed_timer_expirations": 4,
        "watchdog_trips": 5,
        "forces": [{"dev": "P0000", "value": 1}, {"dev": "P0041", "value": 0}],
        "debug": {"paused_at": {"program": "main", "line": 12, "task": "main",
                                "source": "LOAD P0000", "devices": [{"dev": "P0000", "value": 1}]},
                  "running": false, "scan": 41, "breakpoints": ["main:12", "main:20"]},
        "a_field_from_a_newer_daemon": [1, 2]
    })
}

#[test]
fn status_shows_every_figure_in_human_units_and_aligned_columns() {
    let out = exchange("status", &["status"], r#"{"v":1,"cmd":"status"}"#, status_ok());
    for part in [
        "plcd       0.1.0, sim backend, /etc/plcd/plcd.toml",
        "uptime     1h 02m 03s",
        "mode       ERROR",
        "error      3405H: division by zero at main:12",
        "switch     STOP (remote RUN/STOP/DEBUG allowed)",
        "scans      12345",
        "scan time  cur 1.20 ms  min 950.0 µs  max 3.40 ms  p50 1.10 ms  p99 2.00 ms",
        "health     3 lost edges, 4 missed timer expirations, 5 watchdog trips",
        "forces     P0000=1, P0041=0",
        "debug      paused at main:12 in task main; 41 scans completed",
        "             LOAD P0000",
        "             P0000=1",
        "           breakpoints: main:12, main:20",
    ] {
        assert!(out.lines().any(|line| line == part), "missing {part:?} in\n{out}");
    }
    let table: Vec<&str> = out.lines().skip_while(|line| !line.starts_with("TASK")).collect();
    assert_eq!(
        table,
        [
            "TASK         KIND    RUNS  IGNORED  OVERRUNS  LAT P50  LAT P99  LAT P99.9  LAT MAX  \
             EXEC P50  EXEC P99",
            "main         scan   12345        0         0   6.5 µs  18.0 µs    40.1 µs  52.0 µs  \
             900.0 µs   1.50 ms",
            "blink_250ms  cycle      7        2         1  51.2 µs  79.1 µs    79.1 µs  79.1 µs    \
             5.6 µs    9.6 µs",
        ]
    );
}

#[test]
fn status_without_error_switch_debug_or_tasks() {
    let mut ok = status_ok();
    let object = ok.as_object_mut().unwrap();
    for key in ["error", "switch", "debug"] {
        object.remove(key);
    }
    object["mode"] = json!("RUN");
    object["remote_allowed"] = json!(true);
    object["tasks"] = json!([]);
    object["forces"] = json!([]);
    let out = exchange("status-plain", &["status"], r#"{"v":1,"cmd":"status"}"#, ok);
    assert!(out.contains("\nerror      none\n"), "{out}");
    assert!(out.contains("\nswitch     none (remote RUN/STOP/DEBUG allowed)\n"), "{out}");
    assert!(out.contains("\nforces     none\n"), "{out}");
    assert!(!out.contains("debug"), "{out}");
    assert!(out.ends_with("\nno tasks\n"), "{out}");
}

#[test]
fn mode_commands() {
    for (args, request, mode) in [
        (&["run"][..], r#"{"v":1,"cmd":"run"}"#, "RUN"),
        (&["stop"], r#"{"v":1,"cmd":"stop"}"#, "STOP"),
        (&["reset"], r#"{"v":1,"cmd":"reset","cold":false}"#, "STOP"),
        (&["reset", "--cold"], r#"{"v":1,"cmd":"reset","cold":true}"#, "STOP"),
    ] {
        let out = exchange("mode", args, request, json!({"kind": "mode", "mode": mode}));
        assert_eq!(out, format!("mode: {mode}\n"));
    }
}

#[test]
fn debugger_commands() {
    let paused = json!({
        "kind": "debug", "running": false, "scan": 41, "breakpoints": ["main:12", "main:LABEL 3"],
        "paused_at": {"program": "main", "line": 12, "task": "fast", "source": "OUT P0040",
                      "devices": [{"dev": "P0040", "value": 0}, {"dev": "M0001", "value": 1}]}
    });
    let paused_text = "paused at main:12 in task fast; 41 scans completed\n  OUT P0040\n  \
                       P0040=0, M0001=1\nbreakpoints: main:12, main:LABEL 3\n";
    let st = json!({
        "kind": "debug", "running": false, "scan": 2, "breakpoints": ["lib.st:3"],
        "paused_at": {"program": "main", "line": 3, "file": "lib.st", "task": "scan",
                      "source": "Twice := x * 2;"}
    });
    let st_text = "paused at lib.st:3 in program main, task scan; 2 scans completed\n  \
                   Twice := x * 2;\nbreakpoints: lib.st:3\n";
    let between = json!({"kind": "debug", "running": false, "scan": 1, "breakpoints": []});
    let between_text = "between scans; 1 scan completed\nbreakpoints: none\n";
    let running = json!({"kind": "debug", "running": true, "scan": 7, "breakpoints": ["main:3"]});
    let running_text = "running to a breakpoint; 7 scans completed\nbreakpoints: main:3\n";
    for (args, request, ok, text) in [
        (&["debug"][..], r#"{"v":1,"cmd":"debug"}"#, &between, between_text),
        (&["step"], r#"{"v":1,"cmd":"step"}"#, &paused, paused_text),
        (&["step", "--scan"], r#"{"v":1,"cmd":"step","scan":true}"#, &between, between_text),
        (&["break", "lib.st:3"], r#"{"v":1,"cmd":"break","at":"lib.st:3"}"#, &st, st_text),
        (&["continue"], r#"{"v":1,"cmd":"continue"}"#, &running, running_text),
        (&["break", "main:12"], r#"{"v":1,"cmd":"break","at":"main:12"}"#, &paused, paused_text),
        (
            &["break", "main:LABEL", "3"],
            r#"{"v":1,"cmd":"break","at":"main:LABEL 3"}"#,
            &paused,
            paused_text,
        ),
        (
            &["unbreak", "main:3"],
            r#"{"v":1,"cmd":"unbreak","at":"main:3"}"#,
            &between,
            between_text,
        ),
        (&["unbreak"], r#"{"v":1,"cmd":"unbreak"}"#, &between, between_text),
    ] {
        let out = exchange("debug", args, request, ok.clone());
        assert_eq!(out, text, "{args:?}");
    }
}

#[test]
fn force_commands() {
    let table = json!({"kind": "forces", "forces": [{"dev": "P0000", "value": 1},
                                                     {"dev": "P0041", "value": 0}]});
    let table_text = "P0000  1\nP0041  0\n";
    let empty = json!({"kind": "forces", "forces": []});
    for (args, request, ok, text) in [
        (&["forces"][..], r#"{"v":1,"cmd":"forces"}"#, &table, table_text),
        (
            &["force", "P0000=1"],
            r#"{"v":1,"cmd":"force","dev":"P0000","value":1}"#,
            &table,
            table_text,
        ),
        (&["unforce", "P0041"], r#"{"v":1,"cmd":"unforce","dev":"P0041"}"#, &table, table_text),
        (&["unforce", "--all"], r#"{"v":1,"cmd":"unforce_all"}"#, &empty, "no forces\n"),
        (
            &["force", "main.lamp", "TRUE"],
            r#"{"v":1,"cmd":"force","dev":"main.lamp","value":1}"#,
            &table,
            table_text,
        ),
        (
            &["unforce", "main.lamp"],
            r#"{"v":1,"cmd":"unforce","dev":"main.lamp"}"#,
            &table,
            table_text,
        ),
    ] {
        let out = exchange("forces", args, request, ok.clone());
        assert_eq!(out, text, "{args:?}");
    }
}

#[test]
fn get_reads_devices_in_one_request() {
    let ok = json!({"kind": "values", "scan": 1234, "values": [
        {"dev": "D00010", "value": -5}, {"dev": "P0040", "value": 1}]});
    let out = exchange(
        "get",
        &["get", "D00010", "P0040"],
        r#"{"v":1,"cmd":"get","devices":["D00010","P0040"]}"#,
        ok,
    );
    assert_eq!(out, "D00010  -5\nP0040    1\n");
}

#[test]
fn set_sends_every_write_in_one_request() {
    let ok = json!({"kind": "written", "scan": 9, "count": 3});
    let out = exchange(
        "set",
        &["set", "D00010=-5", "M0001=1", "D00011=hFFFF"],
        r#"{"v":1,"cmd":"set","writes":[{"dev":"D00010","value":-5},{"dev":"M0001","value":1},{"dev":"D00011","value":-1}]}"#,
        ok,
    );
    assert_eq!(out, "3 writes applied at the END of scan 9\n");

    let ok = json!({"kind": "written", "scan": 10, "count": 2});
    let out = exchange(
        "set2",
        &["set", "D00001=1", "D00002=2"],
        r#"{"v":1,"cmd":"set","writes":[{"dev":"D00001","value":1},{"dev":"D00002","value":2}]}"#,
        ok,
    );
    assert_eq!(out, "2 writes applied at the END of scan 10\n");

    // Variables: `NAME VALUE` or `NAME=VALUE`, the value sent as written for the daemon to
    // read against the variable's type; devices beside them as before.
    let ok = json!({"kind": "written", "scan": 11, "count": 4});
    let out = exchange(
        "set-names",
        &["set", "main.t", "T#2s", "D00010=h10", "main.speed", "-5", "main.s=a b"],
        r#"{"v":1,"cmd":"set","writes":[{"dev":"main.t","value":"T#2s"},{"dev":"D00010","value":16},{"dev":"main.speed","value":"-5"},{"dev":"main.s","value":"a b"}]}"#,
        ok,
    );
    assert_eq!(out, "4 writes applied at the END of scan 11\n");
}

#[test]
fn get_reads_variables_with_their_types() {
    let ok = json!({"kind": "values", "scan": 7, "values": [
        {"dev": "main.Speed", "value": 5, "type": "INT"},
        {"dev": "main.t1.ET", "value": "T#1s500ms", "type": "TIME"},
        {"dev": "main.s", "value": "it's", "type": "STRING[20]"},
        {"dev": "D00010", "value": -5}]});
    let out = exchange(
        "get-names",
        &["get", "MAIN.SPEED,main.t1.ET", "main.s", "D00010"],
        r#"{"v":1,"cmd":"get","devices":["MAIN.SPEED","main.t1.ET","main.s","D00010"]}"#,
        ok,
    );
    assert_eq!(
        out,
        "main.Speed          5  INT\n\
         main.t1.ET  T#1s500ms  TIME\n\
         main.s        'it$'s'  STRING[20]\n\
         D00010             -5\n"
    );
}

/// A name through a reference (`main.r^`, `main.p^.pos`) goes to the daemon as written, in a
/// `get` as in a `set` (`NAME=VALUE`: the `^` is no part of the value).
#[test]
fn names_through_references_are_sent_as_written() {
    let ok = json!({"kind": "values", "scan": 3, "values": [
        {"dev": "main.r^", "value": 7, "type": "DINT"},
        {"dev": "main.p^.pos", "value": 2.5, "type": "REAL"}]});
    let out = exchange(
        "get-through",
        &["get", "main.r^", "main.p^.pos"],
        r#"{"v":1,"cmd":"get","devices":["main.r^","main.p^.pos"]}"#,
        ok,
    );
    assert_eq!(out, "main.r^        7  DINT\nmain.p^.pos  2.5  REAL\n");
    let ok = json!({"kind": "written", "scan": 4, "count": 2});
    let out = exchange(
        "set-through",
        &["set", "main.r^=100", "main.p^.pos", "1.5"],
        r#"{"v":1,"cmd":"set","writes":[{"dev":"main.r^","value":"100"},{"dev":"main.p^.pos","value":"1.5"}]}"#,
        ok,
    );
    assert_eq!(out, "2 writes applied at the END of scan 4\n");
}

#[test]
fn load_sends_an_absolute_path() {
    let ok = json!({"kind": "loaded", "online": true, "programs": 2, "tasks": 3, "mode": "RUN"});
    let fake = Fake::start("load", vec![Step::Answer(ok_line(&ok))]);
    let run = plcctl(&fake, &["load", "--config", "project/plcd.toml", "--online"]);
    let expected = fake.dir.path().join("project/plcd.toml");
    let expected = expected.to_str().unwrap();
    assert_eq!(
        fake.requests(),
        [format!(r#"{{"v":1,"cmd":"load","config":"{expected}","online":true}}"#)]
    );
    assert_eq!(run.code, 0, "{run:?}");
    assert_eq!(run.stdout, format!("loaded {expected}: 2 programs, 3 tasks, online; mode RUN\n"));

    let ok = json!({"kind": "loaded", "online": false, "programs": 1, "tasks": 1, "mode": "STOP"});
    let out = exchange(
        "load-abs",
        &["load", "--config", "/etc/plcd/plcd.toml"],
        r#"{"v":1,"cmd":"load","config":"/etc/plcd/plcd.toml","online":false}"#,
        ok,
    );
    assert_eq!(out, "loaded /etc/plcd/plcd.toml: 1 program, 1 task; mode STOP\n");
}

#[test]
fn a_refused_load_prints_every_diagnostic_like_a_compiler() {
    let error = json!({
        "kind": "invalid",
        "message": "/p/plcd.toml: 2 errors",
        "details": ["/p/main.il:3:5: error: unknown instruction `LDX`",
                    "/p/main.il:9:1: error: missing END"]
    });
    let fake = Fake::start("load-refused", vec![Step::Answer(error_line(&error))]);
    let run = plcctl(&fake, &["load", "--config", "/p/plcd.toml"]);
    fake.requests();
    assert_eq!(run.code, 1);
    assert_eq!(run.stdout, "");
    assert_eq!(
        run.stderr,
        "plcctl: invalid: /p/plcd.toml: 2 errors\n\
         /p/main.il:3:5: error: unknown instruction `LDX`\n\
         /p/main.il:9:1: error: missing END\n"
    );

    let fake = Fake::start("load-refused-json", vec![Step::Answer(error_line(&error))]);
    let run = plcctl(&fake, &["--json", "load", "--config", "/p/plcd.toml"]);
    fake.requests();
    assert_eq!(run.code, 1);
    assert_eq!(run.stderr, "");
    assert_eq!(serde_json::from_str::<Value>(&run.stdout).unwrap(), error);
    assert_eq!(run.stdout.lines().count(), 1);
}

#[test]
fn every_error_kind_exits_1_with_the_message_on_stderr() {
    for kind in ["refused", "invalid", "busy", "denied", "unavailable", "bad_request", "too_long"] {
        let error = json!({"kind": kind, "message": "the RUN/STOP switch is at RUN"});
        let fake = Fake::start("refused", vec![Step::Answer(error_line(&error))]);
        let run = plcctl(&fake, &["run"]);
        assert_eq!(fake.requests(), [r#"{"v":1,"cmd":"run"}"#]);
        assert_eq!(run.code, 1, "{kind}: {run:?}");
        assert_eq!(run.stdout, "");
        assert!(run.stderr.starts_with("plcctl: "), "{run:?}");
        assert!(run.stderr.ends_with(": the RUN/STOP switch is at RUN\n"), "{run:?}");
    }
}

#[test]
fn no_socket_exits_3() {
    let dir = TempDir::new("nosocket");
    let missing = dir.path().join("missing.sock");
    let run = plcctl_in(dir.path(), &["--socket", missing.to_str().unwrap(), "status"], &[]);
    assert_eq!(run.code, 3, "{run:?}");
    assert_eq!(run.stdout, "");
    assert_eq!(
        run.stderr,
        format!(
            "plcctl: cannot connect to {}: no such socket (is plcd running?)\n",
            missing.display()
        )
    );

    // Through $PLCD_SOCKET, the message says where the path came from.
    let run = plcctl_in(dir.path(), &["status"], &[("PLCD_SOCKET", missing.to_str().unwrap())]);
    assert_eq!(run.code, 3, "{run:?}");
    assert!(run.stderr.contains("$PLCD_SOCKET"), "{run:?}");
}

#[test]
fn a_socket_nobody_listens_on_exits_3() {
    let dir = TempDir::new("refused");
    let path = dir.path().join("plcd.sock");
    drop(UnixListener::bind(&path).unwrap()); // the file stays, nobody listens
    let run = plcctl_in(dir.path(), &["--socket", path.to_str().unwrap(), "stop"], &[]);
    assert_eq!(run.code, 3, "{run:?}");
    assert!(run.stderr.contains("connection refused"), "{run:?}");
}

#[test]
fn a_socket_without_permission_exits_3() {
    use std::os::unix::fs::PermissionsExt;

    let fake = Fake::start("denied", vec![]);
    std::fs::set_permissions(&fake.path, std::fs::Permissions::from_mode(0o600)).unwrap();
    // Root connects anyway: then ask as nobody, from a copy of plcctl that user can run.
    let copy = nobody::unavailable()
        .is_none()
        .then(|| nobody::Copy::of(Path::new(env!("CARGO_BIN_EXE_plcctl"))));
    let mut command = match &copy {
        Some(copy) => copy.command(nobody::NOBODY),
        None => {
            std::fs::set_permissions(&fake.path, std::fs::Permissions::from_mode(0o000)).unwrap();
            runner::command(env!("CARGO_BIN_EXE_plcctl"))
        }
    };
    let output = nobody::output(
        command.args(["--socket", fake.socket(), "status"]).env_remove("PLCD_SOCKET"),
    );
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert_eq!(fake.requests(), Vec::<String>::new());
    assert_eq!(output.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("permission denied"), "{stderr}");
}

#[test]
fn no_answer_in_time_exits_3() {
    let fake = Fake::start("hang", vec![Step::Hang]);
    let run = plcctl(&fake, &["--timeout", "200ms", "status"]);
    assert_eq!(run.code, 3, "{run:?}");
    assert_eq!(
        run.stderr,
        format!("plcctl: no answer from the daemon at {} within 200ms\n", fake.socket())
    );
    assert_eq!(fake.requests(), [r#"{"v":1,"cmd":"status"}"#]);
}

#[test]
fn a_full_listen_queue_is_a_connect_timeout_exit_3() {
    use nix::sys::socket::UnixAddr;
    use nix::sys::socket::{bind, listen, socket, AddressFamily, Backlog, SockFlag, SockType};
    use std::os::fd::AsRawFd;

    let dir = TempDir::new("backlog");
    let path = dir.path().join("plcd.sock");
    let fd = socket(AddressFamily::Unix, SockType::Stream, SockFlag::SOCK_CLOEXEC, None).unwrap();
    bind(fd.as_raw_fd(), &UnixAddr::new(&path).unwrap()).unwrap();
    listen(&fd, Backlog::new(0).unwrap()).unwrap();
    // Nobody accepts: the first connection fills a queue of 0 (Linux admits one more than the
    // backlog), the next one waits.
    let _first = UnixStream::connect(&path).unwrap();
    let run = plcctl_in(
        dir.path(),
        &["--socket", path.to_str().unwrap(), "--timeout", "100ms", "status"],
        &[],
    );
    assert_eq!(run.code, 3, "{run:?}");
    assert!(run.stderr.contains("did not accept the connection within 100ms"), "{run:?}");
}

#[test]
fn answers_that_are_not_this_protocol_exit_4() {
    for (name, step, message) in [
        ("garbage", Step::Answer("hello, I am not plcd".into()), "is not a valid response: not JSON"),
        ("array", Step::Answer("[1,2]".into()), "not a JSON object"),
        ("no-version", Step::Answer(r#"{"ok":{"kind":"mode","mode":"RUN"}}"#.into()), "no protocol version"),
        ("empty-object", Step::Answer(r#"{"v":1}"#.into()), "neither \"ok\" nor \"error\""),
        ("bad-reply", Step::Answer(r#"{"v":1,"ok":{"kind":"mode","mode":"SLEEPING"}}"#.into()), "not a reply"),
        ("closed", Step::CloseAfterRead, "closed the connection without answering"),
        ("truncated", Step::Raw(r#"{"v":1,"ok":{"kind":"mo"#), "closed in the middle of the line"),
        (
            "version",
            Step::Answer(
                r#"{"v":2,"error":{"kind":"version","message":"protocol version 1 is not supported; this daemon speaks 2"}}"#.into(),
            ),
            "the daemon speaks protocol version 2, this plcctl speaks 1\nprotocol version 1 is not supported; this daemon speaks 2\n",
        ),
        ("version-ok", Step::Answer(r#"{"v":2,"ok":{"kind":"mode","mode":"RUN"}}"#.into()), "protocol version 2"),
        (
            "wrong-kind",
            Step::Answer(r#"{"v":1,"ok":{"kind":"values","scan":1,"values":[]}}"#.into()),
            "the daemon answered `run` with a `values` reply",
        ),
    ] {
        for json in [false, true] {
            let fake = Fake::start(name, vec![step.clone()]);
            let args: &[&str] = if json { &["--json", "run"] } else { &["run"] };
            let run = plcctl(&fake, args);
            assert_eq!(fake.requests(), [r#"{"v":1,"cmd":"run"}"#], "{name}");
            assert_eq!(run.code, 4, "{name}: {run:?}");
            assert_eq!(run.stdout, "", "{name}");
            assert!(run.stderr.starts_with("plcctl: "), "{name}: {run:?}");
            assert!(run.stderr.contains(message), "{name}: {run:?}");
        }
    }
}

fn values_ok(scan: u64) -> Value {
    json!({"kind": "values", "scan": scan, "values": [
        {"dev": "D00010", "value": 7}, {"dev": "P0040", "value": 1}]})
}

/// `YYYY-MM-DDTHH:MM:SS.mmmZ` and the rest of the line.
fn split_timestamp(line: &str) -> (&str, &str) {
    let (time, rest) = line.split_at(24);
    let shape = time.bytes().enumerate().all(|(i, b)| match i {
        4 | 7 => b == b'-',
        10 => b == b'T',
        13 | 16 => b == b':',
        19 => b == b'.',
        23 => b == b'Z',
        _ => b.is_ascii_digit(),
    });
    assert!(shape, "not a time stamp: {time:?}");
    (time, rest)
}

#[test]
fn watch_count_3_sends_three_gets_and_prints_three_stamped_lines() {
    let steps = (1..=3).map(|scan| Step::Answer(ok_line(&values_ok(scan)))).collect();
    let fake = Fake::start("watch", steps);
    let run = plcctl(&fake, &["watch", "--interval", "1ms", "--count", "3", "D00010", "P0040"]);
    let get = r#"{"v":1,"cmd":"get","devices":["D00010","P0040"]}"#;
    assert_eq!(fake.requests(), [get, get, get]);
    assert_eq!(run.code, 0, "{run:?}");
    let lines: Vec<&str> = run.stdout.lines().collect();
    assert_eq!(lines.len(), 3, "{run:?}");
    for (i, line) in lines.iter().enumerate() {
        let (_, rest) = split_timestamp(line);
        assert_eq!(rest, format!("  scan {}  D00010=7       P0040=1", i + 1));
    }

    let steps = (1..=3).map(|scan| Step::Answer(ok_line(&values_ok(scan)))).collect();
    let fake = Fake::start("watch-json", steps);
    let run =
        plcctl(&fake, &["--json", "watch", "--interval", "1ms", "--count", "3", "D00010", "P0040"]);
    assert_eq!(fake.requests(), [get, get, get]);
    assert_eq!(run.code, 0, "{run:?}");
    let lines: Vec<&str> = run.stdout.lines().collect();
    assert_eq!(lines.len(), 3, "{run:?}");
    for (i, line) in lines.iter().enumerate() {
        let mut sample: Value = serde_json::from_str(line).unwrap();
        let time = sample.as_object_mut().unwrap().remove("time").expect("a time stamp");
        split_timestamp(time.as_str().unwrap());
        assert_eq!(sample, values_ok(i as u64 + 1));
    }
}

#[test]
fn watch_reconnects_when_the_daemon_closed_an_idle_connection() {
    let fake = Fake::start(
        "watch-idle",
        vec![
            Step::Answer(ok_line(&values_ok(1))),
            Step::CloseIdle,
            Step::Answer(ok_line(&values_ok(2))),
            Step::Answer(ok_line(&values_ok(3))),
        ],
    );
    let run = plcctl(&fake, &["watch", "--interval", "1ms", "--count", "3", "D00010", "P0040"]);
    assert_eq!(fake.requests().len(), 3);
    assert_eq!(run.code, 0, "{run:?}");
    assert_eq!(run.stdout.lines().count(), 3, "{run:?}");
}

#[test]
fn watch_stops_at_an_error_answer() {
    let refused = json!({"kind": "invalid", "message": "`D00010` is gone"});
    let fake = Fake::start(
        "watch-error",
        vec![Step::Answer(ok_line(&values_ok(1))), Step::Answer(error_line(&refused))],
    );
    let run = plcctl(&fake, &["watch", "--interval", "1ms", "--count", "5", "D00010", "P0040"]);
    assert_eq!(fake.requests().len(), 2);
    assert_eq!(run.code, 1, "{run:?}");
    assert_eq!(run.stdout.lines().count(), 1, "{run:?}");
    assert_eq!(run.stderr, "plcctl: invalid: `D00010` is gone\n");
}

#[test]
fn watch_without_count_runs_until_interrupted() {
    use nix::sys::signal::{kill, Signal};
    use nix::unistd::Pid;
    use std::os::unix::process::ExitStatusExt;

    // As when the tests run as a background job of a non-interactive shell: this process
    // ignores SIGINT. The child must not inherit that (runner::command resets it), or the
    // SIGINT below would leave it watching for ever. Nothing else in this test binary relies
    // on receiving SIGINT itself.
    runner::ignore_in_this_process(Signal::SIGINT);

    let steps = (1..=10_000).map(|scan| Step::Answer(ok_line(&values_ok(scan)))).collect();
    let fake = Fake::start("watch-forever", steps);
    let mut child = runner::command(env!("CARGO_BIN_EXE_plcctl"))
        .args(["--socket", fake.socket(), "watch", "--interval", "10ms", "P0040"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // Its output read to the end, so that it never blocks on a full pipe.
    let mut stdout = child.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut out = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut out).map(|_| out)
    });
    // Three samples asked for: it keeps going on its own.
    for _ in 0..3 {
        fake.seen.recv_timeout(Duration::from_secs(20)).expect("a get");
    }
    kill(Pid::from_raw(child.id() as i32), Signal::SIGINT).unwrap();
    let status =
        runner::wait_bounded(&mut child, Duration::from_secs(20), "plcctl watch after SIGINT");
    assert_eq!(status.signal(), Some(Signal::SIGINT as i32), "{status:?}");
    let out = reader.join().unwrap().expect("plcctl's output");
    // It prints a sample before asking for the next: the first two were printed.
    assert!(out.lines().filter(|l| l.contains("P0040=1")).count() >= 2, "{out}");
    assert!(fake.requests().len() >= 3);
}

#[test]
fn usage_errors_exit_2_without_connecting() {
    let dir = TempDir::new("usage");
    let missing = dir.path().join("missing.sock");
    for args in [
        &[][..],
        &["frobnicate"],
        &["get"],
        &["get", ""],
        &["set"],
        &["set", "main.speed"],
        &["set", "main.x", "1", "main.y"],
        &["force", "main.lamp", "2"],
        &["set", "D00010"],
        &["set", "D00010=abc"],
        &["set", "D00010=70000"],
        &["force", "P0000"],
        &["force"],
        &["unforce"],
        &["unforce", "P0000", "--all"],
        &["break"],
        &["reset", "--warm"],
        &["watch", "D00010", "--count", "0"],
        &["watch", "D00010", "--interval", "0ms"],
        &["watch", "D00010", "--interval", "5"],
        &["watch"],
        &["load"],
        &["load", "--config"],
        &["--timeout", "5", "status"],
        &["--timeout", "0s", "status"],
        &["status", "extra"],
    ] {
        let mut all = vec!["--socket", missing.to_str().unwrap()];
        all.extend_from_slice(args);
        let run = plcctl_in(dir.path(), &all, &[]);
        assert_eq!(run.code, 2, "{args:?}: {run:?}");
        assert_eq!(run.stdout, "", "{args:?}");
        assert!(run.stderr.contains("error:"), "{args:?}: {run:?}");
        assert!(!run.stderr.contains("cannot connect"), "{args:?}: {run:?}");
    }
}

#[test]
fn help_documents_the_exit_statuses() {
    let dir = TempDir::new("help");
    let run = plcctl_in(dir.path(), &["--help"], &[]);
    assert_eq!(run.code, 0);
    for part in [
        "Exit status:",
        "0  success",
        "1  the daemon answered with an error",
        "2  usage error",
        "3  cannot reach the daemon",
        "4  protocol error",
        "$PLCD_SOCKET",
    ] {
        assert!(run.stdout.contains(part), "missing {part:?} in\n{}", run.stdout);
    }
}

#[test]
fn global_options_may_follow_the_command() {
    let fake = Fake::start(
        "global",
        vec![Step::Answer(ok_line(&json!({"kind": "mode", "mode": "STOP"})))],
    );
    let socket = fake.socket().to_string();
    let run = plcctl_in(fake.dir.path(), &["stop", "--json", "--socket", &socket], &[]);
    assert_eq!(fake.requests(), [r#"{"v":1,"cmd":"stop"}"#]);
    assert_eq!(run.code, 0, "{run:?}");
    assert_eq!(run.stdout, "{\"kind\":\"mode\",\"mode\":\"STOP\"}\n");
}

#[test]
fn the_socket_comes_from_the_flag_then_plcd_socket_then_the_defaults() {
    let stop = ok_line(&json!({"kind": "mode", "mode": "STOP"}));

    // $PLCD_SOCKET without --socket.
    let fake = Fake::start("env", vec![Step::Answer(stop.clone())]);
    let run = plcctl_in(fake.dir.path(), &["stop"], &[("PLCD_SOCKET", fake.socket())]);
    assert_eq!(fake.requests().len(), 1);
    assert_eq!(run.code, 0, "{run:?}");

    // --socket wins over $PLCD_SOCKET.
    let fake = Fake::start("flag", vec![Step::Answer(stop.clone())]);
    let socket = fake.socket().to_string();
    let run = plcctl_in(
        fake.dir.path(),
        &["--socket", &socket, "stop"],
        &[("PLCD_SOCKET", "/nonexistent/plcd.sock")],
    );
    assert_eq!(fake.requests().len(), 1);
    assert_eq!(run.code, 0, "{run:?}");

    // Neither: the first default that exists, here $XDG_RUNTIME_DIR/plcd.sock (unless a real
    // daemon's socket is on this machine, which would come first).
    if Path::new("/run/plcd/plcd.sock").exists() {
        return skip::skip(None, "a daemon's /run/plcd/plcd.sock comes before the other defaults");
    }
    let fake = Fake::start("xdg", vec![Step::Answer(stop)]);
    let xdg = fake.dir.path().to_str().unwrap().to_string();
    let run = plcctl_in(fake.dir.path(), &["stop"], &[("XDG_RUNTIME_DIR", &xdg)]);
    assert_eq!(fake.requests().len(), 1);
    assert_eq!(run.code, 0, "{run:?}");
    assert_eq!(run.stdout, "mode: STOP\n");

    // Nothing found: the first default, and every path looked at in the message.
    let dir = TempDir::new("nodefault");
    let xdg = dir.path().to_str().unwrap().to_string();
    let run = plcctl_in(dir.path(), &["stop"], &[("XDG_RUNTIME_DIR", &xdg)]);
    let tmp_socket = format!("/tmp/plcd-{}/plcd.sock", nix::unistd::geteuid());
    if Path::new(&tmp_socket).exists() {
        return skip::skip(None, &format!("a daemon's {tmp_socket} is found before nothing is"));
    }
    assert_eq!(run.code, 3, "{run:?}");
    assert!(run.stderr.starts_with("plcctl: cannot connect to /run/plcd/plcd.sock: "), "{run:?}");
    assert!(run.stderr.contains(&format!("{xdg}/plcd.sock")), "{run:?}");
}

#[test]
fn the_client_library_is_usable_on_its_own() {
    let fake = Fake::start(
        "library",
        vec![
            Step::Answer(ok_line(&json!({"kind": "mode", "mode": "RUN"}))),
            Step::Answer(error_line(&json!({"kind": "busy", "message": "too many clients"}))),
        ],
    );
    let mut client = Client::connect(&fake.path, Duration::from_secs(20)).unwrap();
    assert_eq!(client.request(&Request::Run).unwrap(), Reply::Mode { mode: ModeName::Run });
    match client.request(&Request::Status) {
        Err(ClientError::Daemon { failure, .. }) => {
            assert_eq!(failure.kind, protocol::ErrorKind::Busy);
            assert_eq!(failure.message, "too many clients");
        }
        other => panic!("{other:?}"),
    }
    drop(client);
    assert_eq!(fake.requests(), [r#"{"v":1,"cmd":"run"}"#, r#"{"v":1,"cmd":"status"}"#]);
}
