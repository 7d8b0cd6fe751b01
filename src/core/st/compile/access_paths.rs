//! `VAR_ACCESS` (IEC 61131-3 §6.8.2, access paths; docs/ST.md, Access paths): each entry
//! `name : path : TYPE [READ_ONLY | READ_WRITE]` of a CONFIGURATION, RESOURCE or PROGRAM names
//! a variable (of a program instance, a global, a member of an FB instance or a struct inside
//! one) or a device bit or word, under which clients reach it. This module checks what the
//! path names and that the declared type is its type, and turns each entry into a
//! [`crate::lang::AccessPath`]: the name and the name clients would otherwise give (`main.n`,
//! `P0001`). An access path is an alias: no memory, no code, nothing in the scan.
//!
//! Its name shares the clients' name space with the globals and the program instances (the
//! first part of every other variable name), so a name that is also one of those, or another
//! access path's, is an error: a client's name always means one thing.

use crate::device::Address;
use crate::lang::AccessPath;
use crate::st::ast::{self, AccessDecl, Ident, PouKind, VarKind};

use super::ctx::{suggest, Ctx, Scope};
use super::decl::iec_address;
use super::types::{Prim, Ty};
use super::var_config::{Declared, Placed};
use super::Instance;

/// An entry checked, before its name is checked against the other names clients give.
pub struct Checked {
    name: Ident,
    file: usize,
    path: AccessPath,
}

impl Checked {
    /// The path `decl` of `file`, found to name `target`.
    fn new(decl: &AccessDecl, file: usize, target: String) -> Checked {
        let path = AccessPath { name: decl.name.name.clone(), target, read_write: decl.read_write };
        Checked { name: decl.name.clone(), file, path }
    }
}

/// Where a path's variable is looked up: the variables of a PROGRAM (for an instance named
/// so), or the globals.
enum Start<'n> {
    Program { p: usize, instance: &'n str },
    Global,
}

