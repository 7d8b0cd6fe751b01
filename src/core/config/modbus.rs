//! `[modbus]`: the Modbus TCP server of `plcd run`, its register map, and `[modbus.rtu]`, the
//! same map served on a serial line (docs/MODBUS.md).
//!
//! ```toml
//! [modbus]
//! listen = "127.0.0.1:1502"      # no listen: no server (the default)
//! unit_id = 1
//!
//! [[modbus.coils]]               # coil n <-> device bit `device` + n
//! start = 0
//! device = "P0040"
//! count = 16
//! writable = true
//!
//! [modbus.rtu]                   # no [modbus.rtu]: no RTU server (the default)
//! port = "/dev/ttyUSB0"
//! baud = 19200
//! unit_id = 1
//! ```
//!
//! Both passes of the config live here: [`read`] (pass 1, called by the driver in `mod.rs`)
//! turns the `[modbus]` table, `[modbus.rtu]` and the four arrays of tables into loosely typed
//! entries; [`validate`] (pass 2) checks the ranges, the devices each table may map and the
//! overlaps, and resolves every range to the word or bit indices of device memory once, so the
//! server never parses an address. The serial line's keys are checked by `serial`, which
//! `[[remote]]` shares.

use std::net::SocketAddr;
use std::ops::{Range, RangeInclusive};

use serde::de::IgnoredAny;
use serde::Deserialize;
use toml::de::DeValue;
use toml::Spanned;

use super::common::{entries, int, int_or, section, widen, Ctx, Located};
use super::serial::{self, Parity, RawSerial, SerialLine};
use super::Sink;
use crate::device::{layout, Address, Area, Writer};

/// `[modbus]`: the Modbus TCP server, off unless `listen` is given, and the RTU server, off
/// unless `[modbus.rtu]` is given; both serve the one map.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModbusConfig {
    /// `listen`: the IP address and TCP port to serve, `"127.0.0.1:1502"` or `"[::1]:1502"`;
    /// port 0 takes any free port (the log names it). Default `None`: no server.
    pub listen: Option<SocketAddr>,
    /// `unit_id`: the unit identifier served, 0..=255; default 1. Requests to 255 (the
    /// Modbus TCP "no unit" value) are served too; any other is answered with exception 0B.
    pub unit_id: u8,
    /// `max_connections`: clients connected at once, 1..=256; default 32. One more is
    /// accepted and closed at once.
    pub max_connections: u32,
    /// `max_request_bytes`: the longest request frame (MBAP header and PDU), 12..=260;
    /// default 260, the protocol's maximum. A longer one (up to 260) is answered with
    /// exception 03; a frame announcing more than 260 bytes closes the connection.
    pub max_request_bytes: u32,
    /// `idle_timeout_s`: a connection that sends no complete request for this long is closed,
    /// 0..=86400 s, 0 = never; default 60.
    pub idle_timeout_s: u32,
    /// `answer_timeout_ms`: how long a request may wait for the scan thread (a scan boundary)
    /// before it is answered with exception 04, 100..=60000 ms; default 2000 (above the
    /// longest scan watchdog, so a scan that ends within its watchdog always answers in time).
    pub answer_timeout_ms: u32,
    /// `[[modbus.coils]]`: bits, read with FC 1, written with FC 5 and 15 where `writable`.
    pub coils: Vec<ModbusRange>,
    /// `[[modbus.discrete_inputs]]`: bits, read-only, FC 2.
    pub discrete_inputs: Vec<ModbusRange>,
    /// `[[modbus.holding_registers]]`: words, read with FC 3 and 23, written with FC 6, 16
    /// and 23 where `writable`.
    pub holding_registers: Vec<ModbusRange>,
    /// `[[modbus.input_registers]]`: words, read-only, FC 4.
    pub input_registers: Vec<ModbusRange>,
    /// `[modbus.rtu]`: the same map served as a Modbus RTU server on a serial line; default
    /// none.
    pub rtu: Option<ModbusRtuConfig>,
}

/// `[modbus.rtu]`: the register map of `[modbus]` served on a serial line (docs/MODBUS.md).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModbusRtuConfig {
    /// `port`, `baud`, `parity`, `data_bits`, `stop_bits`, `frame_gap_us`.
    pub line: SerialLine,
    /// `unit_id`: the address served, [`ModbusRtuConfig::UNIT_ID`]; default 1. Requests to
    /// 0 (broadcast) are carried out and not answered; other addresses are not for us.
    pub unit_id: u8,
}

