//! The field I/O of the daemon: the configured backend, behind the output gate, and the safe
//! output state the watchdog thread applies on its own.

use std::sync::Arc;

use crate::device::{BitRef, Memory};
use crate::io::gate::{AfterWrite, OutputGate};
use crate::io::gpio::{GpioIo, GpioOutputs};
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

/// Every output OFF, from any thread, without the scan thread's help.
#[derive(Clone)]
pub enum SafeOutputs {
    Simulated(Arc<SimulatedField>),
    Gpio(GpioOutputs),
}

impl SafeOutputs {
    pub fn apply(&self) {
        match self {
            SafeOutputs::Simulated(field) => field.clear_outputs(),
            SafeOutputs::Gpio(outputs) => {
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
    pub gate: Arc<OutputGate>,
    pub safe: SafeOutputs,
    /// `on_fault = "clear"`: a write that overlapped the gate's closing is undone.
    pub clear_on_trip: bool,
}

impl Io for GatedIo {
    #[inline]
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        self.field.refresh_inputs(mem);
    }

    #[inline]
    fn refresh_outputs(&mut self, mem: &Memory) {
        if self.gate.begin_write() {
            self.field.refresh_outputs(mem);
            if self.gate.end_write() == AfterWrite::ApplySafeState && self.clear_on_trip {
                self.safe.apply();
            }
        }
    }

    fn switch(&self) -> Option<SwitchPosition> {
        self.field.switch()
    }

    fn is_input(&self, bit: BitRef) -> bool {
        self.field.is_input(bit)
    }
}
