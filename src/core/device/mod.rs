//! Device memory: every area of docs/LANGUAGE.md in one preallocated, fixed-size array of words.
//!
//! This module owns the layout ([`layout`]), the address syntax ([`address`]), what the IEC
//! direct addresses of Structured Text name in it ([`iec`], by `[iec]`'s layout) and the
//! system-maintained devices (SM400–SM403, the F flags, the scan-time words). Nothing here
//! allocates after [`Memory::new`].

pub mod address;
pub mod iec;
pub mod layout;
pub mod retained;

pub use address::{Address, AddressError, BitRef, UseError, WordRef, Writer};
pub use layout::{Area, FlagBit, FlagWord};
pub use retained::{RetainSet, RetainedWords};

use crate::value::{self, Pointer, Space};

/// The values a device word takes from outside a program (a constant, a stimulus, a client):
/// its 16 bits read as a signed (down to -32768) or an unsigned (up to 65535) number.
pub const WORD_VALUES: std::ops::RangeInclusive<i32> = -32768..=65535;

/// [`value::format_reference`], with a reference into device memory shown as the device it
/// points to (`D00100`, `P0044`, `D00010.3`, `P064 (high byte)`).
pub fn format_reference(slot: u64) -> String {
    let device = |word: u32, bit: Option<u8>| {
        let area = [Area::P, Area::M, Area::K, Area::D]
            .into_iter()
            .find(|a| (a.base()..a.base() + a.word_count()).contains(&word))?;
        Some(Address { area, number: word - area.base(), bit }.to_string())
    };
    let named = match Pointer::from_reference(slot) {
        Some(Pointer { space: Space::Word, offset }) => device(offset, None),
        Some(Pointer { space: Space::Bit, offset }) => {
            device(offset / 16, Some((offset % 16) as u8))
        }
        Some(Pointer { space: Space::Byte, offset }) => {
            device(offset / 2, None).map(|word| format!("{word} ({})", half_name(offset % 2 == 1)))
        }
        _ => None,
    };
    named.unwrap_or_else(|| value::format_reference(slot))
}

/// Which byte of its device word an IEC byte address (`%QB1`) names: plcd's words hold the even
/// byte of an image in their low half (docs/ST.md, "Direct addresses").
pub fn half_name(high: bool) -> &'static str {
    if high {
        "high byte"
    } else {
        "low byte"
    }
}

/// The PLC's device memory.
#[derive(Clone)]
pub struct Memory {
    words: Box<[u16]>,
}

impl Default for Memory {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for Memory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Memory").field("words", &self.words.len()).finish()
    }
}

const fn flag_bit(flag: FlagBit) -> BitRef {
    BitRef { word: layout::F_BITS as u16, mask: 1 << flag as u16 }
}

const fn flag_word(flag: FlagWord) -> WordRef {
    WordRef((layout::F_WORDS + flag as u32) as u16)
}

const fn sm_bit(number: u32) -> BitRef {
    let index = number - 400;
    BitRef { word: (layout::SM + index / 16) as u16, mask: 1 << (index % 16) }
}

/// The relay of DUTY channel `channel` (SM420 + channel).
pub const fn duty_relay(channel: usize) -> BitRef {
    sm_bit(420 + channel as u32)
}

/// The scan counter of DUTY channel `channel` (SD8330 + channel).
pub const fn duty_counter(channel: usize) -> WordRef {
    WordRef((layout::SD + channel as u32) as u16)
}

/// The done contact of timer `n`.
pub const fn timer_done(n: u16) -> BitRef {
    BitRef { word: (layout::TB + n as u32 / 16) as u16, mask: 1 << (n % 16) }
}

/// The current value of timer `n`.
pub const fn timer_value(n: u16) -> WordRef {
    WordRef((layout::TV + n as u32) as u16)
}

/// The done contact of counter `n`.
pub const fn counter_done(n: u16) -> BitRef {
    BitRef { word: (layout::CB + n as u32 / 16) as u16, mask: 1 << (n % 16) }
}

