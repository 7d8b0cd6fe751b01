//! What the control socket drives, in virtual time on the engine itself: forced I/O, the mode
//! rules of XGB §5.2.3 with and without a key switch, a latched error and reset, DEBUG mode
//! (step, breakpoints, continue), the scan-boundary hold and online change.

mod harness;

use plcd::config::SwitchConfig;
use plcd::engine::debug;
use plcd::engine::event::{Event, Mode, Recorder};
use plcd::engine::{online, Activity, Engine, ModeRequest, Refusal};
use plcd::io::SwitchPosition;
use plcd::project::Project;

use harness::engine::{bit, project_of, Field, Plc, MS};

/// A project of `config` and `programs`, with a key switch (`[switch]` as default) or without.
fn project(config: &str, programs: &[(&str, &str)], switch: bool) -> Project {
    let mut config = harness::engine::config(config);
    if switch {
        config.switch = Some(SwitchConfig::default());
    }
    project_of(config, programs)
}

const SCAN: &str = "[[program]]\nfile = \"main.il\"\n";

#[test]
fn forced_inputs_override_the_field_and_forced_outputs_the_program() {
    let main = "LOAD P0000\nOUT P0040\nLOAD _FORCE_IN\nOUT M0000\nLOAD _FORCE_OUT\nOUT M0001\n\
                LOAD _ON\nOUT P0041\nOUT P0042\nEND\n";
    let p = project(SCAN, &[("main.il", main)], false);
    let mut plc = Plc::new(&p);
    plc.field.input("P0000", true);
    plc.engine.set_mode(Mode::Run, 0, &mut plc.field, &mut plc.events);
    plc.run_for(MS);
    assert!(plc.field.output("P0040") && plc.field.output("P0041"));
    assert_eq!((plc.read("M0000"), plc.read("M0001")), (0, 0));

    plc.engine.force(bit("P0000"), false, &plc.field);
    plc.engine.force(bit("P0041"), false, &plc.field);
    plc.run_for(MS);
    assert!(!plc.field.output("P0040"), "the program saw the forced input, not the field");
    assert!(!plc.field.output("P0041"), "the forced output wins over OUT");
    assert!(plc.field.output("P0042"));
    assert_eq!((plc.read("M0000"), plc.read("M0001")), (1, 1), "_FORCE_IN, _FORCE_OUT");
    let listed: Vec<(String, bool)> =
        plc.engine.forces().iter().map(|(a, v)| (a.to_string(), v)).collect();
    assert_eq!(listed, [("P0000".to_string(), false), ("P0041".to_string(), false)]);

    // A forced ON output does not survive the safe state.
    plc.engine.force(bit("P0043"), true, &plc.field);
    plc.run_for(MS);
    assert!(plc.field.output("P0043"));
    plc.engine.set_mode(Mode::Stop, plc.now(), &mut plc.field, &mut plc.events);
    assert!(!plc.field.output("P0043"), "STOP switches every output off, forced or not");
    plc.engine.set_mode(Mode::Run, plc.now(), &mut plc.field, &mut plc.events);
    plc.run_for(MS);
    assert!(plc.field.output("P0043"), "the force applies again in RUN");

    assert!(plc.engine.unforce(bit("P0000")));
    plc.engine.unforce_all();
    plc.run_for(MS);
    assert!(plc.field.output("P0040") && plc.field.output("P0041"));
    assert!(plc.field.output("P0043"), "an output the program does not write keeps the value");
    assert_eq!((plc.read("M0000"), plc.read("M0001")), (0, 0), "flags cleared with the forces");
}

#[test]
fn without_a_switch_remote_mode_changes_are_always_accepted() {
    let p = project(SCAN, &[("main.il", "INC D00000\nEND\n")], false);
    let mut plc = Plc::new(&p);
    assert!(plc.engine.remote_allowed());
    assert_eq!(plc.request(ModeRequest::Run), Ok(()));
    plc.run_for(MS);
    assert_eq!(plc.request(ModeRequest::Stop), Ok(()));
    assert_eq!(plc.engine.mode(), Mode::Stop);
    assert_eq!(plc.modes(), [Mode::Run, Mode::Stop]);
}

