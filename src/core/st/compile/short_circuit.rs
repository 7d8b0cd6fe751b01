//! CODESYS's short-circuit operators `AND_THEN` and `OR_ELSE` (docs/ST.md, "Short-circuit
//! operators"): `AND` and `OR` on `BOOL` whose right operand is evaluated only when the left one
//! does not decide the result, so that `p <> 0 AND_THEN p^ > 0` never reads through a NULL `p`.
//!
//! Checking makes a [`TK::ShortCircuit`] node; the code generator compiles it to a conditional
//! jump over the right operand, with the deciding value pushed instead (no new op: the
//! interpreter and native code run it as any `IF`).

use crate::st::ast::{BinaryOp, Span};
use crate::st::dialect::Habit;

use super::ctx::{Ctx, Cv};
use super::expr::{op_text, TExpr, TK};
use super::types::{Prim, Ty};

impl<'a> Ctx<'a> {
    /// `a AND_THEN b` or `a OR_ELSE b`, both operands `BOOL`.
    pub(super) fn short_circuit(
        &mut self,
        op: BinaryOp,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        self.habit(Habit::ShortCircuit(op_text(op)), file, span);
        // The left operand's value that decides the result alone: FALSE for AND_THEN (the
        // result is FALSE), TRUE for OR_ELSE (the result is TRUE).
        let decides_on = op == BinaryOp::OrElse;
        let boolean = Ty::Prim(Prim::Bool);
        let operand = |s: &mut Self, e: TExpr| {
            if e.ty.is_error() {
                return None;
            }
            if e.ty != boolean {
                let name = s.ty_name(&e.ty);
                let what = op_text(op);
                s.error(file, e.span, format!("`{what}` needs `BOOL` operands, not `{name}`"));
                return None;
            }
            Some(e)
        };
        let (Some(a), Some(b)) = (operand(self, a), operand(self, b)) else {
            return TExpr::error(span);
        };
        // A constant left operand decides now: the right one is either the result or never runs.
        if let TK::Const(Cv::Int(v)) = a.k {
            return if (v != 0) == decides_on {
                TExpr::konst(Cv::Int(i128::from(decides_on)), boolean, span)
            } else {
                TExpr { span, ..b }
            };
        }
        TExpr { k: TK::ShortCircuit(decides_on, Box::new(a), Box::new(b)), ty: boolean, span }
    }
}
