//! The scan thread: the engine on the monotonic clock, fed with the pending work of the other
//! threads between two slices of instructions.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::thread::Thread;

use super::io::GatedIo;
use super::sys::{self, Timer};
use super::{mode_code, pending, Command, Monotonic, Report, Shared, Source, SLICE_STEPS};
use crate::engine::event::{Event, EventSink, Mode};
use crate::engine::{Activity, Engine};
use crate::io::InputEdge;

/// Forwards the events worth logging to the supervisor; the others are counted by the engine's
/// statistics. Never blocks: a full queue drops the report and counts it.
struct ReportSink<'a> {
    reports: &'a mut rtrb::Producer<Report>,
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
            Event::Error(_) | Event::Set { .. } => self.push(Report::Event(t_ns, event)),
            _ => {}
        }
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
    /// Its idle timer, armed at the engine's next wakeup.
    pub timer: Timer,
    /// The watchdog thread, unparked when a scan arms the watchdog.
    pub watchdog: Thread,
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
    pub fn serve(&mut self) {
        let mut next_wakeup = 0u64;
        let mut published_deadline = 0u64;
        let mut published_scans = u64::MAX;
        let mut mode = self.engine.mode();
        self.publish_plan();
        loop {
            let flags = self.shared.pending.swap(0, Ordering::AcqRel);
            let now = sys::now_ns();
            if flags & pending::SHUTDOWN != 0 {
                break;
            }
            let mut sink =
                ReportSink { reports: &mut self.reports, shared: &self.shared, source: None };
            if flags & pending::COMMAND != 0 {
                while let Ok(command) = self.commands.pop() {
                    match command {
                        Command::Mode(to, source) => {
                            sink.source = Some(source);
                            if to == Mode::Stop {
                                // Leaving an error: the gate the watchdog closed opens again
                                // so that STOP's cleared outputs are published.
                                self.io.gate.reopen();
                            }
                            self.engine.set_mode(to, now, &mut self.io, &mut sink);
                            sink.source = None;
                        }
                        Command::Write(address, value) => self.engine.write(&address, value),
                        Command::Replace(new) => {
                            let was = self.engine.mode();
                            sink.source = Some(Source::Reload);
                            self.io.gate.reopen();
                            self.engine.set_mode(Mode::Stop, now, &mut self.io, &mut sink);
                            let old = std::mem::replace(&mut self.engine, new);
                            if was == Mode::Run {
                                self.engine.set_mode(Mode::Run, now, &mut self.io, &mut sink);
                            }
                            sink.source = None;
                            // A full queue would drop (free) the old engine here: rare, and
                            // only on a reload.
                            sink.push(Report::Retired(old));
                            mode = Mode::Stop;
                        }
                    }
                }
            }
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
            if flags & pending::WATCHDOG != 0 {
                self.engine.watchdog_expired(now, &mut self.io, &mut sink);
            }
            if flags != 0 || now >= next_wakeup {
                self.engine.poll_time(now, &mut self.io, &mut sink);
            }
            let activity = self.engine.run(&Monotonic, &mut self.io, &mut sink, SLICE_STEPS);

            // Publish what the other threads watch.
            if self.engine.mode() != mode {
                mode = self.engine.mode();
                self.shared.mode.store(mode_code(mode), Ordering::Relaxed);
                self.publish_plan();
            }
            let deadline = self.engine.watchdog_deadline().unwrap_or(0);
            if deadline != published_deadline {
                self.shared.watchdog_deadline.store(deadline, Ordering::Release);
                if published_deadline == 0 {
                    self.watchdog.unpark();
                }
                published_deadline = deadline;
            }
            let scan = self.engine.scan_stats();
            if scan.count != published_scans {
                published_scans = scan.count;
                self.shared.scans.store(scan.count, Ordering::Relaxed);
                self.shared.scan_last_ns.store(scan.last_ns, Ordering::Relaxed);
                self.shared.scan_min_ns.store(scan.min_ns, Ordering::Relaxed);
                self.shared.scan_max_ns.store(scan.max_ns, Ordering::Relaxed);
                self.shared.progress.fetch_add(1, Ordering::Relaxed);
            }

            let now = sys::now_ns();
            next_wakeup = self.engine.next_wakeup(now).unwrap_or(u64::MAX);
            if activity == Activity::Idle && next_wakeup > now {
                if mode != Mode::Run {
                    // The STOP/ERROR loop is alive.
                    self.shared.progress.fetch_add(1, Ordering::Relaxed);
                }
                self.sleep_until(next_wakeup);
            }
        }
        let mut sink = ReportSink {
            reports: &mut self.reports,
            shared: &self.shared,
            source: Some(Source::Signal),
        };
        self.io.gate.reopen();
        self.engine.set_mode(Mode::Stop, sys::now_ns(), &mut self.io, &mut sink);
        self.shared.mode.store(mode_code(Mode::Stop), Ordering::Relaxed);
        self.shared.watchdog_deadline.store(0, Ordering::Release);
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
                let _ = sys::wait_readable(&fds, None);
            }
            let _ = self.timer.expirations();
            self.shared.scan_wake.drain();
        }
        self.shared.scan_idle.store(false, Ordering::SeqCst);
    }

    fn timer_fd(&self) -> std::os::fd::BorrowedFd<'_> {
        use std::os::fd::AsFd;
        self.timer.as_fd()
    }

    fn wake_fd(&self) -> std::os::fd::BorrowedFd<'_> {
        use std::os::fd::AsFd;
        self.shared.scan_wake.as_fd()
    }

    /// Publishes the cycle deadlines for the event thread's timers (all off outside RUN).
    fn publish_plan(&self) {
        for slot in &self.shared.plan {
            slot[0].store(0, Ordering::Relaxed);
        }
        for (number, next_ns, interval_ns) in self.engine.cycle_deadlines() {
            let slot = &self.shared.plan[usize::from(number) % super::CYCLE_SLOTS];
            slot[1].store(interval_ns, Ordering::Relaxed);
            slot[0].store(next_ns, Ordering::Relaxed);
        }
        self.shared.plan_generation.fetch_add(1, Ordering::Release);
        self.shared.event_wake.wake();
    }
}
