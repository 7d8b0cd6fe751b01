//! What the soak watches: the daemon's process from /proc (resident memory, file descriptors,
//! threads), the machine (steal time, load), and the daemon's own figures from `status`,
//! summed across the reloads that start them again from zero.

use std::time::Duration;

use plcd_ipc::Status;

/// The process, as /proc shows it.
#[derive(Debug, Clone, Copy, Default)]
pub struct Process {
    pub rss_kib: u64,
    pub hwm_kib: u64,
    pub fds: u64,
    pub threads: u64,
}

impl Process {
    /// None once the process is gone.
    pub fn read(pid: u32) -> Option<Process> {
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
        let field = |name: &str| {
            status
                .lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|rest| rest.split_whitespace().next())
                .and_then(|v| v.parse().ok())
                .unwrap_or(0)
        };
        let count =
            |dir: &str| std::fs::read_dir(format!("/proc/{pid}/{dir}")).ok().map(Iterator::count);
        Some(Process {
            rss_kib: field("VmRSS:"),
            hwm_kib: field("VmHWM:"),
            fds: count("fd")? as u64,
            threads: count("task")? as u64,
        })
    }
}

/// CPU time of the daemon's thread named `name` (user and system), in clock ticks.
pub fn thread_ticks(pid: u32, name: &str) -> u64 {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else { return 0 };
    for task in tasks.filter_map(Result::ok) {
        let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
        if comm.trim() != name {
            continue;
        }
        let stat = std::fs::read_to_string(task.path().join("stat")).unwrap_or_default();
        // After the command name in parentheses: state is field 3, utime 14 and stime 15.
        let fields: Vec<&str> =
            stat.rsplit_once(')').map_or("", |(_, rest)| rest).split_whitespace().collect();
        let tick = |i: usize| fields.get(i).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
        return tick(11) + tick(12);
    }
    0
}

/// The machine's CPU time stolen by the hypervisor and spent in all, in clock ticks, and the
/// 1-minute load average.
#[derive(Debug, Clone, Copy, Default)]
pub struct Machine {
    pub steal: u64,
    pub total: u64,
    pub load1: f64,
}

impl Machine {
    pub fn read() -> Machine {
        let stat = std::fs::read_to_string("/proc/stat").unwrap_or_default();
        let cpu: Vec<u64> = stat
            .lines()
            .next()
            .unwrap_or("")
            .split_whitespace()
            .skip(1)
            .filter_map(|v| v.parse().ok())
            .collect();
        let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
        Machine {
            steal: cpu.get(7).copied().unwrap_or(0),
            total: cpu.iter().take(8).sum(),
            load1: load.split_whitespace().next().and_then(|v| v.parse().ok()).unwrap_or(0.0),
        }
    }
}

/// The scan figures of one engine's life (from a RUN start: the daemon's start, a reload).
#[derive(Debug, Clone, Copy, Default)]
pub struct Segment {
    pub scans: u64,
    pub p50_ns: u64,
    pub p99_ns: u64,
    pub max_ns: u64,
}

/// The daemon's per-engine figures summed over the engines a run saw: a reload's new engine
/// starts its task figures and missed expirations from zero, so each figure adds what it grew
/// by since the last look, or all of it when it went down (a new engine).
#[derive(Debug, Default)]
pub struct Tracker {
    last: Option<Status>,
    /// io tasks: runs, and requests ignored (pending or running: a task holds one request).
    pub io_runs: u64,
    pub io_ignored: u64,
    /// Cycle tasks: runs, and overruns (a deadline that found the task still running or
    /// waiting: a period without its run).
    pub cycle_runs: u64,
    pub cycle_overruns: u64,
    /// Cycle deadlines noticed a full interval or more late.
    pub missed_expirations: u64,
    /// Scans started since the first look.
    pub scans: u64,
    /// Each engine's scan figures, at its last look.
    pub segments: Vec<Segment>,
    /// Modes other than RUN seen.
    pub not_run: Vec<String>,
}

fn grown(now: u64, before: u64) -> u64 {
    if now >= before {
        now - before
    } else {
        now
    }
}

impl Tracker {
    pub fn update(&mut self, s: Status) {
        if s.mode != plcd_ipc::ModeName::Run {
            self.not_run.push(format!("{} at {} ms of uptime", s.mode.as_str(), s.uptime_ms));
        }
        let segment = Segment {
            scans: s.scan.count,
            p50_ns: s.scan.p50_ns,
            p99_ns: s.scan.p99_ns,
            max_ns: s.scan.max_ns,
        };
        let new_engine = self.last.as_ref().is_none_or(|l| s.scan.count < l.scan.count);
        if new_engine || self.segments.is_empty() {
            self.segments.push(segment);
        } else {
            *self.segments.last_mut().unwrap() = segment;
        }
        let before = self.last.take();
        let task =
            |name: &str| before.as_ref().and_then(|b| b.tasks.iter().find(|t| t.name == name));
        for t in &s.tasks {
            let (runs, ignored, overruns) =
                task(&t.name).map_or((0, 0, 0), |b| (b.runs, b.ignored, b.overruns));
            match t.kind.as_str() {
                "io" => {
                    self.io_runs += grown(t.runs, runs);
                    self.io_ignored += grown(t.ignored, ignored);
                }
                "cycle" => {
                    self.cycle_runs += grown(t.runs, runs);
                    self.cycle_overruns += grown(t.overruns, overruns);
                }
                _ => {}
            }
        }
        let before_missed = before.as_ref().map_or(0, |b| b.missed_timer_expirations);
        self.missed_expirations += grown(s.missed_timer_expirations, before_missed);
        if before.is_some() {
            self.scans += grown(s.scan.count, before.as_ref().map_or(0, |b| b.scan.count));
        }
        self.last = Some(s);
    }

    pub fn last(&self) -> Option<&Status> {
        self.last.as_ref()
    }
}

/// One look at everything, `at` into the run.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub at: Duration,
    pub process: Process,
    pub machine: Machine,
    pub lost_edges: u64,
    pub edges_seen: u64,
    pub cycle_overruns: u64,
    pub answers: u64,
}
