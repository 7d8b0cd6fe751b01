//! What runs when: task requests (cycle deadlines, input edges, device conditions sampled at
//! END) and why one is ignored, the choice of the next task and preemption, a task's start and
//! end, the system requests of the programs (DI/EI, WDT, INIT_DONE, STOP, IORF), the scan
//! watchdog and congestion, and when the driver must look again.

use crate::config::{DeviceCondition, Edge};
use crate::io::Io;
use crate::lang::ops::SystemRequest;

use super::event::{ErrorKind, Event, EventSink, Ignored, TaskId, INIT, SCAN};
use super::mode::ModeState;
use super::scan::Phase;
use super::task::{read_sample, Kind, Sample, State};
use super::{Engine, NS_PER_MS, STOP_REFRESH_NS};

/// How far the init task is, from a RUN start: XGB runs the init programs instead of the scan
/// program, scan after scan, until one executes `INIT_DONE`. It only moves forward, `Running`
/// to `DoneRequested` to `Done`, until a RUN start sets it afresh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Init {
    /// Each scan runs the init task; requests of other tasks are ignored.
    Running,
    /// `INIT_DONE` executed: the init task runs on to its end, then the init is done.
    DoneRequested,
    /// The scan program runs and tasks start (from the start if there are no init programs).
    Done,
}

impl Init {
    /// `INIT_DONE` in the init task.
    #[inline]
    fn done_requested(&mut self) {
        if *self == Init::Running {
            *self = Init::DoneRequested;
        }
    }

    /// The init task reached its end: true if that ends the init.
    #[inline]
    fn task_ended(&mut self) -> bool {
        let ends = *self == Init::DoneRequested;
        if ends {
            *self = Init::Done;
        }
        ends
    }
}

/// Whether `DI` holds task starts, for all tasks (the engine's, in RUN and DEBUG) or one task
/// number (the task's): held requests stay pending, one each, until `EI`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Starts {
    Enabled,
    Held,
}

impl Starts {
    /// What a `DI` or `EI` asks for.
    #[inline]
    fn of(request: SystemRequest) -> Starts {
        match request {
            SystemRequest::DisableTasks(_) => Starts::Held,
            _ => Starts::Enabled,
        }
    }
}

impl Engine {
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

