//! Latency of the real-time driver, measured on the driver itself: `plcd bench latency` (a
//! cycle task's start latency, to compare with `cyclictest`) and `plcd bench edge` (an input
//! edge's way to its io task while a scan program of a given length runs).
//!
//! Each run writes a small generated project into a private temporary directory, starts a
//! [`Driver`] on it exactly as `plcd run` does (same threads, `[rt]` priorities, locked
//! memory), lets it run, stops it and reads the engine's own histograms. The figures are the
//! engine's: a task's start latency is the time from the moment its start condition occurred
//! (the cycle deadline; the edge's stamp) to the dispatch of its first instruction.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::diag::Diagnostics;
use crate::drivers::real_time::driver::{Driver, DriverError};
use crate::drivers::real_time::{Command, Source};
use crate::engine::event::Mode;
use crate::files;
use crate::stats::{Histogram, Summary};

/// Why a bench could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("{path}: {source}", path = .path.display())]
    Write { path: PathBuf, source: std::io::Error },
    #[error("the generated project is invalid: {}", first_lines(.0))]
    Project(Diagnostics),
    #[error(transparent)]
    Driver(#[from] DriverError),
    #[error("{0}")]
    Usage(String),
    #[error("the scan thread died; no figures")]
    ScanThreadDied,
}

/// The first diagnostics: a generated program of 10^6 lines could report as many.
fn first_lines(diagnostics: &Diagnostics) -> String {
    let text = diagnostics.to_string();
    let mut lines: Vec<&str> = text.lines().take(5).collect();
    if diagnostics.len() > lines.len() {
        lines.push("…");
    }
    lines.join("\n")
}

/// The scheduling the bench threads got.
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct Scheduling {
    /// `fifo` if every real-time setting took, else `other` (not root, no CAP_SYS_NICE).
    pub policy: &'static str,
    pub scan_priority: u8,
    pub memory_locked: bool,
    /// A CPU wake-up latency of 0 is requested from PM QoS (`/dev/cpu_dma_latency`), as
    /// cyclictest requests by default.
    pub cpu_latency_0: bool,
    /// What `[rt]` asked for and did not get.
    pub problems: Vec<String>,
}

/// A latency distribution from the engine's histogram, in ns.
#[derive(Debug, Clone, Serialize)]
pub struct Distribution {
    pub samples: u64,
    pub min_ns: u64,
    pub avg_ns: u64,
    pub p50_ns: u64,
    pub p99_ns: u64,
    pub p999_ns: u64,
    pub max_ns: u64,
    /// The histogram's buckets in use: `[largest value of the bucket in ns, count]`, so that
    /// runs can be merged and quantiles computed again (`benches/latency-vs-cyclictest`).
    pub histogram: Vec<[u64; 2]>,
}

impl Distribution {
    fn of(histogram: &Histogram) -> Distribution {
        let Summary { count, min, avg, p50, p99, p999, max } = histogram.summary();
        Distribution {
            samples: count,
            min_ns: min,
            avg_ns: avg,
            p50_ns: p50,
            p99_ns: p99,
            p999_ns: p999,
            max_ns: max,
            histogram: histogram.buckets().map(|(top, n)| [top, n]).collect(),
        }
    }

    /// `p50 12.3 µs, p99 …` for the text report.
    pub fn micros(&self) -> String {
        let us = |ns: u64| ns as f64 / 1000.0;
        format!(
            "{} samples: min {:.1} avg {:.1} p50 {:.1} p99 {:.1} p99.9 {:.1} max {:.1} µs",
            self.samples,
            us(self.min_ns),
            us(self.avg_ns),
            us(self.p50_ns),
            us(self.p99_ns),
            us(self.p999_ns),
            us(self.max_ns)
        )
    }
}

/// What a latency bench measured.
#[derive(Debug, Clone, Serialize)]
pub struct LatencyReport {
    /// `cycle` or `edge`.
    pub bench: &'static str,
    pub scheduling: Scheduling,
    /// Wall time the driver ran in RUN, ns.
    pub run_ns: u64,
    /// The task's start latency.
    pub start_latency: Distribution,
    /// Its first part: start condition → the engine told of it (the scan thread's wake-up
    /// after a deadline; an edge through the event path). `start_latency` minus this is plcd's
    /// own dispatch.
    pub notice_latency: Distribution,
    /// Scan time of the scan program over the run.
    pub scan_time: Distribution,
    pub scans: u64,
    /// Requests the engine ignored because the task was still running or waiting.
    pub overruns: u64,
    /// Instructions of the scan program, END included.
    pub scan_steps: u64,
    pub interval_ns: u64,
}

