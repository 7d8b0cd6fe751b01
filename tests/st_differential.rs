//! Differential property of Structured Text at the source level: random well-typed expressions
//! over typed variables, written as ST text, compiled by the real compiler into one program,
//! run for one scan on the VM and read back by name, against a plain Rust evaluator of the same
//! expression tree on native values (`i16`, `u32`, `f32`, … and their `wrapping_*` methods)
//! following docs/ST.md: wrapping integer arithmetic, division and `MOD` by zero giving 0 with
//! error 3400H, the implicit widenings, the conversion rules, the shifts, the standard functions,
//! and what plcd accepts of CODESYS's habits: arithmetic on bit strings (with each other, with
//! integers and reals, typed as docs/ST.md says), shifts of integers, the short-circuit
//! `AND_THEN` and `OR_ELSE` (a skipped right operand raises none of its errors), and
//! assignments inside expressions (`(w_int := x)`, whose value is `x`'s).
//!
//! The expressions are generated from a list of choices, so that proptest's shrinking of the
//! list shrinks the expressions (an exhausted list picks variables). Constant subexpressions are
//! folded by the compiler, so the same property checks the folding against the VM's rules.
//! A second property renders the same trees with the fewest parentheses the precedence table of
//! docs/ST.md allows (and `&` for `AND`). A third runs the programs with their native code
//! attached too (plcd-native), which must give the interpreter's results to the bit and its
//! operation errors, also when a small step budget makes native code hand back to the
//! interpreter in the middle of an expression.
//!
//! Each bug the properties found is a minimized test at the end, kept after its fix: shift
//! counts (negative, beyond IN's width, beyond DINT), the folding of constants (REAL to a
//! 64-bit integer saturates, a 64-bit integer to REAL rounds once, -0.0), and a based literal
//! inside an expression taking its own operation's type.

use std::cmp::Ordering;
use std::fmt::Write as _;
use std::path::Path;

use plcd_core::lang::Program;
use plcd_core::st::{compile, parse_file, Compiled, Instance};
use plcd_core::value::{Elem, ValueType};
use plcd_core::vm::{ExecState, Exit, ManualClock, Vm, ERR_DIVIDE_BY_ZERO};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Types and native values

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum T {
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
}

const TYPES: [T; 15] = [
    T::Bool,
    T::SInt,
    T::Int,
    T::DInt,
    T::LInt,
    T::USInt,
    T::UInt,
    T::UDInt,
    T::ULInt,
    T::Byte,
    T::Word,
    T::DWord,
    T::LWord,
    T::Real,
    T::LReal,
];

impl T {
    fn name(self) -> &'static str {
        match self {
            T::Bool => "BOOL",
            T::SInt => "SINT",
            T::Int => "INT",
            T::DInt => "DINT",
            T::LInt => "LINT",
            T::USInt => "USINT",
            T::UInt => "UINT",
            T::UDInt => "UDINT",
            T::ULInt => "ULINT",
            T::Byte => "BYTE",
            T::Word => "WORD",
            T::DWord => "DWORD",
            T::LWord => "LWORD",
            T::Real => "REAL",
            T::LReal => "LREAL",
        }
    }

    fn signed(self) -> bool {
        matches!(self, T::SInt | T::Int | T::DInt | T::LInt)
    }

    fn unsigned(self) -> bool {
        matches!(self, T::USInt | T::UInt | T::UDInt | T::ULInt)
    }

    fn bits(self) -> bool {
        matches!(self, T::Byte | T::Word | T::DWord | T::LWord)
    }

    fn real(self) -> bool {
        matches!(self, T::Real | T::LReal)
    }

    fn integer(self) -> bool {
        self.signed() || self.unsigned()
    }

    fn num(self) -> bool {
        self.integer() || self.real()
    }

    fn width(self) -> u32 {
        match self {
            T::Bool => 1,
            T::SInt | T::USInt | T::Byte => 8,
            T::Int | T::UInt | T::Word => 16,
            T::DInt | T::UDInt | T::DWord | T::Real => 32,
            T::LInt | T::ULInt | T::LWord | T::LReal => 64,
        }
    }

    fn elem(self) -> Elem {
        match self {
            T::Bool => Elem::Bool,
            T::SInt => Elem::I8,
            T::Int => Elem::I16,
            T::DInt => Elem::I32,
            T::LInt => Elem::I64,
            T::USInt | T::Byte => Elem::U8,
            T::UInt | T::Word => Elem::U16,
            T::UDInt | T::DWord => Elem::U32,
            T::ULInt | T::LWord => Elem::U64,
            T::Real => Elem::F32,
            T::LReal => Elem::F64,
        }
    }

    /// Whether a value of `self` converts implicitly to `to` (docs/ST.md, implicit
    /// conversions; a type to itself included).
    fn widens_to(self, to: T) -> bool {
        use T::*;
        self == to
            || match self {
                SInt => matches!(to, Int | DInt | LInt | Real | LReal),
                Int => matches!(to, DInt | LInt | Real | LReal),
                DInt => matches!(to, LInt | LReal),
                USInt => matches!(to, UInt | UDInt | ULInt | Int | DInt | LInt | Real | LReal),
                UInt => matches!(to, UDInt | ULInt | DInt | LInt | Real | LReal),
                UDInt => matches!(to, ULInt | LInt | LReal),
                Byte => matches!(to, Word | DWord | LWord),
                Word => matches!(to, DWord | LWord),
                DWord => matches!(to, LWord),
                Real => to == LReal,
                Bool | LInt | ULInt | LWord | LReal => false,
            }
    }

    /// The types that convert implicitly to `self`, itself included.
    fn narrower(self) -> Vec<T> {
        TYPES.iter().copied().filter(|t| t.widens_to(self)).collect()
    }
}

/// The common type of two operands: the one the other converts to.
fn common(a: T, b: T) -> T {
    if a.widens_to(b) {
        b
    } else {
        assert!(b.widens_to(a), "{a:?} and {b:?} have no common type");
        a
    }
}

/// A value as the reference holds it: the native Rust type of its ST type.
#[derive(Debug, Clone, Copy)]
enum V {
    Bool(bool),
    SInt(i8),
    Int(i16),
    DInt(i32),
    LInt(i64),
    USInt(u8),
    UInt(u16),
    UDInt(u32),
    ULInt(u64),
    Byte(u8),
    Word(u16),
    DWord(u32),
    LWord(u64),
    Real(f32),
    LReal(f64),
}

/// `$body` with `$x` bound to the native value of every integer and bit string variant,
/// rewrapped in the same variant; `$other` for BOOL and the reals.
macro_rules! map_int {
    ($v:expr, $x:ident => $body:expr, $other:expr) => {
        match $v {
            V::SInt($x) => V::SInt($body),
            V::Int($x) => V::Int($body),
            V::DInt($x) => V::DInt($body),
            V::LInt($x) => V::LInt($body),
            V::USInt($x) => V::USInt($body),
            V::UInt($x) => V::UInt($body),
            V::UDInt($x) => V::UDInt($body),
            V::ULInt($x) => V::ULInt($body),
            V::Byte($x) => V::Byte($body),
            V::Word($x) => V::Word($body),
            V::DWord($x) => V::DWord($body),
            V::LWord($x) => V::LWord($body),
            _ => $other,
        }
    };
}

/// `$body` with `$x`, `$y` bound to two values of the same integer or bit string variant.
macro_rules! zip_int {
    ($a:expr, $b:expr, $x:ident, $y:ident => $body:expr, $other:expr) => {
        match ($a, $b) {
            (V::SInt($x), V::SInt($y)) => V::SInt($body),
            (V::Int($x), V::Int($y)) => V::Int($body),
            (V::DInt($x), V::DInt($y)) => V::DInt($body),
            (V::LInt($x), V::LInt($y)) => V::LInt($body),
            (V::USInt($x), V::USInt($y)) => V::USInt($body),
            (V::UInt($x), V::UInt($y)) => V::UInt($body),
            (V::UDInt($x), V::UDInt($y)) => V::UDInt($body),
            (V::ULInt($x), V::ULInt($y)) => V::ULInt($body),
            (V::Byte($x), V::Byte($y)) => V::Byte($body),
            (V::Word($x), V::Word($y)) => V::Word($body),
            (V::DWord($x), V::DWord($y)) => V::DWord($body),
            (V::LWord($x), V::LWord($y)) => V::LWord($body),
            _ => $other,
        }
    };
}

/// A scalar view of a value, for the conversions.
enum Scalar {
    Int(i128),
    Float(f64),
}