impl Ctx<'_> {
    /// The access paths of the configuration `conf` of `file`; `declared` are its program
    /// instances. A path starts with an instance (`i.x`; IEC also writes the resource first,
    /// `Res0.i.x`), a global (`g`, `g.member`) or a direct address (`%IX1.1`, `Res0.%IX1.1`).
    pub fn configuration_access_paths(
        &mut self,
        file: usize,
        conf: &ast::Configuration,
        declared: &[Declared<'_>],
        placed: &Placed,
    ) -> Vec<Checked> {
        let mut checked = Vec::new();
        for decl in &conf.access {
            let is_instance = |id: &Ident| declared.iter().any(|(name, _)| id.is(name));
            let is_resource = |id: &Ident| {
                conf.resources.iter().filter_map(|r| r.name.as_ref()).any(|r| r.is(&id.name))
            };
            let path = match decl.path.split_first() {
                Some((first, rest))
                    if !rest.is_empty() && is_resource(first) && !is_instance(first) =>
                {
                    rest
                }
                _ => &decl.path[..],
            };
            let first = &path[0];
            let target = if first.name.starts_with('%') {
                if !self.unsubscripted(file, decl, decl.path.len()) {
                    continue;
                }
                self.device_target(file, decl, first)
            } else if let Some(&(name, k)) = declared.iter().find(|(name, _)| first.is(name)) {
                if !self.unsubscripted(file, decl, decl.path.len() - path.len() + 1) {
                    continue;
                }
                // an instance of no PROGRAM has been reported
                let Some((p, _)) = placed[k] else { continue };
                if path.len() < 2 {
                    let msg = format!(
                        "`{}` is a program instance: an access path names one of its variables \
                         (`{}.x`)",
                        first.name, first.name
                    );
                    self.error(file, first.span, msg);
                    continue;
                }
                self.variable_target(file, decl, Start::Program { p, instance: name }, &path[1..])
            } else if self.global_names.contains_key(&first.name.to_ascii_lowercase()) {
                if !self.unsubscripted(file, decl, decl.path.len() - path.len()) {
                    continue;
                }
                self.variable_target(file, decl, Start::Global, path)
            } else {
                let known = declared.iter().map(|(name, _)| *name);
                let hint =
                    suggest(&first.name, known.chain(self.globals.iter().map(|g| &g.name[..])));
                let msg = format!(
                    "`{}` is neither a program instance of the configuration nor a global \
                     variable{hint}",
                    first.name
                );
                self.error(file, first.span, msg);
                continue;
            };
            if let Some(target) = target {
                checked.push(Checked::new(decl, file, target));
            }
        }
        checked
    }

    /// The access paths the PROGRAMs declare, for the one instance each PROGRAM has: a path
    /// names a variable of the PROGRAM (`n`, `fb.q`; IEC examples also write the PROGRAM's name
    /// first, `main.n`) or a direct address. A FUNCTION or FUNCTION_BLOCK declares none.
    pub fn program_access_paths(
        &mut self,
        instances: &[Instance<'_>],
        placed: &Placed,
    ) -> Vec<Checked> {
        let mut checked = Vec::new();
        for p in 0..self.pous.len() {
            let pou = &self.pous[p];
            let (ast, file) = (pou.ast, pou.file);
            if ast.access.is_empty() || pou.copy_of.is_some() || pou.action.is_some() {
                continue;
            }
            if pou.kind != PouKind::Program {
                let what =
                    if pou.kind == PouKind::Function { "FUNCTION" } else { "FUNCTION_BLOCK" };
                let msg = format!(
                    "`{}` is a {what}: only a PROGRAM or a CONFIGURATION declares access paths \
                     (a {what}'s variables have no one place clients could name)",
                    pou.name
                );
                self.error(file, ast.access[0].span, msg);
                continue;
            }
            let of_p = |q: usize| q == p || self.pous[q].copy_of == Some(p);
            let mine: Vec<usize> =
                (0..instances.len()).filter(|&k| placed[k].is_some_and(|(q, _)| of_p(q))).collect();
            let [k] = mine[..] else {
                if mine.len() > 1 {
                    let first = &ast.access[0];
                    let msg = format!(
                        "the PROGRAM `{}` has {} instances: its access path `{}` would name a \
                         variable of each; declare the access paths in the CONFIGURATION \
                         (`{} : {}.{} : …`)",
                        pou.name,
                        mine.len(),
                        first.name.name,
                        first.name.name,
                        instances[mine[0]].name,
                        path_text(first)
                    );
                    self.error(file, first.name.span, msg);
                }
                continue;
            };
            let instance = instances[k].name;
            for decl in &ast.access {
                let path = match decl.path.split_first() {
                    Some((first, rest))
                        if !rest.is_empty()
                            && first.is(&self.pous[p].name)
                            && self.pous[p].lookup(&first.name).is_none() =>
                    {
                        rest
                    }
                    _ => &decl.path[..],
                };
                let prefix = if path[0].name.starts_with('%') {
                    decl.path.len()
                } else {
                    decl.path.len() - path.len()
                };
                if !self.unsubscripted(file, decl, prefix) {
                    continue;
                }
                let target = if path[0].name.starts_with('%') {
                    self.device_target(file, decl, &path[0])
                } else {
                    self.variable_target(file, decl, Start::Program { p, instance }, path)
                };
                if let Some(target) = target {
                    checked.push(Checked::new(decl, file, target));
                }
            }
        }
        checked
    }

    /// The access paths whose names are each the only thing clients name so: not another
    /// access path's, a global's or a program instance's.
    pub fn named_access_paths(
        &mut self,
        checked: Vec<Checked>,
        instances: &[Instance<'_>],
    ) -> Vec<AccessPath> {
        let mut named: Vec<AccessPath> = Vec::new();
        let mut lines: Vec<u32> = Vec::new();
        for entry in checked {
            let name = &entry.name;
            if let Some(k) = named.iter().position(|a| name.is(&a.name)) {
                let msg = format!("`{}` is already declared (line {})", name.name, lines[k]);
                self.error(entry.file, name.span, msg);
                continue;
            }
            let other = if self.global_names.contains_key(&name.name.to_ascii_lowercase()) {
                Some("a global variable".to_string())
            } else if Address::parse(&name.name).is_ok() {
                Some(format!("the device `{}`", name.name))
            } else {
                instances
                    .iter()
                    .find(|i| name.is(i.name))
                    .map(|i| format!("the program instance `{}`", i.name))
            };
            if let Some(other) = other {
                let msg = format!(
                    "the access path `{}` has the name of {other}: a client's name must mean one \
                     thing",
                    name.name
                );
                self.error(entry.file, name.span, msg);
                continue;
            }
            lines.push(name.span.line);
            named.push(entry.path);
        }
        named
    }

    /// The device a path's direct address names (`P0001`), checked against the declared
    /// type: a bit is a `BOOL`, a word an `INT`, `UINT` or `WORD` (clients read a device's 16
    /// bits).
    fn device_target(
        &mut self,
        file: usize,
        decl: &AccessDecl,
        location: &Ident,
    ) -> Option<String> {
        let text = &location.name[1..];
        let (device, bits) = match iec_address(text, &self.dialect.iec) {
            Ok(Some((device, bits))) => (device, bits),
            Ok(None) => (text.to_string(), None),
            Err(msg) => {
                self.error(file, location.span, msg);
                return None;
            }
        };
        let address = match Address::parse(&device) {
            Ok(address) => address,
            Err(e) => {
                self.error(file, location.span, e.to_string());
                return None;
            }
        };
        let given = self.resolve_type_ref(&decl.ty, Scope { pou: None, visible: 0, file });
        if given.is_error() {
            return None;
        }
        let is_bit = address.as_word().is_err();
        let fits = match given.prim(&self.types) {
            Some(Prim::Bool) => is_bit,
            Some(Prim::Int | Prim::UInt | Prim::Word) => !is_bit && bits.is_none_or(|b| b == 16),
            _ => false,
        };
        if !fits {
            let (what, types) =
                if is_bit { ("a bit", "BOOL") } else { ("a word", "INT, UINT or WORD") };
            let msg = format!(
                "`{}` is {what} ({address}): its access path's type is {types}, not `{}`",
                location.name,
                self.ty_name(&given)
            );
            self.error(file, location.span, msg);
            return None;
        }
        Some(address.to_string())
    }

    /// The name clients give the variable at `path` (`main.fb.q`, `g.member`), checked: a
    /// variable the instance (or the globals) holds, and of the declared type.
    fn variable_target(
        &mut self,
        file: usize,
        decl: &AccessDecl,
        start: Start<'_>,
        path: &[Ident],
    ) -> Option<String> {
        let first = &path[0];
        // subscripts are constants: of the PROGRAM, or global ones
        let scope = match start {
            Start::Program { p, .. } => {
                Scope { pou: Some(p), visible: self.pous[p].vars.len(), file }
            }
            Start::Global => Scope { pou: None, visible: 0, file },
        };
        let (var, prefix) = match start {
            Start::Program { p, instance } => {
                let pou = &self.pous[p];
                let Some(v) = pou.lookup(&first.name) else {
                    let hint = suggest(&first.name, pou.vars.iter().map(|v| v.name.as_str()));
                    let msg = format!("`{}` has no variable `{}`{hint}", pou.name, first.name);
                    self.error(file, first.span, msg);
                    return None;
                };
                let var = pou.vars[v].clone();
                // one VAR_STAT for every instance, named after the PROGRAM
                let prefix = if var.kind == VarKind::Static {
                    pou.name.clone()
                } else {
                    instance.to_string()
                };
                if !self.held(file, first, var.kind, var.by_ref, &pou.name.clone()) {
                    return None;
                }
                (var, format!("{prefix}."))
            }
            Start::Global => {
                let g = self.global_names[&first.name.to_ascii_lowercase()];
                (self.globals[g].clone(), String::new())
            }
        };
        // the subscripts of `path`'s parts, `decl.path` ending with it
        let subscripts = &decl.subscripts[decl.path.len() - path.len()..];
        let (mut ty, mut name) = self.subscripted(
            scope,
            &subscripts[0],
            var.ty.clone(),
            format!("{prefix}{}", var.name),
        )?;
        for (id, groups) in path[1..].iter().zip(&subscripts[1..]) {
            let (member_ty, member_name) = match &ty {
                Ty::Fb(q) => {
                    let fb = &self.pous[*q];
                    let Some(m) = fb.lookup(&id.name).map(|i| fb.vars[i].clone()) else {
                        let hint = suggest(&id.name, fb.vars.iter().map(|v| v.name.as_str()));
                        let msg = format!("`{}` has no variable `{}`{hint}", fb.name, id.name);
                        self.error(file, id.span, msg);
                        return None;
                    };
                    if !self.held(file, id, m.kind, m.by_ref, &fb.name.clone()) {
                        return None;
                    }
                    (m.ty, m.name)
                }
                Ty::Struct(s) => {
                    let st = &self.types.structs[*s];
                    let Some(m) = st.members.iter().find(|m| id.is(&m.name)).cloned() else {
                        let hint = suggest(&id.name, st.members.iter().map(|m| m.name.as_str()));
                        let msg = format!("`{}` has no member `{}`{hint}", st.name, id.name);
                        self.error(file, id.span, msg);
                        return None;
                    };
                    (m.ty, m.name)
                }
                other => {
                    let n = self.ty_name(other);
                    let msg = format!("`{name}` is `{n}`: it has no variables or members");
                    self.error(file, id.span, msg);
                    return None;
                }
            };
            (ty, name) =
                self.subscripted(scope, groups, member_ty, format!("{name}.{member_name}"))?;
        }
        let given = self.resolve_type_ref(&decl.ty, Scope { pou: None, visible: 0, file });
        if given.is_error() || ty.is_error() {
            return None;
        }
        if given != ty {
            let (given, declared) = (self.ty_name(&given), self.ty_name(&ty));
            let msg = format!("`{}` is `{declared}`, not `{given}`", path_text(decl));
            self.error(file, path[path.len() - 1].span, msg);
            return None;
        }
        Some(name)
    }

    /// The element of the variable `name` of type `ty` that the subscripts written after its
    /// part of the path name (`arr[3]`, `m[1, 2]`, `a[1][2]`), and its name as clients give it
    /// (`main.m[1,2]`): each subscript a constant within its dimension's bounds.
    fn subscripted(
        &mut self,
        scope: Scope,
        groups: &[Vec<ast::Expr>],
        ty: Ty,
        name: String,
    ) -> Option<(Ty, String)> {
        let file = scope.file;
        let (mut ty, mut name) = (ty, name);
        for group in groups {
            let span = group[0].span;
            let Ty::Array(a) = &ty else {
                let n = self.ty_name(&ty);
                self.error(file, span, format!("`{name}` is `{n}`, not an array"));
                return None;
            };
            if a.dims.len() != group.len() {
                let msg = format!(
                    "`{name}` has {} dimension(s), {} index(es) given",
                    a.dims.len(),
                    group.len()
                );
                self.error(file, span, msg);
                return None;
            }
            let mut indexes = Vec::new();
            for (e, &(lo, hi)) in group.iter().zip(&a.dims) {
                let v = self.const_int(e, scope)?;
                if v < i128::from(lo) || v > i128::from(hi) {
                    self.error(
                        file,
                        e.span,
                        format!("index {v} is out of the bounds `{lo}..{hi}`"),
                    );
                    return None;
                }
                indexes.push(v.to_string());
            }
            name = format!("{name}[{}]", indexes.join(","));
            ty = a.of.clone();
        }
        Some((ty, name))
    }

    /// Reports subscripts written after one of the first `parts` parts of the path of `decl`
    /// (a resource, a program instance, the PROGRAM's own name, a direct address): only a
    /// variable is an array. Whether there were none.
    fn unsubscripted(&mut self, file: usize, decl: &AccessDecl, parts: usize) -> bool {
        let mut none = true;
        for (id, groups) in decl.path.iter().zip(&decl.subscripts).take(parts) {
            if let Some(group) = groups.first() {
                let msg = format!(
                    "`{}` takes no subscript: in an access path, only an array variable does",
                    id.name
                );
                self.error(file, group[0].span, msg);
                none = false;
            }
        }
        none
    }

    /// Whether a variable of this kind lives in its instance's memory (not a VAR_TEMP, a
    /// VAR_IN_OUT or a VAR_EXTERNAL); reported when not.
    fn held(&mut self, file: usize, id: &Ident, kind: VarKind, by_ref: bool, owner: &str) -> bool {
        let what = match kind {
            VarKind::Temp => "a VAR_TEMP",
            VarKind::InOut => "a VAR_IN_OUT",
            VarKind::External => "a VAR_EXTERNAL",
            _ if by_ref => "a VAR_IN_OUT",
            _ => return true,
        };
        let msg = format!(
            "`{}` is {what} of `{owner}`: an access path names a variable the instance holds \
             from one scan to the next (VAR, VAR_INPUT, VAR_OUTPUT; a global by its own name)",
            id.name
        );
        self.error(file, id.span, msg);
        false
    }
}

/// A path as written (`i.fb.x`; `i.arr[…]`, as messages write an element).
fn path_text(decl: &AccessDecl) -> String {
    let part = |(id, groups): (&Ident, &Vec<Vec<ast::Expr>>)| {
        format!("{}{}", id.name, "[…]".repeat(groups.len()))
    };
    decl.path.iter().zip(&decl.subscripts).map(part).collect::<Vec<_>>().join(".")
}
