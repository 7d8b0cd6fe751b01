//! The two ways to a remote device, each a [`Transport`]: a Modbus TCP connection and a
//! Modbus RTU serial line shared by the devices on it. A [`Link`] carries one exchange at a
//! time, a request and its answer, over either, turns everything that can go wrong on the way
//! into a [`Fault`], and notes the round trip and the late answers dropped.
//!
//! Both run on a poller thread (not real time), so they block, each wait bounded by the
//! device's `timeout_ms`.

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use super::frame::{self, Ask, Fault, MAX_ADU, MBAP};
use crate::config::SerialLine;
use crate::io::serial::Port;

/// One exchange at a time with a device, over a TCP connection or an RTU line, and what it
/// notes about the last one.
pub struct Link {
    transport: Box<dyn Transport + Send>,
    tally: Tally,
}

/// What an exchange notes besides its result.
#[derive(Debug, Default)]
pub struct Tally {
    /// Answers dropped as too late for their request, since the last [`Link::take_late`].
    late: u32,
    /// When the exchange's request was sent, if it was.
    sent: Option<Instant>,
    round_trip_ns: Option<u64>,
}

/// A way to a device: one exchange, its faults classified.
pub trait Transport {
    /// Sends the request of `ask` to `unit` (a write's values from `values`) and checks the
    /// answer (a read's values into `values`); notes in `tally` when the request was sent and
    /// the late answers dropped on the way.
    fn exchange(
        &mut self,
        unit: u8,
        ask: &Ask,
        values: &mut [u16],
        timeout: Duration,
        tally: &mut Tally,
    ) -> Result<(), Fault>;
}

impl Link {
    pub fn tcp(address: &str) -> Link {
        Link { transport: Box::new(TcpLink::new(address)), tally: Tally::default() }
    }

    pub fn rtu(line: &SerialLine) -> Link {
        Link { transport: Box::new(RtuLink::new(line)), tally: Tally::default() }
    }

    /// See [`Transport::exchange`].
    pub fn exchange(
        &mut self,
        unit: u8,
        ask: &Ask,
        values: &mut [u16],
        timeout: Duration,
    ) -> Result<(), Fault> {
        self.tally.sent = None;
        let result = self.transport.exchange(unit, ask, values, timeout, &mut self.tally);
        self.tally.round_trip_ns = match result {
            // An exception is an answer.
            Ok(()) | Err(Fault::Exception(_)) => {
                self.tally.sent.map(|at| at.elapsed().as_nanos() as u64)
            }
            Err(_) => None,
        };
        result
    }

    /// Answers that came too late for their request and were dropped, since the last call.
    pub fn take_late(&mut self) -> u32 {
        std::mem::take(&mut self.tally.late)
    }

    /// The last exchange's round trip, ns: from its request sent (after the connect, after
    /// the line's silence) to its answer checked; `None` when no answer came.
    pub fn round_trip_ns(&self) -> Option<u64> {
        self.tally.round_trip_ns
    }
}

/// A Modbus TCP connection, made when needed and dropped when the stream cannot be trusted
/// any more (closed, an error, a frame cut short, garbage): the next exchange reconnects.
struct TcpLink {
    address: String,
    stream: Option<TcpStream>,
    next_tid: u16,
    buf: [u8; MAX_ADU],
}

/// How many of the latest transaction ids an answer may carry and count as late rather than
/// wrong.
const RECENT_TIDS: u16 = 64;

impl TcpLink {
    fn new(address: &str) -> TcpLink {
        TcpLink { address: address.to_string(), stream: None, next_tid: 1, buf: [0; MAX_ADU] }
    }

    fn connect(&mut self, timeout: Duration) -> Result<(), Fault> {
        if self.stream.is_none() {
            let addrs = self
                .address
                .to_socket_addrs()
                .map_err(|e| Fault::Connect(format!("cannot resolve {}: {e}", self.address)))?;
            let mut last = None;
            for addr in addrs {
                match TcpStream::connect_timeout(&addr, timeout) {
                    Ok(stream) => {
                        // Requests are small and each waits for its answer: send at once.
                        stream.set_nodelay(true).map_err(|e| Fault::Io(e.to_string()))?;
                        self.stream = Some(stream);
                        break;
                    }
                    Err(e) => last = Some(e),
                }
            }
            if self.stream.is_none() {
                return Err(Fault::Connect(match last {
                    Some(e) => e.to_string(),
                    None => format!("{} resolves to no address", self.address),
                }));
            }
        }
        Ok(())
    }

