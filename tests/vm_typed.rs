//! The typed stack machine of Structured Text, on programs built by hand: each op, the memory
//! spaces, calls with frames and `this`, the operation errors (3400H, 3402H) after which
//! execution goes on, strings, RUN start of variable memory, the tools' accessors, preemption
//! at any budget, and no panic on garbage.
mod harness;

use plcd::device::Address;
use plcd::lang::ops::{CmpOp, Op, Place, StrOp};
use plcd::lang::{Program, Variables};
use plcd::vm::{
    Clock, ExecState, Exit, ManualClock, StepClock, Vm, ERR_CALL_DEPTH, ERR_DIVIDE_BY_ZERO,
    ERR_INDEX_RANGE,
};
use plcd_core::device::RetainSet;
use plcd_core::value::{BinOp, Elem, Pointer, Space, UnOp};
use proptest::prelude::*;

fn program(code: Vec<Op>, consts: Vec<u64>, frame_bytes: u32) -> Program {
    harness::vm::typed_program("main", code, consts, frame_bytes)
}

struct Rig {
    vm: Vm,
    program: Program,
    state: ExecState,
    exits: Vec<Exit>,
}

impl Rig {
    fn new(code: Vec<Op>, consts: Vec<u64>, frame_bytes: u32, vars: usize) -> Rig {
        let program = program(code, consts, frame_bytes);
        let mut vm = Vm::for_programs([&program]);
        vm.set_variables(&Variables { initial: vec![0; vars].into(), ..Variables::default() });
        Rig { vm, state: ExecState::with_frame(frame_bytes), program, exits: Vec::new() }
    }

    fn scan_with<C: Clock>(&mut self, clock: &C) -> &mut Rig {
        self.state.restart();
        self.exits.clear();
        loop {
            match self.vm.run(&self.program, &mut self.state, clock, u64::MAX) {
                Exit::End => break,
                other => self.exits.push(other),
            }
        }
        self
    }

    fn scan(&mut self) -> &mut Rig {
        self.scan_with(&ManualClock::new(0))
    }

    fn var(&self, offset: u32, elem: Elem) -> u64 {
        self.vm.read_value(Pointer { space: Space::Var, offset }, elem)
    }

    fn word(&self, device: &str) -> i32 {
        self.vm.mem.read(&Address::parse(device).unwrap())
    }
}

fn word_place(device: &str) -> Place {
    Place::Word(Address::parse(device).unwrap().as_word().unwrap())
}

fn bit_place(device: &str) -> Place {
    Place::Bit(Address::parse(device).unwrap().as_bit().unwrap())
}

use Op::*;

#[test]
fn pushes_fetches_and_stores_little_endian() {
    let mut rig = Rig::new(
        vec![
            PushInt(-2),
            Store { elem: Elem::I16, at: Place::Var(0) },
            PushConst(0),
            Store { elem: Elem::U64, at: Place::Var(2) },
            PushConst(1),
            Store { elem: Elem::F32, at: Place::Var(10) },
            Fetch { elem: Elem::I16, at: Place::Var(0) },
            Conv { from: Elem::I16, to: Elem::I64 },
            Store { elem: Elem::I64, at: Place::Var(14) },
            PushInt(7),
            Store { elem: Elem::Bool, at: Place::Var(22) },
            End,
        ],
        vec![0x0102_0304_0506_0708, u64::from(1.5f32.to_bits())],
        0,
        32,
    );
    rig.scan();
    let vars = rig.vm.vars();
    assert_eq!(&vars[0..2], &[0xFE, 0xFF]);
    assert_eq!(&vars[2..10], &[8, 7, 6, 5, 4, 3, 2, 1]);
    assert_eq!(&vars[10..14], &1.5f32.to_le_bytes());
    assert_eq!(rig.var(14, Elem::I64) as i64, -2);
    assert_eq!(vars[22], 1, "a BOOL is stored as 0/1");
    assert!(rig.exits.is_empty());
    assert_eq!(rig.state.eval_depth(), 0);
}

