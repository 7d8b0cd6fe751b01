//! Declarations: every TYPE, POU and VAR_GLOBAL of every file by name, their types resolved,
//! their variables laid out (instances inline, FUNCTION variables in the frame), their initial
//! images, and the located variables' devices.

use std::collections::HashMap;
use std::rc::Rc;

use crate::device::iec::{sized, IecLayout};
use crate::device::{Address, BitRef, Writer};
use crate::lang::Place;
use crate::st::ast::{self, ArrayInit, Init, Item, PouKind, Span, TypeDef, TypeRef, VarKind};

use super::ctx::{
    action_key, suggest, Ctx, Cv, PouInfo, Scope, State, Storage, TypeEntry, VarInfo,
};
use super::fb_init;
use super::types::{fits, ArrayTy, EnumTy, Member, Prim, StructTy, Ty};

/// The largest frame or instance the compiler accepts.
pub const MAX_FRAME: u32 = 1 << 20;

fn key(name: &str) -> String {
    name.to_ascii_lowercase()
}

/// An action written outside its POU: its file, the POU it names or follows (name and place),
/// and its declaration.
type OutsideAction<'a> = (usize, Option<(String, Span)>, &'a ast::Action);

impl<'a> Ctx<'a> {
    fn reserved(&mut self, file: usize, id: &ast::Ident) {
        let hidden = fb_init::is_hidden(&id.name)
            || super::ref_init::is_hidden(&id.name)
            || super::heap::is_hidden(&id.name);
        if !self.is_shipped(file) && id.name.starts_with("__") && !hidden {
            self.error(
                file,
                id.span,
                format!("`{}`: names starting with `__` are reserved", id.name),
            );
        }
    }

    fn first_at(&self, file: usize, span: Span, here: usize) -> String {
        if file == here {
            format!("line {}", span.line)
        } else {
            format!("`{}` line {}", self.path(file).display(), span.line)
        }
    }

    /// Registers every top-level name; reports duplicates.
    pub fn collect(&mut self) {
        let files = self.files.clone();
        let mut seen: HashMap<String, (usize, Span)> = HashMap::new();
        // actions written outside their POU, with the POU they name (or follow)
        let mut outside: Vec<OutsideAction<'a>> = Vec::new();
        let mut last_pou: Option<&'a ast::Pou> = None;
        for (fi, file) in files.iter().enumerate() {
            for item in &file.items {
                let (id, is_type) = match item {
                    Item::Type(d) => (&d.name, true),
                    Item::Pou(p) => (&p.name, false),
                    Item::Globals(b) => {
                        self.global_blocks.push((fi, b));
                        continue;
                    }
                    Item::Action { owner, action } => {
                        // the POU named, or the one just before
                        let owner =
                            owner.as_ref().map(|o| (o.name.clone(), o.span)).or_else(|| {
                                last_pou.map(|p: &ast::Pou| (p.name.name.clone(), p.name.span))
                            });
                        outside.push((fi, owner, action));
                        continue;
                    }
                    Item::Interface(i) => (&i.name, true),
                    Item::Configuration(c) => {
                        // its globals are the project's; its tasks and programs the project's
                        // config takes (`st::configuration`)
                        self.global_blocks.extend(c.globals.iter().map(|b| (fi, b)));
                        continue;
                    }
                };
                self.reserved(fi, id);
                if Prim::from_name(&id.name).is_some() || id.is("STRING") {
                    self.error(fi, id.span, format!("`{}` is an elementary type", id.name));
                    continue;
                }
                // a POU would replace the standard function for every caller
                if !is_type && !self.is_shipped(fi) && super::stdlib::is_standard_function(&id.name)
                {
                    let msg = format!("`{}` is a standard function: the name is reserved", id.name);
                    self.error(fi, id.span, msg);
                    continue;
                }
                if let Some(&(f0, s0)) = seen.get(&key(&id.name)) {
                    // A FUNCTION of the prelude (`DAY_OF_WEEK`), and the RTC block newer
                    // projects may have written for themselves, are replaced by the project's
                    // own of the same name (docs/ST.md, "Dates and times of day").
                    let replaceable = matches!(item, Item::Pou(p)
                        if p.kind == PouKind::Function || p.name.is("RTC"));
                    if fi == self.prelude_file && replaceable {
                        continue;
                    }
                    let first = self.first_at(f0, s0, fi);
                    self.error(fi, id.span, format!("`{}` is already declared ({first})", id.name));
                    continue;
                }
                seen.insert(key(&id.name), (fi, id.span));
                match item {
                    Item::Type(d) => {
                        self.type_names.insert(key(&d.name.name), self.type_decls.len());
                        self.type_decls.push(TypeEntry {
                            decl: d,
                            file: fi,
                            state: State::Todo,
                            ty: Ty::Error,
                            image: None,
                        });
                    }
                    Item::Pou(p) => {
                        let owner = self.pous.len();
                        self.pou_names.insert(key(&p.name.name), owner);
                        self.pous.push(PouInfo::new(p, fi));
                        for action in &p.actions {
                            self.add_action(fi, owner, action);
                        }
                        self.add_members(fi, owner, p);
                        last_pou = Some(p);
                    }
                    Item::Interface(i) => self.add_interface(fi, i),
                    Item::Globals(_) | Item::Action { .. } | Item::Configuration(_) => {}
                }
                let _ = is_type;
            }
            last_pou = None;
        }
        for (fi, owner, action) in outside {
            let Some((name, span)) = owner else {
                let msg = "an ACTION outside a POU needs its POU: `ACTION Pou.Name:`";
                self.error(fi, action.span, msg);
                continue;
            };
            match self.pou_names.get(&key(&name)).copied() {
                Some(p) => self.add_action(fi, p, action),
                None => {
                    let msg = format!("`{name}` is not a PROGRAM or FUNCTION_BLOCK of the project");
                    self.error(fi, span, msg);
                }
            }
        }
        self.types.fbs = self
            .pous
            .iter()
            .map(|p| (p.kind == PouKind::FunctionBlock).then(|| (p.name.clone(), 0)))
            .collect();
    }

    /// Resolves every declaration: types, globals, POU interfaces.
    pub fn resolve_all(&mut self) {
        // Global constants first: types use them (`ARRAY [0..LOG_MAX] OF …` in a STRUCT).
        let (constants, blocks): (Vec<_>, Vec<_>) =
            self.global_blocks.clone().into_iter().partition(|(_, b)| b.constant);
        for (file, block) in constants {
            self.resolve_globals(file, block);
        }
        for i in 0..self.type_decls.len() {
            self.resolve_type_decl(i);
        }
        for (file, block) in blocks {
            self.resolve_globals(file, block);
        }
        for p in 0..self.pous.len() {
            self.resolve_pou(p);
        }
    }

    fn global_scope(&self, file: usize) -> Scope {
        Scope { pou: None, visible: 0, file }
    }

    /// A constant integer expression (array bounds, string lengths, repeat counts).
    pub fn const_int(&mut self, e: &ast::Expr, scope: Scope) -> Option<i128> {
        let te = self.check_expr(e, scope, None);
        match (&te.k, &te.ty) {
            (_, Ty::Error) => None,
            (super::expr::TK::Const(Cv::Int(v)), ty)
                if matches!(ty, Ty::IntLit)
                    || ty.prim(&self.types).is_some_and(Prim::is_integral) =>
            {
                Some(*v)
            }
            (super::expr::TK::Const(_), ty) => {
                let n = self.ty_name(ty);
                self.error(
                    scope.file,
                    e.span,
                    format!("an integer constant is needed here, not `{n}`"),
                );
                None
            }
            _ => {
                self.error(scope.file, e.span, "a constant expression is needed here");
                None
            }
        }
    }

