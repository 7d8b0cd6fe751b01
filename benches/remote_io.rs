//! Remote I/O (`[[remote]]`, docs/REMOTE.md) measured: `cargo bench --bench remote_io` (as root
//! for SCHED_FIFO and mlockall, as the service runs; without root the real-time settings fall
//! back and the figures are not real-time ones). Writes target/bench-results/remote.md for
//! BENCHMARKS.md. Four parts, each against Modbus devices that are threads of this bench:
//!
//! 1. **Input age over TCP at a 10 ms period.** The real-time driver (`Driver`, as `plcd run`
//!    starts it) runs a project that polls one TCP device every 10 ms and copies bit 0 of its
//!    input register into a watched output; the device changes the register at random
//!    moments, noting each change's CLOCK_MONOTONIC time. The driver reports each change of
//!    the watched output with the time of the END of the scan that made it: the first scan
//!    whose input refresh copied the new value in. Age = that END − the change.
//! 2. **Scan time and cycle-task latency with 8 TCP devices polled every 10 ms, against none**:
//!    the same project with and without 8 `[[remote]]`, alternated in rounds; the engine's own
//!    histograms.
//! 3. **Scan-thread cost of those 8 devices**: `RemoteIo::refresh_inputs`/`refresh_outputs`
//!    timed alone every millisecond while their pollers run (the scan time of part 2 does not
//!    include the output refresh).
//! 4. **An RTU line at 115200 baud against the protocol's maximum**: plcd's poller on one end
//!    of a pseudo terminal, a device on the other that answers each request when a wire would
//!    have delivered the answer; one and two devices on the line.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU16, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};
use plcd::device::Memory;
use plcd::drivers::real_time::driver::{Driver, Granted};
use plcd::drivers::real_time::sys::now_ns;
use plcd::drivers::real_time::{Command, Report, Source};
use plcd::engine::event::{Event, Mode};
use plcd::io::remote::{self, DeviceReport};
use plcd::stats::Histogram;
use serialport::SerialPort;

/// Part 1: how long the device keeps changing its register.
const AGE_RUN: Duration = Duration::from_secs(30);
/// Part 1: the device changes its register every 20 to 40 ms (uniform): more than a period
/// and an age apart, so that each change is seen before the next.
const CHANGE_EVERY_MS: (u64, u64) = (20, 40);
/// Part 2: rounds, each one phase of each configuration (in alternating order), and a phase.
const ROUNDS: usize = 4;
const PHASE: Duration = Duration::from_secs(6);
const DEVICES: usize = 8;
/// Part 3: refreshes timed.
const REFRESHES: usize = 3000;
/// Part 4: how long each line configuration is polled.
const LINE_RUN: Duration = Duration::from_secs(5);
const BAUD: u32 = 115_200;
/// 8E1, Modbus RTU's default framing: start, 8 data, even parity, stop.
const CHAR_BITS: u64 = 11;
/// t3.5 above 19200 baud, fixed by the Modbus serial line spec.
const T35_NS: u64 = 1_750_000;

fn us(ns: u64) -> String {
    format!("{:.1} µs", ns as f64 / 1000.0)
}

fn ms(ns: u64) -> String {
    format!("{:.2} ms", ns as f64 / 1e6)
}

/// The value below or at which a share `p` of `sorted` lies (nearest rank).
fn pct(sorted: &[u64], p: f64) -> u64 {
    let rank = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// xorshift64*: the device's random moments.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) % n
    }
}

/// Sleeps until CLOCK_MONOTONIC `deadline_ns`: the kernel's sleep to 150 µs before it, then a
/// spin, so that a simulated wire is not as late as a plain sleep would make it.
fn sleep_until(deadline_ns: u64) {
    loop {
        let now = now_ns();
        if now >= deadline_ns {
            return;
        }
        let left = deadline_ns - now;
        if left > 200_000 {
            std::thread::sleep(Duration::from_nanos(left - 150_000));
        } else {
            std::hint::spin_loop();
        }
    }
}

// ---------------------------------------------------------------------------------------------
// A Modbus TCP device.

/// A device's tables, shared by its server thread and the bench.
struct Store {
    /// Holding and input registers alike.
    registers: Vec<AtomicU16>,
    discrete_inputs: Vec<AtomicBool>,
    coils: Vec<AtomicBool>,
    reads: AtomicU64,
    writes: AtomicU64,
}

impl Store {
    fn new() -> Arc<Store> {
        Arc::new(Store {
            registers: (0..128).map(|i| AtomicU16::new(i * 3)).collect(),
            discrete_inputs: (0..128).map(|i| AtomicBool::new(i % 3 == 0)).collect(),
            coils: (0..128).map(|_| AtomicBool::new(false)).collect(),
            reads: AtomicU64::new(0),
            writes: AtomicU64::new(0),
        })
    }

