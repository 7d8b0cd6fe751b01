//! The type model: elementary types, strings, arrays, structures, enumerations, subranges and
//! FB types, their sizes, their names in messages, and the implicit conversions IEC 61131-3
//! allows.
//!
//! # Implicit conversions (IEC 61131-3 ed. 3, Table 11, "implicit")
//!
//! Only widening conversions that keep every value exactly:
//!
//! | from    | to                                            |
//! |---------|-----------------------------------------------|
//! | `SINT`  | `INT DINT LINT REAL LREAL`                    |
//! | `INT`   | `DINT LINT REAL LREAL`                        |
//! | `DINT`  | `LINT LREAL`                                  |
//! | `USINT` | `UINT UDINT ULINT INT DINT LINT REAL LREAL`   |
//! | `UINT`  | `UDINT ULINT DINT LINT REAL LREAL`            |
//! | `UDINT` | `ULINT LINT LREAL`                            |
//! | `BYTE`  | `WORD DWORD LWORD`                            |
//! | `WORD`  | `DWORD LWORD`                                 |
//! | `DWORD` | `LWORD`                                       |
//! | `REAL`  | `LREAL`                                       |
//! | `TIME`  | `LTIME`                                       |
//!
//! `LINT`, `ULINT`, `LWORD`, `LREAL`, `LTIME`, `BOOL` convert implicitly to nothing else, and
//! neither do `DATE`, `TOD`, `DT` and their long forms (CODESYS widens them to nothing either).
//! Every other conversion is explicit (`<T1>_TO_<T2>`). The two operands of a binary operator
//! are brought to the first type of the list `SINT USINT INT UINT DINT UDINT LINT ULINT REAL
//! LREAL BYTE WORD DWORD LWORD TIME LTIME` both convert to implicitly (`INT + UINT` is a `DINT`).
//! An untyped literal takes the type its context needs when its value fits that type.

use std::rc::Rc;

use crate::st::ast::RefKind;
use crate::value::{Calendar, Elem, ValueType};

/// An elementary type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Prim {
    Bool,
    SInt,
    Int,
    DInt,
    LInt,
    USInt,
    UInt,
    UDInt,
    ULInt,
    Byte,
    Word,
    DWord,
    LWord,
    Real,
    LReal,
    Time,
    LTime,
    /// `DATE`, `TOD`, `DT` and their long forms: [`Calendar`] says how they are stored.
    Cal(Calendar),
    /// `CHAR`: one byte, a character of Windows-1252 (as a STRING's characters).
    Char,
    /// `WCHAR`: one UTF-16 code unit, 2 bytes (as a WSTRING's characters).
    WChar,
}

/// The order in which a common type of two operands is searched.
const WIDENING_ORDER: [Prim; 16] = [
    Prim::SInt,
    Prim::USInt,
    Prim::Int,
    Prim::UInt,
    Prim::DInt,
    Prim::UDInt,
    Prim::LInt,
    Prim::ULInt,
    Prim::Real,
    Prim::LReal,
    Prim::Byte,
    Prim::Word,
    Prim::DWord,
    Prim::LWord,
    Prim::Time,
    Prim::LTime,
];

pub const ALL_PRIMS: [Prim; 25] = [
    Prim::Bool,
    Prim::SInt,
    Prim::Int,
    Prim::DInt,
    Prim::LInt,
    Prim::USInt,
    Prim::UInt,
    Prim::UDInt,
    Prim::ULInt,
    Prim::Byte,
    Prim::Word,
    Prim::DWord,
    Prim::LWord,
    Prim::Real,
    Prim::LReal,
    Prim::Time,
    Prim::LTime,
    Prim::Cal(Calendar::Date),
    Prim::Cal(Calendar::Tod),
    Prim::Cal(Calendar::Dt),
    Prim::Cal(Calendar::LDate),
    Prim::Cal(Calendar::LTod),
    Prim::Cal(Calendar::LDt),
    Prim::Char,
    Prim::WChar,
];

