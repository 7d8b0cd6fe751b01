//! TwinCAT 3.1.4026's generic constants: a function block's `VAR_GENERIC CONSTANT` block
//! (`n : UINT := 10;`), whose values each instance's type gives (`log : FB_Log<20>;`,
//! `FB<(N * 2), 5>`), usable wherever a constant is (array bounds, string lengths, the body).
//!
//! A lowering of the syntax trees before every other stage, by monomorphisation: each distinct
//! list of values makes a copy of the block named as it is written, `FB_Log<20>` (or
//! `FB<20, 5>`), whose generic constants are a `VAR CONSTANT` block holding those values, and
//! every type that names the block with arguments names its copy instead, and so does a
//! derived block's `EXTENDS FB_Log<20>`. The copy keeps the
//! spans of the block's source, so a diagnostic in it points there, and its methods,
//! properties and actions are copied with it. The block named alone is the block with the
//! values its declarations give (0 where none is given), as TwinCAT uses the initial values
//! to check the block itself.
//!
//! The arguments are constant integer expressions of literals and of the project's
//! `VAR_GLOBAL CONSTANT`s given by such an expression, of the POU's own `VAR CONSTANT`s (a
//! method's, its block's), and, in a block with generic constants, of its own generic
//! constants (`inner : FB_Buf<n>`): they are evaluated here,
//! since the copies are made before types are known. Checked here: the number of arguments,
//! that each is such a constant, that it fits its generic constant's integer type, that a
//! generic constant has an integer type, and that only a function block with generic
//! constants takes arguments.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, BinaryOp, Expr, ExprKind, Ident, Init, Item, Literal, Pou, Span, TypeDef, TypeRef,
    UnaryOp, VarBlock, VarKind,
};

/// How many copies a project may make: a block whose copy asks for another copy of itself
/// (`inner : FB<n + 1>` in `FB`) would otherwise never end.
const MAX_COPIES: usize = 1000;

/// One generic constant of a block.
#[derive(Clone)]
struct Param {
    name: String,
    /// Its type's name in upper case (`UINT`); a subrange's base.
    ty: String,
    /// Its value when the block is named alone.
    default: i128,
}

/// A block with generic constants: where it is and its constants.
struct Generic {
    file: usize,
    item: usize,
    name: String,
    params: Vec<Param>,
}

/// The lowering's state: the generic blocks (by lower-case name), the global constants, the
/// copies made (by lower-case name and values) and those still to fill in.
struct Lowering<'d> {
    generics: HashMap<String, Generic>,
    globals: HashMap<String, i128>,
    copies: HashMap<(String, Vec<i128>), String>,
    pending: Vec<(String, Vec<i128>, String)>,
    /// Whether the copies went beyond [`MAX_COPIES`] (reported once).
    endless: bool,
    /// `[st] namespaces` and the system libraries' (`compile::libraries::namespaces`): a
    /// block named with one before it (`Lib.FB_Log<20>`) is the block.
    namespaces: &'d [String],
    diags: &'d mut Vec<Diagnostic>,
}

