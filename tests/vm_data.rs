//! Data instructions: 16-bit two's-complement arithmetic, operation errors, `P` forms.
mod harness;
use harness::vm::Rig;
use plcd::vm::Exit;

#[test]
fn moves_and_arithmetic_wrap_at_16_bits() {
    let mut rig = Rig::new(
        "MOV 32767 D00000\nADD D00000 1 D00001\nSUB -32768 1 D00002\nMUL 300 300 D00003\n\
         DIV -7 2 D00004\nDIV -32768 -1 D00005\nMOV hFFFF D00006\nINC D00007\nDEC D00008\nEND",
    );
    rig.set("D00007", 32767).scan();
    assert_eq!(rig.get("D00000"), 32767);
    assert_eq!(rig.get("D00001"), -32768);
    assert_eq!(rig.get("D00002"), 32767);
    assert_eq!(rig.get("D00003"), 90000 - 65536);
    assert_eq!(rig.get("D00004"), -3, "division truncates toward zero");
    assert_eq!(rig.get("D00005"), -32768);
    assert_eq!(rig.get("D00006"), -1);
    assert_eq!(rig.get("D00007"), -32768);
    assert_eq!(rig.get("D00008"), -1);
    assert!(rig.exits.is_empty());
}

#[test]
fn data_instructions_follow_the_rung() {
    let mut rig = Rig::new("LOAD P0000\nMOV 5 D00000\nADD D00001 1 D00001\nEND");
    rig.scan();
    assert_eq!((rig.get("D00000"), rig.get("D00001")), (0, 0));
    rig.set("P0000", 1).scan().scan();
    assert_eq!((rig.get("D00000"), rig.get("D00001")), (5, 2));
}

#[test]
fn pulse_forms_execute_once_per_rising_edge() {
    let mut rig = Rig::new(
        "LOAD P0000\nINCP D00000\nMOVP D00000 D00001\nADDP D00002 10 D00002\nDECP D00003\nEND",
    );
    rig.set("P0000", 1).scan().scan().scan();
    assert_eq!(
        [rig.get("D00000"), rig.get("D00001"), rig.get("D00002"), rig.get("D00003")],
        [1, 1, 10, -1]
    );
    rig.set("P0000", 0).scan().set("P0000", 1).scan();
    assert_eq!(
        [rig.get("D00000"), rig.get("D00001"), rig.get("D00002"), rig.get("D00003")],
        [2, 2, 20, -2]
    );
}

#[test]
fn division_by_zero_sets_err_and_execution_goes_on() {
    let mut rig = Rig::new("MOV 9 D00001\nDIV 10 D00000 D00001\nOUT M0000\nEND");
    rig.scan();
    assert_eq!(rig.exits, vec![Exit::OperationError { code: 0x3400, pc: 1 }]);
    assert_eq!(rig.get("_ERR"), 1);
    assert_eq!(rig.get("_ERR_CODE") as u16, 0x3400);
    assert_eq!(rig.get("D00001"), 9, "destination unchanged");
    assert_eq!(rig.get("M0000"), 1, "the next instruction ran");
    rig.set("D00000", 2);
    rig.vm.begin_scan(false, 0);
    assert_eq!(rig.get("_ERR"), 0, "cleared when a new scan starts");
    rig.scan();
    assert_eq!(rig.get("D00001"), 5);
    assert!(rig.exits.is_empty());
}

#[test]
fn timer_and_counter_values_are_words() {
    let mut rig = Rig::new("MOV 7 C0000\nADD C0000 T0000 D00000\nEND");
    rig.set("T0000", 3).scan();
    assert_eq!(rig.get("D00000"), 10);
}

#[test]
fn scan_time_words_are_readable() {
    let mut rig = Rig::new("MOV _SCAN_MAX D00000\nEND");
    rig.vm.mem.set_scan_times(3, 2, 17);
    rig.scan();
    assert_eq!(rig.get("D00000"), 17);
}
