//! `VAR_CONFIG` of a configuration (docs/ST.md, Configurations): the device of a program
//! instance's variable declared at a partly specified address (`x AT %Q* : BOOL;` in the
//! PROGRAM, `i.x AT %QX0.1 : BOOL;` in the configuration). The variable becomes a located one, as
//! if it had been declared at that address: every piece of code that names it reads and writes
//! the device, and its initial value (the entry's, or else the declaration's) is written to the
//! device at RUN start.
//!
//! A PROGRAM's code is compiled once for all its instances, so a variable is bound for a PROGRAM
//! with one instance in the project, and only a variable of the instance itself (`i.x`), not
//! one inside its FUNCTION_BLOCK instances (whose code every instance of the block shares):
//! the other cases are refused, each with its own message.

use crate::st::ast::{self, ConfigVar, VarKind};

use super::ctx::{suggest, Ctx, Scope};
use super::decl::iec_address;

/// Whether `full` is an IEC direct address (`QX0.1`) with the area letter and the size letter
/// the partly specified address `partial` fixes (`Q*`: `Q` and any size; `QX*`: `Q` and `X`).
fn fits(partial: &str, full: &str) -> bool {
    let partial = partial.trim_end_matches('*').to_ascii_uppercase();
    full.to_ascii_uppercase().starts_with(&partial) && matches!(iec_address(full), Ok(Some(_)))
}

