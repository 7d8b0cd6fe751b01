//! `FB_init` over the starts of a program (docs/ST.md, FB_init and FB_exit), in virtual
//! time: a cold start runs it with `bInitRetains` TRUE, a warm RUN start again with FALSE (the
//! RETAIN variables were kept), an online change does not run it, a cold reset runs it with
//! TRUE again. `bInCopyCode` is always FALSE.

mod harness;

use plcd::engine::event::Mode;
use plcd::engine::ModeRequest;
use plcd::project::Project;
use plcd::value::{Elem, ValueType};

use harness::engine::{project, Plc, MS};

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
