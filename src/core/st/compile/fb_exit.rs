//! `FB_exit` (CODESYS, TwinCAT): the method a function block (or class) declares to run before
//! an instance's memory is given up. In plcd that is when a RUN ends (STOP from RUN or DEBUG):
//! the next RUN start starts every variable from its initial value again and runs `FB_init`
//! (compile/fb_init.rs), and a load, a reset, a replacement and the daemon's shutdown all
//! stop the PLC first.
//!
//! A lowering of the syntax trees, after [`mod@super::fb_init`]'s, so that the calls it adds are
//! the user's own code (and have native code); a project without `FB_exit` is compiled as
//! before.
//!
//! - Each function block with something to finish (its own `FB_exit`, its base's, or one of
//!   its instances') gets a hidden method [`EXIT_ALL`]: the reverse of `__FB_INIT_ALL`'s order,
//!   so its own `FB_exit` first, then its instances in reverse declaration order (an array's
//!   elements from the last), then its base's (`SUPER^.__FB_EXIT_ALL`): CODESYS documents a
//!   derived block's `FB_exit` before its base's.
//! - Code runs only inside a program's body, so each PROGRAM gets an *exit pass*: when the
//!   project has something to finish, every PROGRAM starts with
//!   `IF __FB_EXIT_REQUEST OR __FB_EXIT_GLOBALS_REQUEST THEN … RETURN; END_IF`, which finishes
//!   its own instances (in reverse declaration order) or the top-level `VAR_GLOBAL` instances
//!   (the hidden FUNCTION `__FB_EXIT_GLOBALS`), each once and only if it ran since the RUN
//!   start (`__FB_EXIT_LIVE`, `__FB_EXIT_GLOBALS_LIVE`: a PROGRAM that never ran had its
//!   instances never initialised). The engine (`Engine::finish_instances`) sets the request
//!   flags and runs the programs' bodies to their END, the programs in reverse order, then the
//!   globals. `bInCopyCode` is FALSE.
//!
//! Checked here: an `FB_exit` declares `bInCopyCode : BOOL` as its first VAR_INPUT (CODESYS's
//! C0565).

use std::borrow::Cow;
use std::collections::HashMap;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, Arg, Expr, ExprKind, Ident, Item, Literal, Pou, PouKind, Span, Stmt, StmtKind, TypeRef,
    UnaryOp, VarBlock, VarDecl, VarKind,
};

use super::fb_init::{holds_instances, instance_type};

/// The hidden method that finishes an instance (its `FB_exit`, its instances, its base).
pub const EXIT_ALL: &str = "__FB_EXIT_ALL";
/// The name CODESYS gives the finishing method.
pub const FB_EXIT: &str = "FB_exit";
/// A PROGRAM's request flag, which the engine sets to run its exit pass.
pub const REQUEST: &str = "__FB_EXIT_REQUEST";
/// The global request flag: the exit pass finishes the global instances.
pub const GLOBALS_REQUEST: &str = "__FB_EXIT_GLOBALS_REQUEST";
const LIVE: &str = "__FB_EXIT_LIVE";
const GLOBALS_LIVE: &str = "__FB_EXIT_GLOBALS_LIVE";
const GLOBALS_EXIT: &str = "__FB_EXIT_GLOBALS";
const IN_COPY_CODE: &str = "bInCopyCode";

/// Whether `name` is `FB_exit` or the hidden [`EXIT_ALL`]: methods each block declares for
/// itself, called without dispatch (a derived block's `FB_exit` does not replace its base's).
pub fn is_finaliser(name: &str) -> bool {
    name.eq_ignore_ascii_case(FB_EXIT) || name.eq_ignore_ascii_case(EXIT_ALL)
}

/// The function blocks of the project by name (lower case): (file, item).
type Blocks = HashMap<String, (usize, usize)>;

