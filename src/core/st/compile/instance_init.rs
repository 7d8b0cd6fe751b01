//! An interface (or any declared type) initialised with an instance of the same block,
//! `TestResultLogger : I_TestResultLogger := AdsTestResultLogger;`, as TcUnit's
//! FB_TcUnitRunner and FB_TestSuite write it (github.com/tcunit/TcUnit). The instance's place
//! is known only where the block's instance is, so the value cannot be part of an initial
//! image: this lowering of the syntax trees moves it into the block's `FB_init` (made when the
//! block has none), as the first statement, where compile/fb_init.rs runs it for every
//! instance before the first scan, a derived block's instances included (CODESYS sets the
//! initial values before `FB_init` runs). Nothing changes for a project without one.
//!
//! The initial value taken is a name alone, of a variable the block declares before in a
//! `VAR` block (not CONSTANT), given to a variable of a declared type (not elementary): an
//! elementary variable initialised with a variable stays the usual error.

use std::borrow::Cow;

use crate::st::ast::{
    self, Expr, ExprKind, Init, Item, Method, Pou, PouKind, StmtKind, TypeRef, VarKind,
};

use super::fb_init::is_fb_init;
use super::lifecycle::{block, bool_decl, hidden_pou, name, stmt};
use super::types::Prim;

/// The lowered files, and where each value taken was (file index, span): a habit
/// (CODESYS's), which `[st] strict` refuses.
pub(super) fn lower(
    mut files: Vec<Cow<'_, ast::File>>,
) -> (Vec<Cow<'_, ast::File>>, Vec<(usize, ast::Span)>) {
    let mut taken = Vec::new();
    for (index, file) in files.iter_mut().enumerate() {
        let wanted = file.items.iter().any(|i| matches!(i, Item::Pou(p) if !takes(p).is_empty()));
        if !wanted {
            continue;
        }
        for item in file.to_mut().items.iter_mut() {
            if let Item::Pou(p) = item {
                taken.extend(lower_block(p).into_iter().map(|span| (index, span)));
            }
        }
    }
    (files, taken)
}

/// The (block, declaration) indices of `p`'s initial values this lowering takes.
fn takes(p: &Pou) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    if p.kind != PouKind::FunctionBlock {
        return out;
    }
    let mut earlier: Vec<&str> = Vec::new();
    for (bi, b) in p.vars.iter().enumerate() {
        let local = b.kind == VarKind::Local && !b.constant;
        for (di, d) in b.decls.iter().enumerate() {
            let declared = matches!(&d.ty, TypeRef::Named(t) if Prim::from_name(&t.name).is_none());
            let names_earlier = match &d.init {
                Some(Init::Expr(Expr { kind: ExprKind::Name(n), .. })) => {
                    earlier.iter().any(|e| e.eq_ignore_ascii_case(&n.name))
                }
                _ => false,
            };
            if local && declared && names_earlier {
                out.push((bi, di));
            }
            if local {
                earlier.extend(d.names.iter().map(|n| n.name.as_str()));
            }
        }
    }
    out
}

/// Moves `p`'s taken initial values into assignments that start its `FB_init`; returns where
/// the values were.
fn lower_block(p: &mut Pou) -> Vec<ast::Span> {
    let taken = takes(p);
    if taken.is_empty() {
        return Vec::new();
    }
    let mut assigns = Vec::new();
    let mut values = Vec::new();
    for (bi, di) in taken {
        let d = &mut p.vars[bi].decls[di];
        let Some(Init::Expr(value)) = d.init.take() else { continue };
        values.push(value.span);
        for id in &d.names {
            let target = name(&id.name, id.span);
            assigns.push(stmt(StmtKind::Assign { target, value: value.clone() }, value.span));
        }
    }
    let span = p.name.span;
    if let Some(m) = p.oop.methods.iter_mut().find(|m| is_fb_init(&m.pou.name.name)) {
        m.pou.body.splice(0..0, assigns);
        return values;
    }
    let inputs = vec![bool_decl("bInitRetains", span), bool_decl("bInCopyCode", span)];
    let mut init = hidden_pou(
        "FB_init",
        vec![block(VarKind::Input, false, inputs, span)],
        assigns,
        span,
        p.end,
    );
    init.return_type = Some(TypeRef::Named(ast::Ident { name: "BOOL".into(), span }));
    p.oop.methods.push(Method {
        access: ast::Access::Public,
        is_abstract: false,
        is_final: false,
        pou: init,
    });
    values
}
