//! The real-time driver of `plcd run`: the task engine on real time and real I/O.
//!
//! The engine decides what runs when; this module only feeds it events and time, as the
//! virtual-time driver (`plcd sim`) does in virtual time. Four threads:
//!
//! - **scan** (SCHED_FIFO, `scan_priority`): owns the [`Engine`] and the field I/O. It executes
//!   in slices of [`SLICE_STEPS`] instructions and between two slices takes the [`pending`]
//!   flags all at once — edges queued, commands queued (or a snapshot wanted), the watchdog
//!   tripped, a mirror copy wanted, shutdown — and reads a queue only when its flag says so.
//!   Cycle deadlines need no flag: they are the engine's, and the scan thread looks at the clock
//!   between two slices. When the engine is idle (fixed scan period, STOP) it sleeps on its own
//!   timerfd, armed at the engine's next wakeup (absolute CLOCK_MONOTONIC), and an eventfd that
//!   the other threads write to wake it.
//! - **events** ([`events`], `event_priority`, above scan): the GPIO line request's edge
//!   events (with their kernel timestamps) become queued edges and a pending flag, and the
//!   scan thread is woken if it sleeps.
//! - **watchdog** ([`watchdog`], `watchdog_priority`, the highest): puts the outputs into their
//!   safe state within a millisecond of the scan watchdog's expiry even if the scan thread is
//!   stuck, and makes the engine take its WDT path as soon as the scan thread runs again.
//! - **stimulus** ([`stimulus`], with the simulated field only, not real time): plays the inputs
//!   file in real time into the simulated field.
//!
//! The queues between threads are wait-free single-producer single-consumer rings (`rtrb`),
//! allocated at start. The command queue has several producers (the supervisor, the control
//! socket's requests, the Modbus server, the stimulus player): they share its producer end
//! behind a mutex, which the scan thread, its consumer, never takes. The snapshot and the
//! mirrors sit behind mutexes the scan thread only `try_lock`s. The [`door`] is not the scan
//! thread's: it carries the control protocol's requests of this process's services (the OPC UA
//! server's writes and methods) to the control thread, which queues them as any `plcctl`
//! request's commands. So the scan path neither
//! allocates nor waits for a lock (the rare exceptions are named where they are: an engine
//! dropped when the report queue is full, and the log line of an output that cannot be
//! switched off).

pub mod door;
pub mod driver;
pub mod events;
pub mod io;
pub mod mirror;
pub mod scan;
pub mod snapshot;
pub mod stimulus;
pub mod sys;
pub mod watchdog;

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;

use crate::config::{RtConfig, RtPolicy};
use crate::device::{Address, BitRef};
use crate::engine::debug::Breakpoint;
use crate::engine::event::{Event, Mode};
use crate::engine::online::OnlineChange;
use crate::engine::Engine;
use crate::engine::{ModeRequest, Refusal};
use crate::io::faults::FieldFaults;
use crate::io::SwitchPosition;
use crate::value::{Elem, Pointer};
use crate::vm::Clock;
use sys::{SysError, Wake};

/// Instructions executed between two looks at the pending set: about a microsecond at 3 ns an
/// instruction, so an event waits at most that long for the scan thread to notice it.
pub const SLICE_STEPS: u64 = 256;

/// Capacity of the edge queue (event or stimulus thread → scan thread).
pub const EDGE_QUEUE: usize = 256;
/// Capacity of the command queue (supervisor, control socket, Modbus server, stimulus → scan
/// thread).
pub const COMMAND_QUEUE: usize = 64;
/// Capacity of the report queue (scan thread → supervisor).
pub const REPORT_QUEUE: usize = 4096;
/// Capacity of the message queue (scan thread → supervisor): the programs' ADS log messages
/// (docs/ST.md, "ADS log messages"), each its text inline; a full queue drops the message and
/// counts it in [`Shared::dropped_reports`].
pub const MESSAGE_QUEUE: usize = 64;

