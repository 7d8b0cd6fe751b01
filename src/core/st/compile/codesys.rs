//! CODESYS's arithmetic and library habits that the checker accepts beyond IEC 61131-3
//! (docs/ST.md marks each a **choice**): the types of bit-string arithmetic, the Util
//! library's names, the names CODESYS gives the standard string functions' inputs, and
//! enumeration values named `E.Value`. Each use is a
//! [`Habit`](crate::st::dialect::Habit) noted with [`Ctx::habit`](super::ctx::Ctx::habit),
//! which `[st] strict` refuses.

use super::types::Prim;

/// The functions of CODESYS's Util library the prelude holds (`prelude.st`): calling one is
/// `Habit::UtilBcd`.
pub const UTIL_BCD: &[&str] = &[
    "BCD_TO_INT",
    "INT_TO_BCD",
    "BCD_TO_BYTE",
    "BCD_TO_WORD",
    "BCD_TO_DWORD",
    "BYTE_TO_BCD",
    "WORD_TO_BCD",
    "DWORD_TO_BCD",
];

/// The type CODESYS computes `a op b` in (op one of `+ - * / MOD`) when one operand is a bit
/// string and the other a bit string, an integer or a real, and they are not the same type:
///
/// - two bit strings: the wider one (`BYTE + WORD` is a `WORD`);
/// - a bit string and an integer: the integer when it is wider (`BYTE + INT` is an `INT`), the
///   bit string otherwise (`WORD + INT` is a `WORD`, `DWORD * SINT` a `DWORD`);
/// - a bit string and a `REAL` or `LREAL`: the real (`Habit::BitWithReal`).
///
/// The operands are converted to that type (an integer to a bit string by its two's
/// complement bits, as `INT_TO_WORD`), and the operation wraps at its width.
pub fn bit_arithmetic_type(a: Prim, b: Prim) -> Option<Prim> {
    let (bits, other) = match (a.is_bits(), b.is_bits()) {
        (true, true) => return Some(if a.bits() >= b.bits() { a } else { b }),
        (true, false) => (a, b),
        (false, true) => (b, a),
        (false, false) => return None,
    };
    if other.is_real() {
        Some(other)
    } else if other.is_int() {
        Some(if other.bits() > bits.bits() { other } else { bits })
    } else {
        None
    }
}

/// Whether CODESYS's implicit conversion of a `from` value to `to` applies, between a bit
/// string and an integer, where every value of `from` is one of `to`: a bit string to a wider
/// integer or to an unsigned one as wide (`BYTE` to `INT`, `USINT`); an integer to a bit string
/// as wide or wider (`INT` to `WORD`, its two's complement bits).
pub fn implicit_bits(from: Prim, to: Prim) -> bool {
    if from.is_bits() && to.is_int() {
        let unsigned = to.range().is_some_and(|(lo, _)| lo == 0);
        to.bits() > from.bits() || (unsigned && to.bits() == from.bits())
    } else {
        from.is_int() && to.is_bits() && to.bits() >= from.bits()
    }
}

/// The signed integer a bit string is negated in: one wide enough for all its values (`BYTE`:
/// `INT`, `WORD`: `DINT`, `DWORD` and `LWORD`: `LINT`).
pub fn signed_of(bits: Prim) -> Prim {
    match bits.bits() {
        8 => Prim::Int,
        16 => Prim::DInt,
        _ => Prim::LInt,
    }
}

/// The bit string as wide as an integer type (what a shift of it works on).
pub fn bits_of(p: Prim) -> Prim {
    match p.bits() {
        8 => Prim::Byte,
        16 => Prim::Word,
        32 => Prim::DWord,
        _ => Prim::LWord,
    }
}

