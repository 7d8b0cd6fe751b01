//! The in-process simulated backend: input states set by a stimulus (the inputs CSV, a test,
//! later the control socket), outputs kept as last published. Which P bits are inputs is given
//! by a mask, so that input refresh never overwrites the program's outputs.
//!
//! The field (input and output states, and the RUN/STOP key switch when `[switch]` is
//! configured) is a [`SimulatedField`] of atomics shared behind an `Arc`: in `plcd sim` one thread
//! sets inputs and refreshes, in the daemon a stimulus thread sets inputs while the scan thread
//! refreshes, and neither ever waits for the other.

use std::sync::atomic::{AtomicU16, AtomicU8, Ordering};
use std::sync::Arc;

use super::{Io, SwitchPosition};
use crate::device::layout::P_WORDS;
use crate::device::{Address, Area, BitRef, Memory};
use crate::project::Project;
use crate::stimulus::{Stimulus, Target};

const WORDS: usize = P_WORDS as usize;

/// The simulated wiring: the state of every P word as the field sees it.
#[derive(Debug)]
pub struct SimulatedField {
    inputs: [AtomicU16; WORDS],
    outputs: [AtomicU16; WORDS],
    input_mask: [u16; WORDS],
    /// Contacts of P0000–P0007 whose edges are reported.
    edge_mask: u16,
    /// The key switch: [`NO_SWITCH`] when none is configured, else a [`switch_code`].
    switch: AtomicU8,
}

/// [`SimulatedField::switch`] when no `[switch]` is configured.
const NO_SWITCH: u8 = 0;

fn switch_code(position: SwitchPosition) -> u8 {
    match position {
        SwitchPosition::Run => 1,
        SwitchPosition::Stop => 2,
    }
}

fn switch_of(code: u8) -> Option<SwitchPosition> {
    match code {
        1 => Some(SwitchPosition::Run),
        2 => Some(SwitchPosition::Stop),
        _ => None,
    }
}

/// Simulated field I/O: the scan side of a [`SimulatedField`].
#[derive(Debug, Clone)]
pub struct SimulatedIo {
    field: Arc<SimulatedField>,
    input_mask: [u16; WORDS],
    /// The key switch as of the last input refresh (`None`: no switch).
    switch: Option<SwitchPosition>,
}

impl Default for SimulatedIo {
    /// No inputs; edges reported on every contact; no key switch.
    fn default() -> Self {
        SimulatedIo::new(&[], &[0, 1, 2, 3, 4, 5, 6, 7], None)
    }
}

/// An edge on one of the contacts P0000–P0007 that I/O tasks can start on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContactEdge {
    pub contact: u8,
    pub rising: bool,
}

fn mask_of(address: &Address) -> Option<(usize, u16)> {
    if address.area != Area::P {
        return None;
    }
    Some((address.number as usize, address.bit.map_or(0xFFFF, |bit| 1 << bit)))
}

impl SimulatedIo {
    /// The simulated field: inputs are the io-task contacts, the configured `[[io.input]]`s and
    /// every P device the stimulus writes; the key switch, when `[switch]` is configured, starts at
    /// its `position`.
    pub fn for_project(project: &Project, stimuli: &[Stimulus]) -> SimulatedIo {
        let config = &project.config;
        let edge_contacts: Vec<u8> = config.edge_contacts().iter().map(|(c, _)| *c).collect();
        let mut inputs: Vec<Address> = edge_contacts
            .iter()
            .map(|&c| Address { area: Area::P, number: 0, bit: Some(c) })
            .collect();
        inputs.extend(config.io.inputs.iter().map(|line| line.device));
        inputs.extend(stimuli.iter().filter_map(|s| match s.target {
            Target::Device(address) => Some(address),
            Target::Mode(_) | Target::Switch(_) => None,
        }));
        let switch = config.switch.as_ref().map(|s| s.position);
        SimulatedIo::new(&inputs, &edge_contacts, switch)
    }

