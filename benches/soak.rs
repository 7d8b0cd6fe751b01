//! The soak: the release `plcd run` for `--duration` seconds under everything at once, and
//! what it did meanwhile (docs/SOAK.md has the method, the criteria and the figures):
//!
//! - an edge storm: the sim backend plays P0000–P0007 toggled one line every `--edge-step-ns`
//!   (default 100 ns: far faster than its player thread can apply them, so it plays at the
//!   highest rate it can drive), each edge the start of an io task;
//! - two 1 ms cycle tasks and a scan program with timers and counters every 1 ms;
//! - `--control-clients` (50) control clients and `--modbus-clients` (20) Modbus TCP clients
//!   writing and reading back, back to back or `--pause-ms` apart, reconnecting every
//!   `--reconnect-every` rounds;
//! - every `--change-every` seconds (2.5) a SIGHUP reload to the other of two config variants,
//!   or an online change of the scan program, in turn;
//! - every `--sample` seconds the daemon's resident memory, fds and threads from /proc and its
//!   own figures from `status`.
//!
//! `cargo bench --bench soak -- --duration 600` (the full run), `-- --duration 45` (the CI
//! one). Exit 0 when every criterion held, 1 otherwise, with the figures either way.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;
use plcctl::client::{Client, ClientError};
use plcd_ipc::{ErrorKind, Reply, Request};

#[path = "soak/clients.rs"]
mod clients;
#[path = "soak/project.rs"]
mod project;
#[path = "soak/watch.rs"]
mod watch;

use clients::Tally;
use project::{marker, Project};
use watch::{Machine, Process, Sample, Tracker};

/// Lines of the storm: 8 contacts toggled 5000 times each in a pass.
const STORM_LINES: usize = 40_000;
/// The daemon alone before the clients start: its baseline fds, threads and memory.
const SETTLE: Duration = Duration::from_secs(3);
/// How long a reload or an online change may take to show in device memory.
const CHANGE_PATIENCE: Duration = Duration::from_secs(10);
/// The daemon's threads whose CPU share the report gives.
const THREADS: [&str; 3] = ["plcd-scan", "plcd-stimulus", "plcd-control"];
/// Resident memory may move this much within the second half of the run (see docs/SOAK.md).
const RSS_BAND_KIB: u64 = 2048;

#[derive(Debug, Clone)]
struct Options {
    duration: Duration,
    control_clients: usize,
    modbus_clients: usize,
    reconnect_every: u32,
    /// What each client waits before each round (0: none, back to back).
    pause: Duration,
    change_every: Duration,
    sample: Duration,
    edge_step_ns: u64,
}

fn usage(message: &str) -> ! {
    eprintln!(
        "soak: {message}\nusage: cargo bench --bench soak -- [--duration SECS] \
         [--control-clients N] [--modbus-clients N] [--reconnect-every ROUNDS] [--pause-ms MS] \
         [--change-every SECS] [--sample SECS] [--edge-step-ns NS]"
    );
    std::process::exit(2);
}

fn options() -> Options {
    let mut o = Options {
        duration: Duration::from_secs(600),
        control_clients: 50,
        modbus_clients: 20,
        reconnect_every: 200,
        pause: Duration::ZERO,
        change_every: Duration::from_millis(2500),
        sample: Duration::ZERO,
        edge_step_ns: 100,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        if arg == "--bench" {
            continue; // cargo bench passes it
        }
        let mut value = || args.next().unwrap_or_else(|| usage(&format!("{arg} needs a value")));
        let secs = |v: String| {
            v.parse::<f64>()
                .ok()
                .filter(|s| *s > 0.0)
                .map(Duration::from_secs_f64)
                .unwrap_or_else(|| usage(&format!("{arg}: `{v}` is not a number of seconds")))
        };
        let number = |v: String| {
            v.parse::<u64>()
                .ok()
                .filter(|n| *n > 0)
                .unwrap_or_else(|| usage(&format!("{arg}: `{v}` is not a positive integer")))
        };
        match arg.as_str() {
            "--duration" => o.duration = secs(value()),
            "--control-clients" => o.control_clients = number(value()) as usize,
            "--modbus-clients" => o.modbus_clients = number(value()) as usize,
            "--reconnect-every" => o.reconnect_every = number(value()) as u32,
            "--pause-ms" => o.pause = Duration::from_millis(number(value())),
            "--change-every" => o.change_every = secs(value()),
            "--sample" => o.sample = secs(value()),
            "--edge-step-ns" => o.edge_step_ns = number(value()),
            _ => usage(&format!("unknown argument `{arg}`")),
        }
    }
    if o.control_clients > 60 {
        usage("at most 60 control clients (the socket serves 64 and the soak uses 2 more)");
    }
    if o.modbus_clients > 30 {
        usage("at most 30 Modbus clients (the server serves 32 at once)");
    }
    if o.sample.is_zero() {
        // 120 looks at a run, at least one every 5 s and at most one a second.
        o.sample = (o.duration / 120).clamp(Duration::from_secs(1), Duration::from_secs(5));
    }
    o
}

