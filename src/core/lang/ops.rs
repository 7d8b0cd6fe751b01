//! The compiled, pre-decoded instruction form the VM executes.
//!
//! One [`Op`] per source instruction, so a step counted by the VM is a step the user wrote.
//! Every operand is resolved: bits are a word index and a mask, words an index, constants their
//! 16-bit pattern, jump and call targets program-counter values, edge memory a slot number.
//! Rung structure is resolved too: a contact that opens a nested block (`LOAD` inside a rung)
//! is a distinct op (`LoadPush`, `LoadNotPush`, or an edge or compare contact whose
//! [`Combine::Load`] has `push`), so the VM never has to guess where a rung starts.

use crate::device::{BitRef, WordRef};
use crate::value::{BinOp, Elem, UnOp};

/// A word operand: a device word or a constant (its 16-bit pattern).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Src {
    Word(WordRef),
    Const(u16),
}

/// A double-word operand of the instruction list's `D` and `R` instructions: a device word and
/// the one after it (the low word first), or a constant: an index into `Program::consts`, whose
/// low 32 bits are the value (a `DINT` pattern, or a `REAL`'s bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wide {
    Word(WordRef),
    Const(u16),
}

/// A conversion between the instruction list's 16-bit, 32-bit and real values (`I2D`, `D2R`, …).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum WideConv {
    /// 16-bit signed word to double word (`I2D`).
    IntToDint,
    /// Double word to 16-bit word, wrapping (`D2I`).
    DintToInt,
    /// 16-bit signed word to `REAL` (`I2R`).
    IntToReal,
    /// `REAL` to 16-bit word, rounded, saturated (`R2I`).
    RealToInt,
    /// Double word to `REAL` (`D2R`).
    DintToReal,
    /// `REAL` to double word, rounded, saturated (`R2D`).
    RealToDint,
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

    /// Whether the comparison holds for operands that compare as `order`; `None` (a NaN
    /// operand) satisfies only `<>`.
    #[inline(always)]
    pub fn holds(self, order: Option<std::cmp::Ordering>) -> bool {
        match order {
            // Less, Equal, Greater are -1, 0, 1: shifted to 0, 1, 2.
            Some(order) => (self as u8 >> (order as i8 + 1)) & 1 != 0,
            None => self == CmpOp::Ne,
        }
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

    // The instruction list's double-word (32-bit signed) and real (`REAL`) instructions, on the
    // typed operations of `crate::value`. A double-word destination `d` is `d` (low word) and
    // the word after it.
    /// `DMOV s d` (and `RMOV`): moves a double word.
    DMov {
        s: Wide,
        d: WordRef,
        pulse: Option<EdgeSlot>,
    },
    /// `DADD`, `DSUB`, `DMUL`, `DDIV`: 32-bit signed, wrapping.
    DArith {
        op: ArithOp,
        a: Wide,
        b: Wide,
        d: WordRef,
        pulse: Option<EdgeSlot>,
    },
    /// `RADD`, `RSUB`, `RMUL`, `RDIV`: `REAL`.
    RArith {
        op: ArithOp,
        a: Wide,
        b: Wide,
        d: WordRef,
        pulse: Option<EdgeSlot>,
    },
    /// `DINC d` (`up`) / `DDEC d`.
    DStep {
        d: WordRef,
        up: bool,
        pulse: Option<EdgeSlot>,
    },
    /// `LOADD= a b` and friends: 32-bit signed compare contacts.
    DCompare {
        op: CmpOp,
        a: Wide,
        b: Wide,
        how: Combine,
    },
    /// `LOADR= a b` and friends: `REAL` compare contacts (a NaN operand satisfies only `<>`).
    RCompare {
        op: CmpOp,
        a: Wide,
        b: Wide,
        how: Combine,
    },
    /// `I2D s d`, `D2R s d`, …: `s` is one word for the conversions from a 16-bit word (its
    /// `Wide::Word`), `d` one word for those to one.
    Convert {
        conv: WideConv,
        s: Wide,
        d: WordRef,
        pulse: Option<EdgeSlot>,
    },

    // The typed stack machine of Structured Text. Each op is one step, like an IL
    // instruction, so a task can be preempted between any two. Operands are slots on the
    // activation's evaluation stack (see `crate::value` for their encoding); "pops b, a" means
    // `b` is on top.
    /// Pushes a constant, sign-extended from 32 bits.
    PushInt(i32),
    /// Pushes `Program::consts[index]`.
    PushConst(u32),
    /// Pushes the value at `at`.
    Fetch {
        elem: Elem,
        at: Place,
    },
    /// Pops a value and stores it at `at`.
    Store {
        elem: Elem,
        at: Place,
    },
    /// Pushes a pointer to `at`.
    AddrOf(Place),
    /// Pops an index and a pointer to an array's first element; pushes a pointer to element
    /// `index - lo` (`stride` bytes, or words, or bits apart, by the pointer's space). An
    /// index outside `lo .. lo + len` pushes the discard pointer and raises an operation error.
    Index {
        lo: i32,
        len: u32,
        stride: u32,
    },
    /// Pops a pointer, pushes it moved by `n` (a struct member, an FB instance's variable).
    Offset(u32),
    /// Pops a pointer, pushes the value it points to.
    FetchInd(Elem),
    /// Pops a value, then a pointer; stores the value there.
    StoreInd(Elem),
    /// Pops a source pointer, then a destination pointer; copies `n` bytes (arrays, structs).
    Copy(u32),
    /// Pops a reference value (of a `REF_TO`, `POINTER TO` or `REFERENCE TO`), pushes the
    /// pointer it holds. A reference value is 0 for `NULL`, else the pointer's slot plus
    /// `1 << 32` (its space counted from 1), so that zeroed memory is `NULL`. Checked: `NULL`
    /// raises operation error 2822H; a pointer outside its memory area, or whose `size` bytes
    /// cross the area's end, raises 2820H; both push the discard pointer. `size` 0: members or
    /// elements follow (`r^.x`, `r^[i]`), checked by [`Op::CheckRef`] at the end of the
    /// path; they cannot follow into device memory (2820H).
    Deref {
        size: u32,
    },
    /// Pops a pointer reached through a reference by members and elements; pushes it when its
    /// `size` bytes are inside its memory area, else raises 2820H and pushes the discard
    /// pointer (which passes unchecked: the failure that made it was already raised).
    CheckRef(u32),
    /// Pops `n` (a `LINT`), then a reference value; pushes the reference moved by `n` bytes,
    /// its offset wrapping within 32 bits so that it never leaves its memory area. `NULL`
    /// moves and stays invalid; a pointer into device memory cannot move: 2820H, `NULL`.
    RefAdd,
    /// Pops two reference values b, a; pushes the `DINT` `a - b`, the distance in bytes from
    /// b's place to a's. Not both into one memory area (`NULL` included): 0 and 2820H.
    RefDiff,
    /// Pops b, a; pushes `a op b`. A failed operation pushes 0 and raises an operation error.
    Bin {
        op: BinOp,
        elem: Elem,
    },
    /// Pops a; pushes `op a`.
    Un {
        op: UnOp,
        elem: Elem,
    },
    /// Pops b, a; pushes the BOOL `a op b`.
    Cmp {
        op: CmpOp,
        elem: Elem,
    },
    /// Pops a slot of `from`, pushes it converted to `to`.
    Conv {
        from: Elem,
        to: Elem,
    },
    /// Pushes a copy of the top slot.
    Dup,
    /// Pops and forgets the top slot.
    Drop,
    /// Goes on at `target`.
    Goto(u32),
    /// Pops a BOOL; goes on at `target` when it equals `when`.
    GotoIf {
        target: u32,
        when: bool,
    },
    /// Calls the FUNCTION at `target`: its frame starts `frame` bytes after the caller's base
    /// (the caller has already stored the arguments there).
    CallFn {
        target: u32,
        frame: u32,
    },
    /// Pops a pointer to an FB instance and calls the FUNCTION_BLOCK body at `target` with it
    /// as `this`; its frame (`VAR_TEMP`) starts `frame` bytes after the caller's base.
    CallFb {
        target: u32,
        frame: u32,
    },
    /// Returns from a FUNCTION or FUNCTION_BLOCK body to its caller.
    Return,
    /// Pushes the clock's time in nanoseconds (an `I64`), for the standard timers.
    Now,
    /// Pushes the calendar time (`Clock::utc_ns`, nanoseconds since 1970-01-01 UTC, an `LDT`),
    /// for the real-time clock of ST programs.
    Utc,
    /// A string operation on pointers; `cap` is the destination's capacity, in characters.
    /// `wide`: the strings are `WSTRING`s (2-byte UTF-16 code units and a 2-byte NUL);
    /// [`StrOp::Widen`] and [`StrOp::Narrow`] convert between the two kinds.
    Str {
        op: StrOp,
        cap: u16,
        wide: bool,
    },
}