#[test]
fn the_key_switch_decides_who_may_change_the_mode() {
    let p = project(SCAN, &[("main.il", "INC D00000\nEND\n")], true);
    let mut plc = Plc::new(&p);
    plc.field.switch = Some(SwitchPosition::Run);
    plc.run_for(MS);
    assert_eq!(plc.engine.mode(), Mode::Run, "switch at RUN at power-up: local RUN");
    assert!(!plc.engine.remote_allowed());
    assert_eq!(plc.request(ModeRequest::Stop), Err(Refusal::SwitchAtRun));
    assert_eq!(plc.request(ModeRequest::Debug), Err(Refusal::SwitchAtRun));
    assert_eq!(plc.request(ModeRequest::Reset { cold: false }), Err(Refusal::SwitchAtRun));
    assert_eq!(plc.engine.mode(), Mode::Run);

    plc.field.switch = Some(SwitchPosition::Stop);
    plc.run_for(MS);
    assert_eq!(plc.engine.mode(), Mode::Stop, "RUN → STOP by the switch stops");
    assert!(plc.engine.remote_allowed(), "switch at STOP: remote enabled");
    assert_eq!(plc.request(ModeRequest::Run), Ok(()), "remote RUN");
    plc.run_for(MS);
    let scans = plc.engine.scan_count();
    let counted = plc.read("D00000");
    assert!(scans > 0);

    // Remote RUN → RUN by the switch: the PLC goes on without interruption.
    plc.field.switch = Some(SwitchPosition::Run);
    plc.run_for(MS);
    assert_eq!(plc.engine.mode(), Mode::Run);
    assert!(plc.engine.scan_count() > scans, "no restart: the scan count goes on");
    assert!(plc.read("D00000") > counted, "and device memory was not cleared");
    assert_eq!(plc.request(ModeRequest::Stop), Err(Refusal::SwitchAtRun));

    plc.field.switch = Some(SwitchPosition::Stop);
    plc.run_for(MS);
    assert_eq!(plc.engine.mode(), Mode::Stop);
    assert_eq!(plc.modes(), [Mode::Run, Mode::Stop, Mode::Run, Mode::Stop]);
}

#[test]
fn a_switch_at_stop_at_power_up_keeps_the_plc_stopped() {
    let p = project(SCAN, &[("main.il", "END\n")], true);
    let mut plc = Plc::new(&p);
    plc.field.switch = Some(SwitchPosition::Stop);
    plc.run_for(10 * MS);
    assert_eq!(plc.engine.mode(), Mode::Stop);
    assert_eq!(plc.engine.switch(), Some(SwitchPosition::Stop));
    assert!(plc.modes().is_empty());
}

#[test]
fn an_error_is_latched_until_reset_and_a_cold_reset_clears_retained_memory() {
    let config = "[plc]\nwatchdog_ms = 10\n[[program]]\nfile = \"main.il\"\n";
    let main = "INC K000\nLABEL 1\nLOAD M0000\nJMP 1\nEND\n";
    let p = project(config, &[("main.il", main)], false);
    let mut plc = Plc::new(&p);
    assert_eq!(plc.request(ModeRequest::Run), Ok(()));
    plc.run_for(MS);
    plc.write("M0000", 1);
    plc.run_for(50 * MS);
    assert_eq!(plc.engine.mode(), Mode::Error, "the endless loop tripped the watchdog");
    assert!(plc.engine.latched_error().is_some());
    assert_eq!(plc.request(ModeRequest::Run), Err(Refusal::ErrorLatched));
    assert_eq!(plc.request(ModeRequest::Debug), Err(Refusal::ErrorLatched));
    let kept = plc.read("K000");
    assert!(kept > 0);

    assert_eq!(plc.request(ModeRequest::Reset { cold: false }), Ok(()));
    assert_eq!(plc.engine.mode(), Mode::Stop);
    assert_eq!(plc.engine.latched_error(), None);
    assert_eq!(plc.read("K000"), kept, "a warm reset keeps K");
    assert_eq!(plc.request(ModeRequest::Reset { cold: true }), Ok(()));
    assert_eq!(plc.read("K000"), 0, "a cold reset clears it");
    assert_eq!(plc.read("_ON"), 1, "system flags stay");
}

