//! A session on the control socket: the input is what a client writes, to the socket server of
//! `plcd run` (line framing, the line limit, JSON parsing) and its request handler, in front of
//! a running scan thread (the real-time driver, without real-time scheduling), as in the
//! daemon. The daemon is started once per process, on the first input.
//!
//! Checked: every answer is one line of the protocol's JSON; no more answers than requests
//! (and a last `too_long` for a line longer than the limit, after which nothing comes);
//! every request is answered within 3 s except `continue` (which waits for a breakpoint) and
//! `step`; and after the session a new client is answered `status`, while every thread of
//! the driver lives.

use std::io::{BufRead, BufReader, Write};
use std::net::Shutdown;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use plcd::daemon::requests::{RequestHandler, RequestLinks, Running};
use plcd::drivers::real_time::driver::Driver;
use plcd::services::control::server::ControlServer;
use plcd_ipc::{ErrorKind, Outcome, Request, ResponseLine};

/// Where the project is; `load` requests may name `plcd.toml` and `other.toml` there (the
/// dictionary does).
pub const DIR: &str = "/tmp/plcd-fuzz-control";

/// How long an answer may take (a scan boundary, a load of a small project), with room for a
/// loaded machine; below AFL++'s time limit for the target (`tests/fuzz/run`).
const ANSWER: Duration = Duration::from_secs(3);
/// How long the target waits for the answer to a `continue` or a `step`, which may wait for a
/// breakpoint that never comes.
const PARKED: Duration = Duration::from_millis(200);

const CONFIG: &str = r#"
[plc]
watchdog_ms = 100
[rt]
policy = "other"
lock_memory = false
[control]
max_request_bytes = 2048
[timers]
ms100 = "T0000-T0099"
ms10 = "T0100-T0199"
[[program]]
name = "main"
file = "main.il"
task = "scan"
[[program]]
name = "level"
file = "level.st"
task = "scan"
[[program]]
name = "tick"
file = "tick.il"
task = "tick_1ms"
[[task]]
name = "tick_1ms"
kind = "cycle"
number = 0
priority = 3
interval_ms = 1
"#;

const MAIN: &str = "LOAD P0000\nOUT P0040\nLOAD M0000\nTON T0000 10\nLOAD T0000\nOUT P0041\n\
                    INC D00010\nEND\n";
const TICK: &str = "INC D00500\nEND\n";
const LEVEL: &str = "PROGRAM level\nVAR\n    speed : INT;\n    name : STRING[8];\n\
                     pos AT %D00200 : DINT;\n    flag : BOOL;\nEND_VAR\nVAR CONSTANT\n\
                     k : INT := 3;\nEND_VAR\n    speed := speed + 1;\nEND_PROGRAM\n";
/// A project `load` may switch to: another scan program, the same layout.
const OTHER: &str = "[rt]\npolicy = \"other\"\nlock_memory = false\n[[program]]\nname = \"main\"\n\
                     file = \"main.il\"\n";

struct Daemon {
    socket: PathBuf,
    driver: Mutex<Driver>,
}

fn write_project(dir: &Path) {
    std::fs::create_dir_all(dir).expect("the project's directory");
    for (name, text) in [
        ("plcd.toml", CONFIG),
        ("main.il", MAIN),
        ("tick.il", TICK),
        ("level.st", LEVEL),
        ("other.toml", OTHER),
    ] {
        // Several fuzzers may share the directory: replace, never truncate in place.
        let temp = dir.join(format!(".{name}.{}", std::process::id()));
        std::fs::write(&temp, text).expect("a project file");
        std::fs::rename(&temp, dir.join(name)).expect("a project file");
    }
}

fn daemon() -> &'static Daemon {
    static DAEMON: OnceLock<Daemon> = OnceLock::new();
    DAEMON.get_or_init(|| {
        let dir = Path::new(DIR);
        write_project(dir);
        let config = dir.join("plcd.toml");
        let mut project = plcd::files::project(&config).expect("the target's project");
        let socket = dir.join(format!("plcd-{}.sock", std::process::id()));
        let _ = std::fs::remove_file(&socket);
        project.config.control.socket = Some(socket.clone());
        let mut driver = Driver::start(&project, Vec::new()).expect("the driver");
        let links = RequestLinks {
            shared: Arc::clone(&driver.shared),
            commands: Arc::clone(&driver.commands),
            completions: driver.take_completions().expect("the completions"),
            snapshot: Arc::clone(&driver.snapshot),
            remote: driver.remote_board(),
            running: Arc::new(Mutex::new(Running::new(&config, project.clone()))),
            announce: None,
            mqtt: None,
        };
        let mut server = ControlServer::bind(&project.config.control).expect("the socket");
        std::thread::spawn(move || {
            let mut handler = RequestHandler::new(links);
            server.serve(&mut handler).expect("the control server");
        });
        Daemon { socket, driver: Mutex::new(driver) }
    })
}

