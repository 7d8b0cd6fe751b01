//! The field I/O of the daemon: the configured backend and the remote devices, behind the
//! output gate, and the safe output state the watchdog thread applies on its own.

use std::sync::Arc;

use crate::device::{BitRef, Memory};
use crate::io::gate::{AfterWrite, OutputGate};
use crate::io::gpio::{GpioIo, GpioOutputs};
use crate::io::remote::{RemoteIo, RemoteSafeState};
use crate::io::simulated::{SimulatedField, SimulatedIo};
use crate::io::{Io, SwitchPosition};

/// The backend the scan thread refreshes.
pub enum FieldIo {
    Simulated(SimulatedIo),
    Gpio(GpioIo),
}

impl Io for FieldIo {
    #[inline]
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        match self {
            FieldIo::Simulated(io) => io.refresh_inputs(mem),
            FieldIo::Gpio(io) => io.refresh_inputs(mem),
        }
    }

    #[inline]
    fn refresh_outputs(&mut self, mem: &Memory) {
        match self {
            FieldIo::Simulated(io) => io.refresh_outputs(mem),
            FieldIo::Gpio(io) => io.refresh_outputs(mem),
        }
    }

    fn switch(&self) -> Option<SwitchPosition> {
        match self {
            FieldIo::Simulated(io) => io.switch(),
            FieldIo::Gpio(io) => io.switch(),
        }
    }

    fn is_input(&self, bit: BitRef) -> bool {
        match self {
            FieldIo::Simulated(io) => io.is_input(bit),
            FieldIo::Gpio(io) => io.is_input(bit),
        }
    }
}

/// Every output OFF, from any thread, without the scan thread's help: the field's, and every
/// remote write table's (its poller writes zeros).
#[derive(Clone)]
pub struct SafeOutputs {
    pub field: FieldSafeOutputs,
    pub remote: RemoteSafeState,
}

impl SafeOutputs {
    /// The simulated field's, without remote devices.
    pub fn simulated(field: Arc<SimulatedField>) -> SafeOutputs {
        SafeOutputs {
            field: FieldSafeOutputs::Simulated(field),
            remote: RemoteSafeState::default(),
        }
    }

    pub fn apply(&self) {
        self.field.apply();
        self.remote.apply();
    }
}

/// The field backend's outputs OFF.
#[derive(Clone)]
pub enum FieldSafeOutputs {
    Simulated(Arc<SimulatedField>),
    Gpio(GpioOutputs),
}

impl FieldSafeOutputs {
    pub fn apply(&self) {
        match self {
            FieldSafeOutputs::Simulated(field) => field.clear_outputs(),
            FieldSafeOutputs::Gpio(outputs) => {
                if let Err(e) = outputs.set_all_inactive() {
                    // Logging allocates, but this is the error path of the error path: the
                    // outputs could not be switched off, which the operator must hear about.
                    log::error!("watchdog: cannot switch the outputs off: {e}");
                }
            }
        }
    }
}

/// The scan thread's I/O: outputs pass the gate, which the watchdog thread closes.
pub struct GatedIo {
    pub field: FieldIo,
    /// The remote devices (`[[remote]]`), after the field at each refresh.
    pub remote: RemoteIo,
    pub gate: Arc<OutputGate>,
    pub safe: SafeOutputs,
    /// `on_fault = "clear"`: a write that overlapped the gate's closing is undone.
    pub clear_on_trip: bool,
}

impl Io for GatedIo {
    #[inline]
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        self.field.refresh_inputs(mem);
        self.remote.refresh_inputs(mem);
    }

    #[inline]
    fn refresh_outputs(&mut self, mem: &Memory) {
        if self.gate.begin_write() {
            self.field.refresh_outputs(mem);
            self.remote.refresh_outputs(mem);
            if self.gate.end_write() == AfterWrite::ApplySafeState && self.clear_on_trip {
                self.safe.apply();
            }
        }
    }

    fn switch(&self) -> Option<SwitchPosition> {
        self.field.switch()
    }

    fn is_input(&self, bit: BitRef) -> bool {
        self.field.is_input(bit) || self.remote.is_input(bit)
    }
}
