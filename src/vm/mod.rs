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

pub mod clock;
pub mod counter;
pub mod duty;
pub mod timer;

pub use clock::{Clock, ManualClock, StepClock};

use crate::device::Memory;
use crate::lang::ops::{ArithOp, Combine, Op, Src, SystemRequest};
use crate::lang::{Program, CALL_DEPTH, LOOP_DEPTH};

/// Operation error: division by zero.
pub const ERR_DIVIDE_BY_ZERO: u16 = 0x3400;
/// Operation error: a value out of range (DUTY n1/n2 from a device).
pub const ERR_VALUE_RANGE: u16 = duty::ERR_DUTY_RANGE;
/// Operation error: `CALL` nested deeper than [`CALL_DEPTH`].
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

#[derive(Debug, Clone, Copy, Default)]
struct CallFrame {
    return_pc: u32,
    rung: bool,
    blocks: u32,
    branches: u32,
    loop_depth: u8,
}

#[derive(Debug, Clone, Copy, Default)]
struct LoopFrame {
    remaining: u16,
    end: u32,
}

/// Where one activation of a program stands.
#[derive(Debug, Clone)]
pub struct ExecState {
    pc: u32,
    /// The rung result.
    rung: bool,
    /// The block stack of `LOAD … AND LOAD/OR LOAD`, one bit a level, top in bit 0.
    blocks: u32,
    /// The `MPUSH` stack, one bit a level, top in bit 0.
    branches: u32,
    calls: [CallFrame; CALL_DEPTH],
    call_depth: u8,
    loops: [LoopFrame; LOOP_DEPTH],
    loop_depth: u8,
    finished: bool,
}

impl Default for ExecState {
    fn default() -> Self {
        Self::new()
    }
}

impl ExecState {
    /// A state at the program's first instruction.
    pub fn new() -> ExecState {
        ExecState {
            pc: 0,
            rung: true,
            blocks: 0,
            branches: 0,
            calls: [CallFrame::default(); CALL_DEPTH],
            call_depth: 0,
            loops: [LoopFrame::default(); LOOP_DEPTH],
            loop_depth: 0,
            finished: false,
        }
    }

    /// Back to the first instruction, for the next execution of the program.
    pub fn restart(&mut self) {
        self.pc = 0;
        self.rung = true;
        self.blocks = 0;
        self.branches = 0;
        self.call_depth = 0;
        self.loop_depth = 0;
        self.finished = false;
    }

    /// The next instruction to execute.
    pub fn pc(&self) -> u32 {
        self.pc
    }

