//! References and pointers: `REF_TO T`, `POINTER TO T`, `REFERENCE TO T`, `REF(v)`,
//! `ADR(v)`, `NULL`, `r^`, `r REF= v`, `__ISVALIDREF(r)`, pointer arithmetic and the
//! comparisons of references, checked into the typed tree.
//!
//! A reference value is never a host address: it is the VM pointer of the place it refers
//! to, tagged so that 0 is `NULL` (the encoding is `Op::Deref`'s). Every access through one
//! goes through `Op::Deref`, which checks it at run time, so a reference can only ever reach
//! plcd's own variable, frame or device memory. Integers never convert to references (a
//! reference cannot be forged): the only ways to make one are `REF`, `ADR`, `REF=`, `NULL`
//! (and the constant 0 for a `POINTER TO`, as CODESYS writes it) and arithmetic on a pointer,
//! which keeps it in the memory area it points into.

use crate::lang::ops::CmpOp;
use crate::st::ast::{Arg, BinaryOp, Expr, ExprKind, Ident, RefKind, Span};
use crate::st::dialect::Habit;
use crate::value::{BinOp, UnOp};

use super::ctx::{Ctx, Cv, Scope};
use super::expr::{op_text, Access, TExpr, TK};
use super::types::{Prim, Ty};

impl<'a> Ctx<'a> {
    /// `r^`: what a `REF_TO` or `POINTER TO` refers to (a place).
    pub fn deref(&mut self, base: TExpr, span: Span, text: &str, file: usize) -> TExpr {
        match base.ty.clone() {
            Ty::Error => TExpr::error(span),
            Ty::Ref(RefKind::RefTo | RefKind::Pointer, to) => {
                TExpr { k: TK::Deref(Box::new(base)), ty: (*to).clone(), span }
            }
            other => {
                let n = self.ty_name(&other);
                self.error(
                    file,
                    span,
                    format!(
                        "`{text}` is `{n}`, not a `REF_TO` or `POINTER TO`: `^` cannot be applied"
                    ),
                );
                TExpr::error(span)
            }
        }
    }

    /// A `REFERENCE TO` variable as it is used: what it refers to.
    pub fn auto_deref(&self, te: TExpr) -> TExpr {
        match te.ty.clone() {
            Ty::Ref(RefKind::Reference, to) => {
                let span = te.span;
                TExpr { k: TK::Deref(Box::new(te)), ty: (*to).clone(), span }
            }
            _ => te,
        }
    }

    /// A reference of `kind` to the place `v`; `REF(p^)` is `p` itself.
    fn reference_to(&self, v: TExpr, kind: RefKind) -> TExpr {
        let ty = Ty::Ref(kind, std::rc::Rc::new(v.ty.clone()));
        let span = v.span;
        match v.k {
            TK::Deref(inner) => TExpr { ty, ..*inner },
            _ => TExpr { k: TK::Ref(Box::new(v)), ty, span },
        }
    }

    /// The variable `e` names, for `REF`, `ADR` and `REF=`.
    fn referenced_place(&mut self, e: &Expr, scope: Scope, what: &str) -> Option<TExpr> {
        let v = self.check_place(e, scope, Access::Read, None);
        if v.ty.is_error() {
            return None;
        }
        if !v.is_place() || matches!(v.ty, Ty::IntLit | Ty::RealLit | Ty::Void) {
            self.error(scope.file, e.span, format!("`{what}` needs a variable"));
            return None;
        }
        Some(v)
    }

