//! `plcd run` end to end on the sim backend, in real time: the binary is started on a project
//! in a temporary directory, its log is read line by line, and it is stopped with signals.
//! Timing bounds are loose (seconds): these tests check behaviour, the benchmarks measure time.

mod harness;

use std::os::unix::net::UnixDatagram;
use std::time::Duration;

use nix::sys::signal::Signal;

use harness::daemon::Project;
use harness::log::PATIENCE;

/// A project whose configs get their own control socket in the project's directory, so that
/// daemons of tests running at the same time do not meet.
fn project(name: &str, files: &[(&str, &str)]) -> Project {
    let project = Project::new(name, &[]);
    for (file, text) in files {
        write(&project, file, text);
    }
    project
}

/// Writes a file of the project; a config without `[control]` gets `socket = "plcd.sock"`.
fn write(project: &Project, file: &str, text: &str) {
    if file.ends_with(".toml") && !text.contains("[control]") {
        project.write(file, &format!("{text}\n[control]\nsocket = \"plcd.sock\"\n"));
    } else {
        project.write(file, text);
    }
}

const CONVEYOR: &str = r#"
[plc]
scan_period_ms = 5

[[program]]
file = "main.il"

[[program]]
file = "blink.il"
task = "blink"

[[program]]
file = "count.il"
task = "count"

[[task]]
name = "blink"
kind = "cycle"
number = 0
priority = 3
interval_ms = 50

[[task]]
name = "count"
kind = "io"
number = 8
priority = 2
contact = "P0000"
edge = "rising"

[io]
stimulus = "inputs.csv"
"#;

const MAIN: &str = "LOAD P0001\nOUT P0041\nLOAD>= D00000 3\nOUT P0042\nEND\n";
const BLINK: &str = "LOAD NOT P0040\nOUT P0040\nEND\n";
const COUNT: &str = "INC D00000\nEND\n";
const INPUTS: &str = "100ms, P0000, 1\n150ms, P0000, 0\n200ms, P0000, 1\n250ms, P0000, 0\n\
                      300ms, P0000, 1\n350ms, P0000, 0\n400ms, P0001, 1\n";

fn conveyor(name: &str) -> Project {
    project(
        name,
        &[
            ("plcd.toml", CONVEYOR),
            ("main.il", MAIN),
            ("blink.il", BLINK),
            ("count.il", COUNT),
            ("inputs.csv", INPUTS),
        ],
    )
}

#[test]
fn runs_the_project_in_real_time_and_stops_cleanly_on_sigterm() {
    let project = conveyor("run");
    let daemon = project.start();
    daemon.wait_for("mode RUN (startup)");
    // The cycle task blinks, the io task counts three edges of the stimulus, the scan follows
    // P0001.
    let on = daemon.wait_for("P0040 = 1");
    daemon.wait_for_after(on, "P0040 = 0");
    daemon.wait_for("P0042 = 1");
    daemon.wait_for("P0041 = 1");
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "log:\n{}", log.join("\n"));
    let text = log.join("\n");
    let stopping = text.find("SIGTERM: stopping").expect("the signal is logged");
    let after = &text[stopping..];
    assert!(after.contains("mode STOP (signal)"), "{text}");
    assert!(after.contains("P0041 = 0") && after.contains("P0042 = 0"), "outputs off:\n{text}");
    assert!(text.contains("statistics: task count: 3 runs, 0 ignored"), "{text}");
    assert!(text.contains("stopped; outputs off"), "{text}");
}

/// Time 0 of the inputs file is the first RUN, however long after the start it comes: held in
/// STOP by the key switch for longer than the file's three edges take, the daemon then runs and
/// its io task still counts all three (played from the start of the threads, they would have
/// met an engine in STOP).
#[test]
fn the_inputs_file_plays_from_the_first_run() {
    let project = conveyor("first-run");
    write(&project, "plcd.toml", &format!("{CONVEYOR}\n[switch]\nposition = \"stop\"\n"));
    let daemon = project.start();
    daemon.wait_for("control socket");
    // Not a synchronisation: the gap the file must not be played in (its edges end at 350 ms).
    std::thread::sleep(std::time::Duration::from_millis(600));
    let out = harness::daemon::plcctl(&project.socket(), &["run"]);
    assert!(out.status.success(), "plcctl run: {}", String::from_utf8_lossy(&out.stderr));
    let run = daemon.wait_for("mode RUN");
    daemon.wait_for_after(run, "P0042 = 1");
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "log:\n{}", log.join("\n"));
}

