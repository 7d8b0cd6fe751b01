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

use std::ops::{Range, RangeInclusive};

use super::modbus::ModbusTable;
use super::serial::SerialLine;
use crate::device::{Address, BitRef};

/// One `[[remote]]`: a Modbus server that plcd polls.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RemoteDevice {
    /// `name`: unique among the remotes; names it in logs, `plcctl status` and diagnostics;
    /// required. Letters, digits, `_` and `-`.
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
    /// default 5000.
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
    /// Unit ids over RTU: 0 is broadcast, 248..=255 reserved.
    pub const RTU_UNIT_ID: RangeInclusive<u8> = 1..=247;
    /// At most this many `[[remote]]` (each TCP device has a thread, each RTU port one).
    pub const MAX_DEVICES: usize = 64;

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
