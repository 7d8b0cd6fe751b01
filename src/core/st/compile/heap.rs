//! `__NEW(T[, n])` and `__DELETE(p)` (TwinCAT, CODESYS): dynamic memory, from a heap that is a
//! hidden global of plcd's own variable memory (docs/ST.md, "Dynamic memory").
//!
//! A lowering of the syntax trees before the checker, after compile/fb_init.rs's and
//! compile/fb_exit.rs's (whose hidden `__FB_INIT_ALL` and `__FB_EXIT_ALL` it calls): the
//! allocator is Structured Text (`heap.st`), so the interpreter and native code run it alike and
//! every pointer into the heap is checked at each access as any pointer into variable memory. A
//! project without `__NEW` and `__DELETE` is compiled as before.
//!
//! - Each `__NEW(T, n)` (`n` 1 when left out) becomes a call of a hidden FUNCTION
//!   `__HEAP_NEW_k(n) : POINTER TO T`, `k` the number of the `__NEW` in the project: it takes a
//!   zeroed block of `n` elements (`__HEAP_ALLOC`, which records `k` in the block's header),
//!   writes the type's initial value into each, and for a function block with something to
//!   initialise runs each element's `__FB_INIT_ALL` (`bInitRetains` TRUE, `bInCopyCode` FALSE,
//!   the other inputs of its `FB_init` their initial values); NULL when the heap has no room.
//! - `__DELETE(p);` becomes `IF NOT __HEAP_DELETE(p) THEN __HEAP_NOWHERE^ := 0; END_IF p := 0;`.
//!   `__HEAP_DELETE` finds the live block `p` starts, runs each element's `__FB_EXIT_ALL` when
//!   the `__NEW` recorded in its header made function blocks with something to finish, and frees
//!   the block; for a pointer that starts none it frees nothing and answers FALSE, and the write
//!   through a pointer to no memory area raises 2820H at the `__DELETE`'s line.
//! - The type argument of `__NEW` and of `SIZEOF` is a name, or a hidden alias the parser
//!   declared in its file ([`TYPE_ARGUMENT_PREFIX`]), numbered in that file: renamed here
//!   `__HEAP_TYPE_<file>_<n>`, apart in the project. The hidden FUNCTION of a `__NEW` is
//!   declared with the type itself.
//!
//! Checked here: a `__NEW` or `__DELETE` where `[st] heap_bytes` is 0.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, Arg, Expr, ExprKind, Ident, Item, Literal, Pou, PouKind, Span, Stmt, StmtKind, TypeDef,
    TypeRef, UnaryOp, TYPE_ARGUMENT_PREFIX,
};
use crate::st::dialect::Habit;

use super::lifecycle::{ident, name, stmt};

/// The allocator, with `HEAP_BYTES` and `HEAP_LAST` for the heap's size to write in.
const ALLOCATOR: &str = include_str!("heap.st");
/// The FUNCTION of one `__NEW`, `TAG` its number; the line ending in [`INIT`] initialises a
/// function block.
const NEW_TEMPLATE: &str = include_str!("heap_new.st");
const INIT: &str = "(*INIT*)";
/// `__HEAP_DELETE`, with [`EXITS`] and [`FINISH`] where [`EXIT`]'s parts go.
const DELETE_TEMPLATE: &str = include_str!("heap_delete.st");
const EXITS: &str = "(*EXITS*)";
const FINISH: &str = "(*FINISH*)";
/// What `__HEAP_DELETE` declares and does for the `__NEW` numbered `TAG` of the function
/// block `BLOCK`, which has something to finish: a variable, then after [`FINISH`] the
/// statements.
const EXIT: &str = include_str!("heap_exit.st");
/// The path diagnostics and the trace name for the hidden file the lowering adds.
const HEAP_PATH: &str = "<heap>";
/// The type `heap.st`'s templates name for the type of a `__NEW`.
const PLACEHOLDER: &str = "__HEAP_T";
const NEW: &str = "__NEW";
const DELETE: &str = "__DELETE";
const DELETE_FN: &str = "__HEAP_DELETE";
/// A global `POINTER TO BYTE` to no memory area, which `__HEAP_DELETE` sets before it answers
/// FALSE.
const NOWHERE: &str = "__HEAP_NOWHERE";

/// Whether `name` is one the lowering declares (exempt from the rule that reserves names
/// starting with `__` to plcd).
pub fn is_hidden(name: &str) -> bool {
    name.get(..7).is_some_and(|p| p.eq_ignore_ascii_case("__HEAP_"))
}

/// Whether `path` is the hidden file of the heap (whose forms `[st] strict` does not refuse:
/// they are plcd's, and the `__NEW` that brought them is refused).
pub(super) fn is_heap_file(path: &Path) -> bool {
    path == Path::new(HEAP_PATH)
}

