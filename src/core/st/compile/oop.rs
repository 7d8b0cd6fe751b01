//! Object orientation (IEC 61131-3 ed. 3, as CODESYS and TwinCAT write it): the METHODs and
//! PROPERTYs of function blocks (and programs), `EXTENDS`, `THIS` and `SUPER`, `ABSTRACT` and
//! `FINAL`, `INTERFACE`s (`IMPLEMENTS` checked, variables of an interface type, calls through
//! them).
//!
//! - A method is a POU of its own ([`PouInfo::method`](super::ctx::PouInfo::method) names its
//!   function block). Its own variables are in its frame, as a FUNCTION's, fresh at each call;
//!   its function block's variables are reached through `this`. It is called with `CallFb` on
//!   the instance, its arguments stored in its frame as a FUNCTION's are. A property's GET and
//!   SET are two such methods: GET returns the value in the property's name, SET receives it
//!   in a VAR_INPUT of that name.
//! - `EXTENDS`: a derived instance starts with its base's variables, at the base's offsets (the
//!   base's image, then its own variables), so that code compiled for the base (its body, its
//!   methods) runs on a derived instance as it is.
//! - Dynamic dispatch, without ops of its own: plcd compiles the whole project at once, so the
//!   function blocks that may be behind a place of a function block type are known. Every
//!   function block of a hierarchy (one that EXTENDS, is extended or IMPLEMENTS) carries a
//!   hidden type tag, a UDINT at offset 0 of its instance that its initial image writes: a hash
//!   of its name, the same from one compile to the next, so that RETAIN memory and an online
//!   change keep a right tag. A method called through a place whose function block may be a
//!   derived one (a pointer's or a reference's target, a VAR_IN_OUT, the own instance of a
//!   function block that is extended) compiles to a branch over the candidates: the tag
//!   compared with each derived function block's that overrides the method, and a direct call
//!   of that body; the static type's own method is the default.

use std::collections::{HashMap, HashSet};

use crate::st::ast::{self, Access as Visibility, Arg, Expr, ExprKind, PouKind, Span, VarKind};

use super::ctx::{action_key, Ctx, PouInfo, Scope, Storage, VarInfo};
use super::expr::{Access, TExpr, TK};
use super::stmt::TS;
use super::types::Ty;

/// The methods, properties, bases and interfaces of the project.
#[derive(Debug, Default)]
pub struct Tables<'a> {
    /// A function block's base (`EXTENDS`).
    pub base: HashMap<usize, usize>,
    /// Each method or accessor POU.
    pub members: HashMap<usize, Member>,
    /// The function blocks whose instances carry a type tag (at offset 0).
    pub tagged: HashSet<usize>,
    /// The tag of each tagged function block.
    pub tags: HashMap<usize, u32>,
    pub interfaces: Vec<Interface<'a>>,
    pub interface_names: HashMap<String, usize>,
    /// The interfaces a function block declares it implements, with their places.
    pub implements: HashMap<usize, Vec<(usize, Span)>>,
}

/// A method, or a property's accessor.
#[derive(Debug, Clone)]
pub struct Member {
    /// The function block (or program) it belongs to; `None`: an interface's.
    pub owner: Option<usize>,
    pub name: String,
    pub access: Visibility,
    pub is_abstract: bool,
    pub is_final: bool,
    pub role: Role,
    pub span: Span,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    Method,
    Get,
    Set,
}

impl Role {
    fn what(self) -> &'static str {
        match self {
            Role::Method => "method",
            Role::Get | Role::Set => "property",
        }
    }
}

/// An `INTERFACE`.
#[derive(Debug)]
pub struct Interface<'a> {
    pub ast: &'a ast::Interface,
    pub file: usize,
    /// The interfaces it extends.
    pub extends: Vec<usize>,
    /// Its method and accessor POUs (bodies without code, for their signatures).
    pub members: Vec<usize>,
}

/// The key of a member in [`Ctx::pou_names`]: `owner.name`, `owner.name#get`, `owner.name#set`.
fn member_key(owner: &str, name: &str, role: Role) -> String {
    let key = action_key(owner, name);
    match role {
        Role::Method => key,
        Role::Get => key + "#get",
        Role::Set => key + "#set",
    }
}

/// The type tag of a function block: FNV-1a of its name in lower case.
fn name_tag(name: &str) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    for b in name.to_ascii_lowercase().bytes() {
        h ^= u32::from(b);
        h = h.wrapping_mul(0x0100_0193);
    }
    h
}

/// Why property `name` cannot be a VAR_IN_OUT argument: it has no memory, only its
/// accessors. CODESYS refuses it as well: a VAR_IN_OUT
/// needs a variable with write access (its error C0041). Written (`access` [`Access::Write`]:
/// an assignment inside an expression, a FOR variable), only an assignment statement calls
/// its SET.
fn property_not_a_place(name: &str, access: Access) -> String {
    if access == Access::Write {
        return format!("property `{name}` is written by an assignment statement only (which calls its SET), not here");
    }
    format!(
        "property `{name}` is no variable: it cannot be passed to a VAR_IN_OUT (as in CODESYS, C0041: a VAR_IN_OUT needs a variable with write access); copy it into a variable first"
    )
}

/// Whether `e` is `THIS^` or `SUPER^`: the own instance, whose every variable its code reaches.
pub(super) fn is_own_instance(e: &Expr) -> bool {
    matches!(&e.kind, ExprKind::Deref(inner)
        if matches!(&inner.kind, ExprKind::Name(id) if id.is("THIS") || id.is("SUPER")))
}

