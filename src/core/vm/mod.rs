//! The instruction VM: executes compiled programs one instruction at a time.
//!
//! The VM owns the machine state every program shares — device memory, timer and counter
//! state, edge memory, the DUTY clocks and the executed-step count. What one activation of a
//! program needs to be resumed (program counter, rung result, rung stacks, call and loop
//! frames) lives in an [`ExecState`], one per task, so the task engine can stop a program
//! between any two instructions, run a higher-priority one, and resume the first.
//!
//! [`Vm::run`] returns on `END`, when its step budget is spent, after a system instruction
//! (`DI`, `EI`, `WDT`, `INIT_DONE`, `STOP`, `IORF`) whose effect belongs to the task engine,
//! and after an operation error (which has already set `_ERR`/`_ERR_CODE`). Nothing here
//! allocates after construction.

pub mod counter;
pub mod duty;
pub mod retained;
pub mod timer;
mod typed;
mod wide;

pub use crate::clock::{self, Clock, ManualClock, StepClock};

use crate::device::{
    counter_done, counter_value, timer_done, timer_value, BitRef, Memory, WordRef,
};
use crate::lang::native::{self, StFrame};
use crate::lang::ops::{ArithOp, Combine, Op, Src, SystemRequest, Wide, WideConv};
use crate::lang::{Language, Program, Variables, CALL_DEPTH, LOOP_DEPTH, ST_CALL_DEPTH};
use crate::value::{self, Elem, Pointer, Space};
use typed::EvalStack;

/// Operation error: division by zero.
pub const ERR_DIVIDE_BY_ZERO: u16 = 0x3400;
/// Operation error: a value out of range (DUTY n1/n2 from a device).
pub const ERR_VALUE_RANGE: u16 = duty::ERR_DUTY_RANGE;
/// Operation error: an array index outside the array's bounds (Structured Text); the access
/// goes to the discard pointer.
pub const ERR_INDEX_RANGE: u16 = 0x3402;
/// Operation error: an access through a reference outside its memory area (past the end of
/// variable memory, the frame area or device memory, or across it for the access's width),
/// into device memory by a member, an element or pointer arithmetic, or through a reference
/// that went nowhere (an array element out of bounds); the difference of two pointers into
/// different areas.
pub const ERR_REF_RANGE: u16 = 0x2820;
/// Operation error: an access through `NULL`.
pub const ERR_REF_NULL: u16 = 0x2822;
/// Operation error: `CALL` nested deeper than [`CALL_DEPTH`] (and, impossible for a checked
/// program, a Structured Text call deeper than [`ST_CALL_DEPTH`]).
pub const ERR_CALL_DEPTH: u16 = 0x4210;
/// Operation error: `FOR` nested deeper than [`LOOP_DEPTH`] at run time (through `CALL`).
pub const ERR_LOOP_DEPTH: u16 = 0x4211;

/// Why [`Vm::run`] returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// The program executed `END`; its state is finished.
    End,
    /// The step budget is spent; call `run` again to go on.
    Budget,
    /// A system instruction executed; the engine acts on it, then calls `run` again.
    System(SystemRequest),
    /// An operation error occurred (`_ERR` and `_ERR_CODE` are set); execution may go on.
    OperationError { code: u16, pc: u32 },
}

/// The code of an operation error as PLC manuals write it, e.g. `3405H`.
pub fn error_code_text(code: u16) -> String {
    format!("{code:04X}H")
}

/// An instruction-list call's frame: native code's layout, which it pushes and pops too.
type CallFrame = native::IlFrame;

#[derive(Debug, Clone, Copy, Default)]
struct LoopFrame {
    remaining: u16,
    end: u32,
}

/// Where one activation of a program stands.
#[derive(Debug, Clone)]
pub struct ExecState {
    /// The registers, in the layout native code reads and writes them in place (no copy in
    /// and out at each [`Vm::run`]): the next instruction; the instruction list's rung result
    /// (0 or 1), block stack of `LOAD … AND LOAD/OR LOAD` and `MPUSH` stack (one bit a level,
    /// top in bit 0), and its call and loop depths; Structured Text's call depth, current frame
    /// base (a byte offset into `frame`) and FB instance (a pointer slot). `left`, `sp` and
    /// `error` are a run's own: the budget, the stack pointer and the operation error it leaves
    /// there (the evaluation stack keeps its own pointer between runs).
    regs: native::NativeRegs,
    calls: [CallFrame; CALL_DEPTH],
    loops: [LoopFrame; LOOP_DEPTH],
    finished: bool,
    /// Structured Text: the evaluation stack, the calls and the frame area.
    eval: EvalStack,
    st_calls: [StFrame; ST_CALL_DEPTH],
    frame: Box<[u8]>,
}

/// The registers at a program's first instruction.
const START: native::NativeRegs = native::NativeRegs {
    pc: 0,
    st_depth: 0,
    base: 0,
    error: 0,
    this: Pointer::DISCARD.to_slot(),
    left: 0,
    sp: 0,
    rung: 1,
    blocks: 0,
    branches: 0,
    il_depth: 0,
    loop_depth: 0,
};

impl Default for ExecState {
    fn default() -> Self {
        Self::new()
    }
}

impl ExecState {
    /// A state at the program's first instruction, without frame area (enough for the
    /// instruction list).
    pub fn new() -> ExecState {
        ExecState::with_frame(0)
    }

    /// A state at the program's first instruction with `bytes` of frame area: the largest
    /// [`Program::frame_bytes`] of the programs the task runs.
    pub fn with_frame(bytes: u32) -> ExecState {
        ExecState {
            regs: START,
            calls: [CallFrame::default(); CALL_DEPTH],
            loops: [LoopFrame::default(); LOOP_DEPTH],
            finished: false,
            eval: EvalStack::new(),
            st_calls: [StFrame::default(); ST_CALL_DEPTH],
            frame: vec![0; bytes as usize].into_boxed_slice(),
        }
    }

    /// Bytes of frame area.
    pub fn frame_bytes(&self) -> u32 {
        self.frame.len() as u32
    }

    /// Slots on the evaluation stack (0 between statements of a checked program).
    pub fn eval_depth(&self) -> usize {
        self.eval.depth()
    }

    /// Back to the first instruction, for the next execution of the program.
    pub fn restart(&mut self) {
        // The registers as `START` has them, but a run's own (`left`, `sp`, `error`), which
        // each run sets before it reads them: `NativeRegs` keeps those after the others, and
        // the others' zeros together, so that this is a few stores.
        let regs = &mut self.regs;
        regs.pc = START.pc;
        regs.st_depth = START.st_depth;
        regs.base = START.base;
        regs.il_depth = START.il_depth;
        regs.blocks = START.blocks;
        regs.branches = START.branches;
        regs.loop_depth = START.loop_depth;
        regs.rung = START.rung;
        regs.this = START.this;
        self.finished = false;
        self.eval.clear();
    }

    /// The next instruction to execute.
    pub fn pc(&self) -> u32 {
        self.regs.pc
    }

    /// Calls under way: `CALL`s of the instruction list and Structured Text FUNCTION and
    /// FUNCTION_BLOCK calls (a line step steps over deeper ones).
    pub fn call_depth(&self) -> u32 {
        self.regs.il_depth + self.regs.st_depth
    }

    /// True once the program has executed `END`.
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    /// The instruction list's part of the activation, read-only.
    pub fn il_activation(&self) -> IlActivation {
        IlActivation {
            rung: self.regs.rung != 0,
            blocks: self.regs.blocks,
            branches: self.regs.branches,
            calls: self.calls[..(self.regs.il_depth as usize).min(CALL_DEPTH)]
                .iter()
                .map(|f| (f.return_pc, f.rung, f.blocks, f.branches, f.loop_depth))
                .collect(),
            loops: self.loops[..(self.regs.loop_depth as usize).min(LOOP_DEPTH)]
                .iter()
                .map(|f| (f.remaining, f.end))
                .collect(),
        }
    }

    /// The Structured Text part of the activation, read-only.
    pub fn st_activation(&self) -> StActivation<'_> {
        StActivation {
            eval: self.eval.live(),
            calls: &self.st_calls[..(self.regs.st_depth as usize).min(ST_CALL_DEPTH)],
            base: self.regs.base,
            this: self.regs.this,
            frame: &self.frame,
        }
    }
}

