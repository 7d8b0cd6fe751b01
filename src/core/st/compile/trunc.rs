//! `TRUNC` typed by its use. IEC 61131-3 gives `TRUNC` any integer type (`ANY_REAL` →
//! `ANY_INT`), and matiec the one its use asks: the OpenPLC port of OSCAT writes
//! `INT_TO_WORD(TRUNC(r))`, `UDINT_TO_INT(TRUNC(a * 2.8))`, `i := TRUNC(r) + low` with `INT`s
//! `i` and `low`. CODESYS's `TRUNC` is a `DINT`, and code written for it relies on that: a
//! `DINT` stays its type wherever a `DINT` is accepted (`d := i * TRUNC(r)` multiplies in
//! `DINT`).
//!
//! So `TRUNC(x)` is checked as a `DINT`, marked ([`Ctx::any_int_trunc`]), and where that `DINT`
//! is given to an integer type it does not convert to implicitly (`SINT`, `INT`, `USINT`,
//! `UINT`, `UDINT`, `ULINT`), it becomes `TRUNC_<T>` of that type, saturated at its range as
//! `TRUNC_<T>` is; so does an arithmetic of such TRUNCs with values of that type
//! (`TRUNC(r) + low`, computed in `INT`) ([`Ctx::trunc_by_use`]). A `TRUNC` of a constant is
//! folded to a `DINT` constant and stays one.

use crate::value::{BinOp, UnOp};

use super::ctx::{Ctx, Cv};
use super::expr::{TExpr, TK};
use super::types::{fits, Prim, Ty};

/// Whether `e` is a `TRUNC` whose type its use may choose: the `DINT` node converted to itself,
/// the mark [`Ctx::any_int_trunc`] gives.
fn is_any_int_trunc(e: &TExpr) -> Option<&TExpr> {
    match &e.k {
        TK::Conv(inner) if e.ty == Ty::Prim(Prim::DInt) && inner.ty == e.ty => {
            matches!(&inner.k, TK::Conv(t) if matches!(t.k, TK::Un(UnOp::Trunc, _)))
                .then_some(&**inner)
        }
        _ => None,
    }
}

impl<'a> Ctx<'a> {
    /// `TRUNC(x)`: `trunc`, the `DINT` of `x` toward zero, marked as the `TRUNC` whose type its
    /// use may change ([`Ctx::trunc_by_use`]) by a conversion to itself, which generates no
    /// code. A constant is left as it is.
    pub(super) fn any_int_trunc(&self, trunc: TExpr) -> TExpr {
        if trunc.is_const() || trunc.ty.is_error() {
            return trunc;
        }
        let (ty, span) = (trunc.ty.clone(), trunc.span);
        TExpr { k: TK::Conv(Box::new(trunc)), ty, span }
    }

    /// `te` given to a value of type `to`: when `te` is a marked `TRUNC`, or an arithmetic of
    /// such TRUNCs and values of `to`'s integer type, and `to` is an integer type a `DINT` does
    /// not convert to implicitly, the same computed in that type; else `te` as it is.
    pub(super) fn trunc_by_use(&mut self, te: TExpr, to: &Ty) -> TExpr {
        if te.ty != Ty::Prim(Prim::DInt) || matches!(to, Ty::Enum(_)) {
            return te;
        }
        let Some(p) = to.prim(&self.types) else { return te };
        if !p.is_int() || matches!(p, Prim::DInt | Prim::LInt) {
            return te;
        }
        match self.retyped(&te, p) {
            Some((t, true)) => t,
            _ => te,
        }
    }

    /// `e` (a `DINT`) computed in `p`, and whether it holds a marked `TRUNC`; `None` when some
    /// part of it is not a marked TRUNC, a value of `p` widened, a constant that fits `p`, or
    /// `+ - * / MOD` or a negation of those.
    fn retyped(&mut self, e: &TExpr, p: Prim) -> Option<(TExpr, bool)> {
        let ty = Ty::Prim(p);
        if let Some(dint) = is_any_int_trunc(e) {
            let TK::Conv(trunc) = &dint.k else { return None };
            return Some((self.conv((**trunc).clone(), p, ty), true));
        }
        match &e.k {
            TK::Conv(inner) if !matches!(inner.ty, Ty::Enum(_)) => {
                (inner.ty.prim(&self.types) == Some(p)).then(|| ((**inner).clone(), false))
            }
            TK::Const(Cv::Int(v)) => {
                fits(p, *v).then(|| (TExpr::konst(Cv::Int(*v), ty, e.span), false))
            }
            TK::Bin(
                op @ (BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div | BinOp::Mod),
                a,
                b,
            ) => {
                let (a, ta) = self.retyped(a, p)?;
                let (b, tb) = self.retyped(b, p)?;
                let k = TK::Bin(*op, Box::new(a), Box::new(b));
                Some((TExpr { k, ty, span: e.span }, ta || tb))
            }
            TK::Un(UnOp::Neg, a) => {
                let (a, t) = self.retyped(a, p)?;
                Some((TExpr { k: TK::Un(UnOp::Neg, Box::new(a)), ty, span: e.span }, t))
            }
            _ => None,
        }
    }
}
