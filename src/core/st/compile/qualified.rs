//! Qualified names of CODESYS and TwinCAT: a global variable list's name before one of its
//! variables (`GVL_Param.BufferSize`, which `{attribute 'qualified_only'}` makes the only way),
//! and a library's namespace before one of its declarations (`TcUnit.FB_TestSuite`,
//! `TcUnit.GVL_Param_TcUnit.MaxNumberOfTestSuites`).
//!
//! A lowering of the syntax trees before the checker, which knows one namespace of globals and
//! one of POUs and types: [`lower`] writes `Gvl.x` as `x` and `NS.Name` as `Name` wherever an
//! expression may stand (statements, initial values, array bounds, string lengths, arguments)
//! and in the names of types (`b : NS.FB_Base`, `EXTENDS NS.FB_Base`, `IMPLEMENTS NS.I`).
//!
//! A list's name is its `.TcGVL`'s `<GVL Name>`, or the stem of the `.st` file holding the
//! `VAR_GLOBAL` blocks (CODESYS's plain ST has no list names); a namespace is one of
//! `[st] namespaces`. A name qualifies only when it is none of the scope's variables, no
//! global, no POU and no type: `a.b` keeps its meaning wherever `a` is declared (an
//! enumeration's `E.Value` included). `Gvl.x` (and `NS.x` of a global) where the POU declares
//! its own `x` is the global, as CODESYS resolves it: lowered to `.x`, the form of the global
//! scope operator, which the checker looks up among the globals only.
//!
//! A name two lists declare is each list's own global: its declarations are renamed
//! `Gvl.x` (the checker's one namespace of globals then holds both, and tools name them so),
//! `Gvl.x` is lowered to that name, a list's own declarations name its own plainly, and the
//! plain `x` elsewhere is an error naming both forms.
//!
//! `{attribute 'qualified_only'}` (the one pragma that has an effect) before a list's
//! `VAR_GLOBAL` makes `Gvl.x` the only way to name its variables outside the list, and before
//! `TYPE E` makes `E.Value` (or `E#Value`) the only way to name the enumeration's values, as
//! CODESYS and TwinCAT enforce it: the plain name, where nothing of the scope declares it, is
//! an error naming the qualified form.

use std::borrow::Cow;
use std::collections::{HashMap, HashSet};
use std::path::Path;

use super::generic::system_type_name;
use crate::diag::Diagnostic;
use crate::st::ast::{
    Arg, ArrayInit, Expr, ExprKind, File, Ident, Init, Item, Pou, Stmt, StmtKind, TypeDef, TypeRef,
    VarBlock,
};

/// Lowers the qualified names of every file; `namespaces` are `[st] namespaces` and the system
/// libraries'; `renamed`, the libraries' declarations that keep their qualified name
/// (`tc2_system.memset`, as `compile::libraries` renamed them).
pub(super) fn lower<'f>(
    mut files: Vec<Cow<'f, File>>,
    namespaces: &[String],
    renamed: Option<&HashSet<String>>,
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, File>> {
    let mut names = Names {
        renamed: renamed.cloned().unwrap_or_default(),
        lists: HashMap::new(),
        globals: HashSet::new(),
        declared: HashSet::new(),
        namespaces: namespaces.iter().map(|n| key(n)).collect(),
        qualified_only: HashMap::new(),
        owners: HashMap::new(),
    };
    for file in files.iter() {
        names.gather(file);
    }
    if names.lists.is_empty() && names.namespaces.is_empty() && names.qualified_only.is_empty() {
        return files;
    }
    for file in &mut files {
        let path = file.path.clone();
        let list = list_of(file);
        let mut lowering = Lowering {
            names: &names,
            path: &path,
            diags: &mut *diags,
            plain_ok: false,
            list: list.as_deref(),
        };
        for item in &mut file.to_mut().items {
            lowering.item(item);
        }
    }
    files
}

/// The pragma that makes a qualified name the only one (its braces apart, which the
/// diagnostics' templates read as a placeholder).
const QUALIFIED_ONLY: &str = concat!("{", "attribute 'qualified_only'", "}");

fn key(name: &str) -> String {
    name.to_ascii_lowercase()
}