/// A force is the operator's: a reload (SIGHUP) and a load in STOP keep it, in the force table
/// and on the output (P0045, written by no program).
#[test]
fn forces_survive_a_reload_and_a_load() {
    let project = conveyor("forces");
    let daemon = project.start();
    daemon.wait_for("mode RUN (startup)");
    let socket = project.socket();
    let ok = |args: &[&str]| {
        let out = harness::daemon::plcctl(&socket, args);
        assert!(out.status.success(), "plcctl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let forced = |when: &str| {
        assert!(ok(&["forces"]).contains("P0045"), "the force table {when}");
        let value = ok(&["get", "P0045"]);
        assert_eq!(value.split_whitespace().collect::<Vec<_>>(), ["P0045", "1"], "{when}");
    };
    ok(&["force", "P0045=1"]);
    forced("once forced");

    write(&project, "blink.il", "LOAD NOT P0043\nOUT P0043\nEND\n");
    daemon.signal(Signal::SIGHUP);
    let reloaded = daemon.wait_for("reloaded: 3 programs, 2 tasks");
    daemon.wait_for_after(reloaded, "mode RUN (reload)");
    forced("after the reload");

    ok(&["stop"]);
    let config = project.path("plcd.toml");
    ok(&["load", "--config", config.to_str().unwrap()]);
    ok(&["run"]);
    forced("after the load");
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "log:\n{}", log.join("\n"));
}

#[test]
fn sighup_with_a_broken_program_keeps_the_running_one_then_a_good_one_replaces_it() {
    let project = conveyor("reload");
    let daemon = project.start();
    daemon.wait_for("P0040 = 1");

    write(&project, "blink.il", "LOAD NOT P0040\nOUTT P0040\nEND\n");
    daemon.signal(Signal::SIGHUP);
    let refused = daemon.wait_for("reload refused (1 errors)");
    let lines = daemon.lines();
    assert!(
        lines.iter().any(|l| l.contains("blink.il:2:1: error:")),
        "the diagnostic names file, line and column:\n{}",
        lines.join("\n")
    );
    // Still blinking: both edges again after the refusal.
    let on = daemon.wait_for_after(refused, "P0040 = 1");
    daemon.wait_for_after(on, "P0040 = 0");

    write(&project, "blink.il", "LOAD NOT P0043\nOUT P0043\nEND\n");
    daemon.signal(Signal::SIGHUP);
    let reloaded = daemon.wait_for("reloaded: 3 programs, 2 tasks");
    daemon.wait_for_after(reloaded, "mode STOP (reload)");
    daemon.wait_for_after(reloaded, "mode RUN (reload)");
    daemon.wait_for_after(reloaded, "P0043 = 1");
    assert!(!daemon.lines().iter().any(|l| l.contains("STOP instruction")), "{:?}", daemon.lines());
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "log:\n{}", log.join("\n"));
}

#[test]
fn a_scan_that_never_ends_takes_the_watchdog_error_and_clears_the_outputs() {
    let config = "[plc]\nwatchdog_ms = 50\n[[program]]\nfile = \"main.il\"\n\
                  [io]\nstimulus = \"inputs.csv\"\n";
    // P0040 is ON every scan; once P0001 is ON, the scan loops forever.
    let main = "LOAD _ON\nOUT P0040\nLABEL 1\nLOAD P0001\nJMP 1\nEND\n";
    let project = project(
        "wdt",
        &[("plcd.toml", config), ("main.il", main), ("inputs.csv", "200ms, P0001, 1\n")],
    );
    let daemon = project.start();
    let on = daemon.wait_for("P0040 = 1");
    let error = daemon.wait_for_after(on, "error WDT: scan");
    assert!(daemon.lines()[error].contains("exceeded watchdog_ms 50"));
    daemon.wait_for_after(on, "mode ERROR (error)");
    daemon.wait_for_after(on, "P0040 = 0");
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "log:\n{}", log.join("\n"));
}

