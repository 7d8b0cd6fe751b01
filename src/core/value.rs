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
use std::fmt;

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
    /// `**` / `EXPT`, emitted on floats only. Defined on integers too: wrapping, and a
    /// negative exponent gives the integer part of the inverse (0, except ±1 for bases ±1; a
    /// division by zero for base 0).
    Expt,
    /// Bitwise on bit strings and integers, logical on `Bool`.
    And,
    Or,
    Xor,
    /// `SHL`/`SHR`: the count is the second operand (any non-negative count; ≥ width gives 0;
    /// a negative count, of a signed type, shifts by nothing). Both are logical on the value's
    /// bits, for signed types too (`SHR` of `SINT` -128 by 1 is 64).
    Shl,
    Shr,
    /// `ROL`/`ROR`: the count is taken modulo the width (a negative count too: `ROL` by -1 is
    /// `ROR` by 1).
    Rol,
    Ror,
    /// `MIN`/`MAX`; on floats a NaN operand is ignored (IEEE minNum/maxNum).
    Min,
    Max,
}
// On floats the bitwise, shift and rotate operations act on the bits (as `U32`/`U64`): never
// emitted, defined so that every operation has a result.

impl BinOp {
    /// Every binary operation, for tests that go through them all.
    pub const ALL: [BinOp; 15] = [
        BinOp::Add,
        BinOp::Sub,
        BinOp::Mul,
        BinOp::Div,
        BinOp::Mod,
        BinOp::Expt,
        BinOp::And,
        BinOp::Or,
        BinOp::Xor,
        BinOp::Shl,
        BinOp::Shr,
        BinOp::Rol,
        BinOp::Ror,
        BinOp::Min,
        BinOp::Max,
    ];
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

impl UnOp {
    /// Every unary operation, for tests and tools that go through them all.
    pub const ALL: [UnOp; 14] = [
        UnOp::Neg,
        UnOp::Not,
        UnOp::Abs,
        UnOp::Sqrt,
        UnOp::Ln,
        UnOp::Log,
        UnOp::Exp,
        UnOp::Sin,
        UnOp::Cos,
        UnOp::Tan,
        UnOp::Asin,
        UnOp::Acos,
        UnOp::Atan,
        UnOp::Trunc,
    ];
}

/// Why a typed operation has no result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum OpError {
    #[error("division by zero")]
    DivideByZero,
}

impl Elem {
    /// Every element type, for tests and tools that go through them all.
    pub const ALL: [Elem; 11] = [
        Elem::Bool,
        Elem::I8,
        Elem::I16,
        Elem::I32,
        Elem::I64,
        Elem::U8,
        Elem::U16,
        Elem::U32,
        Elem::U64,
        Elem::F32,
        Elem::F64,
    ];

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
#[inline]
pub fn normalize(elem: Elem, raw: u64) -> u64 {
    match elem {
        Elem::Bool => u64::from(raw != 0),
        _ => wrap(elem, raw),
    }
}

/// `raw` truncated to the width of `elem` and extended: like [`normalize`], except that a
/// `Bool` keeps bit 0 (a 1-bit unsigned integer), which is what arithmetic on it gives.
#[inline]
fn wrap(elem: Elem, raw: u64) -> u64 {
    match elem {
        Elem::Bool => raw & 1,
        Elem::I8 => raw as i8 as i64 as u64,
        Elem::I16 => raw as i16 as i64 as u64,
        Elem::I32 => raw as i32 as i64 as u64,
        Elem::U8 => raw as u8 as u64,
        Elem::U16 => raw as u16 as u64,
        Elem::U32 | Elem::F32 => raw as u32 as u64,
        Elem::I64 | Elem::U64 | Elem::F64 => raw,
    }
}

/// Bits of the value: 1 for `Bool`.
#[inline]
const fn width(elem: Elem) -> u32 {
    match elem {
        Elem::Bool => 1,
        _ => elem.size() * 8,
    }
}

/// The value of an F32 or F64 slot as an `f64` (exactly).
#[inline]
fn to_f64(elem: Elem, a: u64) -> f64 {
    match elem {
        Elem::F32 => f64::from(f32::from_bits(a as u32)),
        Elem::F64 => f64::from_bits(a),
        _ if elem.is_signed() => a as i64 as f64,
        _ => a as f64,
    }
}

/// The float operations, once for `f32` and once for `f64`, each in its own precision.
macro_rules! float_ops {
    ($bin:ident, $un:ident, $t:ty, $bits:ty) => {
        fn $bin(op: BinOp, a: u64, b: u64) -> Result<u64, OpError> {
            let (x, y) = (<$t>::from_bits(a as $bits), <$t>::from_bits(b as $bits));
            let r: $t = match op {
                BinOp::Add => x + y,
                BinOp::Sub => x - y,
                BinOp::Mul => x * y,
                BinOp::Div if y == 0.0 => return Err(OpError::DivideByZero),
                BinOp::Div => x / y,
                BinOp::Mod if y == 0.0 => return Err(OpError::DivideByZero),
                BinOp::Mod => x % y,
                BinOp::Expt => x.powf(y),
                BinOp::Min => x.min(y),
                BinOp::Max => x.max(y),
                // Not emitted for floats: defined on the bits, for totality.
                BinOp::And
                | BinOp::Or
                | BinOp::Xor
                | BinOp::Shl
                | BinOp::Shr
                | BinOp::Rol
                | BinOp::Ror => {
                    let elem = if <$bits>::BITS == 32 { Elem::U32 } else { Elem::U64 };
                    return int_binary(op, elem, a, b);
                }
            };
            Ok(r.to_bits() as u64)
        }

        fn $un(op: UnOp, a: u64) -> u64 {
            let x = <$t>::from_bits(a as $bits);
            let r: $t = match op {
                UnOp::Neg => -x,
                UnOp::Not => return (!(a as $bits)) as u64,
                UnOp::Abs => x.abs(),
                UnOp::Sqrt => x.sqrt(),
                UnOp::Ln => x.ln(),
                UnOp::Log => x.log10(),
                UnOp::Exp => x.exp(),
                UnOp::Sin => x.sin(),
                UnOp::Cos => x.cos(),
                UnOp::Tan => x.tan(),
                UnOp::Asin => x.asin(),
                UnOp::Acos => x.acos(),
                UnOp::Atan => x.atan(),
                UnOp::Trunc => x.trunc(),
            };
            r.to_bits() as u64
        }
    };
}

float_ops!(f32_binary, f32_unary, f32, u32);
float_ops!(f64_binary, f64_unary, f64, u64);

/// `a op b` on integers (and `Bool`, a 1-bit unsigned integer).
fn int_binary(op: BinOp, elem: Elem, a: u64, b: u64) -> Result<u64, OpError> {
    let signed = elem.is_signed();
    let bits = width(elem);
    // The value's own bits, for shifts and rotations.
    let pattern = a & (u64::MAX >> (64 - bits));
    let r = match op {
        BinOp::Add => a.wrapping_add(b),
        BinOp::Sub => a.wrapping_sub(b),
        BinOp::Mul => a.wrapping_mul(b),
        BinOp::Div | BinOp::Mod if wrap(elem, b) == 0 => return Err(OpError::DivideByZero),
        BinOp::Div if signed => (a as i64).wrapping_div(b as i64) as u64,
        BinOp::Div => a / b,
        BinOp::Mod if signed => (a as i64).wrapping_rem(b as i64) as u64,
        BinOp::Mod => a % b,
        BinOp::Expt => int_power(elem, a, b)?,
        BinOp::And => a & b,
        BinOp::Or => a | b,
        BinOp::Xor => a ^ b,
        BinOp::Shl | BinOp::Shr => {
            // A negative count (of a signed type) shifts by nothing.
            let count = if signed && (b as i64) < 0 { 0 } else { b };
            if count >= u64::from(bits) {
                0
            } else if op == BinOp::Shl {
                pattern << count
            } else {
                pattern >> count
            }
        }
        BinOp::Rol | BinOp::Ror => {
            let count = if signed {
                (b as i64).rem_euclid(i64::from(bits)) as u32
            } else {
                (b % u64::from(bits)) as u32
            };
            let count = if op == BinOp::Ror { (bits - count) % bits } else { count };
            if count == 0 {
                pattern
            } else {
                (pattern << count) | (pattern >> (bits - count))
            }
        }
        BinOp::Min | BinOp::Max => {
            let less = if signed { (a as i64) < (b as i64) } else { a < b };
            if less == (op == BinOp::Min) {
                a
            } else {
                b
            }
        }
    };
    Ok(wrap(elem, r))
}

/// `a ** b` on integers, wrapping; a negative exponent gives the integer part of the inverse
/// (0 but for bases 1 and -1), and a division by zero for base 0.
fn int_power(elem: Elem, a: u64, b: u64) -> Result<u64, OpError> {
    let negative = elem.is_signed() && (b as i64) < 0;
    if negative {
        return match a as i64 {
            0 => Err(OpError::DivideByZero),
            1 => Ok(1),
            -1 => Ok(if b & 1 == 0 { 1 } else { u64::MAX }),
            _ => Ok(0),
        };
    }
    // Square and multiply on the low 64 bits, which the width's wrap then cuts.
    let (mut base, mut exp, mut r) = (a, b, 1u64);
    while exp > 0 {
        if exp & 1 == 1 {
            r = r.wrapping_mul(base);
        }
        base = base.wrapping_mul(base);
        exp >>= 1;
    }
    Ok(r)
}

/// `a op b`, both normalized slots of `elem`.
pub fn binary(op: BinOp, elem: Elem, a: u64, b: u64) -> Result<u64, OpError> {
    match elem {
        Elem::F32 => f32_binary(op, a, b),
        Elem::F64 => f64_binary(op, a, b),
        _ => int_binary(op, elem, a, b),
    }
}

/// `op a`.
pub fn unary(op: UnOp, elem: Elem, a: u64) -> u64 {
    match elem {
        Elem::F32 => f32_unary(op, a),
        Elem::F64 => f64_unary(op, a),
        _ => match op {
            UnOp::Neg => wrap(elem, a.wrapping_neg()),
            UnOp::Not => wrap(elem, !a),
            UnOp::Abs if elem.is_signed() => wrap(elem, (a as i64).wrapping_abs() as u64),
            UnOp::Abs | UnOp::Trunc => a,
            // The float functions on an integer: through LREAL and back.
            _ => convert(Elem::F64, elem, f64_unary(op, convert(elem, Elem::F64, a))),
        },
    }
}

/// How `a` compares with `b`; `None` when a float operand is NaN (every comparison but `<>`
/// is then false).
pub fn compare(elem: Elem, a: u64, b: u64) -> Option<Ordering> {
    match elem {
        Elem::F32 => f32::from_bits(a as u32).partial_cmp(&f32::from_bits(b as u32)),
        Elem::F64 => f64::from_bits(a).partial_cmp(&f64::from_bits(b)),
        _ if elem.is_signed() => Some((a as i64).cmp(&(b as i64))),
        _ => Some(a.cmp(&b)),
    }
}

/// Converts a slot of `from` into a slot of `to`. Integer to integer wraps; float to integer
/// rounds to the nearest (half away from zero) and saturates at the target's range, NaN gives
/// 0; integer to float is the nearest float; `Bool` from anything is `value <> 0`, to anything
/// 0 or 1.
pub fn convert(from: Elem, to: Elem, a: u64) -> u64 {
    if to == Elem::Bool {
        return match from {
            Elem::F32 => u64::from(f32::from_bits(a as u32) != 0.0),
            Elem::F64 => u64::from(f64::from_bits(a) != 0.0),
            _ => u64::from(a != 0),
        };
    }
    match (from.is_float(), to) {
        (false, Elem::F32) => {
            let x = if from.is_signed() { a as i64 as f32 } else { a as f32 };
            x.to_bits() as u64
        }
        (false, Elem::F64) => {
            let x = if from.is_signed() { a as i64 as f64 } else { a as f64 };
            x.to_bits()
        }
        (false, _) => wrap(to, a),
        (true, Elem::F32) => match from {
            Elem::F64 => (f64::from_bits(a) as f32).to_bits() as u64,
            _ => a,
        },
        (true, Elem::F64) => to_f64(from, a).to_bits(),
        (true, _) => {
            // `as` saturates and gives 0 for NaN; `round` is half away from zero. An f32 is
            // rounded as an f32 (exactly: its integral values are f32s).
            let x = match from {
                Elem::F32 => f64::from(f32::from_bits(a as u32).round()),
                _ => f64::from_bits(a).round(),
            };
            match to {
                Elem::I8 => x as i8 as i64 as u64,
                Elem::I16 => x as i16 as i64 as u64,
                Elem::I32 => x as i32 as i64 as u64,
                Elem::I64 => x as i64 as u64,
                Elem::U8 => x as u8 as u64,
                Elem::U16 => x as u16 as u64,
                Elem::U32 => x as u32 as u64,
                _ => x as u64,
            }
        }
    }
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
    /// Device memory, by byte index (`word * 2`, plus 1 for the high byte), for 8-bit values at
    /// an IEC byte address (`%QB1`): a store writes that byte of its word and never the other.
    Byte = 5,
}

/// What a reference value adds to its pointer's slot: its space is counted from 1, so that 0
/// (zeroed memory, the default) is `NULL`.
pub const REF_TAG: u64 = 1 << 32;

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