    fn exchange_on(
        &mut self,
        unit: u8,
        ask: &Ask,
        values: &mut [u16],
        timeout: Duration,
        tally: &mut Tally,
    ) -> Result<(), (Fault, bool)> {
        let tid = self.next_tid;
        self.next_tid = self.next_tid.wrapping_add(1);
        let len = frame::encode_tcp(tid, unit, ask, values, &mut self.buf);
        let request = self.buf;
        self.connect(timeout).map_err(|f| (f, false))?;
        let Some(stream) = self.stream.as_mut() else { unreachable!("connected above") };
        stream.set_write_timeout(Some(timeout)).map_err(|e| (Fault::Io(e.to_string()), true))?;
        stream.write_all(&request[..len]).map_err(|e| (io_fault(e), true))?;
        let sent = Instant::now();
        tally.sent = Some(sent);
        let deadline = sent + timeout;
        loop {
            let mut header = [0u8; MBAP];
            read_until(stream, &mut header, deadline)?;
            let (answer_tid, pdu_len) = frame::check_mbap(&header).map_err(|f| (f, true))?;
            let mut pdu = [0u8; MAX_ADU];
            // Its header is read: whatever stops the rest leaves the stream out of step.
            read_until(stream, &mut pdu[..pdu_len], deadline).map_err(|(f, _)| (f, true))?;
            if answer_tid != tid {
                // An answer to an earlier request that timed out: drop it, wait for ours.
                if tid.wrapping_sub(answer_tid) < RECENT_TIDS {
                    tally.late += 1;
                    continue;
                }
                return Err((Fault::WrongTransaction(answer_tid), false));
            }
            if header[6] != unit {
                return Err((Fault::WrongUnit(header[6]), false));
            }
            // An exception is an answer; an answer that does not fit the request is garbage,
            // and a stream that carried garbage cannot be trusted.
            return frame::check_answer(ask, &pdu[..pdu_len], values).map_err(|f| {
                let garbage = matches!(f, Fault::Garbage(_));
                (f, garbage)
            });
        }
    }
}

impl Transport for TcpLink {
    fn exchange(
        &mut self,
        unit: u8,
        ask: &Ask,
        values: &mut [u16],
        timeout: Duration,
        tally: &mut Tally,
    ) -> Result<(), Fault> {
        self.exchange_on(unit, ask, values, timeout, tally).map_err(|(fault, drop_stream)| {
            if drop_stream {
                self.stream = None;
            }
            fault
        })
    }
}

/// A socket error as a fault.
fn io_fault(e: io::Error) -> Fault {
    match e.kind() {
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut => Fault::Timeout,
        io::ErrorKind::ConnectionReset
        | io::ErrorKind::ConnectionAborted
        | io::ErrorKind::BrokenPipe
        | io::ErrorKind::UnexpectedEof => Fault::Closed,
        _ => Fault::Io(e.to_string()),
    }
}

/// Fills `buf` from the stream before `deadline`. The error says whether the stream must be
/// dropped: always, except for a timeout before the first byte (an answer may still come,
/// whole, and be recognized as late by its transaction id).
fn read_until(
    stream: &mut TcpStream,
    buf: &mut [u8],
    deadline: Instant,
) -> Result<(), (Fault, bool)> {
    let mut got = 0;
    while got < buf.len() {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err((Fault::Timeout, got > 0));
        }
        stream.set_read_timeout(Some(left)).map_err(|e| (Fault::Io(e.to_string()), true))?;
        match stream.read(&mut buf[got..]) {
            Ok(0) => return Err((Fault::Closed, true)),
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => {
                let fault = io_fault(e);
                let keep = fault == Fault::Timeout && got == 0;
                return Err((fault, !keep));
            }
        }
    }
    Ok(())
}