#[test]
fn config_errors_stop_the_start_with_every_diagnostic() {
    let config =
        "[rt]\nscan_priority = 0\npolicy = \"round-robin\"\n[[program]]\nfile = \"main.il\"\n";
    let project = project("badrt", &[("plcd.toml", config), ("main.il", "END\n")]);
    let (code, log) = project.start().finish();
    assert_eq!(code, 1);
    let log = log.join("\n");
    let path = project.config().display().to_string();
    assert!(log.contains(&format!("{path}:2:17: error: rt.scan_priority 0 out of range")), "{log}");
    assert!(log.contains(&format!("{path}:3:10: error:")), "{log}");
    assert!(log.contains("not started: 2 errors in the project"), "{log}");
}

#[test]
fn a_missing_gpio_chip_is_named() {
    let config = "[[program]]\nfile = \"main.il\"\n[io]\nbackend = \"gpiocdev\"\n\
                  chip = \"/dev/gpiochip-plcd-test\"\n\
                  [[io.output]]\ndevice = \"P0040\"\nline = 3\n";
    let project = project("nochip", &[("plcd.toml", config), ("main.il", "END\n")]);
    let (code, log) = project.start().finish();
    assert_eq!(code, 1);
    let log = log.join("\n");
    assert!(log.contains("GPIO chip `/dev/gpiochip-plcd-test` not found"), "{log}");
}

#[test]
fn a_broken_stimulus_file_is_located() {
    let config = "[[program]]\nfile = \"main.il\"\n[io]\nstimulus = \"inputs.csv\"\n";
    let project = project(
        "badstim",
        &[
            ("plcd.toml", config),
            ("main.il", "END\n"),
            ("inputs.csv", "10ms, P0000, 1\nsoon, P0000, 0\n"),
        ],
    );
    let (code, log) = project.start().finish();
    assert_eq!(code, 1);
    let log = log.join("\n");
    assert!(log.contains("inputs.csv:2:1: error:"), "{log}");
}

#[test]
fn the_service_manager_hears_ready_status_watchdog_and_stopping() {
    let project = conveyor("notify");
    let socket = project.path("notify.sock");
    let listener = UnixDatagram::bind(&socket).unwrap();
    listener.set_read_timeout(Some(PATIENCE)).unwrap();
    let socket_env = socket.to_str().unwrap().to_string();
    // WATCHDOG_USEC = 200 ms: keepalives every 100 ms while the engine makes progress.
    let daemon =
        project.start_with(&[], &[("NOTIFY_SOCKET", &socket_env), ("WATCHDOG_USEC", "200000")]);
    let mut heard: Vec<String> = Vec::new();
    let mut buf = [0u8; 4096];
    while heard.iter().filter(|m| m.as_str() == "WATCHDOG=1").count() < 3
        || !heard.iter().any(|m| m.starts_with("STATUS=RUN"))
    {
        let n = listener.recv(&mut buf).expect("a notification within the patience");
        heard.push(String::from_utf8_lossy(&buf[..n]).to_string());
    }
    assert_eq!(heard[0], "READY=1", "{heard:?}");
    let (code, _) = daemon.stop();
    assert_eq!(code, 0);
    let mut rest = Vec::new();
    listener.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
    while let Ok(n) = listener.recv(&mut buf) {
        rest.push(String::from_utf8_lossy(&buf[..n]).to_string());
    }
    assert!(rest.iter().any(|m| m == "STOPPING=1"), "{rest:?}");
}

