//! `[[remote]]`, `[[remote.read]]` and `[[remote.write]]`: Modbus devices that `plcd run`
//! polls as remote I/O (docs/REMOTE.md).
//!
//! ```toml
//! [[remote]]
//! name = "rack1"
//! transport = "tcp"
//! address = "127.0.0.1:1502"
//! unit_id = 1
//! period_ms = 10
//! timeout_ms = 100
//! on_loss = "clear"
//! status = "M0100"
//!
//! [[remote.read]]
//! table = "discrete_inputs"
//! address = 0
//! count = 16
//! device = "P0100"
//!
//! [[remote.write]]
//! table = "coils"
//! address = 0
//! count = 16
//! device = "P0140"
//! ```
//!
//! Every table is one Modbus request, so a table is read or written whole: its count stays
//! within the protocol's limit for its function code ([`RemoteTable::max_count`]). Tables are
//! resolved to device memory here, once, as the `[modbus]` map is, so the pollers never parse
//! an address.

use std::collections::HashMap;
use std::net::{Ipv4Addr, Ipv6Addr};
use std::ops::{Range, RangeInclusive};
use std::path::{Path, PathBuf};

use serde::de::IgnoredAny;
use serde::Deserialize;
use toml::de::DeValue;
use toml::Spanned;

use super::common::{entries, entries_as, int, int_or, peek_str, widen, Ctx, Located};
use super::io::{RawInput, RawOutput};
use super::modbus::ModbusTable;
use super::serial::{self, Parity, RawSerial, SerialLine};
use super::Sink;
use crate::device::{Address, Area, BitRef, Writer};

/// One `[[remote]]`: a Modbus server that plcd polls.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RemoteDevice {
    /// `name`: unique among the remotes; names it in logs, `plcctl status` and diagnostics;
    /// required. 1..=[`RemoteDevice::NAME_CHARS`] letters, digits, `_` and `-`.
    pub name: String,
    /// `transport` with its keys: `"tcp"` and `address`, or `"rtu"` and the serial line's
    /// keys (`port`, `baud`, `parity`, `data_bits`, `stop_bits`, `frame_gap_us`).
    pub transport: RemoteTransport,
    /// `unit_id`: the unit addressed, 0..=255 over TCP (default 1), 1..=247 over RTU (0 is
    /// broadcast, which has no answer to poll).
    pub unit_id: u8,
    /// `period_ms`: the poll period of its read tables (and of its `write = "period"`
    /// tables) unless a table sets its own, [`RemoteDevice::PERIOD_MS`]; default 100.
    pub period_ms: u32,
    /// `timeout_ms`: how long an answer may take, [`RemoteDevice::TIMEOUT_MS`]; default 100.
    /// Over TCP, connecting has the same time.
    pub timeout_ms: u32,
    /// `on_loss`: what the inputs it feeds do when it is lost; default `"clear"`.
    pub on_loss: OnLoss,
    /// `loss_after`: consecutive failed requests after which the device is lost (its status
    /// bit OFF, its inputs cleared or held), [`RemoteDevice::LOSS_AFTER`]; default 1.
    pub loss_after: u32,
    /// `reconnect_ms`: the first wait before a lost device is tried again; it doubles with
    /// each failed try up to `reconnect_max_ms`. [`RemoteDevice::RECONNECT_MS`]; default 100.
    pub reconnect_ms: u32,
    /// `reconnect_max_ms`: the longest wait between two tries, `reconnect_ms`..=60000;
    /// default 5000, or `reconnect_ms` if that is longer.
    pub reconnect_max_ms: u32,
    /// `status`: a P, M or K bit that is ON while the device answers; default none.
    pub status: Option<RemoteStatusBit>,
    /// `[[remote.read]]`, in file order.
    pub reads: Vec<RemoteRead>,
    /// `[[remote.write]]`, in file order.
    pub writes: Vec<RemoteWrite>,
}

impl RemoteDevice {
    pub const PERIOD_MS: RangeInclusive<u32> = 1..=3_600_000;
    pub const TIMEOUT_MS: RangeInclusive<u32> = 1..=60_000;
    pub const LOSS_AFTER: RangeInclusive<u32> = 1..=100;
    pub const RECONNECT_MS: RangeInclusive<u32> = 10..=60_000;
    pub const RECONNECT_MAX_MS: u32 = 60_000;
    pub const DEFAULT_PERIOD_MS: u32 = 100;
    pub const DEFAULT_TIMEOUT_MS: u32 = 100;
    pub const DEFAULT_RECONNECT_MS: u32 = 100;
    pub const DEFAULT_RECONNECT_MAX_MS: u32 = 5000;
    /// Unit ids over RTU: 0 is broadcast, 248..=255 reserved.
    pub const RTU_UNIT_ID: RangeInclusive<u8> = 1..=247;
    /// At most this many `[[remote]]` (each TCP device has a thread, each RTU port one).
    pub const MAX_DEVICES: usize = 64;
    /// The longest `name`, in characters.
    pub const NAME_CHARS: usize = 32;

    /// The shortest period among its tables (how often its thread must wake, at most).
    pub fn shortest_period_ms(&self) -> u32 {
        self.reads
            .iter()
            .map(|r| r.period_ms)
            .chain(self.writes.iter().filter_map(|w| match w.on {
                WriteOn::Period { period_ms } => Some(period_ms),
                WriteOn::Change { .. } => None,
            }))
            .min()
            .unwrap_or(self.period_ms)
    }
}

/// How plcd reaches a remote device.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RemoteTransport {
    /// `transport = "tcp"`, `address = "host:port"`: Modbus TCP. The host may be a name;
    /// it is resolved at each connect.
    Tcp { address: String },
    /// `transport = "rtu"`: Modbus RTU on a serial line. Devices on one port share it and
    /// must agree on its settings.
    Rtu(SerialLine),
}

impl RemoteTransport {
    /// `tcp 10.0.0.5:502` or `rtu /dev/ttyUSB0`, for logs and status.
    pub fn describe(&self) -> String {
        match self {
            RemoteTransport::Tcp { address } => format!("tcp {address}"),
            RemoteTransport::Rtu(line) => format!("rtu {}", line.port.display()),
        }
    }
}

/// `on_loss`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OnLoss {
    /// Every input it feeds is cleared (bits OFF, words 0) at the next input refresh.
    #[default]
    Clear,
    /// The inputs keep the last values read.
    Hold,
}

/// The `status` bit, resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RemoteStatusBit {
    pub device: Address,
    pub bit: BitRef,
}

/// One `[[remote.read]]` or `[[remote.write]]` table: `count` consecutive Modbus addresses of
/// `table` from `address`, and as many consecutive device bits or words from `device`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RemoteTable {
    /// `table`: reads: any of the four; writes: `"coils"` or `"holding_registers"`.
    pub table: ModbusTable,
    /// `address`: the first Modbus address (0-based, as on the wire), 0..=65535; required.
    pub address: u16,
    /// `count`: 1..=[`RemoteTable::max_count`], and `address + count` ≤ 65536; required.
    pub count: u16,
    /// `device`: the first device; required. Bits (P, M, K) for coils and discrete inputs,
    /// words (P, M, K, D) for registers.
    pub device: Address,
    /// Where `device` is: a bit index (word index × 16 + bit) for bit tables, a word index
    /// for register tables (as [`super::ModbusRange::first`]).
    pub first: u32,
    /// `swap_bytes`: registers only: the two bytes of each register are swapped; default
    /// false.
    pub swap_bytes: bool,
    /// `swap_words`: registers only, an even `count`: each pair of registers is swapped, for
    /// 32-bit values sent high word first (plcd keeps them low word first); default false.
    pub swap_words: bool,
}

impl RemoteTable {
    /// The most addresses one request reads or writes: FC 1/2 read 2000 bits, FC 3/4 read
    /// 125 registers; FC 15 writes 1968 coils, FC 16 writes 123 registers.
    pub fn max_count(table: ModbusTable, write: bool) -> u16 {
        match (table.is_bits(), write) {
            (true, false) => 2000,
            (false, false) => 125,
            (true, true) => 1968,
            (false, true) => 123,
        }
    }

    /// The Modbus addresses it covers.
    pub fn addresses(&self) -> Range<u32> {
        u32::from(self.address)..u32::from(self.address) + u32::from(self.count)
    }

    /// The device memory words it touches.
    pub fn words(&self) -> Range<u32> {
        if self.table.is_bits() {
            self.first / 16..(self.first + u32::from(self.count) - 1) / 16 + 1
        } else {
            self.first..self.first + u32::from(self.count)
        }
    }

    /// The device memory bits it touches, as bit indices (word × 16 + bit); a register is its
    /// word's 16 bits.
    pub fn bits(&self) -> Range<u32> {
        if self.table.is_bits() {
            self.first..self.first + u32::from(self.count)
        } else {
            self.first * 16..(self.first + u32::from(self.count)) * 16
        }
    }
}

/// One `[[remote.read]]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RemoteRead {
    pub table: RemoteTable,
    /// `period_ms`: its own poll period, [`RemoteDevice::PERIOD_MS`]; default the device's.
    pub period_ms: u32,
}

/// One `[[remote.write]]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RemoteWrite {
    pub table: RemoteTable,
    /// `write` and its period.
    pub on: WriteOn,
}

/// When a write table is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WriteOn {
    /// `write = "change"` (the default): after each output refresh that changed it, and
    /// again every `refresh_ms` (0..=3600000, default 1000; 0: only on change) so that a
    /// device that restarted gets its outputs back.
    Change { refresh_ms: u32 },
    /// `write = "period"`: every `period_ms` ([`RemoteDevice::PERIOD_MS`], default the
    /// device's), changed or not.
    Period { period_ms: u32 },
}

impl WriteOn {
    pub const REFRESH_MS: RangeInclusive<u32> = 0..=3_600_000;
    pub const DEFAULT_REFRESH_MS: u32 = 1000;
}

// ---- pass 1 ----

/// `transport`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawTransport {
    Tcp,
    Rtu,
}