impl ModbusRtuConfig {
    pub const UNIT_ID: RangeInclusive<u8> = 1..=247;
}

impl ModbusConfig {
    pub const MAX_CONNECTIONS: RangeInclusive<u32> = 1..=256;
    /// The MBAP header (7 bytes) and the shortest PDU (5) .. the protocol's largest frame.
    pub const MAX_REQUEST_BYTES: RangeInclusive<u32> = 12..=260;
    pub const IDLE_TIMEOUT_S: RangeInclusive<u32> = 0..=86_400;
    pub const ANSWER_TIMEOUT_MS: RangeInclusive<u32> = 100..=60_000;

    /// The ranges of one table.
    pub fn table(&self, table: ModbusTable) -> &[ModbusRange] {
        match table {
            ModbusTable::Coils => &self.coils,
            ModbusTable::DiscreteInputs => &self.discrete_inputs,
            ModbusTable::HoldingRegisters => &self.holding_registers,
            ModbusTable::InputRegisters => &self.input_registers,
        }
    }
}

impl Default for ModbusConfig {
    fn default() -> Self {
        ModbusConfig {
            listen: None,
            unit_id: 1,
            max_connections: 32,
            max_request_bytes: 260,
            idle_timeout_s: 60,
            answer_timeout_ms: 2000,
            coils: Vec::new(),
            discrete_inputs: Vec::new(),
            holding_registers: Vec::new(),
            input_registers: Vec::new(),
            rtu: None,
        }
    }
}

/// The four Modbus data tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ModbusTable {
    Coils,
    DiscreteInputs,
    HoldingRegisters,
    InputRegisters,
}

impl ModbusTable {
    pub const ALL: [ModbusTable; 4] = [
        ModbusTable::Coils,
        ModbusTable::DiscreteInputs,
        ModbusTable::HoldingRegisters,
        ModbusTable::InputRegisters,
    ];

    /// The key of its array of tables: `coils` for `[[modbus.coils]]`.
    pub fn key(self) -> &'static str {
        match self {
            ModbusTable::Coils => "coils",
            ModbusTable::DiscreteInputs => "discrete_inputs",
            ModbusTable::HoldingRegisters => "holding_registers",
            ModbusTable::InputRegisters => "input_registers",
        }
    }

    /// Single bits (coils, discrete inputs) rather than 16-bit registers.
    pub fn is_bits(self) -> bool {
        matches!(self, ModbusTable::Coils | ModbusTable::DiscreteInputs)
    }

    /// Whether `writable = true` is allowed at all.
    pub fn may_write(self) -> bool {
        matches!(self, ModbusTable::Coils | ModbusTable::HoldingRegisters)
    }

    /// The device areas a range of this table may start in.
    fn areas(self) -> &'static [Area] {
        match self {
            ModbusTable::Coils => &[Area::P, Area::M, Area::K],
            ModbusTable::DiscreteInputs => &[Area::P, Area::M, Area::K, Area::T, Area::C, Area::F],
            ModbusTable::HoldingRegisters => {
                &[Area::P, Area::M, Area::K, Area::D, Area::T, Area::C]
            }
            ModbusTable::InputRegisters => {
                &[Area::P, Area::M, Area::K, Area::D, Area::T, Area::C, Area::SD, Area::F]
            }
        }
    }

    fn areas_text(self) -> &'static str {
        match self {
            ModbusTable::Coils => "P, M or K bits",
            ModbusTable::DiscreteInputs => "P, M or K bits, T or C done bits, or flag bits (_ON …)",
            ModbusTable::HoldingRegisters => {
                "P, M, K or D words or T or C current values (writable only where programs may \
                 write)"
            }
            ModbusTable::InputRegisters => {
                "P, M, K, D or SD words, T or C current values, or flag words (_SCAN_CUR, \
                 _SCAN_MIN, _SCAN_MAX, _ERR_CODE)"
            }
        }
    }
}

/// One `[[modbus.TABLE]]` entry: `count` consecutive Modbus addresses from `start`, mapped to
/// as many consecutive device bits (bit tables) or words (register tables) from `device`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModbusRange {
    /// `start`: the first Modbus address (0-based, as on the wire), 0..=65535; required.
    pub start: u16,
    /// `count`: how many addresses, 1..=65536 − `start`, within the device's area; required.
    pub count: u32,
    /// `device`: the first device; required.
    pub device: Address,
    /// Where `device` is: a word index of device memory for register tables, a bit index
    /// (word index × 16 + bit) for bit tables.
    pub first: u32,
    /// `writable`: coils and holding registers only; default false.
    pub writable: bool,
}

