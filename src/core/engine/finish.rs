//! The end of the function block instances' life (`FB_exit`, docs/ST.md "FB_init and
//! FB_exit"): when a RUN ends (STOP from RUN or DEBUG, and so before a load, a reset, a
//! replacement and the daemon's shutdown, which all stop the PLC first) and when an online
//! change removes a program; and an online change's instances whose declaration changed
//! (`FB_exit` and `FB_init` with `bInCopyCode` TRUE, then `FB_reinit`: [`copied_instances`],
//! [`copied_globals`] for the global instances, `Engine::take_over`) or which it adds to a kept PROGRAM (`FB_init`: [`added_instances`]).
//!
//! Code runs only in a program's body, so the compiler gives each Structured Text PROGRAM an
//! *exit pass* (`compile/fb_exit.rs`): its body starts by testing hidden request flags. Here the
//! engine sets those flags and runs the bodies to their END outside any scan, each with the
//! execution state of a task that runs it (idle then), on a clock standing still: the
//! programs in reverse order, then the global instances. A pass is bounded by
//! [`FINISH_STEPS`] instructions (an `FB_exit` that loops forever must not hang the stop);
//! operation errors and system requests inside it are ignored, as the PLC is stopping.

use crate::clock::StepClock;
use crate::project::Project;
use crate::symbols::Entry;
use crate::value::{Elem, Pointer, Symbol};
use crate::vm::Exit;

use super::Engine;

/// The instructions an exit pass may execute.
pub const FINISH_STEPS: u64 = 10_000_000;

/// The name of a PROGRAM variable's copy flag after the PROGRAM's, in lower case
/// (`compile/fb_exit.rs`'s `copy_flag`).
const COPY_FLAG: &str = ".__fb_exit_copy_";

/// The name of a global instance's copy flag, in lower case (`compile/fb_exit.rs`'s
/// `global_copy_flag`): the global's name follows.
const GLOBAL_COPY_FLAG: &str = "__fb_exit_gcopy_";

/// Where the exit passes' request flags are, found by name in the compiled project.
#[derive(Debug, Default)]
pub(super) struct Finish {
    /// By program index: the program's `__FB_EXIT_REQUEST`, if it has an exit pass.
    requests: Box<[Option<(Pointer, Elem)>]>,
    /// `__FB_EXIT_GLOBALS_REQUEST`, if global instances have something to finish.
    globals: Option<(Pointer, Elem)>,
    /// By program index: the program's `__FB_EXIT_PHASE` (the phases of an online change).
    phases: Box<[Option<(Pointer, Elem)>]>,
    /// `__FB_EXIT_GLOBALS_PHASE`: the phases of an online change over global instances.
    globals_phase: Option<(Pointer, Elem)>,
    /// The global instances whose declaration an online change changes (prepared with it).
    pub(super) global_copies: Box<[CopiedGlobal]>,
    /// The programs of the running engine an online change removes (prepared with it).
    pub(super) removed: Box<[u16]>,
    /// The instances whose declaration an online change changes (prepared with it).
    pub(super) copies: Box<[CopiedInstance]>,
    /// The instances an online change adds to a kept PROGRAM (prepared with it): program and
    /// flag in the new engine.
    pub(super) added: Box<[(u16, (Pointer, Elem))]>,
}

/// A PROGRAM's variable an online change carries over into a changed declaration: its flag
/// (`__FB_EXIT_COPY_<name>`) in each engine, to select it for the phases.
#[derive(Debug, Clone, Copy)]
pub(super) struct CopiedInstance {
    old_program: u16,
    old_flag: (Pointer, Elem),
    new_program: u16,
    new_flag: (Pointer, Elem),
}

/// A global instance an online change carries over into a changed declaration: its flag
/// (`__FB_EXIT_GCOPY_<name>`) in the old engine and in the new.
#[derive(Debug, Clone, Copy)]
pub(super) struct CopiedGlobal {
    old_flag: (Pointer, Elem),
    new_flag: (Pointer, Elem),
}

/// The leaves of `project` whose lower-case name contains `flag`: an array whose name does
/// not contain it holds no flag that names a PROGRAM or global variable, and is not expanded.
fn naming<'a>(project: &'a Project, flag: &'a str) -> impl Iterator<Item = Symbol> + 'a {
    let entries = project.variables.symbols.entries().iter();
    entries.filter(move |e| e.name().to_ascii_lowercase().contains(flag)).flat_map(Entry::leaves)
}

/// The leaves under variable `var` (in lower case) of `project`: their names after `var`, in
/// lower case, and their types, sorted.
fn leaves(project: &Project, var: &str) -> Vec<(String, crate::value::ValueType)> {
    let mut found: Vec<(String, crate::value::ValueType)> = project
        .variables
        .symbols
        .may_start_with(var)
        .filter_map(|s| {
            let name = s.name.to_ascii_lowercase();
            let rest = name.strip_prefix(var)?;
            (rest.starts_with('.') || rest.starts_with('['))
                .then(|| (rest.to_string(), s.ty.clone()))
        })
        .collect();
    found.sort_by(|a, b| a.0.cmp(&b.0));
    found
}