/// The instruction list's part of an activation ([`ExecState::il_activation`]): what native
/// code and the interpreter both leave the same after the same steps (the equivalence tests of
/// plcd-native compare it after every `Vm::run`). For tests and tools, not the scan: it
/// allocates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IlActivation {
    pub rung: bool,
    pub blocks: u32,
    pub branches: u32,
    /// The `CALL`s under way, outermost first: return pc, the caller's rung, blocks, branches
    /// and loop depth.
    pub calls: Vec<(u32, bool, u32, u32, u8)>,
    /// The `FOR` loops under way, outermost first: rounds left, the instruction after `NEXT`.
    pub loops: Vec<(u16, u32)>,
}

/// The Structured Text part of an activation ([`ExecState::st_activation`]): what native code
/// and the interpreter both write, and leave the same after the same steps (the equivalence
/// tests of plcd-native compare it after every `Vm::run`). Slots above the evaluation stack's
/// top and call frames above the call depth are dead and left out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StActivation<'a> {
    /// The live slots of the evaluation stack, bottom first.
    pub eval: &'a [u64],
    /// The FUNCTION and FUNCTION_BLOCK calls under way, outermost first.
    pub calls: &'a [StFrame],
    /// The current frame base: a byte offset into `frame`.
    pub base: u32,
    /// The current FB instance, a pointer slot.
    pub this: u64,
    /// The frame area.
    pub frame: &'a [u8],
}

/// The initial state of an edge memory slot after an online change (see
/// [`crate::engine::online`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeInit {
    /// The old edge memory's slot, of an unchanged program.
    Keep(u32),
    /// The bit's current value (a contact edge of a changed program).
    FromBit(crate::device::BitRef),
    /// A fixed state (a rung edge of a changed program).
    Value(bool),
}

/// The machine: device memory and the state shared by all programs.
pub struct Vm {
    pub mem: Memory,
    timers: Box<[timer::TimerState]>,
    counters: Box<[counter::CounterState]>,
    duty: [duty::DutyClock; duty::CHANNELS],
    edges: Box<[bool]>,
    steps: u64,
    /// Structured Text's variable memory, and what RUN start sets it up from.
    vars: Box<[u8]>,
    /// The project's own image ([`Variables::initial`]), shared, not copied.
    initial: std::sync::Arc<[u8]>,
    /// The byte ranges that are not retained, sorted: what a warm RUN start re-initializes.
    fresh: Box<[(u32, u32)]>,
    /// The byte ranges that are not `PERSISTENT`, sorted: what a cold reset and a cold RUN
    /// start re-initialize (all of memory without PERSISTENT variables).
    fresh_cold: Box<[(u32, u32)]>,
    located_init: Box<[(crate::lang::Place, Elem, u64)]>,
}

/// The complement in `0..size` of `ranges` (`(offset, len)`, any order), as sorted
/// `(start, end)`.
fn complement(ranges: &[(u32, u32)], size: u32) -> Box<[(u32, u32)]> {
    let mut kept: Vec<(u32, u32)> = ranges
        .iter()
        .map(|&(offset, len)| (offset.min(size), offset.saturating_add(len).min(size)))
        .collect();
    kept.sort_unstable();
    let mut out = Vec::new();
    let mut at = 0;
    for (start, end) in kept {
        if start > at {
            out.push((at, start));
        }
        at = at.max(end);
    }
    if at < size {
        out.push((at, size));
    }
    out.into_boxed_slice()
}

impl Vm {
    /// A VM with `edge_slots` slots of edge memory (the sum over the project's programs).
    pub fn new(edge_slots: u32) -> Vm {
        let tc = crate::device::layout::TC_COUNT as usize;
        Vm {
            mem: Memory::new(),
            timers: vec![timer::TimerState::default(); tc].into_boxed_slice(),
            counters: vec![counter::CounterState::default(); tc].into_boxed_slice(),
            duty: [duty::DutyClock::default(); duty::CHANNELS],
            edges: vec![false; edge_slots as usize].into_boxed_slice(),
            steps: 0,
            vars: Box::new([]),
            initial: std::sync::Arc::new([]),
            fresh: Box::new([]),
            fresh_cold: Box::new([]),
            located_init: Box::new([]),
        }
    }

    /// Sets up Structured Text's variable memory: its image at RUN start (copied in now), what
    /// a warm RUN start keeps, the located variables' initial values.
    pub fn set_variables(&mut self, variables: &Variables) {
        self.initial = variables.initial.clone();
        self.vars = Box::from(&variables.initial[..]);
        let size = variables.initial.len() as u32;
        self.fresh = complement(&variables.retained, size);
        self.fresh_cold = complement(&variables.persistent, size);
        self.located_init = variables.located_init.clone();
    }

    /// Structured Text's variable memory.
    pub fn vars(&self) -> &[u8] {
        &self.vars
    }

    /// The value of `elem` at `p` in copies of device memory (`words`, from word 0) and of
    /// variable memory (`vars`), read as [`Vm::read_value`] reads the VM's own: for the
    /// services that read a mirror taken at a scan boundary. A place outside the copies reads 0.
    pub fn read_value_in(words: &[u16], vars: &[u8], p: Pointer, elem: Elem) -> u64 {
        typed::load(words, vars, &[], p, elem)
    }

    /// The characters of the `STRING` at `p` in a copy of variable memory (see
    /// [`Vm::read_value_in`]).
    pub fn string_bytes_in(vars: &[u8], p: Pointer) -> &[u8] {
        typed::string_chars(vars, p)
    }

    /// The code units' bytes (little-endian) of the `WSTRING` at `p` in a copy of variable
    /// memory (see [`Vm::read_value_in`]).
    pub fn wstring_bytes_in(vars: &[u8], p: Pointer) -> &[u8] {
        wide::wstring_bytes(vars, p)
    }

    /// The characters of the `STRING` or `WSTRING` of type `ty` at `p` in a copy of variable
    /// memory, as the services serve them (a `WSTRING`'s unpaired surrogate as U+FFFD);
    /// `None` for a variable of another type.
    pub fn text_in(ty: &crate::value::ValueType, vars: &[u8], p: Pointer) -> Option<String> {
        match ty {
            crate::value::ValueType::String { .. } => {
                Some(crate::value::decode_str(Self::string_bytes_in(vars, p)))
            }
            crate::value::ValueType::WString { .. } => {
                let bytes = Self::wstring_bytes_in(vars, p);
                let units = bytes.chunks_exact(2).map(|u| u16::from_le_bytes([u[0], u[1]]));
                Some(char::decode_utf16(units).map(|c| c.unwrap_or('\u{FFFD}')).collect())
            }
            _ => None,
        }
    }

    /// The value of `elem` at `p`, for tools (a pointer into a frame reads 0: frames belong to
    /// the tasks).
    pub fn read_value(&self, p: Pointer, elem: Elem) -> u64 {
        typed::load(self.mem.words(), &self.vars, &[], p, elem)
    }

    /// Writes `value` (any bits: it is normalized) as `elem` at `p`, for tools.
    pub fn write_value(&mut self, p: Pointer, elem: Elem, value: u64) {
        let value = value::normalize(elem, value);
        typed::store(self.mem.words_mut(), &mut self.vars, &mut [], p, elem, value);
    }

    /// The characters of the `STRING` at `p` in variable memory, for tools (see
    /// [`value::format_string`]).
    pub fn read_string(&self, p: Pointer) -> Vec<u8> {
        typed::string_text(&self.vars, p)
    }

    /// [`Vm::read_string`] without a copy: the characters, borrowed (what watches compare, in
    /// the scan path).
    pub fn string_bytes(&self, p: Pointer) -> &[u8] {
        typed::string_chars(&self.vars, p)
    }

    /// The code units of the `WSTRING` at `p` in variable memory, for tools (see
    /// [`value::format_wstring`]).
    pub fn read_wstring(&self, p: Pointer) -> Vec<u16> {
        wide::wstring_units(&self.vars, p)
    }

    /// [`Vm::read_wstring`] without a copy: the code units' bytes (little-endian), borrowed.
    pub fn wstring_bytes(&self, p: Pointer) -> &[u8] {
        wide::wstring_bytes(&self.vars, p)
    }

    /// Writes the `WSTRING[cap]` at `p` in variable memory: the code units `bytes` (2 a unit,
    /// little-endian), cut to `cap` of them.
    pub fn write_wstring(&mut self, p: Pointer, cap: u32, bytes: &[u8]) {
        wide::write_wstring_bytes(&mut self.vars, p, cap, bytes);
    }