/// One `__NEW` of the project: its type and place.
struct Site {
    ty: TypeRef,
    file: usize,
    span: Span,
}

/// Lowers every `__NEW` and `__DELETE` of `files`; `heap_bytes` is `[st] heap_bytes`.
pub(super) fn lower<'f>(
    mut files: Vec<Cow<'f, ast::File>>,
    heap_bytes: u32,
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, ast::File>> {
    let uses = |f: &ast::File| f.habits.iter().any(|n| matches!(n.habit, Habit::DynamicMemory(_)));
    let typed = |f: &ast::File| f.items.iter().any(|i| type_argument(i).is_some());
    if !files.iter().any(|f| uses(f) || typed(f)) {
        return files;
    }
    let mut sites: Vec<Site> = Vec::new();
    let mut deletes: Vec<(usize, Span)> = Vec::new();
    for (f, file) in files.iter_mut().enumerate() {
        if !uses(file) && !typed(file) {
            continue;
        }
        let file = file.to_mut();
        // the type arguments' aliases, numbered in their file: numbered apart in the project
        let mut aliases: HashMap<String, TypeRef> = HashMap::new();
        for item in &mut file.items {
            if let Item::Type(t) = item {
                if let Some(ty) = type_argument(&Item::Type(t.clone())) {
                    t.name.name = renamed(f, &t.name.name);
                    aliases.insert(t.name.name.clone(), ty.clone());
                }
            }
        }
        let mut lowering =
            Lowering { file: f, aliases: &aliases, sites: &mut sites, deletes: Vec::new() };
        for item in &mut file.items {
            if let Item::Pou(p) = item {
                lowering.pou(p);
            }
        }
        deletes.extend(lowering.deletes.into_iter().map(|span| (f, span)));
    }
    if sites.is_empty() && deletes.is_empty() {
        return files;
    }
    // whole 16-byte blocks; a heap of less than one header and one block of elements is none
    let bytes = heap_bytes / 16 * 16;
    if bytes < 32 {
        let mut places: Vec<(usize, Span, &str)> =
            deletes.iter().map(|&(f, s)| (f, s, DELETE)).collect();
        places.extend(sites.iter().map(|s| (s.file, s.span, NEW)));
        for (f, at, op) in places {
            diags.push(Diagnostic::new(
                &files[f].path,
                at.line,
                at.col,
                format!("`{op}` takes memory from the heap, and `[st] heap_bytes` is {heap_bytes}: give it the bytes the program allocates at most (docs/ST.md, Dynamic memory)"),
            ));
        }
    }
    // reported when too small; a heap of one block keeps the calls declared (no more errors)
    let heap = heap_file(&files, &sites, bytes.max(32), diags);
    files.push(Cow::Owned(heap));
    files
}

/// The hidden file: the allocator, a `__HEAP_NEW_k` for each `__NEW`, and `__HEAP_DELETE`.
fn heap_file(
    files: &[Cow<'_, ast::File>],
    sites: &[Site],
    bytes: u32,
    diags: &mut Vec<Diagnostic>,
) -> ast::File {
    let mut text = ALLOCATOR.replace("HEAP_LAST", &(bytes - 1).to_string());
    fn lifecycle<'t>(
        files: &[Cow<'_, ast::File>],
        ty: &'t TypeRef,
        method: &str,
    ) -> Option<&'t str> {
        match ty {
            TypeRef::Named(id) => has_method(files, &id.name, method).then_some(id.name.as_str()),
            _ => None,
        }
    }
    let (exit_vars, exit_stmts) = EXIT.split_once(FINISH).unwrap_or_default();
    let mut exits = String::new();
    let mut finish = String::new();
    for (k, site) in sites.iter().enumerate() {
        let tag = (k + 1).to_string();
        let init = lifecycle(files, &site.ty, super::fb_init::INIT_ALL).is_some();
        let new: String = NEW_TEMPLATE
            .lines()
            .filter(|line| init || !line.ends_with(INIT))
            .flat_map(|line| [line, "\n"])
            .collect();
        text.push_str(&new.replace("TAG", &tag));
        if let Some(block) = lifecycle(files, &site.ty, super::fb_exit::EXIT_ALL) {
            exits.push_str(&exit_vars.replace("TAG", &tag).replace("BLOCK", block));
            finish.push_str(&exit_stmts.replace("TAG", &tag));
        }
    }
    text.push_str(&DELETE_TEMPLATE.replace(EXITS, &exits).replace(FINISH, &finish));
    text = text.replace("HEAP_BYTES", &bytes.to_string());
    let (mut file, parsed) = crate::st::syntax::parse_file(Path::new(HEAP_PATH), &text);
    diags.extend(parsed.0);
    // each `__NEW`'s type in its FUNCTION and its pristine element
    let site = |name: &str, prefix: &str| {
        let tag = name.strip_prefix(prefix)?.parse::<usize>().ok()?;
        sites.get(tag.checked_sub(1)?)
    };
    for item in &mut file.items {
        match item {
            Item::Pou(p) => {
                let Some(site) = site(&p.name.name, "__HEAP_NEW_") else { continue };
                if let Some(ty) = &mut p.return_type {
                    replace_placeholder(ty, &site.ty);
                }
                for d in p.vars.iter_mut().flat_map(|b| &mut b.decls) {
                    replace_placeholder(&mut d.ty, &site.ty);
                }
            }
            Item::Globals(block) => {
                for d in &mut block.decls {
                    if let Some(site) = d.names.first().and_then(|n| site(&n.name, "__HEAP_FRESH_"))
                    {
                        replace_placeholder(&mut d.ty, &site.ty);
                    }
                }
            }
            _ => {}
        }
    }
    file
}