/// What the project declares, by lowercase name.
struct Names {
    /// Each global variable list: its variables.
    lists: HashMap<String, HashSet<String>>,
    /// Every global variable.
    globals: HashSet<String>,
    /// POUs, types and interfaces.
    declared: HashSet<String>,
    namespaces: HashSet<String>,
    /// The names `{attribute 'qualified_only'}` allows only qualified, each with its
    /// qualified form: a list's global (`GVL_Param.N`), an enumeration's value (`E.Value`).
    qualified_only: HashMap<String, String>,
    /// Each global of a list: the lists declaring it, as written. A name two lists declare
    /// is each list's own global, named `Gvl.x` (the name its declaration is given here),
    /// and the plain `x` is ambiguous.
    owners: HashMap<String, Vec<String>>,
    /// The system libraries' declarations the project's own names hide, as renamed
    /// (`tc2_system.memset`): their qualified name is kept whole.
    renamed: HashSet<String>,
}

/// The name of the global variable list a file's `VAR_GLOBAL` blocks form.
fn list_of(file: &File) -> Option<String> {
    file.list_name
        .clone()
        .or_else(|| file.path.file_stem().and_then(|s| s.to_str()).map(str::to_string))
}

impl Names {
    fn gather(&mut self, file: &File) {
        let list = list_of(file);
        for item in &file.items {
            match item {
                Item::Pou(p) => {
                    self.declared.insert(key(&p.name.name));
                }
                Item::Type(t) => {
                    self.declared.insert(key(&t.name.name));
                    let only = &file.qualified_only.types;
                    if let TypeDef::Enum { def, .. } = &t.def {
                        if only.iter().any(|n| n.eq_ignore_ascii_case(&t.name.name)) {
                            for (value, _) in &def.values {
                                let qualified = format!("{}.{}", t.name.name, value.name);
                                self.qualified_only.insert(key(&value.name), qualified);
                            }
                        }
                    }
                }
                Item::Interface(i) => {
                    self.declared.insert(key(&i.name.name));
                }
                Item::Globals(block) => {
                    let vars: Vec<String> = block_names(block).collect();
                    if let (true, Some(list)) = (file.qualified_only.globals, &list) {
                        for decl in &block.decls {
                            for n in &decl.names {
                                self.qualified_only
                                    .insert(key(&n.name), format!("{list}.{}", n.name));
                            }
                        }
                    }
                    self.globals.extend(vars.iter().cloned());
                    if let Some(list) = &list {
                        for var in &vars {
                            let owners = self.owners.entry(var.clone()).or_default();
                            if !owners.iter().any(|o| o.eq_ignore_ascii_case(list)) {
                                owners.push(list.clone());
                            }
                        }
                        self.lists.entry(key(list)).or_default().extend(vars);
                    }
                }
                Item::Configuration(c) => {
                    self.globals.extend(c.globals.iter().flat_map(block_names));
                }
                Item::Action { .. } => {}
            }
        }
    }

    /// The lists declaring `name` when two or more do.
    fn shared(&self, name: &str) -> Option<&[String]> {
        self.owners.get(&key(name)).filter(|o| o.len() > 1).map(Vec::as_slice)
    }

    /// Whether `name` stands for something the checker knows by itself.
    fn is_declared(&self, name: &str, scope: &HashSet<String>) -> bool {
        let name = key(name);
        scope.contains(&name) || self.globals.contains(&name) || self.declared.contains(&name)
    }
}

fn block_names(block: &VarBlock) -> impl Iterator<Item = String> + '_ {
    block.decls.iter().flat_map(|d| d.names.iter().map(|n| key(&n.name)))
}

struct Lowering<'n, 'd> {
    names: &'n Names,
    path: &'n Path,
    diags: &'d mut Vec<Diagnostic>,
    /// In a global variable list or a type declaration, where a `qualified_only` list's
    /// variables and an enumeration's values are named plainly.
    plain_ok: bool,
    /// The list the file's `VAR_GLOBAL` blocks form.
    list: Option<&'n str>,
}

impl Lowering<'_, '_> {
    fn error(&mut self, at: &Ident, msg: String) {
        self.diags.push(Diagnostic::new(self.path, at.span.line, at.span.col, msg));
    }

