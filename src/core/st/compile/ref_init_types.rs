//! `REF(v)` and `ADR(v)` in the member initial values of a STRUCT type's declaration (`TYPE
//! Link : STRUCT target : REF_TO INT := REF(g_value); END_STRUCT END_TYPE`), for
//! compile/ref_init.rs.
//!
//! A type has no place of its own: its initial values are written into each variable of the
//! type. So the parts of a type's initial values that take a reference are moved out of the
//! type (its image keeps the constant parts) and into the declaration of each variable of the
//! type, as if it were written there (`link : Link := (target := REF(g_value))`), beneath what
//! the declaration gives itself; compile/ref_init.rs then sets them as any reference's initial
//! value, where the variable is. A STRUCT member of such a type takes them too (`outer : Outer`
//! holding a `Link` gets `(inner := (target := …))`), and so does an array of it whose bounds
//! are integer literals and that has no initialiser of its own (`[n(…)]`).
//!
//! The names in such an initial value are looked up where the variable is declared: those of
//! globals, as a type is declared outside any POU. Not taken (the references stay `NULL`, as
//! docs/ST.md says): a `VAR_INPUT`, `VAR_IN_OUT` or `VAR_EXTERNAL` of the type (the caller's or
//! the global's), a CONSTANT (refused by compile/ref_init.rs if given), a FUNCTION's result,
//! an element `__NEW` makes, a CONFIGURATION's globals. Reported here: an array of such a
//! type with an initialiser of its own or bounds that are not integer literals. A member's
//! array initialiser taking a reference moves whole, its constant elements with it.

use std::borrow::Cow;
use std::collections::HashMap;

use crate::diag::Diagnostic;
use crate::st::ast::{
    self, ArrayInit, Expr, ExprKind, Ident, Init, Item, Literal, Span, TypeDef, TypeRef, UnaryOp,
    VarBlock, VarKind,
};

use super::ref_init::takes_ref;

/// How deep a STRUCT type may hold another with references (a type holding itself is reported
/// elsewhere).
const MAX_DEPTH: usize = 32;

/// Whether an item is a STRUCT type one of whose members' initial values takes a reference.
pub(super) fn has_reference_member(item: &Item) -> bool {
    matches!(item, Item::Type(t) if matches!(&t.def, TypeDef::Struct { members }
        if members.iter().any(|d| d.init.as_ref().is_some_and(takes_ref))))
}

