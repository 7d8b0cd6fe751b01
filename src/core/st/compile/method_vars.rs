//! `VAR_INST` in a METHOD (CODESYS): a variable of the method that keeps its value from one
//! call to the next, one for each instance of its function block.
//!
//! A lowering of the syntax trees, then a binding in the method's declarations:
//!
//! - [`lower`] declares each method's `VAR_INST` variables again in its function block (or
//!   program), as `VAR`s named `Method.x`: a name no code can write (an identifier has no dot),
//!   which the tools show as the path it is (`main.fb.Count.calls`), so that an online change
//!   and RETAIN memory keep it by name as any variable. A derived block's override declares
//!   its own, `Block.Method.x`, beside its base's.
//! - [`Ctx::var_inst_storage`] gives the method's `x` the place of that variable in the
//!   instance, which the method reaches through `this` as its block's other variables.
//!
//! Its initial value is the declaration's, written with the instance's initial image; never
//! again at a call (a method's `VAR` is set to its initial value at each call).

use std::borrow::Cow;
use std::collections::{HashMap, HashSet};

use crate::st::ast::{self, Item, Pou, VarKind};

use super::ctx::{Ctx, Storage};
use super::oop::Role;
use super::types::Ty;

/// `Method.x`: the block's variable holding method `Method`'s `VAR_INST x`.
fn hidden_name(method: &str, var: &str) -> String {
    format!("{method}.{var}")
}

pub(super) fn lower<'f>(mut files: Vec<Cow<'f, ast::File>>) -> Vec<Cow<'f, ast::File>> {
    let has_var_inst = |p: &Pou| {
        p.oop.methods.iter().any(|m| m.pou.vars.iter().any(|b| b.kind == VarKind::Instance))
    };
    if !files.iter().any(|f| f.items.iter().any(|i| matches!(i, Item::Pou(p) if has_var_inst(p)))) {
        return files;
    }
    // the hidden names each block declares, to qualify an override's that its base has
    let mut declared: HashMap<String, (Option<String>, HashSet<String>)> = HashMap::new();
    for file in files.iter() {
        for item in &file.items {
            if let Item::Pou(p) = item {
                let names = var_inst_names(p).map(|(m, v)| hidden_name(m, v).to_ascii_lowercase());
                let base = p.oop.extends.as_ref().map(|b| b.name.to_ascii_lowercase());
                declared.insert(p.name.name.to_ascii_lowercase(), (base, names.collect()));
            }
        }
    }
    let in_a_base = |block: &str, hidden: &str| {
        let mut at = declared.get(&block.to_ascii_lowercase()).and_then(|d| d.0.clone());
        for _ in 0..declared.len() {
            let Some(b) = at else { return false };
            let Some((next, names)) = declared.get(&b) else { return false };
            if names.contains(&hidden.to_ascii_lowercase()) {
                return true;
            }
            at = next.clone();
        }
        false
    };
    for file in &mut files {
        if !file.items.iter().any(|i| matches!(i, Item::Pou(p) if has_var_inst(p))) {
            continue;
        }
        for item in &mut file.to_mut().items {
            let Item::Pou(p) = item else { continue };
            let mut added = Vec::new();
            for m in &p.oop.methods {
                for block in m.pou.vars.iter().filter(|b| b.kind == VarKind::Instance) {
                    let mut copy = block.clone();
                    copy.kind = VarKind::Local;
                    for decl in &mut copy.decls {
                        for id in &mut decl.names {
                            let mut hidden = hidden_name(&m.pou.name.name, &id.name);
                            if in_a_base(&p.name.name, &hidden) {
                                hidden = format!("{}.{hidden}", p.name.name);
                            }
                            id.name = hidden;
                        }
                    }
                    added.push(copy);
                }
            }
            p.vars.extend(added);
        }
    }
    files
}

/// The (method, variable) names of `p`'s methods' `VAR_INST`s.
fn var_inst_names(p: &Pou) -> impl Iterator<Item = (&str, &str)> {
    p.oop.methods.iter().flat_map(|m| {
        m.pou.vars.iter().filter(|b| b.kind == VarKind::Instance).flat_map(|b| &b.decls).flat_map(
            move |d| d.names.iter().map(move |n| (m.pou.name.name.as_str(), n.name.as_str())),
        )
    })
}

impl Ctx<'_> {
    /// The place of variable `var` of POU `p` declared in a section `kind`, when it is a
    /// method's (`member`) `VAR_INST`: its block's variable.
    pub(super) fn method_var_inst(
        &self,
        p: usize,
        member: Option<Role>,
        kind: VarKind,
        var: &str,
    ) -> Option<Storage> {
        if member != Some(Role::Method) || kind != VarKind::Instance {
            return None;
        }
        self.var_inst_storage(p, var).map(|(at, _)| at)
    }

    /// The place and type, in its block's instance, of `VAR_INST` `var` of method `method`
    /// (declared there by [`lower`]): the block's own (`Block.Method.var`) first, then the one
    /// it inherits (`Method.var`).
    pub(super) fn var_inst_storage(&self, method: usize, var: &str) -> Option<(Storage, Ty)> {
        let owner = self.pous[method].method?;
        let name = &self.oop.members.get(&method)?.name;
        let plain = hidden_name(name, var);
        let qualified = format!("{}.{plain}", self.pous[owner].name);
        let pou = &self.pous[owner];
        let i = pou.lookup(&qualified).or_else(|| pou.lookup(&plain))?;
        Some((pou.vars[i].storage, pou.vars[i].ty.clone()))
    }
}