pub(super) fn lower<'f>(
    mut files: Vec<Cow<'f, ast::File>>,
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, ast::File>> {
    let mut blocks: Blocks = HashMap::new();
    for (f, file) in files.iter().enumerate() {
        for (i, item) in file.items.iter().enumerate() {
            if let Item::Pou(p) = item {
                if p.kind == PouKind::FunctionBlock {
                    blocks.entry(p.name.name.to_ascii_lowercase()).or_insert((f, i));
                }
            }
        }
    }
    for file in &files {
        for item in &file.items {
            let Item::Pou(p) = item else { continue };
            for m in p.oop.methods.iter().filter(|m| m.pou.name.is(FB_EXIT)) {
                if !signature_ok(&m.pou) {
                    let at = m.pou.name.span;
                    diags.push(Diagnostic::new(
                        &file.path,
                        at.line,
                        at.col,
                        "an FB_exit method declares `bInCopyCode : BOOL` as its first VAR_INPUT",
                    ));
                }
            }
        }
    }
    let mut needs: HashMap<String, bool> = HashMap::new();
    let names: Vec<String> = blocks.keys().cloned().collect();
    for name in &names {
        needs_exit(&files, &blocks, name, &mut needs, &mut Vec::new());
    }
    if !needs.values().any(|&n| n) {
        return files;
    }
    let globals = global_instances(&files, &needs);
    let mut globals_placed = globals.is_empty();
    for file in files.iter_mut() {
        let holds_globals =
            !globals_placed && file.items.iter().any(|i| matches!(i, Item::Globals(_)));
        let wants = holds_globals
            || file.items.iter().any(|item| {
                matches!(item, Item::Pou(p) if p.kind == PouKind::Program || own_work(p, &needs))
            });
        if !wants {
            continue;
        }
        let items = &mut file.to_mut().items;
        for item in items.iter_mut() {
            let Item::Pou(p) = item else { continue };
            match p.kind {
                PouKind::FunctionBlock if own_work(p, &needs) => add_exit_all(p, &needs),
                PouKind::Program => add_exit_pass(p, &needs, !globals.is_empty()),
                _ => {}
            }
        }
        if holds_globals {
            globals_placed = true;
            let at = items.iter().position(|i| matches!(i, Item::Globals(_))).unwrap_or(0);
            let span = match &items[at] {
                Item::Globals(b) => b.span,
                _ => Span::default(),
            };
            items.insert(at, Item::Pou(globals_finisher(&globals, span)));
            let flags = vec![bool_decl(GLOBALS_REQUEST, span), bool_decl(GLOBALS_LIVE, span)];
            items.insert(at, Item::Globals(block(VarKind::Global, flags, span)));
        }
    }
    files
}

