//! `FB_init` and `FB_exit` over the starts and ends of a program (docs/ST.md, FB_init and
//! FB_exit), in virtual time: a cold start runs `FB_init` with `bInitRetains` TRUE, a warm RUN
//! start again with FALSE (the RETAIN variables were kept), an online change does not run it, a
//! cold reset runs it with TRUE again. `FB_exit` runs when a RUN ends (a STOP, a reset from
//! RUN), derived block before base, variables from the last, the global instances last, and
//! for the instances of a program an online change removes. An online change of an instance's
//! declaration runs `FB_exit` and `FB_init` with `bInCopyCode` TRUE, then `FB_reinit`.

mod harness;

use plcd::engine::event::Mode;
use plcd::engine::ModeRequest;
use plcd::project::Project;
use plcd::value::{Elem, ValueType};

use harness::engine::{project, with_native, Plc, MS};

const CONFIG: &str = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n";

/// Counts the calls of FB_init in a retained global; keeps the arguments of the last one.
const AXIS: &str = "
VAR_GLOBAL RETAIN calls : DINT; END_VAR
FUNCTION_BLOCK Axis
VAR_OUTPUT retains, copy : BOOL; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    retains := bInitRetains; copy := bInCopyCode; calls := calls + 1;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR a : Axis; scans : DINT; END_VAR
    scans := scans + 1;
END_PROGRAM
";

fn st(main: &str) -> Project {
    project(CONFIG, &[("main.st", main)])
}

fn var(plc: &Plc, p: &Project, name: &str) -> i64 {
    let symbol = p.variable(name).unwrap_or_else(|| panic!("no variable {name}"));
    let value = plc.engine.vm().read_value(symbol.at, symbol.ty.elem());
    match symbol.ty {
        ValueType::Signed(Elem::I32) => i64::from(value as i32),
        _ => value as i64,
    }
}

/// Runs `ns`, then on to the end of the scan under way.
fn run_scans(plc: &mut Plc, ns: u64) {
    plc.run_for(ns);
    plc.engine.set_hold_at_end(true);
    while !plc.engine.at_scan_boundary() {
        plc.engine.run(&plc.clock, &mut plc.field, &mut plc.events, 1);
    }
    plc.engine.set_hold_at_end(false);
}

#[test]
fn fb_init_runs_at_each_run_start_and_says_whether_the_retained_variables_were_kept() {
    let p = st(AXIS);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    assert!(var(&plc, &p, "main.scans") > 1, "it ran");
    assert_eq!(var(&plc, &p, "calls"), 1, "once, before the first scan");
    assert_eq!(var(&plc, &p, "main.a.retains"), 1, "the first start is cold");
    assert_eq!(var(&plc, &p, "main.a.copy"), 0);

    plc.set_mode(Mode::Stop);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &p, "calls"), 2, "again at the warm RUN start");
    assert_eq!(var(&plc, &p, "main.a.retains"), 0, "the RETAIN variables were kept");

    // an online change keeps the instances: FB_init is not run again
    let changed = st(&AXIS.replace("scans + 1", "scans + 2"));
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &changed, "calls"), 2, "not run by the online change");

    plc.set_mode(Mode::Stop);
    plc.request(ModeRequest::Reset { cold: true }).unwrap();
    assert_eq!(var(&plc, &changed, "calls"), 0, "the cold reset");
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &changed, "calls"), 1, "run at the RUN start after it");
    assert_eq!(var(&plc, &changed, "main.a.retains"), 1, "cold: retained variables reset");
}

/// FB_exit logs each call as a digit of `log` (the instance's `id`), so the order is read in
/// the number.
const EXITS: &str = "
VAR_GLOBAL
    log, exits : DINT;
    copyCode : BOOL;
    g : Leaf := (id := 9);
