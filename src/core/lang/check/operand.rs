//! Operands: one token resolved into what its instruction needs ([`Kind`]) — a bit, a word or a
//! constant, a destination the program may write, a timer, a counter, a number in range, a
//! DUTY scan count or clock relay — with the message that says why it is not; the operand count
//! of a line; and the constants' syntax ([`parse_constant`]).

use super::mnemonic::Mnemonic;
use super::Checker;
use crate::device::{Address, Area, BitRef, WordRef, Writer, WORD_VALUES};
use crate::lang::ops::{Op, Src};
use crate::lang::parse::Token;

/// A resolved operand.
pub(super) enum Operand {
    Bit(BitRef),
    Word(Src),
    Dest(WordRef),
    Timer(u16),
    Counter(u16),
    Number(u32),
    /// `RST` on a timer or counter.
    ResetTarget(Op),
}

/// What an operand position accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Bit,
    BitOut,
    ResetTarget,
    Word,
    WordOut,
    Timer,
    Counter,
    Number(u32),
    DutyScans,
    DutyRelay,
}

impl Checker<'_, '_> {
    /// Whether the line has as many operands as its mnemonic takes; reports it when not.
    pub(super) fn operand_count_ok(
        &mut self,
        mnemonic: Mnemonic,
        name: &str,
        operands: &[Token<'_>],
        line: u32,
        col: u32,
    ) -> bool {
        let expected = mnemonic.operands();
        let (min, max) = match mnemonic {
            Mnemonic::Di | Mnemonic::Ei => (0, 1),
            _ => (expected.len(), expected.len()),
        };
        if (min..=max).contains(&operands.len()) {
            return true;
        }
        let wanted = match (min, max) {
            (0, 0) => "no operands".to_string(),
            (0, 1) => "no operand or a task number".to_string(),
            (n, _) => {
                format!("{n} operand{} ({})", if n == 1 { "" } else { "s" }, expected.join(", "))
            }
        };
        let at = operands.get(max).map_or(col, |t| t.col);
        self.error(line, at, format!("`{name}` takes {wanted}, found {}", operands.len()));
        false
    }
}

/// Resolves one operand as `kind`; `name` is the mnemonic, for the message.
pub(super) fn resolve(token: &Token<'_>, kind: Kind, name: &str) -> Result<Operand, String> {
    let text = token.text;
    if let Kind::Number(max) = kind {
        return match text.parse::<u32>() {
            Ok(n) if n <= max => Ok(Operand::Number(n)),
            _ => Err(format!("`{name}` needs a number 0..={max}, found `{text}`")),
        };
    }
    if let Some(value) = parse_constant(text)? {
        return match kind {
            Kind::Word => Ok(Operand::Word(Src::Const(value as u16))),
            Kind::DutyScans if (0..=32767).contains(&value) => {
                Ok(Operand::Word(Src::Const(value as u16)))
            }
            Kind::DutyScans => Err(format!("DUTY scan count {value} is outside 0..=32767 (3405H)")),
            _ => Err(format!("`{name}` needs a device here, found constant `{text}`")),
        };
    }
    let address = Address::parse(text).map_err(|e| e.to_string())?;
    match kind {
        Kind::Bit => address.as_bit().map(Operand::Bit).map_err(|e| e.to_string()),
        Kind::BitOut => {
            let bit = address.as_bit().map_err(|e| e.to_string())?;
            if !address.writable_by(Writer::ProgramBit) {
                return Err(read_only(&address));
            }
            Ok(Operand::Bit(bit))
        }
        Kind::ResetTarget => match address.area {
            Area::T => Ok(Operand::ResetTarget(Op::RstTimer(address.number as u16))),
            Area::C => Ok(Operand::ResetTarget(Op::RstCounter(address.number as u16))),
            _ => resolve(token, Kind::BitOut, name),
        },
        Kind::Word | Kind::DutyScans => {
            address.as_word().map(|w| Operand::Word(Src::Word(w))).map_err(|e| e.to_string())
        }
        Kind::WordOut => {
            let w = address.as_word().map_err(|e| e.to_string())?;
            if !address.writable_by(Writer::ProgramWord) {
                return Err(read_only(&address));
            }
            Ok(Operand::Dest(w))
        }
        Kind::Timer if address.area == Area::T => Ok(Operand::Timer(address.number as u16)),
        Kind::Timer => Err(format!("`{name}` needs a timer T0000-T2047, found `{text}`")),
        Kind::Counter if address.area == Area::C => Ok(Operand::Counter(address.number as u16)),
        Kind::Counter => Err(format!("`{name}` needs a counter C0000-C2047, found `{text}`")),
        Kind::DutyRelay => match address.duty_channel() {
            Some(channel) => Ok(Operand::Number(channel as u32)),
            None => Err(format!(
                "DUTY clock relay `{text}` is not one of SM420-SM424, SM8330-SM8334 (2820H)"
            )),
        },
        Kind::Number(_) => unreachable!("handled above"),
    }
}

fn read_only(address: &Address) -> String {
    let owner = match address.area {
        Area::T => "timer contacts belong to their timer instruction",
        Area::C => "counter contacts belong to their counter instruction",
        Area::SM if address.is_duty_relay() => "DUTY clock relays are switched by DUTY",
        Area::SM | Area::SD | Area::F => "system devices are maintained by the PLC",
        _ => "read-only",
    };
    format!("`{address}` is read-only: {owner}")
}

pub(super) fn bit(o: Option<Operand>) -> Option<BitRef> {
    match o {
        Some(Operand::Bit(b)) => Some(b),
        _ => None,
    }
}

pub(super) fn word(o: Option<Operand>) -> Option<Src> {
    match o {
        Some(Operand::Word(s)) => Some(s),
        _ => None,
    }
}

pub(super) fn dest(o: Option<Operand>) -> Option<WordRef> {
    match o {
        Some(Operand::Dest(d)) => Some(d),
        _ => None,
    }
}

pub(super) fn counter(o: Option<Operand>) -> Option<u16> {
    match o {
        Some(Operand::Counter(c)) => Some(c),
        _ => None,
    }
}

pub(super) fn number(o: Option<Operand>) -> Option<u32> {
    match o {
        Some(Operand::Number(n)) => Some(n),
        _ => None,
    }
}

/// Parses a constant: decimal `-32768..=65535` or hex `h0`..=`hFFFF`. `Ok(None)` when the text
/// is not a constant at all (a device, then).
pub fn parse_constant(text: &str) -> Result<Option<i32>, String> {
    let bytes = text.as_bytes();
    let is_decimal = bytes.first().is_some_and(|b| b.is_ascii_digit() || *b == b'-' || *b == b'+');
    if is_decimal {
        return match text.parse::<i32>() {
            Ok(v) if WORD_VALUES.contains(&v) => Ok(Some(v)),
            _ => Err(format!("constant `{text}` is not a 16-bit value ({WORD_VALUES:?})")),
        };
    }
    if let Some(hex) = text.strip_prefix(['h', 'H']) {
        if !hex.is_empty() && hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return match u32::from_str_radix(hex, 16) {
                Ok(v) if v <= 0xFFFF => Ok(Some(v as i32)),
                _ => Err(format!("constant `{text}` is not a 16-bit value (h0000..=hFFFF)")),
            };
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants() {
        assert_eq!(parse_constant("100"), Ok(Some(100)));
        assert_eq!(parse_constant("-5"), Ok(Some(-5)));
        assert_eq!(parse_constant("h00FF"), Ok(Some(255)));
        assert_eq!(parse_constant("HFFFF"), Ok(Some(65535)));
        assert_eq!(parse_constant("M0000"), Ok(None));
        assert!(parse_constant("70000").is_err());
        assert!(parse_constant("h10000").is_err());
        assert!(parse_constant("12ab").is_err());
    }
}
