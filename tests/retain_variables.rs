//! Retained Structured Text variables (docs/RETAIN.md), in virtual time and on a real
//! directory: a warm RUN start keeps them and a cold reset sets their initial values at once;
//! a replacement engine (a reload, `plcctl load`, an online change in STOP) and an online
//! change in RUN keep those of unchanged name and type; the retain files store them with the
//! device words and a restore into a changed program restores exactly those of unchanged name
//! and type.

mod harness;

use plcd::config::Restart;
use plcd::engine::event::Mode;
use plcd::engine::ModeRequest;
use plcd::project::Project;
use plcd::services::retain::writer::Writer;
use plcd::services::retain::{self, Store};
use plcd::value::{Elem, ValueType};

use harness::engine::{project, Plc, MS};
use harness::tempdir::TempDir;

const CONFIG: &str = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n";

fn st(main: &str) -> Project {
    project(CONFIG, &[("main.st", main)])
}

/// The value of the variable `name` of `plc`'s project `p`.
fn var(plc: &Plc, p: &Project, name: &str) -> i64 {
    let symbol = p.variable(name).unwrap_or_else(|| panic!("no variable {name}"));
    let value = plc.engine.vm().read_value(symbol.at, symbol.ty.elem());
    match symbol.ty {
        ValueType::Signed(Elem::I16) => i64::from(value as i16),
        ValueType::Signed(Elem::I32) => i64::from(value as i32),
        _ => value as i64,
    }
}

/// Runs `ns`, then on to the end of the scan under way: every statement of a scan executed.
fn run_scans(plc: &mut Plc, ns: u64) {
    plc.run_for(ns);
    plc.engine.set_hold_at_end(true);
    while !plc.engine.at_scan_boundary() {
        plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 1);
    }
    plc.engine.set_hold_at_end(false);
}

/// RUN for 1 ms of scans (every statement of the last one executed), then STOP: a warm RUN
/// start each time but the first.
fn run_then_stop(plc: &mut Plc) {
    plc.set_mode(Mode::Run);
    run_scans(plc, MS);
    plc.set_mode(Mode::Stop);
}

/// [`run_then_stop`]; the scans of this RUN, as `main.scans` counts them.
fn run_1ms(plc: &mut Plc, p: &Project) -> i64 {
    run_then_stop(plc);
    let scans = var(plc, p, "main.scans");
    assert!(scans > 5, "it ran: {scans}");
    scans
}

/// Counts every scan in a retained and in a plain variable, and in a retained FB instance's
/// counter, a retained global and an FB's own RETAIN member.
const COUNTING: &str = "
VAR_GLOBAL RETAIN total : DINT; END_VAR
FUNCTION_BLOCK Keeper
VAR RETAIN kept : INT; END_VAR
VAR lost : INT; END_VAR
    kept := kept + 1; lost := lost + 1;
END_FUNCTION_BLOCK
PROGRAM Main
VAR RETAIN count : DINT := 100; ctr : CTU; END_VAR
VAR scans : DINT; k : Keeper; END_VAR
    count := count + 1; scans := scans + 1; total := total + 2;
    ctr(CU := NOT ctr.CU, PV := 30000);
    k();
END_PROGRAM
";

#[test]
fn a_warm_run_start_keeps_them_a_cold_reset_sets_their_initial_values_at_once() {
    let p = st(COUNTING);
    let mut plc = Plc::new(&p);
    let scans = run_1ms(&mut plc, &p);
    assert_eq!(var(&plc, &p, "main.count"), 100 + scans);
    assert_eq!(var(&plc, &p, "total"), 2 * scans);
    assert_eq!(var(&plc, &p, "main.k.kept"), scans);
    let cv = var(&plc, &p, "main.ctr.CV");
    assert!(cv > 0);

    let again = run_1ms(&mut plc, &p);
    assert!(again < scans + 10, "not retained: started over");
    assert_eq!(var(&plc, &p, "main.count"), 100 + scans + again, "retained: counted on");
    assert_eq!(var(&plc, &p, "total"), 2 * (scans + again), "a retained global");
    assert_eq!(var(&plc, &p, "main.k.kept"), scans + again, "an FB's RETAIN member");
    assert_eq!(var(&plc, &p, "main.k.lost"), again, "its other member started over");
    assert!(var(&plc, &p, "main.ctr.CV") > cv, "a retained FB instance counted on");

    plc.request(ModeRequest::Reset { cold: true }).unwrap();
    assert_eq!(var(&plc, &p, "main.count"), 100, "the initial value, already in STOP");
    assert_eq!(var(&plc, &p, "total"), 0);
    assert_eq!(var(&plc, &p, "main.ctr.CV"), 0);
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    let scans = var(&plc, &p, "main.scans");
    assert_eq!(var(&plc, &p, "main.count"), 100 + scans, "counted from the initial value");
}

