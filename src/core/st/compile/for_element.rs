//! TwinCAT's FOR loop counting in an array element or a struct member (`FOR Offset[1] := 0
//! TO …`, as TcUnit's FB_TestSuite counts): IEC 61131-3 counts in a variable named alone.
//!
//! The parser notes the form as a [`crate::st::dialect::Habit::ForElement`]. The checker
//! takes it where the place is fixed for the whole loop: members, and elements whose indices
//! are constants, of a local variable. Such a place is known when the code is generated, so
//! the loop is compiled as one on a variable (`emit::for_loop`), and the question of when the
//! place is evaluated does not arise. An element whose index is a variable is refused: the
//! body could change the index, and CODESYS's documentation does not say whether the loop
//! then counts in the new element.

use super::ctx::{Ctx, Storage};
use super::expr::{expr_text, TExpr, TK};
use super::types::Ty;
use crate::st::ast::{self, ExprKind, Ident};

/// The variable a FOR loop's control variable is, or is an element or member of; `None` when
/// it is reached through a dereference or a call.
pub(super) fn control_root(var: &ast::Expr) -> Option<&Ident> {
    match &var.kind {
        ExprKind::Name(id) => Some(id),
        ExprKind::Member(base, _) | ExprKind::Index(base, _) => control_root(base),
        _ => None,
    }
}

/// Where a checked place is: at an address known before the loop runs (a variable of the
/// POU's own memory, its members, and its elements at constant indices), or not.
#[derive(PartialEq)]
enum Place {
    Fixed,
    /// At an index the body could change, or reached through a reference.
    Moving,
    /// At a constant index out of its array's bounds (an error the checker reported).
    OutOfBounds,
}

fn place(e: &TExpr) -> Place {
    match &e.k {
        TK::Var { storage: Storage::Inst(_) | Storage::Frame(_) | Storage::Global(_), by_ref } => {
            if *by_ref {
                Place::Moving
            } else {
                Place::Fixed
            }
        }
        TK::Member(base, _, false) => place(base),
        TK::Index(base, index) => {
            let Ty::Array(array) = &base.ty else { return Place::Moving };
            let mut at = place(base);
            for (i, &(lo, hi)) in index.iter().zip(&array.dims) {
                match i.const_int() {
                    None => return Place::Moving,
                    Some(v) if v < i128::from(lo) || v > i128::from(hi) => {
                        at = Place::OutOfBounds;
                    }
                    Some(_) => {}
                }
            }
            at
        }
        _ => Place::Moving,
    }
}

impl Ctx<'_> {
    /// Checks that an element or member counted in (`var`, checked as `place`) is fixed for
    /// the loop; reports why not.
    pub(super) fn for_element_fixed(
        &mut self,
        var: &ast::Expr,
        checked: &TExpr,
        file: usize,
    ) -> bool {
        match place(checked) {
            Place::Fixed => true,
            Place::OutOfBounds => false,
            Place::Moving => {
                self.error(
                    file,
                    var.span,
                    format!(
                        "the FOR variable `{}` must be a variable, or its member or element at constant indices",
                        expr_text(var)
                    ),
                );
                false
            }
        }
    }
}
