//! Remote I/O: Modbus TCP and RTU devices polled by `plcd run` (`[[remote]]`,
//! docs/REMOTE.md), an I/O source beside the field backend.
//!
//! - [`frame`]: requests encoded, answers checked against them (over `modbus-core`);
//! - [`link`]: a TCP connection or an RTU line, one exchange at a time, faults classified;
//! - [`poller`]: a device's schedule, health, backoff and counters, on a clock tests set;
//! - [`threads`]: the poller threads (one per TCP device, one per RTU port);
//! - here: [`RemoteIo`], the scan thread's side, and [`RemoteService`], which owns the
//!   threads.
//!
//! The scan never waits for a device. Each device and the scan thread share two triple
//! buffers (wait-free, allocated at start): the poller publishes the whole inputs image after
//! each read (so a table is never half old, half new), the scan thread takes the newest at its
//! input refresh; the scan thread publishes its write tables at each output refresh and wakes
//! the poller when they changed, and the poller writes what changed after it.

pub mod frame;
pub mod link;
pub mod poller;
pub mod threads;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{JoinHandle, Thread};
use std::time::Instant;

use crate::config::{RemoteDevice, RemoteTable, RemoteTransport};
use crate::device::{BitRef, Memory};
use frame::words_of;
use poller::{DeviceStats, InputImage, OutputImage, Poller};

/// Why remote I/O could not start.
#[derive(Debug, thiserror::Error)]
pub enum RemoteError {
    #[error("{0} remote devices; at most {max}", max = RemoteDevice::MAX_DEVICES)]
    TooMany(usize),
    #[error("cannot start the poller thread of remote {name}: {source}")]
    Spawn {
        name: String,
        #[source]
        source: std::io::Error,
    },
}

/// The scan thread's side of every remote device: see the module documentation.
#[derive(Default)]
pub struct RemoteIo {
    devices: Vec<ScanSide>,
    /// The poller threads, one per TCP device or RTU port.
    threads: Vec<Thread>,
    safe: Arc<AtomicBool>,
}

struct ScanSide {
    inputs: triple_buffer::Output<InputImage>,
    reads: Vec<(RemoteTable, usize)>,
    status: Option<BitRef>,
    outputs: triple_buffer::Input<OutputImage>,
    writes: Vec<(RemoteTable, usize)>,
    /// The write tables as last published.
    last: Vec<u16>,
    captured: bool,
    /// Its poller thread, an index into [`RemoteIo::threads`].
    thread: usize,
}

impl RemoteIo {
    /// Copies each device's newest inputs image into device memory, and its status bit.
    pub fn refresh_inputs(&mut self, mem: &mut Memory) {
        for device in &mut self.devices {
            let image = device.inputs.read();
            let words = mem.words_mut();
            for (table, offset) in &device.reads {
                let values = &image.words[*offset..*offset + words_of(table)];
                if table.table.is_bits() {
                    for k in 0..usize::from(table.count) {
                        let bit = table.first as usize + k;
                        let on = values[k / 16] >> (k % 16) & 1 != 0;
                        let mask = 1u16 << (bit % 16);
                        let word = &mut words[bit / 16];
                        *word = if on { *word | mask } else { *word & !mask };
                    }
                } else {
                    let first = table.first as usize;
                    words[first..first + values.len()].copy_from_slice(values);
                }
            }
            if let Some(status) = device.status {
                mem.set_bit(status, image.online);
            }
        }
    }

    /// Publishes each device's write tables, waking its poller when they changed.
    pub fn refresh_outputs(&mut self, mem: &Memory) {
        // Outputs published again: the safe state of a watchdog trip is over.
        self.safe.store(false, Ordering::Release);
        // Each poller thread is woken once, however many of its devices changed (the devices
        // of one serial port share a thread): a wake-up is a system call.
        let mut wake: u64 = 0;
        for device in &mut self.devices {
            if device.writes.is_empty() {
                continue;
            }
            let buffer = device.outputs.input_buffer_mut();
            buffer.captured = true;
            let words = mem.words();
            for (table, offset) in &device.writes {
                let values = &mut buffer.words[*offset..*offset + words_of(table)];
                if table.table.is_bits() {
                    values.fill(0);
                    for k in 0..usize::from(table.count) {
                        let bit = table.first as usize + k;
                        if words[bit / 16] >> (bit % 16) & 1 != 0 {
                            values[k / 16] |= 1 << (k % 16);
                        }
                    }
                } else {
                    let first = table.first as usize;
                    values.copy_from_slice(&words[first..first + values.len()]);
                }
            }
            let changed = !device.captured || device.last != buffer.words;
            if changed {
                device.last.copy_from_slice(&buffer.words);
            }
            device.captured = true;
            device.outputs.publish();
            if changed {
                wake |= 1 << device.thread;
            }
        }
        while wake != 0 {
            let thread = wake.trailing_zeros() as usize;
            wake &= wake - 1;
            if let Some(thread) = self.threads.get(thread) {
                thread.unpark();
            }
        }
    }

