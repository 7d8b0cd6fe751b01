//! `REF(v)` and `ADR(v)` in initial values (IEC 61131-3 3rd ed. table 12: `r : REF_TO INT :=
//! REF(counter);`, CODESYS: `p : POINTER TO INT := ADR(x);`), also as a member of a structure
//! or instance initialiser (`s : Link := (to := REF(x))`).
//!
//! A reference is the place of a variable in plcd's memory, which is known only where the
//! instance holding it is (an FB instance's place depends on its holder, a FUNCTION's frame on
//! the call), so such an initial value cannot be part of an initial image: this lowering of the
//! syntax trees turns it into an assignment that runs before the POU's own statements, checked
//! and compiled as the user's code (and so with native code). Nothing changes for a project
//! without one.
//!
//! - A FUNCTION's or a method's variables, and any `VAR_TEMP`, are fresh at each call: the
//!   assignments start the body, as every initial value of them is set at each call.
//! - A PROGRAM's or FUNCTION_BLOCK's `VAR`, `VAR_OUTPUT`, `VAR_INST`: set once, by the first call
//!   after the references were reset. A hidden reference [`DONE`] (with [`TARGET`], the BOOL it
//!   designates once set) guards them: it is `NULL` at every RUN start, after a cold restart, an
//!   online change or a reload, exactly when every other non-retained reference is `NULL`, so
//!   the references are set again whenever they lost their value, and only then (a program
//!   that sets `r := NULL` keeps it). A `RETAIN` block has its own guard [`DONE_RETAIN`], itself
//!   `RETAIN`: a warm RUN start keeps both the references and the guard, as docs/ST.md says of
//!   a retained reference.
//! - A `VAR_GLOBAL`'s: the hidden global guards [`GLOBALS_DONE`] (and [`GLOBALS_DONE_RETAIN`]
//!   for a `VAR_GLOBAL RETAIN`), and every PROGRAM's body starts with their assignments, which
//!   whichever program runs first makes.
//! - A `VAR_STAT`'s: once for every instance of the POU, guarded by the hidden `VAR_STAT`s
//!   [`DONE_STATIC`] and [`TARGET_STATIC`]; a method's `VAR_STAT`'s alike, by hidden
//!   `VAR_STAT`s of the method.
//! - An array's initialiser: each element that takes a reference becomes an assignment to
//!   that element, placed by the bounds of the declaration's `ARRAY […] OF` (its own constant
//!   expressions, folded when compiled), and keeps its place in the initialiser as the
//!   element's default (`1()`).
//!
//! Refused here: such an initial value for a `VAR_INPUT` or `VAR_IN_OUT` (the caller gives
//! them; an assignment in the body would overwrite the argument) and in a CONSTANT block (a
//! constant is a constant expression). An array initialiser inside a structure's is placed by
//! the member's type in the STRUCT type's declaration; one of an array type declared by name
//! keeps the usual message (a constant expression is needed). A CONFIGURATION's `VAR_GLOBAL`s
//! are globals as the others.

use std::borrow::Cow;
use std::collections::HashMap;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, ArrayInit, BinaryOp, Expr, ExprKind, Init, Item, Literal, Pou, PouKind, Span, Stmt,
    StmtKind, TypeRef, VarBlock, VarDecl, VarKind,
};

use super::lifecycle::{block, bool_decl, ident, name, stmt};

/// The guard of a POU's non-retained references: `NULL` until they are set.
const DONE: &str = "__REF_INIT_DONE";
/// The guard of a POU's `RETAIN` references.
const DONE_RETAIN: &str = "__REF_INIT_DONE_RETAIN";
/// The BOOL the guards designate once their references are set.
const TARGET: &str = "__REF_INIT_TARGET";
/// The guard of a POU's `VAR_STAT` references, and the BOOL it designates: `VAR_STAT`s
/// themselves, one for every instance, so the first call of any instance sets them.
const DONE_STATIC: &str = "__REF_INIT_DONE_STAT";
const TARGET_STATIC: &str = "__REF_INIT_TARGET_STAT";
/// The guards of the globals' references, and the BOOL they designate.
const GLOBALS_DONE: &str = "__REF_INIT_GLOBALS_DONE";
const GLOBALS_DONE_RETAIN: &str = "__REF_INIT_GLOBALS_DONE_RETAIN";
const GLOBALS_TARGET: &str = "__REF_INIT_GLOBALS_TARGET";

