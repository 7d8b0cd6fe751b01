//! The four counters of XGB §5.2.6. They count rising edges of their inputs, so each keeps the
//! previous input; current values are unsigned 16-bit and saturate at 0 and 65535.

use crate::device::{counter_done, counter_value, BitRef, Memory};
use crate::lang::ops::CounterKind;

/// Run-time state of one counter number.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CounterState {
    prev_input: bool,
    prev_down: bool,
    /// The preset of the last execution, for `RST` of a down counter.
    preset: u16,
    /// A down counter that has loaded its preset (it does so at its first execution after
    /// RUN starts and at `RST`).
    loaded: bool,
    is_down: bool,
}

/// Executes `CTU`, `CTD` or `CTR` with the rung result `input`.
pub fn execute(
    kind: CounterKind,
    state: &mut CounterState,
    mem: &mut Memory,
    counter: u16,
    input: bool,
    preset: u16,
) {
    let value_ref = counter_value(counter);
    let rising = input && !state.prev_input;
    state.prev_input = input;
    state.preset = preset;
    state.is_down = kind == CounterKind::Ctd;
    let mut value = mem.word(value_ref);
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
    mem.set_word(value_ref, value);
    mem.set_bit(counter_done(counter), done);
}

/// Executes `CTUD`: while the rung is ON, rising edges of `up` count up and of `down` count down.
pub fn execute_up_down(
    state: &mut CounterState,
    mem: &mut Memory,
    counter: u16,
    enabled: bool,
    up: BitRef,
    down: BitRef,
    preset: u16,
) {
    let up_now = mem.bit(up);
    let down_now = mem.bit(down);
    let up_edge = up_now && !state.prev_input;
    let down_edge = down_now && !state.prev_down;
    state.prev_input = up_now;
    state.prev_down = down_now;
    state.preset = preset;
    state.is_down = false;
    let value_ref = counter_value(counter);
    let mut value = mem.word(value_ref);
    if enabled {
        if up_edge {
            value = value.saturating_add(1);
        }
        if down_edge {
            value = value.saturating_sub(1);
        }
    }
    mem.set_word(value_ref, value);
    mem.set_bit(counter_done(counter), value >= preset);
}

/// `RST Cn`: contact OFF; the current value 0, or the preset for a down counter.
pub fn reset(state: &mut CounterState, mem: &mut Memory, counter: u16) {
    let value = if state.is_down && state.loaded { state.preset } else { 0 };
    mem.set_word(counter_value(counter), value);
    mem.set_bit(counter_done(counter), false);
}
