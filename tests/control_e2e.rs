//! `plcctl` against a real daemon on the sim backend: every command, a refused peer, malformed
//! input that leaves the daemon unharmed, and 50 clients polling `status` while the scan runs.
//!
//! Real time is only waited on, never asserted: each check waits for a state with a generous
//! bound (the daemon is a separate process), and figures are printed, not compared.

mod harness;

use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::Arc;
use std::time::Duration;

use harness::daemon::{plcctl_binary, Daemon, Project};
use harness::nobody::{self, NOBODY};
use harness::tempdir::TempDir;

const PATIENCE: Duration = Duration::from_secs(10);

const CONFIG: &str = "[plc]\nscan_period_ms = 2\nwatchdog_ms = 100\n\
    [[program]]\nfile = \"main.il\"\n\
    [[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
    [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n\
    [control]\nsocket = \"plcd.sock\"\n";

/// Line 1 counts scans; line 3 copies P0000 to P0040 (for forcing).
const MAIN: &str = "INC D00000\n; copy\nLOAD P0000\nOUT P0040\nLOAD _FORCE_OUT\nOUT M0001\nEND\n";
const TICK: &str = "INC D00001\nEND\n";

/// The daemon on a project of its own (a directory every user can reach, for the peer test),
/// in RUN.
struct Plc {
    // Declared first, dropped first: the daemon is gone before its directory is removed.
    daemon: Daemon,
    project: Project,
}

impl Plc {
    fn start(name: &str, files: &[(&str, &str)]) -> Plc {
        let project = Project::in_dir(TempDir::for_everyone(&format!("e2e-{name}")), files);
        let daemon = project.start().with_patience(PATIENCE);
        let plc = Plc { daemon, project };
        plc.daemon.wait_for("control socket");
        // The mode itself: the human status also says RUN for a key switch at RUN.
        plc.wait(|p| p.status()["mode"] == "RUN", "RUN");
        plc
    }

    fn socket(&self) -> PathBuf {
        self.project.socket()
    }

    fn ctl(&self, args: &[&str]) -> Output {
        self.project.plcctl(args)
    }

    /// `plcctl ARGS` that must succeed; its stdout.
    fn ok(&self, args: &[&str]) -> String {
        let out = self.ctl(args);
        assert_eq!(
            out.status.code(),
            Some(0),
            "plcctl {args:?}: {}{}",
            out.stdout_text(),
            out.stderr_text()
        );
        out.stdout_text()
    }

    /// The value of one device, through `plcctl --json get`.
    fn get(&self, dev: &str) -> i64 {
        let json: serde_json::Value =
            serde_json::from_str(&self.ok(&["--json", "get", dev])).unwrap();
        json["values"][0]["value"].as_i64().unwrap()
    }

    fn status(&self) -> serde_json::Value {
        serde_json::from_str(&self.ok(&["--json", "status"])).unwrap()
    }

    fn wait(&self, mut done: impl FnMut(&Plc) -> bool, what: &str) {
        self.daemon.wait(what, || done(self));
    }

    /// SIGTERM: a clean stop that removes the socket; the whole log.
    fn stop(self) -> Vec<String> {
        let socket = self.socket();
        let (code, log) = self.daemon.stop();
        assert_eq!(code, 0, "clean stop:\n{}", log.join("\n"));
        assert!(!socket.exists(), "the socket is removed at exit");
        log
    }
}

trait Text {
    fn stdout_text(&self) -> String;
    fn stderr_text(&self) -> String;
}

impl Text for Output {
    fn stdout_text(&self) -> String {
        String::from_utf8_lossy(&self.stdout).into_owned()
    }
    fn stderr_text(&self) -> String {
        String::from_utf8_lossy(&self.stderr).into_owned()
    }
}

fn plc(name: &str) -> Plc {
    Plc::start(name, &[("plcd.toml", CONFIG), ("main.il", MAIN), ("tick.il", TICK)])
}

#[test]
fn every_plcctl_command_against_the_daemon() {
    let plc = plc("all");
    // status, human and JSON.
    let human = plc.ok(&["status"]);
    assert!(human.contains("RUN") && human.contains("tick"), "{human}");
    let status = plc.status();
    assert_eq!(status["mode"], "RUN");
    let tick = status["tasks"].as_array().unwrap().iter().find(|t| t["name"] == "tick").unwrap();
    assert_eq!(tick["kind"], "cycle");
    assert!(tick["runs"].as_u64().unwrap() > 0);

    // set / get at END; watch.
    assert!(plc.ok(&["set", "D00100=42", "M0100=1"]).contains("2 writes"));
    assert_eq!(plc.get("D00100"), 42);
    assert_eq!(plc.get("M0100"), 1);
    let watched = plc.ok(&["watch", "--count", "2", "--interval", "20ms", "D00000"]);
    assert_eq!(watched.lines().count(), 2, "{watched}");
    assert_eq!(plc.ctl(&["set", "_ON=0"]).status.code(), Some(1), "system devices are read-only");

    // Forces: an input overrides the field, the program sees the flag.
    assert!(plc.ok(&["force", "P0000=1"]).contains("P0000"));
    plc.wait(|p| p.get("P0040") == 1, "the forced input copied to P0040");
    plc.ok(&["force", "P0041=1"]);
    plc.wait(|p| p.get("M0001") == 1, "_FORCE_OUT seen by the program");
    let forces = plc.ok(&["forces"]);
    assert!(forces.contains("P0000") && forces.contains("P0041"), "{forces}");
    assert_eq!(plc.status()["forces"].as_array().unwrap().len(), 2);
    plc.ok(&["unforce", "P0000"]);
    assert_eq!(plc.ctl(&["unforce", "P0000"]).status.code(), Some(1), "not forced any more");
    assert_eq!(plc.ctl(&["force", "M0000=1"]).status.code(), Some(1), "only P bits");
    plc.ok(&["unforce", "--all"]);
    plc.wait(|p| p.get("M0001") == 0, "forces gone, and _FORCE_OUT with them");
    assert_eq!(plc.get("P0000"), 1, "P0000 is no input here: it keeps the value it was forced to");

    // Modes.
    assert!(plc.ok(&["stop"]).contains("STOP"));
    assert_eq!(plc.status()["mode"], "STOP");
    assert!(plc.ok(&["run"]).contains("RUN"));
    let first = plc.get("D00000");
    plc.wait(|p| p.get("D00000") != first, "RUN again: the scan counts");
    plc.ok(&["set", "K010=7"]);
    plc.ok(&["reset"]);
    assert_eq!(plc.status()["mode"], "STOP");
    assert_eq!(plc.get("K010"), 7, "a warm reset keeps K");
    plc.ok(&["reset", "--cold"]);
    assert_eq!(plc.get("K010"), 0, "a cold reset clears it");

    // DEBUG: break before line 3, step, continue, back to RUN.
    // From STOP, DEBUG starts paused before the first scan.
    let debug = plc.ok(&["debug"]);
    assert!(debug.starts_with("between scans; 0 scans completed\n"), "{debug}");
    assert_eq!(plc.status()["mode"], "DEBUG");
    plc.ok(&["break", "main:3"]);
    let paused = plc.ok(&["--json", "continue"]);
    assert!(paused.contains("main:3"), "{paused}");
    plc.wait(|p| p.status()["debug"]["paused_at"]["line"] == 3, "paused at main:3");
    let at = plc.status();
    assert_eq!(at["debug"]["paused_at"]["source"], "LOAD P0000");
    assert_eq!(at["debug"]["paused_at"]["devices"][0]["dev"], "P0000");
    let counted = plc.get("D00000");
    // Still there once a read of other devices took the newest capture: status reads them.
    let at = plc.status();
    assert_eq!(at["debug"]["paused_at"]["devices"][0]["dev"], "P0000", "{at}");
    let step: serde_json::Value = serde_json::from_str(&plc.ok(&["--json", "step"])).unwrap();
    assert_eq!(step["paused_at"]["line"], 4, "step goes to the next line: {step}");
    assert_eq!(step["paused_at"]["source"], "OUT P0040");
    let step: serde_json::Value =
        serde_json::from_str(&plc.ok(&["--json", "step", "--scan"])).unwrap();
    assert_eq!(step["running"], false, "step --scan answers once the scan is done: {step}");
    assert!(step.get("paused_at").is_none(), "between scans: {step}");
    assert_eq!(plc.get("D00000"), counted, "line 1 ran before the breakpoint, not again");
    plc.ok(&["continue"]);
    plc.wait(|p| p.get("D00000") == counted + 1, "the next scan, stopped at main:3 again");
    assert_eq!(plc.ctl(&["unbreak", "main:4"]).status.code(), Some(1), "no breakpoint there");
    plc.ok(&["unbreak"]);
    // Running to a breakpoint that is gone (for ever): `debug` answers at once, with that state.
    plc.ok(&["continue"]);
    let debug = plc.ok(&["debug"]);
    assert!(debug.starts_with("running to a breakpoint"), "{debug}");
    assert!(plc.ok(&["run"]).contains("RUN"));
    plc.wait(|p| p.get("D00000") > counted + 5, "RUN goes on");
    assert_eq!(plc.ctl(&["step"]).status.code(), Some(1), "step only in DEBUG");

    // load: refused in RUN, online change keeps memory, offline in STOP, a broken project.
    let dir = plc.project.dir.path().to_path_buf();
    std::fs::write(dir.join("main2.il"), "INC D00000\nINC D00002\nLOAD P0000\nOUT P0040\nEND\n")
        .unwrap();
    std::fs::write(dir.join("new.toml"), CONFIG.replace("main.il", "main2.il")).unwrap();
    let new = dir.join("new.toml");
    let new = new.to_str().unwrap();
    assert_eq!(plc.ctl(&["load", "--config", new]).status.code(), Some(1), "RUN needs --online");
    let before = plc.get("D00000");
    assert!(plc.ok(&["load", "--config", new, "--online"]).contains("online"));
    plc.wait(|p| p.get("D00002") > 0, "the new program runs");
    assert!(plc.get("D00000") >= before, "device memory kept across the online change");
    std::fs::write(dir.join("slow.toml"), CONFIG.replace("interval_ms = 1", "interval_ms = 5"))
        .unwrap();
    let refused =
        plc.ctl(&["load", "--config", dir.join("slow.toml").to_str().unwrap(), "--online"]);
    assert_eq!(refused.status.code(), Some(1));
    assert!(refused.stderr_text().contains("task \"tick\" changed"), "{}", refused.stderr_text());
    std::fs::write(dir.join("bad.il"), "LOAD P0000\nOUTT P0040\nEND\n").unwrap();
    std::fs::write(dir.join("bad.toml"), CONFIG.replace("main.il", "bad.il")).unwrap();
    let bad = plc.ctl(&["load", "--config", dir.join("bad.toml").to_str().unwrap()]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(bad.stderr_text().contains("bad.il:2:1: error"), "{}", bad.stderr_text());
    plc.ok(&["stop"]);
    assert!(plc.ok(&["load", "--config", new]).contains("STOP"));
    plc.ok(&["run"]);
    assert_eq!(plc.status()["mode"], "RUN");

    let log = plc.stop();
    for expected in
        ["mode STOP (control socket)", "mode DEBUG (control socket)", "as an online change"]
    {
        assert!(log.iter().any(|l| l.contains(expected)), "no {expected:?} in the log");
    }
}

#[test]
fn a_peer_that_is_not_allowed_is_refused() {
    if let Some(reason) = nobody::unavailable() {
        return harness::skip::skip(None, &reason);
    }
    let plc = plc("peer");
    // The file mode would already stop the connect; open it so SO_PEERCRED has to decide.
    let socket = plc.socket();
    std::fs::set_permissions(&socket, std::os::unix::fs::PermissionsExt::from_mode(0o666)).unwrap();
    let plcctl = nobody::Copy::of(&plcctl_binary());
    let out = nobody::output(plcctl.command(NOBODY).arg("--socket").arg(&socket).arg("status"));
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr_text());
    assert!(out.stderr_text().contains("not allowed"), "{}", out.stderr_text());
    plc.daemon.wait_for("65534");
    assert_eq!(plc.status()["mode"], "RUN", "the daemon goes on");
    plc.stop();
}

fn raw(socket: &Path) -> UnixStream {
    let stream = UnixStream::connect(socket).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    stream
}

#[test]
fn malformed_input_leaves_the_daemon_unharmed() {
    let plc = plc("garbage");
    let socket = plc.socket();
    let scans = plc.status()["scan"]["count"].as_u64().unwrap();
    // Random bytes, newline-terminated: answered with an error, connection still usable.
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..20 {
        let mut s = raw(&socket);
        let mut bytes: Vec<u8> = (0..200)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed & 0xFF) as u8
            })
            .filter(|b| *b != b'\n')
            .collect();
        bytes.push(b'\n');
        s.write_all(&bytes).unwrap();
        let mut line = String::new();
        BufReader::new(&s).read_line(&mut line).unwrap();
        assert!(line.contains("\"error\"") && line.contains("bad_request"), "{line}");
    }
    // Unknown command, wrong version.
    let mut s = raw(&socket);
    s.write_all(b"{\"v\":1,\"cmd\":\"format_disk\"}\n{\"v\":9,\"cmd\":\"status\"}\n").unwrap();
    let mut reader = BufReader::new(s.try_clone().unwrap());
    let mut line = String::new();
    reader.read_line(&mut line).unwrap();
    assert!(line.contains("bad_request"), "{line}");
    line.clear();
    reader.read_line(&mut line).unwrap();
    assert!(line.contains("\"version\""), "{line}");
    // A 1 MiB line: too_long, then the connection is closed.
    let mut s = raw(&socket);
    let big = vec![b'x'; 1 << 20];
    let _ = s.write_all(&big);
    let mut answer = String::new();
    let _ = s.read_to_string(&mut answer);
    assert!(answer.contains("too_long"), "{answer}");
    // Half a request, then a hang-up.
    let mut s = raw(&socket);
    s.write_all(b"{\"v\":1,\"cmd\":\"sta").unwrap();
    drop(s);
    // Unharmed: it answers and it scans.
    plc.wait(|p| p.status()["scan"]["count"].as_u64().unwrap() > scans + 10, "scans go on");
    assert_eq!(plc.status()["mode"], "RUN");
    plc.stop();
}