impl Ctx<'_> {
    /// Binds the `VAR_CONFIG` entries of `conf`, written in `file`: `declared` are the
    /// configuration's program instances (name, PROGRAM when found), `programs` the PROGRAM of
    /// each instance of the project (to count a PROGRAM's instances).
    pub fn bind_var_config(
        &mut self,
        file: usize,
        conf: &ast::Configuration,
        declared: &[(&str, Option<usize>)],
        programs: &[Option<usize>],
    ) {
        let mut bound: Vec<(usize, usize, u32)> = Vec::new();
        for entry in &conf.var_config {
            if let Some((p, v)) = self.bound_variable(file, conf, entry, declared, programs) {
                if let Some(&(_, _, line)) = bound.iter().find(|b| (b.0, b.1) == (p, v)) {
                    let name = path_text(entry);
                    let msg = format!("`{name}` is already bound by VAR_CONFIG (line {line})");
                    self.error(file, entry.path[0].span, msg);
                    continue;
                }
                bound.push((p, v, entry.span.line));
                self.bind(file, entry, p, v);
            }
        }
    }

    /// The PROGRAM and the index of the variable `entry` names, when it may be bound.
    fn bound_variable(
        &mut self,
        file: usize,
        conf: &ast::Configuration,
        entry: &ConfigVar,
        declared: &[(&str, Option<usize>)],
        programs: &[Option<usize>],
    ) -> Option<(usize, usize)> {
        // IEC writes the path from the resource (`Res0.instance0.x`), CODESYS from the instance
        let path = match entry.path.split_first() {
            Some((first, rest))
                if rest.len() >= 2
                    && resource_named(conf, first)
                    && !declared.iter().any(|(name, _)| first.is(name)) =>
            {
                rest
            }
            _ => &entry.path[..],
        };
        let instance = &path[0];
        let Some(&(_, p)) = declared.iter().find(|(name, _)| instance.is(name)) else {
            let hint = suggest(&instance.name, declared.iter().map(|(name, _)| *name));
            let msg =
                format!("`{}` is not a PROGRAM instance of the configuration{hint}", instance.name);
            self.error(file, instance.span, msg);
            return None;
        };
        // an instance of no PROGRAM has been reported
        let p = p?;
        let Some(variable) = path.get(1) else {
            let msg = format!(
                "VAR_CONFIG names a variable of a program instance: `{}.variable`",
                instance.name
            );
            self.error(file, instance.span, msg);
            return None;
        };
        let pou = &self.pous[p];
        let Some(v) = pou.lookup(&variable.name) else {
            let hint = suggest(&variable.name, pou.vars.iter().map(|v| v.name.as_str()));
            let msg = format!("`{}` has no variable `{}`{hint}", pou.name, variable.name);
            self.error(file, variable.span, msg);
            return None;
        };
        if let Some(inner) = path.get(2) {
            let msg = format!(
                "VAR_CONFIG binds a variable of a program instance (`{}.{}`), not one inside it: \
                 the code of a FUNCTION_BLOCK is shared by all its instances",
                instance.name, variable.name
            );
            self.error(file, inner.span, msg);
            return None;
        }
        let count = programs.iter().filter(|&&q| q == Some(p)).count();
        if count > 1 {
            let msg = format!(
                "`{}` has {count} instances in the project: VAR_CONFIG binds a variable of a \
                 PROGRAM with one instance (its code is shared by all)",
                pou.name
            );
            self.error(file, instance.span, msg);
            return None;
        }
        let partial = pou
            .ast
            .vars
            .iter()
            .flat_map(|b| &b.decls)
            .find(|d| d.names.iter().any(|n| n.is(&variable.name)))
            .and_then(|d| d.location.as_ref())
            .filter(|l| l.name.ends_with('*'));
        // a variable of the instance (not a VAR_TEMP, VAR_IN_OUT, VAR_EXTERNAL or VAR_STAT)
        let own = matches!(pou.vars[v].kind, VarKind::Local | VarKind::Input | VarKind::Output);
        let Some(partial) = partial.filter(|_| own) else {
            let msg = format!(
                "`{}.{}` is not declared at a partly specified address (`AT %I*`, `%Q*`, \
                 `%M*`): VAR_CONFIG binds only such a variable",
                instance.name, variable.name
            );
            self.error(file, variable.span, msg);
            return None;
        };
        if !fits(&partial.name, &entry.location.name) {
            let msg = format!(
                "`%{}` does not fit `{}`, declared at `%{}`",
                entry.location.name, variable.name, partial.name
            );
            self.error(file, entry.location.span, msg);
            return None;
        }
        let scope = Scope { pou: None, visible: 0, file };
        let ty = self.resolve_type_ref(&entry.ty, scope);
        let declared_ty = self.pous[p].vars[v].ty.clone();
        if ty != declared_ty && !ty.is_error() && !declared_ty.is_error() {
            let (given, declared) = (self.ty_name(&ty), self.ty_name(&declared_ty));
            let msg =
                format!("`{}.{}` is `{declared}`, not `{given}`", instance.name, variable.name);
            self.error(file, variable.span, msg);
            return None;
        }
        Some((p, v))
    }

    /// Makes the variable `v` of the PROGRAM `p` (and of its actions, which share it) the
    /// located variable `entry` says.
    fn bind(&mut self, file: usize, entry: &ConfigVar, p: usize, v: usize) {
        let var = self.pous[p].vars[v].clone();
        let Some((storage, address)) = self.locate(file, &entry.location, &var.ty, &var.name)
        else {
            return;
        };
        for q in 0..self.pous.len() {
            if q == p || self.pous[q].action.is_some_and(|(_, owner)| owner == p) {
                let shared = &mut self.pous[q].vars[v];
                shared.storage = storage;
                shared.located = Some(address);
                // the device's own retention applies, as to any located variable
                shared.retain = false;
            }
        }
        match &entry.init {
            Some(init) => {
                let scope = Scope { pou: None, visible: 0, file };
                self.located_init_for(storage, &var.ty, &entry.ty, Some(init), scope, &var.name);
            }
            None => {
                let pou = &self.pous[p];
                let decl = pou
                    .ast
                    .vars
                    .iter()
                    .flat_map(|b| &b.decls)
                    .find(|d| d.names.iter().any(|n| n.is(&var.name)));
                if let Some(decl) = decl.filter(|d| d.init.is_some()) {
                    let scope = Scope { pou: Some(p), visible: pou.vars.len(), file: pou.file };
                    let init = decl.init.as_ref();
                    self.located_init_for(storage, &var.ty, &decl.ty, init, scope, &var.name);
                }
            }
        }
    }
}

/// Whether `name` is a RESOURCE of `conf`.
fn resource_named(conf: &ast::Configuration, name: &ast::Ident) -> bool {
    conf.resources.iter().filter_map(|r| r.name.as_ref()).any(|r| r.is(&name.name))
}

/// `i.x` as written.
fn path_text(entry: &ConfigVar) -> String {
    entry.path.iter().map(|id| id.name.as_str()).collect::<Vec<_>>().join(".")
}