/// Whether `name` is one of the variables this lowering declares (exempt from the rule that
/// reserves names starting with `__` to plcd).
pub fn is_hidden(name: &str) -> bool {
    name.get(..11).is_some_and(|p| p.eq_ignore_ascii_case("__REF_INIT_"))
}

/// The assignments a POU's (or the globals') reference initial values became, by guard.
#[derive(Default)]
struct Found {
    /// Set at each call (a FUNCTION's, a method's variables, a `VAR_TEMP`).
    each_call: Vec<Stmt>,
    /// Set once, guarded by [`DONE`].
    once: Vec<Stmt>,
    /// Set once, guarded by [`DONE_RETAIN`].
    once_retained: Vec<Stmt>,
    /// Set once for every instance, guarded by [`DONE_STATIC`].
    once_static: Vec<Stmt>,
}

pub(super) fn lower<'f>(
    mut files: Vec<Cow<'f, ast::File>>,
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, ast::File>> {
    // a STRUCT type's references, moved into its variables' declarations first
    super::ref_init_types::lower(&mut files, diags);
    if !files.iter().any(|f| f.items.iter().any(has_reference_init)) {
        return files;
    }
    let structs = struct_members(&files);
    let mut globals = Found::default();
    let mut globals_file = None;
    for (f, file) in files.iter_mut().enumerate() {
        if !file.items.iter().any(has_reference_init) {
            continue;
        }
        let path = file.path.clone();
        for item in file.to_mut().items.iter_mut() {
            let took_globals = match item {
                Item::Pou(p) => {
                    lower_pou(p, &structs, &path, diags);
                    false
                }
                Item::Globals(b) => take_globals(b, &structs, &mut globals, &path, diags),
                // a CONFIGURATION's globals are the project's, set as the others
                Item::Configuration(c) => {
                    let mut took = false;
                    for b in &mut c.globals {
                        took |= take_globals(b, &structs, &mut globals, &path, diags);
                    }
                    took
                }
                _ => false,
            };
            if took_globals {
                globals_file.get_or_insert(f);
            }
        }
    }
    if let Some(f) = globals_file {
        let span = first_span(&globals);
        let items = &mut files[f].to_mut().items;
        for (k, b) in global_guards(&globals, span).into_iter().enumerate() {
            items.insert(k, Item::Globals(b));
        }
        for file in files.iter_mut() {
            for item in file.to_mut().items.iter_mut() {
                if let Item::Pou(p) = item {
                    if p.kind == PouKind::Program {
                        let prologue = guarded(&globals, GLOBALS_DONE, GLOBALS_DONE_RETAIN, span);
                        p.body.splice(0..0, prologue);
                    }
                }
            }
        }
    }
    files
}

/// Whether an item declares a variable whose initial value takes a reference.
fn has_reference_init(item: &Item) -> bool {
    let block_has = |b: &VarBlock| b.decls.iter().any(|d| d.init.as_ref().is_some_and(takes_ref));
    match item {
        Item::Pou(p) => {
            p.vars.iter().any(block_has)
                || p.oop.methods.iter().any(|m| m.pou.vars.iter().any(block_has))
        }
        Item::Globals(b) => block_has(b),
        Item::Configuration(c) => c.globals.iter().any(block_has),
        _ => false,
    }
}

/// Takes the reference initial values out of the global block `b` into `globals`; whether
/// there was one.
fn take_globals(
    b: &mut VarBlock,
    structs: &Structs,
    globals: &mut Found,
    path: &std::path::Path,
    diags: &mut Vec<Diagnostic>,
) -> bool {
    let mut out = Vec::new();
    take_from_block(b, structs, &mut out, path, diags);
    let any = !out.is_empty();
    if b.retain {
        globals.once_retained.extend(out);
    } else {
        globals.once.extend(out);
    }
    any
}

/// Whether an initial value calls `REF` or `ADR` somewhere.
pub(super) fn takes_ref(init: &Init) -> bool {
    match init {
        Init::Expr(e) => calls_ref(e),
        Init::Struct { members, .. } => members.iter().any(|(_, i)| takes_ref(i)),
        Init::Array { elems, .. } => elems.iter().any(|e| match e {
            ArrayInit::One(v) | ArrayInit::Repeat { value: Some(v), .. } => takes_ref(v),
            ArrayInit::Repeat { value: None, .. } => false,
        }),
    }
}

