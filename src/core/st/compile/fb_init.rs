//! `FB_init` (CODESYS, TwinCAT): the method a function block (or class) declares to initialise
//! each of its instances, before the first scan for the instances a PROGRAM or a `VAR_GLOBAL`
//! holds, at each call for those a FUNCTION's or a method's `VAR` (or any `VAR_TEMP`) holds.
//!
//! A lowering of the syntax trees before compilation, so that every call it adds is checked
//! and compiled as the user's own code (and so has native code): nothing changes for a project
//! without an `FB_init`.
//!
//! - Each function block with something to initialise (its own `FB_init`, or a variable holding
//!   an instance of a block that has) gets a hidden method [`INIT_ALL`]: its base's first
//!   (`SUPER^.__FB_INIT_ALL`), then each of its instances in declaration order (an array's
//!   elements in index order), then its own `FB_init`, which CODESYS documents: a base's
//!   `FB_init` before a derived block's, an embedded instance initialised before the block
//!   that holds it.
//! - Each PROGRAM holding such instances gets a hidden `__FB_INIT_DONE : BOOL`, FALSE at every
//!   RUN start, and its body starts with `IF NOT __FB_INIT_DONE THEN … END_IF`: its instances'
//!   `__FB_INIT_ALL`. `bInitRetains` is TRUE when the RETAIN variables started from their
//!   initial values (a hidden `VAR RETAIN __FB_INIT_RETAINED`, set at the first run, says they
//!   did not: a warm start keeps it); `bInCopyCode` is FALSE (an online change keeps the
//!   instances and the flag: `FB_init` is not called again). Before all that, when the engine
//!   asks for phase 2 of an online change (compile/fb_exit.rs), the PROGRAM's selected
//!   variables (the new copies of instances whose declaration changed) run `__FB_INIT_ALL`
//!   with `bInitRetains` FALSE and `bInCopyCode` TRUE, and nothing else runs.
//! - The top-level `VAR_GLOBAL` instances: a hidden FUNCTION `__FB_INIT_GLOBALS` initialises
//!   them, and every PROGRAM starts with a call of it guarded by hidden global flags (the same
//!   pair, `__FB_INIT_GLOBALS_DONE` and `__FB_INIT_GLOBALS_RETAINED`): whichever PROGRAM runs
//!   first in a RUN start runs it, before its own instances. A hidden FUNCTION
//!   [`GLOBALS_COPY_INIT`] runs phase 2 of an online change over them (the new copies of
//!   those whose declaration changed, selected by compile/fb_exit.rs's flags).
//! - The instances fresh at each call (a FUNCTION's or a method's `VAR`, any `VAR_TEMP`): the
//!   body starts with their `__FB_INIT_ALL`, `bInitRetains` TRUE, `bInCopyCode` FALSE.
//! - A method named `FB_init` is called without dispatch (a derived block's does not replace
//!   its base's, both run) and may add VAR_INPUTs to its base's (compile/oop.rs skips it).
//!
//! - Declaration arguments, `v : T(x := 1)` or `v : T(1)` (which the parser reads as an
//!   enumeration of base `T`, the second form in [`ast::EnumDef::args`]): `v`'s type becomes
//!   `T`, and the arguments go to its `__FB_INIT_ALL`, whose inputs are the two BOOLs and every
//!   other input of the `FB_init`s of `T` and its bases ([`chain_extras`]: the block's own
//!   first, in their order, which is the order of the positional form); each `__FB_INIT_ALL`
//!   passes on to its base's and to its own `FB_init` the inputs they declare.
//!
//! Checked here: an `FB_init` declares `bInitRetains` and `bInCopyCode` (BOOL) as its first two
//! VAR_INPUTs; an instance in a `VAR_STAT` or a CONFIGURATION's `VAR_GLOBAL` whose block has an
//! `FB_init` is refused (nothing runs it); declaration arguments are all named or all
//! positional, name inputs of the chain's `FB_init`s or are no more than those, and are given
//! where `FB_init` runs.

use std::borrow::Cow;
use std::collections::HashMap;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, Arg, Expr, ExprKind, Ident, Item, Literal, Pou, PouKind, Span, Stmt, StmtKind, TypeRef,
    UnaryOp, VarBlock, VarDecl, VarKind,
};

use super::lifecycle::{
    block, bool_decl, counter_block, global_instances, has_work, hidden_pou, holds_instances,
    ident, instance_type, instance_with_work, instances, name, stmt, Blocks,
};

