//! Modes and the moves between them (XGB §5.2.3): RUN, STOP, DEBUG and ERROR, what the driver
//! may command ([`Engine::set_mode`]), what a remote client may ask ([`Engine::request_mode`],
//! under the key switch), DEBUG's pause and resume, a stopping error, and the key switch: read
//! at each input refresh, acted on where the mode may change.

use crate::config::OnFault;
use crate::io::{Io, SwitchPosition};

use super::debug::{Session, Until};
use super::event::{ErrorKind, Event, EventSink, Mode, INIT};
use super::scan::{Phase, ScanStats};
use super::schedule::{Init, Starts};
use super::task::{Kind, State};
use super::{Engine, Refusal, Retained, STOP_REFRESH_NS};

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

/// The mode, carrying what only that mode has: ERROR its stopping error, RUN and DEBUG the state
/// of a started program, DEBUG its session. A latched error outside ERROR, a scan phase in
/// STOP or a breakpoint pause in RUN cannot be written; [`Engine::mode`] and
/// [`Engine::latched_error`] read it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ModeState {
    /// Nothing executes; inputs are refreshed every 10 ms.
    Stop,
    /// Stopped by a stopping error, latched until a change to STOP.
    Error(ErrorKind),
    /// The programs execute.
    Run(Running),
    /// The programs execute only as the engineer lets them (`step`, `continue`), as far as
    /// the session says.
    Debug(Running, Session),
}

impl ModeState {
    pub(super) fn mode(self) -> Mode {
        match self {
            ModeState::Stop => Mode::Stop,
            ModeState::Error(_) => Mode::Error,
            ModeState::Run(_) => Mode::Run,
            ModeState::Debug(..) => Mode::Debug,
        }
    }
}

/// What RUN and DEBUG share, from a RUN start to the next stop: a change between the two keeps
/// it, so a scan DEBUG paused goes on in RUN where it stood.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Running {
    /// How far the current scan is.
    pub(super) phase: Phase,
    /// How far the init task is.
    pub(super) init: Init,
    /// Whether `DI` (all tasks) holds task starts.
    pub(super) starts: Starts,
}

/// The RUN/STOP key switch of a `[switch]`. The engine keeps an `Option<KeySwitch>`, `None`
/// without a configured switch, so no position can be held for a switch that does not exist.
///
/// Invariant: `moved`, when set, differs from `acted_on` — a refresh keeps only a position the
/// rules have not acted on, and acting on it takes it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct KeySwitch {
    /// The position the mode rules last acted on; `None` before the first look.
    acted_on: Option<SwitchPosition>,
    /// A position read at an input refresh, not yet acted on.
    moved: Option<SwitchPosition>,
}

impl KeySwitch {
    /// True when an input refresh saw the switch move and the rules have yet to act.
    #[inline]
    pub(super) fn has_moved(&self) -> bool {
        self.moved.is_some()
    }

    /// The position to act on now, if the switch moved; it becomes the one acted on.
    #[inline]
    fn take_move(&mut self) -> Option<SwitchPosition> {
        let position = self.moved.take()?;
        if Some(position) == self.acted_on {
            return None;
        }
        self.acted_on = Some(position);
        Some(position)
    }
}

impl Engine {
    /// A mode command of the driver itself (startup, the simulator's `MODE` pseudo-device,
    /// shutdown), not subject to the key switch. RUN is refused in ERROR: the error is latched
    /// until a change to STOP.
    pub fn set_mode(&mut self, mode: Mode, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        match (self.mode(), mode) {
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
            ModeRequest::Run | ModeRequest::Debug if self.mode() == Mode::Error => {
                return Err(Refusal::ErrorLatched)
            }
            ModeRequest::Run => self.set_mode(Mode::Run, now, io, sink),
            ModeRequest::Stop => self.set_mode(Mode::Stop, now, io, sink),
            ModeRequest::Debug => self.set_mode(Mode::Debug, now, io, sink),
            ModeRequest::Reset { cold } => {
                if self.mode == ModeState::Stop {
                    self.last_operation_error = None;
                } else {
                    self.enter_stop(now, io, sink);
                }
                if cold {
                    self.vm.mem.clear_all();
                    self.vm.reset_variables();
                    self.retained = Retained::Cold;
                    self.check_watches(now, sink);
                }
            }
        }
        Ok(())
    }

