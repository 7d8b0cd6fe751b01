//! `plcd check --config FILE`: load and validate the config, every program and the users file
//! it names, run nothing.

use std::io::Write;
use std::path::Path;
use std::process::ExitCode;

use crate::diag::Diagnostics;
use crate::files;

/// Prints every diagnostic to `err` (exit 1), or a one-line summary to `out` and the
/// warnings, if any, to `err` (exit 0).
pub fn run(config: &Path, out: &mut impl Write, err: &mut impl Write) -> ExitCode {
    let project = files::project(config);
    // The users file is checked whether or not the programs load, so that one run shows every
    // error: its path comes from the config, read again when the project failed.
    let users_path = match &project {
        Ok(project) => project.config.users.file.clone(),
        Err(_) => files::config(config).ok().and_then(|config| config.users.file),
    };
    let users = users_path.as_deref().map(files::users);
    let mut diags = Diagnostics::default();
    if let Err(project) = &project {
        diags.extend(project.clone());
    }
    if let Some(Err(users)) = &users {
        diags.extend(users.clone());
    }
    match project {
        Ok(project) if diags.is_empty() => {
            let instructions: usize = project.programs.iter().map(|p| p.code.len()).sum();
            let remotes = match project.config.remotes.len() {
                0 => String::new(),
                n => format!(", {n} remote device(s)"),
            };
            let users = match &users {
                Some(Ok(users)) => format!(", {} user(s)", users.users().len()),
                _ => String::new(),
            };
            let _ = writeln!(
                out,
                "{}: ok: {} program(s), {} instruction(s), {} task(s){remotes}{users}",
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
        _ => {
            let _ = write!(err, "{diags}");
            let _ = writeln!(err, "{}: {} error(s)", config.display(), diags.len());
            ExitCode::from(1)
        }
    }
}