#[test]
fn fifty_clients_polling_status_lose_no_scan() {
    let plc = plc("storm");
    let socket = plc.socket();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let answered = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let clients: Vec<_> = (0..50)
        .map(|_| {
            let (socket, stop, answered) =
                (socket.clone(), Arc::clone(&stop), Arc::clone(&answered));
            std::thread::spawn(move || {
                let s = raw(&socket);
                let mut reader = BufReader::new(s.try_clone().unwrap());
                let mut writer = s;
                let mut line = String::new();
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    writer.write_all(b"{\"v\":1,\"cmd\":\"status\"}\n").unwrap();
                    line.clear();
                    reader.read_line(&mut line).unwrap();
                    assert!(line.contains("\"kind\":\"status\""), "{line}");
                    answered.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
            })
        })
        .collect();
    let before = plc.status()["scan"]["count"].as_u64().unwrap();
    plc.wait(
        |p| p.status()["scan"]["count"].as_u64().unwrap() > before + 500,
        "500 scans under load",
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    for client in clients {
        client.join().unwrap();
    }
    // Every scan ran to its END: the program counted each one (a scan is never cut short by a
    // reader, and nothing was applied in the middle of one).
    plc.ok(&["stop"]);
    let status = plc.status();
    let scans = status["scan"]["count"].as_i64().unwrap();
    assert_eq!(plc.get("D00000"), scans, "one INC per scan");
    println!(
        "{} status answers; scan p50 {} ns, p99 {} ns, max {} ns",
        answered.load(std::sync::atomic::Ordering::Relaxed),
        status["scan"]["p50_ns"],
        status["scan"]["p99_ns"],
        status["scan"]["max_ns"]
    );
    plc.stop();
}

#[test]
fn the_key_switch_rules_remote_mode_changes() {
    // The simulated switch starts at RUN and is turned to STOP after 3 s.
    let config = CONFIG.replace(
        "[control]",
        "[switch]\nposition = \"run\"\n[io]\nstimulus = \"switch.csv\"\n[control]",
    );
    let plc = Plc::start(
        "switch",
        &[
            ("plcd.toml", &config),
            ("main.il", MAIN),
            ("tick.il", TICK),
            ("switch.csv", "3s, SWITCH, STOP\n"),
        ],
    );
    // The switch's position as the scan thread's snapshot has it, once it has one.
    let mut status = plc.status();
    plc.wait(
        |p| {
            status = p.status();
            !status["switch"].is_null()
        },
        "the switch in the status",
    );
    if status["switch"] == "RUN" {
        assert_eq!(status["remote_allowed"], false);
        let refused = plc.ctl(&["stop"]);
        assert_eq!(refused.status.code(), Some(1));
        assert!(refused.stderr_text().contains("switch is at RUN"), "{}", refused.stderr_text());
    } else {
        harness::skip::skip(None, "the switch turned to STOP before a remote STOP could be tried");
    }
    // The mode in a status answer is the live one, the switch and remote_allowed come from the
    // scan thread's last snapshot: wait until both say STOP.
    plc.wait(
        |p| {
            let status = p.status();
            status["mode"] == "STOP" && status["switch"] == "STOP"
        },
        "the switch turned to STOP",
    );
    assert_eq!(plc.status()["remote_allowed"], true);
    assert!(plc.ok(&["run"]).contains("RUN"), "remote RUN with the switch at STOP");
    let log = plc.stop();
    for expected in ["mode RUN (key switch)", "key switch at STOP", "mode STOP (key switch)"] {
        assert!(
            log.iter().any(|l| l.contains(expected)),
            "no {expected:?} in:\n{}",
            log.join("\n")
        );
    }
}

/// A `load` compiles the new project on the control thread, and builds its engine there: a
/// program nested as deep as the parser takes (63 levels of parentheses, in an IF 1 deep)
/// loads online, and the daemon answers on (its stack, `CONTROL_THREAD_STACK`, had overflowed
/// once a debug build's frames grew).
#[test]
fn a_program_nested_as_deep_as_the_parser_takes_loads_on_the_control_thread() {
    let st = |depth: usize| {
        let nested = format!("{}x + 1{}", "(".repeat(depth), ")".repeat(depth));
        format!("PROGRAM main\nVAR x : INT; END_VAR\nIF TRUE THEN\n  x := {nested};\nEND_IF;\nEND_PROGRAM\n")
    };
    let config = "[plc]\nscan_period_ms = 5\n[[program]]\nfile = \"main.st\"\n\
        [control]\nsocket = \"plcd.sock\"\n";
    let plc = Plc::start("deep", &[("plcd.toml", config), ("main.st", &st(1))]);
    plc.project.write("deep.st", &st(60));
    plc.project.write("deep.toml", &config.replace("main.st", "deep.st"));
    let deep = plc.project.path("deep.toml");
    assert!(plc.ok(&["load", "--config", deep.to_str().unwrap(), "--online"]).contains("online"));
    assert_eq!(plc.status()["mode"], "RUN", "answering after the load");
}