fn calls_ref(e: &Expr) -> bool {
    match &e.kind {
        ExprKind::Call { callee, args } => {
            matches!(&callee.kind, ExprKind::Name(id) if id.is("REF") || id.is("ADR"))
                || args.iter().any(|a| match a {
                    ast::Arg::Positional(v) | ast::Arg::Input { value: v, .. } => calls_ref(v),
                    _ => false,
                })
        }
        ExprKind::Unary(_, a) => calls_ref(a),
        ExprKind::Binary(_, a, b) => calls_ref(a) || calls_ref(b),
        _ => false,
    }
}

/// Each STRUCT type's members and their types as declared, by the lower-case names of the
/// type and the member: what places an array initialiser inside a structure's
/// (`(arr := [REF(a), REF(b)])`).
type Structs = HashMap<String, HashMap<String, TypeRef>>;

fn struct_members(files: &[Cow<'_, ast::File>]) -> Structs {
    let mut structs = Structs::new();
    for file in files {
        for item in &file.items {
            let Item::Type(t) = item else { continue };
            let ast::TypeDef::Struct { members } = &t.def else { continue };
            let types = members
                .iter()
                .flat_map(|d| d.names.iter().map(|id| (id.name.to_ascii_lowercase(), d.ty.clone())))
                .collect();
            structs.insert(t.name.name.to_ascii_lowercase(), types);
        }
    }
    structs
}

/// The declared type of member `member` of `ty`, a STRUCT type named by its name.
fn member_type<'s>(
    structs: &'s Structs,
    ty: Option<&TypeRef>,
    member: &str,
) -> Option<&'s TypeRef> {
    let Some(TypeRef::Named(id)) = ty else { return None };
    structs.get(&id.name.to_ascii_lowercase())?.get(&member.to_ascii_lowercase())
}

/// Lowers `p`'s reference initial values (and its methods').
fn lower_pou(p: &mut Pou, structs: &Structs, path: &std::path::Path, diags: &mut Vec<Diagnostic>) {
    for m in &mut p.oop.methods {
        let mut each_call = Vec::new();
        let mut once_static = Vec::new();
        for b in &mut m.pou.vars {
            if b.kind == VarKind::Static {
                take_from_block(b, structs, &mut once_static, path, diags);
            } else {
                take_from_block(b, structs, &mut each_call, path, diags);
            }
        }
        // a method's VAR_STAT: once for every call of every instance, guarded by hidden
        // VAR_STATs of the method as a POU's are
        if !once_static.is_empty() {
            let span = m.pou.name.span;
            let guards = vec![guard_decl(DONE_STATIC, span), bool_decl(TARGET_STATIC, span)];
            m.pou.vars.push(block(VarKind::Static, false, guards, span));
            let sets = Found { once: once_static, ..Found::default() };
            each_call.extend(guarded(&sets, DONE_STATIC, DONE_STATIC, span));
        }
        m.pou.body.splice(0..0, each_call);
    }
    if p.oop.is_class && p.body.is_empty() && p.kind == PouKind::FunctionBlock {
        // a CLASS has no body to run them: the usual message stays (none is taken)
        return;
    }
    let fresh_each_call = p.kind == PouKind::Function;
    let mut found = Found::default();
    for b in &mut p.vars {
        let mut out = Vec::new();
        take_from_block(b, structs, &mut out, path, diags);
        if b.kind == VarKind::Static {
            found.once_static.extend(out);
        } else if fresh_each_call || b.kind == VarKind::Temp {
            found.each_call.extend(out);
        } else if b.retain {
            found.once_retained.extend(out);
        } else {
            found.once.extend(out);
        }
    }
    let span = p.name.span;
    let mut prologue = std::mem::take(&mut found.each_call);
    if !found.once.is_empty() || !found.once_retained.is_empty() {
        p.vars.extend(local_guards(&found, span));
        prologue.extend(guarded(&found, DONE, DONE_RETAIN, span));
    }
    if !found.once_static.is_empty() {
        let guards = vec![guard_decl(DONE_STATIC, span), bool_decl(TARGET_STATIC, span)];
        p.vars.push(block(VarKind::Static, false, guards, span));
        let sets = Found { once: std::mem::take(&mut found.once_static), ..Found::default() };
        prologue.extend(guarded(&sets, DONE_STATIC, DONE_STATIC, span));
    }
    p.body.splice(0..0, prologue);
}