#[test]
fn arithmetic_compare_convert_dup_drop() {
    let mut rig = Rig::new(
        vec![
            PushInt(100),
            PushInt(28),
            Bin { op: BinOp::Add, elem: Elem::I8 }, // 128 wraps to -128
            Dup,
            Un { op: UnOp::Neg, elem: Elem::I8 }, // -(-128) = -128
            Cmp { op: CmpOp::Eq, elem: Elem::I8 },
            Store { elem: Elem::Bool, at: Place::Var(0) },
            PushInt(7),
            PushInt(2),
            Bin { op: BinOp::Mod, elem: Elem::I32 },
            Conv { from: Elem::I32, to: Elem::F64 },
            Un { op: UnOp::Sqrt, elem: Elem::F64 },
            Store { elem: Elem::F64, at: Place::Var(8) },
            PushInt(1),
            PushInt(2),
            Drop,
            Store { elem: Elem::U8, at: Place::Var(16) },
            End,
        ],
        vec![],
        0,
        32,
    );
    rig.scan();
    assert_eq!(rig.var(0, Elem::Bool), 1);
    assert_eq!(f64::from_bits(rig.var(8, Elem::F64)), 1.0);
    assert_eq!(rig.var(16, Elem::U8), 1);
}

#[test]
fn division_by_zero_pushes_0_raises_3400h_and_goes_on() {
    let mut rig = Rig::new(
        vec![
            PushInt(5),
            PushInt(0),
            Bin { op: BinOp::Div, elem: Elem::I32 },
            Store { elem: Elem::I32, at: Place::Var(0) },
            PushConst(0),
            PushConst(1),
            Bin { op: BinOp::Div, elem: Elem::F64 },
            Store { elem: Elem::F64, at: Place::Var(4) },
            PushInt(9),
            Store { elem: Elem::I32, at: Place::Var(12) },
            End,
        ],
        vec![1f64.to_bits(), 0f64.to_bits()],
        0,
        16,
    );
    rig.vm.write_value(Pointer { space: Space::Var, offset: 0 }, Elem::I32, 77);
    rig.scan();
    assert_eq!(
        rig.exits,
        [
            Exit::OperationError { code: ERR_DIVIDE_BY_ZERO, pc: 2 },
            Exit::OperationError { code: ERR_DIVIDE_BY_ZERO, pc: 6 },
        ]
    );
    assert_eq!(rig.var(0, Elem::I32), 0, "the failed operation's result is 0");
    assert_eq!(rig.var(4, Elem::F64), 0);
    assert_eq!(rig.var(12, Elem::I32), 9, "execution went on");
    assert_eq!(rig.word("_ERR_CODE"), 0x3400);
    assert_eq!(rig.word("_ERR"), 1);
}

#[test]
fn device_memory_multi_word_values_low_word_first() {
    let mut rig = Rig::new(
        vec![
            PushConst(0),
            Store { elem: Elem::I32, at: word_place("D00100") },
            PushInt(-1),
            Store { elem: Elem::I8, at: word_place("D00102") },
            PushInt(200),
            Store { elem: Elem::U8, at: word_place("D00103") },
            PushConst(1),
            Store { elem: Elem::F64, at: word_place("D00104") },
            PushInt(1),
            Store { elem: Elem::Bool, at: bit_place("M0013") },
            Fetch { elem: Elem::I32, at: word_place("D00100") },
            Store { elem: Elem::I32, at: Place::Var(0) },
            Fetch { elem: Elem::I8, at: word_place("D00110") },
            Store { elem: Elem::I8, at: Place::Var(4) },
            Fetch { elem: Elem::Bool, at: bit_place("M0013") },
            Fetch { elem: Elem::Bool, at: bit_place("M0012") },
            Bin { op: BinOp::Or, elem: Elem::Bool },
            Store { elem: Elem::Bool, at: Place::Var(5) },
            End,
        ],
        vec![0x0001_86A0, 2.5f64.to_bits()],
        0,
        8,
    );
    rig.vm.mem.write(&Address::parse("D00110").unwrap(), 0x12F0);
    rig.scan();
    assert_eq!((rig.word("D00100"), rig.word("D00101")), (0x86A0 - 65536, 1));
    assert_eq!(rig.word("D00102"), -1, "an 8-bit value sign-extended into its word");
    assert_eq!(rig.word("D00103"), 200, "zero-extended");
    let bits = 2.5f64.to_bits();
    let words: Vec<u16> = (104..108).map(|n| rig.word(&format!("D{n:05}")) as u16).collect();
    assert_eq!(words, [bits as u16, (bits >> 16) as u16, (bits >> 32) as u16, (bits >> 48) as u16]);
    assert_eq!(rig.word("M0013"), 1);
    assert_eq!(rig.word("M001"), 1 << 3);
    assert_eq!(rig.var(0, Elem::I32), 100_000);
    assert_eq!(rig.var(4, Elem::I8) as i64, -16, "the low byte 0xF0");
    assert_eq!(rig.var(5, Elem::Bool), 1);
}

