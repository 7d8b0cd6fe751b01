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

pub mod debug;
pub mod event;
pub mod force;
pub mod online;

use crate::config::{Config, DeviceCondition, Edge, OnFault, TaskKind as ConfigTaskKind, TaskRef};
use crate::device::{Address, BitRef, Memory, WordRef};
use crate::io::{Io, SwitchPosition};
use crate::lang::ops::SystemRequest;
use crate::lang::Program;
use crate::project::Project;
use crate::stats::Histogram;
use crate::vm::{Clock, ExecState, Exit, Vm};
use debug::{Breakpoint, DebugRun, Debugger};
use event::{ErrorKind, Event, EventSink, Ignored, Mode, TaskId, INIT, SCAN};
use force::Forces;

const NS_PER_MS: u64 = 1_000_000;
/// Priority of the scan program: below every task (2..=7).
const SCAN_PRIORITY: u8 = 8;
/// How often inputs are refreshed in STOP and ERROR.
const STOP_REFRESH_NS: u64 = 10 * NS_PER_MS;

/// A mode change asked for from outside the PLC (the control socket, an HMI): subject to the
/// mode rules of XGB §5.2.3, see [`Engine::request_mode`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeRequest {
    Run,
    Stop,
    Debug,
    /// Clears a latched error and goes to STOP; `cold` also clears retained memory (K).
    Reset {
        cold: bool,
    },
}

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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sample {
    Bit(BitRef),
    Word(WordRef),
}

#[derive(Debug, Clone)]
enum Kind {
    Scan,
    Init,
    Cycle { interval_ns: u64, next_ns: u64 },
    Io { contact: u8, edge: Edge },
    Device { sample: Sample, when: DeviceCondition, previous: i32 },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Idle,
    /// Requested at `at_ns` (ties of the same instant go by task id, which is config order).
    Pending {
        at_ns: u64,
    },
    /// Started and not finished (executing or preempted).
    Active {
        preempted: bool,
    },
}

/// Figures kept per task, without allocation.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TaskStats {
    pub runs: u64,
    pub ignored: u64,
    /// Cycle deadlines that found the task running or waiting.
    pub overruns: u64,
    /// From the start condition (cycle deadline, the edge's timestamp, the END that sampled a
    /// device condition) to the task's first instruction.
    pub start_latency: Histogram,
    /// The part of `start_latency` before the engine learned of the start condition: how late
    /// the driver woke up for a cycle deadline, the edge's way through the event path. The
    /// rest is the engine's own: dispatch, and waiting for higher-priority tasks.
    pub notice_latency: Histogram,
    /// The task's own execution time per run, from first instruction to END, without the time
    /// higher-priority tasks took while it was preempted.
    pub exec_time: Histogram,
}

#[derive(Debug, Clone)]
struct Task {
    name: String,
    kind: Kind,
    priority: u8,
    number: Option<u8>,
    programs: Box<[u16]>,
    current: usize,
    exec: ExecState,
    state: State,
    /// When the start condition of the pending request occurred.
    occurred_ns: u64,
    disabled: bool,
    max_exec_ns: Option<u64>,
    used_ns: u64,
    congested: bool,
    stats: TaskStats,
}

