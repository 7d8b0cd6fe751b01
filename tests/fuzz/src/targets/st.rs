//! A Structured Text file: compiled as the scan program of a project (beside an
//! instruction-list cycle task) and, if accepted, run for a few scans in virtual time. A
//! rejected file's diagnostics point into it; an accepted one runs without panicking, and twice
//! the same way.

use std::path::Path;

use plcd::config;
use plcd::stimulus;

use super::run_twice;
use crate::assert_located;

pub const CONFIG: &str = r#"
[plc]
watchdog_ms = 10
[[program]]
name = "main"
file = "main.st"
task = "scan"
[[program]]
name = "tick"
file = "tick.il"
task = "tick_1ms"
[[task]]
name = "tick_1ms"
kind = "cycle"
number = 0
priority = 3
interval_ms = 1
"#;

const TICK: &str = "INC D00500\nEND\n";

pub const STIMULUS: &str = "1ms, P0000, 1\n2ms, P0000, 0\n3ms, D00010, 1234\n";

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let config = config::parse(CONFIG, Path::new("plcd.toml")).expect("the target's config");
    let stimuli = stimulus::parse_for(STIMULUS, Path::new("inputs.csv"), &config)
        .expect("the target's stimulus");
    let read = |path: &Path| match path.file_name().and_then(|n| n.to_str()) {
        Some("tick.il") => TICK.to_string(),
        _ => text.to_string(),
    };
    match plcd::project::from_config(config, |p| Ok(read(p))) {
        Err(diags) => assert_located(&diags, Path::new("main.st"), text),
        Ok(project) => run_twice(&project, &stimuli),
    }
}
