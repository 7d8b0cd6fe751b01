//! A Structured Text program's ops as one Cranelift function, `fn(*mut Context) -> u32`.
//!
//! The shape of the function:
//! - the entry loads the registers from the [`Context`] and goes to the dispatch;
//! - the dispatch is a switch on the program counter over the entry points (the leaders of
//!   [`Analysis`]); each goes through a loader, which reloads the evaluation stack's slots of
//!   that instruction from memory into SSA variables, to the leader's block; any other program
//!   counter goes back to the interpreter;
//! - a block first checks what its instructions need (enough step budget for all of them; the
//!   frame and the FB instance holding their operands) and hands the whole block to the
//!   interpreter if anything is missing, then charges the budget and runs the instructions
//!   with the evaluation stack in SSA variables, and goes on to the next block directly;
//! - inside a block the code remembers what it knows of each slot ([`SlotInfo`]: a pointer
//!   into variable memory or the frame that needs no check, a BOOL already 0 or 1, a REAL kept
//!   in a float register) and of each variable it stored or fetched ([`Held`], forgotten at
//!   any store that may change it), and checks an index against a range once;
//! - every way out stores the registers and the live stack slots back, exactly as the
//!   interpreter leaves them: at `END`, after an operation error, before an instruction it
//!   hands to the interpreter (a pointer outside variable memory and the frame, a full call
//!   stack).
//!
//! Calls push a [`StFrame`] as the interpreter does; the caller's stack slots go to memory
//! first (a callee's slots are numbered from its own start), and a return goes through the
//! dispatch to the return address's loader, which reloads them.

use std::mem::offset_of;

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{
    types, AbiParam, Block, Function, InstBuilder, MemFlagsData, SigRef, Signature, Type, Value,
};
use cranelift_codegen::isa::TargetIsa;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Switch, Variable};
use plcd_core::lang::native::{NativeRegs, StFrame};
use plcd_core::lang::ops::{CmpOp, Op, Place};
use plcd_core::lang::{Program, EVAL_DEPTH, ST_CALL_DEPTH};
use plcd_core::value::{BinOp, Elem, Pointer, Space, UnOp};
use plcd_core::vm::{ERR_DIVIDE_BY_ZERO, ERR_INDEX_RANGE};

use crate::analysis::{is_native, Analysis};
use crate::code::{self, Context, RETURN_END, RETURN_ERROR, RETURN_INTERPRET};
use crate::helpers;

const I64: Type = types::I64;
const MASK: i64 = EVAL_DEPTH as i64 - 1;
const LOW32: i64 = 0xFFFF_FFFF;
/// Copies up to this many bytes are inline.
const SHORT_COPY: u32 = 64;

/// The offset of a field of [`NativeRegs`].
fn reg(field: usize) -> i32 {
    field as i32
}

/// Variable memory, the frame, device memory: none of it is aligned, and none of it traps
/// (every access is inside a checked length).
pub(crate) fn data() -> MemFlagsData {
    MemFlagsData::new().with_notrap()
}

/// The [`Context`] and the stacks' slots: aligned.
pub(crate) fn own() -> MemFlagsData {
    MemFlagsData::trusted()
}

/// Fills `func` with the code of `program`.
///
/// Returns the bytes of variable memory the code reaches without checking at each access (the
/// fixed operands, and the elements of arrays at fixed places): the code may run only on at
/// least that much.
pub(crate) fn generate(
    program: &Program,
    analysis: &Analysis,
    isa: &dyn TargetIsa,
    func: &mut Function,
) -> u64 {
    let call_conv = isa.default_call_conv();
    func.signature = Signature::new(call_conv);
    func.signature.params.push(AbiParam::new(I64));
    func.signature.returns.push(AbiParam::new(types::I32));
    let mut fctx = FunctionBuilderContext::new();
    let mut b = FunctionBuilder::new(func, &mut fctx);
    let helper = |n: usize| {
        let mut sig = Signature::new(call_conv);
        sig.params.extend(std::iter::repeat_n(AbiParam::new(I64), n));
        sig.returns.push(AbiParam::new(I64));
        sig
    };
    let binary_sig = b.import_signature(helper(4));
    let unary_sig = b.import_signature(helper(3));
    let mut copy = Signature::new(call_conv);
    copy.params.extend(std::iter::repeat_n(AbiParam::new(I64), 3));
    let copy_sig = b.import_signature(copy);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let ctx = b.block_params(entry)[0];
    let field =
        |b: &mut FunctionBuilder, offset: usize| b.ins().load(I64, own(), ctx, offset as i32);
    let vars = field(&mut b, offset_of!(Context, vars));
    let vars_len = field(&mut b, offset_of!(Context, vars_len));
    let words = field(&mut b, offset_of!(Context, words));
    let frame = field(&mut b, offset_of!(Context, frame));
    let frame_len = field(&mut b, offset_of!(Context, frame_len));
    let eval = field(&mut b, offset_of!(Context, eval));
    let calls = field(&mut b, offset_of!(Context, calls));
    let regs_at = field(&mut b, offset_of!(Context, regs));
    let mut var = || b.declare_var(I64);
    let regs = Regs {
        pc: var(),
        sp: var(),
        left: var(),
        base: var(),
        this: var(),
        depth: var(),
        sb: var(),
        frame_at: var(),
        this_at: var(),
    };
    let stack: Vec<Variable> = (0..=analysis.max_depth).map(|_| b.declare_var(I64)).collect();
    let mut g = Gen {
        b,
        program,
        analysis,
        regs_at,
        vars,
        vars_len,
        words,
        frame,
        frame_len,
        eval,
        calls,
        regs,
        stack,
        binary_sig,
        unary_sig,
        copy_sig,
        blocks: vec![None; program.code.len()],
        loaders: vec![None; program.code.len()],
        dispatch: None,
        info: vec![SlotInfo::default(); analysis.max_depth as usize + 1],
        held: Vec::new(),
        in_range: Vec::new(),
        vars_need: analysis.vars_end,
        checks: analysis.budget_checks(&program.code),
    };
    g.entry();
    g.body();
    let vars_need = g.vars_need;
    g.b.seal_all_blocks();
    g.b.finalize(isa.frontend_config());
    vars_need
}

/// The registers of the activation, as SSA variables. `base` and `pc` hold a `u32`; `sb` is
/// the absolute index (not yet masked) of the current activation's first stack slot.
struct Regs {
    pc: Variable,
    sp: Variable,
    left: Variable,
    base: Variable,
    this: Variable,
    depth: Variable,
    sb: Variable,
    /// The addresses of the frame's base and of the FB instance: set, and checked against what
    /// the body's operands need, wherever `base` and `this` change.
    frame_at: Variable,
    this_at: Variable,
}

struct Gen<'a, 'f> {
    b: FunctionBuilder<'f>,
    program: &'a Program,
    analysis: &'a Analysis,
    /// The [`NativeRegs`] of the call.
    regs_at: Value,
    vars: Value,
    vars_len: Value,
    words: Value,
    frame: Value,
    frame_len: Value,
    eval: Value,
    calls: Value,
    regs: Regs,
    /// The evaluation stack's slots of the current activation, by depth.
    stack: Vec<Variable>,
    binary_sig: SigRef,
    unary_sig: SigRef,
    copy_sig: SigRef,
    /// The block of each leader, and its loader (the way in from the dispatch).
    blocks: Vec<Option<Block>>,
    loaders: Vec<Option<Block>>,
    dispatch: Option<Block>,
    /// In the block being generated: what is known of each stack slot.
    info: Vec<SlotInfo>,
    /// In the block being generated: the values of fixed places it stored or fetched, still
    /// there (no store since could have changed them).
    held: Vec<Held>,
    /// In the block being generated: the indices (value, `lo`, `len` of [`Op::Index`]) it
    /// already found inside their range.
    in_range: Vec<(Value, i32, u32)>,
    /// See [`generate`]'s result.
    vars_need: u64,
    /// [`Analysis::budget_checks`].
    checks: Vec<(bool, u64)>,
}