    /// True for a P bit that a remote read table feeds.
    pub fn is_input(&self, bit: BitRef) -> bool {
        let index = u32::from(bit.word) * 16 + bit.mask.trailing_zeros();
        self.devices.iter().flat_map(|d| &d.reads).any(|(table, _)| table.bits().contains(&index))
    }

    /// The remote outputs' safe state, for the watchdog thread.
    pub fn safe_state(&self) -> RemoteSafeState {
        RemoteSafeState { safe: Arc::clone(&self.safe), threads: self.threads.clone() }
    }
}

/// Sets every remote write table to 0, from any thread: the pollers write zeros until the
/// scan thread publishes outputs again.
#[derive(Clone, Default)]
pub struct RemoteSafeState {
    safe: Arc<AtomicBool>,
    threads: Vec<Thread>,
}

impl RemoteSafeState {
    pub fn apply(&self) {
        self.safe.store(true, Ordering::Release);
        for thread in &self.threads {
            thread.unpark();
        }
    }
}

/// A device's figures, for `plcctl status`.
#[derive(Debug, Clone)]
pub struct DeviceReport {
    pub name: String,
    pub transport: String,
    pub stats: DeviceStats,
    /// How long ago the last error was, ms.
    pub last_error_age_ms: Option<u64>,
}

/// Every device's counters, for the status request (cheap to clone, any thread).
#[derive(Clone)]
pub struct RemoteBoard {
    devices: Arc<[BoardEntry]>,
    epoch: Instant,
}

/// One device on the board.
struct BoardEntry {
    name: String,
    transport: String,
    stats: Arc<Mutex<DeviceStats>>,
}

impl Default for RemoteBoard {
    fn default() -> Self {
        RemoteBoard { devices: Arc::new([]), epoch: Instant::now() }
    }
}

impl RemoteBoard {
    /// Every device's figures now, in config order.
    pub fn reports(&self) -> Vec<DeviceReport> {
        let now = self.epoch.elapsed().as_nanos() as u64;
        self.devices
            .iter()
            .map(|BoardEntry { name, transport, stats }| {
                let stats = stats.lock().unwrap_or_else(|p| p.into_inner()).clone();
                DeviceReport {
                    name: name.clone(),
                    transport: transport.clone(),
                    last_error_age_ms: stats
                        .last_error
                        .as_ref()
                        .map(|(_, at)| now.saturating_sub(*at) / 1_000_000),
                    stats,
                }
            })
            .collect()
    }
}

/// The poller threads; dropping it stops them (after their last writes) and joins them.
pub struct RemoteService {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    board: RemoteBoard,
}

impl RemoteService {
    pub fn board(&self) -> RemoteBoard {
        self.board.clone()
    }
}

impl Drop for RemoteService {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        for handle in &self.threads {
            handle.thread().unpark();
        }
        for handle in self.threads.drain(..) {
            let _ = handle.join();
        }
    }
}

