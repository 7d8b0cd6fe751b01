//! CODESYS's assignment as an expression (`a := b := FALSE;`, `IF (i := i + 1) >= 3 THEN`;
//! the parser reads it, `syntax::parse::assign_expr`): the target is written and the value
//! assigned, converted to the target's type, is the expression's value.
//!
//! It is checked and compiled where it stands, as a [`TK::Assign`] node, rather than lowered
//! into statements before the one using it: a condition of `WHILE`, `REPEAT` or `ELSIF`, or an
//! operand after `AND_THEN`, is evaluated again, or not at all, so hoisting it would change
//! when and how often the target is written; evaluated in its expression it runs exactly where
//! CODESYS runs it, once per evaluation. The code is made of the ops a statement's store
//! already uses (the value kept in a temporary of the frame, stored, then read again), so
//! native code compiles it as it does any assignment, and the statement stays one step for
//! DEBUG stepping and breakpoints at its line.
//!
//! The target is checked as a statement's (`Access::Write`): CONSTANT, an input or output it
//! may not write, the FOR variable (CODESYS's habit, `for_written`) all apply. Only an
//! elementary value is taken: a STRING, an array, a struct or an instance is assigned in a
//! statement of its own.

use super::ctx::{Ctx, Scope};
use super::expr::{expr_text, Access, TExpr, TK};
use super::types::Ty;
use crate::st::ast::{Expr, Span};

impl Ctx<'_> {
    /// `target := value` inside an expression, written at `span`.
    pub(super) fn check_assign_expr(
        &mut self,
        target: &Expr,
        value: &Expr,
        span: Span,
        scope: Scope,
    ) -> TExpr {
        let file = scope.file;
        let t = self.check_place(target, scope, Access::Write, None);
        let v = self.check_given(value, scope, &t.ty);
        if t.ty.is_error() || v.ty.is_error() {
            return TExpr::error(span);
        }
        if t.ty.is_aggregate() {
            let n = self.ty_name(&t.ty);
            self.error(
                file,
                target.span,
                format!("an assignment inside an expression takes an elementary value, not `{n}`: assign it in a statement of its own"),
            );
            return TExpr::error(span);
        }
        if v.ty == Ty::Void {
            self.error(file, value.span, format!("`{}` has no result", expr_text(value)));
            return TExpr::error(span);
        }
        let v = self.coerce(v, &t.ty, file);
        if v.ty.is_error() {
            return TExpr::error(span);
        }
        let ty = t.ty.clone();
        TExpr { k: TK::Assign(Box::new(t), Box::new(v)), ty, span }
    }
}
