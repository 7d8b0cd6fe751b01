//! A `plcd.toml`: parsed and checked; if accepted, its project built with stand-in programs
//! (an instruction-list `END`, a Structured Text program of the configured name) and run for a
//! few scans in virtual time. Rejected, its diagnostics point into it.

use std::path::Path;

use plcd::config;

use super::run_twice;
use crate::assert_located;

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let path = Path::new("plcd.toml");
    let config = match config::parse(text, path) {
        Ok(config) => config,
        Err(diags) => return assert_located(&diags, path, text),
    };
    // An instruction-list file is an END; a Structured Text one a program for each [[program]]
    // of that file (their names are the configured ones).
    let st_programs: Vec<(std::path::PathBuf, String)> = config
        .programs
        .iter()
        .map(|p| (p.resolved.clone(), format!("PROGRAM {}\nEND_PROGRAM\n", p.name)))
        .collect();
    let read = |file: &Path| {
        if file.extension().is_some_and(|e| e.eq_ignore_ascii_case("st")) {
            st_programs.iter().filter(|(f, _)| f == file).map(|(_, t)| t.as_str()).collect()
        } else {
            "END\n".to_string()
        }
    };
    if let Ok(project) = plcd::project::from_config(config, |f| Ok(read(f))) {
        run_twice(&project, &[]);
    }
}
