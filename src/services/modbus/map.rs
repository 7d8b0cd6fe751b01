//! The register map: Modbus addresses of each table to device memory, resolved once from
//! `[modbus]`, and the layout of the mirror image the server reads them from.
//!
//! Bit tables (coils, discrete inputs) map address `start + n` to device bit `first + n` (16 bits
//! a word, as the device addresses count them: `P0040`..`P004F` are bits 0..15 of word `P004`);
//! register tables map it to device word `first + n`. The mirror copies exactly the words the
//! ranges touch, merged into as few ranges as possible.

use std::ops::Range;

use crate::config::{ModbusConfig, ModbusRange, ModbusTable};
use crate::drivers::real_time::WordWrite;

/// Why a request's addresses cannot be served: both are exception 02.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapError {
    /// No range of the table maps this address.
    Unmapped(u32),
    /// Mapped, but not `writable`.
    ReadOnly(u32),
}

#[derive(Debug, Clone)]
struct Entry {
    range: ModbusRange,
    /// Where its first word is in the mirror image.
    image_base: usize,
}

impl Entry {
    fn first_word(&self, bits: bool) -> u32 {
        self.range.words(bits).start
    }
}

/// The resolved map of one `[modbus]` section.
#[derive(Debug, Clone)]
pub struct Map {
    /// Per table (in [`ModbusTable::ALL`] order), sorted by start address.
    tables: [Vec<Entry>; 4],
    /// The device words the mirror copies, sorted, disjoint, not adjacent.
    mirror: Vec<Range<u16>>,
    image_len: usize,
}

fn index(table: ModbusTable) -> usize {
    match table {
        ModbusTable::Coils => 0,
        ModbusTable::DiscreteInputs => 1,
        ModbusTable::HoldingRegisters => 2,
        ModbusTable::InputRegisters => 3,
    }
}

impl Map {
    pub fn new(config: &ModbusConfig) -> Map {
        // The words every range touches, merged.
        let mut words: Vec<Range<u32>> = ModbusTable::ALL
            .iter()
            .flat_map(|&t| config.table(t).iter().map(move |r| r.words(t.is_bits())))
            .collect();
        words.sort_by_key(|r| r.start);
        let mut merged: Vec<Range<u32>> = Vec::new();
        for r in words {
            match merged.last_mut() {
                Some(last) if r.start <= last.end => last.end = last.end.max(r.end),
                _ => merged.push(r),
            }
        }
        let mut offsets = Vec::with_capacity(merged.len());
        let mut at = 0usize;
        for r in &merged {
            offsets.push(at);
            at += r.len();
        }
        let image_of = |word: u32| {
            let i = merged.partition_point(|r| r.end <= word);
            offsets[i] + (word - merged[i].start) as usize
        };
        let tables = ModbusTable::ALL.map(|t| {
            let mut entries: Vec<Entry> = config
                .table(t)
                .iter()
                .map(|&range| Entry { range, image_base: image_of(range.words(t.is_bits()).start) })
                .collect();
            entries.sort_by_key(|e| e.range.start);
            entries
        });
        let mirror = merged.iter().map(|r| r.start as u16..r.end as u16).collect();
        Map { tables, mirror, image_len: at }
    }

    /// The device word ranges for [`crate::drivers::real_time::mirror::Mirror::new`].
    pub fn mirror_ranges(&self) -> &[Range<u16>] {
        &self.mirror
    }

    /// Words in the mirror image.
    pub fn image_len(&self) -> usize {
        self.image_len
    }

    fn entry(&self, table: ModbusTable, address: u32) -> Option<&Entry> {
        let entries = &self.tables[index(table)];
        let i = entries.partition_point(|e| u32::from(e.range.start) <= address);
        let entry = entries.get(i.checked_sub(1)?)?;
        entry.range.addresses().contains(&address).then_some(entry)
    }

    /// Checks that every address of `start..start + count` is mapped (and writable, for a
    /// write).
    pub fn check(
        &self,
        table: ModbusTable,
        start: u16,
        count: u16,
        write: bool,
    ) -> Result<(), MapError> {
        let mut address = u32::from(start);
        let end = address + u32::from(count);
        while address < end {
            let entry = self.entry(table, address).ok_or(MapError::Unmapped(address))?;
            if write && !entry.range.writable {
                return Err(MapError::ReadOnly(address));
            }
            address = entry.range.addresses().end;
        }
        Ok(())
    }

    /// The mirror image position of the bit at `address` of a bit table: (word, mask).
    fn bit_at(&self, table: ModbusTable, address: u32) -> Option<(usize, u16, u32)> {
        let entry = self.entry(table, address)?;
        let bit = entry.range.first + (address - u32::from(entry.range.start));
        let word = bit / 16;
        let at = entry.image_base + (word - entry.first_word(true)) as usize;
        Some((at, 1 << (bit % 16), word))
    }

    fn word_at(&self, table: ModbusTable, address: u32) -> Option<(usize, u32)> {
        let entry = self.entry(table, address)?;
        let word = entry.range.first + (address - u32::from(entry.range.start));
        Some((entry.image_base + (word - entry.first_word(false)) as usize, word))
    }

    /// Reads bits `start..start + out.len()` of a bit table from the mirror image. The range
    /// must have passed [`Map::check`]; an unmapped address reads as OFF.
    pub fn read_bits(&self, table: ModbusTable, start: u16, image: &[u16], out: &mut [bool]) {
        for (n, bit) in out.iter_mut().enumerate() {
            *bit = self
                .bit_at(table, u32::from(start) + n as u32)
                .is_some_and(|(at, mask, _)| image.get(at).is_some_and(|w| w & mask != 0));
        }
    }