/// PERSISTENT variables (TwinCAT, CODESYS) beside RETAIN ones: a program's, a global, an FB's
/// own, one in an instance inside an array, a VAR_STAT.
const PERSISTENT: &str = "
VAR_GLOBAL PERSISTENT hours : DINT := 1000; END_VAR
VAR_GLOBAL RETAIN starts : DINT; END_VAR
FUNCTION_BLOCK Meter
VAR PERSISTENT kept : INT; END_VAR
VAR RETAIN warm : INT; END_VAR
VAR_STAT PERSISTENT calls : DINT; END_VAR
    kept := kept + 1; warm := warm + 1; calls := calls + 1;
END_FUNCTION_BLOCK
PROGRAM Main
VAR PERSISTENT count : DINT := 100; END_VAR
VAR RETAIN PERSISTENT both : DINT; END_VAR
VAR RETAIN count_retain : DINT := 100; END_VAR
VAR scans : DINT; m : Meter; ms : ARRAY [1..2] OF Meter; END_VAR
    count := count + 1; both := both + 1; count_retain := count_retain + 1;
    hours := hours + 1; starts := starts + 1; scans := scans + 1;
    m(); ms[2]();
END_PROGRAM
";

#[test]
fn a_cold_reset_keeps_the_persistent_ones_and_sets_the_retain_ones_to_their_initial_values() {
    let p = st(PERSISTENT);
    let mut plc = Plc::new(&p);
    let scans = run_1ms(&mut plc, &p);
    let again = run_1ms(&mut plc, &p);
    let both = scans + again;
    assert_eq!(var(&plc, &p, "main.count"), 100 + both, "a warm RUN start keeps them");
    assert_eq!(var(&plc, &p, "main.count_retain"), 100 + both);

    plc.request(ModeRequest::Reset { cold: true }).unwrap();
    // TwinCAT's and CODESYS's Reset cold: every variable but the PERSISTENT ones
    assert_eq!(var(&plc, &p, "main.count"), 100 + both, "PERSISTENT: kept, already in STOP");
    assert_eq!(var(&plc, &p, "main.both"), both, "RETAIN PERSISTENT: kept");
    assert_eq!(var(&plc, &p, "hours"), 1000 + both, "a PERSISTENT global: kept");
    assert_eq!(var(&plc, &p, "main.m.kept"), both, "an FB's PERSISTENT member: kept");
    assert_eq!(var(&plc, &p, "main.ms[2].kept"), both, "in an array element: kept");
    assert_eq!(var(&plc, &p, "Meter.calls"), 2 * both, "a VAR_STAT PERSISTENT: kept");
    assert_eq!(var(&plc, &p, "main.count_retain"), 100, "RETAIN: its initial value");
    assert_eq!(var(&plc, &p, "starts"), 0, "a RETAIN global: its initial value");
    assert_eq!(var(&plc, &p, "main.m.warm"), 0, "an FB's RETAIN member: its initial value");
    assert_eq!(var(&plc, &p, "main.ms[1].kept"), 0, "never called: still its initial value");

    // The RUN start after a cold reset is cold, and still keeps them.
    let third = run_1ms(&mut plc, &p);
    assert_eq!(var(&plc, &p, "main.count"), 100 + both + third, "counted on");
    assert_eq!(var(&plc, &p, "main.m.kept"), both + third);
    assert_eq!(var(&plc, &p, "main.count_retain"), 100 + third, "counted from 100");
    assert_eq!(var(&plc, &p, "main.m.warm"), third);

    // A replacement engine (a reload, `plcctl load`) keeps them, as it keeps RETAIN ones.
    let mut new = Plc::new(&p);
    new.engine.inherit_retained(&plc.engine);
    assert_eq!(var(&new, &p, "main.count"), 100 + both + third);
    assert_eq!(var(&new, &p, "hours"), 1000 + both + third);
}

/// FB instances with a RETAIN member in a plain array, in an array of arrays and in a struct:
/// each instance's retained member is kept by a warm RUN start as a single instance's is.
const KEEPERS: &str = "
FUNCTION_BLOCK Keeper
VAR RETAIN kept : INT; END_VAR
VAR lost : INT; END_VAR
    kept := kept + 1; lost := lost + 1;
