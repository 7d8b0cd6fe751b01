//! A function block instance passed as `VAR_IN_OUT CONSTANT` and called, as TwinCAT compiles
//! it: TcUnit's F_GetCpuCounterAs64bit (github.com/tcunit/TcUnit) takes the Tc2_System block
//! `CpuCounter : GETCPUCOUNTER` so and calls `CpuCounter();`. The call runs the block on the
//! caller's instance, which it writes (its inputs, outputs and state) though the parameter is
//! CONSTANT: CONSTANT keeps the body from assigning the instance or its variables, not from
//! calling it. IEC 61131-3 has no call of a CONSTANT instance: a habit, which `[st] strict`
//! refuses.

use super::ctx::{Ctx, Scope};
use super::expr::Access;
use super::types::Ty;
use crate::st::ast::{Expr, ExprKind};
use crate::st::dialect::Habit;

impl Ctx<'_> {
    /// How the callee of a function block call is taken: `Access::Read` for a
    /// `VAR_IN_OUT CONSTANT` instance of the POU (the habit noted), which may not be written;
    /// `Access::Ref` otherwise, as a call writes its instance.
    pub(super) fn called_instance_access(&mut self, callee: &Expr, scope: Scope) -> Access {
        let ExprKind::Name(id) = &callee.kind else { return Access::Ref };
        let Some(p) = scope.pou else { return Access::Ref };
        let pou = &self.pous[p];
        let Some(i) = pou.lookup(&id.name).filter(|&i| i < scope.visible) else {
            return Access::Ref;
        };
        let v = &pou.vars[i];
        if !(v.constant && v.by_ref && matches!(v.ty, Ty::Fb(_))) {
            return Access::Ref;
        }
        self.habit(Habit::ConstantInstanceCalled, scope.file, id.span);
        Access::Read
    }
}