/// Where a typed operand of Structured Text lives, resolved when the program is compiled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// Variable memory (program instances and globals), byte offset.
    Var(u32),
    /// The current activation's frame (function locals, `VAR_TEMP`, temporaries), byte offset
    /// from the frame's base.
    Frame(u32),
    /// The current FB instance (`this`, a pointer set by [`Op::CallFb`]), byte offset into it.
    This(u32),
    /// A device word, and for 32/64-bit values the words after it (low word first).
    Word(WordRef),
    /// A device bit (a BOOL located at a bit device).
    Bit(BitRef),
    /// A device byte (an 8-bit value at an IEC byte address, `%QB1`): byte `n` is the low
    /// (even `n`) or high (odd `n`) half of device word `n / 2`. A store writes that half only.
    Byte(u32),
}

/// A string operation. Strings are passed as pointers ([`crate::value::Pointer`] slots) to
/// `STRING[n]` storage: n bytes of characters ended by a NUL, and a byte for the last NUL. `cap` of [`Op::Str`] is the capacity of
/// the destination; a longer result is cut to it. Stack effects (top last):
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum StrOp {
    /// `dst src` → ``: copies `src` into `dst`.
    Move,
    /// `s` → `len` (an `I64`).
    Len,
    /// `dst s n` → ``: the first `n` characters of `s` into `dst`.
    Left,
    /// `dst s n` → ``: the last `n`.
    Right,
    /// `dst s n p` → ``: `n` characters from position `p` (1-based).
    Mid,
    /// `dst a b` → ``: `a` then `b`.
    Concat,
    /// `a b` → `p`: the 1-based position of `b` in `a`, 0 if absent (an `I64`).
    Find,
    /// `a b` → `order`: -1, 0 or 1 as an `I64` (byte-wise), for the comparisons.
    Compare,
    /// `dst v` → ``: the text of the value `v` of a scalar type into `dst` (`*_TO_STRING`):
    /// `BOOL` as `TRUE`/`FALSE`, the others as `value::write_scalar` writes them.
    FromValue(crate::value::Scalar),
    /// `s` → `v`: the value the text `s` gives a scalar type (`STRING_TO_*`), as
    /// `value::scalar_from_text` reads it; 0 for a text that is none.
    ToValue(crate::value::Scalar),
    /// `dst src` → ``: the STRING `src` into the WSTRING `dst` (`STRING_TO_WSTRING`): each
    /// Windows-1252 byte as its UTF-16 code unit.
    Widen,
    /// `dst src` → ``: the WSTRING `src` into the STRING `dst` (`WSTRING_TO_STRING`): each
    /// code unit as its Windows-1252 byte, `?` for one Windows-1252 has not.
    Narrow,
}

