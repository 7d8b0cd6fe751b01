//! Structured Text on the engine, in virtual time: in every kind of task, preempted between two
//! VM steps like the instruction list (an io task's latency does not depend on the length of an
//! ST scan), an endless loop tripping the scan watchdog, IL and ST sharing devices, watches of
//! variables by name, and an online change keeping the variables it can.

mod harness;

use harness::engine::{project, sim, sim_watching, MS, STEP_NS};
use plcd::engine::event::{ErrorKind, Event, Mode};
use plcd::project::Watched;
use plcd::stimulus::{Stimulus, Target};

fn input(t_ns: u64, dev: &str, value: i32) -> Stimulus {
    Stimulus {
        t_ns,
        target: Target::Device(plcd::device::Address::parse(dev).unwrap()),
        value,
        line: 1,
    }
}

const TASKS: &str = r#"
[plc]
scan_period_ms = 10
[[program]]
name = "boot"
file = "boot.st"
task = "init"
[[program]]
name = "main"
file = "main.st"
[[program]]
name = "il"
file = "il.il"
[[program]]
name = "fast"
file = "fast.st"
task = "fast"
[[program]]
name = "edge"
file = "edge.st"
task = "edge"
[[program]]
name = "dev"
file = "dev.st"
task = "dev"
[[task]]
name = "fast"
kind = "cycle"
number = 0
priority = 3
interval_ms = 5
[[task]]
name = "edge"
kind = "io"
number = 8
priority = 2
contact = "P0000"
edge = "rising"
[[task]]
name = "dev"
kind = "device"
number = 16
priority = 4
device = "M0000"
condition = "rising"
"#;

/// Each program counts its runs into a device the others can see.
fn tasks_project() -> plcd::project::Project {
    project(
        TASKS,
        &[
            (
                "boot.st",
                "PROGRAM Boot VAR n AT %D00001 : INT; END_VAR n := n + 1; INIT_DONE(); END_PROGRAM",
            ),
            (
                "main.st",
                "PROGRAM Main VAR scans AT %D00002 : DINT; i : INT; acc : DINT; go AT %M0000 : BOOL; END_VAR
                   scans := scans + 1;
                   FOR i := 1 TO 200 DO acc := acc + i; END_FOR;
                   go := (scans MOD 4) = 0;
                 END_PROGRAM",
            ),
            ("il.il", "LOAD _ON\nINC D00010\nEND\n"),
            ("fast.st", "PROGRAM Fast VAR n AT %D00004 : INT; END_VAR n := n + 1; END_PROGRAM"),
            ("edge.st", "PROGRAM Edge VAR n AT %D00005 : INT; END_VAR n := n + 1; END_PROGRAM"),
            ("dev.st", "PROGRAM Dev VAR n AT %D00006 : INT; END_VAR n := n + 1; END_PROGRAM"),
        ],
    )
}

#[test]
fn st_programs_run_in_every_kind_of_task_beside_il() {
    let project = tasks_project();
    let stimuli = [input(12 * MS, "P0000", 1), input(13 * MS, "P0000", 0)];
    let (engine, events) = sim(&project, &stimuli, &[], 100 * MS);
    let read = |dev: &str| engine.vm().mem.read(&plcd::device::Address::parse(dev).unwrap());
    assert_eq!(read("D00001"), 1, "init ran once, then INIT_DONE");
    let scans = engine.scan_stats().count as i32;
    assert!(scans >= 9, "{scans} scans");
    assert_eq!(read("D00002"), scans - 1, "the init scan is not a scan of main");
    assert_eq!(read("D00010"), scans - 1, "IL shares the scan");
    assert!(read("D00004") >= 19, "the 5 ms cycle task: {}", read("D00004"));
    assert_eq!(read("D00005"), 1, "one rising edge of P0000");
    assert_eq!(read("D00006"), (scans - 1) / 4, "M0000 rises every 4th scan");
    assert!(!events.0.iter().any(|(_, e)| matches!(e, Event::Error(_))), "{:?}", events.0);
}

