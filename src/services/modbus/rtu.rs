//! The Modbus RTU server: the `[modbus]` register map served on a serial line
//! (`[modbus.rtu]`), one thread, not real time, with the requests answered by [`pdu`] as the
//! TCP server answers them and the same [`Plc`] (reads from the mirror, writes at a scan
//! boundary).
//!
//! - [`Framer`]: bytes and the times they arrived in, frames out. A frame ends at the length
//!   its function code gives ([`expected_len`]) once the CRC there is right, or at a silence
//!   of more than t1.5; a frame whose function code says it is longer than what came waits
//!   [`PIECE_GAP_NS`] for the rest (USB serial adapters hand a long frame over in pieces). A
//!   bad CRC, fewer than 4 bytes or more than 256 is a bad frame, dropped. Pure: tested on
//!   literals in virtual time.
//! - [`Counters`] and [`CounterLog`]: what the line saw, and the log lines worth writing about
//!   it (not one a frame).
//! - [`serve`]: the thread's loop over a [`Port`]: requests to `unit_id` answered after t3.5
//!   of silence, broadcasts (unit 0) that write carried out and not answered, everything else
//!   ignored; a port that fails is reopened every second.
//!
//! modbus-core gives the CRC and encodes the responses. Its `rtu::request_pdu_len` is not used:
//! in 0.2 it takes the byte count of FC 15 and 16 from the quantity's high byte (ADU offset 4
//! instead of 6), so it cuts every such request short, and it does not know FC 43.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use modbus_core::rtu::crc16;

use super::map::Map;
use super::pdu::{self, Plc, Scratch};
use crate::config::ModbusRtuConfig;
use crate::drivers::real_time::sys::now_ns;
use crate::io::serial::Port;

/// The longest RTU frame: address, a PDU of at most 253 bytes, CRC.
pub const MAX_FRAME: usize = modbus_core::rtu::MAX_FRAME_LEN;
/// The shortest: address, function code, CRC.
pub const MIN_FRAME: usize = 4;
/// How long a frame whose function code says it is longer than what came waits for the rest:
/// above the 16 ms latency timer of FTDI adapters, which deliver a long frame in pieces with
/// gaps far longer than t1.5 at high baud rates. A frame that is complete (its CRC is right)
/// ends at t1.5 all the same: another server's response on a shared line does.
pub const PIECE_GAP_NS: u64 = 30_000_000;
/// How long the loop waits for a byte before it looks at the stop flag.
const IDLE: Duration = Duration::from_millis(100);
/// How often a port that failed is opened again.
const REOPEN_EVERY: Duration = Duration::from_secs(1);
/// At most one warning about bad frames this often.
pub const BAD_WARN_EVERY_NS: u64 = 10_000_000_000;
/// Bytes taken from the port at once.
const READ_CHUNK: usize = 512;

/// How long a request frame is, as far as its first bytes tell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expected {
    /// The whole frame (address to CRC) has this many bytes.
    Len(usize),
    /// The function code has a length, but the bytes that give it have not come yet.
    More,
    /// A function code whose requests have no fixed length here: the frame ends at a silence.
    Unknown,
}

/// The length of the request frame that starts `adu` (address, function code, …), by its
/// function code (MODBUS application protocol, chapter 6).
pub fn expected_len(adu: &[u8]) -> Expected {
    let Some(&fc) = adu.get(1) else { return Expected::More };
    // The frame's length when byte `at` is there: `base` + that byte.
    let counted = |at: usize, base: usize| match adu.get(at) {
        Some(&count) => Expected::Len(base + usize::from(count)),
        None => Expected::More,
    };
    match fc {
        0x01..=0x06 => Expected::Len(8),
        0x07 | 0x0B | 0x0C | 0x11 => Expected::Len(4),
        // Address 2, quantity 2, byte count 1, the values.
        0x0F | 0x10 => counted(6, 9),
        0x16 => Expected::Len(10),
        // Read address and quantity, write address and quantity, byte count, the values.
        0x17 => counted(10, 13),
        0x18 => Expected::Len(6),
        // MEI type 14 (device identification): read code and object id.
        0x2B => match adu.get(2) {
            Some(0x0E) => Expected::Len(7),
            Some(_) => Expected::Unknown,
            None => Expected::More,
        },
        _ => Expected::Unknown,
    }
}