impl ModbusRange {
    /// The Modbus addresses it covers.
    pub fn addresses(&self) -> Range<u32> {
        u32::from(self.start)..u32::from(self.start) + self.count
    }

    /// The device memory words it touches (for the mirror).
    pub fn words(&self, bits: bool) -> Range<u32> {
        if bits {
            self.first / 16..(self.first + self.count - 1) / 16 + 1
        } else {
            self.first..self.first + self.count
        }
    }
}

// ---- pass 1 ----

/// `[modbus]` without its arrays; they are declared only so that an unknown key's message
/// lists them among the expected ones.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawModbus {
    pub listen: Option<Spanned<String>>,
    pub unit_id: Option<Spanned<i64>>,
    pub max_connections: Option<Spanned<i64>>,
    pub max_request_bytes: Option<Spanned<i64>>,
    pub idle_timeout_s: Option<Spanned<i64>>,
    pub answer_timeout_ms: Option<Spanned<i64>>,
    #[serde(rename = "coils")]
    _coils: Option<IgnoredAny>,
    #[serde(rename = "discrete_inputs")]
    _discrete_inputs: Option<IgnoredAny>,
    #[serde(rename = "holding_registers")]
    _holding_registers: Option<IgnoredAny>,
    #[serde(rename = "input_registers")]
    _input_registers: Option<IgnoredAny>,
    #[serde(rename = "rtu")]
    _rtu: Option<IgnoredAny>,
}

/// `[modbus.rtu]`: the serial line's keys (see [`RawSerial`]) and the unit served.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawModbusRtu {
    pub port: Option<Spanned<String>>,
    pub baud: Option<Spanned<i64>>,
    pub parity: Option<Spanned<Parity>>,
    pub data_bits: Option<Spanned<i64>>,
    pub stop_bits: Option<Spanned<i64>>,
    pub frame_gap_us: Option<Spanned<i64>>,
    pub unit_id: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRange {
    pub start: Spanned<i64>,
    pub device: Spanned<String>,
    pub count: Spanned<i64>,
    pub writable: Option<Spanned<bool>>,
}

/// `[modbus]` after pass 1: `None` when the document has none.
#[derive(Debug, Default)]
pub(super) struct RawModbusDoc {
    pub section: Option<Located<RawModbus>>,
    /// `[modbus.rtu]`, when the document has one and it deserialized.
    pub rtu: Option<Located<RawModbusRtu>>,
    /// The entries of each table that deserialized, in [`ModbusTable::ALL`] order.
    pub tables: [Vec<Located<RawRange>>; 4],
    /// Some entry or key had errors (already reported).
    pub failed: bool,
}

/// Pass 1 of `[modbus]`.
pub(super) fn read(sink: &mut Sink, value: Option<Spanned<DeValue<'_>>>) -> Option<RawModbusDoc> {
    let value = value?;
    let span = value.span();
    let mut doc = RawModbusDoc::default();
    let DeValue::Table(mut table) = value.into_inner() else {
        sink.error(span.start, "`modbus` must be a table, written [modbus]");
        doc.failed = true;
        return Some(doc);
    };
    let arrays = ModbusTable::ALL.map(|t| table.remove(t.key()));
    let rtu = table.remove("rtu");
    let rest = Spanned::new(span.clone(), DeValue::Table(table));
    let mut failed_keys = Vec::new();
    doc.section = section(sink, Some(rest), "modbus", &mut failed_keys).map(|value| Located {
        span,
        ctx: Ctx::Section("modbus"),
        value,
    });
    if let Some(rtu) = rtu {
        let span = rtu.span();
        doc.rtu = section(sink, Some(rtu), "modbus.rtu", &mut failed_keys).map(|value| Located {
            span,
            ctx: Ctx::Section("modbus.rtu"),
            value,
        });
        doc.failed |= doc.rtu.is_none();
    }
    doc.failed |= doc.section.is_none() || !failed_keys.is_empty();
    for ((table, array), slot) in ModbusTable::ALL.iter().zip(arrays).zip(doc.tables.iter_mut()) {
        let name = format!("modbus.{}", table.key());
        for entry in entries(sink, array, &name, |t| {
            t.get("device").and_then(|v| v.get_ref().as_str()).map(str::to_string)
        }) {
            match entry {
                Ok(entry) => slot.push(entry),
                Err(_) => doc.failed = true,
            }
        }
    }
    Some(doc)
}