/// An ADS log message of a program (`ADSLOGSTR`), on its way to the daemon's log: its text
/// inline, so that sending it allocates nothing.
#[derive(Clone)]
pub struct LogMessage {
    pub t_ns: u64,
    pub task: crate::engine::event::TaskId,
    /// Its `msgCtrlMask`.
    pub mask: u32,
    /// The text's bytes: `text[..len]`.
    pub len: u8,
    pub text: [u8; 255],
}

impl LogMessage {
    /// The message, its text cut to 255 bytes (a `T_MaxString` holds no more).
    pub fn new(t_ns: u64, task: crate::engine::event::TaskId, mask: u32, bytes: &[u8]) -> Self {
        let len = bytes.len().min(255);
        let mut text = [0; 255];
        text[..len].copy_from_slice(&bytes[..len]);
        LogMessage { t_ns, task, mask, len: len as u8, text }
    }

    pub fn bytes(&self) -> &[u8] {
        &self.text[..usize::from(self.len)]
    }
}
/// Capacity of the completion queue (scan thread → control thread): at least the command
/// queue, so that a completion always finds room.
pub const COMPLETION_QUEUE: usize = COMMAND_QUEUE;
/// Writes one control command carries; a longer `set` is split over several commands that
/// are applied at the same END.
pub const WRITES_PER_COMMAND: usize = 16;
/// The longest `STRING` a [`TextWrite`] carries: `STRING[255]`, the longest there is.
pub const MAX_TEXT_WRITE: usize = 255;

/// Flags of [`Shared::pending`].
pub mod pending {
    /// Edges wait in the edge queue.
    pub const EDGE: u32 = 1 << 1;
    /// Commands wait in the command queue.
    pub const COMMAND: u32 = 1 << 2;
    /// The watchdog thread tripped the output gate.
    pub const WATCHDOG: u32 = 1 << 3;
    /// Stop between two instructions and return.
    pub const SHUTDOWN: u32 = 1 << 4;
    /// A [`super::mirror::Mirror`] wants a copy at the next scan boundary.
    pub const MIRROR: u32 = 1 << 5;
}

/// A request to the scan thread, applied between two instructions.
pub enum Command {
    /// RUN or STOP (STOP also leaves ERROR).
    Mode(Mode, Source),
    /// Writes a device (a stimulus line of a non-P device).
    Write(Address, i32),
    /// Replaces the engine (a reloaded project), keeping the mode: RUN stays RUN (a cold
    /// restart of the new programs), STOP and ERROR become STOP. The old engine comes back as
    /// [`Report::Retired`].
    Replace(Box<Engine>),
    /// A command of the control socket, applied at a scan boundary and answered with a
    /// [`Completion`] carrying `ticket`.
    Control(u64, ControlCommand),
    /// Device words written by the Modbus server (see [`WordWrites`]).
    Words(WordWrites),
}

/// Words one [`Command::Words`] carries.
pub const WORDS_PER_COMMAND: usize = 32;

/// One device word changed under a mask: `word = (word & !mask) | (value & mask)`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WordWrite {
    /// A word index of device memory ([`crate::device::Memory::words`]).
    pub word: u16,
    pub mask: u16,
    pub value: u16,
}

/// Word writes of one request of a client off the real-time path, applied at a scan boundary
/// in every mode. A request longer than [`WORDS_PER_COMMAND`] spans several commands with the
/// same `seq`, pushed in one chunk (`rtrb::Producer::write_chunk_uninit`) so that the scan
/// thread pops all of them in the same pass; after the one marked `last` it raises
/// [`Shared::words_applied`] to `seq`. Sequence numbers rise in queue order.
#[derive(Debug, Clone, Copy)]
pub struct WordWrites {
    pub seq: u64,
    pub last: bool,
    /// The first `len` items are written.
    pub len: u8,
    pub items: [WordWrite; WORDS_PER_COMMAND],
}

/// One write of a control `set`: a device, or a Structured Text variable of an elementary
/// type (a located one writes its device words: a `DINT` at D00200 both D00200 and D00201).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Write {
    Device(Address, i32),
    /// `slot` stored as `elem` at `at`, as the VM stores it.
    Value {
        at: Pointer,
        elem: Elem,
        slot: u64,
    },
}