impl<'a> Ctx<'a> {
    /// Registers the methods and properties of POU `owner`.
    pub(super) fn add_members(&mut self, file: usize, owner: usize, pou: &'a ast::Pou) {
        for m in &pou.oop.methods {
            let flags = (m.access, m.is_abstract, m.is_final);
            self.add_member(file, Some(owner), &m.pou, flags, Role::Method);
        }
        for p in &pou.oop.properties {
            // an accessor's own access specifier replaces the property's (CODESYS)
            if let Some(get) = &p.get {
                let flags = (p.get_access.unwrap_or(p.access), p.is_abstract, p.is_final);
                self.add_member(file, Some(owner), get, flags, Role::Get);
            }
            if let Some(set) = &p.set {
                let flags = (p.set_access.unwrap_or(p.access), p.is_abstract, p.is_final);
                self.add_member(file, Some(owner), set, flags, Role::Set);
            }
        }
    }

    /// Registers an `INTERFACE`.
    pub(super) fn add_interface(&mut self, file: usize, itf: &'a ast::Interface) {
        let index = self.oop.interfaces.len();
        self.oop.interface_names.insert(itf.name.name.to_ascii_lowercase(), index);
        self.types.interfaces.push(itf.name.name.clone());
        self.oop.interfaces.push(Interface {
            ast: itf,
            file,
            extends: Vec::new(),
            members: Vec::new(),
        });
        let owner_name = itf.name.name.clone();
        let mut members = Vec::new();
        let flags = (Visibility::Public, true, false);
        for m in &itf.methods {
            members.extend(self.add_interface_member(
                file,
                &owner_name,
                &m.pou,
                flags,
                Role::Method,
            ));
        }
        for p in &itf.properties {
            if let Some(get) = &p.get {
                members.extend(self.add_interface_member(file, &owner_name, get, flags, Role::Get));
            }
            if let Some(set) = &p.set {
                members.extend(self.add_interface_member(file, &owner_name, set, flags, Role::Set));
            }
        }
        self.oop.interfaces[index].members = members;
    }

    fn add_interface_member(
        &mut self,
        file: usize,
        owner_name: &str,
        pou: &'a ast::Pou,
        flags: (Visibility, bool, bool),
        role: Role,
    ) -> Option<usize> {
        self.register_member(file, None, owner_name, pou, flags, role)
    }

    /// A member's POU, under its key: `None` (reported) when its owner has one of that name.
    fn register_member(
        &mut self,
        file: usize,
        owner: Option<usize>,
        owner_name: &str,
        pou: &'a ast::Pou,
        flags: (Visibility, bool, bool),
        role: Role,
    ) -> Option<usize> {
        let key = member_key(owner_name, &pou.name.name, role);
        if self.pou_names.contains_key(&key) {
            let msg = format!("`{}` is already declared in `{owner_name}`", pou.name.name);
            self.error(file, pou.name.span, msg);
            return None;
        }
        let p = self.pous.len();
        let mut info = PouInfo::new(pou, file);
        info.name = format!("{owner_name}.{}", pou.name.name);
        info.method = owner;
        self.pous.push(info);
        self.pou_names.insert(key, p);
        let (access, is_abstract, is_final) = flags;
        let name = pou.name.name.clone();
        let span = pou.name.span;
        let member = Member { owner, name, access, is_abstract, is_final, role, span };
        self.oop.members.insert(p, member);
        Some(p)
    }

    fn add_member(
        &mut self,
        file: usize,
        owner: Option<usize>,
        pou: &'a ast::Pou,
        flags: (Visibility, bool, bool),
        role: Role,
    ) {
        let Some(o) = owner else { return };
        let owner_ast = self.pous[o].ast;
        let owner_name = self.pous[o].name.clone();
        if owner_ast.kind == PouKind::Function {
            return;
        }
        let clash = role == Role::Method
            && owner_ast
                .vars
                .iter()
                .flat_map(|b| &b.decls)
                .flat_map(|d| &d.names)
                .any(|n| n.is(&pou.name.name));
        if clash {
            let msg = format!("`{}` is already declared in `{owner_name}`", pou.name.name);
            self.error(file, pou.name.span, msg);
            return;
        }
        let (_, is_abstract, _) = flags;
        if is_abstract && !owner_ast.oop.is_abstract {
            let msg = format!(
                "`{}` is ABSTRACT: only an ABSTRACT FUNCTION_BLOCK has ABSTRACT {}s (`{owner_name}` is not)",
                pou.name.name,
                role.what()
            );
            self.error(file, pou.name.span, msg);
        }
        self.register_member(file, owner, &owner_name, pou, flags, role);
    }