// ---- pass 2 ----

/// Pass 2 of `[modbus]`: `None` if anything is wrong (reported in `sink`).
pub(super) fn validate(sink: &mut Sink, raw: Option<RawModbusDoc>) -> Option<ModbusConfig> {
    let Some(raw) = raw else {
        return Some(ModbusConfig::default());
    };
    let mut ok = !raw.failed;
    let default = ModbusConfig::default();
    let mut config = ModbusConfig::default();
    if let Some(Located { ctx, value: section, .. }) = raw.section {
        if let Some(listen) = section.listen {
            match listen.get_ref().trim().parse::<SocketAddr>() {
                Ok(addr) => config.listen = Some(addr),
                Err(_) => {
                    sink.error(
                        listen.span().start,
                        format!(
                            "{} {:?} is not an IP address and port (\"127.0.0.1:1502\", \
                             \"0.0.0.0:502\", \"[::1]:1502\"); leave it out to turn the server \
                             off",
                            ctx.key("listen"),
                            listen.get_ref()
                        ),
                    );
                    ok = false;
                }
            }
        }
        let unit_id = int_or(sink, &ctx, "unit_id", section.unit_id, 0..=255, default.unit_id);
        let connections = int_or(
            sink,
            &ctx,
            "max_connections",
            section.max_connections,
            widen(ModbusConfig::MAX_CONNECTIONS),
            default.max_connections,
        );
        let request = int_or(
            sink,
            &ctx,
            "max_request_bytes",
            section.max_request_bytes,
            widen(ModbusConfig::MAX_REQUEST_BYTES),
            default.max_request_bytes,
        );
        let idle = int_or(
            sink,
            &ctx,
            "idle_timeout_s",
            section.idle_timeout_s,
            widen(ModbusConfig::IDLE_TIMEOUT_S),
            default.idle_timeout_s,
        );
        let answer = int_or(
            sink,
            &ctx,
            "answer_timeout_ms",
            section.answer_timeout_ms,
            widen(ModbusConfig::ANSWER_TIMEOUT_MS),
            default.answer_timeout_ms,
        );
        match (unit_id, connections, request, idle, answer) {
            (Some(u), Some(c), Some(r), Some(i), Some(a)) => {
                config.unit_id = u;
                config.max_connections = c;
                config.max_request_bytes = r;
                config.idle_timeout_s = i;
                config.answer_timeout_ms = a;
            }
            _ => ok = false,
        }
    }
    if let Some(rtu) = raw.rtu {
        match rtu_server(sink, rtu) {
            Some(rtu) => config.rtu = Some(rtu),
            None => ok = false,
        }
    }
    for (table, entries) in ModbusTable::ALL.into_iter().zip(raw.tables) {
        let mut ranges: Vec<(ModbusRange, usize, String)> = Vec::new();
        for entry in entries {
            match range(sink, table, &entry) {
                Some(r) => ranges.push((r, entry.span.start, entry.ctx.subject())),
                None => ok = false,
            }
        }
        // Modbus addresses of one table are unique; report each overlap at the later entry.
        for (i, (later, at, subject)) in ranges.iter().enumerate() {
            for (earlier, _, other) in &ranges[..i] {
                let (a, b) = (later.addresses(), earlier.addresses());
                if a.start < b.end && b.start < a.end {
                    sink.error(
                        *at,
                        format!(
                            "{subject}: addresses {}..={} overlap those of {other} ({}..={})",
                            a.start,
                            a.end - 1,
                            b.start,
                            b.end - 1
                        ),
                    );
                    ok = false;
                }
            }
        }
        let ranges = ranges.into_iter().map(|(r, _, _)| r).collect();
        match table {
            ModbusTable::Coils => config.coils = ranges,
            ModbusTable::DiscreteInputs => config.discrete_inputs = ranges,
            ModbusTable::HoldingRegisters => config.holding_registers = ranges,
            ModbusTable::InputRegisters => config.input_registers = ranges,
        }
    }
    ok.then_some(config)
}