#[test]
fn an_io_task_preempts_a_long_st_scan_within_one_step() {
    let project = project(
        r#"
[[program]]
file = "main.st"
[[program]]
name = "edge"
file = "edge.st"
task = "edge"
[[task]]
name = "edge"
kind = "io"
number = 8
priority = 2
contact = "P0000"
edge = "rising"
"#,
        &[
            (
                "main.st",
                "PROGRAM Main VAR i : DINT; acc : DINT; END_VAR
                   FOR i := 1 TO 20000 DO acc := acc + i; END_FOR;
                 END_PROGRAM",
            ),
            ("edge.st", "PROGRAM Edge VAR n AT %D00005 : INT; END_VAR n := n + 1; END_PROGRAM"),
        ],
    );
    // The edge comes in the middle of a scan many ms long.
    let at = 7 * MS + 300;
    let (_, events) = sim(&project, &[input(at, "P0000", 1)], &[], 50 * MS);
    let start = events
        .0
        .iter()
        .find(|(_, e)| matches!(e, Event::TaskStart { task } if *task > 1))
        .map(|(t, _)| *t)
        .expect("the io task started");
    assert!(start - at <= STEP_NS, "the io task started {} ns after its edge", start - at);
    assert!(events.0.iter().any(|(_, e)| matches!(e, Event::TaskPreempt { task: 0, .. })));
}

#[test]
fn an_endless_while_trips_the_scan_watchdog() {
    let project = project(
        "[plc]\nwatchdog_ms = 20\n[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR n : DINT; END_VAR WHILE TRUE DO n := n + 1; END_WHILE; END_PROGRAM",
        )],
    );
    let (engine, events) = sim(&project, &[], &[], 100 * MS);
    let wdt = events
        .0
        .iter()
        .find(|(_, e)| matches!(e, Event::Error(ErrorKind::Watchdog { .. })))
        .map(|(t, _)| *t)
        .expect("a WDT error");
    assert!((20 * MS..=21 * MS).contains(&wdt), "WDT at {wdt}");
    assert_eq!(engine.mode(), Mode::Error);
}

#[test]
fn an_endless_jmp_loop_trips_the_scan_watchdog() {
    // a backward JMP is a loop like WHILE: charged to the step budget, ended at the watchdog
    let project = project(
        "[plc]\nwatchdog_ms = 20\n[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR n : DINT; END_VAR again: n := n + 1; JMP again; END_PROGRAM",
        )],
    );
    let (engine, events) = sim(&project, &[], &[], 100 * MS);
    let wdt = events
        .0
        .iter()
        .find(|(_, e)| matches!(e, Event::Error(ErrorKind::Watchdog { .. })))
        .map(|(t, _)| *t)
        .expect("a WDT error");
    assert!((20 * MS..=21 * MS).contains(&wdt), "WDT at {wdt}");
    assert_eq!(engine.mode(), Mode::Error);
}

#[test]
fn watched_variables_report_changes_by_type_never_their_initial_value() {
    let project = project(
        "[plc]\nscan_period_ms = 1\n[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR n : DINT := 5; r : REAL; t : TIME; END_VAR
               n := n + 1; r := 0.5; t := T#1s500ms;
             END_PROGRAM",
        )],
    );
    let watch: Vec<Watched> =
        ["MAIN.N", "main.r", "main.t"].iter().flat_map(|n| project.watched(n).unwrap()).collect();
    assert_eq!(watch.iter().map(Watched::name).collect::<Vec<_>>(), ["main.n", "main.r", "main.t"]);
    let (_, events) = sim_watching(&project, &[], &watch, 3 * MS + 500_000);
    let sets: Vec<(u16, u64)> = events
        .0
        .iter()
        .filter_map(|(_, e)| match e {
            Event::SetVariable { watch, slot } => Some((*watch, *slot)),
            _ => None,
        })
        .collect();
    let n: Vec<u64> = sets.iter().filter(|(w, _)| *w == 0).map(|(_, s)| *s).collect();
    assert_eq!(n, [6, 7, 8, 9], "5 is the initial value: no event for it");
    assert_eq!(
        sets.iter().filter(|(w, _)| *w == 1).map(|(_, s)| *s).collect::<Vec<_>>(),
        [u64::from(0.5f32.to_bits())]
    );
    assert_eq!(
        sets.iter().filter(|(w, _)| *w == 2).map(|(_, s)| *s).collect::<Vec<_>>(),
        [1_500_000_000]
    );
    assert!(project.watched("main.nope").is_err());
}

