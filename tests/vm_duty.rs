//! DUTY per the Mitsubishi FX5 page.
mod harness;
use harness::vm::Rig;
use plcd::vm::Exit;

/// SM420 after END of each of `scans` scans, as seen by the next scan's program.
fn relay_trace(rig: &mut Rig, scans: usize, relay: &str) -> Vec<i32> {
    (0..scans).map(|_| rig.scan().get(relay)).collect()
}

#[test]
fn fx5_example_on_one_scan_off_three() {
    // "When X0 is set to ON, SM420 is set to ON for 1 scan, and is set to OFF for 3 scans."
    let mut rig = Rig::new("LOAD P0000\nDUTY 1 3 SM420\nLOAD SM420\nOUT M0000\nEND");
    rig.scan();
    assert_eq!(rig.get("SM420"), 0, "nothing before the command");
    rig.set("P0000", 1);
    assert_eq!(relay_trace(&mut rig, 9, "SM420"), [1, 0, 0, 0, 1, 0, 0, 0, 1]);
    // The program sees the relay switched at the previous END.
    rig.scan();
    assert_eq!(rig.get("M0000"), 1);
}

#[test]
fn scan_counter_counts_and_resets_at_n1_plus_n2() {
    let mut rig = Rig::new("LOAD P0000\nDUTY 2 3 SM8331\nEND");
    rig.set("P0000", 1);
    assert_eq!(relay_trace(&mut rig, 10, "SD8331"), [1, 2, 3, 4, 0, 1, 2, 3, 4, 0]);
    let mut rig = Rig::new("LOAD P0000\nDUTY 2 3 SM8331\nEND");
    rig.set("P0000", 1);
    assert_eq!(relay_trace(&mut rig, 10, "SM421"), [1, 1, 0, 0, 0, 1, 1, 0, 0, 0]);
}

#[test]
fn command_off_does_not_stop_and_command_on_restarts() {
    let mut rig = Rig::new("LOAD P0000\nDUTY 1 2 SM422\nEND");
    rig.set("P0000", 1).scan();
    rig.set("P0000", 0);
    assert_eq!(relay_trace(&mut rig, 4, "SM422"), [0, 0, 1, 0]);
    assert_eq!(rig.get("SD8332"), 2);
    // Without a restart the next END would be OFF; the new command resets the count to 0.
    rig.set("P0000", 1);
    assert_eq!(relay_trace(&mut rig, 3, "SM422"), [1, 0, 0]);
}

#[test]
fn zero_scans_fix_the_relay() {
    let mut rig = Rig::new("LOAD P0000\nDUTY 0 5 SM423\nDUTY 4 0 SM424\nEND");
    rig.set("P0000", 1);
    for _ in 0..8 {
        rig.scan();
        assert_eq!((rig.get("SM423"), rig.get("SM424")), (0, 1));
    }
}

#[test]
fn stop_stops_the_clocks() {
    let mut rig = Rig::new("LOAD P0000\nDUTY 1 1 SM420\nEND");
    rig.set("P0000", 1).scan();
    assert_eq!(rig.get("SM420"), 1);
    rig.vm.stop();
    assert_eq!((rig.get("SM420"), rig.get("SD8330")), (0, 0));
    rig.set("P0000", 0);
    assert_eq!(relay_trace(&mut rig, 3, "SM420"), [0, 0, 0], "not running again until commanded");
}

#[test]
fn scan_counts_from_devices_are_checked_at_run_time() {
    let mut rig = Rig::new("LOAD P0000\nDUTY D00000 D00001 SM420\nEND");
    rig.set("D00000", -1).set("D00001", 3).set("P0000", 1).scan();
    assert_eq!(rig.exits, vec![Exit::OperationError { code: 0x3405, pc: 1 }]);
    assert_eq!(rig.get("_ERR_CODE") as u16, 0x3405);
    assert_eq!(rig.get("SM420"), 0, "not started");
    rig.set("D00000", 1).set("P0000", 0).scan().set("P0000", 1);
    assert_eq!(relay_trace(&mut rig, 4, "SM420"), [1, 0, 0, 0]);
}
