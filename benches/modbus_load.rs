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
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};
use plcd::control::protocol::{Reply, Request};
use plcd::plcctl::client::Client;

const PHASE: Duration = Duration::from_secs(5);
const CLIENTS: usize = 20;
const POLL: Duration = Duration::from_millis(10);

fn client(socket: &Path) -> Client {
    let start = Instant::now();
    loop {
        match Client::connect(socket, Duration::from_secs(5)) {
            Ok(c) => return c,
            Err(e) if start.elapsed() > Duration::from_secs(10) => panic!("{e}"),
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

fn status(c: &mut Client) -> Box<plcd::control::protocol::Status> {
    match c.request(&Request::Status).expect("status") {
        Reply::Status(s) => s,
        other => panic!("{other:?}"),
    }
}

fn counted(c: &mut Client) -> i64 {
    match c.request(&Request::Get { devices: vec!["D00000".into()] }).expect("get") {
        Reply::Values { values, .. } => i64::from(values[0].value),
        other => panic!("{other:?}"),
    }
}

struct Figures {
    scans: u64,
    counted: i64,
    periods: u64,
    p50: u64,
    p99: u64,
    max: u64,
    tick_p99: u64,
    answers: u64,
    /// Client-side response times, sorted (ns).
    responses: Vec<u64>,
}

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

fn phase(socket: &Path, modbus: SocketAddr, clients: usize) -> Figures {
    let mut c = client(socket);
    c.request(&Request::Stop).unwrap();
    c.request(&Request::Reset { cold: true }).unwrap();
    c.request(&Request::Run).unwrap();
    let started = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let answers = Arc::new(AtomicU64::new(0));
    let pollers: Vec<_> = (0..clients)
        .map(|k| {
            let (stop, answers) = (Arc::clone(&stop), Arc::clone(&answers));
            std::thread::spawn(move || {
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
                    answers.fetch_add(1, Ordering::Relaxed);
                    i = i.wrapping_add(1);
                    next += POLL;
                    std::thread::sleep(next.saturating_duration_since(Instant::now()));
                }
                times
            })
        })
        .collect();
    std::thread::sleep(PHASE);
    stop.store(true, Ordering::Relaxed);
    let mut responses: Vec<u64> = pollers.into_iter().flat_map(|p| p.join().unwrap()).collect();
    responses.sort_unstable();
    c.request(&Request::Stop).unwrap();
    let elapsed = started.elapsed();
    let s = status(&mut c);
    let tick = s.tasks.iter().find(|t| t.name == "tick").expect("tick task");
    Figures {
        scans: s.scan.count,
        counted: counted(&mut c),
        periods: elapsed.as_millis() as u64,
        p50: s.scan.p50_ns,
        p99: s.scan.p99_ns,
        max: s.scan.max_ns,
        tick_p99: tick.latency.p99_ns,
        answers: answers.load(Ordering::Relaxed),
        responses,
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let dir = std::env::temp_dir().join(format!("plcd-bench-modbus-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let config = "[plc]\nscan_period_ms = 1\n\
        [[program]]\nfile = \"main.il\"\n\
        [[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
        [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n\
        [control]\nsocket = \"plcd.sock\"\n\
        [modbus]\nlisten = \"127.0.0.1:0\"\n\
        [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 125\n\
        writable = true\n\
        [[modbus.coils]]\nstart = 0\ndevice = \"M0000\"\ncount = 64\n";
    let main = format!(
        "INC D00000\n{}END\n",
        "LOAD M0000\nAND M0001\nOUT M0002\nADD D00010 1 D00011\n".repeat(50)
    );
    for (file, text) in
        [("plcd.toml", config), ("main.il", &main), ("tick.il", "INC D00001\nEND\n")]
    {
        std::fs::write(dir.join(file), text).unwrap();
    }
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_plcd"))
        .args(["run", "--config"])
        .arg(dir.join("plcd.toml"))
        .stderr(Stdio::piped())
        .spawn()
        .expect("plcd starts");
    // The port the daemon chose: its log says `modbus: serving ADDR`.
    let mut log = BufReader::new(daemon.stderr.take().unwrap());
    let mut line = String::new();
    let modbus: SocketAddr = loop {
        line.clear();
        assert!(log.read_line(&mut line).unwrap() > 0, "plcd ended before serving Modbus");
        if let Some((_, addr)) = line.trim().split_once("modbus: serving ") {
            break addr.parse().unwrap();
        }
    };
    std::thread::spawn(move || log.lines().for_each(drop));
    let socket: PathBuf = dir.join("plcd.sock");
    let quiet = phase(&socket, modbus, 0);
    let loaded = phase(&socket, modbus, CLIENTS);
    let _ = Command::new("kill").arg(daemon.id().to_string()).status();
    let _ = daemon.wait();
    let _ = std::fs::remove_dir_all(&dir);

    let us = |ns: u64| format!("{:.1} µs", ns as f64 / 1000.0);
    let mut f = Fragment::new("cargo bench --bench modbus_load");
    f.line(format!(
        "The daemon runs a 1 ms fixed scan period with a 201-instruction scan program and a 1 ms \
         cycle task; each phase starts from RUN (which resets the figures) and lasts {} s; in the \
         second, {CLIENTS} Modbus TCP clients on their own connections send one request every \
         10 ms each, in turn FC 3 (125 holding registers), FC 1 (64 coils) and FC 6 (one \
         register). Every read waits for the next scan boundary's mirror capture and every \
         write for the boundary that applied it. Scan figures are the daemon's own \
         histograms.\n",
        PHASE.as_secs()
    ));
    let rows: Vec<Vec<String>> = [
        ("scan time p50", quiet.p50, loaded.p50),
        ("scan time p99", quiet.p99, loaded.p99),
        ("scan time max", quiet.max, loaded.max),
        ("cycle task start latency p99", quiet.tick_p99, loaded.tick_p99),
    ]
    .into_iter()
    .map(|(name, a, b)| {
        vec![name.into(), us(a), us(b), format!("{:.2}", b as f64 / a.max(1) as f64)]
    })
    .collect();
    f.table(
        &["figure", "no clients", &format!("{CLIENTS} Modbus clients every 10 ms"), "ratio"],
        &rows,
    );
    for (name, fig) in [("no clients", &quiet), ("clients", &loaded)] {
        f.line(format!(
            "- {name}: {} scans in {} ms; the program counted {}; {} Modbus answers ({:.0}/s)",
            fig.scans,
            fig.periods,
            fig.counted,
            fig.answers,
            fig.answers as f64 / PHASE.as_secs_f64()
        ));
        assert_eq!(fig.counted as u64, fig.scans, "every scan ran to its END");
    }
    let r = &loaded.responses;
    let pct = |p: f64| r[((r.len() - 1) as f64 * p) as usize];
    f.line(format!(
        "- Modbus response time at the client, {} requests: p50 {}, p99 {}, max {}",
        r.len(),
        us(pct(0.5)),
        us(pct(0.99)),
        us(*r.last().unwrap())
    ));
    write_fragment("modbus", &f).expect("fragment written");
}