/// The current value of counter `n`.
pub const fn counter_value(n: u16) -> WordRef {
    WordRef((layout::CV + n as u32) as u16)
}

/// `_ERR`, the operation error flag.
pub const ERR_FLAG: BitRef = flag_bit(FlagBit::Err);
/// `_ERR_CODE`, the code of the last operation error.
pub const ERR_CODE: WordRef = flag_word(FlagWord::ErrCode);

impl Memory {
    pub fn new() -> Memory {
        let mut memory = Memory { words: vec![0; layout::TOTAL_WORDS as usize].into_boxed_slice() };
        memory.set_constant_flags();
        memory
    }

    #[inline(always)]
    pub fn bit(&self, bit: BitRef) -> bool {
        self.words[bit.word as usize] & bit.mask != 0
    }

    #[inline(always)]
    pub fn set_bit(&mut self, bit: BitRef, on: bool) {
        let word = &mut self.words[bit.word as usize];
        if on {
            *word |= bit.mask;
        } else {
            *word &= !bit.mask;
        }
    }

    #[inline(always)]
    pub fn word(&self, word: WordRef) -> u16 {
        self.words[word.0 as usize]
    }

    #[inline(always)]
    pub fn set_word(&mut self, word: WordRef, value: u16) {
        self.words[word.0 as usize] = value;
    }

    /// The raw words of an area range, for I/O refresh and snapshots.
    pub fn words(&self) -> &[u16] {
        &self.words
    }

    /// The P area as words (the I/O image).
    pub fn io_image(&self) -> &[u16] {
        &self.words[layout::P as usize..(layout::P + layout::P_WORDS) as usize]
    }

    pub fn io_image_mut(&mut self) -> &mut [u16] {
        &mut self.words[layout::P as usize..(layout::P + layout::P_WORDS) as usize]
    }

    /// Reads any device by its address text: bits as 0/1, words as their signed value. For
    /// tests, tools and the control surface; programs use resolved references.
    pub fn read(&self, address: &Address) -> i32 {
        match address.as_word() {
            Ok(word) => i32::from(self.word(word) as i16),
            Err(_) => i32::from(self.bit(address.as_bit().expect("an address is a bit or a word"))),
        }
    }

    /// Writes any device by its address: a bit is ON for any non-zero value, a word takes the
    /// low 16 bits. Used by stimulus files and tests; it ignores write protection on purpose
    /// (a simulation may drive anything), except that flags stay the system's.
    pub fn write(&mut self, address: &Address, value: i32) {
        match address.as_word() {
            Ok(word) => self.set_word(word, value as u16),
            Err(_) => {
                self.set_bit(address.as_bit().expect("an address is a bit or a word"), value != 0)
            }
        }
    }

    /// Clears every area except the retained ones (K, and the bits of `retained`), as at the
    /// start of RUN. No allocation.
    pub fn clear_for_run(&mut self, retained: &[crate::device::RetainedWords]) {
        let k = layout::K as usize..(layout::K + layout::MK_WORDS) as usize;
        for (index, word) in self.words.iter_mut().enumerate() {
            if k.contains(&index) {
                continue;
            }
            let keep = retained
                .iter()
                .filter(|r| usize::from(r.start) <= index && index < usize::from(r.end))
                .fold(0, |mask, r| mask | r.mask);
            *word &= keep;
        }
        self.set_constant_flags();
    }

    /// Every word, for restoring retained memory (and nothing else: programs and tools write
    /// through [`Memory::write`] and the references).
    pub fn words_mut(&mut self) -> &mut [u16] {
        &mut self.words
    }

    /// Clears every area, retained ones included (a cold restart).
    pub fn clear_all(&mut self) {
        self.words.fill(0);
        self.set_constant_flags();
    }