/// The global instances with a life cycle (a copy flag in both projects) whose declaration
/// differs between `old` and `new` (not the same leaves, by name and type, under the global).
pub(super) fn copied_globals(old: &Project, new: &Project) -> Box<[CopiedGlobal]> {
    let mut out = Vec::new();
    for symbol in naming(new, GLOBAL_COPY_FLAG) {
        let lower = symbol.name.to_ascii_lowercase();
        let Some(var) = lower.strip_prefix(GLOBAL_COPY_FLAG) else { continue };
        let Some(before) = old.variable(&symbol.name) else { continue };
        if leaves(old, var) != leaves(new, var) {
            out.push(CopiedGlobal {
                old_flag: (before.at, before.ty.elem()),
                new_flag: (symbol.at, symbol.ty.elem()),
            });
        }
    }
    out.into_boxed_slice()
}

/// The PROGRAM variables with a life cycle (a copy flag) that `new` adds to a PROGRAM `old`
/// has, in a PROGRAM variable of a name `old` did not have: (new program, flag).
pub(super) fn added_instances(old: &Project, new: &Project) -> Box<[(u16, (Pointer, Elem))]> {
    let mut out = Vec::new();
    for symbol in naming(new, COPY_FLAG) {
        let lower = symbol.name.to_ascii_lowercase();
        let Some(at) = lower.find(COPY_FLAG) else { continue };
        let program = &lower[..at];
        let Some(new_program) =
            new.programs.iter().position(|p| p.name.eq_ignore_ascii_case(program))
        else {
            continue;
        };
        let kept = old.programs.iter().any(|p| p.name.eq_ignore_ascii_case(program));
        let var = format!("{program}.{}", &lower[at + COPY_FLAG.len()..]);
        // the variable itself, or a leaf under it
        let existed = old.variables.symbols.may_start_with(&var).any(|s| {
            let name = s.name.to_ascii_lowercase();
            name.strip_prefix(var.as_str())
                .is_some_and(|rest| rest.is_empty() || rest.starts_with(['.', '[']))
        });
        // a PROGRAM without FB_init before the change initialises all its instances at its
        // next scan (its hidden flag is new): not twice
        let initialised = old.variable(&format!("{program}.__fb_init_done")).is_some();
        if kept && initialised && !existed {
            out.push((new_program as u16, (symbol.at, symbol.ty.elem())));
        }
    }
    out.into_boxed_slice()
}

/// The PROGRAM variables with a life cycle (a copy flag in both projects) whose declaration
/// differs between `old` and `new`: not the same leaves, by name and type, under the variable.
pub(super) fn copied_instances(old: &Project, new: &Project) -> Box<[CopiedInstance]> {
    let program_of = |project: &Project, name: &str| {
        project.programs.iter().position(|p| p.name.eq_ignore_ascii_case(name)).map(|i| i as u16)
    };
    let mut out = Vec::new();
    for symbol in naming(new, COPY_FLAG) {
        let lower = symbol.name.to_ascii_lowercase();
        let Some(at) = lower.find(COPY_FLAG) else { continue };
        let (program, var) = (&lower[..at], &lower[at + COPY_FLAG.len()..]);
        let (Some(old_program), Some(new_program)) =
            (program_of(old, program), program_of(new, program))
        else {
            continue;
        };
        let Some(before) = old.variable(&symbol.name) else { continue };
        let path = format!("{program}.{var}");
        if leaves(old, &path) != leaves(new, &path) {
            out.push(CopiedInstance {
                old_program,
                old_flag: (before.at, before.ty.elem()),
                new_program,
                new_flag: (symbol.at, symbol.ty.elem()),
            });
        }
    }
    out.into_boxed_slice()
}

impl Finish {
    pub(super) fn of(project: &Project) -> Finish {
        let flag = |name: &str| project.variable(name).map(|s| (s.at, s.ty.elem()));
        let requests = project
            .programs
            .iter()
            .map(|p| flag(&format!("{}.__FB_EXIT_REQUEST", p.name)))
            .collect();
        let phases =
            project.programs.iter().map(|p| flag(&format!("{}.__FB_EXIT_PHASE", p.name))).collect();
        Finish {
            requests,
            globals: flag("__FB_EXIT_GLOBALS_REQUEST"),
            phases,
            globals_phase: flag("__FB_EXIT_GLOBALS_PHASE"),
            global_copies: Box::default(),
            removed: Box::default(),
            copies: Box::default(),
            added: Box::default(),
        }
    }
}