#[test]
fn an_online_change_keeps_variables_of_unchanged_name_and_type() {
    let old = project(
        "[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR n : DINT; gone : INT; kind : INT; END_VAR
               n := n + 1; gone := 7; kind := 3;
             END_PROGRAM",
        )],
    );
    let new = project(
        "[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR fresh : INT := 4; kind : DINT; N : DINT; END_VAR
               n := n + 10;
             END_PROGRAM",
        )],
    );
    let kept = plcd::engine::online::kept_variables(&old.variables, &new.variables);
    let n_old = old.variable("main.n").unwrap().at.offset;
    let n_new = new.variable("main.n").unwrap().at.offset;
    assert_eq!(&kept[..], [(n_old, n_new, 4)], "only n: same name (any case) and type");
}

/// A chart's state is variables of its instance (docs/ST.md, "Sequential Function Chart"): an
/// online change keeps each step's activity and time, and each action's control, by name; a
/// step the change adds starts afresh.
#[test]
fn an_online_change_keeps_a_charts_steps_by_name() {
    let chart = |extra: &str| {
        format!(
            "PROGRAM Main VAR go : BOOL; lamp : BOOL; END_VAR
               INITIAL_STEP Idle: END_STEP
               STEP Fill: lamp(N); END_STEP
               TRANSITION FROM Idle TO Fill := go; END_TRANSITION
               {extra}
             END_PROGRAM"
        )
    };
    let old = project("[[program]]\nfile = \"main.st\"\n", &[("main.st", &chart(""))]);
    let added = "STEP Done: END_STEP TRANSITION FROM Fill TO Done := NOT go; END_TRANSITION";
    let new = project("[[program]]\nfile = \"main.st\"\n", &[("main.st", &chart(added))]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &new.variables);
    let at = |p: &plcd::project::Project, name: &str| p.variable(name).unwrap().at.offset;
    for name in ["main.Idle.X", "main.Fill.X", "main.Fill.T", "main.Fill.since", "main.sfc$lamp.Q"]
    {
        assert!(
            kept.iter().any(|k| (k.0, k.1) == (at(&old, name), at(&new, name))),
            "{name} is kept"
        );
    }
    let done = at(&new, "main.Done.X");
    assert!(kept.iter().all(|k| k.1 != done), "the new step starts afresh");
}

#[test]
fn an_online_change_sets_references_to_null() {
    // A reference is the offset of its target in the old layout of memory: never kept, even
    // unchanged (docs/ST.md, "References over online change and RETAIN").
    let src = "PROGRAM Main VAR n : DINT; p : POINTER TO DINT; r : REF_TO DINT; END_VAR
                 p := ADR(n); r := REF(n);
               END_PROGRAM";
    let old = project("[[program]]\nfile = \"main.st\"\n", &[("main.st", src)]);
    let new = project("[[program]]\nfile = \"main.st\"\n", &[("main.st", src)]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &new.variables);
    let n = old.variable("main.n").unwrap().at.offset;
    assert_eq!(&kept[..], [(n, n, 4)], "n only: p and r start NULL again");
    let r = new.variable("main.r").unwrap();
    assert_eq!(plcd::value::type_name(&r.ty), "REF_TO DINT");
}

/// A reference whose initial value takes one (`r : REF_TO DINT := REF(n)`) is set again after
/// an online change: the guard that says it was set is itself a reference, which the change
/// never keeps (docs/ST.md, "References and pointers").
#[test]
fn an_online_change_resets_the_guard_of_reference_initial_values() {
    let src = "PROGRAM Main VAR n : DINT; r : REF_TO DINT := REF(n); END_VAR
                 r^ := r^ + 1;
               END_PROGRAM";
    let old = project("[[program]]\nfile = \"main.st\"\n", &[("main.st", src)]);
    let new = project("[[program]]\nfile = \"main.st\"\n", &[("main.st", src)]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &new.variables);
    let guard = new.variable("main.__REF_INIT_DONE").unwrap();
    assert_eq!(plcd::value::type_name(&guard.ty), "REF_TO BOOL");
    assert!(kept.iter().all(|k| k.1 != guard.at.offset), "the guard starts NULL again");
    let n = old.variable("main.n").unwrap().at.offset;
    assert!(kept.iter().any(|k| k.0 == n), "n is kept");
}