impl Default for Write {
    fn default() -> Write {
        Write::Value { at: Pointer::DISCARD, elem: Elem::Bool, slot: 0 }
    }
}

/// The characters a `STRING[cap]` variable is set to (the first `len` of `chars`, at most
/// `cap`); with `wide`, the code units a `WSTRING[cap]` is set to (`len` of them, 2 bytes of
/// `chars` each, little-endian).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TextWrite {
    pub at: Pointer,
    pub cap: u8,
    pub len: u8,
    pub chars: [u8; MAX_TEXT_WRITE],
    pub wide: bool,
}

/// What the control socket asks of the scan thread.
pub enum ControlCommand {
    Mode(ModeRequest),
    /// Device and variable writes (the first `len`), applied together, in order.
    Writes {
        items: [Write; WRITES_PER_COMMAND],
        len: usize,
    },
    /// A `STRING` variable written; the commands of one `set` are applied at the same END.
    WriteText(TextWrite),
    Force(BitRef, bool),
    Unforce(BitRef),
    UnforceAll,
    /// `step`, or `step --scan` (`scan: true`).
    Step {
        scan: bool,
    },
    Continue,
    Break(Breakpoint),
    /// One breakpoint, or all of them.
    Unbreak(Option<Breakpoint>),
    /// Replaces the engine; only in STOP or ERROR (the new one starts in STOP).
    Load(Box<Engine>),
    /// An online change (see [`crate::engine::online`]); in RUN or DEBUG at a scan boundary,
    /// and in STOP or ERROR as a plain replacement.
    Online(Box<OnlineChange>),
}

/// The outcome of a [`ControlCommand`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Completion {
    pub ticket: u64,
    pub result: Result<Applied, Refusal>,
}

/// The state right after a command was applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Applied {
    pub mode: Mode,
    /// Scans since RUN when it was applied.
    pub scan: u64,
    /// False when the command changed nothing: an unforce of a bit that was not forced, an
    /// unbreak of a breakpoint that was not set.
    pub changed: bool,
}

/// Who asked for a mode change, for the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    Startup,
    Stimulus,
    Signal,
    Reload,
    /// The control socket (`plcctl`, an HMI).
    Remote,
    /// The RUN/STOP key switch.
    Switch,
}

impl Source {
    pub fn as_str(self) -> &'static str {
        match self {
            Source::Startup => "startup",
            Source::Stimulus => "stimulus",
            Source::Signal => "signal",
            Source::Reload => "reload",
            Source::Remote => "control socket",
            Source::Switch => "key switch",
        }
    }
}

/// What the scan thread reports, in order.
pub enum Report {
    /// An engine event worth logging (an error, a watched output), at CLOCK_MONOTONIC ns.
    Event(u64, Event),
    /// A mode change, with who asked for it; `None`: the program or an error (STOP
    /// instruction, a stopping error).
    Mode(u64, Mode, Option<Source>),
    /// The engine a [`Command::Replace`] took out, to be dropped off the real-time thread.
    Retired(Box<Engine>),
    /// What an online change leaves behind (the old engine and the edge plan), or a refused
    /// one, to be dropped off the real-time thread.
    RetiredChange(Box<OnlineChange>),
    /// The key switch moved.
    Switch(u64, SwitchPosition),
}