#[test]
fn pointers_index_offset_and_indirect_access() {
    // ARRAY[1..3] OF INT at Var(10), a struct { a: SINT; b: DINT } at Var(20).
    let mut rig = Rig::new(
        vec![
            AddrOf(Place::Var(10)),
            PushInt(3),
            Index { lo: 1, len: 3, stride: 2 },
            PushInt(-300),
            StoreInd(Elem::I16),
            AddrOf(Place::Var(20)),
            Offset(1),
            PushInt(123_456),
            StoreInd(Elem::I32),
            AddrOf(Place::Var(20)),
            Offset(1),
            FetchInd(Elem::I32),
            Store { elem: Elem::I32, at: Place::Var(0) },
            // An array of words at a device: stride 1 word.
            AddrOf(word_place("D00200")),
            PushInt(2),
            Index { lo: 0, len: 4, stride: 1 },
            PushInt(42),
            StoreInd(Elem::I16),
            End,
        ],
        vec![],
        0,
        32,
    );
    rig.scan();
    assert_eq!(rig.var(14, Elem::I16) as i64, -300, "element 3 is 2 × 2 bytes in");
    assert_eq!(rig.var(21, Elem::I32), 123_456);
    assert_eq!(rig.var(0, Elem::I32), 123_456);
    assert_eq!(rig.word("D00202"), 42);
    assert!(rig.exits.is_empty());
}

#[test]
fn an_index_out_of_bounds_raises_3402h_and_points_nowhere() {
    let mut rig = Rig::new(
        vec![
            AddrOf(Place::Var(0)),
            PushInt(4),
            Index { lo: 1, len: 3, stride: 1 },
            PushInt(99),
            StoreInd(Elem::U8),
            AddrOf(Place::Var(0)),
            PushInt(0),
            Index { lo: 1, len: 3, stride: 1 },
            FetchInd(Elem::U8),
            Store { elem: Elem::U8, at: Place::Var(4) },
            PushInt(5),
            Store { elem: Elem::U8, at: Place::Var(5) },
            End,
        ],
        vec![],
        0,
        8,
    );
    rig.vm.write_value(Pointer { space: Space::Var, offset: 4 }, Elem::U8, 9);
    rig.scan();
    assert_eq!(
        rig.exits,
        [
            Exit::OperationError { code: ERR_INDEX_RANGE, pc: 2 },
            Exit::OperationError { code: ERR_INDEX_RANGE, pc: 7 },
        ]
    );
    assert_eq!(&rig.vm.vars()[0..4], &[0, 0, 0, 0], "the store went nowhere");
    assert_eq!(rig.var(4, Elem::U8), 0, "the load gave 0");
    assert_eq!(rig.var(5, Elem::U8), 5, "execution went on");
    assert_eq!(rig.word("_ERR_CODE"), 0x3402);
}

#[test]
fn copy_moves_bytes_between_variables_and_the_frame() {
    let mut rig = Rig::new(
        vec![
            AddrOf(Place::Frame(0)),
            AddrOf(Place::Var(0)),
            Copy(4),
            AddrOf(Place::Var(8)),
            AddrOf(Place::Frame(0)),
            Copy(4),
            AddrOf(Place::Var(1)),
            AddrOf(Place::Var(0)),
            Copy(3), // overlapping: a memmove
            End,
        ],
        vec![],
        8,
        16,
    );
    for (i, b) in [1u8, 2, 3, 4].iter().enumerate() {
        rig.vm.write_value(
            Pointer { space: Space::Var, offset: i as u32 },
            Elem::U8,
            u64::from(*b),
        );
    }
    rig.scan();
    assert_eq!(&rig.vm.vars()[8..12], &[1, 2, 3, 4]);
    assert_eq!(&rig.vm.vars()[0..4], &[1, 1, 2, 3]);
}