/// What the code knows of a stack slot's value in the block being generated.
#[derive(Clone, Copy, Default)]
struct SlotInfo {
    /// A pointer into variable memory whose offset is at most this (an element of an array at
    /// a fixed place).
    known: Option<u64>,
    /// A pointer into the current activation's frame, this many bytes from its base.
    frame: Option<u32>,
    /// It holds 0 or 1 (a BOOL loaded or computed), so BOOL logic needs no normalizing.
    boolean: bool,
    /// The REAL or LREAL whose bits the slot holds, as a float value: float operations on it
    /// need no move from an integer register.
    float: Option<Value>,
}

/// Where a store through a pointer goes, as far as the code knows.
#[derive(Clone, Copy)]
enum Into {
    Vars,
    /// The frame, this many bytes from its base.
    Frame(u32),
    Unknown,
}

/// The value of a fixed place, as a slot fetched from it now would be.
#[derive(Clone, Copy)]
struct Held {
    place: Place,
    elem: Elem,
    value: Value,
    info: SlotInfo,
}

/// Where the block being generated stands: the instruction's index in it and the block's
/// length, for the budget an exit gives back.
#[derive(Clone, Copy)]
struct At {
    pc: u32,
    index: u32,
    len: u32,
}

impl Gen<'_, '_> {
    fn entry(&mut self) {
        let ctx = self.regs_at;
        let load32 = |b: &mut FunctionBuilder, offset: usize| {
            let v = b.ins().load(types::I32, own(), ctx, reg(offset));
            b.ins().uextend(I64, v)
        };
        let pc = load32(&mut self.b, offset_of!(NativeRegs, pc));
        let depth = load32(&mut self.b, offset_of!(NativeRegs, st_depth));
        let base = load32(&mut self.b, offset_of!(NativeRegs, base));
        let this = self.b.ins().load(I64, own(), ctx, reg(offset_of!(NativeRegs, this)));
        let left = self.b.ins().load(I64, own(), ctx, reg(offset_of!(NativeRegs, left)));
        let sp = self.b.ins().load(I64, own(), ctx, reg(offset_of!(NativeRegs, sp)));
        let zero = self.b.ins().iconst(I64, 0);
        self.define(&[
            (self.regs.pc, pc),
            (self.regs.depth, depth),
            (self.regs.base, base),
            (self.regs.this, this),
            (self.regs.left, left),
            (self.regs.sp, sp),
            (self.regs.sb, zero),
            (self.regs.frame_at, zero),
            (self.regs.this_at, zero),
        ]);
        for &leader in &self.analysis.leaders {
            self.blocks[leader as usize] = Some(self.b.create_block());
        }
        for &leader in &self.analysis.leaders {
            self.loaders[leader as usize] = Some(self.b.create_block());
        }
        let dispatch = self.b.create_block();
        self.dispatch = Some(dispatch);
        // A scan starts at 0: straight in, without the dispatch's search.
        match self.loaders.first().copied().flatten() {
            Some(start) => {
                let at_start = self.b.ins().icmp_imm_s(IntCC::Equal, pc, 0);
                self.b.ins().brif(at_start, start, &[], dispatch, &[]);
            }
            None => {
                self.b.ins().jump(dispatch, &[]);
            }
        }
    }

    fn body(&mut self) {
        // The dispatch: a loader for each leader, the interpreter for any other pc.
        let dispatch = self.dispatch.expect("created by entry");
        self.b.switch_to_block(dispatch);
        let mut switch = Switch::new();
        let mut loaders = Vec::new();
        for &leader in &self.analysis.leaders {
            let loader = self.loaders[leader as usize].expect("created by entry");
            switch.set_entry(u128::from(leader), loader);
            loaders.push((leader, loader));
        }
        let elsewhere = self.b.create_block();
        let pc = self.b.use_var(self.regs.pc);
        switch.emit(&mut self.b, pc, elsewhere);

        self.b.switch_to_block(elsewhere);
        self.b.set_cold_block(elsewhere);
        let sp = self.b.use_var(self.regs.sp);
        let pc = self.b.use_var(self.regs.pc);
        let left = self.b.use_var(self.regs.left);
        self.store_regs(pc, sp, left);
        self.ret(RETURN_INTERPRET);

        for (leader, loader) in loaders {
            self.b.switch_to_block(loader);
            // The body's frame and FB instance: checked here, once for all its blocks.
            let base = self.b.use_var(self.regs.base);
            let this = self.b.use_var(self.regs.this);
            let body = self.analysis.owner[leader as usize].unwrap_or(0);
            let (ok, frame_at, this_at) = self.body_pointers(body, base, this, false);
            // The budget of a block that does not check it itself.
            let index = self.analysis.leaders.binary_search(&leader).unwrap_or(0);
            let (checks, need) = self.checks[index];
            let ok = if checks {
                ok
            } else {
                let left = self.b.use_var(self.regs.left);
                let enough =
                    self.b.ins().icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, left, need as i64);
                self.b.ins().band(ok, enough)
            };
            let load = self.b.create_block();
            let refuse = self.b.create_block();
            self.b.set_cold_block(refuse);
            self.b.ins().brif(ok, load, &[], refuse, &[]);
            self.b.switch_to_block(refuse);
            let sp = self.b.use_var(self.regs.sp);
            let left = self.b.use_var(self.regs.left);
            let pc = self.b.ins().iconst(I64, i64::from(leader));
            self.store_regs(pc, sp, left);
            self.ret(RETURN_INTERPRET);
            self.b.switch_to_block(load);
            self.b.def_var(self.regs.frame_at, frame_at);
            self.b.def_var(self.regs.this_at, this_at);
            let depth = self.depth(leader);
            let sp = self.b.use_var(self.regs.sp);
            let sb = self.b.ins().iadd_imm_s(sp, -i64::from(depth));
            self.b.def_var(self.regs.sb, sb);
            for slot in 0..depth {
                let address = self.slot_address(sb, slot);
                let value = self.b.ins().load(I64, own(), address, 0);
                self.b.def_var(self.stack[slot as usize], value);
            }
            let block = self.block_of(leader);
            self.b.ins().jump(block, &[]);
        }

