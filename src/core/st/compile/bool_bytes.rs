//! Whether a project keeps every `BOOL` of variable memory at 0 or 1
//! ([`crate::lang::Program::var_bools_canonical`]), so that native code may read one as the
//! byte it is instead of testing it for nonzero at every read.
//!
//! Code writes a `BOOL` as 0 or 1. Another type's bytes land on a `BOOL` only where two
//! variables share memory, which in plcd's layout only two things make:
//!
//! | what | how it reaches a `BOOL` |
//! |---|---|
//! | a `UNION` with a member that holds a `BOOL` | another member's write overlays it |
//! | a reference followed (`p^`, `r`, `REFERENCE TO`, `__NEW`, `MEMCPY`, `ANY`, an interface) | a pointer of one type may be made from the address of another (`ADR`, pointer arithmetic) |
//!
//! A project with neither keeps its `BOOL`s canonical: every other write is at a place the
//! compiler typed (fixed places, array elements within their bounds, members, `VAR_IN_OUT`s
//! bound to variables of their type). Bytes copied in from outside the code (retained values,
//! another project's memory kept by an online change) are rewritten by the engine
//! ([`crate::lang::bool_variables`]).

use crate::lang::ops::Op;
use crate::lang::Program;

use super::types::{Prim, Ty, Types};

/// Whether the project whose `types` and `programs` these are never writes another type's
/// bytes over a `BOOL` of variable memory (the module's rule).
pub(super) fn canonical(types: &Types, programs: &[Program]) -> bool {
    let follows_a_reference = programs
        .iter()
        .flat_map(|p| p.code.iter())
        .any(|op| matches!(op, Op::Deref { .. } | Op::CheckRef(_) | Op::RefAdd | Op::RefDiff));
    let overlays_a_bool = types
        .structs
        .iter()
        .filter(|s| s.union)
        .any(|s| s.members.iter().any(|m| holds_bool(types, &m.ty)));
    !follows_a_reference && !overlays_a_bool
}

/// Whether a value of `ty` has a `BOOL` among its bytes (a function block's variables are not
/// looked into: taken as holding one).
fn holds_bool(types: &Types, ty: &Ty) -> bool {
    match ty {
        Ty::Prim(p) => *p == Prim::Bool,
        Ty::Array(a) => holds_bool(types, &a.of),
        Ty::OpenArray(a) => holds_bool(types, &a.of),
        Ty::Struct(s) => types.structs[*s].members.iter().any(|m| holds_bool(types, &m.ty)),
        Ty::Fb(_) => true,
        _ => false,
    }
}
