//! One remote device's polling, as a state machine on a given clock: which table is due,
//! what a finished exchange changes (the inputs image, the health, the counters), when the
//! device is lost and when it is tried again. The poller threads ([`super::threads`]) only
//! ask it for the next job, carry the job out on a [`super::link::Link`] and report back; so
//! the schedule, the loss and the backoff are tested here on a clock that tests set.
//!
//! - **Reads** are due every `period_ms` (a table's own or the device's); a period that was
//!   missed is not made up for, the next one is a period after the late poll.
//! - **Writes** wait until the scan has captured outputs once. A `write = "change"` table is
//!   written when its values differ from those last written (the scan wakes the thread when
//!   they change) and every `refresh_ms`; a `write = "period"` table every period. A write that
//!   fails is tried again a device period later, until it succeeds. Writes go before reads.
//! - **Health**: `loss_after` failed exchanges in a row lose the device: its status goes OFF,
//!   its inputs are cleared (`on_loss = "clear"`) or held, and from then on one exchange is
//!   tried after `reconnect_ms`, then after twice that, up to `reconnect_max_ms`. The first
//!   exchange that succeeds brings it back: every read table is polled at once, and the status
//!   goes ON when each has been read since.
//! - **Logs**: a fault is logged when it begins, not at every poll: once per condition (its
//!   kind, an exception's code) until an exchange succeeds.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use super::frame::{words_of, Ask, Fault, FaultKind};
use crate::config::{OnLoss, RemoteDevice, RemoteTable, WriteOn};
use crate::stats::Histogram;

const MS: u64 = 1_000_000;

/// The most words a table's values take: 125 registers, or 2000 bits packed in 125 words.
const MAX_TABLE_WORDS: usize = 125;

/// What the scan thread takes at its input refresh: every read table's values (in
/// [`super::RemoteIo`]'s layout), and whether the device is online. Published whole.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputImage {
    pub online: bool,
    pub words: Vec<u16>,
}

/// What the scan thread gives at its output refresh: every write table's values. `captured`
/// is false until the first output refresh.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OutputImage {
    pub captured: bool,
    pub words: Vec<u16>,
}

/// A device's state as `plcctl status` shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LinkState {
    /// Not every read table has been read yet.
    #[default]
    Starting,
    Online,
    Lost,
}

impl LinkState {
    pub fn as_str(self) -> &'static str {
        match self {
            LinkState::Starting => "starting",
            LinkState::Online => "online",
            LinkState::Lost => "lost",
        }
    }
}

/// The counters of one device, shared with the status request.
#[derive(Debug, Clone, Default)]
pub struct DeviceStats {
    pub state: LinkState,
    /// Exchanges tried.
    pub requests: u64,
    /// Exchanges that failed.
    pub failures: u64,
    /// Failures by kind, in [`FaultKind::ALL`] order.
    pub by_kind: [u64; FaultKind::ALL.len()],
    /// Answers that came after their request had timed out, and were dropped.
    pub late: u64,
    /// Writes that succeeded.
    pub writes: u64,
    /// Times the device was lost.
    pub losses: u64,
    /// The last failure: what it was, and when (the poller clock, ns).
    pub last_error: Option<(String, u64)>,
    /// Round trips of the exchanges that got an answer, ns.
    pub round_trip: Histogram,
}

/// Something worth a log line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Notice {
    /// A fault began (or changed).
    Fault { ask: Ask, fault: Fault },
    /// The device is lost.
    Lost { failures: u32, on_loss: OnLoss },
    /// It answers again.
    Back { failures: u64, lost_ms: Option<u64> },
    /// The first late answer.
    Late,
}

/// What the thread does next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Job {
    Read(usize),
    Write(usize),
}

struct ReadSlot {
    table: RemoteTable,
    period: u64,
    due: u64,
    /// Where its values are in the inputs image.
    offset: usize,
    /// Read since the device was (last) lost.
    fresh: bool,
}

struct WriteSlot {
    table: RemoteTable,
    on: WriteOn,
    /// The next periodic write (a refresh, or the period).
    due: u64,
    /// Not before this: a failed write waits a device period.
    retry_at: u64,
    offset: usize,
    written: Option<Vec<u16>>,
    /// Failed writes since its last good one: while it is not 0 the device is not healthy.
    failed_in_a_row: u32,
}

