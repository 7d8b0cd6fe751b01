//! The simulated field in real time: plays an inputs file (docs/SIMULATION.md) against the
//! simulated field, as `plcd sim` does in virtual time. Input changes go to the field and, when
//! they are edges of P0000–P0007, to the edge queue stamped with the moment they happened;
//! `SWITCH` turns the field's key switch; other devices and `MODE` become commands. Not a real-time thread: its lateness only shifts
//! when an edge happens, and the stamp says when that was.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::{pending, sys, Command, Shared, Source};
use crate::engine::event::Mode;
use crate::io::simulated::SimulatedField;
use crate::io::InputEdge;
use crate::stimulus::{Stimulus, Target};

/// Everything the stimulus thread owns.
pub struct StimulusThread {
    pub shared: Arc<Shared>,
    pub stimuli: Vec<Stimulus>,
    /// Replay from the start after the last line: a pass lasts until its last change.
    pub looped: bool,
    pub field: Arc<SimulatedField>,
    pub edges: rtrb::Producer<InputEdge>,
    pub commands: Arc<Mutex<rtrb::Producer<Command>>>,
}

impl StimulusThread {
    pub fn run(mut self) {
        let Some(last) = self.stimuli.last().map(|s| s.t_ns) else { return };
        // A file whose changes are all at 0 would loop without end in no time.
        let period = last.max(1_000_000);
        // Time 0 of the file is the first RUN, as in `plcd sim`: edges played before it would
        // meet an engine in STOP, and how long a start takes would decide what the program sees.
        if !self.wait_for_run() {
            return;
        }
        let mut origin = sys::now_ns();
        loop {
            for index in 0..self.stimuli.len() {
                let stimulus = self.stimuli[index];
                if !self.sleep_until(origin + stimulus.t_ns) {
                    return;
                }
                self.apply(&stimulus);
            }
            if !self.looped {
                return;
            }
            origin += period;
        }
    }

    /// Until the engine is first in RUN; false on shutdown. The player is no real-time thread:
    /// it looks every millisecond.
    fn wait_for_run(&self) -> bool {
        while self.shared.mode() != Mode::Run {
            if self.shared.shutdown.load(Ordering::SeqCst) {
                return false;
            }
            std::thread::park_timeout(Duration::from_millis(1));
        }
        true
    }

    /// False on shutdown.
    fn sleep_until(&self, at_ns: u64) -> bool {
        loop {
            if self.shared.shutdown.load(Ordering::SeqCst) {
                return false;
            }
            let now = sys::now_ns();
            if now >= at_ns {
                return true;
            }
            std::thread::park_timeout(Duration::from_nanos(at_ns - now));
        }
    }

    fn apply(&mut self, stimulus: &Stimulus) {
        match stimulus.target {
            Target::Device(address) if self.field.is_input(&address) => {
                let mut flags = 0;
                for edge in self.field.set_input(&address, stimulus.value) {
                    let edge = InputEdge {
                        contact: edge.contact,
                        rising: edge.rising,
                        stamp_ns: sys::now_ns(),
                    };
                    if self.edges.push(edge).is_err() {
                        self.shared.lost_edges.fetch_add(1, Ordering::Relaxed);
                    }
                    flags = pending::EDGE;
                }
                if flags != 0 {
                    self.shared.signal(flags);
                }
            }
            Target::Device(address) => self.command(Command::Write(address, stimulus.value)),
            Target::Mode(mode) => self.command(Command::Mode(mode, Source::Stimulus)),
            Target::Switch(position) => {
                // The scan thread reads the switch at its next input refresh; a scan thread
                // asleep (STOP, or between scans) is woken to look, with no flag raised.
                if self.field.set_switch(position) {
                    self.shared.signal(0);
                }
            }
        }
    }

    fn command(&self, command: Command) {
        let pushed = match self.commands.lock() {
            Ok(mut queue) => queue.push(command).is_ok(),
            Err(_) => false,
        };
        if pushed {
            self.shared.signal(pending::COMMAND);
        } else {
            log::warn!("stimulus: the command queue is full; a change was dropped");
        }
    }
}
