//! `[st] variable_memory_bytes`: the most variable memory one array or one function block
//! instance may take. TwinCAT has no such limit but the machine's; plcd keeps one so that a
//! typo in a bound (`ARRAY [1..100000000]`) is a check error rather than a daemon that takes
//! gigabytes at load: every byte of variable memory is held several times over (the
//! compiler's image, the initial image the engine restarts from, the live memory), and each
//! scalar element has a symbol for the tools (TcUnit's default parameters, a results array of
//! about 79 MB, cost `plcd sim` about 3 GB). The message names the setting, the way out for a
//! project that needs more and accepts the cost.

use super::ctx::Ctx;
use crate::config::VARIABLE_MEMORY_BYTES_RANGE;
use crate::st::ast::Span;

impl Ctx<'_> {
    /// `what` (an array, an instance) needs `bytes`, more than the setting allows.
    pub(super) fn memory_too_large(&mut self, what: &str, bytes: u64, file: usize, span: Span) {
        let limit = self.dialect.variable_memory_bytes;
        let most = VARIABLE_MEMORY_BYTES_RANGE.end();
        self.error(
            file,
            span,
            format!("{what} takes {bytes} bytes of variable memory, more than `[st] variable_memory_bytes` allows ({limit}): raise it in the config (at most {most}) or declare less"),
        );
    }
}