    pub fn resolve_type_ref(&mut self, tr: &TypeRef, scope: Scope) -> Ty {
        let file = scope.file;
        match tr {
            TypeRef::Named(id) => {
                if let Some(p) = Prim::from_name(&id.name) {
                    return Ty::Prim(p);
                }
                if id.is("STRING") {
                    return Ty::Str(80);
                }
                if id.is("WSTRING") {
                    return Ty::WStr(80);
                }
                let name = super::generic::system_type_name(&id.name).unwrap_or(&id.name);
                if let Some(&t) = self.type_names.get(&key(name)) {
                    return self.resolve_type_decl(t);
                }
                if let Some(&p) = self.pou_names.get(&key(&id.name)) {
                    if self.pous[p].kind != PouKind::FunctionBlock {
                        self.error(file, id.span, format!("`{}` is not a type", id.name));
                        return Ty::Error;
                    }
                    if self.pous[p].state == State::Busy {
                        self.error(
                            file,
                            id.span,
                            format!("`{}` contains an instance of itself", self.pous[p].name),
                        );
                        return Ty::Error;
                    }
                    self.resolve_pou(p);
                    return Ty::Fb(p);
                }
                if let Some(&i) = self.oop.interface_names.get(&key(&id.name)) {
                    return Ty::Iface(i);
                }
                if let Some(ty) = self.misplaced_generic(file, id) {
                    return ty;
                }
                if let Some(ty) = self.misplaced_bit(file, id) {
                    return ty;
                }
                let mut names: Vec<String> =
                    self.type_decls.iter().map(|t| t.decl.name.name.clone()).collect();
                names.extend(
                    self.pous
                        .iter()
                        .filter(|p| p.kind == PouKind::FunctionBlock)
                        .map(|p| p.name.clone()),
                );
                names.extend(super::types::ALL_PRIMS.iter().map(|p| p.name().to_string()));
                names.extend(["STRING".into(), "WSTRING".into()]);
                let hint = suggest(&id.name, names.iter().map(String::as_str));
                self.error(file, id.span, format!("unknown type `{}`{hint}", id.name));
                Ty::Error
            }
            TypeRef::WString { len, span } => {
                let Some(len) = len else { return Ty::WStr(80) };
                match self.const_int(len, scope) {
                    Some(n) if (1..=255).contains(&n) => Ty::WStr(n as u32),
                    Some(n) => {
                        self.error(
                            file,
                            *span,
                            format!("a WSTRING's length must be 1..255, not {n}"),
                        );
                        Ty::Error
                    }
                    None => Ty::Error,
                }
            }
            TypeRef::String { len, span } => {
                let Some(len) = len else { return Ty::Str(80) };
                match self.const_int(len, scope) {
                    Some(n) if (1..=255).contains(&n) => Ty::Str(n as u32),
                    Some(n) => {
                        self.error(
                            file,
                            *span,
                            format!("a STRING's length must be 1..255, not {n}"),
                        );
                        Ty::Error
                    }
                    None => Ty::Error,
                }
            }
            TypeRef::Array { dims, of, span } => {
                let mut out = Vec::new();
                let mut bad = false;
                for (lo, hi) in dims {
                    let l = self.const_int(lo, scope);
                    let h = self.const_int(hi, scope);
                    match (l, h) {
                        (Some(l), Some(h))
                            if l <= h && l >= i32::MIN as i128 && h <= i32::MAX as i128 =>
                        {
                            out.push((l as i64, h as i64))
                        }
                        (Some(l), Some(h)) => {
                            self.error(
                                file,
                                lo.span,
                                format!("empty or too large array range `{l}..{h}`"),
                            );
                            bad = true;
                        }
                        _ => bad = true,
                    }
                }
                let of = self.resolve_type_ref(of, scope);
                if bad || of.is_error() {
                    return Ty::Error;
                }
                let elem_size = self.types.size(&of);
                let arr = ArrayTy { dims: out, of, elem_size };
                let bytes = arr.count().saturating_mul(u64::from(elem_size));
                if bytes > u64::from(self.dialect.variable_memory_bytes) {
                    self.memory_too_large("the array", bytes, file, *span);
                    return Ty::Error;
                }
                Ty::Array(Rc::new(arr))
            }
            TypeRef::OpenArray { span, .. } => self.misplaced_open_array(file, *span),
            // compile::generic_constants replaced each by its copy's name, or reported it
            TypeRef::Generic { .. } => Ty::Error,
            TypeRef::Enum(def) => {
                let name = format!(
                    "({})",
                    def.values.iter().map(|v| v.0.name.as_str()).collect::<Vec<_>>().join(", ")
                );
                self.make_enum(name, def, None, scope)
            }
            TypeRef::Subrange { base, lo, hi, span } => {
                let Some(p) = Prim::from_name(&base.name).filter(|p| p.is_integral()) else {
                    self.error(
                        file,
                        base.span,
                        format!("a subrange needs an integer type, not `{}`", base.name),
                    );
                    return Ty::Error;
                };
                let (Some(l), Some(h)) = (self.const_int(lo, scope), self.const_int(hi, scope))
                else {
                    return Ty::Error;
                };
                if l > h || !fits(p, l) || !fits(p, h) {
                    self.error(
                        file,
                        *span,
                        format!("`{l}..{h}` is not a subrange of `{}`", p.name()),
                    );
                    return Ty::Error;
                }
                Ty::Sub(p, l, h)
            }
            TypeRef::Ref { kind, to, .. } => {
                if let Some(to) = self.referenced_while_busy(to) {
                    return Ty::Ref(*kind, Rc::new(to));
                }
                match self.resolve_type_ref(to, scope) {
                    Ty::Error => Ty::Error,
                    to => Ty::Ref(*kind, Rc::new(to)),
                }
            }
        }
    }

    /// The STRUCT or FUNCTION_BLOCK a reference type points to while that type's own
    /// declaration is being read (`next : POINTER TO Node` inside `Node`), or the
    /// FUNCTION_BLOCK it points to before that block's declaration is read (`owner : POINTER
    /// TO Component` in a block that `Component` holds, Tc3_Component's pattern): a reference
    /// does not contain what it points to, so it may point to its own type or to a block that
    /// contains it. Reading the block's declaration here would find the block being read
    /// inside it and refuse it as containing itself; a reference needs only the block's
    /// identity, and its variables are known before any body is checked.
    fn referenced_while_busy(&self, to: &TypeRef) -> Option<Ty> {
        let TypeRef::Named(id) = to else { return None };
        if let Some(&t) = self.type_names.get(&key(&id.name)) {
            let entry = &self.type_decls[t];
            return (entry.state == State::Busy && matches!(entry.ty, Ty::Struct(_)))
                .then(|| entry.ty.clone());
        }
        let &p = self.pou_names.get(&key(&id.name))?;
        let pou = &self.pous[p];
        (pou.kind == PouKind::FunctionBlock && pou.state != State::Done).then_some(Ty::Fb(p))
    }

    fn make_enum(
        &mut self,
        name: String,
        def: &ast::EnumDef,
        init: Option<&ast::Ident>,
        scope: Scope,
    ) -> Ty {
        let file = scope.file;
        if !def.args.is_empty() {
            // `INT (5, 6)`: only a function block's declaration takes such arguments
            let msg = "an enumeration's values are names (`INT (A, B := 5)`); arguments that are not names go to a function block's FB_init only (`fb : T(5, 'A')`)";
            self.error(file, def.span, msg);
            return Ty::Error;
        }
        let (base, declared) = match &def.base {
            Some(b) => match Prim::from_name(&b.name).filter(|p| p.is_integral()) {
                Some(p) => (p, true),
                None => {
                    self.error(
                        file,
                        b.span,
                        format!("an enumeration's base must be an integer type, not `{}`", b.name),
                    );
                    (Prim::DInt, false)
                }
            },
            None => (Prim::DInt, false),
        };
        let mut values: Vec<(String, i128)> = Vec::new();
        let mut next = 0i128;
        for (id, v) in &def.values {
            let value = match v {
                Some(e) => self.const_int(e, scope).unwrap_or(next),
                None => next,
            };
            if values.iter().any(|(n, _)| n.eq_ignore_ascii_case(&id.name)) {
                self.error(
                    file,
                    id.span,
                    format!("`{}` is already a value of this enumeration", id.name),
                );
                continue;
            }
            if !fits(base, value) {
                self.error(
                    file,
                    id.span,
                    format!("constant `{value}` does not fit `{}`", base.name()),
                );
            }
            values.push((id.name.clone(), value));
            next = value + 1;
        }
        let mut initial = values.first().map_or(0, |v| v.1);
        if let Some(init) = init {
            match values.iter().find(|(n, _)| init.is(n)) {
                Some(v) => initial = v.1,
                None => {
                    self.error(file, init.span, format!("`{name}` has no value `{}`", init.name))
                }
            }
        }
        let index = self.types.enums.len();
        for (n, v) in &values {
            self.enum_values.entry(key(n)).or_default().push((index, *v));
        }
        self.types.enums.push(EnumTy {
            name,
            base,
            values,
            init: initial,
            declared_base: declared,
        });
        Ty::Enum(index)
    }

