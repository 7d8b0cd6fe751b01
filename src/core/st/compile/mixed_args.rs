//! A call's positional arguments followed by named ones, `REAL_TO_STRF(x, 2, DEC := ',')`, as
//! TwinCAT accepts (OSCAT NETWORK's WORLD_WEATHER writes it): the positional ones go to the
//! first inputs in declaration order, the named ones by name, and a parameter given both ways is
//! given twice. IEC 61131-3 gives a call's arguments all by position or all by name: a habit,
//! which `[st] strict` refuses. A positional argument after a named one stays an error.

use crate::st::ast::{Arg, Span};
use crate::st::dialect::Habit;

use super::ctx::Ctx;

impl<'a> Ctx<'a> {
    /// Whether the arguments of a call of `name` are in an order plcd binds: all positional,
    /// all named, or positional then named (the habit, noted at the first named one). Reports
    /// a positional argument after a named one.
    pub(super) fn argument_order(
        &mut self,
        name: &str,
        args: &[Arg],
        span: Span,
        file: usize,
    ) -> bool {
        let Some(first_named) = args.iter().position(|a| !matches!(a, Arg::Positional(_))) else {
            return true;
        };
        if args[first_named..].iter().any(|a| matches!(a, Arg::Positional(_))) {
            self.error(
                file,
                span,
                format!("the call of `{name}` gives a positional argument after a named one"),
            );
            return false;
        }
        if first_named > 0 {
            let at = match &args[first_named] {
                Arg::Input { name, .. } | Arg::Output { name, .. } => name.span,
                Arg::Positional(e) => e.span,
            };
            self.habit(Habit::PositionalThenNamed, file, at);
        }
        true
    }
}
