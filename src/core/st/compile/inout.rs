//! An FB instance's VAR_IN_OUT named outside its body (`inst.io`), as matiec accepts and the
//! OpenPLC port of OSCAT relies on (`rmp(rmp := out); out := rmp.rmp;`), and an FB call that
//! leaves a VAR_IN_OUT out (`sorter();` after `sorter(pt := a);`): both habits (docs/ST.md,
//! "CODESYS and TwinCAT habits").
//!
//! matiec copies a function block's VAR_IN_OUT into the instance before the call and back
//! after it; plcd passes it by reference, as CODESYS does: the instance holds a pointer to the
//! variable the last call bound. So, outside the body:
//! - `inst.io` is that variable, reached through the pointer as through a `REFERENCE TO`
//!   ([`Ctx::in_out_bound_variable`]): the value matiec's copy holds after the call, checked at run
//!   time like any access through a reference;
//! - `inst.io := v` binds `io` to the variable `v`, as the call's `io := v` would, without the
//!   call ([`Ctx::in_out_binding`]). It is matiec's way of giving an input before a call that
//!   leaves it out (`_ARRAY_MEDIAN`: `s.pt := pt; s(); pt := s.pt;`), which then works on `pt`
//!   itself where matiec works on a copy and copies it back: the same values;
//! - a call that leaves `io` out keeps its binding ([`Ctx::rebind_omitted`]).
//!
//! An instance's VAR_IN_OUT starts [`UNBOUND`]: named from outside before any binding, it is a
//! `NULL` reference (operation error 2822H, the value 0); the body of a call that leaves it out
//! before any binding reads 0 from it and writes nothing.
//!
//! Everything is made of nodes the code generator already has (a member, `+`, a dereference),
//! so native code needs nothing of its own.

use std::rc::Rc;

use crate::st::ast::{Expr, ExprKind, Ident, RefKind, Span, VarKind};
use crate::st::dialect::Habit;
use crate::value::{BinOp, REF_TAG};

use super::ctx::{Ctx, Cv, Scope, Storage, VarInfo};
use super::expr::{expr_text, Access, ArgT, CallT, TExpr, TK};
use super::stmt::TS;
use super::types::{Prim, Ty};

/// What an instance's VAR_IN_OUT holds before anything binds it: the pointer whose reference
/// value (the pointer plus [`REF_TAG`], `Op::Deref`) wraps to 0, `NULL`; as a pointer itself it
/// names no memory area, so that the body's loads through it give 0 and its stores do nothing.
pub(super) const UNBOUND: u64 = REF_TAG.wrapping_neg();

