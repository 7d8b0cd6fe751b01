//! The snapshot the control thread reads the PLC from, published by the scan thread at a scan
//! boundary (after END processing, or any time nothing executes: STOP, ERROR, DEBUG paused).
//!
//! It lives behind a mutex the scan thread only ever `try_lock`s: if a reader holds it, the
//! capture waits for the next boundary, so the scan never waits. A capture happens only when
//! the control thread asked for one ([`super::Shared::snapshot_wanted`]), and copies only what
//! is asked for — the device words of pending `get`s, at most [`MAX_READ_WORDS`], and their
//! Structured Text variables, at most [`MAX_READ_VALUES`] values read as the VM reads them
//! (a located variable from its device words) and [`MAX_READ_TEXT`] bytes of `STRING`
//! characters — plus the figures, whose histograms are copied over their used range only.
//! Everything is allocated once; capturing allocates nothing. The control thread formats what
//! was read.

use crate::engine::debug::{Breakpoint, DebugRun, MAX_BREAKPOINTS};
use crate::engine::event::{ErrorKind, Mode, TaskId};
use crate::engine::force::Forces;
use crate::engine::{Engine, ScanStats, TaskStats};
use crate::io::SwitchPosition;
use crate::value::{Elem, Pointer};

/// Device words one capture reads at most.
pub const MAX_READ_WORDS: usize = 256;
/// Variable values one capture reads at most.
pub const MAX_READ_VALUES: usize = 256;
/// Bytes of `STRING` characters one capture reads at most (64 `STRING[255]`s).
pub const MAX_READ_TEXT: usize = 64 * 256;

/// A Structured Text variable to read at the next capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarRead {
    /// A value of an elementary type: its slot.
    Value { at: Pointer, elem: Elem },
    /// A `STRING[cap]`: its characters.
    Text { at: Pointer, cap: u8 },
    /// A `WSTRING[cap]`: the bytes of its code units (2 a unit, little-endian).
    WideText { at: Pointer, cap: u8 },
}

impl VarRead {
    /// The bytes of [`Snapshot::chars`] it takes.
    pub fn text_bytes(&self) -> usize {
        match self {
            VarRead::Value { .. } => 0,
            VarRead::Text { cap, .. } => usize::from(*cap),
            VarRead::WideText { cap, .. } => 2 * usize::from(*cap),
        }
    }
}

const NO_READ: VarRead = VarRead::Value { at: Pointer::DISCARD, elem: Elem::Bool };
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
    /// Variables to read at the next capture (the control thread writes these); their
    /// [`VarRead::text_bytes`] add up to at most [`MAX_READ_TEXT`].
    pub want_vars: [VarRead; MAX_READ_VALUES],
    pub want_vars_len: usize,
    /// The variables read at the last capture: `read_slots[i]` is the value of `read_vars[i]`,
    /// or for a `STRING` where its characters are in `chars`: `start << 32 | len`.
    pub read_vars: [VarRead; MAX_READ_VALUES],
    pub read_slots: [u64; MAX_READ_VALUES],
    pub read_vars_len: usize,
    pub chars: [u8; MAX_READ_TEXT],
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
            want_vars: [NO_READ; MAX_READ_VALUES],
            want_vars_len: 0,
            read_vars: [NO_READ; MAX_READ_VALUES],
            read_slots: [0; MAX_READ_VALUES],
            read_vars_len: 0,
            chars: [0; MAX_READ_TEXT],
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
        self.capture_variables(engine);
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

    /// Reads the wanted variables, as the VM reads them. Allocates nothing.
    fn capture_variables(&mut self, engine: &Engine) {
        let vm = engine.vm();
        let mut text_at = 0usize;
        self.read_vars_len = 0;
        for i in 0..self.want_vars_len.min(MAX_READ_VALUES) {
            let read = self.want_vars[i];
            let slot = match read {
                VarRead::Value { at, elem } => vm.read_value(at, elem),
                VarRead::Text { .. } | VarRead::WideText { .. } => {
                    let chars = match read {
                        VarRead::WideText { at, .. } => vm.wstring_bytes(at),
                        VarRead::Text { at, .. } | VarRead::Value { at, .. } => vm.string_bytes(at),
                    };
                    let len = chars.len().min(read.text_bytes());
                    let Some(room) = self.chars.get_mut(text_at..text_at + len) else {
                        // Past the buffer (the control thread keeps within it): not read.
                        continue;
                    };
                    room.copy_from_slice(&chars[..len]);
                    let slot = (text_at as u64) << 32 | len as u64;
                    text_at += len;
                    slot
                }
            };
            self.read_vars[self.read_vars_len] = read;
            self.read_slots[self.read_vars_len] = slot;
            self.read_vars_len += 1;
        }
    }

    /// The value of an elementary variable at the last capture, if it was read.
    pub fn value(&self, at: Pointer, elem: Elem) -> Option<u64> {
        let wanted = VarRead::Value { at, elem };
        self.read_vars[..self.read_vars_len]
            .iter()
            .position(|r| *r == wanted)
            .map(|i| self.read_slots[i])
    }

    /// The characters of a `STRING` variable at the last capture, if it was read.
    pub fn text(&self, at: Pointer, cap: u8) -> Option<&[u8]> {
        self.text_of(VarRead::Text { at, cap })
    }

    /// The bytes of the code units of a `WSTRING` variable at the last capture, if it was read.
    pub fn wide_text(&self, at: Pointer, cap: u8) -> Option<&[u8]> {
        self.text_of(VarRead::WideText { at, cap })
    }

    fn text_of(&self, wanted: VarRead) -> Option<&[u8]> {
        let i = self.read_vars[..self.read_vars_len].iter().position(|r| *r == wanted)?;
        let slot = self.read_slots[i];
        let (start, len) = ((slot >> 32) as usize, (slot & 0xFFFF_FFFF) as usize);
        self.chars.get(start..start + len)
    }

    /// Whether the last capture read `read`.
    pub fn has(&self, read: &VarRead) -> bool {
        self.read_vars[..self.read_vars_len].contains(read)
    }

    /// The value of word `index` at the last capture, if it was read.
    pub fn word(&self, index: u16) -> Option<u16> {
        self.read_words[..self.read_len].iter().position(|&w| w == index).map(|i| self.read[i])
    }
}