/// A program calling a FUNCTION `twice(x) := 2 * x + helper(x)` where `helper(y) := y + 1`,
/// and a FUNCTION_BLOCK `counter` (instance variables: count at 0, step at 2) on two instances.
fn calls_program() -> Vec<Op> {
    vec![
        // 0: main: twice(20) into Var(0); main's own frame is 8 bytes.
        PushInt(20),
        Store { elem: Elem::I16, at: Place::Frame(8 + 2) },
        CallFn { target: 20, frame: 8 },
        Fetch { elem: Elem::I16, at: Place::Frame(8) },
        Store { elem: Elem::I16, at: Place::Var(0) },
        // 5: counter instances at Var(10) and Var(20): step 5 into the second, then calls.
        PushInt(5),
        Store { elem: Elem::I16, at: Place::Var(22) },
        AddrOf(Place::Var(10)),
        CallFb { target: 40, frame: 8 },
        AddrOf(Place::Var(20)),
        CallFb { target: 40, frame: 8 },
        AddrOf(Place::Var(10)),
        CallFb { target: 40, frame: 8 },
        End,
        Nop,
        Nop,
        Nop,
        Nop,
        Nop,
        Nop,
        // 20: twice: x at Frame(2), result at Frame(0), helper's frame 4 bytes after.
        Fetch { elem: Elem::I16, at: Place::Frame(2) },
        Store { elem: Elem::I16, at: Place::Frame(4 + 2) },
        CallFn { target: 30, frame: 4 },
        Fetch { elem: Elem::I16, at: Place::Frame(4) },
        Fetch { elem: Elem::I16, at: Place::Frame(2) },
        PushInt(2),
        Bin { op: BinOp::Mul, elem: Elem::I16 },
        Bin { op: BinOp::Add, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::Frame(0) },
        Return,
        // 30: helper: y at Frame(2).
        Fetch { elem: Elem::I16, at: Place::Frame(2) },
        PushInt(1),
        Bin { op: BinOp::Add, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::Frame(0) },
        Return,
        Nop,
        Nop,
        Nop,
        Nop,
        Nop,
        // 40: counter: count += step (a step of 0 counts 1), via a temp in its frame.
        Fetch { elem: Elem::I16, at: Place::This(2) },
        Dup,
        PushInt(0),
        Cmp { op: CmpOp::Eq, elem: Elem::I16 },
        GotoIf { target: 47, when: false },
        Drop,
        PushInt(1),
        // 47
        Store { elem: Elem::I16, at: Place::Frame(0) },
        Fetch { elem: Elem::I16, at: Place::This(0) },
        Fetch { elem: Elem::I16, at: Place::Frame(0) },
        Bin { op: BinOp::Add, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::This(0) },
        Return,
    ]
}

#[test]
fn calls_have_frames_and_fb_instances_this() {
    let mut rig = Rig::new(calls_program(), vec![], 32, 32);
    rig.scan();
    assert_eq!(rig.var(0, Elem::I16), 61, "2 × 20 + 21");
    assert_eq!(rig.var(10, Elem::I16), 2, "the first instance counted 1 twice");
    assert_eq!(rig.var(20, Elem::I16), 5, "the second counted its step once");
    rig.scan();
    assert_eq!((rig.var(10, Elem::I16), rig.var(20, Elem::I16)), (4, 10));
    assert!(rig.exits.is_empty());
    assert_eq!(rig.state.eval_depth(), 0);
}

#[test]
fn a_call_deeper_than_the_limit_is_4210h() {
    // A function that calls itself (the compiler refuses that; the VM must not fail).
    let mut rig = Rig::new(
        vec![CallFn { target: 2, frame: 0 }, End, CallFn { target: 2, frame: 1 }, Return],
        vec![],
        64,
        0,
    );
    rig.state.restart();
    let clock = ManualClock::new(0);
    let exit = rig.vm.run(&rig.program, &mut rig.state, &clock, 10_000);
    assert_eq!(exit, Exit::OperationError { code: ERR_CALL_DEPTH, pc: 2 });
    // Going on, the calls unwind (each Return back to its caller), then END.
    assert_eq!(rig.vm.run(&rig.program, &mut rig.state, &clock, 10_000), Exit::End);
}

#[test]
fn now_is_the_clock_at_the_op() {
    let mut rig = Rig::new(
        vec![Nop, Nop, Now, Store { elem: Elem::I64, at: Place::Var(0) }, End],
        vec![],
        0,
        8,
    );
    rig.scan_with(&StepClock { origin_ns: 1_000, origin_steps: 0, step_ns: 250 });
    // The third op, at step count 3 (the op counted, as timers see it): 1000 + 3 × 250.
    assert_eq!(rig.var(0, Elem::I64), 1_750);
}