    pub fn resolve_type_decl(&mut self, t: usize) -> Ty {
        let entry = &self.type_decls[t];
        let (decl, file) = (entry.decl, entry.file);
        match entry.state {
            State::Done => return entry.ty.clone(),
            State::Busy => {
                self.error(
                    file,
                    decl.name.span,
                    format!("type `{}` is defined in terms of itself", decl.name.name),
                );
                return Ty::Error;
            }
            State::Todo => {}
        }
        self.type_decls[t].state = State::Busy;
        let scope = self.global_scope(file);
        let mut image = None;
        let ty = match &decl.def {
            TypeDef::Alias { ty, init } => {
                let resolved = self.resolve_type_ref(ty, scope);
                if let Some(init) = init {
                    if !resolved.is_error() {
                        image = Some(self.init_image(
                            &resolved,
                            Some(ty),
                            Some(init),
                            scope,
                            &decl.name.name,
                        ));
                    }
                }
                resolved
            }
            TypeDef::Struct { members } => {
                // its index first, for the references to it among its members
                let index = self.types.structs.len();
                self.types.structs.push(StructTy {
                    name: decl.name.name.clone(),
                    members: Vec::new(),
                    size: 0,
                    image: Vec::new(),
                    union: false,
                });
                self.type_decls[t].ty = Ty::Struct(index);
                let mut out: Vec<Member> = Vec::new();
                let mut img = Vec::new();
                // a copy made for a variable whose members a binding places (`fb_config.rs`)
                let copy = decl.name.name.contains('$');
                for m in members {
                    let mty = self.member_type(&m.ty, scope);
                    let partial = m.location.as_ref().is_some_and(is_partial);
                    let mut device = None;
                    match &m.location {
                        Some(loc) if !partial && !copy => {
                            let msg = "a STRUCT member's address is partly specified (`AT %I*`, \
                                       `%Q*`, `%M*`): VAR_CONFIG or [iec.variables] binds it \
                                       for each variable";
                            self.error(file, loc.span, msg);
                        }
                        Some(loc) if !partial => {
                            let name = m.names.first().map_or("", |n| n.name.as_str());
                            if let Some((storage, _)) = self.locate(file, loc, &mty, name) {
                                // at RUN start, as any located variable's
                                let init = m.init.as_ref();
                                self.located_init_for(storage, &mty, &m.ty, init, scope, name);
                                device = Some(storage);
                            }
                        }
                        _ => {}
                    }
                    for id in &m.names {
                        if out.iter().any(|x| id.is(&x.name)) {
                            self.error(
                                file,
                                id.span,
                                format!("`{}` is already declared in this STRUCT", id.name),
                            );
                            continue;
                        }
                        let bytes =
                            self.init_image(&mty, Some(&m.ty), m.init.as_ref(), scope, &id.name);
                        out.push(Member {
                            name: id.name.clone(),
                            ty: mty.clone(),
                            offset: img.len() as u32,
                            partial: partial || device.is_some(),
                            device,
                        });
                        img.extend_from_slice(&bytes);
                    }
                }
                // a copy is named as its type in messages (`fb_config.rs` names it after the
                // variable too, for its declaration alone)
                let name = decl.name.name.split('$').next().unwrap_or_default().to_string();
                self.types.structs[index] = StructTy {
                    name,
                    members: out,
                    size: img.len() as u32,
                    image: img,
                    union: false,
                };
                Ty::Struct(index)
            }
            TypeDef::Union { members } => self.union_type(t, decl, members, scope),
            TypeDef::Enum { def, init } => {
                self.make_enum(decl.name.name.clone(), def, init.as_ref(), scope)
            }
        };
        let entry = &mut self.type_decls[t];
        entry.state = State::Done;
        entry.ty = ty.clone();
        entry.image = image;
        ty
    }

    /// The STRUCT type the struct `s` is a copy of, when a binding of its variable's members
    /// made it (`fb_config.rs` names it `Type$instance.variable`).
    pub(super) fn struct_copy_of(&self, s: usize) -> Option<Ty> {
        let entry = self.type_decls.iter().find(|t| t.ty == Ty::Struct(s))?;
        let (original, _) = entry.decl.name.name.split_once('$')?;
        let &t = self.type_names.get(&key(original))?;
        Some(self.type_decls[t].ty.clone())
    }

    /// The STRUCT type and the member of it at a partly specified address that `ty` holds: a
    /// member of its own, or of a struct or an array element inside it.
    fn partly_located(&self, ty: &Ty) -> Option<(String, String)> {
        match ty {
            Ty::Struct(s) => {
                let st = &self.types.structs[*s];
                match st.members.iter().find(|m| m.partial) {
                    Some(m) => Some((st.name.clone(), m.name.clone())),
                    None => st.members.iter().find_map(|m| self.partly_located(&m.ty)),
                }
            }
            Ty::Array(a) => self.partly_located(&a.of),
            _ => None,
        }
    }

    /// Refuses a VAR_INPUT, VAR_IN_OUT or VAR_TEMP of a STRUCT type with members at partly
    /// specified addresses, as IEC 61131-3 ed3 does: only a variable of an instance's own has
    /// members a configuration binds.
    fn refuse_partly_located(&mut self, ty: &Ty, kind: VarKind, file: usize, decl: &ast::VarDecl) {
        let block = match kind {
            VarKind::Input => "VAR_INPUT",
            VarKind::InOut => "VAR_IN_OUT",
            VarKind::Temp => "VAR_TEMP",
            _ => return,
        };
        let Some((st, m)) = self.partly_located(ty) else { return };
        let msg = format!(
            "`{st}` has its member `{m}` at a partly specified address: a {block} cannot be of \
             it (IEC 61131-3): declare the variable in VAR or VAR_OUTPUT"
        );
        let span = decl.names.first().map_or(decl.span, |n| n.span);
        self.error(file, span, msg);
    }

    /// The default value of a type as bytes (a declared alias's own initial value included).
    pub fn default_image(&self, ty: &Ty, tr: Option<&TypeRef>) -> Vec<u8> {
        if let Some(TypeRef::Named(id)) = tr {
            if let Some(&t) = self.type_names.get(&key(&id.name)) {
                if let Some(img) = &self.type_decls[t].image {
                    return img.clone();
                }
            }
        }
        match ty {
            Ty::Sub(p, lo, hi) if !(*lo..=*hi).contains(&0) => {
                slot_bytes(super::types::int_slot(*p, *lo), p.elem().size())
            }
            Ty::Enum(i) => {
                let e = &self.types.enums[*i];
                slot_bytes(super::types::int_slot(e.base, e.init), e.base.elem().size())
            }
            Ty::Array(a) => {
                let one = self.default_image(&a.of, None);
                let mut out = Vec::with_capacity(one.len() * a.count() as usize);
                for _ in 0..a.count() {
                    out.extend_from_slice(&one);
                }
                out
            }
            Ty::Struct(i) => self.types.structs[*i].image.clone(),
            Ty::Fb(p) => self.pous[*p].image.clone(),
            _ => vec![0; self.types.size(ty) as usize],
        }
    }

    /// The image of a value of `ty` with its initializer.
    pub fn init_image(
        &mut self,
        ty: &Ty,
        tr: Option<&TypeRef>,
        init: Option<&Init>,
        scope: Scope,
        what: &str,
    ) -> Vec<u8> {
        let mut img = self.default_image(ty, tr);
        if let Some(init) = init {
            self.write_init(&mut img, 0, ty, init, scope, what);
        }
        img
    }