impl V {
    fn ty(self) -> T {
        match self {
            V::Bool(_) => T::Bool,
            V::SInt(_) => T::SInt,
            V::Int(_) => T::Int,
            V::DInt(_) => T::DInt,
            V::LInt(_) => T::LInt,
            V::USInt(_) => T::USInt,
            V::UInt(_) => T::UInt,
            V::UDInt(_) => T::UDInt,
            V::ULInt(_) => T::ULInt,
            V::Byte(_) => T::Byte,
            V::Word(_) => T::Word,
            V::DWord(_) => T::DWord,
            V::LWord(_) => T::LWord,
            V::Real(_) => T::Real,
            V::LReal(_) => T::LReal,
        }
    }

    fn scalar(self) -> Scalar {
        match self {
            V::Bool(x) => Scalar::Int(i128::from(x)),
            V::SInt(x) => Scalar::Int(x.into()),
            V::Int(x) => Scalar::Int(x.into()),
            V::DInt(x) => Scalar::Int(x.into()),
            V::LInt(x) => Scalar::Int(x.into()),
            V::USInt(x) | V::Byte(x) => Scalar::Int(x.into()),
            V::UInt(x) | V::Word(x) => Scalar::Int(x.into()),
            V::UDInt(x) | V::DWord(x) => Scalar::Int(x.into()),
            V::ULInt(x) | V::LWord(x) => Scalar::Int(x.into()),
            V::Real(x) => Scalar::Float(x.into()),
            V::LReal(x) => Scalar::Float(x),
        }
    }

    /// The value of an integer, bit string or BOOL.
    fn int(self) -> i128 {
        match self.scalar() {
            Scalar::Int(i) => i,
            Scalar::Float(_) => panic!("{self:?} is a real"),
        }
    }

    fn zero(self) -> bool {
        match self.scalar() {
            Scalar::Int(i) => i == 0,
            Scalar::Float(f) => f == 0.0,
        }
    }

    /// `<FROM>_TO_<TO>` by docs/ST.md's conversion rules, with Rust's casts: `as` wraps an
    /// integer to the target's width, rounds an integer to the nearest float, and saturates a
    /// float (rounded half away from zero first) to an integer, NaN giving 0.
    fn to(self, to: T) -> V {
        macro_rules! cast {
            ($s:expr, $ctor:ident, $t:ty) => {
                V::$ctor(match $s {
                    Scalar::Int(i) => i as $t,
                    Scalar::Float(f) => f.round() as $t,
                })
            };
        }
        let s = self.scalar();
        match to {
            T::Bool => V::Bool(!self.zero()),
            T::SInt => cast!(s, SInt, i8),
            T::Int => cast!(s, Int, i16),
            T::DInt => cast!(s, DInt, i32),
            T::LInt => cast!(s, LInt, i64),
            T::USInt => cast!(s, USInt, u8),
            T::UInt => cast!(s, UInt, u16),
            T::UDInt => cast!(s, UDInt, u32),
            T::ULInt => cast!(s, ULInt, u64),
            T::Byte => cast!(s, Byte, u8),
            T::Word => cast!(s, Word, u16),
            T::DWord => cast!(s, DWord, u32),
            T::LWord => cast!(s, LWord, u64),
            T::Real => V::Real(match s {
                Scalar::Int(i) => i as f32,
                Scalar::Float(f) => f as f32,
            }),
            T::LReal => V::LReal(match s {
                Scalar::Int(i) => i as f64,
                Scalar::Float(f) => f,
            }),
        }
    }

    /// An implicit conversion: one that never loses a value.
    fn widen(self, to: T) -> V {
        assert!(self.ty().widens_to(to), "{:?} does not widen to {to:?}", self.ty());
        self.to(to)
    }

    /// The same value, NaN equal to NaN of any payload, the sign of a zero significant.
    fn same(self, other: V) -> bool {
        match (self, other) {
            (V::Real(a), V::Real(b)) => a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            (V::LReal(a), V::LReal(b)) => a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            (V::Bool(a), V::Bool(b)) => a == b,
            (a, b) => a.ty() == b.ty() && a.int() == b.int(),
        }
    }

    fn compare(self, other: V) -> Option<Ordering> {
        match (self.scalar(), other.scalar()) {
            (Scalar::Int(a), Scalar::Int(b)) => Some(a.cmp(&b)),
            (Scalar::Float(a), Scalar::Float(b)) => a.partial_cmp(&b),
            _ => unreachable!("operands of one type"),
        }
    }

    /// The value as ST source: `typed` adds the type's prefix; `based` writes an integer in
    /// base 16 (its bit pattern for a signed type, which then needs the prefix).
    fn literal(self, typed: bool, based: bool) -> String {
        let text = match self {
            V::Bool(b) if typed => return format!("BOOL#{}", u8::from(b)),
            V::Bool(b) => return if b { "TRUE" } else { "FALSE" }.to_string(),
            V::Real(x) => real_text(f64::from(x), x.to_string(), format!("{x:e}")),
            V::LReal(x) => real_text(x, x.to_string(), format!("{x:e}")),
            v if based && (typed || v.int() >= 0) => {
                let mask = if v.ty().width() == 64 { u64::MAX } else { (1 << v.ty().width()) - 1 };
                format!("16#{:X}", v.int() as u64 & mask)
            }
            v => v.int().to_string(),
        };
        if typed {
            format!("{}#{text}", self.ty().name())
        } else {
            text
        }
    }
}

