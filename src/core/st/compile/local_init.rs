//! Initial values that read the call's or the instance's variables, in the variables that are
//! set at every call: a FUNCTION's and a method's `VAR`, and any `VAR_TEMP`. CODESYS and
//! TwinCAT allow them (`pTest : I_Element := pList[Index];` in a method of PeterZerlauth's
//! Tc3_Component, `pList` the block's, `Index` the method's input); IEC 61131-3 asks a constant
//! expression. Such a variable takes its initial value at each call anyway, so this lowering of
//! the syntax trees turns the initial value into an assignment that starts the body, in the
//! order of the declarations, checked and compiled as the body is (native code included). A
//! habit: `[st] strict` refuses it. Nothing changes for a project without one.
//!
//! What is taken: an initial value written as an expression (`Init::Expr`, not a structure's
//! or an array's initialiser) that names a variable of the call (the POU's own variables, a
//! method's block's too) that is not CONSTANT. One that takes a reference (`REF`, `ADR`) is
//! left to `ref_init`, which sets it first.

use std::borrow::Cow;
use std::collections::HashSet;

use crate::st::ast::{self, Expr, ExprKind, Init, Item, Pou, PouKind, Stmt, StmtKind};
use crate::st::ast::{VarBlock, VarKind};

use super::lifecycle::{name, stmt};

/// The lowered files, and where each initial value taken was (file index, span): a habit,
/// which `[st] strict` refuses.
pub(super) fn lower(
    mut files: Vec<Cow<'_, ast::File>>,
) -> (Vec<Cow<'_, ast::File>>, Vec<(usize, ast::Span)>) {
    let mut taken = Vec::new();
    for (index, file) in files.iter_mut().enumerate() {
        let wanted = file.items.iter().any(|i| matches!(i, Item::Pou(p) if wanted(p)));
        if !wanted {
            continue;
        }
        for item in file.to_mut().items.iter_mut() {
            if let Item::Pou(p) = item {
                taken.extend(lower_pou(p).into_iter().map(|span| (index, span)));
            }
        }
    }
    (files, taken)
}

/// Whether `p` or one of its methods has an initial value to take.
fn wanted(p: &Pou) -> bool {
    let own = readable(&p.vars, &HashSet::new());
    !takes(p, &HashSet::new(), false).is_empty()
        || p.oop.methods.iter().any(|m| !takes(&m.pou, &own, true).is_empty())
}

/// Takes `p`'s initial values (and its methods'); their spans.
fn lower_pou(p: &mut Pou) -> Vec<ast::Span> {
    let own = readable(&p.vars, &HashSet::new());
    let mut spans = Vec::new();
    for m in &mut p.oop.methods {
        spans.extend(take(&mut m.pou, &own, true));
    }
    spans.extend(take(p, &HashSet::new(), false));
    spans
}

/// The lower-case names of the variables of `blocks` that are not CONSTANT, with `outer`'s.
fn readable(blocks: &[VarBlock], outer: &HashSet<String>) -> HashSet<String> {
    let mut names = outer.clone();
    for b in blocks.iter().filter(|b| !b.constant && b.kind != VarKind::External) {
        for d in &b.decls {
            names.extend(d.names.iter().map(|n| n.name.to_ascii_lowercase()));
        }
    }
    names
}

/// The (block, declaration) indices of the initial values of `p` (a POU, or a `method` whose
/// block's variables are `outer`) this lowering takes.
fn takes(p: &Pou, outer: &HashSet<String>, method: bool) -> Vec<(usize, usize)> {
    let names = readable(&p.vars, outer);
    let each_call = |b: &VarBlock| {
        !b.constant
            && (b.kind == VarKind::Temp
                || (b.kind == VarKind::Local && (p.kind == PouKind::Function || method)))
    };
    let mut out = Vec::new();
    for (bi, b) in p.vars.iter().enumerate().filter(|(_, b)| each_call(b)) {
        for (di, d) in b.decls.iter().enumerate() {
            let Some(init @ Init::Expr(e)) = &d.init else { continue };
            if reads(e, &names) && !super::ref_init::takes_ref(init) {
                out.push((bi, di));
            }
        }
    }
    out
}

/// Moves the initial values [`takes`] finds into assignments that start the body; their spans.
fn take(p: &mut Pou, outer: &HashSet<String>, method: bool) -> Vec<ast::Span> {
    let found = takes(p, outer, method);
    let mut sets: Vec<Stmt> = Vec::new();
    let mut spans = Vec::new();
    for (bi, di) in found {
        let d = &mut p.vars[bi].decls[di];
        let Some(Init::Expr(value)) = d.init.take() else { continue };
        spans.push(value.span);
        for id in &d.names {
            let target = name(&id.name, id.span);
            sets.push(stmt(StmtKind::Assign { target, value: value.clone() }, value.span));
        }
    }
    p.body.splice(0..0, sets);
    spans
}

/// Whether `e` names one of `names` (a variable, or the base of a member, element or call).
fn reads(e: &Expr, names: &HashSet<String>) -> bool {
    let mut found = false;
    super::decl::walk_expr(e, &mut |x| {
        found |=
            matches!(&x.kind, ExprKind::Name(id) if names.contains(&id.name.to_ascii_lowercase()));
    });
    found
}