/// State shared by the threads: atomics only, allocated once.
pub struct Shared {
    /// [`pending`] flags; the scan thread takes them all at once.
    pub pending: AtomicU32,
    /// The scan thread sleeps (or is about to): producers wake it through `scan_wake`.
    pub scan_idle: AtomicBool,
    pub scan_wake: Wake,
    /// Wakes the event thread: shutdown.
    pub event_wake: Wake,
    pub shutdown: AtomicBool,
    /// The engine's watchdog deadline (CLOCK_MONOTONIC ns), 0 while no scan runs.
    pub watchdog_deadline: AtomicU64,
    /// The watchdog time in ns: how long the watchdog thread may sleep while no deadline is
    /// published. Published by the scan thread when it starts and when it gets a new engine
    /// (0 until then: the watchdog thread looks every millisecond).
    pub watchdog_period_ns: AtomicU64,
    /// Times the watchdog thread tripped the gate, and how late after the expiry the outputs
    /// were safe the last time (ns).
    pub watchdog_trips: AtomicU64,
    pub watchdog_late_ns: AtomicU64,
    /// Bumped at every END and every pass of the STOP/ERROR loop: the service watchdog's
    /// proof of life.
    pub progress: AtomicU64,
    /// The engine's mode ([`Mode`] as u8: 0 RUN, 1 STOP, 2 ERROR, 3 DEBUG).
    pub mode: AtomicU8,
    /// Scans since RUN, and the last/min/max scan time in ns.
    pub scans: AtomicU64,
    pub scan_last_ns: AtomicU64,
    pub scan_min_ns: AtomicU64,
    pub scan_max_ns: AtomicU64,
    /// Cycle deadlines the engine noticed a full interval or more late
    /// ([`Engine::missed_deadlines`]), published at END.
    pub missed_deadlines: AtomicU64,
    /// Edges lost: by the kernel (sequence gaps) or to a full edge queue.
    pub lost_edges: AtomicU64,
    /// Failed refreshes and edge reads of the field, for the supervisor to log: the scan
    /// side's backend and the event thread count into it.
    pub field_faults: Arc<FieldFaults>,
    /// Reports dropped to a full report queue.
    pub dropped_reports: AtomicU64,
    /// ADS log messages the programs' task runs logged beyond the engine's cap of a run
    /// (docs/ST.md, "ADS log messages").
    pub dropped_messages: AtomicU64,
    /// The control thread wants a [`snapshot::Snapshot`] at the next scan boundary.
    pub snapshot_wanted: AtomicBool,
    /// Wakes the control thread: a completion or a snapshot is ready.
    pub control_wake: Wake,
    /// The `seq` of the last [`Command::Words`] request applied.
    pub words_applied: AtomicU64,
}

impl Shared {
    pub fn new() -> Result<Shared, SysError> {
        Ok(Shared {
            pending: AtomicU32::new(0),
            scan_idle: AtomicBool::new(false),
            scan_wake: Wake::new()?,
            event_wake: Wake::new()?,
            shutdown: AtomicBool::new(false),
            watchdog_deadline: AtomicU64::new(0),
            watchdog_period_ns: AtomicU64::new(0),
            watchdog_trips: AtomicU64::new(0),
            watchdog_late_ns: AtomicU64::new(0),
            progress: AtomicU64::new(0),
            mode: AtomicU8::new(mode_code(Mode::Stop)),
            scans: AtomicU64::new(0),
            scan_last_ns: AtomicU64::new(0),
            scan_min_ns: AtomicU64::new(0),
            scan_max_ns: AtomicU64::new(0),
            missed_deadlines: AtomicU64::new(0),
            lost_edges: AtomicU64::new(0),
            field_faults: Arc::default(),
            dropped_reports: AtomicU64::new(0),
            dropped_messages: AtomicU64::new(0),
            snapshot_wanted: AtomicBool::new(false),
            control_wake: Wake::new()?,
            words_applied: AtomicU64::new(0),
        })
    }

    /// Raises pending flags and wakes the scan thread if it sleeps. SeqCst on both sides (here
    /// and in the scan thread's sleep) so that a flag raised while it decides to sleep is seen
    /// either by its last look or by this load of `scan_idle`.
    pub fn signal(&self, flags: u32) {
        self.pending.fetch_or(flags, Ordering::SeqCst);
        if self.scan_idle.load(Ordering::SeqCst) {
            self.scan_wake.wake();
        }
    }

    pub fn mode(&self) -> Mode {
        match self.mode.load(Ordering::Relaxed) {
            0 => Mode::Run,
            1 => Mode::Stop,
            3 => Mode::Debug,
            _ => Mode::Error,
        }
    }

