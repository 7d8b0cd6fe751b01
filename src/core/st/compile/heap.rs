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
//!   zeroed block of `n` elements (`__HEAP_ALLOC`, which records its type's tag in the block's header),
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
//! - `__NEW(T(x := 5))`, `__NEW(T(5))`: `FB_init`'s arguments, checked as a declaration's
//!   (compile/fb_init.rs's `check_arguments`); the hidden FUNCTION of such a `__NEW` declares
//!   the inputs of `T`'s `__FB_INIT_ALL` and passes them on.
//! - The header of a live block holds a tag of its type ([`header_tag`]), the same from one
//!   compile to the next: `__HEAP_EXIT_ALL`, which compile/fb_exit.rs's exit pass calls last
//!   when a RUN ends, runs the `FB_exit` of the function blocks still live, blocks an online
//!   change kept included.
//!
//! Checked here: a `__NEW` or `__DELETE` where `[st] heap_bytes` is 0; a `__NEW` in an initial
//! value; a `__DELETE` inside an expression; `__NEW(T(…))`'s arguments.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, Arg, ArrayInit, Expr, ExprKind, Ident, Init, Item, Literal, Pou, PouKind, Span, Stmt,
    StmtKind, TypeDef, TypeRef, UnaryOp, VarDecl, VarKind, TYPE_ARGUMENT_PREFIX,
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
/// What `__HEAP_DELETE` and `__HEAP_EXIT_ALL` declare and do for the function blocks of the
/// tag `HASH`, which have something to finish (their type `__HEAP_BLOCK_NUM`, the `NUM`th such
/// type): a variable, then after [`FINISH`] the statements.
const EXIT: &str = include_str!("heap_exit.st");
/// The path diagnostics and the trace name for the hidden file the lowering adds.
const HEAP_PATH: &str = "<heap>";
/// The type `heap.st`'s templates name for the type of a `__NEW`.
const PLACEHOLDER: &str = "__HEAP_T";
/// The type [`EXIT`] names for the function block it finishes, a number after it.
const BLOCK_PLACEHOLDER: &str = "__HEAP_BLOCK_";
const NEW: &str = "__NEW";
const DELETE: &str = "__DELETE";
const DELETE_FN: &str = "__HEAP_DELETE";
/// The hidden FUNCTION that runs the `FB_exit` of the function blocks still live in the heap
/// when a RUN ends (`heap_delete.st`), which compile/fb_exit.rs's exit pass calls.
pub const EXIT_ALL: &str = "__HEAP_EXIT_ALL";
/// A global `POINTER TO BYTE` to no memory area, which `__HEAP_DELETE` sets before it answers
/// FALSE.
const NOWHERE: &str = "__HEAP_NOWHERE";
/// The input of a `__NEW`'s FUNCTION that counts its elements.
const COUNT: &str = "__HEAP_COUNT";
/// The call of `__FB_INIT_ALL` in `heap_new.st`, to which the inputs of `__NEW(T(x := 5))` are
/// added.
const INIT_CALL: &str = "bInCopyCode := FALSE)";

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
    /// `__NEW(T(x := 5))`: the inputs of `T`'s `__FB_INIT_ALL` after the two BOOLs, which its
    /// hidden FUNCTION declares and passes on (the call gives those written); empty otherwise.
    inputs: Vec<VarDecl>,
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
    let inits = init_inputs(&files);
    for (f, file) in files.iter_mut().enumerate() {
        if !uses(file) && !typed(file) {
            continue;
        }
        let file = file.to_mut();
        refuse_in_initial_values(file, diags);
        // the type arguments' aliases, numbered in their file: numbered apart in the project
        let mut aliases: HashMap<String, TypeRef> = HashMap::new();
        for item in &mut file.items {
            if let Item::Type(t) = item {
                if let Some(ty) = type_argument(&Item::Type(t.clone())) {
                    t.name.name = renamed(f, &t.name.name);
                    aliases.insert(t.name.name.clone(), ty.clone());
                    // `__NEW(T(x := 5))`: the alias is `T`, the arguments the call's
                    if let TypeRef::Enum(def) = ty {
                        if let Some(base) = def
                            .base
                            .as_ref()
                            .filter(|b| inits.contains_key(&b.name.to_ascii_lowercase()))
                        {
                            let ty = TypeRef::Named(base.clone());
                            t.def = TypeDef::Alias { ty, init: None };
                        }
                    }
                }
            }
        }
        let mut lowering = Lowering {
            file: f,
            aliases: &aliases,
            inits: &inits,
            sites: &mut sites,
            deletes: Vec::new(),
            reports: Vec::new(),
        };
        for item in &mut file.items {
            if let Item::Pou(p) = item {
                lowering.pou(p);
            }
        }
        deletes.extend(lowering.deletes.into_iter().map(|span| (f, span)));
        for (at, msg) in lowering.reports {
            diags.push(Diagnostic::new(&file.path, at.line, at.col, msg));
        }
    }
    // a `__NEW` refused (in an initial value) keeps the hidden file, whose `__HEAP_EXIT_ALL`
    // compile/fb_exit.rs may call: no other error follows the one reported
    let refused_new =
        files.iter().any(|f| f.habits.iter().any(|n| n.habit == Habit::DynamicMemory(NEW)));
    if sites.is_empty() && deletes.is_empty() && !refused_new {
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
    // the types of the function blocks to finish, by the number their part of `EXIT` names
    // (written into the parsed file: a name such as `FB_Log<20>` is no name in the text)
    let mut finished: Vec<(u32, TypeRef)> = Vec::new();
    for (k, site) in sites.iter().enumerate() {
        let tag = (k + 1).to_string();
        let hash = header_tag(&site.ty).to_string();
        let init = lifecycle(files, &site.ty, super::fb_init::INIT_ALL).is_some();
        // `__NEW(T(x := 5))`: the inputs passed on to `__FB_INIT_ALL`
        let forwarded: String =
            site.inputs.iter().map(|d| format!(", {0} := {0}", d.names[0].name)).collect();
        let init_call = INIT_CALL.replace(')', &format!("{forwarded})"));
        let new: String = NEW_TEMPLATE
            .lines()
            .filter(|line| init || !line.ends_with(INIT))
            .flat_map(|line| [line, "\n"])
            .collect();
        text.push_str(
            &new.replace(INIT_CALL, &init_call).replace("TAG", &tag).replace("HASH", &hash),
        );
        if lifecycle(files, &site.ty, super::fb_exit::EXIT_ALL).is_some() {
            // one part per type: the sites of one type share its tag
            let tag = header_tag(&site.ty);
            if !finished.iter().any(|(t, _)| *t == tag) {
                finished.push((tag, site.ty.clone()));
                let num = finished.len().to_string();
                exits.push_str(&exit_vars.replace("NUM", &num));
                finish.push_str(&exit_stmts.replace("NUM", &num).replace("HASH", &hash));
            }
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
            Item::Pou(p) if p.name.is(DELETE_FN) || p.name.is(EXIT_ALL) => {
                for d in p.vars.iter_mut().flat_map(|b| &mut b.decls) {
                    let TypeRef::Ref { to, .. } = &mut d.ty else { continue };
                    let TypeRef::Named(id) = to.as_ref() else { continue };
                    let Some(num) = id.name.strip_prefix(BLOCK_PLACEHOLDER) else { continue };
                    let at = num.parse::<usize>().ok().and_then(|n| n.checked_sub(1));
                    if let Some((_, ty)) = at.and_then(|n| finished.get(n)) {
                        **to = ty.clone();
                    }
                }
            }
            Item::Pou(p) => {
                let Some(site) = site(&p.name.name, "__HEAP_NEW_") else { continue };
                if let Some(ty) = &mut p.return_type {
                    replace_placeholder(ty, &site.ty);
                }
                if let Some(inputs) = p.vars.iter_mut().find(|b| b.kind == VarKind::Input) {
                    inputs.decls.extend(site.inputs.iter().cloned());
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

/// The tag a block of `__NEW(ty)` has in its header: FNV-1a of the type's name in lower case
/// (never 0, a free block's), the same from one compile to the next, so that an online change,
/// which keeps the heap, finds the type of each block it kept (a site's number would change).
fn header_tag(ty: &TypeRef) -> u32 {
    let name = match ty {
        TypeRef::Named(id) => id.name.as_str(),
        _ => "",
    };
    let mut h: u32 = 0x811c_9dc5;
    for b in name.to_ascii_lowercase().bytes() {
        h ^= u32::from(b);
        h = h.wrapping_mul(0x0100_0193);
    }
    h.max(1)
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

/// For each function block of `files` with an `__FB_INIT_ALL` (its own or a base's,
/// compile/fb_init.rs's), by name in lower case: that method's inputs after `bInitRetains` and
/// `bInCopyCode`, the inputs of its chain's `FB_init`s that `__NEW(T(x := 5))` gives; an empty
/// list for every other function block (whose `__NEW` may then give no argument).
fn init_inputs(files: &[Cow<'_, ast::File>]) -> HashMap<String, Vec<VarDecl>> {
    let blocks: HashMap<String, &Pou> = files
        .iter()
        .flat_map(|f| &f.items)
        .filter_map(|item| match item {
            Item::Pou(p) if p.kind == PouKind::FunctionBlock => {
                Some((p.name.name.to_ascii_lowercase(), p))
            }
            _ => None,
        })
        .collect();
    let inputs_of = |block: &str| {
        let mut at = blocks.get(block).copied();
        // a chain of bases longer than the project's blocks loops (reported elsewhere)
        for _ in 0..=blocks.len() {
            let p = at?;
            if let Some(m) = p.oop.methods.iter().find(|m| m.pou.name.is(super::fb_init::INIT_ALL))
            {
                let inputs = m.pou.vars.iter().filter(|b| b.kind == VarKind::Input);
                let singles = inputs.flat_map(|b| &b.decls).flat_map(|d| {
                    d.names.iter().map(move |n| VarDecl { names: vec![n.clone()], ..d.clone() })
                });
                return Some(singles.skip(2).collect());
            }
            at = p
                .oop
                .extends
                .as_ref()
                .and_then(|b| blocks.get(&b.name.to_ascii_lowercase()).copied());
        }
        None
    };
    blocks.keys().map(|k| (k.clone(), inputs_of(k).unwrap_or_default())).collect()
}

/// The walk over one file's bodies.
struct Lowering<'a> {
    file: usize,
    /// The file's hidden aliases of `__NEW`'s types, by name.
    aliases: &'a HashMap<String, TypeRef>,
    /// The inputs of each function block's `__FB_INIT_ALL` after the two BOOLs, by name in lower
    /// case ([`init_inputs`]).
    inits: &'a HashMap<String, Vec<VarDecl>>,
    sites: &'a mut Vec<Site>,
    /// The places of the file's `__DELETE`s.
    deletes: Vec<Span>,
    /// The errors of `__NEW(T(…))`'s arguments.
    reports: Vec<(Span, String)>,
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
                } else if matches!(&callee.kind, ExprKind::Name(id) if id.is(DELETE)) {
                    // a statement of its own ([`Lowering::stmts`]), so here inside an
                    // expression; called as `__HEAP_DELETE`, whose BOOL adds no other error
                    let msg = "`__DELETE(p)` frees a block and gives no value: write it as a statement of its own, `__DELETE(p);` (TwinCAT, CODESYS)";
                    self.reports.push((e.span, msg.to_string()));
                    self.deletes.push(e.span);
                    **callee = name(DELETE_FN, e.span);
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
        let mut given = Vec::new();
        let mut inputs = Vec::new();
        let ty = match self.aliases.get(&ty.name) {
            // `__NEW(T(x := 5))`, `__NEW(T(5))`: `FB_init`'s arguments, as a declaration's
            Some(TypeRef::Enum(def))
                if def
                    .base
                    .as_ref()
                    .is_some_and(|b| self.inits.contains_key(&b.name.to_ascii_lowercase())) =>
            {
                let base = def.base.clone().unwrap_or_else(|| ty.clone());
                let known = &self.inits[&base.name.to_ascii_lowercase()];
                let written = super::fb_init::written_arguments(def);
                let mut report = |at: Span, msg: String| self.reports.push((at, msg));
                let subject = format!("`__NEW({}(…))`", base.name);
                let place = "this `__NEW`";
                super::fb_init::check_arguments(
                    &base.name,
                    &written,
                    known,
                    (&subject, place),
                    &mut report,
                );
                given = super::fb_init::declared_arguments(&TypeRef::Enum(def.clone()), known);
                if !given.is_empty() {
                    inputs = known.clone();
                }
                TypeRef::Named(base)
            }
            Some(alias) => alias.clone(),
            None => TypeRef::Named(ty.clone()),
        };
        let count = match args.get(1) {
            Some(Arg::Positional(n)) => n.clone(),
            _ => int(1, span),
        };
        self.sites.push(Site { ty, file: self.file, span, inputs });
        let hidden: Ident = ident(&format!("__HEAP_NEW_{}", self.sites.len()), span);
        let callee = Box::new(Expr { kind: ExprKind::Name(hidden), span });
        let mut args = vec![Arg::Input { name: ident(COUNT, span), value: count }];
        args.extend(given);
        Some(ExprKind::Call { callee, args })
    }
}

/// Reports each `__NEW` in an initial value of `file` (the vendors' documentation shows it in
/// statements only, and plcd takes it there), and leaves that initial value out so that no
/// other error follows.
fn refuse_in_initial_values(file: &mut ast::File, diags: &mut Vec<Diagnostic>) {
    fn news(e: &Expr, out: &mut Vec<Span>) {
        match &e.kind {
            ExprKind::Literal(_) | ExprKind::Name(_) => {}
            ExprKind::Member(inner, _)
            | ExprKind::Bit(inner, _)
            | ExprKind::Part(inner, _, _)
            | ExprKind::Deref(inner)
            | ExprKind::Unary(_, inner) => news(inner, out),
            ExprKind::Index(inner, index) => {
                news(inner, out);
                index.iter().for_each(|i| news(i, out));
            }
            ExprKind::Binary(_, a, b) | ExprKind::Assign(a, b) => {
                news(a, out);
                news(b, out);
            }
            ExprKind::Call { callee, args } => {
                if matches!(&callee.kind, ExprKind::Name(id) if id.is(NEW)) {
                    out.push(e.span);
                }
                for arg in args {
                    match arg {
                        Arg::Positional(v) | Arg::Input { value: v, .. } => news(v, out),
                        Arg::Output { target, .. } => news(target, out),
                    }
                }
            }
        }
    }
    fn in_init(init: &Init, out: &mut Vec<Span>) {
        match init {
            Init::Expr(e) => news(e, out),
            Init::Array { elems, .. } => {
                for elem in elems {
                    match elem {
                        ArrayInit::One(v) | ArrayInit::Repeat { value: Some(v), .. } => {
                            in_init(v, out)
                        }
                        ArrayInit::Repeat { value: None, .. } => {}
                    }
                }
            }
            Init::Struct { members, .. } => members.iter().for_each(|(_, v)| in_init(v, out)),
        }
    }
    let path = file.path.clone();
    let mut check = |d: &mut VarDecl| {
        let mut found = Vec::new();
        if let Some(init) = &d.init {
            in_init(init, &mut found);
        }
        if !found.is_empty() {
            d.init = None;
        }
        for at in found {
            let msg = "`__NEW` stands in a POU's statements, not in an initial value: assign it at the first scan, `IF p = 0 THEN p := __NEW(T); END_IF`";
            diags.push(Diagnostic::new(&path, at.line, at.col, msg));
        }
    };
    for item in &mut file.items {
        match item {
            Item::Pou(p) => {
                let methods = p.oop.methods.iter_mut().flat_map(|m| &mut m.pou.vars);
                for d in p.vars.iter_mut().chain(methods).flat_map(|b| &mut b.decls) {
                    check(d);
                }
            }
            Item::Globals(b) => b.decls.iter_mut().for_each(&mut check),
            _ => {}
        }
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