/// The hidden method that initialises an instance (its base, its instances, its `FB_init`).
pub const INIT_ALL: &str = "__FB_INIT_ALL";
/// The name CODESYS gives the initialising method.
pub const FB_INIT: &str = "FB_init";
const DONE: &str = "__FB_INIT_DONE";
/// The hidden DINT counters of the loops over arrays of instances: `__FB_INIT_I1`, ….
const COUNTER: &str = "__FB_INIT_I";
const RETAINED: &str = "__FB_INIT_RETAINED";
/// The hidden FUNCTION that initialises the top-level `VAR_GLOBAL` instances, and its flags
/// (global: whichever PROGRAM runs first runs it).
const GLOBALS_INIT: &str = "__FB_INIT_GLOBALS";
const GLOBALS_DONE: &str = "__FB_INIT_GLOBALS_DONE";
const GLOBALS_RETAINED: &str = "__FB_INIT_GLOBALS_RETAINED";
const INIT_RETAINS: &str = "bInitRetains";
const IN_COPY_CODE: &str = "bInCopyCode";
/// The hidden FUNCTION that runs phase 2 of an online change over the global instances whose
/// declaration changed (their flags are compile/fb_exit.rs's `global_copy_flag`s):
/// `FB_init(bInitRetains := FALSE, bInCopyCode := TRUE)` on each new copy selected.
pub const GLOBALS_COPY_INIT: &str = "__FB_INIT_GLOBALS_COPY";

/// Whether `name` is `FB_init` (case-insensitive, as every IEC name).
pub fn is_fb_init(name: &str) -> bool {
    name.eq_ignore_ascii_case(FB_INIT)
}

/// Whether `name` is `FB_init`, `FB_exit` or their hidden [`INIT_ALL`] and
/// [`super::fb_exit::EXIT_ALL`]: methods each block declares for itself, called without
/// dispatch, whose inputs a derived block may extend.
pub fn is_initialiser(name: &str) -> bool {
    is_fb_init(name) || name.eq_ignore_ascii_case(INIT_ALL) || super::fb_exit::is_finaliser(name)
}

/// Whether `name` is one of the variables this lowering declares (exempt from the rule that
/// reserves names starting with `__` to plcd).
pub fn is_hidden(name: &str) -> bool {
    name.get(..10).is_some_and(|p| p.eq_ignore_ascii_case("__FB_INIT_"))
        || name.get(..10).is_some_and(|p| p.eq_ignore_ascii_case("__FB_EXIT_"))
}

/// What the lowering knows of each block (by name in lower case).
struct Plan {
    /// Whether it has something to initialise.
    needs: HashMap<String, bool>,
    /// The inputs its `FB_init`s (its own and its bases') declare after the two BOOLs: the
    /// inputs of its `__FB_INIT_ALL` beside them, which the declaration arguments give.
    extras: HashMap<String, Vec<VarDecl>>,
}

impl Plan {
    fn needs(&self, block: &str) -> bool {
        self.needs.get(&block.to_ascii_lowercase()).copied().unwrap_or(false)
    }

    fn extras(&self, block: &str) -> &[VarDecl] {
        self.extras.get(&block.to_ascii_lowercase()).map_or(&[], Vec::as_slice)
    }
}

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
    let mut needs: HashMap<String, bool> = HashMap::new();
    let names: Vec<String> = blocks.keys().cloned().collect();
    for name in &names {
        has_work(&files, &blocks, name, &own_fb_init, &mut needs, &mut Vec::new());
    }
    // the checks, on the files as written
    for file in &files {
        for item in &file.items {
            match item {
                Item::Pou(p) => {
                    // one copy for every instance of the POU: which instance would run it?
                    for b in p.vars.iter().filter(|b| b.kind == VarKind::Static) {
                        not_run(&file.path, b, &needs, diags);
                    }
                    for m in p.oop.methods.iter().filter(|m| is_fb_init(&m.pou.name.name)) {
                        if !signature_ok(&m.pou) {
                            diags.push(Diagnostic::new(
                                &file.path,
                                m.pou.name.span.line,
                                m.pou.name.span.col,
                                "an FB_init method declares `bInitRetains : BOOL` and `bInCopyCode : BOOL` as its first two VAR_INPUTs",
                            ));
                        }
                    }
                }
                Item::Configuration(c) => {
                    for b in &c.globals {
                        not_run(&file.path, b, &needs, diags);
                    }
                }
                _ => {}
            }
        }
    }
    let mut extras = HashMap::new();
    for name in &names {
        extras.insert(name.clone(), chain_extras(&files, &blocks, name));
    }
    let plan = Plan { needs, extras };
    if plan.needs.values().any(|&n| n) {
        generate(&mut files, &plan);
    }
    declaration_arguments(&mut files, &blocks, &plan, diags);
    files
}

