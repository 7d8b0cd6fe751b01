//! Variable-length arrays, `ARRAY [*, …] OF T` (IEC 61131-3 ed. 3, CODESYS; docs/ST.md,
//! "Variable-length arrays"): the type of a VAR_IN_OUT of a FUNCTION, FUNCTION_BLOCK or METHOD
//! to which any array of the element type with as many dimensions may be passed, and
//! `LOWER_BOUND` / `UPPER_BOUND`, which give the passed array's bounds.
//!
//! A VAR_IN_OUT is a pointer in the callee's storage (its frame, or its instance). An open
//! array's storage is that pointer followed by a *descriptor*, its bounds as hidden parameters:
//! per dimension the lower bound and the length, each a `LINT` (see [`OpenArrayTy`]). The caller
//! stores them as it stores any argument: constants for a fixed array, or copied from its own
//! descriptor when it passes an open array on. An element access computes the element's
//! number from those bounds with ordinary ops, checks each index against its dimension, and
//! ends in the [`Op::Index`] a fixed array uses, so that an index outside is the same
//! operation error (3402H) and native code needs nothing of its own.

use std::rc::Rc;

use crate::lang::ops::{CmpOp, Op, Place};
use crate::st::ast::Span;
use crate::st::ast::{Expr, PouKind, TypeRef, VarKind};
use crate::value::{BinOp, Elem};

use super::ctx::{Ctx, Cv, Scope, Storage, VarInfo};
use super::emit::Em;
use super::expr::{ArgT, TExpr, TK};
use super::types::{OpenArrayTy, Prim, Ty};

/// The storage `n` bytes into `s` (a field of an open array's descriptor).
fn field(s: Storage, n: u32) -> Storage {
    match s {
        Storage::Inst(o) => Storage::Inst(o + n),
        Storage::Frame(o) => Storage::Frame(o + n),
        Storage::Global(o) => Storage::Global(o + n),
        other => other,
    }
}

/// Whether a place is in device memory (a located variable, or an element or member of one).
fn at_device(t: &TExpr) -> bool {
    match &t.k {
        TK::Var { storage, .. } => matches!(storage, Storage::Word(_) | Storage::Bit(_)),
        TK::Index(b, _) | TK::Member(b, _, _) => at_device(b),
        _ => false,
    }
}

/// A `LINT` field of an open array's descriptor, read as a variable.
fn descriptor_field(s: Storage, n: u32, span: Span) -> TExpr {
    TExpr { k: TK::Var { storage: field(s, n), by_ref: false }, ty: Ty::Prim(Prim::LInt), span }
}

impl<'a> Ctx<'a> {
    /// The type of a declared variable of a `kind` POU's `block`, with the forms only some
    /// declarations allow: an `ARRAY [*]` (a VAR_IN_OUT of a FUNCTION, FUNCTION_BLOCK or
    /// METHOD; a METHOD is compiled as a FUNCTION), a generic input (`compile::generic`), a
    /// `BIT` (`compile::bit`); any other type as [`Ctx::resolve_type_ref`] resolves it.
    pub(super) fn var_type(
        &mut self,
        ty: &TypeRef,
        kind: PouKind,
        block: VarKind,
        scope: Scope,
    ) -> Ty {
        match ty {
            TypeRef::OpenArray { rank, of, .. }
                if block == VarKind::InOut
                    && matches!(kind, PouKind::Function | PouKind::FunctionBlock) =>
            {
                let of = self.resolve_type_ref(of, scope);
                if of.is_error() {
                    return Ty::Error;
                }
                let elem_size = self.types.size(&of);
                Ty::OpenArray(Rc::new(OpenArrayTy { rank: *rank, of, elem_size }))
            }
            _ => match self.generic_input_type(ty, kind, block, scope) {
                Some(generic) => generic,
                None => match self.block_bit_type(ty, kind, block, scope.file) {
                    Some(bit) => bit,
                    None => self.resolve_type_ref(ty, scope),
                },
            },
        }
    }

    /// An `ARRAY [*]` anywhere but as a VAR_IN_OUT's type.
    pub(super) fn misplaced_open_array(&mut self, file: usize, span: Span) -> Ty {
        self.error(
            file,
            span,
            "`ARRAY [*]` is only the type of a VAR_IN_OUT of a FUNCTION, FUNCTION_BLOCK or METHOD",
        );
        Ty::Error
    }

    /// An `ARRAY [*]` read or written whole (assigned, or given as a value): refused, since
    /// its size is known only when the POU runs.
    pub(super) fn open_array_whole(&mut self, span: Span, file: usize) -> TExpr {
        self.error(
            file,
            span,
            "an `ARRAY [*]` is used element by element or passed on to a VAR_IN_OUT, not copied whole",
        );
        TExpr::error(span)
    }

