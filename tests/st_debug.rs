//! DEBUG mode on Structured Text, in virtual time on the engine: breakpoints at `FILE:LINE`
//! (in every program that runs the file's code) and at `PROGRAM:LINE`, and `step` going
//! statement by statement — through loops and branches, over calls, into the next program of
//! the task, and out of a function it paused in. The expected lines were worked out by hand
//! from the sources below.

mod harness;

use harness::engine::{project, Plc, MS};
use plcd::engine::debug::{self, BreakError};
use plcd::engine::event::Mode;
use plcd::engine::ModeRequest;

const CONFIG: &str = r#"
[st]
library = ["lib.st"]
[[program]]
name = "main"
file = "main.st"
[[program]]
name = "other"
file = "other.st"
"#;

const LIB: &str = "\
FUNCTION Twice : INT
VAR_INPUT x : INT; END_VAR
Twice := x * 2;
END_FUNCTION
";

const MAIN: &str = "\
PROGRAM Main
VAR
  i : INT;
  total AT %D00000 : INT;
  big AT %M0000 : BOOL;
END_VAR
total := 0;
FOR i := 1 TO 2 DO
  total := total + Twice(i);
END_FOR;
IF total > 5 THEN
  big := TRUE;
ELSIF total > 2 THEN
  big := FALSE;
END_IF;
END_PROGRAM
";

const OTHER: &str = "\
PROGRAM Other
VAR x AT %D00010 : INT; END_VAR
x := Twice(3);
END_PROGRAM
";

fn plc() -> Plc {
    let p = project(CONFIG, &[("lib.st", LIB), ("main.st", MAIN), ("other.st", OTHER)]);
    Plc::new(&p)
}

/// Where execution waits, as a breakpoint is written (`main.st:8`), if inside a program.
fn paused(plc: &Plc) -> Option<String> {
    let (_, at) = plc.engine.debugger().paused_at()?;
    Some(debug::describe(plc.engine.programs(), at))
}

fn break_at(plc: &mut Plc, text: &str) {
    for at in debug::resolve(plc.engine.programs(), text).unwrap() {
        plc.engine.debugger_mut().add(at).unwrap();
    }
}

fn step(plc: &mut Plc) -> Option<String> {
    plc.engine.debug_step(plc.now()).unwrap();
    plc.run_for(MS);
    paused(plc)
}

/// `step` until the scan ends, every place it paused at.
fn step_through(plc: &mut Plc) -> Vec<String> {
    let mut places = Vec::new();
    while let Some(at) = step(plc) {
        places.push(at);
        assert!(places.len() < 100, "no end of the scan: {places:?}");
    }
    places
}

fn continue_(plc: &mut Plc) -> Option<String> {
    plc.engine.debug_continue(plc.now()).unwrap();
    plc.run_for(MS);
    paused(plc)
}

#[test]
fn step_goes_statement_by_statement_through_loops_branches_and_programs() {
    let mut plc = plc();
    break_at(&mut plc, "main.st:7");
    plc.request(ModeRequest::Debug).unwrap();
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:7"));
    let places = step_through(&mut plc);
    assert_eq!(
        places,
        [
            "main.st:8",  // FOR: i := 1, the first test
            "main.st:9",  // the body, Twice stepped over
            "main.st:8",  // the increment and test
            "main.st:9",  // i = 2
            "main.st:8",  // past the bound
            "main.st:11", // IF total > 5 (total = 6)
            "main.st:12", // THEN; ELSIF is not looked at
            "main.st:16", // END_PROGRAM
            "other.st:3", // the next program of the scan task
            "other.st:4",
        ]
    );
    assert_eq!(plc.engine.scan_count(), 1, "the last step ended the scan");
    assert_eq!((plc.read("D00000"), plc.read("M0000"), plc.read("D00010")), (6, 1, 6));
}