    fn write_init(
        &mut self,
        img: &mut [u8],
        at: usize,
        ty: &Ty,
        init: &Init,
        scope: Scope,
        what: &str,
    ) {
        let file = scope.file;
        match (init, ty) {
            (_, Ty::Error) => {}
            (Init::Expr(e), _) if !matches!(ty, Ty::Array(_) | Ty::Struct(_) | Ty::Fb(_)) => {
                if let Some(bytes) = self.const_bytes(e, ty, scope, what) {
                    img[at..at + bytes.len()].copy_from_slice(&bytes);
                }
            }
            (Init::Array { elems, span }, Ty::Array(a)) => {
                let size = a.elem_size as usize;
                let count = a.count() as usize;
                let mut i = 0usize;
                let mut over = false;
                for el in elems {
                    let (n, value) = match el {
                        ArrayInit::One(v) => (1, Some(v)),
                        ArrayInit::Repeat { count, value } => {
                            let n = self.const_int(count, scope).unwrap_or(0).max(0) as usize;
                            (n, value.as_ref())
                        }
                    };
                    let one = match value {
                        Some(v) => {
                            let mut one = self.default_image(&a.of, None);
                            self.write_init(&mut one, 0, &a.of, v, scope, what);
                            one
                        }
                        None => self.default_image(&a.of, None),
                    };
                    for _ in 0..n {
                        if i >= count {
                            over = true;
                            break;
                        }
                        img[at + i * size..at + (i + 1) * size].copy_from_slice(&one);
                        i += 1;
                    }
                }
                if over {
                    self.error(
                        file,
                        *span,
                        format!("too many initial values for `{what}` ({count} elements)"),
                    );
                }
            }
            (Init::Struct { members, .. }, Ty::Struct(s)) => {
                if self.types.structs[*s].union && members.len() > 1 {
                    let span = members[1].0.span;
                    self.error(file, span, "a UNION's initial value gives one member only");
                }
                for (id, v) in members {
                    let found =
                        self.types.structs[*s].members.iter().find(|m| id.is(&m.name)).cloned();
                    match found {
                        // the lowering moved the variable's own initializer of a bound member
                        // to the member (`fb_config.rs`); one from around the variable would
                        // go to its unused bytes
                        Some(m) if m.device.is_some() => {
                            let msg = format!(
                                "`{what}.{}` is bound to a device (VAR_CONFIG, [iec.variables]): \
                                 give its initial value in its binding or in the declaration of \
                                 `{what}`",
                                m.name
                            );
                            self.error(file, id.span, msg);
                        }
                        Some(m) => {
                            self.write_init(img, at + m.offset as usize, &m.ty, v, scope, &m.name)
                        }
                        None => {
                            let n = self.types.structs[*s].name.clone();
                            let names: Vec<String> = self.types.structs[*s]
                                .members
                                .iter()
                                .map(|m| m.name.clone())
                                .collect();
                            let hint = suggest(&id.name, names.iter().map(String::as_str));
                            self.error(
                                file,
                                id.span,
                                format!("`{n}` has no member `{}`{hint}", id.name),
                            );
                        }
                    }
                }
            }
            (Init::Struct { members, .. }, Ty::Fb(p)) => {
                for (id, v) in members {
                    let found =
                        self.pous[*p].lookup(&id.name).map(|i| self.pous[*p].vars[i].clone());
                    match found {
                        Some(VarInfo {
                            storage: Storage::Inst(off),
                            ty,
                            by_ref: false,
                            kind,
                            ..
                        }) if kind != VarKind::External => {
                            self.write_init(img, at + off as usize, &ty, v, scope, &id.name)
                        }
                        _ => {
                            let n = self.pous[*p].name.clone();
                            self.error(
                                file,
                                id.span,
                                format!("`{n}` has no variable `{}` to initialize", id.name),
                            );
                        }
                    }
                }
            }
            (Init::Expr(e), _) => {
                let n = self.ty_name(ty);
                self.error(
                    file,
                    e.span,
                    format!("`{what}` is `{n}`: its initial value must be written `[…]` or `(…)`"),
                );
            }
            (Init::Array { span, .. } | Init::Struct { span, .. }, _) => {
                let n = self.ty_name(ty);
                self.error(file, *span, format!("this initial value does not fit `{n}`"));
            }
        }
    }

    /// A scalar or string constant of `ty` as its bytes.
    fn const_bytes(&mut self, e: &ast::Expr, ty: &Ty, scope: Scope, what: &str) -> Option<Vec<u8>> {
        let te = self.check_given(e, scope, ty);
        let te = self.coerce(te, ty, scope.file);
        if te.ty.is_error() {
            return None;
        }
        match (&te.k, ty) {
            (super::expr::TK::Const(Cv::WStr(s)), Ty::WStr(n)) => {
                // the code units, then NULs (2 bytes each, little-endian as CODESYS stores them)
                let mut b = vec![0u8; 2 * (*n as usize + 1)];
                for (at, unit) in b.chunks_exact_mut(2).zip(s.iter().take(*n as usize)) {
                    at.copy_from_slice(&unit.to_le_bytes());
                }
                Some(b)
            }
            (super::expr::TK::Const(Cv::Str(s)), Ty::Str(n)) => {
                // the characters, then NULs (a STRING is stored as CODESYS stores it)
                let mut b = vec![0u8; *n as usize + 1];
                let len = s.len().min(*n as usize);
                b[..len].copy_from_slice(&s[..len]);
                Some(b)
            }
            (super::expr::TK::Const(cv), _) => {
                let p = ty.prim(&self.types)?;
                Some(slot_bytes(super::expr::cv_slot(cv, p), p.elem().size()))
            }
            _ => {
                self.error(
                    scope.file,
                    e.span,
                    format!("the initial value of `{what}` must be a constant expression"),
                );
                None
            }
        }
    }

    /// The constant value of a scalar initializer, for CONSTANT variables.
    fn const_value(&mut self, init: Option<&Init>, ty: &Ty, scope: Scope) -> Option<Cv> {
        let Some(Init::Expr(e)) = init else {
            return match ty {
                Ty::Prim(_) | Ty::Sub(..) => Some(Cv::Int(0)).map(|c| match ty.prim(&self.types) {
                    Some(p) if p.is_real() => Cv::Real(0.0),
                    _ => c,
                }),
                Ty::Enum(i) => Some(Cv::Int(self.types.enums[*i].init)),
                _ => None,
            };
        };
        let saved = self.diags.len();
        let te = self.check_given(e, scope, ty);
        let te = self.coerce(te, ty, scope.file);
        self.diags.truncate(saved);
        match te.k {
            super::expr::TK::Const(c) => Some(c),
            _ => None,
        }
    }

    fn resolve_globals(&mut self, file: usize, block: &'a ast::VarBlock) {
        let scope = self.global_scope(file);
        for decl in &block.decls {
            let ty = self.resolve_type_ref(&decl.ty, scope);
            self.check_instantiable(&ty, file, decl.span);
            for id in &decl.names {
                self.reserved(file, id);
                if let Some(&g) = self.global_names.get(&key(&id.name)) {
                    let first = self.globals[g].span;
                    self.error(
                        file,
                        id.span,
                        format!("`{}` is already declared (line {})", id.name, first.line),
                    );
                    continue;
                }
                let mut located = None;
                let storage = match decl.location.as_ref().filter(|l| !is_partial(l)) {
                    Some(loc) => match self.locate(file, loc, &ty, &id.name) {
                        Some((s, a)) => {
                            located = Some(a);
                            self.located_init_for(
                                s,
                                &ty,
                                &decl.ty,
                                decl.init.as_ref(),
                                scope,
                                &id.name,
                            );
                            s
                        }
                        None => Storage::Global(0),
                    },
                    None => {
                        let img = self.init_image(
                            &ty,
                            Some(&decl.ty),
                            decl.init.as_ref(),
                            scope,
                            &id.name,
                        );
                        let at = self.alloc_var(&img, file, id.span);
                        if block.retain {
                            self.retained.push((at, img.len() as u32));
                        }
                        if block.persistent {
                            self.persistent.push((at, img.len() as u32));
                        }
                        Storage::Global(at)
                    }
                };
                let value = if block.constant {
                    self.const_value(decl.init.as_ref(), &ty, scope)
                } else {
                    None
                };
                self.global_names.insert(key(&id.name), self.globals.len());
                self.globals.push(VarInfo {
                    name: id.name.clone(),
                    kind: VarKind::Global,
                    ty: ty.clone(),
                    constant: block.constant,
                    retain: block.retain,
                    persistent: block.persistent,
                    storage,
                    by_ref: false,
                    value,
                    span: id.span,
                    located,
                    global: None,
                    edge_value: None,
                });
            }
        }
    }

