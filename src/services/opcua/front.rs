//! The public side of the OPC UA server, in front of the stack: the limits the stack has no hook
//! for, enforced on the bytes between a client and the stack, with the client's address known.
//!
//! The stack (`async-opcua`) accepts its connections itself and tells nothing of them to plcd:
//! not the client's address, not a message's size across its chunks, not how fast requests
//! come. So the public socket (`[opcua] listen`) is the front's: it admits a connection
//! (`max_connections` at once, `max_connections_per_address` from one address), connects it to
//! the stack's own listener on the loopback interface, and relays the bytes both ways, reading
//! the client's chunk headers (OPC UA Part 6, 7.1.2: type, chunk kind, size) as they pass:
//!
//! | limit | cut off when |
//! |---|---|
//! | `max_request_bytes` | a chunk, or a message's chunks together, are longer |
//! | `max_requests_per_second` | a client sends more messages than this a second, over a burst of as many |
//! | `io_timeout_ms` | a chunk begun does not arrive whole, or the client does not take what the server sends, within it |
//! | — | a chunk header that is not one (an unknown type or chunk kind, a size below 8) |
//!
//! A refusal or a cut is logged once per client address and kind, then again at the 10th,
//! 100th, 1000th… ([`Tally`]), so that a flood of connections cannot flood the journal.
//!
//! The rules ([`Admission`], [`Meter`], [`Tally`]) take the time as an argument and are tested
//! without sockets; [`serve`] and the relay around them are the tokio shell.

use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio::time::Instant;

use opcua::server::ServerInfo;

use crate::config::OpcuaConfig;

/// The front's limits, from `[opcua]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// `max_connections`: connections at once, from all addresses.
    pub connections: usize,
    /// `max_connections_per_address`: connections at once from one address.
    pub per_address: usize,
    /// `max_requests_per_second`: messages a connection may send a second (and at once).
    pub requests_per_second: u32,
    /// `max_request_bytes`: the longest chunk and the longest message.
    pub message_bytes: u32,
    /// `io_timeout_ms`: how long a chunk may take to arrive whole, and a client to take what
    /// the server sends.
    pub io_timeout: Duration,
}

impl Limits {
    pub fn of(config: &OpcuaConfig) -> Limits {
        Limits {
            connections: config.max_connections as usize,
            per_address: config.max_connections_per_address as usize,
            requests_per_second: config.max_requests_per_second,
            message_bytes: config.max_request_bytes,
            io_timeout: Duration::from_millis(u64::from(config.io_timeout_ms)),
        }
    }
}

/// Why the front refused a connection or cut one off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Cut {
    /// `max_connections` connections were open.
    Connections,
    /// `max_connections_per_address` connections from this address were open.
    PerAddress,
    /// More than `max_requests_per_second` messages.
    Flood,
    /// A chunk or a message longer than `max_request_bytes`.
    TooLong,
    /// Bytes that are not an OPC UA chunk header.
    NotOpcUa,
    /// A chunk begun that did not arrive whole within `io_timeout_ms`.
    Stalled,
    /// What the server sent not taken within `io_timeout_ms`.
    NotReading,
}

impl Cut {
    /// What the log says, after the address.
    fn says(self, limits: &Limits) -> String {
        match self {
            Cut::Connections => format!(
                "connection refused: {} connections open ([opcua] max_connections)",
                limits.connections
            ),
            Cut::PerAddress => format!(
                "connection refused: {} connections open from this address ([opcua] \
                 max_connections_per_address)",
                limits.per_address
            ),
            Cut::Flood => format!(
                "cut off: more than {} requests a second ([opcua] max_requests_per_second)",
                limits.requests_per_second
            ),
            Cut::TooLong => format!(
                "cut off: a message longer than {} bytes ([opcua] max_request_bytes)",
                limits.message_bytes
            ),
            Cut::NotOpcUa => "cut off: it sent bytes that are not an OPC UA chunk".to_string(),
            Cut::Stalled => format!(
                "cut off: a chunk begun did not arrive whole within {} ms ([opcua] io_timeout_ms)",
                limits.io_timeout.as_millis()
            ),
            Cut::NotReading => format!(
                "cut off: it did not take what the server sent within {} ms ([opcua] \
                 io_timeout_ms)",
                limits.io_timeout.as_millis()
            ),
        }
    }
}

/// The connections open, in all and by address.
#[derive(Debug, Default)]
pub struct Admission {
    open: usize,
    by_address: HashMap<IpAddr, usize>,
}

