//! An enumeration compared with an integer, and an integer given where CODESYS's type class
//! (`__SYSTEM.TYPE_CLASS`, `IBaseLibrary.TypeClass`) is wanted, as TcUnit writes both
//! (`UDINT_TO_INT(Expected.TypeClass) = IBaseLibrary.TypeClass.TYPE_STRING` and
//! `ReportResult(ExpectedTypeClass := UDINT_TO_INT(Expected.TypeClass), …)` in its
//! FB_AssertResultStatic, github.com/tcunit/TcUnit).
//!
//! CODESYS compares an enumeration's value with an integer by its number, even for an
//! enumeration with `{attribute 'strict'}` (that attribute refuses arithmetic and assignments,
//! not comparisons). It assigns an integer to an enumeration without `'strict'`; TwinCAT gives
//! every new enumeration `'strict'`, so plcd keeps refusing an integer to a user's enumeration
//! and accepts it for the type class alone, the system's enumeration that library code fills
//! from numbers. Both are habits, which `[st] strict` refuses.

use super::ctx::Ctx;
use super::expr::TExpr;
use super::types::Ty;
use crate::st::ast::BinaryOp;
use crate::st::dialect::Habit;

impl Ctx<'_> {
    /// The operands of a comparison, an enumeration's value met by an integer (not a literal,
    /// which takes the enumeration's type as before) turned to its number, of its base type.
    pub(super) fn enum_compared_with_integer(
        &mut self,
        op: BinaryOp,
        a: TExpr,
        b: TExpr,
        file: usize,
    ) -> (TExpr, TExpr) {
        use BinaryOp::*;
        if !matches!(op, Eq | Ne | Lt | Le | Gt | Ge) {
            return (a, b);
        }
        let a = self.enum_number_against(a, &b.ty, file);
        let b = self.enum_number_against(b, &a.ty, file);
        (a, b)
    }

    /// `te` as its enumeration's number when `other` is a plain integer or bit string.
    fn enum_number_against(&mut self, te: TExpr, other: &Ty, file: usize) -> TExpr {
        let Ty::Enum(e) = te.ty else { return te };
        if matches!(other, Ty::Enum(_)) || !other.prim(&self.types).is_some_and(|p| p.is_integral())
        {
            return te;
        }
        self.habit(Habit::EnumToInteger, file, te.span);
        TExpr { ty: Ty::Prim(self.types.enums[e].base), ..te }
    }

    /// An integer or bit string given where the type class is wanted: its number, converted
    /// to the enumeration's base type as an assignment would (a lossy pair warns). `None` when
    /// `to` is not the type class or `te` no integer.
    pub(super) fn integer_as_type_class(
        &mut self,
        te: &TExpr,
        to: &Ty,
        file: usize,
    ) -> Option<TExpr> {
        let Ty::Enum(e) = to else { return None };
        if !self.types.enums[*e].name.eq_ignore_ascii_case(super::generic::TYPE_CLASS) {
            return None;
        }
        if matches!(te.ty, Ty::Enum(_) | Ty::IntLit)
            || !te.ty.prim(&self.types).is_some_and(|p| p.is_integral())
        {
            return None;
        }
        self.habit(Habit::IntegerToTypeClass, file, te.span);
        let base = Ty::Prim(self.types.enums[*e].base);
        let number = self.coerce(te.clone(), &base, file);
        Some(TExpr { ty: to.clone(), ..number })
    }
}
