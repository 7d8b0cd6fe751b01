//! The daemon under a load of clients, for `control_load` and `modbus_load`: a project with a
//! 1 ms fixed scan period, a 201-instruction scan program that counts its scans in D00000 and a
//! 1 ms cycle task; phases that start from RUN (which resets the figures), run `PHASE` with a
//! number of client threads, and read the daemon's own figures through the control socket; the
//! table both benches print.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use plcctl::client::Client;
use plcd::bench::Fragment;
use plcd_ipc::{Reply, Request};

pub const PHASE: Duration = Duration::from_secs(5);

/// The daemon's figures over one phase.
pub struct Figures<T> {
    pub scans: u64,
    /// Scans the program counted (D00000).
    pub counted: i64,
    /// 1 ms periods that passed.
    pub periods: u64,
    pub p50: u64,
    pub p99: u64,
    pub max: u64,
    pub tick_p99: u64,
    /// What each client thread returned.
    pub clients: Vec<T>,
}

/// A project in a private directory, removed on drop, and the daemon running it.
pub struct Daemon {
    pub dir: PathBuf,
    pub child: Child,
}

impl Daemon {
    /// Writes the project with `extra` appended to its config and starts the release `plcd`
    /// on it; its log goes to a pipe when `log` (the caller reads it), else nowhere.
    pub fn start(name: &str, extra: &str, log: bool) -> Daemon {
        let dir = std::env::temp_dir().join(format!("plcd-bench-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let config = format!(
            "[plc]\nscan_period_ms = 1\n\
             [[program]]\nfile = \"main.il\"\n\
             [[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
             [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\n\
             interval_ms = 1\n{extra}"
        );
        let main = format!(
            "INC D00000\n{}END\n",
            "LOAD M0000\nAND M0001\nOUT M0002\nADD D00010 1 D00011\n".repeat(50)
        );
        for (file, text) in
            [("plcd.toml", config.as_str()), ("main.il", &main), ("tick.il", "INC D00001\nEND\n")]
        {
            std::fs::write(dir.join(file), text).unwrap();
        }
        let child = Command::new(env!("CARGO_BIN_EXE_plcd"))
            .args(["run", "--config"])
            .arg(dir.join("plcd.toml"))
            .stderr(if log { Stdio::piped() } else { Stdio::null() })
            .spawn()
            .expect("plcd starts");
        Daemon { dir, child }
    }

    /// The control socket, as `[control] socket = "plcd.sock"` names it.
    pub fn socket(&self) -> PathBuf {
        self.dir.join("plcd.sock")
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = Command::new("kill").arg(self.child.id().to_string()).status();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

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

/// One phase: RUN from a cold reset, `clients` threads running `poll(k, stop)` until `stop`,
/// then STOP and the daemon's figures.
pub fn phase<T: Send + 'static>(
    socket: &Path,
    clients: usize,
    poll: impl Fn(usize, Arc<AtomicBool>) -> T + Send + Sync + 'static,
) -> Figures<T> {
    let mut c = client(socket);
    c.request(&Request::Stop).unwrap();
    c.request(&Request::Reset { cold: true }).unwrap();
    c.request(&Request::Run).unwrap();
    let started = Instant::now();
    let stop = Arc::new(AtomicBool::new(false));
    let poll = Arc::new(poll);
    let pollers: Vec<_> = (0..clients)
        .map(|k| {
            let (stop, poll) = (Arc::clone(&stop), Arc::clone(&poll));
            std::thread::spawn(move || poll(k, stop))
        })
        .collect();
    std::thread::sleep(PHASE);
    stop.store(true, Ordering::Relaxed);
    let clients = pollers.into_iter().map(|p| p.join().unwrap()).collect();
    c.request(&Request::Stop).unwrap();
    let elapsed = started.elapsed();
    let s = match c.request(&Request::Status).expect("status") {
        Reply::Status(s) => s,
        other => panic!("{other:?}"),
    };
    let counted = match c.request(&Request::Get { devices: vec!["D00000".into()] }).expect("get") {
        Reply::Values { values, .. } => values[0].value.as_i64().expect("a device is an integer"),
        other => panic!("{other:?}"),
    };
    let tick = s.tasks.iter().find(|t| t.name == "tick").expect("tick task");
    Figures {
        scans: s.scan.count,
        counted,
        periods: elapsed.as_millis() as u64,
        p50: s.scan.p50_ns,
        p99: s.scan.p99_ns,
        max: s.scan.max_ns,
        tick_p99: tick.latency.p99_ns,
        clients,
    }
}

pub fn us(ns: u64) -> String {
    format!("{:.1} µs", ns as f64 / 1000.0)
}

/// The scan figures of both phases side by side, and a line per phase with its scans and
/// `answers` (what the clients got, named `what`). Asserts that every scan ran to its END.
pub fn table<T>(
    f: &mut Fragment,
    loaded_name: &str,
    what: &str,
    [quiet, loaded]: [(&Figures<T>, u64); 2],
) {
    let rows: Vec<Vec<String>> = [
        ("scan time p50", quiet.0.p50, loaded.0.p50),
        ("scan time p99", quiet.0.p99, loaded.0.p99),
        ("scan time max", quiet.0.max, loaded.0.max),
        ("cycle task start latency p99", quiet.0.tick_p99, loaded.0.tick_p99),
    ]
    .into_iter()
    .map(|(name, a, b)| {
        vec![name.into(), us(a), us(b), format!("{:.2}", b as f64 / a.max(1) as f64)]
    })
    .collect();
    f.table(&["figure", "no clients", loaded_name, "ratio"], &rows);
    for (name, (fig, answers)) in [("no clients", quiet), ("clients", loaded)] {
        f.line(format!(
            "- {name}: {} scans in {} ms; the program counted {}; {answers} {what} ({:.0}/s)",
            fig.scans,
            fig.periods,
            fig.counted,
            answers as f64 / PHASE.as_secs_f64()
        ));
        assert_eq!(fig.counted as u64, fig.scans, "every scan ran to its END");
    }
}