/// Moves the references of the STRUCT types' initial values into the declarations of their
/// variables (see the module's documentation).
pub(super) fn lower(files: &mut [Cow<'_, ast::File>], diags: &mut Vec<Diagnostic>) {
    if !files.iter().any(|f| f.items.iter().any(has_reference_member)) {
        return;
    }
    // each STRUCT type's members, and the reference parts taken out of their initial values
    let mut members: HashMap<String, Vec<(Ident, TypeRef)>> = HashMap::new();
    let mut taken: HashMap<String, Vec<(Ident, Init)>> = HashMap::new();
    for file in files.iter_mut() {
        let has_structs = file
            .items
            .iter()
            .any(|i| matches!(i, Item::Type(t) if matches!(t.def, TypeDef::Struct { .. })));
        if !has_structs {
            continue;
        }
        for item in file.to_mut().items.iter_mut() {
            let Item::Type(t) = item else { continue };
            let TypeDef::Struct { members: decls } = &mut t.def else { continue };
            let key = t.name.name.to_ascii_lowercase();
            for d in decls.iter_mut() {
                for id in &d.names {
                    members.entry(key.clone()).or_default().push((id.clone(), d.ty.clone()));
                }
                let Some(init) = d.init.take() else { continue };
                let (refs, left) = split(init);
                d.init = left;
                if let Some(refs) = refs {
                    for id in &d.names {
                        taken.entry(key.clone()).or_default().push((id.clone(), refs.clone()));
                    }
                }
            }
        }
    }
    let types = Types { members, taken };
    let mut defaults: HashMap<String, Option<Init>> = HashMap::new();
    for name in types.members.keys() {
        let default = types.default_of(name, 0);
        defaults.insert(name.clone(), default);
    }
    let defaults: HashMap<String, Init> =
        defaults.into_iter().filter_map(|(k, v)| v.map(|v| (k, v))).collect();
    if defaults.is_empty() {
        return;
    }
    // every variable of such a type takes them beneath its own initial value
    for file in files.iter_mut() {
        let path = file.path.clone();
        for item in file.to_mut().items.iter_mut() {
            let blocks: Vec<&mut VarBlock> = match item {
                Item::Pou(p) => p
                    .vars
                    .iter_mut()
                    .chain(p.oop.methods.iter_mut().flat_map(|m| m.pou.vars.iter_mut()))
                    .collect(),
                Item::Globals(b) => vec![b],
                _ => Vec::new(),
            };
            for b in blocks {
                if b.constant
                    || matches!(b.kind, VarKind::Input | VarKind::InOut | VarKind::External)
                {
                    continue;
                }
                for d in &mut b.decls {
                    match &d.ty {
                        TypeRef::Named(t) => {
                            if let Some(default) = defaults.get(&t.name.to_ascii_lowercase()) {
                                d.init = Some(merge(default.clone(), d.init.take()));
                            }
                        }
                        TypeRef::Array { dims, of, span } => {
                            let TypeRef::Named(t) = of.as_ref() else { continue };
                            let Some(default) = defaults.get(&t.name.to_ascii_lowercase()) else {
                                continue;
                            };
                            match (elements(dims), &d.init) {
                                (Some(n), None) => {
                                    let count = Expr {
                                        kind: ExprKind::Literal(Literal::Int(n)),
                                        span: *span,
                                    };
                                    let value = Some(default.clone());
                                    let elems = vec![ArrayInit::Repeat { count, value }];
                                    d.init = Some(Init::Array { elems, span: *span });
                                }
                                _ => {
                                    let at = d.names[0].span;
                                    diags.push(Diagnostic::new(
                                        &path,
                                        at.line,
                                        at.col,
                                        format!("`{}`: the initial values of `{}` take references, which plcd sets in an array of it only when the array's bounds are integer literals and it has no initialiser of its own; set them in the body", d.names[0].name, t.name),
                                    ));
                                }
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
    }
}

/// The STRUCT types: their members, and the reference parts of their initial values.
struct Types {
    members: HashMap<String, Vec<(Ident, TypeRef)>>,
    taken: HashMap<String, Vec<(Ident, Init)>>,
}

impl Types {
    /// The reference parts of the initial value of a variable of type `name`: its members'
    /// own, and those of its members of such types.
    fn default_of(&self, name: &str, depth: usize) -> Option<Init> {
        if depth > MAX_DEPTH {
            return None;
        }
        let mut out: Vec<(Ident, Init)> = self.taken.get(name).cloned().unwrap_or_default();
        for (id, ty) in self.members.get(name).into_iter().flatten() {
            let TypeRef::Named(t) = ty else { continue };
            let Some(inner) = self.default_of(&t.name.to_ascii_lowercase(), depth + 1) else {
                continue;
            };
            match out.iter_mut().find(|(m, _)| m.is(&id.name)) {
                Some((_, own)) => *own = merge(inner, Some(own.clone())),
                None => out.push((id.clone(), inner)),
            }
        }
        let span = out.first().map_or(Span::default(), |(id, _)| id.span);
        (!out.is_empty()).then_some(Init::Struct { members: out, span })
    }
}

/// `init` split into its parts that take a reference and the rest.
fn split(init: Init) -> (Option<Init>, Option<Init>) {
    match init {
        Init::Expr(_) if takes_ref(&init) => (Some(init), None),
        Init::Struct { members, span } if takes_ref_struct(&members) => {
            let mut refs = Vec::new();
            let mut left = Vec::new();
            for (id, member) in members {
                let (r, l) = split(member);
                if let Some(r) = r {
                    refs.push((id.clone(), r));
                }
                if let Some(l) = l {
                    left.push((id, l));
                }
            }
            (Some(Init::Struct { members: refs, span }), Some(Init::Struct { members: left, span }))
        }
        // an array's initialiser taking a reference moves whole, its constant elements with
        // it (an array of references has no other constant than NULL): compile/ref_init.rs
        // places its elements by the member's declared bounds
        Init::Array { .. } if takes_ref(&init) => (Some(init), None),
        other => (None, Some(other)),
    }
}

fn takes_ref_struct(members: &[(Ident, Init)]) -> bool {
    members.iter().any(|(_, i)| takes_ref(i))
}

/// `over` (a declaration's own initial value) over `base` (the type's references): a
/// structure's members each from `over` where it gives them, else from `base`.
fn merge(base: Init, over: Option<Init>) -> Init {
    match (base, over) {
        (base, None) => base,
        (Init::Struct { members: base, .. }, Some(Init::Struct { members: mut own, span })) => {
            for (id, b) in base {
                match own.iter_mut().find(|(m, _)| m.is(&id.name)) {
                    Some((_, o)) => *o = merge(b, Some(o.clone())),
                    None => own.push((id, b)),
                }
            }
            Init::Struct { members: own, span }
        }
        (_, Some(over)) => over,
    }
}

/// The number of elements of an array whose bounds are integer literals.
fn elements(dims: &[(Expr, Expr)]) -> Option<u128> {
    let value = |e: &Expr| -> Option<i128> {
        match &e.kind {
            ExprKind::Literal(Literal::Int(n)) => i128::try_from(*n).ok(),
            ExprKind::Unary(UnaryOp::Neg, inner) => match inner.kind {
                ExprKind::Literal(Literal::Int(n)) => i128::try_from(n).ok().map(|n| -n),
                _ => None,
            },
            _ => None,
        }
    };
    let mut n: u128 = 1;
    for (lo, hi) in dims {
        let len = value(hi)? - value(lo)? + 1;
        n = n.checked_mul(u128::try_from(len).ok()?)?;
    }
    Some(n)
}