END_FUNCTION_BLOCK
TYPE Cell : STRUCT k : Keeper; n : INT; END_STRUCT; END_TYPE
PROGRAM Main
VAR ks : ARRAY [1..2] OF Keeper; grid : ARRAY [0..1, 0..1] OF Keeper;
    nested : ARRAY [1..2] OF ARRAY [1..2] OF Keeper; cell : Cell; scans : DINT; END_VAR
    ks[1](); ks[2](); grid[1, 0](); nested[2][1](); cell.k(); cell.n := cell.n + 1;
    scans := scans + 1;
END_PROGRAM
";

#[test]
fn a_warm_run_start_keeps_the_retain_members_of_instances_in_arrays_and_structs() {
    let p = st(KEEPERS);
    let mut plc = Plc::new(&p);
    let scans = run_1ms(&mut plc, &p);
    let again = run_1ms(&mut plc, &p);
    assert!(again < scans + 10, "not retained: started over");
    for kept in [
        "main.ks[1].kept",
        "main.ks[2].kept",
        "main.grid[1,0].kept",
        "main.nested[2][1].kept",
        "main.cell.k.kept",
    ] {
        assert_eq!(var(&plc, &p, kept), scans + again, "{kept}: retained, counted on");
    }
    // the other elements and members were never called or are not RETAIN: started over
    assert_eq!(var(&plc, &p, "main.grid[0,0].kept"), 0);
    assert_eq!(var(&plc, &p, "main.ks[1].lost"), again);
    assert_eq!(var(&plc, &p, "main.cell.n"), again);
}

const OLD: &str = "
PROGRAM Main
VAR RETAIN count : DINT; renamed : DINT; retyped : INT; removed : INT; END_VAR
VAR plain : DINT; END_VAR
    count := count + 1; renamed := renamed + 1; retyped := retyped + 1;
    removed := removed + 1; plain := plain + 1;
END_PROGRAM
";

/// The same program changed: `count` moved (another offset, another spelling), `renamed`
/// renamed, `retyped` of another type, `removed` removed, `fresh` new; `plain` made RETAIN.
const NEW: &str = "
PROGRAM Main
VAR RETAIN fresh : INT := 5; retyped : DINT := 9; COUNT : DINT; renamed2 : DINT := 3;
    plain : DINT := 1; END_VAR
    ;
END_PROGRAM
";

fn assert_changed_program(plc: &Plc, p: &Project, count: i64) {
    assert_eq!(var(plc, p, "main.count"), count, "same name and type: kept");
    assert_eq!(var(plc, p, "main.renamed2"), 3, "renamed: its initial value");
    assert_eq!(var(plc, p, "main.retyped"), 9, "retyped: its initial value");
    assert_eq!(var(plc, p, "main.fresh"), 5, "new: its initial value");
    assert_eq!(var(plc, p, "main.plain"), 1, "retained only now: its initial value");
}

#[test]
fn a_replacement_engine_keeps_those_of_unchanged_name_and_type() {
    let (old_p, new_p) = (st(OLD), st(NEW));
    let mut old = Plc::new(&old_p);
    run_then_stop(&mut old);
    let count = var(&old, &old_p, "main.count");
    assert!(count > 5);
    let mut new = Plc::new(&new_p);
    new.engine.inherit_retained(&old.engine);
    assert_changed_program(&new, &new_p, count);
    // And the first RUN start is warm: it keeps them.
    new.set_mode(Mode::Run);
    new.run_for(MS);
    assert_eq!(var(&new, &new_p, "main.count"), count);
}