    /// Registers `action` of POU `owner`: a POU of its own that shares the owner's variables
    /// (compiled as a function block's body, called with the owner's instance).
    fn add_action(&mut self, file: usize, owner: usize, action: &'a ast::Action) {
        let (owner_ast, owner_name) = (self.pous[owner].ast, self.pous[owner].name.clone());
        if owner_ast.kind == PouKind::Function {
            let msg = format!(
                "`{owner_name}` is a FUNCTION: only a PROGRAM or a FUNCTION_BLOCK has actions"
            );
            self.error(file, action.span, msg);
            return;
        }
        let k = action_key(&owner_name, &action.name.name);
        if let Some(&first) = self.pou_names.get(&k) {
            let at = self.pous[first].name_span();
            let first = self.first_at(self.pous[first].file, at, file);
            self.error(
                file,
                action.name.span,
                format!("`{}` is already declared ({first})", action.name.name),
            );
            return;
        }
        if owner_ast
            .vars
            .iter()
            .flat_map(|b| &b.decls)
            .flat_map(|d| &d.names)
            .any(|n| n.is(&action.name.name))
        {
            self.error(
                file,
                action.name.span,
                format!(
                    "`{}` is already declared (line {})",
                    action.name.name, owner_ast.span.line
                ),
            );
            return;
        }
        self.pou_names.insert(k, self.pous.len());
        let mut info = PouInfo::new(owner_ast, file);
        info.name = format!("{owner_name}.{}", action.name.name);
        info.kind = PouKind::FunctionBlock;
        info.action = Some((action, owner));
        self.pous.push(info);
    }

