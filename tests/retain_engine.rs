//! Retained memory in the engine, in virtual time: what a warm RUN start keeps (K, the
//! `[retain]` D, T and C ranges, a retained counter's state), what a cold reset clears, a
//! restored image, and a replacement engine taking the retained devices over.

mod harness;

use plcd::engine::event::Mode;
use plcd::engine::ModeRequest;
use plcd::project::Project;

use harness::engine::{Plc, MS};

/// A project of `retain` (a `[retain]` section) and one scan program.
fn project(retain: &str, main: &str) -> Project {
    let config = format!("{retain}\n[[program]]\nfile = \"main.il\"\n");
    harness::engine::project(&config, &[("main.il", main)])
}

const RANGES: &str = "[retain]\nranges = [\"D00010-D00010\", \"C0000-C0000\", \"C0002-C0002\", \
                      \"T1500-T1500\"]\n";
const COUNT: &str = "INC K000\nINC D00010\nINC D00020\nEND\n";

#[test]
fn k_and_the_retained_ranges_survive_stop_and_run_the_rest_is_cleared() {
    let mut plc = Plc::new(&project(RANGES, COUNT));
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    plc.set_mode(Mode::Stop);
    let (k, d) = (plc.read("K000"), plc.read("D00010"));
    assert!(k > 10 && k == d && plc.read("D00020") == k, "every scan counted");
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    let scans = plc.read("D00020");
    assert!(scans > 0 && scans < k + 10, "D00020 is not retained: it started over");
    assert_eq!(plc.read("K000"), k + scans, "K counted on");
    assert_eq!(plc.read("D00010"), d + scans, "the retained D range counted on");
}

#[test]
fn a_cold_reset_clears_the_retained_devices_too() {
    let mut plc = Plc::new(&project(RANGES, COUNT));
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    plc.request(ModeRequest::Reset { cold: true }).unwrap();
    assert_eq!((plc.read("K000"), plc.read("D00010")), (0, 0));
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    let scans = plc.read("D00020");
    assert_eq!((plc.read("K000"), plc.read("D00010")), (scans, scans));
}

#[test]
fn a_restored_image_is_what_the_first_run_starts_from() {
    let p = project(RANGES, COUNT);
    let mut before = Plc::new(&p);
    before.set_mode(Mode::Run);
    before.run_for(MS);
    let mut image = Vec::new();
    before.engine.retain_set().capture(before.engine.vm().mem.words(), &mut image);
    let k = before.read("K000");

    let mut after = Plc::new(&p);
    after.engine.restore_retained(&image);
    assert_eq!((after.read("K000"), after.read("D00010"), after.read("D00020")), (k, k, 0));
    after.set_mode(Mode::Run);
    after.run_for(MS);
    let scans = after.read("D00020");
    assert_eq!((after.read("K000"), after.read("D00010")), (k + scans, k + scans));
}

#[test]
fn a_replacement_engine_takes_the_retained_devices_over() {
    let p = project(RANGES, COUNT);
    let mut old = Plc::new(&p);
    old.set_mode(Mode::Run);
    old.run_for(MS);
    old.set_mode(Mode::Stop);
    let k = old.read("K000");
    let mut new = Plc::new(&p);
    new.engine.inherit_retained(&old.engine);
    assert_eq!((new.read("K000"), new.read("D00010"), new.read("D00020")), (k, k, 0));
}

#[test]
fn retained_counters_count_on_without_a_phantom_edge_and_keep_a_down_count() {
    // C0000 retained, C0001 not; C0002 a retained down counter.
    let main =
        "LOAD P0000\nCTU C0000 100\nLOAD P0000\nCTU C0001 100\nLOAD P0001\nCTD C0002 5\nEND\n";
    let mut plc = Plc::new(&project(RANGES, main));
    plc.field.input("P0000", true);
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    assert_eq!((plc.read("C0000"), plc.read("C0001"), plc.read("C0002")), (1, 1, 5));
    plc.field.input("P0001", true);
    plc.run_for(MS);
    assert_eq!(plc.read("C0002"), 4);

    // The inputs stay ON across STOP and RUN: no edge, nothing counted twice.
    plc.set_mode(Mode::Stop);
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    assert_eq!(plc.read("C0000"), 1, "a held input is no new part");
    assert_eq!(plc.read("C0001"), 1, "not retained: cleared, then the ON input counted");
    assert_eq!(plc.read("C0002"), 4, "a retained down counter does not load its preset again");
    plc.field.input("P0000", false);
    plc.run_for(MS);
    plc.field.input("P0000", true);
    plc.run_for(MS);
    assert_eq!(plc.read("C0000"), 2, "the next real edge counts");

    plc.request(ModeRequest::Reset { cold: true }).unwrap();
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    // Cold: as new counters, the ON inputs are edges; the down counter loaded its preset again
    // and counted one down.
    assert_eq!((plc.read("C0000"), plc.read("C0002")), (1, 4));
}

#[test]
fn a_retained_integrating_timer_counts_on_a_retained_on_delay_timer_starts_over() {
    // T1500 and T1501 have a 1 ms base; only T1500 is retained.
    let main = "LOAD P0000\nTMR T1500 1000\nLOAD P0000\nTON T1501 1000\nEND\n";
    let p = project(RANGES, main);
    let mut plc = Plc::new(&p);
    plc.field.input("P0000", true);
    plc.set_mode(Mode::Run);
    plc.run_for(100 * MS);
    plc.set_mode(Mode::Stop);
    let (tmr, ton) = (plc.read("T1500"), plc.read("T1501"));
    assert!(tmr >= 99 && ton >= 99, "both timed: {tmr} {ton}");
    plc.set_mode(Mode::Run);
    plc.run_for(20 * MS);
    assert!(plc.read("T1500") >= tmr + 19, "TMR counted on from {tmr}: {}", plc.read("T1500"));
    assert!(plc.read("T1501") <= 21, "TON started over: {}", plc.read("T1501"));
}
