//! Device addresses as a PLC engineer writes them (`P0040`, `M000`, `D00010.3`, `T0005`,
//! `SM420`, `_T1S`), and their resolution to fixed word indices and bit masks.
//!
//! Resolution happens once, when a program is assembled or a config is checked; the VM only
//! ever sees [`BitRef`] and [`WordRef`].

use std::fmt;

use super::layout::{self, Area, FlagBit, FlagWord};

/// A bit in device memory: the word that holds it and the mask of the bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BitRef {
    pub word: u16,
    pub mask: u16,
}

/// A word in device memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct WordRef(pub u16);

/// A parsed device address, before it is used as a bit or a word.
///
/// Some addresses are both (`T0005` is the done bit or the current value, `D00010.3` is only a
/// bit, `D00010` only a word); [`Address::as_bit`] and [`Address::as_word`] decide by use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Address {
    pub area: Area,
    /// Word number within the area (P/M/K/D/SD), device number (T/C), bit number (SM),
    /// or the flag's code (F).
    pub number: u32,
    /// Bit within the word, for bit addresses of P/M/K (`P0040`) and D (`D00010.3`).
    pub bit: Option<u8>,
}

/// Why an address text is not a device.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AddressError {
    #[error("`{0}` is not a device address")]
    Syntax(String),
    #[error("`{text}` is out of range ({range})")]
    OutOfRange { text: String, range: &'static str },
    #[error("unknown flag `{0}`")]
    UnknownFlag(String),
}

/// Who writes a device, for [`Address::writable_by`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Writer {
    /// A program's instruction that uses the address as a bit.
    ProgramBit,
    /// A program's instruction that uses the address as a word.
    ProgramWord,
    /// A client of the running PLC: the control socket, a Modbus master.
    Client,
    /// A simulation's inputs file (`plcd sim --inputs`, `[io] stimulus`).
    Stimulus,
    /// Remote I/O: what a Modbus device polled by `plcd run` answers (`[[remote.read]]`, and
    /// a remote's `status` bit).
    RemoteInput,
}

/// How an address can be used where a bit or a word is expected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UseError {
    #[error("`{0}` is a word device, a bit is needed here")]
    NotABit(Address),
    #[error("`{0}` is a bit device, a word is needed here")]
    NotAWord(Address),
}

impl Address {
    /// The type and place a service serves this device as beside the variables (a device
    /// range of OPC UA or MQTT): a word an `INT`, a bit a `BOOL`; `None` for a device that is
    /// neither (a timer, a counter).
    pub fn served(&self) -> Option<(crate::value::ValueType, crate::value::Pointer)> {
        use crate::value::{Elem, Pointer, Space, ValueType};
        match (self.as_word(), self.as_bit()) {
            (Ok(word), _) => {
                let at = Pointer { space: Space::Word, offset: u32::from(word.0) };
                Some((ValueType::Signed(Elem::I16), at))
            }
            (_, Ok(bit)) => {
                let offset = u32::from(bit.word) * 16 + bit.mask.trailing_zeros();
                Some((ValueType::Bool, Pointer { space: Space::Bit, offset }))
            }
            _ => None,
        }
    }