/// Strings at Var: a STRING[10] at 0 ('hello'), a STRING[10] at 16 ('lo w'), a STRING[4]
/// destination at 32, a STRING[20] at 40, a STRING[12] at 64.
fn string_rig(code: Vec<Op>) -> Rig {
    let mut rig = Rig::new(code, vec![], 16, 96);
    rig.vm.write_string(Pointer { space: Space::Var, offset: 0 }, 10, b"hello");
    rig.vm.write_string(Pointer { space: Space::Var, offset: 16 }, 10, b"lo w");
    rig.scan();
    rig
}

fn text(rig: &Rig, offset: u32) -> String {
    String::from_utf8(rig.vm.read_string(Pointer { space: Space::Var, offset })).unwrap()
}

#[test]
fn strings_move_concat_and_cut_to_the_capacity() {
    let rig = string_rig(vec![
        // s20 := CONCAT(s10a, s10b); s4 := s20 (cut); s10b := CONCAT(s10a, s10b) (dst is b).
        AddrOf(Place::Var(40)),
        AddrOf(Place::Var(0)),
        AddrOf(Place::Var(16)),
        Str { op: StrOp::Concat, cap: 20, wide: false },
        AddrOf(Place::Var(32)),
        AddrOf(Place::Var(40)),
        Str { op: StrOp::Move, cap: 4, wide: false },
        AddrOf(Place::Var(16)),
        AddrOf(Place::Var(0)),
        AddrOf(Place::Var(16)),
        Str { op: StrOp::Concat, cap: 10, wide: false },
        // A frame temporary: Frame(0) := s4 & s4.
        AddrOf(Place::Frame(0)),
        AddrOf(Place::Var(32)),
        AddrOf(Place::Var(32)),
        Str { op: StrOp::Concat, cap: 10, wide: false },
        AddrOf(Place::Var(64)),
        AddrOf(Place::Frame(0)),
        Str { op: StrOp::Move, cap: 12, wide: false },
        End,
    ]);
    assert_eq!(text(&rig, 40), "hellolo w");
    assert_eq!(text(&rig, 32), "hell");
    assert_eq!(text(&rig, 16), "hellolo w", "the destination was the second operand");
    assert_eq!(text(&rig, 64), "hellhell");
}

#[test]
fn strings_left_right_mid_len_find_compare() {
    let rig = string_rig(vec![
        AddrOf(Place::Var(40)),
        AddrOf(Place::Var(0)),
        PushInt(2),
        Str { op: StrOp::Left, cap: 20, wide: false },
        AddrOf(Place::Var(32)),
        AddrOf(Place::Var(0)),
        PushInt(3),
        Str { op: StrOp::Right, cap: 4, wide: false },
        AddrOf(Place::Var(64)),
        AddrOf(Place::Var(0)),
        PushInt(3),
        PushInt(2),
        Str { op: StrOp::Mid, cap: 10, wide: false },
        AddrOf(Place::Var(0)),
        Str { op: StrOp::Len, cap: 0, wide: false },
        Store { elem: Elem::I64, at: Place::Var(80) },
        AddrOf(Place::Var(0)),
        AddrOf(Place::Var(32)),
        Str { op: StrOp::Find, cap: 0, wide: false },
        Store { elem: Elem::U8, at: Place::Var(30) },
        AddrOf(Place::Var(0)),
        AddrOf(Place::Var(16)),
        Str { op: StrOp::Find, cap: 0, wide: false },
        Store { elem: Elem::U8, at: Place::Var(31) },
        AddrOf(Place::Var(0)),
        AddrOf(Place::Var(16)),
        Str { op: StrOp::Compare, cap: 0, wide: false },
        Store { elem: Elem::I8, at: Place::Var(29) },
        // Left of more than there is, Mid from past the end.
        AddrOf(Place::Var(16)),
        AddrOf(Place::Var(0)),
        PushInt(99),
        Str { op: StrOp::Left, cap: 10, wide: false },
        AddrOf(Place::Var(12)),
        AddrOf(Place::Var(0)),
        PushInt(2),
        PushInt(9),
        Str { op: StrOp::Mid, cap: 2, wide: false },
        End,
    ]);
    assert_eq!(text(&rig, 40), "he");
    assert_eq!(text(&rig, 32), "llo");
    assert_eq!(text(&rig, 64), "ell");
    assert_eq!(rig.var(80, Elem::I64), 5);
    assert_eq!(rig.var(30, Elem::U8), 3, "'llo' is at 3 in 'hello'");
    assert_eq!(rig.var(31, Elem::U8), 0, "'lo w' is not in 'hello'");
    assert_eq!(rig.var(29, Elem::I8) as i64, -1, "'hello' < 'lo w'");
    assert_eq!(text(&rig, 16), "hello");
    assert_eq!(text(&rig, 12), "");
}

