//! Function block instances as values, as CODESYS and TwinCAT have them (TcUnit needs both):
//!
//! - `fbA := fbB;`, both instances of the same FUNCTION_BLOCK: the whole instance is copied
//!   byte for byte (inputs, outputs, internals, nested instances; not the type tag of a block
//!   in a hierarchy, which stays the target's own); pointers, references and interface values inside are copied as they are, so
//!   they go on pointing where they pointed (CODESYS's static analysis rule SA0014, "Assignment
//!   of instances", documents the copy). An instance of another block, a derived one included,
//!   is refused: CODESYS documents the copy between instances of one block only.
//! - A FUNCTION or METHOD whose result is an instance (`METHOD GetTestByPosition : FB_Test`,
//!   `GetTestByPosition := Tests[Position];`): the result slot, at the start of the callee's
//!   frame like any aggregate result, starts each call from the block's declared initial
//!   values (its `FB_init` is not run: the slot is meant to receive a copy, and CODESYS runs no
//!   `FB_init` for a copy either), and the caller copies it out (`emit::call_fn_enabled`), to
//!   assign it to an instance or to read an output of it.
//!
//! - A FUNCTION's `VAR` holding an instance (`CurrentTest : FB_Test;`, TcUnit's
//!   IS_TEST_FINISHED): a fresh instance at each call, as a method's already is (compile/
//!   fb_init.rs runs its `FB_init` at the call).
//!
//! The copies are compiled to the block copy a STRUCT assignment uses, so they have native code
//! as well, and allocate nothing in a scan. All three are [`Habit`]s (`Habit::InstanceResult`
//! and `Habit::InstanceInFunction` noted where decl.rs declares them): IEC 61131-3 assigns no
//! instance, its functions return values of data types and keep no state, so `[st] strict`
//! refuses them.

use std::rc::Rc;

use super::ctx::Ctx;
use super::expr::{TExpr, TK};
use super::types::{ArrayTy, Prim, Ty};
use crate::st::ast::Span;
use crate::st::dialect::Habit;

/// The bytes of a type tag (compile/oop.rs: a UDINT at offset 0 of a block in a hierarchy).
const TAG_BYTES: u32 = 4;

impl Ctx<'_> {
    /// `target := value` where the target is a function block instance (the statement
    /// checker's `t` and `v`): the two places to copy between, or `None` when there is nothing
    /// to copy (after reporting why, unless the instance is its type tag alone). The copy leaves out the type tag of a block in a hierarchy (its first 4 bytes,
    /// compile/oop.rs): an instance of `Base` reached through a `POINTER TO Base` may be a
    /// derived one, and a tag copied from it would make the target, `Base`-sized, dispatch to
    /// the derived block's methods; each instance keeps the tag of what it is.
    pub(super) fn instance_assignment(
        &mut self,
        t: TExpr,
        v: TExpr,
        file: usize,
        span: Span,
    ) -> Option<(TExpr, TExpr)> {
        let (Ty::Fb(to), Ty::Fb(from)) = (&t.ty, &v.ty) else {
            let (to, from) = (self.ty_name(&t.ty), self.ty_name(&v.ty));
            self.error(
                file,
                span,
                format!("type mismatch: `{from}` cannot be assigned to the instance of `{to}`: an instance is assigned an instance of the same function block only"),
            );
            return None;
        };
        if to != from {
            let (to, from) = (self.ty_name(&t.ty), self.ty_name(&v.ty));
            self.error(
                file,
                span,
                format!("an instance of `{from}` cannot be assigned to an instance of `{to}`: the copy is between instances of the same function block only (pass a derived instance as a VAR_IN_OUT or an interface instead)"),
            );
            return None;
        }
        self.habit(Habit::InstanceAssignment, file, span);
        let fb = *to;
        if self.tag_image(fb).is_none() {
            return Some((t, v));
        }
        let size = self.types.size(&t.ty);
        if size <= TAG_BYTES {
            return None; // the tag alone: nothing to copy
        }
        let data = Ty::Array(Rc::new(ArrayTy {
            dims: vec![(0, i64::from(size - TAG_BYTES) - 1)],
            of: Ty::Prim(Prim::Byte),
            elem_size: 1,
        }));
        let after_tag = |e: TExpr| TExpr {
            span: e.span,
            k: TK::Member(Box::new(e), TAG_BYTES, false),
            ty: data.clone(),
        };
        Some((after_tag(t), after_tag(v)))
    }
}
