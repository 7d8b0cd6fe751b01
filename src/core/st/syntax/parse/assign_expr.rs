//! CODESYS's assignment as an expression: `a := b := FALSE;` (OSCAT BUILDING's BOILER) and
//! `IF (i := M_Find(x)) >= 0 THEN` (Tc3_Component). IEC 61131-3 has `:=` only as a statement.
//!
//! Read where the standard gives `:=` no other meaning: the right side of an assignment (so
//! `a := b := c` chains, right-associative), a whole condition of `IF`, `ELSIF`, `WHILE` or
//! `UNTIL` (`IF b := (i = 1) THEN`, the example of CODESYS's and TwinCAT's documentation of
//! the form), and the inside of parentheses. Anywhere else inside an expression it needs
//! them: `x + (i := 1)`. A call's `(name := value` is a named argument as before (`args`
//! reads it first); `((name := value))` is an assignment given by position.

use super::super::lex::{Kw, P};
use super::{PResult, Parser};
use crate::st::ast::{Expr, ExprKind};
use crate::st::dialect::Habit;

impl Parser<'_> {
    /// The value of an assignment: an expression, or another assignment (`b := c` of
    /// `a := b := c`).
    pub(super) fn assigned_value(&mut self) -> PResult<Expr> {
        let value = self.expr()?;
        self.assignment_after(value)
    }

    /// `expr` itself, or, at a `:=`, the assignment to it of what follows.
    pub(super) fn assignment_after(&mut self, target: Expr) -> PResult<Expr> {
        if !self.at_p(P::Assign) {
            return Ok(target);
        }
        self.habit(Habit::AssignExpr);
        self.bump();
        self.enter()?;
        let value = self.assigned_value();
        self.depth -= 1;
        let span = target.span;
        Ok(Expr { kind: ExprKind::Assign(Box::new(target), Box::new(value?)), span })
    }

    /// A condition of `IF`, `ELSIF`, `WHILE` or `UNTIL`, up to one of `stops`: an expression,
    /// or an assignment whose value is tested (`IF b := (i = 1) THEN`). After an error, as
    /// [`Parser::expr_until`].
    pub(super) fn condition_until(&mut self, stops: &[Kw]) -> Expr {
        let target = self.expr_until(stops);
        if !self.at_p(P::Assign) || self.enter().is_err() {
            return target;
        }
        self.habit(Habit::AssignExpr);
        self.bump();
        let value = self.condition_until(stops);
        self.depth -= 1;
        let span = target.span;
        Expr { kind: ExprKind::Assign(Box::new(target), Box::new(value)), span }
    }
}