/// The device an instruction writes as its result.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Written {
    /// A bit, or the bits of a mask (the eight of a byte stored at `Place::Byte`).
    Bit(BitRef),
    Word(WordRef),
    /// A double word: the word and the one after it.
    DoubleWord(WordRef),
    /// Four words from this one (a 64-bit Structured Text value located at a word device).
    QuadWord(WordRef),
}

impl Written {
    /// The device words written whole: `(first, count)`; `None` for a bit.
    pub fn words(self) -> Option<(WordRef, u16)> {
        match self {
            Written::Bit(_) => None,
            Written::Word(w) => Some((w, 1)),
            Written::DoubleWord(w) => Some((w, 2)),
            Written::QuadWord(w) => Some((w, 4)),
        }
    }
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
            Op::DMov { d, .. }
            | Op::DArith { d, .. }
            | Op::RArith { d, .. }
            | Op::DStep { d, .. } => Some(Written::DoubleWord(d)),
            Op::Convert { conv, d, .. } => {
                Some(if conv.to_one_word() { Written::Word(d) } else { Written::DoubleWord(d) })
            }
            // Structured Text: a store to a located variable. Stores through a pointer (an
            // element of a located array at a variable index) are not known before they run.
            Op::Store { at: Place::Bit(b), .. } => Some(Written::Bit(b)),
            // a byte: the eight bits of its half of the word, as a mask
            Op::Store { at: Place::Byte(n), .. } => {
                Some(Written::Bit(BitRef { word: (n / 2) as u16, mask: 0xFF << (8 * (n % 2)) }))
            }
            Op::Store { elem, at: Place::Word(w) } => Some(match elem.words() {
                1 => Written::Word(w),
                2 => Written::DoubleWord(w),
                _ => Written::QuadWord(w),
            }),
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
            | Op::Step { pulse: Some(slot), .. }
            | Op::DMov { pulse: Some(slot), .. }
            | Op::DArith { pulse: Some(slot), .. }
            | Op::RArith { pulse: Some(slot), .. }
            | Op::DStep { pulse: Some(slot), .. }
            | Op::Convert { pulse: Some(slot), .. } => {
                Some((slot, EdgeMemory::Rung { rising: true }))
            }
            _ => None,
        }
    }
}