    /// Writes the `STRING[cap]` at `p` in variable memory, cut to `cap` characters.
    pub fn write_string(&mut self, p: Pointer, cap: u32, text: &[u8]) {
        typed::write_string_bytes(&mut self.vars, p, cap, text);
    }

    /// A VM sized for `programs`.
    pub fn for_programs<'a>(programs: impl IntoIterator<Item = &'a Program>) -> Vm {
        let slots = programs.into_iter().map(|p| p.edge_base + p.edge_slots).max().unwrap_or(0);
        Vm::new(slots)
    }

    /// Online change: takes the machine state of `old` (device memory, timers, counters, DUTY
    /// clocks, the step count) by swapping, and sets up this VM's edge memory by `edges`. No
    /// allocation. Variable memory is [`Vm::keep_variables`]'s.
    pub fn take_over(&mut self, old: &mut Vm, edges: &[EdgeInit]) {
        std::mem::swap(&mut self.mem, &mut old.mem);
        std::mem::swap(&mut self.timers, &mut old.timers);
        std::mem::swap(&mut self.counters, &mut old.counters);
        // Variable memory is not swapped: the new programs may lay it out differently. This
        // VM starts from its own initial image; `keep_variables` brings over what is kept.
        self.duty = old.duty;
        self.steps = old.steps;
        for (slot, init) in self.edges.iter_mut().zip(edges) {
            *slot = match *init {
                EdgeInit::Keep(index) => old.edges.get(index as usize).copied().unwrap_or(false),
                EdgeInit::FromBit(bit) => self.mem.bit(bit),
                EdgeInit::Value(value) => value,
            };
        }
    }

    /// Online change: copies the variables the change keeps from `old`'s variable memory,
    /// `(old offset, new offset, bytes)` each (see `engine::online`). No allocation.
    pub fn keep_variables(&mut self, old: &Vm, keep: &[(u32, u32, u32)]) {
        for &(from, to, len) in keep {
            let (from, to, len) = (from as usize, to as usize, len as usize);
            if let (Some(src), Some(dst)) =
                (old.vars.get(from..from + len), self.vars.get_mut(to..to + len))
            {
                dst.copy_from_slice(src);
            }
        }
    }

    /// Retained variables (docs/RETAIN.md): copies `len` bytes at `from` of `old`'s variable
    /// memory to `to` of this one's. No allocation.
    pub fn copy_variable_from(&mut self, old: &Vm, from: u32, to: u32, len: u32) {
        self.keep_variables(old, &[(from, to, len)]);
    }

    /// Retained variables restored at start: writes `bytes` at byte `at` of variable memory
    /// (nothing if they do not fit).
    pub fn restore_variable(&mut self, at: u32, bytes: &[u8]) {
        let at = at as usize;
        if let Some(to) = self.vars.get_mut(at..at + bytes.len()) {
            to.copy_from_slice(bytes);
        }
    }

    /// Rewrites the `BOOL` at each of `offsets` of variable memory to 0 or 1 (1 for any nonzero
    /// byte, as every read takes it), after bytes were copied in that code of another project
    /// may have written ([`crate::lang::Program::var_bools_canonical`]). No allocation.
    pub fn canonicalize_bools(&mut self, offsets: &[u32]) {
        for &offset in offsets {
            if let Some(byte) = self.vars.get_mut(offset as usize) {
                *byte = u8::from(*byte != 0);
            }
        }
    }

    /// A cold reset: every variable back to its initial value, the retained ones too, but the
    /// `PERSISTENT` ones (as TwinCAT's and CODESYS's Reset cold).
    pub fn reset_variables(&mut self) {
        for &(start, end) in self.fresh_cold.iter() {
            let range = start as usize..end as usize;
            if let (Some(to), Some(from)) =
                (self.vars.get_mut(range.clone()), self.initial.get(range))
            {
                to.copy_from_slice(from);
            }
        }
    }

    /// Instructions executed since the VM was created.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The state machines of the instruction list's devices, read-only: timers, counters and
    /// edge memory (for the tests that compare two VMs).
    pub fn device_states(&self) -> (&[timer::TimerState], &[counter::CounterState], &[bool]) {
        (&self.timers, &self.counters, &self.edges)
    }

    /// RUN start: data areas cleared except the retained words (K and the `[retain]` ranges);
    /// timers, edges and DUTY clocks back to their initial state (a retained timer's current
    /// value is in memory: TMR counts on from it, the others start timing over); counters too,
    /// except that with `warm` (retained values are meaningful: not after a cold start) the
    /// retained ones keep counting from their value ([`counter::CounterState::warm`]).
    pub fn reset_for_run(&mut self, retained: &crate::device::RetainSet, warm: bool) {
        self.mem.clear_for_run(&retained.words);
        self.timers.fill(timer::TimerState::default());
        for (n, state) in self.counters.iter_mut().enumerate() {
            *state = if warm && retained.retains_counter(n) {
                counter::CounterState::warm()
            } else {
                counter::CounterState::default()
            };
        }
        self.edges.fill(false);
        self.duty = [duty::DutyClock::default(); duty::CHANNELS];
        if warm {
            for &(start, end) in self.fresh.iter() {
                let range = start as usize..end as usize;
                if let (Some(to), Some(from)) =
                    (self.vars.get_mut(range.clone()), self.initial.get(range))
                {
                    to.copy_from_slice(from);
                }
            }
        } else {
            self.reset_variables();
        }
        for &(at, elem, value) in self.located_init.iter() {
            let p = typed::pointer(at, 0, Pointer::DISCARD.to_slot());
            typed::store(self.mem.words_mut(), &mut self.vars, &mut [], p, elem, value);
        }
    }

    /// Start of a scan: system flags (see [`Memory::begin_scan`]) and `_ERR` cleared.
    pub fn begin_scan(&mut self, first_scan: bool, since_run_ns: u64) {
        self.mem.begin_scan(first_scan, since_run_ns);
        self.mem.clear_operation_error();
    }

    /// END processing of the VM's own devices: the DUTY clocks.
    pub fn end_scan(&mut self) {
        duty::end_scan(&mut self.duty, &mut self.mem);
    }

    /// STOP: DUTY clocks stop.
    pub fn stop(&mut self) {
        duty::stop(&mut self.duty, &mut self.mem);
    }

    /// Executes `program` from `state` for at most `max_steps` instructions. `clock` gives
    /// timers the current time; it is told the step count so a virtual clock can charge each
    /// instruction. How the loop is kept fast is told at `interpret`, below.
    pub fn run<C: Clock>(
        &mut self,
        program: &Program,
        state: &mut ExecState,
        clock: &C,
        max_steps: u64,
    ) -> Exit {
        match program.native.as_deref() {
            Some(native) => self.run_native(native, program, state, clock, max_steps),
            None => self.interpret(program, state, clock, max_steps),
        }
    }

    /// [`Vm::run`] of a program with native code: native code runs as far as it can, and the
    /// interpreter executes what it hands back, a few instructions at a time ([`native`]).
    ///
    /// Most runs are one call of native code to `END` (a scan from its start): that call is
    /// here, inlined into [`Vm::run`]'s caller; a run that native code hands back goes on in
    /// [`Vm::run_native_on`], a call of its own, so that what the first call keeps in registers
    /// is only what it needs.
    #[inline(always)]
    fn run_native<C: Clock>(
        &mut self,
        native: &dyn native::NativeCode,
        program: &Program,
        state: &mut ExecState,
        clock: &C,
        max_steps: u64,
    ) -> Exit {
        let stop = self.steps.saturating_add(max_steps);
        let left = stop - self.steps;
        if left == 0 {
            return Exit::Budget;
        }
        let exit = self.native_call(native, program, state, clock, stop, left);
        match self.native_end(exit, state) {
            Some(exit) => exit,
            None => self.run_native_on(program, state, clock, stop),
        }
    }

    /// The rest of [`Vm::run_native`] after native code handed the next instruction to the
    /// interpreter: the interpreter executes a few ([`native::NativeCode::interpret_span`]),
    /// native code the rest, in turns, until `END`, an operation error, a system instruction
    /// or step `stop`. It finds the native code in `program` again, so that the first call
    /// keeps no more of it than the call needs.
    #[inline(never)]
    fn run_native_on<C: Clock>(
        &mut self,
        program: &Program,
        state: &mut ExecState,
        clock: &C,
        stop: u64,
    ) -> Exit {
        let Some(native) = program.native.as_deref() else {
            // Not after `run_native`, which ran the native code; the interpreter alone then.
            return self.interpret(program, state, clock, stop - self.steps);
        };
        loop {
            let left = stop - self.steps;
            if left == 0 {
                return Exit::Budget;
            }
            let span = u64::from(native.interpret_span(state.regs.pc).max(1));
            match self.interpret(program, state, clock, left.min(span)) {
                Exit::Budget => {}
                exit => return exit,
            }
            let left = stop - self.steps;
            if left == 0 {
                return Exit::Budget;
            }
            let exit = self.native_call(native, program, state, clock, stop, left);
            if let Some(exit) = self.native_end(exit, state) {
                return exit;
            }
        }
    }

    /// How a call of native code that returned `exit` ends the run: `None` where the
    /// interpreter is to go on.
    #[inline(always)]
    fn native_end(&mut self, exit: native::NativeExit, state: &mut ExecState) -> Option<Exit> {
        match exit {
            native::NativeExit::End => {
                state.finished = true;
                Some(Exit::End)
            }
            native::NativeExit::OperationError => Some(self.native_error(state)),
            native::NativeExit::Interpret => None,
        }
    }

    /// One call of native code from `state` with `left` (not 0) of the budget that ends at
    /// step `stop`: the registers it reads set, its memory lent, the steps it executed
    /// counted.
    #[inline(always)]
    fn native_call<C: Clock>(
        &mut self,
        native: &dyn native::NativeCode,
        program: &Program,
        state: &mut ExecState,
        clock: &C,
        stop: u64,
        left: u64,
    ) -> native::NativeExit {
        state.regs.left = left;
        state.regs.sp = state.eval.sp() as u64;
        let mut memory = native::NativeMemory::new(
            &mut self.vars,
            self.mem.words_mut(),
            &mut state.frame,
            state.eval.slots_mut(),
            &mut state.st_calls,
        );
        // Native code sets `error` when it returns `OperationError`, the only time it is read.
        let exit = match program.language {
            // Structured Text has no instruction-list state, and does not pay for building it.
            Language::StructuredText => native.run(&mut memory, None, &mut state.regs),
            Language::InstructionList => {
                let mut il = native::IlMemory {
                    calls: &mut state.calls,
                    edges: &mut self.edges,
                    counters: native::RawSlice::new(&mut self.counters),
                    timers: native::RawSlice::new(&mut self.timers),
                    clock,
                    stop,
                };
                native.run(&mut memory, Some(&mut il), &mut state.regs)
            }
        };
        state.eval.set_sp(state.regs.sp as usize);
        self.steps = stop - state.regs.left.min(left);
        exit
    }

    /// The operation error native code returned with: `_ERR` set, the exit at the instruction
    /// that raised it.
    #[cold]
    #[inline(never)]
    fn native_error(&mut self, state: &ExecState) -> Exit {
        let code = state.regs.error as u16;
        self.mem.raise_operation_error(code);
        Exit::OperationError { code, pc: state.regs.pc.wrapping_sub(1) }
    }

    /// [`Vm::run`] on the interpreter alone.
    fn interpret<C: Clock>(
        &mut self,
        program: &Program,
        state: &mut ExecState,
        clock: &C,
        max_steps: u64,
    ) -> Exit {
        let code: &[Op] = &program.code;
        // The budget counts down; the step count is `stop - left`.
        let stop = self.steps.saturating_add(max_steps);
        let mut regs = Regs {
            rest: code.get(state.regs.pc as usize..).unwrap_or_default(),
            rung: state.regs.rung != 0,
            blocks: state.regs.blocks,
            branches: state.regs.branches,
            left: stop - self.steps,
        };
        let machine = Machine {
            edges: &mut self.edges,
            timers: &mut self.timers,
            counters: &mut self.counters,
            duty: &mut self.duty,
            vars: &mut self.vars,
            consts: &program.consts,
            clock,
            stop,
        };
        let exit = match program.language {
            Language::InstructionList => {
                interpret::<false, C>(&mut self.mem, machine, state, code, &mut regs)
            }
            Language::StructuredText => {
                interpret::<true, C>(&mut self.mem, machine, state, code, &mut regs)
            }
        };
        state.regs.pc = (code.len() - regs.rest.len()) as u32;
        state.regs.rung = u32::from(regs.rung);
        state.regs.blocks = regs.blocks;
        state.regs.branches = regs.branches;
        self.steps = stop - regs.left;
        exit
    }
}

