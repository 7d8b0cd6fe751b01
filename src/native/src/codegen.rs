//! A Structured Text program's ops as Cranelift functions, one per body (the program's, each
//! FUNCTION's and FUNCTION_BLOCK's), each `fn(*mut Context) -> u32`.
//!
//! The shape of a function:
//! - the entry loads the registers from the [`Context`](code::Context), checks that the frame
//!   and the FB instance hold every operand of the body (else the interpreter goes on), and goes
//!   straight to the body's first block when entered at its start (a call, a scan), else to
//!   the dispatch;
//! - the dispatch is a switch on the program counter over the body's entry points (the
//!   leaders the VM may go on at, [`Analysis::dispatched`]); each goes through a loader, which
//!   reloads the evaluation stack's slots of that instruction from memory into SSA variables,
//!   to the leader's block; any other program counter goes back to the interpreter;
//! - a block first checks what its instructions need (enough step budget for all of them)
//!   and hands the whole block to the interpreter if anything is missing, then charges the
//!   budget and runs the instructions with the evaluation stack in SSA variables, and goes on
//!   to the next block directly;
//! - inside a block the code remembers what it knows of each slot ([`SlotInfo`]: a pointer
//!   into variable memory or the frame that needs no check, a BOOL already 0 or 1, a REAL kept
//!   in a float register) and of each variable it stored or fetched ([`Held`], forgotten at
//!   any store that may change it), and checks an index against a range once;
//! - in a loop, a store of a variable whose value goes on in a register to the next blocks is
//!   not written to memory at once: the value is written back before anything else may read
//!   the place (a load of bytes it overlaps, through a pointer too, a store through a pointer
//!   that may change it, a call, a `RETURN`), on a way to a block that does not receive it,
//!   and on every way out (the budget, an error, the interpreter), so that memory is exactly
//!   the interpreter's wherever the VM or another body can look ([`carry::unwritten`]);
//! - every way out stores the registers and the live stack slots back, exactly as the
//!   interpreter leaves them: at `END`, after an operation error, before an instruction it
//!   hands to the interpreter (a pointer outside variable memory and the frame, a full call
//!   stack, a machine stack used down to the context's floor); but a program's body that
//!   makes no machine call leaves `sp` as the VM stored it where it goes out with the stack it
//!   came in with, and the entry's loads of registers nothing uses are dropped
//!   ([`drop_unused`]).
//!
//! A call pushes a [`StFrame`] as the interpreter does, stores the caller's stack slots (a
//! callee's slots are numbered from its own start) and the callee's registers to memory, and
//! calls the callee's function: a machine call, which the processor's return prediction
//! follows. The callee's `RETURN` pops the frame, stores the caller's registers and returns
//! `RETURN_CONTINUE`; the caller goes on after its call with its own registers and slots,
//! still in its variables. Any other result (the budget spent, `END` cannot be, an error, an
//! instruction for the interpreter) is passed up unchanged: the registers in the context are
//! where the callee stopped, with the frames of every caller pushed, as the interpreter would
//! have them. Entered by the VM inside a body whose caller is not native (the interpreter
//! made the call, or a callee stopped), a `RETURN` gives the VM `RETURN_CONTINUE`, which
//! enters the caller's function at the return address, through its dispatch.
//!
//! A call of a small body that calls nothing ([`inline::plan`]) is compiled inline instead: the callee's blocks are generated
//! once more inside the caller, with the callee's registers (its frame base, its FB instance,
//! the call depth + 1) and its own stack slots, and its `RETURN` jumps to the caller's next
//! block. Nothing is pushed on the way in: the frame record and the caller's slots are
//! written only on the inlined blocks' ways out, so that the VM finds the callee stopped as
//! if called (and goes on in the callee's own function, which is still generated).

use std::mem::offset_of;

use cranelift_codegen::cursor::{Cursor, FuncCursor};
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{
    types, AbiParam, Block, BlockArg, ExtFuncData, ExternalName, FuncRef, Function, InstBuilder,
    InstructionData, MemFlagsData, Opcode, SigRef, Signature, Type, UserExternalName, Value,
    ValueDef,
};
use cranelift_codegen::isa::TargetIsa;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Switch, Variable};
use plcd_core::lang::native::{NativeRegs, StFrame};
use plcd_core::lang::ops::{CmpOp, Op, Place};
use plcd_core::lang::{Program, EVAL_DEPTH, ST_CALL_DEPTH};
use plcd_core::value::{BinOp, Elem, Pointer, Space, UnOp, REF_TAG};
use plcd_core::vm::{ERR_DIVIDE_BY_ZERO, ERR_INDEX_RANGE, ERR_REF_NULL};

use crate::analysis::{is_native, Analysis, BlockRoles};
use crate::carry::{self, in_bytes, Key, Reach, Writes};
use crate::code::{self, RETURN_CONTINUE, RETURN_END, RETURN_ERROR, RETURN_INTERPRET};
use crate::helpers;
use crate::inline::{self, Inlined};

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

/// A machine call of `callee` with `args` in the function `b` builds: when it returns `back`,
/// the code goes on after it (in the block `b` is left in); any other status is returned at
/// once, on a cold path (the callee left every register in the context).
pub(crate) fn call_or_pass_on(b: &mut FunctionBuilder, callee: FuncRef, args: &[Value], back: u32) {
    let call = b.ins().call(callee, args);
    let status = b.inst_results(call)[0];
    let returned = b.ins().icmp_imm_s(IntCC::Equal, status, i64::from(back));
    let goes_on = b.create_block();
    let stopped = b.create_block();
    b.set_cold_block(stopped);
    b.ins().brif(returned, goes_on, &[], stopped, &[]);
    b.switch_to_block(stopped);
    b.ins().return_(&[status]);
    b.switch_to_block(goes_on);
}

/// Generated function `name` (its index in the module), with signature `signature`, imported
/// into the function `b` builds, for a machine call.
pub(crate) fn import_function(b: &mut FunctionBuilder, name: u32, signature: SigRef) -> FuncRef {
    let name =
        b.func.declare_imported_user_function(UserExternalName { namespace: 0, index: name });
    b.import_function(ExtFuncData {
        name: ExternalName::user(name),
        signature,
        colocated: true,
        patchable: false,
    })
}

/// The [`Context`](code::Context) and the stacks' slots: aligned.
pub(crate) fn own() -> MemFlagsData {
    MemFlagsData::trusted()
}

/// Fills `func` with the code of function `function` of `program`: the body that starts at
/// `analysis.functions[function]`. `roles` is [`Analysis::block_roles`]; `names` gives each
/// function's name in the module (the index of its `FuncId`), for the calls between them.
///
/// Returns the bytes of variable memory the code reaches without checking at each access (the
/// fixed operands, and the elements of arrays at fixed places): the code may run only on at
/// least that much.
pub(crate) fn generate(
    program: &Program,
    analysis: &Analysis,
    roles: &BlockRoles,
    function: usize,
    names: &[u32],
    isa: &dyn TargetIsa,
    func: &mut Function,
) -> u64 {
    let call_conv = isa.default_call_conv();
    func.signature = code::entry_signature(call_conv);
    let own_signature = func.signature.clone();
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
    let body_sig = b.import_signature(own_signature);
    let entry = b.create_block();
    b.append_block_params_for_function_params(entry);
    b.switch_to_block(entry);
    let params = b.block_params(entry).to_vec();
    let ctx = params[0];
    let regs = Regs { left: b.declare_var(I64), sb: b.declare_var(I64) };
    let stack: Vec<Variable> = (0..=analysis.max_depth).map(|_| b.declare_var(I64)).collect();
    // The activation's registers, fixed while it runs (set by `Gen::entry`).
    let unset = b.ins().iconst(I64, 0);
    let leaders = &analysis.function_leaders[function][..];
    let leaders_len = leaders.len();
    let body = analysis.functions[function];
    let plan = inline::plan(program, analysis, body, leaders);
    let calls: Vec<(u32, &Writes)> = plan.iter().map(|call| (call.pc, &call.writes)).collect();
    let jumps = carry::Jumps::of(program, analysis, leaders);
    let in_loop = carry::in_loops(&jumps);
    let carried = carry::carried(program, &jumps, &calls, false, &in_loop);
    let unwritten = carry::unwritten(program, &jumps, &carried, &in_loop);
    let mut g = Gen {
        b,
        program,
        analysis,
        context: ctx,
        entry,
        fields: Vec::new(),
        entry_loads: Vec::new(),
        sp_stores: Vec::new(),
        regs,
        activation: Activation {
            pc: unset,
            sp: unset,
            depth: unset,
            base: unset,
            this: unset,
            frame_at: unset,
            this_at: unset,
            called: unset,
            vm_only: false,
        },
        stack,
        binary_sig,
        unary_sig,
        copy_sig,
        body_sig,
        body,
        names,
        callees: Vec::new(),
        blocks: Vec::with_capacity(leaders.len()),
        loaders: Vec::with_capacity(leaders.len()),
        leaders,
        dispatch: None,
        carried,
        carry_vars: Vec::new(),
        unwritten,
        in_loop,
        this_in_vars: false,
        passed_on: Vec::new(),
        info: vec![SlotInfo::default(); analysis.max_depth as usize + 1],
        held: Vec::new(),
        in_range: Vec::new(),
        charged: None,
        back_jumps: back_jumps(program),
        branch_facts: [(0, None); 2],
        known_ranges: vec![None; leaders_len],
        vars_need: analysis.vars_end,
        checks: &roles.checks,
        dispatched: &roles.dispatched,
        handed_over: vec![false; leaders_len],
        bails: 0,
        inline: None,
        plan,
    };
    g.entry(&params);
    g.body();
    let vars_need = g.vars_need;
    let mut entry_loads = std::mem::take(&mut g.entry_loads);
    let sp_stores = std::mem::take(&mut g.sp_stores);
    let sp = g.activation.sp;
    g.b.seal_all_blocks();
    g.b.finalize(isa.frontend_config());
    // A program's body is entered by the VM only, with `sp` in the context; if it makes no
    // machine call, nothing else stores there while it runs. A way out at depth 0 from the
    // stack base it came in with stores the same `sp` (but for the mask, which the VM applies
    // on reading it back): that store is left out, and the `sp` loaded only for it.
    let calls = func.layout.blocks().any(|block| {
        func.layout.block_insts(block).any(|inst| func.dfg.insts[inst].opcode().is_call())
    });
    let mut unused = Vec::new();
    if !calls {
        for (stored, sb) in sp_stores {
            if func.dfg.resolve_aliases(sb) == func.dfg.resolve_aliases(sp) {
                func.layout.remove_inst(stored.store);
                unused.extend([stored.masked, stored.sum]);
            }
        }
        // (After every widening and sum it feeds.)
        entry_loads.push(sp);
    }
    unused.extend(entry_loads);
    drop_unused(func, &unused);
    vars_need
}