    /// Resolves a POU's interface (its variables, their layout and images).
    pub fn resolve_pou(&mut self, p: usize) {
        if self.pous[p].state != State::Todo {
            return;
        }
        if let Some((_, owner)) = self.pous[p].action {
            // the owner's variables, at the owner's offsets
            self.resolve_pou(owner);
            let o = &self.pous[owner];
            let (vars, names, size) = (o.vars.clone(), o.names.clone(), o.inst_size);
            let (image, frame_vars, frame_image) =
                (o.image.clone(), o.frame_vars, o.frame_image.clone());
            let a = &mut self.pous[p];
            (a.vars, a.names, a.inst_size, a.image) = (vars, names, size, image);
            (a.frame_vars, a.frame_image) = (frame_vars, frame_image);
            a.state = State::Done;
            self.types.fbs[p] = Some((a.name.clone(), a.inst_size));
            return;
        }
        if let Some(owner) = self.pous[p].method {
            self.resolve_pou(owner);
        }
        self.pous[p].state = State::Busy;
        let pou: &'a ast::Pou = self.pous[p].ast;
        let file = self.pous[p].file;
        let kind = pou.kind;
        let mut scope = Scope { pou: Some(p), visible: 0, file };
        let mut inst: Vec<u8> = Vec::new();
        let mut frame: Vec<u8> = Vec::new();
        // EXTENDS: the base's variables first (`oop`); a type tag first in a hierarchy
        if kind == PouKind::FunctionBlock {
            self.inherit(p, &mut inst);
            scope.visible = self.pous[p].vars.len();
        }
        let member = self.oop.members.get(&p).map(|m| m.role);
        if kind == PouKind::Function {
            let result = match &pou.return_type {
                Some(tr) => self.resolve_type_ref(tr, scope),
                None => Ty::Void,
            };
            if matches!(result, Ty::Fb(_)) {
                self.habit(crate::st::dialect::Habit::InstanceResult, file, pou.name.span);
            }
            frame = self.default_image(&result, pou.return_type.as_ref());
            self.pous[p].result = result;
        }
        // A POU's constants first, wherever they are written: declarations use them
        // (`ARRAY [0..n] OF …` above a `VAR CONSTANT n`, as OSCAT writes it).
        let (constants, others): (Vec<_>, Vec<_>) =
            pou.vars.iter().partition(|b| b.constant && b.kind == VarKind::Local);
        let mut blocks: Vec<&ast::VarBlock> = constants.into_iter().chain(others).collect();
        if member.is_some() {
            // A method's parameters first in its frame: its overrides' are then at the same
            // offsets, whatever their locals, for a call that dispatches on the instance.
            blocks.sort_by_key(|b| {
                !matches!(b.kind, VarKind::Input | VarKind::InOut | VarKind::Output)
            });
        }
        // a method's implicit ENO, right after its parameters (compile/method_eno.rs)
        let mut method_eno = self.wants_method_eno(member, pou);
        for block in blocks {
            if method_eno && !super::method_eno::is_parameter_block(block.kind) {
                self.declare_method_eno(p, &mut frame, pou.name.span);
                method_eno = false;
            }
            if block.kind == VarKind::Global {
                self.error(file, block.span, "VAR_GLOBAL belongs outside the POUs: declare globals at the top level of a file");
                continue;
            }
            let remanent = if block.persistent { "PERSISTENT" } else { "RETAIN" };
            if block.persistent && member == Some(super::oop::Role::Method) {
                // A method's variables live in its frame, for one call, as a FUNCTION's
                // (TwinCAT and CODESYS keep nothing of them either)
                self.error(file, block.span, "a METHOD's variables cannot be PERSISTENT: declare the variable in its function block's `VAR PERSISTENT`");
            } else if kind == PouKind::Function && block.retain {
                self.error(
                    file,
                    block.span,
                    format!("a FUNCTION's variables cannot be {remanent}"),
                );
            } else if block.persistent && block.kind == VarKind::Temp {
                self.error(file, block.span, "a VAR_TEMP is set at every call and cannot be PERSISTENT: declare the variable in `VAR PERSISTENT`");
            }
            if member.is_some_and(|m| m != super::oop::Role::Method)
                && block.kind == VarKind::Instance
            {
                let msg = "VAR_INST belongs to a METHOD (as in CODESYS, which allows it only in methods), not to a property's GET or SET: declare the variable in its function block";
                // read on as locals, so that its uses make no errors of their own
                self.error(file, block.span, msg);
            }
            for decl in &block.decls {
                let ty = self.var_type(&decl.ty, kind, block.kind, scope);
                if block.kind != VarKind::InOut {
                    self.check_instantiable(&ty, file, decl.span);
                }
                self.refuse_partly_located(&ty, block.kind, file, decl);
                // a method's may (CODESYS): a fresh instance at each call, as its other VARs
                if kind == PouKind::Function
                    && member.is_none()
                    && matches!(ty, Ty::Fb(_))
                    && block.kind != VarKind::InOut
                {
                    self.habit(crate::st::dialect::Habit::InstanceInFunction, file, decl.span);
                }
                for id in &decl.names {
                    self.reserved(file, id);
                    if let Some(i) = self.pous[p].lookup(&id.name) {
                        let first = self.pous[p].vars[i].span;
                        self.error(
                            file,
                            id.span,
                            format!("`{}` is already declared (line {})", id.name, first.line),
                        );
                        continue;
                    }
                    if kind == PouKind::Function
                        && super::libraries::is_own_name(id, &pou.name.name)
                        && member != Some(super::oop::Role::Set)
                    {
                        if pou.return_type.is_some() {
                            self.error(
                                file,
                                id.span,
                                format!("`{}` is the FUNCTION's own name", id.name),
                            );
                            continue;
                        }
                        // No result type, so no result variable the name would be (TcUnit's
                        // `FUNCTION TEST` declares `Test : REFERENCE TO FB_Test`): in the
                        // body the name is the variable, as in CODESYS.
                        self.habit(
                            crate::st::dialect::Habit::VariableNamedAsFunction,
                            file,
                            id.span,
                        );
                    }
                    // `EN` / `ENO` of a FUNCTION or FUNCTION_BLOCK: the standard's, declared
                    // (`Some(true)`: EN, `Some(false)`: ENO).
                    let callable = matches!(kind, PouKind::Function | PouKind::FunctionBlock);
                    let enable = match () {
                        _ if !callable => None,
                        _ if id.is("EN") => Some(true),
                        _ if id.is("ENO") => Some(false),
                        _ => None,
                    };
                    if let Some(input) = enable {
                        let want = if input { VarKind::Input } else { VarKind::Output };
                        if block.kind != want || !ty.is_bool() && !ty.is_error() {
                            let (what, block_name) = if input {
                                ("input", "VAR_INPUT")
                            } else {
                                ("output", "VAR_OUTPUT")
                            };
                            self.error(
                                file,
                                id.span,
                                format!(
                                    "`{}` is the standard's enable {what}: declare it `{} : BOOL` in {block_name}",
                                    id.name, id.name
                                ),
                            );
                            continue;
                        }
                    }
                    if let Some((edge, at)) = decl.edge {
                        let ok = kind == PouKind::FunctionBlock
                            && block.kind == VarKind::Input
                            && (ty.is_bool() || ty.is_error());
                        if !ok {
                            let e = match edge {
                                ast::Edge::Rising => "R_EDGE",
                                ast::Edge::Falling => "F_EDGE",
                            };
                            self.error(
                                file,
                                at,
                                format!("`{e}` belongs to a `BOOL` VAR_INPUT of a FUNCTION_BLOCK"),
                            );
                        }
                    }
                    let mut info = VarInfo {
                        name: id.name.clone(),
                        kind: block.kind,
                        ty: ty.clone(),
                        constant: block.constant,
                        retain: block.retain,
                        persistent: block.persistent,
                        storage: Storage::Inst(0),
                        by_ref: block.kind == VarKind::InOut,
                        value: None,
                        span: id.span,
                        located: None,
                        global: None,
                        edge_value: None,
                    };
                    if let Some(at) = self.method_var_inst(p, member, block.kind, &id.name) {
                        info.storage = at;
                    } else if block.kind == VarKind::External {
                        match self.global_names.get(&key(&id.name)).copied() {
                            Some(g) => {
                                let gv = &self.globals[g];
                                if gv.ty != ty && !ty.is_error() && !gv.ty.is_error() {
                                    let (a, b) = (self.ty_name(&ty), self.ty_name(&gv.ty));
                                    self.error(
                                        file,
                                        id.span,
                                        format!("VAR_EXTERNAL `{}` is `{a}` but the VAR_GLOBAL is `{b}`", id.name),
                                    );
                                }
                                let gv = &self.globals[g];
                                if gv.constant && !block.constant {
                                    self.error(file, id.span, format!("VAR_EXTERNAL `{}` must be CONSTANT like its VAR_GLOBAL", id.name));
                                }
                                let gv = &self.globals[g];
                                info.ty = gv.ty.clone();
                                info.storage = gv.storage;
                                info.located = gv.located;
                                info.value = gv.value.clone();
                                info.constant = gv.constant || block.constant;
                                info.global = Some(g);
                            }
                            None => {
                                let names: Vec<String> =
                                    self.globals.iter().map(|g| g.name.clone()).collect();
                                let hint = suggest(&id.name, names.iter().map(String::as_str));
                                self.error(
                                    file,
                                    id.span,
                                    format!("VAR_EXTERNAL `{}` has no VAR_GLOBAL{hint}", id.name),
                                );
                                info.ty = Ty::Error;
                            }
                        }
                    } else if let Some(loc) = decl.location.as_ref().filter(|l| !is_partial(l)) {
                        // a block's copy for one instance, which VAR_CONFIG binds
                        // (`fb_config.rs`, whose copies' names alone hold a `$`)
                        let bound_copy =
                            kind == PouKind::FunctionBlock && pou.name.name.contains('$');
                        if kind != PouKind::Program && !bound_copy {
                            self.error(
                                file,
                                loc.span,
                                "only a PROGRAM's or a VAR_GLOBAL's variables can be located",
                            );
                        } else if matches!(block.kind, VarKind::InOut | VarKind::Temp) {
                            self.error(
                                file,
                                loc.span,
                                "a VAR_IN_OUT or VAR_TEMP cannot be located",
                            );
                        } else if let Some((s, a)) = self.locate(file, loc, &ty, &id.name) {
                            info.storage = s;
                            info.located = Some(a);
                            self.located_init_for(
                                s,
                                &ty,
                                &decl.ty,
                                decl.init.as_ref(),
                                scope,
                                &id.name,
                            );
                        }
                    } else {
                        let img = if block.kind == VarKind::InOut {
                            if let Some(init) = &decl.init {
                                let sp = init_span(init, decl.span);
                                self.error(file, sp, "a VAR_IN_OUT has no initial value");
                            }
                            // the pointer (and an open array's bounds: `varlen`), bound to
                            // nothing until a call binds it (`inout`)
                            match &ty {
                                Ty::OpenArray(a) => vec![0u8; a.descriptor_size() as usize],
                                _ => super::inout::UNBOUND.to_le_bytes().to_vec(),
                            }
                        } else if enable == Some(true) && decl.init.is_none() {
                            // A declared EN is the standard's: TRUE unless given.
                            vec![1]
                        } else {
                            self.init_image(
                                &ty,
                                Some(&decl.ty),
                                decl.init.as_ref(),
                                scope,
                                &id.name,
                            )
                        };
                        let in_frame = kind == PouKind::Function || block.kind == VarKind::Temp;
                        if block.kind == VarKind::Static {
                            // One copy for the POU, in variable memory beside the globals.
                            let at = self.alloc_var(&img, file, id.span);
                            if block.retain {
                                self.retained.push((at, img.len() as u32));
                            }
                            if block.persistent {
                                self.persistent.push((at, img.len() as u32));
                            }
                            info.storage = Storage::Global(at);
                        } else if in_frame {
                            info.storage = Storage::Frame(frame.len() as u32);
                            frame.extend_from_slice(&img);
                        } else {
                            info.storage = Storage::Inst(inst.len() as u32);
                            inst.extend_from_slice(&img);
                        }
                    }
                    if block.constant {
                        match block.kind {
                            // read-only in the body; the caller gives the value
                            VarKind::Input | VarKind::InOut => {}
                            VarKind::Output => self.error(
                                file,
                                id.span,
                                "only VAR, VAR_INPUT, VAR_IN_OUT, VAR_GLOBAL and VAR_EXTERNAL can be CONSTANT",
                            ),
                            VarKind::External => {}
                            _ => info.value = self.const_value(decl.init.as_ref(), &ty, scope),
                        }
                    }
                    let index = self.pous[p].vars.len();
                    // EN is never given by position (IEC 61131-3 ed3).
                    if matches!(block.kind, VarKind::Input | VarKind::InOut) && enable.is_none() {
                        self.pous[p].positional.push(index);
                    }
                    match enable {
                        Some(true) => self.pous[p].en = Some(index),
                        Some(false) => self.pous[p].eno = Some(index),
                        None => {}
                    }
                    let edge = decl.edge.filter(|_| {
                        kind == PouKind::FunctionBlock
                            && block.kind == VarKind::Input
                            && ty.is_bool()
                            && matches!(info.storage, Storage::Inst(_))
                    });
                    self.pous[p].names.insert(key(&id.name), index);
                    self.pous[p].vars.push(info);
                    scope.visible = index + 1;
                    if let Some((edge, _)) = edge {
                        self.edge_input(p, index, edge == ast::Edge::Rising, &mut inst);
                        scope.visible = self.pous[p].vars.len();
                    }
                }
            }
        }
        if method_eno {
            self.declare_method_eno(p, &mut frame, pou.name.span);
        }
        // The implicit ENO (IEC 61131-3 ed3): a BOOL output, TRUE on entry, that the
        // body may set FALSE; there when something may read it.
        if matches!(kind, PouKind::Function | PouKind::FunctionBlock)
            && member.is_none()
            && self.pous[p].eno.is_none()
            && (self.eno_read || mentions_eno(&pou.body))
        {
            let storage = if kind == PouKind::Function {
                frame.push(1);
                Storage::Frame(frame.len() as u32 - 1)
            } else {
                inst.push(1);
                Storage::Inst(inst.len() as u32 - 1)
            };
            self.declare_implicit_eno(p, storage, pou.name.span);
        }
        self.share_instance(p);
        if inst.len() as u64 > u64::from(self.dialect.variable_memory_bytes) {
            let what = format!("an instance of `{}`", pou.name.name);
            self.memory_too_large(&what, inst.len() as u64, file, pou.name.span);
        }
        if frame.len() as u32 > MAX_FRAME {
            self.error(
                file,
                pou.name.span,
                format!(
                    "the variables of `{}` need {} bytes of frame (limit 1 MiB)",
                    pou.name.name,
                    frame.len()
                ),
            );
        }
        let info = &mut self.pous[p];
        info.inst_size = inst.len() as u32;
        // Grown by doubling: up to twice a large array's bytes, which every instance's copy
        // and the compile's peak would carry.
        inst.shrink_to_fit();
        info.image = inst;
        info.frame_vars = frame.len() as u32;
        info.frame_image = frame;
        info.state = State::Done;
        if kind == PouKind::FunctionBlock {
            self.types.fbs[p] = Some((pou.name.name.clone(), self.pous[p].inst_size));
        }
    }