#[test]
fn run_start_initializes_variables_keeping_the_retained_ones_when_warm() {
    let program = program(vec![End], vec![], 0);
    let mut vm = Vm::for_programs([&program]);
    let d10 = Address::parse("D00010").unwrap().as_word().unwrap();
    vm.set_variables(&Variables {
        initial: (1..=16).collect::<Vec<u8>>().into(),
        retained: vec![(4, 4), (10, 2)].into(),
        persistent: vec![(10, 2)].into(),
        located_init: vec![(Place::Word(d10), Elem::I32, 70_000)].into(),
        symbols: Default::default(),
        referents: vec![],
        access: vec![],
    });
    assert_eq!(vm.vars(), (1..=16).collect::<Vec<u8>>());
    for offset in 0..16 {
        vm.write_value(Pointer { space: Space::Var, offset }, Elem::U8, 0);
    }
    let none = RetainSet::default();
    vm.reset_for_run(&none, true);
    let expected: Vec<u8> = (1..=16)
        .map(|b| if (5..=8).contains(&b) || (11..=12).contains(&b) { 0 } else { b })
        .collect();
    assert_eq!(vm.vars(), expected, "warm: the retained bytes are kept");
    assert_eq!(
        vm.read_value(Pointer { space: Space::Word, offset: u32::from(d10.0) }, Elem::I32),
        70_000
    );
    vm.reset_for_run(&none, false);
    let expected: Vec<u8> = (1..=16).map(|b| if (11..=12).contains(&b) { 0 } else { b }).collect();
    assert_eq!(vm.vars(), expected, "cold: all initial but the PERSISTENT bytes");
    for offset in 0..16 {
        vm.write_value(Pointer { space: Space::Var, offset }, Elem::U8, 0);
    }
    vm.reset_variables();
    assert_eq!(vm.vars(), expected, "a cold reset: the same");
}

#[test]
fn take_over_keeps_the_variables_it_is_told_to() {
    let program = program(vec![End], vec![], 0);
    let mut old = Vm::for_programs([&program]);
    old.set_variables(&Variables { initial: vec![7, 8, 9, 10].into(), ..Variables::default() });
    let mut new = Vm::for_programs([&program]);
    new.set_variables(&Variables { initial: vec![0; 4].into(), ..Variables::default() });
    new.take_over(&mut old, &[]);
    assert_eq!(new.vars(), [0, 0, 0, 0], "the new layout starts from its own image");
    new.keep_variables(&old, &[(2, 0, 2)]);
    assert_eq!(new.vars(), [9, 10, 0, 0]);
}

#[test]
fn tools_read_and_write_every_space() {
    let program = program(vec![End], vec![], 0);
    let mut vm = Vm::for_programs([&program]);
    vm.set_variables(&Variables { initial: vec![0; 8].into(), ..Variables::default() });
    let var = Pointer { space: Space::Var, offset: 2 };
    vm.write_value(var, Elem::I16, (-5i64) as u64);
    assert_eq!(vm.read_value(var, Elem::I16) as i64, -5);
    vm.write_value(var, Elem::U8, 0x1FF);
    assert_eq!(vm.read_value(var, Elem::U8), 0xFF, "normalized");
    // Out of range, the discard space, a frame: nothing happens, 0 is read.
    for p in [
        Pointer { space: Space::Var, offset: 7 },
        Pointer::DISCARD,
        Pointer { space: Space::Frame, offset: 0 },
        Pointer { space: Space::Word, offset: u32::MAX },
        Pointer { space: Space::Bit, offset: u32::MAX },
    ] {
        vm.write_value(p, Elem::I32, 5);
        assert_eq!(vm.read_value(p, Elem::I32), 0, "{p:?}");
    }
    vm.write_string(Pointer { space: Space::Var, offset: 0 }, 3, b"abcdef");
    assert_eq!(vm.read_string(Pointer { space: Space::Var, offset: 0 }), b"abc");
    // a device byte (`%QB1`, `plcctl set main.code 200`): that half of its word, never the
    // other; a located initial value is written the same way
    let p64 = Address::parse("P064").unwrap().as_word().unwrap();
    let word = Pointer { space: Space::Word, offset: u32::from(p64.0) };
    let high = Pointer { space: Space::Byte, offset: u32::from(p64.0) * 2 + 1 };
    vm.write_value(word, Elem::U16, 0x1234);
    vm.write_value(high, Elem::U8, 200);
    assert_eq!(vm.read_value(word, Elem::U16), 0xC834);
    assert_eq!(vm.read_value(high, Elem::I8) as i64, 200 - 256, "a SINT view: sign-extended");
    vm.write_value(high, Elem::I8, (-1i64) as u64);
    assert_eq!(vm.read_value(word, Elem::U16), 0xFF34);
    vm.set_variables(&Variables {
        initial: vec![0; 8].into(),
        located_init: vec![(Place::Byte(u32::from(p64.0) * 2), Elem::U8, 0x56)].into(),
        ..Variables::default()
    });
    vm.write_value(word, Elem::U16, 0xAB00);
    vm.reset_for_run(&RetainSet::default(), false);
    assert_eq!(vm.read_value(word, Elem::U16) & 0xFF, 0x56);
}