    /// Resolves `EXTENDS` and `IMPLEMENTS` (names, cycles, FINAL bases) and gives the
    /// function blocks of hierarchies their type tags.
    pub fn link_hierarchy(&mut self) {
        let n = self.pous.len();
        for p in 0..n {
            let pou = &self.pous[p];
            if pou.action.is_some() || self.oop.members.contains_key(&p) {
                continue;
            }
            let (ast, file) = (pou.ast, pou.file);
            if let Some(base) = &ast.oop.extends {
                if ast.kind != PouKind::FunctionBlock {
                    let msg = "only a FUNCTION_BLOCK can EXTEND another".to_string();
                    self.error(file, base.span, msg);
                } else {
                    match self.pou_names.get(&base.name.to_ascii_lowercase()).copied() {
                        Some(b) if self.pous[b].kind == PouKind::FunctionBlock && b != p => {
                            if self.pous[b].ast.oop.is_final {
                                let msg =
                                    format!("`{}` is FINAL: it cannot be extended", base.name);
                                self.error(file, base.span, msg);
                            }
                            self.oop.base.insert(p, b);
                        }
                        _ => {
                            let msg = format!(
                                "`{}` is not a FUNCTION_BLOCK: EXTENDS names the function block to extend",
                                base.name
                            );
                            self.error(file, base.span, msg);
                        }
                    }
                }
            }
            for itf in &ast.oop.implements {
                if itf.name.to_ascii_lowercase().starts_with("__system.") {
                    continue;
                }
                match self.oop.interface_names.get(&itf.name.to_ascii_lowercase()).copied() {
                    Some(i) => self.oop.implements.entry(p).or_default().push((i, itf.span)),
                    None => self.not_an_interface(file, itf),
                }
            }
        }
        // cycles: a function block among its own bases
        for p in 0..n {
            let mut at = p;
            for _ in 0..n {
                match self.oop.base.get(&at) {
                    Some(&b) if b == p => {
                        let (file, span) = (self.pous[p].file, self.pous[p].ast.name.span);
                        let name = self.pous[p].name.clone();
                        self.error(
                            file,
                            span,
                            format!("`{name}` extends itself through its bases"),
                        );
                        self.oop.base.remove(&p);
                        break;
                    }
                    Some(&b) => at = b,
                    None => break,
                }
            }
        }
        for i in 0..self.oop.interfaces.len() {
            let (ast, file) = (self.oop.interfaces[i].ast, self.oop.interfaces[i].file);
            let mut extends = Vec::new();
            for e in &ast.extends {
                // TwinCAT's interfaces extend the system's `__System.IQueryInterface`: nothing
                // to inherit (`__QUERYINTERFACE` works on any interface: compile/query.rs)
                if e.name.to_ascii_lowercase().starts_with("__system.") {
                    continue;
                }
                match self.oop.interface_names.get(&e.name.to_ascii_lowercase()).copied() {
                    Some(j) if j != i => extends.push(j),
                    Some(_) => {
                        self.error(file, e.span, format!("`{}` is not an INTERFACE", e.name))
                    }
                    None => self.not_an_interface(file, e),
                }
            }
            self.oop.interfaces[i].extends = extends;
        }
        // the tags: every function block of a hierarchy
        let mut tagged: Vec<usize> = self.oop.base.keys().copied().collect();
        tagged.extend(self.oop.base.values().copied());
        tagged.extend(self.oop.implements.keys().copied());
        tagged.sort_unstable();
        tagged.dedup();
        let mut used: HashSet<u32> = HashSet::new();
        for p in tagged {
            let mut tag = name_tag(&self.pous[p].name);
            while !used.insert(tag) {
                tag = tag.wrapping_add(1);
            }
            self.oop.tags.insert(p, tag);
            self.oop.tagged.insert(p);
        }
    }

    /// The tag bytes a tagged function block's image starts with.
    pub(super) fn tag_image(&self, p: usize) -> Option<[u8; 4]> {
        self.oop.tags.get(&p).map(|t| t.to_le_bytes())
    }

    /// The base's variables at the start of derived function block `p`: its image, variables
    /// and inputs by position, its EN, ENO and edge inputs.
    pub(super) fn inherit(&mut self, p: usize, inst: &mut Vec<u8>) {
        let Some(&base) = self.oop.base.get(&p) else {
            if let Some(tag) = self.tag_image(p) {
                inst.extend_from_slice(&tag);
            }
            return;
        };
        self.resolve_pou(base);
        let b = self.pous[base].clone();
        *inst = b.image.clone();
        if let Some(tag) = self.tag_image(p) {
            inst[..4].copy_from_slice(&tag);
        }
        let d = &mut self.pous[p];
        d.vars = b.vars;
        d.names = b.names;
        d.positional = b.positional;
        d.en = b.en;
        d.eno = b.eno;
        d.eno_implicit = b.eno_implicit;
        d.edges = b.edges;
    }

    /// A method's view of its function block's variables: after its own (which hide those of
    /// the same name), at their offsets in the instance; no parameters of its call.
    pub(super) fn share_instance(&mut self, p: usize) {
        let Some(owner) = self.pous[p].method else { return };
        let shared: Vec<VarInfo> = self.pous[owner].vars.clone();
        for mut v in shared {
            if self.pous[p].lookup(&v.name).is_some() {
                continue;
            }
            if matches!(v.kind, VarKind::Input | VarKind::Output | VarKind::InOut) {
                v.kind = VarKind::Instance;
            }
            let index = self.pous[p].vars.len();
            self.pous[p].names.insert(v.name.to_ascii_lowercase(), index);
            self.pous[p].vars.push(v);
        }
    }

    /// Whether `d` is `b` or extends it, directly or not.
    pub(super) fn derives_from(&self, d: usize, b: usize) -> bool {
        let mut at = d;
        for _ in 0..=self.pous.len() {
            if at == b {
                return true;
            }
            match self.oop.base.get(&at) {
                Some(&next) => at = next,
                None => return false,
            }
        }
        false
    }

    /// The member `name` in the role `role` of function block `fb` or of its bases.
    pub(super) fn find_member(&self, fb: usize, name: &str, role: Role) -> Option<usize> {
        let mut at = fb;
        for _ in 0..=self.pous.len() {
            let key = member_key(&self.pous[at].name, name, role);
            if let Some(&m) = self.pou_names.get(&key).filter(|m| self.oop.members.contains_key(m))
            {
                return Some(m);
            }
            at = *self.oop.base.get(&at)?;
        }
        None
    }

    /// The action `name` of POU `owner` or, for a function block, of its bases (CODESYS
    /// inherits actions; a derived block's action of the same name replaces the base's).
    pub(super) fn find_action(&self, owner: usize, name: &str) -> Option<usize> {
        let mut at = owner;
        for _ in 0..=self.pous.len() {
            let key = action_key(&self.pous[at].name, name);
            let found = self.pou_names.get(&key).filter(|&&a| self.pous[a].action.is_some());
            if let Some(&a) = found {
                return Some(a);
            }
            at = *self.oop.base.get(&at)?;
        }
        None
    }

    /// The function block whose instance the code of POU `p` runs on (its own, a method's or
    /// an action's owner's): `None` in a FUNCTION.
    pub(super) fn own_instance(&self, p: usize) -> Option<usize> {
        let pou = &self.pous[p];
        if let Some(o) = pou.method {
            return Some(o);
        }
        if let Some((_, o)) = pou.action {
            return Some(o);
        }
        if self.oop.members.contains_key(&p) {
            return None;
        }
        (pou.kind != PouKind::Function).then_some(p)
    }

    /// The own instance of the code of `scope`, typed as function block `as_fb`.
    fn own_place(as_fb: usize, span: Span) -> TExpr {
        TExpr { k: TK::Var { storage: Storage::Inst(0), by_ref: false }, ty: Ty::Fb(as_fb), span }
    }