impl<'a> Ctx<'a> {
    /// `inst.io` for the VAR_IN_OUT `v` of `inst`'s function block `fb`, at `off` in the
    /// instance (`base` is `inst` as written): the bound variable (its function block's own
    /// body included, `THIS^.io`). An `ARRAY [*]` is refused, and so is a write from outside
    /// other than a binding.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn instance_in_out(
        &mut self,
        inst: TExpr,
        base: &Expr,
        v: &VarInfo,
        off: u32,
        id: &Ident,
        access: Access,
        own: bool,
        fb: &str,
        file: usize,
        span: Span,
    ) -> TExpr {
        if let Ty::OpenArray(_) = v.ty {
            self.error(
                file,
                id.span,
                format!(
                    "`{}` is an `ARRAY [*]` VAR_IN_OUT of `{fb}`: it cannot be named outside the block's body",
                    id.name
                ),
            );
            return TExpr::error(span);
        }
        if !own {
            if access == Access::Write {
                self.error(
                    file,
                    id.span,
                        format!(
                        "`{io}` is a VAR_IN_OUT of `{fb}`: from outside it is not written, only bound to a variable `v` by `{inst}.{io} := v`, as by `{inst}({io} := v)`",
                        inst = expr_text(base),
                        io = id.name
                    ),
                );
                return TExpr::error(span);
            }
            self.habit(Habit::InOutThroughInstance, file, id.span);
        }
        Self::in_out_bound_variable(inst, off, v.ty.clone(), span)
    }

    /// The variable the pointer at `off` in `inst` points to, as a `REFERENCE TO ty` whose value
    /// is the pointer plus [`REF_TAG`]: reading or writing it is checked as through a
    /// reference (2822H while [`UNBOUND`]).
    fn in_out_bound_variable(inst: TExpr, off: u32, ty: Ty, span: Span) -> TExpr {
        let pointer = Self::slot(inst, off, span);
        let tag = TExpr::konst(Cv::Int(i128::from(REF_TAG)), Ty::Prim(Prim::ULInt), span);
        let reference = TExpr {
            k: TK::Bin(BinOp::Add, Box::new(pointer), Box::new(tag)),
            ty: Ty::Ref(RefKind::Reference, Rc::new(ty.clone())),
            span,
        };
        TExpr { k: TK::Deref(Box::new(reference)), ty, span }
    }

    /// The pointer a VAR_IN_OUT at `off` of `inst` holds, as a `ULINT` place.
    fn slot(inst: TExpr, off: u32, span: Span) -> TExpr {
        TExpr { k: TK::Member(Box::new(inst), off, false), ty: Ty::Prim(Prim::ULInt), span }
    }

    /// `inst.io := v` with `io` a VAR_IN_OUT of `inst`'s function block: `io` bound to the
    /// variable `v`, as `inst(io := v)` would bind it. `None` when `target` names no such
    /// VAR_IN_OUT (or names the function block's own: `THIS^.io := v` writes the variable);
    /// `Some(None)` after an error.
    pub(super) fn in_out_binding(
        &mut self,
        target: &Expr,
        value: &Expr,
        scope: Scope,
    ) -> Option<Option<TS>> {
        let file = scope.file;
        let ExprKind::Member(base, id) = &target.kind else { return None };
        if super::oop::is_own_instance(base) {
            return None;
        }
        let saved = self.diags.len();
        let probe = self.check_place(base, scope, Access::Read, None);
        self.diags.truncate(saved);
        let Ty::Fb(p) = probe.ty else { return None };
        let v = self.pous[p].lookup(&id.name).map(|i| self.pous[p].vars[i].clone())?;
        let (VarKind::InOut, Storage::Inst(off)) = (v.kind, v.storage) else { return None };
        let fb = self.pous[p].name.clone();
        self.habit(Habit::InOutThroughInstance, file, id.span);
        if let Ty::OpenArray(_) = v.ty {
            self.error(
                file,
                id.span,
                format!(
                    "`{}` is an `ARRAY [*]` VAR_IN_OUT of `{fb}`: only a call binds it",
                    id.name
                ),
            );
            return Some(None);
        }
        if matches!(value.kind, ExprKind::Literal(_) | ExprKind::Unary(..) | ExprKind::Binary(..)) {
            self.error(
                file,
                value.span,
                format!(
                    "`{inst}.{io} := v` binds VAR_IN_OUT `{io}` of `{fb}` to the variable `v`, as `{inst}({io} := v)` does: `v` cannot be a value",
                    inst = expr_text(base),
                    io = id.name
                ),
            );
            return Some(None);
        }
        let inst = self.check_place(base, scope, Access::Ref, None);
        let bound = self.check_place(value, scope, Access::Ref, None);
        if inst.ty.is_error() || bound.ty.is_error() || v.ty.is_error() {
            return Some(None);
        }
        if !self.in_out_argument(&v, &bound, &fb, value.span, file) {
            return Some(None);
        }
        // the pointer itself: the reference value `REF(v)` less its tag
        let ulint = Ty::Prim(Prim::ULInt);
        let span = value.span;
        let reference = TExpr { k: TK::Ref(Box::new(bound)), ty: ulint.clone(), span };
        let tag = TExpr::konst(Cv::Int(i128::from(REF_TAG)), ulint.clone(), span);
        let pointer =
            TExpr { k: TK::Bin(BinOp::Sub, Box::new(reference), Box::new(tag)), ty: ulint, span };
        Some(Some(TS::Assign(Self::slot(inst, off, target.span), pointer)))
    }

    /// Whether the place `t` may be bound to the VAR_IN_OUT `v` of `callee` (a call's argument,
    /// or `inst.io := t`): a variable, not an array or structure at device words, of `v`'s type
    /// (any STRING for a STRING, a derived function block for its base; an `ARRAY [*]` is
    /// checked by `varlen`). Reports why not.
    pub(super) fn in_out_argument(
        &mut self,
        v: &VarInfo,
        t: &TExpr,
        callee: &str,
        span: Span,
        file: usize,
    ) -> bool {
        if !t.is_place() {
            self.error(
                file,
                span,
                format!("VAR_IN_OUT `{}` of `{callee}` needs a variable", v.name),
            );
            return false;
        }
        if matches!(v.ty, Ty::Array(_) | Ty::Struct(_)) && super::expr::at_device_words(t) {
            // The callee steps through its VAR_IN_OUT in bytes; a device's words are counted
            // in words, so it would read every other one.
            self.error(
                file,
                span,
                format!(
                    "VAR_IN_OUT `{}` of `{callee}`: an array or structure located at a device word cannot be passed by reference: copy it into a variable first",
                    v.name
                ),
            );
            return false;
        }
        if let Ty::OpenArray(_) = v.ty {
            return true;
        }
        let derived = matches!((&t.ty, &v.ty), (Ty::Fb(d), Ty::Fb(b)) if self.derives_from(*d, *b));
        let strings =
            matches!((&t.ty, &v.ty), (Ty::Str(_), Ty::Str(_)) | (Ty::WStr(_), Ty::WStr(_)));
        if t.ty != v.ty && !derived && !strings {
            let (a, b) = (self.ty_name(&v.ty), self.ty_name(&t.ty));
            self.error(
                file,
                span,
                format!("VAR_IN_OUT `{}` of `{callee}` needs a `{a}` variable, not `{b}`", v.name),
            );
            return false;
        }
        true
    }

    /// The VAR_IN_OUTs a call of `inst` leaves out (a habit, allowed by `bind_args` for a
    /// function block's): each bound again to what it is bound to, which checks that something
    /// is (2822H before any binding). Not when finding `inst` calls a function, which this
    /// would call twice: its body then reads 0 from an unbound one.
    pub(super) fn rebind_omitted(&mut self, inst: &TExpr, p: usize, call: &mut CallT) {
        if inst.has_call() {
            return;
        }
        let omitted: Vec<(u32, Ty)> = self.pous[p]
            .vars
            .iter()
            .filter_map(|v| match (v.kind, v.storage, &v.ty) {
                (VarKind::InOut, _, Ty::OpenArray(_)) => None,
                (VarKind::InOut, Storage::Inst(off), ty)
                    if !call.args.iter().any(|a| a.by_ref && a.offset == off) =>
                {
                    Some((off, ty.clone()))
                }
                _ => None,
            })
            .collect();
        for (off, ty) in omitted {
            let value = Self::in_out_bound_variable(inst.clone(), off, ty.clone(), inst.span);
            call.args.push(ArgT { offset: off, ty, by_ref: true, value });
        }
    }
}
