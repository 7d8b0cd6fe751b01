//! `debug`, `step`, `continue`, `break AT`, `unbreak [AT]`: the debugger, answered with its
//! state.

use plcd_ipc::DebugState;

use super::format;

/// `step`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct StepArgs {
    /// Run to the end of the current scan instead of to the next line.
    #[arg(long)]
    pub scan: bool,
}

/// `break`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct BreakArgs {
    /// Where: `PROGRAM:LINE`, `FILE:LINE` (`main.st:12`), `PROGRAM:LABEL n`, `LINE` or
    /// `LABEL n` (the words are joined with spaces, so `break main:LABEL 3` needs no quotes).
    #[arg(required = true, value_name = "AT")]
    pub at: Vec<String>,
}

impl BreakArgs {
    pub fn at(&self) -> String {
        self.at.join(" ")
    }
}

/// `unbreak`'s arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct UnbreakArgs {
    /// The breakpoint to remove, as for `break`; without it, every breakpoint.
    #[arg(value_name = "AT")]
    pub at: Vec<String>,
}

impl UnbreakArgs {
    pub fn at(&self) -> Option<String> {
        (!self.at.is_empty()).then(|| self.at.join(" "))
    }
}

/// The debugger's state, in lines: where it waits, the source line and the values of the
/// devices it names, the breakpoints.
pub fn lines(state: &DebugState) -> Vec<String> {
    let scans = match state.scan {
        1 => "1 scan completed".to_string(),
        n => format!("{n} scans completed"),
    };
    let mut lines = Vec::new();
    match &state.paused_at {
        Some(at) => {
            lines.push(if at.file.is_empty() {
                format!("paused at {}:{} in task {}; {scans}", at.program, at.line, at.task)
            } else {
                format!(
                    "paused at {}:{} in program {}, task {}; {scans}",
                    at.file, at.line, at.program, at.task
                )
            });
            if !at.source.is_empty() {
                lines.push(format!("  {}", at.source));
            }
            if !at.devices.is_empty() {
                lines.push(format!("  {}", format::device_list(&at.devices)));
            }
        }
        None if state.running => lines.push(format!("running to a breakpoint; {scans}")),
        None => lines.push(format!("between scans; {scans}")),
    }
    if state.breakpoints.is_empty() {
        lines.push("breakpoints: none".to_string());
    } else {
        lines.push(format!("breakpoints: {}", state.breakpoints.join(", ")));
    }
    lines
}

pub fn render(state: &DebugState) -> String {
    lines(state).into_iter().map(|line| line + "\n").collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use plcd_ipc::{DeviceValue, Location};

    #[test]
    fn states() {
        let mut state = DebugState { scan: 1, ..DebugState::default() };
        assert_eq!(render(&state), "between scans; 1 scan completed\nbreakpoints: none\n");
        state.running = true;
        state.breakpoints = vec!["main:3".into(), "aux:7".into()];
        assert_eq!(
            render(&state),
            "running to a breakpoint; 1 scan completed\nbreakpoints: main:3, aux:7\n"
        );
        state.running = false;
        state.scan = 41;
        state.paused_at = Some(Location {
            program: "main".into(),
            line: 3,
            file: String::new(),
            task: "scan".into(),
            source: "LOAD P0000".into(),
            devices: vec![DeviceValue { dev: "P0000".into(), value: 1 }],
        });
        assert_eq!(
            render(&state),
            "paused at main:3 in task scan; 41 scans completed\n  LOAD P0000\n  P0000=1\n\
             breakpoints: main:3, aux:7\n"
        );
    }
}
