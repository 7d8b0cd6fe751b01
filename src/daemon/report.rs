//! What the daemon tells its operator: the names behind the engine's ids, the service status
//! line, and the statistics printed on exit.

use std::sync::atomic::Ordering;
use std::time::Duration;

use crate::device::Address;
use crate::drivers::real_time::Shared;
use crate::engine::event::ErrorKind;
use crate::engine::Engine;
use crate::project::Project;
use crate::stats::Summary;

/// Task, watch and program names of one project, for log lines.
#[derive(Debug, Clone)]
pub struct Names {
    tasks: Vec<String>,
    watch: Vec<String>,
    program_lines: Vec<(String, Vec<u32>)>,
}

impl Names {
    pub fn new(project: &Project, watch: &[Address]) -> Names {
        Names {
            tasks: crate::engine::task_names(&project.config),
            watch: watch.iter().map(Address::to_string).collect(),
            program_lines: project
                .programs
                .iter()
                .map(|p| (p.name.clone(), p.lines.to_vec()))
                .collect(),
        }
    }

    pub fn watch(&self, index: u16) -> &str {
        self.watch.get(usize::from(index)).map_or("?", String::as_str)
    }

    pub fn describe_error(&self, kind: ErrorKind) -> (String, String) {
        kind.describe(&self.tasks, &self.program_lines)
    }
}

fn ms(ns: u64) -> String {
    format!("{:.3} ms", ns as f64 / 1e6)
}

/// The one-line `STATUS=` of the service: mode, scan figures, uptime.
pub fn status_line(shared: &Shared, uptime: Duration) -> String {
    let scans = shared.scans.load(Ordering::Relaxed);
    let last = shared.scan_last_ns.load(Ordering::Relaxed);
    let min = shared.scan_min_ns.load(Ordering::Relaxed);
    let max = shared.scan_max_ns.load(Ordering::Relaxed);
    format!(
        "{} · {scans} scans · scan {} (min {}, max {}) · up {}s",
        shared.mode().as_str(),
        ms(last),
        ms(min),
        ms(max),
        uptime.as_secs()
    )
}

fn figures(summary: &Summary) -> String {
    if summary.count == 0 {
        "none".to_string()
    } else {
        summary.micros()
    }
}

/// The statistics printed on exit, one line each.
pub fn statistics(engine: &Engine, shared: &Shared) -> Vec<String> {
    let scan = engine.scan_stats();
    let mut lines = vec![format!(
        "statistics: {} scans since RUN, scan time {}",
        scan.count,
        figures(&scan.time.summary())
    )];
    for (name, stats) in engine.task_names().iter().zip(engine.all_task_stats()).skip(2) {
        lines.push(format!(
            "statistics: task {name}: {} runs, {} ignored, {} overruns; start latency {}; \
             execution {}",
            stats.runs,
            stats.ignored,
            stats.overruns,
            figures(&stats.start_latency.summary()),
            figures(&stats.exec_time.summary())
        ));
    }
    lines.push(format!(
        "statistics: {} lost edges, {} missed timer expirations, {} watchdog trips",
        shared.lost_edges.load(Ordering::Relaxed),
        engine.missed_deadlines(),
        shared.watchdog_trips.load(Ordering::Relaxed)
    ));
    lines
}
