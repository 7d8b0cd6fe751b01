//! The hook for native code of a [`Program`](super::Program): machine code that a code
//! generator outside the core (the `plcd-native` crate) compiled from a Structured Text or an
//! instruction-list program, run by [`Vm::run`] in place of the interpreter wherever it can.
//!
//! The interpreter stays the definition of what a program does. Native code is an
//! accelerator of it with the same observable behaviour to the step: it charges the step
//! budget the instructions it executes, stops where the interpreter would (at `END`, after an
//! operation error, when the budget is spent), and leaves the activation ([`ExecState`]) and
//! memory exactly as the interpreter would have. Whatever it cannot do exactly — an
//! instruction it has no code for, a budget that ends inside one of its blocks, a pointer
//! outside the spaces it reaches directly — it hands back with [`NativeExit::Interpret`], and
//! [`Vm::run`] lets the interpreter execute the next few instructions (at most
//! [`NativeCode::interpret_span`]) before native code takes over again. So every program runs
//! with native code attached or not, and the task engine, the debugger, the trace and the
//! simulator cannot tell the difference except by the time it takes.
//!
//! [`Vm::run`]: crate::vm::Vm::run
//! [`ExecState`]: crate::vm::ExecState

use super::{CALL_DEPTH, EVAL_DEPTH, ST_CALL_DEPTH};
use std::marker::PhantomData;

use crate::clock::Clock;

/// A Structured Text call: where to return, and the caller's frame base and FB instance.
/// `repr(C)`: native code pushes and pops these as the interpreter does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[repr(C)]
pub struct StFrame {
    pub return_pc: u32,
    pub base: u32,
    pub this: u64,
}

/// An instruction-list `CALL`: where to return, and the caller's rung registers and loop
/// depth, restored at `RET`. `repr(C)`: native code pushes and pops these as the interpreter
/// does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[repr(C)]
pub struct IlFrame {
    pub return_pc: u32,
    pub blocks: u32,
    pub branches: u32,
    /// The rung result (a byte, 0 or 1).
    pub rung: bool,
    pub loop_depth: u8,
}

/// An activation's registers as native code reads and writes them: the [`ExecState`] keeps
/// them so, and [`Vm::run`] passes them to native code in place.
///
/// The activation's registers come first, those a program starts with at zero together; then
/// a run's own (`left`, `sp`, `error`), which a run sets before it reads them, so that
/// [`ExecState::restart`] writes only the first 40 bytes.
///
/// [`Vm::run`]: crate::vm::Vm::run
/// [`ExecState`]: crate::vm::ExecState
/// [`ExecState::restart`]: crate::vm::ExecState::restart
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct NativeRegs {
    /// The next instruction: where native code starts, and where it stopped.
    pub pc: u32,
    /// Structured Text calls under way (entries of the call stack,
    /// [`NativeMemoryOffsets::calls`]).
    pub st_depth: u32,
    /// The current frame's base, a byte offset into the frame area
    /// ([`NativeMemoryOffsets::frame`]).
    pub base: u32,
    /// Instruction-list calls under way (entries of [`IlMemory::calls`]).
    pub il_depth: u32,
    /// The instruction list's block stack (`AND LOAD`/`OR LOAD`), one bit a level, top in bit 0.
    pub blocks: u32,
    /// The instruction list's `MPUSH` stack, one bit a level, top in bit 0.
    pub branches: u32,
    /// Instruction-list `FOR` loops under way (a `CALL` keeps it, `RET` restores it).
    pub loop_depth: u32,
    /// The instruction list's rung result: 0 or 1.
    pub rung: u32,
    /// The current FB instance (a [`crate::value::Pointer`] slot).
    pub this: u64,
    /// Instructions left in the step budget.
    pub left: u64,
    /// The evaluation stack's next free slot (an index into the ring,
    /// [`NativeMemoryOffsets::eval`]).
    pub sp: u64,
    /// The operation error's code, when native code returns [`NativeExit::OperationError`].
    pub error: u32,
}