/// The daemon: the child process and its log, read line by line by a thread.
struct Daemon {
    child: Child,
    log: Arc<Mutex<Vec<String>>>,
    reader: Option<std::thread::JoinHandle<()>>,
}

impl Daemon {
    fn start(project: &Project) -> (Daemon, SocketAddr) {
        let mut child = Command::new(env!("CARGO_BIN_EXE_plcd"))
            .args(["run", "--config"])
            .arg(project.config())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .env_remove("NOTIFY_SOCKET")
            .env_remove("WATCHDOG_USEC")
            .env_remove("JOURNAL_STREAM")
            .env_remove("STATE_DIRECTORY")
            .spawn()
            .expect("plcd starts");
        let log = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = mpsc::channel();
        let stderr = BufReader::new(child.stderr.take().unwrap());
        let lines = Arc::clone(&log);
        let reader = std::thread::spawn(move || {
            for line in stderr.lines() {
                let Ok(line) = line else { break };
                if let Some((_, addr)) = line.split_once("modbus: serving ") {
                    if let Ok(addr) = addr.trim().parse::<SocketAddr>() {
                        let _ = tx.send(addr);
                    }
                }
                lines.lock().unwrap().push(line);
            }
        });
        let daemon = Daemon { child, log, reader: Some(reader) };
        let address = rx.recv_timeout(Duration::from_secs(30)).unwrap_or_else(|_| {
            panic!("plcd did not serve Modbus:\n{}", daemon.log.lock().unwrap().join("\n"))
        });
        (daemon, address)
    }

    fn pid(&self) -> u32 {
        self.child.id()
    }

    fn signal(&self, signal: Signal) {
        kill(Pid::from_raw(self.pid() as i32), signal).expect("plcd is signalled");
    }