    fn item(&mut self, item: &mut Item) {
        let none = HashSet::new();
        match item {
            Item::Pou(p) => self.pou(p, &none),
            Item::Type(t) => {
                self.plain_ok = true;
                self.type_decl(t, &none);
                self.plain_ok = false;
            }
            Item::Globals(block) => {
                // a global another list declares too is this list's `Gvl.x`
                if let Some(list) = self.list {
                    for decl in &mut block.decls {
                        for n in &mut decl.names {
                            if self.names.shared(&n.name).is_some() {
                                n.name = format!("{list}.{}", n.name);
                            }
                        }
                    }
                }
                self.plain_ok = true;
                self.block(block, &none);
                self.plain_ok = false;
            }
            Item::Action { action, .. } => self.stmts(&mut action.body, &none),
            Item::Configuration(c) => {
                for block in &mut c.globals {
                    self.block(block, &none);
                }
            }
            Item::Interface(i) => {
                for base in &mut i.extends {
                    self.type_name(base);
                }
                for m in &mut i.methods {
                    self.pou(&mut m.pou, &none);
                }
                for p in &mut i.properties {
                    self.type_ref(&mut p.ty, &none);
                    for accessor in [&mut p.get, &mut p.set].into_iter().flatten() {
                        self.pou(accessor, &none);
                    }
                }
            }
        }
    }

    fn type_decl(&mut self, t: &mut crate::st::ast::TypeDecl, none: &HashSet<String>) {
        match &mut t.def {
            TypeDef::Alias { ty, init } => {
                self.type_ref(ty, none);
                if let Some(init) = init {
                    self.init(init, none);
                }
            }
            TypeDef::Struct { members } | TypeDef::Union { members } => {
                for decl in members {
                    self.type_ref(&mut decl.ty, none);
                    if let Some(init) = &mut decl.init {
                        self.init(init, none);
                    }
                }
            }
            TypeDef::Enum { def, .. } => {
                for (_, value) in &mut def.values {
                    if let Some(value) = value {
                        self.expr(value, none);
                    }
                }
            }
        }
    }

    /// A POU, with the variables of `outer` (its function block's, for a method) in scope.
    fn pou(&mut self, pou: &mut Pou, outer: &HashSet<String>) {
        let mut scope = outer.clone();
        scope.extend(pou.vars.iter().flat_map(block_names));
        if pou.return_type.is_some() {
            scope.insert(key(&pou.name.name));
        }
        for block in &mut pou.vars {
            self.block(block, &scope);
        }
        if let Some(ty) = &mut pou.return_type {
            self.type_ref(ty, &scope);
        }
        self.stmts(&mut pou.body, &scope);
        for action in &mut pou.actions {
            self.stmts(&mut action.body, &scope);
        }
        if let Some(base) = &mut pou.oop.extends {
            self.type_name(base);
        }
        for itf in &mut pou.oop.implements {
            self.type_name(itf);
        }
        for m in &mut pou.oop.methods {
            self.pou(&mut m.pou, &scope);
        }
        for p in &mut pou.oop.properties {
            self.type_ref(&mut p.ty, &scope);
            for accessor in [&mut p.get, &mut p.set].into_iter().flatten() {
                self.pou(accessor, &scope);
            }
        }
    }

    fn block(&mut self, block: &mut VarBlock, scope: &HashSet<String>) {
        for decl in &mut block.decls {
            self.type_ref(&mut decl.ty, scope);
            if let Some(init) = &mut decl.init {
                self.init(init, scope);
            }
        }
    }

    /// `NS.Name` of a type, a base or an interface: `Name` when `NS` is a namespace (but for
    /// CODESYS's `IBaseLibrary.TypeClass`, the checker's to read whole).
    fn type_name(&mut self, id: &mut Ident) {
        while let Some((first, rest)) = id.name.split_once('.') {
            if !self.names.namespaces.contains(&key(first))
                || self.names.renamed.contains(&key(&id.name))
                || system_type_name(&id.name).is_some()
            {
                break;
            }
            id.name = rest.to_string();
        }
    }

    fn type_ref(&mut self, ty: &mut TypeRef, scope: &HashSet<String>) {
        match ty {
            TypeRef::Named(id) => self.type_name(id),
            TypeRef::String { len, .. } | TypeRef::WString { len, .. } => {
                if let Some(len) = len {
                    self.expr(len, scope);
                }
            }
            TypeRef::Array { dims, of, .. } => {
                for (lo, hi) in dims {
                    self.expr(lo, scope);
                    self.expr(hi, scope);
                }
                self.type_ref(of, scope);
            }
            TypeRef::OpenArray { of, .. } => self.type_ref(of, scope),
            // compile::generic_constants, before this lowering, replaced each
            TypeRef::Generic { .. } => {}
            TypeRef::Enum(def) => {
                for (_, value) in &mut def.values {
                    if let Some(value) = value {
                        self.expr(value, scope);
                    }
                }
                self.args(&mut def.args, scope);
            }
            TypeRef::Subrange { lo, hi, .. } => {
                self.expr(lo, scope);
                self.expr(hi, scope);
            }
            TypeRef::Ref { to, .. } => self.type_ref(to, scope),
        }
    }

