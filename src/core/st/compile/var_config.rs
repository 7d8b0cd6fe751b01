//! `VAR_CONFIG` of a configuration (docs/ST.md, Configurations), its two kinds of entries:
//!
//! - `i.x AT %QX0.1 : BOOL [:= v];` binds the variable `x` of the program instance `i`,
//!   declared at a partly specified address (`x AT %Q* : BOOL;`), to a device. The variable
//!   becomes a located one, as if it had been declared at that address: every piece of code
//!   that names it reads and writes the device, and its initial value (the entry's, or else the
//!   declaration's) is written to the device at RUN start. A PROGRAM's code is compiled once
//!   for all its instances: when the PROGRAM has other instances, the instance gets a copy of
//!   the PROGRAM of its own ([`PouInfo::copy_of`](super::ctx::PouInfo)), compiled with the
//!   variable at the device; a PROGRAM with actions (which would need copies too) cannot be so
//!   copied. A variable inside one of its FUNCTION_BLOCK instances (`i.fb.x`) is bound by a
//!   lowering, which gives that instance a copy of its block (`fb_config.rs`), and so is a
//!   member of a struct variable (`i.hw.IN`, `i.fb.hw.IN`), the variable given a copy of its
//!   type; both are checked here. The other cases are refused, each with its own message.
//! - `i.fb.x : INT := v;` gives a variable of the instance, or of a FUNCTION_BLOCK instance or a
//!   struct inside it, its initial value for that instance: written into the instance's own
//!   initial image (each instance has its own memory), or for a located variable to its
//!   device at RUN start.
//!
//! A path may start with the resource's name, as IEC writes it (`Res0.i.x`).
//!
//! The config's `[iec.variables]` (`"main.lamp" = "%QX0.3"`) is applied here too, its entries
//! made into `ConfigVar`s with neither a type (the variable's is taken) nor an initial value
//! ([`config_entries`]), after the configurations' `VAR_CONFIG`s: they bind the variables of
//! any program instance of the project, a configuration's or a `[[program]]`'s, and may name a
//! plcd device (`%P0040`); a variable both bind is an error at the config's key. Errors about
//! them are at the config's keys and values, which the compile sees as a file of no items.

use crate::config::IecVariable;
use crate::device::iec::IecLayout;
use crate::device::Address;
use crate::st::ast::{self, ConfigVar, Ident, PouKind, Span, VarKind};

use super::ctx::{suggest, Ctx, Scope, Storage};
use super::decl::iec_address;
use super::types::Ty;

/// Whether `full` is an IEC direct address (`QX0.1`) with the area letter and the size letter
/// the partly specified address `partial` fixes (`Q*`: `Q` and any size; `QX*`: `Q` and `X`),
/// or, where `devices` (the config's bindings), a plcd device the size letter fits: a bit for
/// `X`, a word for the others, either without one (`Q*`). Which of I, Q, M a device is, is no
/// device's to say: the config's author names the device itself.
pub(super) fn fits(partial: &str, full: &str, layout: &IecLayout, devices: bool) -> bool {
    let partial = partial.trim_end_matches('*').to_ascii_uppercase();
    match iec_address(full, layout) {
        Ok(Some(_)) => full.to_ascii_uppercase().starts_with(&partial),
        Ok(None) if devices => match (Address::parse(full), partial.chars().nth(1)) {
            (Err(_), _) => false,
            (Ok(_), None) => true,
            (Ok(address), Some('X')) => address.bit.is_some(),
            (Ok(address), Some(_)) => address.bit.is_none(),
        },
        _ => false,
    }
}

/// Who binds an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Binder {
    /// A configuration's `VAR_CONFIG`: IEC addresses only, its configuration's instances.
    VarConfig,
    /// The config's `[iec.variables]`: plcd devices too, every instance of the project.
    Config,
}

impl Binder {
    /// How messages name it.
    fn name(self) -> &'static str {
        match self {
            Binder::VarConfig => "VAR_CONFIG",
            Binder::Config => "[iec.variables]",
        }
    }

    /// How messages name the instances its paths start with.
    fn instances(self) -> &'static str {
        match self {
            Binder::VarConfig => "the configuration",
            Binder::Config => "the project",
        }
    }
}

