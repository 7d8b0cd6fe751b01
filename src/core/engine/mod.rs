//! The task engine: decides what runs when, per XGB chapter 5 and the Hitachi congestion rules.
//!
//! It is pure. Time comes from an injected [`Clock`]; events come from its driver
//! ([`Engine::input_edge`], [`Engine::set_mode`], [`Engine::write`], and [`Engine::poll_time`]
//! for time-driven work: cycle deadlines, the scan watchdog, congestion). [`Engine::run`]
//! executes instructions on the VM and preempts between two of them. The simulator
//! (`plcd sim`) and the real-time daemon drive this same engine.
//!
//! Scheduling rules, in one place:
//! - Priorities 2 (highest) to 7; the scan program is below all of them. A pending request of a
//!   higher priority than the executing task preempts it at the next instruction boundary,
//!   nested to any depth. Equal priority never preempts.
//! - Pending requests start by priority, then by request time, then — for requests at the same
//!   instant — in config order (XGB §5.1.3: "in sequence of XG5000 setting").
//! - A task holds at most one request: a request while it runs or waits is ignored.
//! - `DI` holds task starts (requests stay pending, one each); `EI` releases them.
//! - Internal-device conditions are sampled at END; their tasks, and every other pending task,
//!   run before the next scan starts.
//!
//! One `Engine`, its work divided by what it decides: `mode` (the operating modes and the moves
//! between them, the key switch), `schedule` (requests, dispatch, preemption, the system
//! requests of the programs, time-driven work), `scan` (a scan's start and END processing, the
//! I/O refresh points, watches) and `task` (the tasks and their figures). This file holds the
//! engine's state, its construction, its accessors and [`Engine::run`], which ties them
//! together. [`debug`], [`event`], [`force`] and [`online`] are the debugger, the events, forced
//! I/O and online change.
//!
//! The engine's state is typed so that a combination the rules never produce cannot be
//! written: the mode (`mode::ModeState`) carries what only that mode has — ERROR its error, RUN
//! and DEBUG the scan's phase, the init task's progress and `DI`, DEBUG its session — and the
//! key switch, the retained memory and the force flags each have a type of their own.

pub mod debug;
pub mod event;
pub mod force;
pub mod online;

mod finish;
mod mode;
mod scan;
mod schedule;
mod system_info;
mod task;

pub use mode::ModeRequest;
pub use scan::ScanStats;
pub use task::{task_names, TaskStats};

use crate::config::OnFault;
use crate::device::{Address, BitRef};
use crate::io::Io;
use crate::lang::Program;
use crate::project::{Project, Watched};
use crate::vm::{Clock, Exit, Vm};
use debug::{Breakpoint, DebugView, Debugger};
use event::{ErrorKind, Event, EventSink, Mode, TaskId};
use force::Forces;
use mode::{KeySwitch, ModeState};
use scan::{Phase, Watch};
use task::{State, Task};

const NS_PER_MS: u64 = 1_000_000;
/// How often inputs are refreshed in STOP and ERROR.
const STOP_REFRESH_NS: u64 = 10 * NS_PER_MS;

/// Why a request was not carried out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    #[error("the RUN/STOP switch is at RUN (local mode): remote mode changes need it at STOP")]
    SwitchAtRun,
    #[error("the PLC is in ERROR: clear the error first (reset, or STOP)")]
    ErrorLatched,
    #[error("only in DEBUG mode")]
    NotInDebug,
    #[error("execution is paused inside a scan: step to its end first")]
    MidScan,
    #[error("the PLC is in RUN: stop it first, or change online")]
    Running,
    #[error("at most 32 breakpoints")]
    TooManyBreakpoints,
}

/// What [`Engine::run`] leaves behind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Activity {
    /// The step budget is spent with work left.
    Busy,
    /// Nothing to execute until an event or [`Engine::next_wakeup`].
    Idle,
}