    fn init(&mut self, init: &mut Init, scope: &HashSet<String>) {
        match init {
            Init::Expr(e) => self.expr(e, scope),
            Init::Array { elems, .. } => {
                for elem in elems {
                    match elem {
                        ArrayInit::One(init) => self.init(init, scope),
                        ArrayInit::Repeat { count, value } => {
                            self.expr(count, scope);
                            if let Some(value) = value {
                                self.init(value, scope);
                            }
                        }
                    }
                }
            }
            Init::Struct { members, .. } => {
                for (_, init) in members {
                    self.init(init, scope);
                }
            }
        }
    }

    fn args(&mut self, args: &mut [Arg], scope: &HashSet<String>) {
        for arg in args {
            match arg {
                Arg::Positional(e) | Arg::Input { value: e, .. } => self.expr(e, scope),
                Arg::Output { target, .. } => self.expr(target, scope),
            }
        }
    }

    fn stmts(&mut self, body: &mut [Stmt], scope: &HashSet<String>) {
        for stmt in body {
            match &mut stmt.kind {
                StmtKind::Assign { target, value } | StmtKind::RefAssign { target, value } => {
                    self.expr(target, scope);
                    self.expr(value, scope);
                }
                StmtKind::Call(e) => self.expr(e, scope),
                StmtKind::If { branches, otherwise } => {
                    for (cond, body) in branches {
                        self.expr(cond, scope);
                        self.stmts(body, scope);
                    }
                    if let Some((_, body)) = otherwise {
                        self.stmts(body, scope);
                    }
                }
                StmtKind::Case { selector, arms, otherwise } => {
                    self.expr(selector, scope);
                    for arm in arms {
                        for label in &mut arm.labels {
                            match label {
                                crate::st::ast::CaseLabel::Value(e) => self.expr(e, scope),
                                crate::st::ast::CaseLabel::Range(lo, hi) => {
                                    self.expr(lo, scope);
                                    self.expr(hi, scope);
                                }
                            }
                        }
                        self.stmts(&mut arm.body, scope);
                    }
                    if let Some((_, body)) = otherwise {
                        self.stmts(body, scope);
                    }
                }
                StmtKind::For { var, from, to, by, body } => {
                    self.expr(var, scope);
                    self.expr(from, scope);
                    self.expr(to, scope);
                    if let Some(by) = by {
                        self.expr(by, scope);
                    }
                    self.stmts(body, scope);
                }
                StmtKind::While { cond, body } => {
                    self.expr(cond, scope);
                    self.stmts(body, scope);
                }
                StmtKind::Repeat { body, until } => {
                    self.stmts(body, scope);
                    self.expr(until, scope);
                }
                StmtKind::Exit
                | StmtKind::Continue
                | StmtKind::Return
                | StmtKind::Empty
                | StmtKind::Label(_)
                | StmtKind::Jump(_) => {}
            }
        }
    }

    /// An expression, inside out: `NS.Gvl.x` is `Gvl.x` once its inner `NS.Gvl` is `Gvl`.
    fn expr(&mut self, e: &mut Expr, scope: &HashSet<String>) {
        match &mut e.kind {
            ExprKind::Literal(_) => {}
            ExprKind::Name(name) => self.plain(name, scope),
            ExprKind::Member(base, _)
            | ExprKind::Bit(base, _)
            | ExprKind::Part(base, _, _)
            | ExprKind::Deref(base)
            | ExprKind::Unary(_, base) => self.expr(base, scope),
            ExprKind::Index(base, index) => {
                self.expr(base, scope);
                for i in index {
                    self.expr(i, scope);
                }
            }
            ExprKind::Binary(_, a, b) | ExprKind::Assign(a, b) => {
                self.expr(a, scope);
                self.expr(b, scope);
            }
            ExprKind::Call { callee, args } => {
                self.expr(callee, scope);
                self.args(args, scope);
            }
        }
        if let Some(name) = self.unqualified(e, scope) {
            e.kind = ExprKind::Name(name);
        }
    }