/// See the module documentation.
pub struct Poller {
    pub name: String,
    /// `tcp 10.0.0.5:502`, `rtu /dev/ttyUSB0 unit 3`.
    pub describe: String,
    pub unit: u8,
    pub timeout_ms: u32,
    on_loss: OnLoss,
    loss_after: u32,
    reconnect: (u64, u64),
    period: u64,
    reads: Vec<ReadSlot>,
    writes: Vec<WriteSlot>,
    image: Vec<u16>,
    online: bool,
    inputs: triple_buffer::Input<InputImage>,
    outputs: triple_buffer::Output<OutputImage>,
    safe: Arc<AtomicBool>,
    lost: bool,
    lost_at: u64,
    in_a_row: u32,
    failed_since_ok: u64,
    backoff: u64,
    retry_at: u64,
    condition: Option<(FaultKind, u8)>,
    late_seen: bool,
    stats: Arc<Mutex<DeviceStats>>,
    notices: Vec<Notice>,
    scratch: Vec<u16>,
}

impl Poller {
    /// A poller of `device`, exchanging images with the scan side's ends of `inputs` and
    /// `outputs`; `safe` set means every write table's values are 0 (the outputs' safe
    /// state after a watchdog trip).
    pub fn new(
        device: &RemoteDevice,
        inputs: triple_buffer::Input<InputImage>,
        outputs: triple_buffer::Output<OutputImage>,
        safe: Arc<AtomicBool>,
    ) -> Poller {
        let mut offset = 0;
        let reads = device
            .reads
            .iter()
            .map(|read| {
                let slot = ReadSlot {
                    table: read.table,
                    period: u64::from(read.period_ms) * MS,
                    due: 0,
                    offset,
                    fresh: false,
                };
                offset += words_of(&read.table);
                slot
            })
            .collect();
        let image = vec![0; offset];
        let mut offset = 0;
        let writes = device
            .writes
            .iter()
            .map(|write| {
                let slot = WriteSlot {
                    table: write.table,
                    on: write.on,
                    due: 0,
                    retry_at: 0,
                    offset,
                    written: None,
                    failed_in_a_row: 0,
                };
                offset += words_of(&write.table);
                slot
            })
            .collect();
        let describe = match &device.transport {
            crate::config::RemoteTransport::Tcp { .. } => device.transport.describe(),
            crate::config::RemoteTransport::Rtu(_) => {
                format!("{} unit {}", device.transport.describe(), device.unit_id)
            }
        };
        Poller {
            name: device.name.clone(),
            describe,
            unit: device.unit_id,
            timeout_ms: device.timeout_ms,
            on_loss: device.on_loss,
            loss_after: device.loss_after,
            reconnect: (
                u64::from(device.reconnect_ms) * MS,
                u64::from(device.reconnect_max_ms) * MS,
            ),
            period: u64::from(device.period_ms) * MS,
            reads,
            writes,
            image,
            online: false,
            inputs,
            outputs,
            safe,
            lost: false,
            lost_at: 0,
            in_a_row: 0,
            failed_since_ok: 0,
            backoff: 0,
            retry_at: 0,
            condition: None,
            late_seen: false,
            stats: Arc::new(Mutex::new(DeviceStats::default())),
            notices: Vec::new(),
            scratch: vec![0; MAX_TABLE_WORDS],
        }
    }

    /// The counters, for the status request.
    pub fn stats(&self) -> Arc<Mutex<DeviceStats>> {
        Arc::clone(&self.stats)
    }

    /// How many write tables it has.
    pub fn write_tables(&self) -> usize {
        self.writes.len()
    }

