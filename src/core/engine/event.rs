//! What the engine reports: the events of the trace (docs/SIMULATION.md), without allocation.
//!
//! Tasks are named by [`TaskId`]; a sink turns ids into names (`scan`, `init`, or the
//! configured name) with the table the engine gives it.

use crate::io::SwitchPosition;
use crate::vm::error_code_text;

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

impl ErrorKind {
    /// The error's `code` (`WDT`, `CONGESTION`, `3405H` …) and `detail` (what, and where in
    /// which program), as the trace and the daemon's log show them. `names` is indexed by
    /// [`TaskId`]; `program_lines` by the `program` of an operation error: the program's name
    /// and the source line of each instruction (index = pc).
    pub fn describe(
        self,
        names: &[String],
        program_lines: &[(String, Vec<u32>)],
    ) -> (String, String) {
        match self {
            ErrorKind::Watchdog { scan, limit_ms } => {
                ("WDT".to_string(), format!("scan {scan} exceeded watchdog_ms {limit_ms}"))
            }
            ErrorKind::Congestion { task, limit_ms } => (
                "CONGESTION".to_string(),
                format!("task {} exceeded max_exec_ms {limit_ms}", task_name(names, task)),
            ),
            ErrorKind::Operation { code, task, program, pc } => {
                let place = match program_lines.get(usize::from(program)) {
                    Some((name, lines)) => match lines.get(pc as usize) {
                        Some(source_line) => format!("program {name}, line {source_line}"),
                        None => format!("program {name}, step {pc}"),
                    },
                    None => format!("program #{program}, step {pc}"),
                };
                (error_code_text(code), format!("task {}, {place}", task_name(names, task)))
            }
        }
    }
}

/// A task's name from the table indexed by [`TaskId`]; an id outside it is written as `#` and
/// the number (`#9`), which only a bug in the caller produces.
pub fn task_name(names: &[String], task: TaskId) -> String {
    match names.get(usize::from(task)) {
        Some(name) => name.clone(),
        None => format!("#{task}"),
    }
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
    /// Watched Structured Text variable number `watch` changed to `slot` (a value encoded as
    /// `crate::value` says; the watch's type tells how to show it). A `STRING` variable's
    /// change comes through [`EventSink::text`] instead.
    SetVariable {
        watch: u16,
        slot: u64,
    },
    Error(ErrorKind),
    /// The RUN/STOP key switch moved (a mode change it causes follows).
    Switch(SwitchPosition),
}

/// Receives events in time order; `t_ns` is the time since RUN started.
pub trait EventSink {
    fn event(&mut self, t_ns: u64, event: Event);

    /// Watched `STRING` variable number `watch` changed to `text` (its bytes, borrowed from
    /// the variable's memory so that reporting allocates nothing). Ignored unless a sink wants
    /// it.
    fn text(&mut self, t_ns: u64, watch: u16, text: &[u8]) {
        let _ = (t_ns, watch, text);
    }

    /// Watched `WSTRING` variable number `watch` changed to the code units `units` (2 bytes
    /// each, little-endian, borrowed as for [`EventSink::text`]). Ignored unless a sink wants
    /// it.
    fn wide_text(&mut self, t_ns: u64, watch: u16, units: &[u8]) {
        let _ = (t_ns, watch, units);
    }

    /// A message task `task` logged (Tc2_System's `ADSLOGSTR`, `ADSLOGDINT`, `ADSLOGLREAL`,
    /// docs/ST.md "ADS log messages"), reported as the task's run ends: `mask` is its
    /// `msgCtrlMask` (`ADSLOG_MSGTYPE_…` bits), `text` its characters, borrowed from variable
    /// memory. Ignored unless a sink wants it.
    fn message(&mut self, t_ns: u64, task: TaskId, mask: u32, text: &[u8]) {
        let _ = (t_ns, task, mask, text);
    }

    /// Task `task`'s run logged `count` messages beyond the cap of a run, which were dropped.
    fn messages_dropped(&mut self, t_ns: u64, task: TaskId, count: u32) {
        let _ = (t_ns, task, count);
    }
}

/// The kind of an ADS log message by its `msgCtrlMask`, as the trace and the log name it:
/// `error`, `warning`, `hint` (`ADSLOG_MSGTYPE_ERROR`, `_WARN`, `_HINT`; the most severe bit
/// set wins), else `log`.
pub fn message_kind(mask: u32) -> &'static str {
    if mask & 0x04 != 0 {
        "error"
    } else if mask & 0x02 != 0 {
        "warning"
    } else if mask & 0x01 != 0 {
        "hint"
    } else {
        "log"
    }
}

/// A sink that keeps every event, for tests.
#[derive(Debug, Default, Clone)]
pub struct Recorder(pub Vec<(u64, Event)>);

impl EventSink for Recorder {
    fn event(&mut self, t_ns: u64, event: Event) {
        self.0.push((t_ns, event));
    }
}