/// Why [`Engine::run`] returns to its driver with work left and budget to spare: one reason
/// from each side of the call. They are independent (either, both or neither may hold), so
/// they are two fields, not one enum.
#[derive(Debug, Clone, Copy, Default)]
struct HandBack {
    /// The engine's, consumed by the return: a task with a congestion limit started, and its
    /// limit may fall before the wake-up the driver planned, so the driver plans again.
    replan: bool,
    /// The driver's, until it withdraws it ([`Engine::set_hold_at_end`]): it has commands to
    /// apply at END processing, so `run` returns at each scan boundary.
    at_scan_end: bool,
}

/// What the retained devices hold (docs/RETAIN.md): it decides whether a RUN start keeps
/// them (warm) or clears them with the rest (cold). A RUN makes them worth keeping; only
/// clearing the memory makes them not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Retained {
    /// Nothing to keep: a fresh engine never restored, or `reset --cold`. The next RUN start is
    /// cold.
    Cold,
    /// Values to keep: restored at start, inherited from the engine this one replaces, or
    /// written by a RUN since the memory was last cleared. The next RUN start is warm.
    Warm,
}

/// The engine's settings, from `[plc]`.
#[derive(Debug, Clone, Copy)]
struct Settings {
    watchdog_ns: u64,
    watchdog_ms: u32,
    on_fault: OnFault,
    scan_period_ns: u64,
    continue_on_congestion: bool,
}

/// The task engine.
pub struct Engine {
    programs: Vec<Program>,
    vm: Vm,
    tasks: Vec<Task>,
    /// Active tasks, bottom to top; the top one executes.
    stack: Vec<TaskId>,
    /// The mode, with what only that mode has.
    mode: ModeState,
    settings: Settings,
    run_start_ns: u64,
    scan_start_ns: u64,
    watchdog_start_ns: u64,
    next_scan_ns: u64,
    next_stop_refresh_ns: u64,
    scan: ScanStats,
    watches: Vec<Watch>,
    /// Prepared for an online change: the variables this engine keeps from the one it takes
    /// over (`online::kept_variables`).
    kept_variables: Box<[(u32, u32, u32)]>,
    hand_back: HandBack,
    forces: Forces,
    debugger: Debugger,
    /// The key switch, if a `[switch]` is configured.
    switch: Option<KeySwitch>,
    /// The last operation error since RUN.
    last_operation_error: Option<ErrorKind>,
    /// Cycle deadlines noticed a full interval or more after they passed, since RUN.
    missed_deadlines: u64,
    /// What `[retain]` keeps across RUN starts and restarts (docs/RETAIN.md).
    retain: crate::device::RetainSet,
    /// Whether the retained devices hold values to keep, which the next RUN start honours.
    retained: Retained,
    /// The retained Structured Text variables, a record per leaf or array; shared with the
    /// retain writer's copies.
    retained_variables: std::sync::Arc<crate::vm::retained::RetainedVariables>,
    /// The exit passes of the programs (`FB_exit`).
    finish: finish::Finish,
    /// Where TwinCAT's task information goes, when the project has it (`system_info`).
    system_info: Option<Box<system_info::SystemInfo>>,
    /// The `BOOL`s of variable memory the programs' native code reads as they are
    /// ([`crate::lang::bool_variables`]): rewritten to 0 or 1 after bytes are copied in.
    bool_variables: Box<[u32]>,
}