    /// `THIS^` and `SUPER^` as places: the own instance, as its function block or its base.
    pub(super) fn this_place(&mut self, inner: &Expr, span: Span, scope: Scope) -> Option<TExpr> {
        let ExprKind::Name(id) = &inner.kind else { return None };
        let (this, sup) = (id.is("THIS"), id.is("SUPER"));
        if !this && !sup {
            return None;
        }
        if scope.pou.is_some_and(|p| self.pous[p].lookup(&id.name).is_some()) {
            return None;
        }
        let file = scope.file;
        let Some(fb) = scope.pou.and_then(|p| self.own_instance(p)) else {
            let msg = format!(
                "`{}` is used only inside a FUNCTION_BLOCK, its methods and actions",
                id.name.to_ascii_uppercase()
            );
            self.error(file, id.span, msg);
            return Some(TExpr::error(span));
        };
        if this {
            return Some(Self::own_place(fb, span));
        }
        match self.oop.base.get(&fb) {
            Some(&base) => Some(Self::own_place(base, span)),
            None => {
                let name = self.pous[fb].name.clone();
                let msg = format!("`SUPER` needs a base: `{name}` EXTENDS no function block");
                self.error(file, id.span, msg);
                Some(TExpr::error(span))
            }
        }
    }

    /// A name that is no variable: `THIS` (a pointer to the own instance), or a property of
    /// the own function block read.
    pub(super) fn own_member(
        &mut self,
        id: &ast::Ident,
        access: Access,
        scope: Scope,
    ) -> Option<TExpr> {
        let p = scope.pou?;
        let fb = self.own_instance(p)?;
        if id.is("THIS") && access == Access::Read {
            let place = Self::own_place(fb, id.span);
            let ty = Ty::Ref(ast::RefKind::Pointer, std::rc::Rc::new(Ty::Fb(fb)));
            return Some(TExpr { k: TK::Ref(Box::new(place)), ty, span: id.span });
        }
        if access != Access::Read || self.find_member(fb, &id.name, Role::Get).is_none() {
            return None;
        }
        let own = Self::own_place(fb, id.span);
        self.property_read(&own, fb, id, access, scope)
    }

    /// Whether a method called on `receiver` may run a derived function block's override: the
    /// receiver is reached through a reference or a VAR_IN_OUT, or is the own instance.
    pub(super) fn is_dynamic(receiver: &TExpr, own: bool) -> bool {
        own || matches!(
            &receiver.k,
            TK::Deref(_) | TK::Var { by_ref: true, .. } | TK::Member(_, _, true)
        )
    }

    /// The bodies a call of member `m` (found on function block `fb`) may run, by tag: one per
    /// non-abstract function block derived from `fb` whose member differs, then `m`'s own.
    fn candidates(&self, fb: usize, m: usize, role: Role) -> Vec<(Option<u32>, usize)> {
        let name = self.oop.members[&m].name.clone();
        if super::fb_init::is_initialiser(&name) {
            // each block's FB_init runs on its own, bases first (compile/fb_init.rs)
            return Vec::new();
        }
        let mut out = Vec::new();
        for d in 0..self.pous.len() {
            if d == fb || !self.oop.tagged.contains(&d) || !self.derives_from(d, fb) {
                continue;
            }
            if self.pous[d].ast.oop.is_abstract {
                continue;
            }
            if let Some(dm) = self.find_member(d, &name, role) {
                if dm != m {
                    out.push((self.oop.tags.get(&d).copied(), dm));
                }
            }
        }
        if !out.is_empty() || self.oop.members[&m].is_abstract {
            // the static type's own: the default. An abstract one runs only when no block of
            // the project implements it (its empty body: a library's abstract block whose
            // project extends it nowhere still compiles); else the last candidate is it.
            match out.last_mut() {
                Some(last) if self.oop.members[&m].is_abstract => last.0 = None,
                _ => out.push((None, m)),
            }
        }
        out
    }

    /// The bodies a call of an instance of function block `fb` reached through `inst` may run:
    /// the derived function blocks' by their tags, then `fb`'s; none when `inst` is exactly
    /// an `fb` (a variable, a member, an element).
    pub(super) fn body_candidates(&self, inst: &TExpr, fb: usize) -> Vec<(Option<u32>, usize)> {
        if !Self::is_dynamic(inst, false) {
            return Vec::new();
        }
        let mut out: Vec<(Option<u32>, usize)> = (0..self.pous.len())
            .filter(|&d| d != fb && self.oop.tagged.contains(&d) && self.derives_from(d, fb))
            .filter(|&d| !self.pous[d].ast.oop.is_abstract)
            .map(|d| (self.oop.tags.get(&d).copied(), d))
            .collect();
        if !out.is_empty() {
            out.push((None, fb));
        }
        out
    }

    /// Whether the code of `scope` may use member `m` (its access specifier); reports why not.
    fn may_use(&mut self, m: usize, span: Span, scope: Scope) -> bool {
        let member = self.oop.members[&m].clone();
        let Some(owner) = member.owner else { return true };
        let here = scope.pou.and_then(|p| self.own_instance(p));
        let ok = match member.access {
            Visibility::Public | Visibility::Internal => true,
            Visibility::Private => here == Some(owner),
            Visibility::Protected => here.is_some_and(|h| self.derives_from(h, owner)),
        };
        if !ok {
            let (name, owner_name) = (&member.name, self.pous[owner].name.clone());
            let msg = if member.access == Visibility::Private {
                format!("`{name}` is PRIVATE: only the code of `{owner_name}` may use it")
            } else {
                format!(
                    "`{name}` is PROTECTED: only the code of `{owner_name}` and of the function blocks extending it may use it"
                )
            };
            self.error(scope.file, span, msg);
        }
        ok
    }

