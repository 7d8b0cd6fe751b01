//! DEBUG mode (XGB §5.2): the programs run only when the engineer says so — one scan at a
//! time (`step`), or until a breakpoint (`continue`) — and stop *before* a breakpoint's
//! instruction with device memory as that instruction will see it.
//!
//! This module owns the breakpoint syntax, its resolution against the loaded programs, the
//! breakpoints (kept across DEBUG sessions) and the state of a DEBUG session, which only the
//! engine's DEBUG mode holds. The engine asks `Session::pauses_before` before each instruction
//! while a breakpoint is set in the program it executes; without breakpoints the VM runs at full
//! speed even in DEBUG.

use crate::lang::Program;

use super::event::TaskId;

/// Breakpoints at most; fixed so that setting one never allocates on the scan thread.
pub const MAX_BREAKPOINTS: usize = 32;

/// An instruction: program index and program counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Breakpoint {
    pub program: u16,
    pub pc: u32,
}

/// Why a breakpoint text does not name an instruction.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BreakError {
    #[error("`{0}` is not a breakpoint: write PROGRAM:LINE, PROGRAM:LABEL n, PROGRAM:SBRT n, or leave the program out when only one fits")]
    Syntax(String),
    #[error("no program is called \"{0}\" (programs: {1})")]
    UnknownProgram(String, String),
    #[error("{program}:{line} has no instruction (a comment, a blank line, or beyond the end)")]
    NoInstruction { program: String, line: u32 },
    #[error("no program has {0}")]
    NotFound(String),
    #[error("{what} is in more than one place ({places}): name the program, PROGRAM:{what}")]
    Ambiguous { what: String, places: String },
    #[error("at most {MAX_BREAKPOINTS} breakpoints")]
    TooMany,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Target {
    Line(u32),
    Label(u32),
    Subroutine(u32),
}

fn parse_target(text: &str) -> Option<Target> {
    let t = text.trim();
    let upper = t.to_ascii_uppercase();
    let number = |rest: &str| rest.trim().parse::<u32>().ok();
    if let Some(rest) = upper.strip_prefix("LABEL") {
        return number(rest).map(Target::Label);
    }
    if let Some(rest) = upper.strip_prefix("SBRT") {
        return number(rest).map(Target::Subroutine);
    }
    number(t).filter(|&n| n > 0).map(Target::Line)
}

/// The instructions `target` names in `program`.
fn find(program: &Program, target: Target) -> Vec<u32> {
    match target {
        Target::Line(line) => {
            program.lines.iter().position(|&l| l == line).map(|pc| pc as u32).into_iter().collect()
        }
        Target::Label(n) => {
            program.labels.iter().filter(|(l, _)| *l == n).map(|&(_, pc)| pc).collect()
        }
        Target::Subroutine(n) => {
            program.subroutines.iter().filter(|(s, _)| *s == n).map(|&(_, pc)| pc).collect()
        }
    }
}

fn target_text(target: Target) -> String {
    match target {
        Target::Line(n) => format!("line {n}"),
        Target::Label(n) => format!("LABEL {n}"),
        Target::Subroutine(n) => format!("SBRT {n}"),
    }
}

/// Resolves a breakpoint text against the programs: `PROGRAM:LINE`, `PROGRAM:LABEL n`,
/// `PROGRAM:SBRT n`, or any of these without `PROGRAM:` when exactly one program has it. A line
/// stops before its first instruction.
pub fn resolve(programs: &[Program], text: &str) -> Result<Breakpoint, BreakError> {
    let syntax = || BreakError::Syntax(text.to_string());
    let (program, target) = match text.rsplit_once(':') {
        Some((name, rest)) => (Some(name.trim()), parse_target(rest).ok_or_else(syntax)?),
        None => (None, parse_target(text).ok_or_else(syntax)?),
    };
    let candidates: Vec<usize> = match program {
        Some(name) => {
            let index = programs.iter().position(|p| p.name == name).ok_or_else(|| {
                let names: Vec<&str> = programs.iter().map(|p| p.name.as_str()).collect();
                BreakError::UnknownProgram(name.to_string(), names.join(", "))
            })?;
            vec![index]
        }
        None => (0..programs.len()).collect(),
    };
    let mut found = Vec::new();
    for &index in &candidates {
        for pc in find(&programs[index], target) {
            found.push(Breakpoint { program: index as u16, pc });
        }
    }
    match (found.len(), target, program) {
        (1, _, _) => Ok(found[0]),
        (0, Target::Line(line), Some(name)) => {
            Err(BreakError::NoInstruction { program: name.to_string(), line })
        }
        (0, _, _) => Err(BreakError::NotFound(target_text(target))),
        _ => Err(BreakError::Ambiguous {
            what: target_text(target),
            places: found.iter().map(|b| describe(programs, *b)).collect::<Vec<_>>().join(", "),
        }),
    }
}

