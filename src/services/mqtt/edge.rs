//! The Sparkplug B edge node's protocol without a network (docs/MQTT.md): births, data, deaths,
//! sequence numbers, commands, the primary host's state, rebirths and store and forward, as
//! decisions on events — a connect, a copy of the PLC, a command, a state message — that give
//! back what to publish and what to ask of the request handler. The client
//! ([`super::client`]) carries them out on a broker; the tests here drive them directly.

use std::collections::VecDeque;

use plcd_ipc::NamedValue;
use prost::Message as _;

use super::metrics::{self, DataType, Metric, Plan, Source, Value};
use super::sparkplug_b::payload::{
    metric::Value as Wire, property_value, Metric as WireMetric, PropertySet, PropertyValue,
};
use super::sparkplug_b::Payload;

/// The first level of every Sparkplug B topic.
pub const NAMESPACE: &str = "spBv1.0";

/// The topics of one edge node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topics {
    pub group: String,
    pub node: String,
}

impl Topics {
    pub fn new(group: &str, node: &str) -> Topics {
        Topics { group: group.into(), node: node.into() }
    }

    /// `spBv1.0/GROUP/KIND/NODE`.
    pub fn node(&self, kind: &str) -> String {
        format!("{NAMESPACE}/{}/{kind}/{}", self.group, self.node)
    }

    /// `spBv1.0/GROUP/KIND/NODE/DEVICE`.
    pub fn device(&self, kind: &str, device: &str) -> String {
        format!("{NAMESPACE}/{}/{kind}/{}/{device}", self.group, self.node)
    }

    /// `spBv1.0/STATE/HOST`.
    pub fn state(host: &str) -> String {
        format!("{NAMESPACE}/STATE/{host}")
    }

    /// What the node subscribes to: its NCMD, its devices' DCMD, the primary host's STATE.
    pub fn subscriptions(&self, primary: Option<&str>) -> Vec<String> {
        let mut topics = vec![self.node("NCMD"), self.device("DCMD", "+")];
        topics.extend(primary.map(Topics::state));
        topics
    }
}

/// One MQTT message to publish (QoS 0, not retained, as the specification has births, data and
/// deaths).
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    pub topic: String,
    pub payload: Vec<u8>,
}

/// A metric of the plan: the node's (`device` `None`) or a device's, by its index there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MetricRef {
    pub device: Option<usize>,
    pub index: usize,
}

/// What the edge node asks its client to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Publish(Message),
    /// Writes for the request handler, all at one scan boundary (one `set`); `metrics` are the
    /// metrics written, in the same order, for [`Edge::refused`].
    Set {
        writes: Vec<NamedValue>,
        metrics: Vec<MetricRef>,
    },
    /// Publish the NDEATH (this message), disconnect, connect to the next broker.
    NextServer(Message),
    /// The sampling interval is now this many ms (`Node Control/Scan Rate`).
    ScanRate(u32),
}

/// The PLC's status beside a copy.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Status {
    /// `RUN`, `STOP`, `ERROR`, `DEBUG`.
    pub mode: String,
    /// The error code, empty without one.
    pub error: String,
    pub scans: u64,
    /// The last scan, ms.
    pub scan_ms: f64,
}

/// A remote I/O device's state and counters, as its Sparkplug device publishes them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RemoteState {
    /// `starting`, `online`, `lost`.
    pub state: String,
    pub requests: u64,
    pub failures: u64,
    pub losses: u64,
}

impl RemoteState {
    /// A lost device's Sparkplug device is dead.
    fn alive(&self) -> bool {
        self.state != "lost"
    }
}

/// A copy of the PLC taken at a scan boundary.
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// When it was taken, ms since 1970.
    pub at_ms: u64,
    pub words: &'a [u16],
    pub vars: &'a [u8],
    pub status: &'a Status,
}