impl Admission {
    /// Admits one more connection from `ip`, or says which limit refuses it.
    pub fn admit(&mut self, ip: IpAddr, limits: &Limits) -> Result<(), Cut> {
        let from_ip = self.by_address.get(&ip).copied().unwrap_or(0);
        if self.open >= limits.connections {
            return Err(Cut::Connections);
        }
        if from_ip >= limits.per_address {
            return Err(Cut::PerAddress);
        }
        self.open += 1;
        self.by_address.insert(ip, from_ip + 1);
        Ok(())
    }

    /// A connection from `ip` ended.
    pub fn release(&mut self, ip: IpAddr) {
        self.open = self.open.saturating_sub(1);
        if let Some(n) = self.by_address.get_mut(&ip) {
            *n -= 1;
            if *n == 0 {
                self.by_address.remove(&ip);
            }
        }
    }

    /// Connections open.
    pub fn open(&self) -> usize {
        self.open
    }
}

/// The chunk headers of what one client sends: their sizes, the message they add up to, and
/// the rate of messages (a token bucket of `requests_per_second` requests, refilled at that
/// rate, counted in nanoseconds of credit so that the arithmetic is exact).
#[derive(Debug)]
pub struct Meter {
    message_bytes: u32,
    rate: u64,
    /// Credit: a request costs [`Meter::REQUEST`]; a nanosecond adds `rate`.
    credit: u64,
    refilled: Instant,
    /// The bytes of the message whose chunks are arriving, before its final chunk.
    pending: u64,
}

/// The length of a chunk header: type (3 bytes), chunk kind (1), size (4, little-endian).
pub const HEADER: usize = 8;

impl Meter {
    const REQUEST: u64 = 1_000_000_000;

    pub fn new(limits: &Limits, now: Instant) -> Meter {
        let rate = u64::from(limits.requests_per_second);
        let credit = rate * Self::REQUEST;
        Meter { message_bytes: limits.message_bytes, rate, credit, refilled: now, pending: 0 }
    }

    /// The header of the chunk that arrives at `now`: the length of its body, or why the
    /// client is cut off.
    pub fn chunk(&mut self, header: &[u8; HEADER], now: Instant) -> Result<u32, Cut> {
        let size = u32::from_le_bytes([header[4], header[5], header[6], header[7]]);
        let kind = header[3];
        let message = match &header[..3] {
            b"MSG" | b"OPN" | b"CLO" => true,
            // Hello, and what a server or a reverse connection sends (the stack answers those).
            b"HEL" | b"ACK" | b"ERR" | b"RHE" => false,
            _ => return Err(Cut::NotOpcUa),
        };
        if !matches!(kind, b'F' | b'C' | b'A') || (size as usize) < HEADER {
            return Err(Cut::NotOpcUa);
        }
        if size > self.message_bytes {
            return Err(Cut::TooLong);
        }
        if message {
            match kind {
                b'C' => {
                    self.pending += u64::from(size);
                    if self.pending > u64::from(self.message_bytes) {
                        return Err(Cut::TooLong);
                    }
                    return Ok(size - HEADER as u32);
                }
                b'A' => {
                    self.pending = 0;
                    return Ok(size - HEADER as u32);
                }
                _ => {
                    let whole = self.pending + u64::from(size);
                    self.pending = 0;
                    if whole > u64::from(self.message_bytes) {
                        return Err(Cut::TooLong);
                    }
                }
            }
        }
        // A whole message (or a Hello): one request.
        let elapsed = now.saturating_duration_since(self.refilled).as_nanos();
        let elapsed = u64::try_from(elapsed).unwrap_or(u64::MAX);
        self.refilled = now;
        let full = self.rate * Self::REQUEST;
        self.credit = self.credit.saturating_add(elapsed.saturating_mul(self.rate)).min(full);
        if self.credit < Self::REQUEST {
            return Err(Cut::Flood);
        }
        self.credit -= Self::REQUEST;
        Ok(size - HEADER as u32)
    }
}

/// What of `stream` the front hands the stack when it all arrives at once: the length of the
/// whole chunks it lets through, and the cut that ends the rest, if any (a chunk not finished
/// is not a cut here: more may come). The relay does the same chunk by chunk as bytes arrive;
/// the fuzz target `opcua` reads a client's stream through this first.
pub fn passed(stream: &[u8], limits: &Limits) -> (usize, Option<Cut>) {
    let now = Instant::now();
    let mut meter = Meter::new(limits, now);
    let mut at = 0;
    while let Some(header) = stream.get(at..at + HEADER) {
        let header: &[u8; HEADER] = header.try_into().expect("HEADER bytes");
        match meter.chunk(header, now) {
            Err(cut) => return (at, Some(cut)),
            Ok(body) => {
                let end = at + HEADER + body as usize;
                if end > stream.len() {
                    break;
                }
                at = end;
            }
        }
    }
    (at, None)
}

