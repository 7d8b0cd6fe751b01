//! Debugger requests: `step` (answered once execution is paused again), `continue`, `break AT`
//! and `unbreak [AT]`, applied at a scan boundary; each answers with the debugger's state:
//! where execution is paused, that source line as written now and the values of the devices it
//! names, and the breakpoints. `status` shows the same state in DEBUG.

use std::path::Path;

use super::devices::{value_in, word_of};
use super::waiting::{Outcome, Then};
use super::{failure, RequestHandler, Running};
use crate::device::Address;
use crate::drivers::real_time::snapshot::Snapshot;
use crate::drivers::real_time::ControlCommand;
use crate::engine::debug::{self, Breakpoint, DebugRun};
use crate::engine::event::Mode;
use crate::lang::Language;
use crate::services::control::ClientId;
use plcd_ipc::{
    DebugState, DeviceValue, ErrorKind as Kind, Failure, Location, Reply, ResponseLine,
};

impl RequestHandler {
    pub(super) fn step(&mut self, client: ClientId, scan: bool) -> Option<ResponseLine> {
        let then = Then::Debug { unbroken: None, devices: None, until_paused: true };
        self.park(client, vec![ControlCommand::Step { scan }], then)
    }

    pub(super) fn continue_(&mut self, client: ClientId) -> Option<ResponseLine> {
        let then = Then::Debug { unbroken: None, devices: None, until_paused: false };
        self.park(client, vec![ControlCommand::Continue], then)
    }

    pub(super) fn set_breakpoint(&mut self, client: ClientId, at: &str) -> Option<ResponseLine> {
        match self.resolve(at) {
            Ok(places) => {
                let then = Then::Debug { unbroken: None, devices: None, until_paused: false };
                self.park(client, places.into_iter().map(ControlCommand::Break).collect(), then)
            }
            Err(f) => Some(ResponseLine::failure(f)),
        }
    }

    /// One breakpoint (`at`), or every one.
    pub(super) fn unbreak(&mut self, client: ClientId, at: Option<String>) -> Option<ResponseLine> {
        match at {
            Some(at) => match self.resolve(&at) {
                Ok(places) => {
                    let then =
                        Then::Debug { unbroken: Some(at), devices: None, until_paused: false };
                    let commands =
                        places.into_iter().map(|bp| ControlCommand::Unbreak(Some(bp))).collect();
                    self.park(client, commands, then)
                }
                Err(f) => Some(ResponseLine::failure(f)),
            },
            None => {
                let then = Then::Debug { unbroken: None, devices: None, until_paused: false };
                self.park(client, vec![ControlCommand::Unbreak(None)], then)
            }
        }
    }

    /// Every instruction a breakpoint text names (one per program running a file's line).
    fn resolve(&self, at: &str) -> Result<Vec<Breakpoint>, Failure> {
        let running = self.running();
        debug::resolve(&running.project.programs, at)
            .map_err(|e| Failure::new(Kind::Invalid, e.to_string()))
    }

    /// What a debugger request's snapshot wait comes to: wait while a step still runs; once
    /// paused at a line that names devices, wait once more for a capture of them; then the
    /// debugger's state.
    pub(super) fn debug_outcome(
        &self,
        unbroken: Option<String>,
        devices: Option<Vec<Address>>,
        until_paused: bool,
        snapshot: &Snapshot,
    ) -> Outcome {
        // Only a scan or a step in progress ends by itself: `continue` runs until a breakpoint,
        // maybe never, and a `debug` asked meanwhile is answered at once with that state (it
        // waited for a pause that might not come; found by the fuzzer's `control` target).
        if until_paused && snapshot.mode == Mode::Debug && snapshot.debug_run == DebugRun::Scan {
            // Still stepping: look again at the next round (see `collect_answers`).
            let then = Then::Debug { unbroken, devices, until_paused: true };
            return Outcome::Wait { then, again: false };
        }
        if devices.is_none() {
            let devices = self.paused_devices(snapshot);
            if !devices.is_empty() {
                // Paused at a breakpoint: read the devices its line names.
                let then = Then::Debug { unbroken, devices: Some(devices), until_paused: false };
                return Outcome::Wait { then, again: true };
            }
        }
        Outcome::Answer(ResponseLine::ok(Reply::Debug(self.debug_state(snapshot))))
    }

    fn debug_state(&self, snapshot: &Snapshot) -> DebugState {
        let running = self.running();
        debug_state_with(snapshot, &running)
    }