    /// Asks every thread to finish.
    pub fn request_shutdown(&self) {
        self.shutdown.store(true, Ordering::SeqCst);
        self.signal(pending::SHUTDOWN);
        self.event_wake.wake();
    }
}

pub fn mode_code(mode: Mode) -> u8 {
    match mode {
        Mode::Run => 0,
        Mode::Stop => 1,
        Mode::Error => 2,
        Mode::Debug => 3,
    }
}

/// Real time as the VM and the engine see it: CLOCK_MONOTONIC; the calendar time of ST
/// programs is CLOCK_REALTIME, UTC.
#[derive(Debug, Clone, Copy, Default)]
pub struct Monotonic;

impl Clock for Monotonic {
    #[inline]
    fn now_ns(&self, _steps: u64) -> u64 {
        sys::now_ns()
    }

    fn utc_ns(&self, _steps: u64) -> u64 {
        sys::utc_ns()
    }
}

/// Stack every real-time thread touches before its loop, so that with memory locked no page
/// fault comes later.
pub const PREFAULT_STACK: usize = 256 * 1024;
/// Stack size of the real-time threads: twice what they prefault. With memory locked all of it
/// is resident, so it is sized to need, not to habit (the scan path does not recurse: calls
/// and loops of PLC programs live in fixed arrays of their task's state).
pub const THREAD_STACK: usize = 512 * 1024;
/// Stack size of the process's threads that are not real time: the stimulus player, the
/// control socket's server, the Modbus server's listener and connection threads, the retain
/// writer. It lives beside [`THREAD_STACK`] for the same reason: once [`sys::lock_memory`] has
/// locked every later mapping too, each of these stacks is resident in full, so it is sized to
/// need (none of them recurses or keeps large buffers on its stack).
pub const PLAIN_THREAD_STACK: usize = 256 * 1024;

/// Stack size of the control thread, which does more than serve: a `load` compiles the new
/// project there (the parser nests up to 64 levels, and native code is generated) and builds
/// its engine. A debug build's frames are large: 256 KiB, [`PLAIN_THREAD_STACK`], overflowed
/// building a plain project's engine once `Config` grew by 400 bytes (copies of it sit in
/// several frames of the load); a program nested 63 levels deep loads with this one in a debug
/// build (`tests/control_e2e.rs`).
pub const CONTROL_THREAD_STACK: usize = 2 * 1024 * 1024;

/// Why a thread runs without what `[rt]` asked for.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{thread} thread: {error}")]
pub struct RtSetupError {
    pub thread: &'static str,
    pub error: SysError,
}

/// Which thread, for its scheduling settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    Scan,
    Events,
    Watchdog,
}

impl Role {
    pub fn name(self) -> &'static str {
        match self {
            Role::Scan => "scan",
            Role::Events => "events",
            Role::Watchdog => "watchdog",
        }
    }
}

/// Applies `[rt]` to the calling thread: CPU affinity, then SCHED_FIFO at the role's priority
/// (unless the policy is `other`), then a prefaulted stack. Errors are returned for the caller
/// to warn about or refuse; the thread is usable either way.
pub fn setup_thread(rt: &RtConfig, role: Role) -> Vec<RtSetupError> {
    let (priority, cpus) = match role {
        Role::Scan => (rt.scan_priority, &rt.scan_cpus),
        Role::Events => (rt.event_priority, &rt.event_cpus),
        Role::Watchdog => (rt.watchdog_priority, &rt.watchdog_cpus),
    };
    let mut errors = Vec::new();
    if let Err(error) = sys::set_affinity(cpus) {
        errors.push(RtSetupError { thread: role.name(), error });
    }
    if rt.policy == RtPolicy::Fifo {
        if let Err(error) = sys::set_fifo(priority) {
            errors.push(RtSetupError { thread: role.name(), error });
        }
    }
    sys::prefault_stack(PREFAULT_STACK);
    errors
}