/// Adds the hidden methods and prologues.
fn generate(files: &mut [Cow<'_, ast::File>], plan: &Plan) {
    let needs = &plan.needs;
    let globals = global_instances(files, needs);
    let mut globals_placed = false;
    for file in files.iter_mut() {
        let holds_globals = !globals_placed
            && file.items.iter().any(|item| {
                matches!(item, Item::Globals(b) if b.decls.iter().any(|d| instance_with_work(&d.ty, needs).is_some()))
            });
        let wants = holds_globals
            || file.items.iter().any(|item| match item {
                Item::Pou(p) => {
                    p.kind == PouKind::Program && !globals.is_empty()
                        || !instances(p, needs).is_empty()
                        || own_work(p, needs)
                        || !call_instances(p, needs).is_empty()
                        || p.oop.methods.iter().any(|m| !call_instances(&m.pou, needs).is_empty())
                }
                _ => false,
            });
        if !wants {
            continue;
        }
        let items = &mut file.to_mut().items;
        for item in items.iter_mut() {
            let Item::Pou(p) = item else { continue };
            let mut counters = add_call_prologue(p, plan);
            for m in &mut p.oop.methods {
                let used = add_call_prologue(&mut m.pou, plan);
                m.pou.vars.extend(counter_block(COUNTER, used, m.pou.span));
            }
            match p.kind {
                PouKind::FunctionBlock if own_work(p, needs) => add_init_all(p, plan),
                PouKind::Program => {
                    let mut copies = None;
                    if !instances(p, needs).is_empty() {
                        let (used, copy) = add_prologue(p, plan);
                        counters = counters.max(used);
                        copies = Some(copy);
                    }
                    if !globals.is_empty() {
                        add_globals_prologue(p);
                    }
                    // before any initialisation: the new engine's memory is fresh
                    p.body.splice(0..0, copies);
                }
                _ => {}
            }
            p.vars.extend(counter_block(COUNTER, counters, p.name.span));
        }
        if holds_globals {
            globals_placed = true;
            let at = items.iter().position(|i| matches!(i, Item::Globals(_))).unwrap_or(0);
            let span = match &items[at] {
                Item::Globals(b) => b.span,
                _ => Span::default(),
            };
            items.insert(at, Item::Pou(globals_initialiser(&globals, plan, span)));
            items.insert(at, Item::Pou(globals_copy_initialiser(&globals, plan, span)));
            items.insert(
                at,
                Item::Globals(bool_block(VarKind::Global, true, GLOBALS_RETAINED, span)),
            );
            items.insert(at, Item::Globals(bool_block(VarKind::Global, false, GLOBALS_DONE, span)));
        }
    }
}

/// The extra inputs of the `FB_init`s of block `name` and its bases, the block's first (one
/// declaration each, by name).
fn chain_extras(files: &[Cow<'_, ast::File>], blocks: &Blocks, name: &str) -> Vec<VarDecl> {
    let mut out: Vec<VarDecl> = Vec::new();
    let mut at = Some(name.to_ascii_lowercase());
    for _ in 0..=blocks.len() {
        let Some(&(f, i)) = at.as_ref().and_then(|n| blocks.get(n)) else { break };
        let Item::Pou(p) = &files[f].items[i] else { break };
        for m in p.oop.methods.iter().filter(|m| is_fb_init(&m.pou.name.name)) {
            if signature_ok(&m.pou) {
                for d in fb_init_extras(&m.pou) {
                    if !out.iter().any(|o| o.names[0].is(&d.names[0].name)) {
                        out.push(d);
                    }
                }
            }
        }
        at = p.oop.extends.as_ref().map(|b| b.name.to_ascii_lowercase());
    }
    out
}

/// The VAR_INPUTs of an `FB_init` after `bInitRetains` and `bInCopyCode`, one name each.
fn fb_init_extras(m: &Pou) -> Vec<VarDecl> {
    let singles =
        m.vars.iter().filter(|b| b.kind == VarKind::Input).flat_map(|b| &b.decls).flat_map(|d| {
            d.names.iter().map(move |n| VarDecl { names: vec![n.clone()], ..d.clone() })
        });
    singles.skip(2).collect()
}

/// The arguments of a declaration `v : T(…)` as written: each named one (`x := 1`) an input,
/// each other one (`5`, or a name alone) positional.
pub(super) fn written_arguments(def: &ast::EnumDef) -> Vec<Arg> {
    let named = |(n, v): &(Ident, Option<Expr>)| match v {
        Some(value) => Arg::Input { name: n.clone(), value: value.clone() },
        None => Arg::Positional(Expr { kind: ExprKind::Name(n.clone()), span: n.span }),
    };
    def.values.iter().map(named).chain(def.args.iter().cloned()).collect()
}

/// Where an argument is written.
fn arg_span(arg: &Arg) -> Span {
    match arg {
        Arg::Positional(e) => e.span,
        Arg::Input { name, .. } | Arg::Output { name, .. } => name.span,
    }
}

/// Whether the arguments mix the named form and the positional one (reported by
/// [`declaration_arguments`]).
fn mixed(args: &[Arg]) -> Option<&Arg> {
    let positional = |a: &Arg| matches!(a, Arg::Positional(_));
    let first = args.first().map(positional)?;
    args.iter().find(|a| positional(a) != first)
}

/// The arguments of a declaration `v : T(x := 1, …)` or `v : T(1, …)`, as the named inputs of
/// its `__FB_INIT_ALL` (a positional one is the input of its rank among `known`, the inputs
/// after `bInitRetains` and `bInCopyCode`). Those [`declaration_arguments`] reports are left
/// out.
pub(super) fn declared_arguments(ty: &TypeRef, known: &[VarDecl]) -> Vec<Arg> {
    let TypeRef::Enum(def) = ty else { return Vec::new() };
    let written = written_arguments(def);
    if mixed(&written).is_some() {
        return Vec::new();
    }
    let given = |(rank, arg): (usize, Arg)| match arg {
        Arg::Input { name, value } => {
            known.iter().any(|k| k.names[0].is(&name.name)).then_some(Arg::Input { name, value })
        }
        Arg::Positional(value) => {
            known.get(rank).map(|k| Arg::Input { name: ident(&k.names[0].name, value.span), value })
        }
        Arg::Output { .. } => None,
    };
    written.into_iter().enumerate().filter_map(given).collect()
}

/// Whether the instances declared in a section of kind `var` of a POU of kind `pou` have
/// their `FB_init` run (and so may have declaration arguments): a PROGRAM's and a function
/// block's own variables, a FUNCTION's or a method's `VAR`, any `VAR_TEMP`, a top-level
/// `VAR_GLOBAL` (`pou` `None`).
fn runs_fb_init(pou: Option<PouKind>, var: VarKind) -> bool {
    match pou {
        None => var == VarKind::Global,
        Some(PouKind::Function) => matches!(var, VarKind::Local | VarKind::Temp),
        Some(_) => holds_instances(var) || var == VarKind::Temp,
    }
}

/// `v : T(x := 1)` or `v : T(1)` where `T` is a function block: the arguments checked (the
/// instance's `FB_init` runs, they name inputs of the chain's `FB_init`s or are no more than
/// those, one form or the other), the type made `T`.
fn declaration_arguments(
    files: &mut [Cow<'_, ast::File>],
    blocks: &Blocks,
    plan: &Plan,
    diags: &mut Vec<Diagnostic>,
) {
    let is_block_with_arguments = |ty: &TypeRef| {
        matches!(ty, TypeRef::Enum(def)
            if def.base.as_ref().is_some_and(|b| blocks.contains_key(&b.name.to_ascii_lowercase())))
    };
    for file in files.iter_mut() {
        let any = file.items.iter().any(|item| {
            let blocks: Vec<&VarBlock> = match item {
                Item::Pou(p) => {
                    p.vars.iter().chain(p.oop.methods.iter().flat_map(|m| &m.pou.vars)).collect()
                }
                Item::Globals(b) => vec![b],
                Item::Configuration(c) => c.globals.iter().collect(),
                _ => Vec::new(),
            };
            blocks.iter().flat_map(|b| &b.decls).any(|d| is_block_with_arguments(&d.ty))
        });
        if !any {
            continue;
        }
        let path = file.path.clone();
        let mut report = |span: Span, msg: String| {
            diags.push(Diagnostic::new(&path, span.line, span.col, msg));
        };
        for item in &mut file.to_mut().items {
            // (the block, whether its instances are initialised there)
            let mut sections: Vec<(&mut VarBlock, bool)> = Vec::new();
            match item {
                Item::Pou(p) => {
                    for b in &mut p.vars {
                        let run = runs_fb_init(Some(p.kind), b.kind);
                        sections.push((b, run));
                    }
                    // a method's VAR_INST: checked where compile/method_vars.rs declared it
                    // again, in its block; its type made plain here too
                    for m in &mut p.oop.methods {
                        let kind = m.pou.kind;
                        sections.extend(m.pou.vars.iter_mut().map(|b| {
                            let run = runs_fb_init(Some(kind), b.kind);
                            (b, run)
                        }));
                    }
                }
                Item::Globals(b) => sections.push((b, true)),
                Item::Configuration(c) => sections.extend(c.globals.iter_mut().map(|b| (b, false))),
                _ => {}
            }
            for (section, runs) in sections {
                let kind = section.kind;
                for d in &mut section.decls {
                    if !is_block_with_arguments(&d.ty) {
                        continue;
                    }
                    let TypeRef::Enum(def) = &d.ty else { continue };
                    let Some(base) = def.base.clone() else { continue };
                    let v = &d.names[0];
                    let checked_elsewhere = !runs && kind == VarKind::Instance;
                    if checked_elsewhere {
                        d.ty = TypeRef::Named(base);
                        continue;
                    }
                    if !runs {
                        let msg = format!(
                            "`{}`: declaration arguments go to FB_init, which plcd does not run for a VAR_STAT's instance, a CONFIGURATION's VAR_GLOBAL's, nor a VAR_IN_OUT or VAR_EXTERNAL",
                            v.name
                        );
                        report(v.span, msg);
                        d.ty = TypeRef::Named(base);
                        continue;
                    }
                    let written = written_arguments(def);
                    let known = plan.extras(&base.name);
                    let subject = format!("`{}`", v.name);
                    let place = format!("the declaration of `{}`", v.name);
                    check_arguments(&base.name, &written, known, (&subject, &place), &mut report);
                    d.ty = TypeRef::Named(base);
                }
            }
        }
    }
}

/// Checks the arguments `written` for the `FB_init`s of block `base`, whose inputs after the
/// two BOOLs are `known`: one form or the other, inputs only, each named one an input of the
/// chain's, no more positional ones than those. `subject` names what is given them in the
/// messages (`` `fb` ``), and `place` where (`the declaration of `fb``); compile/heap.rs's
/// `__NEW(T(…))` is checked here too.
pub(super) fn check_arguments(
    base: &str,
    written: &[Arg],
    known: &[VarDecl],
    (subject, place): (&str, &str),
    report: &mut dyn FnMut(Span, String),
) {
    if let Some(odd) = mixed(written) {
        let msg = format!(
            "{subject}: the declaration arguments are all named (`x := 5`) or all positional (`{base}(5, 'A')`), not both"
        );
        report(arg_span(odd), msg);
    }
    let mut positional = 0;
    for arg in written {
        match arg {
            Arg::Output { name, .. } => {
                let msg = format!(
                    "{subject}: a declaration argument gives an FB_init input (`{} := …`), not an output",
                    name.name
                );
                report(name.span, msg);
            }
            Arg::Input { name, .. } if !known.iter().any(|e| e.names[0].is(&name.name)) => {
                let msg = format!("`{base}` has no FB_init input `{}` for {place}", name.name);
                report(name.span, msg);
            }
            Arg::Input { .. } => {}
            Arg::Positional(value) => {
                positional += 1;
                if positional == known.len() + 1 {
                    let msg = format!(
                        "{subject}: `{base}`'s FB_init takes {} argument(s) after bInitRetains and bInCopyCode",
                        known.len()
                    );
                    report(value.span, msg);
                }
            }
        }
    }
}

/// Reports each instance of `block` (a VAR_STAT, a CONFIGURATION's VAR_GLOBAL) whose block
/// has something to initialise: nothing runs its `FB_init`.
fn not_run(
    path: &std::path::Path,
    block: &VarBlock,
    needs: &HashMap<String, bool>,
    diags: &mut Vec<Diagnostic>,
) {
    for d in &block.decls {
        if instance_with_work(&d.ty, needs).is_some() {
            let n = &d.names[0];
            let msg = format!(
                "`{}`'s function block has an FB_init, which plcd does not run for a VAR_STAT's instance (one copy for every instance of its POU) nor a CONFIGURATION's VAR_GLOBAL's",
                n.name
            );
            diags.push(Diagnostic::new(path, n.span.line, n.span.col, msg));
        }
    }
}

/// Whether block `p` initialises something itself (its `FB_init` or its instances), beyond
/// what it inherits.
fn own_work(p: &Pou, needs: &HashMap<String, bool>) -> bool {
    own_fb_init(p) || !instances(p, needs).is_empty()
}

/// Whether block `p` declares an `FB_init` to call (one with the wrong signature is reported,
/// and not called).
fn own_fb_init(p: &Pou) -> bool {
    p.oop.methods.iter().any(|m| is_fb_init(&m.pou.name.name) && signature_ok(&m.pou))
}

/// `bInitRetains : BOOL; bInCopyCode : BOOL` first among the VAR_INPUTs.
fn signature_ok(m: &Pou) -> bool {
    let inputs: Vec<(&Ident, &TypeRef)> = m
        .vars
        .iter()
        .filter(|b| b.kind == VarKind::Input)
        .flat_map(|b| &b.decls)
        .flat_map(|d| d.names.iter().map(move |n| (n, &d.ty)))
        .take(2)
        .collect();
    let is_bool = |ty: &TypeRef| matches!(ty, TypeRef::Named(t) if t.is("BOOL"));
    matches!(&inputs[..], [(a, ta), (b, tb)]
        if a.is(INIT_RETAINS) && b.is(IN_COPY_CODE) && is_bool(ta) && is_bool(tb))
}

/// `target.__FB_INIT_ALL(bInitRetains := retains, bInCopyCode := copy)`.
fn init_call(target: Expr, retains: Expr, copy: Expr, more: Vec<Arg>, span: Span) -> Stmt {
    let callee = Expr { kind: ExprKind::Member(Box::new(target), ident(INIT_ALL, span)), span };
    let mut args = vec![
        Arg::Input { name: ident(INIT_RETAINS, span), value: retains },
        Arg::Input { name: ident(IN_COPY_CODE, span), value: copy },
    ];
    args.extend(more);
    let call = Expr { kind: ExprKind::Call { callee: Box::new(callee), args }, span };
    stmt(StmtKind::Call(call), span)
}

/// The calls that initialise variable `v` of type `ty` (each element of an array, in nested
/// FOR loops over hidden DINT counters `__FB_INIT_I1`, …), and the counters they use.
fn init_variable(
    v: &Ident,
    ty: &TypeRef,
    plan: &Plan,
    args: &dyn Fn() -> (Expr, Expr),
    counters: &mut usize,
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
    let (retains, copy) = args();
    let known = plan.extras(instance_type(ty).unwrap_or(""));
    let mut body = init_call(target, retains, copy, declared_arguments(ty, known), span);
    *counters = (*counters).max(dims.len());
    for (k, (lo, hi)) in dims.iter().enumerate().rev() {
        body = stmt(
            StmtKind::For {
                var: name(&counter(k + 1), span),
                from: lo.clone(),
                to: hi.clone(),
                by: None,
                body: vec![body],
            },
            span,
        );
    }
    body
}

/// `x := x` for each of `inputs`: a `__FB_INIT_ALL`'s inputs passed on.
fn forwarded(inputs: &[VarDecl], span: Span) -> Vec<Arg> {
    let pass = |d: &VarDecl| Arg::Input {
        name: ident(&d.names[0].name, span),
        value: name(&d.names[0].name, span),
    };
    inputs.iter().map(pass).collect()
}

/// Adds `METHOD __FB_INIT_ALL` to block `p`.
fn add_init_all(p: &mut Pou, plan: &Plan) {
    let needs = &plan.needs;
    let span = p.name.span;
    let args = || (name(INIT_RETAINS, span), name(IN_COPY_CODE, span));
    let mut body = Vec::new();
    let base_needs = p.oop.extends.as_ref().is_some_and(|b| plan.needs(&b.name));
    if base_needs {
        let sup = Expr { kind: ExprKind::Deref(Box::new(name("SUPER", span))), span };
        let (r, c) = args();
        let base = p.oop.extends.as_ref().map_or("", |b| b.name.as_str());
        body.push(init_call(sup, r, c, forwarded(plan.extras(base), span), span));
    }
    let mut counters = 0;
    for (v, ty) in instances(p, needs) {
        body.push(init_variable(v, ty, plan, &args, &mut counters));
    }
    if own_fb_init(p) {
        let (r, c) = args();
        let mut args = vec![
            Arg::Input { name: ident(INIT_RETAINS, span), value: r },
            Arg::Input { name: ident(IN_COPY_CODE, span), value: c },
        ];
        let own = p.oop.methods.iter().find(|m| is_fb_init(&m.pou.name.name));
        args.extend(forwarded(&own.map(|m| fb_init_extras(&m.pou)).unwrap_or_default(), span));
        let call =
            Expr { kind: ExprKind::Call { callee: Box::new(name(FB_INIT, span)), args }, span };
        body.push(stmt(StmtKind::Call(call), span));
    }
    let mut inputs = vec![bool_decl(INIT_RETAINS, span), bool_decl(IN_COPY_CODE, span)];
    inputs.extend(plan.extras(&p.name.name).iter().cloned());
    let inputs = block(VarKind::Input, false, inputs, span);
    let mut vars = vec![inputs];
    vars.extend(counter_block(COUNTER, counters, span));
    let pou = hidden_pou(INIT_ALL, vars, body, span, p.end);
    p.oop.methods.push(ast::Method {
        access: ast::Access::Public,
        is_abstract: false,
        is_final: false,
        pou,
    });
}

/// Starts program `p`'s body with the initialisation of its instances, once a RUN. Returns
/// the array counters it uses and the statement that initialises the new copies of an online
/// change, to put first.
fn add_prologue(p: &mut Pou, plan: &Plan) -> (usize, Stmt) {
    let needs = &plan.needs;
    let span = p.name.span;
    let not = |e: Expr| Expr { kind: ExprKind::Unary(UnaryOp::Not, Box::new(e)), span };
    let truth = |b: bool| Expr { kind: ExprKind::Literal(Literal::Bool(b)), span };
    let assign = |target: &str, value: Expr| {
        stmt(StmtKind::Assign { target: name(target, span), value }, span)
    };
    let args = || (not(name(RETAINED, span)), truth(false));
    let mut inits = vec![assign(DONE, truth(true))];
    let mut counters = 0;
    for (v, ty) in instances(p, needs) {
        inits.push(init_variable(v, ty, plan, &args, &mut counters));
    }
    inits.push(assign(RETAINED, truth(true)));
    let prologue = stmt(
        StmtKind::If { branches: vec![(not(name(DONE, span)), inits)], otherwise: None },
        span,
    );
    p.body.insert(0, prologue);
    // Asked by the engine in an online change (compile/fb_exit.rs declares the flags): phase
    // 2, the new copy of an instance whose declaration changed, its FB_init with bInitRetains
    // FALSE and bInCopyCode TRUE; phase 4, an instance the change added to a kept PROGRAM,
    // its FB_init as at a first start (TRUE, FALSE).
    let mut phases = Vec::new();
    for (phase, retains, copy) in [(2, false, true), (4, true, false)] {
        let args = || (truth(retains), truth(copy));
        let mut selected = Vec::new();
        for (v, ty) in instances(p, needs) {
            let flag = super::fb_exit::copy_flag(&v.name);
            let init = init_variable(v, ty, plan, &args, &mut counters);
            let branch = vec![assign(&flag, truth(false)), init];
            selected.push(stmt(
                StmtKind::If { branches: vec![(name(&flag, span), branch)], otherwise: None },
                span,
            ));
        }
        selected.push(stmt(StmtKind::Return, span));
        let asked = Expr {
            kind: ExprKind::Binary(
                ast::BinaryOp::Eq,
                Box::new(name(super::fb_exit::PHASE, span)),
                Box::new(Expr { kind: ExprKind::Literal(Literal::Int(phase)), span }),
            ),
            span,
        };
        phases.push((asked, selected));
    }
    let copy = stmt(StmtKind::If { branches: phases, otherwise: None }, span);
    p.vars.push(bool_block(VarKind::Local, false, DONE, span));
    p.vars.push(bool_block(VarKind::Local, true, RETAINED, span));
    (counters, copy)
}

/// A block declaring one hidden BOOL.
fn bool_block(kind: VarKind, retain: bool, n: &str, span: Span) -> VarBlock {
    block(kind, retain, vec![bool_decl(n, span)], span)
}

/// The variables of `p` fresh at each call of its body whose block has something to
/// initialise: a FUNCTION's or a method's `VAR` and any POU's `VAR_TEMP`.
fn call_instances<'p>(p: &'p Pou, needs: &HashMap<String, bool>) -> Vec<(&'p Ident, &'p TypeRef)> {
    let fresh = |kind: VarKind| {
        kind == VarKind::Temp || p.kind == PouKind::Function && kind == VarKind::Local
    };
    let mut out = Vec::new();
    for d in p.vars.iter().filter(|b| fresh(b.kind)).flat_map(|b| &b.decls) {
        if instance_with_work(&d.ty, needs).is_some() {
            out.extend(d.names.iter().map(|n| (n, &d.ty)));
        }
    }
    out
}

/// Starts the body of `p` (a FUNCTION, a method, or any POU with a `VAR_TEMP`) with the
/// initialisation of its instances fresh at each call (CODESYS calls their `FB_init` at each
/// call): `bInitRetains` TRUE (every variable of the instance starts from its initial value),
/// `bInCopyCode` FALSE. Returns the array counters it uses.
fn add_call_prologue(p: &mut Pou, plan: &Plan) -> usize {
    let found: Vec<(Ident, TypeRef)> =
        call_instances(p, &plan.needs).into_iter().map(|(v, t)| (v.clone(), t.clone())).collect();
    let span = p.name.span;
    let truth = |b: bool| Expr { kind: ExprKind::Literal(Literal::Bool(b)), span };
    let args = || (truth(true), truth(false));
    let mut counters = 0;
    let inits: Vec<Stmt> =
        found.iter().map(|(v, ty)| init_variable(v, ty, plan, &args, &mut counters)).collect();
    p.body.splice(0..0, inits);
    counters
}

/// `FUNCTION __FB_INIT_GLOBALS`: initialises each of `globals`, with `bInitRetains` as given
/// and `bInCopyCode` FALSE.
fn globals_initialiser(globals: &[(Ident, TypeRef)], plan: &Plan, span: Span) -> Pou {
    let truth = |b: bool| Expr { kind: ExprKind::Literal(Literal::Bool(b)), span };
    let args = || (name(INIT_RETAINS, span), truth(false));
    let mut counters = 0;
    let body =
        globals.iter().map(|(v, ty)| init_variable(v, ty, plan, &args, &mut counters)).collect();
    let mut vars = vec![block(VarKind::Input, false, vec![bool_decl(INIT_RETAINS, span)], span)];
    vars.extend(counter_block(COUNTER, counters, span));
    hidden_pou(GLOBALS_INIT, vars, body, span, span)
}

/// `FUNCTION __FB_INIT_GLOBALS_COPY`: phase 2 of an online change over the global instances
/// (compile/fb_exit.rs sets nothing of it: the engine selects each new copy by its flag),
/// `FB_init` with `bInitRetains` FALSE and `bInCopyCode` TRUE, in declaration order.
fn globals_copy_initialiser(globals: &[(Ident, TypeRef)], plan: &Plan, span: Span) -> Pou {
    let truth = |b: bool| Expr { kind: ExprKind::Literal(Literal::Bool(b)), span };
    let args = || (truth(false), truth(true));
    let mut counters = 0;
    let body = globals
        .iter()
        .map(|(v, ty)| {
            let init = init_variable(v, ty, plan, &args, &mut counters);
            let flag = name(&super::fb_exit::global_copy_flag(&v.name), span);
            stmt(StmtKind::If { branches: vec![(flag, vec![init])], otherwise: None }, span)
        })
        .collect();
    let vars = counter_block(COUNTER, counters, span).into_iter().collect();
    hidden_pou(GLOBALS_COPY_INIT, vars, body, span, span)
}

/// Starts program `p`'s body with the initialisation of the global instances, once a RUN
/// whichever program runs first (the flags are global).
fn add_globals_prologue(p: &mut Pou) {
    let span = p.name.span;
    let not = |e: Expr| Expr { kind: ExprKind::Unary(UnaryOp::Not, Box::new(e)), span };
    let truth = |b: bool| Expr { kind: ExprKind::Literal(Literal::Bool(b)), span };
    let assign = |target: &str, value: Expr| {
        stmt(StmtKind::Assign { target: name(target, span), value }, span)
    };
    let args = vec![Arg::Input {
        name: ident(INIT_RETAINS, span),
        value: not(name(GLOBALS_RETAINED, span)),
    }];
    let call =
        Expr { kind: ExprKind::Call { callee: Box::new(name(GLOBALS_INIT, span)), args }, span };
    let inits = vec![
        assign(GLOBALS_DONE, truth(true)),
        stmt(StmtKind::Call(call), span),
        assign(GLOBALS_RETAINED, truth(true)),
    ];
    let prologue = stmt(
        StmtKind::If { branches: vec![(not(name(GLOBALS_DONE, span)), inits)], otherwise: None },
        span,
    );
    p.body.insert(0, prologue);
}