/// What happened, counted for the log and the status.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Counters {
    /// NBIRTHs published (each connect, each rebirth).
    pub births: u64,
    /// NDATA and DDATA published live.
    pub data: u64,
    /// DATA messages stored while offline, and of them those dropped (the store full, or the
    /// metrics changed before they could be sent).
    pub stored: u64,
    pub dropped: u64,
    /// Commands taken, and writes refused here (not writable, unknown, wrong type).
    pub commands: u64,
    pub refused: u64,
    /// Commands that were not a Sparkplug payload.
    pub malformed: u64,
}

/// A DATA message kept while offline: the node's (`device` `None`) or a device's metrics, its
/// sequence number to be given when it is sent.
#[derive(Debug, Clone, PartialEq)]
pub struct Stored {
    pub device: Option<usize>,
    pub payload: Payload,
}

/// Where the DATA messages go that the memory store has no room for (the disk, in the
/// client): older than every message in memory, so sent before them. First in, first out.
pub trait Backlog: Send {
    /// Keeps `stored` after the others; the number of older messages dropped to make room
    /// (or 1 if `stored` itself could not be kept).
    fn push(&mut self, stored: Stored) -> u64;
    /// The oldest message, taken.
    fn pop(&mut self) -> Option<Stored>;
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Drops every message (the metrics changed); how many there were.
    fn clear(&mut self) -> u64;
}

/// The edge node's state.
pub struct Edge {
    topics: Topics,
    plan: Plan,
    primary: Option<String>,
    /// The primary host's last STATE said online.
    host_online: bool,
    /// `bdSeq` of the session under way (the one the last will carries).
    bd_seq: u64,
    /// Wills made: the next session's `bdSeq` is this, modulo 256.
    sessions: u64,
    /// The next message's `seq`.
    seq: u8,
    connected: bool,
    /// The births of this connection are out.
    born: bool,
    /// A birth went out once: changes while offline are stored from then on.
    ever_born: bool,
    /// A copy of the PLC was taken: births can carry values.
    copied: bool,
    scan_rate_ms: u32,
    scan_rates: std::ops::RangeInclusive<u32>,
    /// The index of each device's first metric in the flat order of [`Plan::all`].
    offsets: Vec<usize>,
    /// The values last published or stored, in flat order.
    sent: Vec<Option<Value>>,
    /// The last copy's values, in flat order.
    current: Vec<Option<Value>>,
    status: Status,
    stored: VecDeque<Stored>,
    store_limit: usize,
    /// Beyond `store_limit`: the older messages, on disk.
    overflow: Option<Box<dyn Backlog>>,
    /// The remote I/O devices' last states, in `[[remote]]` order.
    remotes: Vec<RemoteState>,
    /// Each device is alive (a remote one dies while it is lost), in the plan's order.
    alive: Vec<bool>,
    pub counters: Counters,
}

/// Settings of an edge node.
#[derive(Debug, Clone)]
pub struct Settings {
    pub topics: Topics,
    pub primary: Option<String>,
    pub scan_rate_ms: u32,
    pub scan_rates: std::ops::RangeInclusive<u32>,
    pub store_limit: usize,
}

impl Edge {
    pub fn new(settings: Settings, plan: Plan) -> Edge {
        let mut edge = Edge {
            topics: settings.topics,
            plan: Plan::default(),
            primary: settings.primary,
            host_online: false,
            bd_seq: 0,
            sessions: 0,
            seq: 0,
            connected: false,
            born: false,
            ever_born: false,
            copied: false,
            scan_rate_ms: settings.scan_rate_ms,
            scan_rates: settings.scan_rates,
            offsets: Vec::new(),
            sent: Vec::new(),
            current: Vec::new(),
            status: Status::default(),
            stored: VecDeque::new(),
            store_limit: settings.store_limit,
            overflow: None,
            remotes: Vec::new(),
            alive: Vec::new(),
            counters: Counters::default(),
        };
        edge.set_plan(plan);
        edge
    }