    /// Parses an address, case-insensitively. Leading zeros may be left out of T, C, D, SD and
    /// SM numbers (`D10` is `D00010`); P, M and K use the digit count to tell bits from words:
    /// four characters (three decimal word digits and one hex bit digit) name a bit, up to three
    /// decimal digits a word.
    pub fn parse(text: &str) -> Result<Address, AddressError> {
        let upper = text.to_ascii_uppercase();
        let syntax = || AddressError::Syntax(text.to_string());
        if upper.starts_with('_') {
            return parse_flag(&upper).ok_or_else(|| AddressError::UnknownFlag(text.to_string()));
        }
        let split = upper.find(|c: char| !c.is_ascii_alphabetic()).ok_or_else(syntax)?;
        let (prefix, rest) = upper.split_at(split);
        let area = match prefix {
            "P" => Area::P,
            "M" => Area::M,
            "K" => Area::K,
            "T" => Area::T,
            "C" => Area::C,
            "D" => Area::D,
            "SM" => Area::SM,
            "SD" => Area::SD,
            _ => return Err(syntax()),
        };
        let out_of_range =
            || AddressError::OutOfRange { text: text.to_string(), range: area.range_text() };
        match area {
            Area::P | Area::M | Area::K => {
                if !rest.chars().all(|c| c.is_ascii_hexdigit()) || rest.is_empty() {
                    return Err(syntax());
                }
                let words = area.word_count();
                if rest.len() == 4 {
                    let word: u32 = rest[..3].parse().map_err(|_| syntax())?;
                    let bit = u8::from_str_radix(&rest[3..], 16).map_err(|_| syntax())?;
                    if word >= words {
                        return Err(out_of_range());
                    }
                    Ok(Address { area, number: word, bit: Some(bit) })
                } else if rest.len() <= 3 {
                    let word: u32 = rest.parse().map_err(|_| syntax())?;
                    if word >= words {
                        return Err(out_of_range());
                    }
                    Ok(Address { area, number: word, bit: None })
                } else {
                    Err(syntax())
                }
            }
            Area::D => {
                let (digits, bit) = match rest.split_once('.') {
                    Some((d, b)) => {
                        if b.len() != 1 {
                            return Err(syntax());
                        }
                        let bit = u8::from_str_radix(b, 16).map_err(|_| syntax())?;
                        (d, Some(bit))
                    }
                    None => (rest, None),
                };
                let number = parse_decimal(digits, 5).ok_or_else(syntax)?;
                if number >= layout::D_WORDS {
                    return Err(out_of_range());
                }
                Ok(Address { area, number, bit })
            }
            Area::T | Area::C => {
                let number = parse_decimal(rest, 4).ok_or_else(syntax)?;
                if number >= layout::TC_COUNT {
                    return Err(out_of_range());
                }
                Ok(Address { area, number, bit: None })
            }
            Area::SM => {
                let number = parse_decimal(rest, 4).ok_or_else(syntax)?;
                if layout::sm_bit_index(number).is_none() {
                    return Err(out_of_range());
                }
                Ok(Address { area, number, bit: None })
            }
            Area::SD => {
                let number = parse_decimal(rest, 4).ok_or_else(syntax)?;
                if !(layout::SD_FIRST..layout::SD_FIRST + layout::SD_WORDS).contains(&number) {
                    return Err(out_of_range());
                }
                Ok(Address { area, number, bit: None })
            }
            Area::F => unreachable!("flags start with an underscore"),
        }
    }

    /// The address used as a bit.
    pub fn as_bit(&self) -> Result<BitRef, UseError> {
        let not_a_bit = || UseError::NotABit(*self);
        let (word, bit) = match (self.area, self.bit) {
            (Area::P | Area::M | Area::K | Area::D, Some(bit)) => {
                (self.area.base() + self.number, u32::from(bit))
            }
            (Area::P | Area::M | Area::K | Area::D | Area::SD, None) => return Err(not_a_bit()),
            (Area::T, _) => (layout::TB + self.number / 16, self.number % 16),
            (Area::C, _) => (layout::CB + self.number / 16, self.number % 16),
            (Area::SM, _) => {
                let index = layout::sm_bit_index(self.number).expect("checked at parse");
                (layout::SM + index / 16, index % 16)
            }
            (Area::F, _) => match FlagBit::from_code(self.number) {
                Some(flag) => (layout::F_BITS, flag as u32),
                None => return Err(not_a_bit()),
            },
            (Area::SD, Some(_)) => return Err(not_a_bit()),
        };
        Ok(BitRef { word: word as u16, mask: 1 << bit })
    }