/// Refusals and cuts by address and kind, for the log: the first of each logged, then the
/// 10th, 100th…; at most [`Tally::ADDRESSES`] addresses remembered (then forgotten all at once,
/// so that a scan of many addresses costs bounded memory and, at worst, logs again).
#[derive(Debug, Default)]
pub struct Tally {
    counts: HashMap<(IpAddr, Cut), u64>,
}

impl Tally {
    pub const ADDRESSES: usize = 1024;

    /// Counts one `cut` of `ip`: `Some(count)` when the log should say so.
    pub fn count(&mut self, ip: IpAddr, cut: Cut) -> Option<u64> {
        if self.counts.len() >= Self::ADDRESSES && !self.counts.contains_key(&(ip, cut)) {
            self.counts.clear();
        }
        let n = self.counts.entry((ip, cut)).or_insert(0);
        *n += 1;
        let n = *n;
        // 1, 10, 100, 1000…
        let mut power = 1;
        while power < n {
            power *= 10;
        }
        (power == n).then_some(n)
    }
}

/// The front: its limits and what it counts; shared by the accept loop and the relays.
#[derive(Debug)]
pub struct Front {
    limits: Limits,
    admission: Mutex<Admission>,
    tally: Mutex<Tally>,
}

impl Front {
    pub fn new(limits: Limits) -> Front {
        Front { limits, admission: Mutex::default(), tally: Mutex::default() }
    }

    /// Connections open through the front.
    pub fn open(&self) -> usize {
        self.admission.lock().unwrap_or_else(|e| e.into_inner()).open()
    }

    fn admit(self: &Arc<Self>, ip: IpAddr) -> Result<Ticket, Cut> {
        let mut admission = self.admission.lock().unwrap_or_else(|e| e.into_inner());
        admission.admit(ip, &self.limits)?;
        Ok(Ticket { front: Arc::clone(self), ip })
    }

    fn note(&self, peer: SocketAddr, cut: Cut) {
        let count = self.tally.lock().unwrap_or_else(|e| e.into_inner()).count(peer.ip(), cut);
        if let Some(count) = count {
            let again = if count > 1 { format!(" ({count} times so far)") } else { String::new() };
            log::warn!("opcua: client {}: {}{again}", peer.ip(), cut.says(&self.limits));
        }
    }
}

/// One admitted connection: released when dropped.
struct Ticket {
    front: Arc<Front>,
    ip: IpAddr,
}

impl Drop for Ticket {
    fn drop(&mut self) {
        self.front.admission.lock().unwrap_or_else(|e| e.into_inner()).release(self.ip);
    }
}

