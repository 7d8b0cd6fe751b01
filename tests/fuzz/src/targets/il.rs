//! An instruction-list program: assembled as the scan program of a project with a 1 ms cycle
//! task and an I/O task, and, if accepted, run for a few scans in virtual time with edges on
//! its inputs. A rejected program's diagnostics point into it; an accepted one runs without
//! panicking, and twice the same way.

use std::path::Path;

use plcd::config;
use plcd::stimulus;

use super::run_twice;
use crate::assert_located;

pub const CONFIG: &str = r#"
[plc]
watchdog_ms = 10
[timers]
ms100 = "T0000-T0099"
ms10 = "T0100-T0199"
ms1 = "T0200-T0299"
[[program]]
name = "main"
file = "main.il"
task = "scan"
[[program]]
name = "tick"
file = "tick.il"
task = "tick_1ms"
[[program]]
name = "edge"
file = "edge.il"
task = "edge_p0000"
[[task]]
name = "tick_1ms"
kind = "cycle"
number = 0
priority = 3
interval_ms = 1
[[task]]
name = "edge_p0000"
kind = "io"
number = 8
priority = 2
contact = "P0000"
edge = "rising"
"#;

/// The other programs: a cycle task and an I/O task that count.
const TICK: &str = "INC D00500\nEND\n";
const EDGE: &str = "INC D00501\nEND\n";

/// Input changes while it runs: edges on P0000 (the I/O task) and P0001, a word.
pub const STIMULUS: &str = "1ms, P0000, 1\n1ms, P0001, 1\n2ms, P0000, 0\n3ms, P0000, 1\n\
                            3ms, D00010, 1234\n4ms, P0001, 0\n";

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let config = config::parse(CONFIG, Path::new("plcd.toml")).expect("the target's config");
    let stimuli = stimulus::parse_for(STIMULUS, Path::new("inputs.csv"), &config)
        .expect("the target's stimulus");
    let read = |path: &Path| match path.file_name().and_then(|n| n.to_str()) {
        Some("tick.il") => TICK.to_string(),
        Some("edge.il") => EDGE.to_string(),
        _ => text.to_string(),
    };
    match plcd::project::from_config(config, |p| Ok(read(p))) {
        Err(diags) => assert_located(&diags, Path::new("main.il"), text),
        Ok(project) => run_twice(&project, &stimuli),
    }
}
