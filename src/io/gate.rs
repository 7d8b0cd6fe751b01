//! The output gate between the scan thread and the watchdog thread.
//!
//! The scan thread publishes outputs at END; the watchdog thread must be able to put the real
//! outputs into the safe state within a millisecond of the watchdog's expiry even when the
//! scan thread is stuck, and the scan thread must not undo that afterwards. Neither may wait
//! for the other: the watchdog thread runs at a higher priority, so spinning until the scan
//! thread finishes a write could spin forever on a single CPU.
//!
//! So the gate is one atomic word with two flags. A writer sets WRITING and checks TRIPPED
//! before publishing; the watchdog sets TRIPPED and applies the safe state. If the two overlap,
//! the writer sees TRIPPED when it clears WRITING and applies the safe state again itself, so
//! whichever order the two threads run in, the safe state is the last one written.

use std::sync::atomic::{AtomicU8, Ordering};

const WRITING: u8 = 1;
const TRIPPED: u8 = 2;

/// See the module documentation.
#[derive(Debug, Default)]
pub struct OutputGate {
    state: AtomicU8,
}

/// What a writer must do after publishing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AfterWrite {
    Done,
    /// The gate tripped while the write was under way: apply the safe state again.
    ApplySafeState,
}

impl OutputGate {
    /// Before publishing outputs: false if the gate is tripped (do not publish).
    pub fn begin_write(&self) -> bool {
        let before = self.state.fetch_or(WRITING, Ordering::AcqRel);
        if before & TRIPPED != 0 {
            self.state.fetch_and(!WRITING, Ordering::AcqRel);
            return false;
        }
        true
    }

    /// After publishing outputs.
    pub fn end_write(&self) -> AfterWrite {
        let before = self.state.fetch_and(!WRITING, Ordering::AcqRel);
        if before & TRIPPED != 0 {
            AfterWrite::ApplySafeState
        } else {
            AfterWrite::Done
        }
    }

    /// Closes the gate: no output is published until [`OutputGate::reopen`]. The caller
    /// applies the safe state after this.
    pub fn trip(&self) {
        self.state.fetch_or(TRIPPED, Ordering::AcqRel);
    }

    pub fn is_tripped(&self) -> bool {
        self.state.load(Ordering::Acquire) & TRIPPED != 0
    }

    /// Opens the gate again (the engine left the error for STOP).
    pub fn reopen(&self) {
        self.state.fetch_and(!TRIPPED, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tripped_gate_refuses_writes_until_reopened() {
        let gate = OutputGate::default();
        assert!(gate.begin_write());
        assert_eq!(gate.end_write(), AfterWrite::Done);
        gate.trip();
        assert!(!gate.begin_write());
        assert!(!gate.begin_write(), "a refused write leaves no WRITING flag behind");
        gate.reopen();
        assert!(gate.begin_write());
        assert_eq!(gate.end_write(), AfterWrite::Done);
    }

    #[test]
    fn a_trip_during_a_write_hands_the_safe_state_to_the_writer() {
        let gate = OutputGate::default();
        assert!(gate.begin_write());
        gate.trip();
        assert_eq!(gate.end_write(), AfterWrite::ApplySafeState);
        assert!(gate.is_tripped());
    }

    #[test]
    fn concurrent_writes_and_a_trip_end_in_the_safe_state() {
        // A model of the field: the writer publishes 1s, the watchdog 0s; after the trip and
        // the writer's last write, the field must read 0.
        use std::sync::atomic::AtomicU32;
        use std::sync::Arc;
        for _ in 0..200 {
            let gate = Arc::new(OutputGate::default());
            let field = Arc::new(AtomicU32::new(0));
            let (g, f) = (Arc::clone(&gate), Arc::clone(&field));
            let writer = std::thread::spawn(move || {
                for _ in 0..1000 {
                    if g.begin_write() {
                        f.store(1, Ordering::SeqCst);
                        if g.end_write() == AfterWrite::ApplySafeState {
                            f.store(0, Ordering::SeqCst);
                        }
                    }
                }
            });
            std::thread::yield_now();
            gate.trip();
            field.store(0, Ordering::SeqCst);
            writer.join().unwrap();
            assert_eq!(field.load(Ordering::SeqCst), 0);
        }
    }
}