const DEBUG_MAIN: &str = "INC D00000\nINC D00001\nEND\n";

fn debug_plc(extra: &str) -> Plc {
    let config = format!("{SCAN}{extra}");
    let p = project(&config, &[("main.il", DEBUG_MAIN), ("tick.il", "INC D00010\nEND\n")], false);
    Plc::new(&p)
}

#[test]
fn debug_runs_one_scan_per_step() {
    let mut plc = debug_plc("");
    assert_eq!(plc.engine.debug_step(0), Err(Refusal::NotInDebug));
    assert_eq!(plc.request(ModeRequest::Debug), Ok(()));
    assert_eq!(plc.engine.mode(), Mode::Debug);
    plc.run_for(10 * MS);
    assert_eq!(plc.engine.scan_count(), 0, "DEBUG starts paused before the first scan");
    for n in 1..=3 {
        plc.engine.debug_step(plc.now()).unwrap();
        plc.run_for(10 * MS);
        assert_eq!(plc.engine.scan_count(), n);
        assert_eq!((plc.read("D00000"), plc.read("D00001")), (n as i32, n as i32));
    }
}

#[test]
fn a_breakpoint_stops_before_its_instruction() {
    let mut plc = debug_plc("");
    let at = debug::resolve(plc.engine.programs(), "main:2").unwrap()[0];
    plc.engine.debugger_mut().add(at).unwrap();
    plc.request(ModeRequest::Debug).unwrap();
    plc.engine.debug_continue(plc.now()).unwrap();
    plc.run_for(10 * MS);
    assert_eq!(plc.engine.debugger().paused_at().map(|(_, b)| b), Some(at));
    assert_eq!((plc.read("D00000"), plc.read("D00001")), (1, 0), "line 1 ran, line 2 did not");

    // Paused at a breakpoint far longer than the watchdog: no WDT.
    plc.run_for(5_000 * MS);
    assert_eq!(plc.engine.mode(), Mode::Debug);
    assert_eq!(plc.engine.watchdog_deadline(), None);

    plc.engine.debug_step_scan(plc.now()).unwrap();
    plc.run_for(10 * MS);
    assert_eq!(plc.engine.debugger().paused_at(), None, "step ran to the end of the scan");
    assert_eq!((plc.read("D00000"), plc.read("D00001")), (1, 1));
    assert_eq!(plc.engine.scan_count(), 1);

    plc.engine.debug_continue(plc.now()).unwrap();
    plc.run_for(10 * MS);
    assert_eq!(plc.engine.debugger().paused_at().map(|(_, b)| b), Some(at), "next scan, again");
    assert_eq!((plc.read("D00000"), plc.read("D00001")), (2, 1));

    // RUN from DEBUG goes on from the breakpoint, device memory kept.
    plc.request(ModeRequest::Run).unwrap();
    plc.run_for(MS);
    assert_eq!(plc.engine.mode(), Mode::Run);
    assert!(plc.read("D00001") > 1);
    assert_eq!(plc.read("D00000") - plc.read("D00001"), 0, "line 2 ran after line 1 each scan");
    assert_eq!(plc.modes(), [Mode::Debug, Mode::Run]);
}

/// The line execution is paused before, if paused in a program.
fn paused_line(plc: &Plc) -> Option<u32> {
    let (_, at) = plc.engine.debugger().paused_at()?;
    Some(plc.engine.programs()[at.program as usize].line_of(at.pc as usize))
}

/// `step` until it pauses between scans, the lines it paused at in order.
fn step_through(plc: &mut Plc) -> Vec<u32> {
    let mut lines = Vec::new();
    for _ in 0..100 {
        plc.engine.debug_step(plc.now()).unwrap();
        plc.run_for(MS);
        match paused_line(plc) {
            Some(line) => lines.push(line),
            None => return lines,
        }
    }
    panic!("no end of the scan after 100 steps: {lines:?}");
}

