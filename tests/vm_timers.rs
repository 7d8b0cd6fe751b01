//! Timers against the timing diagrams of XGB §5.2.5, on a hand-set clock.
//! T1000–T1499 have a 10 ms base, T0000–T0999 100 ms, T1500–T2047 1 ms (the defaults).
mod harness;
use harness::vm::Rig;

/// Scans at each `(ms, input P0000, expected current value, expected contact)`; the programs
/// mirror the timer's contact to M0100.
fn diagram(source: &str, timer: &str, steps: &[(u64, i32, i32, i32)]) {
    let mut rig = Rig::new(source);
    for &(ms, input, value, done) in steps {
        rig.set("P0000", input).scan_at_ms(ms);
        assert_eq!((rig.get(timer), rig.get("M0100")), (value, done), "{source} at {ms} ms");
    }
}

#[test]
fn on_delay() {
    diagram(
        "LOAD P0000\nTON T1000 5\nLOAD T1000\nOUT M0100\nEND",
        "T1000",
        &[
            (0, 0, 0, 0),
            (10, 1, 0, 0),
            (35, 1, 2, 0),
            (59, 1, 4, 0),
            (60, 1, 5, 1),
            (100, 1, 5, 1),
            (110, 0, 0, 0),
            (120, 1, 0, 0),
            (130, 0, 0, 0),
        ],
    );
}

#[test]
fn timer_keeps_the_remainder_of_a_tick() {
    // 7 ms scans against a 10 ms base: counting whole ticks per scan would never advance.
    // The value is always floor(elapsed / base) and the output is late by less than a scan.
    let mut rig = Rig::new("LOAD P0000\nTON T1000 10\nLOAD T1000\nOUT M0100\nEND");
    rig.set("P0000", 1);
    for scan in 0..=15u64 {
        let ms = scan * 7;
        rig.scan_at_ms(ms);
        let expected = (ms / 10).min(10) as i32;
        assert_eq!(rig.get("T1000"), expected, "at {ms} ms");
        assert_eq!(rig.get("M0100"), i32::from(ms >= 100), "at {ms} ms");
    }
}

#[test]
fn off_delay() {
    diagram(
        "LOAD P0000\nTOFF T1001 5\nLOAD T1001\nOUT M0100\nEND",
        "T1001",
        &[
            (0, 0, 0, 0),
            (5, 1, 5, 1),
            (10, 0, 5, 1),
            (30, 0, 3, 1),
            (59, 0, 1, 1),
            (60, 0, 0, 0),
            (80, 0, 0, 0),
            (90, 1, 5, 1),
            (100, 0, 5, 1),
            (120, 1, 5, 1),
            (130, 0, 5, 1),
            (180, 0, 0, 0),
        ],
    );
}

#[test]
fn integrating_timer_accumulates_and_only_rst_clears() {
    diagram(
        "LOAD P0000\nTMR T1002 5\nLOAD T1002\nOUT M0100\nLOAD P0001\nRST T1002\nEND",
        "T1002",
        &[
            (0, 1, 0, 0),
            (10, 1, 1, 0),
            (20, 1, 2, 0),
            (30, 0, 2, 0),
            (60, 0, 2, 0),
            (70, 1, 2, 0),
            (80, 1, 3, 0),
            (100, 1, 5, 1),
            (150, 1, 5, 1),
            (160, 0, 5, 1),
        ],
    );
    let mut rig = Rig::new("LOAD P0000\nTMR T1002 5\nLOAD P0001\nRST T1002\nEND");
    rig.set("P0000", 1).scan_at_ms(0).scan_at_ms(30);
    assert_eq!(rig.get("T1002"), 3);
    rig.set("P0000", 0).set("P0001", 1).scan_at_ms(40);
    assert_eq!(rig.get("T1002"), 0);
}

#[test]
fn monostable_ignores_its_input_while_running() {
    diagram(
        "LOAD P0000\nTMON T1003 5\nLOAD T1003\nOUT M0100\nEND",
        "T1003",
        &[
            (0, 1, 5, 1),
            (10, 0, 4, 1),
            (20, 1, 3, 1), // a new rising edge while running: ignored
            (49, 1, 1, 1),
            (50, 1, 0, 0),
            (60, 1, 0, 0), // still ON: no new pulse without a new edge
            (70, 0, 0, 0),
            (80, 1, 5, 1),
        ],
    );
}

#[test]
fn retriggerable_restarts_on_each_rising_edge() {
    diagram(
        "LOAD P0000\nTRTG T1004 5\nLOAD T1004\nOUT M0100\nEND",
        "T1004",
        &[
            (0, 1, 5, 1),
            (10, 0, 4, 1),
            (20, 1, 5, 1), // retriggered
            (30, 1, 4, 1),
            (69, 0, 1, 1),
            (70, 0, 0, 0),
        ],
    );
}

#[test]
fn time_bases_follow_the_timer_number() {
    let mut rig = Rig::new("LOAD P0000\nTON T0000 3\nTON T1500 3\nTON T1000 3\nEND");
    rig.set("P0000", 1).scan_at_ms(0).scan_at_ms(3);
    assert_eq!((rig.get("T0000"), rig.get("T1500"), rig.get("T1000")), (0, 3, 0));
    rig.scan_at_ms(30);
    assert_eq!((rig.get("T0000"), rig.get("T1500"), rig.get("T1000")), (0, 3, 3));
    rig.scan_at_ms(300);
    assert_eq!(rig.get("T0000"), 3);
}

#[test]
fn rst_restarts_a_running_on_delay() {
    let mut rig = Rig::new("LOAD P0000\nTON T1000 5\nLOAD P0001\nRST T1000\nEND");
    rig.set("P0000", 1).scan_at_ms(0).scan_at_ms(30);
    assert_eq!(rig.get("T1000"), 3);
    rig.set("P0001", 1).scan_at_ms(40);
    assert_eq!(rig.get("T1000"), 0);
    rig.set("P0001", 0).scan_at_ms(50).scan_at_ms(70);
    assert_eq!(rig.get("T1000"), 2, "counts again from the scan after RST");
}

#[test]
fn a_written_current_value_is_continued_from() {
    let mut rig = Rig::new("LOAD P0000\nTON T1000 10\nLOAD P0001\nMOVP 8 T1000\nEND");
    rig.set("P0000", 1).scan_at_ms(0).scan_at_ms(10);
    assert_eq!(rig.get("T1000"), 1);
    rig.set("P0001", 1).scan_at_ms(15);
    assert_eq!(rig.get("T1000"), 8);
    rig.scan_at_ms(25);
    assert_eq!(rig.get("T1000"), 9);
}

#[test]
fn preset_from_a_word_device() {
    let mut rig = Rig::new("LOAD P0000\nTON T1500 D00000\nLOAD T1500\nOUT M0100\nEND");
    rig.set("D00000", 4).set("P0000", 1).scan_at_ms(0).scan_at_ms(3);
    assert_eq!(rig.get("M0100"), 0);
    rig.scan_at_ms(4);
    assert_eq!(rig.get("M0100"), 1);
}