/// The registers of an activation while [`Vm::run`] executes it.
#[derive(Clone, Copy)]
struct Regs<'a> {
    /// The instructions from the next one on: the program counter is `code.len() -
    /// rest.len()`.
    rest: &'a [Op],
    rung: bool,
    blocks: u32,
    branches: u32,
    /// Instructions left in the step budget.
    left: u64,
}

/// The VM's state besides device memory, borrowed for [`interpret`], and the time.
struct Machine<'a, C> {
    edges: &'a mut [bool],
    timers: &'a mut [timer::TimerState],
    counters: &'a mut [counter::CounterState],
    duty: &'a mut [duty::DutyClock; duty::CHANNELS],
    /// Structured Text's variable memory.
    vars: &'a mut [u8],
    /// The program's wide constants.
    consts: &'a [u64],
    clock: &'a C,
    /// The step count at which the budget is spent.
    stop: u64,
}

/// The interpreter loop: executes `code` from `regs` until `END`, a system instruction, an
/// operation error or the end of the budget. `state` holds the call and loop frames.
///
/// How it is kept fast (see `benches/vm.rs`):
/// - The activation's registers are locals for the whole loop and go back to `regs` only on
///   return.
/// - `mem` is a parameter of its own rather than a field behind `&mut Vm`: as a `&mut`
///   parameter it cannot alias anything else, so the words' address and length stay in
///   registers instead of being reloaded after every store. For the same reason nothing the
///   loop calls takes `&mut Memory`: timers and counters are state machines that take the
///   values the loop read and return the values it writes.
/// - The loop runs in chunks of as many instructions as the budget and the end of the code
///   allow, so each instruction costs one end test (a slice iterator's) instead of a budget
///   test and a bounds test. A jump ends the chunk.
/// - Ops are matched by reference, so each arm loads only its own operands; [`Op`] is
///   `repr(u8)` and every variant has an arm, so dispatch is one byte load and one indirect
///   jump through a table without a range check.
/// - One loop per language: `ST` selects the arms of the Structured Text ops, `!ST` those of
///   the instruction list (a program holds only its own language's ops). The other
///   language's arms are compiled out of each instantiation, so neither loop carries the
///   other's code: the instruction list's loop is as small as before Structured Text, and
///   keeps its registers across `CALL` and `RET`.
/// - Outputs, SET/RST and the data instructions write their destination whatever the rung
///   result (the old value when it is OFF), compares evaluate through the truth table in
///   [`CmpOp`](crate::lang::ops::CmpOp), and contacts combine with the rung arithmetically:
///   no branch depends on device data, which the processor cannot predict.
#[inline(never)]
fn interpret<'a, const ST: bool, C: Clock>(
    mem: &mut Memory,
    machine: Machine<'_, C>,
    state: &mut ExecState,
    code: &'a [Op],
    regs: &mut Regs<'a>,
) -> Exit {
    let Machine { edges, timers, counters, duty, vars, consts, clock, stop } = machine;
    let Regs { mut rest, mut rung, mut blocks, mut branches, mut left } = *regs;
    // The evaluation stack's pointer, in a register; back in `state` at every exit.
    let mut sp = state.eval.sp();
    macro_rules! push {
        ($value:expr) => {{
            let value = $value;
            state.eval.push_at(&mut sp, value);
        }};
    }
    macro_rules! pop {
        () => {
            state.eval.pop_at(&mut sp)
        };
    }
    macro_rules! top {
        () => {
            state.eval.top_at(sp)
        };
    }
    macro_rules! set_top {
        ($value:expr) => {{
            let value = $value;
            state.eval.set_top_at(sp, value);
        }};
    }

    // The chunk: the instructions of it still ahead.
    let mut ops: std::slice::Iter<'a, Op>;
    // Instructions executed in this chunk, the one being executed included: the distance of
    // the iterator from the chunk's start (`rest`), computed from the two addresses at an exit.
    // Not `run - ops.len()`: that made LLVM keep the length in a register of its own, one more
    // instruction at every step to count it down.
    macro_rules! taken {
        () => {
            (ops.as_slice().as_ptr() as usize - rest.as_ptr() as usize) / size_of::<Op>()
        };
    }
    // The program counter: the instruction after the one being executed.
    macro_rules! pc {
        () => {
            code.len() - rest.len() + taken!()
        };
    }
    // Ends the chunk: `rest` and `left` catch up with the instructions executed.
    macro_rules! sync {
        () => {{
            let taken = taken!();
            rest = &rest[taken..];
            left -= taken as u64;
        }};
    }
    // Returns `$halt`, evaluated after the chunk is synced (so it must not use `pc!()`).
    macro_rules! halt {
        ($halt:expr) => {{
            sync!();
            *regs = Regs { rest, rung, blocks, branches, left };
            state.eval.set_sp(sp);
            return $halt;
        }};
    }
    macro_rules! fail {
        ($code:expr) => {{
            let code = $code;
            mem.raise_operation_error(code);
            let pc = (pc!() - 1) as u32;
            halt!(Exit::OperationError { code, pc });
        }};
    }

    'chunk: loop {
        let run = rest.len().min(usize::try_from(left).unwrap_or(usize::MAX));
        ops = rest[..run].iter();
        // A jump ends the chunk (a macro here, where it can see the loop's label).
        macro_rules! jump {
            ($target:expr) => {{
                left -= taken!() as u64;
                rest = code.get($target as usize..).unwrap_or_default();
                continue 'chunk;
            }};
        }
        // A Structured Text call: a frame for the return, the callee's base and `this`.
        macro_rules! st_call {
            ($target:expr, $frame:expr, $this:expr) => {{
                let depth = state.regs.st_depth as usize;
                if depth >= ST_CALL_DEPTH {
                    fail!(ERR_CALL_DEPTH);
                }
                state.st_calls[depth] = StFrame {
                    return_pc: pc!() as u32,
                    base: state.regs.base,
                    this: state.regs.this,
                };
                state.regs.st_depth += 1;
                state.regs.base = state.regs.base.wrapping_add($frame);
                state.regs.this = $this;
                jump!($target);
            }};
        }
        loop {
            let Some(op) = ops.next() else {
                // The chunk is done: the budget is spent, or the code is (only a program
                // without END gets there, and the checker refuses those).
                if left == run as u64 {
                    halt!(Exit::Budget);
                }
                state.finished = true;
                halt!(Exit::End);
            };
            match op {
                Op::Load(b) if !ST => rung = mem.bit(*b),
                Op::LoadNot(b) if !ST => rung = !mem.bit(*b),
                Op::LoadPush(b) if !ST => {
                    blocks = (blocks << 1) | rung as u32;
                    rung = mem.bit(*b);
                }
                Op::LoadNotPush(b) if !ST => {
                    blocks = (blocks << 1) | rung as u32;
                    rung = !mem.bit(*b);
                }
                Op::And(b) if !ST => rung &= mem.bit(*b),
                Op::AndNot(b) if !ST => rung &= !mem.bit(*b),
                Op::Or(b) if !ST => rung |= mem.bit(*b),
                Op::OrNot(b) if !ST => rung |= !mem.bit(*b),
                Op::EdgeContact { bit, rising, how, slot } if !ST => {
                    let now = mem.bit(*bit);
                    let before = std::mem::replace(&mut edges[*slot as usize], now);
                    let edge = if *rising { now && !before } else { !now && before };
                    combine(*how, edge, &mut rung, &mut blocks);
                }
                Op::Compare { op, a, b, how } if !ST => {
                    let result = op.eval(read(mem, *a) as i16, read(mem, *b) as i16);
                    combine(*how, result, &mut rung, &mut blocks);
                }
                Op::AndLoad if !ST => {
                    rung &= blocks & 1 != 0;
                    blocks >>= 1;
                }
                Op::OrLoad if !ST => {
                    rung |= blocks & 1 != 0;
                    blocks >>= 1;
                }
                Op::MPush if !ST => branches = (branches << 1) | rung as u32,
                Op::MLoad if !ST => rung = branches & 1 != 0,
                Op::MPop if !ST => {
                    rung = branches & 1 != 0;
                    branches >>= 1;
                }
                Op::Not if !ST => rung = !rung,
                Op::Out(b) if !ST => write_bit(mem, *b, rung),
                Op::OutNot(b) if !ST => write_bit(mem, *b, !rung),
                Op::OutPulse { bit, rising, slot } if !ST => {
                    let before = std::mem::replace(&mut edges[*slot as usize], rung);
                    let edge = if *rising { rung && !before } else { !rung && before };
                    write_bit(mem, *bit, edge);
                }
                Op::Set(b) if !ST => {
                    let word = mem.word(WordRef(b.word));
                    mem.set_word(WordRef(b.word), word | (b.mask & all(rung)));
                }
                Op::Rst(b) if !ST => {
                    let word = mem.word(WordRef(b.word));
                    mem.set_word(WordRef(b.word), word & !(b.mask & all(rung)));
                }
                Op::FlipFlop { bit, slot } if !ST => {
                    if pulse(edges, *slot, rung) {
                        mem.set_bit(*bit, !mem.bit(*bit));
                    }
                }
                Op::RstTimer(n) if !ST => {
                    if rung {
                        timer::reset(&mut timers[*n as usize]);
                        mem.set_word(timer_value(*n), 0);
                        write_bit(mem, timer_done(*n), false);
                    }
                }
                Op::RstCounter(n) if !ST => {
                    if rung {
                        let value = counter::reset(&counters[*n as usize]);
                        mem.set_word(counter_value(*n), value);
                        write_bit(mem, counter_done(*n), false);
                    }
                }
                Op::Timer { kind, timer: n, preset, base_ms } if !ST => {
                    let (value_ref, done_ref) = (timer_value(*n), timer_done(*n));
                    let call = timer::TimerInput {
                        kind: *kind,
                        input: rung,
                        preset: read(mem, *preset),
                        base_ms: *base_ms,
                        now_ns: 0, // read by `run_timer`, out of the loop
                        value: mem.word(value_ref),
                        done: mem.bit(done_ref),
                    };
                    let steps = stop - left + taken!() as u64;
                    let (value, done) = run_timer(&mut timers[*n as usize], call, clock, steps);
                    mem.set_word(value_ref, value);
                    write_bit(mem, done_ref, done);
                }
                Op::Counter { kind, counter: n, preset } if !ST => {
                    let preset = read(mem, *preset);
                    let value_ref = counter_value(*n);
                    let c = &mut counters[*n as usize];
                    let (value, done) =
                        counter::execute(*kind, c, rung, preset, mem.word(value_ref));
                    mem.set_word(value_ref, value);
                    write_bit(mem, counter_done(*n), done);
                }
                Op::CounterUpDown { counter: n, up, down, preset } if !ST => {
                    let preset = read(mem, *preset);
                    let value_ref = counter_value(*n);
                    let (up, down, value) = (mem.bit(*up), mem.bit(*down), mem.word(value_ref));
                    let c = &mut counters[*n as usize];
                    let (value, done) = counter::execute_up_down(c, rung, up, down, preset, value);
                    mem.set_word(value_ref, value);
                    write_bit(mem, counter_done(*n), done);
                }
                Op::Duty { channel, n1, n2, slot } if !ST => {
                    let rising = pulse(edges, *slot, rung);
                    if rung {
                        let channel = &mut duty[*channel as usize];
                        let (n1, n2) = (read(mem, *n1), read(mem, *n2));
                        if let Err(code) = duty::execute(channel, rising, n1, n2) {
                            fail!(code);
                        }
                    }
                }
                Op::Mov { s, d, pulse: p } if !ST => {
                    let on = enabled(edges, *p, rung);
                    let value = read(mem, *s);
                    let old = mem.word(*d);
                    mem.set_word(*d, if on { value } else { old });
                }
                Op::Arith { op, a, b, d, pulse: p } if !ST => {
                    let on = enabled(edges, *p, rung);
                    let (a, b) = (read(mem, *a) as i16, read(mem, *b) as i16);
                    let value = match op {
                        ArithOp::Add => a.wrapping_add(b),
                        ArithOp::Sub => a.wrapping_sub(b),
                        ArithOp::Mul => a.wrapping_mul(b),
                        ArithOp::Div => {
                            if !on {
                                continue;
                            }
                            if b == 0 {
                                fail!(ERR_DIVIDE_BY_ZERO);
                            }
                            a.wrapping_div(b)
                        }
                    };
                    let old = mem.word(*d);
                    mem.set_word(*d, if on { value as u16 } else { old });
                }
                Op::Step { d, up, pulse: p } if !ST => {
                    let on = enabled(edges, *p, rung);
                    let old = mem.word(*d);
                    let step = if *up { 1u16 } else { u16::MAX };
                    mem.set_word(*d, old.wrapping_add(step & all(on)));
                }
                Op::Call { target } if !ST => {
                    if rung {
                        let depth = state.regs.il_depth as usize;
                        if depth >= CALL_DEPTH {
                            fail!(ERR_CALL_DEPTH);
                        }
                        state.calls[depth] = CallFrame {
                            return_pc: pc!() as u32,
                            rung,
                            blocks,
                            branches,
                            loop_depth: state.regs.loop_depth as u8,
                        };
                        state.regs.il_depth += 1;
                        rung = true;
                        blocks = 0;
                        branches = 0;
                        jump!(*target);
                    }
                }
                Op::Ret if !ST => {
                    let Some(depth) = state.regs.il_depth.checked_sub(1) else {
                        // Unreachable for checked programs: RET ends a SBRT, reached by CALL.
                        state.finished = true;
                        halt!(Exit::End);
                    };
                    state.regs.il_depth = depth;
                    let frame = state.calls[depth as usize];
                    rung = frame.rung;
                    blocks = frame.blocks;
                    branches = frame.branches;
                    state.regs.loop_depth = u32::from(frame.loop_depth);
                    jump!(frame.return_pc);
                }
                Op::Jmp { target } if !ST => {
                    if rung {
                        jump!(*target);
                    }
                }
                Op::Label if !ST => rung = true,
                Op::For { count, end } if !ST => {
                    let count = read(mem, *count) as i16;
                    let depth = state.regs.loop_depth as usize;
                    if rung && count > 0 && depth >= LOOP_DEPTH {
                        // 4211H; the loop is skipped, the rung result left as it is.
                        let pc = (pc!() - 1) as u32;
                        left -= taken!() as u64;
                        rest = code.get(*end as usize..).unwrap_or_default();
                        mem.raise_operation_error(ERR_LOOP_DEPTH);
                        *regs = Regs { rest, rung, blocks, branches, left };
                        state.eval.set_sp(sp);
                        return Exit::OperationError { code: ERR_LOOP_DEPTH, pc };
                    }
                    let enter = rung && count > 0;
                    rung = true;
                    if enter {
                        state.loops[depth] = LoopFrame { remaining: count as u16, end: *end };
                        state.regs.loop_depth += 1;
                    } else {
                        jump!(*end);
                    }
                }
                Op::Next { body } if !ST => {
                    rung = true;
                    if let Some(depth) = (state.regs.loop_depth as usize).checked_sub(1) {
                        let frame = &mut state.loops[depth];
                        frame.remaining -= 1;
                        if frame.remaining > 0 {
                            jump!(*body);
                        }
                        state.regs.loop_depth -= 1;
                    }
                }
                Op::Break if !ST => {
                    if rung {
                        if let Some(depth) = (state.regs.loop_depth as usize).checked_sub(1) {
                            state.regs.loop_depth -= 1;
                            jump!(state.loops[depth].end);
                        }
                    }
                }
                Op::End => {
                    state.finished = true;
                    halt!(Exit::End);
                }
                Op::Nop => {}
                Op::System(request) => {
                    if rung {
                        halt!(Exit::System(*request));
                    }
                }

                // The instruction list's double-word and real instructions.
                Op::DMov { s, d, pulse: p } if !ST => {
                    if enabled(edges, *p, rung) {
                        let value = read_wide(mem, consts, *s);
                        write_wide(mem, *d, value);
                    }
                }
                Op::DArith { op, a, b, d, pulse: p } if !ST => {
                    if enabled(edges, *p, rung) {
                        let (a, b) = (read_wide(mem, consts, *a), read_wide(mem, consts, *b));
                        match wide_arith(*op, Elem::I32, a, b) {
                            Some(value) => write_wide(mem, *d, value),
                            None => fail!(ERR_DIVIDE_BY_ZERO),
                        }
                    }
                }
                Op::RArith { op, a, b, d, pulse: p } if !ST => {
                    if enabled(edges, *p, rung) {
                        let (a, b) = (read_wide(mem, consts, *a), read_wide(mem, consts, *b));
                        match wide_arith(*op, Elem::F32, a, b) {
                            Some(value) => write_wide(mem, *d, value),
                            None => fail!(ERR_DIVIDE_BY_ZERO),
                        }
                    }
                }
                Op::DStep { d, up, pulse: p } if !ST => {
                    if enabled(edges, *p, rung) {
                        let value = read_wide(mem, consts, Wide::Word(*d));
                        let step = if *up { 1u32 } else { u32::MAX };
                        write_wide(mem, *d, value.wrapping_add(step));
                    }
                }
                Op::DCompare { op, a, b, how } if !ST => {
                    let a = read_wide(mem, consts, *a) as i32;
                    let b = read_wide(mem, consts, *b) as i32;
                    combine(*how, op.holds(Some(a.cmp(&b))), &mut rung, &mut blocks);
                }
                Op::RCompare { op, a, b, how } if !ST => {
                    let a = f32::from_bits(read_wide(mem, consts, *a));
                    let b = f32::from_bits(read_wide(mem, consts, *b));
                    combine(*how, op.holds(a.partial_cmp(&b)), &mut rung, &mut blocks);
                }
                Op::Convert { conv, s, d, pulse: p } if !ST => {
                    if enabled(edges, *p, rung) {
                        let value = wide_convert(*conv, read_wide(mem, consts, *s));
                        if conv.to_one_word() {
                            if (d.0 as usize) < mem.words().len() {
                                mem.set_word(*d, value as u16);
                            }
                        } else {
                            write_wide(mem, *d, value);
                        }
                    }
                }
                // The typed stack machine (crate::value, st-ir.md).
                Op::PushInt(v) if ST => push!(i64::from(*v) as u64),
                Op::PushConst(index) if ST => {
                    push!(consts.get(*index as usize).copied().unwrap_or(0));
                }
                Op::Fetch { elem, at } if ST => {
                    let v = typed::load_place(
                        mem,
                        vars,
                        &state.frame,
                        *at,
                        state.regs.base,
                        state.regs.this,
                        *elem,
                    );
                    push!(v);
                }
                Op::Store { elem, at } if ST => {
                    let v = pop!();
                    let (base, this) = (state.regs.base, state.regs.this);
                    typed::store_place(mem, vars, &mut state.frame, *at, base, this, *elem, v);
                }
                Op::AddrOf(at) if ST => {
                    push!(typed::pointer(*at, state.regs.base, state.regs.this).to_slot());
                }
                Op::Index { lo, len, stride } if ST => {
                    let index = pop!() as i64;
                    let element = index.wrapping_sub(i64::from(*lo));
                    if (0..i64::from(*len)).contains(&element) {
                        let p = Pointer::from_slot(top!());
                        let p = typed::moved(p, (element as u32).wrapping_mul(*stride));
                        set_top!(p.to_slot());
                    } else {
                        set_top!(Pointer::DISCARD.to_slot());
                        fail!(ERR_INDEX_RANGE);
                    }
                }
                Op::Offset(n) if ST => {
                    let p = typed::moved(Pointer::from_slot(top!()), *n);
                    set_top!(p.to_slot());
                }
                Op::FetchInd(elem) if ST => {
                    let p = Pointer::from_slot(top!());
                    let v = typed::load_at(mem, vars, &state.frame, p, *elem);
                    set_top!(v);
                }
                Op::StoreInd(elem) if ST => {
                    let v = pop!();
                    let p = Pointer::from_slot(pop!());
                    typed::store_at(mem, vars, &mut state.frame, p, *elem, v);
                }
                Op::Copy(n) if ST => {
                    let src = Pointer::from_slot(pop!());
                    let dst = Pointer::from_slot(pop!());
                    typed::copy(vars, &mut state.frame, dst, src, *n as usize);
                }
                Op::Deref { size } if ST => {
                    match typed::deref(
                        top!(),
                        *size,
                        mem.words().len(),
                        vars.len(),
                        state.frame.len(),
                    ) {
                        Ok(p) => set_top!(p.to_slot()),
                        Err(code) => {
                            set_top!(Pointer::DISCARD.to_slot());
                            fail!(code);
                        }
                    }
                }
                Op::CheckRef(size) if ST => {
                    let p = Pointer::from_slot(top!());
                    let words = mem.words().len();
                    if p.space != Space::Discard
                        && !typed::reaches(p, *size, words, vars.len(), state.frame.len())
                    {
                        set_top!(Pointer::DISCARD.to_slot());
                        fail!(ERR_REF_RANGE);
                    }
                }
                Op::RefAdd if ST => {
                    let n = pop!();
                    match typed::ref_add(top!(), n) {
                        Ok(r) => set_top!(r),
                        Err(code) => {
                            set_top!(0);
                            fail!(code);
                        }
                    }
                }
                Op::RefDiff if ST => {
                    let b = pop!();
                    match typed::ref_diff(top!(), b) {
                        Some(d) => set_top!(d),
                        None => {
                            set_top!(0);
                            fail!(ERR_REF_RANGE);
                        }
                    }
                }
                Op::Bin { op, elem } if ST => {
                    let b = pop!();
                    let a = top!();
                    match typed::binary(*op, *elem, a, b) {
                        Ok(r) => set_top!(r),
                        Err(value::OpError::DivideByZero) => {
                            set_top!(0);
                            fail!(ERR_DIVIDE_BY_ZERO);
                        }
                    }
                }
                Op::Un { op, elem } if ST => {
                    let a = top!();
                    set_top!(typed::unary(*op, *elem, a));
                }
                Op::Cmp { op, elem } if ST => {
                    let b = pop!();
                    let a = top!();
                    let holds = op.holds(value::compare(*elem, a, b));
                    set_top!(u64::from(holds));
                }
                Op::Conv { from, to } if ST => {
                    let a = top!();
                    set_top!(typed::convert(*from, *to, a));
                }
                Op::Dup if ST => push!(top!()),
                Op::Drop if ST => {
                    pop!();
                }
                Op::Goto(target) if ST => jump!(*target),
                Op::GotoIf { target, when } if ST => {
                    if (pop!() != 0) == *when {
                        jump!(*target);
                    }
                }
                Op::CallFn { target, frame } if ST => {
                    let this = state.regs.this;
                    st_call!(*target, *frame, this);
                }
                Op::CallFb { target, frame } if ST => {
                    let this = pop!();
                    st_call!(*target, *frame, this);
                }
                Op::Return if ST => {
                    let Some(depth) = state.regs.st_depth.checked_sub(1) else {
                        // Unreachable for checked programs: a PROGRAM body ends with END.
                        state.finished = true;
                        halt!(Exit::End);
                    };
                    state.regs.st_depth = depth;
                    let frame = state.st_calls[depth as usize];
                    state.regs.base = frame.base;
                    state.regs.this = frame.this;
                    jump!(frame.return_pc);
                }
                Op::Now if ST => {
                    let steps = stop - left + taken!() as u64;
                    push!(clock.now_ns(steps));
                }
                Op::Utc if ST => {
                    let steps = stop - left + taken!() as u64;
                    push!(clock.utc_ns(steps));
                }
                Op::Str { op, cap, wide } if ST => {
                    state.eval.set_sp(sp);
                    if *wide {
                        wide::string_op(&mut state.eval, vars, &mut state.frame, *op, *cap);
                    } else {
                        typed::string_op(&mut state.eval, vars, &mut state.frame, *op, *cap);
                    }
                    sp = state.eval.sp();
                }
                // An op of the other language: never in a program of this one (the assembler
                // emits the instruction list's ops, the Structured Text compiler its own).
                _ => debug_assert!(false, "{op:?} in a program of the other language"),
            }
        }
    }
}

