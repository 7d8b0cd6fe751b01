//! Forced I/O, as on a commercial PLC: a forced input overrides what the input refresh read,
//! a forced output overrides what the program wrote, and the program sees `_FORCE_IN` /
//! `_FORCE_OUT` while any force is set.
//!
//! Forces are bits of the P area only (the I/O image), kept as masks over its words, so that
//! applying them is a few word operations per refresh and never allocates. A force does not
//! outlive the safe state: STOP, a stopping error and the watchdog switch the outputs off
//! whatever is forced; the forces apply again from the next RUN. A force that is removed
//! leaves the bit at its forced value until the input refresh or the program writes it, as
//! common PLCs do.

use crate::device::layout::P_WORDS;
use crate::device::{Address, Area, BitRef, Memory};
use crate::value::{Space, Symbol, ValueType};

/// Why a device cannot be forced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ForceError {
    #[error("{0} cannot be forced: only P bits (P0000-P127F) can")]
    NotAnIoBit(Address),
}

/// The force table of the I/O image, and what it last left in the force flags.
#[derive(Debug, Clone, Eq)]
pub struct Forces {
    /// Forced bits per P word.
    mask: [u16; P_WORDS as usize],
    /// Their forced values.
    value: [u16; P_WORDS as usize],
    /// Which forced bits are inputs of the I/O backend (for `_FORCE_IN` / `_FORCE_OUT`).
    input: [u16; P_WORDS as usize],
    /// Forced bits in all.
    count: u32,
    /// The last [`Forces::refresh`] wrote the force flags with a force set, so they may be ON:
    /// the refresh after the last force is removed must still write them (OFF). It outlives
    /// [`Forces::clear_all`], which empties the table but cannot reach the memory.
    flags_on: bool,
}

impl Default for Forces {
    fn default() -> Self {
        Forces {
            mask: [0; P_WORDS as usize],
            value: [0; P_WORDS as usize],
            input: [0; P_WORDS as usize],
            count: 0,
            flags_on: false,
        }
    }
}

/// Two tables are equal when they force the same bits to the same values: what the flags of a
/// memory still hold is that memory's state, not the table's.
impl PartialEq for Forces {
    fn eq(&self, other: &Forces) -> bool {
        self.mask == other.mask
            && self.value == other.value
            && self.input == other.input
            && self.count == other.count
    }
}

/// The P bit an address names, if it names one.
pub fn io_bit(address: &Address) -> Result<BitRef, ForceError> {
    match (address.area, address.bit) {
        (Area::P, Some(_)) => address.as_bit().map_err(|_| ForceError::NotAnIoBit(*address)),
        _ => Err(ForceError::NotAnIoBit(*address)),
    }
}

/// The P bit a Structured Text variable is, if it is one: a `BOOL` located at a P bit
/// (`lamp AT %P0044 : BOOL` is P0044). Any other variable cannot be forced.
pub fn variable_io_bit(symbol: &Symbol) -> Option<(Address, BitRef)> {
    if symbol.ty != ValueType::Bool || symbol.at.space != Space::Bit {
        return None;
    }
    let (word, bit) = (symbol.at.offset / 16, (symbol.at.offset % 16) as u8);
    let address = Address { area: Area::P, number: word, bit: Some(bit) };
    (word < P_WORDS).then(|| io_bit(&address).ok().map(|b| (address, b))).flatten()
}

impl Forces {
    /// Forces `bit` to `on`; `is_input` says whether the backend refreshes it as an input.
    pub fn set(&mut self, bit: BitRef, on: bool, is_input: bool) {
        let w = bit.word as usize;
        if self.mask[w] & bit.mask == 0 {
            self.count += 1;
        }
        self.mask[w] |= bit.mask;
        if on {
            self.value[w] |= bit.mask;
        } else {
            self.value[w] &= !bit.mask;
        }
        if is_input {
            self.input[w] |= bit.mask;
        } else {
            self.input[w] &= !bit.mask;
        }
    }

    /// Removes the force of `bit`; true if it was forced.
    pub fn clear(&mut self, bit: BitRef) -> bool {
        let w = bit.word as usize;
        let was = self.mask[w] & bit.mask != 0;
        if was {
            self.count -= 1;
        }
        self.mask[w] &= !bit.mask;
        self.value[w] &= !bit.mask;
        self.input[w] &= !bit.mask;
        was
    }

