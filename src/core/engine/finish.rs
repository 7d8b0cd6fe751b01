//! The end of the function block instances' life (`FB_exit`, docs/ST.md "FB_init and
//! FB_exit"): when a RUN ends (STOP from RUN or DEBUG, and so before a load, a reset, a
//! replacement and the daemon's shutdown, which all stop the PLC first) and when an online
//! change removes a program.
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
use crate::value::{Elem, Pointer};
use crate::vm::Exit;

use super::Engine;

/// The instructions an exit pass may execute.
pub const FINISH_STEPS: u64 = 10_000_000;

/// Where the exit passes' request flags are, found by name in the compiled project.
#[derive(Debug, Default)]
pub(super) struct Finish {
    /// By program index: the program's `__FB_EXIT_REQUEST`, if it has an exit pass.
    requests: Box<[Option<(Pointer, Elem)>]>,
    /// `__FB_EXIT_GLOBALS_REQUEST`, if global instances have something to finish.
    globals: Option<(Pointer, Elem)>,
    /// The programs of the running engine an online change removes (prepared with it).
    pub(super) removed: Box<[u16]>,
}

impl Finish {
    pub(super) fn of(project: &Project) -> Finish {
        let flag = |name: &str| project.variable(name).map(|s| (s.at, s.ty.elem()));
        let requests = project
            .programs
            .iter()
            .map(|p| flag(&format!("{}.__FB_EXIT_REQUEST", p.name)))
            .collect();
        Finish { requests, globals: flag("__FB_EXIT_GLOBALS_REQUEST"), removed: Box::default() }
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

    /// Program `p`'s exit pass: its own instances, or (`globals`) the global instances.
    fn finish_program(&mut self, p: usize, globals: bool, now: u64) {
        let flag = if globals { self.finish.globals } else { self.finish.requests[p] };
        let Some((at, elem)) = flag else { return };
        let Some(task) = self.tasks.iter_mut().find(|t| t.programs.contains(&(p as u16))) else {
            return;
        };
        self.vm.write_value(at, elem, 1);
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
        // a pass cut short leaves its flag: it must not run at the next scan
        self.vm.write_value(at, elem, 0);
    }
}