/// `plcd bench latency`: one cycle task.
#[derive(Debug, Clone)]
pub struct CycleBench {
    /// Cycle task interval (whole ms: `[[task]] interval_ms`).
    pub interval_ms: u32,
    /// Deadlines to measure.
    pub cycles: u64,
    /// SCHED_FIFO priority of the scan thread (the one that runs the task); the event and
    /// watchdog threads get the next two.
    pub priority: u8,
    /// `[plc] scan_period_ms` of the scan program: with a period the scan thread sleeps
    /// between scans, so that a deadline wakes it as cyclictest's timer wakes its thread.
    pub scan_period_ms: u32,
    /// `[rt] scan_cpus`.
    pub cpus: Vec<u16>,
}

/// `plcd bench edge`: edges of P0000 to an io task while a scan program of `steps` runs
/// without a period (one scan after the other).
#[derive(Debug, Clone)]
pub struct EdgeBench {
    /// Instructions of the scan program (≥ 4; rounded to whole rungs of three, plus END).
    pub steps: u64,
    /// Rising edges to measure.
    pub edges: u64,
    /// Time between two changes of P0000 (a rising edge every two).
    pub interval_us: u32,
    pub priority: u8,
    pub cpus: Vec<u16>,
}

impl CycleBench {
    pub fn run(&self) -> Result<LatencyReport, BenchError> {
        if self.interval_ms == 0 || self.cycles == 0 {
            return Err(BenchError::Usage("the interval and cycles must be above 0".into()));
        }
        let dir = BenchDir::new("latency")?;
        let config = format!(
            "[plc]\nwatchdog_ms = 1000\nscan_period_ms = {period}\n{rt}\n\
             [[program]]\nname = \"main\"\nfile = \"main.il\"\ntask = \"scan\"\n\n\
             [[program]]\nname = \"tick\"\nfile = \"tick.il\"\ntask = \"tick\"\n\n\
             [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 2\n\
             interval_ms = {interval}\n\n[io]\nbackend = \"sim\"\n\n[control]\nenabled = false\n",
            period = self.scan_period_ms,
            rt = rt_section(self.priority, &self.cpus)?,
            interval = self.interval_ms,
        );
        dir.write("main.il", "LOAD M0000\nOUT M0001\nEND\n")?;
        dir.write("tick.il", "INC D00000\nEND\n")?;
        let path = dir.write("plcd.toml", &config)?;
        let interval_ns = u64::from(self.interval_ms) * 1_000_000;
        // The first deadline is one interval after RUN; half an interval more lets the last one
        // be served before the stop.
        let run_for = self.cycles * interval_ns + interval_ns / 2;
        let run_for = Duration::from_nanos(run_for);
        measure(&path, "cycle", "tick", self.cycles, run_for, self.priority, interval_ns)
    }
}

impl EdgeBench {
    pub fn run(&self) -> Result<LatencyReport, BenchError> {
        if self.edges == 0 || self.interval_us < 10 {
            return Err(BenchError::Usage(
                "edges must be above 0 and the interval at least 10 µs".into(),
            ));
        }
        let dir = BenchDir::new("edge")?;
        let config = format!(
            "[plc]\nwatchdog_ms = 1000\n{rt}\n\
             [[program]]\nname = \"main\"\nfile = \"main.il\"\ntask = \"scan\"\n\n\
             [[program]]\nname = \"count\"\nfile = \"count.il\"\ntask = \"count\"\n\n\
             [[task]]\nname = \"count\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
             contact = \"P0000\"\nedge = \"rising\"\n\n\
             [io]\nbackend = \"sim\"\nstimulus = \"edges.csv\"\nstimulus_loop = true\n\n\
             [control]\nenabled = false\n",
            rt = rt_section(self.priority, &self.cpus)?,
        );
        let (program, steps) = scan_program(self.steps);
        dir.write("main.il", &program)?;
        dir.write("count.il", "INC D00000\nEND\n")?;
        let interval = u64::from(self.interval_us);
        dir.write(
            "edges.csv",
            &format!("{}us, P0000, 1\n{}us, P0000, 0\n", interval, 2 * interval),
        )?;
        let path = dir.write("plcd.toml", &config)?;
        let interval_ns = 2 * interval * 1000;
        let run_for = self.edges * interval_ns + interval_ns / 2;
        let mut report = measure(
            &path,
            "edge",
            "count",
            self.edges,
            Duration::from_nanos(run_for),
            self.priority,
            interval_ns,
        )?;
        report.scan_steps = steps;
        Ok(report)
    }
}

/// A scan program of about `steps` instructions: rungs `LOAD a / AND b / OUT c` over M bits
/// (so no rung is the same as the one before), then END. Returns it and its exact length.
pub fn scan_program(steps: u64) -> (String, u64) {
    let rungs = steps.saturating_sub(1).max(3) / 3;
    let mut text = String::with_capacity(rungs as usize * 36);
    for i in 0..rungs {
        // 256 words of M, M0000..M255F; three distinct bits a rung.
        let bit = |k: u64| {
            let n = (i * 3 + k) % (256 * 16);
            format!("M{:03}{:X}", n / 16, n % 16)
        };
        let _ = writeln!(text, "LOAD {}\nAND {}\nOUT {}", bit(0), bit(1), bit(2));
    }
    text.push_str("END\n");
    (text, rungs * 3 + 1)
}

