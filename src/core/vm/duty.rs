//! The Mitsubishi FX5 `DUTY` instruction: user timing clocks SM420–SM424 (= SM8330–SM8334),
//! ON for n1 scans and OFF for n2 scans, switched at END, scan counts in SD8330–SD8334.

use crate::device::{duty_counter, duty_relay, Memory};

/// FX5 error: n1 or n2 outside 0..=32767.
pub const ERR_DUTY_RANGE: u16 = 0x3405;
/// Timing clock channels (SM420 … SM424).
pub const CHANNELS: usize = 5;

/// One timing clock.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DutyClock {
    active: bool,
    on_scans: u16,
    off_scans: u16,
    count: u16,
}

/// Executes `DUTY n1 n2 d` while its command input is ON: takes n1 and n2 (3405H when out of
/// range, the clock then unchanged); the command's rising edge starts the clock or restarts its
/// count. A command that turns OFF does not stop the clock.
pub fn execute(clock: &mut DutyClock, rising: bool, n1: u16, n2: u16) -> Result<(), u16> {
    if n1 > 32767 || n2 > 32767 {
        return Err(ERR_DUTY_RANGE);
    }
    clock.on_scans = n1;
    clock.off_scans = n2;
    if rising {
        clock.active = true;
        clock.count = 0;
    }
    Ok(())
}

/// END processing: switches each running clock's relay and advances its scan count.
pub fn end_scan(clocks: &mut [DutyClock; CHANNELS], mem: &mut Memory) {
    for (channel, clock) in clocks.iter_mut().enumerate() {
        if !clock.active {
            continue;
        }
        // n1 = 0: fixed OFF; n2 = 0 (n1 > 0): fixed ON.
        let on = clock.on_scans > 0 && (clock.off_scans == 0 || clock.count < clock.on_scans);
        mem.set_bit(duty_relay(channel), on);
        let period = u32::from(clock.on_scans) + u32::from(clock.off_scans);
        let next = u32::from(clock.count) + 1;
        clock.count = if next >= period { 0 } else { next as u16 };
        mem.set_word(duty_counter(channel), clock.count);
    }
}

/// STOP: every clock stops, its relay OFF and its count 0.
pub fn stop(clocks: &mut [DutyClock; CHANNELS], mem: &mut Memory) {
    for (channel, clock) in clocks.iter_mut().enumerate() {
        *clock = DutyClock::default();
        mem.set_bit(duty_relay(channel), false);
        mem.set_word(duty_counter(channel), 0);
    }
}