#[test]
fn step_goes_line_by_line_from_a_breakpoint_over_calls() {
    let main = "INC D00000\nCALL 1\nINC D00001\nEND\nSBRT 1\nINC D00002\nRET\n";
    let p = project(SCAN, &[("main.il", main)], false);
    let mut plc = Plc::new(&p);
    let first = debug::resolve(plc.engine.programs(), "main:1").unwrap()[0];
    plc.engine.debugger_mut().add(first).unwrap();
    plc.request(ModeRequest::Debug).unwrap();
    plc.engine.debug_continue(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), Some(1));

    plc.engine.debug_step(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), Some(2));
    assert_eq!(plc.read("D00000"), 1, "line 1 ran");
    plc.engine.debug_step(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), Some(3), "the subroutine was stepped over");
    assert_eq!(plc.read("D00002"), 1, "and it ran");
    assert_eq!(step_through(&mut plc), [4], "END is a line; then the scan ends");
    assert_eq!(plc.engine.scan_count(), 1);
    assert_eq!(plc.read("D00001"), 1);

    // Between scans, step runs a whole scan, stopping at the breakpoint on the way.
    plc.engine.debug_step(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), Some(1));
    // A breakpoint inside the call stops the step over it.
    let inside = debug::resolve(plc.engine.programs(), "main:6").unwrap()[0];
    plc.engine.debugger_mut().add(inside).unwrap();
    assert_eq!(step_through(&mut plc), [2, 6, 7, 3, 4], "in the subroutine, steps go on there");
    assert_eq!(plc.engine.scan_count(), 2);

    // step --scan from a pause inside the program: to the end of the scan.
    plc.engine.debug_step(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), Some(1));
    plc.engine.debug_step_scan(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), Some(6), "a breakpoint still stops it");
    plc.engine.debug_step_scan(plc.now()).unwrap();
    plc.run_for(MS);
    assert_eq!(paused_line(&plc), None);
    assert_eq!(plc.engine.scan_count(), 3);
}

#[test]
fn paused_debug_starts_no_tasks_and_resumes_without_a_burst() {
    let tick = "[[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n[[task]]\nname = \"tick\"\n\
                kind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n";
    let mut plc = debug_plc(tick);
    plc.request(ModeRequest::Debug).unwrap();
    plc.run_for(100 * MS);
    assert_eq!(plc.read("D00010"), 0, "no cycle task while paused");
    let stats = plc.engine.task_stats("tick").unwrap();
    assert_eq!((stats.runs, stats.overruns), (0, 0));
    plc.engine.debug_continue(plc.now()).unwrap();
    plc.run_for(10 * MS);
    let ticks = plc.read("D00010");
    assert!((9..=11).contains(&ticks), "about one per ms after resuming, no catch-up: {ticks}");
    assert_eq!(plc.engine.task_stats("tick").unwrap().overruns, 0);
}

#[test]
fn debug_entered_from_run_pauses_at_the_end_of_the_scan() {
    let mut plc = debug_plc("");
    plc.request(ModeRequest::Run).unwrap();
    plc.run_for(MS);
    plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 1); // inside a scan
    plc.request(ModeRequest::Debug).unwrap();
    plc.run_for(10 * MS);
    assert!(plc.engine.at_scan_boundary());
    assert_eq!(plc.read("D00000"), plc.read("D00001"), "the scan was finished, not cut");
    let scans = plc.engine.scan_count();
    plc.run_for(10 * MS);
    assert_eq!(plc.engine.scan_count(), scans);
}

#[test]
fn hold_at_end_hands_back_at_the_scan_boundary() {
    let p = project(SCAN, &[("main.il", &"INC D00000\n".repeat(50).add_end())], false);
    let mut plc = Plc::new(&p);
    plc.request(ModeRequest::Run).unwrap();
    plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 10);
    assert!(!plc.engine.at_scan_boundary(), "in the middle of a scan");
    plc.engine.set_hold_at_end(true);
    let activity = plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 1000);
    assert_eq!(activity, Activity::Busy);
    assert!(plc.engine.at_scan_boundary());
    assert_eq!(plc.read("D00000"), 50, "exactly one whole scan");
    plc.engine.set_hold_at_end(false);
}

trait AddEnd {
    fn add_end(self) -> String;
}