/// Whether `adu` ends with the CRC of the bytes before it.
pub fn crc_ok(adu: &[u8]) -> bool {
    adu.len() >= MIN_FRAME && {
        let (body, crc) = adu.split_at(adu.len() - 2);
        crc16(body) == u16::from_be_bytes([crc[0], crc[1]])
    }
}

/// `adu` (address and PDU) with its CRC appended.
pub fn with_crc(adu: &[u8]) -> Vec<u8> {
    let mut frame = adu.to_vec();
    frame.extend_from_slice(&crc16(adu).to_be_bytes());
    frame
}

/// What [`Framer::next`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Received {
    /// A frame with a good CRC, this many bytes (CRC included), copied to the caller's buffer.
    Frame(usize),
    /// Bytes that made no frame: a bad CRC, fewer than [`MIN_FRAME`] or more than
    /// [`MAX_FRAME`] bytes. Dropped.
    Bad,
}

/// Frames from the bytes of a serial line and the times they came (ns of any monotonic clock).
#[derive(Debug)]
pub struct Framer {
    /// Bytes received and not yet framed.
    buf: Vec<u8>,
    /// When the last byte came.
    last_ns: u64,
    /// More than [`MAX_FRAME`] bytes came without a silence: everything up to the next one is
    /// dropped.
    garbled: bool,
    /// t1.5.
    char_gap_ns: u64,
}

impl Framer {
    pub fn new(char_gap_ns: u64) -> Framer {
        Framer {
            buf: Vec::with_capacity(MAX_FRAME + READ_CHUNK),
            last_ns: 0,
            garbled: false,
            char_gap_ns,
        }
    }

    /// `bytes` came at `now_ns`.
    pub fn push(&mut self, bytes: &[u8], now_ns: u64) {
        if bytes.is_empty() {
            return;
        }
        self.last_ns = now_ns;
        if !self.garbled {
            self.buf.extend_from_slice(bytes);
        }
    }

    /// When the last byte came.
    pub fn last_ns(&self) -> u64 {
        self.last_ns
    }

    /// From when on a silence ends what has come (the next [`Framer::next`] returns it); `None`
    /// when nothing is pending.
    pub fn deadline(&self) -> Option<u64> {
        if self.buf.is_empty() && !self.garbled {
            return None;
        }
        Some(self.last_ns + self.gap_ns() + 1)
    }

    /// The next frame or bad frame, as of `now_ns`; a frame is copied into `frame`.
    pub fn next(&mut self, now_ns: u64, frame: &mut [u8; MAX_FRAME]) -> Option<Received> {
        if !self.garbled {
            if let Expected::Len(n) = expected_len(&self.buf) {
                if n <= MAX_FRAME && self.buf.len() >= n && crc_ok(&self.buf[..n]) {
                    frame[..n].copy_from_slice(&self.buf[..n]);
                    self.buf.drain(..n);
                    return Some(Received::Frame(n));
                }
            }
            if self.buf.len() > MAX_FRAME {
                self.buf.clear();
                self.garbled = true;
            }
        }
        let deadline = self.deadline()?;
        if now_ns < deadline {
            return None;
        }
        // A silence: what came is one frame.
        let garbled = std::mem::take(&mut self.garbled);
        let n = self.buf.len();
        let ok = !garbled && n <= MAX_FRAME && crc_ok(&self.buf);
        if ok {
            frame[..n].copy_from_slice(&self.buf);
        }
        self.buf.clear();
        Some(if ok { Received::Frame(n) } else { Received::Bad })
    }

    /// The silence that ends what has come: t1.5, or [`PIECE_GAP_NS`] for the start of a frame
    /// whose function code says more is to come.
    fn gap_ns(&self) -> u64 {
        let short = match expected_len(&self.buf) {
            Expected::Len(n) => self.buf.len() < n && !crc_ok(&self.buf),
            Expected::More => true,
            Expected::Unknown => false,
        };
        if short && !self.garbled {
            self.char_gap_ns.max(PIECE_GAP_NS)
        } else {
            self.char_gap_ns
        }
    }
}

/// What the line saw since the server started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Frames with a good CRC, to any address.
    pub frames: u64,
    /// Responses sent (exceptions included).
    pub answered: u64,
    /// Broadcasts (address 0) of a function that writes, carried out and not answered.
    pub broadcasts: u64,
    /// Frames to another address, broadcasts of a function that does not write, and frames
    /// whose function code is 128 or more (responses).
    pub ignored: u64,
    /// Bad frames dropped: a bad CRC, garbage, too short or too long.
    pub crc_errors: u64,
    /// The address of the first frame to another server.
    pub first_other_unit: Option<u8>,
}