END_VAR
FUNCTION_BLOCK Leaf
VAR_INPUT id : DINT; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + id; exits := exits + 1; copyCode := copyCode OR bInCopyCode;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Base
VAR inner : Leaf := (id := 1); END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 2;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Derived EXTENDS Base
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 3;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR
    a : Leaf := (id := 4);
    d : Derived;
    row : ARRAY [1..2] OF Leaf;
    scans : DINT;
END_VAR
    scans := scans + 1;
    row[1].id := 5;
    row[2].id := 6;
END_PROGRAM
";

#[test]
fn fb_exit_runs_when_a_run_ends_derived_before_base_in_reverse_order_then_the_globals() {
    let p = st(EXITS);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    assert!(var(&plc, &p, "main.scans") > 1, "it ran");
    assert_eq!(var(&plc, &p, "exits"), 0, "no FB_exit while running");
    plc.set_mode(Mode::Stop);
    // Main's variables from the last: row[2] (6), row[1] (5); d: Derived's FB_exit (3) before
    // Base's (2), then Base's instance inner (1); a (4); then the global g (9).
    assert_eq!(var(&plc, &p, "log"), 6_532_149);
    assert_eq!(var(&plc, &p, "exits"), 5, "each Leaf once");
    assert_eq!(var(&plc, &p, "copyCode"), 0, "bInCopyCode FALSE");

    // the next RUN starts from the initial values; its end runs them again, once
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &p, "log"), 0, "not at the RUN start");
    plc.request(ModeRequest::Reset { cold: false }).unwrap();
    assert_eq!(var(&plc, &p, "log"), 6_532_149, "a reset from RUN stops first");
    plc.set_mode(Mode::Stop);
    assert_eq!(var(&plc, &p, "exits"), 5, "not again: the RUN had ended");
}

#[test]
fn fb_exit_runs_for_the_instances_of_a_program_an_online_change_removes() {
    let two = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n\
               [[program]]\nname = \"other\"\nfile = \"other.st\"\n";
    let other = "PROGRAM Other\nVAR o : Leaf := (id := 7); END_VAR\nEND_PROGRAM\n";
    let p = project(two, &[("main.st", EXITS), ("other.st", other)]);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    let changed = st(EXITS);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    assert_eq!(var(&plc, &changed, "log"), 7, "only the removed program's instance");
    run_scans(&mut plc, MS);
    plc.set_mode(Mode::Stop);
    assert_eq!(var(&plc, &changed, "log"), 76_532_149, "the rest at the STOP");
}

#[test]
fn fb_exit_runs_for_a_class_instance_and_one_in_a_method_s_var_inst() {
    // A class's FB_exit with an input beyond bInCopyCode, which keeps its initial value 5;
    // the method's VAR_INST k is a variable of User, finished with it after r (declared
    // first, so finished last): 6 (k) then 5 (r).
    let source = "
VAR_GLOBAL log : DINT; END_VAR
CLASS Res
VAR id : DINT := 5; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; extra : DINT := 5; END_VAR
    log := log * 10 + id + extra - 5;
END_METHOD
METHOD Set : DINT
VAR_INPUT v : DINT; END_VAR
    id := v;
END_METHOD
END_CLASS
FUNCTION_BLOCK User
VAR r : Res; END_VAR
METHOD M : DINT
VAR_INST k : Res; END_VAR
    M := k.Set(6);
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR u : User; x : DINT; END_VAR
    x := u.M();
END_PROGRAM
";
    let p = st(source);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    plc.set_mode(Mode::Stop);
    assert_eq!(var(&plc, &p, "log"), 65);
}

