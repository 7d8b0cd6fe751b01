//! Retained Structured Text variables through the real `plcd run` (docs/RETAIN.md): written to
//! the retain files with the retained devices, restored after `kill -9`, kept by a reload and
//! by a restart with a changed program when their name and type are unchanged (the others
//! logged), cleared by `plcctl reset --cold` and by `restart = "cold"`.
//!
//! As in tests/retain_daemon.rs, what the writer acknowledged is the newest intact generation
//! file; every wait is for an event (a generation, a log line), bounded by a generous patience.

mod harness;

use nix::sys::signal::Signal;
use plcd::services::retain::{newest_in, Generation};

use harness::daemon::{Daemon, Project};

const LOG: &str = "plcd.log";

fn config(restart: &str) -> String {
    format!(
        "[plc]\nscan_period_ms = 1\n\n[rt]\npolicy = \"other\"\nlock_memory = false\n\n\
         [control]\nsocket = \"plcd.sock\"\n\n[retain]\ndir = \"retain\"\ninterval_ms = 10\n\
         restart = \"{restart}\"\n\n[[program]]\nname = \"main\"\nfile = \"main.st\"\n"
    )
}

/// `runs` counts RUN starts (`started` is not retained: FALSE again at each), `scans` every
/// scan; both retained.
const COUNTING: &str = "PROGRAM Main
VAR RETAIN runs : DINT; scans : DINT; END_VAR
VAR started : BOOL; END_VAR
    IF NOT started THEN runs := runs + 1; started := TRUE; END_IF;
    scans := scans + 1;
END_PROGRAM
";

struct St(Project);

impl St {
    fn new(name: &str) -> St {
        let project = Project::new(&format!("retain-st-{name}"), &[]);
        project.write("plcd.toml", &config("warm"));
        project.write("main.st", COUNTING);
        St(project)
    }

    fn start(&self) -> Daemon {
        self.0.start_logging_to(LOG)
    }

    fn log(&self) -> String {
        harness::log::Log::File(self.0.path(LOG)).text()
    }

    fn newest(&self) -> Option<Generation> {
        newest_in(&self.0.path("retain"))
    }

    fn wait_for_generation(&self, what: &str, done: impl Fn(&Generation) -> bool) -> Generation {
        harness::log::wait_for_generation(&self.0.path("retain"), || self.log(), what, done)
    }

    fn plcctl(&self, args: &[&str]) {
        let out = self.0.plcctl(args);
        assert!(out.status.success(), "plcctl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

/// The DINT variable `name` of a generation, if it holds one.
fn value(g: &Generation, name: &str) -> Option<i32> {
    let v = g.variables.iter().find(|v| v.name == name)?;
    assert_eq!(v.ty, "DINT", "{name}");
    Some(i32::from_le_bytes(v.bytes[..].try_into().unwrap()))
}

fn runs(g: &Generation) -> i32 {
    value(g, "main.runs").expect("main.runs saved")
}

#[test]
fn kill_9_restores_them_and_reset_cold_clears_them() {
    let project = St::new("kill9");
    let daemon = project.start();
    project.wait_for_generation("a first RUN that counted", |g| {
        runs(g) == 1 && value(g, "main.scans") > Some(20)
    });
    daemon.kill9();
    let acked = project.newest().unwrap();
    let scans = value(&acked, "main.scans").unwrap();
    assert_eq!((acked.version, runs(&acked)), (4, 1));

    let daemon = project.start();
    let g = project.wait_for_generation("the second RUN start", |g| g.seq > acked.seq);
    assert_eq!(runs(&g), 2, "restored, then counted the RUN start");
    assert!(value(&g, "main.scans").unwrap() > scans, "counted on from {scans}");
    daemon.wait_for("retain: restored generation");
    assert!(project.log().contains("2 variables)"), "{}", project.log());

    project.plcctl(&["reset", "--cold"]);
    project.wait_for_generation("the initial values", |g| {
        (runs(g), value(g, "main.scans")) == (0, Some(0))
    });
    project.plcctl(&["run"]);
    project.wait_for_generation("RUN again from the initial values", |g| runs(g) == 1);
    assert_eq!(daemon.stop().0, 0);
    let log = project.log();
    assert!(!log.contains("not restored"), "{log}");
}

#[test]
fn a_changed_program_keeps_those_of_unchanged_name_and_type() {
    let project = St::new("changed");
    let daemon = project.start();
    project.wait_for_generation("a first RUN", |g| runs(g) == 1);

    // A reload with another program: `runs` is kept (and counts the reload's RUN start).
    project.0.write("main.st", &COUNTING.replace("scans := scans + 1;", "scans := scans + 2;"));
    daemon.signal(Signal::SIGHUP);
    daemon.wait_for("reloaded:");
    project.wait_for_generation("the reload's RUN start", |g| runs(g) == 2);
    assert_eq!(daemon.stop().0, 0);

    // A restart with `scans` renamed, a new variable, and `runs` unchanged.
    let changed = COUNTING
        .replace("scans : DINT;", "parts : DINT; fresh : INT := 7;")
        .replace("scans := scans + 1;", "parts := parts + 1;");
    project.0.write("main.st", &changed);
    let daemon = project.start();
    let g = project.wait_for_generation("the changed program's RUN start", |g| runs(g) == 3);
    assert!(value(&g, "main.scans").is_none(), "a variable of the old program only");
    assert!(value(&g, "main.parts").is_some());
    daemon.wait_for("start from their initial values");
    assert_eq!(daemon.stop().0, 0);
    let log = project.log();
    assert!(
        log.contains(
            "1 saved variable(s) not restored, the program no longer retains them with that \
             name and type: main.scans (DINT): not a RETAIN variable of the program"
        ),
        "{log}"
    );
    assert!(
        log.contains(
            "2 RETAIN variable(s) not in the file start from their initial values: \
                      main.parts, main.fresh"
        ),
        "{log}"
    );

    // restart = "cold": everything from its initial value.
    project.0.write("plcd.toml", &config("cold"));
    let seq = project.newest().unwrap().seq;
    let daemon = project.start();
    // A write may come before the first scan (the initial values, where a start is slow): the
    // first one with the RUN start counted is the one to judge.
    let g = project.wait_for_generation("the cold start's RUN", |g| g.seq > seq && runs(g) != 0);
    assert_eq!(runs(&g), 1, "cold: from the initial value");
    assert_eq!(daemon.stop().0, 0);
}
