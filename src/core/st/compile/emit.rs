//! Code generation: a checked POU body to typed stack ops (st-ir.md). Each body is compiled
//! once, with its jump targets relative to its own start, its calls by POU, its PROGRAM
//! variables relative to the instance and its argument stores relative to the callee's frame
//! area; [`super::link`] places the bodies one after the other and resolves all of that.

use crate::device::{BitRef, WordRef};
use crate::lang::ops::{CmpOp, StrOp};
use crate::lang::{Op, Place, EVAL_DEPTH};
use crate::st::ast::PouKind;
use crate::value::{BinOp, Elem, UnOp, REF_TAG};

use super::ctx::{Ctx, Cv, Storage};
use super::decl::MAX_FRAME;
use super::expr::{cv_slot, ArgT, CallT, GateT, TExpr, TK};
use super::stdlib::Std;
use super::stmt::{TStmt, TS};
use super::types::{ArrayTy, Prim, Ty};

/// A compiled POU body before linking.
#[derive(Debug, Clone, Default)]
pub struct Body {
    pub code: Vec<Op>,
    pub lines: Vec<u32>,
    /// The first op of each statement (see `lang::Program::statements`), ascending.
    pub statements: Vec<u32>,
    pub consts: Vec<u64>,
    /// Ops whose `Place::Var` offset is relative to the PROGRAM instance.
    pub var_relocs: Vec<usize>,
    /// `CallFn`/`CallFb` ops and the POU each calls.
    pub calls: Vec<(usize, usize)>,
    /// Ops whose frame offset (a `Place::Frame` or a call's `frame`) is relative to the callee
    /// area, which starts at the end of this body's own frame.
    pub callee_relocs: Vec<usize>,
    /// Bytes of this body's own frame (variables and temporaries).
    pub frame: u32,
}

/// What pushes a value: an expression, or ops computed by the caller (an output read).
enum Src<'e> {
    Expr(&'e TExpr),
    /// Ops and whether each is relative to the callee area.
    Ops(Vec<(Op, bool)>),
}

#[derive(Default)]
struct Loop {
    breaks: Vec<usize>,
    continues: Vec<usize>,
}

/// A place known when compiling, and whether it is relative to the PROGRAM instance.
#[derive(Debug, Clone, Copy)]
struct Static {
    place: Place,
    reloc: bool,
}

impl Static {
    fn plus(self, n: u32) -> Static {
        let place = match self.place {
            Place::Var(o) => Place::Var(o + n),
            Place::Frame(o) => Place::Frame(o + n),
            Place::This(o) => Place::This(o + n),
            Place::Word(w) => Place::Word(WordRef(w.0 + n as u16)),
            Place::Bit(b) => {
                let bit = u32::from(b.word) * 16 + b.mask.trailing_zeros() + n;
                Place::Bit(BitRef { word: (bit / 16) as u16, mask: 1 << (bit % 16) })
            }
            Place::Byte(b) => Place::Byte(b + n),
        };
        Static { place, reloc: self.reloc }
    }

    /// Where the place is, and so the unit of its offsets.
    fn memory(&self) -> Memory {
        match self.place {
            Place::Word(_) => Memory::Words,
            Place::Bit(_) => Memory::Bits,
            Place::Byte(_) => Memory::DeviceBytes,
            _ => Memory::Bytes,
        }
    }
}

/// Where a variable's storage is, which sets the unit of offsets into it: bytes of variable or
/// frame memory, device words (a located array of words), device bits (a located ARRAY OF
/// BOOL at a bit device), device bytes (a located array of 8-bit values at an IEC byte
/// address).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Memory {
    Bytes,
    Words,
    Bits,
    DeviceBytes,
}

impl Memory {
    /// The distance between two elements of `a` stored here.
    fn stride(self, a: &ArrayTy, elem: Elem) -> u32 {
        match self {
            Memory::Bytes => a.elem_size,
            Memory::Words => elem.words(),
            Memory::Bits | Memory::DeviceBytes => 1,
        }
    }
}

pub struct Em<'c, 'a> {
    cx: &'c mut Ctx<'a>,
    kind: PouKind,
    file: usize,
    b: Body,
    line: u32,
    pub(super) sp: usize,
    max_sp: usize,
    tmp: u32,
    loops: Vec<Loop>,
    returns: Vec<usize>,
    depth_reported: bool,
    /// Where the body's labels are (`jumps`).
    labels: super::jumps::Labels,
}

fn unsigned(e: Elem) -> Elem {
    match e {
        Elem::I8 => Elem::U8,
        Elem::I16 => Elem::U16,
        Elem::I32 => Elem::U32,
        Elem::I64 => Elem::U64,
        other => other,
    }
}

fn effect(op: &Op) -> isize {
    match op {
        Op::PushInt(_)
        | Op::PushConst(_)
        | Op::Fetch { .. }
        | Op::AddrOf(_)
        | Op::Dup
        | Op::Now
        | Op::Utc => 1,
        Op::Store { .. }
        | Op::Index { .. }
        | Op::Bin { .. }
        | Op::Cmp { .. }
        | Op::Drop
        | Op::RefAdd
        | Op::RefDiff
        | Op::GotoIf { .. } => -1,
        Op::CallFb { .. } => -1,
        Op::StoreInd(_) | Op::Copy(_) => -2,
        Op::Str { op, .. } => match op {
            StrOp::Move | StrOp::FromValue(_) | StrOp::Widen | StrOp::Narrow => -2,
            StrOp::Len | StrOp::ToValue(_) => 0,
            StrOp::Left | StrOp::Right | StrOp::Concat => -3,
            StrOp::Mid => -4,
            StrOp::Find | StrOp::Compare => -1,
        },
        _ => 0,
    }
}

impl<'c, 'a> Em<'c, 'a> {
    pub(super) fn op(&mut self, op: Op) -> usize {
        let at = self.b.code.len();
        self.sp = (self.sp as isize + effect(&op)).max(0) as usize;
        self.max_sp = self.max_sp.max(self.sp);
        self.b.code.push(op);
        self.b.lines.push(self.line);
        at
    }

    /// The next op starts a statement: a place a breakpoint and a line step stop at.
    fn mark_statement(&mut self) {
        let at = self.b.code.len() as u32;
        if self.b.statements.last() != Some(&at) {
            self.b.statements.push(at);
        }
    }

    fn op_callee(&mut self, op: Op) -> usize {
        let at = self.op(op);
        self.b.callee_relocs.push(at);
        at
    }

    fn op_static(&mut self, op: Op, s: Static) -> usize {
        let at = self.op(op);
        if s.reloc {
            self.b.var_relocs.push(at);
        }
        at
    }

    pub(super) fn pc(&self) -> u32 {
        self.b.code.len() as u32
    }

    pub(super) fn patch(&mut self, at: usize, target: u32) {
        match &mut self.b.code[at] {
            Op::Goto(t) => *t = target,
            Op::GotoIf { target: t, .. } => *t = target,
            _ => unreachable!("not a jump"),
        }
    }

    fn alloc_tmp(&mut self, size: u32) -> u32 {
        let at = self.tmp;
        self.tmp += size;
        self.b.frame = self.b.frame.max(self.tmp);
        at
    }

    fn push_slot(&mut self, slot: u64) {
        if slot == (slot as i32) as i64 as u64 {
            self.op(Op::PushInt(slot as i32));
        } else {
            let i = match self.b.consts.iter().position(|&c| c == slot) {
                Some(i) => i,
                None => {
                    self.b.consts.push(slot);
                    self.b.consts.len() - 1
                }
            };
            self.op(Op::PushConst(i as u32));
        }
    }

    fn push_int(&mut self, e: Elem, v: i128) {
        let p = match e {
            Elem::Bool => Prim::Bool,
            Elem::I8 => Prim::SInt,
            Elem::I16 => Prim::Int,
            Elem::I32 => Prim::DInt,
            Elem::I64 => Prim::LInt,
            Elem::U8 => Prim::USInt,
            Elem::U16 => Prim::UInt,
            Elem::U32 => Prim::UDInt,
            Elem::U64 => Prim::ULInt,
            Elem::F32 => Prim::Real,
            Elem::F64 => Prim::LReal,
        };
        self.push_slot(cv_slot(&Cv::Int(v), p));
    }

    pub(super) fn elem(&self, ty: &Ty) -> Elem {
        ty.elem(&self.cx.types).unwrap_or(Elem::I64)
    }

    fn size(&self, ty: &Ty) -> u32 {
        self.cx.types.size(ty)
    }

    fn storage(&self, s: Storage) -> Static {
        match s {
            Storage::Inst(o) if self.kind == PouKind::Program => {
                Static { place: Place::Var(o), reloc: true }
            }
            Storage::Inst(o) => Static { place: Place::This(o), reloc: false },
            Storage::Frame(o) => Static { place: Place::Frame(o), reloc: false },
            Storage::Global(o) => Static { place: Place::Var(o), reloc: false },
            Storage::Word(w) => Static { place: Place::Word(WordRef(w)), reloc: false },
            Storage::Bit(b) => Static { place: Place::Bit(b), reloc: false },
            Storage::Byte(n) => Static { place: Place::Byte(n), reloc: false },
        }
    }