/// A real's literal from Rust's shortest round-trip texts (plain and exponent): ST wants a
/// decimal point in the mantissa.
fn real_text(x: f64, plain: String, exp: String) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-3..1e9).contains(&a) {
        if plain.contains('.') {
            plain
        } else {
            format!("{plain}.0")
        }
    } else {
        let (m, e) = exp.split_once('e').expect("exponent");
        if m.contains('.') {
            format!("{m}E{e}")
        } else {
            format!("{m}.0E{e}")
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Expressions and the reference evaluator

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Bin {
    Add,
    Sub,
    Mul,
    Div,
    Mod,
    And,
    Or,
    Xor,
    /// CODESYS's short-circuit `AND_THEN`, `OR_ELSE` (BOOL only): the right operand, and
    /// so its operation errors, only when the left does not decide.
    AndThen,
    OrElse,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cmp {
    Lt,
    Gt,
    Le,
    Ge,
    Eq,
    Ne,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Shift {
    Shl,
    Shr,
    Rol,
    Ror,
}

/// How a literal is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Form {
    /// Bare where the context gives the type (see [`Expr::bare_ok`]), else typed.
    Bare,
    Typed,
    /// In base 16, typed.
    Based,
}

#[derive(Debug, Clone)]
enum Expr {
    Var(usize),
    Lit(V, Form),
    Neg(Box<Expr>),
    Not(Box<Expr>),
    /// The operands may be of two types, one of which converts implicitly to the other.
    Bin(Bin, Box<Expr>, Box<Expr>),
    Cmp(Cmp, Box<Expr>, Box<Expr>),
    Abs(Box<Expr>),
    /// `MIN` (`true`) or `MAX` of two or three values.
    MinMax(bool, Vec<Expr>),
    Limit(Box<[Expr; 3]>),
    Sel(Box<[Expr; 3]>),
    Shift(Shift, Box<Expr>, Box<Expr>),
    Conv(T, Box<Expr>),
    /// `TRUNC` of a REAL or LREAL, a DINT.
    Trunc(Box<Expr>),
    /// CODESYS's arithmetic between a bit string and an integer or a real ([`codesys_type`]).
    Mixed(Bin, Box<Expr>, Box<Expr>),
    /// CODESYS's assignment inside an expression, `(w_<type> := x)`: its value is `x`'s,
    /// stored on the way in a variable of `x`'s type that no expression reads (so the
    /// reference evaluator needs no state; the native property compares its memory).
    Assign(Box<Expr>),
}

/// The bit string as wide as `t`.
fn bits_of(t: T) -> T {
    match t.width() {
        8 => T::Byte,
        16 => T::Word,
        32 => T::DWord,
        _ => T::LWord,
    }
}

/// The type of CODESYS's `a op b` for a bit string and an integer or a real (docs/ST.md,
/// "Arithmetic on bit strings"): the real; the integer when it is wider; else the bit string.
fn codesys_type(a: T, b: T) -> T {
    let (bits, other) = if a.bits() { (a, b) } else { (b, a) };
    assert!(bits.bits() && !other.bits(), "{a:?} and {b:?}");
    if other.real() || other.width() > bits.width() {
        other
    } else {
        bits
    }
}

/// The variables of one program: name, type, initial value, and how the value is written.
struct Vars(Vec<(String, V, Form)>);

impl Expr {
    fn ty(&self, vars: &Vars) -> T {
        match self {
            Expr::Var(i) => vars.0[*i].1.ty(),
            Expr::Lit(v, _) => v.ty(),
            Expr::Neg(a) | Expr::Not(a) | Expr::Abs(a) => a.ty(vars),
            Expr::Bin(_, a, b) => common(a.ty(vars), b.ty(vars)),
            Expr::Cmp(..) => T::Bool,
            Expr::MinMax(_, xs) => xs.iter().map(|x| x.ty(vars)).reduce(common).expect("args"),
            Expr::Limit(xs) => common(common(xs[0].ty(vars), xs[1].ty(vars)), xs[2].ty(vars)),
            Expr::Sel(xs) => common(xs[1].ty(vars), xs[2].ty(vars)),
            Expr::Shift(_, x, _) => x.ty(vars),
            Expr::Conv(t, _) => *t,
            Expr::Trunc(_) => T::DInt,
            Expr::Mixed(_, a, b) => codesys_type(a.ty(vars), b.ty(vars)),
            Expr::Assign(a) => a.ty(vars),
        }
    }

    fn has_var(&self) -> bool {
        match self {
            // its type is the variable's, and the compiler folds no assignment
            Expr::Var(_) | Expr::Assign(_) => true,
            Expr::Lit(..) => false,
            Expr::Neg(a) | Expr::Not(a) | Expr::Abs(a) | Expr::Conv(_, a) | Expr::Trunc(a) => {
                a.has_var()
            }
            Expr::Bin(_, a, b)
            | Expr::Cmp(_, a, b)
            | Expr::Shift(_, a, b)
            | Expr::Mixed(_, a, b) => a.has_var() || b.has_var(),
            Expr::MinMax(_, xs) => xs.iter().any(Expr::has_var),
            Expr::Limit(xs) | Expr::Sel(xs) => xs.iter().any(Expr::has_var),
        }
    }

    /// Whether the compiler sees a constant: no variable, or a `SEL` with a constant G that
    /// selects a constant (the compiler keeps only the selected input).
    fn constant(&self, vars: &Vars) -> bool {
        match self {
            Expr::Sel(xs) if xs[0].constant(vars) => {
                let g = xs[0].eval(vars, &mut 0);
                xs[if g.zero() { 1 } else { 2 }].constant(vars)
            }
            // the compiler folds a short-circuit operation whose constant left operand decides
            Expr::Bin(op @ (Bin::AndThen | Bin::OrElse), a, b) if a.constant(vars) => {
                let decides = *op == Bin::OrElse;
                a.eval(vars, &mut 0).zero() != decides || b.constant(vars)
            }
            Expr::Var(_) | Expr::Lit(..) | Expr::Sel(_) | Expr::Assign(_) => !self.has_var(),
            Expr::Neg(a) | Expr::Not(a) | Expr::Abs(a) | Expr::Conv(_, a) | Expr::Trunc(a) => {
                a.constant(vars)
            }
            Expr::Bin(_, a, b)
            | Expr::Cmp(_, a, b)
            | Expr::Shift(_, a, b)
            | Expr::Mixed(_, a, b) => a.constant(vars) && b.constant(vars),
            Expr::MinMax(_, xs) => xs.iter().all(|x| x.constant(vars)),
            Expr::Limit(xs) => xs.iter().all(|x| x.constant(vars)),
        }
    }

    /// The value, and the divisions by zero done on the way. `SEL` evaluates only the input it
    /// selects, as the compiler emits it (a jump).
    fn eval(&self, vars: &Vars, errors: &mut u32) -> V {
        match self {
            Expr::Var(i) => vars.0[*i].1,
            Expr::Lit(v, _) => *v,
            Expr::Assign(a) => a.eval(vars, errors),
            Expr::Neg(a) => match a.eval(vars, errors) {
                V::Real(x) => V::Real(-x),
                V::LReal(x) => V::LReal(-x),
                v => map_int!(v, x => x.wrapping_neg(), unreachable!("- {v:?}")),
            },
            Expr::Not(a) => match a.eval(vars, errors) {
                V::Bool(x) => V::Bool(!x),
                v => map_int!(v, x => !x, unreachable!("NOT {v:?}")),
            },
            Expr::Abs(a) => match a.eval(vars, errors) {
                V::Real(x) => V::Real(x.abs()),
                V::LReal(x) => V::LReal(x.abs()),
                V::SInt(x) => V::SInt(x.wrapping_abs()),
                V::Int(x) => V::Int(x.wrapping_abs()),
                V::DInt(x) => V::DInt(x.wrapping_abs()),
                V::LInt(x) => V::LInt(x.wrapping_abs()),
                v => v,
            },
            Expr::Bin(op, a, b) | Expr::Mixed(op, a, b) => {
                let t = self.ty(vars);
                // CODESYS's mixed operands convert as `<FROM>_TO_<TO>` (two's complement bits)
                let mixed = matches!(self, Expr::Mixed(..));
                let conv = |v: V| if mixed { v.to(t) } else { v.widen(t) };
                let x = conv(a.eval(vars, errors));
                // the value of the left operand that decides a short-circuit operation alone
                let decides = match op {
                    Bin::AndThen => Some(false),
                    Bin::OrElse => Some(true),
                    _ => None,
                };
                if let (Some(d), V::Bool(left)) = (decides, x) {
                    if left == d {
                        return V::Bool(d);
                    }
                }
                let y = conv(b.eval(vars, errors));
                if matches!(op, Bin::Div | Bin::Mod) && y.zero() {
                    *errors += 1;
                    return V::Bool(false).to(t);
                }
                binary(*op, x, y)
            }
            Expr::Cmp(op, a, b) => {
                let t = common(a.ty(vars), b.ty(vars));
                let x = a.eval(vars, errors).widen(t);
                let y = b.eval(vars, errors).widen(t);
                let ord = x.compare(y);
                V::Bool(match op {
                    Cmp::Lt => ord == Some(Ordering::Less),
                    Cmp::Gt => ord == Some(Ordering::Greater),
                    Cmp::Le => matches!(ord, Some(Ordering::Less | Ordering::Equal)),
                    Cmp::Ge => matches!(ord, Some(Ordering::Greater | Ordering::Equal)),
                    Cmp::Eq => ord == Some(Ordering::Equal),
                    Cmp::Ne => ord != Some(Ordering::Equal),
                })
            }
            Expr::MinMax(min, xs) => {
                let t = self.ty(vars);
                let vals = xs.iter().map(|x| x.eval(vars, errors).widen(t));
                vals.reduce(|a, b| min_max(*min, a, b)).expect("args")
            }
            Expr::Limit(xs) => {
                let t = self.ty(vars);
                let [mn, x, mx] = [0, 1, 2].map(|i| xs[i].eval(vars, errors).widen(t));
                min_max(true, min_max(false, x, mn), mx)
            }
            Expr::Sel(xs) => {
                let t = self.ty(vars);
                let g = xs[0].eval(vars, errors);
                let pick = if g.zero() { &xs[1] } else { &xs[2] };
                pick.eval(vars, errors).widen(t)
            }
            Expr::Shift(op, x, n) => {
                // CODESYS: an integer is shifted as the bit pattern of its width
                let t = x.ty(vars);
                let x = x.eval(vars, errors).to(bits_of(t));
                // The count is taken as an unsigned 64-bit number.
                let n = n.eval(vars, errors).int() as u64;
                let width = u64::from(x.ty().width());
                let out = n >= width;
                let r = (n % width) as u32;
                let shifted = match op {
                    Shift::Shl => map_int!(x, v => if out { 0 } else { v << n }, unreachable!()),
                    Shift::Shr => map_int!(x, v => if out { 0 } else { v >> n }, unreachable!()),
                    Shift::Rol => map_int!(x, v => v.rotate_left(r), unreachable!()),
                    Shift::Ror => map_int!(x, v => v.rotate_right(r), unreachable!()),
                };
                shifted.to(t)
            }
            Expr::Conv(t, a) => a.eval(vars, errors).to(*t),
            // toward zero, saturated, NaN 0: Rust's `as`
            Expr::Trunc(a) => match a.eval(vars, errors) {
                V::Real(x) => V::DInt(x as i32),
                V::LReal(x) => V::DInt(x as i32),
                v => unreachable!("TRUNC({v:?})"),
            },
        }
    }
}

/// `x op y` on two values of one type, the divisor not zero.
fn binary(op: Bin, x: V, y: V) -> V {
    match (x, y) {
        (V::Real(a), V::Real(b)) => V::Real(match op {
            Bin::Add => a + b,
            Bin::Sub => a - b,
            Bin::Mul => a * b,
            Bin::Div => a / b,
            _ => unreachable!("{op:?} on REAL"),
        }),
        (V::LReal(a), V::LReal(b)) => V::LReal(match op {
            Bin::Add => a + b,
            Bin::Sub => a - b,
            Bin::Mul => a * b,
            Bin::Div => a / b,
            _ => unreachable!("{op:?} on LREAL"),
        }),
        (V::Bool(a), V::Bool(b)) => V::Bool(match op {
            Bin::And | Bin::AndThen => a & b,
            Bin::Or | Bin::OrElse => a | b,
            Bin::Xor => a ^ b,
            _ => unreachable!("{op:?} on BOOL"),
        }),
        _ => match op {
            Bin::Add => zip_int!(x, y, a, b => a.wrapping_add(b), unreachable!()),
            Bin::Sub => zip_int!(x, y, a, b => a.wrapping_sub(b), unreachable!()),
            Bin::Mul => zip_int!(x, y, a, b => a.wrapping_mul(b), unreachable!()),
            Bin::Div => zip_int!(x, y, a, b => a.wrapping_div(b), unreachable!()),
            Bin::Mod => zip_int!(x, y, a, b => a.wrapping_rem(b), unreachable!()),
            Bin::And => zip_int!(x, y, a, b => a & b, unreachable!()),
            Bin::Or => zip_int!(x, y, a, b => a | b, unreachable!()),
            Bin::Xor => zip_int!(x, y, a, b => a ^ b, unreachable!()),
            Bin::AndThen | Bin::OrElse => unreachable!("{op:?} on an integer"),
        },
    }
}

/// `MIN` (`min`) or `MAX` of two values of one type; on reals, Rust's `min`/`max` (a NaN
/// operand gives the other one), as `MIN`/`MAX` have no rule of their own for NaN.
fn min_max(min: bool, x: V, y: V) -> V {
    match (x, y) {
        (V::Real(a), V::Real(b)) => V::Real(if min { a.min(b) } else { a.max(b) }),
        (V::LReal(a), V::LReal(b)) => V::LReal(if min { a.min(b) } else { a.max(b) }),
        (V::Bool(a), V::Bool(b)) => V::Bool(if min { a & b } else { a | b }),
        _ if min => zip_int!(x, y, a, b => a.min(b), unreachable!()),
        _ => zip_int!(x, y, a, b => a.max(b), unreachable!()),
    }
}

// ---------------------------------------------------------------------------------------------
// Rendering

/// The precedence of `e`'s outermost operator, docs/ST.md's table (1 binds tightest); 0 for
/// an atom.
fn precedence(e: &Expr, bare: bool) -> u8 {
    match e {
        Expr::Lit(v, Form::Bare) if bare && v.literal(false, false).starts_with('-') => 4,
        Expr::Neg(_) | Expr::Not(_) => 4,
        Expr::Bin(Bin::Mul | Bin::Div | Bin::Mod, ..)
        | Expr::Mixed(Bin::Mul | Bin::Div | Bin::Mod, ..) => 5,
        Expr::Bin(Bin::Add | Bin::Sub, ..) | Expr::Mixed(Bin::Add | Bin::Sub, ..) => 6,
        Expr::Cmp(Cmp::Lt | Cmp::Gt | Cmp::Le | Cmp::Ge, ..) => 7,
        Expr::Cmp(Cmp::Eq | Cmp::Ne, ..) => 8,
        Expr::Bin(Bin::And | Bin::AndThen, ..) => 9,
        Expr::Bin(Bin::Xor, ..) => 10,
        Expr::Bin(Bin::Or | Bin::OrElse, ..) => 11,
        _ => 0,
    }
}

struct Render<'a> {
    vars: &'a Vars,
    /// Parentheses around every operation, or only where the precedence needs them.
    full: bool,
}

impl Render<'_> {
    /// `e` where an operator of precedence up to `max` needs no parentheses; `bare` when the
    /// context types an untyped literal (`e`'s type is one the context accepts).
    fn expr(&self, e: &Expr, max: u8, bare: bool, out: &mut String) {
        let p = precedence(e, bare);
        let paren = if self.full { p > 0 } else { p > max };
        if paren {
            out.push('(');
        }
        self.inner(e, bare, out);
        if paren {
            out.push(')');
        }
    }

    fn inner(&self, e: &Expr, bare: bool, out: &mut String) {
        let vars = self.vars;
        match e {
            Expr::Var(i) => out.push_str(&vars.0[*i].0),
            Expr::Lit(v, form) => out.push_str(&match form {
                Form::Bare => v.literal(!bare, false),
                Form::Typed => v.literal(true, false),
                Form::Based => v.literal(!bare || v.int() < 0, true),
            }),
            Expr::Neg(a) | Expr::Not(a) => {
                out.push_str(if matches!(e, Expr::Neg(_)) { "-" } else { "NOT " });
                let before = out.len();
                self.expr(a, 4, false, out);
                // `- -x`, not `--x`
                if out[before..].starts_with('-') {
                    out.insert(before, ' ');
                }
            }
            Expr::Bin(op, a, b) | Expr::Mixed(op, a, b) => {
                let p = precedence(e, false);
                // a mixed operation's literals are typed: untyped, one would take the other
                // operand's type
                let (ba, bb) = if matches!(e, Expr::Mixed(..)) {
                    (false, false)
                } else {
                    pair_bare(vars, a, b)
                };
                self.expr(a, p, ba, out);
                let sym = match op {
                    Bin::Add => "+",
                    Bin::Sub => "-",
                    Bin::Mul => "*",
                    Bin::Div => "/",
                    Bin::Mod => "MOD",
                    Bin::And if self.full => "AND",
                    Bin::And => "&",
                    Bin::Or => "OR",
                    Bin::Xor => "XOR",
                    Bin::AndThen => "AND_THEN",
                    Bin::OrElse => "OR_ELSE",
                };
                let _ = write!(out, " {sym} ");
                self.expr(b, p - 1, bb, out);
            }
            Expr::Cmp(op, a, b) => {
                let p = precedence(e, false);
                let (ba, bb) = pair_bare(vars, a, b);
                self.expr(a, p, ba, out);
                let sym = match op {
                    Cmp::Lt => "<",
                    Cmp::Gt => ">",
                    Cmp::Le => "<=",
                    Cmp::Ge => ">=",
                    Cmp::Eq => "=",
                    Cmp::Ne => "<>",
                };
                let _ = write!(out, " {sym} ");
                self.expr(b, p - 1, bb, out);
            }
            Expr::Abs(a) => self.call("ABS", &[(a, false)], out),
            Expr::Trunc(a) => self.call("TRUNC", &[(a, false)], out),
            Expr::MinMax(min, xs) => {
                let args = args_bare(vars, xs.iter().collect(), e.ty(vars));
                self.call(if *min { "MIN" } else { "MAX" }, &args, out);
            }
            Expr::Limit(xs) => {
                let args = args_bare(vars, xs.iter().collect(), e.ty(vars));
                self.call("LIMIT", &args, out);
            }
            Expr::Sel(xs) => {
                let (b1, b2) = pair_bare(vars, &xs[1], &xs[2]);
                self.call("SEL", &[(&xs[0], true), (&xs[1], b1), (&xs[2], b2)], out);
            }
            Expr::Shift(op, x, n) => {
                let name = match op {
                    Shift::Shl => "SHL",
                    Shift::Shr => "SHR",
                    Shift::Rol => "ROL",
                    Shift::Ror => "ROR",
                };
                // Any integer type counts, so the count may be untyped.
                self.call(name, &[(x, false), (n, true)], out);
            }
            Expr::Conv(to, a) => {
                let name = format!("{}_TO_{}", a.ty(vars).name(), to.name());
                self.call(&name, &[(a, true)], out);
            }
            Expr::Assign(a) => {
                let _ = write!(out, "({} := ", assigned_name(a.ty(vars)));
                self.expr(a, 11, false, out);
                out.push(')');
            }
        }
    }

    fn call(&self, name: &str, args: &[(&Expr, bool)], out: &mut String) {
        out.push_str(name);
        out.push('(');
        for (i, (a, bare)) in args.iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            self.expr(a, 11, *bare, out);
        }
        out.push(')');
    }
}