/// The memory native code works on, borrowed for one call, as the raw parts its code reads at
/// fixed offsets ([`NativeMemory::OFFSETS`]): `repr(C)`, built once by the VM for each call of
/// [`NativeCode::run`] and handed to the code in place (no copy of it into another layout).
///
/// The memory's addresses and lengths are private: a `NativeMemory` holds only slices
/// [`NativeMemory::new`] borrowed for its lifetime, which the code may rely on. The public
/// fields are native code's own: [`NativeCode::run`] sets those its code reads before it enters
/// it (`il` stays the null `new` puts there for code that does not read it), and nothing reads
/// what they held before.
///
/// No two fields that are neighbours in the slices they come from are neighbours here (an
/// address and its length): a compiler copying such a pair with one 16-byte load of what was
/// just written 8 bytes at a time makes the processor stall (measured, when native code copied
/// the memory into a layout of its own).
#[repr(C)]
#[derive(Debug)]
pub struct NativeMemory<'a> {
    /// The activation's registers: [`NativeCode::run`] points this at its `regs`.
    pub regs: *mut NativeRegs,
    vars: *mut u8,
    eval: *mut u64,
    words: *mut u16,
    calls: *mut StFrame,
    frame: *mut u8,
    vars_len: u64,
    words_len: u64,
    frame_len: u64,
    /// What instruction-list code reads its state from, set by [`NativeCode::run`] (null, as
    /// [`NativeMemory::new`] leaves it, for Structured Text).
    pub il: *const u8,
    /// The lowest machine stack address a Structured Text call of native code may start from,
    /// set by [`NativeCode::run`].
    pub stack_floor: u64,
    borrow: PhantomData<&'a mut [u8]>,
}

/// The byte offsets of [`NativeMemory`]'s fields, where native code reads them.
#[derive(Debug, Clone, Copy)]
pub struct NativeMemoryOffsets {
    pub regs: usize,
    /// Variable memory (program instances and globals): its address and length in bytes.
    pub vars: usize,
    pub vars_len: usize,
    /// The evaluation stack, a ring of [`EVAL_DEPTH`] slots indexed modulo its length.
    pub eval: usize,
    /// Device memory's words: the address and the length in words.
    pub words: usize,
    pub words_len: usize,
    /// The Structured Text call stack, [`ST_CALL_DEPTH`] entries.
    pub calls: usize,
    /// The activation's frame area: the address and the length in bytes.
    pub frame: usize,
    pub frame_len: usize,
    pub il: usize,
    pub stack_floor: usize,
}