    /// True when remote mode changes are accepted: no key switch, or the switch at STOP.
    pub fn remote_allowed(&self) -> bool {
        self.switch.is_none_or(|switch| switch.acted_on == Some(SwitchPosition::Stop))
    }

    /// The key switch position the engine acts on, if a switch is configured and was read.
    pub fn switch(&self) -> Option<SwitchPosition> {
        self.switch.and_then(|switch| switch.acted_on)
    }

    /// True between two scans with no task executing (or nothing executing at all: STOP,
    /// ERROR, DEBUG paused): where commands that change PLC state are applied.
    pub fn at_scan_boundary(&self) -> bool {
        !self.executing() || self.between_scans()
    }

    /// No scan under way and no task active.
    fn between_scans(&self) -> bool {
        self.phase() == Phase::Idle && self.stack.is_empty()
    }

    /// DEBUG `step`: paused before an instruction (at a breakpoint, or after a step), runs to
    /// the next statement of that task on another line, stepping over calls; paused between
    /// two scans, runs through the next scan. A breakpoint on the way stops it first.
    pub fn debug_step(&mut self, now: u64) -> Result<(), Refusal> {
        let until = match self.mode {
            ModeState::Debug(_, session) => match session.paused_at() {
                Some((task, from)) => {
                    let depth = self.tasks[usize::from(task)].exec.call_depth();
                    Until::NextLine { task, from, depth }
                }
                None => Until::ScanEnd,
            },
            _ => Until::ScanEnd,
        };
        self.debug_resume(until, now)
    }

    /// DEBUG `step --scan`: runs to the end of the current scan (or through the next one when
    /// paused between scans), or to a breakpoint.
    pub fn debug_step_scan(&mut self, now: u64) -> Result<(), Refusal> {
        self.debug_resume(Until::ScanEnd, now)
    }

    /// DEBUG: runs scan after scan until a breakpoint.
    pub fn debug_continue(&mut self, now: u64) -> Result<(), Refusal> {
        self.debug_resume(Until::Breakpoint, now)
    }

    fn debug_resume(&mut self, until: Until, now: u64) -> Result<(), Refusal> {
        let ModeState::Debug(running, session) = self.mode else {
            return Err(Refusal::NotInDebug);
        };
        if !session.executes() {
            // The pause is not the program's time: the watchdog starts over.
            self.watchdog_start_ns = now;
            self.skip_cycle_deadlines(now);
        }
        self.mode = ModeState::Debug(running, session.resumed(until));
        Ok(())
    }

    /// RUN, or DEBUG while `step` or `continue` lets the programs run.
    #[inline]
    pub(super) fn executing(&self) -> bool {
        match self.mode {
            ModeState::Run(_) => true,
            ModeState::Debug(_, session) => session.executes(),
            ModeState::Stop | ModeState::Error(_) => false,
        }
    }

    /// RUN or DEBUG: the programs are loaded for execution (device memory initialized).
    #[inline]
    pub(super) fn running(&self) -> bool {
        matches!(self.mode, ModeState::Run(_) | ModeState::Debug(..))
    }

    /// The phase of the scan; outside RUN and DEBUG there is no scan, which reads as between
    /// two.
    #[inline]
    pub(super) fn phase(&self) -> Phase {
        match self.mode {
            ModeState::Run(running) | ModeState::Debug(running, _) => running.phase,
            ModeState::Stop | ModeState::Error(_) => Phase::Idle,
        }
    }

    /// What RUN and DEBUG share; `None` in STOP and ERROR.
    #[inline]
    pub(super) fn running_mut(&mut self) -> Option<&mut Running> {
        match &mut self.mode {
            ModeState::Run(running) | ModeState::Debug(running, _) => Some(running),
            ModeState::Stop | ModeState::Error(_) => None,
        }
    }

