//! The compiled, pre-decoded instruction form the VM executes.
//!
//! One [`Op`] per source instruction, so a step counted by the VM is a step the user wrote.
//! Every operand is resolved: bits are a word index and a mask, words an index, constants their
//! 16-bit pattern, jump and call targets program-counter values, edge memory a slot number.
//! Rung structure is resolved too: a contact that opens a nested block (`LOAD` inside a rung)
//! is a distinct op (`LoadPush`, `LoadNotPush`, or an edge or compare contact whose
//! [`Combine::Load`] has `push`), so the VM never has to guess where a rung starts.

use crate::device::{BitRef, WordRef};

/// A word operand: a device word or a constant (its 16-bit pattern).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Src {
    Word(WordRef),
    Const(u16),
}

/// Index into the VM's edge memory: one slot per edge-sensitive instruction instance.
pub type EdgeSlot = u16;

/// A comparison. Each discriminant is the comparison's truth table: bit 0 its result when
/// a < b, bit 1 when a = b, bit 2 when a > b, so that [`CmpOp::eval`] is a shift, not a branch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum CmpOp {
    Eq = 0b010,
    Ne = 0b101,
    Gt = 0b100,
    Ge = 0b110,
    Lt = 0b001,
    Le = 0b011,
}

impl CmpOp {
    /// `a op b`, signed.
    #[inline(always)]
    pub fn eval(self, a: i16, b: i16) -> bool {
        // 0 for a < b, 1 for a = b, 2 for a > b.
        let order = u8::from(a >= b) + u8::from(a > b);
        (self as u8 >> order) & 1 != 0
    }
}

/// How a contact combines with the rung result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Combine {
    /// Starts the rung (or, with `push`, a nested block whose result is pushed first).
    Load {
        push: bool,
    },
    And,
    Or,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArithOp {
    Add,
    Sub,
    Mul,
    Div,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimerKind {
    /// On delay.
    Ton,
    /// Off delay.
    Toff,
    /// Integrating (retentive) on delay, cleared only by `RST`.
    Tmr,
    /// Monostable: ignores its input while running.
    Tmon,
    /// Retriggerable monostable.
    Trtg,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CounterKind {
    Ctu,
    Ctd,
    Ctr,
}

/// An instruction the task engine acts on; the VM stops after executing it and reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SystemRequest {
    /// `DI` (all tasks) or `DI n`.
    DisableTasks(Option<u8>),
    /// `EI` (all tasks) or `EI n`.
    EnableTasks(Option<u8>),
    /// `WDT`: restart the scan watchdog's elapsed time.
    ResetWatchdog,
    /// `INIT_DONE`: the initialization task is finished.
    InitDone,
    /// `STOP`: go to STOP mode after this instruction.
    Stop,
    /// `IORF`: refresh the I/O image now.
    RefreshIo,
}

/// A compiled instruction.
///
/// `repr(u8)`: the variant is a plain byte at offset 0, so the VM dispatches with one byte
/// load and a jump table (the default layout hides it in a niche of the fields, which costs a
/// subtract, a conditional move and a range check per instruction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Op {
    // Contacts. `Load` starts a rung; `LoadPush` pushes the rung result, then starts a block.
    Load(BitRef),
    LoadNot(BitRef),
    LoadPush(BitRef),
    LoadNotPush(BitRef),
    And(BitRef),
    AndNot(BitRef),
    Or(BitRef),
    OrNot(BitRef),
    /// `LOADP`/`ANDP`/`ORP` (`rising`) and `LOADN`/`ANDN`/`ORN`.
    EdgeContact {
        bit: BitRef,
        rising: bool,
        how: Combine,
        slot: EdgeSlot,
    },
    /// `LOAD>= a b` and friends.
    Compare {
        op: CmpOp,
        a: Src,
        b: Src,
        how: Combine,
    },
    AndLoad,
    OrLoad,
    MPush,
    MLoad,
    MPop,
    Not,

    // Outputs.
    Out(BitRef),
    OutNot(BitRef),
    /// `OUTP` (`rising`) / `OUTN`: ON for one execution at the rung's edge.
    OutPulse {
        bit: BitRef,
        rising: bool,
        slot: EdgeSlot,
    },
    Set(BitRef),
    Rst(BitRef),
    /// `RST Tn`: resets the timer.
    RstTimer(u16),
    /// `RST Cn`: resets the counter.
    RstCounter(u16),
    /// `FF x`: toggles at the rung's rising edge.
    FlipFlop {
        bit: BitRef,
        slot: EdgeSlot,
    },

    // Timers and counters; the rung result is their input.
    Timer {
        kind: TimerKind,
        timer: u16,
        preset: Src,
        base_ms: u16,
    },
    Counter {
        kind: CounterKind,
        counter: u16,
        preset: Src,
    },
    /// `CTUD Cn up down preset`: counts while the rung is ON.
    CounterUpDown {
        counter: u16,
        up: BitRef,
        down: BitRef,
        preset: Src,
    },

    // Data. `pulse`: the `P` form, executed only at the rung's rising edge.
    Mov {
        s: Src,
        d: WordRef,
        pulse: Option<EdgeSlot>,
    },
    Arith {
        op: ArithOp,
        a: Src,
        b: Src,
        d: WordRef,
        pulse: Option<EdgeSlot>,
    },
    /// `INC d` (`up`) / `DEC d`.
    Step {
        d: WordRef,
        up: bool,
        pulse: Option<EdgeSlot>,
    },

    // Flow.
    /// `CALL n`, resolved to the first instruction after `SBRT n`.
    Call {
        target: u32,
    },
    Ret,
    /// `JMP n`, resolved to the `LABEL n` instruction.
    Jmp {
        target: u32,
    },
    /// `LABEL n`: a rung boundary.
    Label,
    /// `FOR n`: `end` is the instruction after the matching `NEXT`.
    For {
        count: Src,
        end: u32,
    },
    /// `NEXT`: `body` is the instruction after the matching `FOR`.
    Next {
        body: u32,
    },
    Break,
    End,
    Nop,

    // System.
    System(SystemRequest),
    /// `DUTY n1 n2 d`; `channel` 0..=4 is SM420+channel.
    Duty {
        channel: u8,
        n1: Src,
        n2: Src,
        slot: EdgeSlot,
    },
}