    fn set_plan(&mut self, plan: Plan) {
        let mut at = plan.node.len();
        self.offsets = plan
            .devices
            .iter()
            .map(|d| {
                at += d.metrics.len();
                at - d.metrics.len()
            })
            .collect();
        self.sent = vec![None; plan.len()];
        self.alive = plan
            .devices
            .iter()
            .map(|d| d.remote.is_none_or(|i| self.remotes.get(i).is_none_or(RemoteState::alive)))
            .collect();
        self.current = vec![None; plan.len()];
        self.plan = plan;
    }

    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    pub fn topics(&self) -> &Topics {
        &self.topics
    }

    pub fn primary(&self) -> Option<&str> {
        self.primary.as_deref()
    }

    pub fn scan_rate_ms(&self) -> u32 {
        self.scan_rate_ms
    }

    /// Connected to a broker (births or not).
    pub fn is_connected(&self) -> bool {
        self.connected
    }

    /// Births are out on a connection: data goes to the broker, not to the store.
    pub fn is_born(&self) -> bool {
        self.born
    }

    /// DATA messages waiting for the next connection.
    pub fn stored(&self) -> usize {
        self.stored.len() + self.overflow.as_ref().map_or(0, |o| o.len())
    }

    /// Where what the memory store has no room for goes (the disk), instead of being dropped.
    pub fn set_overflow(&mut self, overflow: Box<dyn Backlog>) {
        self.overflow = Some(overflow);
    }

    fn flat(&self, metric: MetricRef) -> usize {
        match metric.device {
            None => metric.index,
            Some(d) => self.offsets[d] + metric.index,
        }
    }

    fn metric(&self, metric: MetricRef) -> &Metric {
        match metric.device {
            None => &self.plan.node[metric.index],
            Some(d) => &self.plan.devices[d].metrics[metric.index],
        }
    }

    /// The will of the next connection: its NDEATH, with the next `bdSeq` (0 to 255, then 0),
    /// which the births of that connection carry too. Called once before each CONNECT.
    pub fn will(&mut self) -> Message {
        self.bd_seq = self.sessions % 256;
        self.sessions += 1;
        self.death()
    }

    /// The last will was never sent: the connection failed before its CONNECT went out (no
    /// TCP connection, no TLS). The next will has its `bdSeq` again, so that the numbers go
    /// up by one per CONNECT sent, as the specification says.
    pub fn will_unsent(&mut self) {
        self.sessions = self.sessions.saturating_sub(1);
    }

    /// The NDEATH of the session under way: the will, and what a clean stop publishes.
    pub fn death(&self) -> Message {
        let metric = WireMetric {
            name: Some("bdSeq".into()),
            datatype: Some(DataType::Int64.code()),
            value: Some(Wire::LongValue(self.bd_seq)),
            ..WireMetric::default()
        };
        let payload = Payload { metrics: vec![metric], ..Payload::default() };
        Message { topic: self.topics.node("NDEATH"), payload: payload.encode_to_vec() }
    }

    /// Connected to a broker (the CONNACK), `now_ms` since 1970: the births and what was
    /// stored, unless a primary host is configured and not known online yet, or no copy of the
    /// PLC was taken yet (the births wait for the first: they carry every value).
    pub fn connected(&mut self, now_ms: u64) -> Vec<Action> {
        self.connected = true;
        self.born = false;
        // A primary host's state is learned again on each connection (its retained STATE).
        self.host_online = false;
        self.births_if_due(now_ms)
    }

    /// The births, if connected, not born, with a copy taken and the primary host (if any)
    /// online.
    fn births_if_due(&mut self, now_ms: u64) -> Vec<Action> {
        let host = self.primary.is_none() || self.host_online;
        if self.connected && !self.born && self.copied && host {
            return self.births(now_ms);
        }
        Vec::new()
    }