/// The type of a type argument's alias the parser declared ([`TYPE_ARGUMENT_PREFIX`]).
fn type_argument(item: &Item) -> Option<&TypeRef> {
    match item {
        Item::Type(t) if t.name.name.starts_with(TYPE_ARGUMENT_PREFIX) => match &t.def {
            TypeDef::Alias { ty, .. } => Some(ty),
            _ => None,
        },
        _ => None,
    }
}

/// The project's name of the type argument `name` of file `file`: hidden (`__HEAP_TYPE_2_0`).
fn renamed(file: usize, name: &str) -> String {
    let number = name.get(TYPE_ARGUMENT_PREFIX.len()..).unwrap_or_default();
    format!("__HEAP_TYPE_{file}_{number}")
}

/// `ty` with [`PLACEHOLDER`] replaced by `by`.
fn replace_placeholder(ty: &mut TypeRef, by: &TypeRef) {
    match ty {
        TypeRef::Named(id) if id.name == PLACEHOLDER => *ty = by.clone(),
        TypeRef::Ref { to, .. } => replace_placeholder(to, by),
        _ => {}
    }
}

/// Whether the function block `block` (or a base of it) declares the method `method`.
fn has_method(files: &[Cow<'_, ast::File>], block: &str, method: &str) -> bool {
    let mut seen = 0;
    let mut name = block.to_string();
    // a chain of bases longer than the project's blocks loops (reported elsewhere)
    while seen < 64 {
        seen += 1;
        let found = files.iter().flat_map(|f| &f.items).find_map(|item| match item {
            Item::Pou(p) if p.kind == PouKind::FunctionBlock && p.name.is(&name) => Some(p),
            _ => None,
        });
        let Some(p) = found else { return false };
        if p.oop.methods.iter().any(|m| m.pou.name.is(method)) {
            return true;
        }
        match &p.oop.extends {
            Some(base) => name = base.name.clone(),
            None => return false,
        }
    }
    false
}

/// The walk over one file's bodies.
struct Lowering<'a> {
    file: usize,
    /// The file's hidden aliases of `__NEW`'s types, by name.
    aliases: &'a HashMap<String, TypeRef>,
    sites: &'a mut Vec<Site>,
    /// The places of the file's `__DELETE`s.
    deletes: Vec<Span>,
}