/// Whether a literal of `lit` written untyped where the context wants a `ctx` keeps its value:
/// an integer one of a type that converts to `ctx`; a real one of `ctx` itself (the text of a
/// REAL read as an LREAL is another value).
fn keeps_value(lit: T, ctx: T) -> bool {
    lit.widens_to(ctx) && (!lit.real() || lit == ctx)
}

/// Whether each operand of a binary operation may be an untyped literal: when the other one
/// has a variable (so its type is fixed) whose type the literal keeps its value in.
fn pair_bare(vars: &Vars, a: &Expr, b: &Expr) -> (bool, bool) {
    let ok =
        |lit: &Expr, other: &Expr| other.has_var() && keeps_value(lit.ty(vars), other.ty(vars));
    (ok(a, b), ok(b, a))
}

/// The same for the values of `MIN`, `MAX` and `LIMIT`, unified from the left: only the last
/// may be untyped, when the others unify to the common type `t`.
fn args_bare<'e>(vars: &Vars, xs: Vec<&'e Expr>, t: T) -> Vec<(&'e Expr, bool)> {
    let n = xs.len();
    let others: Vec<T> = xs[..n - 1].iter().map(|o| o.ty(vars)).collect();
    let last = unified(&others) == Some(t) && keeps_value(xs[n - 1].ty(vars), t);
    xs.into_iter().enumerate().map(|(i, x)| (x, i == n - 1 && last)).collect()
}