/// Sends `lines` and reads one answer to each.
fn ask(socket: &Path, lines: &[&str]) -> Vec<ResponseLine> {
    let mut stream = UnixStream::connect(socket).expect("connect");
    stream.set_read_timeout(Some(ANSWER)).unwrap();
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    lines
        .iter()
        .map(|line| {
            stream.write_all(format!("{line}\n").as_bytes()).unwrap();
            let mut answer = String::new();
            reader.read_line(&mut answer).expect("an answer in time");
            serde_json::from_str(&answer).expect("an answer line")
        })
        .collect()
}

/// The last session may have changed the PLC's state (a request other than a read).
static CHANGED: AtomicBool = AtomicBool::new(true);

pub fn run(data: &[u8]) {
    let d = daemon();
    // From RUN, with nothing forced and no breakpoint: each session on its own.
    if CHANGED.swap(false, Ordering::Relaxed) {
        reset(d);
    }
    let requests: Vec<&[u8]> = data
        .split_inclusive(|&b| b == b'\n')
        .filter(|l| l.ends_with(b"\n") && !l.iter().all(u8::is_ascii_whitespace))
        .collect();
    let reads_only = requests.iter().all(|l| {
        let request = plcd_ipc::parse_request(l.strip_suffix(b"\n").unwrap_or(l));
        matches!(request, Err(_) | Ok(Request::Status | Request::Get { .. } | Request::Forces))
    });
    CHANGED.store(!reads_only, Ordering::Relaxed);
    session(d, data, &requests);
}

/// RUN, no forces, no breakpoints.
fn reset(d: &Daemon) {
    for answer in ask(
        &d.socket,
        &[
            r#"{"v":1,"cmd":"unbreak"}"#,
            r#"{"v":1,"cmd":"unforce_all"}"#,
            r#"{"v":1,"cmd":"reset"}"#,
            r#"{"v":1,"cmd":"run"}"#,
        ],
    ) {
        assert!(matches!(answer.outcome, Outcome::Ok(_)), "setting up a session: {answer:?}");
    }
}

/// Sends `data` as one client, shuts the connection for writing, and checks what comes back.
fn session(d: &Daemon, data: &[u8], requests: &[&[u8]]) {
    let mut stream = UnixStream::connect(&d.socket).expect("connect");
    stream.set_read_timeout(Some(ANSWER)).unwrap();
    // A write may fail once the server closed the connection (a line too long): what it read
    // is answered all the same.
    let _ = stream.write_all(data);
    let _ = stream.shutdown(Shutdown::Write);
    let mut reader = BufReader::new(stream);
    let (mut answers, mut too_long) = (0, false);
    loop {
        let parked = requests.get(answers).map(|l| plcd_ipc::parse_request(l));
        let parked = matches!(parked, Some(Ok(Request::Continue | Request::Step { .. })));
        reader.get_ref().set_read_timeout(Some(if parked { PARKED } else { ANSWER })).unwrap();
        let mut line = Vec::new();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) => break,
            Ok(_) => {
                assert!(line.ends_with(b"\n"), "half an answer line");
                let answer: ResponseLine = serde_json::from_slice(&line).expect("a protocol line");
                assert_eq!(answer.v, plcd_ipc::VERSION);
                assert!(!too_long, "an answer after `too_long`, which ends the connection");
                if matches!(&answer.outcome, Outcome::Error(f) if f.kind == ErrorKind::TooLong) {
                    // For a line without its end yet: no request of `requests`.
                    too_long = true;
                    continue;
                }
                answers += 1;
                assert!(answers <= requests.len(), "more answers than requests");
            }
            // The server closed a connection whose line was too long, with input unread.
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => break,
            Err(_) => {
                // No answer in time: only a request that waits for the program may be so.
                assert!(
                    parked,
                    "request {answers} unanswered after {ANSWER:?}: {:?}",
                    requests.get(answers).map(|l| String::from_utf8_lossy(l))
                );
                break;
            }
        }
    }
    drop(reader);
    let status = ask(&d.socket, &[r#"{"v":1,"cmd":"status"}"#]);
    assert!(matches!(status[0].outcome, Outcome::Ok(_)), "status after the session: {status:?}");
    let driver = d.driver.lock().unwrap();
    assert_eq!(driver.dead_thread(), None, "a thread of the driver died");
}