#[test]
fn an_online_change_keeps_the_variables_of_an_instance_whose_block_now_extends_another() {
    // Motor gains a base (its variables first, after the hidden type tag) and an interface:
    // its own variables move, and keep their values by name; the tag is no variable, so it
    // takes the new image's value; an interface variable is a reference, never kept.
    let old = project(
        "[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "FUNCTION_BLOCK Motor VAR speed : INT; count : DINT; END_VAR count := count + 1; END_FUNCTION_BLOCK
             PROGRAM Main VAR m : Motor; END_VAR m(); END_PROGRAM",
        )],
    );
    let new = project(
        "[[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "INTERFACE IRun METHOD Run END_METHOD END_INTERFACE
             FUNCTION_BLOCK Device VAR hours : DINT; END_VAR END_FUNCTION_BLOCK
             FUNCTION_BLOCK Motor EXTENDS Device IMPLEMENTS IRun VAR speed : INT; count : DINT; END_VAR
             METHOD Run count := count + 1; END_METHOD
               Run();
             END_FUNCTION_BLOCK
             PROGRAM Main VAR m : Motor; i : IRun; END_VAR i := m; i.Run(); END_PROGRAM",
        )],
    );
    let kept = plcd::engine::online::kept_variables(&old.variables, &new.variables);
    let at = |p: &plcd::project::Project, name: &str| p.variable(name).unwrap().at.offset;
    let speed = (at(&old, "main.m.speed"), at(&new, "main.m.speed"), 2);
    let count = (at(&old, "main.m.count"), at(&new, "main.m.count"), 4);
    // the new layout: tag (4 bytes), Device's hours (4), then Motor's own
    assert_eq!(at(&new, "main.m.speed"), at(&new, "main.m.hours") + 4);
    assert_eq!(at(&new, "main.m.hours"), at(&old, "main.m.speed") + 4);
    assert_eq!(&kept[..], [speed, count], "Motor's own variables, moved: kept by name");
    assert!(new.variable("main.i").is_some(), "the interface variable is a symbol");
}

#[test]
fn located_outputs_written_by_st_are_outputs() {
    // The default watch list of traces and logs: every P bit a program writes, IL or ST,
    // whole words of located INT/DINT/LREAL included; an input only read is not one.
    let p = project(
        "[[program]]\nname = \"main\"\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR lamp AT %QX4.4 : BOOL; word AT %P005 : INT; \
             wide AT %P006 : DINT; long AT %P008 : LREAL; button AT %IX0.1 : BOOL; END_VAR \
             lamp := button; word := 1; wide := 2; long := 3.0; END_PROGRAM",
        )],
    );
    let outputs: Vec<String> = p.output_bits().iter().map(|a| a.to_string()).collect();
    let words = ["P005", "P006", "P007", "P008", "P009", "P010", "P011"]; // word numbers are decimal
    assert_eq!(outputs.len(), 1 + 16 * words.len(), "{outputs:?}");
    // %QX4.4: byte 4 of the %QX image (from P064) is the low half of P066
    assert!(outputs.iter().any(|o| o == "P0664"), "{outputs:?}");
    for word in words {
        let (first, last) = (format!("{word}0"), format!("{word}F"));
        assert!(outputs.contains(&first) && outputs.contains(&last), "{word}: {outputs:?}");
    }
    assert!(!outputs.iter().any(|o| o == "P0001"), "an input it reads");
}