    /// The address used as a word.
    pub fn as_word(&self) -> Result<WordRef, UseError> {
        let not_a_word = || UseError::NotAWord(*self);
        if self.bit.is_some() {
            return Err(not_a_word());
        }
        let index = match self.area {
            Area::P | Area::M | Area::K | Area::D => self.area.base() + self.number,
            Area::T => layout::TV + self.number,
            Area::C => layout::CV + self.number,
            Area::SD => layout::SD + (self.number - layout::SD_FIRST),
            Area::SM => return Err(not_a_word()),
            Area::F => match FlagWord::from_code(self.number) {
                Some(flag) => layout::F_WORDS + flag as u32,
                None => return Err(not_a_word()),
            },
        };
        Ok(WordRef(index as u16))
    }

    /// True where `writer` may write this address: the one rule of who writes what.
    ///
    /// - A program's bit instructions (`OUT`, `SET`, `RST`, `FF`) write P, M, K and D bits:
    ///   timer and counter contacts belong to their instructions, SM and F to the system.
    /// - A program's word instructions (`MOV`, `ADD` …) write P, M, K and D words and, as on the
    ///   XGB, the current values of timers and counters; SD and F belong to the system.
    /// - A client of the running PLC (`plcctl set`, a Modbus write) writes every device but the
    ///   system's own: F, SM and SD, which the PLC maintains.
    /// - A simulation's inputs file may drive anything (it stands in for the whole world,
    ///   SM relays and SD registers included) except the flags, which the PLC recomputes.
    /// - Remote I/O writes P, M, K and D, the devices a program's inputs may be: timers,
    ///   counters, SM, SD and the flags have writers of their own.
    pub fn writable_by(&self, writer: Writer) -> bool {
        match writer {
            Writer::ProgramBit => matches!(self.area, Area::P | Area::M | Area::K | Area::D),
            Writer::ProgramWord => {
                matches!(self.area, Area::P | Area::M | Area::K | Area::D | Area::T | Area::C)
            }
            Writer::Client => !matches!(self.area, Area::F | Area::SM | Area::SD),
            Writer::Stimulus => self.area != Area::F,
            Writer::RemoteInput => matches!(self.area, Area::P | Area::M | Area::K | Area::D),
        }
    }

    /// True for the timing clock relays SM420–SM424 and their aliases SM8330–SM8334.
    pub fn is_duty_relay(&self) -> bool {
        self.area == Area::SM && layout::duty_channel(self.number).is_some()
    }

    /// The DUTY channel 0..=4 of a timing clock relay.
    pub fn duty_channel(&self) -> Option<usize> {
        if self.area == Area::SM {
            layout::duty_channel(self.number)
        } else {
            None
        }
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.area, self.bit) {
            (Area::P | Area::M | Area::K, Some(bit)) => {
                write!(f, "{:?}{:03}{:X}", self.area, self.number, bit)
            }
            (Area::P | Area::M | Area::K, None) => write!(f, "{:?}{:03}", self.area, self.number),
            (Area::D, Some(bit)) => write!(f, "D{:05}.{:X}", self.number, bit),
            (Area::D, None) => write!(f, "D{:05}", self.number),
            (Area::T | Area::C, _) => write!(f, "{:?}{:04}", self.area, self.number),
            (Area::SM | Area::SD, _) => write!(f, "{:?}{}", self.area, self.number),
            (Area::F, _) => f.write_str(layout::flag_name(self.number)),
        }
    }
}

