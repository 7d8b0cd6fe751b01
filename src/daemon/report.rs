//! What the daemon tells its operator: the names behind the engine's ids, the service status
//! line, and the statistics printed on exit.

use std::sync::atomic::Ordering;
use std::time::Duration;

use crate::device::Address;
use crate::drivers::real_time::Shared;
use crate::engine::event::ErrorKind;
use crate::engine::Engine;
use crate::io::faults::{FaultState, FieldFaults};
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

    /// The name of task `task` (`scan`, `init`, a `[[task]]`'s).
    pub fn task(&self, task: crate::engine::event::TaskId) -> String {
        crate::engine::event::task_name(&self.tasks, task)
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

/// What the supervisor last said about the failures of one I/O path of the field
/// ([`crate::io::faults::Faults`]), so that a condition is logged once: when the path starts
/// failing, when the errno changes, and when it works again; never once a failure, which a
/// fault that persists would turn into a log line a scan.
#[derive(Debug)]
struct FaultLog {
    /// The path, as a log line starts: `reading GPIO edge events`.
    what: &'static str,
    /// What a failure means for the PLC until the path works again.
    meanwhile: &'static str,
    /// The failure count already accounted for.
    seen: u64,
    /// The errno of the failure being reported, while the path fails.
    reported: Option<i32>,
}

impl FaultLog {
    const fn new(what: &'static str, meanwhile: &'static str) -> FaultLog {
        FaultLog { what, meanwhile, seen: 0, reported: None }
    }

    /// The line to log, if any, given the path's counters.
    fn update(&mut self, state: FaultState) -> Option<(log::Level, String)> {
        let FaultState { count, errno, failing } = state;
        let (what, new) = (self.what, count.saturating_sub(self.seen));
        self.seen = count;
        let error = describe_errno(errno);
        match (failing, self.reported) {
            (true, Some(reported)) if reported == errno => None,
            (true, Some(_)) => {
                self.reported = Some(errno);
                Some((log::Level::Error, format!("{what} now fails with {error}")))
            }
            (true, None) => {
                self.reported = Some(errno);
                Some((log::Level::Error, format!("{what} failed: {error}; {}", self.meanwhile)))
            }
            (false, Some(_)) => {
                self.reported = None;
                Some((
                    log::Level::Warn,
                    format!("{what} works again, after {count} failures in all"),
                ))
            }
            (false, None) if new > 0 => Some((
                log::Level::Warn,
                format!(
                    "{what} failed {new} times (the last with {error}); the next attempt worked"
                ),
            )),
            (false, None) => None,
        }
    }
}

/// What was last logged about each I/O path of the field, each log beside the path it reads.
#[derive(Debug)]
pub struct FieldFaultLog {
    input_reads: FaultLog,
    output_writes: FaultLog,
    edge_reads: FaultLog,
}

impl Default for FieldFaultLog {
    fn default() -> Self {
        FieldFaultLog {
            input_reads: FaultLog::new(
                "reading the GPIO inputs",
                "the inputs keep their last values until a read works again (retried every scan)",
            ),
            output_writes: FaultLog::new(
                "writing the GPIO outputs",
                "the lines keep what was last written until a write works again (retried every \
                 scan)",
            ),
            edge_reads: FaultLog::new(
                "reading GPIO edge events",
                "io tasks start on no edge until a read works again (retried at most once a \
                 second)",
            ),
        }
    }
}

impl FieldFaultLog {
    /// The lines to log about `faults`, path by path.
    pub fn update(&mut self, faults: &FieldFaults) -> Vec<(log::Level, String)> {
        [
            (&mut self.input_reads, &faults.input_reads),
            (&mut self.output_writes, &faults.output_writes),
            (&mut self.edge_reads, &faults.edge_reads),
        ]
        .into_iter()
        .filter_map(|(log, path)| log.update(path.state()))
        .collect()
    }
}

/// An errno as the log says it; 0 is a failure without one (a short read).
fn describe_errno(errno: i32) -> String {
    if errno == 0 {
        "a short read".to_string()
    } else {
        std::io::Error::from_raw_os_error(errno).to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failing_path_is_logged_once_per_condition() {
        let state = |count, errno, failing| FaultState { count, errno, failing };
        let mut log = FieldFaultLog::default().edge_reads;
        assert_eq!(log.update(state(0, 0, false)), None, "nothing failed");
        let (level, line) = log.update(state(1, libc::ENODEV, true)).unwrap();
        assert_eq!(level, log::Level::Error);
        assert!(line.starts_with("reading GPIO edge events failed: No such device"), "{line}");
        assert!(line.ends_with("io tasks start on no edge until a read works again (retried at most once a second)"), "{line}");
        // The same fault, however often it recurs: nothing more.
        assert_eq!(log.update(state(2, libc::ENODEV, true)), None);
        assert_eq!(log.update(state(500, libc::ENODEV, true)), None);
        // Another errno is another condition.
        let (level, line) = log.update(state(501, libc::EIO, true)).unwrap();
        assert_eq!(level, log::Level::Error);
        assert!(line.starts_with("reading GPIO edge events now fails with Input/output"), "{line}");
        assert_eq!(log.update(state(502, libc::EIO, true)), None);
        // It clears.
        let (level, line) = log.update(state(502, libc::EIO, false)).unwrap();
        assert_eq!(level, log::Level::Warn);
        assert_eq!(line, "reading GPIO edge events works again, after 502 failures in all");
        assert_eq!(log.update(state(502, libc::EIO, false)), None);
        // Failures that came and went between two looks: one line.
        let (_, line) = log.update(state(505, 0, false)).unwrap();
        assert_eq!(
            line,
            "reading GPIO edge events failed 3 times (the last with a short read); the next \
             attempt worked"
        );
        assert_eq!(log.update(state(505, 0, false)), None);
        // Failing again after it cleared is news again.
        assert!(log.update(state(506, libc::ENODEV, true)).is_some());
    }

    #[test]
    fn each_path_of_the_field_says_what_failed_and_what_it_means() {
        let FieldFaultLog { input_reads: mut inputs, output_writes: mut outputs, .. } =
            FieldFaultLog::default();
        let failing = FaultState { count: 1, errno: libc::EIO, failing: true };
        let (_, line) = inputs.update(failing).unwrap();
        assert_eq!(
            line,
            "reading the GPIO inputs failed: Input/output error (os error 5); the inputs keep \
             their last values until a read works again (retried every scan)"
        );
        let (_, line) = outputs.update(failing).unwrap();
        assert!(line.starts_with("writing the GPIO outputs failed: Input/output error"), "{line}");
    }
}