    pub fn clear_all(&mut self) {
        *self = Forces { flags_on: self.flags_on, ..Forces::default() };
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Writes the forced values over the I/O image and maintains the force flags.
    #[inline]
    pub fn apply(&self, mem: &mut Memory) {
        let mut inputs = false;
        let mut outputs = false;
        for (w, word) in mem.io_image_mut().iter_mut().enumerate() {
            let mask = self.mask[w];
            if mask != 0 {
                *word = (*word & !mask) | (self.value[w] & mask);
                inputs |= self.input[w] != 0;
                outputs |= mask & !self.input[w] != 0;
            }
        }
        mem.set_force_flags(inputs, outputs);
    }

    /// A refresh point of the I/O image: writes the forced values over it, and once more after
    /// the last force is gone, to clear the force flags; after that, nothing until the next
    /// force, so that a PLC without forces pays no word loop per refresh.
    #[inline]
    pub(super) fn refresh(&mut self, mem: &mut Memory) {
        if self.count != 0 || self.flags_on {
            self.apply(mem);
            self.flags_on = self.count != 0;
        }
    }

    /// Every forced bit with its value, in address order.
    pub fn iter(&self) -> impl Iterator<Item = (Address, bool)> + '_ {
        (0..P_WORDS as usize).flat_map(move |w| {
            (0..16u8).filter_map(move |b| {
                let m = 1u16 << b;
                (self.mask[w] & m != 0).then(|| {
                    (
                        Address { area: Area::P, number: w as u32, bit: Some(b) },
                        self.value[w] & m != 0,
                    )
                })
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bit(text: &str) -> BitRef {
        io_bit(&Address::parse(text).unwrap()).unwrap()
    }

    #[test]
    fn only_p_bits_can_be_forced() {
        for text in ["M0000", "D00001", "P004", "T0001", "_ON"] {
            let address = Address::parse(text).unwrap();
            assert_eq!(io_bit(&address), Err(ForceError::NotAnIoBit(address)), "{text}");
        }
        assert!(io_bit(&Address::parse("P127F").unwrap()).is_ok());
    }

    #[test]
    fn a_bool_located_at_a_p_bit_is_that_bit() {
        use crate::value::{Elem, Pointer};
        let symbol = |ty: ValueType, space: Space, offset: u32| Symbol {
            name: "main.x".into(),
            ty,
            at: Pointer { space, offset },
            retain: false,
            constant: false,
        };
        let lamp = symbol(ValueType::Bool, Space::Bit, 4 * 16 + 4);
        assert_eq!(variable_io_bit(&lamp), Some((Address::parse("P0044").unwrap(), bit("P0044"))));
        let last = symbol(ValueType::Bool, Space::Bit, P_WORDS * 16 - 1);
        assert_eq!(variable_io_bit(&last).map(|(a, _)| a.to_string()), Some("P127F".into()));
        // An M bit (the word after the P area), a BOOL in variable memory, a word.
        assert_eq!(variable_io_bit(&symbol(ValueType::Bool, Space::Bit, P_WORDS * 16)), None);
        assert_eq!(variable_io_bit(&symbol(ValueType::Bool, Space::Var, 0)), None);
        assert_eq!(variable_io_bit(&symbol(ValueType::Signed(Elem::I16), Space::Word, 4)), None);
    }

    #[test]
    fn forced_bits_override_the_image_and_set_the_flags() {
        let mut mem = Memory::new();
        let mut forces = Forces::default();
        mem.write(&Address::parse("P000").unwrap(), 0x00FF);
        forces.set(bit("P0000"), false, true);
        forces.set(bit("P0041"), true, false);
        forces.apply(&mut mem);
        assert_eq!(mem.read(&Address::parse("P000").unwrap()), 0x00FE);
        assert_eq!(mem.read(&Address::parse("P0041").unwrap()), 1);
        assert_eq!(mem.read(&Address::parse("_FORCE_IN").unwrap()), 1);
        assert_eq!(mem.read(&Address::parse("_FORCE_OUT").unwrap()), 1);
        let listed: Vec<String> = forces.iter().map(|(a, v)| format!("{a}={}", v as u8)).collect();
        assert_eq!(listed, ["P0000=0", "P0041=1"]);

        assert!(forces.clear(bit("P0000")));
        assert!(!forces.clear(bit("P0000")));
        forces.apply(&mut mem);
        assert_eq!(mem.read(&Address::parse("_FORCE_IN").unwrap()), 0);
        assert_eq!(mem.read(&Address::parse("_FORCE_OUT").unwrap()), 1);
        forces.clear_all();
        assert!(forces.is_empty());
        forces.apply(&mut mem);
        assert_eq!(mem.read(&Address::parse("_FORCE_OUT").unwrap()), 0);
    }

    #[test]
    fn the_refresh_after_the_last_force_clears_the_flags() {
        let mut mem = Memory::new();
        let mut forces = Forces::default();
        forces.set(bit("P0041"), true, false);
        forces.refresh(&mut mem);
        assert_eq!(mem.read(&Address::parse("_FORCE_OUT").unwrap()), 1);
        forces.clear_all();
        assert_eq!(forces, Forces::default(), "the same (empty) table");
        forces.refresh(&mut mem);
        assert_eq!(mem.read(&Address::parse("_FORCE_OUT").unwrap()), 0, "cleared once more");
        mem.set_force_flags(false, true);
        forces.refresh(&mut mem);
        assert_eq!(mem.read(&Address::parse("_FORCE_OUT").unwrap()), 1, "then not written");
    }
}