    /// The place of an expression, when it is known at compile time.
    fn static_place(&self, e: &TExpr) -> Option<Static> {
        match &e.k {
            TK::Var { storage, by_ref: false } => Some(self.storage(*storage)),
            TK::Member(b, off, _) => {
                let s = self.static_place(b)?;
                (s.memory() == Memory::Bytes).then(|| s.plus(*off))
            }
            TK::Index(b, ix) => {
                let s = self.static_place(b)?;
                let Ty::Array(a) = &b.ty else { return None };
                let mut lin: i64 = 0;
                for (i, (lo, hi)) in ix.iter().zip(&a.dims) {
                    let v = i.const_int()? as i64;
                    if v < *lo || v > *hi {
                        return None;
                    }
                    lin = lin * (hi - lo + 1) + (v - lo);
                }
                let unit = s.memory().stride(a, self.elem(&a.of));
                Some(s.plus(lin as u32 * unit))
            }
            _ => None,
        }
    }

    /// Where a place expression's storage is (device words or bits for a located array).
    fn memory(&self, e: &TExpr) -> Memory {
        match &e.k {
            TK::Var { storage: Storage::Word(_), .. } => Memory::Words,
            TK::Var { storage: Storage::Bit(_), .. } => Memory::Bits,
            TK::Var { storage: Storage::Byte(_), .. } => Memory::DeviceBytes,
            TK::Member(b, _, _) | TK::Index(b, _) => self.memory(b),
            _ => Memory::Bytes,
        }
    }

    /// Pushes a pointer to a place expression (or to an aggregate value).
    fn addr(&mut self, e: &TExpr) {
        self.addr_in(e, true);
    }

    /// [`Em::addr`]; `whole` when the place is what is accessed, not the start of a member or
    /// element access (which checks a place reached through a reference at its end).
    fn addr_in(&mut self, e: &TExpr, whole: bool) {
        if let Some(s) = self.static_place(e) {
            self.op_static(Op::AddrOf(s.place), s);
            return;
        }
        match &e.k {
            TK::Var { storage, by_ref: true } => {
                let s = self.storage(*storage);
                self.op_static(Op::Fetch { elem: Elem::U64, at: s.place }, s);
            }
            TK::Member(b, off, _) => {
                self.addr_in(b, false);
                if *off != 0 {
                    self.op(Op::Offset(*off));
                }
                self.check_ref_path(e, whole);
            }
            TK::Deref(r) => {
                self.value(r);
                let size = if whole { self.size(&e.ty).max(1) } else { 0 };
                self.op(Op::Deref { size });
            }
            TK::Index(b, ix) => {
                if let Ty::OpenArray(open) = &b.ty {
                    self.open_array_addr(b, ix, open);
                    return;
                }
                let Ty::Array(a) = &b.ty else { unreachable!("checked") };
                let unit = self.memory(b).stride(a, self.elem(&a.of));
                self.addr_in(b, false);
                for (k, (i, (lo, hi))) in ix.iter().zip(&a.dims).enumerate() {
                    let inner: u64 =
                        a.dims[k + 1..].iter().map(|(l, h)| (h - l + 1) as u64).product();
                    self.value(i);
                    self.op(Op::Index {
                        lo: *lo as i32,
                        len: (hi - lo + 1) as u32,
                        stride: (inner as u32) * unit,
                    });
                }
                self.check_ref_path(e, whole);
            }
            _ => {
                // an aggregate value (a call's result, a string operation): its pointer
                self.value(e);
            }
        }
    }

    /// After the member or element `e` is reached from a reference (`r^.x`, `r^[i]`), and when
    /// it is what is accessed: the check of its bytes ([`Op::CheckRef`]).
    fn check_ref_path(&mut self, e: &TExpr, whole: bool) {
        fn through_deref(e: &TExpr) -> bool {
            match &e.k {
                TK::Deref(_) => true,
                TK::Member(b, _, _) | TK::Index(b, _) => through_deref(b),
                _ => false,
            }
        }
        if whole && through_deref(e) {
            let size = self.size(&e.ty).max(1);
            self.op(Op::CheckRef(size));
        }
    }

    /// Pushes a scalar's value, or an aggregate's pointer.
    pub(super) fn value(&mut self, e: &TExpr) {
        match &e.k {
            TK::Const(cv) => match (cv, &e.ty) {
                (Cv::Str(s), _) => {
                    // the characters and their NUL, as a STRING is stored
                    let mut bytes = s.clone();
                    bytes.push(0);
                    let at = self.cx.alloc_var(&bytes, self.file, e.span);
                    self.op(Op::AddrOf(Place::Var(at)));
                }
                (Cv::WStr(s), _) => {
                    // the code units and their 2-byte NUL, as a WSTRING is stored
                    let bytes: Vec<u8> =
                        s.iter().chain([&0]).flat_map(|unit| unit.to_le_bytes()).collect();
                    let at = self.cx.alloc_var(&bytes, self.file, e.span);
                    self.op(Op::AddrOf(Place::Var(at)));
                }
                (cv, ty) => {
                    let p = ty.prim(&self.cx.types).unwrap_or(Prim::LInt);
                    self.push_slot(cv_slot(cv, p));
                }
            },
            TK::Var { .. } | TK::Member(..) | TK::Index(..) | TK::Deref(..) => {
                if let Some((cap, wide)) = self.cx.open_union_string(e) {
                    return self.bounded_string(e, cap, wide);
                }
                if e.ty.is_aggregate() {
                    self.addr(e);
                    return;
                }
                let elem = self.elem(&e.ty);
                if let Some(s) = self.static_place(e) {
                    self.op_static(Op::Fetch { elem, at: s.place }, s);
                } else {
                    self.addr(e);
                    self.op(Op::FetchInd(elem));
                }
            }
            TK::Bit(b, n) => {
                let be = self.elem(&b.ty);
                self.value(b);
                self.push_int(be, 1i128 << n);
                self.op(Op::Bin { op: BinOp::And, elem: be });
                self.op(Op::Conv { from: be, to: Elem::Bool });
            }
            TK::Part(b, start) => {
                // shifted down to bit 0 and cut to the part's size
                let (whole, part) = (self.elem(&b.ty), self.elem(&e.ty));
                self.value(b);
                if *start != 0 {
                    self.push_int(whole, i128::from(*start));
                    self.op(Op::Bin { op: BinOp::Shr, elem: whole });
                }
                self.op(Op::Conv { from: whole, to: part });
            }
            TK::Un(op, a) => {
                self.value(a);
                let elem = self.elem(&e.ty);
                self.op(Op::Un { op: *op, elem });
            }
            TK::Bin(op, a, b) => {
                self.value(a);
                self.value(b);
                let elem = self.elem(&e.ty);
                self.op(Op::Bin { op: *op, elem });
            }
            TK::Cmp(op, a, b) => {
                self.value(a);
                self.value(b);
                if a.ty.string_cap().is_some() {
                    self.op(Op::Str { op: StrOp::Compare, cap: 0, wide: a.ty.is_wide() });
                    self.op(Op::PushInt(0));
                    self.op(Op::Cmp { op: *op, elem: Elem::I64 });
                } else {
                    let elem = self.elem(&a.ty);
                    self.op(Op::Cmp { op: *op, elem });
                }
            }
            TK::Conv(a) => {
                self.value(a);
                let (from, to) = (self.elem(&a.ty), self.elem(&e.ty));
                if from != to {
                    self.op(Op::Conv { from, to });
                }
            }
            TK::Call(call) => self.call_fn(call, &e.ty, true),
            TK::Std(op, args) => self.std(*op, args, &e.ty),
            TK::Gate(g) => {
                let base = self.sp;
                let off = g.en.as_ref().map(|en| {
                    self.value(en);
                    self.op(Op::GotoIf { target: 0, when: false })
                });
                self.eno_stores(g.eno.iter().map(|(t, n)| (t, *n)), true);
                self.value(&g.value);
                if let Some(off) = off {
                    let end = self.op(Op::Goto(0));
                    let here = self.pc();
                    self.patch(off, here);
                    self.sp = base;
                    self.eno_stores(g.eno.iter().map(|(t, n)| (t, *n)), false);
                    let image = self.cx.default_image(&e.ty, None);
                    self.push_image(&image, &e.ty);
                    let here = self.pc();
                    self.patch(end, here);
                }
            }
            TK::Ref(place) => {
                // the pointer, as a reference value (`Op::Deref` says how)
                self.addr(place);
                self.push_slot(REF_TAG);
                self.op(Op::Bin { op: BinOp::Add, elem: Elem::U64 });
            }
            TK::RefAdd(r, n) => {
                self.value(r);
                self.value(n);
                self.op(Op::RefAdd);
            }
            TK::RefDiff(a, b) => {
                self.value(a);
                self.value(b);
                self.op(Op::RefDiff);
            }
            TK::Assign(target, value) => {
                // the value kept in a temporary: stored, then the expression's value
                let elem = self.elem(&e.ty);
                let kept = Place::Frame(self.alloc_tmp(8));
                self.value(value);
                self.op(Op::Store { elem, at: kept });
                self.store(target, Src::Ops(vec![(Op::Fetch { elem, at: kept }, false)]));
                self.op(Op::Fetch { elem, at: kept });
            }
            TK::ShortCircuit(decides_on, a, b) => {
                // a; if a = decides_on goto decided; b; goto end; decided: push decides_on
                let base = self.sp;
                self.value(a);
                let decided = self.op(Op::GotoIf { target: 0, when: *decides_on });
                self.value(b);
                let end = self.op(Op::Goto(0));
                let here = self.pc();
                self.patch(decided, here);
                self.sp = base;
                let result = Cv::Int(i128::from(*decides_on));
                self.value(&TExpr::konst(result, Ty::Prim(Prim::Bool), e.span));
                let here = self.pc();
                self.patch(end, here);
            }
        }
    }