/// A timer instruction, out of line: its state machine is long next to a contact's.
#[inline(never)]
fn run_timer<C: Clock>(
    state: &mut timer::TimerState,
    call: timer::TimerInput,
    clock: &C,
    steps: u64,
) -> (u16, bool) {
    timer::execute(state, timer::TimerInput { now_ns: clock.now_ns(steps), ..call })
}

#[inline(always)]
fn read(mem: &Memory, src: Src) -> u16 {
    match src {
        Src::Word(w) => mem.word(w),
        Src::Const(c) => c,
    }
}

/// A double-word operand's value: the word and the next (low word first), or the constant's
/// low 32 bits. A word outside memory (never, in a checked program) reads 0.
#[inline(always)]
fn read_wide(mem: &Memory, consts: &[u64], w: Wide) -> u32 {
    match w {
        Wide::Word(w) => {
            let words = mem.words();
            let lo = words.get(w.0 as usize).copied().unwrap_or(0);
            let hi = words.get(w.0 as usize + 1).copied().unwrap_or(0);
            u32::from(lo) | u32::from(hi) << 16
        }
        Wide::Const(index) => consts.get(index as usize).copied().unwrap_or(0) as u32,
    }
}

/// Writes a double word at `d` and the word after it; nothing outside memory.
#[inline(always)]
fn write_wide(mem: &mut Memory, d: WordRef, value: u32) {
    if (d.0 as usize + 1) < mem.words().len() {
        mem.set_word(d, value as u16);
        mem.set_word(WordRef(d.0 + 1), (value >> 16) as u16);
    }
}

