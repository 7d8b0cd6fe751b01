//! CODESYS's FOR variable written in the loop's body (`IF c THEN i := i + 2; END_IF` inside
//! `FOR i := …`, as OSCAT's HTML_ENCODE advances its output position): IEC 61131-3 forbids it,
//! CODESYS and TwinCAT compile it and the loop goes on from the value written: the step is
//! added to it, and the loop ends when the result is past the bound.
//!
//! The checker notes each write as a [`Habit`] (an error under `[st] strict`, else a warning)
//! and marks its loop, whose code then tests the bound after the body as well
//! (`emit::for_loop`); a loop whose body does not write its variable is compiled as before.

use super::ctx::Ctx;
use crate::st::ast::Span;
use crate::st::dialect::Habit;

impl Ctx<'_> {
    /// The variable `name` of the enclosing FOR loop `k` (an index of `for_vars`) written at
    /// `span` in its body.
    pub(super) fn for_variable_written(&mut self, k: usize, name: &str, file: usize, span: Span) {
        self.habit(Habit::ForVariableWritten, file, span);
        if !self.dialect.strict {
            self.warn(
                file,
                span,
                format!("`{name}` is the FOR variable, written in the loop: the loop goes on from the value written, plus the step"),
            );
        }
        if let Some(written) = self.for_written.get_mut(k) {
            *written = true;
        }
    }
}