pub(super) fn lower<'f>(
    mut files: Vec<Cow<'f, ast::File>>,
    namespaces: &[String],
    diags: &mut Vec<Diagnostic>,
) -> Vec<Cow<'f, ast::File>> {
    if !files
        .iter()
        .any(|f| f.habits.iter().any(|h| h.habit == crate::st::dialect::Habit::GenericConstants))
    {
        return files;
    }
    let mut lowering = Lowering {
        generics: HashMap::new(),
        globals: global_constants(&files),
        copies: HashMap::new(),
        pending: Vec::new(),
        endless: false,
        namespaces,
        diags,
    };
    // the blocks and their constants
    for (f, file) in files.iter_mut().enumerate() {
        if !file.items.iter().any(|i| matches!(i, Item::Pou(p) if has_generics(p))) {
            continue;
        }
        let path = file.path.clone();
        for (i, item) in file.to_mut().items.iter_mut().enumerate() {
            let Item::Pou(p) = item else { continue };
            if !has_generics(p) {
                continue;
            }
            let params = lowering.params(p, &path);
            lowering.generics.insert(
                p.name.name.to_ascii_lowercase(),
                Generic { file: f, item: i, name: p.name.name.clone(), params },
            );
        }
    }
    // every type naming a block with arguments, in the sources as written but the generic
    // blocks themselves, whose copies are made of them as written
    for file in files.iter_mut() {
        let path = file.path.clone();
        for item in file.to_mut().items.iter_mut() {
            if !matches!(item, Item::Pou(p) if has_generics(p)) {
                lowering.item_types(item, &HashMap::new(), &path);
            }
        }
    }
    lowering.make_copies(&mut files);
    // then the blocks named alone: the values their declarations give
    let mut blocks: Vec<(usize, usize, Vec<Param>)> =
        lowering.generics.values().map(|g| (g.file, g.item, g.params.clone())).collect();
    blocks.sort_by_key(|b| (b.0, b.1));
    for (f, i, params) in blocks {
        let path = files[f].path.clone();
        let defaults: Vec<i128> = params.iter().map(|q| q.default).collect();
        let own = own_values(&params, &defaults);
        let item = &mut files[f].to_mut().items[i];
        lowering.item_types(item, &own, &path);
        if let Item::Pou(p) = item {
            set_constants(p, &params, &defaults);
        }
    }
    lowering.make_copies(&mut files);
    files
}

/// The generic constants' values by lower-case name, for the arguments inside a copy.
fn own_values(params: &[Param], values: &[i128]) -> HashMap<String, i128> {
    params.iter().map(|q| q.name.to_ascii_lowercase()).zip(values.iter().copied()).collect()
}

/// Whether a POU declares generic constants.
fn has_generics(p: &Pou) -> bool {
    p.vars.iter().any(|b| b.kind == VarKind::Generic)
}