/// Handles one frame with a good CRC (the address, the PDU and the CRC, as [`Framer::next`]
/// gives it) for server `unit_id`, and counts it: the length of the answer in `scratch.out`
/// to send once the line is quiet, or `None` when none is due (another unit, a broadcast, a
/// response, a function a broadcast may not carry).
pub fn answer_frame(
    map: &Map,
    plc: &dyn Plc,
    unit_id: u8,
    frame: &[u8],
    deadline: Instant,
    scratch: &mut Scratch,
    counters: &mut Counters,
) -> Option<usize> {
    counters.frames += 1;
    let (unit, pdu) = (frame[0], &frame[1..frame.len() - 2]);
    let broadcast = unit == 0;
    if unit != unit_id && !broadcast {
        counters.ignored += 1;
        counters.first_other_unit.get_or_insert(unit);
        return None;
    }
    if pdu[0] >= 0x80 || (broadcast && !pdu::writes(pdu[0])) {
        counters.ignored += 1;
        return None;
    }
    let answer = pdu::answer_rtu(map, plc, unit_id, pdu, deadline, scratch);
    if broadcast {
        counters.broadcasts += 1;
        return None;
    }
    answer
}

/// The log lines about a line's counters: what matters, not every frame.
#[derive(Debug)]
pub struct CounterLog {
    port: String,
    unit_id: u8,
    seen: Counters,
    /// When bad frames were last warned about.
    warned_ns: Option<u64>,
}

impl CounterLog {
    pub fn new(port: &str, unit_id: u8) -> CounterLog {
        CounterLog { port: port.to_string(), unit_id, seen: Counters::default(), warned_ns: None }
    }

    /// The lines to log now that the counters are `now`: the first request served, the first
    /// request to another address, and bad frames (at most every
    /// [`BAD_WARN_EVERY_NS`], with how many since the last warning).
    pub fn update(&mut self, now: &Counters, now_ns: u64) -> Vec<(log::Level, String)> {
        let mut lines = Vec::new();
        let port = &self.port;
        let served = |c: &Counters| c.answered + c.broadcasts;
        if served(&self.seen) == 0 && served(now) > 0 {
            lines.push((log::Level::Info, format!("modbus: rtu {port}: the first request served")));
        }
        if let (None, Some(unit)) = (self.seen.first_other_unit, now.first_other_unit) {
            lines.push((
                log::Level::Info,
                format!(
                    "modbus: rtu {port}: a request to unit {unit} ignored: this server is unit {} \
                     ([modbus.rtu] unit_id); requests to other units are counted, not logged",
                    self.unit_id
                ),
            ));
        }
        let bad = now.crc_errors - self.seen.crc_errors;
        let due = self.warned_ns.is_none_or(|at| now_ns.saturating_sub(at) >= BAD_WARN_EVERY_NS);
        let crc_errors = if bad > 0 && due {
            self.warned_ns = Some(now_ns);
            lines.push((
                log::Level::Warn,
                format!(
                    "modbus: rtu {port}: {bad} bad frames dropped (a bad CRC or garbled); {} of \
                     {} in all: check the baud rate, parity and wiring if this goes on",
                    now.crc_errors,
                    now.frames + now.crc_errors
                ),
            ));
            now.crc_errors
        } else {
            self.seen.crc_errors
        };
        self.seen = Counters { crc_errors, ..*now };
        lines
    }

    /// The totals, for the log at stop.
    pub fn totals(&self, c: &Counters) -> String {
        format!(
            "modbus: rtu {}: {} frames: {} answered, {} broadcasts carried out, {} ignored; {} bad \
             frames dropped",
            self.port, c.frames, c.answered, c.broadcasts, c.ignored, c.crc_errors
        )
    }
}

/// The serial line's server: one request at a time.
struct Line<'a> {
    port: Option<Port>,
    config: &'a ModbusRtuConfig,
    map: &'a Map,
    plc: &'a dyn Plc,
    answer_timeout: Duration,
    framer: Framer,
    counters: Counters,
    scratch: Box<Scratch>,
    read: [u8; READ_CHUNK],
}

