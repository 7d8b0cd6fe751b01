//! `status`: the daemon's figures for a human.

use plcd_ipc::{Status, SwitchName};

use super::debug;
use super::format::{self, human_ns, Align, Table};

/// Labelled fields, then the task table.
pub fn render(status: &Status) -> String {
    let scan = &status.scan;
    let error = match &status.error {
        Some(e) if e.detail.is_empty() => e.code.clone(),
        Some(e) => format!("{}: {}", e.code, e.detail),
        None => "none".to_string(),
    };
    let switch = match status.switch {
        Some(SwitchName::Run) => "RUN",
        Some(SwitchName::Stop) => "STOP",
        None => "none",
    };
    let remote = if status.remote_allowed { "allowed" } else { "refused" };
    let forces = if status.forces.is_empty() {
        "none".to_string()
    } else {
        format::device_list(&status.forces)
    };
    let mut fields = vec![
        (
            "plcd",
            vec![format!("{}, {} backend, {}", status.version, status.backend, status.config)],
        ),
        ("uptime", vec![format::human_uptime(status.uptime_ms)]),
        ("mode", vec![status.mode.as_str().to_string()]),
        ("error", vec![error]),
        ("switch", vec![format!("{switch} (remote RUN/STOP/DEBUG {remote})")]),
        ("scans", vec![scan.count.to_string()]),
        (
            "scan time",
            vec![format!(
                "cur {}  min {}  max {}  p50 {}  p99 {}",
                human_ns(scan.cur_ns),
                human_ns(scan.min_ns),
                human_ns(scan.max_ns),
                human_ns(scan.p50_ns),
                human_ns(scan.p99_ns)
            )],
        ),
        (
            "health",
            vec![format!(
                "{} lost edges, {} missed timer expirations, {} watchdog trips",
                status.lost_edges, status.missed_timer_expirations, status.watchdog_trips
            )],
        ),
        ("forces", vec![forces]),
    ];
    if let Some(state) = &status.debug {
        fields.push(("debug", debug::lines(state)));
    }
    let mut text = format::fields(&fields);
    text.push('\n');
    if status.tasks.is_empty() {
        text.push_str("no tasks\n");
        return text;
    }
    let mut table = Table::new(&[
        ("TASK", Align::Left),
        ("KIND", Align::Left),
        ("RUNS", Align::Right),
        ("IGNORED", Align::Right),
        ("OVERRUNS", Align::Right),
        ("LAT P50", Align::Right),
        ("LAT P99", Align::Right),
        ("LAT P99.9", Align::Right),
        ("LAT MAX", Align::Right),
        ("EXEC P50", Align::Right),
        ("EXEC P99", Align::Right),
    ]);
    for task in &status.tasks {
        table.row(vec![
            task.name.clone(),
            task.kind.clone(),
            task.runs.to_string(),
            task.ignored.to_string(),
            task.overruns.to_string(),
            human_ns(task.latency.p50_ns),
            human_ns(task.latency.p99_ns),
            human_ns(task.latency.p999_ns),
            human_ns(task.latency.max_ns),
            human_ns(task.exec.p50_ns),
            human_ns(task.exec.p99_ns),
        ]);
    }
    text.push_str(&table.render());
    text
}