impl Prim {
    /// The type a name names: its IEC name, or a long name of a calendar type
    /// (`TIME_OF_DAY`, `DATE_AND_TIME`, `LTIME_OF_DAY`, `LDATE_AND_TIME`).
    pub fn from_name(name: &str) -> Option<Prim> {
        let upper = name.to_ascii_uppercase();
        ALL_PRIMS
            .into_iter()
            .find(|p| p.name() == upper)
            .or_else(|| Calendar::from_name(&upper).map(Prim::Cal))
    }

    pub fn name(self) -> &'static str {
        match self {
            Prim::Bool => "BOOL",
            Prim::SInt => "SINT",
            Prim::Int => "INT",
            Prim::DInt => "DINT",
            Prim::LInt => "LINT",
            Prim::USInt => "USINT",
            Prim::UInt => "UINT",
            Prim::UDInt => "UDINT",
            Prim::ULInt => "ULINT",
            Prim::Byte => "BYTE",
            Prim::Word => "WORD",
            Prim::DWord => "DWORD",
            Prim::LWord => "LWORD",
            Prim::Real => "REAL",
            Prim::LReal => "LREAL",
            Prim::Time => "TIME",
            Prim::LTime => "LTIME",
            Prim::Cal(cal) => cal.name(),
            Prim::Char => "CHAR",
            Prim::WChar => "WCHAR",
        }
    }

    pub fn elem(self) -> Elem {
        match self {
            Prim::Bool => Elem::Bool,
            Prim::SInt => Elem::I8,
            Prim::Int => Elem::I16,
            Prim::DInt => Elem::I32,
            Prim::LInt | Prim::Time | Prim::LTime => Elem::I64,
            Prim::USInt | Prim::Byte | Prim::Char => Elem::U8,
            Prim::UInt | Prim::Word | Prim::WChar => Elem::U16,
            Prim::UDInt | Prim::DWord => Elem::U32,
            Prim::ULInt | Prim::LWord => Elem::U64,
            Prim::Real => Elem::F32,
            Prim::LReal => Elem::F64,
            Prim::Cal(cal) => cal.elem(),
        }
    }

    /// SINT … ULINT (not the bit strings).
    pub fn is_int(self) -> bool {
        matches!(
            self,
            Prim::SInt
                | Prim::Int
                | Prim::DInt
                | Prim::LInt
                | Prim::USInt
                | Prim::UInt
                | Prim::UDInt
                | Prim::ULInt
        )
    }

    pub fn is_bits(self) -> bool {
        matches!(self, Prim::Byte | Prim::Word | Prim::DWord | Prim::LWord)
    }

    pub fn is_real(self) -> bool {
        matches!(self, Prim::Real | Prim::LReal)
    }

    pub fn is_time(self) -> bool {
        matches!(self, Prim::Time | Prim::LTime)
    }

    /// `DATE`, `TOD`, `DT` and their long forms.
    pub fn calendar(self) -> Option<Calendar> {
        match self {
            Prim::Cal(cal) => Some(cal),
            _ => None,
        }
    }

    pub fn is_num(self) -> bool {
        self.is_int() || self.is_real()
    }

    /// Integer-valued: integers and bit strings (what CASE, FOR and indices accept).
    pub fn is_integral(self) -> bool {
        self.is_int() || self.is_bits()
    }

    pub fn bits(self) -> u32 {
        self.elem().size() * 8
    }

    /// The range of an integer or bit string type.
    pub fn range(self) -> Option<(i128, i128)> {
        let e = self.elem();
        if e == Elem::Bool {
            return Some((0, 1));
        }
        if e.is_float() {
            return None;
        }
        let bits = self.bits();
        if e.is_signed() {
            Some((-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1))
        } else {
            Some((0, (1i128 << bits) - 1))
        }
    }

    /// IEC Table 11: may a `self` be assigned where a `to` is expected without a conversion?
    pub fn widens_to(self, to: Prim) -> bool {
        use Prim::*;
        if self == to {
            return true;
        }
        let targets: &[Prim] = match self {
            SInt => &[Int, DInt, LInt, Real, LReal],
            Int => &[DInt, LInt, Real, LReal],
            DInt => &[LInt, LReal],
            USInt => &[UInt, UDInt, ULInt, Int, DInt, LInt, Real, LReal],
            UInt => &[UDInt, ULInt, DInt, LInt, Real, LReal],
            UDInt => &[ULInt, LInt, LReal],
            Byte => &[Word, DWord, LWord],
            Word => &[DWord, LWord],
            DWord => &[LWord],
            Real => &[LReal],
            Time => &[LTime],
            _ => &[],
        };
        targets.contains(&to)
    }

    /// The type two operands meet at, if any.
    pub fn common(a: Prim, b: Prim) -> Option<Prim> {
        if a == b {
            return Some(a);
        }
        WIDENING_ORDER.into_iter().find(|&c| a.widens_to(c) && b.widens_to(c))
    }

    pub fn value_type(self) -> ValueType {
        let e = self.elem();
        match self {
            Prim::Bool => ValueType::Bool,
            Prim::Real | Prim::LReal => ValueType::Real(e),
            Prim::Time | Prim::LTime => ValueType::Time,
            Prim::Cal(cal) => ValueType::Calendar(cal),
            Prim::Char => ValueType::Char,
            Prim::WChar => ValueType::WChar,
            _ if e.is_signed() => ValueType::Signed(e),
            _ => ValueType::Unsigned(e),
        }
    }
}

