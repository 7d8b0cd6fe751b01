//! The field as the task engine sees it: the [`Io`] trait every I/O backend implements, the
//! RUN/STOP key switch, and the edges that start I/O tasks.
//!
//! The engine calls [`Io::refresh_inputs`] at the start of each scan (and for `IORF`),
//! [`Io::refresh_outputs`] after END processing (and for `IORF`, STOP and stopping errors); a
//! backend decides which P bits are its inputs.
//!
//! Edges that start I/O tasks do not go through this trait: a backend reports them as
//! [`InputEdge`]s from its own event source (the gpiocdev line request's edge events, the
//! simulated field's stimulus player), and a driver hands them to the engine.

use crate::device::{BitRef, Memory};

/// An I/O backend as the task engine sees it.
pub trait Io {
    /// Copies the current input states into the input bits of the P area.
    fn refresh_inputs(&mut self, mem: &mut Memory);
    /// Publishes the output bits of the P area.
    fn refresh_outputs(&mut self, mem: &Memory);
    /// The RUN/STOP key switch as of the last [`Io::refresh_inputs`], if the backend has one
    /// (`[switch]`). The engine applies the mode rules of XGB §5.2.3 when it moves.
    fn switch(&self) -> Option<SwitchPosition> {
        None
    }
    /// True if `bit` of the P area is one of the backend's inputs (for the force flags).
    fn is_input(&self, bit: BitRef) -> bool {
        let _ = bit;
        false
    }
}

/// The position of the RUN/STOP key switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SwitchPosition {
    /// Local RUN: the PLC runs; remote mode changes are refused.
    #[default]
    Run,
    /// STOP: the PLC stops; remote RUN/STOP/DEBUG are accepted ("remote enabled").
    Stop,
}

impl SwitchPosition {
    /// The position as traces and logs write it: `RUN` or `STOP`.
    pub fn as_str(self) -> &'static str {
        match self {
            SwitchPosition::Run => "RUN",
            SwitchPosition::Stop => "STOP",
        }
    }
}

/// An edge on one of the contacts P0000–P0007 that I/O tasks start on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InputEdge {
    /// 0..=7: P0000..=P0007.
    pub contact: u8,
    /// true: OFF → ON (after `active_low` is applied).
    pub rising: bool,
    /// When the edge happened, CLOCK_MONOTONIC ns (the kernel's timestamp on gpiocdev).
    pub stamp_ns: u64,
}
