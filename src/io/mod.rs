//! I/O backends behind one trait. The engine calls [`Io::refresh_inputs`] at the start of each
//! scan (and for `IORF`), [`Io::refresh_outputs`] after END processing (and for `IORF`, STOP and
//! stopping errors); a backend decides which P bits are its inputs.

pub mod sim;

use crate::device::Memory;

/// An I/O backend as the task engine sees it.
pub trait Io {
    /// Copies the current input states into the input bits of the P area.
    fn refresh_inputs(&mut self, mem: &mut Memory);
    /// Publishes the output bits of the P area.
    fn refresh_outputs(&mut self, mem: &Memory);
}
