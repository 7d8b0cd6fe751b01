//! CODESYS's implicit conversions that may change a value, which IEC 61131-3 refuses and
//! CODESYS and TwinCAT compile with a warning (C0195 "implicit conversion from signed type to
//! unsigned type", C0196 the other way, and the narrowing ones): an integer or bit string
//! given where another integer or bit string is wanted that does not hold all its values
//! (`size := LEN(s)` with a UDINT `size`, `stop := i - 1` with a UINT `stop`, a WORD
//! expression assigned to an INT), and an enumeration's value where an integer is wanted.
//!
//! They apply wherever the checker converts implicitly ([`Ctx::coerce`]: an assignment, an
//! argument, an initial value, a function's result, a FOR's bounds; and an output bound with
//! `=>`). The value is converted as the explicit `<FROM>_TO_<TO>` converts it: to its two's
//! complement bits, wrapped to the target's width. Each use is noted as a
//! [`Habit`](crate::st::dialect::Habit), so `[st] strict` refuses it, and otherwise warns with
//! the conversion to write (docs/ST.md, "Implicit conversions").
//!
//! The same habit converts an `LREAL` where a `REAL` is wanted (`r := l * 2.0`), and an
//! integer where a real that does not hold all its values is wanted (`r := d` with a DINT `d`,
//! CODESYS's C0197 "implicit conversion from 'DINT' to 'REAL': possible loss of information"):
//! to the nearest value of the target, as `LREAL_TO_REAL` and `DINT_TO_REAL` convert.
//!
//! A `REAL` or `LREAL` never converts implicitly to an integer: that stays an error (no
//! vendor's documentation says CODESYS accepts it, nor how it would round).

use super::codesys;
use super::ctx::Ctx;
use super::expr::TExpr;
use super::types::{Prim, Ty};
use crate::st::ast::Span;
use crate::st::dialect::Habit;

/// Whether CODESYS converts a `from` value implicitly to `to` where plcd's lossless rules do
/// not: both integers or bit strings (`BOOL` is neither), the target of another sign or
/// narrower; an `LREAL` to a `REAL`; an integer (not a bit string) to a real that does not
/// hold all its values.
pub fn lossy(from: Prim, to: Prim) -> bool {
    if from == to || from.widens_to(to) {
        return false;
    }
    let integers = from.is_integral() && to.is_integral() && !codesys::implicit_bits(from, to);
    integers || (from == Prim::LReal && to == Prim::Real) || (from.is_int() && to.is_real())
}

/// The warning for a lossy conversion from `from` to `to`, with a value it changes: −1 when
/// `from` has negative values and `to` none, else the first value above `to`'s range; to a
/// real, a value the target holds only rounded.
pub fn warning(from: Prim, to: Prim) -> String {
    let (f, t) = (from.name(), to.name());
    if to.is_real() {
        let (given, becomes) = match (from, to) {
            (Prim::LReal, _) => ("0.1".to_string(), format!("{}", f64::from(0.1f32))),
            // 2^24 + 1 and 2^53 + 1: the first integers a REAL and an LREAL do not hold
            (_, Prim::Real) => ("16777217".to_string(), "16777216".to_string()),
            _ => ("9007199254740993".to_string(), "9007199254740992".to_string()),
        };
        return format!(
            "`{f}` converted implicitly to `{t}`: the value is rounded to the nearest `{t}` ({given} becomes {becomes}); write `{f}_TO_{t}(…)` to say so"
        );
    }
    let (from_lo, _) = from.range().expect("an integer type");
    let (to_lo, to_hi) = to.range().expect("an integer type");
    let changed = if from_lo < 0 && to_lo == 0 { -1 } else { to_hi + 1 };
    format!(
        "`{f}` converted implicitly to `{t}`: the value wraps to {} bits ({changed} becomes {}); write `{f}_TO_{t}(…)` to say so",
        to.bits(),
        super::types::wrap(to, changed)
    )
}

impl Ctx<'_> {
    /// Notes the lossy conversion of a `from` value to `to` at `span` when [`lossy`] says it
    /// is one: the habit (an error under `[st] strict`), else a warning. Whether it is one.
    pub(super) fn lossy_conversion(
        &mut self,
        from: Prim,
        to: Prim,
        file: usize,
        span: Span,
    ) -> bool {
        if !lossy(from, to) {
            return false;
        }
        self.habit(Habit::LossyConversion { from: from.name(), to: to.name() }, file, span);
        if !self.dialect.strict {
            self.warn(file, span, warning(from, to));
        }
        true
    }

    /// An enumeration's value where an integer or a bit string is wanted (`i := eState`, as
    /// CODESYS): its number, of the enumeration's base type. Converted without a warning when
    /// `to` holds every value of the enumeration (an enumeration without a declared base is a
    /// DINT in plcd, an INT in CODESYS: `i := eState` into an INT is no loss either way), or,
    /// for a constant value, when `to` holds that value; else as its base type would be. `None` when `te` is no enumeration's value or `to` no
    /// integer.
    pub(super) fn enum_as_integer(&mut self, te: TExpr, to: &Ty, file: usize) -> Option<TExpr> {
        let Ty::Enum(e) = te.ty else { return None };
        let target = to.prim(&self.types).filter(|p| p.is_integral());
        let target = target.filter(|_| !matches!(to, Ty::Enum(_)))?;
        self.habit(Habit::EnumToInteger, file, te.span);
        let (lo, hi) = target.range().expect("an integer type");
        let enumeration = &self.types.enums[e];
        let base = enumeration.base;
        // a constant (a CASE label, `i := E.x`) by its own value: TYPE_INTERFACE's 16#F000
        // makes no other value of `__SYSTEM.TYPE_CLASS` lossy as an INT label
        let fits = match te.const_int() {
            Some(v) => (lo..=hi).contains(&v),
            None => enumeration.values.iter().all(|(_, v)| (lo..=hi).contains(v)),
        };
        let te = TExpr { ty: Ty::Prim(base), ..te };
        Some(if fits { self.conv(te, target, to.clone()) } else { self.coerce(te, to, file) })
    }
}