    /// When the scan watchdog expires, if it runs (RUN, a scan under way): the time after
    /// which [`Engine::poll_time`] takes the watchdog error.
    pub fn watchdog_deadline(&self) -> Option<u64> {
        (self.executing() && self.phase() != Phase::Idle)
            .then_some(self.watchdog_start_ns + self.settings.watchdog_ns)
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
            if matches!(self.mode, ModeState::Debug(..)) {
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
        if self.phase() != Phase::Idle && now - self.watchdog_start_ns > self.settings.watchdog_ns {
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
        match self.phase() {
            Phase::Idle if self.stack.is_empty() => next = next.min(self.next_scan_ns),
            Phase::Idle => {}
            Phase::Scan { .. } | Phase::AfterEnd { .. } => {
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

    /// Starts the best pending task if it may start now.
    pub(super) fn dispatch(&mut self, now: u64, sink: &mut impl EventSink) {
        let top_priority = self.stack.last().map_or(u8::MAX, |&t| self.tasks[t as usize].priority);
        let all_held = matches!(
            self.mode,
            ModeState::Run(running) | ModeState::Debug(running, _) if running.starts == Starts::Held
        );
        let mut best: Option<(u8, u64, usize)> = None;
        for (id, task) in self.tasks.iter().enumerate() {
            if let State::Pending { at_ns } = task.state {
                if all_held || task.starts == Starts::Held {
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

    pub(super) fn begin(&mut self, id: TaskId, now: u64, sink: &mut impl EventSink) {
        let task = &mut self.tasks[id as usize];
        if let Some(info) = &self.system_info {
            let period_ns = match task.kind {
                Kind::Scan => self.settings.scan_period_ns,
                Kind::Cycle { interval_ns, .. } => interval_ns,
                _ => 0,
            };
            info.task_started(&mut self.vm, usize::from(id), &task.name, period_ns, task.used_ns);
        }
        task.state = State::Active { preempted: false };
        task.current = 0;
        task.exec.restart();
        task.used_ns = 0;
        task.congested = false;
        task.stats.runs += 1;
        if id != SCAN && id != INIT {
            task.stats.start_latency.record(now.saturating_sub(task.occurred_ns));
        }
        self.hand_back.replan |= task.max_exec_ns.is_some();
        self.stack.push(id);
        if id != SCAN {
            sink.event(now, Event::TaskStart { task: id });
        }
        if self.tasks[id as usize].programs.is_empty() {
            // A task no program runs in (a `[[task]]` only a CONFIGURATION could name) runs
            // nothing: it ends where it starts.
            self.program_end(id, now, sink);
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
        let why = match self.mode {
            ModeState::Stop | ModeState::Error(_) => Some(Ignored::Stop),
            ModeState::Debug(_, session) if !session.executes() => Some(Ignored::Paused),
            ModeState::Run(running) | ModeState::Debug(running, _) => match task.state {
                _ if running.init != Init::Done => Some(Ignored::Init),
                State::Active { .. } => Some(Ignored::Running),
                State::Pending { .. }
                    if running.starts == Starts::Held || task.starts == Starts::Held =>
                {
                    Some(Ignored::Disabled)
                }
                State::Pending { .. } => Some(Ignored::Pending),
                State::Idle => None,
            },
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
    pub(super) fn program_end(&mut self, id: TaskId, now: u64, sink: &mut impl EventSink) {
        let task = &mut self.tasks[id as usize];
        task.current += 1;
        if task.current < task.programs.len() {
            task.exec.restart();
            return;
        }
        task.state = State::Idle;
        self.stack.pop();
        if let Some(info) = &self.system_info {
            info.task_ended(&mut self.vm, now, id, sink);
        }
        if let ModeState::Debug(_, session) = &mut self.mode {
            session.task_finished(id);
        }
        match id {
            SCAN => {
                sink.event(now, Event::ScanEnd { n: self.scan.count });
                self.sample_device_conditions(now, sink);
                self.scan_program_ended();
            }
            INIT => {
                sink.event(now, Event::TaskEnd { task: INIT });
                if self.running_mut().is_some_and(|running| running.init.task_ended()) {
                    self.sample_device_conditions_quietly();
                }
                sink.event(now, Event::ScanEnd { n: self.scan.count });
                self.scan_program_ended();
            }
            _ => {
                task.stats.exec_time.record(task.used_ns);
                sink.event(now, Event::TaskEnd { task: id });
                self.check_watches(now, sink);
            }
        }
    }

    pub(super) fn system(
        &mut self,
        id: TaskId,
        request: SystemRequest,
        now: u64,
        io: &mut impl Io,
        sink: &mut impl EventSink,
    ) {
        match request {
            SystemRequest::DisableTasks(None) | SystemRequest::EnableTasks(None) => {
                if let Some(running) = self.running_mut() {
                    running.starts = Starts::of(request);
                }
            }
            SystemRequest::DisableTasks(Some(n)) | SystemRequest::EnableTasks(Some(n)) => {
                let starts = Starts::of(request);
                for task in self.tasks.iter_mut().filter(|t| t.number == Some(n)) {
                    task.starts = starts;
                }
            }
            SystemRequest::ResetWatchdog => self.watchdog_start_ns = now,
            SystemRequest::InitDone => {
                if id == INIT {
                    if let Some(running) = self.running_mut() {
                        running.init.done_requested();
                    }
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

    /// DEBUG, paused: cycle deadlines that passed are dropped without requests, so that
    /// resuming does not start with a burst of stale ones.
    pub(super) fn skip_cycle_deadlines(&mut self, now: u64) {
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

    fn sample_value(&self, sample: Sample) -> i32 {
        read_sample(&self.vm.mem, sample)
    }

    /// Takes the current samples as the "previous END" ones, without requesting anything.
    pub(super) fn sample_device_conditions_quietly(&mut self) {
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
}