    /// `REF(v)`, `ADR(v)`, `__ISVALIDREF(r)`; `None` when `id` is none of them.
    pub fn ref_call(
        &mut self,
        id: &Ident,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<TExpr> {
        let upper = id.name.to_ascii_uppercase();
        let kind = match upper.as_str() {
            "REF" => Some(RefKind::RefTo),
            "ADR" => Some(RefKind::Pointer),
            "__ISVALIDREF" => None,
            _ => return None,
        };
        let file = scope.file;
        let [Arg::Positional(arg)] = args else {
            self.error(file, span, format!("`{upper}` takes one argument"));
            return Some(TExpr::error(span));
        };
        let Some(kind) = kind else {
            let r = self.check_place(arg, scope, Access::Read, None);
            let r = self.undo_auto_deref(r);
            return Some(match r.ty {
                Ty::Error => TExpr::error(span),
                // an interface is a reference to an instance (`oop`)
                Ty::Ref(..) | Ty::Null | Ty::Iface(_) => {
                    let null = TExpr::konst(Cv::Int(0), Ty::Null, span);
                    let cmp = TK::Cmp(CmpOp::Ne, Box::new(r), Box::new(null));
                    TExpr { k: cmp, ty: Ty::Prim(Prim::Bool), span }
                }
                other => {
                    let n = self.ty_name(&other);
                    self.error(
                        file,
                        arg.span,
                        format!("`__ISVALIDREF` needs a reference, not `{n}`"),
                    );
                    TExpr::error(span)
                }
            });
        };
        Some(match self.referenced_place(arg, scope, &upper) {
            Some(v) => TExpr { span, ..self.reference_to(v, kind) },
            None => TExpr::error(span),
        })
    }

    /// A `REFERENCE TO` variable itself, not what it refers to (`REF=`, `__ISVALIDREF`).
    fn undo_auto_deref(&self, te: TExpr) -> TExpr {
        match te.k {
            TK::Deref(inner) if matches!(inner.ty, Ty::Ref(RefKind::Reference, _)) => *inner,
            k => TExpr { k, ..te },
        }
    }

    /// `target REF= value`: the reference `target` set to refer to the variable `value` (or
    /// to `NULL`). Returns the target and the reference value to store in it.
    pub fn ref_assign(
        &mut self,
        target: &Expr,
        value: &Expr,
        scope: Scope,
    ) -> Option<(TExpr, TExpr)> {
        let file = scope.file;
        let t = self.check_place(target, scope, Access::Write, None);
        let t = self.undo_auto_deref(t);
        if t.ty.is_error() {
            return None;
        }
        let Some((kind, _)) = t.ty.as_ref() else {
            let n = self.ty_name(&t.ty);
            self.error(
                file,
                target.span,
                format!("`REF=` needs a reference on its left, not `{n}`"),
            );
            return None;
        };
        if matches!(&value.kind, ExprKind::Name(id) if id.is("NULL")) {
            return Some((t, TExpr::konst(Cv::Int(0), Ty::Null, value.span)));
        }
        let v = self.referenced_place(value, scope, "REF=")?;
        let r = self.reference_to(v, kind);
        let r = self.coerce(r, &t.ty, file);
        if r.ty.is_error() {
            return None;
        }
        Some((t, r))
    }

    /// The value given to a `REFERENCE TO` input (`fb(r := v)`): a reference to the variable
    /// `v` (bound to it, as CODESYS does), or a reference value as it is.
    pub fn bound_reference(&mut self, value: &Expr, scope: Scope, ty: &Ty) -> TExpr {
        let v = self.check_place(value, scope, Access::Read, Some(ty));
        let v = self.undo_auto_deref(v);
        if matches!(v.ty, Ty::Ref(..) | Ty::Null | Ty::Error) || !v.is_place() {
            return v;
        }
        self.reference_to(v, RefKind::Reference)
    }

    /// Whether a reference of type `from` may be stored in one of type `to`: `NULL` in any;
    /// between `POINTER TO`s whatever they point to (as CODESYS); otherwise to the same type.
    /// Whether `from` converts to `to` as CODESYS converts a pointer and a number: a
    /// `POINTER TO` and a 64-bit unsigned integer or bit string (`ULINT`, `LWORD`), either way.
    pub fn pointer_integer(&self, from: &Ty, to: &Ty) -> bool {
        let wide = |t: &Ty| {
            !matches!(t, Ty::Enum(_))
                && matches!(t.prim(&self.types), Some(Prim::ULInt | Prim::LWord))
        };
        let pointer = |t: &Ty| matches!(t, Ty::Ref(RefKind::Pointer, _));
        (pointer(from) && wide(to)) || (wide(from) && pointer(to))
    }

    pub fn ref_assignable(&self, from: &Ty, to: &Ty) -> bool {
        match (from, to) {
            (Ty::Null, Ty::Ref(..) | Ty::Null) => true,
            (Ty::Ref(RefKind::Pointer, _), Ty::Ref(RefKind::Pointer, _)) => true,
            (Ty::Ref(_, a), Ty::Ref(_, b)) => match (&**a, &**b) {
                // a derived function block is one of its base (`oop`)
                (Ty::Fb(d), Ty::Fb(base)) => self.derives_from(*d, *base),
                _ => a == b,
            },
            _ => false,
        }
    }

    /// A binary operator with a reference operand: `p + n`, `p - n` on a `POINTER TO` (moves
    /// it by n bytes), `p - q` (the bytes between two pointers, a `DINT`), `=`, `<>` between
    /// compatible references, `<`, `>`, `<=`, `>=` between pointers.
    pub fn ref_binary(
        &mut self,
        op: BinaryOp,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        let what = op_text(op);
        let pointer = |t: &Ty| matches!(t, Ty::Ref(RefKind::Pointer, _));
        // `p = 0`, `p <> 0`: the constant 0 is NULL beside a pointer, as in CODESYS
        let equality = matches!(op, BinaryOp::Eq | BinaryOp::Ne);
        let (a, b) = match (&a.ty, &b.ty) {
            (t, Ty::IntLit) if equality && pointer(t) => (a, null_for_zero(b)),
            (Ty::IntLit, t) if equality && pointer(t) => (null_for_zero(a), b),
            _ => (a, b),
        };
        let integer = |s: &Self, t: &Ty| {
            matches!(t, Ty::IntLit)
                || (t.prim(&s.types).is_some_and(Prim::is_integral) && !matches!(t, Ty::Enum(_)))
        };
        match op {
            BinaryOp::Add | BinaryOp::Sub if pointer(&a.ty) && integer(self, &b.ty) => {
                return self.moved(a, b, op == BinaryOp::Sub, span, file)
            }
            BinaryOp::Add if integer(self, &a.ty) && pointer(&b.ty) => {
                return self.moved(b, a, false, span, file)
            }
            BinaryOp::Sub if pointer(&a.ty) && pointer(&b.ty) => {
                let k = TK::RefDiff(Box::new(a), Box::new(b));
                return TExpr { k, ty: Ty::Prim(Prim::DInt), span };
            }
            BinaryOp::Eq | BinaryOp::Ne
                if self.ref_assignable(&a.ty, &b.ty) || self.ref_assignable(&b.ty, &a.ty) =>
            {
                let cmp = if op == BinaryOp::Eq { CmpOp::Eq } else { CmpOp::Ne };
                let k = TK::Cmp(cmp, Box::new(a), Box::new(b));
                return TExpr { k, ty: Ty::Prim(Prim::Bool), span };
            }
            BinaryOp::Lt | BinaryOp::Le | BinaryOp::Gt | BinaryOp::Ge
                if pointer(&a.ty) && pointer(&b.ty) =>
            {
                let cmp = match op {
                    BinaryOp::Lt => CmpOp::Lt,
                    BinaryOp::Le => CmpOp::Le,
                    BinaryOp::Gt => CmpOp::Gt,
                    _ => CmpOp::Ge,
                };
                let k = TK::Cmp(cmp, Box::new(a), Box::new(b));
                return TExpr { k, ty: Ty::Prim(Prim::Bool), span };
            }
            _ => {}
        }
        // a POINTER TO beside a 64-bit number is that number (`pt < end`, `adr AND 3`)
        let number = |s: &Self, t: &Ty| {
            s.pointer_integer(&Ty::Ref(RefKind::Pointer, std::rc::Rc::new(Ty::Error)), t)
        };
        if pointer(&a.ty) && number(self, &b.ty) {
            self.habit(Habit::PointerInteger, file, a.span);
            let a = TExpr { ty: b.ty.clone(), ..a };
            return self.binary_op(op, a, b, span, file);
        }
        if number(self, &a.ty) && pointer(&b.ty) {
            self.habit(Habit::PointerInteger, file, b.span);
            let b = TExpr { ty: a.ty.clone(), ..b };
            return self.binary_op(op, a, b, span, file);
        }
        let (na, nb) = (self.ty_name(&a.ty), self.ty_name(&b.ty));
        self.error(file, span, format!("`{what}` cannot be applied to `{na}` and `{nb}`"));
        TExpr::error(span)
    }

    /// `te` given where a reference of type `to` is expected: the constant 0 is `NULL` for a
    /// `POINTER TO` (`p := 0`, as CODESYS); anything else as it is.
    pub fn zero_as_null(&self, te: TExpr, to: &Ty) -> TExpr {
        match to {
            Ty::Ref(RefKind::Pointer, _) => null_for_zero(te),
            _ => te,
        }
    }

    /// `p[i]` on a `POINTER TO T` (CODESYS): the `T` `i` elements after the one `p` points
    /// to, `(p + i * SIZEOF(T))^`, a place reached through the moved pointer and so checked
    /// at every access as any `p^`. `index` is the checked index (an integer).
    pub fn pointer_element(
        &mut self,
        p: TExpr,
        index: Vec<TExpr>,
        span: Span,
        text: &str,
        file: usize,
    ) -> TExpr {
        let [index] = <[TExpr; 1]>::try_from(index).unwrap_or_else(|ix| {
            let n = ix.len();
            let msg = format!("`{text}` is a `POINTER TO`: it takes one index, not {n}");
            self.error(file, span, msg);
            [TExpr::error(span)]
        });
        if index.ty.is_error() {
            return TExpr::error(span);
        }
        self.habit(Habit::PointerIndex, file, span);
        let Ty::Ref(_, to) = &p.ty else { return TExpr::error(span) };
        let size = i128::from(self.types.size(to));
        let lint = Ty::Prim(Prim::LInt);
        let index = match index.ty {
            Ty::IntLit => self.coerce(index, &lint, file),
            _ => self.conv(index, Prim::LInt, lint.clone()),
        };
        let bytes = match index.k {
            TK::Const(Cv::Int(i)) => TExpr::konst(Cv::Int(i * size), lint, index.span),
            _ => {
                let size = TExpr::konst(Cv::Int(size), lint.clone(), index.span);
                let k = TK::Bin(BinOp::Mul, Box::new(index), Box::new(size));
                TExpr { k, ty: lint, span }
            }
        };
        let moved = self.moved(p, bytes, false, span, file);
        self.deref(moved, span, text, file)
    }

    /// The pointer `p` moved by `n` bytes (back when `back`).
    fn moved(&mut self, p: TExpr, n: TExpr, back: bool, span: Span, file: usize) -> TExpr {
        let lint = Ty::Prim(Prim::LInt);
        let n = match n.ty {
            Ty::IntLit => self.coerce(n, &lint, file),
            _ => self.conv(n, Prim::LInt, lint.clone()),
        };
        if n.ty.is_error() {
            return TExpr::error(span);
        }
        let n = match (&n.k, back) {
            (_, false) => n,
            (TK::Const(Cv::Int(v)), true) => TExpr::konst(Cv::Int(-v), lint, n.span),
            (_, true) => TExpr { k: TK::Un(UnOp::Neg, Box::new(n)), ty: lint, span },
        };
        let ty = p.ty.clone();
        TExpr { k: TK::RefAdd(Box::new(p), Box::new(n)), ty, span }
    }
}

/// The constant 0 as `NULL`; anything else as it is (no other integer is a reference).
fn null_for_zero(te: TExpr) -> TExpr {
    match (&te.k, &te.ty) {
        (TK::Const(Cv::Int(0)), Ty::IntLit) => TExpr::konst(Cv::Int(0), Ty::Null, te.span),
        _ => te,
    }
}