impl Task {
    fn new(name: &str, kind: Kind, priority: u8, number: Option<u8>, programs: Vec<u16>) -> Task {
        Task {
            name: name.to_string(),
            kind,
            priority,
            number,
            programs: programs.into_boxed_slice(),
            current: 0,
            exec: ExecState::new(),
            state: State::Idle,
            occurred_ns: 0,
            disabled: false,
            max_exec_ns: None,
            used_ns: 0,
            congested: false,
            stats: TaskStats::default(),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Between two scans of a fixed scan period (tasks still run).
    Idle,
    /// The scan program (or the init task) is executing or preempted.
    Scan,
    /// After END: device tasks and every pending task run before the next scan.
    AfterEnd,
}

/// A watched device, resolved once: comparing it at every output refresh and task end is a
/// load and a compare, not an address lookup.
#[derive(Debug, Clone, Copy)]
struct Watch {
    at: Sample,
    last: i32,
}

impl Watch {
    fn new(address: &Address) -> Watch {
        // As `Memory::read` resolves it: a word if the address is one, else a bit.
        let at = match address.as_word() {
            Ok(word) => Sample::Word(word),
            Err(_) => Sample::Bit(address.as_bit().expect("an address is a bit or a word")),
        };
        Watch { at, last: 0 }
    }
}

/// A device's value as conditions and watches see it: a bit 0 or 1, a word signed.
#[inline]
fn read_sample(mem: &Memory, sample: Sample) -> i32 {
    match sample {
        Sample::Bit(bit) => i32::from(mem.bit(bit)),
        Sample::Word(word) => i32::from(mem.word(word) as i16),
    }
}

/// Scan time figures in ns (a scan: from its start to the end of END processing, tasks that
/// ran meanwhile included).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ScanStats {
    pub count: u64,
    pub last_ns: u64,
    pub min_ns: u64,
    pub max_ns: u64,
    pub time: Histogram,
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
    mode: Mode,
    phase: Phase,
    settings: Settings,
    init_done: bool,
    init_done_requested: bool,
    tasks_disabled: bool,
    run_start_ns: u64,
    scan_start_ns: u64,
    watchdog_start_ns: u64,
    next_scan_ns: u64,
    next_stop_refresh_ns: u64,
    scan: ScanStats,
    watches: Vec<Watch>,
    /// A task with a congestion limit started: its deadline may come before the one the
    /// driver planned for, so `run` hands back to let the driver plan again.
    replan: bool,
    forces: Forces,
    debugger: Debugger,
    /// A `[switch]` is configured.
    has_switch: bool,
    /// The switch position the mode rules last acted on (`None` before the first look).
    switch: Option<SwitchPosition>,
    /// A position read at an input refresh, not yet acted on.
    switch_moved: Option<SwitchPosition>,
    /// `run` hands back at the next scan boundary (the driver has commands for END).
    hold_at_end: bool,
    /// The stopping error of ERROR mode.
    latched_error: Option<ErrorKind>,
    /// The last operation error since RUN.
    last_operation_error: Option<ErrorKind>,
    /// Cycle deadlines noticed a full interval or more after they passed, since RUN.
    missed_deadlines: u64,
    /// What `[retain]` keeps across RUN starts and restarts (docs/RETAIN.md).
    retain: crate::device::RetainSet,
    /// The retained devices hold values to keep (restored, or a RUN happened since the memory
    /// was cleared): a warm RUN start; false after a cold start or `reset --cold`.
    warm: bool,
    /// The current scan paused in DEBUG: its duration is not a scan time.
    scan_paused: bool,
    /// `_FORCE_IN`/`_FORCE_OUT` may be ON.
    force_flags_on: bool,
}

impl Engine {
    /// An engine for `project`, in STOP; `watch` lists the devices whose changes are reported
    /// as `set` events.
    pub fn new(project: &Project, watch: &[Address]) -> Engine {
        let config = &project.config;
        let vm = Vm::for_programs(&project.programs);
        let programs_of = |task: &TaskRef| -> Vec<u16> {
            config
                .programs
                .iter()
                .enumerate()
                .filter(|(_, p)| &p.task == task)
                .map(|(i, _)| i as u16)
                .collect()
        };
        let names = task_names(config);
        let mut tasks = vec![
            Task::new(
                &names[SCAN as usize],
                Kind::Scan,
                SCAN_PRIORITY,
                None,
                programs_of(&TaskRef::Scan),
            ),
            Task::new(&names[INIT as usize], Kind::Init, 1, None, programs_of(&TaskRef::Init)),
        ];
        for task in &config.tasks {
            let kind = match &task.kind {
                ConfigTaskKind::Cycle { interval_ms } => {
                    Kind::Cycle { interval_ns: u64::from(*interval_ms) * NS_PER_MS, next_ns: 0 }
                }
                ConfigTaskKind::Io { contact, edge } => {
                    Kind::Io { contact: contact.bit.unwrap_or(0), edge: *edge }
                }
                ConfigTaskKind::Device { device, condition } => {
                    let sample = match device.as_bit() {
                        Ok(bit) if is_bit_condition(condition) => Sample::Bit(bit),
                        _ => Sample::Word(device.as_word().expect("validated by the config")),
                    };
                    Kind::Device { sample, when: *condition, previous: 0 }
                }
            };
            let name = TaskRef::Named(task.name.clone());
            let mut t =
                Task::new(&task.name, kind, task.priority, Some(task.number), programs_of(&name));
            t.max_exec_ns = task.max_exec_ms.map(|ms| u64::from(ms) * NS_PER_MS);
            tasks.push(t);
        }
        let plc = &config.plc;
        let capacity = tasks.len();
        Engine {
            programs: project.programs.clone(),
            vm,
            tasks,
            stack: Vec::with_capacity(capacity),
            mode: Mode::Stop,
            phase: Phase::Idle,
            settings: Settings {
                watchdog_ns: u64::from(plc.watchdog_ms) * NS_PER_MS,
                watchdog_ms: plc.watchdog_ms,
                on_fault: plc.on_fault,
                scan_period_ns: u64::from(plc.scan_period_ms) * NS_PER_MS,
                continue_on_congestion: plc.continue_on_congestion,
            },
            init_done: false,
            init_done_requested: false,
            tasks_disabled: false,
            run_start_ns: 0,
            scan_start_ns: 0,
            watchdog_start_ns: 0,
            next_scan_ns: 0,
            next_stop_refresh_ns: 0,
            scan: ScanStats::default(),
            watches: watch.iter().map(Watch::new).collect(),
            replan: false,
            forces: Forces::default(),
            debugger: Debugger::default(),
            has_switch: config.switch.is_some(),
            switch: None,
            switch_moved: None,
            hold_at_end: false,
            latched_error: None,
            last_operation_error: None,
            missed_deadlines: 0,
            retain: crate::device::RetainSet::new(&config.retain.ranges),
            warm: false,
            scan_paused: false,
            force_flags_on: false,
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
        self.warm = true;
    }

    /// A replacement engine (reload, `plcctl load`) takes the retained devices of the one it
    /// replaces, so that a new program does not reset a counter: copies the retained bits of
    /// `old`'s memory and its warm flag. No allocation (the scan thread calls it).
    pub fn inherit_retained(&mut self, old: &Engine) {
        let (from, to) = (old.vm.mem.words(), self.vm.mem.words_mut());
        for r in self.retain.words.iter() {
            for i in usize::from(r.start)..usize::from(r.end) {
                to[i] = (to[i] & !r.mask) | (from[i] & r.mask);
            }
        }
        self.warm = old.warm;
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
        self.mode
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

    /// When the scan watchdog expires, if it runs (RUN, a scan under way): the time after
    /// which [`Engine::poll_time`] takes the watchdog error.
    /// The scan watchdog time in ns (`[plc] watchdog_ms`).
    pub fn watchdog_ns(&self) -> u64 {
        self.settings.watchdog_ns
    }

    pub fn watchdog_deadline(&self) -> Option<u64> {
        (self.executing() && self.phase != Phase::Idle)
            .then_some(self.watchdog_start_ns + self.settings.watchdog_ns)
    }

    /// RUN, or DEBUG while `step` or `continue` lets the programs run.
    fn executing(&self) -> bool {
        match self.mode {
            Mode::Run => true,
            Mode::Debug => self.debugger.run != DebugRun::Paused,
            Mode::Stop | Mode::Error => false,
        }
    }

    /// RUN or DEBUG: the programs are loaded for execution (device memory initialized).
    fn running(&self) -> bool {
        matches!(self.mode, Mode::Run | Mode::Debug)
    }

    /// The deadlines of the cycle tasks in RUN: `(task number, next deadline, interval)`, all
    /// in ns. A driver arms its timers with these; the engine itself decides at
    /// [`Engine::poll_time`] which deadlines have passed.
    pub fn cycle_deadlines(&self) -> impl Iterator<Item = (u8, u64, u64)> + '_ {
        let running = self.executing();
        self.tasks.iter().filter_map(move |t| match (t.kind.clone(), t.number) {
            (Kind::Cycle { interval_ns, next_ns }, Some(n)) if running => {
                Some((n, next_ns, interval_ns))
            }
            _ => None,
        })
    }

    /// A mode command of the driver itself (startup, the simulator's `MODE` pseudo-device,
    /// shutdown), not subject to the key switch. RUN is refused in ERROR: the error is latched
    /// until a change to STOP.
    pub fn set_mode(&mut self, mode: Mode, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        match (self.mode, mode) {
            (Mode::Stop, Mode::Run) => self.enter_run(Mode::Run, now, io, sink),
            (Mode::Debug, Mode::Run) => self.leave_debug(now, sink),
            (Mode::Run | Mode::Error | Mode::Debug, Mode::Stop) => self.enter_stop(now, io, sink),
            (Mode::Stop, Mode::Debug) => self.enter_run(Mode::Debug, now, io, sink),
            (Mode::Run, Mode::Debug) => self.enter_debug(now, sink),
            _ => {}
        }
    }

    /// A remote mode change, under the rules of XGB §5.2.3: accepted only when no key switch
    /// is configured or the switch is at STOP ("remote enabled"); RUN and DEBUG are refused
    /// while an error is latched. DEBUG entered from RUN pauses at the end of the current
    /// scan. On success the mode after the change is [`Engine::mode`].
    pub fn request_mode(
        &mut self,
        request: ModeRequest,
        now: u64,
        io: &mut impl Io,
        sink: &mut impl EventSink,
    ) -> Result<(), Refusal> {
        if !self.remote_allowed() {
            return Err(Refusal::SwitchAtRun);
        }
        match request {
            ModeRequest::Run | ModeRequest::Debug if self.mode == Mode::Error => {
                return Err(Refusal::ErrorLatched)
            }
            ModeRequest::Run => self.set_mode(Mode::Run, now, io, sink),
            ModeRequest::Stop => self.set_mode(Mode::Stop, now, io, sink),
            ModeRequest::Debug => self.set_mode(Mode::Debug, now, io, sink),
            ModeRequest::Reset { cold } => {
                if self.mode == Mode::Stop {
                    self.latched_error = None;
                    self.last_operation_error = None;
                } else {
                    self.enter_stop(now, io, sink);
                }
                if cold {
                    self.vm.mem.clear_all();
                    self.warm = false;
                    self.check_watches(now, sink);
                }
            }
        }
        Ok(())
    }

    /// True when remote mode changes are accepted: no key switch, or the switch at STOP.
    pub fn remote_allowed(&self) -> bool {
        !self.has_switch || self.switch == Some(SwitchPosition::Stop)
    }

    /// The key switch position the engine acts on, if a switch is configured and was read.
    pub fn switch(&self) -> Option<SwitchPosition> {
        self.switch
    }

    /// DEBUG: runs to the end of the current scan (or through the next one when paused
    /// between scans), or to a breakpoint.
    pub fn debug_step(&mut self, now: u64) -> Result<(), Refusal> {
        self.debug_resume(DebugRun::Scan, now)
    }

    /// DEBUG: runs scan after scan until a breakpoint.
    pub fn debug_continue(&mut self, now: u64) -> Result<(), Refusal> {
        self.debug_resume(DebugRun::Continue, now)
    }

    fn debug_resume(&mut self, run: DebugRun, now: u64) -> Result<(), Refusal> {
        if self.mode != Mode::Debug {
            return Err(Refusal::NotInDebug);
        }
        if self.debugger.run == DebugRun::Paused {
            // The pause is not the program's time: the watchdog starts over.
            self.watchdog_start_ns = now;
            self.skip_cycle_deadlines(now);
        }
        if let Some((_, at)) = self.debugger.paused_at.take() {
            self.debugger.resume_from = Some(at);
        }
        self.debugger.run = run;
        Ok(())
    }

    pub fn debugger(&self) -> &Debugger {
        &self.debugger
    }

    /// Breakpoints are set and removed here (resolved with [`debug::resolve`]).
    pub fn debugger_mut(&mut self) -> &mut Debugger {
        &mut self.debugger
    }

    /// Forces P bit `bit` to `on` from the next refresh on.
    pub fn force(&mut self, bit: BitRef, on: bool, io: &impl Io) {
        self.forces.set(bit, on, io.is_input(bit));
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
        self.hold_at_end = hold;
    }

    /// True between two scans with no task executing (or nothing executing at all: STOP,
    /// ERROR, DEBUG paused): where commands that change PLC state are applied.
    pub fn at_scan_boundary(&self) -> bool {
        !self.executing() || (self.phase == Phase::Idle && self.stack.is_empty())
    }

    /// The error latched in ERROR mode.
    pub fn latched_error(&self) -> Option<ErrorKind> {
        self.latched_error
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

    /// An edge on contact P0000+`contact` that happened at `stamp_ns` (<= `now`): requests the
    /// I/O tasks waiting for it.
    pub fn input_edge(
        &mut self,
        contact: u8,
        rising: bool,
        stamp_ns: u64,
        now: u64,
        sink: &mut impl EventSink,
    ) {
        for id in 0..self.tasks.len() {
            if let Kind::Io { contact: c, edge } = self.tasks[id].kind {
                let wanted = match edge {
                    Edge::Rising => rising,
                    Edge::Falling => !rising,
                    Edge::Both => true,
                };
                if c == contact && wanted {
                    self.request(id as TaskId, stamp_ns.min(now), now, sink);
                }
            }
        }
    }

    /// Time-driven work due at `now`: cycle deadlines, the scan watchdog, congestion, and the
    /// input refresh of STOP.
    pub fn poll_time(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        if !self.running() {
            if now >= self.next_stop_refresh_ns {
                self.refresh_inputs(io);
                self.next_stop_refresh_ns = now + STOP_REFRESH_NS;
            }
            self.apply_switch(now, io, sink);
            return;
        }
        self.apply_switch(now, io, sink);
        if !self.executing() {
            if self.mode == Mode::Debug {
                self.skip_cycle_deadlines(now);
            }
            return;
        }
        for id in 0..self.tasks.len() {
            while let Kind::Cycle { interval_ns, next_ns } = self.tasks[id].kind {
                if next_ns > now {
                    break;
                }
                self.tasks[id].kind = Kind::Cycle { interval_ns, next_ns: next_ns + interval_ns };
                if now - next_ns >= interval_ns {
                    self.missed_deadlines += 1;
                }
                let why = self.request(id as TaskId, next_ns, now, sink);
                if matches!(why, Some(Ignored::Running | Ignored::Pending | Ignored::Disabled)) {
                    self.tasks[id].stats.overruns += 1;
                }
            }
        }
        if self.phase != Phase::Idle && now - self.watchdog_start_ns > self.settings.watchdog_ns {
            let scan = self.scan.count;
            let limit_ms = self.settings.watchdog_ms;
            self.fault(ErrorKind::Watchdog { scan, limit_ms }, now, io, sink);
            return;
        }
        if let Some(&top) = self.stack.last() {
            let task = &mut self.tasks[top as usize];
            if let Some(max) = task.max_exec_ns {
                if task.used_ns > max && !task.congested {
                    task.congested = true;
                    let kind =
                        ErrorKind::Congestion { task: top, limit_ms: (max / NS_PER_MS) as u32 };
                    if self.settings.continue_on_congestion {
                        sink.event(now, Event::Error(kind));
                    } else {
                        self.fault(kind, now, io, sink);
                    }
                }
            }
        }
    }

    /// A watchdog outside the engine (the real-time driver's watchdog thread) saw the scan
    /// watchdog expire and already put the outputs into their safe state: take the watchdog
    /// error now, whatever this thread last saw of the scan.
    pub fn watchdog_expired(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        if self.executing() {
            let scan = self.scan.count;
            let limit_ms = self.settings.watchdog_ms;
            self.fault(ErrorKind::Watchdog { scan, limit_ms }, now, io, sink);
        }
    }

    /// The next time the engine needs [`Engine::poll_time`] or [`Engine::run`] without an
    /// external event.
    pub fn next_wakeup(&self, now: u64) -> Option<u64> {
        if !self.running() {
            return Some(self.next_stop_refresh_ns.max(now));
        }
        if !self.executing() {
            // DEBUG, paused: only the cycle deadlines move on (see `poll_time`), and they may
            // do so lazily; wake now and then to keep them close.
            return Some(now + STOP_REFRESH_NS);
        }
        let mut next = u64::MAX;
        for task in &self.tasks {
            if let Kind::Cycle { next_ns, .. } = task.kind {
                next = next.min(next_ns);
            }
        }
        match self.phase {
            Phase::Idle if self.stack.is_empty() => next = next.min(self.next_scan_ns),
            Phase::Idle => {}
            Phase::Scan | Phase::AfterEnd => {
                next = next.min(self.watchdog_start_ns + self.settings.watchdog_ns + 1);
            }
        }
        if let Some(&top) = self.stack.last() {
            let task = &self.tasks[top as usize];
            if let (Some(max), false) = (task.max_exec_ns, task.congested) {
                next = next.min(now + max.saturating_sub(task.used_ns) + 1);
            }
        }
        (next != u64::MAX).then_some(next.max(now))
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
            if std::mem::take(&mut self.replan) {
                return Activity::Busy;
            }
            let Some(&top) = self.stack.last() else {
                match self.phase {
                    Phase::AfterEnd => {
                        self.finish_scan(now, io, sink);
                        if self.hold_at_end {
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
            if self.mode == Mode::Debug && self.debugger.watches(program_index) {
                // One instruction at a time, so that a breakpoint stops before its instruction.
                let at = Breakpoint { program: program_index, pc: task.exec.pc() };
                if self.debugger.stops_at(at) {
                    self.debugger.run = DebugRun::Paused;
                    self.debugger.paused_at = Some((top, at));
                    self.scan_paused = true;
                    return Activity::Idle;
                }
                budget = 1;
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

    /// Starts the best pending task if it may start now.
    fn dispatch(&mut self, now: u64, sink: &mut impl EventSink) {
        let top_priority = self.stack.last().map_or(u8::MAX, |&t| self.tasks[t as usize].priority);
        let mut best: Option<(u8, u64, usize)> = None;
        for (id, task) in self.tasks.iter().enumerate() {
            if let State::Pending { at_ns } = task.state {
                if self.tasks_disabled || task.disabled {
                    continue;
                }
                let key = (task.priority, at_ns, id);
                if best.is_none_or(|b| key < b) {
                    best = Some(key);
                }
            }
        }
        let Some((priority, _, id)) = best else { return };
        if priority >= top_priority {
            return;
        }
        let id = id as TaskId;
        if let Some(&top) = self.stack.last() {
            // A task already preempted (its preemptor just ended) is not preempted twice.
            let task = &mut self.tasks[top as usize];
            if task.state == (State::Active { preempted: false }) {
                task.state = State::Active { preempted: true };
                sink.event(now, Event::TaskPreempt { task: top, by: id });
            }
        }
        self.begin(id, now, sink);
    }

    fn begin(&mut self, id: TaskId, now: u64, sink: &mut impl EventSink) {
        let task = &mut self.tasks[id as usize];
        task.state = State::Active { preempted: false };
        task.current = 0;
        task.exec.restart();
        task.used_ns = 0;
        task.congested = false;
        task.stats.runs += 1;
        if id != SCAN && id != INIT {
            task.stats.start_latency.record(now.saturating_sub(task.occurred_ns));
        }
        self.replan |= task.max_exec_ns.is_some();
        self.stack.push(id);
        if id != SCAN {
            sink.event(now, Event::TaskStart { task: id });
        }
    }

    /// Registers a request whose start condition occurred at `occurred_ns`; why it was ignored,
    /// if it was.
    fn request(
        &mut self,
        id: TaskId,
        occurred_ns: u64,
        now: u64,
        sink: &mut impl EventSink,
    ) -> Option<Ignored> {
        sink.event(now, Event::TaskRequest { task: id });
        let task = &self.tasks[id as usize];
        let why = match task.state {
            _ if !self.running() => Some(Ignored::Stop),
            _ if !self.executing() => Some(Ignored::Paused),
            _ if !self.init_done => Some(Ignored::Init),
            State::Active { .. } => Some(Ignored::Running),
            State::Pending { .. } if self.tasks_disabled || task.disabled => {
                Some(Ignored::Disabled)
            }
            State::Pending { .. } => Some(Ignored::Pending),
            State::Idle => None,
        };
        let task = &mut self.tasks[id as usize];
        match why {
            Some(why) => {
                task.stats.ignored += 1;
                sink.event(now, Event::TaskIgnored { task: id, why });
            }
            None => {
                task.state = State::Pending { at_ns: now };
                task.occurred_ns = occurred_ns;
                if id != SCAN && id != INIT {
                    task.stats.notice_latency.record(now.saturating_sub(occurred_ns));
                }
            }
        }
        why
    }

    /// A program of task `id` reached END: the task's next program, or the task's end.
    fn program_end(&mut self, id: TaskId, now: u64, sink: &mut impl EventSink) {
        let task = &mut self.tasks[id as usize];
        task.current += 1;
        if task.current < task.programs.len() {
            task.exec.restart();
            return;
        }
        task.state = State::Idle;
        self.stack.pop();
        match id {
            SCAN => {
                sink.event(now, Event::ScanEnd { n: self.scan.count });
                self.sample_device_conditions(now, sink);
                self.phase = Phase::AfterEnd;
            }
            INIT => {
                sink.event(now, Event::TaskEnd { task: INIT });
                if self.init_done_requested {
                    self.init_done = true;
                    self.sample_device_conditions_quietly();
                }
                sink.event(now, Event::ScanEnd { n: self.scan.count });
                self.phase = Phase::AfterEnd;
            }
            _ => {
                task.stats.exec_time.record(task.used_ns);
                sink.event(now, Event::TaskEnd { task: id });
                self.check_watches(now, sink);
            }
        }
    }

    fn system(
        &mut self,
        id: TaskId,
        request: SystemRequest,
        now: u64,
        io: &mut impl Io,
        sink: &mut impl EventSink,
    ) {
        match request {
            SystemRequest::DisableTasks(None) => self.tasks_disabled = true,
            SystemRequest::EnableTasks(None) => self.tasks_disabled = false,
            SystemRequest::DisableTasks(Some(n)) | SystemRequest::EnableTasks(Some(n)) => {
                let disable = matches!(request, SystemRequest::DisableTasks(_));
                for task in self.tasks.iter_mut().filter(|t| t.number == Some(n)) {
                    task.disabled = disable;
                }
            }
            SystemRequest::ResetWatchdog => self.watchdog_start_ns = now,
            SystemRequest::InitDone => {
                if id == INIT {
                    self.init_done_requested = true;
                }
            }
            SystemRequest::Stop => self.enter_stop(now, io, sink),
            SystemRequest::RefreshIo => {
                self.refresh_inputs(io);
                self.refresh_outputs(io);
                self.check_watches(now, sink);
            }
        }
    }

    /// RUN (or DEBUG, paused before the first scan) from STOP: device memory initialized.
    fn enter_run(&mut self, mode: Mode, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.vm.reset_for_run(&self.retain, self.warm);
        self.warm = true;
        for task in &mut self.tasks {
            task.state = State::Idle;
            task.disabled = false;
            if let Kind::Cycle { interval_ns, .. } = task.kind {
                task.kind = Kind::Cycle { interval_ns, next_ns: now + interval_ns };
            }
        }
        self.stack.clear();
        self.init_done = self.tasks[INIT as usize].programs.is_empty();
        self.init_done_requested = false;
        self.tasks_disabled = false;
        self.run_start_ns = now;
        self.scan = ScanStats::default();
        self.last_operation_error = None;
        self.missed_deadlines = 0;
        self.mode = mode;
        self.debugger.run = DebugRun::Paused;
        self.debugger.paused_at = None;
        self.debugger.resume_from = None;
        sink.event(now, Event::Mode(mode));
        self.refresh_inputs(io);
        self.sample_device_conditions_quietly();
        self.check_watches(now, sink);
        self.phase = Phase::Idle;
        self.next_scan_ns = now;
    }

    /// DEBUG from RUN: the current scan ends, then execution pauses.
    fn enter_debug(&mut self, now: u64, sink: &mut impl EventSink) {
        self.mode = Mode::Debug;
        self.debugger.paused_at = None;
        self.debugger.resume_from = None;
        self.debugger.run =
            if self.at_scan_boundary_in_run() { DebugRun::Paused } else { DebugRun::Scan };
        sink.event(now, Event::Mode(Mode::Debug));
    }

    /// RUN from DEBUG: execution goes on where it stands, device memory kept.
    fn leave_debug(&mut self, now: u64, sink: &mut impl EventSink) {
        if self.debugger.run == DebugRun::Paused {
            self.watchdog_start_ns = now;
            self.skip_cycle_deadlines(now);
        }
        if let Some((_, at)) = self.debugger.paused_at.take() {
            self.debugger.resume_from = Some(at);
        }
        self.debugger.run = DebugRun::Paused;
        self.mode = Mode::Run;
        sink.event(now, Event::Mode(Mode::Run));
    }

    /// DEBUG, paused: cycle deadlines that passed are dropped without requests, so that
    /// resuming does not start with a burst of stale ones.
    fn skip_cycle_deadlines(&mut self, now: u64) {
        for task in &mut self.tasks {
            if let Kind::Cycle { interval_ns, next_ns } = task.kind {
                if next_ns < now {
                    let missed = (now - next_ns).div_ceil(interval_ns);
                    task.kind =
                        Kind::Cycle { interval_ns, next_ns: next_ns + missed * interval_ns };
                }
            }
        }
    }

    fn at_scan_boundary_in_run(&self) -> bool {
        self.phase == Phase::Idle && self.stack.is_empty()
    }

    fn enter_stop(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.halt();
        self.clear_outputs(io);
        self.latched_error = None;
        self.debugger.paused_at = None;
        self.debugger.resume_from = None;
        self.mode = Mode::Stop;
        sink.event(now, Event::Mode(Mode::Stop));
        self.check_watches(now, sink);
        self.next_stop_refresh_ns = now + STOP_REFRESH_NS;
    }

    /// A stopping error: execution stops at once, outputs cleared or held, mode ERROR.
    fn fault(&mut self, kind: ErrorKind, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        sink.event(now, Event::Error(kind));
        self.latched_error = Some(kind);
        self.debugger.paused_at = None;
        self.halt();
        if self.settings.on_fault == OnFault::Clear {
            self.clear_outputs(io);
        }
        self.mode = Mode::Error;
        sink.event(now, Event::Mode(Mode::Error));
        self.check_watches(now, sink);
        self.next_stop_refresh_ns = now + STOP_REFRESH_NS;
    }

    /// No task active or pending; DUTY stopped.
    fn halt(&mut self) {
        for task in &mut self.tasks {
            task.state = State::Idle;
        }
        self.stack.clear();
        self.phase = Phase::Idle;
        self.vm.stop();
    }

    /// The safe state: every output OFF, forces or not.
    fn clear_outputs(&mut self, io: &mut impl Io) {
        self.vm.mem.io_image_mut().fill(0);
        io.refresh_outputs(&self.vm.mem);
        io.refresh_inputs(&mut self.vm.mem);
        self.note_switch(io);
    }

    /// Input refresh: the backend's inputs, then the forces over them, then a look at the key
    /// switch.
    fn refresh_inputs(&mut self, io: &mut impl Io) {
        io.refresh_inputs(&mut self.vm.mem);
        self.apply_forces();
        self.note_switch(io);
    }

    /// Output refresh: the forces over what the program wrote, then the backend.
    fn refresh_outputs(&mut self, io: &mut impl Io) {
        self.apply_forces();
        io.refresh_outputs(&self.vm.mem);
    }

    /// Writes the forced values over the I/O image; once more after the last force is gone, to
    /// clear the force flags.
    #[inline]
    fn apply_forces(&mut self) {
        if !self.forces.is_empty() || self.force_flags_on {
            self.forces.apply(&mut self.vm.mem);
            self.force_flags_on = !self.forces.is_empty();
        }
    }

    fn note_switch(&mut self, io: &impl Io) {
        if self.has_switch {
            if let Some(position) = io.switch() {
                if Some(position) != self.switch {
                    self.switch_moved = Some(position);
                }
            }
        }
    }

    /// Acts on a key switch move (XGB §5.2.3): to RUN starts the PLC from STOP (and leaves
    /// DEBUG; RUN goes on without interruption; a latched error stays until the switch goes
    /// to STOP); to STOP stops it from any mode, clearing an error.
    fn apply_switch(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        let Some(position) = self.switch_moved.take() else { return };
        if Some(position) == self.switch {
            return;
        }
        self.switch = Some(position);
        sink.event(now, Event::Switch(position));
        match (position, self.mode) {
            (SwitchPosition::Run, Mode::Stop) => self.enter_run(Mode::Run, now, io, sink),
            (SwitchPosition::Run, Mode::Debug) => self.leave_debug(now, sink),
            (SwitchPosition::Stop, Mode::Run | Mode::Debug | Mode::Error) => {
                self.enter_stop(now, io, sink)
            }
            _ => {}
        }
    }

    fn start_scan(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.scan.count += 1;
        self.scan_start_ns = now;
        self.watchdog_start_ns = now;
        self.vm.begin_scan(self.scan.count == 1, now - self.run_start_ns);
        self.refresh_inputs(io);
        if self.switch_moved.is_some() {
            self.apply_switch(now, io, sink);
            if !self.executing() {
                return;
            }
        }
        self.scan_paused = false;
        sink.event(now, Event::ScanStart { n: self.scan.count });
        self.phase = Phase::Scan;
        self.begin(if self.init_done { SCAN } else { INIT }, now, sink);
    }

    /// The rest of END processing once no task is left to run: DUTY, scan time, outputs.
    fn finish_scan(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.vm.end_scan();
        let took = now - self.scan_start_ns;
        let scan = &mut self.scan;
        // A scan that paused at a breakpoint took the engineer's time, not the program's.
        if !self.scan_paused {
            scan.last_ns = took;
            scan.min_ns = if scan.time.count() == 0 { took } else { scan.min_ns.min(took) };
            scan.max_ns = scan.max_ns.max(took);
            scan.time.record(took);
        }
        let tenth_ms = |ns: u64| (ns / 100_000).min(u64::from(u16::MAX)) as u16;
        self.vm.mem.set_scan_times(tenth_ms(took), tenth_ms(scan.min_ns), tenth_ms(scan.max_ns));
        self.refresh_outputs(io);
        if self.mode == Mode::Debug {
            self.debugger.resume_from = None;
            if self.debugger.run == DebugRun::Scan {
                self.debugger.run = DebugRun::Paused;
            }
        }
        self.check_watches(now, sink);
        self.phase = Phase::Idle;
        let period = self.settings.scan_period_ns;
        // On the grid of the schedule, not counted from the (possibly late) start: a scan that
        // started late — a driver's wake-up latency, a task that ran first — does not push
        // every later one back. Grid points already passed are skipped, not caught up.
        self.next_scan_ns = if period == 0 {
            now
        } else {
            let next = self.next_scan_ns + period;
            next + now.saturating_sub(next).div_ceil(period) * period
        };
    }

    fn sample_value(&self, sample: Sample) -> i32 {
        read_sample(&self.vm.mem, sample)
    }

    /// Takes the current samples as the "previous END" ones, without requesting anything.
    fn sample_device_conditions_quietly(&mut self) {
        for id in 0..self.tasks.len() {
            if let Kind::Device { sample, when, .. } = self.tasks[id].kind {
                let previous = self.sample_value(sample);
                self.tasks[id].kind = Kind::Device { sample, when, previous };
            }
        }
    }

    /// END: samples every device condition and requests the tasks whose condition holds.
    fn sample_device_conditions(&mut self, now: u64, sink: &mut impl EventSink) {
        for id in 0..self.tasks.len() {
            let Kind::Device { sample, when, previous } = self.tasks[id].kind else { continue };
            let value = self.sample_value(sample);
            self.tasks[id].kind = Kind::Device { sample, when, previous: value };
            let holds = match when {
                DeviceCondition::Rising => previous == 0 && value != 0,
                DeviceCondition::Falling => previous != 0 && value == 0,
                DeviceCondition::Transition => previous != value,
                DeviceCondition::On => value != 0,
                DeviceCondition::Off => value == 0,
                DeviceCondition::Greater(limit) => value > i32::from(limit),
                DeviceCondition::GreaterEq(limit) => value >= i32::from(limit),
                DeviceCondition::Less(limit) => value < i32::from(limit),
                DeviceCondition::LessEq(limit) => value <= i32::from(limit),
            };
            if holds {
                self.request(id as TaskId, now, now, sink);
            }
        }
    }

    fn check_watches(&mut self, now: u64, sink: &mut impl EventSink) {
        let mem = &self.vm.mem;
        for (index, watch) in self.watches.iter_mut().enumerate() {
            let value = read_sample(mem, watch.at);
            if value != watch.last {
                watch.last = value;
                sink.event(now, Event::Set { watch: index as u16, value });
            }
        }
    }
}

/// Task names by [`TaskId`]: the scan program, the init task, then the `[[task]]`s in config
/// order (also the order of ties between requests of the same instant).
pub fn task_names(config: &Config) -> Vec<String> {
    let mut names = vec![TaskRef::Scan.name().to_string(), TaskRef::Init.name().to_string()];
    names.extend(config.tasks.iter().map(|t| t.name.clone()));
    names
}

fn is_bit_condition(condition: &DeviceCondition) -> bool {
    matches!(
        condition,
        DeviceCondition::Rising
            | DeviceCondition::Falling
            | DeviceCondition::Transition
            | DeviceCondition::On
            | DeviceCondition::Off
    )
}
