//! DEBUG mode (XGB §5.2): the programs run only when the engineer says so — one scan at a
//! time (`step`), or until a breakpoint (`continue`) — and stop *before* a breakpoint's
//! instruction with device memory as that instruction will see it.
//!
//! This module owns the breakpoint syntax, its resolution against the loaded programs, the
//! breakpoints (kept across DEBUG sessions) and the state of a DEBUG session, which only the
//! engine's DEBUG mode holds. The engine asks `Session::pauses_before` before each instruction
//! while a breakpoint is set in the program it executes; without breakpoints the VM runs at full
//! speed even in DEBUG.

use std::path::Path;

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
    #[error("`{0}` is not a breakpoint: write PROGRAM:LINE, FILE:LINE, PROGRAM:LABEL n, PROGRAM:SBRT n, or leave the program out when only one fits")]
    Syntax(String),
    #[error("no program or program file is called \"{0}\" (programs: {1})")]
    UnknownProgram(String, String),
    #[error("{program}:{line} has no statement (a comment, a declaration, a blank line, or beyond the end)")]
    NoInstruction { program: String, line: u32 },
    #[error("no program has {0}")]
    NotFound(String),
    #[error("{what} is in more than one place ({places}): name the program, PROGRAM:{what}")]
    Ambiguous { what: String, places: String },
    #[error("`{name}` is more than one file ({places}): write more of its path")]
    AmbiguousFile { name: String, places: String },
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

/// The first statement at `line` of `file` in `program`, if the program has code there.
fn statement_at(program: &Program, file: &Path, line: u32) -> Option<u32> {
    program
        .statements
        .iter()
        .copied()
        .find(|&pc| program.line_of(pc as usize) == line && program.file_of(pc as usize) == file)
}

/// The instructions `target` names in `program`; a line in the program's own file.
fn find(program: &Program, target: Target) -> Vec<u32> {
    match target {
        Target::Line(line) => statement_at(program, &program.path, line).into_iter().collect(),
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

/// The source files `name` may mean: the files of the programs' code whose path is `name` or
/// ends with it (`main.st`, `st/main.st`, the full path), each once.
fn files_named<'p>(programs: &'p [Program], name: &str) -> Vec<&'p Path> {
    let wanted = Path::new(name);
    let mut files: Vec<&Path> = Vec::new();
    for program in programs {
        let own = std::iter::once(program.path.as_path());
        for file in own.chain(program.regions.iter().map(|(_, f)| f.as_path())) {
            if file.ends_with(wanted) && !files.contains(&file) {
                files.push(file);
            }
        }
    }
    files
}