impl Op {
    /// How a Structured Text op moves its activation's evaluation stack: `(popped, pushed)`
    /// slots; `None` for the instruction list's ops, which have no such stack. A call's callee
    /// starts its own slots above the caller's; the ST compiler checks the deepest chain of them
    /// against `EVAL_DEPTH`, and native code keeps them in registers by this same rule.
    pub fn stack_effect(&self) -> Option<(u32, u32)> {
        Some(match self {
            Op::PushInt(_)
            | Op::PushConst(_)
            | Op::Fetch { .. }
            | Op::AddrOf(_)
            | Op::Now
            | Op::Utc => (0, 1),
            Op::Dup => (1, 2),
            Op::Store { .. } | Op::Drop | Op::GotoIf { .. } | Op::CallFb { .. } => (1, 0),
            Op::Index { .. } | Op::Bin { .. } | Op::Cmp { .. } => (2, 1),
            Op::Offset(_)
            | Op::FetchInd(_)
            | Op::Un { .. }
            | Op::Conv { .. }
            | Op::Deref { .. }
            | Op::CheckRef(_) => (1, 1),
            Op::RefAdd | Op::RefDiff => (2, 1),
            Op::StoreInd(_) | Op::Copy(_) => (2, 0),
            Op::Goto(_) | Op::CallFn { .. } | Op::Return | Op::End | Op::Nop | Op::System(_) => {
                (0, 0)
            }
            Op::Str { op, .. } => match op {
                StrOp::Move | StrOp::FromValue(_) | StrOp::Widen | StrOp::Narrow => (2, 0),
                StrOp::Len | StrOp::ToValue(_) => (1, 1),
                StrOp::Left | StrOp::Right | StrOp::Concat => (3, 0),
                StrOp::Mid => (4, 0),
                StrOp::Find | StrOp::Compare => (2, 1),
            },
            _ => return None,
        })
    }
}

impl WideConv {
    /// Whether the source is one 16-bit word.
    pub fn from_one_word(self) -> bool {
        matches!(self, WideConv::IntToDint | WideConv::IntToReal)
    }

    /// Whether the destination is one 16-bit word.
    pub fn to_one_word(self) -> bool {
        matches!(self, WideConv::DintToInt | WideConv::RealToInt)
    }
}

// The dispatch loop walks an array of these; keep each within 16 bytes, four to a cache line.
const _: () = assert!(std::mem::size_of::<Op>() <= 16);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_store_to_a_device_byte_writes_its_eight_bits() {
        let low = Op::Store { elem: Elem::U8, at: Place::Byte(2 * 64) };
        let high = Op::Store { elem: Elem::I8, at: Place::Byte(2 * 64 + 1) };
        assert_eq!(low.writes(), Some(Written::Bit(BitRef { word: 64, mask: 0x00FF })));
        assert_eq!(high.writes(), Some(Written::Bit(BitRef { word: 64, mask: 0xFF00 })));
        assert_eq!(Op::Fetch { elem: Elem::U8, at: Place::Byte(3) }.writes(), None);
    }

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