    /// The receiver and function block of a member access `base.name`, and whether the
    /// receiver is the own instance (`THIS^`): `None` when `base` is no function block
    /// instance. `SUPER^` is the own instance as the base, called as it is (no dispatch).
    fn receiver(&mut self, base: &Expr, scope: Scope) -> Option<(TExpr, usize, bool)> {
        if let ExprKind::Deref(inner) = &base.kind {
            if let ExprKind::Name(id) = &inner.kind {
                if id.is("THIS") || id.is("SUPER") {
                    let t = self.this_place(inner, base.span, scope)?;
                    let Ty::Fb(fb) = t.ty else { return Some((t, usize::MAX, false)) };
                    return Some((t, fb, id.is("THIS")));
                }
            }
        }
        let saved = self.diags.len();
        let probe = self.check_place(base, scope, Access::Read, None);
        self.diags.truncate(saved);
        let Ty::Fb(fb) = probe.ty else { return None };
        if matches!(base.kind, ExprKind::Call { .. }) {
            // the copy a FUNCTION or METHOD returns is no variable a method could run on
            self.error(
                scope.file,
                base.span,
                "a method cannot be called on the instance a call returns: assign the result to an instance, then call the method on that",
            );
            return Some((TExpr::error(base.span), fb, false));
        }
        Some((self.check_place(base, scope, Access::Ref, None), fb, false))
    }