    /// The answer's PDU to a request's PDU: FC 1, 2, 3, 4, 15, 16.
    fn answer(&self, pdu: &[u8]) -> Vec<u8> {
        let word = |at: usize| usize::from(u16::from_be_bytes([pdu[at], pdu[at + 1]]));
        let fc = pdu[0];
        let (first, count) = (word(1), word(3));
        let mut out = vec![fc];
        match fc {
            1 | 2 => {
                let bits = if fc == 1 { &self.coils } else { &self.discrete_inputs };
                let bytes = count.div_ceil(8);
                out.push(bytes as u8);
                for byte in 0..bytes {
                    let mut value = 0u8;
                    for k in 0..8.min(count - byte * 8) {
                        let on = bits[(first + byte * 8 + k) % bits.len()].load(Ordering::Relaxed);
                        value |= u8::from(on) << k;
                    }
                    out.push(value);
                }
                self.reads.fetch_add(1, Ordering::Relaxed);
            }
            3 | 4 => {
                out.push((2 * count) as u8);
                for k in 0..count {
                    let value =
                        self.registers[(first + k) % self.registers.len()].load(Ordering::Relaxed);
                    out.extend(value.to_be_bytes());
                }
                self.reads.fetch_add(1, Ordering::Relaxed);
            }
            15 => {
                for k in 0..count {
                    let on = pdu[6 + k / 8] >> (k % 8) & 1 != 0;
                    self.coils[(first + k) % self.coils.len()].store(on, Ordering::Relaxed);
                }
                out.extend(&pdu[1..5]);
                self.writes.fetch_add(1, Ordering::Relaxed);
            }
            16 => {
                for k in 0..count {
                    let value = u16::from_be_bytes([pdu[6 + 2 * k], pdu[7 + 2 * k]]);
                    self.registers[(first + k) % self.registers.len()]
                        .store(value, Ordering::Relaxed);
                }
                out.extend(&pdu[1..5]);
                self.writes.fetch_add(1, Ordering::Relaxed);
            }
            _ => out = vec![fc | 0x80, 1],
        }
        out
    }
}

/// Starts a Modbus TCP device on a loopback port: one thread serving one connection at a time
/// (plcd keeps one per device), for as long as the bench runs.
fn tcp_device(store: Arc<Store>) -> SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").expect("a loopback port");
    let address = listener.local_addr().unwrap();
    std::thread::Builder::new()
        .name("bench-device".into())
        .spawn(move || {
            while let Ok((stream, _)) = listener.accept() {
                serve(stream, &store);
            }
        })
        .unwrap();
    address
}