impl Ctx<'_> {
    /// The type of an operation between a real constant and an integer (`i > 0.0`, `n * 0.5`):
    /// the real type the integer converts to without a loss (IEC 61131-3's implicit
    /// conversions; a constant takes its type from the other operand, and an integer no real
    /// type): `REAL` for `SINT` … `INT`, `USINT`, `UINT`, when the constant is within `REAL`'s
    /// range, else `LREAL`. `None` when `literal` is no real constant, `other` no integer, or
    /// no real holds all its values (`LINT`, `ULINT`).
    pub(super) fn real_beside(&self, literal: &TExpr, other: &Ty) -> Option<Prim> {
        let super::expr::TK::Const(super::ctx::Cv::Real(v)) = literal.k else { return None };
        if literal.ty != Ty::RealLit || matches!(other, Ty::Enum(_)) {
            return None;
        }
        let p = other.prim(&self.types).filter(|p| p.is_int())?;
        let in_real = v.is_finite() && v.abs() <= f64::from(f32::MAX);
        [Prim::Real, Prim::LReal]
            .into_iter()
            .find(|w| p.widens_to(*w) && (*w == Prim::LReal || in_real))
    }

    /// Whether `ty` is an integer or bit string type that is no enumeration (what an
    /// enumeration's value converts to beside it).
    pub(super) fn plain_integer(&self, ty: &Ty) -> bool {
        !matches!(ty, Ty::Enum(_)) && ty.prim(&self.types).is_some_and(|p| p.is_integral())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lossy_pairs_are_those_of_another_sign_or_narrower() {
        use Prim::*;
        // signed to unsigned, unsigned to signed as wide, narrower
        assert!(lossy(Int, UInt));
        assert!(lossy(Int, UDInt));
        assert!(lossy(UInt, Int));
        assert!(lossy(DInt, Int));
        assert!(lossy(Word, Int));
        assert!(lossy(DWord, Word));
        assert!(lossy(Int, Byte));
        // lossless: plcd converts them without a word
        assert!(!lossy(Int, DInt));
        assert!(!lossy(UInt, DInt));
        assert!(!lossy(Byte, Int));
        assert!(!lossy(Int, Word));
        assert!(!lossy(Int, Int));
        // reals: LREAL to REAL, an integer to a real that does not hold it
        assert!(lossy(LReal, Real));
        assert!(lossy(DInt, Real));
        assert!(lossy(UDInt, Real));
        assert!(lossy(LInt, LReal));
        assert!(!lossy(Real, LReal));
        assert!(!lossy(Int, Real));
        assert!(!lossy(DInt, LReal));
        assert!(!lossy(DWord, Real), "a bit string to a real stays an error");
        // not integers
        assert!(!lossy(Real, Int));
        assert!(!lossy(LReal, DInt));
        assert!(!lossy(Bool, Int));
        assert!(!lossy(Time, DInt));
    }

    #[test]
    fn the_warning_shows_a_value_that_changes() {
        use Prim::*;
        assert_eq!(
            warning(Int, UInt),
            "`INT` converted implicitly to `UINT`: the value wraps to 16 bits (-1 becomes 65535); write `INT_TO_UINT(…)` to say so"
        );
        assert!(warning(UInt, Int).contains("(32768 becomes -32768)"));
        assert!(warning(DInt, Int).contains("(32768 becomes -32768)"));
        assert!(warning(UDInt, UInt).contains("(65536 becomes 0)"));
        assert!(warning(Int, UDInt).contains("(-1 becomes 4294967295)"));
        assert!(warning(Word, SInt).contains("8 bits (128 becomes -128)"));
        assert_eq!(
            warning(LReal, Real),
            "`LREAL` converted implicitly to `REAL`: the value is rounded to the nearest `REAL` (0.1 becomes 0.10000000149011612); write `LREAL_TO_REAL(…)` to say so"
        );
        assert!(warning(DInt, Real).contains("(16777217 becomes 16777216)"));
        assert!(warning(LInt, LReal).contains("(9007199254740993 becomes 9007199254740992)"));
    }
}