    /// The arguments that pass the place `t` to the open-array VAR_IN_OUT `v` (at `offset` in
    /// the callee) of `callee`: its pointer, then each dimension's lower bound and length.
    /// `None` (and an error) when `t` is not an array of `v`'s element type and rank.
    pub(super) fn open_array_args(
        &mut self,
        v: &VarInfo,
        offset: u32,
        t: TExpr,
        callee: &str,
        file: usize,
    ) -> Option<Vec<ArgT>> {
        let Ty::OpenArray(open) = &v.ty else { unreachable!("an open array's parameter") };
        let span = t.span;
        let bounds: Vec<(TExpr, TExpr)> = match (&t.ty, &t.k) {
            (Ty::Array(a), _) if a.dims.len() == open.rank && a.of == open.of => a
                .dims
                .iter()
                .map(|&(lo, hi)| {
                    let lint = Ty::Prim(Prim::LInt);
                    (
                        TExpr::konst(Cv::Int(i128::from(lo)), lint.clone(), span),
                        TExpr::konst(Cv::Int(i128::from(hi - lo + 1)), lint, span),
                    )
                })
                .collect(),
            // an open array passed on: its own descriptor's bounds
            (Ty::OpenArray(a), TK::Var { storage, by_ref: true })
                if a.rank == open.rank && a.of == open.of =>
            {
                (0..a.rank)
                    .map(|d| {
                        (
                            descriptor_field(*storage, OpenArrayTy::lower_at(d), span),
                            descriptor_field(*storage, OpenArrayTy::len_at(d), span),
                        )
                    })
                    .collect()
            }
            _ => {
                let (a, b) = (self.ty_name(&v.ty), self.ty_name(&t.ty));
                self.error(
                    file,
                    span,
                    format!(
                        "VAR_IN_OUT `{}` of `{callee}` needs a `{a}` variable, not `{b}`",
                        v.name
                    ),
                );
                return None;
            }
        };
        if at_device(&t) {
            // the callee steps through the array in bytes; a device's words are counted in words
            self.error(
                file,
                span,
                "an array located at a device cannot be passed to an `ARRAY [*]`: copy it into a variable first",
            );
            return None;
        }
        let mut args = vec![ArgT { offset, ty: v.ty.clone(), by_ref: true, value: t }];
        for (d, (lower, len)) in bounds.into_iter().enumerate() {
            let lint = Ty::Prim(Prim::LInt);
            let at = offset + OpenArrayTy::lower_at(d);
            args.push(ArgT { offset: at, ty: lint.clone(), by_ref: false, value: lower });
            let at = offset + OpenArrayTy::len_at(d);
            args.push(ArgT { offset: at, ty: lint, by_ref: false, value: len });
        }
        Some(args)
    }

    /// The element `base[ix]` of an open array: `base` is the POU's own VAR_IN_OUT (its
    /// descriptor is in the POU's storage); every index is checked when it runs.
    pub(super) fn open_array_element(
        &mut self,
        base: TExpr,
        ix: Vec<TExpr>,
        open: &OpenArrayTy,
        name: &str,
        span: Span,
        file: usize,
    ) -> TExpr {
        if open.rank != ix.len() {
            self.error(
                file,
                span,
                format!("`{name}` has {} dimension(s), {} index(es) given", open.rank, ix.len()),
            );
            return TExpr::error(span);
        }
        if !matches!(base.k, TK::Var { by_ref: true, .. }) {
            // its bounds are in its POU's storage, which a caller reads only after the call
            self.error(
                file,
                span,
                format!("`{name}` is an `ARRAY [*]`: only its own POU indexes it"),
            );
            return TExpr::error(span);
        }
        TExpr { k: TK::Index(Box::new(base), ix), ty: open.of.clone(), span }
    }