/// One `[[remote]]` without its tables, with the keys of both transports; `validate` checks
/// which belong. `read` and `write` are declared only so that an unknown key's message lists
/// them.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRemote {
    pub name: Spanned<String>,
    pub transport: Spanned<RawTransport>,
    pub address: Option<Spanned<String>>,
    pub port: Option<Spanned<String>>,
    pub baud: Option<Spanned<i64>>,
    pub parity: Option<Spanned<Parity>>,
    pub data_bits: Option<Spanned<i64>>,
    pub stop_bits: Option<Spanned<i64>>,
    pub frame_gap_us: Option<Spanned<i64>>,
    pub unit_id: Option<Spanned<i64>>,
    pub period_ms: Option<Spanned<i64>>,
    pub timeout_ms: Option<Spanned<i64>>,
    #[serde(default)]
    pub on_loss: OnLoss,
    pub loss_after: Option<Spanned<i64>>,
    pub reconnect_ms: Option<Spanned<i64>>,
    pub reconnect_max_ms: Option<Spanned<i64>>,
    pub status: Option<Spanned<String>>,
    #[serde(rename = "read")]
    _read: Option<IgnoredAny>,
    #[serde(rename = "write")]
    _write: Option<IgnoredAny>,
}

/// One `[[remote.read]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRead {
    pub table: Spanned<String>,
    pub address: Spanned<i64>,
    pub count: Spanned<i64>,
    pub device: Spanned<String>,
    pub swap_bytes: Option<Spanned<bool>>,
    pub swap_words: Option<Spanned<bool>>,
    pub period_ms: Option<Spanned<i64>>,
}

/// `write` of a `[[remote.write]]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawWriteOn {
    #[default]
    Change,
    Period,
}

/// One `[[remote.write]]`: the keys every table has, and when it is written (`write`,
/// `refresh_ms`, `period_ms`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawWrite {
    pub table: Spanned<String>,
    pub address: Spanned<i64>,
    pub count: Spanned<i64>,
    pub device: Spanned<String>,
    pub swap_bytes: Option<Spanned<bool>>,
    pub swap_words: Option<Spanned<bool>>,
    pub write: Option<Spanned<RawWriteOn>>,
    pub refresh_ms: Option<Spanned<i64>>,
    pub period_ms: Option<Spanned<i64>>,
}

/// The keys read and write tables share.
struct TableKeys<'a> {
    table: &'a Spanned<String>,
    address: &'a Spanned<i64>,
    count: &'a Spanned<i64>,
    device: &'a Spanned<String>,
    swap_bytes: &'a Option<Spanned<bool>>,
    swap_words: &'a Option<Spanned<bool>>,
}

impl RawRead {
    fn keys(&self) -> TableKeys<'_> {
        TableKeys {
            table: &self.table,
            address: &self.address,
            count: &self.count,
            device: &self.device,
            swap_bytes: &self.swap_bytes,
            swap_words: &self.swap_words,
        }
    }
}

impl RawWrite {
    fn keys(&self) -> TableKeys<'_> {
        TableKeys {
            table: &self.table,
            address: &self.address,
            count: &self.count,
            device: &self.device,
            swap_bytes: &self.swap_bytes,
            swap_words: &self.swap_words,
        }
    }
}

/// One `[[remote]]` after pass 1 with the tables that follow it.
#[derive(Debug)]
pub(super) struct RawRemoteEntry {
    /// `None` when the entry had errors (reported); its tables are still checked.
    pub remote: Option<Located<RawRemote>>,
    /// Its header, and what it is called (`remote "rack1"`, `remote #2`).
    pub at: usize,
    pub subject: String,
    pub reads: Vec<Located<RawRead>>,
    pub writes: Vec<Located<RawWrite>>,
    /// Some table had errors (reported): it may have been what there is to poll.
    pub tables_failed: bool,
}

/// `[[remote]]` after pass 1.
#[derive(Debug, Default)]
pub(super) struct RawRemotes {
    pub entries: Vec<RawRemoteEntry>,
    /// Some entry or table had errors (already reported).
    pub failed: bool,
}

/// Pass 1 of `[[remote]]` and the `[[remote.read]]` and `[[remote.write]]` tables that
/// follow each.
pub(super) fn read(sink: &mut Sink, value: Option<Spanned<DeValue<'_>>>) -> RawRemotes {
    let mut doc = RawRemotes::default();
    let Some(mut value) = value else {
        return doc;
    };
    let span = value.span();
    let DeValue::Array(array) = value.get_mut() else {
        // `[[remote.read]]` before any `[[remote]]` makes `remote` a table; so does `[remote]`.
        sink.error(
            span.start,
            "`remote` must be an array of tables, written [[remote]]; [[remote.read]] and \
             [[remote.write]] follow the [[remote]] they belong to",
        );
        doc.failed = true;
        // What tables there are still have their own keys checked.
        if let DeValue::Table(mut table) = value.into_inner() {
            let _: Vec<Result<Located<RawRead>, _>> =
                entries(sink, table.remove("read"), "remote.read", |_| None);
            let _: Vec<Result<Located<RawWrite>, _>> =
                entries(sink, table.remove("write"), "remote.write", |_| None);
        }
        return doc;
    };
    // Each entry's tables are read apart from it, called after it.
    let tables: Vec<_> = array
        .iter_mut()
        .map(|entry| {
            let at = entry.span().start;
            match entry.get_mut() {
                DeValue::Table(table) => (at, table.remove("read"), table.remove("write")),
                _ => (at, None, None),
            }
        })
        .collect();
    let remotes = entries::<RawRemote>(sink, Some(value), "remote", |t| peek_str(t, "name"));
    for (index, (remote, (at, reads, writes))) in remotes.into_iter().zip(tables).enumerate() {
        let subject = match &remote {
            Ok(remote) => remote.ctx.subject(),
            Err(Some(name)) => format!("remote {name:?}"),
            Err(None) => format!("remote #{}", index + 1),
        };
        let mut entry = RawRemoteEntry {
            at,
            remote: remote.ok(),
            reads: Vec::new(),
            writes: Vec::new(),
            tables_failed: false,
            subject,
        };
        doc.failed |= entry.remote.is_none();
        let label = format!("{} read", entry.subject);
        for read in entries_as(sink, reads, "remote.read", &label, |_| None) {
            match read {
                Ok(read) => entry.reads.push(read),
                Err(_) => entry.tables_failed = true,
            }
        }
        let label = format!("{} write", entry.subject);
        for write in entries_as(sink, writes, "remote.write", &label, |_| None) {
            match write {
                Ok(write) => entry.writes.push(write),
                Err(_) => entry.tables_failed = true,
            }
        }
        doc.failed |= entry.tables_failed;
        doc.entries.push(entry);
    }
    doc
}

// ---- pass 2 ----

/// What the remotes are checked against in other sections.
#[derive(Debug, Default)]
pub(super) struct Neighbours {
    /// The P bits of `[[io.input]]` and `[[io.output]]`, which the local backend owns, and
    /// the contacts io tasks start on.
    pub io_bits: Vec<Owner>,
    /// `[modbus.rtu] port` and where it is.
    pub rtu_server: Option<(String, usize)>,
}

/// Something that writes device bits remote reads may not write too.
#[derive(Debug, Clone)]
pub(super) struct Owner {
    /// Where the key that says which bits is.
    at: usize,
    bits: Range<u32>,
    what: OwnerKind,
}

#[derive(Debug, Clone)]
enum OwnerKind {
    /// A `[[remote.read]]`: its subject and its devices (`P0100-P010F`).
    Read { subject: String, devices: String },
    /// A remote's `status`: the remote's subject and the bit.
    Status { subject: String, bit: Address },
    /// An `[[io.input]]` or `[[io.output]]`: its subject and its P bit.
    Io { subject: String, bit: Address },
    /// The contact an io task starts on: the task's subject and the P bit. Its edges come
    /// from the field's line, so no remote may write it.
    Contact { subject: String, bit: Address },
}

impl Owner {
    /// How a later owner's message names this one.
    fn named(&self) -> String {
        match &self.what {
            OwnerKind::Read { subject, devices } => {
                format!("the devices {subject} writes ({devices})")
            }
            OwnerKind::Status { subject, bit } => format!("the status bit of {subject} ({bit})"),
            OwnerKind::Io { subject, .. } => {
                format!("{subject}, which the local I/O backend owns")
            }
            OwnerKind::Contact { subject, bit } => {
                format!("the contact {subject} starts on ({bit}), whose edges come from the field")
            }
        }
    }

    /// The message at this owner when it overlaps an earlier one.
    fn overlaps(&self, earlier: &Owner) -> String {
        let other = earlier.named();
        match &self.what {
            OwnerKind::Read { subject, devices } => {
                format!("{subject}: device {devices} overlaps {other}")
            }
            OwnerKind::Status { subject, bit } => {
                format!("{subject}: status {bit} overlaps {other}")
            }
            OwnerKind::Io { subject, bit } | OwnerKind::Contact { subject, bit } => {
                format!("{subject}: device {bit} overlaps {other}")
            }
        }
    }
}

/// The P bits of the `[[io.input]]` and `[[io.output]]` entries that deserialized (those
/// that are not P bits are reported by `io`).
pub(super) fn io_bits(inputs: &[Located<RawInput>], outputs: &[Located<RawOutput>]) -> Vec<Owner> {
    let inputs = inputs.iter().map(|e| (&e.ctx, &e.value.device));
    let outputs = outputs.iter().map(|e| (&e.ctx, &e.value.device));
    inputs
        .chain(outputs)
        .filter_map(|(ctx, device)| {
            let bit = Address::parse(device.get_ref()).ok()?;
            let index = bit_index(&bit).filter(|_| bit.area == Area::P)?;
            Some(Owner {
                at: device.span().start,
                bits: index..index + 1,
                what: OwnerKind::Io { subject: ctx.subject(), bit },
            })
        })
        .collect()
}

/// The contacts of the `[[task]]` entries of kind io that deserialized.
pub(super) fn contact_bits(tasks: &[Located<super::task::RawTask>]) -> Vec<Owner> {
    tasks
        .iter()
        .filter_map(|task| {
            let contact = task.value.contact.as_ref()?;
            let bit = Address::parse(contact.get_ref()).ok()?;
            let index = bit_index(&bit).filter(|_| bit.area == Area::P)?;
            Some(Owner {
                at: contact.span().start,
                bits: index..index + 1,
                what: OwnerKind::Contact { subject: task.ctx.subject(), bit },
            })
        })
        .collect()
}

