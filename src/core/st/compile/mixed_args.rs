//! A call that mixes positional and named arguments, as CODESYS and TwinCAT accept:
//! `REAL_TO_STRF(x, 2, DEC := ',')` (OSCAT NETWORK's WORLD_WEATHER) and, since CODESYS's
//! compiler 3.4.10 stopped refusing it (its error C0042), `FIND(STR1 := s, '.')` (TcUnit's
//! F_GetTestSuiteNameFromTestInstancePath). A positional argument binds by its place in the
//! list: the k-th argument goes to the k-th input in declaration order, wherever the named ones
//! stand; a parameter given both ways is given twice. IEC 61131-3 gives a call's arguments all
//! by position or all by name: a habit, which `[st] strict` refuses.

use crate::st::ast::{Arg, Span};
use crate::st::dialect::Habit;

use super::ctx::Ctx;

impl<'a> Ctx<'a> {
    /// Whether the arguments of a call of `name` are in an order plcd binds: every order
    /// binds (a positional argument by its place in the list), so this only notes the habit
    /// of mixing, at the first argument that breaks the standard's all-or-none.
    pub(super) fn argument_order(
        &mut self,
        _name: &str,
        args: &[Arg],
        _span: Span,
        file: usize,
    ) -> bool {
        let positional = |a: &Arg| matches!(a, Arg::Positional(_));
        let Some(first_named) = args.iter().position(|a| !positional(a)) else {
            return true;
        };
        // Positional then named: noted at the first named one; named then positional: at the
        // first positional one after a named one.
        let at = if first_named > 0 {
            Some(&args[first_named])
        } else {
            args.iter().find(|a| positional(a))
        };
        let Some(at) = at else { return true };
        let at = match at {
            Arg::Input { name, .. } | Arg::Output { name, .. } => name.span,
            Arg::Positional(e) => e.span,
        };
        self.habit(Habit::PositionalThenNamed, file, at);
        true
    }
}