impl Engine {
    /// An engine for `project`, in STOP; `watch` lists the devices and variables whose changes
    /// are reported as `set` events.
    pub fn new<W>(project: &Project, watch: &[W]) -> Engine
    where
        for<'w> &'w W: Into<Watched>,
    {
        let config = &project.config;
        let mut vm = Vm::for_programs(&project.programs);
        vm.set_variables(&project.variables);
        let mut tasks = task::tasks_of(config);
        // Each task's frame area holds the deepest Structured Text call chain of any program
        // (a task may run several), allocated once here.
        let frame_bytes = project.frame_bytes();
        if frame_bytes > 0 {
            for task in &mut tasks {
                task.exec = crate::vm::ExecState::with_frame(frame_bytes);
            }
        }
        let plc = &config.plc;
        let capacity = tasks.len();
        Engine {
            programs: project.programs.clone(),
            vm,
            tasks,
            stack: Vec::with_capacity(capacity),
            mode: ModeState::Stop,
            settings: Settings {
                watchdog_ns: u64::from(plc.watchdog_ms) * NS_PER_MS,
                watchdog_ms: plc.watchdog_ms,
                on_fault: plc.on_fault,
                scan_period_ns: u64::from(plc.scan_period_ms) * NS_PER_MS,
                continue_on_congestion: plc.continue_on_congestion,
            },
            run_start_ns: 0,
            scan_start_ns: 0,
            watchdog_start_ns: 0,
            next_scan_ns: 0,
            next_stop_refresh_ns: 0,
            scan: ScanStats::default(),
            watches: watch.iter().map(|w| Watch::new(&w.into())).collect(),
            kept_variables: Box::default(),
            hand_back: HandBack::default(),
            forces: Forces::default(),
            debugger: Debugger::default(),
            switch: config.switch.as_ref().map(|_| KeySwitch::default()),
            last_operation_error: None,
            missed_deadlines: 0,
            retain: crate::device::RetainSet::new(&config.retain.ranges),
            retained: Retained::Cold,
            retained_variables: std::sync::Arc::new(crate::vm::retained::RetainedVariables::new(
                &project.variables,
            )),
            finish: finish::Finish::of(project),
            system_info: system_info::SystemInfo::of(project, capacity),
            bool_variables: {
                let mut all: Vec<u32> =
                    project.programs.iter().flat_map(crate::lang::bool_variables).collect();
                all.sort_unstable();
                all.dedup();
                all.into_boxed_slice()
            },
        }
    }

    /// The retained words (K and the `[retain]` ranges).
    pub fn retain_set(&self) -> &crate::device::RetainSet {
        &self.retain
    }

    /// Restores retained memory at start (the words as [`crate::device::RetainSet::capture`]
    /// lays them out, of a generation whose layout matches): the next RUN start is warm.
    pub fn restore_retained(&mut self, words: &[u16]) {
        self.retain.restore(words, self.vm.mem.words_mut());
        self.retained = Retained::Warm;
    }

    /// A replacement engine (reload, `plcctl load`) takes the retained devices of the one it
    /// replaces, so that a new program does not reset a counter: copies the retained bits of
    /// `old`'s memory, its retained variables whose name and type the new programs retain too
    /// (the others start from their initial values), and whether they are worth keeping. No
    /// allocation (the scan thread calls it).
    pub fn inherit_retained(&mut self, old: &Engine) {
        let (from, to) = (old.vm.mem.words(), self.vm.mem.words_mut());
        for r in self.retain.words.iter() {
            for i in usize::from(r.start)..usize::from(r.end) {
                to[i] = (to[i] & !r.mask) | (from[i] & r.mask);
            }
        }
        let vm = &mut self.vm;
        self.retained_variables.for_each_same(&old.retained_variables, |new, was, len| {
            vm.copy_variable_from(&old.vm, was, new, len)
        });
        // `old`'s programs may have written other bytes there (a UNION's)
        self.vm.canonicalize_bools(&self.bool_variables);
        self.retained = old.retained;
    }

    /// The retained Structured Text variables (docs/RETAIN.md), a record per leaf or array.
    pub fn retained_variables(&self) -> &std::sync::Arc<crate::vm::retained::RetainedVariables> {
        &self.retained_variables
    }

    /// Restores retained variables at start from `saved` (a retain file's, restored with its
    /// device words by [`Engine::restore_retained`]): each into the variable of the same name
    /// and type (an array: its elements at the indices both have). What was restored, dropped and left at its initial value, for the log.
    pub fn restore_retained_variables(
        &mut self,
        saved: &[crate::vm::retained::SavedVariable],
    ) -> crate::vm::retained::RestorePlan {
        let plan = self.retained_variables.plan_restore(saved);
        let vm = &mut self.vm;
        self.retained_variables.restore(&plan, saved, |at, bytes| vm.restore_variable(at, bytes));
        self.vm.canonicalize_bools(&self.bool_variables);
        self.retained = Retained::Warm;
        plan
    }

    /// Task names by [`TaskId`], for traces.
    pub fn task_names(&self) -> Vec<String> {
        self.tasks.iter().map(|t| t.name.clone()).collect()
    }

    /// The programs, by the index error events use.
    pub fn programs(&self) -> &[Program] {
        &self.programs
    }

