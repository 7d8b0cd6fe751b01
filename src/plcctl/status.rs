//! `status`: the daemon's figures for a human.

use plcd_ipc::{MqttFigures, RemoteFigures, Status, SwitchName};

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
    if !status.remotes.is_empty() {
        text.push('\n');
        text.push_str(&remotes(&status.remotes));
    }
    if let Some(mqtt) = &status.mqtt {
        text.push('\n');
        text.push_str(&mqtt_lines(mqtt));
    }
    text
}

/// The Sparkplug B edge node: its state, its counters, its last connection failure.
fn mqtt_lines(mqtt: &MqttFigures) -> String {
    let mut text = format!(
        "mqtt: {} {} on {}: connects {}, failures {}, births {}, data {}, queued {}, dropped {}, \
         commands {}, refused {}, malformed {}\n",
        mqtt.node,
        mqtt.state,
        mqtt.broker,
        mqtt.connects,
        mqtt.failures,
        mqtt.births,
        mqtt.data,
        mqtt.queued,
        mqtt.dropped,
        mqtt.commands,
        mqtt.refused,
        mqtt.malformed
    );
    if let Some(error) = &mqtt.last_error {
        text.push_str(&format!("mqtt: last error: {error}\n"));
    }
    text
}

/// The remote I/O devices: a table, then each device's last error and fault counts.
fn remotes(remotes: &[RemoteFigures]) -> String {
    let mut table = Table::new(&[
        ("REMOTE", Align::Left),
        ("TRANSPORT", Align::Left),
        ("STATE", Align::Left),
        ("REQUESTS", Align::Right),
        ("FAILURES", Align::Right),
        ("LATE", Align::Right),
        ("WRITES", Align::Right),
        ("LOST", Align::Right),
        ("RTT P50", Align::Right),
        ("RTT P99", Align::Right),
    ]);
    for remote in remotes {
        table.row(vec![
            remote.name.clone(),
            remote.transport.clone(),
            remote.state.clone(),
            remote.requests.to_string(),
            remote.failures.to_string(),
            remote.late.to_string(),
            remote.writes.to_string(),
            remote.losses.to_string(),
            human_ns(remote.round_trip.p50_ns),
            human_ns(remote.round_trip.p99_ns),
        ]);
    }
    let mut text = table.render();
    for remote in remotes {
        if let Some(error) = &remote.last_error {
            let faults: Vec<String> =
                remote.faults.iter().map(|(kind, count)| format!("{kind} {count}")).collect();
            let age = remote
                .last_error_age_ms
                .map(|ms| format!(", {} ago", format::human_uptime(ms)))
                .unwrap_or_default();
            text.push_str(&format!(
                "{}: last error: {error}{age} (failures: {})\n",
                remote.name,
                faults.join(", ")
            ));
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use plcd_ipc::{MqttFigures, Percentiles, RemoteFigures};

    #[test]
    fn the_edge_node_shows_its_state_counters_and_last_error() {
        let figures = MqttFigures {
            node: "spBv1.0/plant/press7".into(),
            broker: "mqtts://broker:8883".into(),
            state: "connecting".into(),
            connects: 2,
            failures: 5,
            births: 3,
            data: 1200,
            queued: 40,
            dropped: 1,
            commands: 7,
            refused: 2,
            malformed: 0,
            last_error: Some("mqtts://broker:8883: I/O: connection refused".into()),
        };
        let text = super::mqtt_lines(&figures);
        assert_eq!(
            text,
            "mqtt: spBv1.0/plant/press7 connecting on mqtts://broker:8883: connects 2, failures 5, \
             births 3, data 1200, queued 40, dropped 1, commands 7, refused 2, malformed 0\n\
             mqtt: last error: mqtts://broker:8883: I/O: connection refused\n"
        );
    }

    #[test]
    fn remote_devices_show_their_state_counters_and_last_error() {
        let remote = |name: &str, state: &str, error: Option<&str>| RemoteFigures {
            name: name.into(),
            transport: "tcp 10.0.0.5:502".into(),
            state: state.into(),
            requests: 1200,
            failures: if error.is_some() { 3 } else { 0 },
            faults: if error.is_some() { vec![("timeout".into(), 3)] } else { vec![] },
            late: 1,
            writes: 40,
            losses: u64::from(error.is_some()),
            last_error: error.map(String::from),
            last_error_age_ms: error.map(|_| 65_000),
            round_trip: Percentiles { p50_ns: 850_000, p99_ns: 2_100_000, ..Default::default() },
        };
        let text = super::remotes(&[
            remote("rack1", "online", None),
            remote("rack2", "lost", Some("read of coils 0..=7: no answer in time")),
        ]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        assert!(lines[0].starts_with("REMOTE  TRANSPORT") && lines[0].ends_with("RTT P99"));
        assert!(lines[1].starts_with("rack1   tcp 10.0.0.5:502  online"), "{}", lines[1]);
        assert!(lines[2].contains("lost") && lines[2].contains("2.10 ms"), "{}", lines[2]);
        assert_eq!(
            lines[3],
            "rack2: last error: read of coils 0..=7: no answer in time, 1m 05s ago (failures: \
             timeout 3)"
        );
    }
}