    /// True once the program has executed `END`.
    pub fn is_finished(&self) -> bool {
        self.finished
    }
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
        }
    }

    /// A VM sized for `programs`.
    pub fn for_programs<'a>(programs: impl IntoIterator<Item = &'a Program>) -> Vm {
        let slots = programs.into_iter().map(|p| p.edge_base + p.edge_slots).max().unwrap_or(0);
        Vm::new(slots)
    }

    /// Online change: takes the machine state of `old` (device memory, timers, counters, DUTY
    /// clocks, the step count) by swapping, and sets up this VM's edge memory by `edges`. No
    /// allocation.
    pub fn take_over(&mut self, old: &mut Vm, edges: &[EdgeInit]) {
        std::mem::swap(&mut self.mem, &mut old.mem);
        std::mem::swap(&mut self.timers, &mut old.timers);
        std::mem::swap(&mut self.counters, &mut old.counters);
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

    /// Instructions executed since the VM was created.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// RUN start: data areas cleared except K and `retained` word ranges; timers, counters,
    /// edges and DUTY clocks back to their initial state.
    pub fn reset_for_run(&mut self, retained: &[std::ops::Range<usize>]) {
        self.mem.clear_for_run(retained);
        self.timers.fill(timer::TimerState::default());
        self.counters.fill(counter::CounterState::default());
        self.edges.fill(false);
        self.duty = [duty::DutyClock::default(); duty::CHANNELS];
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
    /// instruction.
    ///
    /// The loop is split in two for speed. This function keeps the activation's registers
    /// (program counter, rung result, rung stacks, remaining budget) in locals and executes the
    /// frequent instructions — contacts, compares, outputs, rung stacks, unconditional data
    /// moves and arithmetic, jumps — inline; every other instruction goes through
    /// [`Vm::execute_rare`], which works on the saved [`ExecState`]. Keeping the rare
    /// instructions (timers, counters, edges, calls, loops, system) out of line keeps the hot
    /// loop's registers free and its per-instruction overhead to a bounds check, a budget
    /// count and one indirect jump.
    pub fn run<C: Clock>(
        &mut self,
        program: &Program,
        state: &mut ExecState,
        clock: &C,
        max_steps: u64,
    ) -> Exit {
        let code: &[Op] = &program.code;
        let mut pc = state.pc as usize;
        let mut rung = state.rung;
        let mut blocks = state.blocks;
        let mut branches = state.branches;
        // The budget counts down; the step count is `stop - left`.
        let stop = self.steps.saturating_add(max_steps);
        let mut left = stop - self.steps;

        macro_rules! save {
            () => {{
                state.pc = pc as u32;
                state.rung = rung;
                state.blocks = blocks;
                state.branches = branches;
                self.steps = stop - left;
            }};
        }
        macro_rules! fail {
            ($at:expr, $code:expr) => {{
                let code = $code;
                self.mem.raise_operation_error(code);
                save!();
                return Exit::OperationError { code, pc: $at };
            }};
        }

        loop {
            if left == 0 {
                save!();
                return Exit::Budget;
            }
            let Some(op) = code.get(pc) else {
                // Only a program without END could get here, and the checker refuses those.
                state.finished = true;
                save!();
                return Exit::End;
            };
            pc += 1;
            left -= 1;
            let mem = &mut self.mem;
            match op {
                Op::Load(b) => rung = mem.bit(*b),
                Op::LoadNot(b) => rung = !mem.bit(*b),
                Op::LoadPush(b) => {
                    blocks = (blocks << 1) | rung as u32;
                    rung = mem.bit(*b);
                }
                Op::LoadNotPush(b) => {
                    blocks = (blocks << 1) | rung as u32;
                    rung = !mem.bit(*b);
                }
                Op::And(b) => rung &= mem.bit(*b),
                Op::AndNot(b) => rung &= !mem.bit(*b),
                Op::Or(b) => rung |= mem.bit(*b),
                Op::OrNot(b) => rung |= !mem.bit(*b),
                Op::Compare { op, a, b, how } => {
                    let result = op.eval(read(mem, *a) as i16, read(mem, *b) as i16);
                    combine(*how, result, &mut rung, &mut blocks);
                }
                Op::AndLoad => {
                    rung &= blocks & 1 != 0;
                    blocks >>= 1;
                }
                Op::OrLoad => {
                    rung |= blocks & 1 != 0;
                    blocks >>= 1;
                }
                Op::MPush => branches = (branches << 1) | rung as u32,
                Op::MLoad => rung = branches & 1 != 0,
                Op::MPop => {
                    rung = branches & 1 != 0;
                    branches >>= 1;
                }
                Op::Not => rung = !rung,
                Op::Out(b) => mem.set_bit(*b, rung),
                Op::OutNot(b) => mem.set_bit(*b, !rung),
                Op::Set(b) => {
                    if rung {
                        mem.set_bit(*b, true);
                    }
                }
                Op::Rst(b) => {
                    if rung {
                        mem.set_bit(*b, false);
                    }
                }
                Op::Mov { s, d, pulse: None } => {
                    if rung {
                        let value = read(mem, *s);
                        mem.set_word(*d, value);
                    }
                }
                Op::Arith { op, a, b, d, pulse: None } => {
                    if rung {
                        let (a, b) = (read(mem, *a) as i16, read(mem, *b) as i16);
                        let value = match op {
                            ArithOp::Add => a.wrapping_add(b),
                            ArithOp::Sub => a.wrapping_sub(b),
                            ArithOp::Mul => a.wrapping_mul(b),
                            ArithOp::Div => {
                                if b == 0 {
                                    fail!(pc as u32 - 1, ERR_DIVIDE_BY_ZERO);
                                }
                                a.wrapping_div(b)
                            }
                        };
                        mem.set_word(*d, value as u16);
                    }
                }
                Op::Step { d, up, pulse: None } => {
                    if rung {
                        let value = mem.word(*d);
                        let value = if *up { value.wrapping_add(1) } else { value.wrapping_sub(1) };
                        mem.set_word(*d, value);
                    }
                }
                Op::Jmp { target } => {
                    if rung {
                        pc = *target as usize;
                    }
                }
                Op::Label => rung = true,
                Op::Nop => {}
                Op::End => {
                    state.finished = true;
                    save!();
                    return Exit::End;
                }
                _ => {
                    save!();
                    if let Some(exit) = self.execute_rare(op, state, clock) {
                        return exit;
                    }
                    pc = state.pc as usize;
                    rung = state.rung;
                    blocks = state.blocks;
                    branches = state.branches;
                }
            }
        }
    }

    /// Executes one instruction that [`Vm::run`] does not handle inline, on the registers
    /// saved in `state` (its `pc` already points past `op`, `self.steps` counts `op`). `Some`
    /// when `run` must return.
    #[inline(never)]
    fn execute_rare<C: Clock>(
        &mut self,
        op: &Op,
        state: &mut ExecState,
        clock: &C,
    ) -> Option<Exit> {
        let at = state.pc - 1;
        let mut pc = state.pc as usize;
        let mut rung = state.rung;
        let mut blocks = state.blocks;
        let mut branches = state.branches;
        let steps = self.steps;

        macro_rules! save {
            () => {{
                state.pc = pc as u32;
                state.rung = rung;
                state.blocks = blocks;
                state.branches = branches;
            }};
        }
        macro_rules! fail {
            ($at:expr, $code:expr) => {{
                let code = $code;
                self.mem.raise_operation_error(code);
                save!();
                return Some(Exit::OperationError { code, pc: $at });
            }};
        }

        let mem = &mut self.mem;
        match *op {
            Op::EdgeContact { bit, rising, how, slot } => {
                let now = mem.bit(bit);
                let before = std::mem::replace(&mut self.edges[slot as usize], now);
                let edge = if rising { now && !before } else { !now && before };
                combine(how, edge, &mut rung, &mut blocks);
            }
            Op::OutPulse { bit, rising, slot } => {
                let before = std::mem::replace(&mut self.edges[slot as usize], rung);
                let edge = if rising { rung && !before } else { !rung && before };
                mem.set_bit(bit, edge);
            }
            Op::RstTimer(n) => {
                if rung {
                    timer::reset(&mut self.timers[n as usize], mem, n);
                }
            }
            Op::RstCounter(n) => {
                if rung {
                    counter::reset(&mut self.counters[n as usize], mem, n);
                }
            }
            Op::FlipFlop { bit, slot } => {
                if pulse(&mut self.edges, slot, rung) {
                    mem.set_bit(bit, !mem.bit(bit));
                }
            }
            Op::Timer { kind, timer: n, preset, base_ms } => {
                let preset = read(mem, preset);
                let call = timer::TimerInput {
                    kind,
                    timer: n,
                    input: rung,
                    preset,
                    base_ms,
                    now_ns: clock.now_ns(steps),
                };
                timer::execute(&mut self.timers[n as usize], mem, call);
            }
            Op::Counter { kind, counter: n, preset } => {
                let preset = read(mem, preset);
                let c = &mut self.counters[n as usize];
                counter::execute(kind, c, mem, n, rung, preset);
            }
            Op::CounterUpDown { counter: n, up, down, preset } => {
                let preset = read(mem, preset);
                let c = &mut self.counters[n as usize];
                counter::execute_up_down(c, mem, n, rung, up, down, preset);
            }
            Op::Mov { s, d, pulse: p } => {
                if enabled(&mut self.edges, p, rung) {
                    let value = read(mem, s);
                    mem.set_word(d, value);
                }
            }
            Op::Arith { op, a, b, d, pulse: p } => {
                if enabled(&mut self.edges, p, rung) {
                    let (a, b) = (read(mem, a) as i16, read(mem, b) as i16);
                    let value = match op {
                        ArithOp::Add => a.wrapping_add(b),
                        ArithOp::Sub => a.wrapping_sub(b),
                        ArithOp::Mul => a.wrapping_mul(b),
                        ArithOp::Div => {
                            if b == 0 {
                                fail!(at, ERR_DIVIDE_BY_ZERO);
                            }
                            a.wrapping_div(b)
                        }
                    };
                    mem.set_word(d, value as u16);
                }
            }
            Op::Step { d, up, pulse: p } => {
                if enabled(&mut self.edges, p, rung) {
                    let value = mem.word(d);
                    let value = if up { value.wrapping_add(1) } else { value.wrapping_sub(1) };
                    mem.set_word(d, value);
                }
            }
            Op::Call { target } => {
                if rung {
                    let depth = state.call_depth as usize;
                    if depth >= CALL_DEPTH {
                        fail!(at, ERR_CALL_DEPTH);
                    }
                    state.calls[depth] = CallFrame {
                        return_pc: pc as u32,
                        rung,
                        blocks,
                        branches,
                        loop_depth: state.loop_depth,
                    };
                    state.call_depth += 1;
                    pc = target as usize;
                    rung = true;
                    blocks = 0;
                    branches = 0;
                }
            }
            Op::Ret => {
                if state.call_depth == 0 {
                    // Unreachable for checked programs: RET ends a SBRT, reached by CALL.
                    state.finished = true;
                    save!();
                    return Some(Exit::End);
                }
                state.call_depth -= 1;
                let frame = state.calls[state.call_depth as usize];
                pc = frame.return_pc as usize;
                rung = frame.rung;
                blocks = frame.blocks;
                branches = frame.branches;
                state.loop_depth = frame.loop_depth;
            }
            Op::For { count, end } => {
                if rung {
                    let count = read(mem, count) as i16;
                    let depth = state.loop_depth as usize;
                    if count <= 0 {
                        pc = end as usize;
                    } else if depth >= LOOP_DEPTH {
                        pc = end as usize;
                        fail!(at, ERR_LOOP_DEPTH);
                    } else {
                        state.loops[depth] = LoopFrame { remaining: count as u16, end };
                        state.loop_depth += 1;
                    }
                } else {
                    pc = end as usize;
                }
                rung = true;
            }
            Op::Next { body } => {
                if let Some(depth) = (state.loop_depth as usize).checked_sub(1) {
                    let frame = &mut state.loops[depth];
                    frame.remaining -= 1;
                    if frame.remaining > 0 {
                        pc = body as usize;
                    } else {
                        state.loop_depth -= 1;
                    }
                }
                rung = true;
            }
            Op::Break => {
                if rung {
                    if let Some(depth) = (state.loop_depth as usize).checked_sub(1) {
                        pc = state.loops[depth].end as usize;
                        state.loop_depth -= 1;
                    }
                }
            }
            Op::System(request) => {
                if rung {
                    save!();
                    return Some(Exit::System(request));
                }
            }
            Op::Duty { channel, n1, n2, slot } => {
                let rising = pulse(&mut self.edges, slot, rung);
                if rung {
                    let clock = &mut self.duty[channel as usize];
                    if let Err(code) = duty::execute(clock, rising, read(mem, n1), read(mem, n2)) {
                        fail!(at, code);
                    }
                }
            }
            // `run` executes every other instruction inline and never passes it here.
            _ => unreachable!("{op:?} is executed by Vm::run"),
        }
        save!();
        None
    }
}

#[inline(always)]
fn read(mem: &Memory, src: Src) -> u16 {
    match src {
        Src::Word(w) => mem.word(w),
        Src::Const(c) => c,
    }
}

#[inline(always)]
fn combine(how: Combine, value: bool, rung: &mut bool, blocks: &mut u32) {
    match how {
        Combine::Load { push } => {
            if push {
                *blocks = (*blocks << 1) | *rung as u32;
            }
            *rung = value;
        }
        Combine::And => *rung &= value,
        Combine::Or => *rung |= value,
    }
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
