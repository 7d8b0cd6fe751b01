//! The four counters of XGB §5.2.6. They count rising edges of their inputs, so each keeps the
//! previous input; current values are unsigned 16-bit and saturate at 0 and 65535.
//!
//! The counters do not touch device memory: they take the current value the caller read and
//! return the new value and contact for the caller to write.

use crate::lang::ops::CounterKind;

/// Run-time state of one counter number. `repr(C)`: native code executes the counters itself
/// on this state, at the offsets of [`layout`] (the fields in the order the compiler gave them
/// before, as [`super::timer::TimerState`]'s).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[repr(C)]
pub struct CounterState {
    /// The preset of the last execution, for `RST` of a down counter.
    preset: u16,
    prev_input: bool,
    prev_down: bool,
    /// A down counter that has loaded its preset (it does so at its first execution after
    /// RUN starts and at `RST`).
    loaded: bool,
    is_down: bool,
}

/// Where native code finds a [`CounterState`]'s fields (the `bool`s are a byte each, 0 or 1).
pub mod layout {
    use super::CounterState;
    use std::mem::offset_of;

    pub const SIZE: usize = std::mem::size_of::<CounterState>();
    pub const PREV_INPUT: usize = offset_of!(CounterState, prev_input);
    pub const PREV_DOWN: usize = offset_of!(CounterState, prev_down);
    pub const PRESET: usize = offset_of!(CounterState, preset);
    pub const LOADED: usize = offset_of!(CounterState, loaded);
    pub const IS_DOWN: usize = offset_of!(CounterState, is_down);
}

impl CounterState {
    /// A retained counter at the start of RUN with its value kept (docs/RETAIN.md): a down
    /// counter does not load its preset again, and an input already ON at its first execution
    /// is no rising edge (it may have been ON before the restart: counting it would count one
    /// part twice).
    pub fn warm() -> CounterState {
        CounterState { prev_input: true, prev_down: true, loaded: true, ..CounterState::default() }
    }
}

/// Executes `CTU`, `CTD` or `CTR` with the rung result `input` on current value `value`: the
/// new value and contact.
pub fn execute(
    kind: CounterKind,
    state: &mut CounterState,
    input: bool,
    preset: u16,
    mut value: u16,
) -> (u16, bool) {
    let rising = input && !state.prev_input;
    state.prev_input = input;
    state.preset = preset;
    state.is_down = kind == CounterKind::Ctd;
    let done = match kind {
        CounterKind::Ctu => {
            if rising {
                value = value.saturating_add(1);
            }
            value >= preset
        }
        CounterKind::Ctd => {
            if !state.loaded {
                state.loaded = true;
                value = preset;
            }
            if rising {
                value = value.saturating_sub(1);
            }
            value == 0
        }
        CounterKind::Ctr => {
            if rising {
                value = if value >= preset { 0 } else { value + 1 };
            }
            value >= preset
        }
    };
    (value, done)
}

/// Executes `CTUD` on current value `value`: while the rung is ON (`enabled`), rising edges of
/// the up input (`up_now`) count up and of the down input count down. The new value and contact.
pub fn execute_up_down(
    state: &mut CounterState,
    enabled: bool,
    up_now: bool,
    down_now: bool,
    preset: u16,
    mut value: u16,
) -> (u16, bool) {
    let up_edge = up_now && !state.prev_input;
    let down_edge = down_now && !state.prev_down;
    state.prev_input = up_now;
    state.prev_down = down_now;
    state.preset = preset;
    state.is_down = false;
    if enabled {
        if up_edge {
            value = value.saturating_add(1);
        }
        if down_edge {
            value = value.saturating_sub(1);
        }
    }
    (value, value >= preset)
}

/// `RST Cn`: the current value to write, 0 or the preset for a down counter (the contact goes
/// OFF).
pub fn reset(state: &CounterState) -> u16 {
    if state.is_down && state.loaded {
        state.preset
    } else {
        0
    }
}