/// Resolves a breakpoint text against the programs: `PROGRAM:LINE`, `FILE:LINE`,
/// `PROGRAM:LABEL n`, `PROGRAM:SBRT n`, or a line, label or subroutine without `PROGRAM:` when
/// exactly one program has it. A line stops before its first statement. `FILE:LINE` names a
/// line of a source file wherever its code runs: a FUNCTION or FUNCTION_BLOCK of a Structured
/// Text file is compiled into every program that calls it, so it may be several instructions,
/// one per program. `PROGRAM:` is tried before `FILE:`.
pub fn resolve(programs: &[Program], text: &str) -> Result<Vec<Breakpoint>, BreakError> {
    let syntax = || BreakError::Syntax(text.to_string());
    let (place, target) = match text.rsplit_once(':') {
        Some((name, rest)) => (Some(name.trim()), parse_target(rest).ok_or_else(syntax)?),
        None => (None, parse_target(text).ok_or_else(syntax)?),
    };
    let candidates: Vec<usize> = match place {
        Some(name) => match programs.iter().position(|p| p.name == name) {
            Some(index) => vec![index],
            None => return resolve_in_file(programs, name, target, text),
        },
        None => (0..programs.len()).collect(),
    };
    let mut found = Vec::new();
    for &index in &candidates {
        for pc in find(&programs[index], target) {
            found.push(Breakpoint { program: index as u16, pc });
        }
    }
    match (found.len(), target, place) {
        (1, _, _) => Ok(found),
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

/// `FILE:LINE`: the line's first statement in every program whose code comes from the file.
fn resolve_in_file(
    programs: &[Program],
    name: &str,
    target: Target,
    text: &str,
) -> Result<Vec<Breakpoint>, BreakError> {
    let files = files_named(programs, name);
    if files.is_empty() {
        let names: Vec<&str> = programs.iter().map(|p| p.name.as_str()).collect();
        return Err(BreakError::UnknownProgram(name.to_string(), names.join(", ")));
    }
    if files.len() > 1 {
        let places: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
        return Err(BreakError::AmbiguousFile {
            name: name.to_string(),
            places: places.join(", "),
        });
    }
    let Target::Line(line) = target else { return Err(BreakError::Syntax(text.to_string())) };
    let found: Vec<Breakpoint> = programs
        .iter()
        .enumerate()
        .filter_map(|(index, program)| {
            let pc = statement_at(program, files[0], line)?;
            Some(Breakpoint { program: index as u16, pc })
        })
        .collect();
    if found.is_empty() {
        return Err(BreakError::NoInstruction { program: name.to_string(), line });
    }
    Ok(found)
}

/// Where an instruction is, as a breakpoint is written: `PROGRAM:LINE` for the instruction
/// list, `FILE:LINE` (the file's name) for Structured Text.
pub fn describe(programs: &[Program], at: Breakpoint) -> String {
    let Some(p) = programs.get(at.program as usize) else {
        return format!("#{}:{}", at.program, at.pc);
    };
    let line = p.line_of(at.pc as usize);
    match p.language {
        crate::lang::Language::InstructionList => format!("{}:{line}", p.name),
        crate::lang::Language::StructuredText => {
            let file = p.file_of(at.pc as usize);
            let name = file.file_name().unwrap_or(file.as_os_str());
            format!("{}:{line}", name.to_string_lossy())
        }
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
    /// To the end of the current (or the next) scan, or to a breakpoint: `step` between two
    /// scans, `step --scan`.
    ScanEnd,
    /// Scan after scan, to a breakpoint: `continue`.
    Breakpoint,
    /// `step` from a pause before an instruction: to the next statement of `task` on another
    /// line than `from`, at a call depth of at most `depth` (calls are stepped over), or to a
    /// breakpoint. When the task's programs end first, to the end of the scan.
    NextLine { task: TaskId, from: Breakpoint, depth: u32 },
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
            Session::Executing { until: Until::ScanEnd | Until::NextLine { .. }, .. } => {
                DebugRun::Scan
            }
            Session::Executing { until: Until::Breakpoint, .. } => DebugRun::Continue,
        }
    }

    /// The task and instruction execution waits before, if paused inside a program.
    #[inline]
    pub(super) fn paused_at(self) -> Option<(TaskId, Breakpoint)> {
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
            Session::Executing { until: Until::ScanEnd | Until::NextLine { .. }, .. } => {
                *self = Session::BETWEEN_SCANS
            }
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

    /// True while a line step runs in `task`: the engine then executes it one instruction at
    /// a time.
    #[inline]
    pub(super) fn steps_lines_of(self, task: TaskId) -> bool {
        matches!(self, Session::Executing { until: Until::NextLine { task: t, .. }, .. } if t == task)
    }

    /// Before instruction `at` of `task`, at call depth `depth`, during a line step: true, and
    /// paused there, if it starts a statement of `task` on another line than the one the step
    /// started from (another program, file or line), no deeper in calls.
    pub(super) fn pauses_at_line(
        &mut self,
        task: TaskId,
        at: Breakpoint,
        depth: u32,
        programs: &[Program],
    ) -> bool {
        let Session::Executing {
            until: Until::NextLine { task: t, from, depth: from_depth }, ..
        } = *self
        else {
            return false;
        };
        if t != task || depth > from_depth {
            return false;
        }
        let Some(program) = programs.get(at.program as usize) else { return false };
        if !program.starts_statement(at.pc) {
            return false;
        }
        let same_line = at.program == from.program && {
            let (pc, from_pc) = (at.pc as usize, from.pc as usize);
            program.line_of(pc) == program.line_of(from_pc)
                && program.file_of(pc) == program.file_of(from_pc)
        };
        if same_line {
            return false;
        }
        *self = Session::Paused { at: Some((task, at)) };
        true
    }

    /// The task executing a line step finished its programs: the step runs to the end of the
    /// scan.
    pub(super) fn task_finished(&mut self, task: TaskId) {
        if let Session::Executing { until: until @ Until::NextLine { .. }, .. } = self {
            if matches!(until, Until::NextLine { task: t, .. } if *t == task) {
                *until = Until::ScanEnd;
            }
        }
    }

    /// The session an online change carries over, at a scan boundary: the places it names
    /// (a breakpoint waited before, one to pass) are in the old programs, so they are dropped.
    pub(super) fn without_places(self) -> Session {
        match self {
            Session::Paused { .. } => Session::BETWEEN_SCANS,
            Session::Executing { until: Until::NextLine { .. }, .. } => {
                Session::Executing { until: Until::ScanEnd, resume_from: None }
            }
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
        assemble(name, Path::new(&format!("dir/{name}.il")), source, &ctx).unwrap()
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
        let at = |t: &str| resolve(&p, t).map(|b| describe(&p, b[0]));
        assert_eq!(at("main:2"), Ok("main:2".into()));
        assert_eq!(resolve(&p, "main:2"), Ok(vec![Breakpoint { program: 0, pc: 0 }]));
        assert_eq!(at("main.il:3"), Ok("main:3".into()), "the file's name");
        assert_eq!(at("dir/other.il:3"), Ok("other:3".into()), "more of its path");
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
            resolve(&p, "2").map(|b| describe(&p, b[0])),
            Ok("main:2".into()),
            "other:2 is blank, so only main fits"
        );
        assert_eq!(
            resolve(&p, "3"),
            Err(BreakError::Ambiguous { what: "line 3".into(), places: "main:3, other:3".into() })
        );
        assert!(matches!(resolve(&p, "LABEL 99"), Err(BreakError::NotFound(_))));
        assert!(matches!(resolve(&p, "main:x"), Err(BreakError::Syntax(_))));
        assert_eq!(
            resolve(&p, "nope.st:3"),
            Err(BreakError::UnknownProgram("nope.st".into(), "main, other".into()))
        );
        assert_eq!(
            resolve(&p, "other.il:2"),
            Err(BreakError::NoInstruction { program: "other.il".into(), line: 2 })
        );
        assert!(matches!(resolve(&p, "main.il:LABEL 3"), Err(BreakError::Syntax(_))));
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