    /// The pointer a reference value holds (`REF_TO`, `POINTER TO`, `REFERENCE TO`: the
    /// pointer's slot plus [`REF_TAG`]); `None` for `NULL` (any value below [`REF_TAG`]).
    pub const fn from_reference(reference: u64) -> Option<Pointer> {
        if reference < REF_TAG {
            None
        } else {
            Some(Pointer::from_slot(reference.wrapping_sub(REF_TAG)))
        }
    }

    pub const fn from_slot(slot: u64) -> Pointer {
        let space = match slot >> 32 {
            0 => Space::Var,
            1 => Space::Frame,
            2 => Space::Word,
            3 => Space::Bit,
            5 => Space::Byte,
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
    /// `DATE`, `TOD`, `DT` and their long forms, shown as IEC literals (`D#2024-03-01`): see
    /// [`Calendar`].
    Calendar(Calendar),
    /// An enumeration: its values' names and numbers, stored as its base type (`I32` for
    /// `DINT`, the default; `TYPE Code : INT (…)` is an `I16`).
    Enum {
        type_name: String,
        values: Vec<(String, i64)>,
        base: Elem,
    },
    /// `STRING[cap]`: `cap` bytes of characters, then room for the NUL that ends them.
    String {
        cap: u32,
    },
    /// `CHAR`: one byte, a Windows-1252 character; shown as the character.
    Char,
    /// `WCHAR`: one UTF-16 code unit; shown as the character.
    WChar,
    /// `WSTRING[cap]`: `cap` UTF-16 code units of 2 bytes, then room for the 2-byte NUL.
    WString {
        cap: u32,
    },
    /// A reference (`REF_TO T`, `POINTER TO T`, `REFERENCE TO T`, named so in `type_name`):
    /// 8 bytes, 0 for `NULL`, else a [`Pointer`]'s slot plus `1 << 32`. Shown as what it
    /// points to ([`format_reference`]); never written by a client, never kept by an online
    /// change or in the retain files (an offset is only meaningful in the memory layout it
    /// was taken in).
    Reference {
        type_name: String,
    },
}

impl ValueType {
    /// How a value of this type is stored and computed; a `STRING` has no slot (its bytes are
    /// read through a pointer) and answers `U8`, its first character.
    pub fn elem(&self) -> Elem {
        match self {
            ValueType::Bool => Elem::Bool,
            ValueType::Signed(elem) | ValueType::Unsigned(elem) | ValueType::Real(elem) => *elem,
            ValueType::Time => Elem::I64,
            ValueType::Calendar(cal) => cal.elem(),
            ValueType::Char => Elem::U8,
            ValueType::WChar => Elem::U16,
            ValueType::Enum { base, .. } => *base,
            ValueType::String { .. } => Elem::U8,
            ValueType::WString { .. } => Elem::U16,
            ValueType::Reference { .. } => Elem::U64,
        }
    }

    /// The bytes a value of this type takes in variable memory (a `STRING[n]`: its length
    /// byte and `n` characters).
    pub fn bytes(&self) -> u32 {
        match self {
            ValueType::String { cap } => cap + 1,
            ValueType::WString { cap } => 2 * (cap + 1),
            ty => ty.elem().size(),
        }
    }
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

/// The IEC name of an elementary type as tools name it in messages.
pub fn type_name(ty: &ValueType) -> String {
    match ty {
        ValueType::Bool => "BOOL".into(),
        ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => match e {
            Elem::Bool => "BOOL",
            Elem::I8 => "SINT",
            Elem::I16 => "INT",
            Elem::I32 => "DINT",
            Elem::I64 => "LINT",
            Elem::U8 => "USINT",
            Elem::U16 => "UINT",
            Elem::U32 => "UDINT",
            Elem::U64 => "ULINT",
            Elem::F32 => "REAL",
            Elem::F64 => "LREAL",
        }
        .into(),
        ValueType::Time => "TIME".into(),
        ValueType::Calendar(cal) => cal.name().into(),
        ValueType::Char => "CHAR".into(),
        ValueType::WChar => "WCHAR".into(),
        ValueType::Enum { type_name, .. } => type_name.clone(),
        ValueType::String { cap } => format!("STRING[{cap}]"),
        ValueType::WString { cap } => format!("WSTRING[{cap}]"),
        ValueType::Reference { type_name } => type_name.clone(),
    }
}

/// The text of a value as the trace and `plcctl get` show it: integers in decimal, `BOOL` as
/// `0`/`1` (like the bits of the instruction list), `REAL`/`LREAL` as the shortest text that
/// reads back to the same value (`1.5`, `1.0`, `1e-7`, `NaN`, `inf`), `TIME` as an IEC literal
/// (`T#1s500ms`, `T#0s`, `T#-5s`), an enumeration by its value's name (or the number when no
/// value has it). Strings are not slots: see [`format_string`].
pub fn format(ty: &ValueType, slot: u64) -> String {
    match ty {
        ValueType::Enum { values, base, .. } => {
            let n = normalize(*base, slot) as i64;
            match values.iter().find(|(_, v)| *v == n) {
                Some((name, _)) => name.clone(),
                None => n.to_string(),
            }
        }
        ValueType::String { .. } | ValueType::WString { .. } => String::new(),
        ValueType::Reference { .. } => format_reference(slot),
        ValueType::Char => format_string(&[slot as u8]),
        ValueType::WChar => format_wstring(&[slot as u16]),
        scalar => {
            let mut text = String::new();
            if let Some(scalar) = scalar.scalar() {
                // Writing into a String cannot fail.
                let _ = write_scalar(&mut text, scalar, slot);
            }
            text
        }
    }
}

/// What a reference value points to, as tools show it: `NULL`; else the memory area and the
/// offset in it: `vars+120` (byte 120 of variable memory), `frame+16` (of the frame area of
/// the task that took it), `word+4992`, `bit+64` and `byte+129` (device memory by word, by bit
/// and by byte: see `device::format_reference`, which names the device); `invalid` for a
/// reference that went nowhere (`ADR` of an element out of bounds).
pub fn format_reference(slot: u64) -> String {
    let Some(p) = Pointer::from_reference(slot) else { return "NULL".into() };
    let area = match p.space {
        Space::Var => "vars",
        Space::Frame => "frame",
        Space::Word => "word",
        Space::Bit => "bit",
        Space::Byte => "byte",
        Space::Discard => return "invalid".into(),
    };
    format!("{area}+{}", p.offset)
}

/// A scalar type: what [`write_scalar`] writes and [`scalar_from_text`] reads, without
/// allocating (the conversions to and from STRING run on the scan thread).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    Bool,
    Signed(Elem),
    Unsigned(Elem),
    Real(Elem),
    Time,
    Calendar(Calendar),
}

impl ValueType {
    /// The scalar this type is; `None` for an enumeration and a `STRING`.
    pub fn scalar(&self) -> Option<Scalar> {
        Some(match self {
            ValueType::Bool => Scalar::Bool,
            ValueType::Signed(e) => Scalar::Signed(*e),
            ValueType::Unsigned(e) => Scalar::Unsigned(*e),
            ValueType::Real(e) => Scalar::Real(*e),
            ValueType::Time => Scalar::Time,
            ValueType::Calendar(cal) => Scalar::Calendar(*cal),
            // stored as their code; shown and read as characters by `format` and `parse`
            ValueType::Char => Scalar::Unsigned(Elem::U8),
            ValueType::WChar => Scalar::Unsigned(Elem::U16),
            ValueType::Enum { .. }
            | ValueType::String { .. }
            | ValueType::WString { .. }
            | ValueType::Reference { .. } => return None,
        })
    }
}

/// Writes a scalar's text as [`format`](fn@format) describes it (`BOOL` as `0`/`1`).
pub fn write_scalar(out: &mut impl fmt::Write, scalar: Scalar, slot: u64) -> fmt::Result {
    match scalar {
        Scalar::Bool => out.write_str(if slot != 0 { "1" } else { "0" }),
        Scalar::Signed(e) => write!(out, "{}", normalize(e, slot) as i64),
        Scalar::Unsigned(e) => write!(out, "{}", normalize(e, slot)),
        Scalar::Real(Elem::F32) => write!(out, "{:?}", f32::from_bits(slot as u32)),
        Scalar::Real(_) => write!(out, "{:?}", f64::from_bits(slot)),
        Scalar::Time => write_time(out, slot as i64),
        Scalar::Calendar(cal) => write_calendar(out, cal, slot),
    }
}

const TIME_UNITS: [(&str, u64); 7] = [
    ("d", 86_400_000_000_000),
    ("h", 3_600_000_000_000),
    ("m", 60_000_000_000),
    ("s", 1_000_000_000),
    ("ms", 1_000_000),
    ("us", 1_000),
    ("ns", 1),
];

/// Nanoseconds as an IEC `TIME` literal: `T#1h2m3s4ms`, `T#0s`, `T#-250ms`.
pub fn format_time(ns: i64) -> String {
    let mut text = String::new();
    // Writing into a String cannot fail.
    let _ = write_time(&mut text, ns);
    text
}

/// Writes [`format_time`]'s text.
pub fn write_time(out: &mut impl fmt::Write, ns: i64) -> fmt::Result {
    out.write_str(if ns < 0 { "T#-" } else { "T#" })?;
    let mut rest = ns.unsigned_abs();
    if rest == 0 {
        out.write_str("0s")?;
    }
    for (unit, size) in TIME_UNITS {
        let n = rest / size;
        rest %= size;
        if n > 0 {
            write!(out, "{n}{unit}")?;
        }
    }
    Ok(())
}

/// Windows-1252's characters for the bytes 0x80–0x9F (0x81, 0x8D, 0x8F, 0x90 and 0x9D, which it
/// leaves undefined, stand for the control characters of the same number, as in WHATWG's
/// `windows-1252`); every other byte is the Unicode character of its number (Latin-1).
const CP1252_80_9F: [char; 32] = [
    '€', '\u{81}', '‚', 'ƒ', '„', '…', '†', '‡', 'ˆ', '‰', 'Š', '‹', 'Œ', '\u{8D}', 'Ž', '\u{8F}',
    '\u{90}', '‘', '’', '“', '”', '•', '–', '—', '˜', '™', 'š', '›', 'œ', '\u{9D}', 'ž', 'Ÿ',
];

/// The character a `STRING` byte stands for: `STRING` holds one byte a character, in the
/// Windows-1252 character set (as CODESYS and TwinCAT store it).
pub fn decode_byte(b: u8) -> char {
    match b {
        0x80..=0x9F => CP1252_80_9F[usize::from(b - 0x80)],
        _ => char::from(b),
    }
}

/// The `STRING` byte of a character; `None` for a character Windows-1252 does not have.
pub fn encode_char(c: char) -> Option<u8> {
    match u32::from(c) {
        n @ (0..=0x7F | 0xA0..=0xFF) => Some(n as u8),
        _ => CP1252_80_9F.iter().position(|&x| x == c).map(|i| 0x80 + i as u8),
    }
}

/// The `STRING` bytes of a text; the first character Windows-1252 does not have, if any.
pub fn encode_str(text: &str) -> Result<Vec<u8>, char> {
    text.chars().map(|c| encode_char(c).ok_or(c)).collect()
}

/// The text of `STRING` bytes.
pub fn decode_str(bytes: &[u8]) -> String {
    bytes.iter().map(|&b| decode_byte(b)).collect()
}

/// The characters of a `STRING` as an IEC literal: `'abc'`, with `$'`, `$$`, `$N`, `$R`,
/// `$T` and `$hh` (two hex digits) for the quote, the dollar and the other non-printing bytes.
pub fn format_string(chars: &[u8]) -> String {
    let mut text = String::with_capacity(chars.len() + 2);
    text.push('\'');
    for &c in chars {
        match c {
            b'\'' => text.push_str("$'"),
            b'$' => text.push_str("$$"),
            b'\n' => text.push_str("$N"),
            b'\r' => text.push_str("$R"),
            b'\t' => text.push_str("$T"),
            0x20..=0x7E => text.push(c as char),
            _ => text.push_str(&format!("${c:02X}")),
        }
    }
    text.push('\'');
    text
}

/// A client's text that a variable of a text type cannot hold: a character a one-byte
/// `STRING` or `CHAR` has not, a `CHAR` or `WCHAR` of other than one character.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TextNotHeld;

/// The text `plcctl set` takes for a variable of the text type `ty` (`STRING`, `WSTRING`,
/// `CHAR`, `WCHAR`) that a client (OPC UA, MQTT) writes `text` to; `None` when `ty` is no text
/// type. What `set` itself refuses (a string longer than the variable) it refuses then.
pub fn text_written(ty: &ValueType, text: &str) -> Option<Result<String, TextNotHeld>> {
    Some(match ty {
        ValueType::String { .. } => {
            encode_str(text).map(|bytes| format_string(&bytes)).map_err(|_| TextNotHeld)
        }
        ValueType::WString { .. } => Ok(format_wstring(&text.encode_utf16().collect::<Vec<u16>>())),
        ValueType::Char => {
            let mut chars = text.chars();
            match (chars.next(), chars.next()) {
                (Some(c), None) => {
                    encode_char(c).map(|byte| format(ty, u64::from(byte))).ok_or(TextNotHeld)
                }
                _ => Err(TextNotHeld),
            }
        }
        ValueType::WChar => match text.encode_utf16().collect::<Vec<u16>>().as_slice() {
            [unit] => Ok(format(ty, u64::from(*unit))),
            _ => Err(TextNotHeld),
        },
        _ => return None,
    })
}

/// The code units of a `WSTRING` as an IEC literal: `"abc"`, with `$"`, `$$`, `$N`, `$R`,
/// `$T` and `$hhhh` (four hex digits) for the quote, the dollar and the units that are no
/// printable character (controls, halves of a surrogate pair); other characters as they are.
pub fn format_wstring(units: &[u16]) -> String {
    let mut text = String::with_capacity(units.len() + 2);
    text.push('"');
    for unit in char::decode_utf16(units.iter().copied()) {
        match unit {
            Ok('"') => text.push_str("$\""),
            Ok('$') => text.push_str("$$"),
            Ok('\n') => text.push_str("$N"),
            Ok('\r') => text.push_str("$R"),
            Ok('\t') => text.push_str("$T"),
            Ok(c) if !c.is_control() => text.push(c),
            Ok(c) => text.push_str(&format!("${:04X}", c as u32)),
            Err(e) => text.push_str(&format!("${:04X}", e.unpaired_surrogate())),
        }
    }
    text.push('"');
    text
}

/// The code units of a `WSTRING` value as a client writes it (`plcctl set main.w '"äb"'`): an
/// IEC literal in double quotes with its `$` escapes (`$hhhh` a code unit), or bare text taken
/// as it is. More than `cap` units is an error.
pub fn parse_wstring(text: &str, cap: u32) -> Result<Vec<u16>, String> {
    let units: Vec<u16> = match text.strip_prefix('"').and_then(|t| t.strip_suffix('"')) {
        None => text.encode_utf16().collect(),
        Some(inner) => {
            let mut out = Vec::with_capacity(inner.len());
            let mut chars = inner.chars();
            while let Some(c) = chars.next() {
                if c != '$' {
                    let mut buf = [0; 2];
                    out.extend_from_slice(c.encode_utf16(&mut buf));
                    continue;
                }
                let escape = chars.next().ok_or("`$` at the end of the string")?;
                out.push(match escape.to_ascii_uppercase() {
                    '$' => u16::from(b'$'),
                    '"' => u16::from(b'"'),
                    'N' | 'L' => u16::from(b'\n'),
                    'R' => u16::from(b'\r'),
                    'T' => u16::from(b'\t'),
                    'P' => 0x0C,
                    hi if hi.is_ascii_hexdigit() => {
                        let rest: String = chars.by_ref().take(3).collect();
                        let digits = format!("{hi}{rest}");
                        if digits.len() != 4 || !digits.chars().all(|d| d.is_ascii_hexdigit()) {
                            return Err("`$` must be followed by four hex digits".into());
                        }
                        u16::from_str_radix(&digits, 16).map_err(|e| e.to_string())?
                    }
                    _ => return Err(format!("unknown escape `${escape}`")),
                });
            }
            out
        }
    };
    if units.len() > cap as usize {
        return Err(format!("{} characters do not fit in a WSTRING[{cap}]", units.len()));
    }
    Ok(units)
}

/// The characters of a string value as a client writes it (`plcctl set main.s 'abc'`): an IEC
/// literal in single quotes with its `$` escapes, or bare text taken as it is. More than `cap`
/// characters is an error.
pub fn parse_string(text: &str, cap: u32) -> Result<Vec<u8>, String> {
    let unknown = |c: char| format!("`{c}` is not a character of STRING (Windows-1252)");
    let chars = match text.strip_prefix('\'').and_then(|t| t.strip_suffix('\'')) {
        None => encode_str(text).map_err(unknown)?,
        Some(inner) => {
            let inner = encode_str(inner).map_err(unknown)?;
            let mut out = Vec::with_capacity(inner.len());
            let mut bytes = inner.into_iter();
            while let Some(c) = bytes.next() {
                if c != b'$' {
                    out.push(c);
                    continue;
                }
                let escape = bytes.next().ok_or("`$` at the end of the string")?;
                out.push(match escape.to_ascii_uppercase() {
                    b'$' => b'$',
                    b'\'' => b'\'',
                    b'N' | b'L' => b'\n',
                    b'R' => b'\r',
                    b'T' => b'\t',
                    b'P' => 0x0C,
                    hi if hi.is_ascii_hexdigit() => {
                        let lo = bytes.next().filter(u8::is_ascii_hexdigit);
                        let lo = lo.ok_or("`$` must be followed by two hex digits")?;
                        let digit = |d: u8| (d as char).to_digit(16).unwrap_or(0) as u8;
                        digit(hi) << 4 | digit(lo)
                    }
                    _ => return Err(format!("unknown escape `${}`", escape as char)),
                });
            }
            out
        }
    };
    if chars.len() > cap as usize {
        return Err(format!("{} characters do not fit in a STRING[{cap}]", chars.len()));
    }
    Ok(chars)
}

/// A value as a client writes it (`plcctl set main.x 5`), as a slot of `ty`:
/// - integers: decimal (`-5`, `1_000`), or based `16#FF`, `8#17`, `2#1010`, which give the bit
///   pattern (`16#FFFF` is -1 in an `INT`); out of the type's range is an error naming it;
/// - `BOOL`: `TRUE`, `FALSE`, `1`, `0` (any case);
/// - `REAL`/`LREAL`: a decimal number (`1.5`, `-2`, `1e-3`), `inf`, `NaN`;
/// - `TIME`: `T#1s500ms`, `TIME#-5s`, or the duration alone (`1.5s`, `250ms`), units `d`, `h`,
///   `m`, `s`, `ms`, `us`, `ns`;
/// - `DATE`, `TOD`, `DT` and their long forms: their IEC literals (`D#2024-03-01`,
///   `TOD#12:30:15.5`, `DT#2024-03-01-12:30:15`, any of the type's prefixes, any case) or the
///   literal's text without its prefix (`2024-03-01`);
/// - an enumeration: one of its value names (`Red`, `Color#Red`, any case).
///
/// Strings are not slots: see [`parse_string`].
pub fn parse(ty: &ValueType, text: &str) -> Result<u64, String> {
    let text = text.trim();
    match ty {
        ValueType::Enum { type_name, values, base } => {
            let name = match text.split_once('#') {
                Some((t, name)) if t.eq_ignore_ascii_case(type_name) => name,
                _ => text,
            };
            match values.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)) {
                Some((_, v)) => Ok(normalize(*base, *v as u64)),
                None => {
                    let names: Vec<&str> = values.iter().map(|(n, _)| n.as_str()).collect();
                    Err(format!("`{text}` is not a value of {type_name} ({})", names.join(", ")))
                }
            }
        }
        ValueType::String { cap } => {
            Err(format!("a STRING[{cap}] is not a single value: write its text"))
        }
        ValueType::WString { cap } => {
            Err(format!("a WSTRING[{cap}] is not a single value: write its text"))
        }
        // one character: a literal (`'a'`, `"ä"`) or the character alone
        ValueType::Char => match parse_string(text, 1)?.as_slice() {
            [c] => Ok(u64::from(*c)),
            _ => Err("a CHAR is one character".into()),
        },
        ValueType::WChar => match parse_wstring(text, 1)?.as_slice() {
            [c] => Ok(u64::from(*c)),
            _ => Err("a WCHAR is one character".into()),
        },
        ValueType::Reference { type_name } => {
            Err(format!("a {type_name} cannot be written: the program sets it (REF, ADR)"))
        }
        scalar => {
            let Some(scalar) = scalar.scalar() else { unreachable!("every other type is scalar") };
            scalar_from_text(scalar, text).map_err(|e| e.message(ty, text))
        }
    }
}