/// The entries of one configuration's `VAR_CONFIG`, or of the config's `[iec.variables]`, with
/// what their paths may name.
pub struct Bindings<'e> {
    pub binder: Binder,
    /// Where they are written: the configuration's file, or the config's.
    pub file: usize,
    pub entries: &'e [ConfigVar],
    /// The resources a path may start with (`Res0.i.x`, as IEC writes it).
    pub resources: Vec<&'e str>,
    /// The program instances the paths name.
    pub declared: Vec<Declared<'e>>,
}

/// The config's `[iec.variables]` as `VAR_CONFIG` entries: each name of the path and the entry
/// itself at the key, the address at the value.
pub(super) fn config_entries(variables: &[IecVariable]) -> Vec<ConfigVar> {
    variables
        .iter()
        .map(|v| {
            let key = Span { line: v.line, col: v.col };
            let value = Span { line: v.value_line, col: v.value_col };
            ConfigVar {
                path: v.path.iter().map(|name| Ident { name: name.clone(), span: key }).collect(),
                location: Some(Ident { name: v.address.clone(), span: value }),
                ty: None,
                init: None,
                span: key,
            }
        })
        .collect()
}

/// Where an entry bound a variable, for the message about a second one.
#[derive(Debug, Clone)]
struct Origin {
    binder: Binder,
    file: usize,
    line: u32,
    /// The path as written (`[iec.variables]`'s key).
    key: String,
}

/// Whether a variable of this kind is the instance's own (not a VAR_TEMP, VAR_IN_OUT,
/// VAR_EXTERNAL or VAR_STAT).
fn own(kind: VarKind) -> bool {
    matches!(kind, VarKind::Local | VarKind::Input | VarKind::Output | VarKind::Instance)
}

/// A configuration's program instance: its name and its index among the compile's instances.
pub type Declared<'n> = (&'n str, usize);

/// Each instance's PROGRAM and the base of its variables (`None` when its PROGRAM was not
/// found), which a copy of the PROGRAM replaces.
pub type Placed = [Option<(usize, u32)>];