#[test]
fn a_line_of_a_library_file_breaks_in_every_program_that_runs_it() {
    let mut plc = plc();
    let places = debug::resolve(plc.engine.programs(), "lib.st:3").unwrap();
    assert_eq!(places.len(), 2, "Twice is compiled into main and other: {places:?}");
    break_at(&mut plc, "lib.st:3");
    plc.request(ModeRequest::Debug).unwrap();
    assert_eq!(continue_(&mut plc).as_deref(), Some("lib.st:3"));
    let (_, at) = plc.engine.debugger().paused_at().unwrap();
    assert_eq!(plc.engine.programs()[at.program as usize].name, "main");
    // Out of the function: END_FUNCTION, then the caller's next statement.
    assert_eq!(step(&mut plc).as_deref(), Some("lib.st:4"));
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:8"));
    assert_eq!(plc.read("D00000"), 2, "Twice(1) was added");
    // The second call in main, then the call in other.
    assert_eq!(continue_(&mut plc).as_deref(), Some("lib.st:3"));
    assert_eq!(plc.read("D00000"), 2);
    assert_eq!(continue_(&mut plc).as_deref(), Some("lib.st:3"));
    let (_, at) = plc.engine.debugger().paused_at().unwrap();
    assert_eq!(plc.engine.programs()[at.program as usize].name, "other");
    assert_eq!(plc.read("D00000"), 6, "main finished its scan first");

    // Both places go with one unbreak, and RUN goes on from the pause.
    for at in debug::resolve(plc.engine.programs(), "lib.st:3").unwrap() {
        assert!(plc.engine.debugger_mut().remove(at));
    }
    assert!(plc.engine.debugger().breakpoints().is_empty());
    plc.request(ModeRequest::Run).unwrap();
    plc.run_for(50 * MS);
    assert_eq!(plc.engine.mode(), Mode::Run);
    assert!(plc.engine.scan_count() > 2);
}

#[test]
fn program_lines_and_what_names_no_statement() {
    let plc = plc();
    let programs = plc.engine.programs();
    let at = |text: &str| debug::resolve(programs, text).map(|b| debug::describe(programs, b[0]));
    assert_eq!(at("main:9"), Ok("main.st:9".into()), "PROGRAM:LINE, a line of its own file");
    assert!(at("MAIN.st:9").is_err(), "file names are as the file system spells them");
    assert_eq!(at("other:3"), Ok("other.st:3".into()));
    assert_eq!(
        at("main.st:3"),
        Err(BreakError::NoInstruction { program: "main.st".into(), line: 3 }),
        "a declaration"
    );
    assert_eq!(
        at("main:10"),
        Err(BreakError::NoInstruction { program: "main".into(), line: 10 }),
        "END_FOR has no code of its own"
    );
    assert_eq!(
        at("lib.st:1"),
        Err(BreakError::NoInstruction { program: "lib.st".into(), line: 1 }),
        "a FUNCTION header"
    );
    assert!(at("lib.st:LABEL 3").is_err(), "labels are the instruction list's");
    assert_eq!(at("3"), Ok("other.st:3".into()), "only other has code at its own line 3");
}

#[test]
fn step_from_between_scans_runs_a_scan_and_step_scan_leaves_the_line() {
    let mut plc = plc();
    plc.request(ModeRequest::Debug).unwrap();
    assert_eq!(step(&mut plc), None, "no breakpoint: one whole scan");
    assert_eq!(plc.engine.scan_count(), 1);
    break_at(&mut plc, "main.st:11");
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:11"));
    plc.engine.debug_step_scan(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused(&plc), None);
    assert_eq!(plc.engine.scan_count(), 2);
}

