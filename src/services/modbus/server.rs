//! The Modbus servers of `[modbus]`: over TCP, a listener thread and one thread per
//! connection, none of them real time, bounded in number (`max_connections`), frame size
//! (`max_request_bytes`) and idle time (`idle_timeout_s`); on a serial line (`[modbus.rtu]`),
//! one thread ([`super::rtu`]). Both read the same mirror and write through the same queue.
//!
//! Blocking sockets and a thread per connection rather than one poll loop: a request waits
//! for a scan boundary (a read for the next mirror capture, a write until it was applied), and
//! with a thread each, every connection waiting meanwhile is served by the same capture.
//!
//! Framing: the MBAP header is read first; a protocol id other than 0 or a length outside
//! 2..=254 (a PDU needs a function code; the largest frame is 260 bytes) is no Modbus frame and
//! closes the connection, as does a function code of 128 or more, a connection that ends
//! inside a frame, or one that sends no complete request within `idle_timeout_s`. Anything
//! else gets an answer (docs/MODBUS.md lists the exceptions).

use std::collections::HashMap;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::os::fd::AsFd;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use modbus_core::tcp::Header;
use modbus_core::Exception;

use super::map::Map;
use super::pdu::{self, Plc, Scratch, HEADER, MAX_ADU};
use super::rtu;
use super::ModbusError;
use crate::config::ModbusConfig;
use crate::drivers::real_time::mirror::Mirror;
use crate::drivers::real_time::sys::{self, Wake};
use crate::drivers::real_time::PLAIN_THREAD_STACK;
use crate::drivers::real_time::{
    pending, Command, Shared, WordWrite, WordWrites, WORDS_PER_COMMAND,
};
use crate::io::serial::Port;

/// How long writing a response may take before the connection is given up (a client that
/// does not read).
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);
/// At most one warning about refused connections this often.
const REFUSED_WARN_EVERY: Duration = Duration::from_secs(10);

/// A bound server, not yet serving: the daemon binds before it starts the real-time threads
/// (so a port in use, or a serial port that cannot be opened, stops the start) and hands
/// [`ModbusServer::mirror`] to the driver.
pub struct ModbusServer {
    /// `[modbus] listen`, bound, and the address it has.
    tcp: Option<(TcpListener, SocketAddr)>,
    /// `[modbus.rtu]`'s port, open.
    rtu: Option<Port>,
    config: ModbusConfig,
    map: Arc<Map>,
    mirror: Arc<Mirror>,
}

/// What the server needs of the running driver.
pub struct ModbusLinks {
    pub shared: Arc<Shared>,
    /// The driver's command queue (shared with the other producers).
    pub commands: Arc<Mutex<rtrb::Producer<Command>>>,
}

/// A serving server; [`RunningServer::stop`] ends it.
pub struct RunningServer {
    local: Option<SocketAddr>,
    inner: Arc<Inner>,
    /// The TCP listener's thread.
    thread: Option<JoinHandle<()>>,
    /// The serial line's thread.
    rtu_thread: Option<JoinHandle<()>>,
}

struct Inner {
    config: ModbusConfig,
    map: Arc<Map>,
    scan: ScanPlc,
    stop: AtomicBool,
    wake: Wake,
    /// The open connections (a clone of each socket, to shut them down at stop).
    connections: Mutex<HashMap<u64, TcpStream>>,
    next_id: AtomicU64,
}

impl ModbusServer {
    /// Binds `[modbus] listen` and opens `[modbus.rtu]`'s port, those of them that are set;
    /// `None` when neither is (the server is off).
    pub fn bind(config: &ModbusConfig) -> Result<Option<ModbusServer>, ModbusError> {
        if config.listen.is_none() && config.rtu.is_none() {
            return Ok(None);
        }
        let tcp = match config.listen {
            Some(addr) => {
                let bind = |source| ModbusError::Bind { addr, source };
                let listener = TcpListener::bind(addr).map_err(bind)?;
                let local = listener.local_addr().map_err(bind)?;
                listener.set_nonblocking(true).map_err(bind)?;
                Some((listener, local))
            }
            None => None,
        };
        let rtu = match &config.rtu {
            Some(rtu) => Some(Port::open(&rtu.line).map_err(ModbusError::Serial)?),
            None => None,
        };
        let map = Arc::new(Map::new(config));
        let mirror = Arc::new(Mirror::new(map.mirror_ranges().iter().cloned()));
        Ok(Some(ModbusServer { tcp, rtu, config: config.clone(), map, mirror }))
    }

