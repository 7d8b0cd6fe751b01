//! What `fb_init` and `fb_exit` share: which function blocks have a life-cycle method to run
//! (their own, a base's, one of their instances'), where instances are, and the small pieces
//! of syntax both generate their hidden methods from.

use std::borrow::Cow;
use std::collections::HashMap;

use crate::st::ast::{
    self, Expr, ExprKind, Ident, Item, Pou, PouKind, Span, Stmt, StmtKind, TypeRef, VarBlock,
    VarDecl, VarKind,
};

/// Each function block's place: its file and item, by its name in lower case.
pub(super) type Blocks = HashMap<String, (usize, usize)>;

/// Whether block `name` has something to run: its own method (`own`), its base's, or one of
/// its instances'. `path` guards against a block that holds itself (reported elsewhere).
pub(super) fn has_work(
    files: &[Cow<'_, ast::File>],
    blocks: &Blocks,
    name: &str,
    own: &dyn Fn(&Pou) -> bool,
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
    let mut needs = own(p);
    if let Some(base) = &p.oop.extends {
        needs |= has_work(files, blocks, &base.name.to_ascii_lowercase(), own, memo, path);
    }
    for d in p.vars.iter().filter(|b| holds_instances(b.kind)).flat_map(|b| &b.decls) {
        if let Some(of) = instance_type(&d.ty) {
            needs |= has_work(files, blocks, &of.to_ascii_lowercase(), own, memo, path);
        }
    }
    path.pop();
    memo.insert(name.to_string(), needs);
    needs
}

/// The sections whose instances belong to the POU's instance (not a caller's, nor a global).
pub(super) fn holds_instances(kind: VarKind) -> bool {
    matches!(kind, VarKind::Local | VarKind::Input | VarKind::Output | VarKind::Instance)
}

/// The block name of an instance or of an array of instances.
pub(super) fn instance_type(ty: &TypeRef) -> Option<&str> {
    match ty {
        TypeRef::Named(id) => Some(&id.name),
        TypeRef::Array { of, .. } => instance_type(of),
        // `fb : T(x := 1)` parses as an enumeration of base `T` (compile/fb_init.rs reads it)
        TypeRef::Enum(def) => def.base.as_ref().map(|b| b.name.as_str()),
        _ => None,
    }
}

/// The block of `ty` when it has something to run (`work`: [`has_work`]'s answers).
pub(super) fn instance_with_work<'t>(
    ty: &'t TypeRef,
    work: &HashMap<String, bool>,
) -> Option<&'t str> {
    instance_type(ty).filter(|n| work.get(&n.to_ascii_lowercase()).copied().unwrap_or(false))
}

/// The variables of `p`'s own instance whose block has something to run, with their types, in
/// declaration order.
pub(super) fn instances<'p>(
    p: &'p Pou,
    work: &HashMap<String, bool>,
) -> Vec<(&'p Ident, &'p TypeRef)> {
    let mut out = Vec::new();
    for d in p.vars.iter().filter(|b| holds_instances(b.kind)).flat_map(|b| &b.decls) {
        if instance_with_work(&d.ty, work).is_some() {
            out.extend(d.names.iter().map(|n| (n, &d.ty)));
        }
    }
    out
}

/// The project's global instances (every file's `VAR_GLOBAL`) whose block has something to
/// run, with their types, in declaration order.
pub(super) fn global_instances(
    files: &[Cow<'_, ast::File>],
    work: &HashMap<String, bool>,
) -> Vec<(Ident, TypeRef)> {
    let mut out = Vec::new();
    for file in files {
        for item in &file.items {
            let Item::Globals(b) = item else { continue };
            for d in b.decls.iter().filter(|d| instance_with_work(&d.ty, work).is_some()) {
                out.extend(d.names.iter().map(|n| (n.clone(), d.ty.clone())));
            }
        }
    }
    out
}

pub(super) fn ident(name: &str, span: Span) -> Ident {
    Ident { name: name.to_string(), span }
}

pub(super) fn name(n: &str, span: Span) -> Expr {
    Expr { kind: ExprKind::Name(ident(n, span)), span }
}

pub(super) fn stmt(kind: StmtKind, span: Span) -> Stmt {
    Stmt { kind, span }
}

/// `n : BOOL` (without an initial value).
pub(super) fn bool_decl(n: &str, span: Span) -> VarDecl {
    VarDecl {
        names: vec![ident(n, span)],
        location: None,
        ty: TypeRef::Named(ident("BOOL", span)),
        init: None,
        edge: None,
        span,
    }
}

pub(super) fn block(kind: VarKind, retain: bool, decls: Vec<VarDecl>, span: Span) -> VarBlock {
    VarBlock { kind, constant: false, retain, persistent: false, span, decls }
}

/// The hidden DINT loop counters `{prefix}1` … `{prefix}{counters}`, if any.
pub(super) fn counter_block(prefix: &str, counters: usize, span: Span) -> Option<VarBlock> {
    (counters > 0).then(|| {
        let decls = (1..=counters)
            .map(|k| VarDecl {
                ty: TypeRef::Named(ident("DINT", span)),
                ..bool_decl(&format!("{prefix}{k}"), span)
            })
            .collect();
        block(VarKind::Local, false, decls, span)
    })
}

/// A hidden FUNCTION or method `name` (what a FUNCTION_BLOCK's methods are made of): no
/// result, its variables and statements.
pub(super) fn hidden_pou(
    name: &str,
    vars: Vec<VarBlock>,
    body: Vec<Stmt>,
    span: Span,
    end: Span,
) -> Pou {
    Pou {
        kind: PouKind::Function,
        name: ident(name, span),
        return_type: None,
        vars,
        body,
        actions: Vec::new(),
        oop: ast::Oop::default(),
        sfc: None,
        access: Vec::new(),
        span,
        end,
    }
}