/// Takes the reference initial values out of block `b` as assignments (pushed on `out`); the
/// variables then start `NULL` (or with the rest of their initialiser) until they run.
fn take_from_block(
    b: &mut VarBlock,
    structs: &Structs,
    out: &mut Vec<Stmt>,
    path: &std::path::Path,
    diags: &mut Vec<Diagnostic>,
) {
    let kind = b.kind;
    if kind == VarKind::External {
        return;
    }
    for d in &mut b.decls {
        let Some(init) = d.init.as_ref().filter(|i| takes_ref(i)) else { continue };
        let refused = if b.constant {
            Some("a CONSTANT's initial value cannot be a reference (`REF`, `ADR`): a constant is a constant expression, and a place is known only when the program runs; declare the reference in VAR")
        } else if matches!(kind, VarKind::Input | VarKind::InOut) {
            Some("an input's initial value cannot be a reference (`REF`, `ADR`): the caller gives it; declare the variable in VAR and set it there")
        } else {
            None
        };
        if let Some(message) = refused {
            let at = init_span(init).unwrap_or(d.span);
            diags.push(Diagnostic::new(path, at.line, at.col, message));
            d.init = None;
            continue;
        }
        let mut left = None;
        for id in &d.names {
            left = d.init.clone();
            take_from_init(&mut left, name(&id.name, id.span), Some(&d.ty), structs, out);
        }
        // every name of the declaration keeps what is left of it (the same for each)
        d.init = left;
    }
}

/// Moves the parts of `init` that take a reference into assignments to `target` (or to its
/// members, its elements), leaving the constant parts; `ty` is `target`'s type where it is
/// written (an array's elements are taken only from an `ARRAY […] OF` written so, whose bounds
/// place them), a member's found in its STRUCT type's declaration in `structs`.
fn take_from_init(
    init: &mut Option<Init>,
    target: Expr,
    ty: Option<&TypeRef>,
    structs: &Structs,
    out: &mut Vec<Stmt>,
) {
    match init {
        Some(Init::Expr(e)) if calls_ref(e) => {
            let span = e.span;
            out.push(stmt(StmtKind::Assign { target, value: e.clone() }, span));
            *init = None;
        }
        Some(Init::Struct { members, .. }) => {
            let mut kept = Vec::new();
            for (id, member_init) in std::mem::take(members) {
                let member = Expr {
                    kind: ExprKind::Member(Box::new(target.clone()), id.clone()),
                    span: id.span,
                };
                let mut member_init = Some(member_init);
                let member_ty = member_type(structs, ty, &id.name);
                take_from_init(&mut member_init, member, member_ty, structs, out);
                if let Some(left) = member_init {
                    kept.push((id, left));
                }
            }
            *members = kept;
        }
        Some(Init::Array { elems, .. }) => {
            let Some(TypeRef::Array { dims, of, .. }) = ty else { return };
            // the flat position of each element: every count before a reference a literal
            let counts: Option<Vec<u128>> = elems
                .iter()
                .map(|e| match e {
                    ArrayInit::One(_) => Some(1),
                    ArrayInit::Repeat { count, .. } => match count.kind {
                        ExprKind::Literal(Literal::Int(n)) => Some(n),
                        _ => None,
                    },
                })
                .collect();
            let Some(counts) = counts else { return };
            let mut at = 0;
            let mut kept = Vec::new();
            for (elem, n) in std::mem::take(elems).into_iter().zip(counts) {
                match elem {
                    ArrayInit::One(v) | ArrayInit::Repeat { value: Some(v), .. }
                        if takes_ref(&v) =>
                    {
                        // each element of a repeat its own assignment, its place kept by the
                        // element's default (`1()`), or what is left of it
                        for k in at..at + n {
                            let mut part = Some(v.clone());
                            let element = element_of(&target, dims, k);
                            take_from_init(&mut part, element, Some(of), structs, out);
                            kept.push(match part {
                                Some(left) => ArrayInit::One(left),
                                None => ArrayInit::Repeat {
                                    count: int_literal(1, target.span),
                                    value: None,
                                },
                            });
                        }
                    }
                    other => kept.push(other),
                }
                at += n;
            }
            *elems = kept;
        }
        _ => {}
    }
}