    /// A field whose inputs are the given P bits (or whole P words; other devices are
    /// ignored), reporting edges of the given contacts (0..=7: those I/O tasks start on, as
    /// the gpiocdev backend detects edges only there). `switch`: the key switch's starting
    /// position (`[switch] position`), `None` when no `[switch]` is configured.
    pub fn new(
        inputs: &[Address],
        edge_contacts: &[u8],
        switch: Option<SwitchPosition>,
    ) -> SimulatedIo {
        let mut input_mask = [0u16; WORDS];
        for (word, mask) in inputs.iter().filter_map(mask_of) {
            input_mask[word] |= mask;
        }
        let edge_mask = edge_contacts.iter().fold(0u16, |m, &c| m | 1 << (c & 7));
        let field = SimulatedField {
            inputs: std::array::from_fn(|_| AtomicU16::new(0)),
            outputs: std::array::from_fn(|_| AtomicU16::new(0)),
            input_mask,
            edge_mask,
            switch: AtomicU8::new(switch.map_or(NO_SWITCH, switch_code)),
        };
        SimulatedIo { field: Arc::new(field), input_mask, switch }
    }

    /// True if the address is a P device.
    pub fn is_io(address: &Address) -> bool {
        address.area == Area::P
    }

    /// The field, for another thread to set inputs and read outputs.
    pub fn field(&self) -> Arc<SimulatedField> {
        Arc::clone(&self.field)
    }

    /// Sets an input as the field sees it; the edges it causes on P0000–P0007.
    pub fn set_input(
        &mut self,
        address: &Address,
        value: i32,
    ) -> impl Iterator<Item = ContactEdge> {
        self.field.set_input(address, value)
    }

    /// Output word `word` as last published.
    pub fn output(&self, word: usize) -> u16 {
        self.field.output(word)
    }

    /// Turns the key switch as the field sees it (the scan sees it at its next input
    /// refresh); false, and nothing happens, when no `[switch]` is configured.
    pub fn set_switch(&mut self, position: SwitchPosition) -> bool {
        self.field.set_switch(position)
    }
}

impl SimulatedField {
    /// Sets an input (a P bit, or a P word) as the field sees it. Returns the edges this causes
    /// on the contacts P0000–P0007, in bit order. One thread sets inputs at a time.
    pub fn set_input(&self, address: &Address, value: i32) -> impl Iterator<Item = ContactEdge> {
        let word = address.number as usize;
        let cell = &self.inputs[word];
        let before = match address.bit {
            Some(bit) if value != 0 => cell.fetch_or(1 << bit, Ordering::Relaxed),
            Some(bit) => cell.fetch_and(!(1 << bit), Ordering::Relaxed),
            None => cell.swap(value as u16, Ordering::Relaxed),
        };
        let after = cell.load(Ordering::Relaxed);
        let changed = if word == 0 { (before ^ after) & self.edge_mask } else { 0 };
        (0..8u8)
            .filter(move |b| changed & 1 << b != 0)
            .map(move |b| ContactEdge { contact: b, rising: after & 1 << b != 0 })
    }

    /// Output word `word` as last published (input bits read 0).
    pub fn output(&self, word: usize) -> u16 {
        self.outputs[word].load(Ordering::Relaxed)
    }

    /// One output bit as last published.
    pub fn output_bit(&self, address: &Address) -> bool {
        let (word, mask) = mask_of(address).expect("a P device");
        self.output(word) & mask != 0
    }

    /// Every output OFF at once (the watchdog's safe state); the scan thread's next refresh
    /// publishes the program's image again.
    pub fn clear_outputs(&self) {
        for out in &self.outputs {
            out.store(0, Ordering::Relaxed);
        }
    }