/// The same through the daemon: `plcctl break FILE:LINE`, `step`, and the debugger's state
/// naming the file, the program and the source line.
#[test]
fn plcctl_breaks_at_a_file_line_and_steps_by_statement() {
    use harness::daemon::Project;
    let config = format!("{CONFIG}[control]\nsocket = \"plcd.sock\"\n");
    let project = Project::new(
        "st-debug",
        &[("plcd.toml", &config), ("lib.st", LIB), ("main.st", MAIN), ("other.st", OTHER)],
    );
    let daemon = project.start();
    daemon.wait_for("control socket");
    let ok = |args: &[&str]| {
        let out = project.plcctl(args);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        assert_eq!(out.status.code(), Some(0), "plcctl {args:?}: {text}{:?}", out.stderr);
        text
    };
    let json = |args: &[&str]| -> serde_json::Value {
        let mut all = vec!["--json"];
        all.extend_from_slice(args);
        serde_json::from_str(&ok(&all)).unwrap()
    };
    ok(&["debug"]);
    let set = json(&["break", "lib.st:3"]);
    assert_eq!(set["breakpoints"], serde_json::json!(["lib.st:3"]), "one text for two places");
    let refused = project.plcctl(&["break", "main.st:2"]);
    assert_eq!(refused.status.code(), Some(1));
    let why = String::from_utf8_lossy(&refused.stderr);
    assert!(why.contains("main.st:2 has no statement"), "{why}");

    ok(&["continue"]);
    daemon.wait("paused in Twice", || json(&["status"])["debug"]["paused_at"]["file"] == "lib.st");
    let at = &json(&["status"])["debug"]["paused_at"];
    assert_eq!((at["program"].as_str(), at["line"].as_u64()), (Some("main"), Some(3)));
    assert_eq!(at["source"], "Twice := x * 2;");
    let human = ok(&["step"]);
    assert!(human.starts_with("paused at lib.st:4 in program main, task scan"), "{human}");
    let next = json(&["step"]);
    assert_eq!(
        (next["paused_at"]["file"].as_str(), next["paused_at"]["line"].as_u64()),
        (Some("main.st"), Some(8))
    );
    assert_eq!(next["paused_at"]["source"], "FOR i := 1 TO 2 DO");
    ok(&["unbreak", "lib.st:3"]);
    assert_eq!(json(&["status"])["debug"]["breakpoints"], serde_json::json!([]));
    let done = json(&["step", "--scan"]);
    assert!(done.get("paused_at").is_none(), "{done}");
    ok(&["run"]);
    let (code, _) = daemon.stop();
    assert_eq!(code, 0);
}

#[test]
fn a_breakpoint_in_an_action_pauses_there_and_steps_back_to_the_caller() {
    let main = "\
PROGRAM Main
VAR n AT %D00000 : INT; END_VAR
n := n + 1;
Bump();
n := n + 10;
ACTION Bump:
  n := n * 2;
END_ACTION
END_PROGRAM
";
    let config = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n";
    let mut plc = Plc::new(&project(config, &[("main.st", main)]));
    break_at(&mut plc, "main.st:7");
    plc.request(ModeRequest::Debug).unwrap();
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:7"));
    assert_eq!(plc.read("D00000"), 1, "paused before the action's statement");
    // END_ACTION, then the caller's next statement
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:8"));
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:5"));
    assert_eq!(plc.read("D00000"), 2);
}

#[test]
fn a_program_instance_arguments_are_statements_on_their_lines() {
    // A configuration's instance: its input is given before the body, its output copied
    // after it, each a statement on its argument's line.
    let configured = "\
PROGRAM Counter
VAR_INPUT step : INT; END_VAR
VAR_OUTPUT total : INT; END_VAR
total := total + step;
END_PROGRAM

CONFIGURATION c
  VAR_GLOBAL out AT %D00020 : INT; END_VAR
  PROGRAM main : Counter (step := 3,
                          total => out);
END_CONFIGURATION
";
    let p = project("[[program]]\nfile = \"plc.st\"\n", &[("plc.st", configured)]);
    let mut plc = Plc::new(&p);
    break_at(&mut plc, "plc.st:9");
    plc.request(ModeRequest::Debug).unwrap();
    assert_eq!(continue_(&mut plc).as_deref(), Some("plc.st:9"));
    assert_eq!(plc.read("D00020"), 0);
    assert_eq!(step_through(&mut plc), ["plc.st:4", "plc.st:10", "plc.st:5"]);
    assert_eq!(plc.read("D00020"), 3, "the output copied out after the body");
}

/// A one-program project of `main.st`, in DEBUG, with a breakpoint at each of `lines`.
fn debugging(main: &str, lines: &[&str]) -> Plc {
    let config = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n";
    let mut plc = Plc::new(&project(config, &[("main.st", main)]));
    for line in lines {
        break_at(&mut plc, line);
    }
    plc.request(ModeRequest::Debug).unwrap();
    plc
}

