//! A Modbus RTU serial line, as `[[remote]]` (transport `"rtu"`) and `[modbus.rtu]` describe
//! it: the port, its character format, and the silences of the Modbus serial line protocol
//! that follow from them (docs/REMOTE.md, docs/MODBUS.md).
//!
//! The timing rules live here, once: a character is a start bit, 8 data bits, the parity bit
//! if any and the stop bits; frames are separated by at least 3.5 character times (t3.5), and
//! a silence of more than 1.5 character times (t1.5) inside a frame ends it. Above 19200 baud
//! the Modbus serial line specification (§2.5.1.1) fixes them at 1750 µs and 750 µs.

use std::ops::RangeInclusive;
use std::path::PathBuf;

use toml::Spanned;

use super::common::{int, int_or, start, widen, Ctx};
use super::Sink;

/// The parity bit of a serial character.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Parity {
    None,
    /// The Modbus serial line default.
    #[default]
    Even,
    Odd,
}

impl Parity {
    /// As the config writes it: `none`, `even`, `odd`.
    pub fn as_str(self) -> &'static str {
        match self {
            Parity::None => "none",
            Parity::Even => "even",
            Parity::Odd => "odd",
        }
    }
}

/// A serial port and its settings.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SerialLine {
    /// `port`: the serial device, `/dev/ttyUSB0`, `/dev/ttyS1`, `/dev/serial/by-id/…`;
    /// required.
    pub port: PathBuf,
    /// `baud`: bits per second, [`SerialLine::BAUD`]; default 19200 (the Modbus default).
    pub baud: u32,
    /// `parity`: `"none"`, `"even"` or `"odd"`; default `"even"` (the Modbus default).
    pub parity: Parity,
    /// `data_bits`: 8, the only size Modbus RTU uses (7 is the ASCII mode); default 8.
    pub data_bits: u8,
    /// `stop_bits`: 1 or 2; default 1.
    pub stop_bits: u8,
    /// `frame_gap_us`: the silence before each frame sent, [`SerialLine::FRAME_GAP_US`];
    /// default none: t3.5 of the baud rate ([`SerialLine::frame_gap_ns`]). For devices that
    /// need a longer turnaround than the protocol's.
    pub frame_gap_us: Option<u32>,
}

impl SerialLine {
    pub const BAUD: RangeInclusive<u32> = 300..=4_000_000;
    pub const DEFAULT_BAUD: u32 = 19_200;
    pub const FRAME_GAP_US: RangeInclusive<u32> = 100..=1_000_000;
    /// Above this baud rate t1.5 and t3.5 are fixed (Modbus serial line §2.5.1.1).
    pub const FIXED_TIMING_ABOVE_BAUD: u32 = 19_200;

    /// A line on `port` with every other setting at its default.
    pub fn new(port: impl Into<PathBuf>) -> SerialLine {
        SerialLine {
            port: port.into(),
            baud: Self::DEFAULT_BAUD,
            parity: Parity::default(),
            data_bits: 8,
            stop_bits: 1,
            frame_gap_us: None,
        }
    }

    /// Bits on the wire per character: start, data, parity, stop.
    pub fn char_bits(&self) -> u32 {
        1 + u32::from(self.data_bits)
            + u32::from(self.parity != Parity::None)
            + u32::from(self.stop_bits)
    }

    /// One character's time on the wire, in ns.
    pub fn char_time_ns(&self) -> u64 {
        u64::from(self.char_bits()) * 1_000_000_000 / u64::from(self.baud)
    }

    /// `bytes` characters' time on the wire, in ns.
    pub fn bytes_time_ns(&self, bytes: usize) -> u64 {
        bytes as u64 * u64::from(self.char_bits()) * 1_000_000_000 / u64::from(self.baud)
    }

    /// The silence between two frames: `frame_gap_us` if given, else t3.5.
    pub fn frame_gap_ns(&self) -> u64 {
        match self.frame_gap_us {
            Some(us) => u64::from(us) * 1000,
            None if self.baud > Self::FIXED_TIMING_ABOVE_BAUD => 1_750_000,
            None => self.char_time_ns() * 7 / 2,
        }
    }

    /// t1.5: a silence this long inside a frame ends it.
    pub fn char_gap_ns(&self) -> u64 {
        if self.baud > Self::FIXED_TIMING_ABOVE_BAUD {
            750_000
        } else {
            self.char_time_ns() * 3 / 2
        }
    }

    /// Whether `other` is the same port with different settings (devices sharing a port must
    /// agree on them).
    pub fn conflicts_with(&self, other: &SerialLine) -> bool {
        self.port == other.port && self != other
    }
}

// ---- the keys, both passes ----