#[test]
fn st_system_functions_disable_tasks_stop_and_refresh_io() {
    // DI(0)/EI(0) gate the 1 ms cycle task while M0000 is on; DI()/EI() all interrupt tasks
    // while M0002 is; STOP() stops the PLC when M0001 comes on. IORF() writes P0040 to the
    // field in the middle of the scan, before the loop after it ends.
    let config = "[plc]\nscan_period_ms = 10\nwatchdog_ms = 1000\n\
                  [[program]]\nname = \"main\"\nfile = \"main.st\"\n\
                  [[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
                  [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\n\
                  interval_ms = 1\n";
    let main = "PROGRAM Main
VAR
    hold AT %M0000 : BOOL;
    halt AT %M0001 : BOOL;
    all AT %M0002 : BOOL;
    lamp AT %P0040 : BOOL;
    i : DINT;
END_VAR
    IF hold THEN DI(0); ELSE EI(0); END_IF;
    IF all THEN DI(); ELSE EI(); END_IF;
    lamp := TRUE;
    IORF();
    FOR i := 1 TO 200 DO END_FOR;
    IF halt THEN STOP(); END_IF;
END_PROGRAM";
    let p = project(config, &[("main.st", main), ("tick.il", "INC D00010\nEND\n")]);
    let mut plc = harness::engine::Plc::new(&p);
    plc.set_mode(Mode::Run);
    // The first scan: step until IORF has run (the loop after it takes hundreds of steps).
    let mut steps = 0;
    while !plc.field.output("P0040") {
        plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 1);
        steps += 1;
        assert!(steps < 200, "IORF did not write the output");
    }
    assert!(!plc.engine.at_scan_boundary(), "IORF wrote P0040 in the middle of the first scan");

    plc.run_for(50 * MS);
    let ticks = plc.read("D00010");
    assert!(ticks > 30, "the cycle task runs: {ticks}");
    plc.write("M0000", 1);
    plc.run_for(50 * MS);
    let held = plc.read("D00010");
    plc.run_for(50 * MS);
    assert_eq!(plc.read("D00010"), held, "DI(0) holds task 0");
    plc.write("M0000", 0);
    plc.run_for(50 * MS);
    assert!(plc.read("D00010") > held + 30, "EI(0) lets it run again");
    plc.write("M0002", 1);
    plc.run_for(50 * MS);
    let held = plc.read("D00010");
    plc.run_for(50 * MS);
    assert_eq!(plc.read("D00010"), held, "DI() holds every interrupt task");
    plc.write("M0002", 0);
    plc.run_for(20 * MS);
    assert!(plc.read("D00010") > held, "EI() again");

    plc.write("M0001", 1);
    plc.run_for(50 * MS);
    assert_eq!(plc.engine.mode(), Mode::Stop, "STOP() stopped the PLC");
}

#[test]
fn the_real_time_clock_of_plcd_sim_starts_at_sim_start_and_follows_virtual_time() {
    let project = project(
        "[plc]\nscan_period_ms = 500\n[sim]\nstart = \"2026-12-31-23:59:59\"\n\
         [[program]]\nfile = \"main.st\"\n",
        &[(
            "main.st",
            "PROGRAM Main VAR now : DT; rtc : RTC; END_VAR
               now := SysRtcGetTime(TRUE);
               rtc(IN := FALSE);
             END_PROGRAM",
        )],
    );
    let watch: Vec<Watched> =
        ["main.now", "main.rtc.CDT"].iter().flat_map(|n| project.watched(n).unwrap()).collect();
    let (_, events) = sim_watching(&project, &[], &watch, 2_600 * MS);
    let ty = plcd::value::ValueType::Calendar(plcd::value::Calendar::Dt);
    let seen = |w: u16| -> Vec<String> {
        events
            .0
            .iter()
            .filter_map(|(_, e)| match e {
                Event::SetVariable { watch, slot } if *watch == w => {
                    Some(plcd::value::format(&ty, *slot))
                }
                _ => None,
            })
            .collect()
    };
    // Scans start every 500 ms of virtual time and read the clock a few µs in: the scans at
    // 0 and 0.5 s read 23:59:59, those at 1 and 1.5 s the next second (the next day, and
    // year), those at 2 and 2.5 s one more.
    let expected = ["DT#2026-12-31-23:59:59", "DT#2027-01-01-00:00:00", "DT#2027-01-01-00:00:01"];
    assert_eq!(seen(0), expected);
    assert_eq!(seen(1), expected);
}