    /// Reads registers `start..start + out.len()` of a register table from the mirror image;
    /// as [`Map::read_bits`].
    pub fn read_words(&self, table: ModbusTable, start: u16, image: &[u16], out: &mut [u16]) {
        for (n, value) in out.iter_mut().enumerate() {
            *value = self
                .word_at(table, u32::from(start) + n as u32)
                .and_then(|(at, _)| image.get(at).copied())
                .unwrap_or(0);
        }
    }

    /// The device writes of coils `start..` set to `values`, consecutive bits of one word
    /// merged into one masked write. The range must have passed [`Map::check`].
    pub fn coil_writes(
        &self,
        start: u16,
        values: impl Iterator<Item = bool>,
        out: &mut Vec<WordWrite>,
    ) {
        for (n, on) in values.enumerate() {
            let Some((_, mask, word)) =
                self.bit_at(ModbusTable::Coils, u32::from(start) + n as u32)
            else {
                continue;
            };
            let value = if on { mask } else { 0 };
            match out.last_mut() {
                Some(last) if u32::from(last.word) == word => {
                    last.mask |= mask;
                    last.value |= value;
                }
                _ => out.push(WordWrite { word: word as u16, mask, value }),
            }
        }
    }

    /// The device writes of holding registers `start..` set to `values`.
    pub fn register_writes(
        &self,
        start: u16,
        values: impl Iterator<Item = u16>,
        out: &mut Vec<WordWrite>,
    ) {
        for (n, value) in values.enumerate() {
            if let Some((_, word)) =
                self.word_at(ModbusTable::HoldingRegisters, u32::from(start) + n as u32)
            {
                out.push(WordWrite { word: word as u16, mask: 0xFFFF, value });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::device::Address;

    fn map(tables: &str) -> Map {
        let text = format!("{tables}\n[[program]]\nfile = \"main.il\"\n");
        let config = crate::config::parse(&text, Path::new("plcd.toml")).unwrap();
        Map::new(&config.modbus)
    }

    fn word(device: &str) -> u16 {
        Address::parse(device).unwrap().as_word().unwrap().0
    }

    #[test]
    fn the_mirror_copies_each_touched_word_once() {
        let m = map("[[modbus.coils]]\nstart = 0\ndevice = \"P0048\"\ncount = 16\n\
             [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"P0050\"\ncount = 4\n\
             [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00010\"\ncount = 3\n\
             [[modbus.input_registers]]\nstart = 0\ndevice = \"D00012\"\ncount = 2\n");
        // P004..=P005 (coils P0048..P0057 and inputs P0050..), D00010..=D00013.
        assert_eq!(
            m.mirror_ranges(),
            [word("P004")..word("P005") + 1, word("D00010")..word("D00013") + 1]
        );
        assert_eq!(m.image_len(), 6);
    }

    #[test]
    fn addresses_resolve_across_ranges_and_gaps_are_errors() {
        let m = map("[[modbus.holding_registers]]\nstart = 10\ndevice = \"D00100\"\ncount = 2\n\
             writable = true\n\
             [[modbus.holding_registers]]\nstart = 12\ndevice = \"D00000\"\ncount = 2\n\
             [[modbus.holding_registers]]\nstart = 20\ndevice = \"D00200\"\ncount = 1\n\
             writable = true\n");
        let t = ModbusTable::HoldingRegisters;
        assert_eq!(m.check(t, 10, 4, false), Ok(()));
        assert_eq!(m.check(t, 10, 4, true), Err(MapError::ReadOnly(12)));
        assert_eq!(m.check(t, 10, 5, false), Err(MapError::Unmapped(14)));
        assert_eq!(m.check(t, 9, 1, false), Err(MapError::Unmapped(9)));
        assert_eq!(m.check(t, 20, 1, true), Ok(()));
        assert_eq!(m.check(ModbusTable::InputRegisters, 10, 1, false), Err(MapError::Unmapped(10)));
        // Image: D00000..=D00001, D00100..=D00101, D00200.
        let image = [1, 2, 3, 4, 5];
        let mut out = [0u16; 4];
        m.read_words(t, 10, &image, &mut out);
        assert_eq!(out, [3, 4, 1, 2]);
        let mut writes = Vec::new();
        m.register_writes(11, [7u16, 8].into_iter(), &mut writes);
        assert_eq!(
            writes,
            [
                WordWrite { word: word("D00101"), mask: 0xFFFF, value: 7 },
                WordWrite { word: word("D00000"), mask: 0xFFFF, value: 8 }
            ]
        );
    }

    #[test]
    fn coils_are_device_bits_and_writes_merge_per_word() {
        let m = map("[[modbus.coils]]\nstart = 0\ndevice = \"M000E\"\ncount = 20\n\
             writable = true\n");
        let image = [0b1100_0000_0000_0000, 0b101];
        let mut bits = [false; 5];
        m.read_bits(ModbusTable::Coils, 0, &image, &mut bits);
        assert_eq!(bits, [true, true, true, false, true]);
        let mut writes = Vec::new();
        m.coil_writes(1, [false, true, true, false].into_iter(), &mut writes);
        assert_eq!(
            writes,
            [
                WordWrite { word: word("M000"), mask: 0x8000, value: 0 },
                WordWrite { word: word("M001"), mask: 0b111, value: 0b011 },
            ]
        );
    }
}
