//! Typed values: the elementary types as the VM stores and computes them, and the typed
//! operations both languages share (Structured Text, and the instruction list's double-word and
//! real instructions `DADD`, `RADD`, …).
//!
//! A value travels as a *slot*, a `u64`:
//! - `Bool`: 0 or 1;
//! - signed integers (`I8`…`I64`): the value sign-extended to 64 bits;
//! - unsigned integers and bit strings (`U8`…`U64`): zero-extended;
//! - `F32`: the `f32` bits in the low 32 bits, the high bits zero; `F64`: the `f64` bits.
//!
//! Every operation returns a normalized slot: integer results wrap to their width (IEC integer
//! arithmetic wraps, as IL's 16-bit arithmetic always has). An operation that cannot give a
//! result (an integer or real division by zero) returns an [`OpError`]; its result is then
//! defined as 0, so that execution can go on exactly as IL's does after an operation error.
//!
//! Nothing here knows about devices, memory or programs.

use std::cmp::Ordering;

/// An elementary type as stored: its width, and whether it is signed, unsigned or floating.
/// `TIME` is an [`Elem::I64`] of nanoseconds; `BYTE`…`LWORD` are `U8`…`U64`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Elem {
    Bool,
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
    F32,
    F64,
}

/// A binary operation on two slots of the same [`Elem`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    /// Integer division truncates toward zero; by zero: [`OpError::DivideByZero`].
    Div,
    /// The remainder with the sign of the dividend (`-7 MOD 2 = -1`); by zero: an error.
    Mod,
    /// `**` / `EXPT`, on floats only.
    Expt,
    /// Bitwise on bit strings and integers, logical on `Bool`.
    And,
    Or,
    Xor,
    /// `SHL`/`SHR`: the count is the second operand (any non-negative count; ≥ width gives 0).
    Shl,
    Shr,
    /// `ROL`/`ROR`: the count is taken modulo the width.
    Rol,
    Ror,
    Min,
    Max,
}

/// A unary operation on one slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum UnOp {
    /// Arithmetic negation (wraps for integers: `-(-128)` is -128 in `SINT`).
    Neg,
    /// Bitwise complement on bit strings and integers, logical on `Bool`.
    Not,
    Abs,
    // Floats only:
    Sqrt,
    Ln,
    Log,
    Exp,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    /// Toward zero, keeping the float type (`TRUNC` is this followed by a conversion).
    Trunc,
}

/// Why a typed operation has no result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum OpError {
    #[error("division by zero")]
    DivideByZero,
}

impl Elem {
    /// Bytes the value takes in variable memory.
    pub const fn size(self) -> u32 {
        match self {
            Elem::Bool | Elem::I8 | Elem::U8 => 1,
            Elem::I16 | Elem::U16 => 2,
            Elem::I32 | Elem::U32 | Elem::F32 => 4,
            Elem::I64 | Elem::U64 | Elem::F64 => 8,
        }
    }

    /// Device words the value takes when located at a word device (`AT %D00100`): 1 for 8-
    /// and 16-bit types (an 8-bit value in the low byte), 2 for 32-bit, 4 for 64-bit.
    pub const fn words(self) -> u32 {
        match self {
            Elem::Bool | Elem::I8 | Elem::U8 | Elem::I16 | Elem::U16 => 1,
            Elem::I32 | Elem::U32 | Elem::F32 => 2,
            Elem::I64 | Elem::U64 | Elem::F64 => 4,
        }
    }

    pub const fn is_float(self) -> bool {
        matches!(self, Elem::F32 | Elem::F64)
    }

    pub const fn is_signed(self) -> bool {
        matches!(self, Elem::I8 | Elem::I16 | Elem::I32 | Elem::I64)
    }
}

/// `raw` (any bits) as a normalized slot of `elem`: truncated to the width, then sign- or
/// zero-extended; `Bool` is 1 for any non-zero value.
pub fn normalize(elem: Elem, raw: u64) -> u64 {
    let _ = (elem, raw);
    unimplemented!("vm-typed helper")
}

