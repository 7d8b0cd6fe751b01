//! TwinCAT's and CODESYS's `BIT` (docs/ST.md, "Elementary types"): a member of a STRUCT or a
//! UNION, or a variable of a FUNCTION_BLOCK, that CODESYS packs with its neighbours into bits
//! of a byte (a UNION's shares the first byte with the other members).
//! plcd stores it as a `BOOL`, a byte of its own: it reads, writes and converts as a `BOOL`,
//! and only `SIZEOF` of the structure or block (and the offsets of the members after it) differ
//! from CODESYS's. Anywhere else, CODESYS refuses it, and so does plcd.

use crate::st::ast::{Ident, PouKind, TypeRef, VarKind};
use crate::st::dialect::Habit;

use super::ctx::{Ctx, Scope};
use super::types::{Prim, Ty};

/// Whether a type as written is `BIT`.
fn is_bit(ty: &TypeRef) -> bool {
    matches!(ty, TypeRef::Named(id) if id.is("BIT"))
}

impl<'a> Ctx<'a> {
    /// The type of a STRUCT or UNION member: a `BIT` is a `BOOL`.
    pub(super) fn member_type(&mut self, ty: &TypeRef, scope: Scope) -> Ty {
        if is_bit(ty) {
            return self.bit(scope.file, ty);
        }
        self.resolve_type_ref(ty, scope)
    }

    /// A `BIT` variable of a FUNCTION_BLOCK (VAR, VAR_INPUT, VAR_OUTPUT): a `BOOL`; `None` for
    /// any other declaration.
    pub(super) fn block_bit_type(
        &mut self,
        ty: &TypeRef,
        kind: PouKind,
        block: VarKind,
        file: usize,
    ) -> Option<Ty> {
        let fb_var = kind == PouKind::FunctionBlock
            && matches!(block, VarKind::Local | VarKind::Input | VarKind::Output);
        (is_bit(ty) && fb_var).then(|| self.bit(file, ty))
    }

    /// An allowed `BIT`: a `BOOL`, a habit `[st] strict` refuses.
    fn bit(&mut self, file: usize, ty: &TypeRef) -> Ty {
        if let TypeRef::Named(id) = ty {
            self.habit(Habit::Bit, file, id.span);
        }
        Ty::Prim(Prim::Bool)
    }

    /// `BIT` anywhere else: an error; `None` when `id` is not `BIT`.
    pub(super) fn misplaced_bit(&mut self, file: usize, id: &Ident) -> Option<Ty> {
        if !id.is("BIT") {
            return None;
        }
        self.error(
            file,
            id.span,
            "`BIT` is only the type of a STRUCT or UNION member or of a FUNCTION_BLOCK's VAR, VAR_INPUT or VAR_OUTPUT",
        );
        Some(Ty::Error)
    }
}