// ---------------------------------------------------------------------------------------------
// Generation

/// Random choices from a list proptest generates and shrinks; 0 once the list is used up.
struct Choices<'a> {
    list: &'a [u32],
    at: usize,
}

impl Choices<'_> {
    fn next(&mut self) -> u32 {
        let c = self.list.get(self.at).copied().unwrap_or(0);
        self.at += 1;
        c
    }

    fn below(&mut self, n: usize) -> usize {
        self.next() as usize % n
    }

    fn pick<X: Copy>(&mut self, xs: &[X]) -> X {
        xs[self.below(xs.len())]
    }

    fn u64(&mut self) -> u64 {
        u64::from(self.next()) << 32 | u64::from(self.next())
    }
}

/// A value of `t`, biased toward the edges.
fn value(t: T, c: &mut Choices) -> V {
    let kind = c.below(4);
    if t.real() {
        const SPECIAL: [f64; 16] = [
            0.0, -0.0, 1.0, -1.0, 0.5, 2.5, -2.5, 0.1, 1.0e30, -3.0e38, 1.0e-30, 16777217.0,
            100000.5, 3.0e9, 1.0e300, -7.0,
        ];
        let x = match kind {
            0 => SPECIAL[c.below(SPECIAL.len())],
            1 => f64::from(c.next() as i32 % 2000) / 16.0,
            _ if t == T::Real => {
                let f = f32::from_bits(c.next());
                f64::from(if f.is_finite() { f } else { 1.5 })
            }
            _ => {
                let f = f64::from_bits(c.u64());
                if f.is_finite() {
                    f
                } else {
                    -1.5
                }
            }
        };
        // a REAL too large for the type is written as its largest finite value
        return match V::LReal(x).to(t) {
            V::Real(f) if f.is_infinite() => V::Real(f32::MAX.copysign(f)),
            v => v,
        };
    }
    if t == T::Bool {
        return V::Bool(c.next() % 2 == 1);
    }
    let bits = match kind {
        0 => {
            // the edges of every width, and a 64-bit integer that rounds to REAL differently
            // straight and through LREAL
            const SPECIAL: [u64; 12] = [
                0,
                1,
                u64::MAX,
                2,
                0x7F,
                0x80,
                0x7FFF,
                0x8000,
                0x7FFF_FFFF,
                0x8000_0000,
                1 << 63,
                (1 << 62) + (1 << 38) + 1,
            ];
            SPECIAL[c.below(SPECIAL.len())]
        }
        1 => u64::from(c.next() % 80),
        2 => u64::from(c.next() % 80).wrapping_neg(),
        _ => c.u64(),
    };
    // the low bits, as a value of the type
    V::LWord(bits).to(t)
}

/// A literal of `t`, in one of the forms.
fn literal(t: T, c: &mut Choices) -> Expr {
    let v = value(t, c);
    let form = match c.below(3) {
        0 => Form::Bare,
        1 => Form::Typed,
        _ if t.real() || t == T::Bool => Form::Typed,
        _ => Form::Based,
    };
    Expr::Lit(v, form)
}

/// An expression of type exactly `t`, at most `depth` operations deep.
fn gen(t: T, depth: u32, vars: &Vars, c: &mut Choices) -> Expr {
    let choice = if depth == 0 { c.below(4) } else { c.below(24) };
    let sub = |t: T, c: &mut Choices| gen(t, depth - 1, vars, c);
    // An operand of `t` or of a type that converts to it implicitly.
    let narrower = |c: &mut Choices| {
        let ts = t.narrower();
        ts[c.below(ts.len())]
    };
    match choice {
        0..=2 => {
            // a variable of the type: two of each
            let i = TYPES.iter().position(|&x| x == t).expect("type") * 2 + c.below(2);
            Expr::Var(i)
        }
        3 => literal(t, c),
        4..=7 if t.num() => {
            let ops: &[Bin] = if t.integer() {
                &[Bin::Add, Bin::Sub, Bin::Mul, Bin::Div, Bin::Mod]
            } else {
                &[Bin::Add, Bin::Sub, Bin::Mul, Bin::Div]
            };
            let op = c.pick(ops);
            binary_of(op, t, depth, vars, c)
        }
        4..=7 if t == T::Bool => {
            let op = c.pick(&[Bin::And, Bin::Or, Bin::Xor, Bin::AndThen, Bin::OrElse]);
            binary_of(op, t, depth, vars, c)
        }
        // bit strings: the bitwise operators, and CODESYS's arithmetic
        4..=7 if t.bits() => {
            let ops =
                [Bin::And, Bin::Or, Bin::Xor, Bin::Add, Bin::Sub, Bin::Mul, Bin::Div, Bin::Mod];
            let op = c.pick(&ops);
            binary_of(op, t, depth, vars, c)
        }
        8..=10 if t == T::Bool => {
            let u = c.pick(&TYPES);
            let op = c.pick(&[Cmp::Lt, Cmp::Gt, Cmp::Le, Cmp::Ge, Cmp::Eq, Cmp::Ne]);
            let (a, b) = operands(u, depth, vars, c);
            Expr::Cmp(op, Box::new(a), Box::new(b))
        }
        11 if t.signed() || t.real() => Expr::Neg(Box::new(sub(t, c))),
        11 if t == T::Bool || t.bits() => Expr::Not(Box::new(sub(t, c))),
        12 if t.num() => Expr::Abs(Box::new(sub(t, c))),
        13 => {
            let n = 2 + c.below(2);
            let ts = chain(t, (0..n).map(|_| narrower(c)).collect(), c);
            let xs: Vec<Expr> = ts.into_iter().map(|u| sub(u, c)).collect();
            Expr::MinMax(c.next().is_multiple_of(2), xs)
        }
        14 => {
            let ts = chain(t, (0..3).map(|_| narrower(c)).collect(), c);
            let xs = [0, 1, 2].map(|i| sub(ts[i], c));
            Expr::Limit(Box::new(xs))
        }
        15 => {
            let g = sub(T::Bool, c);
            let (a, b) = operands(t, depth, vars, c);
            Expr::Sel(Box::new([g, a, b]))
        }
        16..=17 if t.bits() || t.integer() => {
            let op = c.pick(&[Shift::Shl, Shift::Shr, Shift::Rol, Shift::Ror]);
            let n = if c.below(2) == 0 {
                // mostly counts in and near the width, some negative, some far beyond
                let v = match c.below(8) {
                    0 => -i128::from(c.next() % 80),
                    1 => c.pick(&[256, 65_536, 65_537, 1 << 32, (1 << 32) + 3, 1 << 40]),
                    _ => i128::from(c.next() % 80),
                };
                if i32::try_from(v).is_ok() {
                    Expr::Lit(V::DInt(v as i32), c.pick(&[Form::Bare, Form::Typed]))
                } else {
                    // beyond DINT: a bare literal is a LINT, a typed one as it says
                    let v = if v < 0 { V::LInt(v as i64) } else { V::ULInt(v as u64) };
                    Expr::Lit(v, c.pick(&[Form::Bare, Form::Typed]))
                }
            } else {
                let nt = c.pick(&[T::SInt, T::Int, T::DInt, T::LInt, T::USInt, T::UInt, T::UDInt]);
                sub(nt, c)
            };
            Expr::Shift(op, Box::new(sub(t, c)), Box::new(n))
        }
        18 if t == T::DInt => Expr::Trunc(Box::new(sub(c.pick(&[T::Real, T::LReal]), c))),
        21 => Expr::Assign(Box::new(sub(t, c))),
        19..=20 if !mixed_partners(t).is_empty() => {
            let u = c.pick(&mixed_partners(t));
            let ops: &[Bin] = if t.real() {
                &[Bin::Add, Bin::Sub, Bin::Mul, Bin::Div]
            } else {
                &[Bin::Add, Bin::Sub, Bin::Mul, Bin::Div, Bin::Mod]
            };
            let op = c.pick(ops);
            let (a, b) = (sub(t, c), sub(u, c));
            let (a, b) = if c.next().is_multiple_of(2) { (a, b) } else { (b, a) };
            Expr::Mixed(op, Box::new(a), Box::new(b))
        }
        _ => {
            // a conversion from any other type
            let from = c.pick(&TYPES);
            if from == t {
                return sub(t, c);
            }
            Expr::Conv(t, Box::new(sub(from, c)))
        }
    }
}

