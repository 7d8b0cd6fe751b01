//! An instruction-list program as one Cranelift function, `fn(*mut Context) -> u32`.
//!
//! The shape of the function:
//! - the entry loads the registers (the rung, the block and `MPUSH` stacks, the budget) from
//!   the [`Context`]'s [`NativeRegs`] and switches on the program counter over the leaders of
//!   [`Analysis`]; any other program counter goes back to the interpreter, unchanged;
//! - a block first checks that the budget covers all its instructions, and hands itself whole
//!   to the interpreter if not; then charges the budget, runs its instructions with the
//!   registers in SSA variables and goes on to the next block directly (or, at `JMP`, to its
//!   target's block when the rung is ON);
//! - an instruction the interpreter executes is a block of its own that stores the registers
//!   and returns to it;
//! - a program is compiled in pieces ([`Analysis::pieces`]), each such a function; a piece
//!   goes on into another by returning to [`Code::run`](crate::code::Code), which calls it;
//! - as in the interpreter, coils and data instructions store whatever the rung (the old value
//!   when it is OFF) and contacts combine arithmetically: no branch on device data (`DIV` by
//!   zero, an operation error, leaves for the interpreter on a cold path);
//! - within a block a word of device memory read or written by one of the last [`RECENT`]
//!   instructions is not read again: the block keeps it in an SSA value ([`Word`]). Nothing
//!   else touches device memory while a block runs (it calls nothing), so this is exact; the
//!   window keeps the values' lives short, so that they stay in registers (holding every word
//!   a block touches made the `bit` bench 25 % slower: all loads first, spilled).
//!
//! Device memory's words are reached without a check: [`Code`](crate::code::Code) runs the
//! function only on memory of at least [`Analysis::words_end`] words.

use std::collections::HashMap;
use std::mem::offset_of;

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, AbiParam, Block, Function, InstBuilder, Signature, Value};
use cranelift_codegen::isa::TargetIsa;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Switch, Variable};
use plcd_core::device::{BitRef, WordRef};
use plcd_core::lang::native::NativeRegs;
use plcd_core::lang::ops::{ArithOp, CmpOp, Combine, Op, Src};
use plcd_core::lang::Program;

use super::{is_native, Analysis};
use crate::code::{Context, RETURN_CONTINUE, RETURN_END, RETURN_INTERPRET};
use crate::codegen::{data, own};

const I32: types::Type = types::I32;
const I64: types::Type = types::I64;

/// Fills `func` with the code of piece `piece` of `program`.
pub(crate) fn generate(
    program: &Program,
    analysis: &Analysis,
    piece: usize,
    isa: &dyn TargetIsa,
    func: &mut Function,
) {
    func.signature = Signature::new(isa.default_call_conv());
    func.signature.params.push(AbiParam::new(I64));
    func.signature.returns.push(AbiParam::new(I32));
    let mut fctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(func, &mut fctx);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let ctx = b.block_params(entry)[0];
    let regs_at = b.ins().load(I64, own(), ctx, offset_of!(Context, regs) as i32);
    let words = b.ins().load(I64, own(), ctx, offset_of!(Context, words) as i32);
    let regs = Regs {
        rung: b.declare_var(I32),
        blocks: b.declare_var(I32),
        branches: b.declare_var(I32),
        left: b.declare_var(I64),
    };
    let leaders = analysis.pieces[piece].clone();
    let mut g = Gen {
        b,
        code: &program.code,
        analysis,
        regs_at,
        words,
        regs,
        leaders,
        blocks: Vec::new(),
        held: HashMap::new(),
        pc: 0,
    };
    g.entry();
    g.body();
    g.b.seal_all_blocks();
    g.b.finalize(isa.frontend_config());
}

/// A word read or written this many instructions ago or less is not read again.
const RECENT: usize = 8;

/// A word of device memory the current block has read or written.
struct Word {
    /// Its value in the low 16 bits (the upper 16 are whatever arithmetic left there).
    value: Value,
    /// The value sign-extended to 32 bits, once something needed it.
    signed: Option<Value>,
    /// The instruction that last read or wrote it.
    at: usize,
}