#[test]
fn an_online_change_of_a_declaration_runs_fb_exit_fb_init_in_copy_code_then_fb_reinit() {
    let before = "
VAR_GLOBAL log, flags : DINT; END_VAR
FUNCTION_BLOCK Dev
VAR_INPUT kept : DINT; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 1;
    IF bInCopyCode THEN flags := flags + 1; END_IF
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Fix
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 9;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR d : Dev; f : Fix; scans : DINT; END_VAR
    scans := scans + 1;
    d.kept := 7;
END_PROGRAM
";
    // Dev gains variables (its declaration changes), an FB_init and an FB_reinit; Fix is
    // the same
    let after = before
        .replace(
            "VAR_INPUT kept : DINT; END_VAR",
            "VAR_INPUT kept : DINT; END_VAR
VAR_OUTPUT added, seen : DINT; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    IF bInCopyCode AND NOT bInitRetains THEN added := 5; END_IF
END_METHOD
METHOD FB_reinit : BOOL
    seen := kept * 10 + added;
END_METHOD",
        )
        .replace("d.kept := 7;", "d.kept := 8;");
    let p = st(before);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    let changed = st(&after);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    // the old d's FB_exit with bInCopyCode TRUE (its write to log is carried over); Fix's
    // instance is kept as it was: no FB_exit (no 9)
    assert_eq!(var(&plc, &changed, "log"), 1);
    assert_eq!(var(&plc, &changed, "flags"), 1);
    // the new d's FB_init (bInitRetains FALSE, bInCopyCode TRUE) set the new variable added;
    // kept was carried over (7); FB_reinit saw both, before any scan of the new code
    assert_eq!(var(&plc, &changed, "main.d.added"), 5);
    assert_eq!(var(&plc, &changed, "main.d.kept"), 7);
    assert_eq!(var(&plc, &changed, "main.d.seen"), 75);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &changed, "main.d.kept"), 8, "the new code runs");
    assert_eq!(var(&plc, &changed, "main.d.seen"), 75, "FB_reinit once");
}

#[test]
fn an_online_change_of_a_global_instance_s_declaration_runs_the_same_calls_as_a_program_s() {
    for native in [false, true] {
        global_instance_through_an_online_change(native);
    }
}

fn global_instance_through_an_online_change(native: bool) {
    let before = "
VAR_GLOBAL log, flags, inits : DINT; END_VAR
VAR_GLOBAL d : Dev; f : Fix; row : ARRAY [1..2] OF Dev; END_VAR
FUNCTION_BLOCK Dev
VAR_INPUT kept : DINT; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 1;
    IF bInCopyCode THEN flags := flags + 1; END_IF
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Fix
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    inits := inits + 1;
END_METHOD
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 9;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR scans : DINT; END_VAR
    scans := scans + 1;
    d.kept := 7;
    row[2].kept := 3;
END_PROGRAM
";
    // Dev gains variables (its declaration changes), an FB_init and an FB_reinit; Fix is
    // the same
    let after = before
        .replace(
            "VAR_INPUT kept : DINT; END_VAR",
            "VAR_INPUT kept : DINT; END_VAR
VAR_OUTPUT added, seen : DINT; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    IF bInCopyCode AND NOT bInitRetains THEN added := 5; END_IF
END_METHOD
METHOD FB_reinit : BOOL
    seen := kept * 10 + added;
END_METHOD",
        )
        .replace("d.kept := 7;", "d.kept := 8;");
    let p = with_native(st(before), native);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    // f's FB_init at the first scan; nothing finished yet
    assert_eq!(var(&plc, &p, "inits"), 1);
    assert_eq!(var(&plc, &p, "log"), 0);
    let scans = var(&plc, &p, "main.scans");
    let changed = with_native(st(&after), native);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    // the old copies' FB_exit with bInCopyCode TRUE, from the last declared: row[2], row[1],
    // then d (three 1s; their writes to log are carried over); f is kept as it was: no
    // FB_exit (no 9) and no FB_init again
    assert_eq!(var(&plc, &changed, "log"), 111);
    assert_eq!(var(&plc, &changed, "flags"), 3);
    assert_eq!(var(&plc, &changed, "inits"), 1);
    // the new copies' FB_init (bInitRetains FALSE, bInCopyCode TRUE) set the new variable
    // added; kept was carried over; FB_reinit saw both, before any scan of the new code, and
    // no statement of Main ran in the phases
    assert_eq!(var(&plc, &changed, "d.added"), 5);
    assert_eq!(var(&plc, &changed, "d.kept"), 7);
    assert_eq!(var(&plc, &changed, "d.seen"), 75);
    assert_eq!(var(&plc, &changed, "row[1].seen"), 5);
    assert_eq!(var(&plc, &changed, "row[2].seen"), 35);
    assert_eq!(var(&plc, &changed, "main.scans"), scans);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &changed, "d.kept"), 8, "the new code runs");
    assert_eq!(var(&plc, &changed, "d.seen"), 75, "FB_reinit once");
    assert_eq!(var(&plc, &changed, "inits"), 1, "no FB_init at the next scan");
    // a STOP finishes the global instances as usual (bInCopyCode FALSE), from the last
    // declared: row[2], row[1], f (9), d
    plc.set_mode(Mode::Stop);
    assert_eq!(var(&plc, &changed, "log"), 1111191);
    assert_eq!(var(&plc, &changed, "flags"), 3);
}

