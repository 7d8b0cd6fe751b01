//! A Structured Text file: compiled as the scan program of a project (beside an
//! instruction-list cycle task) and, if accepted, run for a few scans in virtual time. A
//! rejected file's diagnostics point into it; an accepted one runs without panicking, and twice
//! the same way.

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
    super::program(CONFIG, "main.st", &[("tick.il", TICK)], STIMULUS, data);
}