/// An online change keeps, by name and type, the variables of issue 29's constructs: a
/// method's `VAR_INST`, a union (as a whole: its members are one place), a WSTRING, dates,
/// and what an action writes.
#[test]
fn an_online_change_keeps_var_inst_unions_wstrings_and_dates_by_name() {
    let source = |union: &str, extra: &str| {
        format!(
            "TYPE U : UNION {union} END_UNION END_TYPE
             FUNCTION_BLOCK Counter
             METHOD Add VAR_INST calls : DINT; END_VAR calls := calls + 1; END_METHOD
             END_FUNCTION_BLOCK
             PROGRAM Main VAR {extra} c : Counter; u : U; w : WSTRING[8]; day : DATE;
               stamp : DT; shift : TOD; n : DINT; END_VAR
               c.Add(); Bump();
             ACTION Bump: n := n + 1; END_ACTION
             END_PROGRAM"
        )
    };
    let config = "[[program]]\nfile = \"main.st\"\n";
    let old = project(config, &[("main.st", &source("dw : DWORD; b : BYTE;", ""))]);
    let same = project(config, &[("main.st", &source("dw : DWORD; b : BYTE;", "x : INT;"))]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &same.variables);
    let at = |p: &plcd::project::Project, name: &str| p.variable(name).unwrap().at.offset;
    for name in [
        "main.c.Add.calls",
        "main.u.dw",
        "main.w",
        "main.day",
        "main.stamp",
        "main.shift",
        "main.n",
    ] {
        assert!(
            kept.iter().any(|k| (k.0, k.1) == (at(&old, name), at(&same, name))),
            "{name} is kept"
        );
    }
    // A member added beside an unchanged one: the union's bytes are kept through the member
    // of unchanged name and type (leaf by leaf, as everywhere), so the new member reads them.
    let changed = project(config, &[("main.st", &source("dw : DWORD; r : REAL;", ""))]);
    let kept = plcd::engine::online::kept_variables(&old.variables, &changed.variables);
    assert!(kept.contains(&(at(&old, "main.u.dw"), at(&changed, "main.u.dw"), 4)), "{kept:?}");
    assert_eq!(at(&changed, "main.u.r"), at(&changed, "main.u.dw"), "one place");
    assert!(kept.iter().any(|k| k.1 == at(&changed, "main.c.Add.calls")));
}

/// The config's `[iec.variables]` binds the variables a `[[program]]` of no CONFIGURATION
/// declares at partly specified addresses (OpenPLC's and CODESYS's way): one of the program,
/// one inside a function block instance at a plcd device, and one at a Beremiz multi-level
/// address `[iec.addresses]` places. The program, the devices and a client naming the variable
/// (as `plcctl get` and `set` do, by the project's symbols) meet at the device.
#[test]
fn iec_variables_bind_a_programs_variables_to_devices() {
    use harness::engine::Plc;
    let config = "[[program]]\nfile = \"main.st\"\n\n[iec.variables]\n\
                  \"main.lamp\" = \"%QX0.3\"\n\"main.tank.level\" = \"%D00100\"\n\
                  \"main.start\" = \"%IX100.0.0\"\n\n[iec.addresses]\n\"%IX100.0.0\" = \"%P0002\"\n";
    let main = "FUNCTION_BLOCK Tank
  VAR level AT %MW* : INT; END_VAR
  level := level + 1;
END_FUNCTION_BLOCK
PROGRAM main
  VAR lamp AT %Q* : BOOL; start AT %IX* : BOOL; tank : Tank; seen : INT; END_VAR
  IF start THEN seen := seen + 1; END_IF;
  lamp := tank.level >= 3;
  tank();
END_PROGRAM
";
    let p = project(config, &[("main.st", main)]);
    // the symbols name the devices: the tools read and write them by the variables' names
    let level = p.variable("main.tank.level").unwrap();
    let d100 = plcd::device::Address::parse("D00100").unwrap().as_word().unwrap();
    assert_eq!((level.at.space, level.at.offset), (plcd::value::Space::Word, u32::from(d100.0)));
    assert_eq!(p.variable("main.lamp").unwrap().at.space, plcd::value::Space::Bit);
    let mut plc = Plc::new(&p);
    plc.engine.set_mode(Mode::Run, 0, &mut plc.field, &mut plc.events);
    plc.run_for(MS);
    // the block's level counts at D00100, the lamp at %QX0.3 = P0643
    let scans = plc.read("D00100");
    assert!(scans >= 3, "{scans}");
    assert!(plc.field.output("P0643"));
    // a client writes the variable by its name: the device changes, the program counts on
    plc.engine.write_value(level.at, level.ty.elem(), (-100i64) as u64);
    assert_eq!(plc.read("D00100"), -100);
    plc.run_for(MS);
    assert!(plc.read("D00100") < 0, "counted on from -100");
    assert!(!plc.field.output("P0643"), "level below 3: the lamp off");
    // start is P0002 (%IX100.0.0): the program reads the input
    let seen = p.variable("main.seen").unwrap();
    assert_eq!(plc.engine.vm().read_value(seen.at, seen.ty.elem()), 0);
    plc.field.input("P0002", true);
    plc.run_for(MS);
    assert!(plc.engine.vm().read_value(seen.at, seen.ty.elem()) > 0);
}