    /// `LOWER_BOUND(arr, dim)` (`upper`: `UPPER_BOUND`), a `DINT`: a bound of dimension `dim`
    /// (a constant from 1) of an array; of an open array, the passed array's, read from its
    /// descriptor.
    pub(super) fn array_bound(
        &mut self,
        args: &[&Expr],
        upper: bool,
        span: Span,
        scope: Scope,
    ) -> TExpr {
        let file = scope.file;
        let fname = if upper { "UPPER_BOUND" } else { "LOWER_BOUND" };
        let arr = self.check_expr(args[0], scope, None);
        let rank = match &arr.ty {
            Ty::Array(a) => a.dims.len(),
            Ty::OpenArray(a) => a.rank,
            Ty::Error => return TExpr::error(span),
            other => {
                let n = self.ty_name(other);
                self.error(file, args[0].span, format!("`{fname}` needs an array, not `{n}`"));
                return TExpr::error(span);
            }
        };
        let dim = self.check_expr(args[1], scope, None);
        let d = match dim.const_int() {
            Some(d) if (1..=rank as i128).contains(&d) => d as usize - 1,
            _ if dim.ty.is_error() => return TExpr::error(span),
            _ => {
                self.error(
                    file,
                    args[1].span,
                    format!("the dimension of `{fname}` must be a constant from 1 to {rank}"),
                );
                return TExpr::error(span);
            }
        };
        let dint = Ty::Prim(Prim::DInt);
        match (&arr.ty, &arr.k) {
            (Ty::Array(a), _) => {
                let (lo, hi) = a.dims[d];
                TExpr::konst(Cv::Int(i128::from(if upper { hi } else { lo })), dint, span)
            }
            (Ty::OpenArray(_), TK::Var { storage, by_ref: true }) => {
                let lower = descriptor_field(*storage, OpenArrayTy::lower_at(d), span);
                let value = if upper {
                    // lower + len - 1
                    let len = descriptor_field(*storage, OpenArrayTy::len_at(d), span);
                    let sum = TExpr {
                        k: TK::Bin(BinOp::Add, Box::new(lower), Box::new(len)),
                        ty: Ty::Prim(Prim::LInt),
                        span,
                    };
                    let one = TExpr::konst(Cv::Int(1), Ty::Prim(Prim::LInt), span);
                    TExpr {
                        k: TK::Bin(BinOp::Sub, Box::new(sum), Box::new(one)),
                        ty: Ty::Prim(Prim::LInt),
                        span,
                    }
                } else {
                    lower
                };
                self.conv(value, Prim::DInt, dint)
            }
            _ => {
                let n = self.ty_name(&arr.ty);
                self.error(file, args[0].span, format!("`{fname}` needs an array, not `{n}`"));
                TExpr::error(span)
            }
        }
    }
}

impl<'c, 'a> Em<'c, 'a> {
    /// Pushes a pointer to the element `base[ix]` of an open array. The element's number is
    /// built dimension by dimension (`n = n * len + (i - lower)`); an index outside its
    /// dimension leaves that computation for a tail that makes the number -1, which the
    /// closing [`Op::Index`] refuses with the operation error a fixed array raises.
    pub(super) fn open_array_addr(&mut self, base: &TExpr, ix: &[TExpr], open: &OpenArrayTy) {
        let TK::Var { storage, by_ref: true } = base.k else {
            unreachable!("an open array is indexed through its own VAR_IN_OUT")
        };
        let place = |n: u32| match field(storage, n) {
            Storage::Frame(o) => Place::Frame(o),
            Storage::Inst(o) => Place::This(o),
            _ => unreachable!("a VAR_IN_OUT of a FUNCTION, FUNCTION_BLOCK or METHOD"),
        };
        let base_sp = self.sp;
        self.op(Op::Fetch { elem: Elem::U64, at: place(0) });
        let mut fails = Vec::new();
        for (d, i) in ix.iter().enumerate() {
            let len = place(OpenArrayTy::len_at(d));
            if d > 0 {
                self.op(Op::Fetch { elem: Elem::I64, at: len });
                self.op(Op::Bin { op: BinOp::Mul, elem: Elem::I64 });
            }
            self.value(i);
            let from = self.elem(&i.ty);
            if from != Elem::I64 {
                self.op(Op::Conv { from, to: Elem::I64 });
            }
            self.op(Op::Fetch { elem: Elem::I64, at: place(OpenArrayTy::lower_at(d)) });
            self.op(Op::Bin { op: BinOp::Sub, elem: Elem::I64 });
            // 0 <= k < len in one unsigned comparison (a negative k is a huge unsigned one)
            self.op(Op::Dup);
            self.op(Op::Fetch { elem: Elem::I64, at: len });
            self.op(Op::Cmp { op: CmpOp::Lt, elem: Elem::U64 });
            fails.push((d, self.op(Op::GotoIf { target: 0, when: false })));
            if d > 0 {
                self.op(Op::Bin { op: BinOp::Add, elem: Elem::I64 });
            }
        }
        let mut to_index = vec![self.op(Op::Goto(0))];
        for (d, at) in fails {
            let here = self.pc();
            self.patch(at, here);
            // the stack holds the pointer, the number so far (after the first dimension) and
            // this dimension's index
            self.sp = base_sp + if d > 0 { 3 } else { 2 };
            self.op(Op::Drop);
            if d > 0 {
                self.op(Op::Drop);
            }
            self.op(Op::PushInt(-1));
            to_index.push(self.op(Op::Goto(0)));
        }
        let index_at = self.pc();
        for j in to_index {
            self.patch(j, index_at);
        }
        self.sp = base_sp + 2;
        self.op(Op::Index { lo: 0, len: u32::MAX, stride: open.elem_size });
    }
}
