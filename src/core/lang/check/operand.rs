//! Operands: one token resolved into what its instruction needs ([`Kind`]) — a bit, a word or a
//! constant, a destination the program may write, a timer, a counter, a number in range, a
//! DUTY scan count or clock relay — with the message that says why it is not; the operand count
//! of a line; and the constants' syntax ([`parse_constant`]).

use super::mnemonic::Mnemonic;
use super::Checker;
use crate::device::{layout, Address, Area, BitRef, WordRef, Writer, WORD_VALUES};
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
    /// A double-word value: a device word and the next, or a constant's slot (the checker
    /// keeps it among the program's constants).
    WideWord(WordRef),
    WideConst(u64),
    /// A double-word destination.
    WideDest(WordRef),
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
    /// A 32-bit signed value: two words or an integer constant.
    DWord,
    /// A `REAL` value: two words or a real constant.
    RWord,
    /// Two words the program may write.
    DWordOut,
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
    if matches!(kind, Kind::DWord | Kind::RWord | Kind::DWordOut) {
        return resolve_wide(text, kind, name);
    }
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
        Kind::Number(_) | Kind::DWord | Kind::RWord | Kind::DWordOut => {
            unreachable!("handled above")
        }
    }
}

/// A double-word operand: a constant (an integer for `D` instructions, a real for `R` ones), or
/// a word device whose next word exists in the same area.
fn resolve_wide(text: &str, kind: Kind, name: &str) -> Result<Operand, String> {
    if kind != Kind::DWordOut {
        if let Some(slot) = parse_wide_constant(text, kind == Kind::RWord, name)? {
            return Ok(Operand::WideConst(slot));
        }
    } else if parse_wide_constant(text, false, name).is_ok_and(|c| c.is_some()) || looks_real(text)
    {
        return Err(format!("`{name}` needs a device here, found constant `{text}`"));
    }
    let address = Address::parse(text).map_err(|e| e.to_string())?;
    let w = address.as_word().map_err(|e| e.to_string())?;
    let last = match address.area {
        Area::SD => layout::SD_FIRST + layout::SD_WORDS - 1,
        Area::F => {
            return Err(format!(
                "`{address}` is a single word: a double word needs a device and the word after it"
            ))
        }
        area => area.word_count() - 1,
    };
    if address.number >= last {
        let next = Address { number: address.number + 1, ..address };
        return Err(format!(
            "`{address}` as a double word needs `{next}` too, which is out of range ({})",
            address.area.range_text()
        ));
    }
    if kind == Kind::DWordOut {
        if !address.writable_by(Writer::ProgramWord) {
            return Err(read_only(&address));
        }
        return Ok(Operand::WideDest(w));
    }
    Ok(Operand::WideWord(w))
}

/// Whether `text` is written as a real number (`1.5`, `2e3`, `.5`), not an integer.
fn looks_real(text: &str) -> bool {
    let digits = text.strip_prefix(['-', '+']).unwrap_or(text);
    digits.bytes().next().is_some_and(|b| b.is_ascii_digit() || b == b'.')
        && digits.bytes().any(|b| matches!(b, b'.' | b'e' | b'E'))
        && digits.parse::<f64>().is_ok()
}

/// A double-word constant as a slot (its low 32 bits are what the instruction uses): for `D`
/// instructions decimal `-2147483648..=4294967295` or hex `h0`..=`hFFFFFFFF`, for `R` ones a
/// decimal real (`1.5`, `-2`, `1e-3`). `Ok(None)` when the text is not a constant at all.
pub fn parse_wide_constant(text: &str, real: bool, name: &str) -> Result<Option<u64>, String> {
    let bytes = text.as_bytes();
    let is_decimal =
        bytes.first().is_some_and(|b| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.'));
    let hex = text
        .strip_prefix(['h', 'H'])
        .filter(|hex| !hex.is_empty() && hex.bytes().all(|b| b.is_ascii_hexdigit()));
    if real {
        if let Some(_hex) = hex {
            return Err(format!("`{name}` needs a real constant (like 1.5), found `{text}`"));
        }
        if !is_decimal {
            return Ok(None);
        }
        return match text.parse::<f32>() {
            Ok(x) if x.is_finite() => Ok(Some(u64::from(x.to_bits()))),
            _ if text.parse::<f64>().is_ok() => {
                Err(format!("constant `{text}` is not a REAL value (±3.4028235e38)"))
            }
            _ => Err(format!("constant `{text}` is not a real number")),
        };
    }
    if let Some(hex) = hex {
        return match u64::from_str_radix(hex, 16) {
            Ok(v) if v <= 0xFFFF_FFFF => Ok(Some(v)),
            _ => Err(format!("constant `{text}` is not a 32-bit value (h0..=hFFFFFFFF)")),
        };
    }
    if !is_decimal {
        return Ok(None);
    }
    if looks_real(text) {
        return Err(format!("`{name}` needs an integer constant, found real constant `{text}`"));
    }
    match text.parse::<i64>() {
        Ok(v) if (-(1i64 << 31)..1i64 << 32).contains(&v) => Ok(Some(u64::from(v as u32))),
        _ => Err(format!("constant `{text}` is not a 32-bit value (-2147483648..=4294967295)")),
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

pub(super) fn wide_dest(o: Option<Operand>) -> Option<WordRef> {
    match o {
        Some(Operand::WideDest(d)) => Some(d),
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

    #[test]
    fn wide_constants() {
        let d = |t| parse_wide_constant(t, false, "DMOV");
        let r = |t| parse_wide_constant(t, true, "RMOV");
        assert_eq!(d("-1"), Ok(Some(0xFFFF_FFFF)));
        assert_eq!(d("4294967295"), Ok(Some(0xFFFF_FFFF)));
        assert_eq!(d("-2147483648"), Ok(Some(0x8000_0000)));
        assert_eq!(d("h12345678"), Ok(Some(0x1234_5678)));
        assert_eq!(d("D00010"), Ok(None));
        assert!(d("4294967296").is_err());
        assert!(d("h100000000").is_err());
        assert!(d("1.5").is_err());
        assert_eq!(r("1.5"), Ok(Some(u64::from(1.5f32.to_bits()))));
        assert_eq!(r("-2"), Ok(Some(u64::from((-2f32).to_bits()))));
        assert_eq!(r(".5"), Ok(Some(u64::from(0.5f32.to_bits()))));
        assert_eq!(r("1e-3"), Ok(Some(u64::from(1e-3f32.to_bits()))));
        assert_eq!(r("D00010"), Ok(None));
        assert!(r("1e39").is_err());
        assert!(r("h10").is_err());
    }
}