fn parse_decimal(digits: &str, max_len: usize) -> Option<u32> {
    if digits.is_empty() || digits.len() > max_len || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

fn parse_flag(upper: &str) -> Option<Address> {
    let code = layout::flag_code(upper)?;
    Some(Address { area: Area::F, number: code, bit: None })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_served_device_is_an_int_word_or_a_bool_bit() {
        use crate::value::{Elem, Pointer, Space, ValueType};
        let served = |text: &str| Address::parse(text).unwrap().served();
        let word = Pointer {
            space: Space::Word,
            offset: u32::from(Address::parse("D00100").unwrap().as_word().unwrap().0),
        };
        assert_eq!(served("D00100"), Some((ValueType::Signed(Elem::I16), word)));
        let bit = Address::parse("M0103").unwrap().as_bit().unwrap();
        let at = Pointer { space: Space::Bit, offset: u32::from(bit.word) * 16 + 3 };
        assert_eq!(served("M0103"), Some((ValueType::Bool, at)));
    }

    fn parse(s: &str) -> Address {
        Address::parse(s).unwrap_or_else(|e| panic!("{s}: {e}"))
    }

    #[test]
    fn p_bits_and_words_follow_the_contract() {
        let bit = parse("P0040").as_bit().unwrap();
        let word = parse("P004").as_word().unwrap();
        assert_eq!(bit.word, word.0);
        assert_eq!(bit.mask, 1);
        let last = parse("p127f").as_bit().unwrap();
        assert_eq!(last.word, layout::P as u16 + 127);
        assert_eq!(last.mask, 0x8000);
        assert!(Address::parse("P128").is_err());
        assert!(Address::parse("P1280").is_err());
        assert!(parse("P0040").as_word().is_err());
        assert!(parse("P004").as_bit().is_err());
    }

    #[test]
    fn d_words_and_bits() {
        assert_eq!(parse("D10"), parse("D00010"));
        let b = parse("D00010.3").as_bit().unwrap();
        assert_eq!(b.word, parse("D00010").as_word().unwrap().0);
        assert_eq!(b.mask, 8);
        assert!(parse("D00010.3").as_word().is_err());
        assert!(matches!(Address::parse("D32768"), Err(AddressError::OutOfRange { .. })));
        assert!(Address::parse("D32767").is_ok());
    }

    #[test]
    fn timers_are_bits_and_words() {
        let t = parse("T0017");
        assert_eq!(t.as_bit().unwrap(), BitRef { word: (layout::TB + 1) as u16, mask: 2 });
        assert_eq!(t.as_word().unwrap(), WordRef((layout::TV + 17) as u16));
        assert!(Address::parse("T2048").is_err());
        assert!(!t.writable_by(Writer::ProgramBit));
        assert!(t.writable_by(Writer::ProgramWord));
    }

    #[test]
    fn sm_aliases_share_a_bit() {
        assert_eq!(parse("SM420").as_bit().unwrap(), parse("SM8330").as_bit().unwrap());
        assert_eq!(parse("SM424").as_bit().unwrap(), parse("SM8334").as_bit().unwrap());
        assert_ne!(parse("SM400").as_bit().unwrap(), parse("SM401").as_bit().unwrap());
        assert!(Address::parse("SM425").is_err());
        assert!(Address::parse("SM8335").is_err());
        assert_eq!(parse("SM8331").duty_channel(), Some(1));
        assert_eq!(parse("SM400").duty_channel(), None);
        assert!(!parse("SM420").writable_by(Writer::ProgramBit));
    }

    #[test]
    fn flags_by_name() {
        assert!(parse("_ON").as_bit().is_ok());
        assert!(parse("_scan_max").as_word().is_ok());
        assert!(parse("_ON").as_word().is_err());
        assert!(matches!(Address::parse("_NOPE"), Err(AddressError::UnknownFlag(_))));
    }

    #[test]
    fn display_round_trips() {
        for s in [
            "P0040",
            "P004",
            "M255F",
            "K000",
            "D00010",
            "D00010.A",
            "T0005",
            "C2047",
            "SM420",
            "SD8330",
            "_T20MS",
            "_ERR_CODE",
        ] {
            assert_eq!(parse(s).to_string(), s);
            assert_eq!(parse(&parse(s).to_string()), parse(s));
        }
    }

    #[test]
    fn garbage_is_a_syntax_error() {
        for s in ["", "X0000", "P", "P00G0", "D-1", "D1.GG", "T", "M00000", "SMX"] {
            assert!(Address::parse(s).is_err(), "{s}");
        }
    }
}
