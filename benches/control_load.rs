//! Scan time with and without 50 clients polling `status` as fast as they can, side by side in
//! one run: `cargo bench --bench control_load` (as root for SCHED_FIFO and mlockall, as the
//! service runs). Writes target/bench-results/control.md for BENCHMARKS.md.
//!
//! The daemon (the release `plcd` binary) runs a 1 ms fixed scan period with a 200-instruction
//! program that counts its scans in D00000 and a 1 ms cycle task. Each phase starts from RUN
//! (which resets the figures) and lasts `PHASE`; the figures are the daemon's own. "Lost scans"
//! compares the scans the program counted with the periods that passed.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};
use plcd::control::protocol::{Reply, Request};
use plcd::plcctl::client::Client;

const PHASE: Duration = Duration::from_secs(5);
const CLIENTS: usize = 50;

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
}

fn phase(socket: &Path, clients: usize) -> Figures {
    let mut c = client(socket);
    c.request(&Request::Stop).unwrap();
    c.request(&Request::Reset { cold: true }).unwrap();
    c.request(&Request::Run).unwrap();
    let started = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let answers = Arc::new(AtomicU64::new(0));
    let pollers: Vec<_> = (0..clients)
        .map(|_| {
            let (socket, stop, answers) =
                (socket.to_path_buf(), Arc::clone(&stop), Arc::clone(&answers));
            std::thread::spawn(move || {
                let stream = UnixStream::connect(&socket).unwrap();
                let mut reader = BufReader::new(stream.try_clone().unwrap());
                let mut writer = stream;
                let mut line = String::new();
                while !stop.load(Ordering::Relaxed) {
                    writer.write_all(b"{\"v\":1,\"cmd\":\"status\"}\n").unwrap();
                    line.clear();
                    reader.read_line(&mut line).unwrap();
                    answers.fetch_add(1, Ordering::Relaxed);
                }
            })
        })
        .collect();
    std::thread::sleep(PHASE);
    stop.store(true, Ordering::Relaxed);
    for p in pollers {
        p.join().unwrap();
    }
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
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let dir = std::env::temp_dir().join(format!("plcd-bench-control-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let config = "[plc]\nscan_period_ms = 1\n\
        [[program]]\nfile = \"main.il\"\n\
        [[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
        [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n\
        [control]\nsocket = \"plcd.sock\"\nmax_clients = 64\n";
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
        .stderr(Stdio::null())
        .spawn()
        .expect("plcd starts");
    let socket: PathBuf = dir.join("plcd.sock");
    let quiet = phase(&socket, 0);
    let loaded = phase(&socket, CLIENTS);
    let _ = Command::new("kill").arg(daemon.id().to_string()).status();
    let _ = daemon.wait();
    let _ = std::fs::remove_dir_all(&dir);

    let us = |ns: u64| format!("{:.1} µs", ns as f64 / 1000.0);
    let mut f = Fragment::new("cargo bench --bench control_load");
    f.line(format!(
        "The daemon runs a 1 ms fixed scan period with a 201-instruction scan program and a 1 ms \
         cycle task; each phase starts from RUN (which resets the figures) and lasts {} s; in the \
         second, {CLIENTS} threads send `status` back to back on their own connections. Figures \
         are the daemon's own histograms.\n",
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
        &["figure", "no clients", &format!("{CLIENTS} clients polling `status`"), "ratio"],
        &rows,
    );
    for (name, fig) in [("no clients", &quiet), ("clients", &loaded)] {
        f.line(format!(
            "- {name}: {} scans in {} ms; the program counted {}; {} `status` answers ({:.0}/s)",
            fig.scans,
            fig.periods,
            fig.counted,
            fig.answers,
            fig.answers as f64 / PHASE.as_secs_f64()
        ));
        assert_eq!(fig.counted as u64, fig.scans, "every scan ran to its END");
    }
    write_fragment("control", &f).expect("fragment written");
}