/// `PROGRAM:LINE` of an instruction.
pub fn describe(programs: &[Program], at: Breakpoint) -> String {
    match programs.get(at.program as usize) {
        Some(p) => format!("{}:{}", p.name, p.line_of(at.pc as usize)),
        None => format!("#{}:{}", at.program, at.pc),
    }
}

/// What the programs may do in DEBUG.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DebugRun {
    /// Nothing executes: between two scans, or before a breakpoint's instruction. Also what
    /// [`DebugView::run_state`] says outside DEBUG, where there is no session.
    Paused,
    /// Execute to the end of the current (or the next) scan, or to a breakpoint.
    Scan,
    /// Execute scan after scan until a breakpoint.
    Continue,
}

/// The breakpoints, kept by the engine across DEBUG sessions (they stay set). Where execution
/// stands in a session is the session's, which ends with DEBUG (see [`DebugView`]).
#[derive(Debug, Clone)]
pub struct Debugger {
    breakpoints: Vec<Breakpoint>,
}

impl Default for Debugger {
    fn default() -> Self {
        Debugger { breakpoints: Vec::with_capacity(MAX_BREAKPOINTS) }
    }
}

impl Debugger {
    pub fn breakpoints(&self) -> &[Breakpoint] {
        &self.breakpoints
    }

    /// Adds a breakpoint (setting one twice is fine).
    pub fn add(&mut self, at: Breakpoint) -> Result<(), BreakError> {
        if self.breakpoints.contains(&at) {
            return Ok(());
        }
        if self.breakpoints.len() >= MAX_BREAKPOINTS {
            return Err(BreakError::TooMany);
        }
        self.breakpoints.push(at);
        self.breakpoints.sort_unstable();
        Ok(())
    }

    /// Removes a breakpoint; true if it was set.
    pub fn remove(&mut self, at: Breakpoint) -> bool {
        let before = self.breakpoints.len();
        self.breakpoints.retain(|b| *b != at);
        before != self.breakpoints.len()
    }

    pub fn clear(&mut self) {
        self.breakpoints.clear();
    }

    /// True if some breakpoint is in `program` (the engine then executes it one instruction
    /// at a time).
    #[inline]
    pub(super) fn watches(&self, program: u16) -> bool {
        self.breakpoints.iter().any(|b| b.program == program)
    }
}

/// How far a DEBUG `step` or `continue` lets the programs run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Until {
    /// To the end of the current (or the next) scan, or to a breakpoint: `step`.
    ScanEnd,
    /// Scan after scan, to a breakpoint: `continue`.
    Breakpoint,
}

/// The state of a DEBUG session. Only the engine's DEBUG mode holds one, so a pause, a place to
/// resume from or a running `step` cannot outlive DEBUG.
///
/// Invariants, by construction: a breakpoint execution waits before exists only while paused;
/// the breakpoint to pass once exists only while executing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Session {
    /// Nothing executes: between two scans (`at: None`), or before the instruction `at` names
    /// in a task.
    Paused { at: Option<(TaskId, Breakpoint)> },
    /// The programs execute, as far as `until` says. `resume_from` is the breakpoint execution
    /// resumed from: passed once, not stopped at again.
    Executing { until: Until, resume_from: Option<Breakpoint> },
}

