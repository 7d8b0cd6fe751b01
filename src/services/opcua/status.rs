//! The PLC's figures beyond the copy's: the scan time's percentiles, the health counters, each
//! task's figures and each remote I/O device's, from the daemon's own status answer (the one
//! `plcctl status` prints, made from a snapshot at a scan boundary), asked through the door once
//! per sampling interval, at most one request outstanding, never waited for.
//!
//! ```text
//! Status
//! ├── ScanTimeP50, ScanTimeP99            Double, ms
//! ├── LostEdges, WatchdogTrips, MissedTimerExpirations   UInt64
//! ├── Tasks/<task>/                       Kind, Runs, Ignored, Overruns, LatencyP50 … ExecMax
//! └── Remote/<device>/                    Transport, State, Requests, Failures, Losses, Writes,
//!                                         Late, LastError
//! ```
//!
//! The tasks and devices are the running project's: when the names change (a load), their
//! objects are replaced.

use std::sync::mpsc::{Receiver, TryRecvError};

use opcua::nodes::{AccessLevel, ObjectBuilder, VariableBuilder};
use opcua::server::SubscriptionCache;
use opcua::types::{DataTypeId, DataValue, NodeId, QualifiedName, Variant};
use plcd_ipc::{Outcome, Percentiles, Reply, Request, ResponseLine, Status};

use super::manager::PlcManager;
use super::nodes::STATUS;
use super::space::id;
use crate::drivers::real_time::door::{Caller, LocalDoor};

/// The status variables of the answer, under `Status`.
pub const FIGURES: [(&str, DataTypeId); 5] = [
    ("ScanTimeP50", DataTypeId::Double),
    ("ScanTimeP99", DataTypeId::Double),
    ("LostEdges", DataTypeId::UInt64),
    ("WatchdogTrips", DataTypeId::UInt64),
    ("MissedTimerExpirations", DataTypeId::UInt64),
];

/// A task's variables, under `Status.Tasks.<task>`.
pub const TASK: [(&str, DataTypeId); 10] = [
    ("Kind", DataTypeId::String),
    ("Runs", DataTypeId::UInt64),
    ("Ignored", DataTypeId::UInt64),
    ("Overruns", DataTypeId::UInt64),
    ("LatencyP50", DataTypeId::Double),
    ("LatencyP99", DataTypeId::Double),
    ("LatencyMax", DataTypeId::Double),
    ("ExecP50", DataTypeId::Double),
    ("ExecP99", DataTypeId::Double),
    ("ExecMax", DataTypeId::Double),
];

/// A remote I/O device's variables, under `Status.Remote.<device>`.
pub const REMOTE: [(&str, DataTypeId); 8] = [
    ("Transport", DataTypeId::String),
    ("State", DataTypeId::String),
    ("Requests", DataTypeId::UInt64),
    ("Failures", DataTypeId::UInt64),
    ("Losses", DataTypeId::UInt64),
    ("Writes", DataTypeId::UInt64),
    ("Late", DataTypeId::UInt64),
    ("LastError", DataTypeId::String),
];

/// The folders of the tasks and of the devices.
pub const TASKS: &str = "Status.Tasks";
pub const REMOTES: &str = "Status.Remote";

fn ms(ns: u64) -> Variant {
    Variant::Double(ns as f64 / 1e6)
}