    /// The connection is gone: what changes from now on is stored.
    pub fn disconnected(&mut self) {
        self.connected = false;
        self.born = false;
    }

    /// NBIRTH, every DBIRTH, then the stored DATA: `seq` from 0.
    fn births(&mut self, now_ms: u64) -> Vec<Action> {
        self.seq = 0;
        self.born = true;
        self.ever_born = true;
        self.counters.births += 1;
        let mut actions = Vec::new();
        let node: Vec<WireMetric> = (0..self.plan.node.len())
            .map(|index| self.birth_metric(MetricRef { device: None, index }, now_ms))
            .collect();
        actions.push(self.publish(self.topics.node("NBIRTH"), node, now_ms));
        for d in 0..self.plan.devices.len() {
            if self.alive[d] {
                actions.push(self.device_birth(d, now_ms));
            }
        }
        self.sent.clone_from(&self.current);
        // The oldest first: those that overflowed, then the memory's.
        let overflowed = std::iter::from_fn(|| self.overflow.as_mut().and_then(|o| o.pop()));
        let backlog: Vec<Stored> = overflowed.collect();
        for stored in backlog.into_iter().chain(std::mem::take(&mut self.stored)) {
            // A device dead now has no birth to go after: its DBIRTH, when it is back,
            // carries its values.
            if stored.device.is_some_and(|d| !self.alive[d]) {
                self.counters.dropped += 1;
                continue;
            }
            let topic = self.data_topic(stored.device);
            let mut payload = stored.payload;
            payload.seq = Some(self.next_seq());
            actions.push(Action::Publish(Message { topic, payload: payload.encode_to_vec() }));
        }
        actions
    }

    /// The DBIRTH of device `d`.
    fn device_birth(&mut self, d: usize, now_ms: u64) -> Action {
        let metrics: Vec<WireMetric> = (0..self.plan.devices[d].metrics.len())
            .map(|index| self.birth_metric(MetricRef { device: Some(d), index }, now_ms))
            .collect();
        let topic = self.topics.device("DBIRTH", &self.plan.devices[d].name);
        self.publish(topic, metrics, now_ms)
    }

    /// The DDEATH of device `d`.
    fn device_death(&mut self, d: usize, now_ms: u64) -> Action {
        let topic = self.topics.device("DDEATH", &self.plan.devices[d].name);
        self.publish(topic, Vec::new(), now_ms)
    }

    /// The remote I/O devices' states now (`[[remote]]` order), before the copy they go with
    /// ([`Edge::sample`]): the Sparkplug device of one that is lost dies (DDEATH), and is born
    /// again (DBIRTH) when it is back, if the node is born.
    pub fn remotes(&mut self, states: Vec<RemoteState>, now_ms: u64) -> Vec<Action> {
        self.remotes = states;
        let mut actions = Vec::new();
        for d in 0..self.plan.devices.len() {
            let Some(index) = self.plan.devices[d].remote else { continue };
            let alive = self.remotes.get(index).is_none_or(RemoteState::alive);
            if alive == self.alive[d] {
                continue;
            }
            self.alive[d] = alive;
            if !self.born {
                // The next births say it.
                continue;
            }
            if alive {
                for index in 0..self.plan.devices[d].metrics.len() {
                    let r = MetricRef { device: Some(d), index };
                    let flat = self.flat(r);
                    self.current[flat] = self.remote_value(self.metric(r));
                    self.sent[flat] = self.current[flat].clone();
                }
                actions.push(self.device_birth(d, now_ms));
            } else {
                actions.push(self.device_death(d, now_ms));
            }
        }
        actions
    }

    /// A remote device's figure, from the last states.
    fn remote_value(&self, metric: &Metric) -> Option<Value> {
        let Source::Remote { index, field } = metric.source else { return None };
        let state = self.remotes.get(index)?;
        Some(match field {
            metrics::RemoteField::State => Value::Text(state.state.clone()),
            metrics::RemoteField::Requests => Value::UInt(state.requests),
            metrics::RemoteField::Failures => Value::UInt(state.failures),
            metrics::RemoteField::Losses => Value::UInt(state.losses),
        })
    }

