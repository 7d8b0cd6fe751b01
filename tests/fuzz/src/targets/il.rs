//! An instruction-list program: assembled as the scan program of a project with a 1 ms cycle
//! task and an I/O task, and, if accepted, run for a few scans in virtual time with edges on
//! its inputs. A rejected program's diagnostics point into it; an accepted one runs without
//! panicking, and twice the same way.

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
    super::program(CONFIG, "main.il", &[("tick.il", TICK), ("edge.il", EDGE)], STIMULUS, data);
}