// ---------------------------------------------------------------------------------------------
// Preemption and garbage

/// Every kind of typed op, calls, a loop, both operation errors and `Now`.
fn everything() -> (Vec<Op>, Vec<u64>) {
    let mut code = calls_program();
    // Replace the final END of main (pc 13) by a jump to more code at the end.
    let more = code.len() as u32;
    code[13] = Goto(more);
    code.extend([
        // A loop: i from 0 to 4, sum the array elements i (one out of bounds) into Var(2).
        PushInt(0),
        Store { elem: Elem::I16, at: Place::Var(4) },
        // loop (more + 2):
        Fetch { elem: Elem::I16, at: Place::Var(4) },
        PushInt(4),
        Cmp { op: CmpOp::Gt, elem: Elem::I16 },
        GotoIf { target: more + 18, when: true },
        Fetch { elem: Elem::I16, at: Place::Var(2) },
        AddrOf(Place::Var(24)),
        Fetch { elem: Elem::I16, at: Place::Var(4) },
        Index { lo: 0, len: 4, stride: 1 },
        FetchInd(Elem::U8),
        Conv { from: Elem::U8, to: Elem::I16 },
        Bin { op: BinOp::Add, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::Var(2) },
        Fetch { elem: Elem::I16, at: Place::Var(4) },
        PushInt(1),
        Bin { op: BinOp::Add, elem: Elem::I16 },
        Store { elem: Elem::I16, at: Place::Var(4) },
        // more + 18 would be here; the loop's back jump first:
    ]);
    code.push(Goto(more + 2));
    // more + 19: (the exit target is fixed up to here)
    let exit = code.len() as u32;
    if let GotoIf { target, .. } = &mut code[more as usize + 5] {
        *target = exit;
    }
    code.extend([
        PushInt(1),
        PushInt(0),
        Bin { op: BinOp::Mod, elem: Elem::I32 },
        Drop,
        Now,
        Store { elem: Elem::I64, at: Place::Var(40) },
        PushConst(0),
        Store { elem: Elem::F32, at: word_place("D00010") },
        AddrOf(Place::Var(48)),
        AddrOf(Place::Var(48)),
        AddrOf(Place::Var(48)),
        Str { op: StrOp::Concat, cap: 8, wide: false },
        End,
    ]);
    (code, vec![u64::from(2.5f32.to_bits())])
}

/// Every exit but `Budget` (with the pc and step count), variable memory, device memory.
type Trace = (Vec<(Exit, u32, u64)>, Vec<u8>, Vec<u16>);

/// Scans three times, giving `run` `budget` steps at a time: every exit but `Budget` with the
/// pc and step count, and the memory at the end.
fn trace(budget: u64) -> Trace {
    let (code, consts) = everything();
    let program = program(code, consts, 32);
    let mut vm = Vm::for_programs([&program]);
    let mut initial = vec![0u8; 64];
    initial[24..28].copy_from_slice(&[1, 2, 3, 4]);
    // a STRING[8] "ab": its characters, then NUL (docs/ST.md)
    initial[48..51].copy_from_slice(&[b'a', b'b', 0]);
    vm.set_variables(&Variables { initial: initial.into(), ..Variables::default() });
    let clock = StepClock { origin_ns: 0, origin_steps: 0, step_ns: 1_000 };
    let mut state = ExecState::with_frame(32);
    let mut exits = Vec::new();
    for _ in 0..3 {
        vm.begin_scan(false, 0);
        state.restart();
        loop {
            match vm.run(&program, &mut state, &clock, budget) {
                Exit::Budget => continue,
                exit => exits.push((exit, state.pc(), vm.steps())),
            }
            if state.is_finished() {
                break;
            }
        }
    }
    (exits, vm.vars().to_vec(), vm.mem.words().to_vec())
}