    /// A payload of `metrics` on `topic`, stamped `now_ms`, with the next `seq`.
    fn publish(&mut self, topic: String, metrics: Vec<WireMetric>, now_ms: u64) -> Action {
        let payload = Payload {
            timestamp: Some(now_ms),
            metrics,
            seq: Some(self.next_seq()),
            ..Payload::default()
        };
        Action::Publish(Message { topic, payload: payload.encode_to_vec() })
    }

    fn next_seq(&mut self) -> u64 {
        let seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        u64::from(seq)
    }

    fn data_topic(&self, device: Option<usize>) -> String {
        match device {
            None => self.topics.node("NDATA"),
            Some(d) => self.topics.device("DDATA", &self.plan.devices[d].name),
        }
    }

    /// A metric as its birth gives it: name, alias, data type, value (null before the first
    /// copy), and whether it is read-only.
    fn birth_metric(&self, metric: MetricRef, now_ms: u64) -> WireMetric {
        let m = self.metric(metric);
        let value = self.value_now(metric);
        let property = |ty: DataType, value: property_value::Value| PropertyValue {
            r#type: Some(ty.code()),
            value: Some(value),
            ..PropertyValue::default()
        };
        let mut keys = vec!["readOnly".to_string()];
        let mut values =
            vec![property(DataType::Boolean, property_value::Value::BooleanValue(!m.writable))];
        if let Some(range) = m.range {
            // Engineering metadata, under the names Sparkplug host applications read.
            keys.extend(["engLow".to_string(), "engHigh".to_string()]);
            values.push(property(DataType::Double, property_value::Value::DoubleValue(range.low)));
            values.push(property(DataType::Double, property_value::Value::DoubleValue(range.high)));
        }
        WireMetric {
            name: Some(m.name.clone()),
            alias: Some(m.alias),
            timestamp: Some(now_ms),
            datatype: Some(m.datatype.code()),
            is_null: value.is_none().then_some(true),
            properties: Some(PropertySet { keys, values }),
            value: value.map(|v| metrics::wire(m.datatype, &v)),
            ..WireMetric::default()
        }
    }

    /// A metric's value now: the node's own from the edge's state, the others from the last
    /// copy.
    fn value_now(&self, metric: MetricRef) -> Option<Value> {
        match &self.metric(metric).source {
            Source::BdSeq => Some(Value::Int(self.bd_seq as i64)),
            Source::Rebirth | Source::NextServer => Some(Value::Bool(false)),
            Source::ScanRate => Some(Value::Int(i64::from(self.scan_rate_ms))),
            _ => self.current[self.flat(metric)].clone(),
        }
    }

    /// The value of `metric` in `sample`.
    fn read(&self, metric: &Metric, sample: &Sample) -> Option<Value> {
        Some(match &metric.source {
            Source::Remote { .. } => return self.remote_value(metric),
            Source::Variable { ty, at, .. } => metrics::read(ty, *at, sample.words, sample.vars),
            Source::Mode => Value::Text(sample.status.mode.clone()),
            Source::Error => Value::Text(sample.status.error.clone()),
            Source::Scans => Value::UInt(sample.status.scans),
            Source::ScanTime => Value::Double(sample.status.scan_ms),
            Source::BdSeq => Value::Int(self.bd_seq as i64),
            Source::Rebirth | Source::NextServer => Value::Bool(false),
            Source::ScanRate => Value::Int(i64::from(self.scan_rate_ms)),
        })
    }

