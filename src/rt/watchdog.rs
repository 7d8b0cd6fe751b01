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

/// How long to sleep when no scan runs, between looks at the deadline. The scan thread
/// unparks this thread when it arms the watchdog, so this is only a backstop.
const IDLE_SLEEP: Duration = Duration::from_millis(100);

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
                std::thread::park_timeout(IDLE_SLEEP);
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
