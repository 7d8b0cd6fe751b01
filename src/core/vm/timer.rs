//! The five timers of XGB §5.2.5. A timer's state keeps elapsed time in nanoseconds, not in base
//! ticks, so the remainder of a tick carries over from scan to scan: the error is at most one
//! scan plus the time from step 0 to the instruction, never a whole base tick.

use crate::lang::ops::TimerKind;

/// Run-time state of one timer number. `repr(C)`: native code executes the timers itself on
/// this state, at the offsets of [`layout`]. (The fields are in the order the compiler gave
/// them before `repr(C)`: the interpreter's machine code stayed the same, and with it the
/// layout of its loop that `benches/layout` guards.)
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[repr(C)]
pub struct TimerState {
    /// Time counted so far: elapsed for TON/TMR, elapsed since the start of the
    /// countdown for TOFF/TMON/TRTG.
    elapsed_ns: u64,
    /// When `elapsed_ns` was last brought up to date.
    last_ns: u64,
    /// The current value this timer last wrote; a different value in memory was written by the
    /// program (`MOV 30 T0001`), and the timer continues from it.
    shown: u16,
    running: bool,
    prev_input: bool,
}

/// Where native code finds a [`TimerState`]'s fields (the `bool`s are a byte each, 0 or 1).
pub mod layout {
    use super::TimerState;
    use std::mem::offset_of;

    pub const SIZE: usize = std::mem::size_of::<TimerState>();
    pub const ELAPSED_NS: usize = offset_of!(TimerState, elapsed_ns);
    pub const LAST_NS: usize = offset_of!(TimerState, last_ns);
    pub const RUNNING: usize = offset_of!(TimerState, running);
    pub const PREV_INPUT: usize = offset_of!(TimerState, prev_input);
    pub const SHOWN: usize = offset_of!(TimerState, shown);
}

impl TimerState {
    fn advance(&mut self, now_ns: u64) {
        self.elapsed_ns += now_ns.saturating_sub(self.last_ns);
        self.last_ns = now_ns;
    }

    fn start(&mut self, now_ns: u64) {
        self.running = true;
        self.elapsed_ns = 0;
        self.last_ns = now_ns;
    }

    /// Counts on if running, else starts from zero.
    fn run(&mut self, now_ns: u64) {
        if self.running {
            self.advance(now_ns);
        } else {
            self.start(now_ns);
        }
    }
}

/// One execution of a timer instruction: what the timer sees now.
#[derive(Debug, Clone, Copy)]
pub struct TimerInput {
    pub kind: TimerKind,
    /// The rung result.
    pub input: bool,
    /// Preset in base units.
    pub preset: u16,
    pub base_ms: u16,
    pub now_ns: u64,
    /// The timer's current value in device memory (the program may have written it).
    pub value: u16,
    /// The timer's contact in device memory.
    pub done: bool,
}

/// Executes a timer instruction: the new current value and contact, for the caller to write
/// to device memory. (The timer does not touch memory itself, so that the interpreter loop
/// can call it without giving up the memory's address held in registers.)
pub fn execute(state: &mut TimerState, call: TimerInput) -> (u16, bool) {
    let TimerInput { kind, input, preset, base_ms, now_ns, value: written, done: was_done } = call;
    let base_ns = u64::from(base_ms) * 1_000_000;
    let preset_ns = u64::from(preset) * base_ns;
    let counts_down = matches!(kind, TimerKind::Toff | TimerKind::Tmon | TimerKind::Trtg);
    if written != state.shown {
        let ticks = if counts_down { preset.saturating_sub(written) } else { written.min(preset) };
        state.elapsed_ns = u64::from(ticks) * base_ns;
    }
    let rising = input && !state.prev_input;
    state.prev_input = input;
    let ticks = |elapsed: u64| (elapsed / base_ns.max(1)).min(u64::from(preset)) as u16;
    // The down-counting timers: value = preset - elapsed ticks, contact OFF and idle at 0.
    let count_down = |state: &mut TimerState| {
        let value = preset - ticks(state.elapsed_ns);
        if value == 0 {
            state.running = false;
        }
        (value, value > 0)
    };

    let (value, done) = match kind {
        TimerKind::Ton => {
            if input {
                state.run(now_ns);
                state.elapsed_ns = state.elapsed_ns.min(preset_ns);
                let value = ticks(state.elapsed_ns);
                (value, value >= preset)
            } else {
                *state = TimerState { prev_input: false, ..TimerState::default() };
                (0, false)
            }
        }
        TimerKind::Tmr => {
            if input {
                if state.running {
                    state.advance(now_ns);
                } else {
                    state.running = true;
                    state.last_ns = now_ns;
                }
                state.elapsed_ns = state.elapsed_ns.min(preset_ns);
            } else {
                state.running = false;
            }
            let value = ticks(state.elapsed_ns);
            (value, value >= preset)
        }
        TimerKind::Toff => {
            if input {
                state.running = false;
                state.elapsed_ns = 0;
                (preset, true)
            } else if was_done {
                state.run(now_ns);
                count_down(state)
            } else {
                (0, false)
            }
        }
        TimerKind::Tmon | TimerKind::Trtg => {
            let retrigger = kind == TimerKind::Trtg && rising;
            if state.running && !retrigger {
                state.advance(now_ns);
            } else if rising {
                state.start(now_ns);
            }
            if state.running {
                count_down(state)
            } else {
                (0, false)
            }
        }
    };
    state.shown = value;
    (value, done)
}

/// `RST Tn`: the timer idle; the caller writes current value 0 and contact OFF.
pub fn reset(state: &mut TimerState) {
    *state = TimerState { prev_input: state.prev_input, ..TimerState::default() };
}