    /// The devices named on the line execution is paused before.
    pub(super) fn paused_devices(&self, snapshot: &Snapshot) -> Vec<Address> {
        let Some((_, at)) = snapshot.paused_at else { return Vec::new() };
        let running = self.running();
        let Some(program) = running.project.programs.get(at.program as usize) else {
            return Vec::new();
        };
        if program.language != Language::InstructionList {
            return Vec::new();
        }
        devices_named(&source_line(
            &program.path,
            program.line_of(at.pc as usize),
            program.language,
        ))
    }
}

/// The answer to an `unbreak AT` where no breakpoint was.
pub(super) fn no_breakpoint(at: &str) -> ResponseLine {
    failure(Kind::Invalid, format!("no breakpoint at {at}"))
}

/// The debugger's state in `snapshot`, named after the `running` project.
pub(super) fn debug_state_with(snapshot: &Snapshot, running: &Running) -> DebugState {
    let programs = &running.project.programs;
    let paused_at = snapshot.paused_at.map(|(task, at)| {
        let program = programs.get(at.program as usize);
        let line = program.map_or(0, |p| p.line_of(at.pc as usize));
        let file = program.map(|p| p.file_of(at.pc as usize));
        let language = program.map_or(Language::InstructionList, |p| p.language);
        let source = file.map(|f| source_line(f, line, language)).unwrap_or_default();
        let named = match language {
            Language::InstructionList => devices_named(&source),
            Language::StructuredText => Vec::new(),
        };
        let devices = named
            .into_iter()
            .filter_map(|d| {
                snapshot
                    .word(word_of(&d))
                    .map(|w| DeviceValue { dev: d.to_string(), value: value_in(&d, w) })
            })
            .collect();
        Location {
            program: program.map_or_else(String::new, |p| p.name.clone()),
            line,
            file: match (language, file.and_then(|f| f.file_name())) {
                (Language::StructuredText, Some(name)) => name.to_string_lossy().into_owned(),
                _ => String::new(),
            },
            task: crate::engine::task_names(&running.project.config)
                .get(usize::from(task))
                .cloned()
                .unwrap_or_default(),
            source,
            devices,
        }
    });
    DebugState {
        paused_at,
        running: snapshot.mode == Mode::Debug && snapshot.debug_run != DebugRun::Paused,
        scan: snapshot.scan.count,
        breakpoints: breakpoint_texts(programs, &snapshot.breakpoints[..snapshot.breakpoint_count]),
    }
}

/// The breakpoints as they are written, each once: a line of a Structured Text file that runs
/// in several programs is one breakpoint per program, and one `FILE:LINE`.
fn breakpoint_texts(programs: &[crate::lang::Program], breakpoints: &[Breakpoint]) -> Vec<String> {
    let mut texts: Vec<String> = Vec::with_capacity(breakpoints.len());
    for b in breakpoints {
        let text = debug::describe(programs, *b);
        if !texts.contains(&text) {
            texts.push(text);
        }
    }
    texts
}

/// Line `line` (1-based) of a program file as written now, without its comment (`;` or `//`
/// in the instruction list, `//` in Structured Text, where `;` ends a statement).
fn source_line(path: &Path, line: u32, language: Language) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let raw = text.lines().nth((line as usize).saturating_sub(1)).unwrap_or("");
    let code = match language {
        Language::InstructionList => raw.split(';').next().unwrap_or(""),
        Language::StructuredText => raw,
    };
    let code = code.split("//").next().unwrap_or("");
    code.trim().to_string()
}

/// The operands of an instruction line that are devices (not constants, not mnemonics).
fn devices_named(source: &str) -> Vec<Address> {
    let mut devices: Vec<Address> = Vec::new();
    for token in source.split_whitespace().skip(1) {
        if let Ok(address) = Address::parse(token) {
            if !devices.contains(&address) {
                devices.push(address);
            }
        }
    }
    devices
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_of_a_source_line() {
        let named = |s: &str| devices_named(s).iter().map(|a| a.to_string()).collect::<Vec<_>>();
        assert_eq!(named("LOAD P0000"), ["P0000"]);
        assert_eq!(named("ADD D00001 5 D00002"), ["D00001", "D00002"]);
        assert_eq!(named("TON T0001 50"), ["T0001"]);
        assert_eq!(named("END"), Vec::<String>::new());
    }
}