/// A `TIME` literal or a duration (`T#1s500ms`, `1.5s`, `-250ms`) in nanoseconds.
pub fn parse_time(text: &str) -> Result<i64, String> {
    time_from_text(text).map_err(|e| e.message(&ValueType::Time, text))
}

/// Why a text is not a value of a scalar type: [`TextError::message`] says it in words; a
/// `STRING_TO_*` conversion, which must not allocate, only needs to know that it is not one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextError {
    NotBool,
    NotInteger,
    NotReal,
    /// Not a `TIME`, and why.
    NotTime(&'static str),
    /// Not a value of a calendar type, and why.
    NotCalendar(Calendar, CalendarError),
    /// A value of the type's form beyond its range.
    OutOfRange,
}

impl TextError {
    /// The error as a client reads it, naming `text` and the type `ty`.
    pub fn message(self, ty: &ValueType, text: &str) -> String {
        match (self, ty) {
            (TextError::NotBool, _) => format!("`{text}` is not a BOOL (TRUE, FALSE, 1 or 0)"),
            (TextError::NotInteger, _) => format!("`{text}` is not an integer"),
            (TextError::NotReal, _) => format!("`{text}` is not a {}", type_name(ty)),
            (TextError::NotTime(why), _) => {
                format!("`{text}` is not a TIME ({why}; e.g. T#1s500ms)")
            }
            (TextError::NotCalendar(cal, why), _) => {
                format!("`{text}` is not a {} ({why}; e.g. {})", cal.name(), cal.example())
            }
            (TextError::OutOfRange, ValueType::Real(Elem::F32)) => {
                format!("`{text}` is out of range for REAL (±3.4028235e38)")
            }
            (TextError::OutOfRange, ValueType::Real(_)) => {
                format!("`{text}` is out of range for LREAL (±1.7976931348623157e308)")
            }
            (TextError::OutOfRange, ValueType::Time) => format!(
                "`{text}` is out of range for TIME (about ±106751 days, T#-106751d..T#106751d)"
            ),
            (TextError::OutOfRange, ValueType::Signed(e) | ValueType::Unsigned(e)) => {
                let (min, max) = integer_range(*e);
                format!("`{text}` is out of range for {} ({min}..={max})", type_name(ty))
            }
            (TextError::OutOfRange, _) => format!("`{text}` is out of range for {}", type_name(ty)),
        }
    }
}