/// Where a P, M or K bit is, as a bit index of device memory (word × 16 + bit).
fn bit_index(address: &Address) -> Option<u32> {
    if !matches!(address.area, Area::P | Area::M | Area::K) || address.bit.is_none() {
        return None;
    }
    let bit = address.as_bit().ok()?;
    Some(u32::from(bit.word) * 16 + bit.mask.trailing_zeros())
}

/// A remote that passed its own checks, with what the checks across remotes report.
struct Checked {
    device: RemoteDevice,
    subject: String,
    /// Where its `address` or `port` is.
    endpoint_at: usize,
    /// Where its `unit_id` is, else its `address` or `port`.
    unit_at: usize,
}

/// Pass 2 of `[[remote]]`: `None` if anything is wrong (reported in `sink`).
pub(super) fn validate(
    sink: &mut Sink,
    raw: RawRemotes,
    neighbours: &Neighbours,
) -> Option<Vec<RemoteDevice>> {
    let mut ok = !raw.failed;
    if let Some(extra) = raw.entries.get(RemoteDevice::MAX_DEVICES) {
        let message = format!(
            "{}: more than {} remotes: plcd polls at most {} [[remote]]",
            extra.subject,
            RemoteDevice::MAX_DEVICES,
            RemoteDevice::MAX_DEVICES
        );
        sink.error(extra.at, message);
        ok = false;
    }
    let mut names: HashMap<String, usize> = HashMap::new();
    let mut checked: Vec<Checked> = Vec::new();
    let mut owners: Vec<Owner> = neighbours.io_bits.clone();
    for entry in raw.entries {
        let remote = entry.remote.as_ref();
        ok &= remote.is_none_or(|r| unique_name(sink, r, &mut names));
        // A remote with errors still has its tables checked, with the default period.
        let period_ms = remote
            .and_then(|r| r.value.period_ms.as_ref())
            .and_then(|p| int_quiet(p, RemoteDevice::PERIOD_MS))
            .unwrap_or(RemoteDevice::DEFAULT_PERIOD_MS);
        // A table with errors that still resolved to device memory takes part in the checks
        // across tables.
        let mut reads = Vec::new();
        for read in &entry.reads {
            if let Some(table) = read_table(sink, read, period_ms, &mut ok) {
                owners.push(Owner {
                    at: read.value.device.span().start,
                    bits: table.table.bits(),
                    what: OwnerKind::Read {
                        subject: read.ctx.subject(),
                        devices: devices(&table.table),
                    },
                });
                reads.push(table);
            }
        }
        let mut writes: Vec<(RemoteWrite, usize, String)> = Vec::new();
        for write in &entry.writes {
            if let Some(table) = write_table(sink, write, period_ms, &mut ok) {
                writes.push((table, write.value.address.span().start, write.ctx.subject()))
            }
        }
        ok &= writes_do_not_overlap(sink, &writes);
        let Some(remote) = entry.remote else {
            continue;
        };
        let status = match &remote.value.status {
            Some(raw) => status_bit(sink, &remote.ctx, raw).map(|status| {
                let index = bit_index(&status.device).expect("checked: a P, M or K bit");
                owners.push(Owner {
                    at: raw.span().start,
                    bits: index..index + 1,
                    what: OwnerKind::Status { subject: remote.ctx.subject(), bit: status.device },
                });
                Some(status)
            }),
            None => Some(None),
        };
        let writes = writes.into_iter().map(|(w, ..)| w).collect();
        let tables = Tables {
            reads,
            writes,
            none_given: entry.reads.is_empty() && entry.writes.is_empty() && !entry.tables_failed,
        };
        match device(sink, &remote, tables, status) {
            Some(device) => {
                let endpoint_at = match device.transport {
                    RemoteTransport::Tcp { .. } => remote.value.address.as_ref(),
                    RemoteTransport::Rtu(_) => remote.value.port.as_ref(),
                }
                .map_or(remote.span.start, |v| v.span().start);
                let unit_at = remote.value.unit_id.as_ref().map_or(endpoint_at, |u| u.span().start);
                let subject = remote.ctx.subject();
                checked.push(Checked { device, subject, endpoint_at, unit_at });
            }
            None => ok = false,
        }
    }
    ok &= endpoints_are_consistent(sink, &checked, neighbours.rtu_server.as_ref());
    ok &= owners_do_not_overlap(sink, owners);
    ok.then(|| checked.into_iter().map(|c| c.device).collect())
}

/// `value` within `range`, without a report (the key's own check reports it).
fn int_quiet(value: &Spanned<i64>, range: RangeInclusive<u32>) -> Option<u32> {
    u32::try_from(*value.get_ref()).ok().filter(|v| range.contains(v))
}

/// `name`: 1..=32 letters, digits, `_` and `-`, unique among the remotes.
fn unique_name(
    sink: &mut Sink,
    remote: &Located<RawRemote>,
    names: &mut HashMap<String, usize>,
) -> bool {
    let (ctx, name) = (&remote.ctx, &remote.value.name);
    let text = name.get_ref();
    let at = name.span().start;
    let well_formed = (1..=RemoteDevice::NAME_CHARS).contains(&text.chars().count())
        && text.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if !well_formed {
        let message = format!(
            "{} {text:?} must be 1 to {} letters, digits, `_` or `-`",
            ctx.key("name"),
            RemoteDevice::NAME_CHARS
        );
        sink.error(at, message);
        return false;
    }
    if let Some(first) = names.get(text) {
        let (line, _) = crate::diag::Diagnostic::line_col(sink.text, *first);
        let message = format!(
            "{}: name {text:?} is already used by the remote at line {line}",
            ctx.subject()
        );
        sink.error(at, message);
        return false;
    }
    names.insert(text.clone(), remote.span.start);
    true
}

/// A remote's checked tables.
struct Tables {
    reads: Vec<RemoteRead>,
    writes: Vec<RemoteWrite>,
    /// The file gives it no table at all (not even one with errors).
    none_given: bool,
}

/// A remote's own keys, with its checked tables and status bit (`None`: reported).
fn device(
    sink: &mut Sink,
    remote: &Located<RawRemote>,
    tables: Tables,
    status: Option<Option<RemoteStatusBit>>,
) -> Option<RemoteDevice> {
    let Located { span, ctx, value: raw } = remote;
    let mut ok = true;
    let serial = RawSerial {
        port: raw.port.clone(),
        baud: raw.baud.clone(),
        parity: raw.parity.clone(),
        data_bits: raw.data_bits.clone(),
        stop_bits: raw.stop_bits.clone(),
        frame_gap_us: raw.frame_gap_us.clone(),
    };
    let transport = match *raw.transport.get_ref() {
        RawTransport::Tcp => {
            for (key, at) in serial.given() {
                let message = format!("{}: `{key}` is a key of transport \"rtu\"", ctx.subject());
                sink.error(at, message);
                ok = false;
            }
            match &raw.address {
                Some(address) => match tcp_address(address.get_ref()) {
                    Ok(address) => Some(RemoteTransport::Tcp { address }),
                    Err(why) => {
                        let message = format!(
                            "{} {:?} {why} (\"10.0.0.5:502\", \"plc1.local:502\", \
                             \"[fd00::5]:502\")",
                            ctx.key("address"),
                            address.get_ref()
                        );
                        sink.error(address.span().start, message);
                        None
                    }
                },
                None => {
                    let message = format!(
                        "{}: transport \"tcp\" needs `address`, the device's \"host:port\"",
                        ctx.subject()
                    );
                    sink.error(span.start, message);
                    None
                }
            }
        }
        RawTransport::Rtu => {
            if let Some(address) = &raw.address {
                let message = format!("{}: `address` is a key of transport \"tcp\"", ctx.subject());
                sink.error(address.span().start, message);
                ok = false;
            }
            serial::line(sink, ctx, &serial, |sink| {
                let message = format!(
                    "{}: transport \"rtu\" needs `port`, the serial device (\"/dev/ttyUSB0\")",
                    ctx.subject()
                );
                sink.error(span.start, message);
            })
            .map(RemoteTransport::Rtu)
        }
    };
    let units = match raw.transport.get_ref() {
        RawTransport::Tcp => 0..=255,
        RawTransport::Rtu => widen(RemoteDevice::RTU_UNIT_ID),
    };
    let unit_id = int_or(sink, ctx, "unit_id", raw.unit_id.clone(), units, 1);
    let mut ms = |key: &str, value: &Option<Spanned<i64>>, range: RangeInclusive<u32>, default| {
        int_or(sink, ctx, key, value.clone(), widen(range), default)
    };
    let period_ms =
        ms("period_ms", &raw.period_ms, RemoteDevice::PERIOD_MS, RemoteDevice::DEFAULT_PERIOD_MS);
    let timeout_ms = ms(
        "timeout_ms",
        &raw.timeout_ms,
        RemoteDevice::TIMEOUT_MS,
        RemoteDevice::DEFAULT_TIMEOUT_MS,
    );
    let loss_after = ms("loss_after", &raw.loss_after, RemoteDevice::LOSS_AFTER, 1);
    let reconnect_ms = ms(
        "reconnect_ms",
        &raw.reconnect_ms,
        RemoteDevice::RECONNECT_MS,
        RemoteDevice::DEFAULT_RECONNECT_MS,
    );
    // The longest wait is at least the first; by default 5000 ms, or the first if longer.
    let shortest = reconnect_ms.unwrap_or(*RemoteDevice::RECONNECT_MS.start());
    let reconnect_max_ms = ms(
        "reconnect_max_ms",
        &raw.reconnect_max_ms,
        shortest..=RemoteDevice::RECONNECT_MAX_MS,
        RemoteDevice::DEFAULT_RECONNECT_MAX_MS.max(shortest),
    );
    if tables.none_given {
        let message = format!(
            "{}: nothing to poll: a remote needs a [[remote.read]] or a [[remote.write]] after \
             it",
            ctx.subject()
        );
        sink.error(span.start, message);
        ok = false;
    }
    let device = RemoteDevice {
        name: raw.name.get_ref().clone(),
        transport: transport?,
        unit_id: unit_id?,
        period_ms: period_ms?,
        timeout_ms: timeout_ms?,
        on_loss: raw.on_loss,
        loss_after: loss_after?,
        reconnect_ms: reconnect_ms?,
        reconnect_max_ms: reconnect_max_ms?,
        status: status?,
        reads: tables.reads,
        writes: tables.writes,
    };
    ok.then_some(device)
}

