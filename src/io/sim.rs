//! The in-process simulated backend: input states set by a stimulus (the inputs CSV, a test),
//! outputs kept as last published. Which P bits are inputs is given by a mask, so that input
//! refresh never overwrites the program's outputs.

use super::Io;
use crate::device::layout::P_WORDS;
use crate::device::{Address, Area, Memory};

/// Simulated field I/O.
#[derive(Debug, Clone)]
pub struct SimIo {
    inputs: [u16; P_WORDS as usize],
    input_mask: [u16; P_WORDS as usize],
    outputs: [u16; P_WORDS as usize],
}

impl Default for SimIo {
    fn default() -> Self {
        SimIo {
            inputs: [0; P_WORDS as usize],
            input_mask: [0; P_WORDS as usize],
            outputs: [0; P_WORDS as usize],
        }
    }
}

/// An edge on one of the contacts P0000–P0007 that I/O tasks can start on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContactEdge {
    pub contact: u8,
    pub rising: bool,
}

impl SimIo {
    /// Marks a P bit (or every bit of a P word) as an input.
    pub fn add_input(&mut self, address: &Address) {
        if address.area != Area::P {
            return;
        }
        let word = address.number as usize;
        self.input_mask[word] |= match address.bit {
            Some(bit) => 1 << bit,
            None => 0xFFFF,
        };
    }

    /// True if the address is a P device.
    pub fn is_io(address: &Address) -> bool {
        address.area == Area::P
    }

    /// Sets an input (a P bit, or a P word) as the field sees it. Returns the edges this causes
    /// on the contacts P0000–P0007, in bit order.
    pub fn set_input(
        &mut self,
        address: &Address,
        value: i32,
    ) -> impl Iterator<Item = ContactEdge> {
        let word = address.number as usize;
        let before = self.inputs[word];
        let after = match address.bit {
            Some(bit) if value != 0 => before | 1 << bit,
            Some(bit) => before & !(1 << bit),
            None => value as u16,
        };
        self.inputs[word] = after;
        let changed = if word == 0 { (before ^ after) & 0xFF } else { 0 };
        (0..8u8)
            .filter(move |b| changed & 1 << b != 0)
            .map(move |b| ContactEdge { contact: b, rising: after & 1 << b != 0 })
    }

    /// The outputs as last published.
    pub fn outputs(&self) -> &[u16] {
        &self.outputs
    }
}

impl Io for SimIo {
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        let image = mem.io_image_mut();
        for ((image, input), mask) in image.iter_mut().zip(&self.inputs).zip(&self.input_mask) {
            *image = (*image & !mask) | (input & mask);
        }
    }

    fn refresh_outputs(&mut self, mem: &Memory) {
        for ((out, image), mask) in
            self.outputs.iter_mut().zip(mem.io_image()).zip(&self.input_mask)
        {
            *out = image & !mask;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(s: &str) -> Address {
        Address::parse(s).unwrap()
    }

    #[test]
    fn input_refresh_keeps_outputs() {
        let mut io = SimIo::default();
        io.add_input(&addr("P0000"));
        io.add_input(&addr("P0001"));
        let mut mem = Memory::new();
        mem.write(&addr("P0040"), 1);
        mem.write(&addr("P0001"), 1);
        let edges: Vec<_> = io.set_input(&addr("P0000"), 1).collect();
        assert_eq!(edges, [ContactEdge { contact: 0, rising: true }]);
        io.refresh_inputs(&mut mem);
        assert_eq!(mem.read(&addr("P0000")), 1);
        assert_eq!(mem.read(&addr("P0001")), 0, "an input follows the field");
        assert_eq!(mem.read(&addr("P0040")), 1, "an output is the program's");
        io.refresh_outputs(&mem);
        assert_eq!(io.outputs()[4], 1);
        assert_eq!(io.outputs()[0], 0);
    }

    #[test]
    fn edges_only_on_contacts_that_change() {
        let mut io = SimIo::default();
        assert_eq!(io.set_input(&addr("P000"), 0b101).count(), 2);
        assert_eq!(io.set_input(&addr("P0000"), 1).count(), 0);
        let falling: Vec<_> = io.set_input(&addr("P0002"), 0).collect();
        assert_eq!(falling, [ContactEdge { contact: 2, rising: false }]);
        assert_eq!(io.set_input(&addr("P0010"), 1).count(), 0, "P0010 is not a task contact");
    }
}