#[test]
fn the_instances_of_a_name_two_global_lists_declare_go_through_an_online_change_each() {
    for native in [false, true] {
        two_lists_through_an_online_change(native);
    }
}

fn two_lists_through_an_online_change(native: bool) {
    let config = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n\
                  [st]\nlibrary = [\"GVL_A.st\", \"GVL_B.st\"]\n";
    let blocks = "
VAR_GLOBAL log, flags : DINT; END_VAR
FUNCTION_BLOCK Dev
VAR_INPUT id : DINT; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + id;
    IF bInCopyCode THEN flags := flags + 1; END_IF
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR scans : DINT; END_VAR
    scans := scans + 1;
    GVL_A.x.id := 1;
    GVL_B.x.id := 2;
END_PROGRAM
";
    let lists = |extra: &str| {
        [
            ("main.st", blocks.replace("END_VAR\nMETHOD", &format!("END_VAR\n{extra}METHOD"))),
            ("GVL_A.st", "VAR_GLOBAL x : Dev; END_VAR\n".to_string()),
            ("GVL_B.st", "VAR_GLOBAL x : Dev; END_VAR\n".to_string()),
        ]
    };
    let files = |extra: &str| -> Project {
        let owned = lists(extra);
        let borrowed: Vec<(&str, &str)> = owned.iter().map(|(n, t)| (*n, t.as_str())).collect();
        with_native(project(config, &borrowed), native)
    };
    let p = files("");
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    // Dev gains a variable: both x change their declaration
    let changed = files("VAR_OUTPUT more : DINT; END_VAR\n");
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    // each old copy's FB_exit with bInCopyCode TRUE, GVL_B's x (declared last) first
    assert_eq!(var(&plc, &changed, "flags"), 2);
    assert_eq!(var(&plc, &changed, "log"), 21);
    assert_eq!(var(&plc, &changed, "GVL_A.x.id"), 1, "carried over");
}

#[test]
fn a_program_s_var_temp_instances_live_for_one_scan_and_no_pass_of_the_engine_touches_them() {
    for native in [false, true] {
        program_temps_through_passes(native);
    }
}

fn program_temps_through_passes(native: bool) {
    let before = "
VAR_GLOBAL tInits, tExits, tCopies, dExits, dCopies : DINT; END_VAR
FUNCTION_BLOCK Tmp
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    tInits := tInits + 1;
END_METHOD
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    tExits := tExits + 1;
    IF bInCopyCode THEN tCopies := tCopies + 1; END_IF
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Dev
VAR_INPUT kept : DINT; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    dExits := dExits + 1;
    IF bInCopyCode THEN dCopies := dCopies + 1; END_IF
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR_TEMP t : Tmp; END_VAR
VAR d : Dev; scans : DINT; END_VAR
    scans := scans + 1;
    IF scans MOD 2 = 0 THEN RETURN; END_IF
END_PROGRAM
";
    // Dev gains a variable: d goes through the phases of the change
    let after = before.replace(
        "VAR_INPUT kept : DINT; END_VAR",
        "VAR_INPUT kept : DINT; END_VAR\nVAR_OUTPUT more : DINT; END_VAR",
    );
    let p = with_native(st(before), native);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    // one FB_init and one FB_exit of t a scan, half of them at the RETURN
    let scans = var(&plc, &p, "main.scans");
    assert!(scans > 1);
    assert_eq!(var(&plc, &p, "tInits"), scans);
    assert_eq!(var(&plc, &p, "tExits"), scans);
    let changed = with_native(st(&after), native);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    // d's FB_exit in copy code; the phases ran no statement of Main: t untouched
    assert_eq!(var(&plc, &changed, "dCopies"), 1);
    assert_eq!(var(&plc, &changed, "tInits"), scans);
    assert_eq!(var(&plc, &changed, "tExits"), scans);
    assert_eq!(var(&plc, &changed, "tCopies"), 0);
    run_scans(&mut plc, MS);
    let scans = var(&plc, &changed, "main.scans");
    assert_eq!(var(&plc, &changed, "tInits"), scans);
    assert_eq!(var(&plc, &changed, "tExits"), scans);
    // a STOP finishes d (bInCopyCode FALSE), not t: no scan holds it
    plc.set_mode(Mode::Stop);
    assert_eq!(var(&plc, &changed, "dExits"), 2);
    assert_eq!(var(&plc, &changed, "dCopies"), 1);
    assert_eq!(var(&plc, &changed, "tExits"), scans);
    assert_eq!(var(&plc, &changed, "tCopies"), 0);
}

#[test]
fn the_phases_of_an_online_change_run_no_statement_of_a_program_without_fb_init() {
    // Ext has only an FB_exit, and gains a variable: its instance's phases 1 to 3 run in
    // Main, whose statements (runs := runs + 1) must not run outside a scan
    let before = "
VAR_GLOBAL log, runs : DINT; END_VAR
FUNCTION_BLOCK Ext
VAR_INPUT a : DINT; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    IF bInCopyCode THEN log := log + 1; END_IF
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR e : Ext; END_VAR
    runs := runs + 1;
END_PROGRAM
";
    // (the new Main's new variable is not carried over: what its statements would do to it
    // outside a scan would stay)
    let after = before
        .replace("VAR_INPUT a : DINT; END_VAR", "VAR_INPUT a, b : DINT; END_VAR")
        .replace("VAR e : Ext; END_VAR", "VAR e : Ext; fresh : DINT; END_VAR")
        .replace("runs := runs + 1;", "runs := runs + 1; fresh := fresh + 1;");
    let p = st(before);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    let runs = var(&plc, &p, "runs");
    let changed = st(&after);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    assert_eq!(var(&plc, &changed, "log"), 1, "FB_exit(bInCopyCode := TRUE) on the old copy");
    assert_eq!(var(&plc, &changed, "runs"), runs, "no statement of Main ran");
    assert_eq!(var(&plc, &changed, "main.fresh"), 0, "nor of the new Main");
}

#[test]
fn an_instance_an_online_change_adds_to_a_kept_program_runs_its_fb_init() {
    // Main gains `b`: its FB_init runs at the change (bInitRetains TRUE, bInCopyCode FALSE,
    // as at a first start), a's does not run again
    let before = "
VAR_GLOBAL calls : DINT; END_VAR
FUNCTION_BLOCK Axis
VAR_OUTPUT retains, copy : BOOL; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    retains := bInitRetains; copy := bInCopyCode; calls := calls + 1;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR a : Axis; scans : DINT; END_VAR
    scans := scans + 1;
END_PROGRAM
";
    let after = before.replace("VAR a : Axis;", "VAR a : Axis; b : Axis;");
    let p = st(before);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &p, "calls"), 1);
    let changed = st(&after);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    assert_eq!(var(&plc, &changed, "calls"), 2, "b's FB_init only");
    assert_eq!(var(&plc, &changed, "main.b.retains"), 1);
    assert_eq!(var(&plc, &changed, "main.b.copy"), 0);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &changed, "calls"), 2, "not again at the next scans");
}

