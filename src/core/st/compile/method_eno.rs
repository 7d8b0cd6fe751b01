//! The implicit `ENO` of a METHOD (CODESYS calls a method as a function: `fb.M(EN := c, x := 1,
//! ENO => ok)`).
//!
//! `EN` needs nothing of its own: a method is called as a FUNCTION is (`bind_args`, `call_fn`),
//! so an implicit `EN := c` FALSE already skips the call. `ENO` is a BOOL output of the method's
//! frame, TRUE from its frame image at each call (as a FUNCTION's), which its body may set FALSE.
//! A method has it when something may read it: the project reads an ENO somewhere, or its body
//! names ENO (the same rule as a FUNCTION's, `decl`).
//!
//! Its place: right after the method's parameters, before its locals. A call that dispatches
//! reads the outputs at the offsets of the method the place is declared with; the parameters of
//! an override are at the same offsets (`decl` sorts them first), so ENO placed after them is
//! too, whatever locals each override declares.

use crate::st::ast::{self, VarKind};

use super::ctx::{Ctx, Storage, VarInfo};
use super::oop::Role;
use super::types::{Prim, Ty};

/// Whether a variable block holds a method's parameters (which come first in its frame).
pub(super) fn is_parameter_block(kind: VarKind) -> bool {
    matches!(kind, VarKind::Input | VarKind::InOut | VarKind::Output)
}

/// Whether POU `pou` declares a variable `name` itself.
fn declares(pou: &ast::Pou, name: &str) -> bool {
    pou.vars.iter().flat_map(|b| &b.decls).flat_map(|d| &d.names).any(|id| id.is(name))
}

impl Ctx<'_> {
    /// Whether method `pou` (member role `role`) gets an implicit ENO: a method (not a
    /// property's accessor) that declares none, when the project or its body may read it.
    pub(super) fn wants_method_eno(&self, role: Option<Role>, pou: &ast::Pou) -> bool {
        role == Some(Role::Method)
            && !declares(pou, "ENO")
            && (self.eno_read || super::decl::mentions_eno(&pou.body))
    }

    /// Declares the implicit ENO of method `p` at the end of `frame`: a BOOL output whose
    /// image is TRUE, so that each call starts with ENO TRUE. An interface's method is the
    /// body a call through a `NULL` interface runs (operation error 2822H, no method ran): its
    /// ENO is FALSE.
    pub(super) fn declare_method_eno(&mut self, p: usize, frame: &mut Vec<u8>, span: ast::Span) {
        let of_interface = self.oop.members.get(&p).is_some_and(|m| m.owner.is_none());
        frame.push(u8::from(!of_interface));
        self.declare_implicit_eno(p, Storage::Frame(frame.len() as u32 - 1), span);
    }

    /// Declares POU `p`'s implicit ENO, a BOOL output at `storage` (its image set by the
    /// caller): a FUNCTION's or a FUNCTION_BLOCK's (decl.rs) or a method's.
    pub(super) fn declare_implicit_eno(&mut self, p: usize, storage: Storage, span: ast::Span) {
        let index = self.pous[p].vars.len();
        self.pous[p].vars.push(VarInfo {
            name: "ENO".into(),
            kind: VarKind::Output,
            ty: Ty::Prim(Prim::Bool),
            constant: false,
            retain: false,
            persistent: false,
            storage,
            by_ref: false,
            value: None,
            span,
            located: None,
            global: None,
            edge_value: None,
        });
        self.pous[p].names.insert("eno".to_string(), index);
        self.pous[p].eno = Some(index);
        self.pous[p].eno_implicit = true;
    }
}