#[test]
fn any_budget_gives_the_same_exits_steps_and_memory() {
    let whole = trace(u64::MAX);
    let count = |code| {
        whole
            .0
            .iter()
            .filter(|e| matches!(e.0, Exit::OperationError { code: c, .. } if c == code))
            .count()
    };
    assert_eq!(count(ERR_INDEX_RANGE), 3, "one out-of-bounds index a scan");
    assert_eq!(count(ERR_DIVIDE_BY_ZERO), 3);
    // Three scans of the sum over the array (the bad index reads 0).
    assert_eq!(whole.1[2], 3 * (1 + 2 + 3 + 4));
    assert_eq!(&whole.1[48..57], b"abababab\0");
    for budget in [1, 2, 3, 5, 8] {
        assert!(trace(budget) == whole, "budget {budget} differs");
    }
}

/// A typed op with operands from random numbers (targets and offsets partly in range).
fn garbage_op(kind: u8, a: u32, b: u32, c: u8) -> Op {
    let elem = Elem::ALL[c as usize % Elem::ALL.len()];
    let place = match b % 5 {
        0 => Place::Var(a % 80),
        1 => Place::Frame(a % 80),
        2 => Place::This(a),
        3 => Place::Word(plcd::device::WordRef((a % 70_000) as u16)),
        _ => Place::Bit(plcd::device::BitRef { word: a as u16, mask: b as u16 }),
    };
    let target = a % 40;
    match kind % 26 {
        0 => PushInt(a as i32),
        1 => PushConst(a % 4),
        2 => Fetch { elem, at: place },
        3 => Store { elem, at: place },
        4 => AddrOf(place),
        5 => Index { lo: a as i32 % 5, len: b % 6, stride: u32::from(c) },
        6 => Offset(a),
        7 => FetchInd(elem),
        8 => StoreInd(elem),
        9 => Copy(b % 200),
        10 => Bin {
            op: [BinOp::Div, BinOp::Mod, BinOp::Shl, BinOp::Expt, BinOp::Ror][a as usize % 5],
            elem,
        },
        11 => Un { op: [UnOp::Neg, UnOp::Ln, UnOp::Abs][a as usize % 3], elem },
        12 => Cmp { op: CmpOp::Lt, elem },
        13 => Conv { from: elem, to: Elem::ALL[a as usize % Elem::ALL.len()] },
        14 => Dup,
        15 => Drop,
        16 => Goto(target),
        17 => GotoIf { target, when: c.is_multiple_of(2) },
        18 => CallFn { target, frame: b },
        19 => CallFb { target, frame: b % 100 },
        20 => Return,
        21 => Now,
        22 => Str {
            op: [
                StrOp::Move,
                StrOp::Len,
                StrOp::Left,
                StrOp::Right,
                StrOp::Mid,
                StrOp::Concat,
                StrOp::Find,
                StrOp::Compare,
                StrOp::Widen,
                StrOp::Narrow,
            ][a as usize % 10],
            cap: b as u16,
            wide: c.is_multiple_of(3),
        },
        23 => Bin { op: BinOp::Add, elem },
        24 => End,
        _ => Nop,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

    #[test]
    fn garbage_never_panics(
        ops in prop::collection::vec((any::<u8>(), any::<u32>(), any::<u32>(), any::<u8>()), 1..40),
        consts in prop::collection::vec(any::<u64>(), 0..4),
        frame in 0u32..100,
    ) {
        let code: Vec<Op> = ops.iter().map(|&(k, a, b, c)| garbage_op(k, a, b, c)).collect();
        let program = program(code, consts, frame);
        let mut vm = Vm::for_programs([&program]);
        vm.set_variables(&Variables { initial: vec![0x55; 64].into(), ..Variables::default() });
        let mut state = ExecState::with_frame(frame);
        let clock = ManualClock::new(0);
        // At most 2000 steps in all: garbage may loop.
        let mut runs = 0;
        while runs < 200 {
            runs += 1;
            match vm.run(&program, &mut state, &clock, 10) {
                Exit::End => break,
                _ => continue,
            }
        }
    }
}
