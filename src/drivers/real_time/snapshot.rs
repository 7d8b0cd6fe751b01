//! The snapshot the control thread reads the PLC from, published by the scan thread at a scan
//! boundary (after END processing, or any time nothing executes: STOP, ERROR, DEBUG paused).
//!
//! It lives behind a mutex the scan thread only ever `try_lock`s: if a reader holds it, the
//! capture waits for the next boundary, so the scan never waits. A capture happens only when
//! the control thread asked for one ([`super::Shared::snapshot_wanted`]), and copies only what
//! is asked for — the device words of pending `get`s, at most [`MAX_READ_WORDS`] — plus the
//! figures, whose histograms are copied over their used range only. Everything is allocated
//! once; capturing allocates nothing.

use crate::engine::debug::{Breakpoint, DebugRun, MAX_BREAKPOINTS};
use crate::engine::event::{ErrorKind, Mode, TaskId};
use crate::engine::force::Forces;
use crate::engine::{Engine, ScanStats, TaskStats};
use crate::io::SwitchPosition;

/// Device words one capture reads at most.
pub const MAX_READ_WORDS: usize = 256;
/// Tasks at most: the scan program, the init task, 8 cycle, 8 io and 8 device tasks.
pub const MAX_TASKS: usize = 26;

/// The PLC as of one scan boundary.
pub struct Snapshot {
    /// Bumped by each capture; 0 before the first.
    pub generation: u64,
    /// When it was taken (CLOCK_MONOTONIC ns).
    pub at_ns: u64,
    /// Word indices to read at the next capture (the control thread writes these).
    pub want: [u16; MAX_READ_WORDS],
    pub want_len: usize,
    /// The words read at the last capture: `read[i]` is the value of `read_words[i]`.
    pub read_words: [u16; MAX_READ_WORDS],
    pub read: [u16; MAX_READ_WORDS],
    pub read_len: usize,
    pub mode: Mode,
    pub scan: ScanStats,
    /// Per task, in [`TaskId`] order; `task_count` of them are in use.
    pub tasks: Vec<TaskStats>,
    pub task_count: usize,
    pub latched_error: Option<ErrorKind>,
    pub last_operation_error: Option<ErrorKind>,
    pub switch: Option<SwitchPosition>,
    pub remote_allowed: bool,
    pub forces: Forces,
    pub debug_run: DebugRun,
    pub paused_at: Option<(TaskId, Breakpoint)>,
    pub breakpoints: [Breakpoint; MAX_BREAKPOINTS],
    pub breakpoint_count: usize,
}

impl Snapshot {
    pub fn new() -> Box<Snapshot> {
        Box::new(Snapshot {
            generation: 0,
            at_ns: 0,
            want: [0; MAX_READ_WORDS],
            want_len: 0,
            read_words: [0; MAX_READ_WORDS],
            read: [0; MAX_READ_WORDS],
            read_len: 0,
            mode: Mode::Stop,
            scan: ScanStats::default(),
            tasks: (0..MAX_TASKS).map(|_| TaskStats::default()).collect(),
            task_count: 0,
            latched_error: None,
            last_operation_error: None,
            switch: None,
            remote_allowed: true,
            forces: Forces::default(),
            debug_run: DebugRun::Paused,
            paused_at: None,
            breakpoints: [Breakpoint { program: 0, pc: 0 }; MAX_BREAKPOINTS],
            breakpoint_count: 0,
        })
    }

    /// Copies what was asked for out of `engine`. Scan thread; allocates nothing.
    pub fn capture(&mut self, engine: &Engine, now_ns: u64) {
        let words = engine.vm().mem.words();
        self.read_len = self.want_len.min(MAX_READ_WORDS);
        for i in 0..self.read_len {
            let index = self.want[i];
            self.read_words[i] = index;
            self.read[i] = words.get(usize::from(index)).copied().unwrap_or(0);
        }
        self.mode = engine.mode();
        let scan = engine.scan_stats();
        self.scan.count = scan.count;
        self.scan.last_ns = scan.last_ns;
        self.scan.min_ns = scan.min_ns;
        self.scan.max_ns = scan.max_ns;
        self.scan.time.copy_from(&scan.time);
        self.task_count = 0;
        for (dst, src) in self.tasks.iter_mut().zip(engine.all_task_stats()) {
            dst.runs = src.runs;
            dst.ignored = src.ignored;
            dst.overruns = src.overruns;
            dst.start_latency.copy_from(&src.start_latency);
            dst.notice_latency.copy_from(&src.notice_latency);
            dst.exec_time.copy_from(&src.exec_time);
            self.task_count += 1;
        }
        self.latched_error = engine.latched_error();
        self.last_operation_error = engine.last_operation_error();
        self.switch = engine.switch();
        self.remote_allowed = engine.remote_allowed();
        self.forces.clone_from(engine.forces());
        let debugger = engine.debugger();
        self.debug_run = debugger.run_state();
        self.paused_at = debugger.paused_at();
        let breakpoints = debugger.breakpoints();
        self.breakpoint_count = breakpoints.len().min(MAX_BREAKPOINTS);
        self.breakpoints[..self.breakpoint_count]
            .copy_from_slice(&breakpoints[..self.breakpoint_count]);
        self.at_ns = now_ns;
        self.generation += 1;
    }

    /// The value of word `index` at the last capture, if it was read.
    pub fn word(&self, index: u16) -> Option<u16> {
        self.read_words[..self.read_len].iter().position(|&w| w == index).map(|i| self.read[i])
    }
}