/// The registers of the activation, as SSA variables: the rung is 0 or 1.
struct Regs {
    rung: Variable,
    blocks: Variable,
    branches: Variable,
    left: Variable,
}

struct Gen<'a, 'f> {
    b: FunctionBuilder<'f>,
    code: &'a [Op],
    analysis: &'a Analysis,
    /// The [`NativeRegs`] of the call.
    regs_at: Value,
    words: Value,
    regs: Regs,
    /// This piece's leaders: a range of [`Analysis::leaders`].
    leaders: std::ops::Range<usize>,
    /// The block of each of this piece's leaders.
    blocks: Vec<Block>,
    /// The words the current block holds, by index.
    held: HashMap<u16, Word>,
    /// The instruction being compiled.
    pc: usize,
}

impl Gen<'_, '_> {
    fn field32(&mut self, offset: usize) -> Value {
        self.b.ins().load(I32, own(), self.regs_at, offset as i32)
    }

    fn entry(&mut self) {
        let pc = self.field32(offset_of!(NativeRegs, pc));
        let rung = self.field32(offset_of!(NativeRegs, rung));
        let blocks = self.field32(offset_of!(NativeRegs, blocks));
        let branches = self.field32(offset_of!(NativeRegs, branches));
        let left = self.b.ins().load(I64, own(), self.regs_at, offset_of!(NativeRegs, left) as i32);
        self.b.def_var(self.regs.rung, rung);
        self.b.def_var(self.regs.blocks, blocks);
        self.b.def_var(self.regs.branches, branches);
        self.b.def_var(self.regs.left, left);
        let leaders = &self.analysis.leaders[self.leaders.clone()];
        self.blocks = leaders.iter().map(|_| self.b.create_block()).collect();
        let mut switch = Switch::new();
        for (&leader, &block) in leaders.iter().zip(&self.blocks) {
            switch.set_entry(u128::from(leader), block);
        }
        // Any other pc: the interpreter, with the registers as they are.
        let elsewhere = self.b.create_block();
        switch.emit(&mut self.b, pc, elsewhere);
        self.b.switch_to_block(elsewhere);
        self.b.set_cold_block(elsewhere);
        self.ret(RETURN_INTERPRET);
    }

    fn ret(&mut self, status: u32) {
        let status = self.b.ins().iconst(I32, i64::from(status));
        self.b.ins().return_(&[status]);
    }

    /// Leaves with `status`: the registers, with `pc`, back to the context.
    fn exit(&mut self, pc: usize, status: u32) {
        let pc = self.b.ins().iconst(I32, pc as i64);
        let rung = self.rung();
        let blocks = self.b.use_var(self.regs.blocks);
        let branches = self.b.use_var(self.regs.branches);
        let left = self.b.use_var(self.regs.left);
        for (value, offset) in [
            (pc, offset_of!(NativeRegs, pc)),
            (rung, offset_of!(NativeRegs, rung)),
            (blocks, offset_of!(NativeRegs, blocks)),
            (branches, offset_of!(NativeRegs, branches)),
            (left, offset_of!(NativeRegs, left)),
        ] {
            self.b.ins().store(own(), value, self.regs_at, offset as i32);
        }
        self.ret(status);
    }

    /// Goes on at `pc`: its block in this piece, the piece that has it (through
    /// [`Code::run`](crate::code::Code)), or the interpreter past the compiled code.
    fn go_on(&mut self, pc: usize) {
        match self.analysis.leaders.binary_search(&(pc as u32)) {
            Ok(index) if self.leaders.contains(&index) => {
                let block = self.blocks[index - self.leaders.start];
                self.b.ins().jump(block, &[]);
            }
            Ok(_) => self.exit(pc, RETURN_CONTINUE),
            Err(_) => self.exit(pc, RETURN_INTERPRET),
        }
    }