#[test]
fn after_an_online_change_in_run_the_next_run_start_is_still_warm() {
    let (old_p, new_p) = (st(OLD), st(&OLD.replace("plain + 1", "plain + 2")));
    let mut plc = Plc::new(&old_p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    let mut change = plcd::engine::online::prepare(&old_p, &new_p, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    run_scans(&mut plc, MS);
    plc.set_mode(Mode::Stop);
    let count = var(&plc, &new_p, "main.count");
    assert!(count > var(&plc, &new_p, "main.plain") / 2, "counted through the change");
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    let scans = var(&plc, &new_p, "main.plain") / 2;
    assert_eq!(var(&plc, &new_p, "main.count"), count + scans, "warm: counted on");
}

#[test]
fn the_files_hold_them_and_a_changed_program_restores_those_of_unchanged_name_and_type() {
    let dir = TempDir::new("retain-variables");
    let (old_p, new_p) = (st(OLD), st(NEW));
    let mut old = Plc::new(&old_p);
    run_then_stop(&mut old);
    let count = var(&old, &old_p, "main.count");

    // What the writer writes: the device words and the variables, in one generation.
    let set = old.engine.retain_set().clone();
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    let mut writer =
        Writer::new(Store::open(dir.path()).unwrap(), &set.words, 0, start.next_seq, None);
    let mut words = Vec::new();
    set.capture(old.engine.vm().mem.words(), &mut words);
    let layout = old.engine.retained_variables();
    let mut copy = Vec::new();
    layout.copy(old.engine.vm().vars(), &mut copy);
    assert!(writer.write_state(&mut words.clone(), Some((layout, &copy))).unwrap());
    assert!(
        !writer.write_state(&mut words.clone(), Some((layout, &copy))).unwrap(),
        "unchanged: not written again"
    );
    let g = retain::newest_in(dir.path()).unwrap();
    assert_eq!(g.version, 4);
    let names: Vec<(&str, &str)> =
        g.variables.iter().map(|v| (v.name.as_str(), v.ty.as_str())).collect();
    assert_eq!(
        names,
        [
            ("main.count", "DINT"),
            ("main.renamed", "DINT"),
            ("main.retyped", "INT"),
            ("main.removed", "INT")
        ]
    );
    assert_eq!(g.variables[0].bytes, (count as i32).to_le_bytes());

    // The same program restores everything.
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    let mut same = Plc::new(&old_p);
    same.engine.restore_retained(start.words.as_deref().unwrap());
    let plan = same.engine.restore_retained_variables(&start.variables);
    assert_eq!((plan.restore.len(), plan.dropped.len(), plan.new.len()), (4, 0, 0));
    assert_eq!(var(&same, &old_p, "main.removed"), count);

    // The changed one restores `count` only, and says what it dropped and what is new.
    let mut new = Plc::new(&new_p);
    new.engine.restore_retained(start.words.as_deref().unwrap());
    let plan = new.engine.restore_retained_variables(&start.variables);
    assert_changed_program(&new, &new_p, count);
    assert_eq!(
        plan.dropped,
        [
            "main.renamed (DINT): not a RETAIN variable of the program",
            "main.retyped (INT): now DINT",
            "main.removed (INT): not a RETAIN variable of the program",
        ]
    );
    assert_eq!(plan.new, ["main.fresh", "main.retyped", "main.renamed2", "main.plain"]);
    new.set_mode(Mode::Run);
    new.run_for(MS);
    assert_eq!(var(&new, &new_p, "main.count"), count, "the restore makes the RUN start warm");

    // restart = "cold" restores nothing.
    let cold = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Cold);
    assert!(cold.words.is_none() && cold.variables.is_empty());
}

#[test]
fn calendar_variables_are_retained_by_name_and_type() {
    let dir = TempDir::new("retain-calendar");
    let p = st("
PROGRAM Main
VAR RETAIN stamp : DT; shift : TOD := TOD#06:00:00; days : ARRAY [1..2] OF DATE; END_VAR
    stamp := DT#2024-03-01-12:30:15; days[2] := D#2024-03-01;
END_PROGRAM
");
    let mut old = Plc::new(&p);
    run_then_stop(&mut old);
    let set = old.engine.retain_set().clone();
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    let mut writer =
        Writer::new(Store::open(dir.path()).unwrap(), &set.words, 0, start.next_seq, None);
    let mut words = Vec::new();
    set.capture(old.engine.vm().mem.words(), &mut words);
    let layout = old.engine.retained_variables();
    let mut copy = Vec::new();
    layout.copy(old.engine.vm().vars(), &mut copy);
    assert!(writer.write_state(&mut words, Some((layout, &copy))).unwrap());
    let g = retain::newest_in(dir.path()).unwrap();
    let names: Vec<(&str, &str)> =
        g.variables.iter().map(|v| (v.name.as_str(), v.ty.as_str())).collect();
    assert_eq!(
        names,
        [("main.stamp", "DT"), ("main.shift", "TOD"), ("main.days", "ARRAY[1..2] OF DATE")]
    );

    // The same program restores all three: DT#2024-03-01-12:30:15 is 1709296215 s.
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    let mut same = Plc::new(&p);
    let plan = same.engine.restore_retained_variables(&start.variables);
    assert_eq!(plan.restore.len(), 3);
    assert_eq!(var(&same, &p, "main.stamp"), 1_709_296_215);
    assert_eq!(var(&same, &p, "main.shift"), 6 * 3_600_000);

    // A DT that became an LDT is another type: dropped.
    let long = st("PROGRAM Main VAR RETAIN stamp : LDT; END_VAR ; END_PROGRAM");
    let mut changed = Plc::new(&long);
    let plan = changed.engine.restore_retained_variables(&start.variables);
    assert!(plan.dropped.contains(&"main.stamp (DT): now LDT".to_string()), "{:?}", plan.dropped);
}

/// A RETAIN reference keeps its value over a warm RUN start (the program and so its memory
/// are the same: it still points where it did), as CODESYS keeps a retained pointer.
#[test]
fn a_warm_run_start_keeps_a_retained_reference() {
    let p = st("PROGRAM Main
VAR RETAIN p : POINTER TO DINT; END_VAR
VAR n : DINT; was_null : BOOL; END_VAR
    was_null := p = NULL;
    IF p = NULL THEN p := ADR(n); END_IF;
    p^ := p^ + 1;
END_PROGRAM
");
    let mut plc = Plc::new(&p);
    run_then_stop(&mut plc);
    let scans = var(&plc, &p, "main.n");
    assert!(scans > 1, "it ran: {scans}");
    run_then_stop(&mut plc);
    assert_eq!(var(&plc, &p, "main.was_null"), 0, "kept over the warm start");
    assert!(var(&plc, &p, "main.n") > 0, "n counts again from 0 through p");
}

/// A retained CODESYS UNION (docs/ST.md, "Unions") is retained as a whole, its bytes: a warm
/// RUN start and a replacement engine keep them, whichever member wrote them last.
#[test]
fn a_retained_union_keeps_its_bytes() {
    let source = "
TYPE U : UNION dw : DWORD; r : REAL; b : ARRAY [0..3] OF BYTE; END_UNION END_TYPE
PROGRAM Main
VAR RETAIN u : U; END_VAR
VAR scans : DINT; END_VAR
    scans := scans + 1;
    u.b[3] := 16#3F;
    u.dw := u.dw + 1;
END_PROGRAM
";
    let p = st(source);
    let mut plc = Plc::new(&p);
    run_then_stop(&mut plc);
    let scans = var(&plc, &p, "main.scans");
    assert!(scans > 5, "it ran: {scans}");
    // byte 3 is 16#3F each scan, the low bytes count the scans
    assert_eq!(var(&plc, &p, "main.u.dw"), 0x3F00_0000 + scans);

    run_then_stop(&mut plc);
    let again = var(&plc, &p, "main.scans");
    assert!(again > 0 && again < scans + 10, "not retained: started over");
    assert_eq!(var(&plc, &p, "main.u.dw"), 0x3F00_0000 + scans + again, "retained: counted on");

    let mut new = Plc::new(&p);
    new.engine.inherit_retained(&plc.engine);
    assert_eq!(var(&new, &p, "main.u.dw"), 0x3F00_0000 + scans + again, "the same bytes");
    assert_eq!(var(&new, &p, "main.u.b[3]"), 0x3F, "read through another member");
}

/// The new types in a RETAIN block (issue 29): an FB instance with a method, its `VAR_INST`
/// included, a WSTRING, a CHAR and a WCHAR, and an FB instance whose body is a chart (its active step and the
/// step's time: docs/ST.md, "Sequential Function Chart", RETAIN) are kept over a warm RUN
/// start and into a replacement engine; the chart of an instance not retained starts again.
#[test]
fn retained_instances_with_methods_and_charts_and_wstrings_are_kept() {
    let source = "
FUNCTION_BLOCK Counter
VAR n : DINT; END_VAR
METHOD Add
VAR_INST calls : DINT; END_VAR
    calls := calls + 1; n := n + 10;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Stepper
VAR_INPUT go : BOOL; END_VAR
    INITIAL_STEP Idle: END_STEP
    STEP Busy: END_STEP
    TRANSITION FROM Idle TO Busy := go; END_TRANSITION
END_FUNCTION_BLOCK
PROGRAM Main
VAR RETAIN c : Counter; chart : Stepper; w : WSTRING[8] := \"ä\"; ch : CHAR; wc : WCHAR; END_VAR
VAR scans : DINT; free : Stepper; END_VAR
    scans := scans + 1;
    c.Add();
    chart(go := scans = 2);
    free(go := scans = 2);
    IF scans = 2 THEN
        w := CONCAT(w, \"Ω\");
        ch := WORD_TO_CHAR(CHAR_TO_WORD(ch) + 1);
        wc := WORD_TO_WCHAR(WCHAR_TO_WORD(wc) + 1);
    END_IF;
END_PROGRAM
";
    let p = st(source);
    let mut plc = Plc::new(&p);
    run_then_stop(&mut plc);
    let scans = var(&plc, &p, "main.scans");
    assert!(scans > 3, "it ran: {scans}");
    assert_eq!(var(&plc, &p, "main.c.Add.calls"), scans);
    assert_eq!(var(&plc, &p, "main.c.n"), 10 * scans);
    assert_eq!(var(&plc, &p, "main.chart.Busy.X"), 1);
    assert_eq!(var(&plc, &p, "main.free.Busy.X"), 1);
    // A WSTRING's characters: UTF-16 code units up to the first 0.
    let wide = |plc: &Plc| {
        let at = p.variable("main.w").unwrap().at.offset as usize;
        let bytes = &plc.engine.vm().vars()[at..];
        let units: Vec<u16> = bytes
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .take_while(|&u| u != 0)
            .collect();
        String::from_utf16(&units).unwrap()
    };
    assert_eq!(wide(&plc), "äΩ");
    assert_eq!((var(&plc, &p, "main.ch"), var(&plc, &p, "main.wc")), (1, 1));

    // A warm RUN start: the chart of the instance that is not retained is reset to its
    // initial values (no step active until its first call), the retained one stays in Busy.
    plc.set_mode(Mode::Run);
    assert_eq!(var(&plc, &p, "main.free.Busy.X"), 0, "a chart not retained");
    assert_eq!(var(&plc, &p, "main.chart.Busy.X"), 1);
    run_scans(&mut plc, MS);
    plc.set_mode(Mode::Stop);
    let again = var(&plc, &p, "main.scans");
    assert!(again > 0 && again < scans + 10, "not retained: started over");
    assert_eq!(var(&plc, &p, "main.c.Add.calls"), scans + again, "the VAR_INST counted on");
    assert_eq!(var(&plc, &p, "main.c.n"), 10 * (scans + again));
    assert_eq!(var(&plc, &p, "main.chart.Busy.X"), 1, "the retained chart stayed in Busy");
    assert_eq!(var(&plc, &p, "main.chart.Idle.X"), 0);
    assert_eq!(wide(&plc), "äΩΩ", "kept, and scan 2 of this RUN added one more");
    assert_eq!((var(&plc, &p, "main.ch"), var(&plc, &p, "main.wc")), (2, 2), "CHAR, WCHAR");

    let mut new = Plc::new(&p);
    new.engine.inherit_retained(&plc.engine);
    assert_eq!(var(&new, &p, "main.c.Add.calls"), scans + again);
    assert_eq!(var(&new, &p, "main.chart.Busy.X"), 1);
    assert_eq!(wide(&new), "äΩΩ");
    assert_eq!((var(&new, &p, "main.ch"), var(&new, &p, "main.wc")), (2, 2));
    assert_eq!(var(&new, &p, "main.free.Busy.X"), 0, "a chart not retained");
}

/// Retained arrays: of scalars, of two dimensions, of structs, of arrays, and one whose
/// element type changes.
const ARRAYS: &str = "
TYPE Pt : STRUCT x : INT; y : DINT; END_STRUCT; END_TYPE
PROGRAM Main
VAR RETAIN buf : ARRAY[1..4] OF DINT; m : ARRAY[1..2, 1..3] OF INT; pts : ARRAY[1..3] OF Pt;
    typed : ARRAY[1..2] OF INT; rows : ARRAY[1..2] OF ARRAY[1..2] OF INT; END_VAR
VAR scans : DINT; i : INT; j : INT; END_VAR
    scans := scans + 1;
    FOR i := 1 TO 4 DO buf[i] := buf[i] + i; END_FOR;
    FOR i := 1 TO 2 DO
        FOR j := 1 TO 3 DO m[i, j] := m[i, j] + 10 * i + j; END_FOR;
        rows[i][2] := rows[i][2] + i;
    END_FOR;
    FOR i := 1 TO 3 DO pts[i].x := pts[i].x + i; pts[i].y := pts[i].y + 100 * i; END_FOR;
    typed[1] := typed[1] + 1;
END_PROGRAM
";

/// The same arrays changed: `buf` shifted and shrunk (1..2 in common), `m` a row more and its
/// columns shifted (rows 1..2, columns 2..3 in common), `pts` shifted and grown (2..3 in
/// common), `typed` of DINT now, `rows` grown; a variable before them moves them all.
const ARRAYS_CHANGED: &str = "
TYPE Pt : STRUCT x : INT; y : DINT; END_STRUCT; END_TYPE
PROGRAM Main
VAR RETAIN first : DINT := 7; BUF : ARRAY[0..2] OF DINT := [3(5)]; m : ARRAY[1..3, 2..4] OF INT;
    pts : ARRAY[2..5] OF Pt; typed : ARRAY[1..2] OF DINT := [2(9)];
    rows : ARRAY[0..2] OF ARRAY[1..3] OF INT; END_VAR
    ;
END_PROGRAM
";

/// What `plc` (of `ARRAYS_CHANGED`, project `p`) holds after taking over `ARRAYS` after
/// `scans` scans: the elements both have, by index; the others their initial values.
fn assert_changed_arrays(plc: &Plc, p: &Project, scans: i64) {
    let v = |name: &str| var(plc, p, name);
    assert_eq!((v("main.buf[0]"), v("main.buf[1]"), v("main.buf[2]")), (5, scans, 2 * scans));
    assert_eq!((v("main.m[1,2]"), v("main.m[1,3]")), (12 * scans, 13 * scans));
    assert_eq!((v("main.m[2,2]"), v("main.m[2,3]")), (22 * scans, 23 * scans));
    for new in ["main.m[1,4]", "main.m[2,4]", "main.m[3,2]", "main.m[3,3]"] {
        assert_eq!(v(new), 0, "{new} is new");
    }
    assert_eq!((v("main.pts[2].x"), v("main.pts[2].y")), (2 * scans, 200 * scans));
    assert_eq!((v("main.pts[3].x"), v("main.pts[3].y")), (3 * scans, 300 * scans));
    assert_eq!((v("main.pts[4].x"), v("main.pts[5].y")), (0, 0));
    assert_eq!((v("main.typed[1]"), v("main.typed[2]")), (9, 9), "another element type");
    assert_eq!(v("main.first"), 7);
    // an array of arrays: another inner bound is another element layout
    assert_eq!((v("main.rows[1][2]"), v("main.rows[2][2]")), (0, 0));
}

#[test]
fn retained_arrays_are_one_record_each_and_keep_the_elements_both_have() {
    let dir = TempDir::new("retain-arrays");
    let (old_p, new_p) = (st(ARRAYS), st(ARRAYS_CHANGED));
    let mut old = Plc::new(&old_p);
    run_then_stop(&mut old);
    let scans = var(&old, &old_p, "main.scans");
    assert!(scans > 1, "it ran: {scans}");

    // A replacement engine (a reload, a load, an online change in STOP).
    let mut new = Plc::new(&new_p);
    new.engine.inherit_retained(&old.engine);
    assert_changed_arrays(&new, &new_p, scans);

    // The file: one record an array, its elements' bytes whole.
    let set = old.engine.retain_set().clone();
    let mut writer = Writer::new(Store::open(dir.path()).unwrap(), &set.words, 0, 1, None);
    let mut words = Vec::new();
    set.capture(old.engine.vm().mem.words(), &mut words);
    let layout = old.engine.retained_variables();
    let mut copy = Vec::new();
    layout.copy(old.engine.vm().vars(), &mut copy);
    assert!(writer.write_state(&mut words, Some((layout, &copy))).unwrap());
    let g = retain::newest_in(dir.path()).unwrap();
    let records: Vec<(&str, &str, usize)> =
        g.variables.iter().map(|v| (v.name.as_str(), v.ty.as_str(), v.bytes.len())).collect();
    assert_eq!(
        records,
        [
            ("main.buf", "ARRAY[1..4] OF DINT", 16),
            ("main.m", "ARRAY[1..2,1..3] OF INT", 12),
            ("main.pts", "ARRAY[1..3] OF {.x@0:INT;.y@2:DINT;@6}", 18),
            ("main.typed", "ARRAY[1..2] OF INT", 4),
            ("main.rows", "ARRAY[1..2] OF ARRAY[1..2] OF INT", 8),
        ]
    );
    assert_eq!(g.variables[0].bytes[12..], (4 * scans as i32).to_le_bytes(), "buf[4]");

    // The same program restores every element; the changed one those both have, and says
    // in one line each what it dropped.
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    let mut same = Plc::new(&old_p);
    let plan = same.engine.restore_retained_variables(&start.variables);
    assert_eq!((plan.restore.len(), plan.dropped.len(), plan.new.len()), (5, 0, 0));
    assert_eq!(var(&same, &old_p, "main.m[2,3]"), 23 * scans);
    assert_eq!(var(&same, &old_p, "main.pts[3].y"), 300 * scans);
    assert_eq!(var(&same, &old_p, "main.rows[2][2]"), 2 * scans);
    let mut new = Plc::new(&new_p);
    let plan = new.engine.restore_retained_variables(&start.variables);
    assert_changed_arrays(&new, &new_p, scans);
    assert_eq!(
        plan.dropped,
        [
            "main.typed (ARRAY[1..2] OF INT): now ARRAY[1..2] OF DINT",
            "main.rows (ARRAY[1..2] OF ARRAY[1..2] OF INT): now ARRAY[0..2] OF ARRAY[1..3] OF INT",
        ]
    );
    assert_eq!(plan.new, ["main.first", "main.typed", "main.rows"]);
}

/// A version 3 file (written by earlier builds: an array element by element, `main.buf[3]`)
/// restores each element record into its element of the array record.
#[test]
fn a_version_3_files_element_records_restore_into_the_arrays() {
    use plcd::services::retain::format;
    let dir = TempDir::new("retain-version-3");
    let (old_p, new_p) = (st(ARRAYS), st(ARRAYS_CHANGED));
    let mut old = Plc::new(&old_p);
    run_then_stop(&mut old);
    let scans = var(&old, &old_p, "main.scans");
    // every retained leaf as its own record, as version 3 wrote them
    let vars = old.engine.vm().vars();
    let leaves: Vec<(String, String, Vec<u8>)> = old_p
        .variables
        .symbols
        .iter()
        .filter(|s| s.retain)
        .map(|s| {
            let (at, len) = (s.at.offset as usize, s.ty.bytes() as usize);
            (s.name.clone(), plcd::vm::retained::type_text(&s.ty), vars[at..at + len].to_vec())
        })
        .collect();
    assert_eq!(leaves.len(), 4 + 6 + 6 + 2 + 4);
    assert_eq!((leaves[0].0.as_str(), leaves[10].0.as_str()), ("main.buf[1]", "main.pts[1].x"));
    let mut section = Vec::new();
    let records = leaves.iter().map(|(n, t, b)| (n.as_str(), t.as_str(), &b[..]));
    format::encode_variables(records, &mut section);
    let set = old.engine.retain_set().clone();
    let mut words = Vec::new();
    set.capture(old.engine.vm().mem.words(), &mut words);
    let mut bytes = Vec::new();
    format::encode(4, 0, &set.words, &words, &section, &mut bytes);
    bytes[8] = 3;
    let body = bytes.len() - 4;
    let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI).checksum(&bytes[..body]);
    bytes[body..].copy_from_slice(&crc.to_le_bytes());
    std::fs::write(dir.path().join("retain-a.bin"), &bytes).unwrap();

    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    assert_eq!(start.version, 3);
    let mut same = Plc::new(&old_p);
    let plan = same.engine.restore_retained_variables(&start.variables);
    assert_eq!((plan.restore.len(), plan.dropped.len(), plan.new.len()), (22, 0, 0));
    assert_eq!(var(&same, &old_p, "main.pts[3].y"), 300 * scans);
    assert_eq!(var(&same, &old_p, "main.m[2,3]"), 23 * scans);
    assert_eq!(var(&same, &old_p, "main.rows[2][2]"), 2 * scans);

    // Into the changed arrays: the elements the new bounds still have, of the same type.
    let mut new = Plc::new(&new_p);
    let plan = new.engine.restore_retained_variables(&start.variables);
    let v = |name: &str| var(&new, &new_p, name);
    assert_eq!((v("main.buf[0]"), v("main.buf[1]"), v("main.buf[2]")), (5, scans, 2 * scans));
    assert_eq!((v("main.m[1,2]"), v("main.m[2,3]"), v("main.m[1,4]")), (12 * scans, 23 * scans, 0));
    assert_eq!((v("main.pts[3].y"), v("main.pts[4].x")), (300 * scans, 0));
    assert_eq!(v("main.typed[1]"), 9, "another element type");
    // as version 3 kept them, leaf by leaf: rows[i][2] is still an INT of that name
    assert_eq!((v("main.rows[1][2]"), v("main.rows[2][2]")), (scans, 2 * scans));
    assert!(plan
        .dropped
        .contains(&"main.buf[3] (DINT): not a RETAIN variable of the program".into()));
    assert!(plan.dropped.contains(&"main.typed[1] (INT): now DINT".into()));
    assert_eq!(plan.new, ["main.first", "main.typed"]);
}
