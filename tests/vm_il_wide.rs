//! The instruction list's double-word (`D…`) and real (`R…`) instructions: a double word is a
//! device word (low half) and the word after it (high half). Expected values are worked out by
//! hand in the comments.
mod harness;
use harness::vm::{try_assemble, Rig};
use plcd::lang::ops::{Op, Written};
use plcd::vm::{Exit, ERR_DIVIDE_BY_ZERO};

/// The double word at `device` and the next word.
fn dword(rig: &Rig, device: &str) -> u32 {
    let lo = rig.get(device) as u16 as u32;
    let number: u32 = device[1..].parse().unwrap();
    let hi = rig.get(&format!("D{:05}", number + 1)) as u16 as u32;
    lo | hi << 16
}

fn real(rig: &Rig, device: &str) -> f32 {
    f32::from_bits(dword(rig, device))
}

fn set_dword(rig: &mut Rig, device: &str, value: u32) {
    let number: u32 = device[1..].parse().unwrap();
    rig.set(device, (value & 0xFFFF) as i32);
    rig.set(&format!("D{:05}", number + 1), (value >> 16) as i32);
}

#[test]
fn dmov_moves_two_words_low_word_first() {
    let mut rig = Rig::new(
        "DMOV 100000 D00000\nDMOV h12345678 D00002\nDMOV -1 D00004\nDMOV D00000 D00006\n\
         DMOV 4294967295 D00008\nEND",
    );
    rig.scan();
    // 100000 = 0x0001_86A0: D00000 = 0x86A0 (-31072 as a signed word), D00001 = 1.
    assert_eq!(rig.get("D00000"), 0x86A0 - 65536);
    assert_eq!(rig.get("D00001"), 1);
    assert_eq!(rig.get("D00002"), 0x5678);
    assert_eq!(rig.get("D00003"), 0x1234);
    assert_eq!(dword(&rig, "D00004"), 0xFFFF_FFFF);
    assert_eq!(dword(&rig, "D00006"), 100_000);
    assert_eq!(dword(&rig, "D00008"), 0xFFFF_FFFF);
}

#[test]
fn double_word_arithmetic_is_32_bit_signed_and_wraps() {
    let mut rig = Rig::new(
        "DADD 70000 70000 D00000\nDSUB 0 1 D00002\nDMUL 65536 65536 D00004\n\
         DMUL 100000 -3 D00006\nDDIV -7 2 D00008\nDADD 2147483647 1 D00010\n\
         DDIV -2147483648 -1 D00012\nDMUL 46341 46341 D00014\nEND",
    );
    rig.scan();
    assert_eq!(dword(&rig, "D00000"), 140_000);
    assert_eq!(dword(&rig, "D00002") as i32, -1);
    // 2^16 × 2^16 = 2^32: the low 32 bits are 0.
    assert_eq!(dword(&rig, "D00004"), 0);
    assert_eq!(dword(&rig, "D00006") as i32, -300_000);
    assert_eq!(dword(&rig, "D00008") as i32, -3, "truncated toward zero");
    assert_eq!(dword(&rig, "D00010") as i32, i32::MIN, "wraps");
    assert_eq!(dword(&rig, "D00012") as i32, i32::MIN);
    // 46341² = 2147488281 = 2^31 + 4633: wraps to -2147479015.
    assert_eq!(dword(&rig, "D00014") as i32, -2_147_479_015);
    assert!(rig.exits.is_empty());
}

#[test]
fn ddiv_by_zero_is_3400h_and_leaves_the_destination() {
    let mut rig = Rig::new("DMOV 5 D00010\nDDIV 10 D00000 D00010\nDMOV 7 D00012\nEND");
    rig.scan();
    assert_eq!(dword(&rig, "D00010"), 5, "left as it was");
    assert_eq!(dword(&rig, "D00012"), 7, "execution goes on");
    assert!(matches!(rig.exits[..], [Exit::OperationError { code: ERR_DIVIDE_BY_ZERO, pc: 1 }]));
    assert_eq!(rig.get("_ERR_CODE"), 0x3400);
}

#[test]
fn real_arithmetic() {
    let mut rig = Rig::new(
        "RMOV 1.5 D00000\nRADD D00000 2.25 D00002\nRSUB D00000 4 D00004\nRMUL D00002 -2 D00006\n\
         RDIV 1 3 D00008\nRDIV 1 0 D00010\nRMOV 1e30 D00012\nRMUL D00012 D00012 D00014\nEND",
    );
    rig.scan();
    assert_eq!(real(&rig, "D00000"), 1.5);
    // 1.5 = 0x3FC00000: the high word is 0x3FC0, the low word 0.
    assert_eq!((rig.get("D00000"), rig.get("D00001")), (0, 0x3FC0));
    assert_eq!(real(&rig, "D00002"), 3.75);
    assert_eq!(real(&rig, "D00004"), -2.5);
    assert_eq!(real(&rig, "D00006"), -7.5);
    assert_eq!(real(&rig, "D00008"), 1.0f32 / 3.0);
    assert_eq!(dword(&rig, "D00010"), 0, "division by zero leaves the destination");
    assert!(matches!(rig.exits[..], [Exit::OperationError { code: ERR_DIVIDE_BY_ZERO, pc: 5 }]));
    assert_eq!(real(&rig, "D00014"), f32::INFINITY, "overflow is no error");
}