    /// SIGTERM; the exit code once it is gone (None: killed by a signal or not gone in 30 s).
    fn stop(mut self) -> (Option<i32>, Vec<String>) {
        self.signal(Signal::SIGTERM);
        let deadline = Instant::now() + Duration::from_secs(30);
        let code = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status.code();
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                let _ = self.child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        if let Some(reader) = self.reader.take() {
            let _ = reader.join();
        }
        let log = self.log.lock().unwrap().clone();
        (code, log)
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn connect(socket: &PathBuf) -> Client {
    let start = Instant::now();
    loop {
        match Client::connect(socket, clients::ANSWER_TIMEOUT) {
            Ok(c) => return c,
            Err(e) if start.elapsed() > Duration::from_secs(20) => panic!("{e}"),
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

/// A request of the soak's own (not a client's), retried while `busy`.
fn request(c: &mut Client, request: &Request) -> Result<Reply, ClientError> {
    loop {
        match c.request(request) {
            Err(ClientError::Daemon { failure, .. }) if failure.kind == ErrorKind::Busy => {
                std::thread::sleep(Duration::from_millis(2));
            }
            other => return other,
        }
    }
}

fn status(c: &mut Client) -> Result<plcd_ipc::Status, String> {
    match request(c, &Request::Status) {
        Ok(Reply::Status(s)) => Ok(*s),
        Ok(other) => Err(format!("status answered {other:?}")),
        Err(e) => Err(format!("status: {e}")),
    }
}

/// Waits until `device` holds `value`: how long that took, or an error after
/// [`CHANGE_PATIENCE`].
fn wait_for(c: &mut Client, device: &str, value: i64) -> Result<Duration, String> {
    let start = Instant::now();
    loop {
        match request(c, &Request::Get { devices: vec![device.into()] }) {
            Ok(Reply::Values { values, .. }) if values[0].value.as_i64() == Some(value) => {
                return Ok(start.elapsed());
            }
            Ok(_) => {}
            Err(e) => return Err(format!("get {device}: {e}")),
        }
        if start.elapsed() > CHANGE_PATIENCE {
            return Err(format!("{device} is not {value} after {CHANGE_PATIENCE:?}"));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// What the changer did.
#[derive(Default)]
struct Changes {
    reloads: AtomicU64,
    online: AtomicU64,
    /// The longest time from the request to its marker in device memory, in µs.
    slowest_us: AtomicU64,
    failures: Mutex<Vec<String>>,
}

/// Every `every`, in turn: a SIGHUP reload to the other config variant (its marker must reach
/// D00001), and an online change of the scan program (its marker must reach D00002). The
/// tracker gets a look just before each reload, whose new engine starts its figures from zero.
#[allow(clippy::too_many_arguments)]
fn changer(
    project: &Project,
    pid: u32,
    every: Duration,
    modbus_clients: usize,
    stop: &AtomicBool,
    changes: &Changes,
    tracker: &Mutex<Tracker>,
) {
    let mut c = connect(&project.socket());
    let (mut reloads, mut online) = (0u32, 0u32);
    let mut next = Instant::now() + every;
    let fail = |what: String| changes.failures.lock().unwrap().push(what);
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(next.saturating_duration_since(Instant::now()).min(every));
        if Instant::now() < next {
            continue;
        }
        next += every;
        let took = if (reloads + online) % 2 == 0 {
            reloads += 1;
            project.write_variant(reloads, online, modbus_clients);
            match status(&mut c) {
                Ok(s) => tracker.lock().unwrap().update(s),
                Err(e) => fail(e),
            }
            kill(Pid::from_raw(pid as i32), Signal::SIGHUP).expect("SIGHUP");
            changes.reloads.fetch_add(1, Ordering::Relaxed);
            let seen = wait_for(&mut c, "D00001", marker(reloads))
                .map_err(|e| format!("reload {reloads}: {e}"));
            seen
        } else {
            online += 1;
            project.write_scan_program(reloads, online);
            let load = Request::Load {
                config: project.config().to_string_lossy().into_owned(),
                online: true,
            };
            match request(&mut c, &load) {
                Ok(Reply::Loaded { online: true, .. }) => {
                    changes.online.fetch_add(1, Ordering::Relaxed);
                    wait_for(&mut c, "D00002", marker(online))
                        .map_err(|e| format!("online change {online}: {e}"))
                }
                Ok(other) => Err(format!("online change {online}: answered {other:?}")),
                Err(e) => Err(format!("online change {online}: {e} {:?}", e.details())),
            }
        };
        match took {
            Ok(took) => {
                changes.slowest_us.fetch_max(took.as_micros() as u64, Ordering::Relaxed);
            }
            Err(e) => fail(e),
        }
    }
}

fn mib(kib: u64) -> String {
    format!("{:.1} MiB", kib as f64 / 1024.0)
}

fn us(ns: u64) -> String {
    format!("{:.1} µs", ns as f64 / 1000.0)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let o = options();
    let dir = std::env::temp_dir().join(format!("plcd-soak-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let project = Project::write(&dir, STORM_LINES, o.edge_step_ns, o.modbus_clients);
    let (daemon, modbus) = Daemon::start(&project);
    let pid = daemon.pid();
    let socket = project.socket();
    let mut watcher = connect(&socket);
    let tracker = Mutex::new(Tracker::default());
    let failures: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let fail = |what: String| failures.lock().unwrap().push(what);

    // The daemon alone, storm and tasks running: its baseline.
    std::thread::sleep(SETTLE);
    match status(&mut watcher) {
        Ok(s) => tracker.lock().unwrap().update(s),
        Err(e) => fail(e),
    }
    let baseline = Process::read(pid).expect("plcd runs");
    let alone_overruns = tracker.lock().unwrap().last().map_or(0, |s| {
        s.tasks.iter().filter(|t| t.kind == "cycle").map(|t| t.overruns).sum::<u64>()
    });

    let stop = Arc::new(AtomicBool::new(false));
    let control_tally = Arc::new(Tally::default());
    let modbus_tally = Arc::new(Tally::default());
    let changes = Changes::default();
    let started = Instant::now();
    let machine_start = Machine::read();
    let threads_start = THREADS.map(|name| watch::thread_ticks(pid, name));
    let mut samples: Vec<Sample> = Vec::new();
    std::thread::scope(|scope| {
        let mut threads = Vec::new();
        for k in 0..o.control_clients {
            let (socket, stop, tally) =
                (socket.clone(), Arc::clone(&stop), Arc::clone(&control_tally));
            let (every, pause) = (o.reconnect_every, o.pause);
            threads.push(
                scope.spawn(move || clients::control_client(k, socket, every, pause, stop, tally)),
            );
        }
        for k in 0..o.modbus_clients {
            let (stop, tally) = (Arc::clone(&stop), Arc::clone(&modbus_tally));
            let (every, pause) = (o.reconnect_every, o.pause);
            threads.push(
                scope.spawn(move || clients::modbus_client(k, modbus, every, pause, stop, tally)),
            );
        }
        let changer_thread = scope.spawn(|| {
            changer(&project, pid, o.change_every, o.modbus_clients, &stop, &changes, &tracker)
        });

        let mut next = started;
        while started.elapsed() < o.duration {
            next += o.sample;
            std::thread::sleep(next.saturating_duration_since(Instant::now()));
            let Some(process) = Process::read(pid) else {
                fail(format!("plcd is gone after {:?}", started.elapsed()));
                break;
            };
            let lost_edges = match status(&mut watcher) {
                Ok(s) => {
                    let lost = s.lost_edges;
                    if s.watchdog_trips > 0 {
                        fail(format!("{} watchdog trips", s.watchdog_trips));
                    }
                    tracker.lock().unwrap().update(s);
                    lost
                }
                Err(e) => {
                    fail(e);
                    watcher = connect(&socket);
                    samples.last().map_or(0, |s| s.lost_edges)
                }
            };
            let t = tracker.lock().unwrap();
            samples.push(Sample {
                at: started.elapsed(),
                process,
                machine: Machine::read(),
                lost_edges,
                edges_seen: t.io_runs + t.io_ignored,
                cycle_overruns: t.cycle_overruns,
                answers: control_tally.ok.load(Ordering::Relaxed)
                    + modbus_tally.ok.load(Ordering::Relaxed),
            });
        }
        stop.store(true, Ordering::Relaxed);
        for t in threads {
            t.join().expect("a client thread");
        }
        changer_thread.join().expect("the changer thread");
    });
    let elapsed = started.elapsed();
    let machine_end = Machine::read();
    let threads_end = THREADS.map(|name| watch::thread_ticks(pid, name));

    // Every connection closed: the fds and threads go back to the baseline.
    let settle_start = Instant::now();
    let settled = loop {
        let p = Process::read(pid);
        match p {
            Some(p) if p.fds == baseline.fds && p.threads == baseline.threads => break Some(p),
            Some(p) if settle_start.elapsed() > Duration::from_secs(10) => {
                fail(format!(
                    "10 s after the clients stopped: {} fds, {} threads; before they started \
                     {} fds, {} threads",
                    p.fds, p.threads, baseline.fds, baseline.threads
                ));
                break Some(p);
            }
            None => {
                fail("plcd is gone at the end".into());
                break None;
            }
            _ => std::thread::sleep(Duration::from_millis(100)),
        }
    };
    let last = match status(&mut watcher) {
        Ok(s) => {
            if s.mode != plcd_ipc::ModeName::Run {
                fail(format!("mode {} at the end", s.mode.as_str()));
            }
            tracker.lock().unwrap().update(s.clone());
            Some(s)
        }
        Err(e) => {
            fail(format!("at the end: {e}"));
            None
        }
    };
    drop(watcher);
    let (code, log) = daemon.stop();
    if code != Some(0) {
        fail(format!("plcd exited with {code:?}"));
    }
    let _ = std::fs::remove_dir_all(&dir);

    // The log: errors are failures; the only warnings expected are lost edges.
    let mut lost_edge_warnings = 0;
    for line in &log {
        if line.contains(" ERROR ") || line.contains("panicked") {
            fail(format!("log: {line}"));
        } else if line.contains(" WARN ") {
            if line.contains("input edges lost") {
                lost_edge_warnings += 1;
            } else {
                fail(format!("log: {line}"));
            }
        }
    }
    let tracker = tracker.into_inner().unwrap();
    for mode in &tracker.not_run {
        fail(format!("mode {mode}"));
    }
    for f in changes.failures.lock().unwrap().iter() {
        fail(f.clone());
    }
    for (name, tally) in [("control", &control_tally), ("Modbus", &modbus_tally)] {
        let n = tally.failures.load(Ordering::Relaxed);
        if n > 0 {
            fail(format!(
                "{n} {name} requests failed; the first: {:#?}",
                tally.quoted.lock().unwrap()
            ));
        }
    }

    // Resident memory after warm-up: the second half of the run.
    let half: Vec<&Sample> = samples.iter().filter(|s| s.at >= elapsed / 2).collect();
    let rss = |s: &&Sample| s.process.rss_kib;
    let (rss_min, rss_max) =
        (half.iter().map(rss).min().unwrap_or(0), half.iter().map(rss).max().unwrap_or(0));
    if rss_max - rss_min > RSS_BAND_KIB {
        fail(format!(
            "resident memory moved by {} in the second half ({} to {})",
            mib(rss_max - rss_min),
            mib(rss_min),
            mib(rss_max)
        ));
    }
    let first_half_max =
        samples.iter().filter(|s| s.at < elapsed / 2).map(|s| s.process.rss_kib).max();

    // The report.
    let lost_edges = last.as_ref().map_or(0, |s| s.lost_edges);
    let seen = tracker.io_runs + tracker.io_ignored;
    let segments = &tracker.segments;
    let first = segments.first().copied().unwrap_or_default();
    let end = segments.last().copied().unwrap_or_default();
    let worst = segments.iter().map(|s| s.max_ns).max().unwrap_or(0);
    let steal = machine_end.steal - machine_start.steal;
    let total = (machine_end.total - machine_start.total).max(1);
    let answers = |t: &Tally| t.ok.load(Ordering::Relaxed);
    let busy = |t: &Tally| t.busy.load(Ordering::Relaxed);
    let conns = |t: &Tally| t.connections.load(Ordering::Relaxed);
    let max = |f: fn(&Sample) -> u64| samples.iter().map(f).max().unwrap_or(0);
    let load_avg =
        samples.iter().map(|s| s.machine.load1).sum::<f64>() / samples.len().max(1) as f64;
    println!("\n## Soak: {:.0} s\n", elapsed.as_secs_f64());
    println!(
        "`cargo bench --bench soak -- --duration {}`: {} control clients, {} Modbus clients \
         (reconnecting every {} rounds, {} ms between two rounds), a reload or an online change every {:.1} s, a look \
         every {:.1} s; the storm: {} lines a pass, one every {} ns.\n",
        o.duration.as_secs(),
        o.control_clients,
        o.modbus_clients,
        o.reconnect_every,
        o.pause.as_millis(),
        o.change_every.as_secs_f64(),
        o.sample.as_secs_f64(),
        project.storm_lines,
        o.edge_step_ns
    );
    println!("| figure | start | end |\n|---|---|---|");
    println!(
        "| scan time p50 / p99 / max (the first and the last engine) | {} / {} / {} ({} scans) \
         | {} / {} / {} ({} scans) |",
        us(first.p50_ns),
        us(first.p99_ns),
        us(first.max_ns),
        first.scans,
        us(end.p50_ns),
        us(end.p99_ns),
        us(end.max_ns),
        end.scans
    );
    let at_end = settled.unwrap_or_default();
    println!(
        "| resident memory (VmRSS) | {} before the clients | {} after them (peak VmHWM {}) |",
        mib(baseline.rss_kib),
        mib(at_end.rss_kib),
        mib(at_end.hwm_kib)
    );
    println!(
        "| file descriptors | {} before the clients | {} after them (max {} during) |",
        baseline.fds,
        at_end.fds,
        max(|s| s.process.fds)
    );
    println!(
        "| threads | {} before the clients | {} after them (max {} during) |",
        baseline.threads,
        at_end.threads,
        max(|s| s.process.threads)
    );
    println!();
    println!(
        "- resident memory: first half max {}, second half {} to {} (band {}, allowed {})",
        first_half_max.map_or("-".into(), mib),
        mib(rss_min),
        mib(rss_max),
        mib(rss_max - rss_min),
        mib(RSS_BAND_KIB)
    );
    println!(
        "- scans: {} counted in {} engines (a reload starts a new one, and the scans between \
         the last look at the old one and the swap are not counted); worst scan time of any \
         engine {}",
        tracker.scans,
        segments.len(),
        us(worst)
    );
    println!(
        "- scans lost: {} (a `get` whose D00000 differed from its scan count, a watchdog trip, \
         an ERROR or STOP seen); cycle task periods without their run: {} overruns of {} runs \
         ({} in the {:.0} s alone before the clients), {} deadlines noticed a full period late",
        control_tally.counter_mismatches.load(Ordering::Relaxed)
            + tracker.not_run.len() as u64
            + last.as_ref().map_or(0, |s| s.watchdog_trips),
        tracker.cycle_overruns,
        tracker.cycle_runs,
        alone_overruns,
        SETTLE.as_secs_f64(),
        tracker.missed_expirations
    );
    println!(
        "- control: {} answers checked, {} failed, {} busy (retried), {} connections",
        answers(&control_tally),
        control_tally.failures.load(Ordering::Relaxed),
        busy(&control_tally),
        conns(&control_tally)
    );
    println!(
        "- Modbus: {} answers checked, {} failed, {} exception 06 (retried), {} connections",
        answers(&modbus_tally),
        modbus_tally.failures.load(Ordering::Relaxed),
        busy(&modbus_tally),
        conns(&modbus_tally)
    );
    println!(
        "- changes: {} SIGHUP reloads, {} online changes, each seen in device memory within {:.1} ms at most",
        changes.reloads.load(Ordering::Relaxed),
        changes.online.load(Ordering::Relaxed),
        changes.slowest_us.load(Ordering::Relaxed) as f64 / 1000.0
    );
    println!(
        "- edges: {seen} reached the io tasks ({} runs, {} ignored: the task still held a \
         request), {:.0}/s; {lost_edges} lost to a full edge queue ({:.4} %), {} warnings of it \
         in the log",
        tracker.io_runs,
        tracker.io_ignored,
        seen as f64 / elapsed.as_secs_f64(),
        lost_edges as f64 * 100.0 / (seen + lost_edges).max(1) as f64,
        lost_edge_warnings
    );
    // Lost edges and lost cycle periods, look by look: do they come together?
    let stalled: Vec<&[Sample]> =
        samples.windows(2).filter(|w| w[1].cycle_overruns > w[0].cycle_overruns).collect();
    let lost_in = |w: &[Sample]| w[1].lost_edges - w[0].lost_edges;
    println!(
        "- lost edges in the {} look intervals in which the cycle tasks also lost periods: {} \
         of the {} lost while the clients ran; intervals that lost edges: {} of {}",
        stalled.len(),
        stalled.iter().map(|w| lost_in(w)).sum::<u64>(),
        samples.last().map_or(0, |s| s.lost_edges) - samples.first().map_or(0, |s| s.lost_edges),
        samples.windows(2).filter(|w| lost_in(w) > 0).count(),
        samples.len().saturating_sub(1)
    );
    let ticks_per_s =
        nix::unistd::sysconf(nix::unistd::SysconfVar::CLK_TCK).ok().flatten().unwrap_or(100) as f64;
    let shares: Vec<String> = THREADS
        .iter()
        .zip(threads_start.iter().zip(threads_end))
        .map(|(name, (a, b))| {
            format!(
                "{name} {:.0} %",
                (b.saturating_sub(*a)) as f64 * 100.0 / ticks_per_s / elapsed.as_secs_f64()
            )
        })
        .collect();
    println!("- CPU time of one CPU, while the clients ran: {}", shares.join(", "));
    println!(
        "- machine: {} CPUs' time {:.1} % stolen by the hypervisor, load average {:.1}",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        steal as f64 * 100.0 / total as f64,
        load_avg
    );
    println!(
        "\nseries (s, RSS MiB, fds, threads, lost edges, edges seen, cycle overruns, answers):"
    );
    for s in &samples {
        println!(
            "  {:6.1} {:6.2} {:4} {:3} {:9} {:11} {:6} {:9}",
            s.at.as_secs_f64(),
            s.process.rss_kib as f64 / 1024.0,
            s.process.fds,
            s.process.threads,
            s.lost_edges,
            s.edges_seen,
            s.cycle_overruns,
            s.answers
        );
    }
    let failures = failures.into_inner().unwrap();
    if failures.is_empty() {
        println!("\nsoak: passed");
    } else {
        println!("\nsoak: FAILED");
        for f in &failures {
            println!("- {f}");
        }
        std::process::exit(1);
    }
}