/// The types that meet a `t` in CODESYS's arithmetic to give a `t`: integers as wide or
/// narrower for a bit string, narrower bit strings for an integer, any for a real.
fn mixed_partners(t: T) -> Vec<T> {
    TYPES
        .iter()
        .copied()
        .filter(|&u| {
            (t.bits() && u.integer() || u.bits() && (t.integer() || t.real()))
                && codesys_type(t, u) == t
        })
        .collect()
}

/// Whether the types of `MIN`'s or `LIMIT`'s arguments have a common type, unified from the
/// left as the compiler does, and which.
fn unified(ts: &[T]) -> Option<T> {
    let mut acc = *ts.first()?;
    for &u in &ts[1..] {
        if acc.widens_to(u) {
            acc = u;
        } else if !u.widens_to(acc) {
            return None;
        }
    }
    Some(acc)
}

/// The argument types `ts` (each converting to `t`), made to unify to `t`: one is `t`, and
/// any that would not unify with those before it becomes `t`.
fn chain(t: T, mut ts: Vec<T>, c: &mut Choices) -> Vec<T> {
    let k = c.below(ts.len());
    ts[k] = t;
    for i in 1..ts.len() {
        if unified(&ts[..=i]).is_none() {
            ts[i] = t;
        }
    }
    debug_assert_eq!(unified(&ts), Some(t));
    ts
}

/// Two operands whose common type is `t`: one of `t`, the other of `t` or narrower.
fn operands(t: T, depth: u32, vars: &Vars, c: &mut Choices) -> (Expr, Expr) {
    let ts = t.narrower();
    let u = ts[c.below(ts.len())];
    let a = gen(t, depth - 1, vars, c);
    let b = gen(u, depth - 1, vars, c);
    if c.next().is_multiple_of(2) {
        (a, b)
    } else {
        (b, a)
    }
}

fn binary_of(op: Bin, t: T, depth: u32, vars: &Vars, c: &mut Choices) -> Expr {
    let (a, b) = operands(t, depth, vars, c);
    Expr::Bin(op, Box::new(a), Box::new(b))
}

/// A variable of type `t`.
fn var_of(t: T) -> Expr {
    Expr::Var(TYPES.iter().position(|&x| x == t).expect("type") * 2)
}

/// Makes `e` compile: a divisor the compiler sees as the constant zero is a check error, so
/// such a divisor becomes a variable of its type.
fn fix_up(e: &mut Expr, vars: &Vars) {
    avoid_constant_zero_divisors(e, vars);
}

fn avoid_constant_zero_divisors(e: &mut Expr, vars: &Vars) {
    match e {
        Expr::Var(_) | Expr::Lit(..) => {}
        Expr::Neg(a)
        | Expr::Not(a)
        | Expr::Abs(a)
        | Expr::Trunc(a)
        | Expr::Conv(_, a)
        | Expr::Assign(a) => avoid_constant_zero_divisors(a, vars),
        Expr::Bin(op, a, b) | Expr::Mixed(op, a, b) => {
            avoid_constant_zero_divisors(a, vars);
            avoid_constant_zero_divisors(b, vars);
            if matches!(op, Bin::Div | Bin::Mod) && b.constant(vars) && b.eval(vars, &mut 0).zero()
            {
                **b = var_of(b.ty(vars));
            }
        }
        Expr::Cmp(_, a, b) | Expr::Shift(_, a, b) => {
            avoid_constant_zero_divisors(a, vars);
            avoid_constant_zero_divisors(b, vars);
        }
        Expr::MinMax(_, xs) => xs.iter_mut().for_each(|x| avoid_constant_zero_divisors(x, vars)),
        Expr::Limit(xs) | Expr::Sel(xs) => {
            xs.iter_mut().for_each(|x| avoid_constant_zero_divisors(x, vars))
        }
    }
}

/// The variable an [`Expr::Assign`] of type `t` writes, `w_<type>` in lower case.
fn assigned_name(t: T) -> String {
    format!("w_{}", t.name().to_lowercase())
}

/// Two variables of each type, `<type>_<n>` in lower case, with random initial values.
fn variables(c: &mut Choices) -> Vars {
    let mut vars = Vec::new();
    for t in TYPES {
        for n in 0..2 {
            let form = match c.below(3) {
                0 | 1 => Form::Bare,
                _ if t.real() || t == T::Bool => Form::Typed,
                _ => Form::Based,
            };
            vars.push((format!("{}_{n}", t.name().to_lowercase()), value(t, c), form));
        }
    }
    Vars(vars)
}

// ---------------------------------------------------------------------------------------------
// Compiling and running

/// One program: the variables, then `r<k> := <expression k>;`, one a line.
struct Case {
    vars: Vars,
    /// Each expression, and the type of the variable it is assigned to (its own type or one it
    /// converts to implicitly).
    exprs: Vec<(Expr, T)>,
}

impl Case {
    fn new(var_choices: &[u32], expr_choices: &[Vec<u32>], depth: u32) -> Case {
        let vars = variables(&mut Choices { list: var_choices, at: 0 });
        let exprs = expr_choices
            .iter()
            .map(|list| {
                let mut c = Choices { list, at: 0 };
                let t = c.pick(&TYPES);
                let mut e = gen(t, depth, &vars, &mut c);
                fix_up(&mut e, &vars);
                let wider: Vec<T> = TYPES.iter().copied().filter(|&u| t.widens_to(u)).collect();
                let r = if c.below(4) == 0 { wider[c.below(wider.len())] } else { t };
                (e, r)
            })
            .collect();
        Case { vars, exprs }
    }

    /// The source, and the line of each expression's statement.
    fn source(&self, full: bool) -> (String, Vec<u32>) {
        let mut src = String::from("PROGRAM main\nVAR\n");
        for (name, v, form) in &self.vars.0 {
            let lit = match form {
                Form::Bare => v.literal(false, false),
                Form::Typed => v.literal(true, false),
                Form::Based => v.literal(true, true),
            };
            let _ = writeln!(src, "    {name} : {} := {lit};", v.ty().name());
        }
        for (k, e) in self.exprs.iter().enumerate() {
            let _ = writeln!(src, "    r{k} : {};", e.1.name());
        }
        for t in TYPES {
            let _ = writeln!(src, "    {} : {};", assigned_name(t), t.name());
        }
        src.push_str("END_VAR\n");
        let mut lines = Vec::new();
        let render = Render { vars: &self.vars, full };
        for (k, (e, _)) in self.exprs.iter().enumerate() {
            lines.push(src.lines().count() as u32 + 1);
            let _ = write!(src, "    r{k} := ");
            render.expr(e, 11, false, &mut src);
            src.push_str(";\n");
        }
        src.push_str("END_PROGRAM\n");
        (src, lines)
    }
}

fn build(src: &str) -> Result<Compiled, String> {
    let (file, diags) = parse_file(Path::new("main.st"), src);
    if !diags.is_empty() {
        return Err(diags.to_string());
    }
    let inst = Instance {
        name: "main",
        pou: None,
        file: Path::new("main.st"),
        config: Path::new("plcd.toml"),
        line: 1,
        col: 1,
    };
    compile(&[file], &[inst]).map_err(|d| d.to_string())
}

/// One scan of `compiled`: the VM, and the line of each operation error with its code.
fn scan(compiled: &Compiled) -> (Vm, Vec<(u32, u16)>) {
    scan_program(compiled, &compiled.programs[0], u64::MAX)
}

