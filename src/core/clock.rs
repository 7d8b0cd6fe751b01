//! Time as the VM sees it: injected, so the same VM runs on the monotonic clock in the daemon,
//! on virtual time in `plcd sim`, and on a hand-set clock in tests. A clock also tells the
//! calendar time (the real-time clock ST programs read): the system's UTC clock in the daemon,
//! a start date plus virtual time in `plcd sim`.

use std::cell::Cell;

/// A source of the current time in nanoseconds since RUN started.
pub trait Clock {
    /// The time now; `steps` is the VM's executed-step count at this instruction, which a
    /// virtual clock uses to charge each instruction its cost.
    fn now_ns(&self, steps: u64) -> u64;

    /// The calendar time now, in nanoseconds since 1970-01-01 00:00:00 UTC (an `LDT`): what
    /// the real-time clock of ST programs reads. A clock that knows no calendar counts from
    /// that origin: the calendar time is [`Clock::now_ns`] (so 1970-01-01 at RUN start).
    fn utc_ns(&self, steps: u64) -> u64 {
        self.now_ns(steps)
    }

    /// The clock as a [`StepClock`], if it is one: native code then computes the time itself
    /// instead of calling [`Clock::now_ns`].
    fn linear(&self) -> Option<StepClock> {
        None
    }
}

/// Virtual time: `origin_ns` at step `origin_steps`, and `step_ns` for every instruction since.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepClock {
    pub origin_ns: u64,
    pub origin_steps: u64,
    pub step_ns: u64,
}

impl StepClock {
    /// Moves the clock to `now_ns` at step `steps` (idle time, which costs no steps).
    pub fn rebase(&mut self, now_ns: u64, steps: u64) {
        self.origin_ns = now_ns;
        self.origin_steps = steps;
    }
}

impl Clock for StepClock {
    #[inline]
    fn now_ns(&self, steps: u64) -> u64 {
        self.origin_ns + steps.saturating_sub(self.origin_steps) * self.step_ns
    }

    fn linear(&self) -> Option<StepClock> {
        Some(*self)
    }
}

/// Virtual time with a calendar: a [`StepClock`] whose zero is the calendar time `start_utc_ns`
/// (`plcd sim`'s `[sim] start`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CalendarClock {
    pub steps: StepClock,
    /// Nanoseconds since 1970-01-01 00:00:00 UTC at virtual time 0.
    pub start_utc_ns: u64,
}

impl Clock for CalendarClock {
    #[inline]
    fn now_ns(&self, steps: u64) -> u64 {
        self.steps.now_ns(steps)
    }

    fn utc_ns(&self, steps: u64) -> u64 {
        self.start_utc_ns.saturating_add(self.steps.now_ns(steps))
    }

    fn linear(&self) -> Option<StepClock> {
        Some(self.steps)
    }
}

/// A clock set by hand, for tests and timing diagrams.
#[derive(Debug, Default)]
pub struct ManualClock {
    now: Cell<u64>,
}

impl ManualClock {
    pub fn new(now_ns: u64) -> ManualClock {
        ManualClock { now: Cell::new(now_ns) }
    }
    pub fn set(&self, now_ns: u64) {
        self.now.set(now_ns);
    }
    pub fn advance(&self, by_ns: u64) {
        self.now.set(self.now.get() + by_ns);
    }
    pub fn get(&self) -> u64 {
        self.now.get()
    }
}

impl Clock for ManualClock {
    fn now_ns(&self, _steps: u64) -> u64 {
        self.now.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_clock_charges_each_step() {
        let mut clock = StepClock { origin_ns: 1_000, origin_steps: 10, step_ns: 250 };
        assert_eq!(clock.now_ns(10), 1_000);
        assert_eq!(clock.now_ns(14), 2_000);
        clock.rebase(5_000, 14);
        assert_eq!(clock.now_ns(15), 5_250);
    }

    #[test]
    fn the_calendar_advances_with_virtual_time() {
        let steps = StepClock { origin_ns: 0, origin_steps: 0, step_ns: 1_000 };
        let clock = CalendarClock { steps, start_utc_ns: 1_767_225_600_000_000_000 };
        assert_eq!(clock.now_ns(3), 3_000);
        assert_eq!(clock.utc_ns(3), 1_767_225_600_000_003_000);
        assert_eq!(clock.linear(), Some(steps));
        assert_eq!(steps.utc_ns(3), 3_000);
    }
}