    /// The job due at `now`, or the time the next one is due.
    pub fn next_job(&mut self, now: u64) -> Result<Job, u64> {
        self.outputs.update();
        if self.lost {
            if now < self.retry_at {
                return Err(self.retry_at);
            }
            // One exchange tells whether it is back: a write that failed (a device that answers
            // reads but refuses a write is not back until the write goes through), else a
            // read, else a write.
            let captured = self.outputs.output_buffer().captured;
            if let Some(i) = self.writes.iter().position(|w| w.failed_in_a_row > 0) {
                if captured {
                    return Ok(Job::Write(i));
                }
            }
            if !self.reads.is_empty() {
                return Ok(Job::Read(0));
            }
            if captured && !self.writes.is_empty() {
                return Ok(Job::Write(0));
            }
            return Err(now + self.period);
        }
        let mut wake = u64::MAX;
        if self.outputs.output_buffer().captured {
            let safe = self.safe.load(Ordering::Acquire);
            for (i, slot) in self.writes.iter().enumerate() {
                let words = words_of(&slot.table);
                let wanted = &self.outputs.output_buffer().words[slot.offset..slot.offset + words];
                let changed = match &slot.written {
                    None => true,
                    Some(written) if safe => written.iter().any(|&w| w != 0),
                    Some(written) => written[..] != *wanted,
                };
                let due = match slot.on {
                    // Changed or not, on its period (a failed write waits for the next one).
                    WriteOn::Period { .. } => Some(slot.due.max(slot.retry_at)),
                    WriteOn::Change { refresh_ms } => {
                        let refresh =
                            (refresh_ms > 0 && slot.written.is_some()).then_some(slot.due);
                        refresh.into_iter().chain(changed.then_some(slot.retry_at)).min()
                    }
                };
                match due {
                    Some(due) if due <= now => return Ok(Job::Write(i)),
                    Some(due) => wake = wake.min(due),
                    None => {}
                }
            }
        }
        let next_read = self.reads.iter().enumerate().min_by_key(|(_, slot)| slot.due);
        match next_read {
            Some((i, slot)) if slot.due <= now => Ok(Job::Read(i)),
            Some((_, slot)) => Err(wake.min(slot.due)),
            None => Err(wake),
        }
    }

    /// The request of `job`, and in `values` a write's values on the wire (byte and word
    /// swaps applied).
    pub fn prepare(&mut self, job: Job) -> (Ask, &mut [u16]) {
        match job {
            Job::Read(i) => {
                let table = &self.reads[i].table;
                (Ask::read(table), &mut self.scratch[..words_of(table)])
            }
            Job::Write(i) => {
                let slot = &self.writes[i];
                let words = words_of(&slot.table);
                let values = &mut self.scratch[..words];
                if self.safe.load(Ordering::Acquire) {
                    values.fill(0);
                } else {
                    let image = &self.outputs.output_buffer().words;
                    values.copy_from_slice(&image[slot.offset..slot.offset + words]);
                }
                swap(&slot.table, values);
                (Ask::write(&slot.table), values)
            }
        }
    }