#[test]
fn real_time_that_cannot_be_had_is_a_warning_or_with_require_a_refusal() {
    // CPU 1000 does not exist on the test machine: pinning the scan thread there fails, like a
    // missing CAP_SYS_NICE would, on any machine and for any user.
    let config = |require: bool| {
        format!("[rt]\nscan_cpus = [1000]\nrequire = {require}\n[[program]]\nfile = \"main.il\"\n")
    };
    let project = project("rtwarn", &[("plcd.toml", &config(false)), ("main.il", "END\n")]);
    let daemon = project.start();
    let warning = daemon.wait_for("running without full real-time guarantees");
    assert!(
        daemon.lines()[warning].contains("scan thread: sched_setaffinity"),
        "{:?}",
        daemon.lines()
    );
    daemon.wait_for("mode RUN (startup)");
    let (code, _) = daemon.stop();
    assert_eq!(code, 0);

    write(&project, "plcd.toml", &config(true));
    let (code, log) = project.start().finish();
    assert_eq!(code, 1);
    let log = log.join("\n");
    assert!(
        log.contains(
            "real time required by [rt] require = true, but: scan thread: sched_setaffinity"
        ),
        "{log}"
    );
    assert!(!log.contains("mode RUN"), "{log}");
}

#[test]
fn a_looping_stimulus_replays_its_edges() {
    let config = CONVEYOR
        .replace("stimulus = \"inputs.csv\"", "stimulus = \"inputs.csv\"\nstimulus_loop = true");
    let project = conveyor("loop");
    write(&project, "plcd.toml", &config);
    // One pass is 400 ms with three edges; the ninth edge needs a third pass.
    write(&project, "main.il", "LOAD>= D00000 9\nOUT P0042\nEND\n");
    let daemon = project.start();
    daemon.wait_for("P0042 = 1");
    let (code, _) = daemon.stop();
    assert_eq!(code, 0);
}

#[test]
fn sighup_refuses_a_new_control_socket_or_key_switch_and_keeps_running() {
    let project = conveyor("reload-control");
    let daemon = project.start();
    daemon.wait_for("P0040 = 1");
    let config = std::fs::read_to_string(project.config()).unwrap();
    assert!(config.contains("[control]\n"), "{config}");
    for (changed, section) in [
        (config.replacen("[control]\n", "[control]\nmax_clients = 3\n", 1), "[control]"),
        (format!("{config}\n[switch]\nposition = \"stop\"\n"), "[switch]"),
    ] {
        let before = daemon.lines().len();
        std::fs::write(project.config(), &changed).unwrap();
        daemon.signal(Signal::SIGHUP);
        let refused = daemon.wait_for_after(
            before,
            &format!("reload refused: {section} changed, which takes a restart of the service"),
        );
        // The running project goes on: the cycle task still blinks.
        let on = daemon.wait_for_after(refused, "P0040 = 1");
        daemon.wait_for_after(on, "P0040 = 0");
    }
    std::fs::write(project.config(), config).unwrap();
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "log:\n{}", log.join("\n"));
    assert!(!log.iter().any(|l| l.contains("reloaded:")), "{}", log.join("\n"));
}

#[test]
fn a_programs_warnings_reach_the_log_and_it_runs() {
    // CODESYS's implicit conversion that may change a value: accepted with a warning (docs/ST.md
    // "Implicit conversions"), which `plcd run` logs at load, with its place, and runs.
    let project = project(
        "daemon-st-warning",
        &[
            ("plcd.toml", "[plc]\nscan_period_ms = 5\n\n[[program]]\nfile = \"main.st\"\n"),
            (
                "main.st",
                "PROGRAM main\nVAR i : INT := -1; u : UINT; END_VAR\n    u := i;\nEND_PROGRAM\n",
            ),
        ],
    );
    let daemon = project.start();
    let line = daemon.wait_for_line("converted implicitly");
    assert!(line.contains("main.st:3:") && line.contains("INT_TO_UINT"), "{line}");
    daemon.wait_for("mode RUN (startup)");
    let (code, _) = daemon.stop();
    assert_eq!(code, 0);
}