/// `[modbus.rtu]`: the serial line and the unit served.
fn rtu_server(sink: &mut Sink, rtu: Located<RawModbusRtu>) -> Option<ModbusRtuConfig> {
    let Located { span, ctx, value: raw } = rtu;
    let serial = RawSerial {
        port: raw.port,
        baud: raw.baud,
        parity: raw.parity,
        data_bits: raw.data_bits,
        stop_bits: raw.stop_bits,
        frame_gap_us: raw.frame_gap_us,
    };
    let line = serial::line(sink, &ctx, &serial, |sink| {
        let message =
            format!("{} needs `port`: the serial device, as \"/dev/ttyUSB0\"", ctx.subject());
        sink.error(span.start, message);
    });
    let unit_id = int_or(sink, &ctx, "unit_id", raw.unit_id, widen(ModbusRtuConfig::UNIT_ID), 1);
    Some(ModbusRtuConfig { line: line?, unit_id: unit_id? })
}

/// Where `[modbus.rtu] port` is and what it says, for the check that no `[[remote]]` polls
/// the port the server answers on.
pub(super) fn rtu_port(raw: Option<&RawModbusDoc>) -> Option<(String, usize)> {
    let port = raw?.rtu.as_ref()?.value.port.as_ref()?;
    Some((port.get_ref().clone(), port.span().start))
}