impl AddEnd for String {
    fn add_end(self) -> String {
        self + "END\n"
    }
}

#[test]
fn online_change_keeps_memory_and_fires_no_edge() {
    let old_main = "LOADP P0000\nINC D00001\nLOAD M0000\nOUTP M0001\nINC D00000\nEND\n";
    let new_main = "LOADP P0000\nINC D00001\nLOAD M0000\nOUTP M0001\nINC D00000\nINC D00002\nEND\n";
    let old = project(SCAN, &[("main.il", old_main)], false);
    let new = project(SCAN, &[("main.il", new_main)], false);
    let mut plc = Plc::new(&old);
    plc.field.input("P0000", true);
    plc.request(ModeRequest::Run).unwrap();
    plc.write("M0000", 1);
    plc.run_for(MS);
    let scans = plc.engine.scan_count();
    let counted = plc.read("D00000");
    assert_eq!(plc.read("D00001"), 1, "one rising edge of P0000");

    let change = online::prepare(&old, &new, &[]).expect("compatible");
    plc.engine.set_hold_at_end(true);
    plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 1000);
    assert!(plc.engine.at_scan_boundary());
    let online::OnlineChange { mut engine, edges } = change;
    engine.take_over(&mut plc.engine, &edges).unwrap();
    plc.engine = *engine;
    plc.run_for(MS);

    assert_eq!(plc.engine.mode(), Mode::Run);
    assert!(plc.engine.scan_count() > scans, "the scan count goes on");
    assert!(plc.read("D00000") > counted, "device memory kept");
    assert!(plc.read("D00002") > 0, "the new instruction runs");
    assert_eq!(plc.read("D00001"), 1, "LOADP of a held input did not fire again");
    assert_eq!(plc.read("M0001"), 0, "OUTP of a held rung did not pulse again");
    plc.field.input("P0000", false);
    plc.run_for(MS);
    plc.field.input("P0000", true);
    plc.run_for(MS);
    assert_eq!(plc.read("D00001"), 2, "a real edge after the change still counts");
}

#[test]
fn an_incompatible_online_change_is_refused_with_reasons() {
    let task = |interval: u32, name: &str| {
        format!(
            "{SCAN}[[program]]\nfile = \"tick.il\"\ntask = \"{name}\"\n[[task]]\nname = \"{name}\"\n\
             kind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = {interval}\n"
        )
    };
    let programs = [("main.il", "END\n"), ("tick.il", "END\n")];
    let old = project(&task(10, "tick"), &programs, false);
    let slower = project(&task(20, "tick"), &programs, false);
    let renamed = project(&task(10, "tock"), &programs, false);
    let reasons = |new: &Project| online::prepare(&old, new, &[]).err().unwrap();
    assert_eq!(
        reasons(&slower),
        ["task \"tick\" changed (its start condition); tasks can only \
                                   change with the PLC in STOP"]
    );
    assert_eq!(reasons(&renamed), ["task \"tick\" is removed", "task \"tock\" is added"]);
    let mut watchdog = old.clone();
    watchdog.config.plc.watchdog_ms = 50;
    assert_eq!(reasons(&watchdog), ["[plc] changed; it can only change with the PLC in STOP"]);
}

#[test]
fn plcd_sim_follows_the_simulated_key_switch() {
    use plcd::stimulus::{Stimulus, Target};
    let config =
        "[io]\nbackend = \"sim\"\n[switch]\nposition = \"stop\"\n[[program]]\nfile = \"main.il\"\n";
    let p = project(config, &[("main.il", "INC D00000\nEND\n")], false);
    let switch = |ms: u64, position| Stimulus {
        t_ns: ms * MS,
        target: Target::Switch(position),
        value: 0,
        line: 1,
    };
    // In STOP the inputs (and the switch) are read every 10 ms, in RUN at every scan.
    let stimuli = [switch(5, SwitchPosition::Run), switch(15, SwitchPosition::Stop)];
    let (engine, events) = harness::engine::sim(&p, &stimuli, &[], 20 * MS);
    let seen: Vec<(u64, Event)> = events
        .0
        .into_iter()
        .filter(|(_, e)| matches!(e, Event::Mode(_) | Event::Switch(_)))
        .map(|(t, e)| (t / MS, e))
        .collect();
    assert_eq!(
        seen,
        [
            (0, Event::Switch(SwitchPosition::Stop)),
            (10, Event::Switch(SwitchPosition::Run)),
            (10, Event::Mode(Mode::Run)),
            (15, Event::Switch(SwitchPosition::Stop)),
            (15, Event::Mode(Mode::Stop)),
        ]
    );
    assert_eq!(engine.mode(), Mode::Stop);
}