    /// The exchange of `job` ended at `now` with `result`, its answer after `round_trip_ns`
    /// if one came; `late` answers were dropped on the way. A read's values are in the slice
    /// [`Poller::prepare`] gave.
    pub fn finish(
        &mut self,
        job: Job,
        now: u64,
        round_trip_ns: Option<u64>,
        result: Result<(), Fault>,
        late: u32,
    ) {
        let mut stats = self.stats.lock().unwrap_or_else(|p| p.into_inner());
        stats.requests += 1;
        if late > 0 {
            stats.late += u64::from(late);
            if !self.late_seen {
                self.late_seen = true;
                self.notices.push(Notice::Late);
            }
        }
        if let Some(ns) = round_trip_ns {
            stats.round_trip.record(ns);
        }
        match result {
            Ok(()) => {
                match job {
                    Job::Read(i) => {
                        let slot = &mut self.reads[i];
                        let words = words_of(&slot.table);
                        let values = &mut self.scratch[..words];
                        swap(&slot.table, values);
                        self.image[slot.offset..slot.offset + words].copy_from_slice(values);
                        slot.fresh = true;
                        slot.due = next_due(slot.due, slot.period, now);
                    }
                    Job::Write(i) => {
                        let slot = &mut self.writes[i];
                        let words = words_of(&slot.table);
                        let mut values = self.scratch[..words].to_vec();
                        // What was written, as the scan sees it (the swaps undone).
                        swap(&slot.table, &mut values);
                        slot.written = Some(values);
                        slot.failed_in_a_row = 0;
                        slot.due = match slot.on {
                            WriteOn::Change { refresh_ms } => now + u64::from(refresh_ms) * MS,
                            WriteOn::Period { period_ms } => {
                                next_due(slot.due, u64::from(period_ms) * MS, now)
                            }
                        };
                        stats.writes += 1;
                    }
                }
                self.in_a_row = 0;
                // Healthy: no write waits to be retried. Until then an answer does not end the
                // fault, so a device that reads well and refuses a write neither comes back
                // nor logs again at each turn.
                let healthy = self.writes.iter().all(|w| w.failed_in_a_row == 0);
                if healthy && self.lost {
                    // Back: every table not read since the loss is due at once.
                    self.lost = false;
                    for slot in self.reads.iter_mut().filter(|slot| !slot.fresh) {
                        slot.due = now;
                    }
                    let lost_ms = (now - self.lost_at) / MS;
                    self.condition = None;
                    // The episode is over: the next late answer is news again.
                    self.late_seen = false;
                    self.notices.push(Notice::Back {
                        failures: self.failed_since_ok,
                        lost_ms: Some(lost_ms),
                    });
                } else if healthy && self.condition.take().is_some() {
                    self.late_seen = false;
                    self.notices
                        .push(Notice::Back { failures: self.failed_since_ok, lost_ms: None });
                } else if self.lost {
                    // Another write that failed is tried at once.
                    self.retry_at = now;
                }
                if healthy {
                    self.failed_since_ok = 0;
                }
            }
            Err(fault) => {
                let ask = match job {
                    Job::Read(i) => Ask::read(&self.reads[i].table),
                    Job::Write(i) => Ask::write(&self.writes[i].table),
                };
                stats.failures += 1;
                let kind = FaultKind::ALL.iter().position(|&k| k == fault.kind()).unwrap_or(0);
                stats.by_kind[kind] += 1;
                stats.last_error = Some((format!("{ask}: {fault}"), now));
                self.in_a_row = self.in_a_row.saturating_add(1);
                self.failed_since_ok += 1;
                match job {
                    Job::Read(i) => {
                        let slot = &mut self.reads[i];
                        slot.due = next_due(slot.due, slot.period, now);
                    }
                    Job::Write(i) => {
                        let slot = &mut self.writes[i];
                        slot.retry_at = now + self.period;
                        slot.failed_in_a_row = slot.failed_in_a_row.saturating_add(1);
                    }
                }
                let table_in_a_row = match job {
                    Job::Write(i) => self.writes[i].failed_in_a_row,
                    Job::Read(_) => 0,
                };
                if self.condition != Some(fault.condition()) {
                    self.condition = Some(fault.condition());
                    self.notices.push(Notice::Fault { ask, fault });
                }
                if self.lost {
                    self.retry_at = now + self.backoff;
                    self.backoff = (self.backoff * 2).min(self.reconnect.1);
                } else if self.in_a_row.max(table_in_a_row) >= self.loss_after {
                    self.lost = true;
                    self.lost_at = now;
                    stats.losses += 1;
                    self.retry_at = now + self.reconnect.0;
                    self.backoff = (self.reconnect.0 * 2).min(self.reconnect.1);
                    for slot in &mut self.reads {
                        slot.fresh = false;
                    }
                    if self.on_loss == OnLoss::Clear {
                        self.image.fill(0);
                    }
                    let failures = self.in_a_row.max(table_in_a_row);
                    self.notices.push(Notice::Lost { failures, on_loss: self.on_loss });
                }
            }
        }
        self.online = !self.lost && self.reads.iter().all(|slot| slot.fresh);
        stats.state = match (self.lost, self.online) {
            (true, _) => LinkState::Lost,
            (false, true) => LinkState::Online,
            (false, false) => LinkState::Starting,
        };
        drop(stats);
        self.publish();
    }

    /// The notices since the last call, oldest first.
    pub fn take_notices(&mut self) -> Vec<Notice> {
        std::mem::take(&mut self.notices)
    }

    fn publish(&mut self) {
        let buffer = self.inputs.input_buffer_mut();
        buffer.online = self.online;
        buffer.words.copy_from_slice(&self.image);
        self.inputs.publish();
    }
}

/// The next poll after one that was due at `due` and ran at `now`: a period later on the
/// same phase, or a period after `now` when the poll was more than a period late.
fn next_due(due: u64, period: u64, now: u64) -> u64 {
    let next = due + period;
    if next <= now {
        now + period
    } else {
        next
    }
}

/// The `swap_bytes` and `swap_words` of a register table, both ways (each is its own
/// inverse).
pub fn swap(table: &RemoteTable, values: &mut [u16]) {
    if table.swap_bytes {
        for value in values.iter_mut() {
            *value = value.swap_bytes();
        }
    }
    if table.swap_words {
        for pair in values.chunks_exact_mut(2) {
            pair.swap(0, 1);
        }
    }
}