impl Session {
    /// Paused between two scans: DEBUG entered from STOP or at a scan boundary of RUN.
    pub(super) const BETWEEN_SCANS: Session = Session::Paused { at: None };

    /// True while `step` or `continue` lets the programs run.
    #[inline]
    pub(super) fn executes(self) -> bool {
        matches!(self, Session::Executing { .. })
    }

    #[inline]
    fn run_state(self) -> DebugRun {
        match self {
            Session::Paused { .. } => DebugRun::Paused,
            Session::Executing { until: Until::ScanEnd, .. } => DebugRun::Scan,
            Session::Executing { until: Until::Breakpoint, .. } => DebugRun::Continue,
        }
    }

    #[inline]
    fn paused_at(self) -> Option<(TaskId, Breakpoint)> {
        match self {
            Session::Paused { at } => at,
            Session::Executing { .. } => None,
        }
    }

    /// `step` or `continue`: a breakpoint execution waited before is passed once; a resume
    /// while executing keeps the one not yet passed.
    #[inline]
    pub(super) fn resumed(self, until: Until) -> Session {
        let resume_from = match self {
            Session::Paused { at } => at.map(|(_, at)| at),
            Session::Executing { resume_from, .. } => resume_from,
        };
        Session::Executing { until, resume_from }
    }

    /// END processing finished a scan: a `step` pauses here, and what it resumed from is
    /// behind it either way.
    #[inline]
    pub(super) fn scan_ended(&mut self) {
        match self {
            Session::Executing { until: Until::ScanEnd, .. } => *self = Session::BETWEEN_SCANS,
            Session::Executing { resume_from, .. } => *resume_from = None,
            Session::Paused { .. } => {}
        }
    }

    /// Before instruction `at` of `task`: true, and paused there, if a breakpoint is set at it
    /// and it is not the one execution resumes from. That one is passed only as the next
    /// instruction looked at: any other look forgets it.
    pub(super) fn pauses_before(
        &mut self,
        task: TaskId,
        at: Breakpoint,
        debugger: &Debugger,
    ) -> bool {
        if let Session::Executing { resume_from, .. } = self {
            if resume_from.take() == Some(at) {
                return false;
            }
        }
        if !debugger.breakpoints.contains(&at) {
            return false;
        }
        *self = Session::Paused { at: Some((task, at)) };
        true
    }

    /// The session an online change carries over, at a scan boundary: the places it names
    /// (a breakpoint waited before, one to pass) are in the old programs, so they are dropped.
    pub(super) fn without_places(self) -> Session {
        match self {
            Session::Paused { .. } => Session::BETWEEN_SCANS,
            Session::Executing { until, .. } => Session::Executing { until, resume_from: None },
        }
    }
}

/// The debugger as [`Engine::debugger`](super::Engine::debugger) shows it: the breakpoints,
/// and the DEBUG session's state if the PLC is in DEBUG.
#[derive(Debug, Clone, Copy)]
pub struct DebugView<'a> {
    debugger: &'a Debugger,
    session: Option<Session>,
}

impl<'a> DebugView<'a> {
    pub(super) fn new(debugger: &'a Debugger, session: Option<Session>) -> DebugView<'a> {
        DebugView { debugger, session }
    }

    pub fn breakpoints(&self) -> &'a [Breakpoint] {
        &self.debugger.breakpoints
    }

    /// What the programs may do in DEBUG; [`DebugRun::Paused`] outside DEBUG.
    pub fn run_state(&self) -> DebugRun {
        self.session.map_or(DebugRun::Paused, Session::run_state)
    }