    /// A copy of the PLC: the metrics that changed since they were last sent (by their
    /// deadband) in one NDATA and one DDATA per device, live when born, else stored.
    pub fn sample(&mut self, sample: &Sample) -> Vec<Action> {
        let refs: Vec<MetricRef> = self.refs().collect();
        for &r in &refs {
            let value = self.read(self.metric(r), sample);
            let flat = self.flat(r);
            self.current[flat] = value;
        }
        self.status = sample.status.clone();
        if !self.copied {
            self.copied = true;
            return self.births_if_due(sample.at_ms);
        }
        let mut changed: Vec<Vec<usize>> = vec![Vec::new(); self.plan.devices.len() + 1];
        for &r in &refs {
            let flat = self.flat(r);
            let m = self.metric(r);
            if matches!(m.source, Source::Rebirth | Source::NextServer | Source::BdSeq) {
                continue;
            }
            let moved = match (&self.sent[flat], &self.current[flat]) {
                (Some(sent), Some(now)) => sent.changed(now, m.deadband),
                (None, Some(_)) => true,
                _ => false,
            };
            // A dead device sends nothing: its birth carries its values when it is back.
            let dead = r.device.is_some_and(|d| !self.alive[d]);
            if moved && !dead {
                changed[r.device.map_or(0, |d| d + 1)].push(r.index);
            }
        }
        let mut actions = Vec::new();
        if !self.born && !self.ever_born {
            // Nothing was born yet: the first births carry these values.
            return actions;
        }
        for (slot, indices) in changed.into_iter().enumerate() {
            if indices.is_empty() {
                continue;
            }
            let device = slot.checked_sub(1);
            let metrics =
                indices.into_iter().map(|index| MetricRef { device, index }).collect::<Vec<_>>();
            actions.extend(self.data(device, &metrics, sample.at_ms));
        }
        actions
    }