    pub fn mode(&self) -> Mode {
        self.mode.mode()
    }

    pub fn vm(&self) -> &Vm {
        &self.vm
    }

    /// Instructions executed so far.
    pub fn steps(&self) -> u64 {
        self.vm.steps()
    }

    pub fn scan_stats(&self) -> &ScanStats {
        &self.scan
    }

    /// Figures of a task, by name.
    pub fn task_stats(&self, name: &str) -> Option<&TaskStats> {
        self.tasks.iter().find(|t| t.name == name).map(|t| &t.stats)
    }

    /// Figures of every task by [`TaskId`] (the order of [`Engine::task_names`]).
    pub fn all_task_stats(&self) -> impl Iterator<Item = &TaskStats> {
        self.tasks.iter().map(|t| &t.stats)
    }

    /// The scan watchdog time in ns (`[plc] watchdog_ms`).
    pub fn watchdog_ns(&self) -> u64 {
        self.settings.watchdog_ns
    }

    /// The breakpoints and, in DEBUG, where the session stands; a view, because the session
    /// lives in the mode and ends with DEBUG.
    pub fn debugger(&self) -> DebugView<'_> {
        let session = match self.mode {
            ModeState::Debug(_, session) => Some(session),
            ModeState::Stop | ModeState::Error(_) | ModeState::Run(_) => None,
        };
        DebugView::new(&self.debugger, session)
    }

    /// Breakpoints are set and removed here (resolved with [`debug::resolve`]).
    pub fn debugger_mut(&mut self) -> &mut Debugger {
        &mut self.debugger
    }

    /// Forces P bit `bit` to `on` from the next refresh on.
    pub fn force(&mut self, bit: BitRef, on: bool, io: &impl Io) {
        self.forces.set(bit, on, io.is_input(bit));
    }

    /// A replacement engine (a reload, a load, an online change in STOP) keeps the forces of the
    /// one it replaces, as an online change in RUN does: a force is the operator's, set for a
    /// reason on the machine, and a new program must not release it unasked. Each force is set
    /// again as an input or an output of `io`, the field the new engine runs with. No
    /// allocation (the scan thread calls it).
    pub fn inherit_forces(&mut self, old: &Engine, io: &impl Io) {
        self.forces.clear_all();
        for (address, on) in old.forces.iter() {
            if let Ok(bit) = force::io_bit(&address) {
                self.force(bit, on, io);
            }
        }
    }

    /// Removes a force; true if the bit was forced.
    pub fn unforce(&mut self, bit: BitRef) -> bool {
        self.forces.clear(bit)
    }

    pub fn unforce_all(&mut self) {
        self.forces.clear_all();
    }

    pub fn forces(&self) -> &Forces {
        &self.forces
    }

    /// Asks [`Engine::run`] to hand back at the next scan boundary (the driver has commands
    /// to apply at END processing), or stops asking.
    pub fn set_hold_at_end(&mut self, hold: bool) {
        self.hand_back.at_scan_end = hold;
    }

    /// The error latched in ERROR mode.
    pub fn latched_error(&self) -> Option<ErrorKind> {
        match self.mode {
            ModeState::Error(kind) => Some(kind),
            ModeState::Stop | ModeState::Run(_) | ModeState::Debug(..) => None,
        }
    }

    /// The last operation error since RUN started.
    pub fn last_operation_error(&self) -> Option<ErrorKind> {
        self.last_operation_error
    }

    /// Cycle deadlines noticed a full interval or more after they passed, since RUN: periods
    /// the driver did not look at the clock (its thread starved or preempted), whatever
    /// became of the requests (a late request is still served or counted as an overrun).
    pub fn missed_deadlines(&self) -> u64 {
        self.missed_deadlines
    }

    /// The current scan number (scans started since RUN).
    pub fn scan_count(&self) -> u64 {
        self.scan.count
    }

    /// Writes a device from outside the program (a stimulus, later the control socket).
    pub fn write(&mut self, address: &Address, value: i32) {
        self.vm.mem.write(address, value);
    }

    /// Writes the bits of `mask` of word `word` (an index of device memory) from `value`;
    /// an index beyond device memory is ignored.
    pub fn write_masked(&mut self, word: u16, mask: u16, value: u16) {
        if u32::from(word) < crate::device::layout::TOTAL_WORDS {
            let at = crate::device::WordRef(word);
            let old = self.vm.mem.word(at);
            self.vm.mem.set_word(at, (old & !mask) | (value & mask));
        }
    }

    /// Writes a Structured Text variable from outside the program (the control socket):
    /// `slot` as `elem` at `at`, as the program would store it (a located variable writes its
    /// device words). Allocates nothing.
    pub fn write_value(&mut self, at: crate::value::Pointer, elem: crate::value::Elem, slot: u64) {
        self.vm.write_value(at, elem, slot);
    }

    /// Writes the `STRING[cap]` variable at `at` from outside the program, cut to `cap`
    /// characters. Allocates nothing.
    pub fn write_string(&mut self, at: crate::value::Pointer, cap: u32, chars: &[u8]) {
        self.vm.write_string(at, cap, chars);
    }

    /// Writes the `WSTRING[cap]` variable at `at` from outside the program: the code units
    /// `bytes` (2 a unit, little-endian), cut to `cap` of them. Allocates nothing.
    pub fn write_wstring(&mut self, at: crate::value::Pointer, cap: u32, bytes: &[u8]) {
        self.vm.write_wstring(at, cap, bytes);
    }

    /// Executes at most `max_steps` instructions: starts and preempts tasks, runs scans, END
    /// processing and I/O refresh.
    pub fn run<C: Clock>(
        &mut self,
        clock: &C,
        io: &mut impl Io,
        sink: &mut impl EventSink,
        max_steps: u64,
    ) -> Activity {
        let limit = self.vm.steps().saturating_add(max_steps);
        loop {
            if !self.executing() {
                return Activity::Idle;
            }
            let now = clock.now_ns(self.vm.steps());
            self.dispatch(now, sink);
            if std::mem::take(&mut self.hand_back.replan) {
                return Activity::Busy;
            }
            let Some(&top) = self.stack.last() else {
                match self.phase() {
                    Phase::AfterEnd { .. } => {
                        self.finish_scan(now, io, sink);
                        if self.hand_back.at_scan_end {
                            return Activity::Busy;
                        }
                    }
                    Phase::Idle if now >= self.next_scan_ns => self.start_scan(now, io, sink),
                    _ => return Activity::Idle,
                }
                continue;
            };
            let steps = self.vm.steps();
            if steps >= limit {
                return Activity::Busy;
            }
            let task = &mut self.tasks[top as usize];
            if let State::Active { preempted: true } = task.state {
                task.state = State::Active { preempted: false };
                sink.event(now, Event::TaskResume { task: top });
            }
            let program_index = task.programs[task.current];
            let program = &self.programs[program_index as usize];
            let mut budget = limit - steps;
            if let ModeState::Debug(running, session) = &mut self.mode {
                let stepping = session.steps_lines_of(top);
                if stepping || self.debugger.watches(program_index) {
                    // One instruction at a time, so that a breakpoint or a line step stops
                    // before its instruction.
                    let at = Breakpoint { program: program_index, pc: task.exec.pc() };
                    let depth = task.exec.call_depth();
                    if session.pauses_before(top, at, &self.debugger)
                        || session.pauses_at_line(top, at, depth, &self.programs)
                    {
                        running.phase.pause();
                        return Activity::Idle;
                    }
                    budget = 1;
                }
            }
            if let Some(info) = &self.system_info {
                info.running(&mut self.vm, usize::from(top));
            }
            let exit = self.vm.run(program, &mut task.exec, clock, budget);
            let after = clock.now_ns(self.vm.steps());
            task.used_ns += after - now;
            match exit {
                Exit::Budget => return Activity::Busy,
                Exit::End => self.program_end(top, after, sink),
                Exit::System(request) => self.system(top, request, after, io, sink),
                Exit::OperationError { code, pc } => {
                    let kind = ErrorKind::Operation { code, task: top, program: program_index, pc };
                    self.last_operation_error = Some(kind);
                    sink.event(after, Event::Error(kind));
                }
            }
        }
    }
}
