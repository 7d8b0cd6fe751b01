//! The fixed layout of device memory: one flat array of 16-bit words, each area at a constant
//! offset, so that every operand of a compiled program is a word index and a bit mask.

/// A device area (docs/LANGUAGE.md, Devices).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Area {
    P,
    M,
    K,
    T,
    C,
    D,
    SM,
    SD,
    F,
}

pub const P_WORDS: u32 = 128;
pub const MK_WORDS: u32 = 256;
pub const TC_COUNT: u32 = 2048;
pub const D_WORDS: u32 = 32768;
pub const SD_FIRST: u32 = 8330;
pub const SD_WORDS: u32 = 5;

/// Word offsets of the areas.
pub const P: u32 = 0;
pub const M: u32 = P + P_WORDS;
pub const K: u32 = M + MK_WORDS;
/// Timer done bits, 16 a word.
pub const TB: u32 = K + MK_WORDS;
/// Counter done bits, 16 a word.
pub const CB: u32 = TB + TC_COUNT / 16;
/// Timer current values.
pub const TV: u32 = CB + TC_COUNT / 16;
/// Counter current values.
pub const CV: u32 = TV + TC_COUNT;
pub const D: u32 = CV + TC_COUNT;
/// SM400–SM424 as bits 0..=24 of two words (SM8330–SM8334 alias SM420–SM424).
pub const SM: u32 = D + D_WORDS;
pub const SD: u32 = SM + 2;
/// The flag bits of [`FlagBit`].
pub const F_BITS: u32 = SD + SD_WORDS;
/// The flag words of [`FlagWord`].
pub const F_WORDS: u32 = F_BITS + 1;
pub const TOTAL_WORDS: u32 = F_WORDS + FlagWord::COUNT;

const _: () = assert!(TOTAL_WORDS <= u16::MAX as u32, "word indices must fit a u16");

impl Area {
    pub(crate) fn base(self) -> u32 {
        match self {
            Area::P => P,
            Area::M => M,
            Area::K => K,
            Area::D => D,
            Area::T => TV,
            Area::C => CV,
            Area::SM => SM,
            Area::SD => SD,
            Area::F => F_BITS,
        }
    }

    pub(crate) fn word_count(self) -> u32 {
        match self {
            Area::P => P_WORDS,
            Area::M | Area::K => MK_WORDS,
            Area::D => D_WORDS,
            Area::T | Area::C => TC_COUNT,
            Area::SM => 2,
            Area::SD => SD_WORDS,
            Area::F => 1 + FlagWord::COUNT,
        }
    }

    pub(crate) fn range_text(self) -> &'static str {
        match self {
            Area::P => "P0000-P127F, P000-P127",
            Area::M => "M0000-M255F, M000-M255",
            Area::K => "K0000-K255F, K000-K255",
            Area::T => "T0000-T2047",
            Area::C => "C0000-C2047",
            Area::D => "D00000-D32767",
            Area::SM => "SM400-SM424, SM8330-SM8334",
            Area::SD => "SD8330-SD8334",
            Area::F => "named flags",
        }
    }
}

/// Bit index (0..=24) of SM400..=SM424 and of the aliases SM8330..=SM8334.
pub(crate) fn sm_bit_index(number: u32) -> Option<u32> {
    match number {
        400..=424 => Some(number - 400),
        8330..=8334 => Some(number - 8330 + 20),
        _ => None,
    }
}

/// DUTY channel 0..=4 of SM420..=SM424 / SM8330..=SM8334.
pub(crate) fn duty_channel(sm_number: u32) -> Option<usize> {
    match sm_number {
        420..=424 => Some((sm_number - 420) as usize),
        8330..=8334 => Some((sm_number - 8330) as usize),
        _ => None,
    }
}

/// The named flag bits (area F), in their bit order within the flag word.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FlagBit {
    On = 0,
    Off,
    FirstOn,
    FirstOff,
    T20ms,
    T100ms,
    T200ms,
    T1s,
    T2s,
    T10s,
    T20s,
    T60s,
    Err,
    /// `_FORCE_IN`: ON while an input is forced.
    ForceIn,
    /// `_FORCE_OUT`: ON while an output is forced.
    ForceOut,
}

/// The named flag words (area F), in their order after the flag bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FlagWord {
    ScanCur = 0,
    ScanMin,
    ScanMax,
    ErrCode,
}

impl FlagWord {
    pub const COUNT: u32 = 4;
    const ALL: [FlagWord; 4] =
        [FlagWord::ScanCur, FlagWord::ScanMin, FlagWord::ScanMax, FlagWord::ErrCode];

    pub(crate) fn from_code(code: u32) -> Option<FlagWord> {
        code.checked_sub(WORD_CODE_BASE).and_then(|i| Self::ALL.get(i as usize).copied())
    }
}

impl FlagBit {
    pub(crate) const ALL: [FlagBit; 15] = [
        FlagBit::On,
        FlagBit::Off,
        FlagBit::FirstOn,
        FlagBit::FirstOff,
        FlagBit::T20ms,
        FlagBit::T100ms,
        FlagBit::T200ms,
        FlagBit::T1s,
        FlagBit::T2s,
        FlagBit::T10s,
        FlagBit::T20s,
        FlagBit::T60s,
        FlagBit::Err,
        FlagBit::ForceIn,
        FlagBit::ForceOut,
    ];

    pub(crate) fn from_code(code: u32) -> Option<FlagBit> {
        Self::ALL.get(code as usize).copied()
    }

    /// The half period of the clock flags in ms (a clock flag is ON for the second half of each
    /// period, counted from RUN start).
    pub(crate) fn clock_half_period_ms(self) -> Option<u64> {
        Some(match self {
            FlagBit::T20ms => 10,
            FlagBit::T100ms => 50,
            FlagBit::T200ms => 100,
            FlagBit::T1s => 500,
            FlagBit::T2s => 1000,
            FlagBit::T10s => 5000,
            FlagBit::T20s => 10_000,
            FlagBit::T60s => 30_000,
            _ => return None,
        })
    }
}

/// Flag names; bit flags have codes 0..15, word flags codes from [`WORD_CODE_BASE`].
const FLAG_NAMES: [(&str, u32); 19] = [
    ("_ON", 0),
    ("_OFF", 1),
    ("_1ON", 2),
    ("_1OFF", 3),
    ("_T20MS", 4),
    ("_T100MS", 5),
    ("_T200MS", 6),
    ("_T1S", 7),
    ("_T2S", 8),
    ("_T10S", 9),
    ("_T20S", 10),
    ("_T60S", 11),
    ("_ERR", 12),
    ("_FORCE_IN", 13),
    ("_FORCE_OUT", 14),
    ("_SCAN_CUR", WORD_CODE_BASE),
    ("_SCAN_MIN", WORD_CODE_BASE + 1),
    ("_SCAN_MAX", WORD_CODE_BASE + 2),
    ("_ERR_CODE", WORD_CODE_BASE + 3),
];
const WORD_CODE_BASE: u32 = 100;

pub(crate) fn flag_code(upper_name: &str) -> Option<u32> {
    FLAG_NAMES.iter().find(|(n, _)| *n == upper_name).map(|(_, c)| *c)
}

pub(crate) fn flag_name(code: u32) -> &'static str {
    FLAG_NAMES.iter().find(|(_, c)| *c == code).map(|(n, _)| *n).unwrap_or("_?")
}