/// One scan of `program` (`compiled`'s, or the same with native code), `budget` steps a
/// `run` call.
fn scan_program(compiled: &Compiled, program: &Program, budget: u64) -> (Vm, Vec<(u32, u16)>) {
    let mut vm = Vm::for_programs(&compiled.programs);
    vm.set_variables(&compiled.variables);
    vm.reset_for_run(&plcd_core::device::RetainSet::default(), false);
    let mut state = ExecState::with_frame(program.frame_bytes);
    let clock = ManualClock::new(0);
    let mut errors = Vec::new();
    let mut calls = 0u64;
    loop {
        match vm.run(program, &mut state, &clock, budget) {
            Exit::End => break,
            Exit::Budget => {}
            Exit::OperationError { code, pc } => errors.push((program.lines[pc as usize], code)),
            other => panic!("unexpected exit {other:?}"),
        }
        calls += 1;
        assert!(calls < 10_000_000, "no END");
    }
    (vm, errors)
}

/// `compiled`'s program with its native code attached (plcd-native).
/// One scan of `compiled` on the interpreter, without an operation error, and its native code
/// leaving the same variable memory whole and at budgets of a few steps (handed back in the
/// middle of anything); the interpreter's VM.
fn native_agrees_at_small_budgets(compiled: &Compiled) -> Vm {
    let (vm, errors) = scan(compiled);
    assert_eq!(errors, []);
    let program = with_native(compiled);
    for budget in [u64::MAX, 1, 2, 3, 5, 8] {
        let (native_vm, native_errors) = scan_program(compiled, &program, budget);
        assert_eq!(native_errors, []);
        assert!(native_vm.vars() == vm.vars(), "budget {budget}: variable memory differs");
    }
    vm
}

fn with_native(compiled: &Compiled) -> Program {
    let mut program = compiled.programs[0].clone();
    let native = plcd_native::compile(&program).unwrap_or_else(|e| panic!("no native code: {e}"));
    program.native = Some(native);
    program
}

/// The slot of the variable `name` of type `t`, its bits as they are.
fn slot(compiled: &Compiled, vm: &Vm, name: &str, t: T) -> u64 {
    let sym = compiled.variables.symbols.iter().find(|s| s.name.eq_ignore_ascii_case(name));
    vm.read_value(sym.unwrap_or_else(|| panic!("no variable {name}")).at, t.elem())
}

/// Reads the variable `name` as a value of `t`.
fn read(compiled: &Compiled, vm: &Vm, name: &str, t: T) -> V {
    let sym = compiled.variables.symbols.iter().find(|s| s.name.eq_ignore_ascii_case(name));
    let sym = sym.unwrap_or_else(|| panic!("no variable {name}"));
    let expected_ty = match t {
        T::Bool => ValueType::Bool,
        t if t.signed() => ValueType::Signed(t.elem()),
        t if t.real() => ValueType::Real(t.elem()),
        t => ValueType::Unsigned(t.elem()),
    };
    assert_eq!(sym.ty, expected_ty, "{name}'s type");
    let raw = vm.read_value(sym.at, t.elem());
    match t {
        T::Real => V::Real(f32::from_bits(raw as u32)),
        T::LReal => V::LReal(f64::from_bits(raw)),
        // the slot's low bits, as a value of the type
        t => V::LWord(raw).to(t),
    }
}

/// Compiles and runs `case` rendered one way, and checks every result and every division by
/// zero against the reference; with `native`, the same program with native code attached too,
/// with the whole budget and with `native` steps a `run` call (which makes native code hand
/// back to the interpreter inside expressions), against the interpreter to the bit.
fn check(case: &Case, full: bool, native: Option<u64>) -> Result<(), TestCaseError> {
    let (src, lines) = case.source(full);
    let compiled = match build(&src) {
        Ok(c) => c,
        Err(e) => return Err(TestCaseError::fail(format!("does not compile:\n{e}\n{src}"))),
    };
    let (vm, errors) = scan(&compiled);
    if let Some(budget) = native {
        let program = with_native(&compiled);
        for budget in [u64::MAX, budget] {
            let (native_vm, native_errors) = scan_program(&compiled, &program, budget);
            for (k, (_, t)) in case.exprs.iter().enumerate() {
                let name = format!("main.r{k}");
                let (a, b) =
                    (slot(&compiled, &vm, &name, *t), slot(&compiled, &native_vm, &name, *t));
                let line = lines[k];
                let source_line = src.lines().nth(line as usize - 1).unwrap_or("");
                prop_assert!(
                    a == b,
                    "native code, budget {budget}: line {line}: `{}`\ninterpreter {:?} ({a:#x}), \
                     native {:?} ({b:#x})\n{src}",
                    source_line.trim(),
                    read(&compiled, &vm, &name, *t),
                    read(&compiled, &native_vm, &name, *t)
                );
            }
            prop_assert!(
                native_vm.vars() == vm.vars(),
                "native code, budget {budget}: variable memory differs\n{src}"
            );
            prop_assert_eq!(
                &native_errors,
                &errors,
                "native code, budget {}: operation errors\n{}",
                budget,
                src
            );
        }
    }
    for (k, (e, t)) in case.exprs.iter().enumerate() {
        let mut expected_errors = 0;
        let expected = e.eval(&case.vars, &mut expected_errors).widen(*t);
        let actual = read(&compiled, &vm, &format!("main.r{k}"), *t);
        let line = lines[k];
        let raised = errors.iter().filter(|(l, _)| *l == line).collect::<Vec<_>>();
        let source_line = src.lines().nth(line as usize - 1).unwrap_or("");
        prop_assert!(
            expected.same(actual),
            "line {line}: `{}`\nexpected {expected:?}, got {actual:?}\n{src}",
            source_line.trim()
        );
        prop_assert!(
            raised.iter().all(|(_, code)| *code == ERR_DIVIDE_BY_ZERO),
            "line {line}: `{}`: errors {raised:?}",
            source_line.trim()
        );
        prop_assert_eq!(
            raised.len(),
            expected_errors as usize,
            "line {}: `{}`: divisions by zero\n{}",
            line,
            source_line.trim(),
            src
        );
    }
    Ok(())
}

