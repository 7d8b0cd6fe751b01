//! Failures of the field's I/O paths, counted where they happen and logged elsewhere.
//!
//! The paths that fail are real-time ones (the scan thread's input and output refresh, the
//! event thread's read of edge events), where logging is out of the question: it allocates and
//! takes locks, and a fault that persists would log at every scan. So a failure is only counted
//! here, with its errno, in atomics; the supervisor reads them a few times a second and logs
//! once per condition (when a path starts failing, when the errno changes, when it works again).

use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU64, Ordering};

/// The failures of one I/O path.
#[derive(Debug, Default)]
pub struct Faults {
    /// Failed attempts since start.
    count: AtomicU64,
    /// The errno of the last failure; 0 when it had none (a short read).
    errno: AtomicI32,
    /// The last attempt failed.
    failing: AtomicBool,
}

/// What a [`Faults`] holds, read at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultState {
    pub count: u64,
    pub errno: i32,
    pub failing: bool,
}

impl Faults {
    /// An attempt failed with `errno` (0: a failure without one). No allocation.
    pub fn failed(&self, errno: i32) {
        self.errno.store(errno, Ordering::Relaxed);
        self.failing.store(true, Ordering::Relaxed);
        // Last and with Release: a reader that sees the new count sees the errno with it.
        self.count.fetch_add(1, Ordering::Release);
    }

    /// An attempt worked. Writes only when it ends a failure, so that a path that works costs
    /// a load, not a store to a line the supervisor reads.
    #[inline]
    pub fn worked(&self) {
        if self.failing.load(Ordering::Relaxed) {
            self.failing.store(false, Ordering::Relaxed);
        }
    }

    pub fn state(&self) -> FaultState {
        // The count first (it is written last), so the errno is at least as new.
        let count = self.count.load(Ordering::Acquire);
        FaultState {
            count,
            errno: self.errno.load(Ordering::Relaxed),
            failing: self.failing.load(Ordering::Relaxed),
        }
    }
}

/// Every I/O path of the field that can fail while the PLC runs.
#[derive(Debug, Default)]
pub struct FieldFaults {
    /// The input refresh: one read of every input line.
    pub input_reads: Faults,
    /// The output refresh: one write of every output line.
    pub output_writes: Faults,
    /// The event thread's reads of edge events.
    pub edge_reads: Faults,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failure_is_counted_with_its_errno_until_an_attempt_works() {
        let faults = Faults::default();
        assert_eq!(faults.state(), FaultState { count: 0, errno: 0, failing: false });
        faults.failed(5);
        faults.failed(19);
        assert_eq!(faults.state(), FaultState { count: 2, errno: 19, failing: true });
        faults.worked();
        assert_eq!(faults.state(), FaultState { count: 2, errno: 19, failing: false });
    }
}