/// The value a text gives a scalar, as [`parse`] describes it, without allocating.
pub fn scalar_from_text(scalar: Scalar, text: &str) -> Result<u64, TextError> {
    let text = text.trim();
    match scalar {
        Scalar::Bool if text.eq_ignore_ascii_case("TRUE") || text == "1" => Ok(1),
        Scalar::Bool if text.eq_ignore_ascii_case("FALSE") || text == "0" => Ok(0),
        Scalar::Bool => Err(TextError::NotBool),
        Scalar::Signed(e) | Scalar::Unsigned(e) => integer_from_text(e, text),
        Scalar::Real(e) => real_from_text(e, text),
        Scalar::Time => time_from_text(text).map(|ns| ns as u64),
        Scalar::Calendar(cal) => {
            calendar_from_text(cal, text).map_err(|why| TextError::NotCalendar(cal, why))
        }
    }
}

fn integer_range(elem: Elem) -> (i128, i128) {
    let bits = width(elem);
    if elem.is_signed() {
        (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
    } else {
        (0, (1i128 << bits) - 1)
    }
}

/// Room for a number's characters without its `_` separators: longer texts are no number of
/// any type plcd has.
const NUMBER_TEXT: usize = 128;

/// `text` without its `_` digit separators, in `buf`; `None` when it does not fit.
fn without_underscores<'b>(text: &str, buf: &'b mut [u8; NUMBER_TEXT]) -> Option<&'b str> {
    let mut len = 0;
    for b in text.bytes().filter(|&b| b != b'_') {
        *buf.get_mut(len)? = b;
        len += 1;
    }
    std::str::from_utf8(&buf[..len]).ok()
}

fn integer_from_text(elem: Elem, text: &str) -> Result<u64, TextError> {
    let bits = width(elem);
    let (min, max) = integer_range(elem);
    let mut buf = [0u8; NUMBER_TEXT];
    let digits = |s: &str, radix: u32, buf: &mut [u8; NUMBER_TEXT]| -> Option<i128> {
        let s = without_underscores(s, buf)?;
        if s.is_empty() || s.starts_with(['+', '-']) {
            return None;
        }
        i128::from_str_radix(s, radix).ok()
    };
    if let Some((base, rest)) = text.split_once('#') {
        let radix = match base {
            "16" => 16,
            "8" => 8,
            "2" => 2,
            "10" => 10,
            _ => return Err(TextError::NotInteger),
        };
        let value = digits(rest, radix, &mut buf).ok_or(TextError::NotInteger)?;
        if radix != 10 {
            // A bit pattern of the width.
            if value >= 1i128 << bits {
                return Err(TextError::OutOfRange);
            }
            return Ok(wrap(elem, value as u64));
        }
        return if (min..=max).contains(&value) {
            Ok(wrap(elem, value as u64))
        } else {
            Err(TextError::OutOfRange)
        };
    }
    let (negative, unsigned) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let magnitude = digits(unsigned, 10, &mut buf).ok_or(TextError::NotInteger)?;
    let value = if negative { -magnitude } else { magnitude };
    if (min..=max).contains(&value) {
        Ok(wrap(elem, value as u64))
    } else {
        Err(TextError::OutOfRange)
    }
}

fn real_from_text(elem: Elem, text: &str) -> Result<u64, TextError> {
    let mut buf = [0u8; NUMBER_TEXT];
    let clean = without_underscores(text, &mut buf).ok_or(TextError::NotReal)?;
    let infinite_text = clean.as_bytes().windows(3).any(|w| w.eq_ignore_ascii_case(b"inf"));
    if elem == Elem::F32 {
        let x: f32 = clean.parse().map_err(|_| TextError::NotReal)?;
        if x.is_infinite() && !infinite_text {
            return Err(TextError::OutOfRange);
        }
        Ok(x.to_bits() as u64)
    } else {
        let x: f64 = clean.parse().map_err(|_| TextError::NotReal)?;
        if x.is_infinite() && !infinite_text {
            return Err(TextError::OutOfRange);
        }
        Ok(x.to_bits())
    }
}

