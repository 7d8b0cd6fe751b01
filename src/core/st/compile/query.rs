//! `__QUERYINTERFACE(itfSource, itfDest)` and `__QUERYPOINTER(itfSource, pDest)` (CODESYS,
//! TwinCAT): what an interface value holds, asked at run time.
//!
//! - `__QUERYINTERFACE` is TRUE when the instance behind `itfSource` implements the interface
//!   of `itfDest` (its block's type tag is one of the tags of the blocks implementing it,
//!   compile/oop.rs): `itfDest` then holds that instance; otherwise (a block that does not
//!   implement it, or `itfSource` NULL) FALSE, and `itfDest` is NULL.
//! - `__QUERYPOINTER` is TRUE when `itfSource` is not NULL: `pDest` (a `POINTER TO` or `REF_TO`) then
//!   points to the instance; otherwise FALSE, and `pDest` is NULL. As in CODESYS, the pointer's
//!   type is the caller's business.
//!
//! Both compile to existing ops ([`Std::QueryInterface`], [`Std::QueryPointer`] in
//! compile/emit.rs): a comparison of the instance's tag with each candidate's, as a dispatch.

use crate::st::ast::{Arg, Ident, PouKind, RefKind, Span};

use super::ctx::{Ctx, Scope};
use super::expr::{Access, TExpr, TK};
use super::stdlib::Std;
use super::types::{Prim, Ty};

impl Ctx<'_> {
    /// `__QUERYINTERFACE(…)` or `__QUERYPOINTER(…)`; `None` for any other name.
    pub(super) fn query_call(
        &mut self,
        id: &Ident,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<TExpr> {
        let upper = id.name.to_ascii_uppercase();
        let is_interface = match upper.as_str() {
            "__QUERYINTERFACE" => true,
            "__QUERYPOINTER" => false,
            _ => return None,
        };
        let file = scope.file;
        let [Arg::Positional(source), Arg::Positional(dest)] = args else {
            self.error(file, span, format!("`{upper}` takes two arguments, by position"));
            return Some(TExpr::error(span));
        };
        let source_span = source.span;
        let source = self.check_expr(source, scope, None);
        let dest_span = dest.span;
        let dest = self.check_place(dest, scope, Access::Write, None);
        if source.ty.is_error() || dest.ty.is_error() {
            return Some(TExpr::error(span));
        }
        if !matches!(source.ty, Ty::Iface(_)) {
            let n = self.ty_name(&source.ty);
            self.error(file, source_span, format!("`{upper}` asks an interface value, not `{n}`"));
            return Some(TExpr::error(span));
        }
        let op = match (&dest.ty, is_interface) {
            (Ty::Iface(i), true) => Std::QueryInterface(*i),
            (Ty::Ref(RefKind::Pointer | RefKind::RefTo, _), false) => Std::QueryPointer,
            (other, _) => {
                let n = self.ty_name(other);
                let msg = if is_interface {
                    format!("`{upper}` writes its answer to an interface variable, not `{n}`")
                } else {
                    format!(
                        "`{upper}` writes its answer to a POINTER TO or REF_TO variable, not `{n}`"
                    )
                };
                self.error(file, dest_span, msg);
                return Some(TExpr::error(span));
            }
        };
        let ty = Ty::Prim(Prim::Bool);
        Some(TExpr { k: TK::Std(op, vec![source, dest]), ty, span })
    }

    /// The type tags of the blocks whose instances an interface value of `itf` may hold.
    pub(super) fn implementing_tags(&self, itf: usize) -> Vec<u32> {
        (0..self.pous.len())
            .filter(|&d| self.pous[d].kind == PouKind::FunctionBlock && self.implements(d, itf))
            .filter(|&d| !self.pous[d].ast.oop.is_abstract)
            .filter_map(|d| self.oop.tags.get(&d).copied())
            .collect()
    }
}