    /// Pushes a pointer to a copy of the `cap` units of the string `e` (a UNION's member that
    /// another member overlaps: `union::open_union_string`) ended by a zero unit of its own:
    /// its value is its characters up to the first zero among them, or all `cap`, and nothing
    /// past its bytes is ever read as its characters.
    fn bounded_string(&mut self, e: &TExpr, cap: u32, wide: bool) {
        let width = if wide { 2 } else { 1 };
        let copy = self.alloc_tmp((cap + 1) * width);
        self.op(Op::AddrOf(Place::Frame(copy)));
        self.addr(e);
        self.op(Op::Copy(cap * width));
        self.op(Op::PushInt(0));
        let unit = if wide { Elem::U16 } else { Elem::U8 };
        self.op(Op::Store { elem: unit, at: Place::Frame(copy + cap * width) });
        self.op(Op::AddrOf(Place::Frame(copy)));
    }

    /// `ran` (negated for a negated binding) into each `ENO => target`.
    fn eno_stores<'t>(&mut self, targets: impl Iterator<Item = (&'t TExpr, bool)>, ran: bool) {
        for (target, negated) in targets {
            let v = TExpr::konst(
                Cv::Int(i128::from(ran != negated)),
                Ty::Prim(Prim::Bool),
                target.span,
            );
            self.store(target, Src::Expr(&v));
        }
    }

    /// Pushes a value of `ty` given as its bytes (a scalar's slot, or the pointer to a copy of
    /// an aggregate kept in variable memory).
    fn push_image(&mut self, image: &[u8], ty: &Ty) {
        if ty.is_aggregate() {
            let span = crate::st::ast::Span { line: self.line, col: 1 };
            let at = self.cx.alloc_var(image, self.file, span);
            self.op(Op::AddrOf(Place::Var(at)));
            return;
        }
        let elem = self.elem(ty);
        let size = elem.size() as usize;
        let mut raw = [0u8; 8];
        raw[..size].copy_from_slice(&image[..size]);
        let mut slot = u64::from_le_bytes(raw);
        if elem.is_signed() && size < 8 {
            let shift = 64 - size * 8;
            slot = (((slot << shift) as i64) >> shift) as u64;
        }
        self.push_slot(slot);
    }

    /// `__QUERYINTERFACE` (`tags`: the blocks implementing the asked interface) or
    /// `__QUERYPOINTER` (no tags: any instance): the instance behind `source` into `dest`
    /// and TRUE when it is not NULL and (for an interface) its tag is one of `tags`; NULL and
    /// FALSE otherwise.
    fn query(&mut self, source: &TExpr, dest: &TExpr, tags: &[u32]) {
        let base = self.sp;
        let t = self.alloc_tmp(8);
        self.value(source);
        self.op(Op::Store { elem: Elem::U64, at: Place::Frame(t) });
        self.op(Op::Fetch { elem: Elem::U64, at: Place::Frame(t) });
        self.op(Op::PushInt(0));
        self.op(Op::Cmp { op: CmpOp::Ne, elem: Elem::U64 });
        let null = self.op(Op::GotoIf { target: 0, when: false });
        let mut found = Vec::new();
        if tags.is_empty() {
            found.push(self.op(Op::Goto(0)));
        }
        for &tag in tags {
            // the reference made an address (checked), then the tag at the instance's start
            self.op(Op::Fetch { elem: Elem::U64, at: Place::Frame(t) });
            self.op(Op::Deref { size: 4 });
            self.op(Op::FetchInd(Elem::U32));
            self.push_int(Elem::U32, i128::from(tag));
            self.op(Op::Cmp { op: CmpOp::Eq, elem: Elem::U32 });
            found.push(self.op(Op::GotoIf { target: 0, when: true }));
        }
        // not found (or NULL): dest NULL, FALSE
        let here = self.pc();
        self.patch(null, here);
        self.sp = base;
        self.store(dest, Src::Ops(vec![(Op::PushInt(0), false)]));
        self.op(Op::PushInt(0));
        let end = self.op(Op::Goto(0));
        let here = self.pc();
        for j in found {
            self.patch(j, here);
        }
        self.sp = base;
        self.store(
            dest,
            Src::Ops(vec![(Op::Fetch { elem: Elem::U64, at: Place::Frame(t) }, false)]),
        );
        self.op(Op::PushInt(1));
        let here = self.pc();
        self.patch(end, here);
        self.sp = base + 1;
    }

    fn std(&mut self, op: Std, args: &[TExpr], ty: &Ty) {
        match op {
            Std::Utc => {
                self.op(Op::Utc);
            }
            Std::Now => {
                self.op(Op::Now);
            }
            Std::System(request) => {
                self.op(Op::System(request));
                self.op(Op::PushInt(1));
            }
            Std::QueryInterface(itf) => {
                let tags = self.cx.implementing_tags(itf);
                self.query(&args[0], &args[1], &tags);
            }
            Std::QueryPointer => self.query(&args[0], &args[1], &[]),
            Std::Sel => {
                let base = self.sp;
                self.value(&args[0]);
                let to_in0 = self.op(Op::GotoIf { target: 0, when: false });
                self.value(&args[2]);
                let to_end = self.op(Op::Goto(0));
                let l0 = self.pc();
                self.patch(to_in0, l0);
                self.sp = base;
                self.value(&args[1]);
                let end = self.pc();
                self.patch(to_end, end);
            }
            Std::Mux => {
                // K is kept in a temporary and compared with 0, 1, … in turn; a K that selects
                // no input gives the default (0, '') and raises 3402H, as an index out of
                // bounds does.
                let base = self.sp;
                let ke = self.elem(&args[0].ty);
                let k = self.alloc_tmp(8);
                self.value(&args[0]);
                self.op(Op::Store { elem: ke, at: Place::Frame(k) });
                let inputs = &args[1..];
                let mut jumps = Vec::new();
                for i in 0..inputs.len() {
                    self.op(Op::Fetch { elem: ke, at: Place::Frame(k) });
                    self.push_int(ke, i as i128);
                    self.op(Op::Cmp { op: CmpOp::Eq, elem: ke });
                    jumps.push(self.op(Op::GotoIf { target: 0, when: true }));
                }
                self.op(Op::AddrOf(Place::Frame(k)));
                self.op(Op::Fetch { elem: ke, at: Place::Frame(k) });
                self.op(Op::Index { lo: 0, len: 0, stride: 0 });
                if ty.string_cap().is_none() {
                    let elem = self.elem(ty);
                    self.op(Op::FetchInd(elem));
                }
                let mut ends = vec![self.op(Op::Goto(0))];
                for (i, j) in jumps.into_iter().enumerate() {
                    let here = self.pc();
                    self.patch(j, here);
                    self.sp = base;
                    self.value(&inputs[i]);
                    ends.push(self.op(Op::Goto(0)));
                }
                let end = self.pc();
                for j in ends {
                    self.patch(j, end);
                }
                self.sp = base + 1;
            }
            Std::Chain(cmp) => {
                // each input once, into a temporary; then each pair compared, all ANDed
                let elem = if args[0].ty.string_cap().is_some() {
                    Elem::U64
                } else {
                    self.elem(&args[0].ty)
                };
                let mut temps = Vec::new();
                for a in args {
                    let t = self.alloc_tmp(8);
                    self.value(a);
                    self.op(Op::Store { elem, at: Place::Frame(t) });
                    temps.push(t);
                }
                for (k, w) in temps.windows(2).enumerate() {
                    self.op(Op::Fetch { elem, at: Place::Frame(w[0]) });
                    self.op(Op::Fetch { elem, at: Place::Frame(w[1]) });
                    if args[0].ty.string_cap().is_some() {
                        let wide = args[0].ty.is_wide();
                        self.op(Op::Str { op: StrOp::Compare, cap: 0, wide });
                        self.op(Op::PushInt(0));
                        self.op(Op::Cmp { op: cmp, elem: Elem::I64 });
                    } else {
                        self.op(Op::Cmp { op: cmp, elem });
                    }
                    if k > 0 {
                        self.op(Op::Bin { op: BinOp::And, elem: Elem::Bool });
                    }
                }
            }
            Std::Len => {
                self.value(&args[0]);
                self.op(Op::Str { op: StrOp::Len, cap: 0, wide: args[0].ty.is_wide() });
                self.op(Op::Conv { from: Elem::I64, to: Elem::I16 });
            }
            Std::Find => {
                self.value(&args[0]);
                self.value(&args[1]);
                self.op(Op::Str { op: StrOp::Find, cap: 0, wide: args[0].ty.is_wide() });
                self.op(Op::Conv { from: Elem::I64, to: Elem::I16 });
            }
            Std::ToString(scalar) => {
                let (cap, wide) = (ty.string_cap().unwrap_or(255), ty.is_wide());
                let tmp = self.alloc_tmp(self.size(ty).max(256));
                self.op(Op::AddrOf(Place::Frame(tmp)));
                self.value(&args[0]);
                self.op(Op::Str { op: StrOp::FromValue(scalar), cap: cap as u16, wide });
                self.op(Op::AddrOf(Place::Frame(tmp)));
            }
            Std::FromString(scalar) => {
                self.value(&args[0]);
                let wide = args[0].ty.is_wide();
                self.op(Op::Str { op: StrOp::ToValue(scalar), cap: 0, wide });
            }
            Std::Widen | Std::Narrow => {
                // into a temporary of the result's kind, as the other string functions
                let cap = ty.string_cap().unwrap_or(255);
                let tmp = self.alloc_tmp(self.size(ty).max(1));
                self.op(Op::AddrOf(Place::Frame(tmp)));
                self.value(&args[0]);
                let sop = if op == Std::Widen { StrOp::Widen } else { StrOp::Narrow };
                self.op(Op::Str { op: sop, cap: cap as u16, wide: false });
                self.op(Op::AddrOf(Place::Frame(tmp)));
            }
            Std::CharToString => {
                // the character, then the NUL (a WSTRING's 2 bytes wide)
                let elem = if ty.is_wide() { Elem::U16 } else { Elem::U8 };
                let tmp = self.alloc_tmp(self.size(ty));
                self.op(Op::AddrOf(Place::Frame(tmp)));
                self.value(&args[0]);
                self.op(Op::StoreInd(elem));
                self.op(Op::AddrOf(Place::Frame(tmp + elem.size())));
                self.op(Op::PushInt(0));
                self.op(Op::StoreInd(elem));
                self.op(Op::AddrOf(Place::Frame(tmp)));
            }
            Std::StringToChar => {
                // the first character: the NUL of an empty string is 0
                self.value(&args[0]);
                let elem = if args[0].ty.is_wide() { Elem::U16 } else { Elem::U8 };
                self.op(Op::FetchInd(elem));
            }
            Std::Left | Std::Right | Std::Mid | Std::Concat => {
                let (cap, wide) = (ty.string_cap().unwrap_or(255), ty.is_wide());
                let tmp = self.alloc_tmp(self.size(ty).max(256));
                self.op(Op::AddrOf(Place::Frame(tmp)));
                for a in args {
                    self.value(a);
                }
                let sop = match op {
                    Std::Left => StrOp::Left,
                    Std::Right => StrOp::Right,
                    Std::Mid => StrOp::Mid,
                    _ => StrOp::Concat,
                };
                self.op(Op::Str { op: sop, cap: cap as u16, wide });
                self.op(Op::AddrOf(Place::Frame(tmp)));
            }
        }
    }

    fn template(&mut self, p: usize) -> Option<u32> {
        let pou = &self.cx.pous[p];
        if pou.frame_vars == 0 {
            return None;
        }
        if let Some(t) = pou.frame_template {
            return Some(t);
        }
        let img = pou.frame_image.clone();
        let (file, span) = (pou.file, pou.name_span());
        let at = self.cx.alloc_var(&img, file, span);
        self.cx.pous[p].frame_template = Some(at);
        Some(at)
    }

    /// Copies `size` bytes (or a string) from the pointer on top into the pointer below.
    fn copy(&mut self, ty: &Ty) {
        match ty {
            Ty::Str(n) => self.op(Op::Str { op: StrOp::Move, cap: *n as u16, wide: false }),
            Ty::WStr(n) => self.op(Op::Str { op: StrOp::Move, cap: *n as u16, wide: true }),
            _ => {
                let n = self.size(ty);
                self.op(Op::Copy(n))
            }
        };
    }

    /// A FUNCTION call; leaves its result (a scalar, or a pointer to a copy) when `want`. With
    /// an implicit EN FALSE: nothing of the call, each `ENO =>` target FALSE, and the result's
    /// initial value (what the result holds before the body runs).
    fn call_fn(&mut self, call: &CallT, ty: &Ty, want: bool) {
        let Some(en) = &call.en else {
            return self.call_fn_enabled(call, ty, want);
        };
        let base = self.sp;
        self.value(en);
        let off = self.op(Op::GotoIf { target: 0, when: false });
        self.call_fn_enabled(call, ty, want);
        let end = self.op(Op::Goto(0));
        let here = self.pc();
        self.patch(off, here);
        self.sp = base;
        self.eno_off(call);
        if want && *ty != Ty::Void {
            let size = self.size(ty) as usize;
            let image = self.cx.pous[call.pou].frame_image[..size].to_vec();
            self.push_image(&image, ty);
        }
        let here = self.pc();
        self.patch(end, here);
    }

    /// FALSE (TRUE for a negated binding) into the `ENO =>` targets of a call that did not run.
    fn eno_off(&mut self, call: &CallT) {
        let targets: EnoTargets =
            call.outs.iter().filter(|o| o.eno).map(|o| (o.target.clone(), o.negated)).collect();
        self.eno_stores(targets.iter().map(|(t, n)| (t, *n)), false);
    }

    fn call_fn_enabled(&mut self, call: &CallT, ty: &Ty, want: bool) {
        // a method's instance: its place, or its pointer in a temporary (before the arguments,
        // which may call functions in the callee area)
        let this = call.this.as_ref().map(|this| match self.static_place(this) {
            Some(s) => Inst::Static(s),
            None => {
                let t = self.alloc_tmp(8);
                self.addr(this);
                self.op(Op::Store { elem: Elem::U64, at: Place::Frame(t) });
                Inst::Ptr(t)
            }
        });
        // arguments that call functions themselves: into temporaries first (every argument
        // when the call dispatches: each candidate stores them after its own frame image)
        let dispatching = !call.dispatch.is_empty();
        let mut pre: Vec<Option<u32>> = Vec::new();
        for a in &call.args {
            if a.value.has_call() || dispatching {
                let size = if a.by_ref { 8 } else { self.size(&a.ty).max(self.size(&a.value.ty)) };
                let t = self.alloc_tmp(size);
                if a.by_ref {
                    self.addr(&a.value);
                    self.op(Op::Store { elem: Elem::U64, at: Place::Frame(t) });
                } else if a.ty.is_aggregate() {
                    self.op(Op::AddrOf(Place::Frame(t)));
                    self.value(&a.value);
                    self.copy(&a.ty);
                } else {
                    self.value(&a.value);
                    let elem = self.elem(&a.ty);
                    self.op(Op::Store { elem, at: Place::Frame(t) });
                }
                pre.push(Some(t));
            } else {
                pre.push(None);
            }
        }
        match this {
            None => {
                self.enter_callee(call, call.pou, &pre);
                let at = self.op_callee(Op::CallFn { target: 0, frame: 0 });
                self.b.calls.push((at, call.pou));
            }
            Some(this) if !dispatching => {
                self.enter_callee(call, call.pou, &pre);
                self.call_method(this, call.pou);
            }
            Some(this) => self.dispatch(this, &call.dispatch, |em, pou| {
                em.enter_callee(call, pou, &pre);
                em.call_method(this, pou);
            }),
        }
        if want && *ty != Ty::Void {
            if ty.is_aggregate() {
                let size = self.size(ty);
                let t = self.alloc_tmp(size);
                self.op(Op::AddrOf(Place::Frame(t)));
                self.op_callee(Op::AddrOf(Place::Frame(0)));
                self.copy(ty);
                self.op(Op::AddrOf(Place::Frame(t)));
            } else {
                let elem = self.elem(ty);
                self.op_callee(Op::Fetch { elem, at: Place::Frame(0) });
            }
        }
        for o in &call.outs {
            let elem = self.elem(&o.ty);
            let mut ops = vec![(Op::Fetch { elem, at: Place::Frame(o.offset) }, true)];
            self.out_tail(&mut ops, o.negated, &o.ty, &o.target.ty);
            self.store(&o.target, Src::Ops(ops));
        }
    }

    /// The callee area made ready for `pou`: its frame's initial image, then the arguments.
    fn enter_callee(&mut self, call: &CallT, pou: usize, pre: &[Option<u32>]) {
        if let Some(t) = self.template(pou) {
            let n = self.cx.pous[pou].frame_vars;
            self.op_callee(Op::AddrOf(Place::Frame(0)));
            self.op(Op::AddrOf(Place::Var(t)));
            self.op(Op::Copy(n));
        }
        for (a, t) in call.args.iter().zip(pre) {
            self.store_arg(a, *t, None);
        }
    }

    /// One branch per candidate body, chosen by the instance's type tag (`oop`): `call` emits
    /// the call of each; a candidate without a tag is the default, taken when no tag before
    /// it matched.
    fn dispatch(
        &mut self,
        inst: Inst,
        candidates: &[(Option<u32>, usize)],
        mut call: impl FnMut(&mut Self, usize),
    ) {
        let mut ends = Vec::new();
        for &(tag, pou) in candidates {
            let next = tag.map(|tag| self.unless_tag(inst, tag));
            call(self, pou);
            ends.push(self.op(Op::Goto(0)));
            if let Some(next) = next {
                let here = self.pc();
                self.patch(next, here);
            }
        }
        let here = self.pc();
        for j in ends {
            self.patch(j, here);
        }
    }

    /// A jump, to be patched, taken when the instance's type tag (its first UDINT) is not
    /// `tag`.
    fn unless_tag(&mut self, inst: Inst, tag: u32) -> usize {
        self.push_inst(inst);
        self.op(Op::FetchInd(Elem::U32));
        self.push_int(Elem::U32, i128::from(tag));
        self.op(Op::Cmp { op: CmpOp::Eq, elem: Elem::U32 });
        self.op(Op::GotoIf { target: 0, when: false })
    }

    /// Pushes the pointer to an instance.
    fn push_inst(&mut self, inst: Inst) {
        match inst {
            Inst::Static(s) => {
                self.op_static(Op::AddrOf(s.place), s);
            }
            Inst::Ptr(t) => {
                self.op(Op::Fetch { elem: Elem::U64, at: Place::Frame(t) });
            }
        }
    }

    /// A method's body called on the instance, its frame in the callee area.
    fn call_method(&mut self, this: Inst, pou: usize) {
        self.push_inst(this);
        let at = self.op_callee(Op::CallFb { target: 0, frame: 0 });
        self.b.calls.push((at, pou));
    }

    fn out_tail(&self, ops: &mut Vec<(Op, bool)>, negated: bool, from: &Ty, to: &Ty) {
        if negated {
            ops.push((Op::Un { op: UnOp::Not, elem: Elem::Bool }, false));
        }
        let (f, t) = (self.elem(from), self.elem(to));
        if f != t && !from.is_aggregate() {
            ops.push((Op::Conv { from: f, to: t }, false));
        }
    }

    /// Stores one argument: into the callee's frame (`inst` None) or into an FB instance.
    fn store_arg(&mut self, a: &ArgT, pre: Option<u32>, inst: Option<Inst>) {
        let elem = if a.by_ref { Elem::U64 } else { self.elem(&a.ty) };
        let agg = !a.by_ref && a.ty.is_aggregate();
        // destination
        let dest = match inst {
            None => Dest::Callee(a.offset),
            Some(Inst::Static(s)) => Dest::Static(s.plus(a.offset)),
            Some(Inst::Ptr(t)) => Dest::Ptr(t, a.offset),
        };
        if agg {
            self.dest_addr(&dest);
            match pre {
                Some(t) => {
                    self.op(Op::AddrOf(Place::Frame(t)));
                }
                None => self.value(&a.value),
            }
            self.copy(&a.ty);
            return;
        }
        if let Dest::Ptr(..) = dest {
            self.dest_addr(&dest);
        }
        match (pre, a.by_ref) {
            (Some(t), _) => {
                self.op(Op::Fetch { elem, at: Place::Frame(t) });
            }
            (None, true) => self.addr(&a.value),
            (None, false) => self.value(&a.value),
        }
        match dest {
            Dest::Callee(off) => {
                self.op_callee(Op::Store { elem, at: Place::Frame(off) });
            }
            Dest::Static(s) => {
                self.op_static(Op::Store { elem, at: s.place }, s);
            }
            Dest::Ptr(..) => {
                self.op(Op::StoreInd(elem));
            }
        }
    }

    fn dest_addr(&mut self, d: &Dest) {
        match *d {
            Dest::Callee(off) => {
                self.op_callee(Op::AddrOf(Place::Frame(off)));
            }
            Dest::Static(s) => {
                self.op_static(Op::AddrOf(s.place), s);
            }
            Dest::Ptr(t, off) => {
                self.op(Op::Fetch { elem: Elem::U64, at: Place::Frame(t) });
                if off != 0 {
                    self.op(Op::Offset(off));
                }
            }
        }
    }

    fn fb_call(&mut self, inst: &TExpr, call: &CallT) {
        let where_ = match self.static_place(inst) {
            Some(s) => Inst::Static(s),
            None => {
                let t = self.alloc_tmp(8);
                self.addr(inst);
                self.op(Op::Store { elem: Elem::U64, at: Place::Frame(t) });
                Inst::Ptr(t)
            }
        };
        // An implicit EN FALSE: nothing of the call, the instance's ENO and the `ENO =>`
        // targets FALSE.
        let Some(en) = &call.en else {
            return self.fb_call_enabled(where_, call);
        };
        self.value(en);
        let off = self.op(Op::GotoIf { target: 0, when: false });
        self.fb_call_enabled(where_, call);
        let end = self.op(Op::Goto(0));
        let here = self.pc();
        self.patch(off, here);
        if let Some(v) = self.cx.pous[call.pou].eno {
            let Storage::Inst(off) = self.cx.pous[call.pou].vars[v].storage else {
                unreachable!("an FB's ENO is in its instance")
            };
            match where_ {
                Inst::Static(s) => {
                    let s = s.plus(off);
                    self.op(Op::PushInt(0));
                    self.op_static(Op::Store { elem: Elem::Bool, at: s.place }, s);
                }
                Inst::Ptr(t) => {
                    self.op(Op::Fetch { elem: Elem::U64, at: Place::Frame(t) });
                    if off != 0 {
                        self.op(Op::Offset(off));
                    }
                    self.op(Op::PushInt(0));
                    self.op(Op::StoreInd(Elem::Bool));
                }
            }
        }
        self.eno_off(call);
        let here = self.pc();
        self.patch(end, here);
    }

    fn fb_call_enabled(&mut self, where_: Inst, call: &CallT) {
        for a in &call.args {
            self.store_arg(a, None, Some(where_));
        }
        if call.dispatch.is_empty() {
            self.call_method(where_, call.pou);
        } else {
            // the body of the instance's own function block
            self.dispatch(where_, &call.dispatch, |em, pou| em.call_method(where_, pou));
        }
        for o in &call.outs {
            let elem = self.elem(&o.ty);
            let mut ops = match where_ {
                Inst::Static(s) => {
                    let s = s.plus(o.offset);
                    vec![(Op::Fetch { elem, at: s.place }, s.reloc)]
                }
                Inst::Ptr(t) => vec![
                    (Op::Fetch { elem: Elem::U64, at: Place::Frame(t) }, false),
                    (Op::Offset(o.offset), false),
                    (Op::FetchInd(elem), false),
                ],
            };
            if o.ty.is_aggregate() {
                // a pointer to the output: drop the FetchInd / make it an address
                ops = match where_ {
                    Inst::Static(s) => {
                        let s = s.plus(o.offset);
                        vec![(Op::AddrOf(s.place), s.reloc)]
                    }
                    Inst::Ptr(t) => vec![
                        (Op::Fetch { elem: Elem::U64, at: Place::Frame(t) }, false),
                        (Op::Offset(o.offset), false),
                    ],
                };
            }
            self.out_tail(&mut ops, o.negated, &o.ty, &o.target.ty);
            self.store_ops_instance(&o.target, ops);
        }
    }

    /// Output stores of an FB: `reloc` in the ops means instance-relative (not callee).
    fn store_ops_instance(&mut self, target: &TExpr, ops: Vec<(Op, bool)>) {
        self.store(target, Src::Ops(ops));
    }

    fn push_src(&mut self, src: &Src<'_>) {
        match src {
            Src::Expr(e) => self.value(e),
            Src::Ops(ops) => {
                for (op, rel) in ops {
                    let at = self.op(*op);
                    if *rel {
                        match op {
                            Op::Fetch { at: Place::Frame(_), .. } | Op::AddrOf(Place::Frame(_)) => {
                                self.b.callee_relocs.push(at)
                            }
                            _ => self.b.var_relocs.push(at),
                        }
                    }
                }
            }
        }
    }

    /// `whole.<start>` or `whole.%B<n>` `:= src` (a bit, a part of `elem`): a read-modify-write
    /// of `whole` that changes its bits `start..start + elem's bits` only.
    fn store_bits(&mut self, whole: &TExpr, start: u8, elem: Elem, src: Src<'_>) {
        let we = self.elem(&whole.ty);
        let ones = |e: Elem| -> i128 {
            match e {
                Elem::Bool => 1,
                _ if e.size() == 8 => -1,
                _ => (1i128 << (e.size() * 8)) - 1,
            }
        };
        let mask = (ones(elem) << start) & ones(we);
        let stat = self.static_place(whole);
        match stat {
            Some(s) => {
                self.op_static(Op::Fetch { elem: we, at: s.place }, s);
            }
            None => {
                self.addr(whole);
                self.op(Op::Dup);
                self.op(Op::FetchInd(we));
            }
        }
        self.push_int(we, ones(we) & !mask);
        self.op(Op::Bin { op: BinOp::And, elem: we });
        self.push_src(&src);
        self.op(Op::Conv { from: elem, to: we });
        self.push_int(we, i128::from(start));
        self.op(Op::Bin { op: BinOp::Shl, elem: we });
        self.op(Op::Bin { op: BinOp::Or, elem: we });
        match stat {
            Some(s) => {
                self.op_static(Op::Store { elem: we, at: s.place }, s);
            }
            None => {
                self.op(Op::StoreInd(we));
            }
        }
    }

    /// `target := src`.
    fn store(&mut self, target: &TExpr, src: Src<'_>) {
        let ty = &target.ty;
        match &target.k {
            TK::Bit(b, n) => return self.store_bits(b, *n, Elem::Bool, src),
            TK::Part(b, start) => return self.store_bits(b, *start, self.elem(ty), src),
            _ => {}
        }
        if ty.is_aggregate() {
            let at_device = |e: &TExpr| self.memory(e) != Memory::Bytes;
            let located = at_device(target) || matches!(&src, Src::Expr(e) if at_device(e));
            if located {
                if let (Src::Expr(e), Ty::Array(a)) = (&src, ty) {
                    self.copy_elementwise(target, e, a.count());
                    return;
                }
            }
            self.addr(target);
            self.push_src(&src);
            self.copy(ty);
            return;
        }
        let elem = self.elem(ty);
        match self.static_place(target) {
            Some(s) => {
                self.push_src(&src);
                self.op_static(Op::Store { elem, at: s.place }, s);
            }
            None => {
                self.addr(target);
                self.push_src(&src);
                self.op(Op::StoreInd(elem));
            }
        }
    }

    /// An array assignment where one side is at devices: element by element.
    fn copy_elementwise(&mut self, target: &TExpr, src: &TExpr, count: u64) {
        let Ty::Array(a) = &target.ty else { return };
        let elem = self.elem(&a.of);
        let (tw, sw) = (self.memory(target).stride(a, elem), self.memory(src).stride(a, elem));
        for i in 0..count as u32 {
            self.addr(target);
            if i > 0 {
                self.op(Op::Offset(i * tw));
            }
            self.addr(src);
            if i > 0 {
                self.op(Op::Offset(i * sw));
            }
            self.op(Op::FetchInd(elem));
            self.op(Op::StoreInd(elem));
        }
    }

    fn stmts(&mut self, body: &[TStmt]) {
        for s in body {
            self.stmt(s);
        }
    }

    fn stmt(&mut self, s: &TStmt) {
        let saved_line = self.line;
        let saved_tmp = self.tmp;
        self.line = s.line;
        self.sp = 0;
        self.max_sp = 0;
        self.mark_statement();
        match &s.k {
            TS::Assign(t, v) => match ungated(v) {
                // `v := F(EN := c, …)`: with c FALSE the assignment is not made, as CODESYS
                // leaves the variable a box with EN/ENO is connected to.
                Some((en, inner, eno)) => {
                    self.value(&en);
                    let off = self.op(Op::GotoIf { target: 0, when: false });
                    self.store(t, Src::Expr(&inner));
                    let end = self.op(Op::Goto(0));
                    let here = self.pc();
                    self.patch(off, here);
                    self.sp = 0;
                    self.eno_stores(eno.iter().map(|(t, n)| (t, *n)), false);
                    let here = self.pc();
                    self.patch(end, here);
                }
                None => self.store(t, Src::Expr(v)),
            },
            TS::Eval(e) => {
                if let TK::Call(call) = &e.k {
                    self.call_fn(call, &e.ty, false);
                } else {
                    self.value(e);
                    if e.ty != Ty::Void {
                        self.op(Op::Drop);
                    }
                }
            }
            TS::FbCall(inst, call) => self.fb_call(inst, call),
            TS::If(branches, otherwise) => {
                let mut ends = Vec::new();
                let mut done = false;
                for (k, (c, body)) in branches.iter().enumerate() {
                    self.line = s.line.max(c.span.line);
                    if k > 0 {
                        self.mark_statement();
                    }
                    match c.const_int() {
                        Some(0) => continue,
                        Some(_) => {
                            self.stmts(body);
                            done = true;
                            break;
                        }
                        None => {}
                    }
                    self.sp = 0;
                    self.value(c);
                    self.check_depth();
                    let skip = self.op(Op::GotoIf { target: 0, when: false });
                    self.stmts(body);
                    self.line = s.line;
                    // The last branch without ELSE ends where the statement does: no jump.
                    if k + 1 < branches.len() || !otherwise.is_empty() {
                        ends.push(self.op(Op::Goto(0)));
                    }
                    let next = self.pc();
                    self.patch(skip, next);
                }
                if !done {
                    self.stmts(otherwise);
                }
                let end = self.pc();
                for j in ends {
                    self.patch(j, end);
                }
            }
            TS::Case { sel, arms, otherwise } => {
                let elem = self.elem(&sel.ty);
                let place = match self.static_place(sel) {
                    Some(s) => s,
                    None => {
                        let t = self.alloc_tmp(8);
                        self.value(sel);
                        self.op(Op::Store { elem, at: Place::Frame(t) });
                        Static { place: Place::Frame(t), reloc: false }
                    }
                };
                let mut to_arm = Vec::new();
                for (i, (ranges, _)) in arms.iter().enumerate() {
                    for &(lo, hi) in ranges {
                        self.op_static(Op::Fetch { elem, at: place.place }, place);
                        self.push_int(elem, lo);
                        if lo == hi {
                            self.op(Op::Cmp { op: CmpOp::Eq, elem });
                        } else {
                            self.op(Op::Cmp { op: CmpOp::Ge, elem });
                            self.op_static(Op::Fetch { elem, at: place.place }, place);
                            self.push_int(elem, hi);
                            self.op(Op::Cmp { op: CmpOp::Le, elem });
                            self.op(Op::Bin { op: BinOp::And, elem: Elem::Bool });
                        }
                        to_arm.push((self.op(Op::GotoIf { target: 0, when: true }), i));
                    }
                }
                self.check_depth();
                self.stmts(otherwise);
                self.line = s.line;
                let mut ends = vec![self.op(Op::Goto(0))];
                for (i, (_, body)) in arms.iter().enumerate() {
                    let here = self.pc();
                    for (j, arm) in &to_arm {
                        if *arm == i {
                            let j = *j;
                            self.patch(j, here);
                        }
                    }
                    self.stmts(body);
                    self.line = s.line;
                    // The last arm ends where the statement does: no jump.
                    if i + 1 < arms.len() {
                        ends.push(self.op(Op::Goto(0)));
                    }
                }
                let end = self.pc();
                for j in ends {
                    self.patch(j, end);
                }
            }
            TS::While(c, body) => {
                let head = self.pc();
                self.loops.push(Loop::default());
                let exit = match c.const_int() {
                    Some(0) => {
                        self.loops.pop();
                        self.tmp = saved_tmp;
                        self.line = saved_line;
                        return;
                    }
                    Some(_) => None,
                    None => {
                        self.value(c);
                        self.check_depth();
                        Some(self.op(Op::GotoIf { target: 0, when: false }))
                    }
                };
                self.stmts(body);
                self.line = s.line;
                self.op(Op::Goto(head));
                let end = self.pc();
                let l = self.loops.pop().expect("pushed");
                if let Some(e) = exit {
                    self.patch(e, end);
                }
                self.close_loop(l, head, end);
            }
            TS::Repeat(body, c) => {
                let head = self.pc();
                self.loops.push(Loop::default());
                self.stmts(body);
                self.line = c.span.line;
                self.mark_statement();
                let cont = self.pc();
                self.sp = 0;
                self.value(c);
                self.check_depth();
                self.op(Op::GotoIf { target: head, when: false });
                let end = self.pc();
                let l = self.loops.pop().expect("pushed");
                self.close_loop(l, cont, end);
            }
            TS::For { var, from, to, by, body, written } => {
                self.for_loop(s.line, var, [from, to, by], body, *written)
            }
            TS::Exit => {
                let j = self.op(Op::Goto(0));
                if let Some(l) = self.loops.last_mut() {
                    l.breaks.push(j);
                }
            }
            TS::Continue => {
                let j = self.op(Op::Goto(0));
                if let Some(l) = self.loops.last_mut() {
                    l.continues.push(j);
                }
            }
            TS::Label(label) => {
                let here = self.pc();
                for op in self.labels.place(*label, here) {
                    self.patch(op, here);
                }
            }
            // a backward jump is a loop: charged to the step budget as WHILE's `Goto` is
            TS::Jump(label, backward) => match self.labels.before(*label).filter(|_| *backward) {
                Some(target) => {
                    self.op(Op::Goto(target));
                }
                None => {
                    let op = self.op(Op::Goto(0));
                    self.labels.wait(op, *label);
                }
            },
            TS::Return => {
                if self.kind == PouKind::Program {
                    let j = self.op(Op::Goto(0));
                    self.returns.push(j);
                } else {
                    self.op(Op::Return);
                }
            }
        }
        self.check_depth();
        self.tmp = saved_tmp;
        self.line = saved_line;
    }

    /// A FUNCTION's or FB's entry, before its first statement: a declared EN FALSE returns at
    /// once with ENO FALSE; ENO is TRUE on entry; each edge input's value is computed.
    fn entry(&mut self, p: usize) {
        let pou = &self.cx.pous[p];
        let place = |v: usize| match pou.vars[v].storage {
            Storage::Frame(o) => Place::Frame(o),
            Storage::Inst(o) => Place::This(o),
            _ => unreachable!("a FUNCTION's or FB's own variable"),
        };
        let en = pou.en.map(place);
        let eno = pou.eno.map(place);
        // A FUNCTION's implicit ENO starts TRUE from its frame's initial image; an FB's ENO
        // may have been left FALSE by its body or by a call with EN FALSE.
        let set_eno = eno.filter(|_| {
            !pou.eno_implicit
                || pou.kind == PouKind::FunctionBlock
                    && (pou.eno_assigned || pou.called_with_en || pou.en.is_some())
        });
        let edges: Vec<(Place, Place, Place, bool)> = pou
            .edges
            .iter()
            .map(|e| (place(e.input), place(e.memory), Place::This(e.value), e.rising))
            .collect();
        if let Some(en) = en {
            self.op(Op::Fetch { elem: Elem::Bool, at: en });
            let run = self.op(Op::GotoIf { target: 0, when: true });
            if let Some(eno) = eno {
                self.op(Op::PushInt(0));
                self.op(Op::Store { elem: Elem::Bool, at: eno });
            }
            self.op(Op::Return);
            let here = self.pc();
            self.patch(run, here);
        }
        if let Some(eno) = set_eno {
            self.op(Op::PushInt(1));
            self.op(Op::Store { elem: Elem::Bool, at: eno });
        }
        // A base's body runs on a derived instance only through SUPER^(), after the derived
        // body's entry computed the edges of the call: computed again, they would be FALSE.
        let derived_skip = if edges.is_empty() { None } else { self.unless_exactly(p) };
        for (input, memory, value, rising) in edges {
            // R_EDGE: input AND NOT memory; F_EDGE: NOT input AND memory (memory: the input at
            // the previous execution)
            self.op(Op::Fetch { elem: Elem::Bool, at: input });
            if !rising {
                self.op(Op::Un { op: UnOp::Not, elem: Elem::Bool });
            }
            self.op(Op::Fetch { elem: Elem::Bool, at: memory });
            if rising {
                self.op(Op::Un { op: UnOp::Not, elem: Elem::Bool });
            }
            self.op(Op::Bin { op: BinOp::And, elem: Elem::Bool });
            self.op(Op::Store { elem: Elem::Bool, at: value });
            self.op(Op::Fetch { elem: Elem::Bool, at: input });
            self.op(Op::Store { elem: Elem::Bool, at: memory });
        }
        if let Some(skip) = derived_skip {
            let here = self.pc();
            self.patch(skip, here);
        }
    }

    /// In the body of function block `p` that some block extends: a jump, to be patched, taken
    /// when the own instance is not exactly a `p` (its type tag is another's); `None` when
    /// no block extends `p`.
    fn unless_exactly(&mut self, p: usize) -> Option<usize> {
        let tag = *self.cx.oop.tags.get(&p)?;
        let extended = (0..self.cx.pous.len()).any(|d| d != p && self.cx.derives_from(d, p));
        if !extended {
            return None;
        }
        self.op(Op::Fetch { elem: Elem::U32, at: Place::This(0) });
        self.push_int(Elem::U32, i128::from(tag));
        self.op(Op::Cmp { op: CmpOp::Eq, elem: Elem::U32 });
        Some(self.op(Op::GotoIf { target: 0, when: false }))
    }

    fn close_loop(&mut self, l: Loop, cont: u32, end: u32) {
        for j in l.breaks {
            self.patch(j, end);
        }
        for j in l.continues {
            self.patch(j, cont);
        }
    }

    fn check_depth(&mut self) {
        if self.max_sp > EVAL_DEPTH && !self.depth_reported {
            self.depth_reported = true;
            let msg = format!(
                "this statement needs {} evaluation stack slots (limit {EVAL_DEPTH})",
                self.max_sp
            );
            self.cx.error(self.file, crate::st::ast::Span { line: self.line, col: 1 }, msg);
        }
    }

    fn for_loop(
        &mut self,
        line: u32,
        var: &TExpr,
        [from, to, by]: [&TExpr; 3],
        body: &[TStmt],
        written: bool,
    ) {
        let elem = self.elem(&var.ty);
        let ue = unsigned(elem);
        let v = self.static_place(var).expect("a FOR variable is a local");
        let fetch_v = |em: &mut Self| {
            em.op_static(Op::Fetch { elem, at: v.place }, v);
        };
        self.value(from);
        self.op_static(Op::Store { elem, at: v.place }, v);
        // bound and step, evaluated once
        let to_tmp = if to.is_const() {
            None
        } else {
            let t = self.alloc_tmp(8);
            self.value(to);
            self.op(Op::Store { elem, at: Place::Frame(t) });
            Some(t)
        };
        let by_const = by.const_int();
        let by_tmp = if by_const.is_some() {
            None
        } else {
            let t = self.alloc_tmp(8);
            self.value(by);
            self.op(Op::Store { elem, at: Place::Frame(t) });
            Some(t)
        };
        let push_to = |em: &mut Self| match to_tmp {
            Some(t) => {
                em.op(Op::Fetch { elem, at: Place::Frame(t) });
            }
            None => em.value(to),
        };
        let push_by = |em: &mut Self| match by_tmp {
            Some(t) => {
                em.op(Op::Fetch { elem, at: Place::Frame(t) });
            }
            None => em.push_int(elem, by_const.unwrap_or(1)),
        };
        let mut exits = Vec::new();
        // the entry test
        let neg_test = |em: &mut Self, exits: &mut Vec<usize>| {
            fetch_v(em);
            push_to(em);
            em.op(Op::Cmp { op: CmpOp::Lt, elem });
            exits.push(em.op(Op::GotoIf { target: 0, when: true }));
        };
        let pos_test = |em: &mut Self, exits: &mut Vec<usize>| {
            fetch_v(em);
            push_to(em);
            em.op(Op::Cmp { op: CmpOp::Gt, elem });
            exits.push(em.op(Op::GotoIf { target: 0, when: true }));
        };
        match by_const {
            Some(b) if b > 0 => pos_test(self, &mut exits),
            Some(_) => neg_test(self, &mut exits),
            None => {
                push_by(self);
                self.push_int(elem, 0);
                self.op(Op::Cmp { op: CmpOp::Lt, elem });
                let to_neg = self.op(Op::GotoIf { target: 0, when: true });
                pos_test(self, &mut exits);
                let to_body = self.op(Op::Goto(0));
                let here = self.pc();
                self.patch(to_neg, here);
                neg_test(self, &mut exits);
                let body_at = self.pc();
                self.patch(to_body, body_at);
            }
        }
        let body_at = self.pc();
        self.loops.push(Loop::default());
        self.stmts(body);
        self.line = line;
        self.mark_statement();
        let cont = self.pc();
        self.sp = 0;
        let mut rest_exits = Vec::new();
        if written {
            // The body wrote the variable (CODESYS's habit): one past the bound already ends
            // the loop, as the test after CODESYS's increment would; the distance below
            // assumes a variable between the start and the bound.
            match by_const {
                Some(b) if b > 0 => pos_test(self, &mut rest_exits),
                Some(_) => neg_test(self, &mut rest_exits),
                None => {
                    push_by(self);
                    self.push_int(elem, 0);
                    self.op(Op::Cmp { op: CmpOp::Lt, elem });
                    let to_neg = self.op(Op::GotoIf { target: 0, when: true });
                    pos_test(self, &mut rest_exits);
                    let to_rest = self.op(Op::Goto(0));
                    let here = self.pc();
                    self.patch(to_neg, here);
                    neg_test(self, &mut rest_exits);
                    let rest = self.pc();
                    self.patch(to_rest, rest);
                }
            }
        }
        // the remaining distance to the bound, unsigned, against the step: no wrap-around
        let pos_rest = |em: &mut Self, exits: &mut Vec<usize>| {
            push_to(em);
            fetch_v(em);
            em.op(Op::Bin { op: BinOp::Sub, elem });
            if ue != elem {
                em.op(Op::Conv { from: elem, to: ue });
            }
            push_by(em);
            if ue != elem {
                em.op(Op::Conv { from: elem, to: ue });
            }
            em.op(Op::Cmp { op: CmpOp::Lt, elem: ue });
            exits.push(em.op(Op::GotoIf { target: 0, when: true }));
        };
        let neg_rest = |em: &mut Self, exits: &mut Vec<usize>| {
            fetch_v(em);
            push_to(em);
            em.op(Op::Bin { op: BinOp::Sub, elem });
            if ue != elem {
                em.op(Op::Conv { from: elem, to: ue });
            }
            push_by(em);
            em.op(Op::Un { op: UnOp::Neg, elem });
            if ue != elem {
                em.op(Op::Conv { from: elem, to: ue });
            }
            em.op(Op::Cmp { op: CmpOp::Lt, elem: ue });
            exits.push(em.op(Op::GotoIf { target: 0, when: true }));
        };
        match by_const {
            // A step of 1 or -1: the distance is less than the step exactly when it is 0, when
            // the variable is at the bound (4 ops where the general test takes 8).
            Some(1 | -1) => {
                fetch_v(self);
                push_to(self);
                self.op(Op::Cmp { op: CmpOp::Eq, elem });
                rest_exits.push(self.op(Op::GotoIf { target: 0, when: true }));
            }
            Some(b) if b > 0 => pos_rest(self, &mut rest_exits),
            Some(_) => neg_rest(self, &mut rest_exits),
            None => {
                push_by(self);
                self.push_int(elem, 0);
                self.op(Op::Cmp { op: CmpOp::Lt, elem });
                let to_neg = self.op(Op::GotoIf { target: 0, when: true });
                pos_rest(self, &mut rest_exits);
                let to_inc = self.op(Op::Goto(0));
                let here = self.pc();
                self.patch(to_neg, here);
                neg_rest(self, &mut rest_exits);
                let inc = self.pc();
                self.patch(to_inc, inc);
            }
        }
        fetch_v(self);
        push_by(self);
        self.op(Op::Bin { op: BinOp::Add, elem });
        self.op_static(Op::Store { elem, at: v.place }, v);
        self.op(Op::Goto(body_at));
        // Past the bound: the variable takes the first value that fails the test, as CODESYS
        // leaves it (the step is added with wrap-around; the test before it never wraps).
        let past = self.pc();
        for j in rest_exits {
            self.patch(j, past);
        }
        fetch_v(self);
        push_by(self);
        self.op(Op::Bin { op: BinOp::Add, elem });
        self.op_static(Op::Store { elem, at: v.place }, v);
        let end = self.pc();
        for j in exits {
            self.patch(j, end);
        }
        let l = self.loops.pop().expect("pushed");
        self.close_loop(l, cont, end);
    }
}

