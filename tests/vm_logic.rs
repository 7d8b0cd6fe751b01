//! Contacts, block logic, stacks, edges and outputs.
mod harness;
use harness::vm::Rig;

/// Truth table of `f` over inputs P0000/P0001/P0002, checked on output P0040.
fn truth(source: &str, f: impl Fn(bool, bool, bool) -> bool) {
    let mut rig = Rig::new(source);
    for bits in 0..8 {
        let (a, b, c) = (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0);
        rig.set("P0000", a as i32).set("P0001", b as i32).set("P0002", c as i32).scan();
        assert_eq!(rig.get("P0040") != 0, f(a, b, c), "{source} with {a} {b} {c}");
    }
}

#[test]
fn series_parallel_and_negation() {
    truth("LOAD P0000\nAND P0001\nOUT P0040\nEND", |a, b, _| a && b);
    truth("LOAD P0000\nOR P0001\nOUT P0040\nEND", |a, b, _| a || b);
    truth("LOAD NOT P0000\nAND NOT P0001\nOUT P0040\nEND", |a, b, _| !a && !b);
    truth("LOAD P0000\nOR NOT P0001\nOUT P0040\nEND", |a, b, _| a || !b);
    truth("LOAD P0000\nNOT\nOUT P0040\nEND", |a, _, _| !a);
    truth("LOAD P0000\nOUT NOT P0040\nEND", |a, _, _| !a);
}

#[test]
fn block_logic() {
    // (a OR b) AND (c OR NOT a)
    truth("LOAD P0000\nOR P0001\nLOAD P0002\nOR NOT P0000\nAND LOAD\nOUT P0040\nEND", |a, b, c| {
        (a || b) && (c || !a)
    });
    // (a AND b) OR (b AND c) OR (NOT c)
    truth(
        "LOAD P0000\nAND P0001\nLOAD P0001\nAND P0002\nOR LOAD\nLOAD NOT P0002\nOR LOAD\nOUT P0040\nEND",
        // (a AND b) OR (b AND c) OR NOT c, which is b OR NOT c
        |_, b, c| b || !c,
    );
    // Nested: a AND (b OR (c AND NOT b)), which is a AND (b OR c)
    truth(
        "LOAD P0000\nLOAD P0001\nLOAD P0002\nAND NOT P0001\nOR LOAD\nAND LOAD\nOUT P0040\nEND",
        |a, b, c| a && (b || c),
    );
}

#[test]
fn branch_stack() {
    let source = "LOAD P0000\nMPUSH\nAND P0001\nOUT P0040\nMLOAD\nAND P0002\nOUT P0041\nMPOP\nAND NOT P0001\nOUT P0042\nEND";
    let mut rig = Rig::new(source);
    for bits in 0..8 {
        let (a, b, c) = (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0);
        rig.set("P0000", a as i32).set("P0001", b as i32).set("P0002", c as i32).scan();
        assert_eq!(rig.get("P0040") != 0, a && b);
        assert_eq!(rig.get("P0041") != 0, a && c);
        assert_eq!(rig.get("P0042") != 0, a && !b);
    }
}

#[test]
fn rung_result_is_on_at_program_start() {
    let mut rig = Rig::new("OUT M0000\nMOV 7 D00001\nEND");
    rig.scan();
    assert_eq!(rig.get("M0000"), 1);
    assert_eq!(rig.get("D00001"), 7);
}

#[test]
fn several_outputs_and_continued_rungs() {
    let mut rig =
        Rig::new("LOAD P0000\nOUT M0000\nAND P0001\nOUT M0001\nLOAD P0001\nOUT M0002\nEND");
    rig.set("P0000", 1).scan();
    assert_eq!((rig.get("M0000"), rig.get("M0001"), rig.get("M0002")), (1, 0, 0));
    rig.set("P0001", 1).scan();
    assert_eq!((rig.get("M0000"), rig.get("M0001"), rig.get("M0002")), (1, 1, 1));
}