        for index in 0..self.analysis.leaders.len() {
            self.block(index);
        }
    }

    /// Whether the frame at `base` and the FB instance `this` hold every operand of `body`
    /// (an `i8` truth value), and their addresses. `this_in_vars`: `this` is known to point
    /// into variable memory, far enough from its end (the caller makes sure).
    fn body_pointers(
        &mut self,
        body: u32,
        base: Value,
        this: Value,
        this_in_vars: bool,
    ) -> (Value, Value, Value) {
        let needs = &self.analysis.bodies[&body];
        let (frame_end, this_end) = (needs.frame_end, needs.this_end);
        let mut ok = self.b.ins().iconst(types::I8, 1);
        let frame_at = self.b.ins().iadd(self.frame, base);
        if frame_end > 0 {
            let end = self.b.ins().iadd_imm_s(base, frame_end as i64);
            let inside = self.b.ins().icmp(IntCC::UnsignedLessThanOrEqual, end, self.frame_len);
            ok = self.b.ins().band(ok, inside);
        }
        let this_at = if this_end > 0 && this_in_vars {
            self.b.ins().iadd(self.vars, this)
        } else if this_end > 0 {
            let (address, inside) = self.reach(this, this_end);
            ok = self.b.ins().band(ok, inside);
            address
        } else {
            self.b.ins().iconst(I64, 0)
        };
        (ok, frame_at, this_at)
    }

    fn depth(&self, pc: u32) -> u32 {
        self.analysis.depth.get(pc as usize).copied().flatten().unwrap_or(0)
    }

    fn block_of(&self, pc: u32) -> Block {
        self.blocks[pc as usize].expect("a leader")
    }

    /// The block `pc` starts, or an exit to the interpreter at `pc` (the end of the code).
    fn target(&mut self, pc: u32, depth: u32) -> Block {
        if let Some(Some(block)) = self.blocks.get(pc as usize) {
            return *block;
        }
        let current = self.b.current_block();
        let exit = self.b.create_block();
        self.b.set_cold_block(exit);
        self.b.switch_to_block(exit);
        let left = self.b.use_var(self.regs.left);
        self.exit(pc, depth, left, RETURN_INTERPRET);
        if let Some(current) = current {
            self.b.switch_to_block(current);
        }
        exit
    }

    /// Defines each register variable with its value.
    fn define(&mut self, registers: &[(Variable, Value)]) {
        for &(var, value) in registers {
            self.b.def_var(var, value);
        }
    }

    fn slot_address(&mut self, sb: Value, slot: u32) -> Value {
        let index = self.b.ins().iadd_imm_s(sb, i64::from(slot));
        let index = self.b.ins().band_imm_s(index, MASK);
        let offset = self.b.ins().ishl_imm_s(index, 3);
        self.b.ins().iadd(self.eval, offset)
    }

    fn store_regs(&mut self, pc: Value, sp: Value, left: Value) {
        let ctx = self.regs_at;
        let sp = self.b.ins().band_imm_s(sp, MASK);
        let base = self.b.use_var(self.regs.base);
        let this = self.b.use_var(self.regs.this);
        let depth = self.b.use_var(self.regs.depth);
        for (value, offset) in [
            (pc, offset_of!(NativeRegs, pc)),
            (base, offset_of!(NativeRegs, base)),
            (depth, offset_of!(NativeRegs, st_depth)),
        ] {
            let value = self.b.ins().ireduce(types::I32, value);
            self.b.ins().store(own(), value, ctx, reg(offset));
        }
        for (value, offset) in [
            (this, offset_of!(NativeRegs, this)),
            (left, offset_of!(NativeRegs, left)),
            (sp, offset_of!(NativeRegs, sp)),
        ] {
            self.b.ins().store(own(), value, ctx, reg(offset));
        }
    }

    fn ret(&mut self, status: u32) {
        let status = self.b.ins().iconst(types::I32, i64::from(status));
        self.b.ins().return_(&[status]);
    }

    /// Leaves with `status`: the stack's `depth` slots to memory, the registers with `pc` and
    /// `left` to the context.
    fn exit(&mut self, pc: u32, depth: u32, left: Value, status: u32) {
        let sb = self.b.use_var(self.regs.sb);
        for slot in 0..depth {
            let value = self.b.use_var(self.stack[slot as usize]);
            let address = self.slot_address(sb, slot);
            self.b.ins().store(own(), value, address, 0);
        }
        let sp = self.b.ins().iadd_imm_s(sb, i64::from(depth));
        let pc = self.b.ins().iconst(I64, i64::from(pc));
        self.store_regs(pc, sp, left);
        self.ret(status);
    }

    /// A cold branch out of the block when `fail` holds: back to the interpreter before the
    /// instruction at `at` (the stack as it was before it, `depth` slots).
    fn bail_if(&mut self, fail: Value, at: At, depth: u32) {
        let cold = self.b.create_block();
        let next = self.b.create_block();
        self.b.set_cold_block(cold);
        self.b.ins().brif(fail, cold, &[], next, &[]);
        self.b.switch_to_block(cold);
        let left = self.b.use_var(self.regs.left);
        let left = self.b.ins().iadd_imm_s(left, i64::from(at.len - at.index));
        self.exit(at.pc, depth, left, RETURN_INTERPRET);
        self.b.switch_to_block(next);
    }

    /// A cold branch when `fail` holds: the operation error `code` after the instruction at
    /// `at`, whose result slot (the top of `depth` slots) is `result`.
    fn error_if(&mut self, fail: Value, at: At, depth: u32, result: i64, code: u16) {
        let cold = self.b.create_block();
        let next = self.b.create_block();
        self.b.set_cold_block(cold);
        self.b.ins().brif(fail, cold, &[], next, &[]);
        self.b.switch_to_block(cold);
        let result = self.b.ins().iconst(I64, result);
        self.b.def_var(self.stack[depth as usize - 1], result);
        let code = self.b.ins().iconst(types::I32, i64::from(code));
        self.b.ins().store(own(), code, self.regs_at, reg(offset_of!(NativeRegs, error)));
        let left = self.b.use_var(self.regs.left);
        let left = self.b.ins().iadd_imm_s(left, i64::from(at.len - at.index - 1));
        self.exit(at.pc + 1, depth, left, RETURN_ERROR);
        self.b.switch_to_block(next);
    }

    fn block(&mut self, index: usize) {
        let code = &self.program.code;
        let range = self.analysis.block(code, index);
        let start = range.start as u32;
        let len = range.len() as u32;
        self.b.switch_to_block(self.block_of(start));
        let mut depth = self.depth(start);
        if !is_native(&code[range.start]) {
            let left = self.b.use_var(self.regs.left);
            self.exit(start, depth, left, RETURN_INTERPRET);
            return;
        }
        let at = At { pc: start, index: 0, len };
        // The budget (`Analysis::budget_checks`; the frame and the FB instance were checked on
        // the way into the body).
        let left = self.b.use_var(self.regs.left);
        let (checks, need) = self.checks[index];
        if checks {
            let short = self.b.ins().icmp_imm_s(IntCC::UnsignedLessThan, left, need as i64);
            self.bail_if(short, At { index: len, ..at }, depth);
        }
        self.info.fill(SlotInfo::default());
        self.held.clear();
        self.in_range.clear();
        let left = self.b.ins().iadd_imm_s(left, -i64::from(len));
        self.b.def_var(self.regs.left, left);
        let mut falls_through = true;
        for (index, pc) in range.clone().enumerate() {
            let at = At { pc: pc as u32, index: index as u32, len };
            falls_through = self.op(&code[pc], at, &mut depth);
        }
        if falls_through {
            let next = self.target(range.end as u32, depth);
            self.b.ins().jump(next, &[]);
        }
    }

    /// The address of `pointer` (a slot) in variable memory or the frame, and whether `bytes`
    /// from it are inside that space (an `i8` truth value).
    fn reach(&mut self, pointer: Value, bytes: u64) -> (Value, Value) {
        let space = self.b.ins().ushr_imm_s(pointer, 32);
        let offset = self.b.ins().band_imm_s(pointer, LOW32);
        let is_var = self.b.ins().icmp_imm_s(IntCC::Equal, space, Space::Var as i64);
        let is_frame = self.b.ins().icmp_imm_s(IntCC::Equal, space, Space::Frame as i64);
        let limit = self.b.ins().select(is_var, self.vars_len, self.frame_len);
        let start = self.b.ins().select(is_var, self.vars, self.frame);
        let end = self.b.ins().iadd_imm_s(offset, bytes as i64);
        let inside = self.b.ins().icmp(IntCC::UnsignedLessThanOrEqual, end, limit);
        let byte_space = self.b.ins().bor(is_var, is_frame);
        let ok = self.b.ins().band(byte_space, inside);
        (self.b.ins().iadd(start, offset), ok)
    }

    fn push(&mut self, depth: &mut u32, value: Value) {
        self.b.def_var(self.stack[*depth as usize], value);
        self.info[*depth as usize] = SlotInfo::default();
        *depth += 1;
    }

    /// Defines slot `index` (not a known pointer).
    fn set(&mut self, index: u32, value: Value) {
        self.b.def_var(self.stack[index as usize], value);
        self.info[index as usize] = SlotInfo::default();
    }

    /// The address of the value of `bytes` bytes at the pointer in slot `index` when it is a
    /// known pointer into variable memory (no check at run time: the code's need of variable
    /// memory grows to cover it).
    fn known_address(&mut self, index: u32, bytes: u32) -> Option<Value> {
        let most = self.info[index as usize].known?;
        self.vars_need = self.vars_need.max(most + u64::from(bytes));
        let pointer = self.slot(index);
        Some(self.b.ins().iadd(self.vars, pointer))
    }

    fn slot(&mut self, depth: u32) -> Value {
        self.b.use_var(self.stack[depth as usize])
    }

    /// The instruction `op` at `at`; false if control does not fall through to the next.
    fn op(&mut self, op: &Op, at: At, depth: &mut u32) -> bool {
        let d = *depth;
        match *op {
            Op::PushInt(v) => {
                let value = self.b.ins().iconst(I64, i64::from(v));
                self.push(depth, value);
                self.info[d as usize].boolean = v == 0 || v == 1;
            }
            Op::PushConst(index) => {
                let v = self.program.consts.get(index as usize).copied().unwrap_or(0);
                let v = self.b.ins().iconst(I64, v as i64);
                self.push(depth, v);
            }
            Op::Fetch { elem, at: place } => {
                if let Some(held) = self.held.iter().find(|h| h.place == place && h.elem == elem) {
                    let (value, info) = (held.value, held.info);
                    self.push(depth, value);
                    self.info[d as usize] = info;
                } else if let (true, Some((address, offset))) =
                    (elem.is_float(), self.byte_place(place))
                {
                    let f = self.b.ins().load(float_type(elem), data(), address, offset);
                    let v = self.float_bits(elem, f);
                    self.push(depth, v);
                    self.info[d as usize].float = Some(f);
                    self.hold(place, elem, v, self.info[d as usize]);
                } else {
                    let v = self.load_place(place, elem);
                    self.push(depth, v);
                    self.info[d as usize].boolean = elem == Elem::Bool;
                    self.hold(place, elem, v, self.info[d as usize]);
                }
            }
            Op::Store { elem, at: place } => {
                let v = self.slot(d - 1);
                let info = self.info[d as usize - 1];
                match (elem, self.byte_place(place)) {
                    // 0 or 1 already: stored as it is.
                    (Elem::Bool, Some((address, offset))) if info.boolean => {
                        self.b.ins().istore8(data(), v, address, offset);
                    }
                    (Elem::F32 | Elem::F64, Some((address, offset))) if info.float.is_some() => {
                        let f = self.float(elem, d - 1);
                        self.b.ins().store(data(), f, address, offset);
                    }
                    _ => self.store_place(place, elem, v),
                }
                self.forget(place, elem.size());
                if in_bytes(place) {
                    // A fetch from it now gives the value cut to `elem` (`Bool`: 0 or 1).
                    let value = match elem {
                        _ if info.float.is_some() && elem.is_float() => v,
                        Elem::Bool if info.boolean => v,
                        _ => self.normalize(elem, v),
                    };
                    let info = SlotInfo {
                        known: info.known.filter(|_| elem.size() == 8),
                        frame: info.frame.filter(|_| elem.size() == 8),
                        boolean: elem == Elem::Bool,
                        float: info.float.filter(|_| elem.is_float()),
                    };
                    self.hold(place, elem, value, info);
                }
                *depth -= 1;
            }
            Op::AddrOf(place) => {
                let v = self.address_of(place);
                self.push(depth, v);
                match place {
                    Place::Var(offset) => self.info[d as usize].known = Some(u64::from(offset)),
                    Place::Frame(offset) => self.info[d as usize].frame = Some(offset),
                    _ => {}
                }
            }
            Op::Index { lo, len, stride } => {
                let index = self.slot(d - 1);
                let pointer = self.slot(d - 2);
                let element = self.b.ins().iadd_imm_s(index, -i64::from(lo));
                // The same index into the same range again in this block: it passed.
                if !self.in_range.contains(&(index, lo, len)) {
                    let out = self.b.ins().icmp_imm_s(
                        IntCC::UnsignedGreaterThanOrEqual,
                        element,
                        i64::from(len),
                    );
                    let discard = Pointer::DISCARD.to_slot() as i64;
                    self.error_if(out, at, d - 1, discard, ERR_INDEX_RANGE);
                    self.in_range.push((index, lo, len));
                }
                let step = self.b.ins().imul_imm_s(element, i64::from(stride));
                // An element of an array at a fixed place: its offset is at most the last one's.
                let last = u64::from(len.saturating_sub(1)) * u64::from(stride);
                let known = self.info[d as usize - 2]
                    .known
                    .map(|most| most + last)
                    .filter(|&most| len > 0 && most <= u64::from(u32::MAX));
                let moved = self.moved(pointer, step, known.is_some());
                *depth -= 1;
                self.set(d - 2, moved);
                self.info[d as usize - 2].known = known;
            }
            Op::Offset(n) => {
                let pointer = self.slot(d - 1);
                let step = self.b.ins().iconst(I64, i64::from(n));
                let known = self.info[d as usize - 1]
                    .known
                    .map(|most| most + u64::from(n))
                    .filter(|&most| most <= u64::from(u32::MAX));
                let frame = self.info[d as usize - 1].frame.and_then(|o| o.checked_add(n));
                let moved = self.moved(pointer, step, known.is_some());
                self.set(d - 1, moved);
                self.info[d as usize - 1].known = known;
                self.info[d as usize - 1].frame = frame;
            }
            Op::FetchInd(elem) => {
                let (address, _) = self.address(d - 1, elem.size(), at, d);
                if elem.is_float() {
                    let f = self.b.ins().load(float_type(elem), data(), address, 0);
                    let v = self.float_bits(elem, f);
                    self.set(d - 1, v);
                    self.info[d as usize - 1].float = Some(f);
                } else {
                    let v = self.load(elem, address, 0);
                    self.set(d - 1, v);
                    self.info[d as usize - 1].boolean = elem == Elem::Bool;
                }
            }
            Op::StoreInd(elem) => {
                let v = self.slot(d - 1);
                let (address, into) = self.address(d - 2, elem.size(), at, d);
                if elem.is_float() && self.info[d as usize - 1].float.is_some() {
                    let f = self.float(elem, d - 1);
                    self.b.ins().store(data(), f, address, 0);
                } else {
                    self.store(elem, address, 0, v);
                }
                self.forget_indirect(into, elem.size());
                *depth -= 2;
            }
            Op::Copy(n) => {
                // Both ranges are checked before either is touched: the interpreter copies
                // nothing when one is outside its space.
                let (from, _) = self.address(d - 1, n, at, d);
                let (to, into) = self.address(d - 2, n, at, d);
                self.copy(to, from, n);
                self.forget_indirect(into, n);
                *depth -= 2;
            }
            Op::Bin { op, elem } => {
                let b = self.slot(d - 1);
                let a = self.slot(d - 2);
                let both = self.info[d as usize - 1].boolean && self.info[d as usize - 2].boolean;
                *depth -= 1;
                match op {
                    // BOOL logic on 0s and 1s gives 0 or 1: no normalizing.
                    BinOp::And | BinOp::Or | BinOp::Xor if elem == Elem::Bool && both => {
                        let r = match op {
                            BinOp::And => self.b.ins().band(a, b),
                            BinOp::Or => self.b.ins().bor(a, b),
                            _ => self.b.ins().bxor(a, b),
                        };
                        self.set(d - 2, r);
                        self.info[d as usize - 2].boolean = true;
                    }
                    _ if elem.is_float() => {
                        let (x, y) = (self.float(elem, d - 2), self.float(elem, d - 1));
                        let (r, f) = self.float_binary(op, elem, (a, x), (b, y), at, d - 1);
                        self.set(d - 2, r);
                        self.info[d as usize - 2].float = f;
                    }
                    _ => {
                        let r = self.binary(op, elem, a, b, at, d - 1);
                        self.set(d - 2, r);
                    }
                }
            }
            Op::Un { op, elem } => {
                let a = self.slot(d - 1);
                if op == UnOp::Not && elem == Elem::Bool && self.info[d as usize - 1].boolean {
                    let r = self.b.ins().bxor_imm_s(a, 1);
                    self.set(d - 1, r);
                    self.info[d as usize - 1].boolean = true;
                } else if elem.is_float() {
                    let x = self.float(elem, d - 1);
                    let (r, f) = self.float_unary(op, elem, a, x);
                    self.set(d - 1, r);
                    self.info[d as usize - 1].float = f;
                } else {
                    let r = self.unary(op, elem, a);
                    self.set(d - 1, r);
                }
            }
            Op::Cmp { op, elem } => {
                let holds = if elem.is_float() {
                    let (x, y) = (self.float(elem, d - 2), self.float(elem, d - 1));
                    self.float_compare(op, x, y)
                } else {
                    let (a, b) = (self.slot(d - 2), self.slot(d - 1));
                    self.compare(op, elem, a, b)
                };
                let r = self.b.ins().uextend(I64, holds);
                *depth -= 1;
                self.set(d - 2, r);
                self.info[d as usize - 2].boolean = true;
            }
            Op::Conv { from, to } => {
                let a = self.slot(d - 1);
                if from != to || !from.is_float() {
                    let x = if from.is_float() { Some(self.float(from, d - 1)) } else { None };
                    let (r, f) = self.convert(from, to, a, x);
                    self.set(d - 1, r);
                    self.info[d as usize - 1].boolean = to == Elem::Bool;
                    self.info[d as usize - 1].float = f;
                }
            }
            Op::Dup => {
                let v = self.slot(d - 1);
                self.push(depth, v);
                self.info[d as usize] = self.info[d as usize - 1];
            }
            Op::Drop => *depth -= 1,
            Op::Nop => {}
            Op::Goto(target) => {
                let block = self.target(target, d);
                self.b.ins().jump(block, &[]);
                return false;
            }
            Op::GotoIf { target, when } => {
                let c = self.slot(d - 1);
                *depth -= 1;
                let taken = self.target(target, d - 1);
                let next = self.target(at.pc + 1, d - 1);
                let (on_true, on_false) = if when { (taken, next) } else { (next, taken) };
                self.b.ins().brif(c, on_true, &[], on_false, &[]);
                return false;
            }
            Op::CallFn { target, frame } => {
                self.call(at, d, target, frame, false);
                return false;
            }
            Op::CallFb { target, frame } => {
                self.call(at, d, target, frame, true);
                return false;
            }
            Op::Return => {
                let calls = self.b.use_var(self.regs.depth);
                let empty = self.b.ins().icmp_imm_s(IntCC::Equal, calls, 0);
                self.bail_if(empty, at, d);
                let calls = self.b.ins().iadd_imm_s(calls, -1);
                let frame = self.call_frame(calls);
                let return_pc =
                    self.b.ins().uload32(own(), frame, offset_of!(StFrame, return_pc) as i32);
                let base = self.b.ins().uload32(own(), frame, offset_of!(StFrame, base) as i32);
                let this = self.b.ins().load(I64, own(), frame, offset_of!(StFrame, this) as i32);
                let sb = self.b.use_var(self.regs.sb);
                self.define(&[
                    (self.regs.depth, calls),
                    (self.regs.base, base),
                    (self.regs.this, this),
                    (self.regs.pc, return_pc),
                    (self.regs.sp, sb),
                ]);
                // Straight to the loader of a return site of this body, the others through the
                // dispatch.
                let dispatch = self.dispatch.expect("created by entry");
                let body = self.analysis.owner[at.pc as usize].unwrap_or(0);
                let mut switch = Switch::new();
                for &site in &self.analysis.bodies[&body].return_sites {
                    if let Some(Some(loader)) = self.loaders.get(site as usize) {
                        switch.set_entry(u128::from(site), *loader);
                    }
                }
                switch.emit(&mut self.b, return_pc, dispatch);
                return false;
            }
            Op::End => {
                let left = self.b.use_var(self.regs.left);
                self.exit(at.pc + 1, d, left, RETURN_END);
                return false;
            }
            // `analysis::is_native` keeps the others out of native blocks.
            _ => unreachable!("{op:?} in a native block"),
        }
        true
    }

    /// The address of call frame `index`.
    fn call_frame(&mut self, index: Value) -> Value {
        let offset = self.b.ins().imul_imm_s(index, std::mem::size_of::<StFrame>() as i64);
        self.b.ins().iadd(self.calls, offset)
    }

    fn call(&mut self, at: At, d: u32, target: u32, frame: u32, fb: bool) {
        let calls = self.b.use_var(self.regs.depth);
        let full =
            self.b.ins().icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, calls, ST_CALL_DEPTH as i64);
        self.bail_if(full, at, d);
        let (this, after) =
            if fb { (self.slot(d - 1), d - 1) } else { (self.b.use_var(self.regs.this), d) };
        let base = self.b.use_var(self.regs.base);
        let callee_base = self.b.ins().iadd_imm_s(base, i64::from(frame));
        let callee_base = self.b.ins().band_imm_s(callee_base, LOW32);
        // An FB instance in an array at a fixed place (or a fixed one) needs no check at run
        // time: the code's need of variable memory covers it.
        let known = if fb { self.info[d as usize - 1].known } else { None };
        let this_end = self.analysis.bodies[&target].this_end;
        let (ok, frame_at, this_at) =
            self.body_pointers(target, callee_base, this, known.is_some());
        if let Some(most) = known.filter(|_| this_end > 0) {
            self.vars_need = self.vars_need.max(most + this_end);
        }
        let refused = self.b.ins().bxor_imm_s(ok, 1);
        self.bail_if(refused, at, d);
        let record = self.call_frame(calls);
        let return_pc = self.b.ins().iconst(types::I32, i64::from(at.pc + 1));
        let base = self.b.use_var(self.regs.base);
        let base32 = self.b.ins().ireduce(types::I32, base);
        let old_this = self.b.use_var(self.regs.this);
        self.b.ins().store(own(), return_pc, record, offset_of!(StFrame, return_pc) as i32);
        self.b.ins().store(own(), base32, record, offset_of!(StFrame, base) as i32);
        self.b.ins().store(own(), old_this, record, offset_of!(StFrame, this) as i32);
        // The caller's slots to memory: the callee numbers its own from 0.
        let sb = self.b.use_var(self.regs.sb);
        for slot in 0..after {
            let value = self.slot(slot);
            let address = self.slot_address(sb, slot);
            self.b.ins().store(own(), value, address, 0);
        }
        let calls = self.b.ins().iadd_imm_s(calls, 1);
        let sb = self.b.ins().iadd_imm_s(sb, i64::from(after));
        self.define(&[
            (self.regs.depth, calls),
            (self.regs.base, callee_base),
            (self.regs.this, this),
            (self.regs.sb, sb),
            (self.regs.frame_at, frame_at),
            (self.regs.this_at, this_at),
        ]);
        let callee = self.target(target, 0);
        self.b.ins().jump(callee, &[]);
    }

    /// Copies `n` bytes from `from` to `to` as `memmove` does (the ranges may overlap): a short
    /// copy as loads of every chunk, then their stores; a long one by a call.
    fn copy(&mut self, to: Value, from: Value, n: u32) {
        if n > SHORT_COPY {
            let function = code::copy_bytes as extern "C" fn(*mut u8, *const u8, u64) as usize;
            let length = self.b.ins().iconst(I64, i64::from(n));
            self.call_helper(self.copy_sig, function, &[to, from, length]);
            return;
        }
        let mut chunks = Vec::new();
        let mut offset = 0;
        for (size, ty) in [(8, I64), (4, types::I32), (2, types::I16), (1, types::I8)] {
            while n - offset >= size {
                let v = self.b.ins().load(ty, data(), from, offset as i32);
                chunks.push((v, offset));
                offset += size;
            }
        }
        for (v, offset) in chunks {
            self.b.ins().store(data(), v, to, offset as i32);
        }
    }

    /// `pointer` moved by `n` units of its space: the offset wraps in 32 bits, the space stays.
    /// `fits`: the offset is known not to pass `u32::MAX` (a known pointer's), so a plain add.
    fn moved(&mut self, pointer: Value, n: Value, fits: bool) -> Value {
        if fits {
            return self.b.ins().iadd(pointer, n);
        }
        let space = self.b.ins().band_imm_s(pointer, !LOW32);
        let offset = self.b.ins().iadd(pointer, n);
        let offset = self.b.ins().band_imm_s(offset, LOW32);
        self.b.ins().bor(space, offset)
    }

    fn address_of(&mut self, place: Place) -> Value {
        let slot = |space, offset| Pointer { space, offset }.to_slot() as i64;
        match place {
            Place::Var(offset) => self.b.ins().iconst(I64, slot(Space::Var, offset)),
            Place::Frame(offset) => {
                let base = self.b.use_var(self.regs.base);
                let offset = self.b.ins().iadd_imm_s(base, i64::from(offset));
                let offset = self.b.ins().band_imm_s(offset, LOW32);
                self.b.ins().bor_imm_s(offset, slot(Space::Frame, 0))
            }
            Place::This(offset) => {
                let this = self.b.use_var(self.regs.this);
                let n = self.b.ins().iconst(I64, i64::from(offset));
                self.moved(this, n, false)
            }
            Place::Word(w) => self.b.ins().iconst(I64, slot(Space::Word, u32::from(w.0))),
            Place::Bit(b) => {
                let bit = b.mask.trailing_zeros().min(15);
                self.b.ins().iconst(I64, slot(Space::Bit, u32::from(b.word) * 16 + bit))
            }
        }
    }

    /// The address of `bytes` bytes at the pointer in slot `index`, and where it points: without
    /// a check at run time for a known pointer into variable memory, or into the frame inside
    /// what the body's entry checked; else after [`Gen::checked_address`]'s check.
    fn address(&mut self, index: u32, bytes: u32, at: At, depth: u32) -> (Value, Into) {
        if let Some(address) = self.known_address(index, bytes) {
            return (address, Into::Vars);
        }
        if let Some(offset) = self.info[index as usize].frame {
            let end = u64::from(offset) + u64::from(bytes);
            let body = self.analysis.owner[at.pc as usize].unwrap_or(0);
            if end > self.analysis.bodies[&body].frame_end {
                let base = self.b.use_var(self.regs.base);
                let end = self.b.ins().iadd_imm_s(base, end as i64);
                let out = self.b.ins().icmp(IntCC::UnsignedGreaterThan, end, self.frame_len);
                self.bail_if(out, at, depth);
            }
            let frame_at = self.b.use_var(self.regs.frame_at);
            let address = self.b.ins().iadd_imm_s(frame_at, i64::from(offset));
            return (address, Into::Frame(offset));
        }
        (self.checked_address(index, bytes, at, depth), Into::Unknown)
    }

    /// The address of `bytes` bytes at the pointer in slot `index`, after a cold branch back to
    /// the interpreter (before the instruction at `at`, the stack `depth` deep) when they are
    /// not all inside variable memory or the frame.
    fn checked_address(&mut self, index: u32, bytes: u32, at: At, depth: u32) -> Value {
        let pointer = self.slot(index);
        let (address, ok) = self.reach(pointer, u64::from(bytes));
        let out = self.b.ins().bxor_imm_s(ok, 1);
        self.bail_if(out, at, depth);
        address
    }

    /// The address and offset of a byte-space place.
    fn byte_place(&mut self, place: Place) -> Option<(Value, i32)> {
        match place {
            Place::Var(offset) => Some((self.vars, offset as i32)),
            Place::Frame(offset) => Some((self.b.use_var(self.regs.frame_at), offset as i32)),
            Place::This(offset) => Some((self.b.use_var(self.regs.this_at), offset as i32)),
            Place::Word(_) | Place::Bit(_) => None,
        }
    }

    fn load_place(&mut self, place: Place, elem: Elem) -> Value {
        if let Some((address, offset)) = self.byte_place(place) {
            return self.load(elem, address, offset);
        }
        match place {
            Place::Word(w) => {
                let offset = i32::from(w.0) * 2;
                let raw = match elem.words() {
                    1 => self.b.ins().uload16(I64, data(), self.words, offset),
                    2 => self.b.ins().uload32(data(), self.words, offset),
                    _ => self.b.ins().load(I64, data(), self.words, offset),
                };
                self.normalize(elem, raw)
            }
            Place::Bit(b) => {
                let bit = b.mask.trailing_zeros().min(15);
                let word = self.b.ins().uload16(I64, data(), self.words, i32::from(b.word) * 2);
                let shifted = self.b.ins().ushr_imm_s(word, i64::from(bit));
                self.b.ins().band_imm_s(shifted, 1)
            }
            _ => unreachable!("a byte place"),
        }
    }

    fn store_place(&mut self, place: Place, elem: Elem, v: Value) {
        if let Some((address, offset)) = self.byte_place(place) {
            return self.store(elem, address, offset, v);
        }
        match place {
            Place::Word(w) => {
                let offset = i32::from(w.0) * 2;
                let v = if elem == Elem::Bool { self.truth(v) } else { v };
                match elem.words() {
                    1 => self.b.ins().istore16(data(), v, self.words, offset),
                    2 => self.b.ins().istore32(data(), v, self.words, offset),
                    _ => self.b.ins().store(data(), v, self.words, offset),
                };
            }
            Place::Bit(b) => {
                let bit = b.mask.trailing_zeros().min(15);
                let mask = 1i64 << bit;
                let offset = i32::from(b.word) * 2;
                let word = self.b.ins().uload16(I64, data(), self.words, offset);
                let set = self.b.ins().bor_imm_s(word, mask);
                let cleared = self.b.ins().band_imm_s(word, !mask);
                let on = self.b.ins().icmp_imm_s(IntCC::NotEqual, v, 0);
                let word = self.b.ins().select(on, set, cleared);
                self.b.ins().istore16(data(), word, self.words, offset);
            }
            _ => unreachable!("a byte place"),
        }
    }

    /// A slot of `elem` from little-endian bytes (variable memory, the frame).
    fn load(&mut self, elem: Elem, address: Value, offset: i32) -> Value {
        let ins = self.b.ins();
        match elem {
            Elem::Bool => {
                let byte = ins.uload8(I64, data(), address, offset);
                self.truth(byte)
            }
            Elem::I8 => ins.sload8(I64, data(), address, offset),
            Elem::U8 => ins.uload8(I64, data(), address, offset),
            Elem::I16 => ins.sload16(I64, data(), address, offset),
            Elem::U16 => ins.uload16(I64, data(), address, offset),
            Elem::I32 => ins.sload32(data(), address, offset),
            Elem::U32 | Elem::F32 => ins.uload32(data(), address, offset),
            Elem::I64 | Elem::U64 | Elem::F64 => ins.load(I64, data(), address, offset),
        }
    }

    fn store(&mut self, elem: Elem, address: Value, offset: i32, v: Value) {
        match elem {
            Elem::Bool => {
                let v = self.truth(v);
                self.b.ins().istore8(data(), v, address, offset);
            }
            Elem::I8 | Elem::U8 => {
                self.b.ins().istore8(data(), v, address, offset);
            }
            Elem::I16 | Elem::U16 => {
                self.b.ins().istore16(data(), v, address, offset);
            }
            Elem::I32 | Elem::U32 | Elem::F32 => {
                self.b.ins().istore32(data(), v, address, offset);
            }
            Elem::I64 | Elem::U64 | Elem::F64 => {
                self.b.ins().store(data(), v, address, offset);
            }
        }
    }

    /// 1 if `v` is not 0, else 0.
    fn truth(&mut self, v: Value) -> Value {
        let ne = self.b.ins().icmp_imm_s(IntCC::NotEqual, v, 0);
        self.b.ins().uextend(I64, ne)
    }

    /// `raw` cut to the width of `elem` and extended (`Bool` keeps bit 0), as the VM wraps an
    /// integer result.
    fn wrap(&mut self, elem: Elem, raw: Value) -> Value {
        let ins = self.b.ins();
        match elem {
            Elem::Bool => ins.band_imm_s(raw, 1),
            Elem::I8 => {
                let v = ins.ireduce(types::I8, raw);
                self.b.ins().sextend(I64, v)
            }
            Elem::I16 => {
                let v = ins.ireduce(types::I16, raw);
                self.b.ins().sextend(I64, v)
            }
            Elem::I32 => {
                let v = ins.ireduce(types::I32, raw);
                self.b.ins().sextend(I64, v)
            }
            Elem::U8 => ins.band_imm_s(raw, 0xFF),
            Elem::U16 => ins.band_imm_s(raw, 0xFFFF),
            Elem::U32 | Elem::F32 => ins.band_imm_s(raw, LOW32),
            Elem::I64 | Elem::U64 | Elem::F64 => raw,
        }
    }

    /// `raw` as a normalized slot of `elem` (`Bool`: 1 for anything but 0).
    fn normalize(&mut self, elem: Elem, raw: Value) -> Value {
        match elem {
            Elem::Bool => self.truth(raw),
            _ => self.wrap(elem, raw),
        }
    }

    /// Slot `index` as a float of `elem`: the value it was computed as, or its bits moved.
    fn float(&mut self, elem: Elem, index: u32) -> Value {
        let ty = float_type(elem);
        match self.info[index as usize].float {
            Some(f) if self.b.func.dfg.value_type(f) == ty => f,
            _ => {
                let v = self.slot(index);
                self.as_float(elem, v)
            }
        }
    }

    /// Records that fixed place `place` holds `value` (with `info`) as a fetch of `elem` from
    /// it would give it now. Device memory is not held: the places overlap in ways a `Word` and
    /// a `Bit` do not show.
    fn hold(&mut self, place: Place, elem: Elem, value: Value, info: SlotInfo) {
        if in_bytes(place) {
            self.held.push(Held { place, elem, value, info });
        }
    }

    /// Forgets the held values a store of `bytes` bytes at fixed place `at` may change. An FB
    /// instance (`This`) may be in variable memory or in a frame, anywhere.
    fn forget(&mut self, at: Place, bytes: u32) {
        let range = |offset: u32, n: u32| u64::from(offset)..u64::from(offset) + u64::from(n);
        self.held.retain(|h| {
            let overlaps = |a: u32, b: u32| {
                let (x, y) = (range(a, bytes), range(b, h.elem.size()));
                x.start < y.end && y.start < x.end
            };
            match (at, h.place) {
                (Place::Var(a), Place::Var(b))
                | (Place::Frame(a), Place::Frame(b))
                | (Place::This(a), Place::This(b)) => !overlaps(a, b),
                (Place::Word(_) | Place::Bit(_), _) => true,
                (Place::Var(_), Place::Frame(_)) | (Place::Frame(_), Place::Var(_)) => true,
                _ => false,
            }
        });
    }

    /// Forgets the held values a store of `bytes` bytes through a pointer to `into` may change.
    fn forget_indirect(&mut self, into: Into, bytes: u32) {
        match into {
            Into::Vars => self.held.retain(|h| matches!(h.place, Place::Frame(_))),
            Into::Frame(offset) => self.forget(Place::Frame(offset), bytes),
            Into::Unknown => self.held.clear(),
        }
    }

    fn as_float(&mut self, elem: Elem, v: Value) -> Value {
        if elem == Elem::F32 {
            let bits = self.b.ins().ireduce(types::I32, v);
            self.b.ins().bitcast(types::F32, MemFlagsData::new(), bits)
        } else {
            self.b.ins().bitcast(types::F64, MemFlagsData::new(), v)
        }
    }

    fn float_bits(&mut self, elem: Elem, f: Value) -> Value {
        if elem == Elem::F32 {
            let bits = self.b.ins().bitcast(types::I32, MemFlagsData::new(), f);
            self.b.ins().uextend(I64, bits)
        } else {
            self.b.ins().bitcast(I64, MemFlagsData::new(), f)
        }
    }

    fn float_zero(&mut self, elem: Elem) -> Value {
        if elem == Elem::F32 {
            self.b.ins().f32const(0.0)
        } else {
            self.b.ins().f64const(0.0)
        }
    }

    fn call_helper(&mut self, sig: SigRef, function: usize, args: &[Value]) -> Value {
        let callee = self.b.ins().iconst(I64, function as i64);
        let call = self.b.ins().call_indirect(sig, callee, args);
        self.b.inst_results(call).first().copied().unwrap_or(callee)
    }

    fn binary_helper(&mut self, op: BinOp, elem: Elem, a: Value, b: Value) -> Value {
        let op = self.b.ins().iconst(I64, helpers::binary_index(op));
        let elem = self.b.ins().iconst(I64, helpers::elem_index(elem));
        let function = helpers::binary as extern "C" fn(u64, u64, u64, u64) -> u64 as usize;
        self.call_helper(self.binary_sig, function, &[op, elem, a, b])
    }

    /// `a op b` (`depth`: the stack's depth after the instruction, for its error exit).
    /// `a op b` on REALs or LREALs, each given as its slot and its float value; the result's
    /// slot, and its float value when it was computed inline.
    fn float_binary(
        &mut self,
        op: BinOp,
        elem: Elem,
        (a, x): (Value, Value),
        (b, y): (Value, Value),
        at: At,
        depth: u32,
    ) -> (Value, Option<Value>) {
        let r = match op {
            BinOp::Add => self.b.ins().fadd(x, y),
            BinOp::Sub => self.b.ins().fsub(x, y),
            BinOp::Mul => self.b.ins().fmul(x, y),
            BinOp::Div | BinOp::Mod => {
                let zero = self.float_zero(elem);
                let by_zero = self.b.ins().fcmp(FloatCC::Equal, y, zero);
                self.error_if(by_zero, at, depth, 0, ERR_DIVIDE_BY_ZERO);
                if op == BinOp::Mod {
                    return (self.binary_helper(op, elem, a, b), None);
                }
                self.b.ins().fdiv(x, y)
            }
            _ => return (self.binary_helper(op, elem, a, b), None),
        };
        (self.float_bits(elem, r), Some(r))
    }

    /// `a op b` on integers and bit strings.
    fn binary(&mut self, op: BinOp, elem: Elem, a: Value, b: Value, at: At, depth: u32) -> Value {
        let r = match op {
            BinOp::Add => self.b.ins().iadd(a, b),
            BinOp::Sub => self.b.ins().isub(a, b),
            BinOp::Mul => self.b.ins().imul(a, b),
            BinOp::And => self.b.ins().band(a, b),
            BinOp::Or => self.b.ins().bor(a, b),
            BinOp::Xor => self.b.ins().bxor(a, b),
            BinOp::Div | BinOp::Mod => {
                let divisor = self.wrap(elem, b);
                let by_zero = self.b.ins().icmp_imm_s(IntCC::Equal, divisor, 0);
                self.error_if(by_zero, at, depth, 0, ERR_DIVIDE_BY_ZERO);
                if elem.is_signed() {
                    // i64::MIN / -1 traps in the processor; the VM's `wrapping_div` gives
                    // -a, `wrapping_rem` 0.
                    let minus_one = self.b.ins().icmp_imm_s(IntCC::Equal, b, -1);
                    let one = self.b.ins().iconst(I64, 1);
                    let safe = self.b.ins().select(minus_one, one, b);
                    if op == BinOp::Div {
                        let q = self.b.ins().sdiv(a, safe);
                        let negated = self.b.ins().ineg(a);
                        self.b.ins().select(minus_one, negated, q)
                    } else {
                        let r = self.b.ins().srem(a, safe);
                        let zero = self.b.ins().iconst(I64, 0);
                        self.b.ins().select(minus_one, zero, r)
                    }
                } else if op == BinOp::Div {
                    self.b.ins().udiv(a, b)
                } else {
                    self.b.ins().urem(a, b)
                }
            }
            BinOp::Min | BinOp::Max => {
                let cc =
                    if elem.is_signed() { IntCC::SignedLessThan } else { IntCC::UnsignedLessThan };
                let less = self.b.ins().icmp(cc, a, b);
                if op == BinOp::Min {
                    self.b.ins().select(less, a, b)
                } else {
                    self.b.ins().select(less, b, a)
                }
            }
            // Shifts, rotations (and the integer power, which `is_native` leaves to the
            // interpreter because it can fail).
            _ => return self.binary_helper(op, elem, a, b),
        };
        self.wrap(elem, r)
    }

    /// `op a` on a REAL or LREAL given as its slot and its float value, as
    /// [`Gen::float_binary`].
    fn float_unary(&mut self, op: UnOp, elem: Elem, a: Value, x: Value) -> (Value, Option<Value>) {
        let r = match op {
            UnOp::Neg => self.b.ins().fneg(x),
            UnOp::Abs => self.b.ins().fabs(x),
            UnOp::Sqrt => self.b.ins().sqrt(x),
            _ => return (self.unary_helper(op, elem, a), None),
        };
        (self.float_bits(elem, r), Some(r))
    }

    /// `op a` on an integer or bit string.
    fn unary(&mut self, op: UnOp, elem: Elem, a: Value) -> Value {
        let r = match op {
            UnOp::Neg => self.b.ins().ineg(a),
            UnOp::Not => self.b.ins().bnot(a),
            _ => return self.unary_helper(op, elem, a),
        };
        self.wrap(elem, r)
    }

    fn unary_helper(&mut self, op: UnOp, elem: Elem, a: Value) -> Value {
        let op = self.b.ins().iconst(I64, helpers::unary_index(op));
        let elem = self.b.ins().iconst(I64, helpers::elem_index(elem));
        let function = helpers::unary as extern "C" fn(u64, u64, u64) -> u64 as usize;
        self.call_helper(self.unary_sig, function, &[op, elem, a])
    }

    /// `x op y` on floats as an `i8` truth value: a NaN satisfies only `<>`.
    fn float_compare(&mut self, op: CmpOp, x: Value, y: Value) -> Value {
        let cc = match op {
            CmpOp::Eq => FloatCC::Equal,
            CmpOp::Ne => FloatCC::NotEqual,
            CmpOp::Lt => FloatCC::LessThan,
            CmpOp::Le => FloatCC::LessThanOrEqual,
            CmpOp::Gt => FloatCC::GreaterThan,
            CmpOp::Ge => FloatCC::GreaterThanOrEqual,
        };
        self.b.ins().fcmp(cc, x, y)
    }

    /// `a op b` on integers and bit strings as an `i8` truth value.
    fn compare(&mut self, op: CmpOp, elem: Elem, a: Value, b: Value) -> Value {
        let signed = elem.is_signed();
        let cc = match (op, signed) {
            (CmpOp::Eq, _) => IntCC::Equal,
            (CmpOp::Ne, _) => IntCC::NotEqual,
            (CmpOp::Lt, true) => IntCC::SignedLessThan,
            (CmpOp::Le, true) => IntCC::SignedLessThanOrEqual,
            (CmpOp::Gt, true) => IntCC::SignedGreaterThan,
            (CmpOp::Ge, true) => IntCC::SignedGreaterThanOrEqual,
            (CmpOp::Lt, false) => IntCC::UnsignedLessThan,
            (CmpOp::Le, false) => IntCC::UnsignedLessThanOrEqual,
            (CmpOp::Gt, false) => IntCC::UnsignedGreaterThan,
            (CmpOp::Ge, false) => IntCC::UnsignedGreaterThanOrEqual,
        };
        self.b.ins().icmp(cc, a, b)
    }

    /// The slot `a` of `from` converted to `to` (`x`: its float value when `from` is a float),
    /// and the result's float value when it is one computed inline.
    fn convert(
        &mut self,
        from: Elem,
        to: Elem,
        a: Value,
        x: Option<Value>,
    ) -> (Value, Option<Value>) {
        let float = |g: &mut Self| x.unwrap_or_else(|| g.as_float(from, a));
        if to == Elem::Bool {
            if from.is_float() {
                let x = float(self);
                let zero = self.float_zero(from);
                let ne = self.b.ins().fcmp(FloatCC::NotEqual, x, zero);
                return (self.b.ins().uextend(I64, ne), None);
            }
            return (self.truth(a), None);
        }
        match (from.is_float(), to.is_float()) {
            (false, false) => (self.wrap(to, a), None),
            (false, true) => {
                let ty = float_type(to);
                let y = if from.is_signed() {
                    self.b.ins().fcvt_from_sint(ty, a)
                } else {
                    self.b.ins().fcvt_from_uint(ty, a)
                };
                (self.float_bits(to, y), Some(y))
            }
            (true, true) if from == to => (a, None),
            (true, true) => {
                let x = float(self);
                let y = if to == Elem::F32 {
                    self.b.ins().fdemote(types::F32, x)
                } else {
                    self.b.ins().fpromote(types::F64, x)
                };
                (self.float_bits(to, y), Some(y))
            }
            (true, false) => {
                let from = self.b.ins().iconst(I64, helpers::elem_index(from));
                let to = self.b.ins().iconst(I64, helpers::elem_index(to));
                let function = helpers::convert as extern "C" fn(u64, u64, u64) -> u64 as usize;
                (self.call_helper(self.unary_sig, function, &[from, to, a]), None)
            }
        }
    }
}

/// True for a place in variable memory, the frame or the FB instance (byte-addressed).
fn in_bytes(place: Place) -> bool {
    matches!(place, Place::Var(_) | Place::Frame(_) | Place::This(_))
}

/// The Cranelift type of a REAL (`F32`) or LREAL.
fn float_type(elem: Elem) -> Type {
    if elem == Elem::F32 {
        types::F32
    } else {
        types::F64
    }
}