/// The choices of one case: the variables', and each expression's.
fn case_choices(exprs: usize) -> impl Strategy<Value = (Vec<u32>, Vec<Vec<u32>>)> {
    (
        prop::collection::vec(any::<u32>(), 120),
        prop::collection::vec(prop::collection::vec(any::<u32>(), 0..120), exprs),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    /// Fully parenthesized expressions.
    #[test]
    fn st_expressions_match_the_reference((vars, exprs) in case_choices(24)) {
        check(&Case::new(&vars, &exprs, 5), true, None)?;
    }

    /// The same with only the parentheses the precedence needs.
    #[test]
    fn st_precedence_matches_the_reference((vars, exprs) in case_choices(24)) {
        check(&Case::new(&vars, &exprs, 5), false, None)?;
    }
}

proptest! {
    // Fewer cases: Cranelift compiles each program in some 40 ms in a debug build; 4000 cases ran clean once.
    #![proptest_config(ProptestConfig { cases: 150, ..ProptestConfig::default() })]

    /// The same programs with native code attached (plcd-native): the reference's values, and
    /// the interpreter's bits and operation errors, with the whole budget and with `budget`
    /// steps a `run` call.
    #[test]
    fn st_native_code_matches_the_interpreter(
        (vars, exprs) in case_choices(24),
        full in any::<bool>(),
        budget in 1..14u64,
    ) {
        check(&Case::new(&vars, &exprs, 5), full, Some(budget))?;
    }
}

// ---------------------------------------------------------------------------------------------
// The bugs the properties found, minimized; each `AVOID_*` switch above keeps the properties
// off one of them until it is fixed.

/// Compiles `body` in a PROGRAM with `vars` declared, runs one scan: the values of `names`.
fn run(vars: &str, body: &str, names: &[(&str, T)]) -> Vec<V> {
    let src = format!("PROGRAM main\nVAR\n{vars}\nEND_VAR\n{body}\nEND_PROGRAM\n");
    let compiled = build(&src).unwrap_or_else(|e| panic!("{e}"));
    let (vm, errors) = scan(&compiled);
    assert_eq!(errors, []);
    names.iter().map(|(n, t)| read(&compiled, &vm, &format!("main.{n}"), *t)).collect()
}

fn assert_values(actual: &[V], expected: &[V]) {
    assert_eq!(actual.len(), expected.len());
    for (a, e) in actual.iter().zip(expected) {
        assert!(a.same(*e), "expected {expected:?}, got {actual:?}");
    }
}

/// docs/ST.md, standard functions: the count of `SHL` … `ROR` is an unsigned 64-bit number: a
/// negative count shifts everything out and rotates the other way; a count at or beyond the
/// width shifts everything out.
#[test]
fn shift_count_negative_constant() {
    let r = run(
        "w : WORD := 16#00FF; b : BYTE := 16#81; a : WORD; c : BYTE;",
        "a := SHL(w, -1); c := ROL(b, -1);",
        &[("a", T::Word), ("c", T::Byte)],
    );
    assert_values(&r, &[V::Word(0), V::Byte(0xC0)]);
}

#[test]
fn shift_count_beyond_the_type_of_in() {
    let r = run(
        "w : WORD := 16#00FF; n : DINT := 65537; a : WORD; c : WORD;",
        "a := SHL(w, n); c := SHR(w, 65536);",
        &[("a", T::Word), ("c", T::Word)],
    );
    assert_values(&r, &[V::Word(0), V::Word(0)]);
}

/// docs/ST.md, expressions: a literal-only expression without a context type is a DINT, or a
/// LINT when a literal needs it.
#[test]
fn shift_count_untyped_beyond_dint() {
    let r = run("d : DWORD := 1; a : DWORD;", "a := ROL(d, 4294967297);", &[("a", T::DWord)]);
    assert_values(&r, &[V::DWord(2)]);
}

/// docs/ST.md, conversion functions: REAL/LREAL to an integer saturates at the target's range.
/// The VM does; the folding of a constant wraps the bound, as 2^63 − 1 and 2^64 − 1 are no
/// LREALs and round up.
#[test]
fn constant_real_to_64_bit_saturates() {
    let r = run(
        "x : LREAL := 1.0E30; a, b : LINT; c, d : ULINT;",
        "a := LREAL_TO_LINT(x); b := LREAL_TO_LINT(1.0E30); c := LREAL_TO_ULINT(x); d := LREAL_TO_ULINT(1.0E30);",
        &[("a", T::LInt), ("b", T::LInt), ("c", T::ULInt), ("d", T::ULInt)],
    );
    assert_values(
        &r,
        &[V::LInt(i64::MAX), V::LInt(i64::MAX), V::ULInt(u64::MAX), V::ULInt(u64::MAX)],
    );
}

/// docs/ST.md, conversion functions: integer to REAL is the nearest float. The VM rounds once;
/// the folding of a constant rounds to LREAL first, then to REAL: 2^62 + 2^38 + 1 is nearer
/// 2^62 + 2^39, but its LREAL, 2^62 + 2^38, is a tie that rounds to even, 2^62.
#[test]
fn constant_64_bit_to_real_rounds_once() {
    let r = run(
        "u : ULINT := 16#4000004000000001; a, b : REAL;",
        "a := ULINT_TO_REAL(u); b := ULINT_TO_REAL(ULINT#16#4000004000000001);",
        &[("a", T::Real), ("b", T::Real)],
    );
    let nearest = V::Real(f32::from_bits(0x5E80_0001));
    assert_values(&r, &[nearest, nearest]);
}

/// Unary minus on a REAL is the IEEE negation, as the VM does at run time: -0.0 for 0.0. The
/// folding of a typed constant computes 0 - x, which is +0.0.
#[test]
fn constant_negated_real_zero() {
    let r = run(
        "z : REAL := 0.0; a, b : REAL; c : LREAL;",
        "a := -z; b := -REAL#0.0; c := -LREAL#0.0;",
        &[("a", T::Real), ("b", T::Real), ("c", T::LReal)],
    );
    assert_values(&r, &[V::Real(-0.0), V::Real(-0.0), V::LReal(-0.0)]);
}

/// docs/ST.md, expressions: an untyped literal takes the type of the other operand: in
/// `16#B2 + d` a DINT, 178, not the type the outer operation expects (SINT, from `s`), where
/// the based literal would read as the bit pattern −78 (it once did).
#[test]
fn based_literal_takes_its_own_operations_type() {
    let r = run(
        "s : SINT; d : DINT; r : DINT; c : BOOL;",
        "r := s + (16#B2 + d); c := s < (16#B2 + d);",
        &[("r", T::DInt), ("c", T::Bool)],
    );
    assert_values(&r, &[V::DInt(178), V::Bool(true)]);
}

/// The same, where the literal's own operation is on a USINT: `16#B2 * u` is 178 of a USINT
/// (it was once refused as "constant `-78` does not fit `USINT`").
#[test]
fn based_literal_in_a_narrower_operation_keeps_its_value() {
    let r = run(
        "s : SINT; d : DINT; u : USINT := 1; q : DINT;",
        "q := s + ((16#B2 * u) + d);",
        &[("q", T::DInt)],
    );
    assert_values(&r, &[V::DInt(178)]);
}

/// The habits of statements: a FOR loop counting in an array element and in a struct member
/// (TwinCAT), assignments inside expressions (CODESYS: chained, in a condition, in a loop's
/// test, as an index); native code gives the interpreter's memory, also when a budget of a
/// few steps hands back to the interpreter in the middle of a loop or an expression.
#[test]
fn statement_habits_native_code_matches_the_interpreter() {
    let src = "TYPE Pair : STRUCT n : INT; k : DINT; END_STRUCT; END_TYPE
PROGRAM main
VAR
    offset : ARRAY [1..2] OF DINT; s : DINT; p : Pair; g : ARRAY [1..3] OF Pair;
    a, b : BOOL := TRUE; i, k, m, n, cnt : INT; x, y : DINT; r : REAL;
    arr : ARRAY [0..3] OF INT;
END_VAR
    FOR offset[1] := 0 TO 3 DO s := s + offset[1]; END_FOR;
    FOR p.n := 10 TO 0 BY -5 DO n := n + p.n; END_FOR;
    FOR g[2].k := 1 TO 3 DO IF g[2].k = 2 THEN g[2].k := 3; END_IF; x := x + g[2].k; END_FOR;
    a := b := NOT a;
    IF (i := i + 1) >= 3 THEN i := 0; END_IF;
    r := k := i * 7;
    y := (m := 4) * 2 + m;
    arr[(k := 2)] := 9;
    cnt := 0;
    WHILE (cnt := cnt + 1) < 5 DO x := x + cnt; END_WHILE;
END_PROGRAM
";
    let compiled = build(src).unwrap_or_else(|e| panic!("{e}"));
    let vm = native_agrees_at_small_budgets(&compiled);
    // and the values docs/ST.md gives: 0 + 1 + 2 + 3; 10 + 5 + 0; g[2].k 1, 3 (written): 1 + 3
    // then 1 + 2 + 3 + 4 from the WHILE; 4 * 2 + 4
    let names = [("s", T::DInt), ("n", T::Int), ("x", T::DInt), ("y", T::DInt), ("cnt", T::Int)];
    let values: Vec<V> =
        names.iter().map(|(n, t)| read(&compiled, &vm, &format!("main.{n}"), *t)).collect();
    assert_values(&values, &[V::DInt(6), V::Int(15), V::DInt(14), V::DInt(12), V::Int(5)]);
}

/// Function block instances as values (CODESYS, TwinCAT; compile/fb_value.rs): an instance
/// assigned whole, an array element from an instance, and a METHOD whose result is an
/// instance, its copy assigned and an output read from it in place; native code gives the
/// interpreter's memory, also when a budget of a few steps hands back in the middle.
#[test]
fn instance_values_native_code_matches_the_interpreter() {
    let src = "FUNCTION_BLOCK Counter
VAR_INPUT step : INT := 1; END_VAR
VAR_OUTPUT count : INT; END_VAR
VAR name : STRING[8] := 'c'; END_VAR
count := count + step;
END_FUNCTION_BLOCK
FUNCTION_BLOCK Bank
VAR cs : ARRAY [1..3] OF Counter; END_VAR
END_FUNCTION_BLOCK
METHOD Pick : Counter
VAR_INPUT k : INT; END_VAR
Pick := cs[k];
END_METHOD
METHOD Bump
cs[2](step := 7);
END_METHOD
PROGRAM main
VAR
    a, b, c : Counter; bank : Bank; n, m : INT;
END_VAR
    a(step := 3);
    b := a;
    b();
    bank.Bump();
    c := bank.Pick(2);
    c();
    n := bank.Pick(2).count;
    m := c.count + b.count;
END_PROGRAM
";
    let compiled = build(src).unwrap_or_else(|e| panic!("{e}"));
    let vm = native_agrees_at_small_budgets(&compiled);
    // a: 3; b := a, b() with step 3: 6; bank.cs[2]: 7; c := its copy, c() with step 7: 14;
    // Pick(2).count: 7; m: 14 + 6
    let names = [("b.count", T::Int), ("c.count", T::Int), ("n", T::Int), ("m", T::Int)];
    let values: Vec<V> =
        names.iter().map(|(n, t)| read(&compiled, &vm, &format!("main.{n}"), *t)).collect();
    assert_values(&values, &[V::Int(6), V::Int(14), V::Int(7), V::Int(20)]);
}