impl Engine {
    /// Runs every instance's `FB_exit` (`bInCopyCode` FALSE): the programs' in reverse order,
    /// then the global instances'. The tasks are idle (after `halt`). Allocates nothing.
    pub(super) fn finish_instances(&mut self, now: u64) {
        for p in (0..self.programs.len()).rev() {
            self.finish_program(p, false, now);
        }
        if self.finish.globals.is_some() {
            if let Some(p) = self.finish.requests.iter().position(Option::is_some) {
                self.finish_program(p, true, now);
            }
        }
    }

    /// Runs the exit passes of the programs an online change removes from this (the running)
    /// engine: those of `removed`, in reverse order. At a scan boundary. Allocates nothing.
    pub(super) fn finish_removed(&mut self, removed: &[u16], now: u64) {
        for &p in removed.iter().rev() {
            self.finish_program(usize::from(p), false, now);
        }
    }

    /// Phase `phase` of an online change (see [`Finish::copies`]) over `copies`, in this engine
    /// (`old`: the running one, whose flags are the old ones). Allocates nothing.
    pub(super) fn copy_phase(
        &mut self,
        copies: &[CopiedInstance],
        old: bool,
        phase: u64,
        now: u64,
    ) {
        for copy in copies {
            let (p, (at, elem)) = if old {
                (copy.old_program, copy.old_flag)
            } else {
                (copy.new_program, copy.new_flag)
            };
            let Some(Some((phase_at, phase_elem))) = self.finish.phases.get(usize::from(p)) else {
                continue;
            };
            let (phase_at, phase_elem) = (*phase_at, *phase_elem);
            self.vm.write_value(at, elem, 1);
            self.vm.write_value(phase_at, phase_elem, phase);
            self.run_pass(usize::from(p), now);
            self.vm.write_value(phase_at, phase_elem, 0);
            self.vm.write_value(at, elem, 0);
        }
    }

    /// Phase `phase` of an online change over the global instances `copies` (see
    /// [`Finish::global_copies`]), in this engine (`old`: the running one): all selected at
    /// once, in the exit pass of the first program that has one. Allocates nothing.
    pub(super) fn copy_globals_phase(
        &mut self,
        copies: &[CopiedGlobal],
        old: bool,
        phase: u64,
        now: u64,
    ) {
        let Some((phase_at, phase_elem)) = self.finish.globals_phase else { return };
        let Some(p) = self.finish.requests.iter().position(Option::is_some) else { return };
        if copies.is_empty() {
            return;
        }
        let flag = |copy: &CopiedGlobal| if old { copy.old_flag } else { copy.new_flag };
        for (at, elem) in copies.iter().map(flag) {
            self.vm.write_value(at, elem, 1);
        }
        self.vm.write_value(phase_at, phase_elem, phase);
        self.run_pass(p, now);
        self.vm.write_value(phase_at, phase_elem, 0);
        for (at, elem) in copies.iter().map(flag) {
            self.vm.write_value(at, elem, 0);
        }
    }

    /// The `FB_init` of the instances an online change added to kept PROGRAMs (phase 4), in
    /// this, the new engine. Allocates nothing.
    pub(super) fn init_added(&mut self, added: &[(u16, (Pointer, Elem))], now: u64) {
        for &(p, (at, elem)) in added {
            let Some(Some((phase_at, phase_elem))) = self.finish.phases.get(usize::from(p)) else {
                continue;
            };
            let (phase_at, phase_elem) = (*phase_at, *phase_elem);
            self.vm.write_value(at, elem, 1);
            self.vm.write_value(phase_at, phase_elem, 4);
            self.run_pass(usize::from(p), now);
            self.vm.write_value(phase_at, phase_elem, 0);
            self.vm.write_value(at, elem, 0);
        }
    }

    /// Program `p`'s exit pass: its own instances, or (`globals`) the global instances.
    fn finish_program(&mut self, p: usize, globals: bool, now: u64) {
        let flag = if globals { self.finish.globals } else { self.finish.requests[p] };
        let Some((at, elem)) = flag else { return };
        self.vm.write_value(at, elem, 1);
        self.run_pass(p, now);
        // a pass cut short leaves its flag: it must not run at the next scan
        self.vm.write_value(at, elem, 0);
    }

    /// Runs program `p`'s body to its END (the flags it tests set), with the execution state
    /// of a task that runs it, on a clock standing still at `now`.
    fn run_pass(&mut self, p: usize, now: u64) {
        let Some(task) = self.tasks.iter_mut().find(|t| t.programs.contains(&(p as u16))) else {
            return;
        };
        let clock = StepClock { origin_ns: now, origin_steps: 0, step_ns: 0 };
        let program = &self.programs[p];
        task.exec.restart();
        let limit = self.vm.steps().saturating_add(FINISH_STEPS);
        loop {
            let left = limit.saturating_sub(self.vm.steps());
            if left == 0 {
                break;
            }
            match self.vm.run(program, &mut task.exec, &clock, left) {
                Exit::End | Exit::Budget => break,
                Exit::System(_) | Exit::OperationError { .. } => {}
            }
        }
        task.exec.restart();
    }
}