fn serve(mut stream: TcpStream, store: &Store) {
    let _ = stream.set_nodelay(true);
    let mut header = [0u8; 7];
    let mut pdu = [0u8; 260];
    while stream.read_exact(&mut header).is_ok() {
        let len = usize::from(u16::from_be_bytes([header[4], header[5]])).saturating_sub(1);
        if len == 0 || len > pdu.len() || stream.read_exact(&mut pdu[..len]).is_err() {
            return;
        }
        let answer = store.answer(&pdu[..len]);
        let mut frame = Vec::with_capacity(7 + answer.len());
        frame.extend(&header[..4]);
        frame.extend((answer.len() as u16 + 1).to_be_bytes());
        frame.push(header[6]);
        frame.extend(&answer);
        if stream.write_all(&frame).is_err() {
            return;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Projects and the driver.

/// A generated project in a private directory, removed on drop.
struct ProjectDir {
    path: PathBuf,
}

impl ProjectDir {
    fn new(name: &str, files: &[(&str, &str)]) -> ProjectDir {
        let path =
            std::env::temp_dir().join(format!("plcd-bench-remote-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).unwrap();
        for (file, text) in files {
            std::fs::write(path.join(file), text).unwrap();
        }
        ProjectDir { path }
    }

    fn config(&self) -> PathBuf {
        self.path.join("plcd.toml")
    }
}

impl Drop for ProjectDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

fn start(dir: &ProjectDir) -> Driver {
    let project = plcd::files::project(&dir.config()).unwrap_or_else(|d| panic!("{d}"));
    let driver = Driver::start(&project, Vec::new()).expect("the driver starts");
    assert!(driver.command(Command::Mode(Mode::Run, Source::Startup)));
    driver
}

/// `[[remote]]` of a TCP device polled every 10 ms.
fn tcp_remote(name: &str, address: SocketAddr) -> String {
    format!(
        "\n[[remote]]\nname = \"{name}\"\ntransport = \"tcp\"\naddress = \"{address}\"\n\
         period_ms = 10\ntimeout_ms = 100\n"
    )
}

/// What the driver got of `[rt]`, for the text; what it did not get goes to stderr.
fn scheduling(granted: &Granted, problems: &[String]) -> String {
    for problem in problems {
        eprintln!("remote_io: [rt]: {problem}");
    }
    match (granted.fifo, granted.memory_locked) {
        (true, true) => "SCHED_FIFO, memory locked".into(),
        (true, false) => "SCHED_FIFO, memory not locked".into(),
        (false, _) => "not real time: SCHED_OTHER, not root".into(),
    }
}

// ---------------------------------------------------------------------------------------------
// Part 1: input age.

struct Age {
    /// Change → END of the first scan that had it, ns, sorted.
    ages: Vec<u64>,
    changes: usize,
    /// Changes the program never saw (superseded, or a poll that failed).
    unseen: usize,
    round_trip: Histogram,
    scan: Histogram,
    device: DeviceReport,
    scheduling: String,
}

fn input_age() -> Age {
    let store = Store::new();
    store.registers[0].store(0, Ordering::Relaxed);
    let address = tcp_device(Arc::clone(&store));
    let config = format!(
        "[plc]\nscan_period_ms = 1\n\n[[program]]\nfile = \"main.il\"\n\n[control]\n\
         enabled = false\n{}\n[[remote.read]]\ntable = \"input_registers\"\naddress = 0\n\
         count = 1\ndevice = \"D00100\"\n",
        tcp_remote("age", address)
    );
    let dir = ProjectDir::new(
        "age",
        &[("plcd.toml", &config), ("main.il", "LOAD D00100.0\nOUT P0050\nEND\n")],
    );
    let mut driver = start(&dir);
    let scheduling = scheduling(&driver.granted, &driver.problems);
    // The device's changes, (time, new value), from a thread of their own.
    let changes = Arc::new(Mutex::new(Vec::<(u64, u16)>::new()));
    let done = Arc::new(AtomicBool::new(false));
    let changer = {
        let (changes, done, store) = (Arc::clone(&changes), Arc::clone(&done), Arc::clone(&store));
        std::thread::spawn(move || {
            // Online and scanning first.
            std::thread::sleep(Duration::from_millis(500));
            let mut rng = Rng(now_ns() | 1);
            let end = Instant::now() + AGE_RUN;
            let mut n = 0u16;
            while Instant::now() < end {
                let (lo, hi) = CHANGE_EVERY_MS;
                std::thread::sleep(Duration::from_micros(rng.below((hi - lo) * 1000) + lo * 1000));
                n = n.wrapping_add(1);
                let at = now_ns();
                store.registers[0].store(n, Ordering::Relaxed);
                changes.lock().unwrap().push((at, n));
            }
            // The last change's way to the program.
            std::thread::sleep(Duration::from_millis(200));
            done.store(true, Ordering::Release);
        })
    };
    let mut seen: Vec<(u64, i32)> = Vec::new();
    while !done.load(Ordering::Acquire) {
        while let Ok(report) = driver.reports.pop() {
            if let Report::Event(at, Event::Set { watch: 0, value }) = report {
                seen.push((at, value));
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    changer.join().unwrap();
    let device = driver.remote_board().reports().remove(0);
    let engine = driver.stop().expect("the scan thread ran to the end");
    let changes = std::mem::take(&mut *changes.lock().unwrap());
    // Each change is seen as the first change of the output to its bit 0 after it.
    let mut ages = Vec::new();
    let mut unseen = 0;
    let mut j = 0;
    for &(at, n) in &changes {
        while j < seen.len() && (seen[j].0 < at || seen[j].1 != i32::from(n & 1)) {
            j += 1;
        }
        match seen.get(j) {
            Some(&(end, _)) => {
                ages.push(end - at);
                j += 1;
            }
            None => unseen += 1,
        }
    }
    ages.sort_unstable();
    let mut scan = Histogram::new();
    scan.copy_from(&engine.scan_stats().time);
    Age {
        ages,
        changes: changes.len(),
        unseen,
        round_trip: device.stats.round_trip.clone(),
        scan,
        device,
        scheduling,
    }
}

/// The quantile `q` of U(0, a) + U(0, b), a ≥ b > 0: the wait for the next poll plus the wait
/// for the next scan, for a change at a random moment.
fn uniform_sum_quantile(a: f64, b: f64, q: f64) -> f64 {
    let (low, high) = (b / (2.0 * a), 1.0 - b / (2.0 * a));
    if q <= low {
        (2.0 * a * b * q).sqrt()
    } else if q <= high {
        q * a + b / 2.0
    } else {
        a + b - (2.0 * a * b * (1.0 - q)).sqrt()
    }
}

// ---------------------------------------------------------------------------------------------
// Part 2: scan time and cycle-task latency with 8 devices, against none.

/// The scan program of part 2, the same with and without devices: it counts its scans,
/// toggles the 16 coils of each device every 10 ms (M100–M107, from the 20 ms clock flag),
/// reads the devices' inputs, and 40 rungs of bit logic and arithmetic.
fn load_program() -> String {
    let mut p = String::from("INC D00000\nLOAD _T20MS\n");
    for k in 0..DEVICES {
        p.push_str(&format!("MOV -1 M{:03}\n", 100 + k));
    }
    p.push_str("LOAD NOT _T20MS\n");
    for k in 0..DEVICES {
        p.push_str(&format!("MOV 0 M{:03}\n", 100 + k));
    }
    for k in 0..DEVICES {
        p.push_str(&format!(
            "LOAD P{:03}0\nAND P{:03}F\nOUT M02{k}0\nADD D00{:03} D00{:03} D0020{k}\n",
            10 + k,
            10 + k,
            100 + 10 * k,
            109 + 10 * k
        ));
    }
    p.push_str(&"LOAD M0000\nAND M0001\nOUT M0002\nADD D00010 1 D00011\n".repeat(40));
    p.push_str("END\n");
    p
}

/// The 8 devices' `[[remote]]`: 16 discrete inputs → P0100.. (a word each), 10 input
/// registers → D00100.. (10 words each), 16 coils ← M100..M107.
fn load_remotes(addresses: &[SocketAddr]) -> String {
    let mut text = String::new();
    for (k, address) in addresses.iter().enumerate() {
        text.push_str(&tcp_remote(&format!("dev{k}"), *address));
        text.push_str(&format!(
            "\n[[remote.read]]\ntable = \"discrete_inputs\"\naddress = 0\ncount = 16\n\
             device = \"P{:03}0\"\n\n[[remote.read]]\ntable = \"input_registers\"\naddress = 0\n\
             count = 10\ndevice = \"D00{:03}\"\n\n[[remote.write]]\ntable = \"coils\"\n\
             address = 0\ncount = 16\ndevice = \"M{:03}0\"\n",
            10 + k,
            100 + 10 * k,
            100 + k
        ));
    }
    text
}

fn load_config(remotes: &str) -> String {
    format!(
        "[plc]\nscan_period_ms = 1\n\n[[program]]\nfile = \"main.il\"\n\n[[program]]\n\
         file = \"tick.il\"\ntask = \"tick\"\n\n[[task]]\nname = \"tick\"\nkind = \"cycle\"\n\
         number = 0\npriority = 3\ninterval_ms = 1\n\n[control]\nenabled = false\n{remotes}"
    )
}

/// A histogram merged from several: each bucket's count recorded at its upper edge (which
/// the quantiles report anyway); the exact maximum kept aside.
#[derive(Default)]
struct Merged {
    histogram: Histogram,
    max: u64,
}

impl Merged {
    fn add(&mut self, h: &Histogram) {
        for (top, n) in h.buckets() {
            for _ in 0..n {
                self.histogram.record(top);
            }
        }
        self.max = self.max.max(h.summary().max);
    }

    fn q(&self, q: f64) -> u64 {
        self.histogram.quantile(q).min(self.max)
    }
}

#[derive(Default)]
struct Load {
    scan: Merged,
    tick: Merged,
    scans: u64,
    /// Scans the program counted (D00000), against `scans`.
    counted: u64,
    tick_runs: u64,
    tick_overruns: u64,
    run_ns: u64,
    /// Per device over all rounds: exchanges, failures, writes, round trips.
    devices: Vec<(u64, u64, u64, Merged)>,
    scheduling: String,
}

fn load_phase(dir: &ProjectDir, figures: &mut Load) {
    let mut driver = start(dir);
    figures.scheduling = scheduling(&driver.granted, &driver.problems);
    let started = Instant::now();
    let end = started + PHASE;
    while Instant::now() < end {
        while driver.reports.pop().is_ok() {}
        std::thread::sleep(Duration::from_millis(5));
    }
    let board = driver.remote_board().reports();
    let engine = driver.stop().expect("the scan thread ran to the end");
    figures.run_ns += started.elapsed().as_nanos() as u64;
    let scan = engine.scan_stats();
    figures.scan.add(&scan.time);
    figures.scans += scan.count;
    let scans = plcd::device::Address::parse("D00000").unwrap();
    figures.counted += engine.vm().mem.read(&scans) as u16 as u64;
    let tick = engine.task_stats("tick").expect("the tick task");
    figures.tick.add(&tick.start_latency);
    figures.tick_runs += tick.runs;
    figures.tick_overruns += tick.overruns;
    figures.devices.resize_with(board.len(), Default::default);
    for (sum, report) in figures.devices.iter_mut().zip(&board) {
        sum.0 += report.stats.requests;
        sum.1 += report.stats.failures;
        sum.2 += report.stats.writes;
        sum.3.add(&report.stats.round_trip);
    }
}

fn scan_load(addresses: &[SocketAddr]) -> (Load, Load) {
    let main = load_program();
    let none = ProjectDir::new(
        "none",
        &[("plcd.toml", &load_config("")), ("main.il", &main), ("tick.il", "INC D00001\nEND\n")],
    );
    let eight = ProjectDir::new(
        "eight",
        &[
            ("plcd.toml", &load_config(&load_remotes(addresses))),
            ("main.il", &main),
            ("tick.il", "INC D00001\nEND\n"),
        ],
    );
    let (mut quiet, mut loaded) = (Load::default(), Load::default());
    for round in 0..ROUNDS {
        if round % 2 == 0 {
            load_phase(&none, &mut quiet);
            load_phase(&eight, &mut loaded);
        } else {
            load_phase(&eight, &mut loaded);
            load_phase(&none, &mut quiet);
        }
        eprintln!("remote_io: scan load round {} of {ROUNDS} done", round + 1);
    }
    (quiet, loaded)
}

// ---------------------------------------------------------------------------------------------
// Part 3: the scan thread's refreshes of 8 devices.

struct Refresh {
    /// The timing thread ran under SCHED_FIFO 80, as the scan thread does.
    fifo: bool,
    inputs: Vec<u64>,
    unchanged: Vec<u64>,
    changed: Vec<u64>,
}

/// Times the refreshes of the 8 devices on a thread of their own: under SCHED_FIFO 80 (the
/// scan thread's default priority) when `fifo` and permitted, else a plain thread.
fn refresh_cost(addresses: &[SocketAddr], fifo: bool) -> Refresh {
    let text = load_config(&load_remotes(addresses));
    let config =
        plcd::config::parse(&text, Path::new("plcd.toml")).unwrap_or_else(|d| panic!("{d}"));
    let (mut io, service) = remote::start(&config.remotes).expect("pollers start");
    let coils: Vec<usize> =
        config.remotes.iter().map(|r| r.writes[0].table.first as usize / 16).collect();
    let refresh = std::thread::scope(|scope| {
        scope
            .spawn(|| {
                let fifo = fifo && plcd::drivers::real_time::sys::set_fifo(80).is_ok();
                let mut mem = Memory::new();
                std::thread::sleep(Duration::from_millis(300));
                let (mut inputs, mut unchanged, mut changed) = (Vec::new(), Vec::new(), Vec::new());
                let mut next = now_ns();
                for i in 0..REFRESHES {
                    next += 1_000_000;
                    std::thread::sleep(Duration::from_nanos(next.saturating_sub(now_ns())));
                    let t = Instant::now();
                    io.refresh_inputs(&mut mem);
                    inputs.push(t.elapsed().as_nanos() as u64);
                    // Every 10 ms the program toggles the coils, as part 2's does.
                    let change = i % 10 == 0;
                    if change {
                        for &w in &coils {
                            mem.words_mut()[w] ^= 0xFFFF;
                        }
                    }
                    let t = Instant::now();
                    io.refresh_outputs(&mem);
                    let took = t.elapsed().as_nanos() as u64;
                    if change {
                        changed.push(took);
                    } else {
                        unchanged.push(took);
                    }
                }
                for v in [&mut inputs, &mut unchanged, &mut changed] {
                    v.sort_unstable();
                }
                Refresh { fifo, inputs, unchanged, changed }
            })
            .join()
            .unwrap()
    });
    drop(service);
    refresh
}

// ---------------------------------------------------------------------------------------------
// Part 4: an RTU line.

fn wire_ns(bytes: usize) -> u64 {
    bytes as u64 * CHAR_BITS * 1_000_000_000 / u64::from(BAUD)
}

/// CRC-16/MODBUS, low byte first on the wire.
fn crc(bytes: &[u8]) -> [u8; 2] {
    crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(bytes).to_le_bytes()
}

struct Line {
    devices: usize,
    count: u16,
    /// Successful polls per second, all devices, and each device's share.
    polls_per_s: f64,
    shares: Vec<f64>,
    failures: u64,
    /// The request-to-answer wait plcd measured (the simulated wire's time and what it adds).
    round_trip: Histogram,
    /// How late the simulated device wrote its answers after their wire time, ns, sorted.
    device_late: Vec<u64>,
    /// The line's silence as the device saw it: from an answer written to the next request
    /// read, ns, sorted (the spec's minimum is t3.5).
    gaps: Vec<u64>,
}

/// The theoretical maximum of polls per second: request and answer on the wire, each followed
/// by t3.5.
fn theoretical(count: u16) -> f64 {
    1e9 / (wire_ns(8) + wire_ns(5 + 2 * usize::from(count)) + 2 * T35_NS) as f64
}

/// A device end of the line: reads FC 3 requests, answers each as a wire would deliver it:
/// when the request's 8 characters, t3.5 and the answer's characters have passed since the
/// request arrived.
fn line_device(
    mut end: serialport::TTYPort,
    units: Vec<u8>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<(Vec<u64>, Vec<u64>)> {
    std::thread::spawn(move || {
        end.set_timeout(Duration::from_millis(100)).unwrap();
        let mut late = Vec::new();
        let mut gaps = Vec::new();
        let mut written = None;
        let mut request = [0u8; 8];
        let mut got = 0;
        while !stop.load(Ordering::Acquire) {
            match end.read(&mut request[got..]) {
                Ok(n) => got += n,
                Err(e) if e.kind() == ErrorKind::TimedOut => continue,
                // The other end not open (yet, or any more): a hangup.
                Err(_) => {
                    std::thread::sleep(Duration::from_millis(10));
                    continue;
                }
            }
            if got < request.len() {
                continue;
            }
            got = 0;
            let arrived = now_ns();
            if let Some(written) = written.take() {
                gaps.push(arrived - written);
            }
            assert_eq!(crc(&request[..6]), request[6..8], "a request with a bad CRC");
            assert_eq!(request[1], 3, "FC 3 only");
            if !units.contains(&request[0]) {
                continue;
            }
            let count = usize::from(u16::from_be_bytes([request[4], request[5]]));
            let mut answer = vec![request[0], 3, (2 * count) as u8];
            for k in 0..count {
                answer.extend((k as u16 * 7).to_be_bytes());
            }
            answer.extend(crc(&answer));
            let due = arrived + wire_ns(request.len()) + T35_NS + wire_ns(answer.len());
            sleep_until(due);
            late.push(now_ns() - due);
            if end.write_all(&answer).is_ok() {
                written = Some(now_ns());
            }
        }
        (late, gaps)
    })
}

fn rtu_line(devices: usize, count: u16) -> Line {
    let (end, line_end) = serialport::TTYPort::pair().expect("a pseudo terminal");
    let port = line_end.name().expect("the pseudo terminal's name");
    drop(line_end);
    let mut text = String::from("[plc]\nscan_period_ms = 1\n\n[[program]]\nfile = \"main.il\"\n");
    for unit in 1..=devices {
        text.push_str(&format!(
            "\n[[remote]]\nname = \"rtu{unit}\"\ntransport = \"rtu\"\nport = \"{port}\"\n\
             baud = {BAUD}\nparity = \"even\"\nstop_bits = 1\nunit_id = {unit}\nperiod_ms = 1\n\
             timeout_ms = 100\n\n[[remote.read]]\ntable = \"holding_registers\"\naddress = 0\n\
             count = {count}\ndevice = \"D{:05}\"\n",
            1000 * unit
        ));
    }
    let config =
        plcd::config::parse(&text, Path::new("plcd.toml")).unwrap_or_else(|d| panic!("{d}"));
    let stop = Arc::new(AtomicBool::new(false));
    let device = line_device(end, (1..=devices as u8).collect(), Arc::clone(&stop));
    let (_io, service) = remote::start(&config.remotes).expect("the line's poller starts");
    let board = service.board();
    let ok = |reports: &[DeviceReport]| -> Vec<u64> {
        reports.iter().map(|r| r.stats.requests - r.stats.failures).collect()
    };
    // Until the line runs.
    std::thread::sleep(Duration::from_millis(500));
    let (t0, before) = (Instant::now(), board.reports());
    std::thread::sleep(LINE_RUN);
    let (elapsed, after) = (t0.elapsed().as_secs_f64(), board.reports());
    stop.store(true, Ordering::Release);
    drop(service);
    let (mut device_late, mut gaps) = device.join().unwrap();
    device_late.sort_unstable();
    gaps.sort_unstable();
    let polls: Vec<f64> =
        ok(&after).iter().zip(ok(&before)).map(|(a, b)| (a - b) as f64 / elapsed).collect();
    let total: f64 = polls.iter().sum();
    let mut round_trip = Histogram::new();
    round_trip.copy_from(&after[0].stats.round_trip);
    Line {
        devices,
        count,
        polls_per_s: total,
        shares: polls,
        failures: after.iter().map(|r| r.stats.failures).sum::<u64>()
            - before.iter().map(|r| r.stats.failures).sum::<u64>(),
        round_trip,
        device_late,
        gaps,
    }
}

// ---------------------------------------------------------------------------------------------

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let load_before = load_average();
    let stores: Vec<Arc<Store>> = (0..DEVICES).map(|_| Store::new()).collect();
    let addresses: Vec<SocketAddr> = stores.iter().map(|s| tcp_device(Arc::clone(s))).collect();

    eprintln!("remote_io: input age ({} s)", AGE_RUN.as_secs());
    let age = input_age();
    eprintln!("remote_io: scan load ({ROUNDS} rounds of 2 × {} s)", PHASE.as_secs());
    let reads_before: u64 = stores.iter().map(|s| s.reads.load(Ordering::Relaxed)).sum();
    let writes_before: u64 = stores.iter().map(|s| s.writes.load(Ordering::Relaxed)).sum();
    let (quiet, loaded) = scan_load(&addresses);
    let reads: u64 =
        stores.iter().map(|s| s.reads.load(Ordering::Relaxed)).sum::<u64>() - reads_before;
    let writes: u64 =
        stores.iter().map(|s| s.writes.load(Ordering::Relaxed)).sum::<u64>() - writes_before;
    eprintln!("remote_io: refresh cost");
    let refresh = [refresh_cost(&addresses, true), refresh_cost(&addresses, false)];
    eprintln!("remote_io: RTU line");
    let lines: Vec<Line> = [(1, 10), (2, 10), (1, 125), (2, 125)]
        .into_iter()
        .map(|(devices, count)| rtu_line(devices, count))
        .collect();

    let mut f = Fragment::new("cargo bench --bench remote_io");
    f.line(format!(
        "Load average (1 min) of this shared machine before the run: {load_before}, after it: \
         {} (the bench's own threads count in the second).\n",
        load_average()
    ));
    report_age(&mut f, &age);
    report_load(&mut f, &quiet, &loaded, reads, writes);
    report_refresh(&mut f, &refresh);
    report_lines(&mut f, &lines);
    write_fragment("remote", &f).expect("fragment written");
}

/// The 1-minute load average, as /proc/loadavg says.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|l| l.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".into())
}

fn report_age(f: &mut Fragment, age: &Age) {
    let a = &age.ages;
    let rtt = age.round_trip.summary();
    let scan = age.scan.summary();
    // Over starts: the wait for the next poll U(0, 10 ms), for the next scan U(0, 1 ms), the
    // answer's way back (half a round trip), the scan to its END.
    let expected = |q: f64| {
        (uniform_sum_quantile(10e6, 1e6, q) + rtt.p50 as f64 / 2.0 + scan.p50 as f64) as u64
    };
    // In one run the poll grid and the scan grid keep their phase: the wait for the next scan
    // is about constant, and the smallest age (a change just before a poll) shows it.
    let min = a[0];
    let this_run = |q: f64| (q * 10e6) as u64 + min;
    f.line(format!(
        "**Input age over TCP, `period_ms = 10`.** The real-time driver (`Driver`, the threads \
         of `plcd run`; {}) runs a project with a 1 ms fixed scan period whose program is \
         `LOAD D00100.0` / `OUT P0050`; D00100 is input register 0 of a Modbus TCP device on \
         the loopback (a thread of the bench), polled every 10 ms. The device sets the register \
         to the next number at random moments ({}–{} ms apart, uniform), noting the \
         CLOCK_MONOTONIC time; the driver reports each change of the watched output P0050 with \
         the time of the END of the scan that made it, the first scan whose input refresh \
         copied the new value. Age = that END − the change, for {} changes in {} s.\n",
        age.scheduling,
        CHANGE_EVERY_MS.0,
        CHANGE_EVERY_MS.1,
        age.changes,
        AGE_RUN.as_secs()
    ));
    f.table(
        &["input age", "p50", "p99", "max", "count"],
        &[
            vec![
                "measured".into(),
                ms(pct(a, 0.5)),
                ms(pct(a, 0.99)),
                ms(*a.last().unwrap()),
                format!("{} (unseen: {})", a.len(), age.unseen),
            ],
            vec![
                "U(0, 10 ms) + the smallest age (this run's phase)".into(),
                ms(this_run(0.5)),
                ms(this_run(0.99)),
                ms(this_run(1.0)),
                String::new(),
            ],
            vec![
                "expected over starts: U(0, 10 ms) + U(0, 1 ms) + RTT p50 / 2 + scan p50".into(),
                ms(expected(0.5)),
                ms(expected(0.99)),
                ms(expected(1.0)),
                String::new(),
            ],
        ],
    );
    f.line(format!(
        "- smallest age {}; the device's round trip as plcd measured it ({} exchanges, {} \
         failed): p50 {}, p99 {}, max {}; the scan time (input refresh to END): p50 {}, p99 {}",
        us(min),
        age.device.stats.requests,
        age.device.stats.failures,
        us(rtt.p50),
        us(rtt.p99),
        us(rtt.max),
        us(scan.p50),
        us(scan.p99)
    ));
    f.line("");
}

fn report_load(f: &mut Fragment, quiet: &Load, loaded: &Load, reads: u64, writes: u64) {
    f.line(format!(
        "**Scan time and cycle-task latency with {DEVICES} TCP devices, against none.** The \
         real-time driver ({}) runs a project with a 1 ms fixed scan period, a scan program of \
         {} instructions (it counts its scans, toggles 16 coils per device every 10 ms from the \
         20 ms clock flag, reads every device's inputs, 40 rungs of bit logic and arithmetic) \
         and a 1 ms cycle task (`INC`); the same project once without and once with \
         {DEVICES} `[[remote]]` on the loopback, each a thread of the bench, polled every 10 ms: \
         16 discrete inputs (FC 2) → a P word and 10 input registers (FC 4) → 10 D words read, \
         16 coils written from an M word (FC 15, on change: every 10 ms). {ROUNDS} rounds, each \
         a {} s phase of each configuration, in alternating order; figures from the engine's \
         histograms, merged over the rounds. The scan time runs from the scan's start (input \
         refresh) to END; the output refresh comes after it (its cost is the next table).\n",
        loaded.scheduling,
        load_program().lines().count(),
        PHASE.as_secs()
    ));
    let row = |name: &str, a: u64, b: u64| {
        vec![name.to_string(), us(a), us(b), format!("{:.2}", b as f64 / a.max(1) as f64)]
    };
    f.table(
        &["figure", "no remote", &format!("{DEVICES} remotes every 10 ms"), "ratio"],
        &[
            row("scan time p50", quiet.scan.q(0.5), loaded.scan.q(0.5)),
            row("scan time p99", quiet.scan.q(0.99), loaded.scan.q(0.99)),
            row("scan time max", quiet.scan.max, loaded.scan.max),
            row("cycle task start latency p50", quiet.tick.q(0.5), loaded.tick.q(0.5)),
            row("cycle task start latency p99", quiet.tick.q(0.99), loaded.tick.q(0.99)),
            row("cycle task start latency max", quiet.tick.max, loaded.tick.max),
        ],
    );
    for (name, l) in [("no remote", quiet), ("remotes", loaded)] {
        f.line(format!(
            "- {name}: {} scans in {} ms, the program counted {}; the cycle task ran {} times, \
             deadlines that found it still running: {}",
            l.scans,
            l.run_ns / 1_000_000,
            l.counted,
            l.tick_runs,
            l.tick_overruns
        ));
    }
    let secs = loaded.run_ns as f64 / 1e9;
    let mut rtt = Merged::default();
    let (mut exchanges, mut failures) = (0, 0);
    for (requests, failed, _, round_trip) in &loaded.devices {
        exchanges += requests;
        failures += failed;
        for (top, n) in round_trip.histogram.buckets() {
            for _ in 0..n {
                rtt.histogram.record(top);
            }
        }
        rtt.max = rtt.max.max(round_trip.max);
    }
    f.line(format!(
        "- the devices served {:.0} reads/s and {:.0} writes/s in all ({} exchanges, {} failed); \
         round trip as plcd measured it: p50 {}, p99 {}, max {}",
        reads as f64 / secs,
        writes as f64 / secs,
        exchanges,
        failures,
        us(rtt.q(0.5)),
        us(rtt.q(0.99)),
        us(rtt.max)
    ));
    f.line("");
}

fn report_refresh(f: &mut Fragment, refresh: &[Refresh; 2]) {
    f.line(format!(
        "**The scan thread's part of {DEVICES} remotes**: `RemoteIo::refresh_inputs` and \
         `refresh_outputs` of the {DEVICES} devices above (their pollers running), timed alone \
         every millisecond, {REFRESHES} times, on a thread under SCHED_FIFO 80 as the scan \
         thread ({}), then on a plain thread; the write tables toggle every tenth refresh, \
         which then wakes the {DEVICES} pollers (one `unpark` each).\n",
        if refresh[0].fifo { "granted" } else { "refused: not real time either" }
    ));
    let mut rows = Vec::new();
    for (k, r) in refresh.iter().enumerate() {
        let thread = match (k, r.fifo) {
            (0, true) => "SCHED_FIFO 80",
            (0, false) => "SCHED_OTHER (SCHED_FIFO refused)",
            _ => "SCHED_OTHER",
        };
        let mut row = |name: &str, v: &[u64]| {
            rows.push(vec![
                thread.to_string(),
                name.to_string(),
                us(pct(v, 0.5)),
                us(pct(v, 0.99)),
                us(*v.last().unwrap()),
                v.len().to_string(),
            ])
        };
        row("inputs (16 bits + 10 words a device)", &r.inputs);
        row("outputs, unchanged", &r.unchanged);
        row(&format!("outputs, changed ({DEVICES} unparks)"), &r.changed);
    }
    f.table(&["thread", "refresh", "p50", "p99", "max", "count"], &rows);
}

fn report_lines(f: &mut Fragment, lines: &[Line]) {
    f.line(format!(
        "**An RTU line at {BAUD} baud, 8E1 (11 bits a character), against the protocol's \
         maximum.** plcd's RTU poller (`plcd::io::remote::start` with `rtu` devices, \
         `period_ms = 1`, so it polls flat out) on one end of a pseudo terminal; on the other a \
         bench thread that answers each FC 3 request when a wire would have delivered the \
         answer: the request's 8 characters, t3.5 (1.75 ms) and the answer's characters after \
         the request arrived (a pseudo terminal has no baud rate). The maximum is the Modbus \
         serial line's: request + t3.5 + answer + t3.5 on the wire per poll. Each \
         configuration polled for {} s.\n",
        LINE_RUN.as_secs()
    ));
    let rows: Vec<Vec<String>> = lines
        .iter()
        .map(|l| {
            let max = theoretical(l.count);
            let rtt = l.round_trip.summary();
            let shares = l.shares.iter().map(|s| format!("{s:.1}")).collect::<Vec<_>>().join(" + ");
            vec![
                format!("{} device{}", l.devices, if l.devices == 1 { "" } else { "s" }),
                format!("{} registers ({} + {} bytes)", l.count, 8, 5 + 2 * l.count),
                format!("{:.1} ({shares})", l.polls_per_s),
                format!("{max:.1}"),
                format!("{:.3}", l.polls_per_s / max),
                format!("{} / {}", ms(rtt.p50), ms(rtt.p99)),
                format!("{} / {}", ms(pct(&l.gaps, 0.5)), ms(pct(&l.gaps, 0.99))),
                us(pct(&l.device_late, 0.5)),
                l.failures.to_string(),
            ]
        })
        .collect();
    f.table(
        &[
            "line",
            "table (FC 3)",
            "polls/s measured",
            "maximum",
            "measured / maximum",
            "plcd's round trip p50 / p99",
            "silence before a request p50 / p99",
            "device late p50",
            "failures",
        ],
        &rows,
    );
}