/// A store of `sp` to the context ([`Gen::store_registers`]): the store, the value stored
/// (masked) and the sum it masks.
#[derive(Clone, Copy)]
struct SpStore {
    store: cranelift_codegen::ir::Inst,
    masked: Value,
    sum: Value,
}

/// Removes the instructions that define `values` (the entry's loads of registers, their
/// widenings after them) where nothing uses their results. Cranelift keeps every load that is
/// not read-only, used or not (a register allocated and an instruction run on each entry); these
/// cannot be read-only: a call stores the callee's registers at the same places.
fn drop_unused(func: &mut Function, values: &[Value]) {
    let mut uses: std::collections::HashMap<Value, u32> = Default::default();
    for block in func.layout.blocks() {
        for inst in func.layout.block_insts(block) {
            for value in func.dfg.inst_values(inst) {
                *uses.entry(func.dfg.resolve_aliases(value)).or_default() += 1;
            }
        }
    }
    // In order: a widening before the load it widens.
    for &value in values {
        let value = func.dfg.resolve_aliases(value);
        let ValueDef::Result(inst, _) = func.dfg.value_def(value) else { continue };
        let unused = uses.get(&value).is_none_or(|&n| n == 0);
        if !unused
            || func.layout.inst_block(inst).is_none()
            || func.dfg.inst_results(inst).len() != 1
        {
            continue;
        }
        let args: Vec<Value> = func.dfg.inst_values(inst).collect();
        for arg in args {
            if let Some(n) = uses.get_mut(&func.dfg.resolve_aliases(arg)) {
                *n -= 1;
            }
        }
        func.layout.remove_inst(inst);
    }
}

/// The registers that change inside an activation, as SSA variables: the budget left, and
/// `sb`, the absolute index (not yet masked) of the activation's first stack slot.
struct Regs {
    left: Variable,
    sb: Variable,
}

/// The registers as the function was entered with them, which do not change while its
/// activation runs (a call returns with them as they were): the program counter and stack
/// pointer it was entered at, the call depth, the frame's `base` (a `u32`), the FB instance
/// `this`, and the addresses of the frame's base and of the FB instance, checked against what
/// the body's operands need on the way in; `called`: 1 if a native caller called it (its
/// `RETURN` goes back to it), 0 if the VM entered it; `vm_only`: no caller ever calls it (a
/// program's body), so the context's registers hold its `depth`, `base` and `this` as long
/// as it runs (a callee returns having written only the budget).
#[derive(Clone, Copy)]
struct Activation {
    pc: Value,
    sp: Value,
    depth: Value,
    base: Value,
    this: Value,
    frame_at: Value,
    this_at: Value,
    called: Value,
    vm_only: bool,
}

/// The registers as the context holds them between two activations' code (`NativeRegs`);
/// `frame`: the activation's own (`None` where the context holds them already).
struct Registers {
    pc: Value,
    sp: Value,
    left: Value,
    frame: Option<FrameRegisters>,
}

/// An activation's call depth, frame `base` and FB instance `this`, as `NativeRegs` holds them.
struct FrameRegisters {
    base: Value,
    this: Value,
    depth: Value,
}

struct Gen<'a, 'f> {
    b: FunctionBuilder<'f>,
    program: &'a Program,
    analysis: &'a Analysis,
    /// The [`Context`](code::Context), the function's first parameter (passed on to the
    /// bodies it calls).
    context: Value,
    /// The function's first block, where the context's fields are loaded.
    entry: Block,
    /// The context's fields loaded so far, by offset ([`Gen::field`]).
    fields: Vec<(usize, Value)>,
    /// The entry's loads of registers a body may not use, with their widenings, for
    /// [`drop_unused`].
    entry_loads: Vec<Value>,
    /// The stores of `sp` on the ways out of a program's body at depth 0 from its `sb`, for
    /// [`drop_unused`].
    sp_stores: Vec<(SpStore, Value)>,
    regs: Regs,
    activation: Activation,
    /// The evaluation stack's slots of the current activation, by depth.
    stack: Vec<Variable>,
    binary_sig: SigRef,
    unary_sig: SigRef,
    copy_sig: SigRef,
    /// The signature of every body's function (this one's).
    body_sig: SigRef,
    /// The body this function runs (its first instruction).
    body: u32,
    /// [`generate`]'s `names`.
    names: &'a [u32],
    /// The functions of the bodies this one calls, by their first instruction.
    callees: Vec<(u32, FuncRef)>,
    /// The body's leaders (their indices in [`Analysis::leaders`]), and the block and the
    /// loader (the way in from the dispatch) of each.
    leaders: &'a [usize],
    blocks: Vec<Block>,
    loaders: Vec<Option<Block>>,
    dispatch: Option<Block>,
    /// The values of fixed places each of the body's blocks receives in registers, by its
    /// index in `leaders` ([`carry::carried`]), and the variable that passes each on.
    carried: Vec<Vec<Key>>,
    carry_vars: Vec<(Key, Variable)>,
    /// The values each of the body's blocks receives not yet written to memory
    /// ([`carry::unwritten`]), by its index in `leaders`.
    unwritten: Vec<Vec<Key>>,
    /// Whether each of the body's blocks is in a loop ([`carry::in_loops`]).
    in_loop: Vec<bool>,
    /// The activation's FB instance is known to be in variable memory ([`carry::may_change`]):
    /// in a call compiled inline whose caller knows where the instance is.
    this_in_vars: bool,
    /// In the block being generated: the values the blocks after it receive, if it is in a
    /// loop (else none: its stores are written at once).
    passed_on: Vec<Key>,
    /// In the block being generated: what is known of each stack slot.
    info: Vec<SlotInfo>,
    /// In the block being generated: the values of fixed places it stored or fetched, still
    /// there (no store since could have changed them).
    held: Vec<Held>,
    /// In the block being generated: the indices it already found inside their range.
    in_range: Vec<InRange>,
    /// In the block being generated: the budget as it came in and what the block charged it
    /// at its start, with the value that left ([`Gen::charge_on_edges`]).
    charged: Option<(Value, u32, Value)>,
    /// The program's jumps back, `(pc, target)` with `target <= pc`, by `pc`
    /// ([`Gen::loop_exit`]).
    back_jumps: Vec<(u32, u32)>,
    /// After a branch on a comparison with a constant that ends the block being generated: for
    /// each way, the range the compared value lies in on it ([`Gen::branch_fact`]), passed on
    /// with the indices.
    branch_facts: [(u32, Option<InRange>); 2],
    /// For each block of the body that one jump reaches and the dispatch does not enter: the
    /// indices the block before it found inside their range, which its code dominates.
    known_ranges: Vec<Option<Vec<InRange>>>,
    /// See [`generate`]'s result.
    vars_need: u64,
    /// [`Analysis::budget_checks`].
    checks: &'a [(bool, u64)],
    /// [`Analysis::dispatched`].
    dispatched: &'a [bool],
    /// The body's blocks that may hand an instruction to the interpreter ([`Gen::block`]).
    handed_over: Vec<bool>,
    /// The [`Gen::bail_if`]s generated so far.
    bails: u32,
    /// The call whose callee's blocks are being generated inline, if any ([`Gen::inline_call`]).
    inline: Option<Inline>,
    /// The body's calls compiled inline ([`inline::plan`]).
    plan: Vec<Inlined>,
}

/// A call compiled inline: its callee's `RETURN`s go on at `back`, in the caller; `record` is
/// what the call would have pushed, written only where the code leaves the inlined callee.
struct Inline {
    back: Block,
    record: CallRecord,
}

/// A call's frame record and the caller's stack slots below the callee's, as [`Gen::call`]
/// stores them before a machine call: `calls` is the caller's call depth, `sb` its first slot.
struct CallRecord {
    calls: Value,
    return_pc: u32,
    base: Value,
    this: Value,
    sb: Value,
    slots: Vec<Value>,
}

/// What the code of one activation works with ([`Gen::swap_scope`]): the caller's, set aside
/// while [`Gen::inline_call`] generates its callee's.
struct Scope<'a> {
    body: u32,
    activation: Activation,
    leaders: &'a [usize],
    blocks: Vec<Block>,
    carried: Vec<Vec<Key>>,
    carry_vars: Vec<(Key, Variable)>,
    unwritten: Vec<Vec<Key>>,
    in_loop: Vec<bool>,
    this_in_vars: bool,
    stack: Vec<Variable>,
    info: Vec<SlotInfo>,
    held: Vec<Held>,
    known_ranges: Vec<Option<Vec<InRange>>>,
}

/// The smallest and largest value of an integer `elem` up to 32 bits, which a slot holds
/// extended from its width: the ranges [`Gen::branch_fact`] and [`Gen::fits`] reason
/// on (an `InRange` holds an `i32` start and a `u32` length).
fn small_int_bounds(elem: Elem) -> Option<(i64, i64)> {
    match elem {
        Elem::I8 => Some((i64::from(i8::MIN), i64::from(i8::MAX))),
        Elem::I16 => Some((i64::from(i16::MIN), i64::from(i16::MAX))),
        Elem::I32 => Some((i64::from(i32::MIN), i64::from(i32::MAX))),
        Elem::U8 => Some((0, i64::from(u8::MAX))),
        Elem::U16 => Some((0, i64::from(u16::MAX))),
        _ => None,
    }
}

/// The jumps back of `program`'s code, `(pc, target)`, by `pc`.
fn back_jumps(program: &Program) -> Vec<(u32, u32)> {
    (program.code.iter().enumerate())
        .filter_map(|(pc, op)| match *op {
            Op::Goto(target) | Op::GotoIf { target, .. } if target as usize <= pc => {
                Some((pc as u32, target))
            }
            _ => None,
        })
        .collect()
}

/// How deep [`Gen::same_value`] looks: an index computed from a variable and a constant, cut
/// to its type (`ireduce`, `isub`, `sextend`, the constant).
const SAME_VALUE_DEPTH: u32 = 4;

/// True if `opcode` computes its result from its operands alone: no memory, no trap, no other
/// effect.
fn pure(opcode: Opcode) -> bool {
    !(opcode.can_load()
        || opcode.can_store()
        || opcode.can_trap()
        || opcode.is_call()
        || opcode.other_side_effects())
}

/// An index value found inside the range `lo`, `len` of an [`Op::Index`].
type InRange = (Value, i32, u32);

/// What the code knows of a stack slot's value in the block being generated.
#[derive(Clone, Copy, Default)]
struct SlotInfo {
    /// A pointer into variable memory, and where it may point (an element of an array at a
    /// fixed place).
    known: Option<Reach>,
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
    /// Variable memory, there.
    Vars(Reach),
    /// The frame, this many bytes from its base.
    Frame(u32),
    Unknown,
}

/// A way a branch takes ([`Gen::edge`]): the block it goes to, and for a block that writes
/// values back on the way, the block after it and the values.
type Edge = (Block, Option<(Block, Vec<Held>)>);

/// The value of a fixed place, as a slot fetched from it now would be.
#[derive(Clone, Copy)]
struct Held {
    place: Place,
    elem: Elem,
    value: Value,
    info: SlotInfo,
    /// Stored by the code and not written to memory yet ([`Gen::write_back`]).
    dirty: bool,
}