/// The device an instruction writes as its result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Written {
    Bit(BitRef),
    Word(WordRef),
}

/// What an instruction keeps in its edge-memory slot, to see an edge at its next execution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeMemory {
    /// The contact's value at the last execution (`LOADP`, `ANDN`, …).
    Contact(BitRef),
    /// The rung result at the last execution; the instruction acts on its rising edge
    /// (`rising`: `OUTP`, `FF`, `DUTY`, the `P` forms) or its falling edge (`OUTN`).
    Rung { rising: bool },
}

impl Op {
    /// The device the instruction writes as its result (outputs, `SET`/`RST` of a bit, the
    /// destination of data instructions); timers, counters and flow write none a program names.
    pub fn writes(&self) -> Option<Written> {
        match *self {
            Op::Out(b) | Op::OutNot(b) | Op::Set(b) | Op::Rst(b) => Some(Written::Bit(b)),
            Op::OutPulse { bit, .. } | Op::FlipFlop { bit, .. } => Some(Written::Bit(bit)),
            Op::Mov { d, .. } | Op::Arith { d, .. } | Op::Step { d, .. } => Some(Written::Word(d)),
            _ => None,
        }
    }

    /// The edge-memory slot the instruction owns and what it keeps there; `None` for an
    /// instruction that sees no edges.
    pub fn edge_memory(&self) -> Option<(EdgeSlot, EdgeMemory)> {
        match *self {
            Op::EdgeContact { bit, slot, .. } => Some((slot, EdgeMemory::Contact(bit))),
            Op::OutPulse { rising, slot, .. } => Some((slot, EdgeMemory::Rung { rising })),
            Op::FlipFlop { slot, .. } | Op::Duty { slot, .. } => {
                Some((slot, EdgeMemory::Rung { rising: true }))
            }
            Op::Mov { pulse: Some(slot), .. }
            | Op::Arith { pulse: Some(slot), .. }
            | Op::Step { pulse: Some(slot), .. } => Some((slot, EdgeMemory::Rung { rising: true })),
            _ => None,
        }
    }
}

// The dispatch loop walks an array of these; keep each within 16 bytes, four to a cache line.
const _: () = assert!(std::mem::size_of::<Op>() <= 16);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compares_follow_their_truth_tables() {
        use CmpOp::*;
        for (a, b) in [(-3i16, 2i16), (2, 2), (7, -7), (i16::MIN, i16::MAX), (0, -1)] {
            assert_eq!(Eq.eval(a, b), a == b);
            assert_eq!(Ne.eval(a, b), a != b);
            assert_eq!(Gt.eval(a, b), a > b);
            assert_eq!(Ge.eval(a, b), a >= b);
            assert_eq!(Lt.eval(a, b), a < b);
            assert_eq!(Le.eval(a, b), a <= b);
        }
    }
}
