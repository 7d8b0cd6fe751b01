//! An instruction-list program as one Cranelift function, `fn(*mut Context) -> u32`.
//!
//! The shape of the function:
//! - the entry loads the registers (the rung, the block and `MPUSH` stacks, the budget) from
//!   the [`Context`](code::Context)'s [`NativeRegs`] and goes to the dispatch, which finds the
//!   program counter's block in the piece's table ([`Analysis::dispatch`]) and jumps to it
//!   through a jump table (a `Switch` over thousands of leaders was a binary search of a dozen
//!   unpredictable branches, at every `RET`); any other program counter goes back to
//!   [`Code::run`](crate::code::Code): to the interpreter if it is in this piece's range, to
//!   the piece that has it if not (a `RET` dispatches on its return address too);
//! - a block first checks that the budget covers all its instructions, and hands itself whole
//!   to the interpreter if not; then charges the budget, runs its instructions with the
//!   registers in SSA variables and goes on to the next block directly (or, at `JMP`, to its
//!   target's block when the rung is ON);
//! - an instruction the interpreter executes is a block of its own that stores the registers
//!   and returns to it;
//! - a program is compiled in pieces ([`Analysis::pieces`]), each such a function; a piece
//!   goes on into another by returning to [`Code::run`](crate::code::Code), which calls it;
//! - each subroutine (up to a piece's size) is also a function of its own
//!   ([`Analysis::subroutines`]), entered only by a machine call from a `CALL` of native code
//!   after it pushed the call's frame, with the budget as a parameter; its `RET` pops the frame
//!   and returns [`RETURN_RETURNED`], and the caller goes on after the `CALL` with its own
//!   registers. Any other exit of the subroutine is passed up through its callers to the VM,
//!   registers and frames in memory, and the VM goes on in the piece that holds the place
//!   (whose `RET` returns through the dispatch). A `CALL` that finds the machine stack spent
//!   goes through the dispatch: a piece jumps to the subroutine's block, a subroutine's
//!   function leaves for the VM (so that its `RET` always ends the machine call that entered
//!   it);
//! - a small subroutine without calls is compiled inline at each `CALL` instead
//!   ([`Subroutine::inline`](super::Subroutine), up to [`INLINE_BUDGET`] instructions per
//!   function): its blocks again, for that call alone, its `RET` a jump back after the `CALL`.
//!   Its frame is pushed only by the paths that leave native code from inside it (a stop, or
//!   control leaving its blocks), as the interpreter would have it there: until then nothing
//!   reads the frame, and the `RET` would pop it again;
//! - as in the interpreter, coils and data instructions store whatever the rung (the old value
//!   when it is OFF) and contacts combine arithmetically: no branch on device data (`DIV` by
//!   zero, an operation error, leaves for the interpreter on a cold path);
//! - within a block a word of device memory read or written by one of the last [`RECENT`]
//!   instructions is not read again: the block keeps it in an SSA value ([`Word`]). Nothing
//!   else touches device memory while a block runs, so this is exact; the
//!   window keeps the values' lives short, so that they stay in registers (holding every word
//!   a block touches made the `bit` bench 25 % slower: all loads first, spilled).
//!
//! Device memory's words are reached without a check: [`Code`](crate::code::Code) runs the
//! function only on memory of at least [`Analysis::words_end`] words.

use std::collections::HashMap;
use std::mem::offset_of;

use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{
    types, AbiParam, Block, FuncRef, Function, InstBuilder, InstructionData, JumpTableData,
    MemFlagsData, Opcode, SigRef, Signature, Value,
};
use cranelift_codegen::isa::TargetIsa;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use plcd_core::device::{counter_done, counter_value, timer_done, timer_value, BitRef, WordRef};
use plcd_core::lang::native::{IlFrame, NativeRegs};
use plcd_core::lang::ops::{ArithOp, CmpOp, Combine, CounterKind, Op, Src, TimerKind};
use plcd_core::lang::{Program, CALL_DEPTH};
use plcd_core::vm::{counter, timer};

use super::{is_native, Analysis};
use crate::code::{
    self, IlContext, RETURN_CONTINUE, RETURN_END, RETURN_INTERPRET, RETURN_RETURNED,
};
use crate::codegen::{data, own};

const I32: types::Type = types::I32;
const I64: types::Type = types::I64;