/// A `TIME` literal or a duration in nanoseconds, without allocating.
fn time_from_text(text: &str) -> Result<i64, TextError> {
    let bad = TextError::NotTime;
    let text = text.trim();
    let body = ["LTIME#", "TIME#", "LT#", "T#"]
        .iter()
        .find_map(|p| {
            let head = text.get(..p.len())?;
            head.eq_ignore_ascii_case(p).then(|| &text[p.len()..])
        })
        .unwrap_or(text);
    let (negative, body) = match body.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, body.strip_prefix('+').unwrap_or(body)),
    };
    let mut buf = [0u8; NUMBER_TEXT];
    let body = without_underscores(body, &mut buf).ok_or(bad("too long"))?;
    if body.is_empty() {
        return Err(bad("no duration"));
    }
    let mut total: i128 = 0;
    let mut rest = body;
    while !rest.is_empty() {
        let number_len =
            rest.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(rest.len());
        let (number, after) = rest.split_at(number_len);
        let unit_len = after.find(|c: char| !c.is_ascii_alphabetic()).unwrap_or(after.len());
        let (unit, after) = after.split_at(unit_len);
        if number.is_empty() {
            return Err(bad("a number must come before each unit"));
        }
        let size = TIME_UNITS
            .iter()
            .find(|(u, _)| u.eq_ignore_ascii_case(unit))
            .map(|(_, size)| *size)
            .ok_or(bad(if unit.is_empty() { "a unit is missing" } else { "unknown unit" }))?;
        let (whole, fraction) = number.split_once('.').unwrap_or((number, ""));
        let whole: i128 = if whole.is_empty() {
            0
        } else {
            whole.parse().map_err(|_| bad("a number is too long"))?
        };
        total = total.saturating_add(whole.saturating_mul(i128::from(size)));
        if !fraction.is_empty() {
            if fraction.contains('.') {
                return Err(bad("a number has two points"));
            }
            // The fraction's digits, to the nanosecond (digits beyond it are cut).
            let mut scale = i128::from(size);
            for digit in fraction.bytes() {
                scale /= 10;
                total += i128::from(digit - b'0') * scale;
            }
        }
        rest = after;
    }
    let ns = if negative { -total } else { total };
    i64::try_from(ns).map_err(|_| TextError::OutOfRange)
}

/// The date and time-of-day types of IEC 61131-3 ed3, stored as CODESYS stores them: a count of
/// a unit since an origin, unsigned, so the conversions to and from integers and bit strings
/// give CODESYS's numbers (`DT_TO_DWORD`, `DWORD_TO_TOD`).
///
/// | type | stored as | counts | origin |
/// |---|---|---|---|
/// | `DATE` | `U32` | seconds (a whole day's) | 1970-01-01 |
/// | `TOD` | `U32` | milliseconds | midnight |
/// | `DT` | `U32` | seconds | 1970-01-01 00:00:00 |
/// | `LDATE` | `U64` | nanoseconds (a whole day's) | 1970-01-01 |
/// | `LTOD` | `U64` | nanoseconds | midnight |
/// | `LDT` | `U64` | nanoseconds | 1970-01-01 00:00:00 |
///
/// Dates are of the proleptic Gregorian calendar, without leap seconds and without a time zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Calendar {
    Date,
    Tod,
    Dt,
    LDate,
    LTod,
    LDt,
}

/// Nanoseconds in a day.
pub const DAY_NS: u64 = 86_400_000_000_000;

/// What a calendar type holds: a date, a time of day, or both.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalendarKind {
    Date,
    Tod,
    Dt,
}

impl Calendar {
    pub const ALL: [Calendar; 6] = [
        Calendar::Date,
        Calendar::Tod,
        Calendar::Dt,
        Calendar::LDate,
        Calendar::LTod,
        Calendar::LDt,
    ];

    /// The type's name in messages and in conversion functions (`DT_TO_DWORD`).
    pub const fn name(self) -> &'static str {
        match self {
            Calendar::Date => "DATE",
            Calendar::Tod => "TOD",
            Calendar::Dt => "DT",
            Calendar::LDate => "LDATE",
            Calendar::LTod => "LTOD",
            Calendar::LDt => "LDT",
        }
    }

    /// Every name of the type (IEC 61131-3 ed3, table 10), the short one first.
    pub const fn names(self) -> &'static [&'static str] {
        match self {
            Calendar::Date => &["DATE"],
            Calendar::Tod => &["TOD", "TIME_OF_DAY"],
            Calendar::Dt => &["DT", "DATE_AND_TIME"],
            Calendar::LDate => &["LDATE"],
            Calendar::LTod => &["LTOD", "LTIME_OF_DAY"],
            Calendar::LDt => &["LDT", "LDATE_AND_TIME"],
        }
    }

    /// The prefixes of its literals (`D#`, `DATE#`), the one values are written with first.
    pub const fn prefixes(self) -> &'static [&'static str] {
        match self {
            Calendar::Date => &["D", "DATE"],
            Calendar::Tod => &["TOD", "TIME_OF_DAY"],
            Calendar::Dt => &["DT", "DATE_AND_TIME"],
            Calendar::LDate => &["LDATE", "LD"],
            Calendar::LTod => &["LTOD", "LTIME_OF_DAY"],
            Calendar::LDt => &["LDT", "LDATE_AND_TIME"],
        }
    }

    /// The type a literal prefix (without its `#`, any case) names.
    pub fn from_prefix(prefix: &str) -> Option<Calendar> {
        Calendar::ALL
            .into_iter()
            .find(|c| c.prefixes().iter().any(|p| p.eq_ignore_ascii_case(prefix)))
    }

    /// The type a type name (any case) names.
    pub fn from_name(name: &str) -> Option<Calendar> {
        Calendar::ALL.into_iter().find(|c| c.names().iter().any(|n| n.eq_ignore_ascii_case(name)))
    }

    pub const fn elem(self) -> Elem {
        if self.is_long() {
            Elem::U64
        } else {
            Elem::U32
        }
    }

    /// `LDATE`, `LTOD`, `LDT`.
    pub const fn is_long(self) -> bool {
        matches!(self, Calendar::LDate | Calendar::LTod | Calendar::LDt)
    }

    pub const fn kind(self) -> CalendarKind {
        match self {
            Calendar::Date | Calendar::LDate => CalendarKind::Date,
            Calendar::Tod | Calendar::LTod => CalendarKind::Tod,
            Calendar::Dt | Calendar::LDt => CalendarKind::Dt,
        }
    }

    /// The nanoseconds one unit of the stored count is.
    pub const fn unit_ns(self) -> u64 {
        match self {
            Calendar::Date | Calendar::Dt => 1_000_000_000,
            Calendar::Tod => 1_000_000,
            Calendar::LDate | Calendar::LTod | Calendar::LDt => 1,
        }
    }

    /// The largest count the type stores.
    pub const fn max(self) -> u64 {
        if self.is_long() {
            u64::MAX
        } else {
            u32::MAX as u64
        }
    }

    /// A literal of the type, for messages.
    pub const fn example(self) -> &'static str {
        match self {
            Calendar::Date => "D#2024-03-01",
            Calendar::Tod => "TOD#12:30:15.5",
            Calendar::Dt => "DT#2024-03-01-12:30:15",
            Calendar::LDate => "LDATE#2024-03-01",
            Calendar::LTod => "LTOD#12:30:15.5",
            Calendar::LDt => "LDT#2024-03-01-12:30:15",
        }
    }

    /// The form of a literal's text after its prefix, for messages.
    const fn form(self) -> &'static str {
        match self.kind() {
            CalendarKind::Date => "YYYY-MM-DD",
            CalendarKind::Tod => "HH:MM:SS",
            CalendarKind::Dt => "YYYY-MM-DD-HH:MM:SS",
        }
    }

    /// The unit a value of the type is a whole number of, for messages.
    const fn unit_name(self) -> &'static str {
        match self.unit_ns() {
            1 => "nanoseconds",
            1_000_000 => "milliseconds",
            _ => "seconds",
        }
    }
}

/// Why a text is not a value of a calendar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalendarError {
    /// Not of the type's form (`YYYY-MM-DD`, `HH:MM:SS`, `YYYY-MM-DD-HH:MM:SS`).
    Form(Calendar),
    Month(u64),
    Day {
        day: u64,
        year: u64,
        month: u64,
    },
    Hour(u64),
    Minute(u64),
    Second(u64),
    /// A fraction of a second finer than the type holds (`TOD#12:00:00.0001`).
    Finer(Calendar),
    /// Before 1970-01-01 or after the last value the type holds.
    Range(Calendar),
}

impl CalendarError {
    /// Every message of [`CalendarError`]'s `Display`, its varying parts `{}`.
    pub const TEMPLATES: [&'static str; 8] = [
        "expected {}",
        "month {} is not 1 to 12",
        "day {} is not a day of {}",
        "hour {} is not 0 to 23",
        "minute {} is not 0 to 59",
        "second {} is not 0 to 59",
        "a {} holds whole {}",
        "out of range: {} to {}",
    ];
}

impl fmt::Display for CalendarError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            CalendarError::Form(cal) => write!(f, "expected {}", cal.form()),
            CalendarError::Month(m) => write!(f, "month {m} is not 1 to 12"),
            CalendarError::Day { day, year, month } => {
                write!(f, "day {day} is not a day of {year}-{month:02}")
            }
            CalendarError::Hour(h) => write!(f, "hour {h} is not 0 to 23"),
            CalendarError::Minute(m) => write!(f, "minute {m} is not 0 to 59"),
            CalendarError::Second(s) => write!(f, "second {s} is not 0 to 59"),
            CalendarError::Finer(cal) => {
                write!(f, "a {} holds whole {}", cal.name(), cal.unit_name())
            }
            CalendarError::Range(cal) => {
                f.write_str("out of range: ")?;
                write_calendar(f, cal, 0)?;
                f.write_str(" to ")?;
                write_calendar(f, cal, cal.max())
            }
        }
    }
}