impl Lowering<'_> {
    fn pou(&mut self, p: &mut Pou) {
        self.stmts(&mut p.body);
        for a in &mut p.actions {
            self.stmts(&mut a.body);
        }
        for m in &mut p.oop.methods {
            self.pou(&mut m.pou);
        }
        for prop in &mut p.oop.properties {
            for accessor in [&mut prop.get, &mut prop.set].into_iter().flatten() {
                self.pou(accessor);
            }
        }
    }

    fn stmts(&mut self, body: &mut Vec<Stmt>) {
        let mut out = Vec::with_capacity(body.len());
        for mut s in body.drain(..) {
            if let Some(target) = delete_target(&s) {
                // `__DELETE(p);`: `IF NOT __HEAP_DELETE(p) THEN __HEAP_NOWHERE^ := 0; END_IF
                // p := 0;`, the write through a pointer to nowhere raising 2820H here
                let span = s.span;
                self.deletes.push(span);
                let mut target = target.clone();
                self.expr(&mut target);
                let callee = Box::new(name(DELETE_FN, span));
                let args = vec![Arg::Positional(target.clone())];
                let freed = Expr { kind: ExprKind::Call { callee, args }, span };
                let failed = Expr { kind: ExprKind::Unary(UnaryOp::Not, Box::new(freed)), span };
                let nowhere = Expr { kind: ExprKind::Deref(Box::new(name(NOWHERE, span))), span };
                let raise = StmtKind::Assign { target: nowhere, value: int(0, span) };
                let branches = vec![(failed, vec![stmt(raise, span)])];
                out.push(stmt(StmtKind::If { branches, otherwise: None }, span));
                out.push(stmt(StmtKind::Assign { target, value: int(0, span) }, span));
                continue;
            }
            self.stmt(&mut s);
            out.push(s);
        }
        *body = out;
    }

    fn stmt(&mut self, s: &mut Stmt) {
        match &mut s.kind {
            StmtKind::Assign { target, value } | StmtKind::RefAssign { target, value } => {
                self.expr(target);
                self.expr(value);
            }
            StmtKind::Call(e) => self.expr(e),
            StmtKind::If { branches, otherwise } => {
                for (c, b) in branches {
                    self.expr(c);
                    self.stmts(b);
                }
                if let Some((_, b)) = otherwise {
                    self.stmts(b);
                }
            }
            StmtKind::Case { selector, arms, otherwise } => {
                self.expr(selector);
                for arm in arms {
                    self.stmts(&mut arm.body);
                }
                if let Some((_, b)) = otherwise {
                    self.stmts(b);
                }
            }
            StmtKind::For { from, to, by, body, .. } => {
                self.expr(from);
                self.expr(to);
                if let Some(by) = by {
                    self.expr(by);
                }
                self.stmts(body);
            }
            StmtKind::While { cond, body } => {
                self.expr(cond);
                self.stmts(body);
            }
            StmtKind::Repeat { body, until } => {
                self.stmts(body);
                self.expr(until);
            }
            StmtKind::Exit
            | StmtKind::Continue
            | StmtKind::Return
            | StmtKind::Empty
            | StmtKind::Label(_)
            | StmtKind::Jump(_) => {}
        }
    }

    fn expr(&mut self, e: &mut Expr) {
        match &mut e.kind {
            ExprKind::Name(id) if id.name.starts_with(TYPE_ARGUMENT_PREFIX) => {
                id.name = renamed(self.file, &id.name);
            }
            ExprKind::Literal(_) | ExprKind::Name(_) => {}
            ExprKind::Member(inner, _)
            | ExprKind::Bit(inner, _)
            | ExprKind::Part(inner, _, _)
            | ExprKind::Deref(inner)
            | ExprKind::Unary(_, inner) => self.expr(inner),
            ExprKind::Index(inner, index) => {
                self.expr(inner);
                index.iter_mut().for_each(|i| self.expr(i));
            }
            ExprKind::Binary(_, a, b) | ExprKind::Assign(a, b) => {
                self.expr(a);
                self.expr(b);
            }
            ExprKind::Call { callee, args } => {
                self.expr(callee);
                for arg in args.iter_mut() {
                    match arg {
                        Arg::Positional(v) | Arg::Input { value: v, .. } => self.expr(v),
                        Arg::Output { target, .. } => self.expr(target),
                    }
                }
                if let Some(kind) = self.new_call(callee, args, e.span) {
                    e.kind = kind;
                }
            }
        }
    }

    /// `__NEW(T[, n])` as the call of its hidden FUNCTION; `None` for any other call.
    fn new_call(&mut self, callee: &Expr, args: &[Arg], span: Span) -> Option<ExprKind> {
        let ExprKind::Name(id) = &callee.kind else { return None };
        if !id.is(NEW) {
            return None;
        }
        let Some(Arg::Positional(Expr { kind: ExprKind::Name(ty), .. })) = args.first() else {
            return None;
        };
        let ty = match self.aliases.get(&ty.name) {
            Some(alias) => alias.clone(),
            None => TypeRef::Named(ty.clone()),
        };
        let count = match args.get(1) {
            Some(Arg::Positional(n)) => n.clone(),
            _ => int(1, span),
        };
        self.sites.push(Site { ty, file: self.file, span });
        let hidden: Ident = ident(&format!("__HEAP_NEW_{}", self.sites.len()), span);
        let callee = Box::new(Expr { kind: ExprKind::Name(hidden), span });
        Some(ExprKind::Call { callee, args: vec![Arg::Positional(count)] })
    }
}

fn int(n: u128, span: Span) -> Expr {
    Expr { kind: ExprKind::Literal(Literal::Int(n)), span }
}

/// The pointer of a `__DELETE(p);` statement.
fn delete_target(s: &Stmt) -> Option<&Expr> {
    let StmtKind::Call(Expr { kind: ExprKind::Call { callee, args }, .. }) = &s.kind else {
        return None;
    };
    let ExprKind::Name(id) = &callee.kind else { return None };
    match args.as_slice() {
        [Arg::Positional(target)] if id.is(DELETE) => Some(target),
        _ => None,
    }
}