/// `ENO => target` bindings: each target, and whether the binding is negated.
type EnoTargets = Vec<(TExpr, bool)>;

/// A value that is a call with an implicit EN (a FUNCTION's or a standard function's),
/// implicitly converted or not: its EN, the value without it, and its `ENO =>` targets.
fn ungated(v: &TExpr) -> Option<(TExpr, TExpr, EnoTargets)> {
    match &v.k {
        TK::Conv(inner) => {
            let (en, inner, eno) = ungated(inner)?;
            Some((en, TExpr { k: TK::Conv(Box::new(inner)), ..v.clone() }, eno))
        }
        TK::Call(call) => {
            let en = call.en.as_deref()?.clone();
            let eno = call.outs.iter().filter(|o| o.eno).map(|o| (o.target.clone(), o.negated));
            let eno = eno.collect();
            let call = CallT { en: None, ..(**call).clone() };
            Some((en, TExpr { k: TK::Call(Box::new(call)), ..v.clone() }, eno))
        }
        TK::Gate(g) => {
            let en = g.en.clone()?;
            let eno = g.eno.clone();
            let g = GateT { en: None, ..(**g).clone() };
            Some((en, TExpr { k: TK::Gate(Box::new(g)), ..v.clone() }, eno))
        }
        _ => None,
    }
}