/// The values of the status variables of `status`: (node id string, value), the figures, then
/// each task's, then each device's.
pub fn values(status: &Status) -> Vec<(String, Variant)> {
    let mut out: Vec<(String, Variant)> = vec![
        (format!("{STATUS}.ScanTimeP50"), ms(status.scan.p50_ns)),
        (format!("{STATUS}.ScanTimeP99"), ms(status.scan.p99_ns)),
        (format!("{STATUS}.LostEdges"), Variant::UInt64(status.lost_edges)),
        (format!("{STATUS}.WatchdogTrips"), Variant::UInt64(status.watchdog_trips)),
        (
            format!("{STATUS}.MissedTimerExpirations"),
            Variant::UInt64(status.missed_timer_expirations),
        ),
    ];
    let percentiles = |p: &Percentiles| [ms(p.p50_ns), ms(p.p99_ns), ms(p.max_ns)];
    for task in &status.tasks {
        let [l50, l99, lmax] = percentiles(&task.latency);
        let [e50, e99, emax] = percentiles(&task.exec);
        let values = [
            Variant::from(task.kind.clone()),
            Variant::UInt64(task.runs),
            Variant::UInt64(task.ignored),
            Variant::UInt64(task.overruns),
            l50,
            l99,
            lmax,
            e50,
            e99,
            emax,
        ];
        for ((name, _), value) in TASK.iter().zip(values) {
            out.push((format!("{TASKS}.{}.{name}", task.name), value));
        }
    }
    for remote in &status.remotes {
        let values = [
            Variant::from(remote.transport.clone()),
            Variant::from(remote.state.clone()),
            Variant::UInt64(remote.requests),
            Variant::UInt64(remote.failures),
            Variant::UInt64(remote.losses),
            Variant::UInt64(remote.writes),
            Variant::UInt64(remote.late),
            Variant::from(remote.last_error.clone().unwrap_or_default()),
        ];
        for ((name, _), value) in REMOTE.iter().zip(values) {
            out.push((format!("{REMOTES}.{}.{name}", remote.name), value));
        }
    }
    out
}

/// The status's nodes as the sampler keeps them.
pub struct StatusNodes {
    ns: u16,
    door: LocalDoor,
    /// The answer asked for and not taken yet.
    pending: Option<Receiver<ResponseLine>>,
    /// The tasks and devices that have nodes, by name.
    tasks: Vec<String>,
    remotes: Vec<String>,
}

impl StatusNodes {
    /// The fixed nodes (the figures and the two folders) into the address space.
    pub fn new(manager: &PlcManager, ns: u16, door: LocalDoor) -> StatusNodes {
        let mut space = manager.address_space().write();
        let name = |text: &str| QualifiedName::new(ns, text);
        let parent = id(ns, STATUS);
        for (label, ty) in FIGURES {
            variable(&mut space, ns, &format!("{STATUS}.{label}"), label, ty, &parent);
        }
        for (folder, browse) in [(TASKS, "Tasks"), (REMOTES, "Remote")] {
            ObjectBuilder::new(&id(ns, folder), name(browse), browse)
                .is_folder()
                .organized_by(parent.clone())
                .insert(&mut *space);
        }
        StatusNodes { ns, door, pending: None, tasks: Vec::new(), remotes: Vec::new() }
    }

