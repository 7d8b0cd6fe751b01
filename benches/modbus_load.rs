//! Scan time with and without 20 Modbus TCP clients polling every 10 ms, side by side in one
//! run: `cargo bench --bench modbus_load` (as root for SCHED_FIFO and mlockall, as the service
//! runs). Writes target/bench-results/modbus.md for BENCHMARKS.md.
//!
//! The daemon (the release `plcd` binary) runs a 1 ms fixed scan period with a 200-instruction
//! program that counts its scans in D00000 and a 1 ms cycle task. Each phase starts from RUN
//! (which resets the figures) and lasts `PHASE`; the figures are the daemon's own. "Lost scans"
//! compares the scans the program counted with the periods that passed. Each client reads 125
//! holding registers (FC 3), 64 coils (FC 1) and writes one register (FC 6) in turn, one
//! request every 10 ms, each on its own connection; their response times are the clients'.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};

#[path = "common/load.rs"]
mod load;

const CLIENTS: usize = 20;
const POLL: Duration = Duration::from_millis(10);

/// One Modbus request and its response on `stream`.
fn transact(stream: &mut TcpStream, transaction: u16, pdu: &[u8]) {
    let mut frame = Vec::with_capacity(7 + pdu.len());
    frame.extend_from_slice(&transaction.to_be_bytes());
    frame.extend_from_slice(&[0, 0]);
    frame.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    frame.push(1);
    frame.extend_from_slice(pdu);
    stream.write_all(&frame).unwrap();
    let mut header = [0u8; 7];
    stream.read_exact(&mut header).unwrap();
    let mut body = vec![0u8; usize::from(u16::from_be_bytes([header[4], header[5]])) - 1];
    stream.read_exact(&mut body).unwrap();
    assert_eq!(body[0], pdu[0], "no exception: {body:02x?}");
}

/// A client polling every 10 ms: FC 3 (125 holding registers), FC 1 (64 coils), FC 6 (one
/// register) in turn. It returns its response times (ns).
fn modbus_poller(modbus: SocketAddr) -> impl Fn(usize, Arc<AtomicBool>) -> Vec<u64> + Send + Sync {
    move |k, stop| {
        let mut stream = TcpStream::connect(modbus).unwrap();
        stream.set_nodelay(true).unwrap();
        let requests: [&[u8]; 3] =
            [&[3, 0, 0, 0, 125], &[1, 0, 0, 0, 64], &[6, 0, 100 + k as u8, 0, 1]];
        let mut times = Vec::new();
        let mut next = Instant::now();
        let mut i = 0u16;
        while !stop.load(Ordering::Relaxed) {
            let sent = Instant::now();
            transact(&mut stream, i, requests[usize::from(i) % 3]);
            times.push(sent.elapsed().as_nanos() as u64);
            i = i.wrapping_add(1);
            next += POLL;
            std::thread::sleep(next.saturating_duration_since(Instant::now()));
        }
        times
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let mut daemon = load::Daemon::start(
        "modbus",
        "[control]\nsocket = \"plcd.sock\"\n\
         [modbus]\nlisten = \"127.0.0.1:0\"\n\
         [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 125\n\
         writable = true\n\
         [[modbus.coils]]\nstart = 0\ndevice = \"M0000\"\ncount = 64\n",
        true,
    );
    // The port the daemon chose: its log says `modbus: serving ADDR`.
    let mut log = BufReader::new(daemon.child.stderr.take().unwrap());
    let mut line = String::new();
    let modbus: SocketAddr = loop {
        line.clear();
        assert!(log.read_line(&mut line).unwrap() > 0, "plcd ended before serving Modbus");
        if let Some((_, addr)) = line.trim().split_once("modbus: serving ") {
            break addr.parse().unwrap();
        }
    };
    std::thread::spawn(move || log.lines().for_each(drop));
    let socket = daemon.socket();
    let quiet = load::phase(&socket, 0, modbus_poller(modbus));
    let loaded = load::phase(&socket, CLIENTS, modbus_poller(modbus));
    drop(daemon);

    let mut f = Fragment::new("cargo bench --bench modbus_load");
    f.line(format!(
        "The daemon runs a 1 ms fixed scan period with a 201-instruction scan program and a 1 ms \
         cycle task; each phase starts from RUN (which resets the figures) and lasts {} s; in the \
         second, {CLIENTS} Modbus TCP clients on their own connections send one request every \
         10 ms each, in turn FC 3 (125 holding registers), FC 1 (64 coils) and FC 6 (one \
         register). Every read waits for the next scan boundary's mirror capture and every \
         write for the boundary that applied it. Scan figures are the daemon's own \
         histograms.\n",
        load::PHASE.as_secs()
    ));
    let mut responses: Vec<u64> = loaded.clients.iter().flatten().copied().collect();
    responses.sort_unstable();
    load::table(
        &mut f,
        &format!("{CLIENTS} Modbus clients every 10 ms"),
        "Modbus answers",
        [(&quiet, 0), (&loaded, responses.len() as u64)],
    );
    let r = &responses;
    let pct = |p: f64| r[((r.len() - 1) as f64 * p) as usize];
    f.line(format!(
        "- Modbus response time at the client, {} requests: p50 {}, p99 {}, max {}",
        r.len(),
        load::us(pct(0.5)),
        load::us(pct(0.99)),
        load::us(*r.last().unwrap())
    ));
    write_fragment("modbus", &f).expect("fragment written");
}