/// `a op b` of the `D` (`elem` I32) or `R` (F32) instructions; `None` on a division by zero.
#[inline(never)]
fn wide_arith(op: ArithOp, elem: Elem, a: u32, b: u32) -> Option<u32> {
    let op = match op {
        ArithOp::Add => value::BinOp::Add,
        ArithOp::Sub => value::BinOp::Sub,
        ArithOp::Mul => value::BinOp::Mul,
        ArithOp::Div => value::BinOp::Div,
    };
    // I32 slots are sign-extended, F32 slots the bits.
    let slot = |v: u32| if elem == Elem::I32 { v as i32 as i64 as u64 } else { u64::from(v) };
    value::binary(op, elem, slot(a), slot(b)).ok().map(|r| r as u32)
}

/// A conversion of `I2D`, `D2R`, …: `s` is the source's word (16-bit sources use its low half),
/// the result's low 16 or 32 bits are the destination's.
#[inline(never)]
fn wide_convert(conv: WideConv, s: u32) -> u32 {
    let (from, to, slot) = match conv {
        WideConv::IntToDint => (Elem::I16, Elem::I32, s as i16 as i64 as u64),
        WideConv::IntToReal => (Elem::I16, Elem::F32, s as i16 as i64 as u64),
        WideConv::DintToInt => (Elem::I32, Elem::I16, s as i32 as i64 as u64),
        WideConv::DintToReal => (Elem::I32, Elem::F32, s as i32 as i64 as u64),
        WideConv::RealToInt => (Elem::F32, Elem::I16, u64::from(s)),
        WideConv::RealToDint => (Elem::F32, Elem::I32, u64::from(s)),
    };
    value::convert(from, to, slot) as u32
}

