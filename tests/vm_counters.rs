//! Counters per XGB §5.2.6: rising edges counted, reset by RST.
mod harness;
use harness::vm::Rig;

/// Pulses P0000 once (ON scan, OFF scan) and returns (current value, contact via M0100).
fn pulse(rig: &mut Rig, counter: &str) -> (i32, i32) {
    rig.set("P0000", 1).scan();
    let after = (rig.get(counter), rig.get("M0100"));
    rig.set("P0000", 0).scan();
    after
}

#[test]
fn up_counter() {
    let mut rig =
        Rig::new("LOAD P0000\nCTU C0000 3\nLOAD C0000\nOUT M0100\nLOAD P0001\nRST C0000\nEND");
    rig.set("P0000", 1).scan().scan().scan();
    assert_eq!(rig.get("C0000"), 1, "a held input counts once");
    rig.set("P0000", 0).scan();
    assert_eq!(pulse(&mut rig, "C0000"), (2, 0));
    assert_eq!(pulse(&mut rig, "C0000"), (3, 1));
    assert_eq!(pulse(&mut rig, "C0000"), (4, 1));
    rig.set("P0001", 1).scan();
    assert_eq!(rig.get("C0000"), 0);
    rig.scan();
    assert_eq!(
        rig.get("M0100"),
        0,
        "the contact, read before RST in the program, follows a scan later"
    );
}

#[test]
fn down_counter_counts_down_from_the_preset() {
    let mut rig =
        Rig::new("LOAD P0000\nCTD C0001 3\nLOAD C0001\nOUT M0100\nLOAD P0001\nRST C0001\nEND");
    rig.scan();
    assert_eq!((rig.get("C0001"), rig.get("M0100")), (3, 0));
    assert_eq!(pulse(&mut rig, "C0001"), (2, 0));
    assert_eq!(pulse(&mut rig, "C0001"), (1, 0));
    assert_eq!(pulse(&mut rig, "C0001"), (0, 1));
    assert_eq!(pulse(&mut rig, "C0001"), (0, 1), "stays at 0");
    rig.set("P0001", 1).scan();
    assert_eq!(rig.get("C0001"), 3, "RST reloads the preset");
    rig.set("P0001", 0).scan();
    assert_eq!((rig.get("C0001"), rig.get("M0100")), (3, 0));
}

#[test]
fn up_down_counter() {
    let mut rig = Rig::new(
        "LOAD M0000\nCTUD C0002 P0000 P0001 2\nLOAD C0002\nOUT M0100\nLOAD P0002\nRST C0002\nEND",
    );
    rig.set("M0000", 1);
    let edge = |rig: &mut Rig, dev: &str| {
        rig.set(dev, 1).scan();
        rig.set(dev, 0).scan();
        (rig.get("C0002"), rig.get("M0100"))
    };
    assert_eq!(edge(&mut rig, "P0001"), (0, 0), "does not go below 0");
    assert_eq!(edge(&mut rig, "P0000"), (1, 0));
    assert_eq!(edge(&mut rig, "P0000"), (2, 1));
    assert_eq!(edge(&mut rig, "P0000"), (3, 1));
    assert_eq!(edge(&mut rig, "P0001"), (2, 1));
    assert_eq!(edge(&mut rig, "P0001"), (1, 0));
    rig.set("M0000", 0);
    assert_eq!(edge(&mut rig, "P0000"), (1, 0), "not counting while the rung is OFF");
    rig.set("M0000", 1).set("P0000", 1).set("P0001", 1).scan();
    assert_eq!(rig.get("C0002"), 1, "simultaneous up and down cancel");
    rig.set("P0002", 1).scan();
    assert_eq!(rig.get("C0002"), 0);
}

#[test]
fn ring_counter_wraps_to_zero_after_the_preset() {
    let mut rig =
        Rig::new("LOAD P0000\nCTR C0003 3\nLOAD C0003\nOUT M0100\nLOAD P0001\nRST C0003\nEND");
    assert_eq!(pulse(&mut rig, "C0003"), (1, 0));
    assert_eq!(pulse(&mut rig, "C0003"), (2, 0));
    assert_eq!(pulse(&mut rig, "C0003"), (3, 1));
    assert_eq!(pulse(&mut rig, "C0003"), (0, 0));
    assert_eq!(pulse(&mut rig, "C0003"), (1, 0));
    rig.set("P0001", 1).scan();
    assert_eq!(rig.get("C0003"), 0);
}

#[test]
fn up_counter_saturates() {
    let mut rig = Rig::new("LOAD P0000\nCTU C0004 10\nEND");
    rig.set("C0004", 65535);
    pulse(&mut rig, "C0004");
    assert_eq!(rig.get("C0004") as u16, 65535);
}