fn rt_section(priority: u8, cpus: &[u16]) -> Result<String, BenchError> {
    if !(1..=97).contains(&priority) {
        return Err(BenchError::Usage(format!("priority {priority}: expected 1..=97")));
    }
    let cpus = cpus.iter().map(u16::to_string).collect::<Vec<_>>().join(", ");
    Ok(format!(
        "\n[rt]\npolicy = \"fifo\"\nscan_priority = {}\nevent_priority = {}\n\
         watchdog_priority = {}\nscan_cpus = [{cpus}]\nlock_memory = true\n\
         cpu_dma_latency_us = 0\nrequire = false\n",
        priority,
        priority + 1,
        priority + 2
    ))
}

/// Starts of the bench task (the engine's third: after the scan and init programs) and the
/// requests it ignored, as of the last snapshot.
fn requests(driver: &Driver) -> u64 {
    let snapshot = driver.snapshot.lock().unwrap_or_else(|e| e.into_inner());
    snapshot.tasks.get(2).map_or(0, |t| t.runs + t.overruns)
}

fn measure(
    config: &Path,
    bench: &'static str,
    task: &str,
    wanted: u64,
    run_for: Duration,
    priority: u8,
    interval_ns: u64,
) -> Result<LatencyReport, BenchError> {
    let project = files::project(config).map_err(BenchError::Project)?;
    let scan_steps =
        project.programs.iter().find(|p| p.name == "main").map_or(0, |p| p.code.len()) as u64;
    let mut driver = Driver::start(&project, Vec::new())?;
    let problems = driver.problems.clone();
    let started = Instant::now();
    driver.command(Command::Mode(Mode::Run, Source::Startup));
    // Until the task has been asked to start `wanted` times (served or overrun), as the
    // snapshot the scan thread publishes at a scan boundary says; checked from the expected
    // end on, every interval. A machine too loaded to get there in three times the expected
    // time ends the run with what it has.
    let poll = Duration::from_nanos(interval_ns)
        .clamp(Duration::from_millis(1), Duration::from_millis(20));
    let give_up = started + run_for * 3 + Duration::from_secs(2);
    let mut next_check = started + run_for;
    loop {
        while driver.reports.pop().is_ok() {}
        let now = Instant::now();
        if now >= next_check {
            if requests(&driver) >= wanted || now >= give_up {
                break;
            }
            driver.shared.snapshot_wanted.store(true, std::sync::atomic::Ordering::Release);
            next_check = now + poll;
        }
        std::thread::sleep((next_check - now).min(Duration::from_millis(50)));
    }
    let run_ns = started.elapsed().as_nanos() as u64;
    let granted = driver.granted;
    let engine = driver.stop().ok_or(BenchError::ScanThreadDied)?;
    let stats = engine.task_stats(task).expect("the bench task exists");
    let scan = engine.scan_stats();
    Ok(LatencyReport {
        bench,
        scheduling: Scheduling {
            policy: if granted.fifo { "fifo" } else { "other" },
            scan_priority: priority,
            memory_locked: granted.memory_locked,
            cpu_latency_0: granted.cpu_latency_us == Some(0),
            problems,
        },
        run_ns,
        start_latency: Distribution::of(&stats.start_latency),
        notice_latency: Distribution::of(&stats.notice_latency),
        scan_time: Distribution::of(&scan.time),
        scans: scan.count,
        overruns: stats.overruns,
        scan_steps,
        interval_ns,
    })
}

/// A private directory for a generated project, removed on drop.
struct BenchDir {
    path: PathBuf,
}

impl BenchDir {
    fn new(what: &str) -> Result<BenchDir, BenchError> {
        use std::sync::atomic::{AtomicU32, Ordering};
        static SERIAL: AtomicU32 = AtomicU32::new(0);
        let n = SERIAL.fetch_add(1, Ordering::Relaxed);
        let path =
            std::env::temp_dir().join(format!("plcd-bench-{what}-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&path)
            .map_err(|source| BenchError::Write { path: path.clone(), source })?;
        Ok(BenchDir { path })
    }

    fn write(&self, name: &str, text: &str) -> Result<PathBuf, BenchError> {
        let path = self.path.join(name);
        std::fs::write(&path, text)
            .map_err(|source| BenchError::Write { path: path.clone(), source })?;
        Ok(path)
    }
}

impl Drop for BenchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_programs_have_the_length_asked_for() {
        for steps in [4, 1000, 1_000_000] {
            let (text, len) = scan_program(steps);
            assert_eq!(text.lines().count() as u64, len);
            assert!(len.abs_diff(steps) <= 3, "{steps} → {len}");
        }
    }
}