/// Combines a contact's `value` with the rung: the rung becomes `(value & (rung | !and)) | (rung
/// & or)`. Only `how`, fixed for each instruction, may be branched on, never `value`.
#[inline(always)]
fn combine(how: Combine, value: bool, rung: &mut bool, blocks: &mut u32) {
    // (AND: value needs the rung, OR: the rung stays, push).
    let (and, or, push) = match how {
        Combine::Load { push } => (false, false, push),
        Combine::And => (true, false, false),
        Combine::Or => (false, true, false),
    };
    let pushed = (*blocks << 1) | *rung as u32;
    *blocks = if push { pushed } else { *blocks };
    *rung = (value & (*rung | !and)) | (*rung & or);
}

/// All ones when `on`, else zero: a mask for branch-free writes.
#[inline(always)]
fn all(on: bool) -> u16 {
    u16::from(on).wrapping_neg()
}

/// Sets or clears `bit` without a branch.
#[inline(always)]
fn write_bit(mem: &mut Memory, bit: BitRef, on: bool) {
    let word = mem.word(WordRef(bit.word));
    mem.set_word(WordRef(bit.word), (word & !bit.mask) | (bit.mask & all(on)));
}

/// True at the rising edge of `rung` as seen by edge slot `slot`.
#[inline(always)]
fn pulse(edges: &mut [bool], slot: u16, rung: bool) -> bool {
    let before = std::mem::replace(&mut edges[slot as usize], rung);
    rung && !before
}