    fn set_constant_flags(&mut self) {
        self.set_bit(flag_bit(FlagBit::On), true);
        self.set_bit(flag_bit(FlagBit::Off), false);
        self.set_bit(sm_bit(400), true);
        self.set_bit(sm_bit(401), false);
    }

    /// Maintains the system bits at the start of a scan: `_ON`/`_OFF`/SM400/SM401, the first-scan
    /// flags `_1ON`/`_1OFF`/SM402/SM403, and the clock flags from the time since RUN started
    /// (each clock is OFF for the first half of its period and ON for the second).
    pub fn begin_scan(&mut self, first_scan: bool, since_run_ns: u64) {
        self.set_constant_flags();
        self.set_bit(flag_bit(FlagBit::FirstOn), first_scan);
        self.set_bit(flag_bit(FlagBit::FirstOff), !first_scan);
        self.set_bit(sm_bit(402), first_scan);
        self.set_bit(sm_bit(403), !first_scan);
        self.update_clock_flags(since_run_ns);
    }

    /// Updates the clock flags `_T20MS` … `_T60S` for the time since RUN started.
    pub fn update_clock_flags(&mut self, since_run_ns: u64) {
        let ms = since_run_ns / 1_000_000;
        for flag in FlagBit::ALL {
            if let Some(half) = flag.clock_half_period_ms() {
                self.set_bit(flag_bit(flag), (ms / half) % 2 == 1);
            }
        }
    }

    /// Records an operation error: `_ERR` ON and its code in `_ERR_CODE`.
    pub fn raise_operation_error(&mut self, code: u16) {
        self.set_bit(ERR_FLAG, true);
        self.set_word(ERR_CODE, code);
    }

    /// Clears `_ERR` and `_ERR_CODE` (the engine does this when a new scan starts).
    pub fn clear_operation_error(&mut self) {
        self.set_bit(ERR_FLAG, false);
        self.set_word(ERR_CODE, 0);
    }

    /// `_FORCE_IN` / `_FORCE_OUT`: whether any input / output is forced.
    pub fn set_force_flags(&mut self, inputs: bool, outputs: bool) {
        self.set_bit(flag_bit(FlagBit::ForceIn), inputs);
        self.set_bit(flag_bit(FlagBit::ForceOut), outputs);
    }