    /// RUN (or DEBUG, paused before the first scan) from STOP: device memory initialized.
    fn enter_run(&mut self, mode: Mode, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        self.vm.reset_for_run(&self.retain, self.retained == Retained::Warm);
        self.retained = Retained::Warm;
        for task in &mut self.tasks {
            task.state = State::Idle;
            task.starts = Starts::Enabled;
            if let Kind::Cycle { interval_ns, .. } = task.kind {
                task.kind = Kind::Cycle { interval_ns, next_ns: now + interval_ns };
            }
        }
        self.stack.clear();
        self.run_start_ns = now;
        self.scan = ScanStats::default();
        self.last_operation_error = None;
        self.missed_deadlines = 0;
        let init =
            if self.tasks[INIT as usize].programs.is_empty() { Init::Done } else { Init::Running };
        let running = Running { phase: Phase::Idle, init, starts: Starts::Enabled };
        self.mode = match mode {
            Mode::Debug => ModeState::Debug(running, Session::BETWEEN_SCANS),
            _ => ModeState::Run(running),
        };
        sink.event(now, Event::Mode(mode));
        self.refresh_inputs(io);
        self.sample_device_conditions_quietly();
        // Variables start at their initial values, which are not changes; devices were
        // cleared, and an output that was on and is now off is one.
        for watch in self.watches.iter_mut().filter(|w| !w.watches_device()) {
            watch.sample_quietly(&self.vm);
        }
        self.check_watches(now, sink);
        self.next_scan_ns = now;
    }

    /// DEBUG from RUN: the current scan ends, then execution pauses.
    fn enter_debug(&mut self, now: u64, sink: &mut impl EventSink) {
        let ModeState::Run(running) = self.mode else { return };
        let session = if self.between_scans() {
            Session::BETWEEN_SCANS
        } else {
            Session::Executing { until: Until::ScanEnd, resume_from: None }
        };
        self.mode = ModeState::Debug(running, session);
        sink.event(now, Event::Mode(Mode::Debug));
    }

    /// RUN from DEBUG: execution goes on where it stands, device memory kept.
    fn leave_debug(&mut self, now: u64, sink: &mut impl EventSink) {
        let ModeState::Debug(running, session) = self.mode else { return };
        if !session.executes() {
            self.watchdog_start_ns = now;
            self.skip_cycle_deadlines(now);
        }
        self.mode = ModeState::Run(running);
        sink.event(now, Event::Mode(Mode::Run));
    }

    /// STOP from RUN, DEBUG or ERROR: execution stops, every output OFF, an error cleared.
    /// A RUN that ends gives up its instances (the next RUN start initialises them again):
    /// their `FB_exit` runs (not after a stopping error, which left them as they were).
    pub(super) fn enter_stop(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        let finishing = self.running();
        self.halt();
        if finishing {
            self.finish_instances(now);
        }
        self.clear_outputs(io);
        self.mode = ModeState::Stop;
        sink.event(now, Event::Mode(Mode::Stop));
        self.check_watches(now, sink);
        self.next_stop_refresh_ns = now + STOP_REFRESH_NS;
    }

    /// A stopping error: execution stops at once, outputs cleared or held, mode ERROR.
    pub(super) fn fault(
        &mut self,
        kind: ErrorKind,
        now: u64,
        io: &mut impl Io,
        sink: &mut impl EventSink,
    ) {
        sink.event(now, Event::Error(kind));
        self.halt();
        if self.settings.on_fault == OnFault::Clear {
            self.clear_outputs(io);
        }
        self.mode = ModeState::Error(kind);
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
        self.vm.stop();
    }

    /// An input refresh's look at the key switch: a position the rules have not acted on is
    /// kept for [`Engine::apply_switch`], which acts where the mode may change.
    pub(super) fn note_switch(&mut self, io: &impl Io) {
        if let Some(switch) = &mut self.switch {
            if let Some(position) = io.switch() {
                if Some(position) != switch.acted_on {
                    switch.moved = Some(position);
                }
            }
        }
    }

    /// Acts on a key switch move (XGB §5.2.3): to RUN starts the PLC from STOP (and leaves
    /// DEBUG; RUN goes on without interruption; a latched error stays until the switch goes
    /// to STOP); to STOP stops it from any mode, clearing an error.
    pub(super) fn apply_switch(&mut self, now: u64, io: &mut impl Io, sink: &mut impl EventSink) {
        let Some(position) = self.switch.as_mut().and_then(KeySwitch::take_move) else { return };
        sink.event(now, Event::Switch(position));
        match (position, self.mode()) {
            (SwitchPosition::Run, Mode::Stop) => self.enter_run(Mode::Run, now, io, sink),
            (SwitchPosition::Run, Mode::Debug) => self.leave_debug(now, sink),
            (SwitchPosition::Stop, Mode::Run | Mode::Debug | Mode::Error) => {
                self.enter_stop(now, io, sink)
            }
            _ => {}
        }
    }
}