    /// Every metric of the plan, in flat order.
    fn refs(&self) -> impl Iterator<Item = MetricRef> + '_ {
        let node = (0..self.plan.node.len()).map(|index| MetricRef { device: None, index });
        let devices = self.plan.devices.iter().enumerate().flat_map(|(d, dev)| {
            (0..dev.metrics.len()).map(move |index| MetricRef { device: Some(d), index })
        });
        node.chain(devices)
    }

    /// A DATA message of `metrics` (all of the node, or all of device `device`) with their
    /// current values, by alias: published when born, else stored (historical).
    fn data(
        &mut self,
        device: Option<usize>,
        metrics: &[MetricRef],
        now_ms: u64,
    ) -> Option<Action> {
        let historical = !self.born;
        let wire: Vec<WireMetric> = metrics
            .iter()
            .filter_map(|&r| {
                let value = self.value_now(r)?;
                let m = self.metric(r);
                Some(WireMetric {
                    alias: Some(m.alias),
                    timestamp: Some(now_ms),
                    datatype: Some(m.datatype.code()),
                    is_historical: historical.then_some(true),
                    value: Some(metrics::wire(m.datatype, &value)),
                    ..WireMetric::default()
                })
            })
            .collect();
        for &r in metrics {
            let flat = self.flat(r);
            self.sent[flat] = self.value_now(r);
        }
        if wire.is_empty() {
            return None;
        }
        if historical {
            let payload = Payload { timestamp: Some(now_ms), metrics: wire, ..Payload::default() };
            self.counters.stored += 1;
            self.store(Stored { device, payload });
            return None;
        }
        self.counters.data += 1;
        let topic = self.data_topic(device);
        Some(self.publish(topic, wire, now_ms))
    }

    /// Keeps `stored` for the next connection: in memory, the oldest moving to the overflow
    /// (or dropped, without one) when the memory holds `store_limit` messages.
    fn store(&mut self, stored: Stored) {
        self.stored.push_back(stored);
        while self.stored.len() > self.store_limit {
            let Some(oldest) = self.stored.pop_front() else { break };
            self.counters.dropped += match &mut self.overflow {
                Some(overflow) => overflow.push(oldest),
                None => 1,
            };
        }
    }

    /// A message on one of the node's command topics (or the primary host's STATE).
    pub fn message(&mut self, topic: &str, payload: &[u8], now_ms: u64) -> Vec<Action> {
        if let Some(host) = topic.strip_prefix(&format!("{NAMESPACE}/STATE/")) {
            return self.state(host, payload, now_ms);
        }
        let node_cmd = self.topics.node("NCMD");
        let device = if topic == node_cmd {
            None
        } else if let Some(name) = topic.strip_prefix(&format!("{}/", self.topics.node("DCMD"))) {
            match self.plan.devices.iter().position(|d| d.name == name) {
                Some(d) => Some(d),
                None => {
                    self.counters.refused += 1;
                    return Vec::new();
                }
            }
        } else {
            return Vec::new();
        };
        let Ok(command) = Payload::decode(payload) else {
            self.counters.malformed += 1;
            return Vec::new();
        };
        self.counters.commands += 1;
        self.command(device, command, now_ms)
    }

    /// A command's metrics: node control, and writes of writable metrics.
    fn command(&mut self, device: Option<usize>, command: Payload, now_ms: u64) -> Vec<Action> {
        let mut actions = Vec::new();
        let mut writes = Vec::new();
        let mut written = Vec::new();
        let mut refused = Vec::new();
        for metric in command.metrics {
            let Some(r) = self.find(device, &metric) else {
                self.counters.refused += 1;
                continue;
            };
            let m = self.metric(r).clone();
            let on = matches!(metric.value, Some(Wire::BooleanValue(true)));
            match &m.source {
                Source::Rebirth if on => {
                    if self.connected && self.born {
                        actions.extend(self.births(now_ms));
                    }
                }
                Source::NextServer if on => {
                    actions.push(Action::NextServer(self.death()));
                }
                Source::ScanRate => {
                    let rate = match metric.value {
                        Some(Wire::LongValue(v)) => u32::try_from(v as i64).ok(),
                        Some(Wire::IntValue(v)) => u32::try_from(v as i32).ok(),
                        _ => None,
                    };
                    match rate.filter(|r| self.scan_rates.contains(r)) {
                        Some(rate) => {
                            self.scan_rate_ms = rate;
                            actions.push(Action::ScanRate(rate));
                            actions.extend(self.data(None, &[r], now_ms));
                        }
                        None => refused.push(r),
                    }
                }
                Source::Variable { name, ty, device: is_device, .. } if m.writable => {
                    match written_value(name, ty, *is_device, m.datatype, metric.value.as_ref()) {
                        Some(write) => {
                            writes.push(write);
                            written.push(r);
                        }
                        None => refused.push(r),
                    }
                }
                Source::Rebirth | Source::NextServer => {}
                _ => refused.push(r),
            }
        }
        if !writes.is_empty() {
            actions.push(Action::Set { writes, metrics: written });
        }
        actions.extend(self.refused(&refused, now_ms));
        actions
    }

    /// The metric a command's metric names: by alias if it has one, else by name, among the
    /// node's metrics or device `device`'s.
    fn find(&self, device: Option<usize>, metric: &WireMetric) -> Option<MetricRef> {
        let metrics = match device {
            None => &self.plan.node,
            Some(d) => &self.plan.devices[d].metrics,
        };
        let index = match (metric.alias, &metric.name) {
            (Some(alias), _) => metrics.iter().position(|m| m.alias == alias),
            (None, Some(name)) => metrics.iter().position(|m| &m.name == name),
            (None, None) => None,
        }?;
        Some(MetricRef { device, index })
    }

    /// Writes that were not applied (refused here or by the request handler): their metrics'
    /// current values sent again, so that the host application shows what the PLC holds.
    pub fn refused(&mut self, metrics: &[MetricRef], now_ms: u64) -> Vec<Action> {
        self.counters.refused += metrics.len() as u64;
        let mut by_device: Vec<(Option<usize>, Vec<MetricRef>)> = Vec::new();
        for &r in metrics {
            match by_device.iter_mut().find(|(d, _)| *d == r.device) {
                Some((_, list)) => list.push(r),
                None => by_device.push((r.device, vec![r])),
            }
        }
        let mut actions = Vec::new();
        if !self.born {
            return actions;
        }
        for (device, list) in by_device {
            // A dead device sends nothing: its birth carries its values when it is back.
            if device.is_some_and(|d| !self.alive[d]) {
                continue;
            }
            actions.extend(self.data(device, &list, now_ms));
        }
        actions
    }

    /// The primary host's STATE: births when it comes online (if connected and not born), and
    /// when it goes offline the NDEATH and the next broker, as the specification asks.
    fn state(&mut self, host: &str, payload: &[u8], now_ms: u64) -> Vec<Action> {
        if self.primary.as_deref() != Some(host) {
            return Vec::new();
        }
        let Some(online) = host_online(payload) else {
            self.counters.malformed += 1;
            return Vec::new();
        };
        let was = std::mem::replace(&mut self.host_online, online);
        match (was, online) {
            (false, true) => self.births_if_due(now_ms),
            (true, false) if self.connected => {
                self.born = false;
                vec![Action::NextServer(self.death())]
            }
            _ => Vec::new(),
        }
    }

    /// The project changed (a reload, a load, an online change): the devices that are gone
    /// die, and the node is born again with the new metrics, if it is born now. What was
    /// stored for the old metrics is dropped (its aliases mean nothing to the new births).
    pub fn replan(&mut self, plan: Plan, now_ms: u64) -> Vec<Action> {
        let born = self.born;
        let mut out = Vec::new();
        if born {
            for d in 0..self.plan.devices.len() {
                let name = &self.plan.devices[d].name;
                if !plan.devices.iter().any(|new| &new.name == name) {
                    out.push(self.device_death(d, now_ms));
                }
            }
        }
        self.counters.dropped += self.stored.len() as u64;
        self.stored.clear();
        if let Some(overflow) = &mut self.overflow {
            self.counters.dropped += overflow.clear();
        }
        self.set_plan(plan);
        if born {
            out.extend(self.births(now_ms));
        }
        out
    }
}

