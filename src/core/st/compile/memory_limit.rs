//! `[st] variable_memory_bytes`: the most variable memory a project may take in all (its
//! globals, program instances, `VAR_STAT`s, constants kept in memory, as CODESYS's data area
//! size bounds all of a PLC's data); one array or one function block instance larger than
//! that is reported at its type, the total at the declaration that crosses it. TwinCAT has no such limit but the machine's; plcd keeps one so that a
//! typo in a bound (`ARRAY [1..100000000]`) is a check error rather than a daemon that takes
//! gigabytes at load: every byte of variable memory is held several times over (the
//! compiler's image, the initial image the engine restarts from, the live memory), and each
//! scalar element has a symbol for the tools (TcUnit's default parameters, a results array of
//! about 79 MB, cost `plcd sim` about 1.5 GB; BENCHMARKS.md, "Large variables"). The message names the setting, the way out for a
//! project that needs more and accepts the cost.

use super::ctx::Ctx;
use crate::config::VARIABLE_MEMORY_BYTES_RANGE;
use crate::st::ast::Span;

impl Ctx<'_> {
    /// `what` (an array, an instance) needs `bytes`, more than the setting allows.
    pub(super) fn memory_too_large(&mut self, what: &str, bytes: u64, file: usize, span: Span) {
        let limit = self.dialect.variable_memory_bytes;
        let most = VARIABLE_MEMORY_BYTES_RANGE.end();
        // the declaration's own error says it: no second one for the total
        self.memory_exceeded = true;
        self.error(
            file,
            span,
            format!("{what} takes {bytes} bytes of variable memory, more than `[st] variable_memory_bytes` allows ({limit}): raise it in the config (at most {most}) or declare less"),
        );
    }

    /// Whether `more` bytes fit in variable memory after what is laid out; if not, an error at
    /// `span` (the first declaration past the limit only: the ones after it add nothing).
    /// The sum is a `u64`, so it never wraps however large the declarations.
    pub(super) fn total_within_limit(&mut self, more: u64, file: usize, span: Span) -> bool {
        let limit = self.dialect.variable_memory_bytes;
        let total = self.image.len() as u64 + more;
        if total <= u64::from(limit) {
            return true;
        }
        if !self.memory_exceeded {
            self.memory_exceeded = true;
            let most = VARIABLE_MEMORY_BYTES_RANGE.end();
            self.error(
                file,
                span,
                format!("with this declaration, variable memory takes {total} bytes in all, more than `[st] variable_memory_bytes` allows ({limit}): raise it in the config (at most {most}) or declare less"),
            );
        }
        false
    }
}