    fn body(&mut self) {
        for index in self.leaders.clone() {
            let range = self.analysis.block(self.code, index);
            self.b.switch_to_block(self.blocks[index - self.leaders.start]);
            self.held.clear();
            if !is_native(&self.code[range.start]) {
                self.exit(range.start, RETURN_INTERPRET);
                continue;
            }
            // The budget covers the whole block, or the interpreter takes it.
            let n = range.len() as i64;
            let left = self.b.use_var(self.regs.left);
            let enough = self.b.ins().icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, left, n);
            let run = self.b.create_block();
            let refuse = self.b.create_block();
            self.b.set_cold_block(refuse);
            self.b.ins().brif(enough, run, &[], refuse, &[]);
            self.b.switch_to_block(refuse);
            self.exit(range.start, RETURN_INTERPRET);
            self.b.switch_to_block(run);
            let left = self.b.ins().iadd_imm_s(left, -n);
            self.b.def_var(self.regs.left, left);
            let mut ended = false;
            for pc in range.clone() {
                self.pc = pc;
                match self.code[pc] {
                    Op::End => {
                        self.exit(pc + 1, RETURN_END);
                        ended = true;
                    }
                    Op::Jmp { target } => {
                        let rung = self.rung();
                        let taken = self.b.create_block();
                        let not_taken = self.b.create_block();
                        self.b.ins().brif(rung, taken, &[], not_taken, &[]);
                        self.b.switch_to_block(taken);
                        self.go_on(target as usize);
                        self.b.switch_to_block(not_taken);
                        self.go_on(pc + 1);
                        ended = true;
                    }
                    Op::Arith { op: ArithOp::Div, a, b, d, .. } => {
                        self.div(a, b, d, pc, range.end);
                    }
                    op => self.op(op),
                }
            }
            if !ended {
                self.go_on(range.end);
            }
        }
    }

    /// The word at `index`: held, or read now and held.
    fn held_value(&mut self, index: u16) -> Value {
        let pc = self.pc;
        if let Some(word) = self.held.get_mut(&index) {
            if pc - word.at <= RECENT {
                word.at = pc;
                return word.value;
            }
        }
        let value = self.b.ins().uload16(I32, data(), self.words, i32::from(index) * 2);
        self.held.insert(index, Word { value, signed: None, at: pc });
        value
    }

    /// The bit in bit 0 of the result, the other bits undefined (a contact's value, see
    /// [`Gen::rung`]).
    fn bit(&mut self, b: BitRef) -> Value {
        let word = self.held_value(b.word);
        if b.mask.is_power_of_two() {
            return self.b.ins().ushr_imm_s(word, i64::from(b.mask.trailing_zeros()));
        }
        let masked = self.b.ins().band_imm_s(word, i64::from(b.mask));
        let on = self.b.ins().icmp_imm_s(IntCC::NotEqual, masked, 0);
        self.b.ins().uextend(I32, on)
    }

    fn word(&mut self, w: WordRef) -> Value {
        self.held_value(w.0)
    }

    fn set_word(&mut self, w: WordRef, value: Value) {
        self.b.ins().istore16(data(), value, self.words, i32::from(w.0) * 2);
        self.held.insert(w.0, Word { value, signed: None, at: self.pc });
    }

    /// A source as a signed 16-bit value, in 32 bits.
    fn signed(&mut self, s: Src) -> Value {
        let index = match s {
            Src::Word(w) => w.0,
            Src::Const(c) => return self.b.ins().iconst(I32, i64::from(c as i16)),
        };
        let pc = self.pc;
        match self.held.get_mut(&index) {
            Some(word) if pc - word.at <= RECENT => {
                word.at = pc;
                if let Some(signed) = word.signed {
                    return signed;
                }
                let value = word.value;
                let narrow = self.b.ins().ireduce(types::I16, value);
                let signed = self.b.ins().sextend(I32, narrow);
                self.held.get_mut(&index).expect("held above").signed = Some(signed);
                signed
            }
            _ => {
                // Read sign-extended: its low 16 bits are the word as well.
                let value = self.b.ins().sload16(I32, data(), self.words, i32::from(index) * 2);
                self.held.insert(index, Word { value, signed: Some(value), at: pc });
                value
            }
        }
    }

    /// `DIV a b d` at `pc` in a block that ends before `end`: when the rung is ON and `b` is 0
    /// (an operation error), the interpreter takes the instruction, with the budget of the
    /// block's instructions from `pc` on given back; otherwise `d` gets the quotient when the
    /// rung is ON and stays when it is OFF. In 32 bits, -32768 / -1 is 32768, whose low 16
    /// bits are the interpreter's wrapping result, and the division cannot trap.
    fn div(&mut self, a: Src, b: Src, d: WordRef, pc: usize, end: usize) {
        let (a, b) = (self.signed(a), self.signed(b));
        let rung = self.rung();
        let zero = self.b.ins().icmp_imm_s(IntCC::Equal, b, 0);
        let zero = self.b.ins().uextend(I32, zero);
        let fails = self.b.ins().band(rung, zero);
        let error = self.b.create_block();
        let divide = self.b.create_block();
        self.b.set_cold_block(error);
        self.b.ins().brif(fails, error, &[], divide, &[]);
        self.b.switch_to_block(error);
        let left = self.b.use_var(self.regs.left);
        let back = self.b.ins().iadd_imm_s(left, (end - pc) as i64);
        self.b.def_var(self.regs.left, back);
        self.exit(pc, RETURN_INTERPRET);
        self.b.switch_to_block(divide);
        let one = self.b.ins().iconst(I32, 1);
        let divisor = self.b.ins().select(zero, one, b);
        let quotient = self.b.ins().sdiv(a, divisor);
        self.store_if_on(d, quotient);
    }

    /// The rung, 0 or 1. (The variable's other bits are whatever the contacts left there:
    /// only bit 0 is the rung, so that a contact is a shift and an `and` or `or`.)
    fn rung(&mut self) -> Value {
        let raw = self.b.use_var(self.regs.rung);
        self.b.ins().band_imm_s(raw, 1)
    }

    /// All ones when the rung is ON, else zero.
    fn all(&mut self) -> Value {
        let rung = self.rung();
        self.b.ins().ineg(rung)
    }

    /// Bit 0 inverted (and the others).
    fn not(&mut self, v: Value) -> Value {
        self.b.ins().bnot(v)
    }

    fn push_rung(&mut self, stack: Variable) {
        let rung = self.rung();
        let s = self.b.use_var(stack);
        let s = self.b.ins().ishl_imm_s(s, 1);
        let s = self.b.ins().bor(s, rung);
        self.b.def_var(stack, s);
    }

    /// The top of `stack` (0 or 1), popped when `pop`.
    fn top(&mut self, stack: Variable, pop: bool) -> Value {
        let s = self.b.use_var(stack);
        let top = self.b.ins().band_imm_s(s, 1);
        if pop {
            let rest = self.b.ins().ushr_imm_s(s, 1);
            self.b.def_var(stack, rest);
        }
        top
    }

    fn combine(&mut self, how: Combine, value: Value) {
        let rung = self.b.use_var(self.regs.rung);
        let rung = match how {
            Combine::Load { push } => {
                if push {
                    self.push_rung(self.regs.blocks);
                }
                value
            }
            Combine::And => self.b.ins().band(rung, value),
            Combine::Or => self.b.ins().bor(rung, value),
        };
        self.b.def_var(self.regs.rung, rung);
    }

    /// Writes `bit` as `on` (0 or 1), without a branch.
    fn write_bit(&mut self, b: BitRef, on: Value) {
        let w = WordRef(b.word);
        let word = self.word(w);
        let cleared = self.b.ins().band_imm_s(word, i64::from(!b.mask));
        let set = if b.mask.is_power_of_two() {
            self.b.ins().ishl_imm_s(on, i64::from(b.mask.trailing_zeros()))
        } else {
            let ones = self.b.ins().ineg(on);
            self.b.ins().band_imm_s(ones, i64::from(b.mask))
        };
        let word = self.b.ins().bor(cleared, set);
        self.set_word(w, word);
    }

    /// Stores `value` at `d` when the rung is ON, the old value when it is OFF.
    fn store_if_on(&mut self, d: WordRef, value: Value) {
        let old = self.word(d);
        let rung = self.rung();
        let v = self.b.ins().select(rung, value, old);
        self.set_word(d, v);
    }

    fn op(&mut self, op: Op) {
        match op {
            Op::Load(b) | Op::LoadNot(b) | Op::LoadPush(b) | Op::LoadNotPush(b) => {
                let v = self.bit(b);
                let v =
                    if matches!(op, Op::LoadNot(_) | Op::LoadNotPush(_)) { self.not(v) } else { v };
                let push = matches!(op, Op::LoadPush(_) | Op::LoadNotPush(_));
                self.combine(Combine::Load { push }, v);
            }
            Op::And(b) | Op::AndNot(b) => {
                let v = self.bit(b);
                let v = if matches!(op, Op::AndNot(_)) { self.not(v) } else { v };
                self.combine(Combine::And, v);
            }
            Op::Or(b) | Op::OrNot(b) => {
                let v = self.bit(b);
                let v = if matches!(op, Op::OrNot(_)) { self.not(v) } else { v };
                self.combine(Combine::Or, v);
            }
            Op::Compare { op, a, b, how } => {
                let (a, b) = (self.signed(a), self.signed(b));
                let cc = match op {
                    CmpOp::Eq => IntCC::Equal,
                    CmpOp::Ne => IntCC::NotEqual,
                    CmpOp::Gt => IntCC::SignedGreaterThan,
                    CmpOp::Ge => IntCC::SignedGreaterThanOrEqual,
                    CmpOp::Lt => IntCC::SignedLessThan,
                    CmpOp::Le => IntCC::SignedLessThanOrEqual,
                };
                let holds = self.b.ins().icmp(cc, a, b);
                let holds = self.b.ins().uextend(I32, holds);
                self.combine(how, holds);
            }
            Op::AndLoad | Op::OrLoad => {
                let top = self.top(self.regs.blocks, true);
                let how = if op == Op::AndLoad { Combine::And } else { Combine::Or };
                self.combine(how, top);
            }
            Op::MPush => self.push_rung(self.regs.branches),
            Op::MLoad | Op::MPop => {
                let top = self.top(self.regs.branches, op == Op::MPop);
                self.b.def_var(self.regs.rung, top);
            }
            Op::Not => {
                let rung = self.b.use_var(self.regs.rung);
                let rung = self.not(rung);
                self.b.def_var(self.regs.rung, rung);
            }
            Op::Out(b) | Op::OutNot(b) => {
                let rung = self.rung();
                let on = if matches!(op, Op::OutNot(_)) {
                    self.b.ins().bxor_imm_s(rung, 1)
                } else {
                    rung
                };
                self.write_bit(b, on);
            }
            Op::Set(b) | Op::Rst(b) => {
                let w = WordRef(b.word);
                let word = self.word(w);
                // The mask where the rung is ON, else 0.
                let bits = if b.mask.is_power_of_two() {
                    let rung = self.rung();
                    self.b.ins().ishl_imm_s(rung, i64::from(b.mask.trailing_zeros()))
                } else {
                    let all = self.all();
                    self.b.ins().band_imm_s(all, i64::from(b.mask))
                };
                let word = if matches!(op, Op::Set(_)) {
                    self.b.ins().bor(word, bits)
                } else {
                    self.b.ins().band_not(word, bits)
                };
                self.set_word(w, word);
            }
            Op::Mov { s, d, .. } => {
                let value = self.signed(s);
                self.store_if_on(d, value);
            }
            Op::Arith { op, a, b, d, .. } => {
                let (a, b) = (self.signed(a), self.signed(b));
                // The low 16 bits of the 32-bit result are the 16-bit wrapping result.
                let value = match op {
                    ArithOp::Add => self.b.ins().iadd(a, b),
                    ArithOp::Sub => self.b.ins().isub(a, b),
                    ArithOp::Mul => self.b.ins().imul(a, b),
                    ArithOp::Div => unreachable!("DIV is compiled by Gen::div"),
                };
                self.store_if_on(d, value);
            }
            Op::Step { d, up, .. } => {
                let old = self.word(d);
                let all = self.all();
                let step = if up { 1 } else { 0xFFFF };
                let step = self.b.ins().band_imm_s(all, step);
                let value = self.b.ins().iadd(old, step);
                self.set_word(d, value);
            }
            Op::Label => {
                let on = self.b.ins().iconst(I32, 1);
                self.b.def_var(self.regs.rung, on);
            }
            Op::Nop => {}
            other => unreachable!("{other:?} is not compiled (il::is_native)"),
        }
    }
}