/// Serves the map on `port` until `stop`; the counters at the end. Logs as it goes (see
/// [`CounterLog`]) and the totals at the end.
pub fn serve(
    port: Port,
    config: &ModbusRtuConfig,
    map: &Map,
    plc: &dyn Plc,
    answer_timeout: Duration,
    stop: &AtomicBool,
) -> Counters {
    let name = config.line.port.display().to_string();
    let mut log = CounterLog::new(&name, config.unit_id);
    let mut line = Line {
        port: Some(port),
        config,
        map,
        plc,
        answer_timeout,
        framer: Framer::new(config.line.char_gap_ns()),
        counters: Counters::default(),
        scratch: Box::default(),
        read: [0; READ_CHUNK],
    };
    let mut failing = false;
    while !stop.load(Ordering::SeqCst) {
        match line.step() {
            Ok(()) => {}
            Err(e) => {
                if !failing {
                    log::error!(
                        "modbus: rtu {name}: {e}; opening it again every {}s until it works",
                        REOPEN_EVERY.as_secs()
                    );
                    failing = true;
                }
                line.port = None;
                line.framer = Framer::new(config.line.char_gap_ns());
                let until = Instant::now() + REOPEN_EVERY;
                while !stop.load(Ordering::SeqCst) && Instant::now() < until {
                    std::thread::sleep(IDLE.min(until.saturating_duration_since(Instant::now())));
                }
                if stop.load(Ordering::SeqCst) {
                    break;
                }
                match Port::open(&config.line) {
                    Ok(port) => line.port = Some(port),
                    Err(_) => continue,
                }
            }
        }
        if failing && line.port.is_some() {
            log::warn!("modbus: rtu {name}: open again; serving");
            failing = false;
        }
        for (level, text) in log.update(&line.counters, now_ns()) {
            log::log!(level, "{text}");
        }
    }
    log::info!("{}", log.totals(&line.counters));
    line.counters
}

/// The port, unless it failed and is not open again.
fn open(port: &mut Option<Port>) -> io::Result<&mut Port> {
    port.as_mut().ok_or_else(|| io::Error::other("the port is closed"))
}