    /// The memory of the edge input `input` of the FB `p` (a variable the tools see, named
    /// `__<input>_PREV`, so that an online change keeps it) and the byte the body reads.
    fn edge_input(&mut self, p: usize, input: usize, rising: bool, inst: &mut Vec<u8>) {
        let v = self.pous[p].vars[input].clone();
        // F_EDGE starts as if the input had been TRUE, so that a first call with it FALSE is an
        // edge, as the standard's F_TRIG has it (`Q := NOT CLK AND NOT M`, M FALSE).
        inst.push(u8::from(!rising));
        let memory = self.pous[p].vars.len();
        self.pous[p].vars.push(VarInfo {
            name: format!("__{}_PREV", v.name),
            kind: VarKind::Local,
            storage: Storage::Inst(inst.len() as u32 - 1),
            ..v.clone()
        });
        inst.push(0);
        let value = inst.len() as u32 - 1;
        self.pous[p].vars[input].edge_value = Some(value);
        self.pous[p].edges.push(super::ctx::EdgeInput { input, memory, value, rising });
    }

    /// The device of `AT %…` for a variable of `ty`.
    pub(super) fn locate(
        &mut self,
        file: usize,
        loc: &ast::Ident,
        ty: &Ty,
        name: &str,
    ) -> Option<(Storage, Address)> {
        let text = loc.name.as_str();
        let (addr_text, size_bits) = match iec_address(text, &self.dialect.iec) {
            Ok(Some(x)) => x,
            Ok(None) => (text.to_string(), None),
            Err(msg) => {
                self.error(file, loc.span, msg);
                return None;
            }
        };
        let addr = match Address::parse(&addr_text) {
            Ok(a) => a,
            Err(e) => {
                self.error(file, loc.span, e.to_string());
                return None;
            }
        };
        let (elem_ty, count) = match ty {
            Ty::Error => return None,
            Ty::Array(a) if a.of.prim(&self.types).is_some() => (a.of.clone(), a.count()),
            Ty::Prim(_) | Ty::Sub(..) | Ty::Enum(_) => (ty.clone(), 1),
            _ => {
                let n = self.ty_name(ty);
                self.error(
                    file,
                    loc.span,
                    format!(
                        "`{name}` is `{n}`: only elementary types and their arrays can be located"
                    ),
                );
                return None;
            }
        };
        let prim = elem_ty.prim(&self.types).expect("scalar");
        if let Some(bits) = size_bits {
            if bits != prim.bits() && !(bits == 1 && prim == Prim::Bool) {
                let (a, ty) = (sized(bits), prim.name());
                let message = if name.starts_with('%') {
                    // A variable without a name (`AT %QB2 : WORD;`) goes by its address.
                    format!(
                        "`%{text}` is {a} {bits}-bit location, `{ty}` a {}-bit type",
                        prim.bits()
                    )
                } else {
                    format!("`%{text}` is {a} {bits}-bit location, `{name}` is `{ty}`")
                };
                self.error(file, loc.span, message);
                return None;
            }
        }
        if size_bits == Some(8) && addr.bit.is_some() {
            return self.locate_byte(file, loc, addr, count, name);
        }
        if prim == Prim::Bool && count == 1 {
            return match addr.as_bit() {
                Ok(b) => Some((Storage::Bit(b), addr)),
                Err(e) => {
                    self.error(file, loc.span, e.to_string());
                    None
                }
            };
        }
        if prim == Prim::Bool {
            // An ARRAY OF BOOL at a bit device: consecutive bits (`AT %P0050`: P0050, P0051, …,
            // P005F, P0060, …). Like a BOOL, never at a word device.
            let first = match addr.as_bit() {
                Ok(b) => b,
                Err(e) => {
                    self.error(file, loc.span, e.to_string());
                    return None;
                }
            };
            {
                let bit = u64::from(first.word) * 16 + u64::from(first.mask.trailing_zeros());
                let last = bit + count - 1;
                let last_address = Address {
                    number: addr.number + (last / 16 - bit / 16) as u32,
                    bit: Some((last % 16) as u8),
                    ..addr
                };
                if Address::parse(&last_address.to_string())
                    .ok()
                    .and_then(|a| a.as_bit().ok())
                    .is_none()
                {
                    self.error(
                        file,
                        loc.span,
                        format!(
                            "`{name}` needs {count} bits from `{addr}`: past the end of its area"
                        ),
                    );
                    return None;
                }
                return Some((Storage::Bit(first), addr));
            }
        }
        let word = match addr.as_word() {
            Ok(w) => w,
            Err(e) => {
                self.error(file, loc.span, e.to_string());
                return None;
            }
        };
        let words = u64::from(prim.elem().words()) * count;
        if words > 1 {
            let last = Address { number: addr.number + words as u32 - 1, ..addr };
            let ok = Address::parse(&last.to_string()).ok().and_then(|a| a.as_word().ok());
            if ok.is_none_or(|w| u64::from(w.0) != u64::from(word.0) + words - 1) {
                self.error(
                    file,
                    loc.span,
                    format!("`{name}` needs {words} words from `{addr}`: past the end of its area"),
                );
                return None;
            }
        }
        Some((Storage::Word(word.0), addr))
    }

    /// The device bytes of an 8-bit variable (or an array of them) at an IEC byte address of
    /// a byte image: `first` is the byte's first bit ([`crate::device::iec::Direct`]), and the
    /// located [`Address`] is the word that holds it (whose area says whether it is writable).
    fn locate_byte(
        &mut self,
        file: usize,
        loc: &ast::Ident,
        first: Address,
        count: u64,
        name: &str,
    ) -> Option<(Storage, Address)> {
        let bit = match first.as_bit() {
            Ok(b) => b,
            Err(e) => {
                self.error(file, loc.span, e.to_string());
                return None;
            }
        };
        let word = Address { bit: None, ..first };
        let byte = u32::from(bit.word) * 2 + bit.mask.trailing_zeros() / 8;
        let last_word = (u64::from(byte) + count - 1) / 2;
        let last =
            Address { number: word.number + (last_word - u64::from(bit.word)) as u32, ..word };
        let ok = Address::parse(&last.to_string()).ok().and_then(|a| a.as_word().ok());
        if ok.is_none_or(|l| u64::from(l.0) != last_word) {
            self.error(
                file,
                loc.span,
                format!(
                    "`{name}` needs {count} bytes from `%{}`: past the end of its area",
                    loc.name
                ),
            );
            return None;
        }
        Some((Storage::Byte(byte), word))
    }