impl Ctx<'_> {
    /// Applies the entries of `sources`, the configurations' `VAR_CONFIG`s and then the
    /// config's `[iec.variables]`: `placed` is every instance's PROGRAM (a copy of it replaces
    /// it for an instance that binds a variable its PROGRAM's other instances keep). The
    /// bindings first, so that an initial value given a bound variable goes to its device.
    pub fn apply_var_config(&mut self, sources: &[Bindings<'_>], placed: &mut Placed) {
        let mut bound: Vec<(usize, usize, Origin)> = Vec::new();
        let mut bound_inside: Vec<(usize, String, Origin)> = Vec::new();
        for source in sources {
            for entry in source.entries {
                let Some(location) = &entry.location else { continue };
                let before = self.diags.len();
                let inside = &mut bound_inside;
                self.bind_entry(source, (entry, location), placed, &mut bound, inside);
                if source.binder == Binder::Config {
                    // named by the key, as the config's own errors are
                    let (key, config) = (path_text(&entry.path), self.path(source.file));
                    for d in self.diags[before..].iter_mut().filter(|d| d.path == config) {
                        d.message = format!("iec.variables {key:?}: {}", d.message);
                    }
                }
            }
        }
        for source in sources {
            for entry in source.entries.iter().filter(|e| e.location.is_none()) {
                self.initialize(source, entry, placed);
            }
        }
    }

    /// Binds the variable an entry with an address names, when it may be bound; `bound` and
    /// `inside` hold those bound so far (of the instances, of their blocks' instances).
    fn bind_entry(
        &mut self,
        source: &Bindings<'_>,
        (entry, location): (&ConfigVar, &Ident),
        placed: &mut Placed,
        bound: &mut Vec<(usize, usize, Origin)>,
        inside: &mut Vec<(usize, String, Origin)>,
    ) {
        let Some((k, p, v)) = self.bound_variable(source, (entry, location), placed, inside) else {
            return;
        };
        if let Some((_, _, first)) = bound.iter().find(|b| (b.0, b.1) == (k, v)) {
            let msg = self.already_bound(&entry.path, first, source.file);
            self.error(source.file, entry.path[0].span, msg);
            return;
        }
        bound.push((k, v, origin(source, entry)));
        let shared = self.instances_of(p, placed) > 1;
        let target = match placed[k] {
            Some((q, base)) if shared && self.pous[q].copy_of.is_none() => {
                let mut copy = self.pous[q].clone();
                copy.copy_of = Some(q);
                self.pous.push(copy);
                placed[k] = Some((self.pous.len() - 1, base));
                self.pous.len() - 1
            }
            Some((q, _)) => q,
            None => return,
        };
        self.bind(source.file, entry, location, target, v);
    }

    /// The message about a second binding of the variable at `path`, which `first` bound,
    /// written in `file`.
    fn already_bound(&self, path: &[Ident], first: &Origin, file: usize) -> String {
        let by = match first.binder {
            Binder::VarConfig => first.binder.name().to_string(),
            Binder::Config => format!("[iec.variables] {:?}", first.key),
        };
        let at = match first.file == file {
            true => format!("line {}", first.line),
            false => format!("{}:{}", self.path(first.file).display(), first.line),
        };
        format!("`{}` is already bound by {by} ({at})", path_text(path))
    }

    /// The instance an entry's path starts with: the path from it on, the instance's index,
    /// its PROGRAM and base.
    fn instance_of<'e>(
        &mut self,
        source: &Bindings<'_>,
        entry: &'e ConfigVar,
        placed: &Placed,
    ) -> Option<(&'e [Ident], usize, usize, u32)> {
        let (file, declared) = (source.file, &source.declared);
        // IEC writes the path from the resource (`Res0.instance0.x`), CODESYS from the instance
        let path = match entry.path.split_first() {
            Some((first, rest))
                if rest.len() >= 2
                    && source.resources.iter().any(|r| first.is(r))
                    && !declared.iter().any(|(name, _)| first.is(name)) =>
            {
                rest
            }
            _ => &entry.path[..],
        };
        let instance = &path[0];
        let Some(&(_, k)) = declared.iter().find(|(name, _)| instance.is(name)) else {
            let hint = suggest(&instance.name, declared.iter().map(|(name, _)| *name));
            let of = source.binder.instances();
            let msg = format!("`{}` is not a PROGRAM instance of {of}{hint}", instance.name);
            self.error(file, instance.span, msg);
            return None;
        };
        // an instance of no PROGRAM has been reported
        let (p, base) = placed[k]?;
        if path.len() < 2 {
            let msg = format!(
                "VAR_CONFIG names a variable of a program instance: `{}.variable`",
                instance.name
            );
            self.error(file, instance.span, msg);
            return None;
        }
        Some((path, k, p, base))
    }

    /// How many instances of the project are of the PROGRAM `p` (or run a copy of it).
    fn instances_of(&self, p: usize, placed: &Placed) -> usize {
        let of_p = |q: usize| q == p || self.pous[q].copy_of == Some(p);
        placed.iter().filter(|x| x.is_some_and(|(q, _)| of_p(q))).count()
    }

    /// The variable `p.vars[v]` that `path[1]` names, reported when there is none.
    fn program_variable(&mut self, file: usize, p: usize, name: &Ident) -> Option<usize> {
        let pou = &self.pous[p];
        let found = pou.lookup(&name.name);
        if found.is_none() {
            let hint = suggest(&name.name, pou.vars.iter().map(|v| v.name.as_str()));
            let msg = format!("`{}` has no variable `{}`{hint}", pou.name, name.name);
            self.error(file, name.span, msg);
        }
        found
    }

    /// The instance, its PROGRAM and the index of the variable a binding names, when it may be
    /// bound; `None` too for a variable inside a FUNCTION_BLOCK instance, which the lowering
    /// bound (`fb_config.rs`) and which is checked here, `inside` holding those bound so far.
    fn bound_variable(
        &mut self,
        source: &Bindings<'_>,
        (entry, location): (&ConfigVar, &Ident),
        placed: &Placed,
        inside: &mut Vec<(usize, String, Origin)>,
    ) -> Option<(usize, usize, usize)> {
        let (file, binder) = (source.file, source.binder);
        let (path, k, p, _) = self.instance_of(source, entry, placed)?;
        if path.len() > 2 {
            let text = path_text(path).to_ascii_lowercase();
            if let Some((_, _, first)) = inside.iter().find(|b| (b.0, &b.1) == (k, &text)) {
                let msg = self.already_bound(&entry.path, first, file);
                self.error(file, entry.path[0].span, msg);
            } else if self.check_bound_inside(source, (entry, location), path, p) {
                inside.push((k, text, origin(source, entry)));
            }
            return None;
        }
        // the PROGRAM itself, when this instance has a copy of it already
        let p = self.pous[p].copy_of.unwrap_or(p);
        let (instance, variable) = (&path[0], &path[1]);
        let v = self.program_variable(file, p, variable)?;
        let pou = &self.pous[p];
        let count = self.instances_of(p, placed);
        let actions = self.pous.iter().any(|a| a.action.is_some_and(|(_, owner)| owner == p));
        if count > 1 && actions {
            let msg = format!(
                "`{}` has {count} instances in the project and actions: {} binds a variable of \
                 a PROGRAM with actions for its only instance (the actions' code is shared by \
                 all)",
                pou.name,
                binder.name()
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
        let Some(partial) = partial.filter(|_| own(pou.vars[v].kind)) else {
            let msg = not_partly_specified(&format!("{}.{}", instance.name, variable.name), binder);
            self.error(file, variable.span, msg);
            return None;
        };
        if !fits(&partial.name, &location.name, &self.dialect.iec, binder == Binder::Config) {
            let msg = format!(
                "`%{}` does not fit `{}`, declared at `%{}`",
                location.name, variable.name, partial.name
            );
            self.error(file, location.span, msg);
            return None;
        }
        let declared_ty = self.pous[p].vars[v].ty.clone();
        self.same_type(file, entry, path, &declared_ty).then_some((k, p, v))
    }

    /// Checks a binding of a variable inside a FUNCTION_BLOCK instance of the instance whose
    /// PROGRAM (or copy of it) is `p`, which the lowering made when it fits (`fb_config.rs`):
    /// the variable is then declared at the entry's address in a copy of its block. Whether
    /// the entry binds it.
    fn check_bound_inside(
        &mut self,
        source: &Bindings<'_>,
        (entry, location): (&ConfigVar, &Ident),
        path: &[Ident],
        p: usize,
    ) -> bool {
        let (file, binder) = (source.file, source.binder);
        let Some(v) = self.program_variable(file, p, &path[1]) else { return false };
        let var = &self.pous[p].vars[v];
        let mut ty = var.ty.clone();
        // the kind of the variable `ty` is of, and whether it is CONSTANT
        let mut holder = (var.kind, var.constant);
        // where the struct variable is in the path, once one is met
        let mut variable = None;
        for (at, id) in path.iter().enumerate().skip(2) {
            let q = match ty {
                Ty::Fb(q) => q,
                Ty::Error => return false,
                Ty::Struct(s) if at + 1 == path.len() => {
                    let variable = variable.unwrap_or(at - 1);
                    let bound = (entry, location);
                    return self.check_bound_member(source, bound, path, variable, s, holder);
                }
                Ty::Struct(s) => {
                    // a member of a member: the lowering copied each struct on the way
                    variable.get_or_insert(at - 1);
                    let st = &self.types.structs[s];
                    let Some(m) = st.members.iter().find(|m| id.is(&m.name)) else {
                        let hint = suggest(&id.name, st.members.iter().map(|m| m.name.as_str()));
                        let msg = format!("`{}` has no member `{}`{hint}", st.name, id.name);
                        self.error(file, id.span, msg);
                        return false;
                    };
                    ty = m.ty.clone();
                    continue;
                }
                other => {
                    let n = self.ty_name(&other);
                    let msg = format!(
                        "`{}` is `{n}`: {} binds a variable of a program instance or of a \
                         FUNCTION_BLOCK instance inside it, or a member of a struct variable \
                         of one at any depth, not an element of an array",
                        path_text(&path[..at]),
                        binder.name()
                    );
                    self.error(file, id.span, msg);
                    return false;
                }
            };
            let fb = &self.pous[q];
            let Some(m) = fb.lookup(&id.name) else {
                let hint = suggest(&id.name, fb.vars.iter().map(|v| v.name.as_str()));
                let msg = format!("`{}` has no variable `{}`{hint}", fb.name, id.name);
                self.error(file, id.span, msg);
                return false;
            };
            if at + 1 < path.len() {
                ty = fb.vars[m].ty.clone();
                holder = (fb.vars[m].kind, fb.vars[m].constant);
                continue;
            }
            let kind = fb.vars[m].kind;
            let written = |pou: &ast::Pou| {
                pou.vars
                    .iter()
                    .flat_map(|b| &b.decls)
                    .find(|d| d.names.iter().any(|n| n.is(&id.name)))
                    .and_then(|d| d.location.clone())
            };
            let at_address = written(fb.ast);
            let bound = at_address.is_some_and(|l| l.name.eq_ignore_ascii_case(&location.name));
            // a copy's name is its block's and the instance's (`fb_config.rs`)
            let copy_of = fb.name.split_once('$').map(|(block, _)| block);
            if bound && copy_of.is_some() {
                let declared_ty = fb.vars[m].ty.clone();
                return self.same_type(file, entry, path, &declared_ty);
            }
            let block = copy_of.and_then(|name| {
                let named = |b: &&super::ctx::PouInfo| b.name.eq_ignore_ascii_case(name);
                self.pous.iter().filter(|b| b.kind == PouKind::FunctionBlock).find(named)
            });
            let partial = written(block.map_or(fb.ast, |b| b.ast));
            let partial = partial.filter(|l| l.name.ends_with('*') && own(kind));
            let name = format!("{}.{}", path_text(&path[..at]), id.name);
            self.refuse_binding(file, (location, id), &name, partial, binder);
        }
        false
    }

    /// Reports why `location` does not bind the variable `name` (`id` the last name of its
    /// path): its partly specified address `partial` does not fit (an error at the address),
    /// or it has none (an error at the name).
    fn refuse_binding(
        &mut self,
        file: usize,
        (location, id): (&Ident, &Ident),
        name: &str,
        partial: Option<Ident>,
        binder: Binder,
    ) {
        match partial {
            Some(partial) => {
                let msg = format!(
                    "`%{}` does not fit `{}`, declared at `%{}`",
                    location.name, id.name, partial.name
                );
                self.error(file, location.span, msg);
            }
            None => self.error(file, id.span, not_partly_specified(name, binder)),
        }
    }

    /// Checks a binding of the member `path[last]` of the struct variable `path[variable]`, or
    /// of a member of a member of it (`s.inner.x`), the struct holding it `s`, which the
    /// lowering made when it fits (`fb_config.rs`): the variable then has a copy of its type
    /// (and each member on the way one of its own) with the member at the entry's address.
    /// Whether the entry binds it.
    fn check_bound_member(
        &mut self,
        source: &Bindings<'_>,
        (entry, location): (&ConfigVar, &Ident),
        path: &[Ident],
        variable: usize,
        s: usize,
        (kind, constant): (VarKind, bool),
    ) -> bool {
        let (file, binder) = (source.file, source.binder);
        let id = &path[path.len() - 1];
        // the lowering binds a member of a variable of the instance's own only, as a variable
        if constant {
            let variable = &path[variable];
            let msg = format!("`{}` is CONSTANT: it cannot be written", variable.name);
            self.error(file, variable.span, msg);
            return false;
        }
        if !own(kind) {
            self.error(file, id.span, not_partly_specified(&path_text(path), binder));
            return false;
        }
        let st = &self.types.structs[s];
        let type_name = st.name.clone();
        let Some(m) = st.members.iter().find(|m| id.is(&m.name)).cloned() else {
            let hint = suggest(&id.name, st.members.iter().map(|m| m.name.as_str()));
            let msg = format!("`{type_name}` has no member `{}`{hint}", id.name);
            self.error(file, id.span, msg);
            return false;
        };
        // the member's address as the type declares it: `ty` the copy or the type itself
        let written = |ty: &Ty| {
            self.type_decls.iter().find(|t| &t.ty == ty).and_then(|t| match &t.decl.def {
                ast::TypeDef::Struct { members } => members
                    .iter()
                    .find(|d| d.names.iter().any(|n| n.is(&id.name)))
                    .and_then(|d| d.location.clone()),
                _ => None,
            })
        };
        if m.device.is_some() {
            let bound = written(&Ty::Struct(s))
                .is_some_and(|l| l.name.eq_ignore_ascii_case(&location.name));
            if bound {
                // the lowering bound it by this entry, whose type is reported when wrong
                self.same_type(file, entry, path, &m.ty);
                return true;
            }
        }
        // the type's own declaration, which the copy's (if any) is of
        let original = self.type_decls.iter().find(|t| t.decl.name.is(&type_name));
        let partial = original.map(|t| t.ty.clone()).and_then(|ty| written(&ty));
        let partial = partial.filter(|l| m.partial && l.name.ends_with('*'));
        self.refuse_binding(file, (location, id), &path_text(path), partial, binder);
        false
    }

    /// Whether the type `entry` gives is `ty`, the type of the variable at `path` (an entry of
    /// the config gives none: the variable's); reported when not.
    fn same_type(&mut self, file: usize, entry: &ConfigVar, path: &[Ident], ty: &Ty) -> bool {
        let Some(written) = &entry.ty else { return true };
        let scope = Scope { pou: None, visible: 0, file };
        let given = self.resolve_type_ref(written, scope);
        if given.is_error() || ty.is_error() {
            return false;
        }
        // a struct variable whose members are bound has a copy of the type written
        let copied = match ty {
            Ty::Struct(s) => self.struct_copy_of(*s),
            _ => None,
        };
        if &given == ty || copied.as_ref() == Some(&given) {
            return true;
        }
        let (given, declared) = (self.ty_name(&given), self.ty_name(ty));
        let msg = format!("`{}` is `{declared}`, not `{given}`", path_text(path));
        self.error(file, path[path.len() - 1].span, msg);
        false
    }

    /// Makes the variable `v` of the PROGRAM `p` (and of its actions, which share it) the
    /// located variable at `location`.
    fn bind(&mut self, file: usize, entry: &ConfigVar, location: &Ident, p: usize, v: usize) {
        let var = self.pous[p].vars[v].clone();
        let Some((storage, address)) = self.locate(file, location, &var.ty, &var.name) else {
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
        match (&entry.init, &entry.ty) {
            (Some(init), Some(written)) => {
                let scope = Scope { pou: None, visible: 0, file };
                self.located_init_for(storage, &var.ty, written, Some(init), scope, &var.name);
            }
            _ => {
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

    /// Gives the variable an entry without an address names its initial value, in the
    /// instance's own image (or at its device).
    fn initialize(&mut self, source: &Bindings<'_>, entry: &ConfigVar, placed: &Placed) {
        let file = source.file;
        let Some((path, _, p, base)) = self.instance_of(source, entry, placed) else {
            return;
        };
        // an entry of the config has an address always: this is VAR_CONFIG's, typed
        let (Some(init), Some(written)) = (&entry.init, &entry.ty) else {
            let msg = format!(
                "VAR_CONFIG entry `{}` gives neither an address (`AT %QX0.1`) nor an initial value",
                path_text(&entry.path)
            );
            self.error(file, entry.path[0].span, msg);
            return;
        };
        let Some(v) = self.program_variable(file, p, &path[1]) else { return };
        let var = self.pous[p].vars[v].clone();
        let (mut ty, mut storage) = (var.ty.clone(), var.storage);
        let mut checked = (&path[1], var.kind, var.constant);
        for id in &path[2..] {
            if !self.instance_value(file, path, checked) {
                return;
            }
            let (member_ty, member_offset, kind, constant) = match &ty {
                Ty::Fb(q) => {
                    let fb = &self.pous[*q];
                    let Some(m) = fb.lookup(&id.name).map(|i| fb.vars[i].clone()) else {
                        let hint = suggest(&id.name, fb.vars.iter().map(|v| v.name.as_str()));
                        let msg = format!("`{}` has no variable `{}`{hint}", fb.name, id.name);
                        self.error(file, id.span, msg);
                        return;
                    };
                    let Storage::Inst(o) = m.storage else {
                        self.instance_value(file, path, (id, VarKind::Temp, false));
                        return;
                    };
                    let kind = if m.by_ref { VarKind::InOut } else { m.kind };
                    (m.ty, o, kind, m.constant)
                }
                Ty::Struct(s) => {
                    let st = &self.types.structs[*s];
                    let Some(m) = st.members.iter().find(|m| id.is(&m.name)).cloned() else {
                        let hint = suggest(&id.name, st.members.iter().map(|m| m.name.as_str()));
                        let n = st.name.clone();
                        self.error(
                            file,
                            id.span,
                            format!("`{n}` has no member `{}`{hint}", id.name),
                        );
                        return;
                    };
                    let last = path.last().is_some_and(|l| std::ptr::eq(l, id));
                    if let Some(device) = m.device.filter(|_| last) {
                        // the member a binding placed at a device: its initial value there
                        ty = m.ty;
                        storage = device;
                        checked = (id, VarKind::Local, false);
                        break;
                    }
                    (m.ty, m.offset, VarKind::Local, false)
                }
                other => {
                    let n = self.ty_name(other);
                    let msg =
                        format!("`{}` is `{n}`: it has no variables or members", checked.0.name);
                    self.error(file, id.span, msg);
                    return;
                }
            };
            // a FUNCTION_BLOCK instance or a struct is never located
            let Storage::Inst(offset) = storage else { return };
            ty = member_ty;
            storage = Storage::Inst(offset + member_offset);
            checked = (id, kind, constant);
        }
        if !self.instance_value(file, path, checked) || !self.same_type(file, entry, path, &ty) {
            return;
        }
        let scope = Scope { pou: None, visible: 0, file };
        let name = path_text(path);
        match storage {
            Storage::Inst(offset) => {
                let image = self.init_image(&ty, Some(written), Some(init), scope, &name);
                let at = (base + offset) as usize;
                if let Some(slot) = self.image.get_mut(at..at + image.len()) {
                    slot.copy_from_slice(&image);
                }
            }
            Storage::Bit(_) | Storage::Word(_) | Storage::Byte(_) => {
                self.located_init_for(storage, &ty, written, Some(init), scope, &name);
            }
            Storage::Frame(_) | Storage::Global(_) => {}
        }
    }

    /// Whether the variable `name` (of `kind`, CONSTANT or not) has a value of the instance's
    /// own that VAR_CONFIG may set; reported when not.
    fn instance_value(
        &mut self,
        file: usize,
        path: &[Ident],
        (name, kind, constant): (&Ident, VarKind, bool),
    ) -> bool {
        if !own(kind) {
            let msg = format!(
                "`{}` has no value of the instance's own: a VAR_TEMP, VAR_IN_OUT, VAR_EXTERNAL \
                 or VAR_STAT cannot be given one in VAR_CONFIG",
                path_text(path)
            );
            self.error(file, name.span, msg);
            return false;
        }
        if constant {
            self.error(
                file,
                name.span,
                format!("`{}` is CONSTANT: it cannot be written", name.name),
            );
            return false;
        }
        true
    }
}

/// The names of the RESOURCEs of `conf`.
pub(super) fn resources(conf: &ast::Configuration) -> impl Iterator<Item = &str> {
    conf.resources.iter().filter_map(|r| r.name.as_ref()).map(|r| r.name.as_str())
}

/// Where `entry` of `source` is, for the message about a second binding of its variable.
fn origin(source: &Bindings<'_>, entry: &ConfigVar) -> Origin {
    let (binder, file, line) = (source.binder, source.file, entry.span.line);
    Origin { binder, file, line, key: path_text(&entry.path) }
}

/// The message about a variable `name` not at a partly specified address, which `binder`
/// cannot bind.
fn not_partly_specified(name: &str, binder: Binder) -> String {
    format!(
        "`{name}` is not declared at a partly specified address (`AT %I*`, `%Q*`, `%M*`): {} \
         binds only such a variable",
        binder.name()
    )
}

/// A path as written (`i.fb.x`).
fn path_text(path: &[Ident]) -> String {
    path.iter().map(|id| id.name.as_str()).collect::<Vec<_>>().join(".")
}