    /// The address it listens on (with the port chosen when `listen` said port 0); `None`
    /// without `listen`.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.tcp.as_ref().map(|(_, local)| *local)
    }

    /// The mirror of the mapped words, for [`crate::drivers::real_time::driver::Driver::start`].
    pub fn mirror(&self) -> Arc<Mirror> {
        Arc::clone(&self.mirror)
    }

    /// Starts the listener thread and the serial line's.
    pub fn start(self, links: ModbusLinks) -> Result<RunningServer, ModbusError> {
        let wake = Wake::new().map_err(|e| ModbusError::Sys(e.to_string()))?;
        let inner = Arc::new(Inner {
            scan: ScanPlc {
                shared: links.shared,
                commands: links.commands,
                mirror: self.mirror,
                seq: Mutex::new(0),
            },
            config: self.config,
            map: self.map,
            stop: AtomicBool::new(false),
            wake,
            connections: Mutex::new(HashMap::new()),
            next_id: AtomicU64::new(0),
        });
        // Stopped and joined on drop if the second thread cannot start.
        let mut running = RunningServer {
            local: self.tcp.as_ref().map(|(_, local)| *local),
            inner,
            thread: None,
            rtu_thread: None,
        };
        if let Some((listener, _)) = self.tcp {
            let inner = Arc::clone(&running.inner);
            let thread = std::thread::Builder::new()
                .name("plcd-modbus".into())
                .stack_size(PLAIN_THREAD_STACK)
                .spawn(move || inner.listen(listener))
                .map_err(|source| ModbusError::Spawn { source })?;
            running.thread = Some(thread);
        }
        if let Some(port) = self.rtu {
            let inner = Arc::clone(&running.inner);
            let thread = std::thread::Builder::new()
                .name("plcd-modbus-rtu".into())
                .stack_size(PLAIN_THREAD_STACK)
                .spawn(move || inner.serve_rtu(port))
                .map_err(|source| ModbusError::Spawn { source })?;
            running.rtu_thread = Some(thread);
        }
        Ok(running)
    }
}