/// A TCP `address`, trimmed: `host:port`, the host a name, an IPv4 address or `[IPv6]`, the
/// port 1..=65535. The name is resolved when plcd connects.
fn tcp_address(text: &str) -> Result<String, &'static str> {
    let address = text.trim();
    let (host, port) = address.rsplit_once(':').ok_or("is not \"host:port\"")?;
    let port_ok = !port.is_empty()
        && port.chars().all(|c| c.is_ascii_digit())
        && port.parse::<u32>().is_ok_and(|p| (1..=65_535).contains(&p));
    if !port_ok {
        return Err("needs a port 1..=65535 after the last `:`");
    }
    let host_ok = if let Some(v6) = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        v6.parse::<Ipv6Addr>().is_ok()
    } else if host.chars().all(|c| c.is_ascii_digit() || c == '.') {
        // All digits and dots is meant as an IPv4 address, not a name.
        host.parse::<Ipv4Addr>().is_ok()
    } else {
        // A host name: labels of letters, digits, `-` and `_`, separated by dots.
        host.split('.').all(|label| {
            !label.is_empty()
                && !label.starts_with('-')
                && label.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        })
    };
    if !host_ok {
        return Err("has no host name, IPv4 address or [IPv6] address before the port");
    }
    Ok(address.to_string())
}

/// `status`: a P, M or K bit, which remote I/O may write.
fn status_bit(sink: &mut Sink, ctx: &Ctx, status: &Spanned<String>) -> Option<RemoteStatusBit> {
    let at = status.span().start;
    match Address::parse(status.get_ref()) {
        Ok(device) if device.writable_by(Writer::RemoteInput) && bit_index(&device).is_some() => {
            let bit = device.as_bit().ok()?;
            Some(RemoteStatusBit { device, bit })
        }
        Ok(_) => {
            let message = format!(
                "{} {:?} is not a P, M or K bit (P0000, M0100, K0010 …)",
                ctx.key("status"),
                status.get_ref()
            );
            sink.error(at, message);
            None
        }
        Err(e) => {
            sink.error(at, format!("{}: {e}", ctx.key("status")));
            None
        }
    }
}

/// A `[[remote.read]]`: `None` if it did not resolve to device memory. Every error clears
/// `ok`.
fn read_table(
    sink: &mut Sink,
    read: &Located<RawRead>,
    default_period: u32,
    ok: &mut bool,
) -> Option<RemoteRead> {
    let Located { ctx, value: raw, .. } = read;
    let table = table(sink, ctx, raw.keys(), false, ok);
    *ok &= table.is_some();
    let period_ms = int_or(
        sink,
        ctx,
        "period_ms",
        raw.period_ms.clone(),
        widen(RemoteDevice::PERIOD_MS),
        default_period,
    );
    *ok &= period_ms.is_some();
    Some(RemoteRead { table: table?, period_ms: period_ms.unwrap_or(default_period) })
}

/// A `[[remote.write]]`: `None` if it did not resolve to device memory. Every error clears
/// `ok`.
fn write_table(
    sink: &mut Sink,
    write: &Located<RawWrite>,
    default_period: u32,
    ok: &mut bool,
) -> Option<RemoteWrite> {
    let Located { ctx, value: raw, .. } = write;
    let table = table(sink, ctx, raw.keys(), true, ok);
    *ok &= table.is_some();
    // The key the other way of writing has, if given.
    let (on, stray) = match raw.write.as_ref().map_or(RawWriteOn::Change, |w| *w.get_ref()) {
        RawWriteOn::Change => {
            let refresh_ms = int_or(
                sink,
                ctx,
                "refresh_ms",
                raw.refresh_ms.clone(),
                widen(WriteOn::REFRESH_MS),
                WriteOn::DEFAULT_REFRESH_MS,
            );
            *ok &= refresh_ms.is_some();
            let refresh_ms = refresh_ms.unwrap_or(WriteOn::DEFAULT_REFRESH_MS);
            (
                WriteOn::Change { refresh_ms },
                raw.period_ms.as_ref().map(|p| ("period_ms", p, "period")),
            )
        }
        RawWriteOn::Period => {
            let period_ms = int_or(
                sink,
                ctx,
                "period_ms",
                raw.period_ms.clone(),
                widen(RemoteDevice::PERIOD_MS),
                default_period,
            );
            *ok &= period_ms.is_some();
            let period_ms = period_ms.unwrap_or(default_period);
            (
                WriteOn::Period { period_ms },
                raw.refresh_ms.as_ref().map(|r| ("refresh_ms", r, "change")),
            )
        }
    };
    if let Some((key, value, write)) = stray {
        let message = format!("{}: {key} is only for write = \"{write}\"", ctx.subject());
        sink.error(value.span().start, message);
        *ok = false;
    }
    Some(RemoteWrite { table: table?, on })
}

/// The keys every table has, resolved to device memory: `None` if they do not resolve; an
/// error that leaves the table resolved (a swap key) clears `ok`.
fn table(
    sink: &mut Sink,
    ctx: &Ctx,
    raw: TableKeys<'_>,
    write: bool,
    ok: &mut bool,
) -> Option<RemoteTable> {
    let name = raw.table.get_ref();
    let table = match ModbusTable::ALL.into_iter().find(|t| t.key() == name) {
        Some(table) if write && !table.may_write() => {
            let message = format!(
                "{} {name:?}: {} are read-only in Modbus; a write table is \"coils\" or \
                 \"holding_registers\"",
                ctx.key("table"),
                table.key().replace('_', " ")
            );
            sink.error(raw.table.span().start, message);
            None
        }
        Some(table) => Some(table),
        None => {
            let expected = if write {
                "\"coils\" or \"holding_registers\""
            } else {
                "\"coils\", \"discrete_inputs\", \"holding_registers\" or \"input_registers\""
            };
            let message =
                format!("{} {name:?} is not a Modbus table: expected {expected}", ctx.key("table"));
            sink.error(raw.table.span().start, message);
            None
        }
    };
    let address: Option<u16> = int(sink, ctx, "address", raw.address, 0..=65_535);
    let device = match Address::parse(raw.device.get_ref()) {
        Ok(device) => Some(device),
        Err(e) => {
            sink.error(raw.device.span().start, format!("{}: {e}", ctx.key("device")));
            None
        }
    };
    // The rest depends on the table.
    let table = table?;
    let max = RemoteTable::max_count(table, write);
    let count: Option<u16> = int(sink, ctx, "count", raw.count, 1..=i64::from(max));
    for (key, swap) in [("swap_bytes", raw.swap_bytes), ("swap_words", raw.swap_words)] {
        if let Some(swap) = swap.as_ref().filter(|s| *s.get_ref() && table.is_bits()) {
            let message = format!(
                "{}: {key} is only for register tables: {} are bits",
                ctx.subject(),
                table.key().replace('_', " ")
            );
            sink.error(swap.span().start, message);
            *ok = false;
        }
    }
    let swap_bytes = raw.swap_bytes.as_ref().is_some_and(|s| *s.get_ref());
    let swap_words = raw.swap_words.as_ref().is_some_and(|s| *s.get_ref());
    if let (Some(swap), Some(count)) = (raw.swap_words, count) {
        if *swap.get_ref() && !table.is_bits() && count % 2 == 1 {
            let message = format!(
                "{}: swap_words swaps pairs of registers: count {count} is odd",
                ctx.subject()
            );
            sink.error(swap.span().start, message);
            *ok = false;
        }
    }
    // Remote I/O writes what a read's devices may be; a write's are the same kinds.
    let device = device?;
    let fits = device.writable_by(Writer::RemoteInput)
        && if table.is_bits() { bit_index(&device).is_some() } else { device.bit.is_none() };
    if !fits {
        let name = table.key().replace('_', " ");
        let what = if table.is_bits() {
            "P, M or K bits (as M0100)"
        } else {
            "P, M, K or D words (as D00100)"
        };
        let message = format!(
            "{}: {device} cannot start a table of {name}: {name} map {what}",
            ctx.key("device")
        );
        sink.error(raw.device.span().start, message);
        return None;
    }
    let (address, count) = (address?, count?);
    // The first bit or word, and the end of the area it is in.
    let area_words = device.area.base() + device.area.word_count();
    let (first, area_end) = match bit_index(&device) {
        Some(bit) if table.is_bits() => (bit, area_words * 16),
        _ => (u32::from(device.as_word().ok()?.0), area_words),
    };
    let count_at = raw.count.span().start;
    if u32::from(address) + u32::from(count) > 65_536 {
        let message = format!(
            "{} {count} from address {address} runs past the last Modbus address 65535",
            ctx.key("count")
        );
        sink.error(count_at, message);
        return None;
    }
    if first + u32::from(count) > area_end {
        let message = format!(
            "{} {count} from {device} runs past the end of its area ({}): at most {}",
            ctx.key("count"),
            device.area.range_text(),
            area_end - first
        );
        sink.error(count_at, message);
        return None;
    }
    Some(RemoteTable { table, address, count, device, first, swap_bytes, swap_words })
}

/// The devices of a table as a message names them: `P0100-P010F`, `D00010`.
fn devices(table: &RemoteTable) -> String {
    let first = table.device;
    let last = u32::from(table.count) - 1;
    let last = match first.bit {
        Some(bit) if table.table.is_bits() => {
            let index = first.number * 16 + u32::from(bit) + last;
            Address { number: index / 16, bit: Some((index % 16) as u8), ..first }
        }
        _ => Address { number: first.number + last, ..first },
    };
    if last == first {
        first.to_string()
    } else {
        format!("{first}-{last}")
    }
}

/// Two write tables of one remote do not write the same Modbus addresses of one table.
fn writes_do_not_overlap(sink: &mut Sink, writes: &[(RemoteWrite, usize, String)]) -> bool {
    let mut ok = true;
    for (i, (later, at, subject)) in writes.iter().enumerate() {
        for (earlier, _, other) in &writes[..i] {
            let (a, b) = (later.table.addresses(), earlier.table.addresses());
            if later.table.table == earlier.table.table && a.start < b.end && b.start < a.end {
                let message = format!(
                    "{subject}: {} {}..={} overlap those of {other} ({}..={})",
                    later.table.table.key().replace('_', " "),
                    a.start,
                    a.end - 1,
                    b.start,
                    b.end - 1
                );
                sink.error(*at, message);
                ok = false;
            }
        }
    }
    ok
}