    /// Turns the key switch (a stimulus line `SWITCH, RUN|STOP`); the scan sees it at its next
    /// input refresh. False, and nothing happens, when no `[switch]` is configured.
    pub fn set_switch(&self, position: SwitchPosition) -> bool {
        let code = switch_code(position);
        self.switch
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |now| {
                (now != NO_SWITCH).then_some(code)
            })
            .is_ok()
    }

    /// The key switch as the field sees it now; `None` when no `[switch]` is configured.
    pub fn switch(&self) -> Option<SwitchPosition> {
        switch_of(self.switch.load(Ordering::Relaxed))
    }

    /// True if the bit is an input of this field.
    pub fn is_input(&self, address: &Address) -> bool {
        mask_of(address).is_some_and(|(word, mask)| self.input_mask[word] & mask != 0)
    }
}

impl Io for SimulatedIo {
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        let image = mem.io_image_mut();
        for ((image, input), mask) in image.iter_mut().zip(&self.field.inputs).zip(&self.input_mask)
        {
            *image = (*image & !mask) | (input.load(Ordering::Relaxed) & mask);
        }
        self.switch = self.field.switch();
    }

    fn refresh_outputs(&mut self, mem: &Memory) {
        for ((out, image), mask) in
            self.field.outputs.iter().zip(mem.io_image()).zip(&self.input_mask)
        {
            out.store(image & !mask, Ordering::Relaxed);
        }
    }

    /// The key switch as of the last input refresh (at first, its starting position).
    fn switch(&self) -> Option<SwitchPosition> {
        self.switch
    }

    fn is_input(&self, bit: BitRef) -> bool {
        self.input_mask.get(usize::from(bit.word)).is_some_and(|m| m & bit.mask != 0)
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
        let mut io = SimulatedIo::new(&[addr("P0000"), addr("P0001")], &[0], None);
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
        assert_eq!(io.output(4), 1);
        assert_eq!(io.output(0), 0);
    }

    #[test]
    fn edges_only_on_contacts_that_change() {
        let mut io = SimulatedIo::default();
        assert_eq!(io.set_input(&addr("P000"), 0b101).count(), 2);
        assert_eq!(io.set_input(&addr("P0000"), 1).count(), 0);
        let falling: Vec<_> = io.set_input(&addr("P0002"), 0).collect();
        assert_eq!(falling, [ContactEdge { contact: 2, rising: false }]);
        assert_eq!(io.set_input(&addr("P0010"), 1).count(), 0, "P0010 is not a task contact");
        let mut io = SimulatedIo::new(&[addr("P000")], &[1], None);
        let edges: Vec<_> = io.set_input(&addr("P000"), 0b11).collect();
        assert_eq!(edges, [ContactEdge { contact: 1, rising: true }], "only watched contacts");
    }

    #[test]
    fn the_switch_is_seen_at_the_input_refresh() {
        let mut io = SimulatedIo::new(&[], &[], Some(SwitchPosition::Stop));
        let field = io.field();
        assert_eq!(io.switch(), Some(SwitchPosition::Stop), "the starting position at once");
        assert!(field.set_switch(SwitchPosition::Run));
        assert_eq!(field.switch(), Some(SwitchPosition::Run));
        assert_eq!(io.switch(), Some(SwitchPosition::Stop), "not before the refresh");
        let mut mem = Memory::new();
        io.refresh_inputs(&mut mem);
        assert_eq!(io.switch(), Some(SwitchPosition::Run));
        assert!(io.set_switch(SwitchPosition::Stop));
        io.refresh_inputs(&mut mem);
        assert_eq!(io.switch(), Some(SwitchPosition::Stop));
        assert_eq!(mem.io_image().iter().copied().max(), Some(0), "the switch is no P bit");
    }

    #[test]
    fn without_a_switch_there_is_none_to_turn() {
        let mut io = SimulatedIo::new(&[addr("P0000")], &[0], None);
        assert_eq!(io.switch(), None);
        assert!(!io.set_switch(SwitchPosition::Stop));
        io.refresh_inputs(&mut Memory::new());
        assert_eq!(io.switch(), None);
        assert_eq!(io.field().switch(), None);
        assert_eq!(SimulatedIo::default().switch(), None);
    }
}