/// Days since 1970-01-01 of a date of the proleptic Gregorian calendar (H. Hinnant's
/// `days_from_civil`).
pub const fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let march_month = (month as i64 + 9) % 12;
    let day_of_year = (153 * march_month + 2) / 5 + day as i64 - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    era * 146_097 + day_of_era - 719_468
}

/// The year, month (1–12) and day (1–31) of a count of days since 1970-01-01.
pub const fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z - era * 146_097;
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let march_month = (5 * day_of_year + 2) / 153;
    let day = (day_of_year - (153 * march_month + 2) / 5 + 1) as u32;
    let month = if march_month < 10 { march_month + 3 } else { march_month - 9 } as u32;
    let year = year_of_era + era * 400 + if month <= 2 { 1 } else { 0 };
    (year, month, day)
}

/// The days of a month of a year.
pub const fn days_in_month(year: i64, month: u32) -> u32 {
    match month {
        2 if year % 4 == 0 && (year % 100 != 0 || year % 400 == 0) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Writes a calendar value as its IEC literal: `D#2024-03-01`, `TOD#12:30:15.5`,
/// `DT#2024-03-01-12:30:15`, `LDATE#…`, `LTOD#…`, `LDT#…`; a fraction of a second only when
/// there is one, without its trailing zeros. A `TOD` beyond a day (`DWORD_TO_TOD` of a large
/// number) shows its hours beyond 23; a `DATE` that is not a whole day shows its day.
pub fn write_calendar(out: &mut impl fmt::Write, cal: Calendar, slot: u64) -> fmt::Result {
    let ns = u128::from(slot & cal.max()) * u128::from(cal.unit_ns());
    let (days, in_day) = ((ns / u128::from(DAY_NS)) as i64, (ns % u128::from(DAY_NS)) as u64);
    write!(out, "{}#", cal.prefixes()[0])?;
    let (date, tod_ns) = match cal.kind() {
        CalendarKind::Date => (Some(days), None),
        CalendarKind::Tod => (None, Some(ns)),
        CalendarKind::Dt => (Some(days), Some(u128::from(in_day))),
    };
    if let Some(days) = date {
        let (y, m, d) = civil_from_days(days);
        write!(out, "{y:04}-{m:02}-{d:02}")?;
        if tod_ns.is_some() {
            out.write_char('-')?;
        }
    }
    if let Some(ns) = tod_ns {
        let secs = ns / 1_000_000_000;
        let (h, m, s) = (secs / 3600, secs / 60 % 60, secs % 60);
        write!(out, "{h:02}:{m:02}:{s:02}")?;
        let mut fraction = (ns % 1_000_000_000) as u32;
        if fraction > 0 {
            let mut digits = 9;
            while fraction % 10 == 0 {
                fraction /= 10;
                digits -= 1;
            }
            write!(out, ".{fraction:0digits$}")?;
        }
    }
    Ok(())
}

/// A number of at most 9 decimal digits, nothing else.
fn calendar_field(text: &str) -> Option<u64> {
    if text.is_empty() || text.len() > 9 || !text.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    text.parse().ok()
}

/// The days since 1970-01-01 of `YYYY-MM-DD`.
fn date_days(cal: Calendar, text: &str) -> Result<i64, CalendarError> {
    let mut fields = text.split('-');
    let mut next = || fields.next().and_then(calendar_field).ok_or(CalendarError::Form(cal));
    let (year, month, day) = (next()?, next()?, next()?);
    if fields.next().is_some() {
        return Err(CalendarError::Form(cal));
    }
    if !(1..=12).contains(&month) {
        return Err(CalendarError::Month(month));
    }
    if day < 1 || day > u64::from(days_in_month(year as i64, month as u32)) {
        return Err(CalendarError::Day { day, year, month });
    }
    Ok(days_from_civil(year as i64, month as u32, day as u32))
}

/// The nanoseconds since midnight of `HH:MM:SS` with an optional fraction of a second (digits
/// beyond the nanosecond must be zeros), or of `HH:MM` (CODESYS writes `TOD#00:00`).
fn tod_ns(cal: Calendar, text: &str) -> Result<u64, CalendarError> {
    let mut fields = text.split(':');
    let mut next = || fields.next().ok_or(CalendarError::Form(cal));
    let (hour, minute) = (next()?, next()?);
    let second = fields.next().unwrap_or("0");
    if fields.next().is_some() {
        return Err(CalendarError::Form(cal));
    }
    let (second, fraction) = second.split_once('.').unwrap_or((second, ""));
    let field = |t: &str| calendar_field(t).ok_or(CalendarError::Form(cal));
    let (hour, minute, second) = (field(hour)?, field(minute)?, field(second)?);
    if !fraction.bytes().all(|b| b.is_ascii_digit()) || text.ends_with('.') {
        return Err(CalendarError::Form(cal));
    }
    if hour > 23 {
        return Err(CalendarError::Hour(hour));
    }
    if minute > 59 {
        return Err(CalendarError::Minute(minute));
    }
    if second > 59 {
        return Err(CalendarError::Second(second));
    }
    let mut ns = ((hour * 60 + minute) * 60 + second) * 1_000_000_000;
    let mut scale = 1_000_000_000;
    for digit in fraction.bytes() {
        scale /= 10;
        if scale == 0 && digit != b'0' {
            return Err(CalendarError::Finer(cal));
        }
        ns += u64::from(digit - b'0') * scale;
    }
    Ok(ns)
}

/// The stored count of a literal's text after its prefix (`2024-03-01` for a `DATE`), without
/// allocating.
pub fn calendar_body(cal: Calendar, body: &str) -> Result<u64, CalendarError> {
    let (date, tod) = match cal.kind() {
        CalendarKind::Date => (Some(body), None),
        CalendarKind::Tod => (None, Some(body)),
        CalendarKind::Dt => {
            let at = body.match_indices('-').nth(2).ok_or(CalendarError::Form(cal))?.0;
            (Some(&body[..at]), Some(&body[at + 1..]))
        }
    };
    let mut ns: i128 = 0;
    if let Some(date) = date {
        ns += i128::from(date_days(cal, date)?) * i128::from(DAY_NS);
    }
    if let Some(tod) = tod {
        ns += i128::from(tod_ns(cal, tod)?);
    }
    let unit = i128::from(cal.unit_ns());
    if ns % unit != 0 {
        return Err(CalendarError::Finer(cal));
    }
    let count = ns / unit;
    if count < 0 || count > i128::from(cal.max()) {
        return Err(CalendarError::Range(cal));
    }
    Ok(count as u64)
}

/// A calendar value as a client or `STRING_TO_DATE` writes it: the literal with one of the
/// type's prefixes (any case), or its text alone; spaces around it ignored.
pub fn calendar_from_text(cal: Calendar, text: &str) -> Result<u64, CalendarError> {
    let text = text.trim();
    let body = match text.split_once('#') {
        Some((prefix, body)) if Calendar::from_prefix(prefix) == Some(cal) => body,
        Some(_) => return Err(CalendarError::Form(cal)),
        None => text,
    };
    calendar_body(cal, body)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_client_s_text_becomes_what_set_takes_or_is_not_held() {
        let written = |ty: &ValueType, text: &str| text_written(ty, text);
        assert_eq!(written(&ValueType::String { cap: 8 }, "it's"), Some(Ok("'it$'s'".into())));
        assert_eq!(written(&ValueType::String { cap: 8 }, "\u{3042}"), Some(Err(TextNotHeld)));
        assert_eq!(
            written(&ValueType::WString { cap: 8 }, "\u{3042}"),
            Some(Ok("\"\u{3042}\"".into()))
        );
        assert_eq!(written(&ValueType::Char, "ä"), Some(Ok(format(&ValueType::Char, 0xE4))));
        assert_eq!(written(&ValueType::Char, "ab"), Some(Err(TextNotHeld)));
        assert_eq!(written(&ValueType::WChar, ""), Some(Err(TextNotHeld)));
        assert_eq!(written(&ValueType::Bool, "TRUE"), None, "no text type");
    }

    #[test]
    fn string_bytes_are_windows_1252_characters_both_ways() {
        for b in 0..=255u8 {
            assert_eq!(encode_char(decode_byte(b)), Some(b), "byte {b:#04X}");
        }
        assert_eq!(encode_str("Grüße €5"), Ok(b"Gr\xFC\xDFe \x805".to_vec()));
        assert_eq!(encode_str("π"), Err('π'));
        assert_eq!(decode_str(b"\x80\xE4\x9F"), "€äŸ");
        assert_eq!(parse_string("'€$E4'", 5), Ok(vec![0x80, 0xE4]));
        assert_eq!(parse_string("größe", 5), Ok(b"gr\xF6\xDFe".to_vec()));
        assert!(parse_string("'π'", 5).unwrap_err().contains("Windows-1252"));
    }
    use BinOp::*;
    use Elem::*;

    #[test]
    fn references_are_shown_by_what_they_point_to() {
        let r = |space, offset| Pointer { space, offset }.to_slot() + REF_TAG;
        assert_eq!(format_reference(0), "NULL");
        assert_eq!(format_reference(12), "NULL");
        assert_eq!(format_reference(r(Space::Var, 120)), "vars+120");
        assert_eq!(format_reference(r(Space::Frame, 16)), "frame+16");
        assert_eq!(format_reference(r(Space::Word, 4992)), "word+4992");
        assert_eq!(format_reference(r(Space::Bit, 64)), "bit+64");
        assert_eq!(format_reference(r(Space::Byte, 129)), "byte+129");
        assert_eq!(format_reference(r(Space::Discard, 0)), "invalid");
        assert_eq!(
            Pointer::from_reference(r(Space::Frame, 3)),
            Some(Pointer { space: Space::Frame, offset: 3 })
        );
        let ty = ValueType::Reference { type_name: "POINTER TO INT".into() };
        assert_eq!(format(&ty, 0), "NULL");
        assert_eq!(ty.bytes(), 8);
        assert!(parse(&ty, "5").is_err());
    }

    fn i(elem: Elem, v: i64) -> u64 {
        normalize(elem, v as u64)
    }
    fn f32s(x: f32) -> u64 {
        x.to_bits() as u64
    }
    fn f64s(x: f64) -> u64 {
        x.to_bits()
    }
    fn bin(op: BinOp, elem: Elem, a: i64, b: i64) -> Result<i64, OpError> {
        binary(op, elem, i(elem, a), i(elem, b)).map(|r| r as i64)
    }

    #[test]
    fn normalize_truncates_and_extends() {
        assert_eq!(normalize(I8, 0x1FF), u64::MAX);
        assert_eq!(normalize(U8, 0x1FF), 0xFF);
        assert_eq!(normalize(I16, 0x8000), 0xFFFF_FFFF_FFFF_8000);
        assert_eq!(normalize(U32, u64::MAX), 0xFFFF_FFFF);
        assert_eq!(normalize(F32, u64::MAX), 0xFFFF_FFFF);
        assert_eq!(normalize(Bool, 2), 1);
        assert_eq!(normalize(Bool, 0), 0);
        assert_eq!(normalize(I64, 5), 5);
    }

    #[test]
    fn integer_arithmetic_wraps() {
        assert_eq!(bin(Add, I8, 127, 1), Ok(-128));
        assert_eq!(bin(Sub, U8, 0, 1), Ok(255));
        assert_eq!(bin(Mul, I16, 300, 300), Ok(24464));
        assert_eq!(bin(Add, I64, i64::MAX, 1), Ok(i64::MIN));
        assert_eq!(bin(Mul, U32, 0x10000, 0x10000), Ok(0));
    }

    #[test]
    fn division_truncates_and_mod_takes_the_dividends_sign() {
        assert_eq!(bin(Div, I32, -7, 2), Ok(-3));
        assert_eq!(bin(Mod, I32, -7, 2), Ok(-1));
        assert_eq!(bin(Mod, I32, 7, -2), Ok(1));
        assert_eq!(bin(Div, I8, -128, -1), Ok(-128));
        assert_eq!(bin(Mod, I8, -128, -1), Ok(0));
        assert_eq!(bin(Div, U16, 65535, 2), Ok(32767));
        assert_eq!(bin(Div, I16, 5, 0), Err(OpError::DivideByZero));
        assert_eq!(bin(Mod, U64, 5, 0), Err(OpError::DivideByZero));
        assert_eq!(binary(Div, F32, f32s(1.0), f32s(0.0)), Err(OpError::DivideByZero));
        assert_eq!(binary(Div, F64, f64s(1.0), f64s(-0.0)), Err(OpError::DivideByZero));
        assert_eq!(binary(Mod, F64, f64s(1.0), f64s(0.0)), Err(OpError::DivideByZero));
        assert_eq!(binary(Div, F64, f64s(7.0), f64s(2.0)), Ok(f64s(3.5)));
    }

    #[test]
    fn shifts_and_rotations() {
        assert_eq!(bin(Shl, U8, 0x81, 1), Ok(0x02));
        assert_eq!(bin(Shr, U8, 0x81, 1), Ok(0x40));
        assert_eq!(bin(Shl, U16, 1, 16), Ok(0));
        assert_eq!(bin(Shr, U64, -1, 64), Ok(0));
        assert_eq!(bin(Shl, U64, 1, 63), Ok(i64::MIN));
        // Shifts are logical on the value's bits, for signed types too.
        assert_eq!(bin(Shr, I8, -128, 1), Ok(64));
        assert_eq!(bin(Shl, I8, 64, 1), Ok(-128));
        // A negative count shifts by nothing.
        assert_eq!(bin(Shl, I16, 5, -1), Ok(5));
        assert_eq!(bin(Rol, U8, 0x81, 1), Ok(0x03));
        assert_eq!(bin(Ror, U8, 0x81, 1), Ok(0xC0));
        assert_eq!(bin(Rol, U8, 0x81, 9), Ok(0x03));
        assert_eq!(bin(Ror, U16, 1, 16), Ok(1));
        assert_eq!(bin(Rol, I8, 1, -1), Ok(-128), "ROL by -1 is ROR by 1");
        assert_eq!(bin(Rol, U32, 0x8000_0000, 1), Ok(1));
        assert_eq!(bin(Ror, U64, 1, 1), Ok(i64::MIN));
    }

    #[test]
    fn logic_min_max_and_power() {
        assert_eq!(bin(And, U8, 0xF0, 0x3C), Ok(0x30));
        assert_eq!(bin(Or, I16, -2, 1), Ok(-1));
        assert_eq!(bin(Xor, Bool, 1, 1), Ok(0));
        assert_eq!(bin(And, Bool, 1, 1), Ok(1));
        assert_eq!(bin(Min, I32, -5, 3), Ok(-5));
        assert_eq!(bin(Max, U32, 0xFFFF_FFFF, 3), Ok(0xFFFF_FFFF));
        assert_eq!(bin(Expt, I32, 3, 4), Ok(81));
        assert_eq!(bin(Expt, I8, 2, 7), Ok(-128));
        assert_eq!(bin(Expt, I32, 2, -1), Ok(0));
        assert_eq!(bin(Expt, I32, -1, -3), Ok(-1));
        assert_eq!(bin(Expt, I32, 0, -1), Err(OpError::DivideByZero));
        assert_eq!(binary(Expt, F64, f64s(2.0), f64s(0.5)), Ok(f64s(2f64.sqrt())));
        assert_eq!(binary(Max, F32, f32s(f32::NAN), f32s(1.0)), Ok(f32s(1.0)));
    }

    #[test]
    fn bool_is_a_one_bit_integer() {
        assert_eq!(bin(Add, Bool, 1, 1), Ok(0));
        assert_eq!(unary(UnOp::Not, Bool, 1), 0);
        assert_eq!(unary(UnOp::Not, Bool, 0), 1);
        assert_eq!(unary(UnOp::Neg, Bool, 1), 1);
    }

    #[test]
    fn unary_operations() {
        assert_eq!(unary(UnOp::Neg, I8, i(I8, -128)), i(I8, -128));
        assert_eq!(unary(UnOp::Abs, I16, i(I16, -5)), 5);
        assert_eq!(unary(UnOp::Abs, I16, i(I16, -32768)), i(I16, -32768));
        assert_eq!(unary(UnOp::Not, U8, 0x0F), 0xF0);
        assert_eq!(unary(UnOp::Not, I32, 0), i(I32, -1));
        assert_eq!(unary(UnOp::Sqrt, F32, f32s(9.0)), f32s(3.0));
        assert_eq!(unary(UnOp::Trunc, F64, f64s(-2.7)), f64s(-2.0));
        assert_eq!(unary(UnOp::Log, F64, f64s(1000.0)), f64s(3.0));
        assert_eq!(unary(UnOp::Neg, F32, f32s(1.5)), f32s(-1.5));
        assert_eq!(unary(UnOp::Sqrt, I32, 17), 4, "through LREAL, rounded");
        assert!(f32::from_bits(unary(UnOp::Ln, F32, f32s(-1.0)) as u32).is_nan());
    }

    #[test]
    fn comparisons() {
        assert_eq!(compare(I8, i(I8, -1), 1), Some(Ordering::Less));
        assert_eq!(compare(U8, 255, 1), Some(Ordering::Greater));
        assert_eq!(compare(F32, f32s(-0.0), f32s(0.0)), Some(Ordering::Equal));
        assert_eq!(compare(F64, f64s(f64::NAN), f64s(0.0)), None);
        assert_eq!(compare(Bool, 1, 0), Some(Ordering::Greater));
    }

    #[test]
    fn conversions() {
        assert_eq!(convert(I16, U8, i(I16, -1)), 255);
        assert_eq!(convert(U16, I8, 0xFF80), i(I8, -128));
        assert_eq!(convert(I8, U64, i(I8, -1)), u64::MAX);
        assert_eq!(convert(F32, I16, f32s(2.5)), 3);
        assert_eq!(convert(F32, I16, f32s(-2.5)), i(I16, -3));
        assert_eq!(convert(F64, I16, f64s(1e9)), i(I16, 32767));
        assert_eq!(convert(F64, U8, f64s(-3.0)), 0);
        assert_eq!(convert(F64, I32, f64s(f64::NAN)), 0);
        assert_eq!(convert(F64, I64, f64s(-1e300)), i64::MIN as u64);
        assert_eq!(convert(I32, F32, 16_777_217), f32s(16_777_216.0));
        assert_eq!(convert(U64, F64, u64::MAX), f64s(18446744073709551615.0));
        assert_eq!(convert(I64, F64, i(I64, -3)), f64s(-3.0));
        assert_eq!(convert(F32, F64, f32s(0.1)), f64s(f64::from(0.1f32)));
        assert_eq!(convert(F64, F32, f64s(0.1)), f32s(0.1));
        assert_eq!(convert(F64, Bool, f64s(0.5)), 1);
        assert_eq!(convert(F32, Bool, f32s(-0.0)), 0);
        assert_eq!(convert(I32, Bool, i(I32, -7)), 1);
        assert_eq!(convert(Bool, F32, 1), f32s(1.0));
        assert_eq!(convert(Bool, I16, 1), 1);
        assert_eq!(convert(U8, U8, 7), 7);
    }

    #[test]
    fn formats_values() {
        assert_eq!(format(&ValueType::Bool, 1), "1");
        assert_eq!(format(&ValueType::Signed(I16), i(I16, -5)), "-5");
        assert_eq!(format(&ValueType::Unsigned(U64), u64::MAX), "18446744073709551615");
        assert_eq!(format(&ValueType::Real(F32), f32s(1.5)), "1.5");
        assert_eq!(format(&ValueType::Real(F32), f32s(0.1)), "0.1");
        assert_eq!(format(&ValueType::Real(F64), f64s(2.0)), "2.0");
        assert_eq!(format(&ValueType::Real(F64), f64s(1e-7)), "1e-7");
        assert_eq!(format(&ValueType::Time, 1_500_000_000), "T#1s500ms");
        assert_eq!(format(&ValueType::Time, 0), "T#0s");
        assert_eq!(format(&ValueType::Time, (-5_000_000_000i64) as u64), "T#-5s");
        assert_eq!(format(&ValueType::Time, 90 * 60 * 1_000_000_000 + 7), "T#1h30m7ns");
        assert_eq!(format(&ValueType::Time, i64::MIN as u64), "T#-106751d23h47m16s854ms775us808ns");
        let color = ValueType::Enum {
            type_name: "Color".into(),
            values: vec![("Red".into(), 0), ("Green".into(), 1), ("Blue".into(), -2)],
            base: I32,
        };
        assert_eq!(format(&color, 1), "Green");
        assert_eq!(format(&color, i(I32, -2)), "Blue");
        assert_eq!(format(&color, 7), "7");
        assert_eq!(format_string(b"it's $5\n\x01"), "'it$'s $$5$N$01'");
    }

    #[test]
    fn parses_values() {
        let sint = ValueType::Signed(I8);
        assert_eq!(parse(&sint, "-128"), Ok(i(I8, -128)));
        assert_eq!(parse(&sint, "16#FF"), Ok(i(I8, -1)));
        assert_eq!(parse(&sint, "2#0111_1111"), Ok(127));
        assert_eq!(parse(&sint, "128"), Err("`128` is out of range for SINT (-128..=127)".into()));
        assert_eq!(
            parse(&sint, "16#100"),
            Err("`16#100` is out of range for SINT (-128..=127)".into())
        );
        assert!(parse(&sint, "x").is_err());
        assert!(parse(&sint, "--1").is_err());
        let word = ValueType::Unsigned(U16);
        assert_eq!(parse(&word, "65535"), Ok(65535));
        assert_eq!(parse(&word, "+1_000"), Ok(1000));
        assert_eq!(parse(&word, "-1"), Err("`-1` is out of range for UINT (0..=65535)".into()));
        assert_eq!(parse(&ValueType::Unsigned(U64), "18446744073709551615"), Ok(u64::MAX));
        assert_eq!(parse(&ValueType::Signed(I64), "-9223372036854775808"), Ok(i64::MIN as u64));
        assert_eq!(parse(&ValueType::Bool, "true"), Ok(1));
        assert_eq!(parse(&ValueType::Bool, "0"), Ok(0));
        assert!(parse(&ValueType::Bool, "2").is_err());
        assert_eq!(parse(&ValueType::Real(F32), "1.5"), Ok(f32s(1.5)));
        assert_eq!(parse(&ValueType::Real(F32), "-2"), Ok(f32s(-2.0)));
        assert_eq!(parse(&ValueType::Real(F64), "1e-3"), Ok(f64s(1e-3)));
        assert!(parse(&ValueType::Real(F32), "1e40").is_err());
        assert_eq!(parse(&ValueType::Real(F32), "inf"), Ok(f32s(f32::INFINITY)));
        assert_eq!(parse(&ValueType::Time, "T#1s500ms"), Ok(1_500_000_000));
        assert_eq!(parse(&ValueType::Time, "time#-5s"), Ok((-5_000_000_000i64) as u64));
        assert_eq!(parse(&ValueType::Time, "1.5s"), Ok(1_500_000_000));
        assert_eq!(parse(&ValueType::Time, "1m30s"), Ok(90_000_000_000));
        assert_eq!(parse(&ValueType::Time, "250ms"), Ok(250_000_000));
        assert_eq!(parse(&ValueType::Time, "T#1d_2h"), Ok(93_600_000_000_000));
        assert!(parse(&ValueType::Time, "5").is_err());
        assert!(parse(&ValueType::Time, "5x").is_err());
        assert!(parse(&ValueType::Time, "T#200000d").is_err());
        let color = ValueType::Enum {
            type_name: "Color".into(),
            values: vec![("Red".into(), 0), ("Blue".into(), -2)],
            base: I32,
        };
        assert_eq!(parse(&color, "blue"), Ok(i(I32, -2)));
        assert_eq!(parse(&color, "Color#Red"), Ok(0));
        assert_eq!(parse(&color, "Pink"), Err("`Pink` is not a value of Color (Red, Blue)".into()));
        assert_eq!(parse_string("'a$'b$24'", 10), Ok(b"a'b$".to_vec()));
        assert_eq!(parse_string("abc", 3), Ok(b"abc".to_vec()));
        assert!(parse_string("abcd", 3).is_err());
    }

    #[test]
    fn format_and_parse_round_trip() {
        for ns in [0i64, 1, -1, 1_500_000_000, i64::MAX, i64::MIN, 86_400_000_000_123] {
            assert_eq!(parse(&ValueType::Time, &format_time(ns)), Ok(ns as u64));
        }
        for x in [0.1f32, 1.0, -3.25e-20, f32::MAX, f32::MIN_POSITIVE] {
            let ty = ValueType::Real(F32);
            assert_eq!(parse(&ty, &format(&ty, f32s(x))), Ok(f32s(x)));
        }
        for x in [0.1f64, 1e300, -2.5] {
            let ty = ValueType::Real(F64);
            assert_eq!(parse(&ty, &format(&ty, f64s(x))), Ok(f64s(x)));
        }
    }

    #[test]
    fn pointers_round_trip() {
        let p = Pointer { space: Space::Bit, offset: 1234 };
        assert_eq!(Pointer::from_slot(p.to_slot()), p);
        assert_eq!(Pointer::from_slot(99 << 32).space, Space::Discard);
        let p = Pointer { space: Space::Byte, offset: 129 };
        assert_eq!(Pointer::from_slot(p.to_slot()), p);
    }

    #[test]
    fn calendar_values_are_codesys_counts() {
        // 2024-03-01 is 19783 days after 1970-01-01 (54 years, 13 of them leap: 1972 … 2020).
        assert_eq!(days_from_civil(2024, 3, 1), 19_783);
        assert_eq!(civil_from_days(19_783), (2024, 3, 1));
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        let date = ValueType::Calendar(Calendar::Date);
        assert_eq!(parse(&date, "D#2024-03-01"), Ok(19_783 * 86_400));
        assert_eq!(format(&date, 19_783 * 86_400), "D#2024-03-01");
        let tod = ValueType::Calendar(Calendar::Tod);
        assert_eq!(parse(&tod, "TOD#12:30:15.5"), Ok(45_015_500));
        assert_eq!(parse(&tod, "time_of_day#00:00:00"), Ok(0));
        assert_eq!(format(&tod, 45_015_500), "TOD#12:30:15.5");
        assert_eq!(format(&tod, 100_000_000), "TOD#27:46:40");
        let dt = ValueType::Calendar(Calendar::Dt);
        assert_eq!(parse(&dt, "DT#2024-03-01-12:30:15"), Ok(19_783 * 86_400 + 45_015));
        assert_eq!(parse(&dt, "2024-03-01-12:30:15"), Ok(19_783 * 86_400 + 45_015));
        assert_eq!(format(&dt, u64::from(u32::MAX)), "DT#2106-02-07-06:28:15");
        let ldt = ValueType::Calendar(Calendar::LDt);
        assert_eq!(parse(&ldt, "LDT#1970-01-01-00:00:00.000000001"), Ok(1));
        assert_eq!(format(&ldt, u64::MAX), "LDT#2554-07-21-23:34:33.709551615");
        let ltod = ValueType::Calendar(Calendar::LTod);
        assert_eq!(format(&ltod, 1_500), "LTOD#00:00:00.0000015");
        for cal in Calendar::ALL {
            for slot in [0, 1, 86_399, 86_400_000, 1_234_567_890, cal.max()] {
                let text = format(&ValueType::Calendar(cal), slot);
                let back = parse(&ValueType::Calendar(cal), &text);
                let whole =
                    cal.kind() != CalendarKind::Date || slot % (DAY_NS / cal.unit_ns()) == 0;
                let in_day = cal.kind() != CalendarKind::Tod || slot < DAY_NS / cal.unit_ns();
                if whole && in_day {
                    assert_eq!(back, Ok(slot), "{text}");
                }
            }
        }
    }

    #[test]
    fn invalid_calendar_texts_say_why() {
        let why = |cal, text| calendar_from_text(cal, text).unwrap_err().to_string();
        assert_eq!(why(Calendar::Date, "2024-13-01"), "month 13 is not 1 to 12");
        assert_eq!(why(Calendar::Date, "2023-02-29"), "day 29 is not a day of 2023-02");
        assert_eq!(why(Calendar::Date, "2024-3"), "expected YYYY-MM-DD");
        assert_eq!(why(Calendar::Tod, "25:00:00"), "hour 25 is not 0 to 23");
        assert_eq!(why(Calendar::Tod, "12:60:00"), "minute 60 is not 0 to 59");
        assert_eq!(why(Calendar::Tod, "12:00:60"), "second 60 is not 0 to 59");
        assert_eq!(why(Calendar::Tod, "12:00:00.0001"), "a TOD holds whole milliseconds");
        assert_eq!(why(Calendar::Dt, "2024-01-01-12:00:00.5"), "a DT holds whole seconds");
        assert_eq!(why(Calendar::Date, "1969-12-31"), "out of range: D#1970-01-01 to D#2106-02-07");
        assert_eq!(why(Calendar::Date, "TOD#12:00:00"), "expected YYYY-MM-DD");
        assert_eq!(why(Calendar::Tod, "12"), "expected HH:MM:SS");
        assert_eq!(why(Calendar::Tod, "12:00:00:00"), "expected HH:MM:SS");
        // The seconds may be left out, as CODESYS writes them.
        assert_eq!(calendar_from_text(Calendar::Tod, "TOD#12:30"), Ok(45_000_000));
        assert_eq!(calendar_from_text(Calendar::Dt, "DT#1970-01-01-00:01"), Ok(60));
        assert_eq!(
            parse(&ValueType::Calendar(Calendar::Date), "D#2024-13-01"),
            Err("`D#2024-13-01` is not a DATE (month 13 is not 1 to 12; e.g. D#2024-03-01)".into())
        );
        assert_eq!(scalar_from_text(Scalar::Calendar(Calendar::Tod), " 1:2:3 "), Ok(3_723_000));
    }
}