#[test]
fn compare_contacts_are_signed() {
    let mut rig = Rig::new(
        "LOAD= D00000 5\nOUT M0000\nLOAD<> D00000 5\nOUT M0001\nLOAD> D00000 D00001\nOUT M0002\n\
         LOAD>= D00000 5\nOUT M0003\nLOAD< D00000 -1\nOUT M0004\nLOAD<= D00000 5\nAND> D00000 0\nOR= D00000 -7\nOUT M0005\nEND",
    );
    let outs = |rig: &Rig| (0..6).map(|i| rig.get(&format!("M000{i}"))).collect::<Vec<_>>();
    rig.set("D00000", 5).set("D00001", 4).scan();
    assert_eq!(outs(&rig), [1, 0, 1, 1, 0, 1]);
    rig.set("D00000", -7).scan();
    assert_eq!(outs(&rig), [0, 1, 0, 0, 1, 1]);
    rig.set("D00000", 0).scan();
    assert_eq!(outs(&rig), [0, 1, 0, 0, 0, 0]);
}

#[test]
fn edge_contacts_fire_once_per_edge() {
    let mut rig = Rig::new(
        "LOADP P0000\nOUT M0000\nLOADN P0000\nOUT M0001\nLOAD M0100\nANDP P0000\nOUT M0002\n\
         LOAD M0101\nORN P0000\nOUT M0003\nEND",
    );
    rig.set("M0100", 1);
    let row = |rig: &Rig| [rig.get("M0000"), rig.get("M0001"), rig.get("M0002"), rig.get("M0003")];
    rig.scan();
    assert_eq!(row(&rig), [0, 0, 0, 0]);
    rig.set("P0000", 1).scan();
    assert_eq!(row(&rig), [1, 0, 1, 0]);
    rig.scan();
    assert_eq!(row(&rig), [0, 0, 0, 0]);
    rig.set("P0000", 0).scan();
    assert_eq!(row(&rig), [0, 1, 0, 1]);
    rig.scan();
    assert_eq!(row(&rig), [0, 0, 0, 0]);
}

#[test]
fn each_edge_instruction_has_its_own_memory() {
    // The same contact read twice in one scan: both instances see the edge.
    let mut rig = Rig::new("LOADP P0000\nOUT M0000\nLOADP P0000\nOUT M0001\nEND");
    rig.set("P0000", 1).scan();
    assert_eq!((rig.get("M0000"), rig.get("M0001")), (1, 1));
}

#[test]
fn pulse_outputs_set_reset_flip_flop() {
    let mut rig = Rig::new(
        "LOAD P0000\nOUTP M0000\nOUTN M0001\nLOAD P0001\nSET M0002\nLOAD P0002\nRST M0002\nLOAD P0000\nFF M0003\nEND",
    );
    let row = |rig: &Rig| [rig.get("M0000"), rig.get("M0001"), rig.get("M0002"), rig.get("M0003")];
    rig.set("P0000", 1).scan();
    assert_eq!(row(&rig), [1, 0, 0, 1]);
    rig.scan();
    assert_eq!(row(&rig), [0, 0, 0, 1]);
    rig.set("P0000", 0).set("P0001", 1).scan();
    assert_eq!(row(&rig), [0, 1, 1, 1]);
    rig.set("P0001", 0).scan();
    assert_eq!(row(&rig), [0, 0, 1, 1], "SET holds");
    rig.set("P0000", 1).set("P0002", 1).scan();
    assert_eq!(row(&rig), [1, 0, 0, 0], "RST clears, FF toggles back");
}

#[test]
fn bits_of_words_and_keep_relays() {
    let mut rig = Rig::new("LOAD D00010.3\nOUT K0001\nLOAD P0000\nOUT D00011.F\nEND");
    rig.set("D00010", 8).set("P0000", 1).scan();
    assert_eq!(rig.get("K0001"), 1);
    assert_eq!(rig.get("D00011") as u16, 0x8000);
}

#[test]
fn system_bits() {
    let mut rig = Rig::new(
        "LOAD SM400\nAND NOT SM401\nOUT M0000\nLOAD SM402\nOUT M0001\nLOAD _1ON\nOUT M0002\nLOAD _ON\nAND NOT _OFF\nOUT M0003\nEND",
    );
    rig.scan();
    assert_eq!(
        [rig.get("M0000"), rig.get("M0001"), rig.get("M0002"), rig.get("M0003")],
        [1, 1, 1, 1]
    );
    rig.scan();
    assert_eq!(
        [rig.get("M0000"), rig.get("M0001"), rig.get("M0002"), rig.get("M0003")],
        [1, 0, 0, 1]
    );
}