#[derive(Debug, Clone, Copy)]
enum Inst {
    Static(Static),
    /// A frame temporary holding the instance's pointer.
    Ptr(u32),
}

enum Dest {
    Callee(u32),
    Static(Static),
    Ptr(u32, u32),
}

/// Compiles a checked body.
pub fn compile_body(cx: &mut Ctx<'_>, p: usize, body: &[TStmt]) -> Body {
    let kind = cx.pous[p].kind;
    let file = cx.pous[p].file;
    let frame_vars = cx.pous[p].frame_vars;
    let (start, end) = cx.pous[p].start_end();
    let (start_line, end_line) = (start.line, end.line);
    let mut em = Em {
        cx,
        kind,
        file,
        b: Body { frame: frame_vars, ..Body::default() },
        line: start_line,
        sp: 0,
        max_sp: 0,
        tmp: frame_vars,
        loops: Vec::new(),
        returns: Vec::new(),
        depth_reported: false,
        labels: Default::default(),
    };
    // VAR_TEMP of a PROGRAM or FB starts from its initial values at each call
    if kind != PouKind::Function {
        if let Some(t) = em.template(p) {
            em.op(Op::AddrOf(Place::Frame(0)));
            em.op(Op::AddrOf(Place::Var(t)));
            em.op(Op::Copy(frame_vars));
        }
    }
    em.entry(p);
    em.stmts(body);
    em.line = end_line;
    em.mark_statement();
    let end = em.pc();
    for j in std::mem::take(&mut em.returns) {
        em.patch(j, end);
    }
    em.op(if kind == PouKind::Program { Op::End } else { Op::Return });
    let b = em.b;
    // Variables alone past the limit were reported with the declarations.
    if b.frame > MAX_FRAME && cx.pous[p].frame_vars <= MAX_FRAME {
        let name = cx.pous[p].name.clone();
        let span = cx.pous[p].name_span();
        cx.error(file, span, format!("`{name}` needs {} bytes of frame (limit 1 MiB)", b.frame));
    }
    b
}