/// A type.
#[derive(Debug, Clone, PartialEq)]
pub enum Ty {
    Prim(Prim),
    /// A subrange of an integer type: behaves as its base, constants are checked against it.
    Sub(Prim, i128, i128),
    /// `STRING[n]`: `n` characters and the NUL after them.
    Str(u32),
    /// `WSTRING[n]`: `n` UTF-16 code units of 2 bytes and the 2-byte NUL after them.
    WStr(u32),
    Array(Rc<ArrayTy>),
    /// `ARRAY [*, …] OF T`, the type of a VAR_IN_OUT only: its storage is the passed array's
    /// pointer and its bounds ([`OpenArrayTy`]).
    OpenArray(Rc<OpenArrayTy>),
    /// Index into [`Types::structs`].
    Struct(usize),
    /// Index into [`Types::enums`].
    Enum(usize),
    /// A FUNCTION_BLOCK type: the index of its POU.
    Fb(usize),
    /// `REF_TO T`, `POINTER TO T`, `REFERENCE TO T`: a reference value (8 bytes, see
    /// `crate::lang::ops::Op::Deref` for its encoding) to a `T`.
    Ref(RefKind, Rc<Ty>),
    /// An `INTERFACE` (index into [`Types::interfaces`]): a reference value to an instance of
    /// a function block implementing it, `NULL` (0) until one is assigned.
    Iface(usize),
    /// `NULL`, and `ADR(v)` before it meets a pointer type: a reference to anything.
    Null,
    /// An integer literal whose type comes from its context.
    IntLit,
    /// A real literal whose type comes from its context.
    RealLit,
    /// No value (a FUNCTION without a result type).
    Void,
    /// The type of an expression that already has an error: no further error about it.
    Error,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ArrayTy {
    /// `(lo, hi)` of each dimension.
    pub dims: Vec<(i64, i64)>,
    pub of: Ty,
    /// Bytes of one element.
    pub elem_size: u32,
}

impl ArrayTy {
    pub fn count(&self) -> u64 {
        self.dims.iter().map(|(lo, hi)| (hi - lo + 1) as u64).product()
    }
}

/// `ARRAY [*, …] OF of`: `rank` open dimensions of `elem_size`-byte elements (`compile::varlen`).
#[derive(Debug, Clone, PartialEq)]
pub struct OpenArrayTy {
    pub rank: usize,
    pub of: Ty,
    pub elem_size: u32,
}

impl OpenArrayTy {
    /// The bytes of a VAR_IN_OUT of this type: the pointer, then a lower bound and a length
    /// (each a `LINT`) per dimension.
    pub fn descriptor_size(&self) -> u32 {
        8 + 16 * self.rank as u32
    }

    /// Where dimension `d`'s (0-based) lower bound is, from the start of the storage.
    pub fn lower_at(d: usize) -> u32 {
        8 + 16 * d as u32
    }