/// The element at flat position `k` (storage order: the last index fastest) of `target`, an
/// array of the bounds `dims`: each index its lower bound plus its part of `k`, written with
/// the bounds' own constant expressions (folded when compiled).
fn element_of(target: &Expr, dims: &[(Expr, Expr)], k: u128) -> Expr {
    let span = target.span;
    let binary = |op: BinaryOp, a: Expr, b: Expr| Expr {
        kind: ExprKind::Binary(op, Box::new(a), Box::new(b)),
        span,
    };
    // the length of dimension `d`: `(hi - lo + 1)`
    let length = |d: usize| {
        let (lo, hi) = &dims[d];
        binary(BinaryOp::Add, binary(BinaryOp::Sub, hi.clone(), lo.clone()), int_literal(1, span))
    };
    let index = (0..dims.len())
        .map(|d| {
            // k / (the lengths of the later dimensions) MOD (this one's length)
            let mut part = int_literal(k, span);
            for later in d + 1..dims.len() {
                part = binary(BinaryOp::Div, part, length(later));
            }
            if d > 0 {
                part = binary(BinaryOp::Mod, part, length(d));
            }
            binary(BinaryOp::Add, dims[d].0.clone(), part)
        })
        .collect();
    Expr { kind: ExprKind::Index(Box::new(target.clone()), index), span }
}

fn int_literal(n: u128, span: Span) -> Expr {
    Expr { kind: ExprKind::Literal(Literal::Int(n)), span }
}

fn init_span(init: &Init) -> Option<Span> {
    match init {
        Init::Expr(e) => Some(e.span),
        Init::Struct { span, .. } | Init::Array { span, .. } => Some(*span),
    }
}

fn first_span(found: &Found) -> Span {
    found.once.iter().chain(&found.once_retained).map(|s| s.span).next().unwrap_or_default()
}

/// `guard : REF_TO BOOL` (without an initial value: `NULL`).
fn guard_decl(guard: &str, span: Span) -> VarDecl {
    let to = Box::new(TypeRef::Named(ident("BOOL", span)));
    VarDecl { ty: TypeRef::Ref { kind: ast::RefKind::RefTo, to, span }, ..bool_decl(guard, span) }
}

/// A POU's hidden guards: a `VAR` block with [`DONE`] and [`TARGET`], and a `VAR RETAIN` one
/// with [`DONE_RETAIN`] when a retained reference is set.
fn local_guards(found: &Found, span: Span) -> Vec<VarBlock> {
    let mut blocks = Vec::new();
    blocks.push(block(
        VarKind::Local,
        false,
        vec![guard_decl(DONE, span), bool_decl(TARGET, span)],
        span,
    ));
    if !found.once_retained.is_empty() {
        blocks.push(block(VarKind::Local, true, vec![guard_decl(DONE_RETAIN, span)], span));
    }
    blocks
}

/// The globals' hidden guards: a `VAR_GLOBAL` block with [`GLOBALS_DONE`] and
/// [`GLOBALS_TARGET`], and a `VAR_GLOBAL RETAIN` one with [`GLOBALS_DONE_RETAIN`] (kept over a
/// warm start as the retained references it guards; a reference is never written to the
/// retain files, so it is `NULL` after a restart of the daemon, as they are).
fn global_guards(found: &Found, span: Span) -> Vec<VarBlock> {
    let mut blocks = vec![block(
        VarKind::Global,
        false,
        vec![guard_decl(GLOBALS_DONE, span), bool_decl(GLOBALS_TARGET, span)],
        span,
    )];
    if !found.once_retained.is_empty() {
        blocks.push(block(
            VarKind::Global,
            true,
            vec![guard_decl(GLOBALS_DONE_RETAIN, span)],
            span,
        ));
    }
    blocks
}

/// `IF done = NULL THEN done := REF(target); … END_IF` for each guard with something to set
/// (`found.once` under `done`, `found.once_retained` under `done_retain`).
fn guarded(found: &Found, done: &str, done_retain: &str, span: Span) -> Vec<Stmt> {
    let target = match done {
        DONE => TARGET,
        DONE_STATIC => TARGET_STATIC,
        _ => GLOBALS_TARGET,
    };
    let mut out = Vec::new();
    for (guard, sets) in [(done, &found.once), (done_retain, &found.once_retained)] {
        if sets.is_empty() {
            continue;
        }
        let null = Expr { kind: ExprKind::Name(ident("NULL", span)), span };
        let cond = Expr {
            kind: ExprKind::Binary(BinaryOp::Eq, Box::new(name(guard, span)), Box::new(null)),
            span,
        };
        let reference = Expr {
            kind: ExprKind::Call {
                callee: Box::new(name("REF", span)),
                args: vec![ast::Arg::Positional(name(target, span))],
            },
            span,
        };
        let mut body =
            vec![stmt(StmtKind::Assign { target: name(guard, span), value: reference }, span)];
        body.extend(sets.iter().cloned());
        out.push(stmt(StmtKind::If { branches: vec![(cond, body)], otherwise: None }, span));
    }
    out
}