/// A serial line and the devices on it, polled in turn: before each request the line has
/// been silent for the frame gap (t3.5 or `frame_gap_us`), and whatever arrived since the
/// last answer (a late answer, noise) is dropped.
struct RtuLink {
    line: SerialLine,
    port: Option<Port>,
    /// When the line last carried a frame (or a frame's wait ended).
    quiet_since: Instant,
    buf: [u8; MAX_ADU],
}

/// Slack for a non-real-time thread between bytes of one answer: the kernel hands a UART's
/// bytes over in chunks, and the thread may not run at once.
const SCHEDULING_SLACK: Duration = Duration::from_millis(20);

impl RtuLink {
    fn new(line: &SerialLine) -> RtuLink {
        RtuLink { line: line.clone(), port: None, quiet_since: Instant::now(), buf: [0; MAX_ADU] }
    }

    fn exchange_on(
        &mut self,
        unit: u8,
        ask: &Ask,
        values: &mut [u16],
        timeout: Duration,
        tally: &mut Tally,
    ) -> Result<(), Fault> {
        if self.port.is_none() {
            let port = Port::open(&self.line).map_err(|e| Fault::Connect(e.to_string()))?;
            self.port = Some(port);
        }
        let port = self.port.as_mut().expect("opened above");
        let gap = Duration::from_nanos(self.line.frame_gap_ns());
        let since = self.quiet_since.elapsed();
        if since < gap {
            std::thread::sleep(gap - since);
        }
        // Anything waiting now is not the answer to the request about to go out.
        let stale = port
            .read_within(&mut self.buf, Duration::ZERO)
            .map_err(|e| Fault::Io(e.to_string()))?;
        if stale > 0 {
            tally.late += 1;
            port.discard_input().map_err(|e| Fault::Io(e.to_string()))?;
        }
        let mut request = [0u8; MAX_ADU];
        let len = frame::encode_rtu(unit, ask, values, &mut request);
        tally.sent = Some(Instant::now());
        port.send(&request[..len]).map_err(|e| Fault::Io(e.to_string()))?;
        let sent = Instant::now();
        // The answer must begin within the timeout, and then arrive at the line's rate.
        let mut deadline = sent + timeout;
        let mut got = 0;
        let mut expected = None;
        let result = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let n = match port.read_within(&mut self.buf[got..], left) {
                Ok(n) => n,
                Err(e) => break Err(Fault::Io(e.to_string())),
            };
            if n == 0 {
                break Err(match got {
                    0 => Fault::Timeout,
                    _ => Fault::Garbage(format!("a frame cut short after {got} bytes")),
                });
            }
            if got == 0 {
                let whole = Duration::from_nanos(
                    self.line.bytes_time_ns(MAX_ADU) + self.line.frame_gap_ns(),
                );
                deadline = Instant::now() + whole + SCHEDULING_SLACK;
            }
            got += n;
            if expected.is_none() {
                match frame::rtu_answer_len(&self.buf[..got]) {
                    Ok(len) => expected = len,
                    Err(fault) => break Err(fault),
                }
            }
            match expected {
                Some(len) if got > len => {
                    break Err(Fault::Garbage(format!("{} bytes after the answer", got - len)))
                }
                Some(len) if got == len => {
                    break frame::check_rtu(unit, &self.buf[..len])
                        .and_then(|pdu| frame::check_answer(ask, pdu, values))
                }
                _ if got == self.buf.len() => {
                    break Err(Fault::Garbage("a frame longer than 256 bytes".into()))
                }
                _ => {}
            }
        };
        self.quiet_since = Instant::now();
        result
    }
}

impl Transport for RtuLink {
    fn exchange(
        &mut self,
        unit: u8,
        ask: &Ask,
        values: &mut [u16],
        timeout: Duration,
        tally: &mut Tally,
    ) -> Result<(), Fault> {
        let result = self.exchange_on(unit, ask, values, timeout, tally);
        if let Err(Fault::Io(_)) = result {
            // A port that fails (an adapter unplugged) is opened again at the next exchange.
            self.port = None;
        }
        result
    }
}