impl RunningServer {
    /// The TCP address served, if any.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.local
    }

    /// What is served, for the log: the TCP address, `rtu PORT`.
    pub fn serving(&self) -> Vec<String> {
        let rtu = self.rtu_thread.as_ref().and(self.inner.config.rtu.as_ref());
        self.local
            .map(|local| local.to_string())
            .into_iter()
            .chain(rtu.map(|rtu| format!("rtu {}", rtu.line.port.display())))
            .collect()
    }

    /// Connections open now.
    pub fn connections(&self) -> usize {
        self.inner.connections.lock().map(|c| c.len()).unwrap_or(0)
    }

    /// Stops accepting, closes every connection (a request being answered finishes first,
    /// within `answer_timeout_ms`) and waits for the threads.
    pub fn stop(mut self) {
        self.shut();
    }

    fn shut(&mut self) {
        let (thread, rtu_thread) = (self.thread.take(), self.rtu_thread.take());
        if thread.is_none() && rtu_thread.is_none() {
            return;
        }
        self.inner.stop.store(true, Ordering::SeqCst);
        self.inner.wake.wake();
        if let Some(thread) = thread {
            let _ = thread.join();
        }
        // A request being answered finishes first, within `answer_timeout_ms`.
        if let Some(thread) = rtu_thread {
            let _ = thread.join();
        }
        if let Ok(connections) = self.inner.connections.lock() {
            for stream in connections.values() {
                let _ = stream.shutdown(Shutdown::Both);
            }
        }
        let until = Instant::now()
            + Duration::from_millis(u64::from(self.inner.config.answer_timeout_ms))
            + Duration::from_secs(1);
        while self.connections() > 0 && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for RunningServer {
    fn drop(&mut self) {
        self.shut();
    }
}

impl Inner {
    fn serve_rtu(self: Arc<Self>, port: Port) {
        let Some(rtu) = &self.config.rtu else { return };
        let answer_timeout = Duration::from_millis(u64::from(self.config.answer_timeout_ms));
        rtu::serve(port, rtu, &self.map, &self.scan, answer_timeout, &self.stop);
    }

    fn listen(self: Arc<Self>, listener: TcpListener) {
        let mut last_warned: Option<Instant> = None;
        let mut refused = 0u64;
        while !self.stop.load(Ordering::SeqCst) {
            let _ = sys::wait_readable(&[listener.as_fd(), self.wake.as_fd()], None);
            if self.stop.load(Ordering::SeqCst) {
                break;
            }
            loop {
                let (stream, peer) = match listener.accept() {
                    Ok(accepted) => accepted,
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        // Out of descriptors, most likely: the listener stays readable.
                        log::warn!("modbus: accept: {e}");
                        std::thread::sleep(Duration::from_millis(100));
                        break;
                    }
                };
                if !self.admit(stream, peer) {
                    refused += 1;
                    if last_warned.is_none_or(|at| at.elapsed() >= REFUSED_WARN_EVERY) {
                        last_warned = Some(Instant::now());
                        log::warn!(
                            "modbus: {peer} refused: {} connections open ([modbus] \
                             max_connections); {refused} refused so far",
                            self.config.max_connections
                        );
                    }
                }
            }
        }
    }

    /// Starts serving a connection; false if the limit is reached (it is closed).
    fn admit(self: &Arc<Self>, stream: TcpStream, peer: SocketAddr) -> bool {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        {
            let mut connections = self.connections.lock().unwrap_or_else(|e| e.into_inner());
            if connections.len() >= self.config.max_connections as usize {
                return false;
            }
            let Ok(clone) = stream.try_clone() else { return false };
            connections.insert(id, clone);
        }
        let inner = Arc::clone(self);
        let spawned = std::thread::Builder::new()
            .name("plcd-modbus-conn".into())
            .stack_size(PLAIN_THREAD_STACK)
            .spawn(move || {
                log::debug!("modbus: {peer} connected");
                let mut stream = stream;
                let why = inner.serve(&mut stream);
                // Out of the table before the socket closes: a client that saw the close
                // finds the room it left.
                inner.connections.lock().unwrap_or_else(|e| e.into_inner()).remove(&id);
                drop(stream);
                log::debug!("modbus: {peer} closed: {why}");
            });
        if let Err(e) = spawned {
            log::warn!("modbus: cannot serve {peer}: {e}");
            self.connections.lock().unwrap_or_else(|e| e.into_inner()).remove(&id);
            return false;
        }
        true
    }

    /// Serves one connection until it closes; why it ended.
    fn serve(&self, stream: &mut TcpStream) -> String {
        let _ = stream.set_nonblocking(false);
        let _ = stream.set_nodelay(true);
        let _ = stream.set_write_timeout(Some(WRITE_TIMEOUT));
        let idle = match self.config.idle_timeout_s {
            0 => None,
            s => Some(Duration::from_secs(u64::from(s))),
        };
        let answer_timeout = Duration::from_millis(u64::from(self.config.answer_timeout_ms));
        let mut frame = [0u8; MAX_ADU];
        let mut scratch = Box::<Scratch>::default();
        loop {
            let deadline = idle.map(|d| Instant::now() + d);
            match read_exact(stream, &mut frame[..HEADER], deadline) {
                Ok(()) => {}
                Err(ReadEnd::Closed(0)) => return "by the client".into(),
                Err(end) => return end.why("the MBAP header"),
            }
            let header: &[u8; HEADER] = frame[..HEADER].try_into().expect("the header");
            let size = match frame_size(header) {
                Ok(size) => size,
                Err(why) => return why,
            };
            if let Err(end) = read_exact(stream, &mut frame[HEADER..size], deadline) {
                return end.why("the PDU");
            }
            let deadline = Instant::now() + answer_timeout;
            let answer = answer_frame(
                &self.map,
                &self.scan,
                &self.config,
                &frame[..size],
                deadline,
                &mut scratch,
            );
            let n = match answer {
                Ok(n) => n,
                Err(why) => return why,
            };
            if let Err(e) = stream.write_all(&scratch.out[..n]) {
                return format!("writing the response: {e}");
            }
        }
    }
}

/// The size of the frame an MBAP header starts (header and PDU), or why it is no Modbus frame
/// and the connection ends: a protocol id other than 0, a length outside 2..=254.
pub fn frame_size(header: &[u8; HEADER]) -> Result<usize, String> {
    let protocol = u16::from_be_bytes([header[2], header[3]]);
    let length = usize::from(u16::from_be_bytes([header[4], header[5]]));
    if protocol != 0 {
        return Err(format!("protocol id {protocol:#06x} is not Modbus"));
    }
    if !(2..=MAX_ADU - 6).contains(&length) {
        return Err(format!("MBAP length {length} is outside 2..=254"));
    }
    Ok(6 + length)
}