#[test]
fn an_instance_added_to_a_program_without_fb_init_before_is_initialised_once() {
    // Main had no instance with an FB_init: its first scan after the change initialises
    // every instance it has (its hidden flag is new), so the change itself does not
    let before = "
VAR_GLOBAL calls : DINT; END_VAR
FUNCTION_BLOCK Axis
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
    calls := calls + 1;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR scans : DINT; END_VAR
    scans := scans + 1;
END_PROGRAM
";
    let after = before.replace("VAR scans : DINT;", "VAR b : Axis; scans : DINT;");
    let p = st(before);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    run_scans(&mut plc, MS);
    let changed = st(&after);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    run_scans(&mut plc, MS);
    assert_eq!(var(&plc, &changed, "calls"), 1, "once");
}

/// Function blocks made by `__NEW` (docs/ST.md, Dynamic memory): `a` deleted at scan 2 (2);
/// `b`, two elements (3, 4), never deleted; `o.p` (1), deleted by its owner's FB_exit (9
/// first). FB_exit logs each call's `id` as a digit of `log`.
const HEAP: &str = "
VAR_GLOBAL log : DINT; END_VAR
FUNCTION_BLOCK Node
VAR_INPUT id : DINT; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; nId : DINT; END_VAR
    id := nId;
END_METHOD
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + id;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Owner
VAR_INPUT p : POINTER TO Node; END_VAR
METHOD FB_exit : BOOL
VAR_INPUT bInCopyCode : BOOL; END_VAR
    log := log * 10 + 9;
    __DELETE(p);
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR o : Owner; a, b : POINTER TO Node; scans : DINT; END_VAR
    scans := scans + 1;
    IF scans = 1 THEN
        a := __NEW(Node(nId := 2));
        b := __NEW(Node(3), 2);
        b[1].id := 4;
        o.p := __NEW(Node(nId := 1));
    ELSIF scans = 2 THEN
        __DELETE(a);
    END_IF
