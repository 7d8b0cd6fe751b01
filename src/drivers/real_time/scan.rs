//! The scan thread: the engine on the monotonic clock, fed with the pending work of the other
//! threads between two slices of instructions.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};

use super::io::GatedIo;
use super::mirror::Mirror;
use super::snapshot::Snapshot;
use super::sys::{self, Timer};
use super::{
    mode_code, pending, Applied, Command, Completion, ControlCommand, LogMessage, Monotonic,
    Report, Shared, Source, Write, SLICE_STEPS,
};
use crate::engine::event::{Event, EventSink, Mode, TaskId};
use crate::engine::{Activity, Engine, Refusal};
use crate::io::InputEdge;

/// Forwards the events worth logging to the supervisor; the others are counted by the engine's
/// statistics. Never blocks: a full queue drops the report and counts it.
struct ReportSink<'a> {
    reports: &'a mut rtrb::Producer<Report>,
    messages: &'a mut rtrb::Producer<LogMessage>,
    shared: &'a Shared,
    /// Who asked for the mode change being applied, if one is.
    source: Option<Source>,
}

impl ReportSink<'_> {
    fn push(&mut self, report: Report) {
        if self.reports.push(report).is_err() {
            self.shared.dropped_reports.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl EventSink for ReportSink<'_> {
    fn event(&mut self, t_ns: u64, event: Event) {
        match event {
            Event::Mode(mode) => self.push(Report::Mode(t_ns, mode, self.source)),
            Event::Switch(position) => {
                // What follows in this pass is the switch's doing.
                self.source = Some(Source::Switch);
                self.push(Report::Switch(t_ns, position));
            }
            Event::Error(_) | Event::Set { .. } | Event::SetVariable { .. } => {
                self.push(Report::Event(t_ns, event))
            }
            _ => {}
        }
    }

    fn message(&mut self, t_ns: u64, task: TaskId, mask: u32, text: &[u8]) {
        if self.messages.push(LogMessage::new(t_ns, task, mask, text)).is_err() {
            self.shared.dropped_reports.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn messages_dropped(&mut self, _: u64, _: TaskId, count: u32) {
        self.shared.dropped_messages.fetch_add(u64::from(count), Ordering::Relaxed);
    }
}

/// Everything the scan thread owns.
pub struct ScanThread {
    pub engine: Box<Engine>,
    pub io: GatedIo,
    pub shared: Arc<Shared>,
    pub edges: rtrb::Consumer<InputEdge>,
    pub commands: rtrb::Consumer<Command>,
    pub reports: rtrb::Producer<Report>,
    /// The programs' ADS log messages.
    pub messages: rtrb::Producer<LogMessage>,
    /// Answers to control commands.
    pub completions: rtrb::Producer<Completion>,
    /// Published at scan boundaries when the control thread asks.
    pub snapshot: Arc<Mutex<Box<Snapshot>>>,
    /// Its idle timer, armed at the engine's next wakeup.
    pub timer: Timer,
    /// Device words copied at a scan boundary for the threads that ask (retain, Modbus).
    pub mirrors: Vec<Arc<Mirror>>,
}

impl ScanThread {
    /// Runs until shutdown: then STOP (outputs to the safe state) and returns the engine.
    pub fn run(mut self) -> Box<Engine> {
        self.serve();
        self.into_engine()
    }

    /// The engine, after [`ScanThread::serve`] returned.
    pub fn into_engine(self) -> Box<Engine> {
        self.engine
    }

    /// The scan loop, until shutdown, then STOP. Allocates nothing (tests/scan_no_alloc.rs).
    ///
    /// Commands wait for a scan boundary: the engine is asked to hand back at END
    /// ([`Engine::set_hold_at_end`]) while commands or a snapshot request wait, so they are
    /// applied between two scans, never inside one.
    pub fn serve(&mut self) {
        let mut next_wakeup = 0u64;
        let mut published_deadline = 0u64;
        let mut published_scans = u64::MAX;
        let mut mode = self.engine.mode();
        let mut commands_waiting = false;
        self.publish_watchdog_period();
        loop {
            let flags = self.shared.pending.swap(0, Ordering::AcqRel);
            let now = sys::now_ns();
            if flags & pending::SHUTDOWN != 0 {
                break;
            }
            commands_waiting |= flags & pending::COMMAND != 0;
            if flags & pending::WATCHDOG != 0 {
                let mut sink = ReportSink {
                    reports: &mut self.reports,
                    messages: &mut self.messages,
                    shared: &self.shared,
                    source: None,
                };
                self.engine.watchdog_expired(now, &mut self.io, &mut sink);
            }
            if self.engine.mode() == Mode::Error && self.io.gate.is_tripped() {
                // The engine took the watchdog's verdict and writes no outputs in ERROR: the
                // gate opens again, so that leaving ERROR (STOP, reset, the key switch)
                // publishes its cleared outputs.
                self.io.gate.reopen();
            }
            if self.engine.at_scan_boundary() {
                if commands_waiting {
                    commands_waiting = false;
                    if self.apply_commands(now) {
                        // Another engine: its plan, whatever the mode.
                        mode = self.engine.mode();
                        self.shared.mode.store(mode_code(mode), Ordering::Relaxed);
                        self.publish_watchdog_period();
                    }
                }
                if self.shared.snapshot_wanted.load(Ordering::Acquire) {
                    if let Ok(mut snapshot) = self.snapshot.try_lock() {
                        snapshot.capture(&self.engine, now);
                        self.shared.snapshot_wanted.store(false, Ordering::Release);
                        drop(snapshot);
                        self.shared.control_wake.wake();
                    }
                }
                self.capture_mirrors(now);
            }
            let mut sink = ReportSink {
                reports: &mut self.reports,
                messages: &mut self.messages,
                shared: &self.shared,
                source: None,
            };
            if flags & pending::EDGE != 0 {
                while let Ok(edge) = self.edges.pop() {
                    self.engine.input_edge(
                        edge.contact,
                        edge.rising,
                        edge.stamp_ns,
                        now,
                        &mut sink,
                    );
                }
            }
            if flags != 0 || now >= next_wakeup {
                self.engine.poll_time(now, &mut self.io, &mut sink);
            }
            // Hand back at every END, not only every SLICE_STEPS instructions: a slice of a
            // short program spans many scans, and their END processing and I/O refresh count no
            // steps, so pending work (an edge, a deadline, a command) would wait for many scans.
            self.engine.set_hold_at_end(true);
            let mut activity = self.engine.run(&Monotonic, &mut self.io, &mut sink, SLICE_STEPS);
            let waiting = commands_waiting
                || self.shared.snapshot_wanted.load(Ordering::Relaxed)
                || self.mirrors.iter().any(|m| m.is_wanted());
            if waiting && self.engine.at_scan_boundary() {
                // Round again at once: the boundary is now.
                activity = Activity::Busy;
            }

            // Publish what the other threads watch.
            if self.engine.mode() != mode {
                mode = self.engine.mode();
                self.shared.mode.store(mode_code(mode), Ordering::Relaxed);
            }
            let deadline = self.engine.watchdog_deadline().unwrap_or(0);
            if deadline != published_deadline {
                self.shared.watchdog_deadline.store(deadline, Ordering::Release);
                published_deadline = deadline;
            }
            let scan = self.engine.scan_stats();
            if scan.count != published_scans {
                published_scans = scan.count;
                self.shared.scans.store(scan.count, Ordering::Relaxed);
                self.shared.scan_last_ns.store(scan.last_ns, Ordering::Relaxed);
                self.shared.scan_min_ns.store(scan.min_ns, Ordering::Relaxed);
                self.shared.scan_max_ns.store(scan.max_ns, Ordering::Relaxed);
                let missed = self.engine.missed_deadlines();
                self.shared.missed_deadlines.store(missed, Ordering::Relaxed);
                self.shared.progress.fetch_add(1, Ordering::Relaxed);
            }

            let now = sys::now_ns();
            next_wakeup = self.engine.next_wakeup(now).unwrap_or(u64::MAX);
            if activity == Activity::Idle && next_wakeup > now {
                if mode != Mode::Run {
                    // The STOP/ERROR/DEBUG loop is alive.
                    self.shared.progress.fetch_add(1, Ordering::Relaxed);
                }
                self.sleep_until(next_wakeup);
            }
        }
        let mut sink = ReportSink {
            reports: &mut self.reports,
            messages: &mut self.messages,
            shared: &self.shared,
            source: Some(Source::Signal),
        };
        self.io.gate.reopen();
        self.engine.set_mode(Mode::Stop, sys::now_ns(), &mut self.io, &mut sink);
        self.shared.mode.store(mode_code(Mode::Stop), Ordering::Relaxed);
        self.shared.watchdog_deadline.store(0, Ordering::Release);
    }

    /// Applies every queued command; true if the engine was replaced.
    fn apply_commands(&mut self, now: u64) -> bool {
        let mut replaced = false;
        while let Ok(command) = self.commands.pop() {
            match command {
                Command::Mode(to, source) => {
                    let mut sink = ReportSink {
                        reports: &mut self.reports,
                        messages: &mut self.messages,
                        shared: &self.shared,
                        source: Some(source),
                    };
                    self.engine.set_mode(to, now, &mut self.io, &mut sink);
                }
                Command::Write(address, value) => self.engine.write(&address, value),
                Command::Replace(new) => {
                    let was = self.engine.mode();
                    let mut sink = ReportSink {
                        reports: &mut self.reports,
                        messages: &mut self.messages,
                        shared: &self.shared,
                        source: Some(Source::Reload),
                    };
                    self.engine.set_mode(Mode::Stop, now, &mut self.io, &mut sink);
                    let old = std::mem::replace(&mut self.engine, new);
                    self.engine.inherit_retained(&old);
                    self.engine.inherit_forces(&old, &self.io);
                    if was == Mode::Run {
                        self.engine.set_mode(Mode::Run, now, &mut self.io, &mut sink);
                    }
                    // A full queue would drop (free) the old engine here: rare, and only on a
                    // reload.
                    sink.push(Report::Retired(old));
                    replaced = true;
                }
                Command::Words(writes) => {
                    let len = usize::from(writes.len).min(writes.items.len());
                    for w in &writes.items[..len] {
                        self.engine.write_masked(w.word, w.mask, w.value);
                    }
                    if writes.last {
                        self.shared.words_applied.fetch_max(writes.seq, Ordering::AcqRel);
                    }
                }
                Command::Control(ticket, command) => {
                    let result = self.apply_control(command, now, &mut replaced);
                    let completion = Completion { ticket, result };
                    // The queue holds as many completions as there can be commands.
                    let _ = self.completions.push(completion);
                    self.shared.control_wake.wake();
                }
            }
        }
        replaced
    }

    fn apply_control(
        &mut self,
        command: ControlCommand,
        now: u64,
        replaced: &mut bool,
    ) -> Result<Applied, Refusal> {
        let mut changed = true;
        let mut sink = ReportSink {
            reports: &mut self.reports,
            messages: &mut self.messages,
            shared: &self.shared,
            source: Some(Source::Remote),
        };
        let engine = &mut self.engine;
        match command {
            ControlCommand::Mode(request) => {
                engine.request_mode(request, now, &mut self.io, &mut sink)?;
            }
            ControlCommand::Writes { items, len } => {
                for write in &items[..len.min(items.len())] {
                    match *write {
                        Write::Device(address, value) => engine.write(&address, value),
                        Write::Value { at, elem, slot } => engine.write_value(at, elem, slot),
                    }
                }
            }
            ControlCommand::WriteText(text) if text.wide => {
                let len = usize::from(text.len.min(text.cap));
                engine.write_wstring(text.at, u32::from(text.cap), &text.chars[..2 * len]);
            }
            ControlCommand::WriteText(text) => {
                let len = usize::from(text.len.min(text.cap));
                engine.write_string(text.at, u32::from(text.cap), &text.chars[..len]);
            }
            ControlCommand::Force(bit, on) => engine.force(bit, on, &self.io),
            ControlCommand::Unforce(bit) => changed = engine.unforce(bit),
            ControlCommand::UnforceAll => engine.unforce_all(),
            ControlCommand::Step { scan: false } => engine.debug_step(now)?,
            ControlCommand::Step { scan: true } => engine.debug_step_scan(now)?,
            ControlCommand::Continue => engine.debug_continue(now)?,
            ControlCommand::Break(at) => {
                engine.debugger_mut().add(at).map_err(|_| Refusal::TooManyBreakpoints)?
            }
            ControlCommand::Unbreak(Some(at)) => changed = engine.debugger_mut().remove(at),
            ControlCommand::Unbreak(None) => engine.debugger_mut().clear(),
            ControlCommand::Load(new) => {
                if matches!(engine.mode(), Mode::Run | Mode::Debug) {
                    sink.push(Report::Retired(new));
                    return Err(Refusal::Running);
                }
                engine.set_mode(Mode::Stop, now, &mut self.io, &mut sink);
                let old = std::mem::replace(engine, new);
                engine.inherit_retained(&old);
                engine.inherit_forces(&old, &self.io);
                sink.push(Report::Retired(old));
                *replaced = true;
            }
            ControlCommand::Online(mut change) => {
                if matches!(engine.mode(), Mode::Stop | Mode::Error) {
                    engine.set_mode(Mode::Stop, now, &mut self.io, &mut sink);
                    std::mem::swap(engine, &mut change.engine);
                    engine.inherit_retained(&change.engine);
                    engine.inherit_forces(&change.engine, &self.io);
                } else {
                    let taken = change.engine.take_over(engine, &change.edges);
                    if let Err(refusal) = taken {
                        sink.push(Report::RetiredChange(change));
                        return Err(refusal);
                    }
                    std::mem::swap(engine, &mut change.engine);
                }
                sink.push(Report::RetiredChange(change));
                *replaced = true;
            }
        }
        Ok(Applied { mode: engine.mode(), scan: engine.scan_count(), changed })
    }

    /// Sleeps until `deadline` or a wake. Announces the sleep first, then looks at the pending
    /// flags once more: a producer either sees `scan_idle` and wakes us, or raised its flag
    /// before this last look.
    fn sleep_until(&mut self, deadline: u64) {
        self.shared.scan_idle.store(true, Ordering::SeqCst);
        if self.shared.pending.load(Ordering::SeqCst) == 0 {
            let armed = if deadline == u64::MAX {
                self.timer.disarm()
            } else {
                self.timer.arm(deadline, 0)
            };
            if armed.is_ok() {
                let fds = [self.timer_fd(), self.wake_fd()];
                // The timer's expiration count needs no read: arming it again resets it.
                // The wake eventfd is drained only when it was written.
                if sys::wait_any(&fds, None).map_or(true, |ready| ready & 0b10 != 0) {
                    self.shared.scan_wake.drain();
                }
            } else {
                self.shared.scan_wake.drain();
            }
        }
        self.shared.scan_idle.store(false, Ordering::SeqCst);
    }

    /// Copies the mirrors that asked for it (a boundary: after END, or any time in STOP).
    fn capture_mirrors(&self, now: u64) {
        if self.mirrors.is_empty() {
            return;
        }
        for mirror in &self.mirrors {
            mirror.capture_engine(&self.engine, now);
        }
    }

    /// The watchdog thread's idle sleep: the engine's watchdog time (a new engine may bring
    /// another).
    fn publish_watchdog_period(&self) {
        let period = self.engine.watchdog_ns();
        self.shared.watchdog_period_ns.store(period, Ordering::Relaxed);
    }

    fn timer_fd(&self) -> std::os::fd::BorrowedFd<'_> {
        use std::os::fd::AsFd;
        self.timer.as_fd()
    }

    fn wake_fd(&self) -> std::os::fd::BorrowedFd<'_> {
        use std::os::fd::AsFd;
        self.shared.scan_wake.as_fd()
    }
}