#[test]
fn dinc_and_ddec_carry_into_the_high_word() {
    let mut rig = Rig::new("DINC D00000\nDDEC D00002\nEND");
    set_dword(&mut rig, "D00000", 0x0000_FFFF);
    rig.scan();
    assert_eq!(dword(&rig, "D00000"), 0x0001_0000);
    assert_eq!(dword(&rig, "D00002"), 0xFFFF_FFFF, "0 - 1 wraps");
    set_dword(&mut rig, "D00000", 0xFFFF_FFFF);
    rig.scan();
    assert_eq!(dword(&rig, "D00000"), 0);
}

#[test]
fn pulse_forms_act_once_per_rising_edge() {
    let mut rig = Rig::new(
        "LOAD P0000\nDINCP D00000\nDADDP D00002 100000 D00002\nRADDP D00004 0.5 D00004\n\
         DMOVP D00000 D00006\nEND",
    );
    rig.set("P0000", 1).scan().scan().scan();
    assert_eq!(dword(&rig, "D00000"), 1);
    assert_eq!(dword(&rig, "D00002"), 100_000);
    assert_eq!(real(&rig, "D00004"), 0.5);
    assert_eq!(dword(&rig, "D00006"), 1);
    rig.set("P0000", 0).scan().set("P0000", 1).scan();
    assert_eq!(dword(&rig, "D00000"), 2);
    assert_eq!(dword(&rig, "D00002"), 200_000);
    assert_eq!(real(&rig, "D00004"), 1.0);
}

#[test]
fn data_instructions_follow_the_rung() {
    let mut rig = Rig::new("LOAD P0000\nDMOV 70000 D00000\nDINC D00002\nRADD 1 1 D00004\nEND");
    rig.scan();
    assert_eq!((dword(&rig, "D00000"), dword(&rig, "D00002"), dword(&rig, "D00004")), (0, 0, 0));
    rig.set("P0000", 1).scan();
    assert_eq!(dword(&rig, "D00000"), 70_000);
    assert_eq!(dword(&rig, "D00002"), 1);
    assert_eq!(real(&rig, "D00004"), 2.0);
}

#[test]
fn double_word_compare_contacts_are_signed_32_bit() {
    // D00000 = 70000, D00002 = -1 (0xFFFF_FFFF): as 16-bit words these would compare
    // differently (70000's low word is 4464; -1's words are both -1).
    let mut rig = Rig::new(
        "DMOV 70000 D00000\nDMOV -1 D00002\n\
         LOADD> D00000 D00002\nOUT M0000\n\
         LOADD< D00002 0\nOUT M0001\n\
         LOADD= D00000 70000\nOUT M0002\n\
         LOADD<> D00000 70000\nOUT M0003\n\
         LOADD>= D00000 70001\nOUT M0004\n\
         LOADD<= -2147483648 D00002\nOUT M0005\n\
         LOAD _ON\nANDD= D00002 hFFFFFFFF\nOUT M0006\n\
         LOAD _OFF\nORD> D00000 65535\nOUT M0007\n\
         LOAD _ON\nLOADD= D00000 0\nOR LOAD\nOUT M0008\nEND",
    );
    rig.scan();
    let bits: Vec<i32> = (0..9).map(|n| rig.get(&format!("M000{n}"))).collect();
    assert_eq!(bits, [1, 1, 1, 0, 0, 1, 1, 1, 1]);
}

#[test]
fn real_compare_contacts() {
    let mut rig = Rig::new(
        "RMOV 1.5 D00000\nRMOV -0.25 D00002\nRDIV 0 0 D00004\n\
         LOADR> D00000 D00002\nOUT M0000\n\
         LOADR= D00000 1.5\nOUT M0001\n\
         LOADR< D00000 1\nOUT M0002\n\
         LOADR>= D00002 -0.25\nOUT M0003\n\
         LOADR<= D00002 -1e3\nOUT M0004\n\
         LOADR<> D00000 1.5\nOUT M0005\n\
         LOAD _ON\nANDR= D00000 1.5\nOUT M0006\n\
         LOAD _OFF\nORR< D00002 0\nOUT M0007\nEND",
    );
    rig.scan();
    let bits: Vec<i32> = (0..8).map(|n| rig.get(&format!("M000{n}"))).collect();
    assert_eq!(bits, [1, 1, 0, 1, 0, 0, 1, 1]);
}