    /// Publishes the scan time figures in 0.1 ms units (`_SCAN_CUR`, `_SCAN_MIN`, `_SCAN_MAX`).
    pub fn set_scan_times(&mut self, current: u16, min: u16, max: u16) {
        self.set_word(flag_word(FlagWord::ScanCur), current);
        self.set_word(flag_word(FlagWord::ScanMin), min);
        self.set_word(flag_word(FlagWord::ScanMax), max);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_into_device_memory_name_the_device() {
        let reference = |p: Pointer| p.to_slot() + value::REF_TAG;
        let d100 = Address::parse("D00100").unwrap().as_word().unwrap();
        let word = Pointer { space: Space::Word, offset: u32::from(d100.0) };
        assert_eq!(format_reference(reference(word)), "D00100");
        let p44 = Address::parse("P0044").unwrap().as_bit().unwrap();
        let offset = u32::from(p44.word) * 16 + p44.mask.trailing_zeros();
        assert_eq!(format_reference(reference(Pointer { space: Space::Bit, offset })), "P0044");
        let d_bit = Address::parse("D00010.3").unwrap().as_bit().unwrap();
        let offset = u32::from(d_bit.word) * 16 + d_bit.mask.trailing_zeros();
        assert_eq!(format_reference(reference(Pointer { space: Space::Bit, offset })), "D00010.3");
        let p64 = Address::parse("P064").unwrap().as_word().unwrap();
        let high = Pointer { space: Space::Byte, offset: u32::from(p64.0) * 2 + 1 };
        assert_eq!(format_reference(reference(high)), "P064 (high byte)");
        let low = Pointer { space: Space::Byte, offset: u32::from(p64.0) * 2 };
        assert_eq!(format_reference(reference(low)), "P064 (low byte)");
        // a word of no nameable area (a timer's value), variable memory, NULL: as value's
        let tv = Pointer { space: Space::Word, offset: layout::TV };
        assert_eq!(format_reference(reference(tv)), format!("word+{}", layout::TV));
        let var = Pointer { space: Space::Var, offset: 8 };
        assert_eq!(format_reference(reference(var)), "vars+8");
        assert_eq!(format_reference(0), "NULL");
    }

    fn addr(s: &str) -> Address {
        Address::parse(s).unwrap()
    }

    #[test]
    fn bits_and_words_alias() {
        let mut m = Memory::new();
        m.write(&addr("M0013"), 1);
        assert_eq!(m.read(&addr("M001")), 8);
        m.write(&addr("D00005"), -2);
        assert_eq!(m.read(&addr("D00005")), -2);
        assert_eq!(m.read(&addr("D00005.0")), 0);
        assert_eq!(m.read(&addr("D00005.1")), 1);
    }

    #[test]
    fn constant_and_first_scan_flags() {
        let mut m = Memory::new();
        assert_eq!(m.read(&addr("_ON")), 1);
        assert_eq!(m.read(&addr("SM400")), 1);
        assert_eq!(m.read(&addr("SM401")), 0);
        m.begin_scan(true, 0);
        assert_eq!(m.read(&addr("_1ON")), 1);
        assert_eq!(m.read(&addr("SM402")), 1);
        assert_eq!(m.read(&addr("SM403")), 0);
        m.begin_scan(false, 0);
        assert_eq!(m.read(&addr("_1ON")), 0);
        assert_eq!(m.read(&addr("_1OFF")), 1);
        assert_eq!(m.read(&addr("SM403")), 1);
    }

    #[test]
    fn clock_flags_follow_time() {
        let mut m = Memory::new();
        m.update_clock_flags(9_999_999);
        assert_eq!(m.read(&addr("_T20MS")), 0);
        m.update_clock_flags(10_000_000);
        assert_eq!(m.read(&addr("_T20MS")), 1);
        m.update_clock_flags(20_000_000);
        assert_eq!(m.read(&addr("_T20MS")), 0);
        m.update_clock_flags(500_000_000);
        assert_eq!(m.read(&addr("_T1S")), 1);
        assert_eq!(m.read(&addr("_T2S")), 0);
    }

    #[test]
    fn clear_for_run_keeps_k_and_retained_ranges() {
        let mut m = Memory::new();
        m.write(&addr("K001"), 7);
        m.write(&addr("M001"), 7);
        m.write(&addr("D00100"), 7);
        m.write(&addr("D00200"), 7);
        m.write(&addr("D00300"), 0b1011);
        let d100 = addr("D00100").as_word().unwrap().0;
        let d300 = addr("D00300").as_word().unwrap().0;
        m.clear_for_run(&[
            crate::device::RetainedWords { start: d100, end: d100 + 1, mask: 0xFFFF },
            crate::device::RetainedWords { start: d300, end: d300 + 1, mask: 0b0011 },
        ]);
        assert_eq!(m.read(&addr("D00300")), 0b0011);
        assert_eq!(m.read(&addr("K001")), 7);
        assert_eq!(m.read(&addr("M001")), 0);
        assert_eq!(m.read(&addr("D00100")), 7);
        assert_eq!(m.read(&addr("D00200")), 0);
        assert_eq!(m.read(&addr("_ON")), 1);
    }

    #[test]
    fn operation_error_flags() {
        let mut m = Memory::new();
        m.raise_operation_error(0x3405);
        assert_eq!(m.read(&addr("_ERR")), 1);
        assert_eq!(m.read(&addr("_ERR_CODE")) as u16, 0x3405);
        m.clear_operation_error();
        assert_eq!(m.read(&addr("_ERR")), 0);
    }
}
