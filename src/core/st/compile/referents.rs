//! What each reference type of a project points to, as tools name it: for every `REF_TO`,
//! `POINTER TO` and `REFERENCE TO` type a variable can hold (inside structs, arrays and
//! FB instances, and inside the targets themselves), the leaves of its target relative to
//! the place it points to (`""` for an `INT`, `.pos` and `.speed` for a struct). A client
//! names them after the reference and a `^` (`main.r^`, `main.p^.pos`), and the tools find
//! the place each time they read ([`crate::project::Through`]).

use super::ctx::Ctx;
use super::types::Ty;
use crate::symbols::Symbols;
use crate::value::{Pointer, Space};

/// Every reference type of the project's variables by its name (`REF_TO Axis`) with the
/// leaves of its target, their places counted from the start of the target.
pub(super) fn referents(cx: &Ctx<'_>) -> Vec<(String, Symbols)> {
    let mut found: Vec<(String, Symbols)> = Vec::new();
    let mut work: Vec<Ty> = cx.globals.iter().map(|v| v.ty.clone()).collect();
    work.extend(cx.pous.iter().flat_map(|p| p.vars.iter().map(|v| v.ty.clone())));
    while let Some(ty) = work.pop() {
        match &ty {
            Ty::Ref(_, to) => {
                let name = cx.ty_name(&ty);
                if found.iter().any(|(n, _)| *n == name) {
                    continue;
                }
                let start = Pointer { space: Space::Var, offset: 0 };
                let mut target = Symbols::default();
                super::leaves(cx, "", to, start, false, false, &mut target);
                found.push((name, target));
                // A reference inside the target (`next : REF_TO Node`) is named through too.
                work.push((**to).clone());
            }
            Ty::Array(a) => work.push(a.of.clone()),
            Ty::Struct(s) => work.extend(cx.types.structs[*s].members.iter().map(|m| m.ty.clone())),
            // An FB's variables are walked with its POU's.
            _ => {}
        }
    }
    found
}
