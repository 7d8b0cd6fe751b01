//! `plcd bench latency|edge`: measures the real-time driver on this machine (see
//! [`crate::bench::realtime`]). Prints a summary, or the whole report as JSON with `--json`.

use std::io::Write;
use std::process::ExitCode;

use crate::bench::realtime::{BenchError, CycleBench, EdgeBench, LatencyReport};
use crate::duration;

/// The command's arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub bench: Bench,
}

#[derive(Debug, Clone, clap::Subcommand)]
pub enum Bench {
    /// Start latency of a cycle task: deadline → first instruction, as cyclictest measures a
    /// timer's wake-up (benches/latency-vs-cyclictest runs both side by side).
    Latency {
        /// The cycle task's interval, whole milliseconds (e.g. `1ms`).
        #[arg(long, default_value = "1ms", value_parser = parse_ms)]
        interval: u32,
        /// Deadlines to measure.
        #[arg(long, default_value_t = 10_000)]
        cycles: u64,
        /// SCHED_FIFO priority of the scan thread; the event and watchdog threads get the next
        /// two (cyclictest's `-p`).
        #[arg(long, default_value_t = 80)]
        priority: u8,
        /// The scan program's fixed period (0: scan after scan, the scan thread never sleeps).
        #[arg(long, default_value_t = 10)]
        scan_period_ms: u32,
        /// CPUs the scan thread may run on, comma separated (default: any).
        #[arg(long, value_delimiter = ',')]
        cpus: Vec<u16>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Input edge → io task start, through the sim backend's full event path, while a scan
    /// program of `--steps` instructions runs scan after scan.
    Edge {
        /// Instructions of the scan program.
        #[arg(long, default_value_t = 1000)]
        steps: u64,
        /// Rising edges of P0000 to measure.
        #[arg(long, default_value_t = 10_000)]
        edges: u64,
        /// Time between two changes of P0000 (a rising edge every two), e.g. `500us`.
        #[arg(long, default_value = "500us", value_parser = parse_us)]
        interval: u32,
        #[arg(long, default_value_t = 80)]
        priority: u8,
        #[arg(long, value_delimiter = ',')]
        cpus: Vec<u16>,
        #[arg(long)]
        json: bool,
    },
    /// Print the one-line description of this machine that BENCHMARKS.md quotes.
    Machine,
}

/// Exit 0 with a report, 1 when the bench could not run, 2 for bad usage.
pub fn run(args: &BenchArgs, out: &mut impl Write, err: &mut impl Write) -> ExitCode {
    let (result, json) = match &args.bench {
        Bench::Latency { interval, cycles, priority, scan_period_ms, cpus, json } => (
            CycleBench {
                interval_ms: *interval,
                cycles: *cycles,
                priority: *priority,
                scan_period_ms: *scan_period_ms,
                cpus: cpus.clone(),
            }
            .run(),
            *json,
        ),
        Bench::Machine => {
            let _ = writeln!(out, "{}", crate::bench::machine());
            return ExitCode::SUCCESS;
        }
        Bench::Edge { steps, edges, interval, priority, cpus, json } => (
            EdgeBench {
                steps: *steps,
                edges: *edges,
                interval_us: *interval,
                priority: *priority,
                cpus: cpus.clone(),
            }
            .run(),
            *json,
        ),
    };
    match result {
        Ok(report) => {
            let written = if json {
                serde_json::to_writer(&mut *out, &report)
                    .map_err(std::io::Error::from)
                    .and_then(|()| writeln!(out))
            } else {
                write!(out, "{}", text(&report))
            };
            if written.is_err() {
                return ExitCode::from(1);
            }
            ExitCode::SUCCESS
        }
        Err(BenchError::Usage(message)) => {
            let _ = writeln!(err, "plcd bench: {message}");
            ExitCode::from(2)
        }
        Err(e) => {
            let _ = writeln!(err, "plcd bench: {e}");
            ExitCode::from(1)
        }
    }
}

fn text(report: &LatencyReport) -> String {
    let s = &report.scheduling;
    let mut text = String::new();
    let what = match report.bench {
        "cycle" => "cycle task start latency (deadline → first instruction)",
        _ => "io task start latency (edge stamp → first instruction)",
    };
    text.push_str(&format!("{what}\n  {}\n", report.start_latency.micros()));
    let notice = match report.bench {
        "cycle" => "of which the scan thread's wake-up (deadline → engine told)",
        _ => "of which the event path (edge stamp → engine told)",
    };
    text.push_str(&format!("{notice}\n  {}\n", report.notice_latency.micros()));
    text.push_str(&format!(
        "scan time ({} steps, {} scans)\n  {}\n",
        report.scan_steps,
        report.scans,
        report.scan_time.micros()
    ));
    text.push_str(&format!(
        "{} overruns; scheduling {} priority {}, memory {}, CPU latency request {}\n",
        report.overruns,
        s.policy,
        s.scan_priority,
        if s.memory_locked { "locked" } else { "not locked" },
        if s.cpu_latency_0 { "0 µs" } else { "none" }
    ));
    for problem in &s.problems {
        text.push_str(&format!("warning: {problem}\n"));
    }
    text
}

fn parse_ms(text: &str) -> Result<u32, String> {
    let ns = duration::parse_duration(text)?;
    if ns == 0 || ns % 1_000_000 != 0 || ns / 1_000_000 > u64::from(u32::MAX) {
        return Err(format!("`{text}`: expected whole milliseconds, e.g. 1ms"));
    }
    Ok((ns / 1_000_000) as u32)
}

fn parse_us(text: &str) -> Result<u32, String> {
    let ns = duration::parse_duration(text)?;
    if ns % 1000 != 0 || ns / 1000 > u64::from(u32::MAX) {
        return Err(format!("`{text}`: expected whole microseconds, e.g. 500us"));
    }
    Ok((ns / 1000) as u32)
}