/// `a op b`, both normalized slots of `elem`.
pub fn binary(op: BinOp, elem: Elem, a: u64, b: u64) -> Result<u64, OpError> {
    let _ = (op, elem, a, b);
    unimplemented!("vm-typed helper")
}

/// `op a`.
pub fn unary(op: UnOp, elem: Elem, a: u64) -> u64 {
    let _ = (op, elem, a);
    unimplemented!("vm-typed helper")
}

/// How `a` compares with `b`; `None` when a float operand is NaN (every comparison but `<>`
/// is then false).
pub fn compare(elem: Elem, a: u64, b: u64) -> Option<Ordering> {
    let _ = (elem, a, b);
    unimplemented!("vm-typed helper")
}

/// Converts a slot of `from` into a slot of `to`. Integer to integer wraps; float to integer
/// rounds to the nearest (half away from zero) and saturates at the target's range, NaN gives
/// 0; integer to float is the nearest float; `Bool` from anything is `value <> 0`, to anything
/// 0 or 1.
pub fn convert(from: Elem, to: Elem, a: u64) -> u64 {
    let _ = (from, to, a);
    unimplemented!("vm-typed helper")
}

/// Where a value lives, as a run-time pointer: `space << 32 | offset`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Space {
    /// Variable memory (the program instances, their FB instances, the globals): byte offset.
    Var = 0,
    /// The task's frame area (function locals, `VAR_TEMP`, temporaries): byte offset from the
    /// start of the area.
    Frame = 1,
    /// Device memory, by word index (`WordRef`); a multi-word value takes consecutive words,
    /// low word first.
    Word = 2,
    /// Device memory, by bit index (`word * 16 + bit`), for BOOLs at bit devices.
    Bit = 3,
    /// Nowhere: loads give 0, stores do nothing. What a failed array index points to.
    Discard = 4,
}

/// A run-time pointer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Pointer {
    pub space: Space,
    pub offset: u32,
}

impl Pointer {
    pub const DISCARD: Pointer = Pointer { space: Space::Discard, offset: 0 };

    pub const fn to_slot(self) -> u64 {
        (self.space as u64) << 32 | self.offset as u64
    }

    pub const fn from_slot(slot: u64) -> Pointer {
        let space = match slot >> 32 {
            0 => Space::Var,
            1 => Space::Frame,
            2 => Space::Word,
            3 => Space::Bit,
            _ => Space::Discard,
        };
        Pointer { space, offset: slot as u32 }
    }
}

/// The type of a named variable, as tools show and parse its value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ValueType {
    Bool,
    /// `SINT`…`LINT`.
    Signed(Elem),
    /// `USINT`…`ULINT`, `BYTE`…`LWORD`.
    Unsigned(Elem),
    /// `REAL` (`F32`), `LREAL` (`F64`).
    Real(Elem),
    /// `TIME`: nanoseconds in an `I64`, shown as an IEC literal (`T#1s500ms`).
    Time,
    /// An enumeration: its values' names and numbers, stored as an `I32`.
    Enum { type_name: String, values: Vec<(String, i64)> },
    /// `STRING[cap]`: a length byte, then `cap` bytes.
    String { cap: u32 },
}

/// A named variable of Structured Text, one leaf of the tree of program instances (a struct
/// member, an array element, an FB instance's variable): what `--watch`, `plcctl get/set`,
/// the trace and the retain files see.
#[derive(Debug, Clone, PartialEq)]
pub struct Symbol {
    /// The full name with the spelling of its declarations: `main.pid.out`, `main.buf[3]`.
    pub name: String,
    pub ty: ValueType,
    pub at: Pointer,
    /// Declared in a `VAR RETAIN` block (or inside a retained instance).
    pub retain: bool,
    /// `CONSTANT`: a client may not write it.
    pub constant: bool,
}