/// Whether block `name` has something to finish: its `FB_exit`, its base's, or one of its
/// instances'. `path` guards against a block that holds itself (reported elsewhere).
fn needs_exit(
    files: &[Cow<'_, ast::File>],
    blocks: &Blocks,
    name: &str,
    memo: &mut HashMap<String, bool>,
    path: &mut Vec<String>,
) -> bool {
    if let Some(&n) = memo.get(name) {
        return n;
    }
    let Some(&(f, i)) = blocks.get(name) else { return false };
    if path.iter().any(|p| p == name) {
        return false;
    }
    let Item::Pou(p) = &files[f].items[i] else { return false };
    path.push(name.to_string());
    let mut needs = own_fb_exit(p);
    if let Some(base) = &p.oop.extends {
        needs |= needs_exit(files, blocks, &base.name.to_ascii_lowercase(), memo, path);
    }
    for d in p.vars.iter().filter(|b| holds_instances(b.kind)).flat_map(|b| &b.decls) {
        if let Some(of) = instance_type(&d.ty) {
            needs |= needs_exit(files, blocks, &of.to_ascii_lowercase(), memo, path);
        }
    }
    path.pop();
    memo.insert(name.to_string(), needs);
    needs
}

fn needs(ty: &TypeRef, needs: &HashMap<String, bool>) -> bool {
    instance_type(ty).is_some_and(|n| needs.get(&n.to_ascii_lowercase()).copied().unwrap_or(false))
}

/// The variables of `p` to finish, with their types, in declaration order.
fn instances(p: &Pou, map: &HashMap<String, bool>) -> Vec<(Ident, TypeRef)> {
    let mut out = Vec::new();
    for d in p.vars.iter().filter(|b| holds_instances(b.kind)).flat_map(|b| &b.decls) {
        if needs(&d.ty, map) {
            out.extend(d.names.iter().map(|n| (n.clone(), d.ty.clone())));
        }
    }
    out
}

/// The top-level `VAR_GLOBAL` instances to finish, in the order of the files and of their
/// declarations.
fn global_instances(
    files: &[Cow<'_, ast::File>],
    map: &HashMap<String, bool>,
) -> Vec<(Ident, TypeRef)> {
    let mut out = Vec::new();
    for file in files {
        for item in &file.items {
            let Item::Globals(b) = item else { continue };
            for d in b.decls.iter().filter(|d| needs(&d.ty, map)) {
                out.extend(d.names.iter().map(|n| (n.clone(), d.ty.clone())));
            }
        }
    }
    out
}

/// Whether block `p` finishes something itself (its `FB_exit` or its instances).
fn own_work(p: &Pou, map: &HashMap<String, bool>) -> bool {
    p.kind == PouKind::FunctionBlock && (own_fb_exit(p) || !instances(p, map).is_empty())
}

/// Whether block `p` declares an `FB_exit` to call (one with the wrong signature is reported,
/// and not called).
fn own_fb_exit(p: &Pou) -> bool {
    p.oop.methods.iter().any(|m| m.pou.name.is(FB_EXIT) && signature_ok(&m.pou))
}

/// `bInCopyCode : BOOL` first among the VAR_INPUTs.
fn signature_ok(m: &Pou) -> bool {
    let first = m
        .vars
        .iter()
        .filter(|b| b.kind == VarKind::Input)
        .flat_map(|b| &b.decls)
        .flat_map(|d| d.names.iter().map(move |n| (n, &d.ty)))
        .next();
    matches!(first, Some((n, TypeRef::Named(t))) if n.is(IN_COPY_CODE) && t.is("BOOL"))
}

fn ident(name: &str, span: Span) -> Ident {
    Ident { name: name.to_string(), span }
}

fn name(n: &str, span: Span) -> Expr {
    Expr { kind: ExprKind::Name(ident(n, span)), span }
}

fn truth(b: bool, span: Span) -> Expr {
    Expr { kind: ExprKind::Literal(Literal::Bool(b)), span }
}

fn stmt(kind: StmtKind, span: Span) -> Stmt {
    Stmt { kind, span }
}

fn assign(target: &str, value: Expr, span: Span) -> Stmt {
    stmt(StmtKind::Assign { target: name(target, span), value }, span)
}

fn when(cond: Expr, then: Vec<Stmt>, span: Span) -> Stmt {
    stmt(StmtKind::If { branches: vec![(cond, then)], otherwise: None }, span)
}

fn bool_decl(n: &str, span: Span) -> VarDecl {
    VarDecl {
        names: vec![ident(n, span)],
        location: None,
        ty: TypeRef::Named(ident("BOOL", span)),
        init: None,
        edge: None,
        span,
    }
}

fn block(kind: VarKind, decls: Vec<VarDecl>, span: Span) -> VarBlock {
    VarBlock { kind, constant: false, retain: false, span, decls }
}

/// `target.<method>(bInCopyCode := copy)`.
fn call_method(target: Expr, method: &str, copy: Expr, span: Span) -> Stmt {
    let callee = Expr { kind: ExprKind::Member(Box::new(target), ident(method, span)), span };
    let args = vec![Arg::Input { name: ident(IN_COPY_CODE, span), value: copy }];
    let call = Expr { kind: ExprKind::Call { callee: Box::new(callee), args }, span };
    stmt(StmtKind::Call(call), span)
}

/// The calls that finish variable `v` of type `ty` (each element of an array from the last, in
/// nested FOR loops over hidden DINT counters `__FB_EXIT_I1`, …), and the counters they use.
fn exit_variable(v: &Ident, ty: &TypeRef, copy: &dyn Fn() -> Expr, counters: &mut usize) -> Stmt {
    let span = v.span;
    let mut dims: Vec<&(Expr, Expr)> = Vec::new();
    let mut at = ty;
    while let TypeRef::Array { dims: d, of, .. } = at {
        dims.extend(d.iter());
        at = of;
    }
    let counter = |k: usize| format!("__FB_EXIT_I{k}");
    let target = if dims.is_empty() {
        name(&v.name, span)
    } else {
        let index = (1..=dims.len()).map(|k| name(&counter(k), span)).collect();
        Expr { kind: ExprKind::Index(Box::new(name(&v.name, span)), index), span }
    };
    let mut body = call_method(target, EXIT_ALL, copy(), span);
    *counters = (*counters).max(dims.len());
    let minus_one = Expr {
        kind: ExprKind::Unary(
            UnaryOp::Neg,
            Box::new(Expr { kind: ExprKind::Literal(Literal::Int(1)), span }),
        ),
        span,
    };
    for (k, (lo, hi)) in dims.iter().enumerate().rev() {
        body = stmt(
            StmtKind::For {
                var: ident(&counter(k + 1), span),
                from: hi.clone(),
                to: lo.clone(),
                by: Some(minus_one.clone()),
                body: vec![body],
            },
            span,
        );
    }
    body
}

fn counter_block(counters: usize, span: Span) -> Option<VarBlock> {
    (counters > 0).then(|| {
        let decls = (1..=counters)
            .map(|k| VarDecl {
                ty: TypeRef::Named(ident("DINT", span)),
                ..bool_decl(&format!("__FB_EXIT_I{k}"), span)
            })
            .collect();
        block(VarKind::Local, decls, span)
    })
}

fn hidden_method(name: &str, vars: Vec<VarBlock>, body: Vec<Stmt>, span: Span, end: Span) -> Pou {
    Pou {
        kind: PouKind::Function,
        name: ident(name, span),
        return_type: None,
        vars,
        body,
        actions: Vec::new(),
        oop: ast::Oop::default(),
        sfc: None,
        span,
        end,
    }
}

/// Adds `METHOD __FB_EXIT_ALL` to block `p`.
fn add_exit_all(p: &mut Pou, map: &HashMap<String, bool>) {
    let span = p.name.span;
    let copy = || name(IN_COPY_CODE, span);
    let mut body = Vec::new();
    if own_fb_exit(p) {
        let call = Expr {
            kind: ExprKind::Call {
                callee: Box::new(name(FB_EXIT, span)),
                args: vec![Arg::Input { name: ident(IN_COPY_CODE, span), value: copy() }],
            },
            span,
        };
        body.push(stmt(StmtKind::Call(call), span));
    }
    let mut counters = 0;
    for (v, ty) in instances(p, map).iter().rev() {
        body.push(exit_variable(v, ty, &copy, &mut counters));
    }
    if p.oop.extends.as_ref().is_some_and(|b| map.get(&b.name.to_ascii_lowercase()) == Some(&true))
    {
        let sup = Expr { kind: ExprKind::Deref(Box::new(name("SUPER", span))), span };
        body.push(call_method(sup, EXIT_ALL, copy(), span));
    }
    let mut vars = vec![block(VarKind::Input, vec![bool_decl(IN_COPY_CODE, span)], span)];
    vars.extend(counter_block(counters, span));
    let pou = hidden_method(EXIT_ALL, vars, body, span, p.end);
    p.oop.methods.push(ast::Method {
        access: ast::Access::Public,
        is_abstract: false,
        is_final: false,
        pou,
    });
}

/// `FUNCTION __FB_EXIT_GLOBALS`: finishes each of `globals`, from the last.
fn globals_finisher(globals: &[(Ident, TypeRef)], span: Span) -> Pou {
    let copy = || truth(false, span);
    let mut counters = 0;
    let body =
        globals.iter().rev().map(|(v, ty)| exit_variable(v, ty, &copy, &mut counters)).collect();
    let vars = counter_block(counters, span).into_iter().collect();
    hidden_method(GLOBALS_EXIT, vars, body, span, span)
}

/// Starts program `p`'s body with its exit pass (see the module's documentation).
fn add_exit_pass(p: &mut Pou, map: &HashMap<String, bool>, globals: bool) {
    let span = p.name.span;
    let copy = || truth(false, span);
    let mut counters = 0;
    let mut own = vec![assign(LIVE, truth(false, span), span)];
    for (v, ty) in instances(p, map).iter().rev() {
        own.push(exit_variable(v, ty, &copy, &mut counters));
    }
    let mut pass = vec![when(
        name(REQUEST, span),
        vec![assign(REQUEST, truth(false, span), span), when(name(LIVE, span), own, span)],
        span,
    )];
    let mut asked = name(REQUEST, span);
    if globals {
        let call = Expr {
            kind: ExprKind::Call { callee: Box::new(name(GLOBALS_EXIT, span)), args: Vec::new() },
            span,
        };
        let finish =
            vec![assign(GLOBALS_LIVE, truth(false, span), span), stmt(StmtKind::Call(call), span)];
        pass.push(when(
            name(GLOBALS_REQUEST, span),
            vec![
                assign(GLOBALS_REQUEST, truth(false, span), span),
                when(name(GLOBALS_LIVE, span), finish, span),
            ],
            span,
        ));
        asked = Expr {
            kind: ExprKind::Binary(
                ast::BinaryOp::Or,
                Box::new(asked),
                Box::new(name(GLOBALS_REQUEST, span)),
            ),
            span,
        };
    }
    pass.push(stmt(StmtKind::Return, span));
    let mut prologue = vec![when(asked, pass, span), assign(LIVE, truth(true, span), span)];
    if globals {
        prologue.push(assign(GLOBALS_LIVE, truth(true, span), span));
    }
    p.body.splice(0..0, prologue);
    p.vars.push(block(VarKind::Local, vec![bool_decl(REQUEST, span), bool_decl(LIVE, span)], span));
    p.vars.extend(counter_block(counters, span));
}
