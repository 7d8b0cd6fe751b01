//! `CLASS … END_CLASS` (IEC 61131-3 ed. 3, §6.6.5): what makes a class more than a function
//! block without a body.
//!
//! The parser reads a class as a FUNCTION_BLOCK marked [`is_class`](crate::st::ast::Oop::is_class), so
//! that its variables, methods, properties, `EXTENDS`, `IMPLEMENTS`, `THIS`, `SUPER` and the
//! dispatch through interfaces and bases are the function block's (compile/oop.rs); its body
//! is empty. This module checks the rules the standard gives a class beyond that, each with
//! its place: no VAR_INPUT, VAR_OUTPUT, VAR_IN_OUT or VAR_TEMP (a class is never called, so
//! nothing would pass or read them), no body, no actions, a class extends only a class, and
//! an instance of a class is never called (`c()`, `SUPER^()`): its code is in its methods.

use crate::st::ast::{Span, StmtKind, VarKind};

use super::ctx::Ctx;

impl Ctx<'_> {
    /// Whether POU `p` is a CLASS (a method's or an action's owner's flag is not its own).
    pub(super) fn is_class(&self, p: usize) -> bool {
        let pou = &self.pous[p];
        pou.action.is_none() && pou.method.is_none() && pou.ast.oop.is_class
    }

    /// After `EXTENDS` is resolved: the declarations of every class (its actions, inside it or
    /// not, are POUs of their own, each reported once).
    pub(super) fn check_classes(&mut self) {
        for p in 0..self.pous.len() {
            if let Some((action, owner)) = self.pous[p].action {
                if self.is_class(owner) {
                    let msg = format!(
                        "`{}` is a CLASS: a class has no actions (write `{}` as a METHOD)",
                        self.pous[owner].name, action.name.name
                    );
                    self.error(self.pous[p].file, action.name.span, msg);
                }
                continue;
            }
            if !self.is_class(p) {
                continue;
            }
            let (ast, file, name) =
                (self.pous[p].ast, self.pous[p].file, self.pous[p].name.clone());
            for block in &ast.vars {
                if let Some(section) = section_not_in_a_class(block.kind) {
                    let msg = format!(
                        "`{name}` is a CLASS: a class declares no {section} (it is never called: its methods take and give the values)"
                    );
                    self.error(file, block.span, msg);
                }
            }
            if let Some(first) = ast.body.iter().find(|s| s.kind != StmtKind::Empty) {
                let msg = format!(
                    "`{name}` is a CLASS: a class has no body (its code is in its METHODs)"
                );
                self.error(file, first.span, msg);
            }
            if let (Some(&base), Some(written)) = (self.oop.base.get(&p), &ast.oop.extends) {
                if !self.is_class(base) {
                    let msg = format!(
                        "`{}` is a FUNCTION_BLOCK: a CLASS extends only a CLASS",
                        self.pous[base].name
                    );
                    self.error(file, written.span, msg);
                }
            }
        }
    }

    /// Reports a call of an instance of class `p` (`c()`, `SUPER^()` of a class's body): a
    /// class has no body. Returns whether `p` is a class.
    pub(super) fn class_called(&mut self, p: usize, file: usize, span: Span) -> bool {
        if !self.is_class(p) {
            return false;
        }
        let msg = format!(
            "`{}` is a CLASS: an instance of a class is not called, its methods are (`inst.Method()`)",
            self.pous[p].name
        );
        self.error(file, span, msg);
        true
    }
}

/// The keyword of a variable section a class may not declare (§6.6.5: a class has VAR,
/// VAR_EXTERNAL and their CONSTANT/RETAIN forms, and methods for the rest).
fn section_not_in_a_class(kind: VarKind) -> Option<&'static str> {
    Some(match kind {
        VarKind::Input => "VAR_INPUT",
        VarKind::Output => "VAR_OUTPUT",
        VarKind::InOut => "VAR_IN_OUT",
        VarKind::Temp => "VAR_TEMP",
        _ => return None,
    })
}