impl<'a> super::ctx::Ctx<'a> {
    /// `E.Value`, CODESYS's and TwinCAT's way to name a value of the enumeration `E` (required
    /// by `{attribute 'qualified_only'}`, accepted always): IEC 61131-3's `E#Value`, when `base`
    /// names an enumeration type and no variable of the scope. `Habit::EnumDotValue`.
    pub(super) fn dotted_enum_value(
        &mut self,
        base: &crate::st::ast::Expr,
        value: &crate::st::ast::Ident,
        span: crate::st::ast::Span,
        scope: super::ctx::Scope,
        expected: Option<&super::types::Ty>,
    ) -> Option<super::expr::TExpr> {
        use crate::st::ast::{Expr, ExprKind, Literal};
        let ExprKind::Name(ty) = &base.kind else { return None };
        let name = ty.name.to_ascii_lowercase();
        let variable = scope.pou.is_some_and(|p| self.pous[p].lookup(&ty.name).is_some())
            || self.global_names.contains_key(&name);
        let &t = self.type_names.get(&name).filter(|_| !variable)?;
        if !matches!(self.resolve_type_decl(t), super::types::Ty::Enum(_)) {
            return None;
        }
        self.habit(crate::st::dialect::Habit::EnumDotValue, scope.file, span);
        let value = Expr { kind: ExprKind::Name(value.clone()), span: value.span };
        let typed = Literal::Typed { ty: ty.clone(), value: Box::new(value) };
        Some(self.literal(&typed, span, scope, expected))
    }
}

impl super::ctx::Ctx<'_> {
    /// `.x`, CODESYS's global scope operator (`Habit::GlobalScope`, noted by the parser, which
    /// keeps the dot in the name): the global `x`, past any variable of the scope called `x`;
    /// an error when there is no such global.
    pub(super) fn global_scope_operator(
        &mut self,
        id: &crate::st::ast::Ident,
        scope: super::ctx::Scope,
        access: super::expr::Access,
    ) -> super::expr::TExpr {
        let name = &id.name[1..];
        let Some(&g) = self.global_names.get(&name.to_ascii_lowercase()) else {
            let msg = format!("`.{name}` names a global, and no global is called `{name}`");
            self.error(scope.file, id.span, msg);
            return super::expr::TExpr::error(id.span);
        };
        let plain = crate::st::ast::Ident { name: name.to_string(), span: id.span };
        self.global_var(g, &plain, access, scope.file)
    }
}

/// The names CODESYS (and TwinCAT's Tc2_Standard) gives the inputs of the standard string
/// functions, each with the IEC 61131-3 name of the same input (`LEN(STR := s)` is
/// `LEN(IN := s)`): a formal argument so named is `Habit::CodesysParameter`.
pub fn string_parameters(function: &str) -> &'static [(&'static str, &'static str)] {
    match function {
        "LEN" => &[("STR", "IN")],
        "LEFT" | "RIGHT" => &[("STR", "IN"), ("SIZE", "L")],
        "MID" | "DELETE" => &[("STR", "IN"), ("LEN", "L"), ("POS", "P")],
        "CONCAT" | "FIND" | "REPLACE" => &[("STR1", "IN1"), ("STR2", "IN2")],
        "INSERT" => &[("STR1", "IN1"), ("STR2", "IN2"), ("POS", "P")],
        _ => &[],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_arithmetic_types_as_codesys() {
        use Prim::*;
        assert_eq!(bit_arithmetic_type(Byte, Word), Some(Word));
        assert_eq!(bit_arithmetic_type(DWord, Byte), Some(DWord));
        assert_eq!(bit_arithmetic_type(Byte, Int), Some(Int));
        assert_eq!(bit_arithmetic_type(Word, Int), Some(Word));
        assert_eq!(bit_arithmetic_type(SInt, DWord), Some(DWord));
        assert_eq!(bit_arithmetic_type(LWord, ULInt), Some(LWord));
        assert_eq!(bit_arithmetic_type(Byte, Real), Some(Real));
        assert_eq!(bit_arithmetic_type(LWord, LReal), Some(LReal));
        assert_eq!(bit_arithmetic_type(Byte, Time), None);
        assert_eq!(bit_arithmetic_type(Byte, Bool), None);
        assert_eq!(bit_arithmetic_type(Int, Real), None);
    }
}