impl Held {
    fn key(&self) -> Key {
        (self.place, self.elem)
    }
}

/// Where the block being generated stands: the instruction's index in it and the block's
/// length, for the budget an exit gives back.
#[derive(Clone, Copy)]
struct At {
    pc: u32,
    index: u32,
    len: u32,
}

impl<'a> Gen<'a, '_> {
    /// The way in. From the VM (`base` is [`code::FROM_VM`]) the registers are in the
    /// context, and the frame and the FB instance are checked here, once for all the body's
    /// blocks (refused, the interpreter goes on with the registers as they are); from a native
    /// caller, they are the parameters, checked by the caller.
    fn entry(&mut self, params: &[Value]) {
        let &[_, base, this, depth, sp, left, this_at] = params else {
            unreachable!("code::entry_signature has 7 parameters")
        };
        // The program's body is never called: it has the VM's way in only.
        let called_ever = !self.analysis.bodies[&self.body].return_sites.is_empty();
        let join = self.b.create_block();
        let from_vm = self.b.create_block();
        if called_ever {
            for _ in 0..8 {
                self.b.append_block_param(join, I64);
            }
            let from_caller = self.b.create_block();
            let vm = self.b.ins().icmp_imm_s(IntCC::Equal, base, code::FROM_VM as i64);
            self.b.ins().brif(vm, from_vm, &[], from_caller, &[]);
            self.b.switch_to_block(from_caller);
            let start = self.b.ins().iconst(I64, i64::from(self.body));
            let called = self.b.ins().iconst(I64, 1);
            let args = [start, sp, depth, base, this, left, this_at, called].map(BlockArg::from);
            self.b.ins().jump(join, &args);
        } else {
            self.b.ins().jump(from_vm, &[]);
        }

        self.b.switch_to_block(from_vm);
        let ctx = self.field(code::CONTEXT.regs);
        let load32 = |b: &mut FunctionBuilder, offset: usize| {
            let v = b.ins().load(types::I32, own(), ctx, reg(offset));
            b.ins().uextend(I64, v)
        };
        let pc = load32(&mut self.b, offset_of!(NativeRegs, pc));
        // A program's body is the bottom activation: no call frame below it.
        let depth = if called_ever {
            load32(&mut self.b, offset_of!(NativeRegs, st_depth))
        } else {
            self.b.ins().iconst(I64, 0)
        };
        let base = load32(&mut self.b, offset_of!(NativeRegs, base));
        let this = self.b.ins().load(I64, own(), ctx, reg(offset_of!(NativeRegs, this)));
        // The frame's base and the FB instance: a program's body without operands in either
        // uses neither (`drop_unused`).
        for value in [base, this] {
            self.entry_loads.push(value);
            if let ValueDef::Result(inst, _) = self.b.func.dfg.value_def(value) {
                if self.b.func.dfg.insts[inst].opcode() == Opcode::Uextend {
                    self.entry_loads.push(self.b.func.dfg.inst_args(inst)[0]);
                }
            }
        }
        let left = self.b.ins().load(I64, own(), ctx, reg(offset_of!(NativeRegs, left)));
        let sp = self.b.ins().load(I64, own(), ctx, reg(offset_of!(NativeRegs, sp)));
        let (refused, this_at) = self.body_pointers(self.body, base, this, false);
        let ok = match refused {
            Some(refused) => self.b.ins().bxor_imm_s(refused, 1),
            None => self.b.ins().iconst(types::I8, 1),
        };
        let called = self.b.ins().iconst(I64, 0);
        let refuse = self.b.create_block();
        self.b.set_cold_block(refuse);
        let (pc, sp, depth, base, this, left, this_at, called) = if called_ever {
            let args = [pc, sp, depth, base, this, left, this_at, called].map(BlockArg::from);
            self.b.ins().brif(ok, join, &args, refuse, &[]);
            let &[pc, sp, depth, base, this, left, this_at, called] = self.b.block_params(join)
            else {
                unreachable!("8 parameters")
            };
            (pc, sp, depth, base, this, left, this_at, called)
        } else {
            self.b.ins().brif(ok, join, &[], refuse, &[]);
            (pc, sp, depth, base, this, left, this_at, called)
        };
        self.b.switch_to_block(refuse);
        self.ret(RETURN_INTERPRET);

        self.b.switch_to_block(join);
        // The frame's address, if the body reaches into its frame.
        let frame_at = if self.analysis.bodies[&self.body].uses_frame {
            let frame = self.field(code::CONTEXT.frame);
            self.b.ins().iadd(frame, base)
        } else {
            self.b.ins().iconst(I64, 0)
        };
        let vm_only = !called_ever;
        self.activation =
            Activation { pc, sp, depth, base, this, frame_at, this_at, called, vm_only };
        self.b.def_var(self.regs.left, left);
        for _ in 0..self.leaders.len() {
            let block = self.b.create_block();
            self.blocks.push(block);
        }
        for index in 0..self.leaders.len() {
            let dispatched = self.dispatched[self.leaders[index]];
            let loader = dispatched.then(|| self.b.create_block());
            self.loaders.push(loader);
        }
        let dispatch = self.b.create_block();
        self.dispatch = Some(dispatch);
        // A call, and a scan, start at the body's first instruction: straight in, without
        // the dispatch's search.
        match self.loader_of(self.body) {
            Some(start) => {
                let at_start = self.b.ins().icmp_imm_s(IntCC::Equal, pc, i64::from(self.body));
                self.b.ins().brif(at_start, start, &[], dispatch, &[]);
            }
            None => {
                self.b.ins().jump(dispatch, &[]);
            }
        }
    }

    /// The context's field at `offset`, loaded in the function's first block when first
    /// needed: a function loads only what its code uses.
    fn field(&mut self, offset: usize) -> Value {
        if let Some(&(_, value)) = self.fields.iter().find(|(at, _)| *at == offset) {
            return value;
        }
        let last = self.b.func.layout.last_inst(self.entry).expect("the entry's branch");
        let mut cursor = FuncCursor::new(self.b.func).at_inst(last);
        // The pointers the body works on are loaded here, before its first block; the others
        // (the registers, the stacks, the lengths for checks) may move to where they are used,
        // mostly the cold ways out.
        let hot = [code::CONTEXT.vars, code::CONTEXT.words, code::CONTEXT.frame];
        let flags =
            if hot.contains(&offset) { own() } else { own().with_readonly().with_can_move() };
        let value = cursor.ins().load(I64, flags, self.context, offset as i32);
        self.fields.push((offset, value));
        value
    }

    /// The index of leader `pc` among the body's leaders.
    fn leader_index(&self, pc: u32) -> Option<usize> {
        self.leaders.binary_search_by_key(&pc, |&index| self.analysis.leaders[index]).ok()
    }

    fn loader_of(&self, pc: u32) -> Option<Block> {
        self.leader_index(pc).and_then(|index| self.loaders[index])
    }

    fn body(&mut self) {
        for index in 0..self.leaders.len() {
            self.block(index);
        }
        // Where the interpreter hands back after an instruction a block handed to it: the
        // next block, or the one its last instruction jumps to (the interpreter runs to the
        // next leader).
        for index in 0..self.leaders.len() {
            if !self.handed_over[index] {
                continue;
            }
            for pc in self.successors(index) {
                if let Some(to) = self.leader_index(pc) {
                    if self.loaders[to].is_none() {
                        self.loaders[to] = Some(self.b.create_block());
                    }
                }
            }
        }
        // The dispatch: a loader for each leader it enters, the interpreter for any other pc
        // (with the registers as they are).
        let dispatch = self.dispatch.expect("created by entry");
        self.b.switch_to_block(dispatch);
        let mut switch = Switch::new();
        for (index, &leader) in self.leaders.iter().enumerate() {
            if let Some(loader) = self.loaders[index] {
                switch.set_entry(u128::from(self.analysis.leaders[leader]), loader);
            }
        }
        let elsewhere = self.b.create_block();
        switch.emit(&mut self.b, self.activation.pc, elsewhere);
        self.b.switch_to_block(elsewhere);
        self.b.set_cold_block(elsewhere);
        self.ret(RETURN_INTERPRET);

        for index in 0..self.leaders.len() {
            let leader_index = self.leaders[index];
            let leader = self.analysis.leaders[leader_index];
            let Some(loader) = self.loaders[index] else { continue };
            self.b.switch_to_block(loader);
            // The budget of a block that does not check it itself; short, the interpreter
            // goes on with the registers as they are.
            let (checks, need) = self.checks[leader_index];
            if !checks {
                let left = self.b.use_var(self.regs.left);
                let enough =
                    self.b.ins().icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, left, need as i64);
                let load = self.b.create_block();
                let refuse = self.b.create_block();
                self.b.set_cold_block(refuse);
                self.b.ins().brif(enough, load, &[], refuse, &[]);
                self.b.switch_to_block(refuse);
                self.ret(RETURN_INTERPRET);
                self.b.switch_to_block(load);
            }
            let depth = self.depth(leader);
            // (At depth 0 the very value loaded, the same on every way: [`drop_unused`]
            // finds the `sp` stored on the way out equal to it.)
            let sb = match depth {
                0 => self.activation.sp,
                _ => self.b.ins().iadd_imm_s(self.activation.sp, -i64::from(depth)),
            };
            self.b.def_var(self.regs.sb, sb);
            for slot in 0..depth {
                let address = self.slot_address(sb, slot);
                let value = self.b.ins().load(I64, own(), address, 0);
                self.b.def_var(self.stack[slot as usize], value);
            }
            // The values the block receives, from memory.
            self.held.clear();
            self.pass_on(leader);
            let block = self.blocks[index];
            self.b.ins().jump(block, &[]);
        }
    }

    /// Whether the frame at `base` or the FB instance `this` lacks room for an operand of
    /// `body` (an `i8` truth value, `None` where nothing needs checking), and the instance's
    /// address. `this_in_vars`: `this` is known to point into variable memory, far enough from
    /// its end (the caller makes sure).
    fn body_pointers(
        &mut self,
        body: u32,
        base: Value,
        this: Value,
        this_in_vars: bool,
    ) -> (Option<Value>, Value) {
        let needs = &self.analysis.bodies[&body];
        let (frame_end, this_end) = (needs.frame_end, needs.this_end);
        let mut refused = None;
        if frame_end > 0 {
            let end = self.b.ins().iadd_imm_s(base, frame_end as i64);
            let frame_len = self.field(code::CONTEXT.frame_len);
            refused = Some(self.b.ins().icmp(IntCC::UnsignedGreaterThan, end, frame_len));
        }
        let this_at = if this_end > 0 && this_in_vars {
            let vars = self.field(code::CONTEXT.vars);
            self.b.ins().iadd(vars, this)
        } else if this_end > 0 {
            let (address, inside) = self.reach(this, this_end);
            let outside = self.b.ins().bxor_imm_s(inside, 1);
            refused = Some(match refused {
                Some(frame) => self.b.ins().bor(frame, outside),
                None => outside,
            });
            address
        } else {
            self.b.ins().iconst(I64, 0)
        };
        (refused, this_at)
    }

    fn depth(&self, pc: u32) -> u32 {
        self.analysis.depth.get(pc as usize).copied().flatten().unwrap_or(0)
    }

    /// The block `pc` starts, or an exit to the interpreter at `pc` (the end of the code).
    fn target(&mut self, pc: u32, depth: u32) -> Block {
        if let Some(index) = self.leader_index(pc) {
            return self.blocks[index];
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

    fn slot_address(&mut self, sb: Value, slot: u32) -> Value {
        let index = self.b.ins().iadd_imm_s(sb, i64::from(slot));
        let index = self.b.ins().band_imm_s(index, MASK);
        let offset = self.b.ins().ishl_imm_s(index, 3);
        let eval = self.field(code::CONTEXT.eval);
        self.b.ins().iadd(eval, offset)
    }

    /// The registers to the context on a way out of this activation with `depth` slots on its
    /// stack: `pc`, `sp` (masked on the store), `left`, and the activation's own unless the
    /// context holds them already (`vm_only`).
    fn store_regs(&mut self, pc: Value, depth: u32, left: Value) {
        let Activation { base, this, depth: calls, vm_only, .. } = self.activation;
        let sb = self.b.use_var(self.regs.sb);
        // (Not the same `sp` as on the way in when it came in inside an expression.)
        let sp = self.b.ins().iadd_imm_s(sb, i64::from(depth));
        let frame = (!vm_only).then_some(FrameRegisters { base, this, depth: calls });
        let stored = self.store_registers(Registers { pc, sp, left, frame });
        if vm_only && depth == 0 {
            self.sp_stores.push((stored, sb));
        }
    }

    /// Stores the registers; returns the store of `sp`.
    fn store_registers(&mut self, r: Registers) -> SpStore {
        let ctx = self.field(code::CONTEXT.regs);
        let pc = self.b.ins().ireduce(types::I32, r.pc);
        self.b.ins().store(own(), pc, ctx, reg(offset_of!(NativeRegs, pc)));
        self.b.ins().store(own(), r.left, ctx, reg(offset_of!(NativeRegs, left)));
        let sp = self.b.ins().band_imm_s(r.sp, MASK);
        let store = self.b.ins().store(own(), sp, ctx, reg(offset_of!(NativeRegs, sp)));
        let stored = SpStore { store, masked: sp, sum: r.sp };
        let Some(frame) = r.frame else { return stored };
        for (value, offset) in [
            (frame.base, offset_of!(NativeRegs, base)),
            (frame.depth, offset_of!(NativeRegs, st_depth)),
        ] {
            let value = self.b.ins().ireduce(types::I32, value);
            self.b.ins().store(own(), value, ctx, reg(offset));
        }
        self.b.ins().store(own(), frame.this, ctx, reg(offset_of!(NativeRegs, this)));
        stored
    }

    fn ret(&mut self, status: u32) {
        let status = self.b.ins().iconst(types::I32, i64::from(status));
        self.b.ins().return_(&[status]);
    }

    /// Leaves with `status`: the stack's `depth` slots to memory, the registers with `pc` and
    /// `left` to the context.
    fn exit(&mut self, pc: u32, depth: u32, left: Value, status: u32) {
        self.write_back_leaving();
        if let Some(inline) = self.inline.take() {
            self.store_record(&inline.record);
            self.inline = Some(inline);
        }
        let sb = self.b.use_var(self.regs.sb);
        for slot in 0..depth {
            let value = self.b.use_var(self.stack[slot as usize]);
            let address = self.slot_address(sb, slot);
            self.b.ins().store(own(), value, address, 0);
        }
        let pc = self.b.ins().iconst(I64, i64::from(pc));
        self.store_regs(pc, depth, left);
        self.ret(status);
    }

    /// A cold branch out of the block when `fail` holds: back to the interpreter before the
    /// instruction at `at` (the stack as it was before it, `depth` slots).
    fn bail_if(&mut self, fail: Value, at: At, depth: u32) {
        self.bails += 1;
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
        let regs = self.field(code::CONTEXT.regs);
        self.b.ins().store(own(), code, regs, reg(offset_of!(NativeRegs, error)));
        let left = self.b.use_var(self.regs.left);
        let left = self.b.ins().iadd_imm_s(left, i64::from(at.len - at.index - 1));
        self.exit(at.pc + 1, depth, left, RETURN_ERROR);
        self.b.switch_to_block(next);
    }

    /// The block of the body's leader `body_index`; notes whether it may hand an instruction to
    /// the interpreter (other than for the budget), whose dispatch must then enter the blocks
    /// after it.
    fn block(&mut self, body_index: usize) {
        let bails = self.bails;
        let checked = self.block_code(body_index);
        let handed_over = self.bails > bails + u32::from(checked);
        if self.inline.is_none() {
            self.handed_over[body_index] = handed_over;
        }
        if !handed_over {
            self.pass_on_ranges(body_index);
        }
    }

    /// Where control goes after the last instruction of the block of leader `body_index` (a
    /// call's return site included).
    fn successors(&self, body_index: usize) -> Vec<u32> {
        self.analysis.successors(&self.program.code, self.leaders[body_index])
    }

    /// After the block of leader `body_index`: the indices it found inside their range, to
    /// each block after it that only it jumps to and that no loader enters (a block that hands
    /// an instruction to the interpreter gets loaders for the blocks after it: it passes
    /// nothing).
    fn pass_on_ranges(&mut self, body_index: usize) {
        let facts = std::mem::take(&mut self.branch_facts);
        for pc in self.successors(body_index) {
            let Some(to) = self.leader_index(pc) else { continue };
            if to > body_index && !self.dispatched[self.leaders[to]] {
                let mut known = self.in_range.clone();
                known.extend(facts.iter().filter(|(at, _)| *at == pc).filter_map(|(_, f)| *f));
                self.known_ranges[to] = Some(known);
            }
        }
    }

    /// [`Gen::block`]'s code; true if it checks the budget (one [`Gen::bail_if`]).
    fn block_code(&mut self, body_index: usize) -> bool {
        let index = self.leaders[body_index];
        let code = &self.program.code;
        let range = self.analysis.block(code, index);
        let start = range.start as u32;
        let len = range.len() as u32;
        self.b.switch_to_block(self.blocks[body_index]);
        let known_ranges = self.known_ranges[body_index].take();
        self.branch_facts = Default::default();
        if known_ranges.is_some() {
            // Its one predecessor has jumped to it and nothing else will: sealed now, the
            // values it uses are the very values of the block before it.
            self.b.seal_block(self.blocks[body_index]);
        }
        let mut depth = self.depth(start);
        // What it receives, before any way out (which writes back what it received unwritten).
        self.info.fill(SlotInfo::default());
        self.held.clear();
        for (place, elem) in self.carried[body_index].clone() {
            let var = self.carry_var((place, elem));
            let mut info = SlotInfo { boolean: elem == Elem::Bool, ..SlotInfo::default() };
            let value = if elem.is_float() {
                let f = self.b.use_var(var);
                info.float = Some(f);
                self.float_bits(elem, f)
            } else if elem == Elem::Bool {
                let x = self.b.use_var(var);
                self.b.ins().uextend(I64, x)
            } else {
                self.b.use_var(var)
            };
            let dirty = self.unwritten[body_index].contains(&(place, elem));
            self.held.push(Held { place, elem, value, info, dirty });
        }
        if !is_native(&code[range.start]) {
            let left = self.b.use_var(self.regs.left);
            self.exit(start, depth, left, RETURN_INTERPRET);
            return false;
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
        self.in_range = known_ranges.unwrap_or_default();
        self.passed_on.clear();
        let successors =
            if self.in_loop[body_index] { self.successors(body_index) } else { vec![] };
        for pc in successors {
            if let Some(to) = self.leader_index(pc) {
                for &key in &self.carried[to] {
                    if !self.passed_on.contains(&key) {
                        self.passed_on.push(key);
                    }
                }
            }
        }
        let charged = self.b.ins().iadd_imm_s(left, -i64::from(len));
        self.b.def_var(self.regs.left, charged);
        self.charged = Some((left, len, charged));
        let mut falls_through = true;
        for (index, pc) in range.clone().enumerate() {
            let at = At { pc: pc as u32, index: index as u32, len };
            falls_through = self.op(&code[pc], at, &mut depth);
        }
        if falls_through {
            let next = self.target(range.end as u32, depth);
            self.pass_on(range.end as u32);
            self.b.ins().jump(next, &[]);
        }
        checks
    }

    /// The variable that passes the value of `key` from block to block: a REAL's or an
    /// LREAL's as a float, a BOOL's as its 8-bit 0 or 1 ([`Gen::narrow`]), the others as a slot.
    fn carry_var(&mut self, key: Key) -> Variable {
        if let Some(&(_, var)) = self.carry_vars.iter().find(|(k, _)| *k == key) {
            return var;
        }
        let ty = match key.1 {
            elem if elem.is_float() => float_type(elem),
            Elem::Bool => types::I8,
            _ => I64,
        };
        let var = self.b.declare_var(ty);
        self.carry_vars.push((key, var));
        var
    }

    /// Before a jump to the block at `pc`: the values it receives, as held here, or from memory
    /// where this block does not hold them (memory always holds the same).
    fn pass_on(&mut self, pc: u32) {
        // A value not written yet goes on unwritten only to a block that receives it (it
        // counts what it receives as unwritten where a block before it may have stored it:
        // [`carry::unwritten`]); a way out to the interpreter wrote it back already
        // ([`Gen::target`]).
        if let Some(index) = self.leader_index(pc) {
            let unwanted: Vec<Key> = self.unreceived(index).iter().map(Held::key).collect();
            self.write_back_where(|key| unwanted.contains(&key));
        }
        self.define_carried(&[pc]);
    }

    /// The held values not written yet that the block of `leaders[index]` does not receive.
    fn unreceived(&self, index: usize) -> Vec<Held> {
        (self.held.iter())
            .filter(|h| h.dirty && !self.carried[index].contains(&h.key()))
            .copied()
            .collect()
    }

    /// The way to `block`, the block at `pc`, from a branch of several ways: directly, or
    /// through a new block that writes back the values not written yet that it does not
    /// receive (returned with them, for [`Gen::fill_edges`] once the branch is generated).
    fn edge(&mut self, pc: u32, block: Block) -> Edge {
        let Some(index) = self.leader_index(pc) else { return (block, None) };
        let unwanted = self.unreceived(index);
        if unwanted.is_empty() {
            return (block, None);
        }
        let edge = self.b.create_block();
        (edge, Some((block, unwanted)))
    }

    /// At a branch of two ways that ends a block whose budget nothing changed since its start,
    /// where one way leaves a loop the other goes on in ([`Gen::loop_exit`]): the way out gets
    /// its own block (in `edges`), which charges the block's length to the budget it came in
    /// with. The way on uses the charge made at the block's start, which Cranelift adds to the
    /// next block's into one; so the budget of the way out is computed on that way only, not on
    /// each round (a `lea` a round in `sort`'s insertion loop). Returns the budget that came in
    /// and the length, for [`Gen::fill_edges`].
    fn charge_on_edges(&mut self, edges: &mut [Edge; 2], out: usize) -> Option<(Value, u32)> {
        let (left, len, charged) = self.charged?;
        if self.b.use_var(self.regs.left) != charged {
            return None;
        }
        let edge = &mut edges[out];
        if edge.1.is_none() {
            let block = edge.0;
            edge.0 = self.b.create_block();
            edge.1 = Some((block, Vec::new()));
        }
        Some((left, len))
    }

    /// Of a branch at `pc` that jumps to `target`: true if the jump leaves a loop that going on
    /// to `pc + 1` stays in (a forward jump past a jump back to `pc` or before it: a `WHILE`'s
    /// or `FOR`'s test), false if going on leaves one the jump stays in (a jump back: `REPEAT`),
    /// `None` if neither.
    fn loop_exit(&self, pc: u32, target: u32) -> Option<bool> {
        if target <= pc {
            return Some(false);
        }
        let from = self.back_jumps.partition_point(|&(at, _)| at <= pc);
        let to = self.back_jumps.partition_point(|&(at, _)| at < target);
        self.back_jumps[from..to].iter().any(|&(_, back_to)| back_to <= pc).then_some(true)
    }

    /// The blocks [`Gen::edge`] made, after the branch that ends the current block; with
    /// `recharge`, each charges the budget ([`Gen::charge_on_edges`]).
    fn fill_edges(&mut self, edges: [Edge; 2], recharge: Option<(Value, u32)>) {
        for (edge, way) in edges {
            let Some((block, unwanted)) = way else { continue };
            self.b.switch_to_block(edge);
            if let Some((left, len)) = recharge {
                let charged = self.b.ins().iadd_imm_s(left, -i64::from(len));
                self.b.def_var(self.regs.left, charged);
            }
            for h in unwanted {
                self.write_back(h);
            }
            self.b.ins().jump(block, &[]);
        }
    }

    /// The carried variables of the blocks at `pcs` defined for a jump to them: the values
    /// held here, else loaded.
    fn define_carried(&mut self, pcs: &[u32]) {
        let mut keys: Vec<Key> = Vec::new();
        for &pc in pcs {
            if let Some(index) = self.leader_index(pc) {
                for &key in &self.carried[index] {
                    if !keys.contains(&key) {
                        keys.push(key);
                    }
                }
            }
        }
        for (place, elem) in keys {
            let held = self.held.iter().find(|h| h.place == place && h.elem == elem);
            let held = held.map(|h| (h.value, h.info.float));
            if held.is_none() && in_bytes(place) {
                self.write_back_overlapping(place, elem.size());
            }
            let value = match (held, self.byte_place(place)) {
                (Some((v, float)), _) if elem.is_float() => self.float_of(elem, v, float),
                (Some((v, _)), _) => v,
                (None, Some((address, offset))) if elem.is_float() => {
                    self.b.ins().load(float_type(elem), data(), address, offset)
                }
                (None, _) => self.load_place(place, elem),
            };
            // A held BOOL is 0 or 1 (a fetch gives it so).
            let value = match elem {
                Elem::Bool => match self.narrow(value) {
                    Some(x) => x,
                    None => self.b.ins().ireduce(types::I8, value),
                },
                _ => value,
            };
            let var = self.carry_var((place, elem));
            self.b.def_var(var, value);
        }
    }

    /// The address of `pointer` (a slot) in variable memory or the frame, and whether `bytes`
    /// from it are inside that space (an `i8` truth value).
    fn reach(&mut self, pointer: Value, bytes: u64) -> (Value, Value) {
        let space = self.b.ins().ushr_imm_s(pointer, 32);
        let offset = self.b.ins().band_imm_s(pointer, LOW32);
        let is_var = self.b.ins().icmp_imm_s(IntCC::Equal, space, Space::Var as i64);
        let is_frame = self.b.ins().icmp_imm_s(IntCC::Equal, space, Space::Frame as i64);
        let vars_len = self.field(code::CONTEXT.vars_len);
        let frame_len = self.field(code::CONTEXT.frame_len);
        let limit = self.b.ins().select(is_var, vars_len, frame_len);
        let vars = self.field(code::CONTEXT.vars);
        let frame = self.field(code::CONTEXT.frame);
        let start = self.b.ins().select(is_var, vars, frame);
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
    fn known_address(&mut self, index: u32, bytes: u32) -> Option<(Value, Reach)> {
        let reach = self.info[index as usize].known?;
        self.vars_need = self.vars_need.max(reach.most + u64::from(bytes));
        let pointer = self.slot(index);
        let vars = self.field(code::CONTEXT.vars);
        Some((self.b.ins().iadd(vars, pointer), reach))
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
                    self.write_back_overlapping(place, elem.size());
                    let f = self.b.ins().load(float_type(elem), data(), address, offset);
                    let v = self.float_bits(elem, f);
                    self.push(depth, v);
                    self.info[d as usize].float = Some(f);
                    self.hold(place, elem, v, self.info[d as usize]);
                } else {
                    if in_bytes(place) {
                        self.write_back_overlapping(place, elem.size());
                    }
                    let v = self.load_place(place, elem);
                    self.push(depth, v);
                    self.info[d as usize].boolean = elem == Elem::Bool;
                    self.hold(place, elem, v, self.info[d as usize]);
                }
            }
            Op::Store { elem, at: place } => {
                let v = self.slot(d - 1);
                let info = self.info[d as usize - 1];
                if in_bytes(place) {
                    // Held, written to memory where something else may read it
                    // ([`Gen::write_back`]); a value of the place not written yet is replaced.
                    self.held.retain(|h| (h.place, h.elem) != (place, elem));
                } else {
                    self.store_place(place, elem, v);
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
                    self.held.push(Held { place, elem, value, info, dirty: true });
                    // Kept in a register only when it goes on in one to a block after this one
                    // (a loop's variable): else written at once, which keeps no register busy.
                    if !self.passed_on.contains(&(place, elem)) {
                        self.write_back_where(|key| key == (place, elem));
                    }
                }
                *depth -= 1;
            }
            Op::AddrOf(place) => {
                let v = self.address_of(place);
                self.push(depth, v);
                match place {
                    Place::Var(offset) => self.info[d as usize].known = Some(Reach::at(offset)),
                    Place::Frame(offset) => self.info[d as usize].frame = Some(offset),
                    _ => {}
                }
            }
            Op::Index { lo, len, stride } => {
                let index = self.slot(d - 1);
                let pointer = self.slot(d - 2);
                let element = self.b.ins().iadd_imm_s(index, -i64::from(lo));
                // The same index into the same range again in this block, or in the one before
                // it that alone leads here: it passed.
                let passed = self.in_range.iter().any(|&(known, l, n)| {
                    (l, n) == (lo, len) && self.same_value(known, index, SAME_VALUE_DEPTH)
                });
                if !passed {
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
                // An element of an array at a fixed place: between its first and last.
                let known =
                    self.info[d as usize - 2].known.and_then(|reach| reach.element(len, stride));
                let moved = self.moved(pointer, step, known.is_some());
                *depth -= 1;
                self.set(d - 2, moved);
                self.info[d as usize - 2].known = known;
            }
            Op::Deref { size } => {
                // NULL raises its error here; a pointer that is not all inside variable memory
                // or the frame (a device, out of its area) goes to the interpreter, which
                // checks it the same way and raises the error when there is one.
                let reference = self.slot(d - 1);
                let null =
                    self.b.ins().icmp_imm_s(IntCC::UnsignedLessThan, reference, REF_TAG as i64);
                self.error_if(null, at, d, Pointer::DISCARD.to_slot() as i64, ERR_REF_NULL);
                let pointer = self.b.ins().iadd_imm_s(reference, -(REF_TAG as i64));
                let (_, ok) = self.reach(pointer, u64::from(size));
                let out = self.b.ins().bxor_imm_s(ok, 1);
                self.bail_if(out, at, d);
                self.set(d - 1, pointer);
            }
            Op::CheckRef(size) => {
                // Outside variable memory and the frame (the discard pointer included): the
                // interpreter's.
                let pointer = self.slot(d - 1);
                let (_, ok) = self.reach(pointer, u64::from(size));
                let out = self.b.ins().bxor_imm_s(ok, 1);
                self.bail_if(out, at, d);
            }
            Op::RefAdd => {
                // A pointer into device memory (its area numbered 3, 4 or 6, from 1) fails:
                // the interpreter's. Else the offset moves, wrapping within 32 bits.
                let n = self.slot(d - 1);
                let reference = self.slot(d - 2);
                let area = self.b.ins().ushr_imm_s(reference, 32);
                let device_from = (Space::Word as i64) + 1;
                let device = self.b.ins().iadd_imm_s(area, -device_from);
                let device = self.b.ins().icmp_imm_s(IntCC::UnsignedLessThan, device, 2);
                let byte = self.b.ins().icmp_imm_s(IntCC::Equal, area, Space::Byte as i64 + 1);
                let device = self.b.ins().bor(device, byte);
                self.bail_if(device, at, d);
                let moved = self.moved(reference, n, false);
                *depth -= 1;
                self.set(d - 2, moved);
            }
            Op::Offset(n) => {
                let pointer = self.slot(d - 1);
                let step = self.b.ins().iconst(I64, i64::from(n));
                let known = self.info[d as usize - 1].known.and_then(|reach| reach.member(n));
                let frame = self.info[d as usize - 1].frame.and_then(|o| o.checked_add(n));
                let moved = self.moved(pointer, step, known.is_some());
                self.set(d - 1, moved);
                self.info[d as usize - 1].known = known;
                self.info[d as usize - 1].frame = frame;
            }
            Op::FetchInd(elem) => {
                let (address, from) = self.address(d - 1, elem.size(), at, d);
                self.write_back_into(from, elem.size());
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
                self.forget_indirect(into, elem.size());
                if elem.is_float() && self.info[d as usize - 1].float.is_some() {
                    let f = self.float(elem, d - 1);
                    self.b.ins().store(data(), f, address, 0);
                } else {
                    self.store(elem, address, 0, v);
                }
                *depth -= 2;
            }
            Op::Copy(n) => {
                // Both ranges are checked before either is touched: the interpreter copies
                // nothing when one is outside its space.
                let (from, source) = self.address(d - 1, n, at, d);
                let (to, into) = self.address(d - 2, n, at, d);
                self.write_back_into(source, n);
                self.forget_indirect(into, n);
                self.copy(to, from, n);
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
                        let r = self.bool_logic(op, a, Some(b));
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
                    let r = self.bool_logic(BinOp::Xor, a, None);
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
                self.pass_on(target);
                self.b.ins().jump(block, &[]);
                return false;
            }
            Op::GotoIf { target, when } => {
                let c = self.slot(d - 1);
                *depth -= 1;
                let taken = self.target(target, d - 1);
                let next = self.target(at.pc + 1, d - 1);
                let (on_true, on_false) = if when { (taken, next) } else { (next, taken) };
                let c = self.narrow(c).unwrap_or(c);
                // What neither way receives is written back before the branch, what one way
                // does not on its way.
                let (a, b) = (self.leader_index(target), self.leader_index(at.pc + 1));
                if let (Some(a), Some(b)) = (a, b) {
                    let not_a: Vec<Key> = self.unreceived(a).iter().map(Held::key).collect();
                    let neither: Vec<Key> = (self.unreceived(b).iter().map(Held::key))
                        .filter(|key| not_a.contains(key))
                        .collect();
                    self.write_back_where(|key| neither.contains(&key));
                }
                self.define_carried(&[target, at.pc + 1]);
                let (true_pc, false_pc) =
                    if when { (target, at.pc + 1) } else { (at.pc + 1, target) };
                if true_pc != false_pc && at.index > 0 {
                    self.branch_facts = [true_pc, false_pc]
                        .map(|pc| (pc, self.branch_fact(at.pc, c, pc == true_pc)));
                }
                let mut edges = [self.edge(true_pc, on_true), self.edge(false_pc, on_false)];
                // Which of `edges` leaves a loop: the taken way is the true one if `when`.
                let recharge = self.loop_exit(at.pc, target).and_then(|taken_leaves| {
                    let out = usize::from(taken_leaves != when);
                    self.charge_on_edges(&mut edges, out)
                });
                self.b.ins().brif(c, edges[0].0, &[], edges[1].0, &[]);
                self.fill_edges(edges, recharge);
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
                // The caller may read any place.
                self.write_back_all();
                // Inline: on in the caller, right here.
                if let Some(inline) = &self.inline {
                    self.b.ins().jump(inline.back, &[]);
                    return false;
                }
                // To a native caller: it goes on after its call with its own registers; only
                // the budget changed.
                let to_vm = self.b.create_block();
                let to_caller = self.b.create_block();
                self.b.ins().brif(self.activation.called, to_caller, &[], to_vm, &[]);
                self.b.switch_to_block(to_caller);
                let left = self.b.use_var(self.regs.left);
                let regs = self.field(code::CONTEXT.regs);
                self.b.ins().store(own(), left, regs, reg(offset_of!(NativeRegs, left)));
                self.ret(RETURN_CONTINUE);
                // To the VM: the caller's frame popped, its registers to the context; its
                // function goes on at the return address, through the dispatch.
                self.b.switch_to_block(to_vm);
                let calls = self.activation.depth;
                let empty = self.b.ins().icmp_imm_s(IntCC::Equal, calls, 0);
                self.bail_if(empty, at, d);
                let depth = self.b.ins().iadd_imm_s(calls, -1);
                let frame = self.call_frame(depth);
                let pc = self.b.ins().uload32(own(), frame, offset_of!(StFrame, return_pc) as i32);
                let base = self.b.ins().uload32(own(), frame, offset_of!(StFrame, base) as i32);
                let this = self.b.ins().load(I64, own(), frame, offset_of!(StFrame, this) as i32);
                let sp = self.b.use_var(self.regs.sb);
                let left = self.b.use_var(self.regs.left);
                let frame = Some(FrameRegisters { base, this, depth });
                let _ = self.store_registers(Registers { pc, sp, left, frame });
                self.ret(RETURN_CONTINUE);
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
        let calls = self.field(code::CONTEXT.calls);
        self.b.ins().iadd(calls, offset)
    }

    /// A call of the body at `target`: its frame pushed as the interpreter pushes it and the
    /// caller's stack slots stored (where the interpreter finds them if the callee stops),
    /// then a call of the callee's function with its registers as parameters. When the callee
    /// returned (`RETURN_CONTINUE`), the caller goes on at the return address with its
    /// activation as it was (only the budget changed, in the context); any other result is
    /// passed on, with every register in the context where the callee stopped.
    fn call(&mut self, at: At, d: u32, target: u32, frame: u32, fb: bool) {
        // The callee may read any place.
        self.write_back_all();
        let calls = self.activation.depth;
        let full =
            self.b.ins().icmp_imm_s(IntCC::UnsignedGreaterThanOrEqual, calls, ST_CALL_DEPTH as i64);
        self.bail_if(full, at, d);
        let inline = self.plan.iter().position(|call| call.pc == at.pc);
        if inline.is_none() {
            // The machine stack: below the context's floor, the interpreter makes the call.
            let stack = self.b.ins().get_stack_pointer(I64);
            let floor = self.field(code::CONTEXT.stack_floor);
            let low = self.b.ins().icmp(IntCC::UnsignedLessThan, stack, floor);
            self.bail_if(low, at, d);
        }
        let Activation { base, this: old_this, .. } = self.activation;
        let (this, after) = if fb { (self.slot(d - 1), d - 1) } else { (old_this, d) };
        let callee_base = self.b.ins().iadd_imm_s(base, i64::from(frame));
        let callee_base = self.b.ins().band_imm_s(callee_base, LOW32);
        // An FB instance in an array at a fixed place (or a fixed one) needs no check at run
        // time: the code's need of variable memory covers it.
        let known = if fb { self.info[d as usize - 1].known } else { None };
        let this_end = self.analysis.bodies[&target].this_end;
        let (refused, this_at) = self.body_pointers(target, callee_base, this, known.is_some());
        if let Some(reach) = known.filter(|_| this_end > 0) {
            self.vars_need = self.vars_need.max(reach.most + this_end);
        }
        if let Some(refused) = refused {
            self.bail_if(refused, at, d);
        }
        // The caller's slots below the callee's: the callee numbers its own from 0. They stay
        // in the caller's variables too.
        let sb = self.b.use_var(self.regs.sb);
        let slots = (0..after).map(|slot| self.slot(slot)).collect();
        let record = CallRecord { calls, return_pc: at.pc + 1, base, this: old_this, sb, slots };
        let depth = self.b.ins().iadd_imm_s(calls, 1);
        let sp = self.b.ins().iadd_imm_s(sb, i64::from(after));
        if let Some(planned) = inline {
            let function = self.plan[planned].function;
            let frame_at = if self.analysis.bodies[&target].uses_frame {
                let frame = self.field(code::CONTEXT.frame);
                self.b.ins().iadd(frame, callee_base)
            } else {
                self.b.ins().iconst(I64, 0)
            };
            let pc = self.b.ins().iconst(I64, i64::from(target));
            let called = self.b.ins().iconst(I64, 1);
            let callee = Activation {
                pc,
                sp,
                depth,
                base: callee_base,
                this,
                frame_at,
                this_at,
                called,
                vm_only: false,
            };
            let this_in_vars = if fb { known.is_some() } else { self.this_in_vars };
            self.inline_call(function, target, callee, record, this_in_vars);
            // The caller goes on knowing what it knew, but what the callee may have changed.
            let writes = &self.plan[planned].writes;
            match writes.changes(|bytes| known.map(|reach| reach.store(bytes))) {
                Some(changes) => {
                    for (at, bytes) in changes {
                        self.forget(at, bytes);
                    }
                }
                None => self.held.clear(),
            }
        } else {
            self.store_record(&record);
            let left = self.b.use_var(self.regs.left);
            let callee = self.callee(target);
            let args = [self.context, callee_base, this, depth, sp, left, this_at];
            call_or_pass_on(&mut self.b, callee, &args, RETURN_CONTINUE);
            let regs = self.field(code::CONTEXT.regs);
            let left = self.b.ins().load(I64, own(), regs, reg(offset_of!(NativeRegs, left)));
            self.b.def_var(self.regs.left, left);
        }
        let next = self.target(at.pc + 1, after);
        if inline.is_none() {
            // The callee may have changed any place.
            self.held.clear();
        }
        self.pass_on(at.pc + 1);
        self.b.ins().jump(next, &[]);
    }

    /// Pushes the frame record of a call as the interpreter pushes it, and stores the caller's
    /// slots where the interpreter finds them if the callee stops.
    fn store_record(&mut self, record: &CallRecord) {
        let at = self.call_frame(record.calls);
        let return_pc = self.b.ins().iconst(types::I32, i64::from(record.return_pc));
        let base32 = self.b.ins().ireduce(types::I32, record.base);
        self.b.ins().store(own(), return_pc, at, offset_of!(StFrame, return_pc) as i32);
        self.b.ins().store(own(), base32, at, offset_of!(StFrame, base) as i32);
        self.b.ins().store(own(), record.this, at, offset_of!(StFrame, this) as i32);
        for (slot, &value) in record.slots.iter().enumerate() {
            let address = self.slot_address(record.sb, slot as u32);
            self.b.ins().store(own(), value, address, 0);
        }
    }

    /// The body of `function` (at `target`) generated here, for a call whose callee has the
    /// registers `callee` and would push `record`: its blocks run in this function with the
    /// callee's activation, leave it as the callee's own function would (the record written
    /// first), and return by a jump to the caller's next block.
    fn inline_call(
        &mut self,
        function: usize,
        target: u32,
        callee: Activation,
        record: CallRecord,
        this_in_vars: bool,
    ) {
        let back = self.b.create_block();
        let caller_sb = record.sb;
        let leaders = &self.analysis.function_leaders[function][..];
        let blocks = leaders.iter().map(|_| self.b.create_block()).collect();
        let stack = (0..self.stack.len()).map(|_| self.b.declare_var(I64)).collect();
        let jumps = carry::Jumps::of(self.program, self.analysis, leaders);
        let in_loop = carry::in_loops(&jumps);
        let carried = carry::carried(self.program, &jumps, &[], this_in_vars, &in_loop);
        let unwritten = carry::unwritten(self.program, &jumps, &carried, &in_loop);
        let mut scope = Scope {
            body: target,
            activation: callee,
            leaders,
            blocks,
            carried,
            carry_vars: Vec::new(),
            unwritten,
            in_loop,
            this_in_vars,
            stack,
            info: vec![SlotInfo::default(); self.info.len()],
            held: Vec::new(),
            known_ranges: vec![None; leaders.len()],
        };
        self.swap_scope(&mut scope);
        self.inline = Some(Inline { back, record });
        self.b.def_var(self.regs.sb, callee.sp);
        self.pass_on(target);
        let first = self.leader_index(target).expect("a body starts a block");
        self.b.ins().jump(self.blocks[first], &[]);
        for index in 0..self.leaders.len() {
            self.block(index);
        }
        self.inline = None;
        self.swap_scope(&mut scope);
        self.b.switch_to_block(back);
        self.b.def_var(self.regs.sb, caller_sb);
    }

    /// Exchanges the activation's scope the code is generated in with `scope`.
    fn swap_scope(&mut self, scope: &mut Scope<'a>) {
        std::mem::swap(&mut self.body, &mut scope.body);
        std::mem::swap(&mut self.activation, &mut scope.activation);
        std::mem::swap(&mut self.leaders, &mut scope.leaders);
        std::mem::swap(&mut self.blocks, &mut scope.blocks);
        std::mem::swap(&mut self.carried, &mut scope.carried);
        std::mem::swap(&mut self.carry_vars, &mut scope.carry_vars);
        std::mem::swap(&mut self.unwritten, &mut scope.unwritten);
        std::mem::swap(&mut self.in_loop, &mut scope.in_loop);
        std::mem::swap(&mut self.this_in_vars, &mut scope.this_in_vars);
        std::mem::swap(&mut self.stack, &mut scope.stack);
        std::mem::swap(&mut self.info, &mut scope.info);
        std::mem::swap(&mut self.held, &mut scope.held);
        std::mem::swap(&mut self.known_ranges, &mut scope.known_ranges);
    }

    /// The function of the body at `target`, imported into this one.
    fn callee(&mut self, target: u32) -> FuncRef {
        if let Some(&(_, callee)) = self.callees.iter().find(|(at, _)| *at == target) {
            return callee;
        }
        let function = self.analysis.functions.binary_search(&target).expect("a body's start");
        let callee = import_function(&mut self.b, self.names[function], self.body_sig);
        self.callees.push((target, callee));
        callee
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
                let base = self.activation.base;
                let offset = self.b.ins().iadd_imm_s(base, i64::from(offset));
                let offset = self.b.ins().band_imm_s(offset, LOW32);
                self.b.ins().bor_imm_s(offset, slot(Space::Frame, 0))
            }
            Place::This(offset) => {
                let this = self.activation.this;
                let n = self.b.ins().iconst(I64, i64::from(offset));
                self.moved(this, n, false)
            }
            Place::Word(w) => self.b.ins().iconst(I64, slot(Space::Word, u32::from(w.0))),
            Place::Bit(b) => {
                let bit = b.mask.trailing_zeros().min(15);
                self.b.ins().iconst(I64, slot(Space::Bit, u32::from(b.word) * 16 + bit))
            }
            Place::Byte(n) => self.b.ins().iconst(I64, slot(Space::Byte, n)),
        }
    }

    /// The address of `bytes` bytes at the pointer in slot `index`, and where it points: without
    /// a check at run time for a known pointer into variable memory, or into the frame inside
    /// what the body's entry checked; else after [`Gen::checked_address`]'s check.
    fn address(&mut self, index: u32, bytes: u32, at: At, depth: u32) -> (Value, Into) {
        if let Some((address, reach)) = self.known_address(index, bytes) {
            return (address, Into::Vars(reach));
        }
        if let Some(offset) = self.info[index as usize].frame {
            let end = u64::from(offset) + u64::from(bytes);
            if end > self.analysis.bodies[&self.body].frame_end {
                let base = self.activation.base;
                let end = self.b.ins().iadd_imm_s(base, end as i64);
                let frame_len = self.field(code::CONTEXT.frame_len);
                let out = self.b.ins().icmp(IntCC::UnsignedGreaterThan, end, frame_len);
                self.bail_if(out, at, depth);
            }
            let frame_at = self.activation.frame_at;
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
            Place::Var(offset) => Some((self.field(code::CONTEXT.vars), offset as i32)),
            Place::Frame(offset) => Some((self.activation.frame_at, offset as i32)),
            Place::This(offset) => Some((self.activation.this_at, offset as i32)),
            Place::Word(_) | Place::Bit(_) | Place::Byte(_) => None,
        }
    }

    fn load_place(&mut self, place: Place, elem: Elem) -> Value {
        if let (Place::Var(offset), Elem::Bool, true) =
            (place, elem, self.program.var_bools_canonical)
        {
            // 0 or 1 already: the compiler proved that no code writes another type over it,
            // and the engine rewrites it after copying bytes in (`Program::var_bools_canonical`)
            let vars = self.field(code::CONTEXT.vars);
            return self.b.ins().uload8(I64, data(), vars, offset as i32);
        }
        if let Some((address, offset)) = self.byte_place(place) {
            return self.load(elem, address, offset);
        }
        match place {
            Place::Word(w) => {
                let offset = i32::from(w.0) * 2;
                let words = self.field(code::CONTEXT.words);
                let raw = match elem.words() {
                    1 => self.b.ins().uload16(I64, data(), words, offset),
                    2 => self.b.ins().uload32(data(), words, offset),
                    _ => self.b.ins().load(I64, data(), words, offset),
                };
                self.normalize(elem, raw)
            }
            Place::Bit(b) => {
                let bit = b.mask.trailing_zeros().min(15);
                let words = self.field(code::CONTEXT.words);
                let word = self.b.ins().uload16(I64, data(), words, i32::from(b.word) * 2);
                let shifted = self.b.ins().ushr_imm_s(word, i64::from(bit));
                self.b.ins().band_imm_s(shifted, 1)
            }
            Place::Byte(n) => {
                // the word's half, as the interpreter reads it (whatever the host's byte order)
                let words = self.field(code::CONTEXT.words);
                let word = self.b.ins().uload16(I64, data(), words, (n / 2) as i32 * 2);
                let shifted = self.b.ins().ushr_imm_s(word, i64::from(8 * (n % 2)));
                let byte = self.b.ins().band_imm_s(shifted, 0xFF);
                self.normalize(elem, byte)
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
                let words = self.field(code::CONTEXT.words);
                match elem.words() {
                    1 => self.b.ins().istore16(data(), v, words, offset),
                    2 => self.b.ins().istore32(data(), v, words, offset),
                    _ => self.b.ins().store(data(), v, words, offset),
                };
            }
            Place::Bit(b) => {
                let bit = b.mask.trailing_zeros().min(15);
                let mask = 1i64 << bit;
                let offset = i32::from(b.word) * 2;
                let words = self.field(code::CONTEXT.words);
                let word = self.b.ins().uload16(I64, data(), words, offset);
                let set = self.b.ins().bor_imm_s(word, mask);
                let cleared = self.b.ins().band_imm_s(word, !mask);
                let on = self.b.ins().icmp_imm_s(IntCC::NotEqual, v, 0);
                let word = self.b.ins().select(on, set, cleared);
                self.b.ins().istore16(data(), word, words, offset);
            }
            Place::Byte(n) => {
                // the low 8 bits of the value into the word's half, the other half kept
                let shift = i64::from(8 * (n % 2));
                let offset = (n / 2) as i32 * 2;
                let words = self.field(code::CONTEXT.words);
                let word = self.b.ins().uload16(I64, data(), words, offset);
                let kept = self.b.ins().band_imm_s(word, !(0xFF << shift));
                let byte = self.b.ins().band_imm_s(v, 0xFF);
                let byte = self.b.ins().ishl_imm_s(byte, shift);
                let word = self.b.ins().bor(kept, byte);
                self.b.ins().istore16(data(), word, words, offset);
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

    /// BOOL `And`, `Or` or `Xor` of the 0s and 1s `a` and `b` (`None`: 1, so that `Xor` is a
    /// NOT): on the 8-bit values behind both when they have them (`narrow`), extended once.
    fn bool_logic(&mut self, op: BinOp, a: Value, b: Option<Value>) -> Value {
        let narrowed = match b {
            Some(b) => self.narrow(a).zip(self.narrow(b)).map(|(x, y)| (x, Some(y))),
            None => self.narrow(a).map(|x| (x, None)),
        };
        let (x, y) = narrowed.unwrap_or((a, b));
        let r = match (op, y) {
            (_, None) => self.b.ins().bxor_imm_s(x, 1),
            (BinOp::And, Some(y)) => self.b.ins().band(x, y),
            (BinOp::Or, Some(y)) => self.b.ins().bor(x, y),
            (_, Some(y)) => self.b.ins().bxor(x, y),
        };
        match narrowed {
            Some(_) => self.b.ins().uextend(I64, r),
            None => r,
        }
    }

    /// The 8-bit value `v` is the zero extension of, if it is one (a BOOL fetched, a
    /// comparison, logic on them): where `v` is a BOOL's 0 or 1, so is it, and BOOL logic done
    /// on it and extended once is shorter code than on the extensions (Cranelift does not
    /// narrow through `bxor` itself).
    fn narrow(&self, v: Value) -> Option<Value> {
        let ValueDef::Result(inst, _) = self.b.func.dfg.value_def(v) else { return None };
        match self.b.func.dfg.insts[inst] {
            InstructionData::Unary { opcode: Opcode::Uextend, arg }
                if self.b.func.dfg.value_type(arg) == types::I8 =>
            {
                Some(arg)
            }
            _ => None,
        }
    }

    /// True if `a` and `b` are the same value: one value, or the results of the same pure
    /// instruction on the same values (constants included), looked into `depth` deep. The
    /// code of a block recomputes what the block before computed (`j - 1` in both), which
    /// Cranelift merges later; a range check needs to know it now.
    fn same_value(&self, a: Value, b: Value, depth: u32) -> bool {
        let dfg = &self.b.func.dfg;
        let (a, b) = (dfg.resolve_aliases(a), dfg.resolve_aliases(b));
        if a == b {
            return true;
        }
        if depth == 0 || dfg.value_type(a) != dfg.value_type(b) {
            return false;
        }
        let (ValueDef::Result(x, 0), ValueDef::Result(y, 0)) = (dfg.value_def(a), dfg.value_def(b))
        else {
            return false;
        };
        let same_args = |p: &[Value], q: &[Value]| {
            p.len() == q.len() && p.iter().zip(q).all(|(&p, &q)| self.same_value(p, q, depth - 1))
        };
        match (dfg.insts[x], dfg.insts[y]) {
            (
                InstructionData::UnaryImm { opcode: o, imm: i },
                InstructionData::UnaryImm { opcode: p, imm: j },
            ) => o == p && i == j,
            (
                InstructionData::Unary { opcode: o, arg: a },
                InstructionData::Unary { opcode: p, arg: b },
            ) => o == p && pure(o) && same_args(&[a], &[b]),
            (
                InstructionData::Binary { opcode: o, args: a },
                InstructionData::Binary { opcode: p, args: b },
            ) => o == p && pure(o) && same_args(&a, &b),
            _ => false,
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
        if self.fits(elem, raw) {
            return raw;
        }
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
        let v = self.slot(index);
        self.float_of(elem, v, self.info[index as usize].float)
    }

    /// The float of `elem` whose bits are `v`: `float`, the value it was computed as, when it
    /// is one of that type, else the bits moved.
    fn float_of(&mut self, elem: Elem, v: Value, float: Option<Value>) -> Value {
        match float {
            Some(f) if self.b.func.dfg.value_type(f) == float_type(elem) => f,
            _ => self.as_float(elem, v),
        }
    }

    /// Records that fixed place `place` holds `value` (with `info`) as a fetch of `elem` from
    /// it would give it now. Device memory is not held: the places overlap in ways a `Word` and
    /// a `Bit` do not show.
    fn hold(&mut self, place: Place, elem: Elem, value: Value, info: SlotInfo) {
        if in_bytes(place) {
            self.held.push(Held { place, elem, value, info, dirty: false });
        }
    }

    /// Forgets the held values a store of `bytes` bytes at fixed place `at` may change, after
    /// writing back those not written yet (so that the store, emitted after, has the last word).
    fn forget(&mut self, at: Place, bytes: u32) {
        self.write_back_overlapping(at, bytes);
        let this_in_vars = self.this_in_vars;
        self.held.retain(|h| !carry::may_change(at, bytes, (h.place, h.elem), this_in_vars));
    }

    /// Forgets the held values a store of `bytes` bytes through a pointer to `into` may change,
    /// as [`Gen::forget`]: called before the store.
    fn forget_indirect(&mut self, into: Into, bytes: u32) {
        match into {
            Into::Vars(reach) => {
                let (at, bytes) = reach.store(bytes);
                self.forget(at, bytes);
            }
            Into::Frame(offset) => self.forget(Place::Frame(offset), bytes),
            Into::Unknown => {
                self.write_back_all();
                self.held.clear();
            }
        }
    }

    /// Writes the held value `h` to its place (a store of the code that was kept in a register
    /// until something else could read the place).
    fn write_back(&mut self, h: Held) {
        let (address, offset) = self.byte_place(h.place).expect("held places are in bytes");
        match h.elem {
            // 0 or 1 (held so).
            Elem::Bool => {
                match self.narrow(h.value) {
                    Some(x) => self.b.ins().store(data(), x, address, offset),
                    None => self.b.ins().istore8(data(), h.value, address, offset),
                };
            }
            elem if elem.is_float() && h.info.float.is_some() => {
                let f = self.float_of(elem, h.value, h.info.float);
                self.b.ins().store(data(), f, address, offset);
            }
            elem => self.store(elem, address, offset, h.value),
        }
    }

    /// Writes back every held value not written yet, and counts them written: before what may
    /// read any place (a call), on the way that goes on.
    fn write_back_all(&mut self) {
        self.write_back_where(|_| true);
    }

    /// As [`Gen::write_back_all`] for the held values a load or a store of `bytes` bytes at
    /// `at` may overlap.
    fn write_back_overlapping(&mut self, at: Place, bytes: u32) {
        let this_in_vars = self.this_in_vars;
        self.write_back_where(|key| carry::may_change(at, bytes, key, this_in_vars));
    }

    /// As [`Gen::write_back_overlapping`] for `bytes` bytes through a pointer to `into`.
    fn write_back_into(&mut self, into: Into, bytes: u32) {
        match into {
            Into::Vars(reach) => {
                let (at, bytes) = reach.store(bytes);
                self.write_back_overlapping(at, bytes);
            }
            Into::Frame(offset) => self.write_back_overlapping(Place::Frame(offset), bytes),
            Into::Unknown => self.write_back_all(),
        }
    }

    fn write_back_where(&mut self, select: impl Fn(Key) -> bool) {
        for i in 0..self.held.len() {
            let h = self.held[i];
            if h.dirty && select((h.place, h.elem)) {
                self.write_back(h);
                self.held[i].dirty = false;
            }
        }
    }

    /// On a way out of native code (a cold branch): writes back every held value not written
    /// yet, and leaves them counted unwritten for the way that goes on.
    fn write_back_leaving(&mut self) {
        for i in 0..self.held.len() {
            let h = self.held[i];
            if h.dirty {
                self.write_back(h);
            }
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

    /// True if the slot `v` already holds a value of `elem`'s range, as cutting it to `elem`
    /// would give it: it lies in a range this block knows, or it is such a value plus or minus
    /// a constant that keeps it inside (`j - 1` after `WHILE j > 0`: [`Gen::branch_fact`]).
    fn fits(&self, elem: Elem, v: Value) -> bool {
        let Some((min, max)) = small_int_bounds(elem) else { return false };
        let inside = |v: Value, c: i64| {
            self.in_range.iter().any(|&(known, lo, len)| {
                let (lo, hi) = (i64::from(lo), i64::from(lo) + i64::from(len) - 1);
                len > 0 && lo + c >= min && hi + c <= max && self.same_value(known, v, 1)
            })
        };
        if inside(v, 0) {
            return true;
        }
        let dfg = &self.b.func.dfg;
        let ValueDef::Result(inst, 0) = dfg.value_def(dfg.resolve_aliases(v)) else { return false };
        let InstructionData::Binary { opcode, args: [a, b] } = dfg.insts[inst] else {
            return false;
        };
        let c = match (opcode, self.constant(b)) {
            (Opcode::Iadd, Some(c)) if c.unsigned_abs() <= u64::from(u32::MAX) => c,
            (Opcode::Isub, Some(c)) if c.unsigned_abs() <= u64::from(u32::MAX) => -c,
            _ => return false,
        };
        inside(a, c)
    }

    /// The value of `v` if it is an integer constant.
    fn constant(&self, v: Value) -> Option<i64> {
        let dfg = &self.b.func.dfg;
        let ValueDef::Result(inst, 0) = dfg.value_def(dfg.resolve_aliases(v)) else { return None };
        match dfg.insts[inst] {
            InstructionData::UnaryImm { opcode: Opcode::Iconst, imm } => Some(imm.bits()),
            _ => None,
        }
    }

    /// Of a branch on the comparison `x op k` of an integer `x` with a constant `k` just before
    /// it (at `pc - 1`): the range `x` lies in on the way where the comparison holds (`holds`)
    /// or the other, as an [`InRange`], when `x`'s type is one [`small_int_bounds`] knows.
    fn branch_fact(&self, pc: u32, c: Value, holds: bool) -> Option<InRange> {
        let Op::Cmp { op, elem } = *self.program.code.get(pc.checked_sub(1)? as usize)? else {
            return None;
        };
        let (min, max) = small_int_bounds(elem)?;
        let dfg = &self.b.func.dfg;
        // `c` as the branch takes it: the comparison's 8-bit result ([`Gen::narrow`]).
        let cmp = self.narrow(c).unwrap_or(c);
        let ValueDef::Result(inst, 0) = dfg.value_def(cmp) else { return None };
        let InstructionData::IntCompare { args: [x, k], .. } = dfg.insts[inst] else {
            return None;
        };
        let k = self.constant(k)?;
        // The comparison as it holds on this way.
        let op = if holds {
            op
        } else {
            match op {
                CmpOp::Lt => CmpOp::Ge,
                CmpOp::Le => CmpOp::Gt,
                CmpOp::Gt => CmpOp::Le,
                CmpOp::Ge => CmpOp::Lt,
                CmpOp::Eq | CmpOp::Ne => return None,
            }
        };
        let (lo, hi) = match op {
            CmpOp::Gt => (k.checked_add(1)?, max),
            CmpOp::Ge => (k, max),
            CmpOp::Lt => (min, k.checked_sub(1)?),
            CmpOp::Le => (min, k),
            CmpOp::Eq | CmpOp::Ne => return None,
        };
        let (lo, hi) = (lo.max(min), hi.min(max));
        let lo32 = i32::try_from(lo).ok()?;
        let len = u32::try_from(hi.checked_sub(lo)?.checked_add(1)?).ok()?;
        Some((x, lo32, len))
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

/// The Cranelift type of a REAL (`F32`) or LREAL.
fn float_type(elem: Elem) -> Type {
    if elem == Elem::F32 {
        types::F32
    } else {
        types::F64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analysed_test_program;
    use cranelift_codegen::settings::{self, Configurable};

    /// The PROGRAM of `source`'s body as generated: what it loads from the registers in the
    /// context and what it stores there, as (is a store, offset in `NativeRegs`).
    fn register_accesses(source: &str) -> Vec<(bool, usize)> {
        let (program, analysis) = analysed_test_program("codegen.st", source);
        let roles = analysis.block_roles(&program.code);
        let mut flags = settings::builder();
        flags.set("opt_level", "speed").expect("a flag");
        let isa = cranelift_native::builder()
            .expect("a host ISA")
            .finish(settings::Flags::new(flags))
            .expect("an ISA");
        let names: Vec<u32> = (0..analysis.functions.len() as u32).collect();
        let function = (analysis.functions.iter())
            .position(|body| analysis.bodies[body].return_sites.is_empty())
            .expect("the program's body");
        let mut func = Function::new();
        generate(&program, &analysis, &roles, function, &names, &*isa, &mut func);
        let insts: Vec<_> =
            func.layout.blocks().flat_map(|block| func.layout.block_insts(block)).collect();
        let context = func.dfg.block_params(func.layout.entry_block().expect("an entry"))[0];
        let regs = insts
            .iter()
            .find_map(|&inst| match func.dfg.insts[inst] {
                InstructionData::Load { arg, offset, .. }
                    if arg == context && i32::from(offset) == code::CONTEXT.regs as i32 =>
                {
                    Some(func.dfg.first_result(inst))
                }
                _ => None,
            })
            .expect("the registers' address");
        let regs = func.dfg.resolve_aliases(regs);
        let mut accesses: Vec<(bool, usize)> = (insts.iter())
            .filter_map(|&inst| {
                let (store, address, offset) = match func.dfg.insts[inst] {
                    InstructionData::Load { arg, offset, .. } => (false, arg, offset),
                    InstructionData::Store { args, offset, .. } => (true, args[1], offset),
                    _ => return None,
                };
                let at = func.dfg.resolve_aliases(address) == regs;
                at.then(|| (store, i32::from(offset) as usize))
            })
            .collect();
        accesses.sort_unstable();
        accesses.dedup();
        accesses
    }

    const SP: usize = offset_of!(NativeRegs, sp);

    #[test]
    fn a_program_without_calls_neither_loads_nor_stores_sp_nor_loads_its_frame_and_instance() {
        let accesses = register_accesses(
            "PROGRAM Main VAR a, b : BOOL; n : INT; END_VAR
             n := n + 1; IF a THEN b := NOT b; END_IF; END_PROGRAM",
        );
        for field in [SP, offset_of!(NativeRegs, base), offset_of!(NativeRegs, this)] {
            assert!(!accesses.iter().any(|&(_, at)| at == field), "{field}: {accesses:?}");
        }
        // The pc and the budget, loaded and stored.
        for field in [offset_of!(NativeRegs, pc), offset_of!(NativeRegs, left)] {
            assert!(accesses.contains(&(false, field)) && accesses.contains(&(true, field)));
        }
    }

    #[test]
    fn a_program_that_makes_a_machine_call_stores_sp() {
        // (`f` calls `g`: it is not inlined.)
        let accesses = register_accesses(
            "FUNCTION g : INT VAR_INPUT x : INT; END_VAR g := x * 2; END_FUNCTION
             FUNCTION f : INT VAR_INPUT x : INT; END_VAR f := g(x) + 1; END_FUNCTION
             PROGRAM Main VAR n : INT; END_VAR n := f(n); END_PROGRAM",
        );
        assert!(accesses.contains(&(false, SP)) && accesses.contains(&(true, SP)), "{accesses:?}");
    }
}