    /// Where dimension `d`'s length is.
    pub fn len_at(d: usize) -> u32 {
        16 + 16 * d as u32
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    pub name: String,
    pub ty: Ty,
    pub offset: u32,
    /// Declared at a partly specified address (`IN AT %I* : BOOL;`, IEC 61131-3 ed3).
    pub partial: bool,
    /// The device a binding (VAR_CONFIG, `[iec.variables]`) placed the member at, in the copy
    /// of the type the bound variable was given (`fb_config.rs`): code reads and writes the
    /// device, and the member's bytes in the struct are unused.
    pub device: Option<super::ctx::Storage>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct StructTy {
    pub name: String,
    pub members: Vec<Member>,
    pub size: u32,
    /// The default value of an instance.
    pub image: Vec<u8>,
    /// A CODESYS `UNION`: every member at offset 0 (`compile::union`).
    pub union: bool,
}

#[derive(Debug, Clone, PartialEq)]
pub struct EnumTy {
    pub name: String,
    pub base: Prim,
    pub values: Vec<(String, i128)>,
    /// The default value.
    pub init: i128,
    /// Whether the base type was declared (`INT (A, B)`), which stores it as that type.
    pub declared_base: bool,
}

/// The FB types' sizes and the structures and enumerations, indexed by `Ty`.
#[derive(Debug, Default)]
pub struct Types {
    pub structs: Vec<StructTy>,
    pub enums: Vec<EnumTy>,
    /// Per POU (indexed like the POU list): instance size of a FUNCTION_BLOCK and its name.
    pub fbs: Vec<Option<(String, u32)>>,
    /// The INTERFACEs' names.
    pub interfaces: Vec<String>,
}

impl Types {
    pub fn name(&self, ty: &Ty) -> String {
        match ty {
            Ty::Prim(p) => p.name().to_string(),
            Ty::Sub(p, lo, hi) => format!("{} ({lo}..{hi})", p.name()),
            Ty::Str(n) => format!("STRING[{n}]"),
            Ty::WStr(n) => format!("WSTRING[{n}]"),
            Ty::Array(a) => {
                let dims: Vec<String> = a.dims.iter().map(|(l, h)| format!("{l}..{h}")).collect();
                format!("ARRAY [{}] OF {}", dims.join(", "), self.name(&a.of))
            }
            Ty::Struct(i) => self.structs[*i].name.clone(),
            Ty::Enum(i) => self.enums[*i].name.clone(),
            Ty::Fb(i) => {
                self.fbs.get(*i).and_then(|f| f.as_ref()).map_or("?".into(), |f| f.0.clone())
            }
            Ty::Ref(kind, to) => {
                let word = match kind {
                    RefKind::RefTo => "REF_TO",
                    RefKind::Pointer => "POINTER TO",
                    RefKind::Reference => "REFERENCE TO",
                };
                format!("{word} {}", self.name(to))
            }
            Ty::Iface(i) => self.interfaces[*i].clone(),
            Ty::Null => "NULL".into(),
            Ty::OpenArray(a) => {
                let stars = vec!["*"; a.rank].join(", ");
                format!("ARRAY [{stars}] OF {}", self.name(&a.of))
            }
            Ty::IntLit => "ANY_INT".into(),
            Ty::RealLit => "ANY_REAL".into(),
            Ty::Void => "no value".into(),
            Ty::Error => "?".into(),
        }
    }

    pub fn size(&self, ty: &Ty) -> u32 {
        match ty {
            Ty::Prim(p) | Ty::Sub(p, _, _) => p.elem().size(),
            Ty::Str(n) => n + 1,
            Ty::WStr(n) => 2 * (n + 1),
            Ty::Array(a) => (a.count() as u32).saturating_mul(a.elem_size),
            Ty::Struct(i) => self.structs[*i].size,
            Ty::Enum(i) => self.enums[*i].base.elem().size(),
            Ty::Fb(i) => self.fbs.get(*i).and_then(|f| f.as_ref()).map_or(0, |f| f.1),
            Ty::Ref(..) | Ty::Null | Ty::Iface(_) => 8,
            Ty::OpenArray(a) => a.descriptor_size(),
            Ty::IntLit => 8,
            Ty::RealLit => 8,
            Ty::Void | Ty::Error => 0,
        }
    }
}

impl Ty {
    /// The elementary type a scalar is computed as (subranges and enumerations as their base).
    pub fn prim(&self, types: &Types) -> Option<Prim> {
        match self {
            Ty::Prim(p) | Ty::Sub(p, _, _) => Some(*p),
            Ty::Enum(i) => Some(types.enums[*i].base),
            _ => None,
        }
    }

    /// How a scalar of this type is stored (a reference as a 64-bit slot).
    pub fn elem(&self, types: &Types) -> Option<Elem> {
        match self {
            Ty::Ref(..) | Ty::Null | Ty::Iface(_) => Some(Elem::U64),
            _ => self.prim(types).map(Prim::elem),
        }
    }

    /// A reference type's kind and target.
    pub fn as_ref(&self) -> Option<(RefKind, &Ty)> {
        match self {
            Ty::Ref(kind, to) => Some((*kind, to)),
            _ => None,
        }
    }

    /// Held by reference (copied with `Copy` or `Str`), not as a slot.
    pub fn is_aggregate(&self) -> bool {
        matches!(
            self,
            Ty::Str(_) | Ty::WStr(_) | Ty::Array(_) | Ty::OpenArray(_) | Ty::Struct(_) | Ty::Fb(_)
        )
    }

    /// A `WSTRING[n]`: its string operations are [`crate::lang::ops::Op::Str`] with `wide`.
    pub fn is_wide(&self) -> bool {
        matches!(self, Ty::WStr(_))
    }

    /// The capacity of a STRING or WSTRING, in characters.
    pub fn string_cap(&self) -> Option<u32> {
        match self {
            Ty::Str(n) | Ty::WStr(n) => Some(*n),
            _ => None,
        }
    }

    pub fn is_error(&self) -> bool {
        matches!(self, Ty::Error)
    }

    pub fn is_bool(&self) -> bool {
        matches!(self, Ty::Prim(Prim::Bool))
    }
}

/// Whether `v` fits `p` (integer constants).
pub fn fits(p: Prim, v: i128) -> bool {
    match p.range() {
        Some((lo, hi)) => (lo..=hi).contains(&v),
        None => true,
    }
}

/// `v` wrapped to the width of `p`, as the VM normalizes integer results.
pub fn wrap(p: Prim, v: i128) -> i128 {
    let e = p.elem();
    if e == Elem::Bool {
        return i128::from(v != 0);
    }
    let bits = p.bits();
    let mask = if bits == 128 { !0u128 } else { (1u128 << bits) - 1 };
    let low = (v as u128) & mask;
    if e.is_signed() && low >> (bits - 1) & 1 == 1 {
        (low as i128) - (1i128 << bits)
    } else {
        low as i128
    }
}

/// The slot of an integer constant of `p`.
pub fn int_slot(p: Prim, v: i128) -> u64 {
    wrap(p, v) as i64 as u64
}

/// The slot of a real constant of `p`.
pub fn real_slot(p: Prim, v: f64) -> u64 {
    if p == Prim::Real {
        u64::from((v as f32).to_bits())
    } else {
        v.to_bits()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widening_follows_the_table() {
        assert!(Prim::Int.widens_to(Prim::DInt));
        assert!(!Prim::DInt.widens_to(Prim::Int));
        assert!(!Prim::DInt.widens_to(Prim::Real));
        assert!(Prim::DInt.widens_to(Prim::LReal));
        assert!(!Prim::Int.widens_to(Prim::UInt));
        assert!(!Prim::Byte.widens_to(Prim::Int));
        assert_eq!(Prim::common(Prim::Int, Prim::UInt), Some(Prim::DInt));
        assert_eq!(Prim::common(Prim::Real, Prim::DInt), Some(Prim::LReal));
        assert_eq!(Prim::common(Prim::LInt, Prim::ULInt), None);
        assert_eq!(Prim::common(Prim::Bool, Prim::Int), None);
    }

    #[test]
    fn wrapping_matches_two_complement() {
        assert_eq!(wrap(Prim::Int, 32768), -32768);
        assert_eq!(wrap(Prim::SInt, 255), -1);
        assert_eq!(wrap(Prim::USInt, -1), 255);
        assert_eq!(wrap(Prim::ULInt, -1), u64::MAX as i128);
        assert_eq!(int_slot(Prim::Int, -1), u64::MAX);
        assert_eq!(int_slot(Prim::UInt, -1), 0xFFFF);
    }
}
