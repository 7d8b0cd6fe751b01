//! `plcd check --config FILE`: load and validate the config and every program, run nothing.

use std::io::Write;
use std::path::Path;
use std::process::ExitCode;

use crate::files;

/// Prints every diagnostic to `err` (exit 1), or a one-line summary to `out` and the
/// warnings, if any, to `err` (exit 0).
pub fn run(config: &Path, out: &mut impl Write, err: &mut impl Write) -> ExitCode {
    match files::project(config) {
        Ok(project) => {
            let instructions: usize = project.programs.iter().map(|p| p.code.len()).sum();
            let remotes = match project.config.remotes.len() {
                0 => String::new(),
                n => format!(", {n} remote device(s)"),
            };
            let _ = writeln!(
                out,
                "{}: ok: {} program(s), {} instruction(s), {} task(s){remotes}",
                config.display(),
                project.programs.len(),
                instructions,
                project.config.tasks.len()
            );
            for note in &project.notes {
                let _ = writeln!(out, "  {note}");
            }
            // warnings go where a compiler's go; they fail nothing
            for warning in &project.warnings {
                let _ = writeln!(err, "{warning}");
            }
            ExitCode::SUCCESS
        }
        Err(diags) => {
            let _ = write!(err, "{diags}");
            let _ = writeln!(err, "{}: {} error(s)", config.display(), diags.len());
            ExitCode::from(1)
        }
    }
}
