//! What the engine reports: the events of the trace (CONTRACT §4), without allocation.
//!
//! Tasks are named by [`TaskId`]; a sink turns ids into names (`scan`, `init`, or the
//! configured name) with the table the engine gives it.

/// A task of the engine: 0 is the scan program, 1 the initialization task, then the
/// configured `[[task]]`s in config order.
pub type TaskId = u16;

/// The scan program.
pub const SCAN: TaskId = 0;
/// The initialization task.
pub const INIT: TaskId = 1;

/// Operating modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Run,
    Stop,
    Error,
    /// XGB §5.2 DEBUG: the programs run by `step` and `continue` only.
    Debug,
}

impl Mode {
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Run => "RUN",
            Mode::Stop => "STOP",
            Mode::Error => "ERROR",
            Mode::Debug => "DEBUG",
        }
    }
}

/// Why a task request was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ignored {
    /// The task is running (or preempted, not yet finished).
    Running,
    /// The task already has a request waiting.
    Pending,
    /// The initialization task has not finished.
    Init,
    /// Not in RUN mode.
    Stop,
    /// The task's start is disabled and it already holds its one request.
    Disabled,
    /// DEBUG mode, paused: nothing starts until `step` or `continue`.
    Paused,
}

impl Ignored {
    pub fn as_str(self) -> &'static str {
        match self {
            Ignored::Running => "running",
            Ignored::Pending => "pending",
            Ignored::Init => "init",
            Ignored::Stop => "stop",
            Ignored::Disabled => "disabled",
            Ignored::Paused => "paused",
        }
    }
}

/// A stopping or operation error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The scan watchdog expired; `limit_ms` is `watchdog_ms`.
    Watchdog { scan: u64, limit_ms: u32 },
    /// A task ran longer than its `max_exec_ms`.
    Congestion { task: TaskId, limit_ms: u32 },
    /// An operation error of an instruction (`3400H` …) at `program`'s instruction `pc`.
    Operation { code: u16, task: TaskId, program: u16, pc: u32 },
}

/// One trace event. `set` values are the device's value after the change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    Mode(Mode),
    ScanStart {
        n: u64,
    },
    ScanEnd {
        n: u64,
    },
    TaskRequest {
        task: TaskId,
    },
    TaskIgnored {
        task: TaskId,
        why: Ignored,
    },
    TaskStart {
        task: TaskId,
    },
    TaskEnd {
        task: TaskId,
    },
    TaskPreempt {
        task: TaskId,
        by: TaskId,
    },
    TaskResume {
        task: TaskId,
    },
    /// Watched device number `watch` (an index into the watch list) changed to `value`.
    Set {
        watch: u16,
        value: i32,
    },
    Error(ErrorKind),
    /// The RUN/STOP key switch moved (a mode change it causes follows).
    Switch(crate::io::SwitchPosition),
}

/// Receives events in time order; `t_ns` is the time since RUN started.
pub trait EventSink {
    fn event(&mut self, t_ns: u64, event: Event);
}

/// A sink that keeps every event, for tests.
#[derive(Debug, Default, Clone)]
pub struct Recorder(pub Vec<(u64, Event)>);

impl EventSink for Recorder {
    fn event(&mut self, t_ns: u64, event: Event) {
        self.0.push((t_ns, event));
    }
}
