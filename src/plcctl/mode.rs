//! `run`, `stop`, `reset [--cold]`: mode changes, answered with the mode after the command.

use plcd_ipc::ModeName;

/// `reset`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct ResetArgs {
    /// Also clear retained memory.
    #[arg(long)]
    pub cold: bool,
}

/// `mode: RUN`.
pub fn render(mode: ModeName) -> String {
    format!("mode: {}\n", mode.as_str())
}
