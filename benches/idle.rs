//! What plcd costs a machine that it runs on: the CPU share and the resident memory of the
//! daemon running `benches/projects/idle` (a 1,000-step scan program every 10 ms, sim
//! backend, control socket on). `cargo bench --bench idle`; as root, the daemon runs as the
//! service does (SCHED_FIFO threads, memory locked: every mapped page is resident then).
//!
//! CPU time is the sum over the daemon's threads of `/proc/PID/task/TID/schedstat` (ns on a
//! CPU, exact) across a window, after a warm-up; memory is `VmRSS`/`VmHWM` of
//! `/proc/PID/status` at the end of the window.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use plcd::bench::{write_fragment, Fragment};

const WARM_UP: Duration = Duration::from_secs(3);
const WINDOW: Duration = Duration::from_secs(30);

/// ns the process's threads spent on a CPU so far.
fn cpu_ns(pid: u32) -> u64 {
    let mut total = 0;
    for task in std::fs::read_dir(format!("/proc/{pid}/task")).expect("the daemon runs") {
        let path = task.unwrap().path().join("schedstat");
        if let Ok(text) = std::fs::read_to_string(path) {
            total +=
                text.split_whitespace().next().and_then(|n| n.parse::<u64>().ok()).unwrap_or(0);
        }
    }
    total
}

/// A `kB` field of /proc/PID/status.
fn status_kib(pid: u32, field: &str) -> u64 {
    let text = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    text.lines()
        .find_map(|l| l.strip_prefix(field))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let project = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/projects/idle/plcd.toml");
    let daemon = Command::new(env!("CARGO_BIN_EXE_plcd"))
        .args(["run", "--config"])
        .arg(&project)
        .stderr(Stdio::piped())
        .spawn()
        .expect("plcd starts");
    let pid = daemon.id();
    std::thread::sleep(WARM_UP);
    let (cpu0, t0) = (cpu_ns(pid), Instant::now());
    std::thread::sleep(WINDOW);
    let (cpu1, elapsed) = (cpu_ns(pid), t0.elapsed());
    let rss = status_kib(pid, "VmRSS:");
    let hwm = status_kib(pid, "VmHWM:");
    let locked = status_kib(pid, "VmLck:") > 0;
    let threads = std::fs::read_dir(format!("/proc/{pid}/task")).unwrap().count();
    let _ = Command::new("kill").arg(pid.to_string()).status();
    let output = daemon.wait_with_output().expect("plcd stops");
    let log = String::from_utf8_lossy(&output.stderr);
    let scans = log
        .lines()
        .find_map(|l| l.split("statistics: ").nth(1)?.split(" scans").next()?.parse::<u64>().ok())
        .unwrap_or(0);
    assert!(output.status.success(), "plcd ended badly:\n{log}");

    let share = (cpu1 - cpu0) as f64 / elapsed.as_nanos() as f64 * 100.0;
    let per_scan_us = if scans > 0 {
        (cpu1 - cpu0) as f64 / 1000.0 / (elapsed.as_secs_f64() * 100.0)
    } else {
        0.0
    };
    let mib = |kib: u64| format!("{:.1} MiB", kib as f64 / 1024.0);
    let verdict = |ok: bool| if ok { "met" } else { "**not met**" }.to_string();
    let mut f = Fragment::new("cargo bench --bench idle");
    f.line(format!(
        "`plcd run` on `benches/projects/idle` (a 1,000-step scan program every 10 ms, sim backend, \
         control socket on), {} threads, memory {}; a {} s window after {} s of warm-up.\n",
        threads,
        if locked { "locked (as root: every mapped page resident)" } else { "not locked" },
        WINDOW.as_secs(),
        WARM_UP.as_secs()
    ));
    f.table(
        &["figure", "plcd", "target", ""],
        &[
            vec![
                "CPU share of one core".into(),
                format!("{share:.2} %"),
                "< 2 %".into(),
                verdict(share < 2.0),
            ],
            vec![
                "CPU time per 10 ms period (scan, refresh, wake-ups)".into(),
                format!("{per_scan_us:.1} µs"),
                "".into(),
                "".into(),
            ],
            vec![
                "resident memory (VmRSS)".into(),
                mib(rss),
                "< 10 MiB".into(),
                verdict(rss < 10 * 1024),
            ],
            vec!["peak resident memory (VmHWM)".into(), mib(hwm), "".into(), "".into()],
        ],
    );
    write_fragment("idle", &f).expect("fragment written");
}