/// Starts a poller thread for each TCP device and each RTU port; returns the scan thread's
/// side and the service that owns the threads. Nothing is connected yet: a device that does
/// not answer is lost and tried again, it does not stop the start.
pub fn start(devices: &[RemoteDevice]) -> Result<(RemoteIo, RemoteService), RemoteError> {
    // The wake-up mask of `RemoteIo::refresh_outputs` has a bit per poller thread.
    const _: () = assert!(RemoteDevice::MAX_DEVICES <= 64);
    if devices.len() > RemoteDevice::MAX_DEVICES {
        return Err(RemoteError::TooMany(devices.len()));
    }
    let epoch = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let safe = Arc::new(AtomicBool::new(false));
    let mut io = RemoteIo { devices: Vec::new(), threads: Vec::new(), safe: Arc::clone(&safe) };
    let mut handles = Vec::new();
    let mut boards = Vec::new();
    // Devices grouped by link: each TCP device alone, RTU devices by port. `members` are
    // indices into `io.devices`, whose threads are known once the group's thread runs.
    let mut groups: Vec<(threads::Group, Vec<usize>, String)> = Vec::new();
    for device in devices {
        log::info!(
            "remote {}: polling {} unit {} every {} ms ({} read and {} write tables)",
            device.name,
            device.transport.describe(),
            device.unit_id,
            device.shortest_period_ms(),
            device.reads.len(),
            device.writes.len()
        );
        let (scan_side, poller) = pair(device, &safe);
        boards.push(BoardEntry {
            name: device.name.clone(),
            transport: device.transport.describe(),
            stats: poller.stats(),
        });
        io.devices.push(scan_side);
        let index = io.devices.len() - 1;
        let shared_port = match &device.transport {
            RemoteTransport::Rtu(line) => {
                groups.iter().position(|(_, _, key)| *key == format!("rtu {}", line.port.display()))
            }
            RemoteTransport::Tcp { .. } => None,
        };
        match shared_port {
            Some(g) => {
                groups[g].0.pollers.push(poller);
                groups[g].1.push(index);
            }
            None => {
                let link = match &device.transport {
                    RemoteTransport::Tcp { address } => link::Link::tcp(address),
                    RemoteTransport::Rtu(line) => link::Link::rtu(line),
                };
                let key = match &device.transport {
                    RemoteTransport::Tcp { .. } => format!("tcp {}", device.name),
                    RemoteTransport::Rtu(line) => format!("rtu {}", line.port.display()),
                };
                groups.push((threads::Group { pollers: vec![poller], link }, vec![index], key));
            }
        }
    }
    for (group, members, _) in groups {
        let name = group.pollers[0].name.clone();
        let stop = Arc::clone(&stop);
        let handle = std::thread::Builder::new()
            .name(format!("remote-{name}"))
            .spawn(move || threads::run(group, stop, epoch))
            .map_err(|source| RemoteError::Spawn { name, source })?;
        for index in members {
            io.devices[index].thread = io.threads.len();
        }
        io.threads.push(handle.thread().clone());
        handles.push(handle);
    }
    let board = RemoteBoard { devices: boards.into(), epoch };
    Ok((io, RemoteService { stop, threads: handles, board }))
}

/// A device's scan side and poller, joined by their two triple buffers.
fn pair(device: &RemoteDevice, safe: &Arc<AtomicBool>) -> (ScanSide, Poller) {
    let mut offset = 0;
    let reads: Vec<(RemoteTable, usize)> = device
        .reads
        .iter()
        .map(|read| {
            let at = offset;
            offset += words_of(&read.table);
            (read.table, at)
        })
        .collect();
    let (inputs_tx, inputs_rx) =
        triple_buffer::triple_buffer(&InputImage { online: false, words: vec![0; offset] });
    let mut offset = 0;
    let writes: Vec<(RemoteTable, usize)> = device
        .writes
        .iter()
        .map(|write| {
            let at = offset;
            offset += words_of(&write.table);
            (write.table, at)
        })
        .collect();
    let (outputs_tx, outputs_rx) =
        triple_buffer::triple_buffer(&OutputImage { captured: false, words: vec![0; offset] });
    let poller = Poller::new(device, inputs_tx, outputs_rx, Arc::clone(safe));
    let scan = ScanSide {
        inputs: inputs_rx,
        reads,
        status: device.status.map(|s| s.bit),
        outputs: outputs_tx,
        writes,
        last: vec![0; offset],
        captured: false,
        thread: 0,
    };
    (scan, poller)
}

#[cfg(test)]
pub(crate) fn pair_for_tests(device: &RemoteDevice) -> (RemoteIo, Poller) {
    let safe = Arc::new(AtomicBool::new(false));
    let (scan, poller) = pair(device, &safe);
    (RemoteIo { devices: vec![scan], threads: Vec::new(), safe }, poller)
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod link_tests;