/// Answers one whole frame (the MBAP header of [`frame_size`], then the PDU) into
/// `scratch.out`: the response's length, or why the connection ends (a function code of 128
/// or more). A frame longer than `max_request_bytes` is answered with exception 03.
pub fn answer_frame(
    map: &Map,
    plc: &dyn Plc,
    config: &ModbusConfig,
    frame: &[u8],
    deadline: Instant,
    scratch: &mut Scratch,
) -> Result<usize, String> {
    let hdr =
        Header { transaction_id: u16::from_be_bytes([frame[0], frame[1]]), unit_id: frame[6] };
    let pdu = &frame[HEADER..];
    if frame.len() > config.max_request_bytes as usize {
        return Ok(pdu::exception(hdr, pdu[0], Exception::IllegalDataValue, &mut scratch.out));
    }
    pdu::answer(map, plc, config.unit_id, hdr, pdu, deadline, scratch)
        .ok_or_else(|| format!("function code {:#04x} is no request", pdu[0]))
}

enum ReadEnd {
    /// End of stream after this many bytes of what was wanted.
    Closed(usize),
    Idle,
    Error(io::Error),
}

impl ReadEnd {
    fn why(&self, what: &str) -> String {
        match self {
            ReadEnd::Closed(n) => format!("the connection ended {n} bytes into {what}"),
            ReadEnd::Idle => "idle timeout ([modbus] idle_timeout_s)".into(),
            ReadEnd::Error(e) => format!("reading {what}: {e}"),
        }
    }
}

/// Fills `buf`, giving up at `deadline`.
fn read_exact(
    stream: &mut TcpStream,
    buf: &mut [u8],
    deadline: Option<Instant>,
) -> Result<(), ReadEnd> {
    let mut at = 0;
    while at < buf.len() {
        if let Some(deadline) = deadline {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(ReadEnd::Idle);
            }
            let _ = stream.set_read_timeout(Some(left));
        }
        match stream.read(&mut buf[at..]) {
            Ok(0) => return Err(ReadEnd::Closed(at)),
            Ok(n) => at += n,
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                return Err(ReadEnd::Idle)
            }
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(ReadEnd::Error(e)),
        }
    }
    Ok(())
}

/// The PLC behind the driver's queues: reads from the mirror, writes as [`Command::Words`].
struct ScanPlc {
    shared: Arc<Shared>,
    commands: Arc<Mutex<rtrb::Producer<Command>>>,
    mirror: Arc<Mirror>,
    /// The last sequence number given out; taken with the queue held, so that numbers rise
    /// in queue order.
    seq: Mutex<u64>,
}

impl Plc for ScanPlc {
    fn read(&self, deadline: Instant, read: &mut dyn FnMut(&[u16])) -> Result<(), Exception> {
        let generation = self.mirror.lock().generation;
        self.mirror.request();
        self.shared.signal(pending::MIRROR);
        let left = deadline.saturating_duration_since(Instant::now());
        let image = self.mirror.wait_newer(generation, left);
        if image.generation <= generation {
            return Err(Exception::ServerDeviceFailure);
        }
        read(&image.words);
        Ok(())
    }

    fn running(&self) -> bool {
        self.shared.mode() == crate::engine::event::Mode::Run
    }

    fn write(&self, writes: &[WordWrite], deadline: Instant) -> Result<(), Exception> {
        if writes.is_empty() {
            return Ok(());
        }
        let parts = writes.len().div_ceil(WORDS_PER_COMMAND);
        let seq = {
            let mut queue = self.commands.lock().unwrap_or_else(|e| e.into_inner());
            let Ok(chunk) = queue.write_chunk_uninit(parts) else {
                return Err(Exception::ServerDeviceBusy);
            };
            let mut last = self.seq.lock().unwrap_or_else(|e| e.into_inner());
            *last += 1;
            let seq = *last;
            // One chunk: the scan thread sees all parts or none, and applies them in one pass.
            chunk.fill_from_iter(writes.chunks(WORDS_PER_COMMAND).enumerate().map(|(i, part)| {
                let mut items = [WordWrite::default(); WORDS_PER_COMMAND];
                items[..part.len()].copy_from_slice(part);
                Command::Words(WordWrites {
                    seq,
                    last: i + 1 == parts,
                    len: part.len() as u8,
                    items,
                })
            }));
            seq
        };
        // Every mirror capture comes after the commands of its boundary were applied, so a
        // capture is the moment to look whether ours were.
        loop {
            let generation = self.mirror.lock().generation;
            if self.shared.words_applied.load(Ordering::Acquire) >= seq {
                return Ok(());
            }
            self.mirror.request();
            self.shared.signal(pending::COMMAND | pending::MIRROR);
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(Exception::ServerDeviceFailure);
            }
            drop(self.mirror.wait_newer(generation, left));
        }
    }
}