/// Serves the public `listener`: each admitted connection relayed to the stack at `inner`.
///
/// The stack writes the port of the listener it was given (the loopback one) into `info`, whose
/// port goes into the endpoint URLs it announces and checks clients' Hellos against: once it
/// has, the front puts the public port back, before it accepts anything.
pub async fn serve(
    listener: TcpListener,
    inner: SocketAddr,
    front: Arc<Front>,
    info: Arc<ServerInfo>,
    public_port: u16,
) {
    let port = &info.port;
    let deadline = Instant::now() + Duration::from_secs(30);
    while port.load(Ordering::Relaxed) != inner.port() && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
    if port.load(Ordering::Relaxed) != inner.port() {
        log::error!("opcua: the stack did not start listening within 30 s");
    }
    port.store(public_port, Ordering::Relaxed);
    loop {
        let (client, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            Err(e) => {
                // Out of file descriptors and the like: wait rather than spin.
                log::warn!("opcua: accept failed: {e}");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        match front.admit(peer.ip()) {
            Ok(ticket) => {
                tokio::spawn(relay(client, peer, inner, ticket));
            }
            Err(cut) => {
                front.note(peer, cut);
                drop(client);
            }
        }
    }
}

/// How a relay ended: a side closed (or failed), or the front cut the client off.
enum End {
    Closed,
    Cut(Cut),
}

/// Relays one client's connection to the stack and back until either side closes or the
/// client breaks a limit.
async fn relay(client: TcpStream, peer: SocketAddr, inner: SocketAddr, ticket: Ticket) {
    let front = Arc::clone(&ticket.front);
    let limits = front.limits;
    let server = match TcpStream::connect(inner).await {
        Ok(server) => server,
        Err(e) => {
            log::error!("opcua: cannot reach the stack's listener {inner}: {e}");
            return;
        }
    };
    // Small requests and answers: sent at once, not gathered.
    let _ = client.set_nodelay(true);
    let _ = server.set_nodelay(true);
    let (from_client, to_client) = client.into_split();
    let (from_server, to_server) = server.into_split();
    let meter = Meter::new(&limits, Instant::now());
    let up = upstream(from_client, to_server, meter, limits.io_timeout);
    let down = downstream(from_server, to_client, limits.io_timeout);
    tokio::pin!(up, down);
    let end = tokio::select! {
        end = &mut up => match end {
            // The client closed its side: its place is free at once (it sends no more
            // requests); what the server still sends goes to it, for a while.
            End::Closed => {
                drop(ticket);
                tokio::time::timeout(limits.io_timeout, &mut down).await.unwrap_or(End::Closed)
            }
            cut => cut,
        },
        end = &mut down => end,
    };
    if let End::Cut(cut) = end {
        front.note(peer, cut);
    }
}

/// Client to stack, chunk by chunk through the [`Meter`]. The first byte of a chunk may take
/// as long as the client likes (the stack's own timeouts end idle channels and sessions); the
/// rest of the chunk must follow within `io_timeout`.
async fn upstream(
    mut from: OwnedReadHalf,
    mut to: OwnedWriteHalf,
    mut meter: Meter,
    io_timeout: Duration,
) -> End {
    let mut header = [0u8; HEADER];
    let mut body = vec![0u8; 64 * 1024];
    loop {
        match from.read(&mut header[..1]).await {
            Ok(0) | Err(_) => {
                let _ = to.shutdown().await;
                return End::Closed;
            }
            Ok(_) => {}
        }
        let deadline = Instant::now() + io_timeout;
        match tokio::time::timeout_at(deadline, from.read_exact(&mut header[1..])).await {
            Err(_) => return End::Cut(Cut::Stalled),
            Ok(Err(_)) => return End::Closed,
            Ok(Ok(_)) => {}
        }
        let mut left = match meter.chunk(&header, Instant::now()) {
            Ok(left) => left as usize,
            Err(cut) => return End::Cut(cut),
        };
        if to.write_all(&header).await.is_err() {
            return End::Closed;
        }
        while left > 0 {
            let n = left.min(body.len());
            match tokio::time::timeout_at(deadline, from.read_exact(&mut body[..n])).await {
                Err(_) => return End::Cut(Cut::Stalled),
                Ok(Err(_)) => return End::Closed,
                Ok(Ok(_)) => {}
            }
            if to.write_all(&body[..n]).await.is_err() {
                return End::Closed;
            }
            left -= n;
        }
    }
}

/// Stack to client, as it comes; a client that takes nothing for `io_timeout` is cut off.
async fn downstream(mut from: OwnedReadHalf, mut to: OwnedWriteHalf, io_timeout: Duration) -> End {
    let mut buffer = vec![0u8; 64 * 1024];
    loop {
        let n = match from.read(&mut buffer).await {
            Ok(0) | Err(_) => return End::Closed,
            Ok(n) => n,
        };
        match tokio::time::timeout(io_timeout, to.write_all(&buffer[..n])).await {
            Err(_) => return End::Cut(Cut::NotReading),
            Ok(Err(_)) => return End::Closed,
            Ok(Ok(())) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> Limits {
        Limits {
            connections: 3,
            per_address: 2,
            requests_per_second: 10,
            message_bytes: 1000,
            io_timeout: Duration::from_secs(1),
        }
    }

    fn header(kind: &[u8; 3], chunk: u8, size: u32) -> [u8; HEADER] {
        let mut h = [0u8; HEADER];
        h[..3].copy_from_slice(kind);
        h[3] = chunk;
        h[4..].copy_from_slice(&size.to_le_bytes());
        h
    }

    fn ip(last: u8) -> IpAddr {
        IpAddr::from([10, 0, 0, last])
    }

    #[test]
    fn admission_counts_all_and_each_address() {
        let limits = limits();
        let mut admission = Admission::default();
        assert_eq!(admission.admit(ip(1), &limits), Ok(()));
        assert_eq!(admission.admit(ip(1), &limits), Ok(()));
        assert_eq!(admission.admit(ip(1), &limits), Err(Cut::PerAddress));
        assert_eq!(admission.admit(ip(2), &limits), Ok(()));
        assert_eq!(admission.admit(ip(3), &limits), Err(Cut::Connections));
        admission.release(ip(1));
        assert_eq!(admission.open(), 2);
        assert_eq!(admission.admit(ip(3), &limits), Ok(()), "a place freed");
        assert_eq!(admission.admit(ip(1), &limits), Err(Cut::Connections));
        for a in [1, 2, 3] {
            admission.release(ip(a));
        }
        assert_eq!(admission.open(), 0);
        assert!(admission.by_address.is_empty(), "no address kept without a connection");
    }

    #[test]
    fn a_message_is_bounded_whole_and_each_chunk() {
        let now = Instant::now();
        let mut meter = Meter::new(&limits(), now);
        assert_eq!(meter.chunk(&header(b"HEL", b'F', 40), now), Ok(32));
        assert_eq!(meter.chunk(&header(b"MSG", b'C', 400), now), Ok(392));
        assert_eq!(meter.chunk(&header(b"MSG", b'C', 400), now), Ok(392));
        assert_eq!(meter.chunk(&header(b"MSG", b'F', 200), now), Ok(192), "1000 bytes: the limit");
        assert_eq!(meter.chunk(&header(b"MSG", b'C', 600), now), Ok(592));
        assert_eq!(meter.chunk(&header(b"MSG", b'A', 30), now), Ok(22), "an abort forgets");
        assert_eq!(meter.chunk(&header(b"MSG", b'C', 600), now), Ok(592));
        assert_eq!(meter.chunk(&header(b"MSG", b'F', 401), now), Err(Cut::TooLong));
        let mut meter = Meter::new(&limits(), now);
        assert_eq!(meter.chunk(&header(b"MSG", b'C', 600), now), Ok(592));
        assert_eq!(meter.chunk(&header(b"MSG", b'C', 401), now), Err(Cut::TooLong), "early");
        let mut meter = Meter::new(&limits(), now);
        assert_eq!(meter.chunk(&header(b"OPN", b'F', 1001), now), Err(Cut::TooLong));
    }

    #[test]
    fn what_is_not_a_chunk_header_is_cut_off() {
        let now = Instant::now();
        let mut meter = Meter::new(&limits(), now);
        assert_eq!(meter.chunk(b"GET / HT", now), Err(Cut::NotOpcUa));
        assert_eq!(meter.chunk(&header(b"MSG", b'X', 100), now), Err(Cut::NotOpcUa));
        assert_eq!(meter.chunk(&header(b"MSG", b'F', 7), now), Err(Cut::NotOpcUa));
        assert_eq!(meter.chunk(&header(b"CLO", b'F', 8), now), Ok(0), "an empty body");
    }

    #[test]
    fn messages_beyond_the_rate_are_a_flood() {
        let start = Instant::now();
        let mut meter = Meter::new(&limits(), start);
        // A burst of 10 at once, then the 11th.
        for _ in 0..10 {
            assert_eq!(meter.chunk(&header(b"MSG", b'F', 50), start), Ok(42));
        }
        assert_eq!(meter.chunk(&header(b"MSG", b'F', 50), start), Err(Cut::Flood));
        // Intermediate chunks are not requests.
        let mut meter = Meter::new(&limits(), start);
        for _ in 0..9 {
            assert_eq!(meter.chunk(&header(b"MSG", b'F', 50), start), Ok(42));
        }
        for _ in 0..15 {
            assert_eq!(meter.chunk(&header(b"MSG", b'C', 50), start), Ok(42));
        }
        assert_eq!(meter.chunk(&header(b"MSG", b'F', 50), start), Ok(42), "the 10th request");
        // 10 a second go on for ever.
        for k in 1..=100 {
            let t = start + Duration::from_millis(100 * k);
            assert_eq!(meter.chunk(&header(b"MSG", b'F', 50), t), Ok(42), "request {k}");
        }
        assert_eq!(
            meter.chunk(&header(b"MSG", b'F', 50), start + Duration::from_millis(10_050)),
            Err(Cut::Flood),
            "the 11th within a second"
        );
        // 20 a second, from a full bucket: the 10 it holds and the 9.5 it gains in 950 ms pass,
        // the 20th (at 950 ms) does not.
        let t = start + Duration::from_secs(20);
        let flooded = (0..40)
            .map(|k| meter.chunk(&header(b"MSG", b'F', 50), t + Duration::from_millis(50 * k)))
            .position(|r| r == Err(Cut::Flood));
        assert_eq!(flooded, Some(19));
    }

    #[test]
    fn a_stream_passes_whole_chunks_up_to_a_cut() {
        let chunk = |kind: &[u8; 3], c: u8, size: u32| {
            let mut bytes = header(kind, c, size).to_vec();
            bytes.resize(size as usize, 0);
            bytes
        };
        let mut stream = [chunk(b"HEL", b'F', 40), chunk(b"OPN", b'F', 100)].concat();
        assert_eq!(passed(&stream, &limits()), (140, None));
        stream.extend_from_slice(&chunk(b"MSG", b'F', 60)[..30]);
        assert_eq!(passed(&stream, &limits()), (140, None), "a chunk not finished waits");
        stream.truncate(140);
        stream.extend(chunk(b"MSG", b'C', 900));
        stream.extend(chunk(b"MSG", b'F', 200));
        assert_eq!(passed(&stream, &limits()), (1040, Some(Cut::TooLong)));
        let flood: Vec<u8> = (0..12).flat_map(|_| chunk(b"MSG", b'F', 20)).collect();
        assert_eq!(passed(&flood, &limits()), (200, Some(Cut::Flood)), "10 at once");
    }

    /// Relays one connection to a stand-in stack that sends without end, the client doing
    /// `client` (then holding its socket): how the relay ended, as the tally counted it.
    fn relayed<F: std::future::Future<Output = ()> + Send + 'static>(
        client: impl FnOnce(TcpStream) -> F,
    ) -> Option<Cut> {
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
        runtime.block_on(async {
            let stack = TcpListener::bind("127.0.0.1:0").await.unwrap();
            let inner = stack.local_addr().unwrap();
            tokio::spawn(async move {
                let (mut to_front, _) = stack.accept().await.unwrap();
                let block = vec![0u8; 64 * 1024];
                while to_front.write_all(&block).await.is_ok() {}
            });
            let public = TcpListener::bind("127.0.0.1:0").await.unwrap();
            let socket = TcpStream::connect(public.local_addr().unwrap()).await.unwrap();
            let (accepted, peer) = public.accept().await.unwrap();
            let limits = Limits { io_timeout: Duration::from_millis(100), ..limits() };
            let front = Arc::new(Front::new(limits));
            let ticket = front.admit(peer.ip()).unwrap();
            let client = tokio::spawn(client(socket));
            tokio::time::timeout(Duration::from_secs(20), relay(accepted, peer, inner, ticket))
                .await
                .expect("the relay ends within 20 s");
            client.abort();
            assert_eq!(front.open(), 0, "the connection released");
            let tally = front.tally.lock().unwrap();
            tally.counts.keys().find(|(ip, _)| *ip == peer.ip()).map(|(_, cut)| *cut)
        })
    }

    #[test]
    fn a_client_that_takes_nothing_is_cut_off() {
        // The client reads nothing and keeps its socket: the stack's bytes fill the buffers.
        let cut = relayed(|socket| async move {
            tokio::time::sleep(Duration::from_secs(30)).await;
            drop(socket);
        });
        assert_eq!(cut, Some(Cut::NotReading));
    }

    #[test]
    fn a_chunk_begun_and_not_finished_is_cut_off() {
        let cut = relayed(|mut socket| async move {
            socket.write_all(b"HEL").await.unwrap();
            // Read what the stack sends, so that only the stall can end the relay.
            let mut sink = vec![0u8; 64 * 1024];
            let _ = tokio::time::timeout(Duration::from_secs(30), async {
                while socket.read(&mut sink).await.is_ok_and(|n| n > 0) {}
            })
            .await;
        });
        assert_eq!(cut, Some(Cut::Stalled));
    }

    #[test]
    fn the_log_says_the_first_and_every_power_of_ten() {
        let mut tally = Tally::default();
        let said: Vec<u64> = (0..1000).filter_map(|_| tally.count(ip(1), Cut::Flood)).collect();
        assert_eq!(said, [1, 10, 100, 1000]);
        assert_eq!(tally.count(ip(1), Cut::TooLong), Some(1), "each kind apart");
        assert_eq!(tally.count(ip(2), Cut::Flood), Some(1), "each address apart");
        for a in 0..Tally::ADDRESSES as u32 + 10 {
            tally.count(IpAddr::from(a.to_be_bytes()), Cut::PerAddress);
        }
        assert!(tally.counts.len() <= Tally::ADDRESSES);
    }
}