/// The project's `VAR_GLOBAL CONSTANT` integers whose values this lowering can compute
/// (literals and earlier such constants), by lower-case name.
fn global_constants(files: &[Cow<'_, ast::File>]) -> HashMap<String, i128> {
    let mut values = HashMap::new();
    for file in files {
        for item in &file.items {
            let Item::Globals(b) = item else { continue };
            if !b.constant {
                continue;
            }
            for d in &b.decls {
                let Some(Init::Expr(e)) = &d.init else { continue };
                if let Some(v) = evaluate(e, &values, &HashMap::new()) {
                    for id in &d.names {
                        values.insert(id.name.to_ascii_lowercase(), v);
                    }
                }
            }
        }
    }
    values
}

/// The value of a constant integer expression: literals, `+ - * / MOD`, names of `own`
/// (the block's generic constants) or of `globals`.
fn evaluate(
    e: &Expr,
    globals: &HashMap<String, i128>,
    own: &HashMap<String, i128>,
) -> Option<i128> {
    match &e.kind {
        ExprKind::Literal(Literal::Int(n) | Literal::Based(n)) => i128::try_from(*n).ok(),
        ExprKind::Name(id) => {
            let k = id.name.to_ascii_lowercase();
            own.get(&k).or_else(|| globals.get(&k)).copied()
        }
        ExprKind::Unary(UnaryOp::Neg, a) => evaluate(a, globals, own)?.checked_neg(),
        ExprKind::Unary(UnaryOp::Plus, a) => evaluate(a, globals, own),
        ExprKind::Binary(op, a, b) => {
            let (a, b) = (evaluate(a, globals, own)?, evaluate(b, globals, own)?);
            match op {
                BinaryOp::Add => a.checked_add(b),
                BinaryOp::Sub => a.checked_sub(b),
                BinaryOp::Mul => a.checked_mul(b),
                // IEC's integer division truncates towards zero, as Rust's
                BinaryOp::Div => a.checked_div(b),
                BinaryOp::Mod => a.checked_rem(b),
                _ => None,
            }
        }
        _ => None,
    }
}

/// The range of an integer type by its upper-case name.
fn int_range(ty: &str) -> Option<(i128, i128)> {
    Some(match ty {
        "SINT" => (i8::MIN as i128, i8::MAX as i128),
        "INT" => (i16::MIN as i128, i16::MAX as i128),
        "DINT" => (i32::MIN as i128, i32::MAX as i128),
        "LINT" => (i64::MIN as i128, i64::MAX as i128),
        "USINT" | "BYTE" => (0, u8::MAX as i128),
        "UINT" | "WORD" => (0, u16::MAX as i128),
        "UDINT" | "DWORD" => (0, u32::MAX as i128),
        "ULINT" | "LWORD" => (0, u64::MAX as i128),
        _ => return None,
    })
}

/// A literal of `v` (a negative value as the negation of its magnitude).
fn literal(v: i128, span: Span) -> Expr {
    let lit = Expr { kind: ExprKind::Literal(Literal::Int(v.unsigned_abs())), span };
    if v < 0 {
        Expr { kind: ExprKind::Unary(UnaryOp::Neg, Box::new(lit)), span }
    } else {
        lit
    }
}

/// Makes `p`'s `VAR_GENERIC CONSTANT` blocks one `VAR CONSTANT` block of `values`.
fn set_constants(p: &mut Pou, params: &[Param], values: &[i128]) {
    for b in p.vars.iter_mut().filter(|b| b.kind == VarKind::Generic) {
        b.kind = VarKind::Local;
        b.constant = true;
        // one declaration per name, so that each takes its own value
        let decls = std::mem::take(&mut b.decls);
        for d in decls {
            for id in &d.names {
                let k = params.iter().position(|q| q.name.eq_ignore_ascii_case(&id.name));
                let init = k
                    .and_then(|k| values.get(k))
                    .map(|v| Init::Expr(literal(*v, id.span)))
                    .or_else(|| d.init.clone());
                // a generic constant at `AT %I*` (as a TwinCAT export has one) is a constant
                // all the same: it has no place to link
                let location = None;
                b.decls.push(ast::VarDecl { names: vec![id.clone()], init, location, ..d.clone() });
            }
        }
    }
}

/// The actions a block has outside its body (`ACTION FB.Act:` items, and those without an
/// owner that follow it in its file), as actions of its copy `copy`.
pub(super) fn actions_of(items: &[Item], at: usize, original: &str, copy: &str) -> Vec<Item> {
    let mut out = Vec::new();
    let mut after_it = false;
    for (i, item) in items.iter().enumerate() {
        match item {
            Item::Pou(_) => after_it = i == at,
            Item::Action { owner, action } => {
                let ours = match owner {
                    Some(o) => o.name.eq_ignore_ascii_case(original),
                    None => after_it,
                };
                if ours {
                    let span = owner.as_ref().map_or(action.span, |o| o.span);
                    out.push(Item::Action {
                        owner: Some(Ident { name: copy.to_string(), span }),
                        action: action.clone(),
                    });
                }
            }
            _ => {}
        }
    }
    out
}

impl Lowering<'_> {
    fn error(&mut self, path: &Path, span: Span, message: impl Into<String>) {
        self.diags.push(Diagnostic::new(path, span.line, span.col, message));
    }

    /// A block's generic constants, checked: an integer type, a constant default.
    fn params(&mut self, p: &Pou, path: &Path) -> Vec<Param> {
        let mut params = Vec::new();
        for b in p.vars.iter().filter(|b| b.kind == VarKind::Generic) {
            if !b.constant {
                self.error(
                    path,
                    b.span,
                    "`VAR_GENERIC` declares constants: write `VAR_GENERIC CONSTANT`",
                );
            }
            for d in &b.decls {
                let ty = match &d.ty {
                    TypeRef::Named(id) => Some(id.name.to_ascii_uppercase()),
                    TypeRef::Subrange { base, .. } => Some(base.name.to_ascii_uppercase()),
                    _ => None,
                };
                let Some(ty) = ty.filter(|t| int_range(t).is_some()) else {
                    let at = d.names.first().map_or(d.span, |n| n.span);
                    self.error(
                        path,
                        at,
                        "a generic constant has an integer type (`n : UINT := 10;`)",
                    );
                    continue;
                };
                let default = match &d.init {
                    None => 0,
                    Some(Init::Expr(e)) => match evaluate(e, &self.globals, &HashMap::new()) {
                        Some(v) => v,
                        None => {
                            self.error(path, e.span, "a generic constant's initial value must be a constant integer expression");
                            0
                        }
                    },
                    Some(_) => 0,
                };
                for id in &d.names {
                    params.push(Param { name: id.name.clone(), ty: ty.clone(), default });
                }
            }
        }
        params
    }

    /// Makes the copies asked for, each of which may ask for more, after their block's items.
    fn make_copies(&mut self, files: &mut [Cow<'_, ast::File>]) {
        while let Some((key, values, copy_name)) = self.pending.pop() {
            let (f, i, params) = {
                let g = &self.generics[&key];
                (g.file, g.item, g.params.clone())
            };
            let path = files[f].path.clone();
            let Item::Pou(original) = &files[f].items[i] else { continue };
            let mut copy = original.clone();
            let original_name = original.name.name.clone();
            copy.name.name = copy_name.clone();
            let own = own_values(&params, &values);
            set_constants(&mut copy, &params, &values);
            let mut item = Item::Pou(copy);
            self.item_types(&mut item, &own, &path);
            let actions = actions_of(&files[f].items, i, &original_name, &copy_name);
            let items = &mut files[f].to_mut().items;
            items.push(item);
            items.extend(actions);
        }
    }

    /// Rewrites every type of `item` that gives a block arguments.
    fn item_types(&mut self, item: &mut Item, own: &HashMap<String, i128>, path: &Path) {
        match item {
            Item::Pou(p) => self.pou_types(p, own, path),
            Item::Globals(b) => self.block_types(b, own, path),
            Item::Type(t) => match &mut t.def {
                TypeDef::Alias { ty, .. } => self.type_ref(ty, own, path),
                TypeDef::Struct { members } | TypeDef::Union { members } => {
                    for d in members {
                        self.type_ref(&mut d.ty, own, path);
                    }
                }
                TypeDef::Enum { .. } => {}
            },
            Item::Configuration(c) => {
                for b in &mut c.globals {
                    self.block_types(b, own, path);
                }
            }
            Item::Interface(i) => {
                for m in &mut i.methods {
                    self.pou_types(&mut m.pou, own, path);
                }
            }
            Item::Action { .. } => {}
        }
    }

    fn pou_types(&mut self, p: &mut Pou, own: &HashMap<String, i128>, path: &Path) {
        // the POU's own constants (`VAR CONSTANT cLen : UDINT := 5;`, `FB_Str<cLen>`), as
        // constant as a global's; a method sees its block's too
        let mut own = own.clone();
        for d in
            p.vars.iter().filter(|b| b.constant && b.kind == VarKind::Local).flat_map(|b| &b.decls)
        {
            let Some(Init::Expr(e)) = &d.init else { continue };
            if let Some(v) = evaluate(e, &self.globals, &own) {
                for id in &d.names {
                    own.insert(id.name.to_ascii_lowercase(), v);
                }
            }
        }
        let own = &own;
        // `EXTENDS FB_Base<20>`: the base's copy for those values
        if let (Some(base), Some(args)) = (p.oop.extends.clone(), p.oop.extends_args.take()) {
            let span = args.first().map_or(base.span, |a| a.span);
            let copy = self.copy_for(&base, &args, span, own, path);
            p.oop.extends = Some(Ident { name: copy, span: base.span });
        }
        for b in &mut p.vars {
            self.block_types(b, own, path);
        }
        if let Some(ty) = &mut p.return_type {
            self.type_ref(ty, own, path);
        }
        for m in &mut p.oop.methods {
            self.pou_types(&mut m.pou, own, path);
        }
        for prop in &mut p.oop.properties {
            self.type_ref(&mut prop.ty, own, path);
            for accessor in [&mut prop.get, &mut prop.set].into_iter().flatten() {
                self.pou_types(accessor, own, path);
            }
        }
    }

    fn block_types(&mut self, b: &mut VarBlock, own: &HashMap<String, i128>, path: &Path) {
        for d in &mut b.decls {
            self.type_ref(&mut d.ty, own, path);
        }
    }

    /// Replaces `FB<…>` in `ty` by the name of the copy of `FB` for its values.
    fn type_ref(&mut self, ty: &mut TypeRef, own: &HashMap<String, i128>, path: &Path) {
        match ty {
            TypeRef::Array { of, .. } | TypeRef::OpenArray { of, .. } => {
                self.type_ref(of, own, path)
            }
            TypeRef::Ref { to, .. } => self.type_ref(to, own, path),
            TypeRef::Generic { name, args, span } => {
                let copy = self.copy_for(name, args, *span, own, path);
                *ty = TypeRef::Named(Ident { name: copy, span: name.span });
            }
            _ => {}
        }
    }

    /// `name` without the namespaces written before it (`Lib.FB_Log`: `FB_Log`), as
    /// `compile::qualified` reads a type's name after this lowering.
    fn unqualified<'n>(&self, name: &'n str) -> &'n str {
        let mut name = name;
        while let Some((first, rest)) = name.split_once('.') {
            if !self.namespaces.iter().any(|n| n.eq_ignore_ascii_case(first.trim())) {
                break;
            }
            name = rest.trim();
        }
        name
    }

    /// The name of the copy of block `name` for `args` (asked for when new); `name` itself
    /// after an error.
    fn copy_for(
        &mut self,
        name: &Ident,
        args: &[Expr],
        span: Span,
        own: &HashMap<String, i128>,
        path: &Path,
    ) -> String {
        let key = self.unqualified(&name.name).to_ascii_lowercase();
        let Some(g) = self.generics.get(&key) else {
            self.error(
                path,
                span,
                format!("`{}` is not a function block with generic constants (`VAR_GENERIC CONSTANT`): it takes no `<…>`", name.name),
            );
            return name.name.clone();
        };
        if args.len() != g.params.len() {
            let n = g.params.len();
            let names: Vec<String> = g.params.iter().map(|q| format!("`{}`", q.name)).collect();
            let message = format!(
                "`{}` has {n} generic constant{} ({}), given {} argument{}",
                g.name,
                if n == 1 { "" } else { "s" },
                names.join(", "),
                args.len(),
                if args.len() == 1 { "" } else { "s" },
            );
            self.error(path, span, message);
            return name.name.clone();
        }
        let mut values = Vec::new();
        let mut failed = false;
        let checks: Vec<(String, String)> =
            g.params.iter().map(|q| (q.name.clone(), q.ty.clone())).collect();
        let block = g.name.clone();
        for (arg, (param, ty)) in args.iter().zip(checks) {
            match evaluate(arg, &self.globals, own) {
                None => {
                    self.error(path, arg.span, format!("the value of `{block}`'s generic constant `{param}` must be a constant integer expression (literals, global constants, the POU's own constants and generic constants)"));
                    failed = true;
                }
                Some(v) => {
                    let (lo, hi) = int_range(&ty).unwrap_or((i128::MIN, i128::MAX));
                    if v < lo || v > hi {
                        self.error(
                            path,
                            arg.span,
                            format!("{v} does not fit `{param} : {ty}` of `{block}`"),
                        );
                        failed = true;
                    }
                    values.push(v);
                }
            }
        }
        if failed {
            return name.name.clone();
        }
        if let Some(copy) = self.copies.get(&(key.clone(), values.clone())) {
            return copy.clone();
        }
        if self.copies.len() >= MAX_COPIES {
            if !self.endless {
                self.endless = true;
                let message = format!("`{block}` asks for copies of itself without end (its generic constants give an instance of it new values each time); more than {MAX_COPIES} were made");
                self.error(path, span, message);
            }
            return name.name.clone();
        }
        let shown: Vec<String> = values.iter().map(i128::to_string).collect();
        let copy = format!("{}<{}>", block, shown.join(", "));
        self.copies.insert((key.clone(), values.clone()), copy.clone());
        self.pending.push((key, values, copy.clone()));
        copy
    }
}