END_PROGRAM
";

#[test]
fn the_function_blocks_still_in_the_heap_when_a_run_ends_run_their_fb_exit_last() {
    for native in [false, true] {
        heap_through_a_stop(native);
    }
}

fn heap_through_a_stop(native: bool) {
    let p = with_native(st(HEAP), native);
    let mut plc = Plc::new(&p);
    plc.set_mode(Mode::Run);
    while var(&plc, &p, "main.scans") < 2 {
        run_scans(&mut plc, MS);
    }
    assert_eq!(var(&plc, &p, "log"), 2, "a's FB_exit at its __DELETE");
    plc.set_mode(Mode::Stop);
    // Main's o: its FB_exit (9) deletes o.p (1); then the heap's live blocks from the first: b's
    // elements 3 and 4
    assert_eq!(var(&plc, &p, "log"), 29_134, "native: {native}");

    // an online change keeps the heap's blocks but sets the pointers to NULL: o's FB_exit
    // deletes nothing, and the heap's blocks run their FB_exit in their order: 3, 4, then 1
    plc.set_mode(Mode::Run);
    while var(&plc, &p, "main.scans") < 2 {
        run_scans(&mut plc, MS);
    }
    assert_eq!(var(&plc, &p, "log"), 2, "the heap emptied at the RUN start");
    let changed = with_native(st(HEAP), native);
    let mut change = plcd::engine::online::prepare(&p, &changed, &[]).unwrap();
    change.engine.take_over(&mut plc.engine, &change.edges).unwrap();
    std::mem::swap(&mut plc.engine, &mut change.engine);
    run_scans(&mut plc, MS);
    plc.set_mode(Mode::Stop);
    assert_eq!(var(&plc, &changed, "log"), 29_341, "native: {native}");
}