    /// The task and instruction execution waits before, if paused at a breakpoint.
    pub fn paused_at(&self) -> Option<(TaskId, Breakpoint)> {
        self.session.and_then(Session::paused_at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lang::{assemble, Context};
    use std::path::Path;

    fn program(name: &str, source: &str, edge_base: u32) -> Program {
        let base = |_n: u32| Some(100);
        let ctx = Context { is_init: false, task_numbers: &[], timer_base_ms: &base, edge_base };
        assemble(name, Path::new(&format!("{name}.il")), source, &ctx).unwrap()
    }

    fn programs() -> Vec<Program> {
        vec![
            program(
                "main",
                "; main\nLOAD P0000\nOUT P0040\nJMP 3\nLABEL 3\nCALL 1\nEND\nSBRT 1\nLABEL 3\nRET\n",
                0,
            ),
            program("other", "LOAD M0000\n\nOUT M0001\nLABEL 7\nEND\n", 0),
        ]
    }

    #[test]
    fn lines_labels_and_subroutines_resolve() {
        let p = programs();
        let at = |t: &str| resolve(&p, t).map(|b| describe(&p, b));
        assert_eq!(at("main:2"), Ok("main:2".into()));
        assert_eq!(resolve(&p, "main:2"), Ok(Breakpoint { program: 0, pc: 0 }));
        assert_eq!(at("other:3"), Ok("other:3".into()));
        assert_eq!(
            at("main:LABEL 3"),
            Err(BreakError::Ambiguous { what: "LABEL 3".into(), places: "main:5, main:9".into() })
        );
        assert_eq!(at("LABEL 7"), Ok("other:4".into()), "only one program has it");
        assert_eq!(at("label7"), Ok("other:4".into()));
        assert_eq!(at("main:SBRT 1"), Ok("main:8".into()));
        assert_eq!(at("SBRT 1"), Ok("main:8".into()));
    }

    #[test]
    fn bad_breakpoints_say_why() {
        let p = programs();
        assert_eq!(
            resolve(&p, "main:1"),
            Err(BreakError::NoInstruction { program: "main".into(), line: 1 })
        );
        assert_eq!(
            resolve(&p, "other:2"),
            Err(BreakError::NoInstruction { program: "other".into(), line: 2 })
        );
        assert_eq!(
            resolve(&p, "main:99"),
            Err(BreakError::NoInstruction { program: "main".into(), line: 99 })
        );
        assert_eq!(
            resolve(&p, "nope:3"),
            Err(BreakError::UnknownProgram("nope".into(), "main, other".into()))
        );
        assert_eq!(
            resolve(&p, "2").map(|b| describe(&p, b)),
            Ok("main:2".into()),
            "other:2 is blank, so only main fits"
        );
        assert_eq!(
            resolve(&p, "3"),
            Err(BreakError::Ambiguous { what: "line 3".into(), places: "main:3, other:3".into() })
        );
        assert!(matches!(resolve(&p, "LABEL 99"), Err(BreakError::NotFound(_))));
        assert!(matches!(resolve(&p, "main:x"), Err(BreakError::Syntax(_))));
        assert!(matches!(resolve(&p, "main:0"), Err(BreakError::Syntax(_))));
    }

    #[test]
    fn breakpoints_are_bounded_and_passed_once_on_resume() {
        let mut d = Debugger::default();
        for pc in 0..MAX_BREAKPOINTS as u32 {
            d.add(Breakpoint { program: 0, pc }).unwrap();
        }
        d.add(Breakpoint { program: 0, pc: 0 }).unwrap();
        assert_eq!(d.add(Breakpoint { program: 0, pc: 99 }), Err(BreakError::TooMany));
        let at = Breakpoint { program: 0, pc: 3 };
        let mut session = Session::BETWEEN_SCANS.resumed(Until::Breakpoint);
        assert!(session.pauses_before(2, at, &d));
        assert_eq!(session.paused_at(), Some((2, at)));
        assert_eq!(session.run_state(), DebugRun::Paused);
        session = session.resumed(Until::ScanEnd);
        assert_eq!(session.run_state(), DebugRun::Scan);
        assert!(
            !session.pauses_before(2, at, &d),
            "resuming executes the instruction it stopped before"
        );
        assert!(session.pauses_before(2, at, &d), "and stops there the next time");
        session = session.resumed(Until::ScanEnd);
        session.scan_ended();
        assert_eq!(session, Session::BETWEEN_SCANS, "a step pauses at the end of the scan");
        assert!(d.remove(at));
        assert!(!session.resumed(Until::Breakpoint).pauses_before(2, at, &d));
        assert!(d.watches(0) && !d.watches(1));
    }
}