    /// A method call `inst.M(…)`, `THIS^.M(…)`, `SUPER^.M(…)` or, inside its function block,
    /// `M(…)`: `None` when `callee` names no method.
    pub(super) fn method_call(
        &mut self,
        callee: &Expr,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<TExpr> {
        let (receiver, fb, own, name) = match &callee.kind {
            ExprKind::Name(id) => {
                let p = scope.pou?;
                if self.pous[p].lookup(&id.name).is_some() {
                    return None;
                }
                let fb = self.own_instance(p)?;
                self.find_member(fb, &id.name, Role::Method)?;
                (Self::own_place(fb, callee.span), fb, true, id)
            }
            ExprKind::Member(base, id) => {
                if let Some(t) = self.interface_method(base, id, args, span, scope) {
                    return Some(t);
                }
                let (receiver, fb, own) = self.receiver(base, scope)?;
                if receiver.ty.is_error() {
                    return Some(receiver);
                }
                if self.find_member(fb, &id.name, Role::Method).is_none() {
                    // an action, or an error the ordinary checks report
                    if self.find_action(fb, &id.name).is_some() {
                        return None;
                    }
                    let fb_name = self.pous[fb].name.clone();
                    let what = if self.pous[fb].lookup(&id.name).is_some() {
                        format!("`{}` is a variable of `{fb_name}`, not a method", id.name)
                    } else {
                        format!("`{fb_name}` has no method `{}`", id.name)
                    };
                    self.error(scope.file, id.span, what);
                    return Some(TExpr::error(span));
                }
                (receiver, fb, own, id)
            }
            _ => return None,
        };
        let m = self.find_member(fb, &name.name, Role::Method)?;
        let dynamic = Self::is_dynamic(&receiver, own);
        Some(self.member_call(receiver, fb, m, Role::Method, args, span, scope, dynamic))
    }

    /// A call of member `m` of function block `fb` on `receiver`.
    #[allow(clippy::too_many_arguments)]
    fn member_call(
        &mut self,
        receiver: TExpr,
        fb: usize,
        m: usize,
        role: Role,
        args: &[Arg],
        span: Span,
        scope: Scope,
        dynamic: bool,
    ) -> TExpr {
        if !self.may_use(m, span, scope) {
            return TExpr::error(span);
        }
        let dispatch = if dynamic { self.candidates(fb, m, role) } else { Vec::new() };
        if dispatch.is_empty() && self.oop.members[&m].is_abstract {
            let name = self.pous[m].name.clone();
            self.error(scope.file, span, format!("`{name}` is ABSTRACT: it has no body to call"));
            return TExpr::error(span);
        }
        self.record_call_of(scope, m, &dispatch, span);
        let Some(mut call) = self.bind_args(m, args, span, scope) else {
            return TExpr::error(span);
        };
        call.this = Some(Box::new(receiver));
        call.dispatch = dispatch;
        let ty = self.pous[m].result.clone();
        TExpr { k: TK::Call(Box::new(call)), ty, span }
    }

    /// `inst.P` read, where `P` is a property of `fb` (the function block of `base`).
    pub(super) fn property_read(
        &mut self,
        base: &TExpr,
        fb: usize,
        id: &ast::Ident,
        access: Access,
        scope: Scope,
    ) -> Option<TExpr> {
        let get = self.find_member(fb, &id.name, Role::Get);
        let Some(get) = get else {
            if self.find_member(fb, &id.name, Role::Set).is_some() && access == Access::Read {
                let msg = format!("property `{}` has no GET: it cannot be read", id.name);
                self.error(scope.file, id.span, msg);
                return Some(TExpr::error(id.span));
            }
            return None;
        };
        if access != Access::Read {
            let msg = property_not_a_place(&id.name, access);
            self.error(scope.file, id.span, msg);
            return Some(TExpr::error(id.span));
        }
        let own = matches!(base.k, TK::Var { storage: Storage::Inst(0), by_ref: false })
            && scope.pou.and_then(|p| self.own_instance(p)) == Some(fb);
        let dynamic = Self::is_dynamic(base, own);
        Some(self.member_call(base.clone(), fb, get, Role::Get, &[], id.span, scope, dynamic))
    }

    /// `inst.P := v` or, inside the function block, `P := v`: a call of P's SET. `None` when
    /// the target is no property.
    pub(super) fn property_write(
        &mut self,
        target: &Expr,
        value: &Expr,
        scope: Scope,
    ) -> Option<Option<TS>> {
        let (receiver, fb, own, id) = match &target.kind {
            ExprKind::Name(id) => {
                let p = scope.pou?;
                // a variable, or the result of the method or GET being written
                let result = self.pous[p].kind == PouKind::Function
                    && super::libraries::is_own_name(id, &self.pous[p].ast.name.name);
                if self.pous[p].lookup(&id.name).is_some() || result {
                    return None;
                }
                let fb = self.own_instance(p)?;
                self.find_member(fb, &id.name, Role::Set)
                    .or_else(|| self.find_member(fb, &id.name, Role::Get))?;
                (Self::own_place(fb, target.span), fb, true, id)
            }
            ExprKind::Member(base, id) => {
                if let Some(set) = self.interface_setter(base, id, value, scope) {
                    return Some(set);
                }
                let (receiver, fb, own) = self.receiver(base, scope)?;
                if receiver.ty.is_error() || self.pous[fb].lookup(&id.name).is_some() {
                    return None;
                }
                self.find_member(fb, &id.name, Role::Set)
                    .or_else(|| self.find_member(fb, &id.name, Role::Get))?;
                (receiver, fb, own, id)
            }
            _ => return None,
        };
        let Some(set) = self.find_member(fb, &id.name, Role::Set) else {
            let msg = format!("property `{}` has no SET: it cannot be written", id.name);
            self.error(scope.file, id.span, msg);
            return Some(None);
        };
        let arg = Arg::Input { name: id.clone(), value: value.clone() };
        let dynamic = Self::is_dynamic(&receiver, own);
        let call =
            self.member_call(receiver, fb, set, Role::Set, &[arg], target.span, scope, dynamic);
        if call.ty.is_error() {
            return Some(None);
        }
        Some(Some(TS::Eval(call)))
    }

    /// A call statement of object orientation: `SUPER^(…)` (the base's body on the own
    /// instance) or a method call. `None` when `callee` is neither.
    pub(super) fn oop_statement(
        &mut self,
        callee: &Expr,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<Option<TS>> {
        if let ExprKind::Deref(inner) = &callee.kind {
            if matches!(&inner.kind, ExprKind::Name(id) if id.is("SUPER")) {
                let inst = self.this_place(inner, callee.span, scope)?;
                let Ty::Fb(base) = inst.ty else { return Some(None) };
                if self.class_called(base, scope.file, span) {
                    return Some(None);
                }
                self.record_call(scope, base, span);
                let call = self.bind_args(base, args, span, scope);
                return Some(call.map(|c| TS::FbCall(inst, c)));
            }
        }
        let t = self.method_call(callee, args, span, scope)?;
        if t.ty.is_error() {
            return Some(None);
        }
        Some(Some(TS::Eval(t)))
    }

    /// After every interface is resolved: overrides (same signature, not FINAL), ABSTRACT
    /// function blocks never instantiated, every interface's members implemented.
    pub fn check_oop(&mut self) {
        let members: Vec<(usize, Member)> =
            self.oop.members.iter().map(|(&p, m)| (p, m.clone())).collect();
        for (m, member) in &members {
            let Some(owner) = member.owner else { continue };
            let Some(&base) = self.oop.base.get(&owner) else { continue };
            let Some(over) = self.find_member(base, &member.name, member.role) else { continue };
            if super::fb_init::is_initialiser(&member.name) {
                // a derived block's FB_init runs after its base's, and may take more inputs
                continue;
            }
            let file = self.pous[*m].file;
            let base_member = self.oop.members[&over].clone();
            if base_member.is_final {
                let name = self.pous[over].name.clone();
                let msg = format!("`{name}` is FINAL: `{}` cannot override it", self.pous[*m].name);
                self.error(file, member.span, msg);
            }
            if let Some(why) = self.signature_differs(over, *m) {
                let name = self.pous[over].name.clone();
                let msg = format!(
                    "`{}` overrides `{name}` with another signature: {why}",
                    self.pous[*m].name
                );
                self.error(file, member.span, msg);
            }
        }
        // IMPLEMENTS: every member of each interface (and of those it extends)
        let implements: Vec<(usize, Vec<(usize, Span)>)> =
            self.oop.implements.iter().map(|(&p, v)| (p, v.clone())).collect();
        for (fb, itfs) in implements {
            for (itf, span) in itfs {
                for required in self.interface_members(itf) {
                    let req = self.oop.members[&required].clone();
                    let file = self.pous[fb].file;
                    let fb_name = self.pous[fb].name.clone();
                    match self.find_member(fb, &req.name, req.role) {
                        None => {
                            let what = match req.role {
                                Role::Method => format!("method `{}`", req.name),
                                Role::Get => format!("the GET of property `{}`", req.name),
                                Role::Set => format!("the SET of property `{}`", req.name),
                            };
                            let itf_name = self.oop.interfaces[itf].ast.name.name.clone();
                            let msg =
                                format!("`{fb_name}` does not implement {what} of `{itf_name}`");
                            self.error(file, span, msg);
                        }
                        Some(have) => {
                            if let Some(why) = self.signature_differs(required, have) {
                                let name = self.pous[required].name.clone();
                                let msg = format!(
                                    "`{}` implements `{name}` with another signature: {why}",
                                    self.pous[have].name
                                );
                                let at = self.oop.members[&have].span;
                                let hfile = self.pous[have].file;
                                self.error(hfile, at, msg);
                            }
                        }
                    }
                }
            }
        }
    }

    /// The members of interface `itf` and of the interfaces it extends.
    fn interface_members(&self, itf: usize) -> Vec<usize> {
        let mut out = Vec::new();
        let mut work = vec![itf];
        let mut seen = HashSet::new();
        while let Some(i) = work.pop() {
            if !seen.insert(i) {
                continue;
            }
            out.extend(self.oop.interfaces[i].members.iter().copied());
            work.extend(self.oop.interfaces[i].extends.iter().copied());
        }
        out
    }

    /// How the signature of member `b` differs from `a`'s (result, parameters in order).
    fn signature_differs(&self, a: usize, b: usize) -> Option<String> {
        let params = |p: usize| -> Vec<(VarKind, String, Ty)> {
            self.pous[p]
                .vars
                .iter()
                .filter(|v| matches!(v.kind, VarKind::Input | VarKind::Output | VarKind::InOut))
                .filter(|v| !v.name.eq_ignore_ascii_case("ENO"))
                .map(|v| (v.kind, v.name.to_ascii_lowercase(), v.ty.clone()))
                .collect()
        };
        let (ra, rb) = (&self.pous[a].result, &self.pous[b].result);
        if ra != rb {
            return Some(format!(
                "its result is `{}`, not `{}`",
                self.ty_name(rb),
                self.ty_name(ra)
            ));
        }
        let (pa, pb) = (params(a), params(b));
        if pa.len() != pb.len() {
            return Some(format!("{} parameter(s), not {}", pb.len(), pa.len()));
        }
        for ((ka, na, ta), (kb, nb, tb)) in pa.iter().zip(&pb) {
            if ka != kb || na != nb || ta != tb {
                let name = &self.pous[a].vars.iter().find(|v| v.name.eq_ignore_ascii_case(na));
                let shown = name.map_or(na.clone(), |v| v.name.clone());
                return Some(format!("parameter `{shown}` differs in name, kind or type"));
            }
        }
        None
    }

    /// An ABSTRACT function block declared as a variable's type: reported at the variable.
    pub(super) fn check_instantiable(&mut self, ty: &Ty, file: usize, span: Span) {
        if let Ty::Fb(p) = ty {
            if self.pous[*p].ast.oop.is_abstract && self.pous[*p].action.is_none() {
                let name = self.pous[*p].name.clone();
                let msg = format!("`{name}` is ABSTRACT: it cannot be instantiated (extend it)");
                self.error(file, span, msg);
            }
        }
    }

    /// Whether interface `i` is `target` or extends it, directly or not.
    pub(super) fn interface_extends(&self, i: usize, target: usize) -> bool {
        let mut work = vec![i];
        let mut seen = HashSet::new();
        while let Some(at) = work.pop() {
            if at == target {
                return true;
            }
            if seen.insert(at) {
                work.extend(self.oop.interfaces[at].extends.iter().copied());
            }
        }
        false
    }

    /// Whether function block `fb` implements interface `itf`: it or one of its bases
    /// declares `itf`, or an interface extending it.
    pub(super) fn implements(&self, fb: usize, itf: usize) -> bool {
        let mut at = Some(fb);
        for _ in 0..=self.pous.len() {
            let Some(p) = at else { return false };
            let declared = self.oop.implements.get(&p).map_or(&[][..], Vec::as_slice);
            if declared.iter().any(|&(i, _)| self.interface_extends(i, itf)) {
                return true;
            }
            at = self.oop.base.get(&p).copied();
        }
        false
    }

    /// `te` given to a value of interface type `to` (or an interface value given to `to`):
    /// an instance of a function block implementing it (its reference), an interface value of
    /// an interface extending it, `NULL` or `0`.
    pub(super) fn as_interface(&mut self, te: TExpr, to: &Ty, file: usize) -> TExpr {
        let span = te.span;
        match (&te.ty, to) {
            (Ty::Fb(p), Ty::Iface(i)) if self.implements(*p, *i) && te.is_place() => {
                TExpr { k: TK::Ref(Box::new(te)), ty: to.clone(), span }
            }
            (Ty::Iface(a), Ty::Iface(b)) if self.interface_extends(*a, *b) => {
                TExpr { ty: to.clone(), ..te }
            }
            (Ty::Null, Ty::Iface(_)) => TExpr { ty: to.clone(), ..te },
            (Ty::IntLit, Ty::Iface(_)) if te.const_int() == Some(0) => {
                TExpr::konst(super::ctx::Cv::Int(0), to.clone(), span)
            }
            _ => self.mismatch(te, to, file),
        }
    }

    /// `x = y`, `x <> y` with an interface value: another of a related interface, `NULL` or
    /// `0` (unassigned), as CODESYS compares them.
    pub(super) fn interface_compare(
        &mut self,
        op: ast::BinaryOp,
        a: TExpr,
        b: TExpr,
        span: Span,
        file: usize,
    ) -> TExpr {
        use crate::lang::ops::CmpOp;
        let cmp = match op {
            ast::BinaryOp::Eq => CmpOp::Eq,
            ast::BinaryOp::Ne => CmpOp::Ne,
            _ => {
                let msg = format!(
                    "`{}` compares interfaces: only `=` and `<>` do",
                    super::expr::op_text(op)
                );
                self.error(file, span, msg);
                return TExpr::error(span);
            }
        };
        let (a, b) = match (&a.ty, &b.ty) {
            (Ty::Iface(_), Ty::Iface(_)) => {
                let t = a.ty.clone();
                let b = if self.related(&b.ty, &t) { TExpr { ty: t.clone(), ..b } } else { b };
                (a, b)
            }
            (Ty::Iface(_), _) => {
                let t = a.ty.clone();
                let b = self.as_interface(b, &t, file);
                (a, b)
            }
            _ => {
                let t = b.ty.clone();
                let a = self.as_interface(a, &t, file);
                (a, b)
            }
        };
        if a.ty.is_error() || b.ty.is_error() {
            return TExpr::error(span);
        }
        if a.ty != b.ty {
            let (x, y) = (self.ty_name(&a.ty), self.ty_name(&b.ty));
            self.error(file, span, format!("`{x}` and `{y}` cannot be compared"));
            return TExpr::error(span);
        }
        let k = TK::Cmp(cmp, Box::new(a), Box::new(b));
        TExpr { k, ty: Ty::Prim(super::types::Prim::Bool), span }
    }

    fn related(&self, a: &Ty, b: &Ty) -> bool {
        match (a, b) {
            (Ty::Iface(x), Ty::Iface(y)) => {
                self.interface_extends(*x, *y) || self.interface_extends(*y, *x)
            }
            _ => false,
        }
    }

    /// The instance behind an interface value, as the receiver of a call: reached through the
    /// reference (`NULL`: operation error 2822H, as for a reference), its type tag checked.
    fn interface_receiver(itf_value: TExpr) -> TExpr {
        let span = itf_value.span;
        let tag = Ty::Prim(super::types::Prim::UDInt);
        TExpr { k: TK::Deref(Box::new(itf_value)), ty: tag, span }
    }

    /// The bodies a call of interface member `m` (`name`, `role`) may run: each function block
    /// implementing `itf` by its tag, then `m`'s own empty body (reached only when the value is
    /// `NULL`, after its operation error).
    fn interface_candidates(&self, itf: usize, m: usize) -> Vec<(Option<u32>, usize)> {
        let member = &self.oop.members[&m];
        let mut out: Vec<(Option<u32>, usize)> = (0..self.pous.len())
            .filter(|&d| {
                self.oop.tagged.contains(&d) && self.pous[d].kind == PouKind::FunctionBlock
            })
            .filter(|&d| !self.pous[d].ast.oop.is_abstract && self.implements(d, itf))
            .filter_map(|d| {
                let found = self.find_member(d, &member.name, member.role)?;
                (!self.oop.members[&found].is_abstract)
                    .then(|| (self.oop.tags.get(&d).copied(), found))
            })
            .collect();
        out.push((None, m));
        out
    }

    /// The member `name` (`role`) of interface `itf` or of those it extends.
    fn interface_member(&self, itf: usize, name: &str, role: Role) -> Option<usize> {
        self.interface_members(itf).into_iter().find(|m| {
            let member = &self.oop.members[m];
            member.role == role && member.name.eq_ignore_ascii_case(name)
        })
    }

    /// A call of member `m` of interface `itf` through the interface value `value`.
    fn interface_call(
        &mut self,
        value: TExpr,
        itf: usize,
        m: usize,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> TExpr {
        let dispatch = self.interface_candidates(itf, m);
        self.record_dispatch(scope, &dispatch, span);
        let Some(mut call) = self.bind_args(m, args, span, scope) else {
            return TExpr::error(span);
        };
        call.this = Some(Box::new(Self::interface_receiver(value)));
        call.dispatch = dispatch;
        let ty = self.pous[m].result.clone();
        TExpr { k: TK::Call(Box::new(call)), ty, span }
    }

    /// `x.P` read where `x` is an interface value.
    pub(super) fn interface_property(
        &mut self,
        value: TExpr,
        itf: usize,
        id: &ast::Ident,
        access: Access,
        scope: Scope,
    ) -> TExpr {
        let Some(get) = self.interface_member(itf, &id.name, Role::Get) else {
            let name = self.types.interfaces[itf].clone();
            let msg = if self.interface_member(itf, &id.name, Role::Set).is_some() {
                format!("property `{}` has no GET: it cannot be read", id.name)
            } else {
                format!("`{name}` has no property `{}`", id.name)
            };
            self.error(scope.file, id.span, msg);
            return TExpr::error(id.span);
        };
        if access != Access::Read {
            let msg = property_not_a_place(&id.name, access);
            self.error(scope.file, id.span, msg);
            return TExpr::error(id.span);
        }
        self.interface_call(value, itf, get, &[], id.span, scope)
    }

    /// `x.M(…)` where `x` is an interface value: `None` when `base` is none.
    fn interface_method(
        &mut self,
        base: &Expr,
        id: &ast::Ident,
        args: &[Arg],
        span: Span,
        scope: Scope,
    ) -> Option<TExpr> {
        let saved = self.diags.len();
        let probe = self.check_place(base, scope, Access::Read, None);
        self.diags.truncate(saved);
        let Ty::Iface(itf) = probe.ty else { return None };
        let value = self.check_place(base, scope, Access::Read, None);
        let Some(m) = self.interface_member(itf, &id.name, Role::Method) else {
            let name = self.types.interfaces[itf].clone();
            self.error(scope.file, id.span, format!("`{name}` has no method `{}`", id.name));
            return Some(TExpr::error(span));
        };
        Some(self.interface_call(value, itf, m, args, span, scope))
    }

    /// `x.P := v` where `x` is an interface value: `None` when `base` is none.
    fn interface_setter(
        &mut self,
        base: &Expr,
        id: &ast::Ident,
        value: &Expr,
        scope: Scope,
    ) -> Option<Option<TS>> {
        let saved = self.diags.len();
        let probe = self.check_place(base, scope, Access::Read, None);
        self.diags.truncate(saved);
        let Ty::Iface(itf) = probe.ty else { return None };
        let this = self.check_place(base, scope, Access::Read, None);
        let Some(set) = self.interface_member(itf, &id.name, Role::Set) else {
            let msg = if self.interface_member(itf, &id.name, Role::Get).is_some() {
                format!("property `{}` has no SET: it cannot be written", id.name)
            } else {
                let name = self.types.interfaces[itf].clone();
                format!("`{name}` has no property `{}`", id.name)
            };
            self.error(scope.file, id.span, msg);
            return Some(None);
        };
        let arg = Arg::Input { name: id.clone(), value: value.clone() };
        let call = self.interface_call(this, itf, set, &[arg], id.span, scope);
        if call.ty.is_error() {
            return Some(None);
        }
        Some(Some(TS::Eval(call)))
    }
}

impl Ctx<'_> {
    /// Reports that `id`, named by IMPLEMENTS or an interface's EXTENDS, is no interface: a
    /// POU or a type declared under that name, or nothing declared at all (a library file
    /// left out of `[st] library`, as often), with the closest interface's name.
    fn not_an_interface(&mut self, file: usize, id: &ast::Ident) {
        let key = id.name.to_ascii_lowercase();
        if self.pou_names.contains_key(&key) || self.type_names.contains_key(&key) {
            self.error(file, id.span, format!("`{}` is not an INTERFACE", id.name));
            return;
        }
        let hint = super::ctx::suggest(
            &id.name,
            self.oop.interfaces.iter().map(|i| i.ast.name.name.as_str()),
        );
        let msg = format!("no INTERFACE `{}` is declared{hint}", id.name);
        self.error(file, id.span, msg);
    }
}