impl<'a> NativeMemory<'a> {
    /// Where native code reads each field.
    pub const OFFSETS: NativeMemoryOffsets = NativeMemoryOffsets {
        regs: std::mem::offset_of!(NativeMemory<'static>, regs),
        vars: std::mem::offset_of!(NativeMemory<'static>, vars),
        vars_len: std::mem::offset_of!(NativeMemory<'static>, vars_len),
        eval: std::mem::offset_of!(NativeMemory<'static>, eval),
        words: std::mem::offset_of!(NativeMemory<'static>, words),
        words_len: std::mem::offset_of!(NativeMemory<'static>, words_len),
        calls: std::mem::offset_of!(NativeMemory<'static>, calls),
        frame: std::mem::offset_of!(NativeMemory<'static>, frame),
        frame_len: std::mem::offset_of!(NativeMemory<'static>, frame_len),
        il: std::mem::offset_of!(NativeMemory<'static>, il),
        stack_floor: std::mem::offset_of!(NativeMemory<'static>, stack_floor),
    };

    /// Variable memory, device memory's words, the activation's frame area, its evaluation
    /// stack and its Structured Text call stack, borrowed for the call.
    #[inline]
    pub fn new(
        vars: &'a mut [u8],
        words: &'a mut [u16],
        frame: &'a mut [u8],
        eval: &'a mut [u64; EVAL_DEPTH],
        calls: &'a mut [StFrame; ST_CALL_DEPTH],
    ) -> NativeMemory<'a> {
        NativeMemory {
            regs: std::ptr::null_mut(),
            vars: vars.as_mut_ptr(),
            eval: eval.as_mut_ptr(),
            words: words.as_mut_ptr(),
            calls: calls.as_mut_ptr(),
            frame: frame.as_mut_ptr(),
            vars_len: vars.len() as u64,
            words_len: words.len() as u64,
            frame_len: frame.len() as u64,
            il: std::ptr::null(),
            stack_floor: 0,
            borrow: PhantomData,
        }
    }

    /// Bytes of variable memory.
    pub fn vars_len(&self) -> u64 {
        self.vars_len
    }

    /// Device memory's words.
    pub fn words_len(&self) -> u64 {
        self.words_len
    }

    /// Bytes of frame area.
    pub fn frame_len(&self) -> u64 {
        self.frame_len
    }
}

/// The instruction list's state besides device memory, borrowed for one call.
pub struct IlMemory<'a> {
    /// The call stack.
    pub calls: &'a mut [IlFrame; CALL_DEPTH],
    /// Edge memory (`LOADP`, `OUTP`, `FF`, the `P` forms).
    pub edges: &'a mut [bool],
    /// The counters, which native code executes itself: the VM's
    /// `vm::counter::CounterState`s, laid out as `vm::counter::layout` says.
    pub counters: RawSlice<'a>,
    /// The timers, which native code executes itself: the VM's
    /// `vm::timer::TimerState`s, laid out as `vm::timer::layout` says.
    pub timers: RawSlice<'a>,
    /// The time: a timer reads it at its own step, `stop - left` with `left` the budget left
    /// after the timer's instruction (as [`Vm::run`](crate::vm::Vm::run) counts steps).
    pub clock: &'a dyn Clock,
    /// The step count at which the budget is spent.
    pub stop: u64,
}

/// A slice mutably borrowed for one call of native code, as its address and length: for the
/// VM's state machines, whose types belong to the VM (a higher layer than this hook), and
/// whose layout native code reads from the VM's `layout` modules.
#[derive(Debug)]
pub struct RawSlice<'a> {
    address: *mut u8,
    len: usize,
    borrow: PhantomData<&'a mut [u8]>,
}

impl<'a> RawSlice<'a> {
    pub fn new<T>(slice: &'a mut [T]) -> RawSlice<'a> {
        RawSlice { address: slice.as_mut_ptr().cast(), len: slice.len(), borrow: PhantomData }
    }

    /// The first element's address.
    pub fn address(&self) -> *mut u8 {
        self.address
    }

    /// Elements, not bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Why native code returned. The discriminants are fixed: a code generator may number its
/// functions' returns alike, and map one to the other by the number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum NativeExit {
    /// It executed `END`.
    End = 0,
    /// The interpreter is to execute the instruction at `pc` (and at most
    /// [`NativeCode::interpret_span`] of them), or the budget is spent (`left` is 0).
    Interpret,
    /// An operation error (its code in [`NativeRegs::error`]); `pc` is after the instruction
    /// that raised it. Native code does not set `_ERR`: [`Vm::run`](crate::vm::Vm::run) does.
    OperationError = 2,
}

/// Native code of one program.
pub trait NativeCode: Send + Sync + std::fmt::Debug {
    /// Executes the program from `regs` on `memory` (and `il`, the instruction list's state
    /// besides device memory: `None` for a Structured Text program, which does not pay for
    /// building it) until `END`, an operation error, an instruction it hands to the interpreter
    /// or the end of the budget, and updates `regs`.
    fn run(
        &self,
        memory: &mut NativeMemory<'_>,
        il: Option<&mut IlMemory<'_>>,
        regs: &mut NativeRegs,
    ) -> NativeExit;

    /// How many instructions from `pc` on the interpreter may execute before native code can
    /// take over again (at least 1).
    fn interpret_span(&self, pc: u32) -> u32;
}
