//! The `status` request: mode, error, key switch, scan and task figures, the health counters,
//! forces and (in DEBUG) the debugger's state. It answers from a snapshot younger than
//! [`STATUS_MAX_AGE`](super::STATUS_MAX_AGE) when no command completed since, so that polling
//! clients cost the scan at most one capture per that period; otherwise it waits for a capture.
//! Paused in DEBUG, the snapshot must also hold the devices the paused line names (their values
//! are part of the debugger's state), as a debugger request's answer does: else it waits once
//! more for a capture of them.

use std::sync::atomic::Ordering;
use std::time::Instant;

use super::debugger::debug_state_with;
use super::devices::word_of;
use super::forces::forces_of;
use super::mode::mode_name;
use super::waiting::{Outcome, Then};
use super::RequestHandler;
use crate::config::{TaskKind, TaskRef};
use crate::device::Address;
use crate::drivers::real_time::snapshot::Snapshot;
use crate::engine::event::Mode;
use crate::io::remote::frame::FaultKind;
use crate::io::remote::DeviceReport;
use crate::io::SwitchPosition;
use crate::services::control::ClientId;
use crate::stats::Histogram;
use plcd_ipc::{
    ErrorInfo, Percentiles, RemoteFigures, Reply, ResponseLine, ScanFigures, Status, SwitchName,
    TaskFigures,
};

impl RequestHandler {
    pub(super) fn status_request(&mut self, client: ClientId) -> Option<ResponseLine> {
        if let Some((generation, until)) = self.fresh_until {
            if Instant::now() < until && generation == self.generation() {
                let snapshot = self.links.snapshot.lock().ok()?;
                if self
                    .paused_devices(&snapshot)
                    .iter()
                    .all(|d| snapshot.word(word_of(d)).is_some())
                {
                    return Some(ResponseLine::ok(Reply::Status(Box::new(self.status(&snapshot)))));
                }
            }
        }
        self.park_for_snapshot(client, Then::Status { devices: None })
    }

    /// What a `status` snapshot wait comes to: paused at a line that names devices the capture
    /// lacks, wait once more for a capture of them; then the status.
    pub(super) fn status_outcome(
        &self,
        devices: Option<Vec<Address>>,
        snapshot: &Snapshot,
    ) -> Outcome {
        if devices.is_none() {
            let devices = self.paused_devices(snapshot);
            if !devices.iter().all(|d| snapshot.word(word_of(d)).is_some()) {
                return Outcome::Wait {
                    then: Then::Status { devices: Some(devices) },
                    again: true,
                };
            }
        }
        Outcome::Answer(ResponseLine::ok(Reply::Status(Box::new(self.status(snapshot)))))
    }

    pub(super) fn status(&self, snapshot: &Snapshot) -> Status {
        let shared = &self.links.shared;
        let running = self.running();
        let config = &running.project.config;
        let mode = shared.mode();
        let error = match mode {
            Mode::Error => snapshot.latched_error,
            _ => snapshot.last_operation_error,
        }
        .map(|kind| {
            let (code, detail) = running.names.describe_error(kind);
            ErrorInfo { code, detail }
        });
        let scan_time = snapshot.scan.time.summary();
        let names = crate::engine::task_names(config);
        let kinds = ["scan".to_string(), "init".to_string()].into_iter().chain(
            config.tasks.iter().map(|t| {
                match t.kind {
                    TaskKind::Cycle { .. } => "cycle",
                    TaskKind::Io { .. } => "io",
                    TaskKind::Device { .. } => "device",
                }
                .to_string()
            }),
        );
        let has_init = running.project.config.programs.iter().any(|p| p.task == TaskRef::Init);
        let tasks = names
            .into_iter()
            .zip(kinds)
            .zip(snapshot.tasks.iter().take(snapshot.task_count))
            .enumerate()
            .filter(|(id, _)| *id != 1 || has_init)
            .map(|(_, ((name, kind), stats))| TaskFigures {
                name,
                kind,
                runs: stats.runs,
                ignored: stats.ignored,
                overruns: stats.overruns,
                latency: percentiles(&stats.start_latency),
                exec: percentiles(&stats.exec_time),
            })
            .collect();
        Status {
            version: env!("CARGO_PKG_VERSION").to_string(),
            config: running.config_path.display().to_string(),
            backend: config.io.backend.as_str().to_string(),
            uptime_ms: self.started.elapsed().as_millis() as u64,
            mode: mode_name(mode),
            error,
            switch: snapshot.switch.map(|p| match p {
                SwitchPosition::Run => SwitchName::Run,
                SwitchPosition::Stop => SwitchName::Stop,
            }),
            remote_allowed: snapshot.remote_allowed,
            scan: ScanFigures {
                count: shared.scans.load(Ordering::Relaxed),
                cur_ns: shared.scan_last_ns.load(Ordering::Relaxed),
                min_ns: shared.scan_min_ns.load(Ordering::Relaxed),
                max_ns: shared.scan_max_ns.load(Ordering::Relaxed),
                p50_ns: scan_time.p50,
                p99_ns: scan_time.p99,
            },
            tasks,
            lost_edges: shared.lost_edges.load(Ordering::Relaxed),
            missed_timer_expirations: shared.missed_deadlines.load(Ordering::Relaxed),
            watchdog_trips: shared.watchdog_trips.load(Ordering::Relaxed),
            forces: forces_of(snapshot),
            debug: (mode == Mode::Debug).then(|| debug_state_with(snapshot, &running)),
            remotes: self.links.remote.reports().into_iter().map(remote_figures).collect(),
            mqtt: self
                .links
                .mqtt
                .as_ref()
                .map(|figures| figures.lock().unwrap_or_else(|e| e.into_inner()).clone()),
        }
    }
}

fn remote_figures(report: DeviceReport) -> RemoteFigures {
    let stats = report.stats;
    RemoteFigures {
        name: report.name,
        transport: report.transport,
        state: stats.state.as_str().to_string(),
        requests: stats.requests,
        failures: stats.failures,
        faults: FaultKind::ALL
            .iter()
            .zip(stats.by_kind)
            .filter(|(_, count)| *count > 0)
            .map(|(kind, count)| (kind.name().to_string(), count))
            .collect(),
        late: stats.late,
        writes: stats.writes,
        losses: stats.losses,
        last_error: stats.last_error.map(|(text, _)| text),
        last_error_age_ms: report.last_error_age_ms,
        round_trip: percentiles(&stats.round_trip),
    }
}

fn percentiles(histogram: &Histogram) -> Percentiles {
    let s = histogram.summary();
    Percentiles { p50_ns: s.p50, p99_ns: s.p99, p999_ns: s.p999, max_ns: s.max }
}