impl Line<'_> {
    /// Waits for bytes (until the pending frame's silence, at most [`IDLE`]), then handles
    /// every frame they complete.
    fn step(&mut self) -> io::Result<()> {
        let now = now_ns();
        let wait = match self.framer.deadline() {
            Some(deadline) => Duration::from_nanos(deadline.saturating_sub(now)).min(IDLE),
            None => IDLE,
        };
        self.receive(wait)?;
        let mut frame = [0u8; MAX_FRAME];
        while let Some(received) = self.framer.next(now_ns(), &mut frame) {
            match received {
                Received::Bad => self.counters.crc_errors += 1,
                Received::Frame(n) => self.handle(&frame[..n])?,
            }
        }
        Ok(())
    }

    /// Reads what comes within `wait` into the framer.
    fn receive(&mut self, wait: Duration) -> io::Result<()> {
        let Line { port, read, framer, .. } = self;
        let n = open(port)?
            .read_within(read, wait)
            .map_err(|e| io::Error::new(e.kind(), format!("reading: {e}")))?;
        framer.push(&read[..n], now_ns());
        Ok(())
    }

    /// One frame with a good CRC: `frame` is the address, the PDU and the CRC.
    fn handle(&mut self, frame: &[u8]) -> io::Result<()> {
        let deadline = Instant::now() + self.answer_timeout;
        let Some(n) = answer_frame(
            self.map,
            self.plc,
            self.config.unit_id,
            frame,
            deadline,
            &mut self.scratch,
            &mut self.counters,
        ) else {
            return Ok(());
        };
        if !self.quiet(deadline + self.answer_timeout)? {
            return Ok(());
        }
        let Line { port, scratch, .. } = self;
        open(port)?
            .send(&scratch.out[..n])
            .map_err(|e| io::Error::new(e.kind(), format!("sending: {e}")))?;
        self.counters.answered += 1;
        Ok(())
    }

    /// Waits until the line has been silent for t3.5 (`frame_gap_ns`) since the last byte
    /// came; bytes that come meanwhile are kept for the next frame. False if it was not by
    /// `give_up` (bytes without end: the answer is not sent).
    fn quiet(&mut self, give_up: Instant) -> io::Result<bool> {
        let gap = self.config.line.frame_gap_ns();
        loop {
            let until = self.framer.last_ns() + gap;
            let now = now_ns();
            if now >= until {
                return Ok(true);
            }
            if Instant::now() >= give_up {
                return Ok(false);
            }
            self.receive(Duration::from_nanos(until - now))?;
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Mutex;

    use modbus_core::Exception;
    use serialport::{SerialPort, TTYPort};

    use super::*;
    use crate::config::{Parity, SerialLine};
    use crate::drivers::real_time::WordWrite;

    /// t1.5 at 19200 baud 8E1.
    const T15: u64 = 859_374;
    const MS: u64 = 1_000_000;

    fn frames(framer: &mut Framer, now: u64) -> Vec<Result<Vec<u8>, ()>> {
        let mut out = Vec::new();
        let mut frame = [0u8; MAX_FRAME];
        while let Some(r) = framer.next(now, &mut frame) {
            out.push(match r {
                Received::Frame(n) => Ok(frame[..n].to_vec()),
                Received::Bad => Err(()),
            });
        }
        out
    }

    #[test]
    fn the_crc_is_modbus_s() {
        // The Modbus serial line guide's example: 02 07 has the CRC 41 12 (low byte first).
        assert_eq!(with_crc(&[0x02, 0x07]), [0x02, 0x07, 0x41, 0x12]);
        // modbus-core's own example: 01 03 08 2B 00 02 -> B6 63.
        assert_eq!(with_crc(&[1, 3, 8, 0x2B, 0, 2])[6..], [0xB6, 0x63]);
        assert!(crc_ok(&[0x02, 0x07, 0x41, 0x12]));
        assert!(!crc_ok(&[0x02, 0x07, 0x12, 0x41]));
        assert!(!crc_ok(&[0x41, 0x12]), "too short");
    }

    #[test]
    fn expected_lengths_follow_the_function_code() {
        let len = |adu: &[u8]| expected_len(adu);
        assert_eq!(len(&[1]), Expected::More);
        assert_eq!(len(&[1, 3]), Expected::Len(8));
        assert_eq!(len(&[1, 6, 0]), Expected::Len(8));
        assert_eq!(len(&[1, 17]), Expected::Len(4));
        assert_eq!(len(&[1, 22]), Expected::Len(10));
        // FC 16 of 2 registers: the byte count (4) is the 7th byte, after the quantity 00 02.
        assert_eq!(len(&[1, 16, 0, 0, 0, 2]), Expected::More);
        assert_eq!(len(&[1, 16, 0, 0, 0, 2, 4]), Expected::Len(13));
        assert_eq!(len(&[1, 15, 0, 0, 0, 10, 2]), Expected::Len(11));
        assert_eq!(len(&[1, 23, 0, 0, 0, 1, 0, 0, 0, 1]), Expected::More);
        assert_eq!(len(&[1, 23, 0, 0, 0, 1, 0, 0, 0, 1, 2]), Expected::Len(15));
        assert_eq!(len(&[1, 43]), Expected::More);
        assert_eq!(len(&[1, 43, 14]), Expected::Len(7));
        assert_eq!(len(&[1, 43, 13]), Expected::Unknown);
        assert_eq!(len(&[1, 8, 0, 0]), Expected::Unknown, "diagnostics: no fixed length");
        assert_eq!(len(&[1, 0x83, 2]), Expected::Unknown, "an exception response");
    }

    #[test]
    fn a_frame_ends_at_its_length_without_waiting_for_silence() {
        let mut f = Framer::new(T15);
        let read = with_crc(&[1, 3, 0, 0, 0, 1]);
        f.push(&read[..3], 0);
        assert_eq!(frames(&mut f, 0), []);
        f.push(&read[3..], 100);
        assert_eq!(frames(&mut f, 100), [Ok(read.clone())], "at once, no silence needed");
        assert_eq!(f.deadline(), None);
        // Two frames in one read: two frames; the rest of a third waits.
        let write = with_crc(&[1, 16, 0, 4, 0, 2, 4, 0, 7, 0, 8]);
        let both = [read.clone(), write.clone(), read[..2].to_vec()].concat();
        f.push(&both, 200);
        assert_eq!(frames(&mut f, 200), [Ok(read.clone()), Ok(write)]);
        f.push(&read[2..], 300);
        assert_eq!(frames(&mut f, 300), [Ok(read)]);
    }

    #[test]
    fn a_frame_of_unknown_length_ends_at_a_silence_of_more_than_t15() {
        let mut f = Framer::new(T15);
        // FC 8 (diagnostics), sub-function 0, data 12 34: no fixed length.
        let diag = with_crc(&[1, 8, 0, 0, 0x12, 0x34]);
        f.push(&diag, 1000);
        assert_eq!(f.deadline(), Some(1000 + T15 + 1));
        assert_eq!(frames(&mut f, 1000 + T15), [], "t1.5 exactly is not more than t1.5");
        assert_eq!(frames(&mut f, 1000 + T15 + 1), [Ok(diag)]);
        // A frame longer than its function code says, with a good CRC over the whole (FC 3 a
        // byte too many): it ends at the silence, and pdu.rs answers it with exception 03.
        let long = with_crc(&[1, 3, 0, 0, 0, 1, 0]);
        f.push(&long, 5 * MS);
        assert_eq!(frames(&mut f, 5 * MS + T15), []);
        assert_eq!(frames(&mut f, 5 * MS + T15 + 1), [Ok(long)]);
        // Another server's response on a shared line: its CRC is right at t1.5.
        let response = with_crc(&[2, 3, 2, 0, 42]);
        f.push(&response, 10 * MS);
        assert_eq!(frames(&mut f, 10 * MS + T15 + 1), [Ok(response)]);
    }

    #[test]
    fn a_frame_in_pieces_waits_for_its_rest_and_a_cut_one_is_dropped() {
        let mut f = Framer::new(T15);
        let write = with_crc(&[1, 16, 0, 0, 0, 3, 6, 0, 1, 0, 2, 0, 3]);
        // A USB adapter's pieces, 16 ms apart: one frame.
        f.push(&write[..7], 0);
        assert_eq!(frames(&mut f, 16 * MS), []);
        f.push(&write[7..], 16 * MS);
        assert_eq!(frames(&mut f, 16 * MS), [Ok(write.clone())]);
        // Cut short and nothing more: dropped after the piece gap.
        f.push(&write[..9], 100 * MS);
        assert_eq!(frames(&mut f, 100 * MS + PIECE_GAP_NS), []);
        assert_eq!(frames(&mut f, 100 * MS + PIECE_GAP_NS + 1), [Err(())]);
    }

    #[test]
    fn bad_crcs_and_garbage_are_dropped_and_the_next_frame_is_read() {
        let mut f = Framer::new(T15);
        let mut bad = with_crc(&[1, 3, 0, 0, 0, 1]);
        bad[3] ^= 0x01;
        f.push(&bad, 0);
        assert_eq!(frames(&mut f, 0), [], "a bad CRC at the length: maybe a longer frame");
        assert_eq!(frames(&mut f, T15 + 1), [Err(())]);
        // A lone byte of noise, then garbage without a known function code.
        f.push(&[0xFF], MS);
        assert_eq!(frames(&mut f, MS + PIECE_GAP_NS + 1), [Err(())]);
        f.push(&[1, 0x99, 7, 7, 7], 40 * MS);
        assert_eq!(frames(&mut f, 40 * MS + T15 + 1), [Err(())]);
        // More than 256 bytes without a silence: dropped whole, up to the silence.
        f.push(&[1, 0x99], 50 * MS);
        f.push(&[0x55; 300], 51 * MS);
        assert_eq!(frames(&mut f, 51 * MS), []);
        f.push(&with_crc(&[1, 3, 0, 0, 0, 1]), 52 * MS);
        assert_eq!(frames(&mut f, 52 * MS), [], "still inside the garbled run");
        assert_eq!(frames(&mut f, 52 * MS + T15 + 1), [Err(())]);
        // After the silence, the next frame is read.
        let read = with_crc(&[1, 3, 0, 0, 0, 1]);
        f.push(&read, 60 * MS);
        assert_eq!(frames(&mut f, 60 * MS), [Ok(read)]);
    }

    #[test]
    fn counters_are_logged_when_they_matter_not_per_frame() {
        let mut log = CounterLog::new("/dev/ttyUSB0", 1);
        let mut c = Counters::default();
        assert_eq!(log.update(&c, 0), []);
        c.frames = 1;
        c.answered = 1;
        let lines = log.update(&c, MS);
        assert_eq!(
            lines,
            [(log::Level::Info, "modbus: rtu /dev/ttyUSB0: the first request served".into())]
        );
        c.frames = 500;
        c.answered = 500;
        assert_eq!(log.update(&c, 2 * MS), [], "more requests: nothing");
        c.frames += 1;
        c.ignored += 1;
        c.first_other_unit = Some(5);
        let lines = log.update(&c, 3 * MS);
        assert_eq!(lines.len(), 1);
        assert!(
            lines[0].1.contains("a request to unit 5 ignored: this server is unit 1"),
            "{lines:?}"
        );
        c.ignored += 10;
        assert_eq!(log.update(&c, 4 * MS), [], "other units again: nothing");
        // Bad frames: a warning at once, then at most one every 10 s with what came meanwhile.
        c.crc_errors = 2;
        let lines = log.update(&c, 5 * MS);
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0].0, log::Level::Warn);
        assert!(
            lines[0].1.starts_with("modbus: rtu /dev/ttyUSB0: 2 bad frames dropped"),
            "{lines:?}"
        );
        assert!(lines[0].1.contains("2 of 503 in all"), "{lines:?}");
        c.crc_errors = 7;
        assert_eq!(log.update(&c, 5 * MS + BAD_WARN_EVERY_NS - 1), []);
        c.crc_errors = 9;
        let lines = log.update(&c, 5 * MS + BAD_WARN_EVERY_NS);
        assert!(lines[0].1.contains(": 7 bad frames dropped"), "{lines:?}");
        assert_eq!(log.update(&c, 100 * BAD_WARN_EVERY_NS), [], "none since: nothing");
        c.broadcasts = 3;
        assert_eq!(
            log.totals(&c),
            "modbus: rtu /dev/ttyUSB0: 501 frames: 500 answered, 3 broadcasts carried out, 11 \
             ignored; 9 bad frames dropped"
        );
    }

    /// Device memory as a plain array: reads and writes at once.
    struct Memory {
        map: Map,
        words: Mutex<Vec<u16>>,
    }

    impl Plc for Memory {
        fn read(&self, _: Instant, read: &mut dyn FnMut(&[u16])) -> Result<(), Exception> {
            let words = self.words.lock().unwrap();
            let image: Vec<u16> = self
                .map
                .mirror_ranges()
                .iter()
                .flat_map(|r| words[usize::from(r.start)..usize::from(r.end)].to_vec())
                .collect();
            read(&image);
            Ok(())
        }

        fn write(&self, writes: &[WordWrite], _: Instant) -> Result<(), Exception> {
            let mut words = self.words.lock().unwrap();
            for w in writes {
                let word = &mut words[usize::from(w.word)];
                *word = (*word & !w.mask) | (w.value & w.mask);
            }
            Ok(())
        }

        fn running(&self) -> bool {
            true
        }
    }

    fn memory() -> Memory {
        let text = "[[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 10\n\
                    writable = true\n[[program]]\nfile = \"main.il\"\n";
        let config = crate::config::parse(text, Path::new("plcd.toml")).unwrap();
        Memory { map: Map::new(&config.modbus), words: Mutex::new(vec![0; 1 << 16]) }
    }

    /// Sends `adu` with its CRC; the response frame, or `None` if none came within 2 s.
    fn transact(master: &mut TTYPort, adu: &[u8]) -> Option<Vec<u8>> {
        io::Write::write_all(master, &with_crc(adu)).unwrap();
        response(master)
    }

    /// Reads one response: bytes until they end with their CRC.
    fn response(master: &mut TTYPort) -> Option<Vec<u8>> {
        let mut got = Vec::new();
        let mut buf = [0u8; 300];
        let until = Instant::now() + Duration::from_secs(2);
        while !crc_ok(&got) {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            master.set_timeout(left).unwrap();
            match io::Read::read(master, &mut buf) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == io::ErrorKind::TimedOut => {}
                Err(e) => panic!("reading the pty: {e}"),
            }
        }
        Some(got)
    }

    /// A master as a real one works: a request without an answer is sent again.
    fn request(master: &mut TTYPort, adu: &[u8]) -> Vec<u8> {
        for _ in 0..5 {
            if let Some(r) = transact(master, adu) {
                return r;
            }
        }
        panic!("no answer to {adu:02x?}");
    }

    /// Serves unit 7 on a pty with `line` changed by `tune`; runs `talk` as the master, then
    /// stops the server; its counters.
    fn on_a_pty(tune: impl FnOnce(&mut SerialLine), talk: impl FnOnce(&mut TTYPort)) -> Counters {
        let (mut master, slave) = TTYPort::pair().expect("a pty pair");
        let mut line = SerialLine::new(slave.name().unwrap());
        // A pty carries bytes; the kernel may refuse PARENB on one.
        line.parity = Parity::None;
        tune(&mut line);
        let config = ModbusRtuConfig { line, unit_id: 7 };
        let plc = memory();
        let port = Port::open(&config.line).expect("the pty opens");
        let stop = AtomicBool::new(false);
        std::thread::scope(|s| {
            let server =
                s.spawn(|| serve(port, &config, &plc.map, &plc, Duration::from_secs(2), &stop));
            talk(&mut master);
            stop.store(true, Ordering::SeqCst);
            server.join().unwrap()
        })
    }

    #[test]
    fn a_line_answers_its_unit_carries_out_broadcasts_and_ignores_the_rest() {
        let counters = on_a_pty(
            |_| {},
            |m| {
                // FC 16 (its length from the byte count), then FC 3 reads it back.
                let r = request(m, &[7, 16, 0, 1, 0, 2, 4, 0x12, 0x34, 0x56, 0x78]);
                assert_eq!(r, with_crc(&[7, 16, 0, 1, 0, 2]));
                let r = request(m, &[7, 3, 0, 0, 0, 3]);
                assert_eq!(r, with_crc(&[7, 3, 6, 0, 0, 0x12, 0x34, 0x56, 0x78]));
                // A request to unit 2, then one to unit 7, back to back: the first answer is
                // unit 7's; unit 2's was not answered.
                let to_2 = with_crc(&[2, 6, 0, 0, 0, 9]);
                io::Write::write_all(m, &to_2).unwrap();
                let r = request(m, &[7, 3, 0, 0, 0, 1]);
                assert_eq!(r, with_crc(&[7, 3, 2, 0, 0]), "unit 2's write was not carried out");
                // A broadcast write, then a read: not answered, carried out.
                io::Write::write_all(m, &with_crc(&[0, 6, 0, 0, 0, 42])).unwrap();
                // A broadcast read is ignored, a response-like frame to unit 7 too.
                io::Write::write_all(m, &with_crc(&[0, 3, 0, 0, 0, 1])).unwrap();
                let r = request(m, &[7, 3, 0, 0, 0, 1]);
                assert_eq!(r, with_crc(&[7, 3, 2, 0, 42]), "the broadcast was carried out");
                // Exceptions as over TCP: an unmapped register, an unknown function.
                assert_eq!(request(m, &[7, 3, 0, 10, 0, 1]), with_crc(&[7, 0x83, 2]));
                assert_eq!(request(m, &[7, 8, 0, 0, 0x12, 0x34]), with_crc(&[7, 0x88, 1]));
                // FC 17 names this unit; FC 43/14 is framed by its length.
                let r = request(m, &[7, 17]);
                assert_eq!(&r[..4], [7, 17, r[2], 7]);
                assert_eq!(*r.iter().rev().nth(2).unwrap(), 0xFF, "RUN");
                assert_eq!(&request(m, &[7, 43, 14, 4, 0])[..4], [7, 43, 14, 4]);
                // A bad CRC is dropped; the master's retry is answered.
                let mut bad = with_crc(&[7, 6, 0, 0, 0, 99]);
                bad[5] ^= 0x10;
                io::Write::write_all(m, &bad).unwrap();
                // A master waits for an answer before it sends again; a short pause here
                // (anything above t1.5) keeps the next request apart, and if it does not, the
                // request is dropped with the bad frame and sent again.
                std::thread::sleep(Duration::from_millis(20));
                assert_eq!(request(m, &[7, 3, 0, 0, 0, 1]), with_crc(&[7, 3, 2, 0, 42]));
            },
        );
        assert_eq!(counters.crc_errors, 1, "{counters:?}");
        assert_eq!(counters.broadcasts, 1, "{counters:?}");
        assert_eq!(counters.ignored, 2, "unit 2 and the broadcast read: {counters:?}");
        assert_eq!(counters.first_other_unit, Some(2));
        assert_eq!(counters.answered, 9, "{counters:?}");
        assert_eq!(counters.frames, counters.answered + counters.broadcasts + counters.ignored);
    }

    #[test]
    fn an_answer_waits_for_the_frame_gap() {
        // 100 ms instead of t3.5: the answer cannot come sooner after the request was sent.
        on_a_pty(
            |line| line.frame_gap_us = Some(100_000),
            |m| {
                let sent = Instant::now();
                let r = request(m, &[7, 3, 0, 0, 0, 1]);
                assert_eq!(r, with_crc(&[7, 3, 2, 0, 0]));
                assert!(sent.elapsed() >= Duration::from_millis(100), "{:?}", sent.elapsed());
            },
        );
    }
}