/// Whether a data instruction executes: on the rung, or on its rising edge for the `P` form.
#[inline(always)]
fn enabled(edges: &mut [bool], slot: Option<u16>, rung: bool) -> bool {
    match slot {
        None => rung,
        Some(slot) => pulse(edges, slot, rung),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::Address;
    use crate::lang::{self, Context};
    use std::path::Path;

    fn assemble(source: &str) -> Program {
        let base = |n: u32| Some(if n >= 1500 { 1 } else { 100 });
        let ctx = Context { is_init: false, task_numbers: &[], timer_base_ms: &base, edge_base: 0 };
        lang::assemble("t", Path::new("t.il"), source, &ctx)
            .unwrap_or_else(|d| panic!("does not assemble: {d:?}"))
    }

    fn word(vm: &Vm, device: &str) -> i32 {
        vm.mem.read(&Address::parse(device).unwrap())
    }

    /// Every instruction kind, an operation error of each kind the loop raises, a system
    /// request, and timers on a clock that charges each step.
    const EVERYTHING: &str = "\
        LOAD _ON\nFOR 3\nINC D00001\nLOAD= D00001 5\nBREAK\nNEXT\n\
        LOAD _ON\nJMP 1\nINC D00002\nLABEL 1\n\
        CALL 1\n\
        LOAD _ON\nDIV D00003 D00004 D00005\nADD D00001 2 D00003\n\
        LOAD NOT M0005\nOUT M0005\n\
        LOADP M0005\nOUTP M0002\nLOAD M0005\nMOVP D00001 D00006\nINCP D00008\n\
        LOAD M0005\nTON T1500 3\nLOAD T1500\nOUT M0004\nCTU C0001 2\n\
        LOAD M0005\nTOFF T1501 2\nTMR T1502 9\nLOAD M0005\nCTUD C0002 M0005 M0004 3\n\
        LOAD C0001\nRST C0001\nLOAD T1500\nRST T1502\n\
        LOAD M0005\nLOAD M0004\nOR LOAD\nMPUSH\nOUT M0006\nMPOP\nNOT\nOUT M0007\n\
        LOAD>= D00001 3\nAND<> D00002 1\nSET M0008\nLOAD< D00001 0\nRST M0008\n\
        LOAD _ON\nTON T1503 1000\nDUTY 1 1 SM420\nWDT\nFF M0009\nEND\n\
        SBRT 1\nINC D00007\nLOAD< D00007 20\nCALL 1\nRET\n";

    /// Scans `program` five times, giving `run` `budget` steps at a time: every exit but
    /// `Budget` with the pc and step count it left, and the memory at the end.
    fn trace(program: &Program, budget: u64) -> (Vec<(Exit, u32, u64)>, Vec<u16>) {
        let mut vm = Vm::for_programs([program]);
        let clock = StepClock { origin_ns: 0, origin_steps: 0, step_ns: 250_000 };
        let mut state = ExecState::new();
        let mut exits = Vec::new();
        for _ in 0..5 {
            vm.begin_scan(false, 0);
            state.restart();
            loop {
                match vm.run(program, &mut state, &clock, budget) {
                    Exit::Budget => continue,
                    exit => exits.push((exit, state.pc(), vm.steps())),
                }
                if state.is_finished() {
                    break;
                }
            }
            vm.end_scan();
        }
        (exits, vm.mem.words().to_vec())
    }

    #[test]
    fn any_budget_gives_the_same_exits_steps_and_memory() {
        let program = assemble(EVERYTHING);
        let whole = trace(&program, u64::MAX);
        let errors = |code| {
            whole
                .0
                .iter()
                .filter(|e| matches!(e.0, Exit::OperationError { code: c, .. } if c == code))
                .count()
        };
        assert_eq!(errors(ERR_DIVIDE_BY_ZERO), 5);
        assert_eq!(errors(ERR_CALL_DEPTH), 1);
        assert!(whole.0.iter().any(|e| e.0 == Exit::System(SystemRequest::ResetWatchdog)));
        for budget in [1, 2, 3, 5, 8, 13] {
            assert!(trace(&program, budget) == whole, "budget {budget} differs");
        }
    }

    /// Native code that hands every instruction to the interpreter: a run with it attached
    /// takes `Vm::run`'s native path, and its hand-backs, at every step.
    #[derive(Debug)]
    struct Interpreting;

    impl native::NativeCode for Interpreting {
        fn run(
            &self,
            _memory: &mut native::NativeMemory<'_>,
            _il: Option<&mut native::IlMemory<'_>>,
            _regs: &mut native::NativeRegs,
        ) -> native::NativeExit {
            native::NativeExit::Interpret
        }

        fn interpret_span(&self, _pc: u32) -> u32 {
            1
        }
    }

    #[test]
    fn native_code_that_hands_everything_back_runs_as_the_interpreter() {
        let program = assemble(EVERYTHING);
        let whole = trace(&program, u64::MAX);
        let mut handing = program.clone();
        handing.native = Some(std::sync::Arc::new(Interpreting));
        for budget in [u64::MAX, 1, 2, 3, 5, 8, 13] {
            assert!(trace(&handing, budget) == whole, "budget {budget} differs");
        }
    }

    #[test]
    fn the_rest_of_a_native_run_without_native_code_is_the_interpreters() {
        let program = assemble(EVERYTHING);
        let whole = {
            let mut vm = Vm::for_programs([&program]);
            let mut state = ExecState::new();
            let exit = vm.run(&program, &mut state, &ManualClock::new(0), 7);
            (exit, state.pc(), vm.steps())
        };
        let mut vm = Vm::for_programs([&program]);
        let mut state = ExecState::new();
        let exit = vm.run_native_on(&program, &mut state, &ManualClock::new(0), 7);
        assert_eq!((exit, state.pc(), vm.steps()), whole);
    }

    #[test]
    fn restart_brings_back_the_registers_a_program_starts_with() {
        // Stopped inside the subroutine, in a FOR loop of its caller's, a block open: the
        // activation's registers all away from their start.
        let program = assemble(
            "LOAD _ON\nFOR 2\nLOAD _ON\nCALL 1\nNEXT\nEND\n\
             SBRT 1\nLOAD _ON\nLOAD _ON\nMPUSH\nNOP\nNOP\nNOP\nMPOP\nOR LOAD\nOUT M0001\nRET\n",
        );
        let mut vm = Vm::for_programs([&program]);
        let mut state = ExecState::new();
        assert_eq!(vm.run(&program, &mut state, &ManualClock::new(0), 8), Exit::Budget);
        let moved = state.regs;
        assert!(moved.pc != 0 && moved.il_depth == 1 && moved.loop_depth == 1, "{moved:?}");
        assert!(moved.blocks != 0 && moved.branches != 0, "{moved:?}");
        state.st_calls[0] = StFrame { return_pc: 3, base: 8, this: 5 };
        state.regs.st_depth = 1;
        state.regs.base = 8;
        state.regs.this = 5;
        state.regs.rung = 0;
        state.restart();
        // All but a run's own, which each run sets before it reads them.
        let own = native::NativeRegs { left: 0, sp: 0, error: 0, ..state.regs };
        assert_eq!(own, native::NativeRegs { left: 0, sp: 0, error: 0, ..START });
        assert_eq!((state.is_finished(), state.eval_depth()), (false, 0));
    }

    #[test]
    fn an_operation_error_reports_its_own_instruction() {
        let program = assemble("NOP\nNOP\nLOAD _ON\nDIV 1 D00000 D00001\nNOP\nEND");
        let mut vm = Vm::for_programs([&program]);
        let mut state = ExecState::new();
        let exit = vm.run(&program, &mut state, &ManualClock::new(0), u64::MAX);
        assert_eq!(exit, Exit::OperationError { code: ERR_DIVIDE_BY_ZERO, pc: 3 });
        assert_eq!((state.pc(), vm.steps()), (4, 4));
        assert_eq!(vm.run(&program, &mut state, &ManualClock::new(0), u64::MAX), Exit::End);
        assert_eq!(vm.steps(), 6);
    }

    #[test]
    fn timers_see_the_step_clock_at_their_own_instruction() {
        // T1500 has a 1 ms base; each step costs 1 ms.
        let program = assemble("NOP\nNOP\nLOAD _ON\nTON T1500 100\nEND");
        let mut vm = Vm::for_programs([&program]);
        let clock = StepClock { origin_ns: 0, origin_steps: 0, step_ns: 1_000_000 };
        let mut state = ExecState::new();
        assert_eq!(vm.run(&program, &mut state, &clock, u64::MAX), Exit::End);
        assert_eq!(word(&vm, "T1500"), 0, "started at step 4");
        state.restart();
        assert_eq!(vm.run(&program, &mut state, &clock, 2), Exit::Budget);
        assert_eq!(vm.run(&program, &mut state, &clock, u64::MAX), Exit::End);
        assert_eq!(word(&vm, "T1500"), 5, "step 9 is 5 ms after step 4");
    }
}