/// The `set` of a command's value for a writable metric; `None` if the value is of another
/// type or out of the type's range.
fn written_value(
    name: &str,
    ty: &crate::value::ValueType,
    device: bool,
    datatype: DataType,
    wire: Option<&Wire>,
) -> Option<NamedValue> {
    if device {
        // A device range's word (Int16) or bit (Boolean).
        let value = match (datatype, wire?) {
            (DataType::Boolean, Wire::BooleanValue(b)) => i32::from(*b),
            (DataType::Int16, Wire::IntValue(v)) => i32::from(i16::try_from(*v as i32).ok()?),
            (DataType::Int16, Wire::LongValue(v)) => i32::from(i16::try_from(*v as i64).ok()?),
            _ => return None,
        };
        return Some(NamedValue::device(name, value));
    }
    let text = metrics::written(ty, datatype, wire).ok()?;
    Some(NamedValue::write(name, plcd_ipc::Value::Text(text)))
}

/// The state a primary host's STATE payload gives: Sparkplug 3.0's JSON `{"online": true, …}`,
/// or 2.2's `ONLINE`/`OFFLINE`. `None`: neither.
pub fn host_online(payload: &[u8]) -> Option<bool> {
    #[derive(serde::Deserialize)]
    struct State {
        online: bool,
    }
    if let Ok(state) = serde_json::from_slice::<State>(payload) {
        return Some(state.online);
    }
    match payload {
        b"ONLINE" => Some(true),
        b"OFFLINE" => Some(false),
        _ => None,
    }
}

#[cfg(test)]
mod tests;
