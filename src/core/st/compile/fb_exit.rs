//! `FB_exit` (CODESYS, TwinCAT): the method a function block (or class) declares to run before
//! an instance's memory is given up. In plcd that is when a RUN ends (STOP from RUN or DEBUG):
//! the next RUN start starts every variable from its initial value again and runs `FB_init`
//! (compile/fb_init.rs), and a load, a reset, a replacement and the daemon's shutdown all
//! stop the PLC first.
//!
//! A lowering of the syntax trees, after [`mod@super::fb_init`]'s, so that the calls it adds are
//! the user's own code (and have native code); a project without `FB_init`, `FB_exit` and
//! `FB_reinit` is compiled as before.
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
//! - The instances fresh at each call (a method's `VAR`, a function block's or a PROGRAM's
//!   `VAR_TEMP`): their `__FB_EXIT_ALL` at the end of the body and before each `RETURN`; a
//!   PROGRAM's by [`finish_program_temps`], before the other lowerings add `RETURN`s.
//! - An online change's instances whose declaration changed: the exit pass also tests
//!   [`PHASE`] and a flag per PROGRAM variable with a life cycle ([`copy_flag`]), to run on
//!   the selected variables `__FB_EXIT_ALL(bInCopyCode := TRUE)` (phase 1, the old engine) or
//!   `FB_reinit()` (phase 3, the new engine after the carry-over); phase 2, `__FB_INIT_ALL`
//!   with `bInCopyCode` TRUE, is compile/fb_init.rs's, which knows the declaration arguments.
//!   The global instances likewise: hidden globals [`GLOBALS_PHASE`] and a flag per global
//!   instance with a life cycle ([`global_copy_flag`]), which the exit pass tests to run the
//!   hidden FUNCTION `__FB_EXIT_GLOBALS_COPY` (phases 1 and 3; phase 2 calls fb_init.rs's
//!   `__FB_INIT_GLOBALS_COPY`).
//!
//! Checked here: an `FB_exit` declares `bInCopyCode : BOOL` as its first VAR_INPUT (CODESYS's
//! C0565).

use std::borrow::Cow;
use std::collections::HashMap;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, Arg, Expr, ExprKind, Ident, Item, Literal, Pou, PouKind, Span, Stmt, StmtKind, TypeRef,
    UnaryOp, VarDecl, VarKind,
};

use super::fb_init::INIT_ALL;
use super::lifecycle::{
    block, bool_decl, counter_block, global_instances, has_work, hidden_pou, holds_instances,
    ident, instance_with_work, instances, name, stmt, Blocks,
};
use crate::st::dialect::Habit;

/// The hidden method that finishes an instance (its `FB_exit`, its instances, its base).
pub const EXIT_ALL: &str = "__FB_EXIT_ALL";
/// The name CODESYS gives the finishing method.
pub const FB_EXIT: &str = "FB_exit";
/// A PROGRAM's request flag, which the engine sets to run its exit pass.
pub const REQUEST: &str = "__FB_EXIT_REQUEST";
/// The global request flag: the exit pass finishes the global instances.
pub const GLOBALS_REQUEST: &str = "__FB_EXIT_GLOBALS_REQUEST";
/// A PROGRAM's phase of an online change, which the engine sets to run a pass over the
/// instances whose declaration changed ([`copy_flag`]): 1 their `FB_exit(bInCopyCode :=
/// TRUE)` on the old copy, 2 their `FB_init(bInitRetains := FALSE, bInCopyCode := TRUE)` on
/// the new (compile/fb_init.rs writes that one), 3 their `FB_reinit()` on the new, after the
/// values were carried over; and 4 the `FB_init(bInitRetains := TRUE, bInCopyCode := FALSE)`
/// of an instance the change adds to a kept PROGRAM (compile/fb_init.rs's too).
pub const PHASE: &str = "__FB_EXIT_PHASE";
const LIVE: &str = "__FB_EXIT_LIVE";
/// The hidden DINT counters of the loops over arrays of instances: `__FB_EXIT_I1`, ….
const COUNTER: &str = "__FB_EXIT_I";
const FB_REINIT: &str = "FB_reinit";
const GLOBALS_LIVE: &str = "__FB_EXIT_GLOBALS_LIVE";
const GLOBALS_EXIT: &str = "__FB_EXIT_GLOBALS";
const IN_COPY_CODE: &str = "bInCopyCode";
/// The habit the parser notes for each `__NEW`.
const NEW: Habit = Habit::DynamicMemory("__NEW");