/// The serial line's keys as written, shared by `[modbus.rtu]` and a `[[remote]]` of
/// transport `"rtu"`. serde cannot flatten them into those tables and still deny unknown
/// keys, so each raw table declares them and hands them over in this.
#[derive(Debug, Default)]
pub(super) struct RawSerial {
    pub port: Option<Spanned<String>>,
    pub baud: Option<Spanned<i64>>,
    pub parity: Option<Spanned<Parity>>,
    pub data_bits: Option<Spanned<i64>>,
    pub stop_bits: Option<Spanned<i64>>,
    pub frame_gap_us: Option<Spanned<i64>>,
}

impl RawSerial {
    /// The keys given, each with where it is, in the order of the docs.
    pub fn given(&self) -> impl Iterator<Item = (&'static str, usize)> {
        [
            ("port", start(&self.port)),
            ("baud", start(&self.baud)),
            ("parity", start(&self.parity)),
            ("data_bits", start(&self.data_bits)),
            ("stop_bits", start(&self.stop_bits)),
            ("frame_gap_us", start(&self.frame_gap_us)),
        ]
        .into_iter()
        .filter_map(|(key, at)| Some((key, at?)))
    }
}

/// Pass 2 of the serial line's keys: `None` if any is wrong (reported). Every key is checked
/// even when `port` is missing; `no_port` reports that.
pub(super) fn line(
    sink: &mut Sink,
    ctx: &Ctx,
    raw: &RawSerial,
    no_port: impl FnOnce(&mut Sink),
) -> Option<SerialLine> {
    let port = match &raw.port {
        Some(port) if port.get_ref().trim().is_empty() => {
            sink.error(port.span().start, format!("{} must not be empty", ctx.key("port")));
            None
        }
        // Kept as given: a serial device is named by its path, not relative to the config.
        Some(port) => Some(PathBuf::from(port.get_ref())),
        None => {
            no_port(sink);
            None
        }
    };
    let baud = int_or(
        sink,
        ctx,
        "baud",
        raw.baud.clone(),
        widen(SerialLine::BAUD),
        SerialLine::DEFAULT_BAUD,
    );
    let data_bits = match &raw.data_bits {
        Some(bits) if *bits.get_ref() == 8 => Some(8),
        Some(bits) if *bits.get_ref() == 7 => {
            let message = format!(
                "{} 7: 7 data bits is the Modbus ASCII mode, which plcd does not speak; Modbus \
                 RTU has 8",
                ctx.key("data_bits")
            );
            sink.error(bits.span().start, message);
            None
        }
        Some(bits) => {
            let message = format!(
                "{} {} must be 8: Modbus RTU characters have 8 data bits",
                ctx.key("data_bits"),
                bits.get_ref()
            );
            sink.error(bits.span().start, message);
            None
        }
        None => Some(8),
    };
    let stop_bits = int_or(sink, ctx, "stop_bits", raw.stop_bits.clone(), 1..=2, 1);
    let frame_gap_us = match &raw.frame_gap_us {
        Some(gap) => int(sink, ctx, "frame_gap_us", gap, widen(SerialLine::FRAME_GAP_US)).map(Some),
        None => Some(None),
    };
    Some(SerialLine {
        port: port?,
        baud: baud?,
        parity: raw.parity.as_ref().map_or_else(Parity::default, |p| *p.get_ref()),
        data_bits: data_bits?,
        stop_bits: stop_bits?,
        frame_gap_us: frame_gap_us?,
    })
}

impl SerialLine {
    /// `19200 baud 8E1`, with the frame gap if set: what devices on one port disagree on.
    pub fn describe_settings(&self) -> String {
        let parity = match self.parity {
            Parity::None => 'N',
            Parity::Even => 'E',
            Parity::Odd => 'O',
        };
        let mut text = format!("{} baud {}{parity}{}", self.baud, self.data_bits, self.stop_bits);
        if let Some(gap) = self.frame_gap_us {
            text.push_str(&format!(", frame_gap_us {gap}"));
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timing_follows_the_character_format_and_is_fixed_above_19200_baud() {
        let mut line = SerialLine::new("/dev/ttyUSB0");
        assert_eq!(line.char_bits(), 11, "8E1: start, 8 data, parity, stop");
        assert_eq!(line.char_time_ns(), 572_916);
        assert_eq!(line.frame_gap_ns(), 572_916 * 7 / 2);
        assert_eq!(line.char_gap_ns(), 572_916 * 3 / 2);
        line.parity = Parity::None;
        assert_eq!(line.char_bits(), 10);
        line.baud = 115_200;
        assert_eq!(line.char_time_ns(), 86_805);
        assert_eq!(line.bytes_time_ns(8), 694_444);
        assert_eq!((line.frame_gap_ns(), line.char_gap_ns()), (1_750_000, 750_000));
        line.frame_gap_us = Some(5000);
        assert_eq!(line.frame_gap_ns(), 5_000_000);
        let other = SerialLine { baud: 9600, ..line.clone() };
        assert!(line.conflicts_with(&other));
        assert!(!line.conflicts_with(&line.clone()));
        assert!(!line.conflicts_with(&SerialLine::new("/dev/ttyS0")));
    }
}