    /// Takes the last answer if it came (its values to the stack), and asks for the next.
    pub fn sample(&mut self, manager: &PlcManager, subscriptions: &SubscriptionCache) {
        if let Some(pending) = &self.pending {
            match pending.try_recv() {
                Err(TryRecvError::Empty) => return,
                Err(TryRecvError::Disconnected) => {}
                Ok(line) => {
                    if let Outcome::Ok(Reply::Status(status)) = line.outcome {
                        self.show(manager, subscriptions, &status);
                    }
                }
            }
            self.pending = None;
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let reply = Box::new(move |line| {
            let _ = tx.try_send(line);
        });
        let caller = Caller::Service("opcua status".into());
        if self.door.submit(Request::Status, caller, reply).is_ok() {
            self.pending = Some(rx);
        }
    }

    /// `status`'s values to the stack, the task and device objects first made to match it.
    fn show(&mut self, manager: &PlcManager, subscriptions: &SubscriptionCache, status: &Status) {
        let tasks: Vec<String> = status.tasks.iter().map(|t| t.name.clone()).collect();
        let remotes: Vec<String> = status.remotes.iter().map(|r| r.name.clone()).collect();
        if tasks != self.tasks {
            self.replace(manager, TASKS, &self.tasks, &tasks, &TASK);
            self.tasks = tasks;
        }
        if remotes != self.remotes {
            self.replace(manager, REMOTES, &self.remotes, &remotes, &REMOTE);
            self.remotes = remotes;
        }
        let values: Vec<(NodeId, DataValue)> = values(status)
            .into_iter()
            .map(|(node, value)| (id(self.ns, &node), DataValue::new_now(value)))
            .collect();
        let values = values.iter().map(|(node, value)| (node, None, value.clone()));
        if let Err(status) = manager.set_values(subscriptions, values) {
            log::warn!("opcua: the status figures not handed to the server: {status}");
        }
    }

    /// The objects of `old` under `folder` replaced by objects of `new`, each with `members`.
    fn replace(
        &self,
        manager: &PlcManager,
        folder: &str,
        old: &[String],
        new: &[String],
        members: &[(&str, DataTypeId)],
    ) {
        let ns = self.ns;
        let mut space = manager.address_space().write();
        for name in old {
            for (member, _) in members {
                space.delete(&id(ns, &format!("{folder}.{name}.{member}")), true);
            }
            space.delete(&id(ns, &format!("{folder}.{name}")), true);
        }
        for name in new {
            let object = id(ns, &format!("{folder}.{name}"));
            ObjectBuilder::new(&object, QualifiedName::new(ns, name), name.as_str())
                .organized_by(id(ns, folder))
                .insert(&mut *space);
            for (member, ty) in members {
                let node = format!("{folder}.{name}.{member}");
                variable(&mut space, ns, &node, member, *ty, &object);
            }
        }
    }
}

/// A read-only variable of type `ty`.
fn variable(
    space: &mut opcua::server::address_space::AddressSpace,
    ns: u16,
    node: &str,
    browse: &str,
    ty: DataTypeId,
    parent: &NodeId,
) {
    VariableBuilder::new(&id(ns, node), QualifiedName::new(ns, browse), browse)
        .has_type_definition(opcua::types::VariableTypeId::BaseDataVariableType)
        .data_type(ty)
        .value(super::space::initial(ty))
        .access_level(AccessLevel::CURRENT_READ)
        .user_access_level(AccessLevel::CURRENT_READ)
        .organized_by(parent.clone())
        .insert(space);
}

#[cfg(test)]
mod tests {
    use super::*;
    use plcd_ipc::{ModeName, RemoteFigures, ScanFigures, TaskFigures};

    #[test]
    fn the_answer_becomes_the_status_nodes_values() {
        let status = Status {
            version: "0".into(),
            config: "plcd.toml".into(),
            backend: "sim".into(),
            uptime_ms: 1,
            mode: ModeName::Run,
            error: None,
            switch: None,
            remote_allowed: true,
            scan: ScanFigures {
                count: 9,
                p50_ns: 1_500_000,
                p99_ns: 2_000_000,
                ..Default::default()
            },
            tasks: vec![TaskFigures {
                name: "tick".into(),
                kind: "cycle".into(),
                runs: 5,
                ignored: 1,
                overruns: 0,
                latency: Percentiles { p50_ns: 1000, p99_ns: 2000, p999_ns: 0, max_ns: 3000 },
                exec: Percentiles::default(),
            }],
            lost_edges: 2,
            missed_timer_expirations: 0,
            watchdog_trips: 3,
            forces: Vec::new(),
            debug: None,
            remotes: vec![RemoteFigures {
                name: "rack1".into(),
                transport: "tcp 10.0.0.5:502".into(),
                state: "online".into(),
                requests: 40,
                failures: 1,
                faults: Vec::new(),
                late: 0,
                writes: 7,
                losses: 0,
                last_error: None,
                last_error_age_ms: None,
                round_trip: Percentiles::default(),
            }],
            mqtt: None,
        };
        let values = values(&status);
        let get = |node: &str| values.iter().find(|(n, _)| n == node).map(|(_, v)| v.clone());
        assert_eq!(get("Status.ScanTimeP99"), Some(Variant::Double(2.0)));
        assert_eq!(get("Status.WatchdogTrips"), Some(Variant::UInt64(3)));
        assert_eq!(get("Status.Tasks.tick.Kind"), Some(Variant::from("cycle".to_string())));
        assert_eq!(get("Status.Tasks.tick.LatencyMax"), Some(Variant::Double(0.003)));
        assert_eq!(get("Status.Remote.rack1.State"), Some(Variant::from("online".to_string())));
        assert_eq!(get("Status.Remote.rack1.LastError"), Some(Variant::from(String::new())));
        assert_eq!(values.len(), FIGURES.len() + TASK.len() + REMOTE.len());
    }
}