/// Whether `name` is `FB_exit` or the hidden [`EXIT_ALL`]: methods each block declares for
/// itself, called without dispatch (a derived block's `FB_exit` does not replace its base's).
pub fn is_finaliser(name: &str) -> bool {
    name.eq_ignore_ascii_case(FB_EXIT) || name.eq_ignore_ascii_case(EXIT_ALL)
}

/// The flag by which the engine selects a PROGRAM's variable `v` for a phase of an online
/// change ([`PHASE`]).
pub fn copy_flag(v: &str) -> String {
    format!("__FB_EXIT_COPY_{v}")
}

/// The phase of an online change over the global instances whose declaration changed (the
/// numbers of [`PHASE`]: 1, 2, 3), which the engine sets, with their flags
/// ([`global_copy_flag`]), to run the hidden FUNCTION `__FB_EXIT_GLOBALS_COPY` in a PROGRAM's exit
/// pass.
pub const GLOBALS_PHASE: &str = "__FB_EXIT_GLOBALS_PHASE";
const GLOBALS_COPY: &str = "__FB_EXIT_GLOBALS_COPY";

/// The flag by which the engine selects global `v` for a phase of an online change.
pub fn global_copy_flag(v: &str) -> String {
    format!("__FB_EXIT_GCOPY_{v}")
}

/// What a block's instances go through, besides `FB_exit` (by block name in lower case).
struct Life {
    /// `__FB_INIT_ALL` in its chain (compile/fb_init.rs added it).
    init: HashMap<String, bool>,
    /// `FB_reinit` in its chain.
    reinit: HashMap<String, bool>,
}