    /// A plain name that `{attribute 'qualified_only'}` allows only qualified, where nothing
    /// of the scope, no other global, no POU and no type declares it: an error naming the
    /// qualified form (the name is left, for the checker to go on with).
    fn plain(&mut self, name: &mut Ident, scope: &HashSet<String>) {
        let k = key(&name.name);
        if let (Some(owners), false) = (self.names.shared(&name.name), scope.contains(&k)) {
            let own = self.list.filter(|l| owners.iter().any(|o| o.eq_ignore_ascii_case(l)));
            match own {
                // a list's own declarations name its own global
                Some(list) if self.plain_ok => name.name = format!("{list}.{}", name.name),
                _ => {
                    let forms: Vec<String> =
                        owners.iter().map(|o| format!("`{o}.{}`", name.name)).collect();
                    let msg = format!(
                        "`{}` is ambiguous: {} global variable lists declare it; name one, {}",
                        name.name,
                        owners.len(),
                        forms.join(" or ")
                    );
                    self.error(name, msg);
                    // the checker goes on with the first list's: one message for one mistake
                    name.name = format!("{}.{}", owners[0], name.name);
                }
            }
            return;
        }
        if self.plain_ok {
            return;
        }
        let Some(qualified) = self.names.qualified_only.get(&key(&name.name)) else { return };
        let k = key(&name.name);
        if scope.contains(&k) || self.names.declared.contains(&k) {
            return;
        }
        let (owner, _) = qualified.split_once('.').unwrap_or((qualified, ""));
        let msg = if self.names.lists.contains_key(&key(owner)) && self.names.globals.contains(&k) {
            format!(
                "`{}` is a global of the list `{owner}`, which is {QUALIFIED_ONLY}: name it \
                 `{qualified}`",
                name.name
            )
        } else if self.names.globals.contains(&k) {
            // a global of that name: the plain name is the global
            return;
        } else {
            format!(
                "`{}` is a value of the enumeration `{owner}`, which is {QUALIFIED_ONLY}: name it \
                 `{qualified}` (or `{owner}#{}`)",
                name.name, name.name
            )
        };
        self.error(name, msg);
    }

    /// The name `Q.x` stands for when `Q` is a namespace or a global variable list (`.x` where
    /// the scope declares its own `x`); an error when `x` is another list's global.
    fn unqualified(&mut self, e: &Expr, scope: &HashSet<String>) -> Option<Ident> {
        let ExprKind::Member(base, name) = &e.kind else { return None };
        let ExprKind::Name(qualifier) = &base.kind else { return None };
        if self.names.is_declared(&qualifier.name, scope) {
            return None;
        }
        let q = key(&qualifier.name);
        if self.names.namespaces.contains(&q) {
            let whole = format!("{}.{}", qualifier.name, name.name);
            if system_type_name(&whole).is_some() {
                // `IBaseLibrary.TypeClass` is CODESYS's type classes, the checker's to read
                // whole, also where a `.plcproj` names `IBaseLibrary` a namespace (TcUnit's)
                return None;
            }
            if self.names.renamed.contains(&key(&whole)) {
                return Some(Ident { name: whole, ..name.clone() });
            }
            return Some(past_scope(name, scope, &self.names.globals));
        }
        let list = self.names.lists.get(&q)?;
        let x = key(&name.name);
        if list.contains(&x) && self.names.shared(&name.name).is_some() {
            // the list's own global of a name another list declares too (no local hides it)
            return Some(Ident {
                name: format!("{}.{}", qualifier.name, name.name),
                ..name.clone()
            });
        }
        // each error leaves the plain name, which the checker then finds (the other list's
        // global, the POU's variable) or reports as not declared: one message for one mistake
        if !list.contains(&x) && self.names.globals.contains(&x) {
            let msg = format!(
                "the global variable list `{}` declares no `{}`",
                qualifier.name, name.name
            );
            self.error(name, msg);
        } else if list.contains(&x) {
            // the qualifier names the list, so the list's `x` even where the POU declares its
            // own `x`, as CODESYS resolves it
            return Some(past_scope(name, scope, &self.names.globals));
        }
        Some(name.clone())
    }
}

/// `x` as the name of the global `x`: `.x` (the global scope operator's form, which the checker
/// looks up among the globals only) where the scope declares its own `x`, else plainly.
fn past_scope(name: &Ident, scope: &HashSet<String>, globals: &HashSet<String>) -> Ident {
    let x = key(&name.name);
    if scope.contains(&x) && globals.contains(&x) {
        return Ident { name: format!(".{}", name.name), ..name.clone() };
    }
    name.clone()
}