#[test]
fn a_nan_satisfies_only_not_equal() {
    // D00000 holds a NaN pattern (0x7FC00000: high word 0x7FC0).
    let mut rig = Rig::new(
        "LOADR= D00000 0\nOUT M0000\nLOADR< D00000 0\nOUT M0001\nLOADR> D00000 0\nOUT M0002\n\
         LOADR<> D00000 0\nOUT M0003\nEND",
    );
    rig.set("D00001", 0x7FC0).scan();
    let bits: Vec<i32> = (0..4).map(|n| rig.get(&format!("M000{n}"))).collect();
    assert_eq!(bits, [0, 0, 0, 1]);
}

#[test]
fn conversions() {
    let mut rig = Rig::new(
        "I2D -5 D00000\nD2I 70000 D00002\nI2R D00010 D00004\nR2I 2.5 D00006\nR2I -1e9 D00007\n\
         D2R 16777217 D00008\nR2D -2.5 D00012\nR2D 1e20 D00014\nEND",
    );
    rig.set("D00010", -300).scan();
    assert_eq!(dword(&rig, "D00000") as i32, -5);
    // 70000 = 0x11170: the low 16 bits are 0x1170 = 4464.
    assert_eq!(rig.get("D00002"), 4464);
    assert_eq!(real(&rig, "D00004"), -300.0);
    assert_eq!(rig.get("D00006"), 3, "rounded half away from zero");
    assert_eq!(rig.get("D00007"), -32768, "saturated");
    assert_eq!(real(&rig, "D00008"), 16_777_216.0, "the nearest REAL");
    assert_eq!(dword(&rig, "D00012") as i32, -3);
    assert_eq!(dword(&rig, "D00014") as i32, i32::MAX);
}

#[test]
fn ops_say_what_they_write_and_keep() {
    let program = harness::vm::assemble(
        "LOAD P0000\nDMOVP 1 P010\nDADD 1 2 D00000\nRADD 1 2 D00002\nDINC D00004\n\
         D2I 5 D00006\nI2D 5 D00008\nEND",
    );
    let writes: Vec<Option<Written>> = program.code.iter().map(Op::writes).collect();
    assert!(matches!(writes[1], Some(Written::DoubleWord(_))));
    assert!(writes[2..5].iter().all(|w| matches!(w, Some(Written::DoubleWord(_)))));
    assert!(matches!(writes[5], Some(Written::Word(_))));
    assert!(matches!(writes[6], Some(Written::DoubleWord(_))));
    assert!(program.code[1].edge_memory().is_some());
    assert!(program.code[2].edge_memory().is_none());
    // Constants are kept once each: 1, 2 and REAL 1.0, 2.0, and 5 (twice).
    assert_eq!(program.consts.len(), 5);
}

#[test]
fn operand_errors_are_precise() {
    let error = |source: &str| try_assemble(source).unwrap_err().to_string();
    let e = error("DMOV 0 D32767\nEND");
    assert!(
        e.contains("`D32767` as a double word needs `D32768` too, which is out of range"),
        "{e}"
    );
    let e = error("DADD D00000 1.5 D00002\nEND");
    assert!(e.contains("`DADD` needs an integer constant, found real constant `1.5`"), "{e}");
    let e = error("RADD D00000 h10 D00002\nEND");
    assert!(e.contains("`RADD` needs a real constant (like 1.5), found `h10`"), "{e}");
    let e = error("DMOV 4294967296 D00000\nEND");
    assert!(e.contains("is not a 32-bit value"), "{e}");
    let e = error("DMOV D00000 _SCAN_CUR\nEND");
    assert!(e.contains("`_SCAN_CUR` is a single word"), "{e}");
    let e = error("DMOV D00000 SD8330\nEND");
    assert!(e.contains("read-only"), "{e}");
    let e = error("DMOV 1 2\nEND");
    assert!(e.contains("needs a device here, found constant `2`"), "{e}");
    let e = error("DINC P127\nEND");
    assert!(e.contains("`P127` as a double word needs `P128` too"), "{e}");
    let e = error("LOADD= T2047 0\nOUT M0000\nEND");
    assert!(e.contains("`T2047` as a double word needs `T2048` too"), "{e}");
    let e = error("DMOV 1\nEND");
    assert!(e.contains("`DMOV` takes 2 operands (source, destination), found 1"), "{e}");
    assert!(try_assemble("DMOV 0 D32766\nLOADR= D32766 0\nOUT M0000\nEND").is_ok());
}