    pub(super) fn located_init_for(
        &mut self,
        s: Storage,
        ty: &Ty,
        tr: &TypeRef,
        init: Option<&Init>,
        scope: Scope,
        what: &str,
    ) {
        let Some(init) = init else { return };
        let img = self.init_image(ty, Some(tr), Some(init), scope, what);
        let (elem_ty, count) = match ty {
            Ty::Array(a) => (a.of.clone(), a.count()),
            _ => (ty.clone(), 1),
        };
        let Some(p) = elem_ty.prim(&self.types) else { return };
        let e = p.elem();
        let size = e.size() as usize;
        for i in 0..count as usize {
            let mut raw = [0u8; 8];
            raw[..size].copy_from_slice(&img[i * size..(i + 1) * size]);
            let mut slot = u64::from_le_bytes(raw);
            if e.is_signed() && size < 8 {
                let shift = 64 - size * 8;
                slot = (((slot << shift) as i64) >> shift) as u64;
            }
            let place = match s {
                Storage::Bit(b) => {
                    let bit = u32::from(b.word) * 16 + b.mask.trailing_zeros() + i as u32;
                    Place::Bit(BitRef { word: (bit / 16) as u16, mask: 1 << (bit % 16) })
                }
                Storage::Word(w) => {
                    Place::Word(crate::device::WordRef(w + (i as u32 * e.words()) as u16))
                }
                Storage::Byte(n) => Place::Byte(n + i as u32),
                _ => return,
            };
            self.located_init.push((place, e, slot));
        }
    }

    /// Whether a program may write the device of a located variable.
    pub fn writable(&self, addr: &Address, ty: &Ty) -> bool {
        let bit = ty.is_bool() && addr.as_bit().is_ok();
        addr.writable_by(if bit { Writer::ProgramBit } else { Writer::ProgramWord })
    }
}

/// Whether a body names `ENO` (reads or writes its own ENO).
pub(super) fn mentions_eno(body: &[ast::Stmt]) -> bool {
    let mut found = false;
    walk_stmts(body, &mut |e| {
        found |= matches!(&e.kind, ast::ExprKind::Name(id) if id.is("ENO"));
    });
    found
}

/// Whether a file may read an `ENO` from outside a POU: `ENO => v` in a call, or `x.ENO`.
pub fn reads_eno(file: &ast::File) -> bool {
    let mut found = false;
    for item in &file.items {
        if let Item::Pou(p) = item {
            walk_stmts(&p.body, &mut |e| {
                found |= match &e.kind {
                    ast::ExprKind::Member(_, id) => id.is("ENO"),
                    ast::ExprKind::Call { args, .. } => args
                        .iter()
                        .any(|a| matches!(a, ast::Arg::Output { name, .. } if name.is("ENO"))),
                    _ => false,
                };
            });
        }
    }
    found
}

/// Every expression of the statements, nested ones included.
fn walk_stmts(body: &[ast::Stmt], f: &mut impl FnMut(&ast::Expr)) {
    use ast::StmtKind as S;
    for s in body {
        match &s.kind {
            S::Assign { target, value } | S::RefAssign { target, value } => {
                walk_expr(target, f);
                walk_expr(value, f);
            }
            S::Call(e) => walk_expr(e, f),
            S::If { branches, otherwise } => {
                for (c, b) in branches {
                    walk_expr(c, f);
                    walk_stmts(b, f);
                }
                if let Some((_, b)) = otherwise {
                    walk_stmts(b, f);
                }
            }
            S::Case { selector, arms, otherwise } => {
                walk_expr(selector, f);
                for arm in arms {
                    walk_stmts(&arm.body, f);
                }
                if let Some((_, b)) = otherwise {
                    walk_stmts(b, f);
                }
            }
            S::For { var, from, to, by, body } => {
                walk_expr(var, f);
                walk_expr(from, f);
                walk_expr(to, f);
                if let Some(b) = by {
                    walk_expr(b, f);
                }
                walk_stmts(body, f);
            }
            S::While { cond, body } | S::Repeat { body, until: cond } => {
                walk_expr(cond, f);
                walk_stmts(body, f);
            }
            S::Exit | S::Continue | S::Return | S::Empty | S::Label(_) | S::Jump(_) => {}
        }
    }
}

/// Calls `f` on `e` and on every expression inside it, outer first.
pub(super) fn walk_expr(e: &ast::Expr, f: &mut impl FnMut(&ast::Expr)) {
    use ast::ExprKind as K;
    f(e);
    match &e.kind {
        K::Literal(_) | K::Name(_) => {}
        K::Member(b, _) | K::Bit(b, _) | K::Part(b, ..) | K::Unary(_, b) | K::Deref(b) => {
            walk_expr(b, f)
        }
        K::Index(b, ix) => {
            walk_expr(b, f);
            for i in ix {
                walk_expr(i, f);
            }
        }
        K::Binary(_, a, b) | K::Assign(a, b) => {
            walk_expr(a, f);
            walk_expr(b, f);
        }
        K::Call { callee, args } => {
            walk_expr(callee, f);
            for a in args {
                match a {
                    ast::Arg::Positional(v) | ast::Arg::Input { value: v, .. } => walk_expr(v, f),
                    ast::Arg::Output { target, .. } => walk_expr(target, f),
                }
            }
        }
    }
}

fn init_span(init: &Init, or: Span) -> Span {
    match init {
        Init::Expr(e) => e.span,
        Init::Array { span, .. } | Init::Struct { span, .. } => *span,
    }
    .max(or)
}

/// The first `size` bytes of a slot, little-endian.
pub fn slot_bytes(slot: u64, size: u32) -> Vec<u8> {
    slot.to_le_bytes()[..size as usize].to_vec()
}

/// Whether a location is partly specified (`%I*`, `%QX*`): the variable is then kept in
/// variable memory, as an unlocated one (docs/ST.md, Located variables).
fn is_partial(loc: &ast::Ident) -> bool {
    loc.name.ends_with('*')
}

/// An IEC direct address (`IX0.3`, `QW5`, `MD10`) as the plcd device address `layout` maps
/// it onto (`[iec]`, [`IecLayout::resolve`]) and its size in bits; `Ok(None)` for a plcd
/// device address (`P0040`, `D00100`), which means itself whatever the layout.
pub fn iec_address(
    text: &str,
    layout: &IecLayout,
) -> Result<Option<(String, Option<u32>)>, String> {
    Ok(layout.resolve(text)?.map(|d| (d.address.to_string(), Some(d.bits))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::iec::Preset;

    #[test]
    fn iec_addresses_follow_the_layout() {
        let plcd = IecLayout::of(Preset::Plcd);
        assert_eq!(iec_address("IX0.3", &plcd).unwrap(), Some(("P0003".into(), Some(1))));
        assert_eq!(iec_address("QX12.15", &plcd).unwrap(), Some(("P012F".into(), Some(1))));
        assert_eq!(iec_address("IW5", &plcd).unwrap(), Some(("P005".into(), Some(16))));
        assert_eq!(iec_address("MD10", &plcd).unwrap(), Some(("M010".into(), Some(32))));
        assert!(iec_address("IX0.16", &plcd).is_err());
        let openplc = IecLayout::of(Preset::OpenPlc);
        assert_eq!(iec_address("QX0.0", &openplc).unwrap(), Some(("P0640".into(), Some(1))));
        for layout in [plcd, openplc] {
            assert_eq!(iec_address("D00100", &layout).unwrap(), None);
            assert_eq!(iec_address("M0010", &layout).unwrap(), None);
            // No size prefix is a bit (IEC 61131-3; IEC's Annex F writes `%I0.0`): `%I` and
            // `%Q` always (plcd has no such devices), `%M` with the bit level only.
            for (bare, sized) in [("I0.3", "IX0.3"), ("q12.7", "QX12.7"), ("M1.2", "MX1.2")] {
                assert_eq!(iec_address(bare, &layout), iec_address(sized, &layout), "{bare}");
                assert!(iec_address(bare, &layout).unwrap().is_some(), "{bare}");
            }
            assert_eq!(iec_address("I*", &layout).unwrap(), None);
        }
    }
}