/// Device bits have one writer among remote reads, status bits, the local I/O lines and io
/// tasks' contacts: at
/// each overlap the later in the file is reported, naming the earlier.
fn owners_do_not_overlap(sink: &mut Sink, mut owners: Vec<Owner>) -> bool {
    owners.sort_by_key(|o| o.at);
    let mut ok = true;
    for (i, later) in owners.iter().enumerate() {
        for earlier in &owners[..i] {
            let io = |o: &Owner| matches!(o.what, OwnerKind::Io { .. } | OwnerKind::Contact { .. });
            // Lines and contacts against each other are `io`'s and `task`'s to report (a
            // contact is usually an input line).
            if io(later) && io(earlier) {
                continue;
            }
            if later.bits.start < earlier.bits.end && earlier.bits.start < later.bits.end {
                sink.error(later.at, later.overlaps(earlier));
                ok = false;
            }
        }
    }
    ok
}

/// Across remotes: one unit per TCP address or RTU port, one set of line settings per port,
/// and no port both polled and served by `[modbus.rtu]`.
fn endpoints_are_consistent(
    sink: &mut Sink,
    remotes: &[Checked],
    rtu_server: Option<&(String, usize)>,
) -> bool {
    let mut ok = true;
    let mut lines: HashMap<&PathBuf, (&SerialLine, &str)> = HashMap::new();
    for (i, later) in remotes.iter().enumerate() {
        let device = &later.device;
        let same_endpoint = |other: &Checked| match (&device.transport, &other.device.transport) {
            (RemoteTransport::Tcp { address: a }, RemoteTransport::Tcp { address: b }) => a == b,
            (RemoteTransport::Rtu(a), RemoteTransport::Rtu(b)) => a.port == b.port,
            _ => false,
        };
        if let Some(first) = remotes[..i]
            .iter()
            .find(|other| same_endpoint(other) && other.device.unit_id == device.unit_id)
        {
            let message = format!(
                "{}: unit {} of {} is already polled by {}",
                later.subject,
                device.unit_id,
                device.transport.describe(),
                first.subject
            );
            sink.error(later.unit_at, message);
            ok = false;
        }
        let RemoteTransport::Rtu(line) = &device.transport else {
            continue;
        };
        match lines.get(&line.port) {
            Some((first, subject)) if first.conflicts_with(line) => {
                let message = format!(
                    "{}: port {} is shared with {subject}, whose settings differ ({} here, {} \
                     there): devices on one port share its settings",
                    later.subject,
                    line.port.display(),
                    line.describe_settings(),
                    first.describe_settings()
                );
                sink.error(later.endpoint_at, message);
                ok = false;
            }
            Some(_) => {}
            None => {
                lines.insert(&line.port, (line, &later.subject));
            }
        }
        if let Some((server, server_at)) =
            rtu_server.filter(|(p, _)| line.port.as_path() == Path::new(p))
        {
            let why = "a port either serves (`[modbus.rtu]`) or polls (`[[remote]]`)";
            let (at, message) = if *server_at > later.endpoint_at {
                (
                    *server_at,
                    format!("modbus.rtu.port {server} is polled by {}: {why}", later.subject),
                )
            } else {
                let port = line.port.display();
                (
                    later.endpoint_at,
                    format!("{}: port {port} is served by [modbus.rtu]: {why}", later.subject),
                )
            };
            sink.error(at, message);
            ok = false;
        }
    }
    ok
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::super::tests::{scan_config as config, scan_errors as errors};

    /// A TCP remote named `name` on 10.0.0.5:502, with `extra` keys and one coil written from
    /// M1000, to make it valid (write tables may share their devices).
    fn tcp(name: &str, extra: &str) -> String {
        format!(
            "[[remote]]\nname = \"{name}\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
             {extra}\n[[remote.write]]\ntable = \"coils\"\naddress = 0\ncount = 1\n\
             device = \"M1000\"\n"
        )
    }

    fn only_remote(text: &str) -> RemoteDevice {
        let remotes = config(text).remotes;
        assert_eq!(remotes.len(), 1, "{remotes:#?}");
        remotes[0].clone()
    }

    fn addr(text: &str) -> Address {
        Address::parse(text).unwrap()
    }

    /// The bit index of device memory of a P, M or K bit.
    fn bit(text: &str) -> u32 {
        let b = addr(text).as_bit().unwrap();
        u32::from(b.word) * 16 + b.mask.trailing_zeros()
    }

    fn word(text: &str) -> u32 {
        u32::from(addr(text).as_word().unwrap().0)
    }

    #[test]
    fn without_remotes_there_are_none_and_a_remote_takes_the_documented_defaults() {
        assert!(config("").remotes.is_empty());
        let remote = only_remote(
            "[[remote]]\nname = \"rack1\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
             [[remote.read]]\ntable = \"discrete_inputs\"\naddress = 0\ncount = 16\n\
             device = \"P0100\"\n\
             [[remote.write]]\ntable = \"coils\"\naddress = 0\ncount = 16\ndevice = \"P0140\"\n",
        );
        assert_eq!(
            remote,
            RemoteDevice {
                name: "rack1".into(),
                transport: RemoteTransport::Tcp { address: "10.0.0.5:502".into() },
                unit_id: 1,
                period_ms: 100,
                timeout_ms: 100,
                on_loss: OnLoss::Clear,
                loss_after: 1,
                reconnect_ms: 100,
                reconnect_max_ms: 5000,
                status: None,
                reads: vec![RemoteRead {
                    table: RemoteTable {
                        table: ModbusTable::DiscreteInputs,
                        address: 0,
                        count: 16,
                        device: addr("P0100"),
                        first: bit("P0100"),
                        swap_bytes: false,
                        swap_words: false,
                    },
                    period_ms: 100,
                }],
                writes: vec![RemoteWrite {
                    table: RemoteTable {
                        table: ModbusTable::Coils,
                        address: 0,
                        count: 16,
                        device: addr("P0140"),
                        first: bit("P0140"),
                        swap_bytes: false,
                        swap_words: false,
                    },
                    on: WriteOn::Change { refresh_ms: 1000 },
                }],
            }
        );
        // Over RTU the line takes the Modbus defaults.
        let rtu = only_remote(
            "[[remote]]\nname = \"bus-1\"\ntransport = \"rtu\"\nport = \"/dev/ttyUSB0\"\n\
             [[remote.write]]\ntable = \"holding_registers\"\naddress = 7\ncount = 2\n\
             device = \"D00010\"\n",
        );
        assert_eq!(rtu.transport, RemoteTransport::Rtu(SerialLine::new("/dev/ttyUSB0")));
        assert_eq!(rtu.unit_id, 1);
        assert!(rtu.reads.is_empty());
        assert_eq!(rtu.writes[0].table.first, word("D00010"));
    }

    #[test]
    fn every_key_resolves() {
        let remotes = config(
            "[[remote]]\nname = \"Rack_2-b\"\ntransport = \"tcp\"\naddress = \" plc2.local:1502 \"\n\
             unit_id = 0\nperiod_ms = 10\ntimeout_ms = 250\non_loss = \"hold\"\nloss_after = 3\n\
             reconnect_ms = 50\nreconnect_max_ms = 60000\nstatus = \"M0100\"\n\
             [[remote.read]]\ntable = \"input_registers\"\naddress = 100\ncount = 4\n\
             device = \"D00100\"\nswap_bytes = true\nswap_words = true\nperiod_ms = 1000\n\
             [[remote.read]]\ntable = \"coils\"\naddress = 65535\ncount = 1\ndevice = \"k2003\"\n\
             [[remote.read]]\ntable = \"holding_registers\"\naddress = 0\ncount = 125\n\
             device = \"D01000\"\n\
             [[remote.write]]\ntable = \"holding_registers\"\naddress = 10\ncount = 2\n\
             device = \"P010\"\nwrite = \"period\"\nperiod_ms = 20\nswap_words = true\n\
             [[remote.write]]\ntable = \"coils\"\naddress = 0\ncount = 1968\ndevice = \"M0000\"\n\
             write = \"change\"\nrefresh_ms = 0\n\
             [[remote.write]]\ntable = \"holding_registers\"\naddress = 12\ncount = 1\n\
             device = \"D00000\"\nwrite = \"period\"\n\
             [[remote]]\nname = \"bus\"\ntransport = \"rtu\"\nport = \"/dev/ttyS1\"\nbaud = 9600\n\
             parity = \"none\"\ndata_bits = 8\nstop_bits = 2\nframe_gap_us = 4000\nunit_id = 247\n\
             [[remote.read]]\ntable = \"discrete_inputs\"\naddress = 0\ncount = 2000\n\
             device = \"K0000\"\n",
        )
        .remotes;
        let [tcp, rtu] = &remotes[..] else { panic!("{remotes:#?}") };
        assert_eq!(tcp.name, "Rack_2-b");
        assert_eq!(tcp.transport, RemoteTransport::Tcp { address: "plc2.local:1502".into() });
        assert_eq!((tcp.unit_id, tcp.period_ms, tcp.timeout_ms), (0, 10, 250));
        assert_eq!((tcp.on_loss, tcp.loss_after), (OnLoss::Hold, 3));
        assert_eq!((tcp.reconnect_ms, tcp.reconnect_max_ms), (50, 60_000));
        let status = tcp.status.unwrap();
        assert_eq!(status.device, addr("M0100"));
        assert_eq!(status.bit, addr("M0100").as_bit().unwrap());
        let [ir, coil, hr] = &tcp.reads[..] else { panic!() };
        assert_eq!(
            (ir.table.table, ir.table.address, ir.table.count),
            (ModbusTable::InputRegisters, 100, 4)
        );
        assert_eq!(
            (ir.table.first, ir.table.swap_bytes, ir.table.swap_words),
            (word("D00100"), true, true)
        );
        assert_eq!(ir.period_ms, 1000);
        assert_eq!(
            (coil.table.address, coil.table.device, coil.table.first),
            (65535, addr("K2003"), bit("K2003"))
        );
        assert_eq!(coil.period_ms, 10, "the remote's period");
        assert_eq!((hr.table.first, hr.table.count), (word("D01000"), 125));
        assert_eq!(hr.table.bits(), word("D01000") * 16..(word("D01000") + 125) * 16);
        let [period, change, default_period] = &tcp.writes[..] else { panic!() };
        assert_eq!(period.on, WriteOn::Period { period_ms: 20 });
        assert_eq!((period.table.first, period.table.swap_words), (word("P010"), true));
        assert_eq!(change.on, WriteOn::Change { refresh_ms: 0 });
        assert_eq!(change.table.count, 1968);
        assert_eq!(default_period.on, WriteOn::Period { period_ms: 10 });
        assert_eq!(tcp.shortest_period_ms(), 10);
        assert_eq!(
            rtu.transport,
            RemoteTransport::Rtu(SerialLine {
                port: "/dev/ttyS1".into(),
                baud: 9600,
                parity: Parity::None,
                data_bits: 8,
                stop_bits: 2,
                frame_gap_us: Some(4000),
            })
        );
        assert_eq!(rtu.unit_id, 247);
        assert_eq!(rtu.reads[0].table.count, 2000);
        assert_eq!(rtu.reads[0].table.words(), word("K000")..word("K000") + 125);
    }

    #[test]
    fn the_longest_wait_defaults_to_at_least_the_first() {
        let remote = only_remote(&tcp("a", "reconnect_ms = 10000"));
        assert_eq!((remote.reconnect_ms, remote.reconnect_max_ms), (10_000, 10_000));
        let remote = only_remote(&tcp("a", "reconnect_ms = 10\nreconnect_max_ms = 10"));
        assert_eq!((remote.reconnect_ms, remote.reconnect_max_ms), (10, 10));
        assert_eq!(
            errors(&tcp("a", "reconnect_ms = 200\nreconnect_max_ms = 199")),
            ["6:20: remote \"a\": reconnect_max_ms 199 out of range 200..=60000"]
        );
    }

    #[test]
    fn remote_keys_are_range_checked_all_at_once() {
        assert_eq!(
            errors(
                "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 unit_id = 256\nperiod_ms = 0\ntimeout_ms = 60001\nloss_after = 101\n\
                 reconnect_ms = 9\nreconnect_max_ms = 60001\non_loss = \"keep\"\nspeed = 1\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n\
                 [[remote]]\nname = \"b\"\ntransport = \"tcp\"\naddress = \"10.0.0.6:502\"\n\
                 period_ms = 3600001\ntimeout_ms = 0\nloss_after = 0\nreconnect_ms = 60001\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0001\"\n"
            ),
            [
                "11:11: remote \"a\": on_loss: unknown variant `keep`, expected `clear` or `hold`",
                "12:1: remote \"a\": unknown key `speed`, expected one of `name`, `transport`, \
                 `address`, `port`, `baud`, `parity`, `data_bits`, `stop_bits`, \
                 `frame_gap_us`, `unit_id`, `period_ms`, `timeout_ms`, `on_loss`, \
                 `loss_after`, `reconnect_ms`, `reconnect_max_ms`, `status`, `read`, `write`",
                "22:13: remote \"b\": period_ms 3600001 out of range 1..=3600000",
                "23:14: remote \"b\": timeout_ms 0 out of range 1..=60000",
                "24:14: remote \"b\": loss_after 0 out of range 1..=100",
                "25:16: remote \"b\": reconnect_ms 60001 out of range 10..=60000",
            ]
        );
        // An entry with a malformed key is left out of pass 2 (as every entry is); its own
        // range errors show once that key is fixed.
        assert_eq!(
            errors(
                "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 unit_id = 256\nperiod_ms = 0\ntimeout_ms = 60001\nloss_after = 101\n\
                 reconnect_ms = 9\nreconnect_max_ms = 60001\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n"
            ),
            [
                "5:11: remote \"a\": unit_id 256 out of range 0..=255",
                "6:13: remote \"a\": period_ms 0 out of range 1..=3600000",
                "7:14: remote \"a\": timeout_ms 60001 out of range 1..=60000",
                "8:14: remote \"a\": loss_after 101 out of range 1..=100",
                "9:16: remote \"a\": reconnect_ms 9 out of range 10..=60000",
                "10:20: remote \"a\": reconnect_max_ms 60001 out of range 10..=60000",
            ]
        );
    }

    #[test]
    fn names_are_short_plain_and_unique() {
        let long = "a".repeat(32);
        assert_eq!(only_remote(&tcp(&long, "")).name, long);
        let errs = errors(&format!(
            "{}{}{}{}{}",
            tcp("rack 1", "unit_id = 1"),
            tcp("", "unit_id = 2"),
            tcp(&"b".repeat(33), "unit_id = 3"),
            tcp("rack1", "unit_id = 4"),
            tcp("rack1", "unit_id = 5"),
        ));
        assert_eq!(
            errs,
            [
                "2:8: remote \"rack 1\": name \"rack 1\" must be 1 to 32 letters, digits, `_` or \
                 `-`",
                "12:8: remote \"\": name \"\" must be 1 to 32 letters, digits, `_` or `-`",
                format!(
                    "22:8: remote \"{b}\": name \"{b}\" must be 1 to 32 letters, digits, `_` or \
                     `-`",
                    b = "b".repeat(33)
                )
                .as_str(),
                "42:8: remote \"rack1\": name \"rack1\" is already used by the remote at line 31",
            ]
        );
    }

    #[test]
    fn each_transport_has_its_own_keys() {
        assert_eq!(
            errors(
                "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\nport = \"/dev/ttyUSB0\"\n\
                 baud = 9600\nparity = \"odd\"\ndata_bits = 8\nstop_bits = 1\nframe_gap_us = 500\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n\
                 [[remote]]\nname = \"b\"\ntransport = \"rtu\"\naddress = \"10.0.0.5:502\"\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0001\"\n\
                 [[remote]]\nname = \"c\"\ntransport = \"rtu\"\nport = \"\"\ndata_bits = 7\n\
                 stop_bits = 0\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0002\"\n\
                 [[remote]]\nname = \"d\"\ntransport = \"udp\"\n\
                 [[remote]]\nname = \"e\"\n"
            ),
            [
                "1:1: remote \"a\": transport \"tcp\" needs `address`, the device's \"host:port\"",
                "4:8: remote \"a\": `port` is a key of transport \"rtu\"",
                "5:8: remote \"a\": `baud` is a key of transport \"rtu\"",
                "6:10: remote \"a\": `parity` is a key of transport \"rtu\"",
                "7:13: remote \"a\": `data_bits` is a key of transport \"rtu\"",
                "8:13: remote \"a\": `stop_bits` is a key of transport \"rtu\"",
                "9:16: remote \"a\": `frame_gap_us` is a key of transport \"rtu\"",
                "15:1: remote \"b\": transport \"rtu\" needs `port`, the serial device \
                 (\"/dev/ttyUSB0\")",
                "18:11: remote \"b\": `address` is a key of transport \"tcp\"",
                "27:8: remote \"c\": port must not be empty",
                "28:13: remote \"c\": data_bits 7: 7 data bits is the Modbus ASCII mode, which \
                 plcd does not speak; Modbus RTU has 8",
                "29:13: remote \"c\": stop_bits 0 out of range 1..=2",
                "37:13: remote \"d\": transport: unknown variant `udp`, expected `tcp` or `rtu`",
                "38:1: remote \"e\": missing key `transport`",
            ]
        );
    }

    #[test]
    fn a_tcp_address_is_a_host_and_a_port() {
        for good in ["10.0.0.5:502", "plc-1.local:1502", "[fd00::5]:502", "[::1]:65535", "h:1"] {
            let remote = only_remote(&tcp("a", "").replace("10.0.0.5:502", good));
            assert_eq!(remote.transport, RemoteTransport::Tcp { address: good.into() });
        }
        let bad = |address: &str| {
            let errs = errors(&tcp("a", "").replace("10.0.0.5:502", address));
            assert_eq!(errs.len(), 1, "{errs:#?}");
            errs[0].clone()
        };
        let examples = "(\"10.0.0.5:502\", \"plc1.local:502\", \"[fd00::5]:502\")";
        assert_eq!(
            bad("10.0.0.5"),
            format!("4:11: remote \"a\": address \"10.0.0.5\" is not \"host:port\" {examples}")
        );
        let no_port = "needs a port 1..=65535 after the last `:`";
        for address in ["h:0", "h:65536", "h:", "h:+5", "h:x"] {
            let want = format!("4:11: remote \"a\": address {address:?} {no_port} {examples}");
            assert_eq!(bad(address), want);
        }
        let no_host = "has no host name, IPv4 address or [IPv6] address before the port";
        for address in [
            ":502",
            "10.0.0.256:502",
            "1.2.3:502",
            "fd00::5:502",
            "[fd00::x]:502",
            "a..b:1",
            "a b:1",
        ] {
            let want = format!("4:11: remote \"a\": address {address:?} {no_host} {examples}");
            assert_eq!(bad(address), want);
        }
    }

    #[test]
    fn unit_ids_depend_on_the_transport_and_a_unit_is_polled_once() {
        let rtu = |name: &str, extra: &str| {
            format!(
                "[[remote]]\nname = \"{name}\"\ntransport = \"rtu\"\nport = \"/dev/ttyUSB0\"\n\
                 {extra}\n[[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\n\
                 device = \"M{name}0\"\n"
            )
        };
        assert_eq!(only_remote(&tcp("a", "unit_id = 255")).unit_id, 255);
        assert_eq!(only_remote(&rtu("100", "unit_id = 247")).unit_id, 247);
        assert_eq!(
            errors(&format!("{}{}", rtu("100", "unit_id = 0"), rtu("101", "unit_id = 248"))),
            [
                "5:11: remote \"100\": unit_id 0 out of range 1..=247",
                "15:11: remote \"101\": unit_id 248 out of range 1..=247",
            ]
        );
        // The same unit on one address (trimmed) or one port; other units, other addresses
        // and other ports are fine.
        let errs = errors(&format!(
            "{}{}{}{}{}{}{}",
            tcp("a", ""),
            tcp("b", "unit_id = 2"),
            tcp("c", "").replace("10.0.0.5:502", " 10.0.0.5:502"),
            tcp("d", "unit_id = 2").replace("10.0.0.5:502", "10.0.0.5:503"),
            rtu("100", "unit_id = 5"),
            rtu("101", "unit_id = 5").replace("ttyUSB0", "ttyUSB1"),
            rtu("102", "unit_id = 5"),
        ));
        assert_eq!(
            errs,
            [
                "24:11: remote \"c\": unit 1 of tcp 10.0.0.5:502 is already polled by remote \"a\"",
                "65:11: remote \"102\": unit 5 of rtu /dev/ttyUSB0 is already polled by remote \
                 \"100\"",
            ]
        );
    }

    #[test]
    fn devices_on_one_port_share_its_settings_and_a_port_is_served_or_polled() {
        let rtu = |name: &str, extra: &str| {
            format!(
                "[[remote]]\nname = \"{name}\"\ntransport = \"rtu\"\nport = \"/dev/ttyUSB0\"\n\
                 {extra}\n[[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\n\
                 device = \"M{name}0\"\n"
            )
        };
        // The same settings, written or defaulted, are one line.
        let remotes = config(&format!(
            "{}{}",
            rtu("100", "unit_id = 1\nbaud = 19200\nparity = \"even\""),
            rtu("101", "unit_id = 2")
        ))
        .remotes;
        assert_eq!(remotes[0].transport, remotes[1].transport);
        assert_eq!(
            errors(&format!(
                "{}{}{}",
                rtu("100", "unit_id = 1\nbaud = 9600"),
                rtu("101", "unit_id = 2\nparity = \"none\"\nframe_gap_us = 2000"),
                rtu("102", "unit_id = 3\nbaud = 9600"),
            )),
            ["15:8: remote \"101\": port /dev/ttyUSB0 is shared with remote \"100\", whose \
                 settings differ (19200 baud 8N1, frame_gap_us 2000 here, 9600 baud 8E1 there): \
                 devices on one port share its settings",]
        );
        // [modbus.rtu] before or after the remote: the later is reported.
        assert_eq!(
            errors(&format!("[modbus.rtu]\nport = \"/dev/ttyUSB0\"\n{}", rtu("100", ""))),
            ["6:8: remote \"100\": port /dev/ttyUSB0 is served by [modbus.rtu]: a port either \
                 serves (`[modbus.rtu]`) or polls (`[[remote]]`)",]
        );
        assert_eq!(
            errors(&format!("{}[modbus.rtu]\nport = \"/dev/ttyUSB0\"\n", rtu("100", ""))),
            ["12:8: modbus.rtu.port /dev/ttyUSB0 is polled by remote \"100\": a port either \
                 serves (`[modbus.rtu]`) or polls (`[[remote]]`)",]
        );
        let both = config(&format!("{}[modbus.rtu]\nport = \"/dev/ttyS0\"\n", rtu("100", "")));
        assert_eq!(both.modbus.rtu.unwrap().line.port, PathBuf::from("/dev/ttyS0"));
    }

    #[test]
    fn remote_reads_and_status_bits_write_p_m_k_and_d_only() {
        let writes = |text: &str| addr(text).writable_by(Writer::RemoteInput);
        assert!(["P0000", "M010", "K2550", "D00010", "D00010.3"].iter().all(|a| writes(a)));
        assert!(!["T0001", "C0001", "SM420", "SD8330", "_ON"].iter().any(|a| writes(a)));
        assert_eq!(
            only_remote(&tcp("a", "status = \"k0013\"")).status.unwrap().device,
            addr("K0013")
        );
        assert_eq!(
            errors(&format!(
                "{}{}{}{}{}",
                tcp("a", "unit_id = 1\nstatus = \"M010\""),
                tcp("b", "unit_id = 2\nstatus = \"D00010.1\""),
                tcp("c", "unit_id = 3\nstatus = \"T0001\""),
                tcp("d", "unit_id = 4\nstatus = \"SM420\""),
                tcp("e", "unit_id = 5\nstatus = \"X1\""),
            )),
            [
                "6:10: remote \"a\": status \"M010\" is not a P, M or K bit (P0000, M0100, K0010 …)",
                "17:10: remote \"b\": status \"D00010.1\" is not a P, M or K bit (P0000, M0100, \
                 K0010 …)",
                "28:10: remote \"c\": status \"T0001\" is not a P, M or K bit (P0000, M0100, \
                 K0010 …)",
                "39:10: remote \"d\": status \"SM420\" is not a P, M or K bit (P0000, M0100, \
                 K0010 …)",
                "50:10: remote \"e\": status: `X1` is not a device address",
            ]
        );
    }

    #[test]
    fn a_remote_has_something_to_poll_and_there_are_at_most_64() {
        assert_eq!(
            errors(
                "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 [[remote]]\nname = \"b\"\ntransport = \"tcp\"\naddress = \"10.0.0.6:502\"\n\
                 [[remote.read]]\ntable = \"coils\"\naddress = 0\ndevice = \"M0000\"\n"
            ),
            [
                "1:1: remote \"a\": nothing to poll: a remote needs a [[remote.read]] or a \
                 [[remote.write]] after it",
                // Not "nothing to poll" as well: the table it has is wrong.
                "9:1: remote \"b\" read #1: missing key `count`",
            ]
        );
        let many = |n: u8| (0..n).map(|i| tcp(&format!("r{i}"), &format!("unit_id = {i}")));
        let remotes = config(&many(64).collect::<String>()).remotes;
        assert_eq!(remotes.len(), RemoteDevice::MAX_DEVICES);
        let errs = errors(&many(66).collect::<String>());
        assert_eq!(
            errs,
            ["641:1: remote \"r64\": more than 64 remotes: plcd polls at most 64 [[remote]]"]
        );
    }

    #[test]
    fn tables_name_a_modbus_table_and_stay_within_it() {
        let table = |kind: &str, t: &str, address: u32, count: u32, device: &str| {
            format!(
                "[[remote.{kind}]]\ntable = \"{t}\"\naddress = {address}\ncount = {count}\n\
                 device = \"{device}\"\n"
            )
        };
        let remote = "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n";
        let errs = errors(
            &[
                remote,
                &table("read", "coil", 0, 1, "M0000"),
                &table("write", "discrete_inputs", 0, 1, "M0000"),
                &table("write", "input_registers", 0, 1, "D00000"),
                &table("write", "holding", 0, 1, "D00000"),
                &table("read", "coils", 65536, 0, "M0000"),
                &table("read", "coils", 0, 2001, "M0000"),
                &table("read", "discrete_inputs", 0, 2001, "M0000"),
                &table("read", "holding_registers", 0, 126, "D00000"),
                &table("read", "input_registers", 0, 126, "D00000"),
                &table("write", "coils", 0, 1969, "M0000"),
                &table("write", "holding_registers", 0, 124, "D00000"),
                &table("read", "input_registers", 65530, 7, "D00000"),
            ]
            .concat(),
        );
        assert_eq!(
            errs,
            [
                "6:9: remote \"a\" read #1: table \"coil\" is not a Modbus table: expected \
                 \"coils\", \"discrete_inputs\", \"holding_registers\" or \"input_registers\"",
                "11:9: remote \"a\" write #1: table \"discrete_inputs\": discrete inputs are \
                 read-only in Modbus; a write table is \"coils\" or \"holding_registers\"",
                "16:9: remote \"a\" write #2: table \"input_registers\": input registers are \
                 read-only in Modbus; a write table is \"coils\" or \"holding_registers\"",
                "21:9: remote \"a\" write #3: table \"holding\" is not a Modbus table: expected \
                 \"coils\" or \"holding_registers\"",
                "27:11: remote \"a\" read #2: address 65536 out of range 0..=65535",
                "28:9: remote \"a\" read #2: count 0 out of range 1..=2000",
                "33:9: remote \"a\" read #3: count 2001 out of range 1..=2000",
                "38:9: remote \"a\" read #4: count 2001 out of range 1..=2000",
                "43:9: remote \"a\" read #5: count 126 out of range 1..=125",
                "48:9: remote \"a\" read #6: count 126 out of range 1..=125",
                "53:9: remote \"a\" write #4: count 1969 out of range 1..=1968",
                "58:9: remote \"a\" write #5: count 124 out of range 1..=123",
                "63:9: remote \"a\" read #7: count 7 from address 65530 runs past the last \
                 Modbus address 65535",
            ]
        );
        // The largest counts at the last addresses are fine.
        config(
            &[
                remote,
                &table("read", "holding_registers", 65411, 125, "D00000"),
                &table("read", "coils", 63536, 2000, "M0000"),
                &table("write", "holding_registers", 65413, 123, "D00000"),
                &table("write", "coils", 63568, 1968, "M0000"),
            ]
            .concat(),
        );
    }

    #[test]
    fn tables_map_the_devices_their_table_holds_within_their_area() {
        let read = |t: &str, count: u32, device: &str, extra: &str| {
            format!(
                "[[remote.read]]\ntable = \"{t}\"\naddress = 0\ncount = {count}\n\
                 device = \"{device}\"\n{extra}\n"
            )
        };
        let remote = "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n";
        let errs = errors(
            &[
                remote,
                &read("coils", 1, "M010", ""),
                &read("discrete_inputs", 1, "D00000.1", ""),
                &read("coils", 1, "T0001", ""),
                &read("holding_registers", 1, "M0100", ""),
                &read("input_registers", 1, "SD8330", ""),
                &read("holding_registers", 1, "T0001", ""),
                &read("coils", 17, "P1270", ""),
                &read("input_registers", 2, "D32767", ""),
                &read("holding_registers", 2, "K255", ""),
                &read("coils", 3, "M2000", "swap_bytes = true\nswap_words = true"),
                &read("input_registers", 3, "D01000", "swap_words = true\nswap_bytes = true"),
            ]
            .concat(),
        );
        let bits = "coils map P, M or K bits (as M0100)";
        let words = "map P, M, K or D words (as D00100)";
        assert_eq!(
            errs,
            [
                format!("9:10: remote \"a\" read #1: device: M010 cannot start a table of coils: {bits}"),
                "15:10: remote \"a\" read #2: device: D00000.1 cannot start a table of discrete \
                 inputs: discrete inputs map P, M or K bits (as M0100)"
                    .into(),
                format!("21:10: remote \"a\" read #3: device: T0001 cannot start a table of coils: {bits}"),
                format!(
                    "27:10: remote \"a\" read #4: device: M0100 cannot start a table of holding \
                     registers: holding registers {words}"
                ),
                format!(
                    "33:10: remote \"a\" read #5: device: SD8330 cannot start a table of input \
                     registers: input registers {words}"
                ),
                format!(
                    "39:10: remote \"a\" read #6: device: T0001 cannot start a table of holding \
                     registers: holding registers {words}"
                ),
                "44:9: remote \"a\" read #7: count 17 from P1270 runs past the end of its area \
                 (P0000-P127F, P000-P127): at most 16"
                    .into(),
                "50:9: remote \"a\" read #8: count 2 from D32767 runs past the end of its area \
                 (D00000-D32767): at most 1"
                    .into(),
                "56:9: remote \"a\" read #9: count 2 from K255 runs past the end of its area \
                 (K0000-K255F, K000-K255): at most 1"
                    .into(),
                "64:14: remote \"a\" read #10: swap_bytes is only for register tables: coils are \
                 bits"
                    .into(),
                "65:14: remote \"a\" read #10: swap_words is only for register tables: coils are \
                 bits"
                    .into(),
                "71:14: remote \"a\" read #11: swap_words swaps pairs of registers: count 3 is \
                 odd"
                    .into(),
            ]
        );
        // `false` is no swap, on any table.
        config(
            &[remote, &read("coils", 3, "M2000", "swap_bytes = false\nswap_words = false")]
                .concat(),
        );
    }

    #[test]
    fn a_write_table_is_written_on_change_or_periodically() {
        let write = |extra: &str| {
            format!(
                "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 period_ms = 50\n\
                 [[remote.write]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n\
                 {extra}\n"
            )
        };
        let on = |extra: &str| only_remote(&write(extra)).writes[0].on;
        assert_eq!(on(""), WriteOn::Change { refresh_ms: 1000 });
        assert_eq!(on("refresh_ms = 3600000"), WriteOn::Change { refresh_ms: 3_600_000 });
        assert_eq!(on("write = \"period\""), WriteOn::Period { period_ms: 50 });
        assert_eq!(on("write = \"period\"\nperiod_ms = 7"), WriteOn::Period { period_ms: 7 });
        assert_eq!(
            errors(&write("write = \"change\"\nperiod_ms = 10")),
            ["12:13: remote \"a\" write #1: period_ms is only for write = \"period\""]
        );
        assert_eq!(
            errors(&write("write = \"period\"\nrefresh_ms = 10\nperiod_ms = 0")),
            [
                "12:14: remote \"a\" write #1: refresh_ms is only for write = \"change\"",
                "13:13: remote \"a\" write #1: period_ms 0 out of range 1..=3600000",
            ]
        );
        assert_eq!(
            errors(&write("refresh_ms = 3600001")),
            ["11:14: remote \"a\" write #1: refresh_ms 3600001 out of range 0..=3600000"]
        );
        assert_eq!(
            errors(&write("write = \"always\"")),
            ["11:9: remote \"a\" write #1: write: unknown variant `always`, expected `change` or \
              `period`"]
        );
        // A read table's own period.
        let read = "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                    [[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n\
                    period_ms = 0\n";
        assert_eq!(
            errors(read),
            ["10:13: remote \"a\" read #1: period_ms 0 out of range 1..=3600000"]
        );
    }

    #[test]
    fn no_remote_writes_the_contact_an_io_task_starts_on() {
        let task = "[[task]]\nname = \"edge\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
                    contact = \"P0002\"\nedge = \"rising\"\n";
        let remote = "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                      [[remote.read]]\ntable = \"discrete_inputs\"\naddress = 0\ncount = 8\n\
                      device = \"P0000\"\n";
        assert_eq!(
            errors(&format!("{task}{remote}")),
            ["16:10: remote \"a\" read #1: device P0000-P0007 overlaps the contact task \"edge\" \
              starts on (P0002), whose edges come from the field"]
        );
        // The contacts io tasks do not use are free.
        let free = remote.replace("count = 8", "count = 4").replace("P0000", "P0004");
        config(&format!("{task}{free}"));
        // A contact is usually an input line too: that is no overlap of the remotes'.
        config(&format!("{task}[[io.input]]\ndevice = \"P0002\"\nline = 2\n{free}"));
    }

    #[test]
    fn a_device_bit_has_one_remote_writer_and_is_no_local_line() {
        let remote = |name: &str, unit: u8, status: &str, tables: &str| {
            format!(
                "[[remote]]\nname = \"{name}\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 unit_id = {unit}\n{status}\n{tables}"
            )
        };
        let read = |t: &str, count: u32, device: &str| {
            format!(
                "[[remote.read]]\ntable = \"{t}\"\naddress = 0\ncount = {count}\n\
                 device = \"{device}\"\n"
            )
        };
        let errs = errors(
            &[
                "[[io.input]]\ndevice = \"P0003\"\nline = 1\n",
                &remote("a", 1, "status = \"M0105\"", &read("coils", 16, "P0000")),
                &read("holding_registers", 2, "M010"),
                &remote("b", 2, "status = \"M0105\"", &read("discrete_inputs", 8, "P0008")),
                &read("coils", 1, "M1000"),
                "[[io.output]]\ndevice = \"M1000\"\nline = 2\n",
                "[[io.output]]\ndevice = \"P0200\"\nline = 3\n",
                &read("discrete_inputs", 1, "P0200"),
            ]
            .concat(),
        );
        assert_eq!(
            errs,
            [
                "14:10: remote \"a\" read #1: device P0000-P000F overlaps io.input \"P0003\", \
                 which the local I/O backend owns",
                "19:10: remote \"a\" read #2: device M010-M011 overlaps the status bit of remote \
                 \"a\" (M0105)",
                "25:10: remote \"b\": status M0105 overlaps the status bit of remote \"a\" \
                 (M0105)",
                "25:10: remote \"b\": status M0105 overlaps the devices remote \"a\" read #2 \
                 writes (M010-M011)",
                "30:10: remote \"b\" read #1: device P0008-P000F overlaps the devices remote \"a\" \
                 read #1 writes (P0000-P000F)",
                // M1000 is not a P bit: `io` reports it. The local I/O only owns P bits.
                "37:10: io.output \"M1000\": device \"M1000\" is not a P bit (P0000..=P127F)",
                "46:10: remote \"b\" read #3: device P0200 overlaps io.output \"P0200\", which the \
                 local I/O backend owns",
            ]
        );
        // An [[io.input]] after the read is the one reported.
        assert_eq!(
            errors(
                &[
                    &remote("a", 1, "", &read("coils", 16, "P0000")),
                    "[[io.input]]\ndevice = \"P000F\"\nline = 1\n",
                ]
                .concat()
            ),
            ["13:10: io.input \"P000F\": device P000F overlaps the devices remote \"a\" read #1 \
              writes (P0000-P000F)"]
        );
        // Write tables read their devices: they may share them with anything.
        let write = |t: &str, address: u32, count: u32, device: &str| {
            format!(
                "[[remote.write]]\ntable = \"{t}\"\naddress = {address}\ncount = {count}\n\
                 device = \"{device}\"\n"
            )
        };
        config(
            &[
                "[[io.output]]\ndevice = \"P0003\"\nline = 1\n",
                &remote("a", 1, "status = \"M0000\"", &read("coils", 16, "M0100")),
                &write("coils", 0, 16, "P0000"),
                &write("coils", 16, 16, "M0000"),
                &write("holding_registers", 0, 16, "M010"),
                &remote("b", 2, "", &write("coils", 0, 16, "M0100")),
            ]
            .concat(),
        );
        // But two of one remote do not write the same Modbus addresses.
        assert_eq!(
            errors(&remote(
                "a",
                1,
                "",
                &[
                    write("coils", 0, 16, "M0000"),
                    write("holding_registers", 0, 16, "D00000"),
                    write("coils", 15, 2, "M0100"),
                ]
                .concat()
            )),
            ["19:11: remote \"a\" write #3: coils 15..=16 overlap those of remote \"a\" write #1 \
              (0..=15)"]
        );
    }

    #[test]
    fn misplaced_tables_and_unknown_keys_are_reported() {
        let not_an_array = "`remote` must be an array of tables, written [[remote]]; \
                            [[remote.read]] and [[remote.write]] follow the [[remote]] they \
                            belong to";
        assert_eq!(errors("[remote]\nname = \"a\"\n"), [format!("1:1: {not_an_array}")]);
        assert_eq!(errors("remote = 5\n"), [format!("1:10: {not_an_array}")]);
        assert_eq!(
            errors(
                "[[remote.read]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n\
                 colour = 1\n[[remote.write]]\ntable = \"coils\"\n"
            ),
            [
                format!("1:3: {not_an_array}"),
                "6:1: remote.read #1: unknown key `colour`, expected one of `table`, `address`, \
                 `count`, `device`, `swap_bytes`, `swap_words`, `period_ms`"
                    .into(),
                "7:1: remote.write #1: missing key `address`".into(),
            ]
        );
        assert_eq!(
            errors(
                "[[remote]]\nname = \"a\"\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 [remote.read]\ntable = \"coils\"\n\
                 [[remote]]\nname = \"b\"\ntransport = \"tcp\"\naddress = \"10.0.0.6:502\"\n\
                 [[remote.write]]\ntable = \"coils\"\naddress = 0\ncount = 1\ndevice = \"M0000\"\n\
                 refresh = 5\n"
            ),
            [
                "5:1: `remote.read` must be an array of tables, written [[remote.read]]",
                "16:1: remote \"b\" write #1: unknown key `refresh`, expected one of `table`, \
                 `address`, `count`, `device`, `swap_bytes`, `swap_words`, `write`, \
                 `refresh_ms`, `period_ms`",
            ]
        );
    }

    #[test]
    fn every_key_of_a_table_is_checked_and_a_remote_with_errors_still_has_its_tables_checked() {
        assert_eq!(
            errors(
                "[[remote]]\ntransport = \"tcp\"\naddress = \"10.0.0.5:502\"\n\
                 [[remote.write]]\ntable = \"holding_registers\"\naddress = -1\ncount = 1\n\
                 device = \"D00010.3\"\n\
                 [[remote.write]]\ntable = \"holding_registers\"\naddress = 0\ncount = 1\n\
                 device = \"T0001\"\n"
            ),
            [
                "1:1: remote #1: missing key `name`",
                "6:11: remote #1 write #1: address -1 out of range 0..=65535",
                "8:10: remote #1 write #1: device: D00010.3 cannot start a table of holding \
                 registers: holding registers map P, M, K or D words (as D00100)",
                "13:10: remote #1 write #2: device: T0001 cannot start a table of holding \
                 registers: holding registers map P, M, K or D words (as D00100)",
            ]
        );
    }
}