/// The copies of a program instance's arguments (`instance_args`), written in `file`: code of
/// the instance, its variables relative to it as its body's are, without an end of its own.
pub fn compile_copies(cx: &mut Ctx<'_>, file: usize, copies: &[TStmt]) -> Body {
    let mut em = Em {
        cx,
        kind: PouKind::Program,
        file,
        b: Body::default(),
        line: copies.first().map_or(0, |s| s.line),
        sp: 0,
        max_sp: 0,
        tmp: 0,
        loops: Vec::new(),
        returns: Vec::new(),
        depth_reported: false,
        labels: Default::default(),
    };
    em.stmts(copies);
    em.b
}

/// A PROGRAM's body with one instance's argument copies: `inputs` first, then the body, then
/// `outputs` where the body's final `End` was (so a RETURN, a jump to it, copies the outputs
/// too), then the `End`, still the statement of `END_PROGRAM`. The copies' temporaries share
/// the frame with the body's `VAR_TEMP`, which is set up after them and dead before them.
pub fn with_copies(body: &Body, inputs: &Body, outputs: &Body) -> Body {
    let mut out =
        Body { frame: body.frame.max(inputs.frame).max(outputs.frame), ..Body::default() };
    let end = body.code.len() - 1;
    debug_assert!(matches!(body.code[end], Op::End));
    for (part, len) in [(inputs, inputs.code.len()), (body, end), (outputs, outputs.code.len())] {
        let start = out.code.len();
        let first_const = out.consts.len() as u32;
        out.consts.extend_from_slice(&part.consts);
        let shift = start as u32;
        out.code.extend(part.code[..len].iter().map(|op| match *op {
            Op::Goto(t) => Op::Goto(t + shift),
            Op::GotoIf { target, when } => Op::GotoIf { target: target + shift, when },
            Op::PushConst(i) => Op::PushConst(i + first_const),
            other => other,
        }));
        out.lines.extend_from_slice(&part.lines[..len]);
        let inside = |at: &usize| *at < len;
        out.statements
            .extend(part.statements.iter().filter(|&&pc| (pc as usize) < len).map(|pc| pc + shift));
        out.var_relocs.extend(part.var_relocs.iter().filter(|r| inside(r)).map(|r| r + start));
        out.callee_relocs
            .extend(part.callee_relocs.iter().filter(|r| inside(r)).map(|r| r + start));
        out.calls
            .extend(part.calls.iter().filter(|(at, _)| inside(at)).map(|&(at, c)| (at + start, c)));
    }
    out.statements.push(out.code.len() as u32);
    out.code.push(Op::End);
    out.lines.push(body.lines[end]);
    out
}