#[test]
fn a_fixed_scan_period_keeps_its_grid_when_a_scan_starts_late() {
    // The driver notices the scan time 80 µs late (its wake-up latency): the next scan is still
    // due on the 10 ms grid, not 10 ms after the late start.
    let p = project(
        "[plc]\nscan_period_ms = 10\n[[program]]\nfile = \"main.il\"\n",
        &[("main.il", "END\n")],
        false,
    );
    let mut engine = Engine::new::<plcd::device::Address>(&p, &[]);
    let mut field = Field::default();
    let mut events = Recorder::default();
    let clock = plcd::vm::ManualClock::new(0);
    engine.set_mode(Mode::Run, 0, &mut field, &mut events);
    engine.run(&clock, &mut field, &mut events, 100);
    assert_eq!(engine.next_wakeup(0), Some(10 * MS));
    clock.set(10 * MS + 80_000);
    engine.run(&clock, &mut field, &mut events, 100);
    assert_eq!(engine.scan_count(), 2);
    assert_eq!(engine.next_wakeup(10 * MS + 80_000), Some(20 * MS), "on the grid");
    // A scan (here: its driver) 25 ms late skips the grid points it missed.
    clock.set(45 * MS);
    engine.run(&clock, &mut field, &mut events, 100);
    assert_eq!(engine.next_wakeup(45 * MS), Some(50 * MS));
}

#[test]
fn deadlines_noticed_a_full_interval_late_are_counted_as_missed() {
    // A 1 ms cycle task; the driver looks at the clock late: 0.9 ms after the 1 ms deadline
    // (not missed), then at 5.5 ms (the deadlines of 2, 3, 4 and 5 ms passed, three of them a
    // full interval or more before it looked).
    let p = project(
        "[plc]\nscan_period_ms = 10\n[[program]]\nfile = \"main.il\"\n\
         [[program]]\nname = \"tick\"\nfile = \"tick.il\"\ntask = \"tick\"\n\
         [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 2\ninterval_ms = 1\n",
        &[("main.il", "END\n"), ("tick.il", "INC D00000\nEND\n")],
        false,
    );
    let mut engine = Engine::new::<plcd::device::Address>(&p, &[]);
    let mut field = Field::default();
    let mut events = Recorder::default();
    let clock = plcd::vm::ManualClock::new(0);
    engine.set_mode(Mode::Run, 0, &mut field, &mut events);
    engine.run(&clock, &mut field, &mut events, 100);
    for now in [MS + 900_000, 5 * MS + 500_000] {
        clock.set(now);
        engine.poll_time(now, &mut field, &mut events);
        engine.run(&clock, &mut field, &mut events, 100);
    }
    assert_eq!(engine.missed_deadlines(), 3, "the deadlines of 2, 3 and 4 ms");
    let stats = engine.task_stats("tick").unwrap();
    assert_eq!(stats.runs, 2);
    // How late the driver looked is the notice latency: 0.9 ms for the 1 ms deadline, 3.5 ms for
    // the 2 ms one (3, 4 and 5 ms found it waiting). The clock stood still while the engine
    // dispatched, so the start latency is the notice latency.
    let noticed = stats.notice_latency.summary();
    assert_eq!((noticed.count, noticed.min, noticed.max), (2, 900_000, 3_500_000), "{noticed:?}");
    assert_eq!(stats.start_latency.summary(), noticed);
    // RUN starts the count again.
    engine.set_mode(Mode::Stop, 6 * MS, &mut field, &mut events);
    engine.set_mode(Mode::Run, 6 * MS, &mut field, &mut events);
    assert_eq!(engine.missed_deadlines(), 0);
}