/// A METHOD's line is a breakpoint, whether the method is called on the instance or through an
/// interface; `step` goes on inside it, then back to the caller's next statement. A `step` on
/// the calling line steps over the call.
const METHODS: &str = "\
INTERFACE ICount
METHOD Add : INT
VAR_INPUT delta : INT; END_VAR
END_METHOD
END_INTERFACE
FUNCTION_BLOCK Counter IMPLEMENTS ICount
VAR n : INT; END_VAR
METHOD Add : INT
VAR_INPUT delta : INT; END_VAR
VAR_INST calls : INT; END_VAR
  calls := calls + 1;
  n := n + delta;
  Add := n;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR c : Counter; i : ICount; total AT %D00000 : INT; END_VAR
  i := c;
  total := c.Add(1);
  total := i.Add(10);
  total := total + 100;
END_PROGRAM
";

#[test]
fn a_breakpoint_in_a_method_pauses_there_called_directly_and_through_an_interface() {
    let mut plc = debugging(METHODS, &["main.st:12"]);
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:12"));
    assert_eq!(plc.read("D00000"), 0, "c.Add(1): paused before n := n + by");
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:13"));
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:14"), "END_METHOD, the return");
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:20"), "the caller's next statement");
    assert_eq!(plc.read("D00000"), 1);
    // The call through the interface stops at the same line of the same method.
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:12"));
    assert_eq!(plc.read("D00000"), 1);
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:13"));
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:14"));
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:21"));
    assert_eq!(plc.read("D00000"), 11);
}

#[test]
fn step_over_a_method_call_runs_the_method_whole() {
    let mut plc = debugging(METHODS, &["main.st:19"]);
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:19"));
    assert_eq!(step_through(&mut plc), ["main.st:20", "main.st:21", "main.st:22"]);
    assert_eq!(plc.read("D00000"), 111);
}

/// A chart's elements are code of the POU: an action associated with a step stops at its
/// line when the step makes it run, a transition's condition at its TRANSITION line when it
/// is evaluated (only while its step is active).
const CHART: &str = "\
PROGRAM Main
VAR go AT %M0000 : BOOL; n AT %D00000 : INT; END_VAR
  INITIAL_STEP Idle:
  END_STEP
  STEP Fill:
    Bump(N);
  END_STEP
  TRANSITION FROM Idle TO Fill := go;
  END_TRANSITION
  TRANSITION FROM Fill TO Idle := n >= 3;
  END_TRANSITION
  ACTION Bump:
    n := n + 1;
  END_ACTION
END_PROGRAM
";

#[test]
fn a_breakpoint_in_an_sfc_action_pauses_only_while_its_step_is_active() {
    let mut plc = debugging(CHART, &["main.st:13"]);
    plc.engine.debug_step_scan(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused(&plc), None, "Idle: Bump does not run");
    plc.write("M0000", 1);
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:13"), "Fill entered: Bump runs");
    assert_eq!(plc.read("D00000"), 0);
    assert_eq!(step(&mut plc).as_deref(), Some("main.st:14"), "END_ACTION");
    plc.engine.debug_step_scan(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(plc.read("D00000"), 1);
}

#[test]
fn a_breakpoint_at_a_transition_pauses_at_every_evolution_and_steps_through_the_chart() {
    // The TRANSITION line's code tests its preceding steps, then its condition: a breakpoint
    // there stops at every evolution, the step active or not. From there `step` goes through
    // the evolution: the steps left and entered, the associations (Bump, stepped over), the
    // return.
    let mut plc = debugging(CHART, &["main.st:10"]);
    plc.write("M0000", 1);
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:10"));
    assert_eq!(plc.engine.scan_count(), 1, "the first evolution, Fill not active yet");
    assert_eq!(step_through(&mut plc), ["main.st:3", "main.st:5", "main.st:6", "main.st:15"]);
    assert_eq!(plc.read("D00000"), 1, "Fill entered, Bump ran once");
    assert_eq!(continue_(&mut plc).as_deref(), Some("main.st:10"));
    assert_eq!(plc.engine.scan_count(), 2, "the second evolution");
}