/// Whether block `name` or one of its bases declares a method `method`.
fn in_chain(files: &[Cow<'_, ast::File>], blocks: &Blocks, name: &str, method: &str) -> bool {
    let mut at = Some(name.to_ascii_lowercase());
    for _ in 0..=blocks.len() {
        let Some(&(f, i)) = at.as_ref().and_then(|n| blocks.get(n)) else { return false };
        let Item::Pou(p) = &files[f].items[i] else { return false };
        if p.oop.methods.iter().any(|m| m.pou.name.is(method)) {
            return true;
        }
        at = p.oop.extends.as_ref().map(|b| b.name.to_ascii_lowercase());
    }
    false
}

/// Each function block's place, and whether it has something to finish ([`has_work`] with
/// its own `FB_exit`), by its name in lower case.
fn exit_work(files: &[Cow<'_, ast::File>]) -> (Blocks, HashMap<String, bool>) {
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
    let mut needs: HashMap<String, bool> = HashMap::new();
    let names: Vec<String> = blocks.keys().cloned().collect();
    for name in &names {
        has_work(files, &blocks, name, &own_fb_exit, &mut needs, &mut Vec::new());
    }
    (blocks, needs)
}

/// Finishes the instances in a PROGRAM's `VAR_TEMP` (fresh at each scan, as CODESYS has
/// them) when the body's call ends: at its END and before each `RETURN` written in it, from
/// the last declared, with `bInCopyCode` FALSE. A lowering that runs before
/// compile/fb_init.rs's: the `RETURN`s that lowering and [`lower`] put at the start of the
/// body (the phases of an online change, the exit pass) end passes that never reach the
/// user's statements nor the temporaries' `FB_init`, so they must finish nothing. The loop
/// counters over arrays are the body's own temporaries (the same names as the exit pass's,
/// declared once).
pub(super) fn finish_program_temps(files: Vec<Cow<'_, ast::File>>) -> Vec<Cow<'_, ast::File>> {
    let (_, needs) = exit_work(&files);
    if !needs.values().any(|&n| n) {
        return files;
    }
    let mut files = files;
    for file in files.iter_mut() {
        let wants = file.items.iter().any(|item| {
            matches!(item, Item::Pou(p) if p.kind == PouKind::Program
                && !fresh_instances(p, &needs).is_empty())
        });
        if !wants {
            continue;
        }
        for item in file.to_mut().items.iter_mut() {
            let Item::Pou(p) = item else { continue };
            if p.kind == PouKind::Program {
                let counters = finish_fresh(p, &needs);
                p.vars.extend(counter_block(COUNTER, counters, p.name.span).map(|mut b| {
                    b.kind = VarKind::Temp;
                    b
                }));
            }
        }
    }
    files
}

pub(super) fn lower<'f>(
    mut files: Vec<Cow<'f, ast::File>>,
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, ast::File>> {
    let (blocks, needs) = exit_work(&files);
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
    let names: Vec<String> = blocks.keys().cloned().collect();
    let life = Life {
        init: names.iter().map(|n| (n.clone(), in_chain(&files, &blocks, n, INIT_ALL))).collect(),
        reinit: names
            .iter()
            .map(|n| (n.clone(), in_chain(&files, &blocks, n, FB_REINIT)))
            .collect(),
    };
    let any = |m: &HashMap<String, bool>| m.values().any(|&n| n);
    if !any(&needs) && !any(&life.init) && !any(&life.reinit) {
        return files;
    }
    let globals = global_instances(&files, &needs);
    // the function blocks `__NEW` made and no `__DELETE` finished: compile/heap.rs's
    // `__HEAP_EXIT_ALL`, called last by the exit pass over the global instances
    let heap = any(&needs) && files.iter().any(|f| f.habits.iter().any(|n| n.habit == NEW));
    let finishes_globals = !globals.is_empty() || heap;
    // the global instances with a life cycle, which an online change of their declaration
    // takes through the phases (as a PROGRAM's variables)
    let lifelong: HashMap<String, bool> = names
        .iter()
        .map(|n| {
            let has = |m: &HashMap<String, bool>| m.get(n).copied().unwrap_or(false);
            (n.clone(), has(&needs) || has(&life.init) || has(&life.reinit))
        })
        .collect();
    let global_lives = global_instances(&files, &lifelong);
    let init_copies = files
        .iter()
        .flat_map(|f| &f.items)
        .any(|i| matches!(i, Item::Pou(p) if p.name.name == super::fb_init::GLOBALS_COPY_INIT));
    let mut globals_placed = !finishes_globals && global_lives.is_empty();
    for file in files.iter_mut() {
        let holds_globals = !globals_placed
            && file.items.iter().any(|i| {
                matches!(i, Item::Globals(_))
                    || (heap && matches!(i, Item::Pou(p) if p.kind == PouKind::Program))
            });
        let wants = holds_globals
            || file.items.iter().any(|item| {
                matches!(item, Item::Pou(p) if p.kind == PouKind::Program
                    || own_work(p, &needs)
                    || !fresh_instances(p, &needs).is_empty()
                    || p.oop.methods.iter().any(|m| !fresh_instances(&m.pou, &needs).is_empty()))
            });
        if !wants {
            continue;
        }
        let items = &mut file.to_mut().items;
        for item in items.iter_mut() {
            let Item::Pou(p) = item else { continue };
            for m in &mut p.oop.methods {
                let counters = finish_fresh(&mut m.pou, &needs);
                m.pou.vars.extend(counter_block(COUNTER, counters, m.pou.span));
            }
            if p.kind == PouKind::FunctionBlock {
                let counters = finish_fresh(p, &needs);
                p.vars.extend(counter_block(COUNTER, counters, p.name.span));
            }
            match p.kind {
                PouKind::FunctionBlock if own_work(p, &needs) => add_exit_all(p, &needs),
                PouKind::Program => {
                    add_exit_pass(p, &needs, &life, finishes_globals, !global_lives.is_empty())
                }
                _ => {}
            }
        }
        if holds_globals {
            globals_placed = true;
            let at = items.iter().position(|i| matches!(i, Item::Globals(_))).unwrap_or(0);
            let span = match &items[at] {
                Item::Globals(b) => b.span,
                Item::Pou(p) => p.name.span,
                _ => Span::default(),
            };
            if !global_lives.is_empty() {
                let copier = globals_copier(&global_lives, &needs, &life, init_copies, span);
                items.insert(at, Item::Pou(copier));
                let mut flags: Vec<VarDecl> = global_lives
                    .iter()
                    .map(|(v, _)| bool_decl(&global_copy_flag(&v.name), span))
                    .collect();
                flags.push(VarDecl {
                    ty: TypeRef::Named(ident("DINT", span)),
                    ..bool_decl(GLOBALS_PHASE, span)
                });
                items.insert(at, Item::Globals(block(VarKind::Global, false, flags, span)));
            }
            if finishes_globals {
                items.insert(at, Item::Pou(globals_finisher(&globals, heap, span)));
                let flags = vec![bool_decl(GLOBALS_REQUEST, span), bool_decl(GLOBALS_LIVE, span)];
                items.insert(at, Item::Globals(block(VarKind::Global, false, flags, span)));
            }
        }
    }
    files
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

fn truth(b: bool, span: Span) -> Expr {
    Expr { kind: ExprKind::Literal(Literal::Bool(b)), span }
}

fn assign(target: &str, value: Expr, span: Span) -> Stmt {
    stmt(StmtKind::Assign { target: name(target, span), value }, span)
}

fn when(cond: Expr, then: Vec<Stmt>, span: Span) -> Stmt {
    stmt(StmtKind::If { branches: vec![(cond, then)], otherwise: None }, span)
}

/// `target.<method>(bInCopyCode := copy)`.
fn call_method(target: Expr, method: &str, copy: Expr, span: Span) -> Stmt {
    let callee = Expr { kind: ExprKind::Member(Box::new(target), ident(method, span)), span };
    let args = vec![Arg::Input { name: ident(IN_COPY_CODE, span), value: copy }];
    let call = Expr { kind: ExprKind::Call { callee: Box::new(callee), args }, span };
    stmt(StmtKind::Call(call), span)
}

/// `make(element)` for variable `v` of type `ty`, or for each of its elements if an array (in
/// nested FOR loops over hidden DINT counters `__FB_EXIT_I1`, …, from the last element unless
/// `forward`), and the counters it uses.
fn each_element(
    v: &Ident,
    ty: &TypeRef,
    forward: bool,
    counters: &mut usize,
    make: &dyn Fn(Expr) -> Stmt,
) -> Stmt {
    let span = v.span;
    let mut dims: Vec<&(Expr, Expr)> = Vec::new();
    let mut at = ty;
    while let TypeRef::Array { dims: d, of, .. } = at {
        dims.extend(d.iter());
        at = of;
    }
    let counter = |k: usize| format!("{COUNTER}{k}");
    let target = if dims.is_empty() {
        name(&v.name, span)
    } else {
        let index = (1..=dims.len()).map(|k| name(&counter(k), span)).collect();
        Expr { kind: ExprKind::Index(Box::new(name(&v.name, span)), index), span }
    };
    let mut body = make(target);
    *counters = (*counters).max(dims.len());
    let minus_one = Expr {
        kind: ExprKind::Unary(
            UnaryOp::Neg,
            Box::new(Expr { kind: ExprKind::Literal(Literal::Int(1)), span }),
        ),
        span,
    };
    for (k, (lo, hi)) in dims.iter().enumerate().rev() {
        let (from, to, by) = if forward {
            ((*lo).clone(), (*hi).clone(), None)
        } else {
            ((*hi).clone(), (*lo).clone(), Some(minus_one.clone()))
        };
        body = stmt(
            StmtKind::For { var: name(&counter(k + 1), span), from, to, by, body: vec![body] },
            span,
        );
    }
    body
}

/// The calls that finish variable `v` of type `ty`, from its last element.
fn exit_variable(v: &Ident, ty: &TypeRef, copy: &dyn Fn() -> Expr, counters: &mut usize) -> Stmt {
    let span = v.span;
    each_element(v, ty, false, counters, &|target| call_method(target, EXIT_ALL, copy(), span))
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
    for &(v, ty) in instances(p, map).iter().rev() {
        body.push(exit_variable(v, ty, &copy, &mut counters));
    }
    if p.oop.extends.as_ref().is_some_and(|b| map.get(&b.name.to_ascii_lowercase()) == Some(&true))
    {
        let sup = Expr { kind: ExprKind::Deref(Box::new(name("SUPER", span))), span };
        body.push(call_method(sup, EXIT_ALL, copy(), span));
    }
    let mut vars = vec![block(VarKind::Input, false, vec![bool_decl(IN_COPY_CODE, span)], span)];
    vars.extend(counter_block(COUNTER, counters, span));
    let pou = hidden_pou(EXIT_ALL, vars, body, span, p.end);
    p.oop.methods.push(ast::Method {
        access: ast::Access::Public,
        is_abstract: false,
        is_final: false,
        pou,
    });
}

/// `FUNCTION __FB_EXIT_GLOBALS`: finishes each of `globals`, from the last, then (`heap`) the
/// function blocks still live in the heap, which their owners' `FB_exit` did not `__DELETE`.
fn globals_finisher(globals: &[(Ident, TypeRef)], heap: bool, span: Span) -> Pou {
    let copy = || truth(false, span);
    let mut counters = 0;
    let mut body: Vec<Stmt> =
        globals.iter().rev().map(|(v, ty)| exit_variable(v, ty, &copy, &mut counters)).collect();
    if heap {
        let callee = Box::new(name(super::heap::EXIT_ALL, span));
        let call = Expr { kind: ExprKind::Call { callee, args: Vec::new() }, span };
        body.push(stmt(StmtKind::Call(call), span));
    }
    let vars = counter_block(COUNTER, counters, span).into_iter().collect();
    hidden_pou(GLOBALS_EXIT, vars, body, span, span)
}

/// The variables of `p` fresh at each call whose block has something to finish: a method's
/// `VAR` and `VAR_TEMP`, a function block's or a PROGRAM's `VAR_TEMP` (the PROGRAM's are
/// finished by [`finish_program_temps`], before the body gets its generated `RETURN`s).
fn fresh_instances(p: &Pou, map: &HashMap<String, bool>) -> Vec<(Ident, TypeRef)> {
    let fresh = |kind: VarKind| match p.kind {
        PouKind::Function => matches!(kind, VarKind::Local | VarKind::Temp),
        PouKind::FunctionBlock | PouKind::Program => kind == VarKind::Temp,
    };
    let mut out = Vec::new();
    for d in p.vars.iter().filter(|b| fresh(b.kind)).flat_map(|b| &b.decls) {
        if instance_with_work(&d.ty, map).is_some() {
            out.extend(d.names.iter().map(|n| (n.clone(), d.ty.clone())));
        }
    }
    out
}

/// Finishes the instances fresh at each call of `p`'s body when the call returns (at its end
/// and before each `RETURN`), from the last, with `bInCopyCode` FALSE. Returns the array
/// counters it uses.
fn finish_fresh(p: &mut Pou, map: &HashMap<String, bool>) -> usize {
    let found = fresh_instances(p, map);
    if found.is_empty() {
        return 0;
    }
    let span = p.name.span;
    let copy = || truth(false, span);
    let mut counters = 0;
    let exits: Vec<Stmt> =
        found.iter().rev().map(|(v, ty)| exit_variable(v, ty, &copy, &mut counters)).collect();
    before_returns(&mut p.body, &exits);
    p.body.extend(exits);
    counters
}

/// Puts `exits` before each `RETURN` of `body`, at any depth (`IF TRUE THEN exits; RETURN;
/// END_IF` in its place).
fn before_returns(body: &mut [Stmt], exits: &[Stmt]) {
    for s in body.iter_mut() {
        match &mut s.kind {
            StmtKind::Return => {
                let span = s.span;
                let mut then = exits.to_vec();
                then.push(stmt(StmtKind::Return, span));
                *s = when(truth(true, span), then, span);
            }
            StmtKind::If { branches, otherwise } => {
                for (_, b) in branches {
                    before_returns(b, exits);
                }
                if let Some((_, b)) = otherwise {
                    before_returns(b, exits);
                }
            }
            StmtKind::Case { arms, otherwise, .. } => {
                for arm in arms {
                    before_returns(&mut arm.body, exits);
                }
                if let Some((_, b)) = otherwise {
                    before_returns(b, exits);
                }
            }
            StmtKind::For { body, .. }
            | StmtKind::While { body, .. }
            | StmtKind::Repeat { body, .. } => before_returns(body, exits),
            _ => {}
        }
    }
}

/// `FUNCTION __FB_EXIT_GLOBALS_COPY`: phase `phase` of an online change over the global instances
/// `lives` selected by their flags: 1, `FB_exit(bInCopyCode := TRUE)` on the old copies, from
/// the last declared; 2, compile/fb_init.rs's `__FB_INIT_GLOBALS_COPY` (when there is one:
/// `init_copies`) on the new copies; 3, `FB_reinit()` on the new copies, in declaration order
/// (the same order as a PROGRAM's variables).
fn globals_copier(
    lives: &[(Ident, TypeRef)],
    map: &HashMap<String, bool>,
    life: &Life,
    init_copies: bool,
    span: Span,
) -> Pou {
    const PHASE_INPUT: &str = "phase";
    let in_phase = |k: u128| phase_is(PHASE_INPUT, k, span);
    let selected =
        |v: &Ident, work: Stmt| when(name(&global_copy_flag(&v.name), span), vec![work], span);
    let copy_true = || truth(true, span);
    let mut counters = 0;
    let exits: Vec<Stmt> = lives
        .iter()
        .rev()
        .filter(|(_, ty)| instance_with_work(ty, map).is_some())
        .map(|(v, ty)| selected(v, exit_variable(v, ty, &copy_true, &mut counters)))
        .collect();
    let reinits: Vec<Stmt> = lives
        .iter()
        .filter(|(_, ty)| instance_with_work(ty, &life.reinit).is_some())
        .map(|(v, ty)| {
            selected(v, each_element(v, ty, true, &mut counters, &|t| reinit_call(t, span)))
        })
        .collect();
    let mut body = vec![when(in_phase(1), exits, span)];
    if init_copies {
        let callee = Box::new(name(super::fb_init::GLOBALS_COPY_INIT, span));
        let call = Expr { kind: ExprKind::Call { callee, args: Vec::new() }, span };
        body.push(when(in_phase(2), vec![stmt(StmtKind::Call(call), span)], span));
    }
    body.push(when(in_phase(3), reinits, span));
    let phase = VarDecl { ty: TypeRef::Named(ident("DINT", span)), ..bool_decl(PHASE_INPUT, span) };
    let mut vars = vec![block(VarKind::Input, false, vec![phase], span)];
    vars.extend(counter_block(COUNTER, counters, span));
    hidden_pou(GLOBALS_COPY, vars, body, span, span)
}

/// `target.FB_reinit()`.
fn reinit_call(target: Expr, span: Span) -> Stmt {
    let callee = Expr { kind: ExprKind::Member(Box::new(target), ident(FB_REINIT, span)), span };
    let call = Expr { kind: ExprKind::Call { callee: Box::new(callee), args: Vec::new() }, span };
    stmt(StmtKind::Call(call), span)
}

/// Starts program `p`'s body with its exit pass (see the module's documentation); with
/// `global_copies`, the pass also runs `__FB_EXIT_GLOBALS_COPY` when the engine asks for a phase of
/// an online change over the global instances ([`GLOBALS_PHASE`]).
fn add_exit_pass(
    p: &mut Pou,
    map: &HashMap<String, bool>,
    life: &Life,
    globals: bool,
    global_copies: bool,
) {
    let span = p.name.span;
    let copy = || truth(false, span);
    let mut counters = 0;
    let mut own = vec![assign(LIVE, truth(false, span), span)];
    for &(v, ty) in instances(p, map).iter().rev() {
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
    // the phases of an online change over the variables whose declaration changed
    let has = |m: &HashMap<String, bool>, ty: &TypeRef| instance_with_work(ty, m).is_some();
    let lives: Vec<(Ident, TypeRef)> = p
        .vars
        .iter()
        .filter(|b| holds_instances(b.kind))
        .flat_map(|b| &b.decls)
        .filter(|d| {
            instance_with_work(&d.ty, map).is_some()
                || has(&life.init, &d.ty)
                || has(&life.reinit, &d.ty)
        })
        .flat_map(|d| d.names.iter().map(|n| (n.clone(), d.ty.clone())))
        .collect();
    let in_phase = |k: u128| phase_is(PHASE, k, span);
    let selected = |v: &Ident, work: Stmt| {
        let flag = copy_flag(&v.name);
        when(name(&flag, span), vec![assign(&flag, truth(false, span), span), work], span)
    };
    let copy_true = || truth(true, span);
    let exits: Vec<Stmt> = lives
        .iter()
        .rev()
        .filter(|(_, ty)| instance_with_work(ty, map).is_some())
        .map(|(v, ty)| selected(v, exit_variable(v, ty, &copy_true, &mut counters)))
        .collect();
    let reinit = |target: Expr| reinit_call(target, span);
    let reinits: Vec<Stmt> = lives
        .iter()
        .filter(|(_, ty)| has(&life.reinit, ty))
        .map(|(v, ty)| selected(v, each_element(v, ty, true, &mut counters, &reinit)))
        .collect();
    pass.push(when(in_phase(1), exits, span));
    pass.push(when(in_phase(3), reinits, span));
    if global_copies {
        let phase = || name(GLOBALS_PHASE, span);
        let zero = Expr { kind: ExprKind::Literal(Literal::Int(0)), span };
        let asked_globals = Expr {
            kind: ExprKind::Binary(ast::BinaryOp::Ne, Box::new(phase()), Box::new(zero)),
            span,
        };
        let args = vec![Arg::Input { name: ident("phase", span), value: phase() }];
        let call = Expr {
            kind: ExprKind::Call { callee: Box::new(name(GLOBALS_COPY, span)), args },
            span,
        };
        pass.push(when(asked_globals.clone(), vec![stmt(StmtKind::Call(call), span)], span));
        asked = Expr {
            kind: ExprKind::Binary(ast::BinaryOp::Or, Box::new(asked), Box::new(asked_globals)),
            span,
        };
    }
    // phases 2 and 4 are compile/fb_init.rs's, in a PROGRAM with instances to initialise; in
    // any other they must not run the body
    let phases: &[u128] =
        if lives.iter().any(|(_, ty)| has(&life.init, ty)) { &[1, 3] } else { &[1, 2, 3, 4] };
    for &k in phases {
        asked = Expr {
            kind: ExprKind::Binary(ast::BinaryOp::Or, Box::new(asked), Box::new(in_phase(k))),
            span,
        };
    }
    pass.push(stmt(StmtKind::Return, span));
    let mut prologue = vec![when(asked, pass, span), assign(LIVE, truth(true, span), span)];
    if globals {
        prologue.push(assign(GLOBALS_LIVE, truth(true, span), span));
    }
    p.body.splice(0..0, prologue);
    let mut flags = vec![bool_decl(REQUEST, span), bool_decl(LIVE, span)];
    flags.extend(lives.iter().map(|(v, _)| bool_decl(&copy_flag(&v.name), span)));
    flags.push(VarDecl { ty: TypeRef::Named(ident("DINT", span)), ..bool_decl(PHASE, span) });
    p.vars.push(block(VarKind::Local, false, flags, span));
    // the counters [`finish_program_temps`] declared already serve the exit pass too
    let declared = |n: &Ident| p.vars.iter().flat_map(|b| &b.decls).any(|d| d.names[0].is(&n.name));
    let counters = counter_block(COUNTER, counters, span).map(|mut b| {
        b.decls.retain(|d| !declared(&d.names[0]));
        b
    });
    p.vars.extend(counters.filter(|b| !b.decls.is_empty()));
}

/// `phase = k`: the test of the phase variable `phase` that selects one step of a pass.
fn phase_is(phase: &str, k: u128, span: Span) -> Expr {
    let k = Expr { kind: ExprKind::Literal(Literal::Int(k)), span };
    let test = ExprKind::Binary(ast::BinaryOp::Eq, Box::new(name(phase, span)), Box::new(k));
    Expr { kind: test, span }
}