/// Fills `func` with the code of function `function` of `program`: a piece (the first
/// `analysis.pieces.len()`), else a subroutine's function. `names` gives each function's name
/// in the module (for the machine calls of subroutines).
pub(crate) fn generate(
    program: &Program,
    analysis: &Analysis,
    function: usize,
    names: &[u32],
    isa: &dyn TargetIsa,
    func: &mut Function,
) {
    // The signature of every generated function; a piece uses only the context, a
    // subroutine's function the context and the budget left.
    let signature = crate::code::entry_signature(isa.default_call_conv());
    func.signature = signature.clone();
    let mut fctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(func, &mut fctx);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let params = b.block_params(entry).to_vec();
    let ctx = params[0];
    let pieces = analysis.pieces.len();
    // The context and the instruction list's part of it do not change while the code runs:
    // read-only loads. (Cranelift still keeps such a load where nothing uses it: the counters'
    // and timers' pointers in a function without any.)
    let field =
        |b: &mut FunctionBuilder, offset: usize| b.ins().load(I64, readonly(), ctx, offset as i32);
    // A subroutine's function gets from its caller, besides the budget, the pointers every
    // function uses: a call costs fewer instructions than loading them again.
    let piece = function < pieces;
    let (regs_at, words, il) = if piece {
        let regs_at = field(&mut b, code::CONTEXT.regs);
        let words = field(&mut b, code::CONTEXT.words);
        (regs_at, words, field(&mut b, code::CONTEXT.il))
    } else {
        (params[2], params[3], params[4])
    };
    let il_field =
        |b: &mut FunctionBuilder, offset: usize| b.ins().load(I64, readonly(), il, offset as i32);
    let (il_calls, edges) = if piece {
        let il_calls = il_field(&mut b, offset_of!(IlContext<'static>, calls));
        (il_calls, il_field(&mut b, offset_of!(IlContext<'static>, edges)))
    } else {
        (params[5], params[6])
    };
    let counters = il_field(&mut b, offset_of!(IlContext<'static>, counters));
    let timers = il_field(&mut b, offset_of!(IlContext<'static>, timers));
    let mut now_sig = Signature::new(isa.default_call_conv());
    now_sig.params.extend([I64, I64].map(AbiParam::new));
    now_sig.returns.push(AbiParam::new(I64));
    let now_sig = b.import_signature(now_sig);
    let regs = Regs {
        rung: b.declare_var(I32),
        blocks: b.declare_var(I32),
        branches: b.declare_var(I32),
        left: b.declare_var(I64),
    };
    let sub_sig = b.import_signature(signature);
    let (piece, members) = match analysis.pieces.get(function) {
        Some(range) => (Some(function), range.clone().collect()),
        None => (None, analysis.subroutines[function - pieces].blocks.clone()),
    };
    let mut g = Gen {
        b,
        code: &program.code,
        analysis,
        ctx,
        il,
        regs_at,
        words,
        edges,
        il_calls,
        counters,
        timers,
        now_sig,
        elsewhere: None,
        regs,
        piece,
        members,
        blocks: Vec::new(),
        names,
        sub_sig,
        callees: Vec::new(),
        inline: None,
        inlined: 0,
        held: HashMap::new(),
        pc: 0,
        block_end: 0,
    };
    match piece {
        Some(_) => g.entry(),
        None => g.subroutine_entry(analysis.subroutines[function - pieces].target),
    }
    g.body();
    g.b.seal_all_blocks();
    g.b.finalize(isa.frontend_config());
}

/// A load from a dispatch table (never written while the code lives, always inside it), or of
/// a field of the [`Context`](code::Context) or its [`IlContext`] (never written while the code
/// runs).
fn readonly() -> MemFlagsData {
    MemFlagsData::trusted().with_readonly()
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

/// Instructions of subroutines inlined into one function, at most: each inlined call compiles
/// the subroutine's blocks again, so this bounds a function's growth.
const INLINE_BUDGET: usize = 2 * super::PIECE;

/// A subroutine compiled inline at one `CALL`.
struct Inline {
    /// Its blocks, as indices into [`Analysis::leaders`], sorted, and the Cranelift block of
    /// each for this call.
    members: Vec<usize>,
    blocks: Vec<Block>,
    /// Where its `RET` goes: after the `CALL`, where the caller's registers are restored.
    back: Block,
    /// The call's frame, pushed only when the code leaves from inside ([`Gen::exit`]).
    frame: Frame,
}

/// The frame of a `CALL` as the interpreter pushes it: where to return, and the caller's
/// registers (the loop depth is the context's, which native code never changes).
#[derive(Clone, Copy)]
struct Frame {
    return_pc: usize,
    rung: Value,
    blocks: Value,
    branches: Value,
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
    /// The [`Context`](code::Context) of the call.
    ctx: Value,
    /// Its [`IlContext`].
    il: Value,
    /// The [`NativeRegs`] of the call.
    regs_at: Value,
    words: Value,
    /// Edge memory, a byte a slot.
    edges: Value,
    /// The instruction list's call stack.
    il_calls: Value,
    /// The counters' states.
    counters: Value,
    /// The timers' states.
    timers: Value,
    /// The signature of [`code::il_now`].
    now_sig: cranelift_codegen::ir::SigRef,
    /// The block for a program counter that is no leader of this piece (its parameter).
    elsewhere: Option<Block>,
    regs: Regs,
    /// The piece this function is; `None` for a subroutine's function.
    piece: Option<usize>,
    /// The blocks this function has, as indices into [`Analysis::leaders`], sorted: a piece's
    /// range, or a subroutine's blocks.
    members: Vec<usize>,
    /// The Cranelift block of each of `members`.
    blocks: Vec<Block>,
    /// Each function's name in the module.
    names: &'a [u32],
    /// The signature of a subroutine's function (every generated function's).
    sub_sig: SigRef,
    /// The subroutine functions this one calls, by their index in `analysis.subroutines`.
    callees: Vec<(usize, FuncRef)>,
    /// The inlined subroutine being compiled, if any.
    inline: Option<Inline>,
    /// Instructions of subroutines inlined into this function so far.
    inlined: usize,
    /// The words the current block holds, by index.
    held: HashMap<u16, Word>,
    /// The instruction being compiled.
    pc: usize,
    /// The end of the block being compiled.
    block_end: usize,
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
        self.blocks = self.members.iter().map(|_| self.b.create_block()).collect();
        let elsewhere = self.b.create_block();
        let pc_param = self.b.append_block_param(elsewhere, I32);
        self.elsewhere = Some(elsewhere);
        self.switch_on(pc);
        // Any other pc: the interpreter if this piece's range has it (the entry's pc, unchanged,
        // or a return address that is no leader), else the piece that has it.
        self.b.switch_to_block(elsewhere);
        self.b.set_cold_block(elsewhere);
        let piece = self.piece.expect("a piece");
        let low = self.analysis.leaders[self.members[0]];
        let high = self
            .analysis
            .pieces
            .get(piece + 1)
            .map_or(u32::MAX, |next| self.analysis.leaders[next.start]);
        let below = self.b.ins().icmp_imm_u(IntCC::UnsignedLessThan, pc_param, i64::from(low));
        let above =
            self.b.ins().icmp_imm_u(IntCC::UnsignedGreaterThanOrEqual, pc_param, i64::from(high));
        let outside = self.b.ins().bor(below, above);
        let interpret = self.b.ins().iconst(I32, i64::from(RETURN_INTERPRET));
        let other = self.b.ins().iconst(I32, i64::from(RETURN_CONTINUE));
        let status = self.b.ins().select(outside, other, interpret);
        self.store_regs(pc_param);
        self.b.ins().return_(&[status]);
    }

    /// The entry of a subroutine's function, which only native code calls (a `CALL` that has
    /// pushed the call's frame): the registers of a subroutine's start (the rung ON, both
    /// stacks empty), the budget left from the parameter, straight to the target's block.
    fn subroutine_entry(&mut self, target: u32) {
        let entry = self.b.current_block().expect("the entry block");
        let left = self.b.block_params(entry)[1];
        let (on, zero) = (self.b.ins().iconst(I32, 1), self.b.ins().iconst(I32, 0));
        self.b.def_var(self.regs.rung, on);
        self.b.def_var(self.regs.blocks, zero);
        self.b.def_var(self.regs.branches, zero);
        self.b.def_var(self.regs.left, left);
        self.blocks = self.members.iter().map(|_| self.b.create_block()).collect();
        let index = self.analysis.leaders.binary_search(&target).expect("a call target leads");
        let block = self.block_of(index).expect("a subroutine has its first block");
        self.b.ins().jump(block, &[]);
    }

    /// Goes on in a new block when `ok`, else in a cold one where `cold` ends the code.
    fn unless(&mut self, ok: Value, cold: impl FnOnce(&mut Self)) {
        let run = self.b.create_block();
        let refuse = self.b.create_block();
        self.b.set_cold_block(refuse);
        self.b.ins().brif(ok, run, &[], refuse, &[]);
        self.b.switch_to_block(refuse);
        cold(self);
        self.b.switch_to_block(run);
    }

    /// The block of leader `index` in this function, if it has it.
    fn block_of(&self, index: usize) -> Option<Block> {
        self.members.binary_search(&index).ok().map(|member| self.blocks[member])
    }

    /// Goes on at the block of `pc` (I32), found in the piece's dispatch table where `pc` is in
    /// its range, or at the block for any other pc. Each use is a jump table of its own (the
    /// entry's, and each `RET`'s), so that the processor predicts each indirect jump from its
    /// own history: one shared by every `RET` of the program was mispredicted at most returns.
    fn switch_on(&mut self, pc: Value) {
        let table = &self.analysis.dispatch[self.piece.expect("a piece")];
        let low = self.analysis.leaders[self.members[0]];
        let offset = self.b.ins().iadd_imm_s(pc, -i64::from(low));
        let inside = self.b.ins().icmp_imm_u(IntCC::UnsignedLessThan, offset, table.len() as i64);
        let zero = self.b.ins().iconst(I32, 0);
        let offset = self.b.ins().select(inside, offset, zero);
        let offset = self.b.ins().uextend(I64, offset);
        let offset = self.b.ins().ishl_imm_s(offset, 1);
        let table_at = self.b.ins().iconst(I64, table.as_ptr() as i64);
        let entry = self.b.ins().iadd(table_at, offset);
        let index = self.b.ins().uload16(I32, readonly(), entry, 0);
        let none = self.b.ins().iconst(I32, self.blocks.len() as i64);
        let index = self.b.ins().select(inside, index, none);
        let calls: Vec<_> =
            self.blocks.iter().map(|&block| self.b.func.dfg.block_call(block, &[])).collect();
        let elsewhere = self.elsewhere.expect("the entry made it");
        let default = self.b.func.dfg.block_call(elsewhere, &[pc.into()]);
        let jump_table = self.b.create_jump_table(JumpTableData::new(default, &calls));
        self.b.ins().br_table(index, jump_table);
    }

    fn ret(&mut self, status: u32) {
        let status = self.b.ins().iconst(I32, i64::from(status));
        self.b.ins().return_(&[status]);
    }

    /// Leaves with `status`: the registers, with `pc`, back to the context, and the frame of
    /// the inlined call the code is in, if any, pushed as the interpreter would have it.
    fn exit(&mut self, pc: usize, status: u32) {
        if let Some(frame) = self.inline.as_ref().map(|inline| inline.frame) {
            // The depth in the context is still the caller's: read again here rather than
            // held in a register through the subroutine for the cold paths alone.
            let depth = self.field32(offset_of!(NativeRegs, il_depth));
            self.push(frame, depth);
        }
        let pc = self.b.ins().iconst(I32, pc as i64);
        self.store_regs(pc);
        self.ret(status);
    }

    /// The registers, with `pc`, back to the context.
    fn store_regs(&mut self, pc: Value) {
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
    }

    /// Goes on at `pc`: its block in this piece, the piece that has it (through
    /// [`Code::run`](crate::code::Code)), or the interpreter past the compiled code.
    fn go_on(&mut self, pc: usize) {
        if let Some(inline) = &self.inline {
            // An inlined subroutine's blocks, or out of it by the VM (never into the blocks
            // around it: a subroutine's function returns at its own `RET`).
            let index = self.analysis.leaders.binary_search(&(pc as u32));
            match index.map(|index| inline.members.binary_search(&index)) {
                Ok(Ok(member)) => {
                    let block = inline.blocks[member];
                    self.b.ins().jump(block, &[]);
                }
                Ok(Err(_)) => self.exit(pc, RETURN_CONTINUE),
                Err(_) => self.exit(pc, RETURN_INTERPRET),
            }
            return;
        }
        match self.analysis.leaders.binary_search(&(pc as u32)) {
            Ok(index) if self.block_of(index).is_some() => {
                let block = self.block_of(index).expect("just found");
                self.b.ins().jump(block, &[]);
            }
            Ok(_) => self.exit(pc, RETURN_CONTINUE),
            Err(_) => self.exit(pc, RETURN_INTERPRET),
        }
    }

    fn body(&mut self) {
        for (member, index) in self.members.clone().into_iter().enumerate() {
            self.b.switch_to_block(self.blocks[member]);
            self.block(index);
        }
    }

    /// The code of the block at `analysis.leaders[index]`, in the current Cranelift block.
    fn block(&mut self, index: usize) {
        let range = self.analysis.block(self.code, index);
        self.held.clear();
        if !is_native(&self.code[range.start]) {
            self.exit(range.start, RETURN_INTERPRET);
            return;
        }
        // The budget covers the whole block, or the interpreter takes it.
        let n = range.len() as i64;
        let left = self.b.use_var(self.regs.left);
        let enough = self.b.ins().icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, left, n);
        self.unless(enough, |g| g.exit(range.start, RETURN_INTERPRET));
        let left = self.b.ins().iadd_imm_s(left, -n);
        self.b.def_var(self.regs.left, left);
        let mut ended = false;
        self.block_end = range.end;
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
                Op::Arith { op: ArithOp::Div, a, b, d, pulse } => {
                    let on = self.enabled(pulse);
                    self.div(a, b, d, on, pc, range.end);
                }
                Op::Call { target } => {
                    self.call(target, pc);
                    ended = true;
                }
                Op::Ret => {
                    self.ret_op(pc);
                    ended = true;
                }
                op => self.op(op),
            }
        }
        if !ended {
            self.go_on(range.end);
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

    /// `DIV a b d` at `pc` in a block that ends before `end`, executed when `on` (0 or 1):
    /// when `on` and `b` is 0 (an operation error), the interpreter takes the instruction, with
    /// the budget of the block's instructions from `pc` on given back; otherwise `d` gets the
    /// quotient when `on` and stays when not. In 32 bits, -32768 / -1 is 32768, whose low 16
    /// bits are the interpreter's wrapping result, and the division cannot trap.
    ///
    /// The `P` form has taken its edge by then, and the interpreter would take it again: its
    /// edge slot is put back first (the instruction wrote nothing else).
    fn div(&mut self, a: Src, b: Src, d: WordRef, on: Value, pc: usize, end: usize) {
        let (a, b) = (self.signed(a), self.signed(b));
        let zero = self.b.ins().icmp_imm_s(IntCC::Equal, b, 0);
        let zero = self.b.ins().uextend(I32, zero);
        let fails = self.b.ins().band(on, zero);
        let error = self.b.create_block();
        let divide = self.b.create_block();
        self.b.set_cold_block(error);
        self.b.ins().brif(fails, error, &[], divide, &[]);
        self.b.switch_to_block(error);
        if let Op::Arith { pulse: Some(slot), .. } = self.code[pc] {
            // The slot held OFF (there was a rising edge): OFF again.
            let off = self.b.ins().iconst(types::I8, 0);
            self.b.ins().store(data(), off, self.edges, i32::from(slot));
        }
        self.give_back_and_exit(pc, end);
        self.b.switch_to_block(divide);
        let one = self.b.ins().iconst(I32, 1);
        let divisor = self.b.ins().select(zero, one, b);
        let quotient = self.b.ins().sdiv(a, divisor);
        self.store_if(on, d, quotient);
    }

    /// Leaves for the interpreter at `pc`, with the budget of the block's instructions from
    /// `pc` to `end` given back.
    fn give_back_and_exit(&mut self, pc: usize, end: usize) {
        let left = self.b.use_var(self.regs.left);
        let back = self.b.ins().iadd_imm_s(left, (end - pc) as i64);
        self.b.def_var(self.regs.left, back);
        self.exit(pc, RETURN_INTERPRET);
    }

    /// The edge of the value `now` (bit 0) seen by edge slot `slot`, which then holds it: 1 at
    /// a rising (`rising`) or falling edge, else 0.
    fn edge(&mut self, slot: u16, now: Value, rising: bool) -> Value {
        let now = self.b.ins().band_imm_s(now, 1);
        self.edge_at(self.edges, usize::from(slot), now, rising)
    }

    /// The edge of `now` (0 or 1) against the byte at `at` from `base` (an edge slot, a timer's
    /// or a counter's previous input), which then holds `now`.
    fn edge_at(&mut self, base: Value, at: usize, now: Value, rising: bool) -> Value {
        let before = self.load_field(base, at, types::I8);
        self.store_field(base, at, types::I8, now);
        if rising {
            self.b.ins().band_not(now, before)
        } else {
            self.b.ins().band_not(before, now)
        }
    }

    /// Whether a data instruction executes (0 or 1): the rung, or its rising edge for the `P`
    /// form.
    fn enabled(&mut self, pulse: Option<u16>) -> Value {
        let rung = self.rung();
        match pulse {
            None => rung,
            Some(slot) => self.edge(slot, rung, true),
        }
    }

    /// `CALL` at `pc`, the last instruction of its block: when the rung is ON, a frame for the
    /// return (pushed now, or only where the code leaves an inlined call: [`Gen::inline_call`])
    /// and the subroutine at `target`, with the rung ON and empty stacks; a call deeper than
    /// `CALL_DEPTH` (an operation error) is the interpreter's.
    fn call(&mut self, target: u32, pc: usize) {
        let rung = self.rung();
        let taken = self.b.create_block();
        let not_taken = self.b.create_block();
        self.b.ins().brif(rung, taken, &[], not_taken, &[]);
        self.b.switch_to_block(not_taken);
        self.go_on(pc + 1);
        self.b.switch_to_block(taken);
        let depth = if (pc as u32) < self.analysis.main_end {
            // the main routine's: at depth 0, whatever the context holds
            self.b.ins().iconst(I32, 0)
        } else {
            let depth = self.field32(offset_of!(NativeRegs, il_depth));
            let full = self.b.ins().icmp_imm_u(
                IntCC::UnsignedGreaterThanOrEqual,
                depth,
                CALL_DEPTH as i64,
            );
            let push = self.b.create_block();
            let error = self.b.create_block();
            self.b.set_cold_block(error);
            self.b.ins().brif(full, error, &[], push, &[]);
            self.b.switch_to_block(error);
            self.give_back_and_exit(pc, pc + 1);
            self.b.switch_to_block(push);
            depth
        };
        let blocks = self.b.use_var(self.regs.blocks);
        let branches = self.b.use_var(self.regs.branches);
        let frame = Frame { return_pc: pc + 1, rung, blocks, branches };
        let (on, zero) = (self.b.ins().iconst(I32, 1), self.b.ins().iconst(I32, 0));
        self.b.def_var(self.regs.rung, on);
        self.b.def_var(self.regs.blocks, zero);
        self.b.def_var(self.regs.branches, zero);
        match self.analysis.subroutine_at(target) {
            Some(sub) if self.inlines(sub) => self.inline_call(sub, target, frame),
            Some(sub) => {
                self.push(frame, depth);
                self.machine_call(sub, target, frame);
            }
            None => {
                self.push(frame, depth);
                self.enter_by_dispatch(target);
            }
        }
    }

    /// Pushes `frame` where the interpreter has it, on the caller's call depth `depth`: the
    /// frame there, the depth one more. The loop depth it keeps is the context's: `FOR` and
    /// `NEXT` are the interpreter's.
    fn push(&mut self, frame: Frame, depth: Value) {
        let at = self.frame_at(depth);
        let return_pc = self.b.ins().iconst(I32, frame.return_pc as i64);
        let loop_depth = self.field32(offset_of!(NativeRegs, loop_depth));
        for (value, offset) in [
            (return_pc, offset_of!(IlFrame, return_pc)),
            (frame.blocks, offset_of!(IlFrame, blocks)),
            (frame.branches, offset_of!(IlFrame, branches)),
        ] {
            self.b.ins().store(own(), value, at, offset as i32);
        }
        // The rung and the loop depth are bytes.
        for (value, offset) in
            [(frame.rung, offset_of!(IlFrame, rung)), (loop_depth, offset_of!(IlFrame, loop_depth))]
        {
            self.b.ins().istore8(own(), value, at, offset as i32);
        }
        let deeper = self.b.ins().iadd_imm_s(depth, 1);
        self.store32(deeper, offset_of!(NativeRegs, il_depth));
    }

    /// Whether a `CALL` of subroutine `sub` here is compiled inline: a small subroutine without
    /// calls, while this function's inlined instructions stay within [`INLINE_BUDGET`].
    fn inlines(&mut self, sub: usize) -> bool {
        let Some(size) = self.analysis.subroutines[sub].inline else { return false };
        if self.inline.is_some() || self.inlined + size > INLINE_BUDGET {
            return false;
        }
        self.inlined += size;
        true
    }

    /// The `CALL` (of `frame`) of subroutine `sub` (at `target`), the callee's registers set,
    /// with the subroutine's blocks compiled here, for this call alone: its `RET` goes on after
    /// the `CALL` with the caller's registers (`frame`'s), the budget where the subroutine left
    /// it. The frame is not pushed: nothing reads it while the code runs inside, and the `RET`
    /// would pop it again (the call depth back to the caller's, the loop depth to what it was,
    /// which nothing inside changes). Only leaving native code from inside pushes it
    /// ([`Gen::exit`]: a stop, or control leaving the blocks), for the VM, which goes on in the
    /// piece that holds the place.
    fn inline_call(&mut self, sub: usize, target: u32, frame: Frame) {
        let members = self.analysis.subroutines[sub].blocks.clone();
        let blocks: Vec<Block> = members.iter().map(|_| self.b.create_block()).collect();
        let back = self.b.create_block();
        let first = self.analysis.leaders.binary_search(&target).expect("a call target leads");
        let entry = blocks[members.binary_search(&first).expect("a subroutine's first block")];
        self.b.ins().jump(entry, &[]);
        self.inline =
            Some(Inline { members: members.clone(), blocks: blocks.clone(), back, frame });
        for (member, index) in members.into_iter().enumerate() {
            self.b.switch_to_block(blocks[member]);
            self.block(index);
        }
        self.inline = None;
        self.b.switch_to_block(back);
        self.returned(frame);
    }

    /// After the subroutine called with `frame` returned: the caller's rung and stacks as they
    /// were at the call (what its `RET` restores from the frame), the words held before
    /// forgotten (the subroutine may have written any), on at the return address.
    fn returned(&mut self, frame: Frame) {
        self.b.def_var(self.regs.rung, frame.rung);
        self.b.def_var(self.regs.blocks, frame.blocks);
        self.b.def_var(self.regs.branches, frame.branches);
        self.held.clear();
        self.go_on(frame.return_pc);
    }

    /// Goes on at `target`, the frame of its call pushed, other than by a machine call: a
    /// piece jumps to it (its `RET` goes back through the dispatch); a subroutine's function
    /// leaves for the VM, which enters the piece that holds it, so that a `RET` of this
    /// function always returns from the machine call that entered it.
    fn enter_by_dispatch(&mut self, target: u32) {
        if self.piece.is_some() {
            self.go_on(target as usize);
        } else {
            self.exit(target as usize, RETURN_CONTINUE);
        }
    }

    /// The `CALL` (of `frame`) of subroutine `sub` (at `target`), its frame pushed and the
    /// callee's registers set: a machine call of the subroutine's function. When it returned
    /// ([`RETURN_RETURNED`]), the caller goes on after the `CALL` with its registers as they
    /// were (`frame`'s: the rung and both stacks, which the `RET` restores from the frame) and
    /// the budget the callee left; any other result is passed on, every register in the
    /// context where the callee stopped, as the VM finds them.
    fn machine_call(&mut self, sub: usize, target: u32, frame: Frame) {
        // The machine stack: below the context's floor, the call goes through the dispatch.
        let stack = self.b.ins().get_stack_pointer(I64);
        let floor = self.b.ins().load(I64, readonly(), self.ctx, code::CONTEXT.stack_floor as i32);
        let room = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, stack, floor);
        self.unless(room, |g| g.enter_by_dispatch(target));
        let left = self.b.use_var(self.regs.left);
        let callee = self.callee(sub);
        let args = [self.ctx, left, self.regs_at, self.words, self.il, self.il_calls, self.edges];
        crate::codegen::call_or_pass_on(&mut self.b, callee, &args, RETURN_RETURNED);
        let left = self.b.ins().load(I64, own(), self.regs_at, offset_of!(NativeRegs, left) as i32);
        self.b.def_var(self.regs.left, left);
        self.returned(frame);
    }

    /// Subroutine `sub`'s function, imported into this one.
    fn callee(&mut self, sub: usize) -> FuncRef {
        if let Some(&(_, callee)) = self.callees.iter().find(|(at, _)| *at == sub) {
            return callee;
        }
        let function = self.analysis.pieces.len() + sub;
        let callee =
            crate::codegen::import_function(&mut self.b, self.names[function], self.sub_sig);
        self.callees.push((sub, callee));
        callee
    }

    /// `RET` at `pc`, the last instruction of its block: back to the caller's registers and
    /// return address, through the dispatch; an inlined call's, which pushed no frame, a jump
    /// back after its `CALL`. A `RET` without a call (never, in a checked program) is the
    /// interpreter's.
    fn ret_op(&mut self, pc: usize) {
        if let Some(inline) = &self.inline {
            let back = inline.back;
            self.b.ins().jump(back, &[]);
            return;
        }
        let depth = self.field32(offset_of!(NativeRegs, il_depth));
        let pop = self.b.create_block();
        let none = self.b.create_block();
        self.b.set_cold_block(none);
        self.b.ins().brif(depth, pop, &[], none, &[]);
        self.b.switch_to_block(none);
        self.give_back_and_exit(pc, pc + 1);
        self.b.switch_to_block(pop);
        let depth = self.b.ins().iadd_imm_s(depth, -1);
        self.store32(depth, offset_of!(NativeRegs, il_depth));
        let frame = self.frame_at(depth);
        let load = |g: &mut Self, offset: usize| g.b.ins().load(I32, own(), frame, offset as i32);
        let byte = |g: &mut Self, offset: usize| g.b.ins().uload8(I32, own(), frame, offset as i32);
        let loop_depth = byte(self, offset_of!(IlFrame, loop_depth));
        self.store32(loop_depth, offset_of!(NativeRegs, loop_depth));
        if self.piece.is_none() {
            // A subroutine's function returns to the machine call that entered it, which has
            // the caller's registers; only the budget goes back.
            let left = self.b.use_var(self.regs.left);
            let at = offset_of!(NativeRegs, left) as i32;
            self.b.ins().store(own(), left, self.regs_at, at);
            self.ret(RETURN_RETURNED);
            return;
        }
        let return_pc = load(self, offset_of!(IlFrame, return_pc));
        let rung = byte(self, offset_of!(IlFrame, rung));
        let blocks = load(self, offset_of!(IlFrame, blocks));
        let branches = load(self, offset_of!(IlFrame, branches));
        self.b.def_var(self.regs.rung, rung);
        self.b.def_var(self.regs.blocks, blocks);
        self.b.def_var(self.regs.branches, branches);
        self.switch_on(return_pc);
    }

    /// The address of call frame `depth` (below `CALL_DEPTH`).
    fn frame_at(&mut self, depth: Value) -> Value {
        let depth = self.b.ins().uextend(I64, depth);
        let offset = self.b.ins().imul_imm_u(depth, std::mem::size_of::<IlFrame>() as i64);
        self.b.ins().iadd(self.il_calls, offset)
    }

    fn store32(&mut self, value: Value, offset: usize) {
        self.b.ins().store(own(), value, self.regs_at, offset as i32);
    }

    /// The time of the instruction being compiled (I64). The common case, a `StepClock` at or
    /// after its origin, is `stop_ns - left * step_ns` with `left` the budget left after the
    /// instruction (`IlContext::fast_below` says when it holds); otherwise the time is computed
    /// as the clock does, or asked of the clock ([`code::il_now`]), on a cold path.
    fn now(&mut self) -> Value {
        let field = |g: &mut Self, offset: usize| g.b.ins().load(I64, own(), g.il, offset as i32);
        let left = self.b.use_var(self.regs.left);
        // The budget left after this instruction: the block charged all of it at its start.
        let left = self.b.ins().iadd_imm_s(left, (self.block_end - self.pc - 1) as i64);
        let fast_below = field(self, offset_of!(IlContext<'static>, fast_below));
        let fast = self.b.ins().icmp(IntCC::UnsignedLessThan, left, fast_below);
        let fast_block = self.b.create_block();
        let slow = self.b.create_block();
        let compute = self.b.create_block();
        let ask = self.b.create_block();
        let done = self.b.create_block();
        let now = self.b.append_block_param(done, I64);
        self.b.ins().brif(fast, fast_block, &[], slow, &[]);
        self.b.switch_to_block(fast_block);
        let step_ns = field(self, offset_of!(IlContext<'static>, step_ns));
        let stop_ns = field(self, offset_of!(IlContext<'static>, stop_ns));
        let since = self.b.ins().imul(left, step_ns);
        let fast_now = self.b.ins().isub(stop_ns, since);
        self.b.ins().jump(done, &[fast_now.into()]);
        self.b.switch_to_block(slow);
        self.b.set_cold_block(slow);
        let stop = field(self, offset_of!(IlContext<'static>, stop));
        let steps = self.b.ins().isub(stop, left);
        let linear = field(self, offset_of!(IlContext<'static>, linear));
        self.b.ins().brif(linear, compute, &[], ask, &[]);
        self.b.switch_to_block(compute);
        self.b.set_cold_block(compute);
        let origin_ns = field(self, offset_of!(IlContext<'static>, origin_ns));
        let origin_steps = field(self, offset_of!(IlContext<'static>, origin_steps));
        let step_ns = field(self, offset_of!(IlContext<'static>, step_ns));
        let since = self.b.ins().isub(steps, origin_steps);
        let after = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, steps, origin_steps);
        let zero = self.b.ins().iconst(I64, 0);
        let since = self.b.ins().select(after, since, zero);
        let elapsed = self.b.ins().imul(since, step_ns);
        let computed = self.b.ins().iadd(origin_ns, elapsed);
        self.b.ins().jump(done, &[computed.into()]);
        self.b.switch_to_block(ask);
        self.b.set_cold_block(ask);
        let function =
            code::il_now as extern "C" fn(*const code::Context<'static>, u64) -> u64 as usize;
        let callee = self.b.ins().iconst(I64, function as i64);
        let call = self.b.ins().call_indirect(self.now_sig, callee, &[self.ctx, steps]);
        let asked = self.b.inst_results(call)[0];
        self.b.ins().jump(done, &[asked.into()]);
        self.b.switch_to_block(done);
        now
    }

    /// A field of a state machine at `at` bytes from `base` (an 8-, 16- or 64-bit one, by
    /// `ty`), in 32 bits but for the 64-bit ones.
    fn load_field(&mut self, base: Value, at: usize, ty: types::Type) -> Value {
        let at = at as i32;
        match ty {
            I64 => self.b.ins().load(I64, data(), base, at),
            types::I16 => self.b.ins().uload16(I32, data(), base, at),
            _ => self.b.ins().uload8(I32, data(), base, at),
        }
    }

    /// Stores `value` (I64, or I32 for the narrower fields) in the field at `at` bytes from
    /// `base`. A constant is stored as an immediate: x86's `mov` to memory takes one, but
    /// Cranelift gives it only to a `store` of a constant of the field's own type (an
    /// `istore8` or `istore16` of an I32 constant took a register for it, held across the
    /// block, and spilled).
    fn store_field(&mut self, base: Value, at: usize, ty: types::Type, value: Value) {
        let at = at as i32;
        if let Some(c) = self.constant(value) {
            let c = if ty == I64 { c } else { c & ((1 << ty.bits()) - 1) };
            let narrow = self.b.ins().iconst(ty, c);
            self.b.ins().store(data(), narrow, base, at);
            return;
        }
        match ty {
            I64 => self.b.ins().store(data(), value, base, at),
            types::I16 => self.b.ins().istore16(data(), value, base, at),
            _ => self.b.ins().istore8(data(), value, base, at),
        };
    }

    /// The value of `v` if an `iconst` defines it.
    fn constant(&self, v: Value) -> Option<i64> {
        let dfg = &self.b.func.dfg;
        let inst = dfg.value_def(v).inst()?;
        match dfg.insts[inst] {
            InstructionData::UnaryImm { opcode: Opcode::Iconst, imm } => Some(imm.bits()),
            _ => None,
        }
    }

    /// Timer `n`'s field at `offset` (`timer::layout`).
    fn timer_field(&mut self, n: u16, offset: usize, ty: types::Type) -> Value {
        let at = usize::from(n) * timer::layout::SIZE + offset;
        self.load_field(self.timers, at, ty)
    }

    fn set_timer_field(&mut self, n: u16, offset: usize, ty: types::Type, value: Value) {
        let at = usize::from(n) * timer::layout::SIZE + offset;
        self.store_field(self.timers, at, ty, value);
    }

    /// A timer (the VM's `timer::execute`): a branch on what the timer does now (count, stay
    /// idle, stop), each path computing only its own fields, and a cold path for a current
    /// value the program wrote. The paths meet to write the value and the contact.
    fn timer(&mut self, kind: TimerKind, n: u16, preset: Src, base_ms: u16) {
        use timer::layout::{ELAPSED_NS, PREV_INPUT, RUNNING, SHOWN};
        let base_ns = i64::from(base_ms) * 1_000_000;
        let input = self.rung();
        let preset = self.unsigned(preset);
        let written = self.word(timer_value(n));
        let written = self.b.ins().band_imm_s(written, 0xFFFF);
        // The contact's word, read here so that the paths' meeting point has it held.
        let was_done = self.bit(timer_done(n));
        let was_done = self.b.ins().band_imm_s(was_done, 1);
        // A value the program wrote (`MOV 30 T0001`): the timer goes on from it.
        let counts_down = matches!(kind, TimerKind::Toff | TimerKind::Tmon | TimerKind::Trtg);
        let shown = self.timer_field(n, SHOWN, types::I16);
        let changed = self.b.ins().icmp(IntCC::NotEqual, written, shown);
        let from_written = self.b.create_block();
        let go_on = self.b.create_block();
        self.b.set_cold_block(from_written);
        self.b.ins().brif(changed, from_written, &[], go_on, &[]);
        self.b.switch_to_block(from_written);
        let ticks_written = if counts_down {
            let below = self.b.ins().icmp(IntCC::UnsignedLessThan, written, preset);
            let rest = self.b.ins().isub(preset, written);
            let zero = self.b.ins().iconst(I32, 0);
            self.b.ins().select(below, rest, zero)
        } else {
            self.b.ins().umin(written, preset)
        };
        let ticks_written = self.b.ins().uextend(I64, ticks_written);
        let elapsed = self.b.ins().imul_imm_s(ticks_written, base_ns);
        self.set_timer_field(n, ELAPSED_NS, I64, elapsed);
        self.b.ins().jump(go_on, &[]);
        self.b.switch_to_block(go_on);
        // The input's edge (the timers that start at it), or the input kept.
        let rising = if matches!(kind, TimerKind::Tmon | TimerKind::Trtg) {
            let prev_input = usize::from(n) * timer::layout::SIZE + PREV_INPUT;
            Some(self.edge_at(self.timers, prev_input, input, true))
        } else {
            self.set_timer_field(n, PREV_INPUT, types::I8, input);
            None
        };
        // Where the paths meet, with the current value and the contact (0 or 1).
        let meet = self.b.create_block();
        let value = self.b.append_block_param(meet, I32);
        let done = self.b.append_block_param(meet, I32);
        match kind {
            TimerKind::Ton => {
                // ON: counting (from 0 if it was not running); OFF: idle at 0.
                let on = self.b.create_block();
                let off = self.b.create_block();
                self.b.ins().brif(input, on, &[], off, &[]);
                self.b.switch_to_block(off);
                self.timer_reset(n, meet);
                self.b.switch_to_block(on);
                let elapsed = self.timer_elapsed(n, false);
                self.timer_counts_up(n, elapsed, preset, base_ns, meet);
            }
            TimerKind::Tmr => {
                // ON: counting on; OFF: stopped, its value kept.
                let on = self.b.create_block();
                let off = self.b.create_block();
                self.b.ins().brif(input, on, &[], off, &[]);
                self.b.switch_to_block(off);
                let zero = self.b.ins().iconst(I32, 0);
                self.set_timer_field(n, RUNNING, types::I8, zero);
                let elapsed = self.timer_field(n, ELAPSED_NS, I64);
                let value = self.timer_ticks(elapsed, preset, base_ns);
                let done = self.flag(IntCC::UnsignedGreaterThanOrEqual, value, preset);
                self.b.ins().jump(meet, &[value.into(), done.into()]);
                self.b.switch_to_block(on);
                let elapsed = self.timer_elapsed(n, true);
                self.timer_counts_up(n, elapsed, preset, base_ns, meet);
            }
            TimerKind::Toff => {
                // ON: idle at the preset, contact ON; OFF after ON (the contact still ON):
                // counting down; OFF and idle: 0 and OFF.
                let on = self.b.create_block();
                let off = self.b.create_block();
                let down = self.b.create_block();
                let idle = self.b.create_block();
                self.b.ins().brif(input, on, &[], off, &[]);
                self.b.switch_to_block(on);
                let (zero, zero64) = (self.b.ins().iconst(I32, 0), self.b.ins().iconst(I64, 0));
                self.set_timer_field(n, RUNNING, types::I8, zero);
                self.set_timer_field(n, ELAPSED_NS, I64, zero64);
                let one = self.b.ins().iconst(I32, 1);
                self.b.ins().jump(meet, &[preset.into(), one.into()]);
                self.b.switch_to_block(off);
                self.b.ins().brif(was_done, down, &[], idle, &[]);
                self.b.switch_to_block(idle);
                let zero = self.b.ins().iconst(I32, 0);
                self.b.ins().jump(meet, &[zero.into(), zero.into()]);
                self.b.switch_to_block(down);
                let elapsed = self.timer_elapsed(n, false);
                self.timer_counts_down(n, elapsed, preset, base_ns, meet);
            }
            TimerKind::Tmon | TimerKind::Trtg => {
                // Running or started by the edge: counting down (from the preset when it
                // starts: TMON when it was not running, TRTG at every edge); else idle.
                let rising = rising.expect("taken above");
                let running = self.timer_field(n, RUNNING, types::I8);
                let active = self.b.ins().bor(running, rising);
                let count = self.b.create_block();
                let idle = self.b.create_block();
                self.b.ins().brif(active, count, &[], idle, &[]);
                self.b.switch_to_block(idle);
                let zero = self.b.ins().iconst(I32, 0);
                self.b.ins().jump(meet, &[zero.into(), zero.into()]);
                self.b.switch_to_block(count);
                let start = if kind == TimerKind::Trtg {
                    rising
                } else {
                    self.b.ins().bxor_imm_s(running, 1)
                };
                let elapsed = self.timer_field(n, ELAPSED_NS, I64);
                let advanced = self.timer_advanced(n, elapsed);
                let zero = self.b.ins().iconst(I64, 0);
                let elapsed = self.b.ins().select(start, zero, advanced);
                self.timer_counts_down(n, elapsed, preset, base_ns, meet);
            }
        }
        self.b.switch_to_block(meet);
        self.set_timer_field(n, SHOWN, types::I16, value);
        self.set_word(timer_value(n), value);
        self.write_bit(timer_done(n), done);
    }

    /// Timer `n`'s elapsed time: brought up to now if it is running, else its stored time
    /// (`kept`) or 0.
    fn timer_elapsed(&mut self, n: u16, kept: bool) -> Value {
        use timer::layout::{ELAPSED_NS, RUNNING};
        let running = self.timer_field(n, RUNNING, types::I8);
        let elapsed = self.timer_field(n, ELAPSED_NS, I64);
        let advanced = self.timer_advanced(n, elapsed);
        let stopped = if kept { elapsed } else { self.b.ins().iconst(I64, 0) };
        self.b.ins().select(running, advanced, stopped)
    }

    /// Timer `n`'s `elapsed` time brought up to now (plus the time since it was last brought up
    /// to date, if any: the clock may be behind), now its last time.
    fn timer_advanced(&mut self, n: u16, elapsed: Value) -> Value {
        use timer::layout::LAST_NS;
        let last = self.timer_field(n, LAST_NS, I64);
        let now = self.now();
        self.set_timer_field(n, LAST_NS, I64, now);
        let later = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, now, last);
        let gone = self.b.ins().isub(now, last);
        let zero = self.b.ins().iconst(I64, 0);
        let gone = self.b.ins().select(later, gone, zero);
        self.b.ins().iadd(elapsed, gone)
    }

    /// The ticks of `elapsed` (I64): elapsed / base, at most the preset (I32).
    fn timer_ticks(&mut self, elapsed: Value, preset: Value, base_ns: i64) -> Value {
        let preset = self.b.ins().uextend(I64, preset);
        let t = self.b.ins().udiv_imm_u(elapsed, base_ns.max(1));
        let t = self.b.ins().umin(t, preset);
        self.b.ins().ireduce(I32, t)
    }

    /// TON and TMR counting with the input ON: `elapsed` (up to now) at most the preset, the
    /// timer running; on to `meet` with the value and the contact.
    fn timer_counts_up(
        &mut self,
        n: u16,
        elapsed: Value,
        preset: Value,
        base_ns: i64,
        meet: Block,
    ) {
        use timer::layout::{ELAPSED_NS, RUNNING};
        let preset64 = self.b.ins().uextend(I64, preset);
        let preset_ns = self.b.ins().imul_imm_s(preset64, base_ns);
        let elapsed = self.b.ins().umin(elapsed, preset_ns);
        self.set_timer_field(n, ELAPSED_NS, I64, elapsed);
        let one = self.b.ins().iconst(I32, 1);
        self.set_timer_field(n, RUNNING, types::I8, one);
        let value = self.timer_ticks(elapsed, preset, base_ns);
        let done = self.flag(IntCC::UnsignedGreaterThanOrEqual, value, preset);
        self.b.ins().jump(meet, &[value.into(), done.into()]);
    }

    /// TOFF, TMON and TRTG counting down: `elapsed` (up to now) kept, the value the preset less
    /// its ticks, the timer running and the contact ON while that is not 0; on to `meet`.
    fn timer_counts_down(
        &mut self,
        n: u16,
        elapsed: Value,
        preset: Value,
        base_ns: i64,
        meet: Block,
    ) {
        use timer::layout::{ELAPSED_NS, RUNNING};
        self.set_timer_field(n, ELAPSED_NS, I64, elapsed);
        let ticks = self.timer_ticks(elapsed, preset, base_ns);
        let value = self.b.ins().isub(preset, ticks);
        let zero = self.b.ins().iconst(I32, 0);
        let on = self.flag(IntCC::NotEqual, value, zero);
        self.set_timer_field(n, RUNNING, types::I8, on);
        self.b.ins().jump(meet, &[value.into(), on.into()]);
    }

    /// TON with the input OFF: the timer idle at 0 (its state all zeros, the input OFF as
    /// stored already); on to `meet` with value 0, contact OFF.
    fn timer_reset(&mut self, n: u16, meet: Block) {
        use timer::layout::{ELAPSED_NS, LAST_NS, RUNNING};
        let (zero, zero64) = (self.b.ins().iconst(I32, 0), self.b.ins().iconst(I64, 0));
        self.set_timer_field(n, ELAPSED_NS, I64, zero64);
        self.set_timer_field(n, LAST_NS, I64, zero64);
        self.set_timer_field(n, RUNNING, types::I8, zero);
        self.b.ins().jump(meet, &[zero.into(), zero.into()]);
    }

    /// `RST Tn`: with the rung ON, the timer idle (its input's edge memory kept), its value 0
    /// and its contact OFF.
    fn rst_timer(&mut self, n: u16) {
        use timer::layout::{ELAPSED_NS, LAST_NS, RUNNING, SHOWN};
        let rung = self.rung();
        for (offset, ty) in
            [(ELAPSED_NS, I64), (LAST_NS, I64), (RUNNING, types::I8), (SHOWN, types::I16)]
        {
            let old = self.timer_field(n, offset, ty);
            let zero = self.b.ins().iconst(if ty == I64 { I64 } else { I32 }, 0);
            let value = self.b.ins().select(rung, zero, old);
            self.set_timer_field(n, offset, ty, value);
        }
        let old = self.word(timer_value(n));
        let zero = self.b.ins().iconst(I32, 0);
        let value = self.b.ins().select(rung, zero, old);
        self.set_word(timer_value(n), value);
        let done = self.bit(timer_done(n));
        let done = self.b.ins().band_not(done, rung);
        let done = self.b.ins().band_imm_s(done, 1);
        self.write_bit(timer_done(n), done);
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
        let word = self.with_bit(b, on);
        self.set_word(WordRef(b.word), word);
    }

    /// The word of `bit` with the bit made `on` (0 or 1), not stored.
    fn with_bit(&mut self, b: BitRef, on: Value) -> Value {
        let word = self.word(WordRef(b.word));
        let cleared = self.b.ins().band_imm_s(word, i64::from(!b.mask));
        let set = if b.mask.is_power_of_two() {
            self.b.ins().ishl_imm_s(on, i64::from(b.mask.trailing_zeros()))
        } else {
            let ones = self.b.ins().ineg(on);
            self.b.ins().band_imm_s(ones, i64::from(b.mask))
        };
        self.b.ins().bor(cleared, set)
    }

    /// Stores `value` at `d` when `on` (0 or 1), the old value when not.
    fn store_if(&mut self, on: Value, d: WordRef, value: Value) {
        let old = self.word(d);
        let v = self.b.ins().select(on, value, old);
        self.set_word(d, v);
    }

    /// A source as an unsigned 16-bit value, in 32 bits.
    fn unsigned(&mut self, s: Src) -> Value {
        match s {
            Src::Word(w) => {
                let word = self.word(w);
                self.b.ins().band_imm_s(word, 0xFFFF)
            }
            Src::Const(c) => self.b.ins().iconst(I32, i64::from(c)),
        }
    }

    /// Counter `n`'s byte or half-word (`wide`) at `offset` (`counter::layout`), in 32 bits.
    fn counter_field(&mut self, n: u16, offset: usize, wide: bool) -> Value {
        let at = usize::from(n) * counter::layout::SIZE + offset;
        self.load_field(self.counters, at, if wide { types::I16 } else { types::I8 })
    }

    fn set_counter_field(&mut self, n: u16, offset: usize, wide: bool, value: Value) {
        let at = usize::from(n) * counter::layout::SIZE + offset;
        self.store_field(self.counters, at, if wide { types::I16 } else { types::I8 }, value);
    }

    /// The rising edge of `now` (0 or 1) against the counter field at `offset`, which then
    /// holds `now`.
    fn counter_edge(&mut self, n: u16, offset: usize, now: Value) -> Value {
        let at = usize::from(n) * counter::layout::SIZE + offset;
        self.edge_at(self.counters, at, now, true)
    }

    /// Counter `n`'s current value (unsigned, in 32 bits).
    fn counter_now(&mut self, n: u16) -> Value {
        let value = self.word(counter_value(n));
        self.b.ins().band_imm_s(value, 0xFFFF)
    }

    /// Writes counter `n`'s current value and contact (0 or 1).
    fn counter_out(&mut self, n: u16, value: Value, done: Value) {
        self.set_word(counter_value(n), value);
        self.write_bit(counter_done(n), done);
    }

    /// `value + add` (`add` 0 or 1), saturating at 65535.
    fn saturating_up(&mut self, value: Value, add: Value) -> Value {
        let top = self.b.ins().icmp_imm_s(IntCC::Equal, value, 0xFFFF);
        let sum = self.b.ins().iadd(value, add);
        self.b.ins().select(top, value, sum)
    }

    /// `value - sub` (`sub` 0 or 1), saturating at 0.
    fn saturating_down(&mut self, value: Value, sub: Value) -> Value {
        let zero = self.b.ins().icmp_imm_s(IntCC::Equal, value, 0);
        let difference = self.b.ins().isub(value, sub);
        self.b.ins().select(zero, value, difference)
    }

    fn flag(&mut self, cc: IntCC, a: Value, b: Value) -> Value {
        let holds = self.b.ins().icmp(cc, a, b);
        self.b.ins().uextend(I32, holds)
    }

    /// `CTU`, `CTD` or `CTR` (the VM's `counter::execute`, branch-free).
    fn counter(&mut self, kind: CounterKind, n: u16, preset: Src) {
        use counter::layout::{IS_DOWN, LOADED, PRESET, PREV_INPUT};
        let preset = self.unsigned(preset);
        let rung = self.rung();
        let rising = self.counter_edge(n, PREV_INPUT, rung);
        self.set_counter_field(n, PRESET, true, preset);
        let is_down = self.b.ins().iconst(I32, i64::from(kind == CounterKind::Ctd));
        self.set_counter_field(n, IS_DOWN, false, is_down);
        let value = self.counter_now(n);
        let (value, done) = match kind {
            CounterKind::Ctu => {
                let value = self.saturating_up(value, rising);
                (value, self.flag(IntCC::UnsignedGreaterThanOrEqual, value, preset))
            }
            CounterKind::Ctd => {
                // The preset, at the first execution since RUN (or RST).
                let loaded = self.counter_field(n, LOADED, false);
                let value = self.b.ins().select(loaded, value, preset);
                let one = self.b.ins().iconst(I32, 1);
                self.set_counter_field(n, LOADED, false, one);
                let value = self.saturating_down(value, rising);
                let done = self.b.ins().icmp_imm_s(IntCC::Equal, value, 0);
                (value, self.b.ins().uextend(I32, done))
            }
            CounterKind::Ctr => {
                let full = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, value, preset);
                let next = self.b.ins().iadd_imm_s(value, 1);
                let zero = self.b.ins().iconst(I32, 0);
                let next = self.b.ins().select(full, zero, next);
                let value = self.b.ins().select(rising, next, value);
                (value, self.flag(IntCC::UnsignedGreaterThanOrEqual, value, preset))
            }
        };
        self.counter_out(n, value, done);
    }

    /// `CTUD Cn up down preset` (the VM's `counter::execute_up_down`).
    fn up_down(&mut self, n: u16, up: BitRef, down: BitRef, preset: Src) {
        use counter::layout::{IS_DOWN, PRESET, PREV_DOWN, PREV_INPUT};
        let preset = self.unsigned(preset);
        let up = self.bit(up);
        let up = self.b.ins().band_imm_s(up, 1);
        let down = self.bit(down);
        let down = self.b.ins().band_imm_s(down, 1);
        let up_edge = self.counter_edge(n, PREV_INPUT, up);
        let down_edge = self.counter_edge(n, PREV_DOWN, down);
        self.set_counter_field(n, PRESET, true, preset);
        let zero = self.b.ins().iconst(I32, 0);
        self.set_counter_field(n, IS_DOWN, false, zero);
        let rung = self.rung();
        let up_edge = self.b.ins().band(up_edge, rung);
        let down_edge = self.b.ins().band(down_edge, rung);
        let value = self.counter_now(n);
        let value = self.saturating_up(value, up_edge);
        let value = self.saturating_down(value, down_edge);
        let done = self.flag(IntCC::UnsignedGreaterThanOrEqual, value, preset);
        self.counter_out(n, value, done);
    }

    /// `RST Cn`: with the rung ON, the current value 0 (the preset for a down counter that has
    /// loaded it) and the contact OFF.
    fn rst_counter(&mut self, n: u16) {
        use counter::layout::{IS_DOWN, LOADED, PRESET};
        let is_down = self.counter_field(n, IS_DOWN, false);
        let loaded = self.counter_field(n, LOADED, false);
        let preset = self.counter_field(n, PRESET, true);
        let keeps = self.b.ins().band(is_down, loaded);
        let zero = self.b.ins().iconst(I32, 0);
        let reset = self.b.ins().select(keeps, preset, zero);
        let rung = self.rung();
        let old = self.word(counter_value(n));
        let value = self.b.ins().select(rung, reset, old);
        let done = self.bit(counter_done(n));
        let done = self.b.ins().band_not(done, rung);
        let done = self.b.ins().band_imm_s(done, 1);
        self.counter_out(n, value, done);
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
            Op::EdgeContact { bit, rising, how, slot } => {
                let now = self.bit(bit);
                let edge = self.edge(slot, now, rising);
                self.combine(how, edge);
            }
            Op::OutPulse { bit, rising, slot } => {
                let rung = self.rung();
                let edge = self.edge(slot, rung, rising);
                self.write_bit(bit, edge);
            }
            Op::FlipFlop { bit, slot } => {
                // At the rung's rising edge the bit becomes the opposite of what it reads (all
                // of its mask, as the interpreter's `set_bit`).
                let rung = self.rung();
                let edge = self.edge(slot, rung, true);
                let was = self.bit(bit);
                let flipped = self.b.ins().bnot(was);
                let flipped = self.b.ins().band_imm_s(flipped, 1);
                let w = WordRef(bit.word);
                let old = self.word(w);
                let new = self.with_bit(bit, flipped);
                let word = self.b.ins().select(edge, new, old);
                self.set_word(w, word);
            }
            Op::Counter { kind, counter, preset } => self.counter(kind, counter, preset),
            Op::CounterUpDown { counter, up, down, preset } => {
                self.up_down(counter, up, down, preset);
            }
            Op::RstCounter(n) => self.rst_counter(n),
            Op::Timer { kind, timer, preset, base_ms } => self.timer(kind, timer, preset, base_ms),
            Op::RstTimer(n) => self.rst_timer(n),
            Op::Mov { s, d, pulse } => {
                let on = self.enabled(pulse);
                let value = self.signed(s);
                self.store_if(on, d, value);
            }
            Op::Arith { op, a, b, d, pulse } => {
                let on = self.enabled(pulse);
                let (a, b) = (self.signed(a), self.signed(b));
                // The low 16 bits of the 32-bit result are the 16-bit wrapping result.
                let value = match op {
                    ArithOp::Add => self.b.ins().iadd(a, b),
                    ArithOp::Sub => self.b.ins().isub(a, b),
                    ArithOp::Mul => self.b.ins().imul(a, b),
                    ArithOp::Div => unreachable!("DIV is compiled by Gen::div"),
                };
                self.store_if(on, d, value);
            }
            Op::Step { d, up, pulse } => {
                let on = self.enabled(pulse);
                let old = self.word(d);
                let all = self.b.ins().ineg(on);
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