/// One entry of a table, resolved to device memory.
fn range(sink: &mut Sink, table: ModbusTable, entry: &Located<RawRange>) -> Option<ModbusRange> {
    let Located { ctx, value: raw, .. } = entry;
    let start: Option<u16> = int(sink, ctx, "start", &raw.start, 0..=65_535);
    let count: Option<u32> = int(sink, ctx, "count", &raw.count, 1..=65_536);
    let writable = match &raw.writable {
        Some(w) if *w.get_ref() && !table.may_write() => {
            sink.error(
                w.span().start,
                format!(
                    "{}: {} are read-only in Modbus; map the devices as {} to write them",
                    ctx.key("writable"),
                    table.key().replace('_', " "),
                    if table.is_bits() { "coils" } else { "holding registers" }
                ),
            );
            None
        }
        Some(w) => Some(*w.get_ref()),
        None => Some(false),
    };
    let device = match Address::parse(raw.device.get_ref()) {
        Ok(device) => Some(device),
        Err(e) => {
            sink.error(raw.device.span().start, format!("{}: {e}", ctx.key("device")));
            None
        }
    };
    let (start, count, writable, device) = (start?, count?, writable?, device?);
    let device_at = raw.device.span().start;
    let wrong_kind = |sink: &mut Sink| {
        sink.error(
            device_at,
            format!(
                "{}: {device} cannot start a range of {}: they map {}",
                ctx.key("device"),
                table.key().replace('_', " "),
                table.areas_text()
            ),
        );
    };
    if !table.areas().contains(&device.area) {
        wrong_kind(sink);
        return None;
    }
    // The first bit or word, and the end of the area it is in.
    let (first, area_end) = if table.is_bits() {
        let Ok(bit) = device.as_bit() else {
            wrong_kind(sink);
            return None;
        };
        let first = u32::from(bit.word) * 16 + bit.mask.trailing_zeros();
        let end = match device.area {
            Area::T => (layout::TB + layout::TC_COUNT / 16) * 16,
            Area::C => (layout::CB + layout::TC_COUNT / 16) * 16,
            Area::F => (layout::F_BITS + 1) * 16,
            area => (area.base() + area.word_count()) * 16,
        };
        (first, end)
    } else {
        let Ok(word) = device.as_word() else {
            wrong_kind(sink);
            return None;
        };
        if writable && !device.writable_by(Writer::Client) {
            wrong_kind(sink);
            return None;
        }
        (u32::from(word.0), device.area.base() + device.area.word_count())
    };
    if u32::from(start) + count > 65_536 {
        sink.error(
            raw.count.span().start,
            format!(
                "{} {count} from start {start} runs past the last Modbus address 65535",
                ctx.key("count")
            ),
        );
        return None;
    }
    if first + count > area_end {
        let room = area_end - first;
        sink.error(
            raw.count.span().start,
            format!(
                "{} {count} from {device} runs past the end of its area ({}): at most {room}",
                ctx.key("count"),
                device.area.range_text()
            ),
        );
        return None;
    }
    Some(ModbusRange { start, count, device, first, writable })
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::super::tests::{scan_config as config, scan_errors as errors};

    #[test]
    fn without_a_section_the_server_is_off_with_the_documented_defaults() {
        let modbus = config("").modbus;
        assert_eq!(modbus, ModbusConfig::default());
        assert_eq!(modbus.listen, None);
        assert_eq!(
            (
                modbus.unit_id,
                modbus.max_connections,
                modbus.max_request_bytes,
                modbus.idle_timeout_s,
                modbus.answer_timeout_ms
            ),
            (1, 32, 260, 60, 2000)
        );
        // A section without `listen` is off too.
        assert_eq!(config("[modbus]\nunit_id = 3\n").modbus.listen, None);
    }

    #[test]
    fn every_table_resolves_to_device_memory() {
        let modbus = config(
            "[modbus]\nlisten = \"127.0.0.1:1502\"\nunit_id = 7\nmax_connections = 4\n\
             max_request_bytes = 100\nidle_timeout_s = 0\nanswer_timeout_ms = 100\n\
             [[modbus.coils]]\nstart = 0\ndevice = \"P0040\"\ncount = 16\nwritable = true\n\
             [[modbus.coils]]\nstart = 100\ndevice = \"m0003\"\ncount = 4\n\
             [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"P0000\"\ncount = 8\n\
             [[modbus.discrete_inputs]]\nstart = 8\ndevice = \"T0002\"\ncount = 2\n\
             [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 100\n\
             writable = true\n\
             [[modbus.input_registers]]\nstart = 0\ndevice = \"T0000\"\ncount = 4\n\
             [[modbus.input_registers]]\nstart = 10\ndevice = \"_SCAN_CUR\"\ncount = 4\n",
        )
        .modbus;
        assert_eq!(modbus.listen, Some("127.0.0.1:1502".parse().unwrap()));
        assert_eq!((modbus.unit_id, modbus.max_connections), (7, 4));
        assert_eq!((modbus.max_request_bytes, modbus.idle_timeout_s), (100, 0));
        assert_eq!(modbus.answer_timeout_ms, 100);
        let p004 = Address::parse("P004").unwrap().as_word().unwrap().0 as u32;
        assert_eq!(modbus.coils[0].first, p004 * 16);
        assert!(modbus.coils[0].writable);
        let m000 = Address::parse("M000").unwrap().as_word().unwrap().0 as u32;
        assert_eq!((modbus.coils[1].first, modbus.coils[1].writable), (m000 * 16 + 3, false));
        assert_eq!(modbus.discrete_inputs[1].first, layout::TB * 16 + 2);
        assert_eq!(modbus.holding_registers[0].first, layout::D);
        assert_eq!(modbus.holding_registers[0].words(false), layout::D..layout::D + 100);
        assert_eq!(modbus.input_registers[0].first, layout::TV);
        assert_eq!(modbus.input_registers[1].first, layout::F_WORDS);
        assert_eq!(modbus.coils[1].words(true), m000..m000 + 1);
        assert_eq!(modbus.table(ModbusTable::InputRegisters).len(), 2);
    }

    #[test]
    fn section_keys_are_range_checked() {
        assert_eq!(
            errors(
                "[modbus]\nlisten = \"localhost:502\"\nunit_id = 256\nmax_connections = 0\n\
                 max_request_bytes = 261\nidle_timeout_s = 86401\nanswer_timeout_ms = 99\n\
                 port = 502\n"
            ),
            [
                "2:10: modbus.listen \"localhost:502\" is not an IP address and port \
                 (\"127.0.0.1:1502\", \"0.0.0.0:502\", \"[::1]:1502\"); leave it out to turn \
                 the server off",
                "3:11: modbus.unit_id 256 out of range 0..=255",
                "4:19: modbus.max_connections 0 out of range 1..=256",
                "5:21: modbus.max_request_bytes 261 out of range 12..=260",
                "6:18: modbus.idle_timeout_s 86401 out of range 0..=86400",
                "7:21: modbus.answer_timeout_ms 99 out of range 100..=60000",
                "8:1: [modbus]: unknown key `port`, expected one of `listen`, `unit_id`, \
                 `max_connections`, `max_request_bytes`, `idle_timeout_s`, \
                 `answer_timeout_ms`, `coils`, `discrete_inputs`, `holding_registers`, \
                 `input_registers`, `rtu`",
            ]
        );
        assert_eq!(config("[modbus]\nlisten = \"[::1]:0\"\n").modbus.listen.unwrap().port(), 0);
    }

    #[test]
    fn ranges_map_only_what_their_table_can_hold() {
        let errs = errors(
            "[[modbus.coils]]\nstart = 0\ndevice = \"D00000\"\ncount = 1\n\
             [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"P0000\"\ncount = 1\n\
             writable = true\n\
             [[modbus.input_registers]]\nstart = 0\ndevice = \"P0000\"\ncount = 1\n\
             [[modbus.holding_registers]]\nstart = 0\ndevice = \"_SCAN_CUR\"\ncount = 1\n\
             [[modbus.holding_registers]]\nstart = 1\ndevice = \"D0000X\"\ncount = 1\n",
        );
        assert_eq!(errs.len(), 5, "{errs:#?}");
        assert!(errs[0].starts_with("3:10: modbus.coils \"D00000\": device: D00000 cannot start"));
        assert!(errs[0].ends_with("they map P, M or K bits"), "{}", errs[0]);
        assert!(errs[1]
            .contains("modbus.discrete_inputs \"P0000\": writable: discrete inputs are read-only"));
        assert!(errs[2].contains("input_registers \"P0000\": device: P0000 cannot start"));
        assert!(errs[3].contains("holding_registers \"_SCAN_CUR\": device: _SCAN_CUR cannot"));
        assert!(errs[4].contains("`D0000X` is not a device address"), "{}", errs[4]);
    }

    #[test]
    fn counts_stay_within_the_area_and_the_address_space_and_tables_do_not_overlap() {
        let errs = errors(
            "[[modbus.coils]]\nstart = 0\ndevice = \"P1270\"\ncount = 17\n\
             [[modbus.holding_registers]]\nstart = 65000\ndevice = \"D00000\"\ncount = 537\n\
             [[modbus.holding_registers]]\nstart = 10\ndevice = \"D00000\"\ncount = 0\n\
             [[modbus.input_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 10\n\
             [[modbus.input_registers]]\nstart = 9\ndevice = \"D00100\"\ncount = 2\n\
             [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"_ON\"\ncount = 17\n",
        );
        assert_eq!(
            errs,
            [
                "4:9: modbus.coils \"P1270\": count 17 from P1270 runs past the end of its area \
                 (P0000-P127F, P000-P127): at most 16",
                "8:9: modbus.holding_registers \"D00000\": count 537 from start 65000 runs past \
                 the last Modbus address 65535",
                "12:9: modbus.holding_registers \"D00000\": count 0 out of range 1..=65536",
                "17:1: modbus.input_registers \"D00100\": addresses 9..=10 overlap those of \
                 modbus.input_registers \"D00000\" (0..=9)",
                "24:9: modbus.discrete_inputs \"_ON\": count 17 from _ON runs past the end of \
                 its area (named flags): at most 16",
            ]
        );
        // The same addresses in two tables are two different things.
        config(
            "[[modbus.coils]]\nstart = 0\ndevice = \"M0000\"\ncount = 8\n\
             [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"M0000\"\ncount = 8\n\
             [[modbus.holding_registers]]\nstart = 65535\ndevice = \"D32767\"\ncount = 1\n",
        );
    }

    #[test]
    fn entries_need_their_keys_and_know_no_others() {
        let errs = errors(
            "[[modbus.coils]]\nstart = 0\ndevice = \"M0000\"\n\
             [[modbus.coils]]\nstart = 1\ndevice = \"M0001\"\ncount = 1\nwriteable = true\n\
             [modbus]\nlisten = \"127.0.0.1:1502\"\n",
        );
        assert_eq!(errs.len(), 2, "{errs:#?}");
        assert!(errs[0].contains("modbus.coils \"M0000\": missing key `count`"), "{}", errs[0]);
        assert!(errs[1].contains("unknown key `writeable`"), "{}", errs[1]);
    }

    #[test]
    fn an_rtu_section_serves_on_a_serial_line_with_the_modbus_defaults() {
        // Without `listen` the TCP server stays off; the RTU server serves the same map.
        let modbus = config("[modbus.rtu]\nport = \"/dev/ttyUSB0\"\n").modbus;
        assert_eq!(modbus.listen, None);
        let rtu = modbus.rtu.expect("an RTU server");
        assert_eq!(rtu, ModbusRtuConfig { line: SerialLine::new("/dev/ttyUSB0"), unit_id: 1 });
        assert_eq!(
            (rtu.line.baud, rtu.line.parity, rtu.line.data_bits, rtu.line.stop_bits),
            (19_200, Parity::Even, 8, 1)
        );
        assert_eq!(rtu.line.frame_gap_us, None);
        assert_eq!(config("").modbus.rtu, None);
        // With `listen`, both.
        let modbus =
            config("[modbus]\nlisten = \"127.0.0.1:1502\"\n[modbus.rtu]\nport = \"/dev/ttyS1\"\n")
                .modbus;
        assert!(modbus.listen.is_some() && modbus.rtu.is_some());
    }

    #[test]
    fn every_rtu_key_resolves() {
        let rtu = config(
            "[modbus.rtu]\nport = \"/dev/serial/by-id/usb-FTDI-if00\"\nbaud = 115200\n\
             parity = \"none\"\ndata_bits = 8\nstop_bits = 2\nframe_gap_us = 5000\n\
             unit_id = 247\n",
        )
        .modbus
        .rtu
        .unwrap();
        assert_eq!(
            rtu,
            ModbusRtuConfig {
                line: SerialLine {
                    port: "/dev/serial/by-id/usb-FTDI-if00".into(),
                    baud: 115_200,
                    parity: Parity::None,
                    data_bits: 8,
                    stop_bits: 2,
                    frame_gap_us: Some(5000),
                },
                unit_id: 247,
            }
        );
        let odd = config("[modbus.rtu]\nport = \"COM3 \"\nparity = \"odd\"\n").modbus.rtu.unwrap();
        assert_eq!((odd.line.port.to_str(), odd.line.parity), (Some("COM3 "), Parity::Odd));
    }

    #[test]
    fn rtu_keys_are_range_checked_all_at_once() {
        assert_eq!(
            errors(
                "[modbus.rtu]\nport = \" \"\nbaud = 299\nparity = \"mark\"\ndata_bits = 7\n\
                 stop_bits = 3\nframe_gap_us = 99\nunit_id = 0\nspeed = 9600\n"
            ),
            [
                "2:8: modbus.rtu.port must not be empty",
                "3:8: modbus.rtu.baud 299 out of range 300..=4000000",
                "4:10: modbus.rtu.parity: unknown variant `mark`, expected one of `none`, \
                 `even`, `odd`",
                "5:13: modbus.rtu.data_bits 7: 7 data bits is the Modbus ASCII mode, which plcd \
                 does not speak; Modbus RTU has 8",
                "6:13: modbus.rtu.stop_bits 3 out of range 1..=2",
                "7:16: modbus.rtu.frame_gap_us 99 out of range 100..=1000000",
                "8:11: modbus.rtu.unit_id 0 out of range 1..=247",
                "9:1: [modbus.rtu]: unknown key `speed`, expected one of `port`, `baud`, \
                 `parity`, `data_bits`, `stop_bits`, `frame_gap_us`, `unit_id`",
            ]
        );
        assert_eq!(
            errors(
                "[modbus.rtu]\nbaud = 4000001\ndata_bits = 9\nunit_id = 248\nframe_gap_us = \
                 1000001\n"
            ),
            [
                "1:1: [modbus.rtu] needs `port`: the serial device, as \"/dev/ttyUSB0\"",
                "2:8: modbus.rtu.baud 4000001 out of range 300..=4000000",
                "3:13: modbus.rtu.data_bits 9 must be 8: Modbus RTU characters have 8 data bits",
                "4:11: modbus.rtu.unit_id 248 out of range 1..=247",
                "5:16: modbus.rtu.frame_gap_us 1000001 out of range 100..=1000000",
            ]
        );
        assert_eq!(
            errors("[modbus]\nrtu = \"/dev/ttyUSB0\"\n"),
            ["2:7: `modbus.rtu` must be a table, written [modbus.rtu]"]
        );
        // The range edges are accepted.
        let rtu = config(
            "[modbus.rtu]\nport = \"/dev/ttyS0\"\nbaud = 300\nframe_gap_us = 100\nunit_id = 1\n",
        )
        .modbus
        .rtu
        .unwrap();
        assert_eq!((rtu.line.baud, rtu.line.frame_gap_us), (300, Some(100)));
        config("[modbus.rtu]\nport = \"/dev/ttyS0\"\nbaud = 4000000\nframe_gap_us = 1000000\n");
    }
}
