//! The watchdog thread: the scan watchdog as a hardware watchdog would be, outside the thread
//! it watches.
//!
//! The engine detects the watchdog's expiry itself, but only when its thread runs. This thread
//! sleeps until the deadline the scan thread published; if the same deadline is still
//! published [`GRACE_NS`] after it passed, the scan thread is stuck (or starved), so this
//! thread closes the output gate, applies the safe output state (`on_fault = "clear"`; with
//! `"hold"` the outputs stay as they are and only further writes stop), and flags the scan
//! thread to take the engine's WDT path as soon as it runs. The error then stays until STOP.

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use super::io::SafeOutputs;
use super::{pending, sys, Shared};
use crate::io::gate::OutputGate;

/// How long past the deadline the scan thread has to take the WDT path by itself before this
/// thread acts: longer than a slice of instructions (the scan thread republishes its deadline
/// between slices), short enough that the outputs are safe well within 1 ms of the expiry.
pub const GRACE_NS: u64 = 200_000;

/// Everything the watchdog thread owns.
pub struct WatchdogThread {
    pub shared: Arc<Shared>,
    pub gate: Arc<OutputGate>,
    pub safe: SafeOutputs,
    /// `on_fault = "clear"`.
    pub clear: bool,
}

impl WatchdogThread {
    pub fn run(self) {
        let shared = &self.shared;
        while !shared.shutdown.load(Ordering::SeqCst) {
            let deadline = shared.watchdog_deadline.load(Ordering::Acquire);
            if deadline == 0 {
                // No scan runs. One that starts from now on has a deadline at least one
                // watchdog time away, so looking again after that time is early enough, and
                // the scan thread never has to wake this one (at a 10 ms scan period that
                // would be a futex call and a context switch every scan).
                let period = shared.watchdog_period_ns.load(Ordering::Relaxed);
                std::thread::park_timeout(Duration::from_nanos(period.max(1_000_000)));
                continue;
            }
            let now = sys::now_ns();
            let act_at = deadline + GRACE_NS;
            if now < act_at {
                std::thread::park_timeout(Duration::from_nanos(act_at - now));
                continue;
            }
            if shared.watchdog_deadline.load(Ordering::Acquire) != deadline {
                continue;
            }
            self.gate.trip();
            if self.clear {
                self.safe.apply();
            }
            let late = sys::now_ns().saturating_sub(deadline);
            shared.watchdog_late_ns.store(late, Ordering::Relaxed);
            shared.watchdog_trips.fetch_add(1, Ordering::Relaxed);
            shared.signal(pending::WATCHDOG);
            // Until the scan thread has taken the error (the deadline goes to 0), or shutdown.
            while shared.watchdog_deadline.load(Ordering::Acquire) == deadline
                && !shared.shutdown.load(Ordering::SeqCst)
            {
                std::thread::park_timeout(Duration::from_millis(10));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::{Address, Memory};
    use crate::io::simulated::SimulatedIo;
    use crate::io::Io;
    use std::time::Instant;

    /// A watchdog thread over a sim field whose P0040 is ON, and the field.
    fn setup() -> (Arc<Shared>, Arc<OutputGate>, Arc<crate::io::simulated::SimulatedField>) {
        let mut io = SimulatedIo::new(&[], &[], None);
        let mut mem = Memory::new();
        mem.write(&Address::parse("P0040").unwrap(), 1);
        io.refresh_outputs(&mem);
        let field = io.field();
        assert_eq!(field.output(4), 1);
        (Arc::new(Shared::new().unwrap()), Arc::new(OutputGate::default()), field)
    }

    fn start(
        shared: &Arc<Shared>,
        gate: &Arc<OutputGate>,
        field: &Arc<crate::io::simulated::SimulatedField>,
        clear: bool,
    ) -> std::thread::JoinHandle<()> {
        let thread = WatchdogThread {
            shared: Arc::clone(shared),
            gate: Arc::clone(gate),
            safe: SafeOutputs::simulated(Arc::clone(field)),
            clear,
        };
        std::thread::spawn(move || thread.run())
    }

    fn wait_for_trip(shared: &Shared) {
        let start = Instant::now();
        while shared.watchdog_trips.load(Ordering::Relaxed) == 0 {
            assert!(start.elapsed() < Duration::from_secs(20), "the watchdog never tripped");
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    fn stop(shared: &Shared, handle: std::thread::JoinHandle<()>) {
        shared.request_shutdown();
        handle.thread().unpark();
        handle.join().unwrap();
    }

    #[test]
    fn a_stuck_scan_gets_its_outputs_cleared_and_the_engine_told() {
        let (shared, gate, field) = setup();
        let handle = start(&shared, &gate, &field, true);
        // The scan thread arms the watchdog and never comes back.
        let deadline = sys::now_ns() + 20_000_000;
        shared.watchdog_deadline.store(deadline, Ordering::Release);
        handle.thread().unpark();
        wait_for_trip(&shared);
        assert_eq!(field.output(4), 0, "outputs cleared");
        assert!(gate.is_tripped(), "no further writes");
        assert_ne!(shared.pending.load(Ordering::SeqCst) & pending::WATCHDOG, 0);
        assert!(shared.watchdog_late_ns.load(Ordering::Relaxed) >= GRACE_NS);
        stop(&shared, handle);
    }

    #[test]
    fn with_hold_the_outputs_stay_but_writes_stop() {
        let (shared, gate, field) = setup();
        let handle = start(&shared, &gate, &field, false);
        shared.watchdog_deadline.store(sys::now_ns() + 10_000_000, Ordering::Release);
        handle.thread().unpark();
        wait_for_trip(&shared);
        assert_eq!(field.output(4), 1, "outputs held");
        assert!(gate.is_tripped());
        stop(&shared, handle);
    }

    #[test]
    fn a_scan_that_keeps_finishing_never_trips() {
        let (shared, gate, field) = setup();
        let handle = start(&shared, &gate, &field, true);
        // Scans end well before their deadline: each new scan publishes a later one.
        for _ in 0..30 {
            shared.watchdog_deadline.store(sys::now_ns() + 500_000_000, Ordering::Release);
            handle.thread().unpark();
            std::thread::sleep(Duration::from_millis(10));
        }
        shared.watchdog_deadline.store(0, Ordering::Release);
        assert_eq!(shared.watchdog_trips.load(Ordering::Relaxed), 0);
        assert_eq!(field.output(4), 1);
        assert!(!gate.is_tripped());
        stop(&shared, handle);
    }
}
