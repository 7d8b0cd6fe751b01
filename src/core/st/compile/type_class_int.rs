//! An integer given where CODESYS's type class (`__SYSTEM.TYPE_CLASS`,
//! `IBaseLibrary.TypeClass`) is wanted, as TcUnit writes it (`ReportResult(ExpectedTypeClass :=
//! UDINT_TO_INT(Expected.TypeClass), …)` in its FB_AssertResultStatic,
//! github.com/tcunit/TcUnit). An enumeration's value beside an integer (TcUnit's
//! `UDINT_TO_INT(Expected.TypeClass) = IBaseLibrary.TypeClass.TYPE_STRING`) is `unify`'s, as
//! the number `implicit::enum_as_integer` gives.
//!
//! CODESYS assigns an integer to an enumeration without `{attribute 'strict'}`; TwinCAT gives
//! every new enumeration `'strict'`, so plcd keeps refusing an integer to a user's enumeration
//! and accepts it for the type class alone, the system's enumeration that library code fills
//! from numbers. A habit, which `[st] strict` refuses.

use super::ctx::Ctx;
use super::expr::TExpr;
use super::types::Ty;
use crate::st::dialect::Habit;

impl Ctx<'_> {
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
