//! What a Sparkplug B edge node takes from outside (`[mqtt]`, docs/MQTT.md): messages on the
//! topics it subscribes to — its NCMD, its devices' DCMD, the primary host's STATE — with any
//! payload, handed to the protocol's state machine (`services::mqtt::edge::Edge::message`) as
//! the client hands them, between copies of the PLC of any bytes (`Edge::remotes` and
//! `Edge::sample`), the request handler refusing a command's writes or not (`Edge::refused`),
//! and the broker's connection lost and made again. The edge's metrics are those of a small
//! compiled Structured Text project ([`MAIN`], [`CELL`]): every IEC type, enumerations, a
//! struct, an array, located variables, device ranges of words and bits, most of them
//! writable, and a remote I/O device ([`REMOTE`]); in two plans, a device per program
//! instance or the devices of `[[mqtt.devices]]`. The edge starts connected and born (its
//! primary host online); its store of 4 messages has a backlog beyond it or not.
//!
//! The input: its first byte chooses the plan (bit 0) and the backlog ([`OVERFLOW`]); then
//! steps, each `op`, a payload's length (two bytes, big-endian) and the payload, then, if `op`
//! asks for one, a copy: where in memory (two bytes), how many bytes (one), those bytes, and
//! the PLC's status (one byte: the mode, the remote I/O device's state, an error, counts).
//! `op`'s bits 0–2 choose the topic ([`TOPICS`]), [`REFUSE`] has the request handler refuse
//! the writes of a `Set`, [`COPY`] takes a copy after the message, [`RECONNECT`] loses the
//! connection (or, lost, makes it again) before the message. The copy's bytes go into
//! variable memory and the device words the metrics read, one image, from the place given.
//!
//! What must hold, on everything the edge gives back: every published payload decodes as a
//! Sparkplug `Payload`; it is a birth, data or death of the node or of one of its devices,
//! sent while connected, after the births; its `seq` is 0 in an NBIRTH and one more (modulo
//! 256) than the message before in every other, the DBIRTHs of the living devices following
//! their NBIRTH in the plan's order; an NBIRTH's `bdSeq` is its will's; a birth names every
//! metric of its node or device with its alias, data type and `readOnly`, a DATA message
//! metrics of it by alias alone; every value is of its metric's data type (an Int8 below 256,
//! …). No DATA of a device between its DDEATH and its DBIRTH (or without a DBIRTH since the
//! NBIRTH); a DDEATH, or a DBIRTH without an NBIRTH, only of the remote I/O device lost or back.
//! What was stored goes out in the order stored. An NDEATH has the session's `bdSeq` and no
//! `seq`. A `Set` comes of a command on the device it names, and each of its writes names a
//! writable metric's variable: a device range's word or bit as a number within it, a
//! variable's value as a text that `plcctl set`'s parser (`value::parse`, `parse_string`,
//! `parse_wstring`) takes back to the same text. A scan rate is within `sample_interval_ms`'s
//! range. And every value a command carries is converted by `metrics::written` for every IEC
//! type into a refusal or a text that parser takes back to the same text (but an
//! enumeration's number that no value of it has, which `set` refuses by design), and that the
//! slot it parses to, published again and written back, gives again.

use std::collections::{BTreeSet, VecDeque};
use std::path::Path;
use std::sync::OnceLock;

use plcd::device::layout::TOTAL_WORDS;
use plcd::project::{self, Project};
use plcd::services::mqtt::edge::{
    Action, Backlog, Edge, MetricRef, RemoteState, Sample, Settings, Status, Stored, Topics,
};
use plcd::services::mqtt::metrics::{self, DataType, Metric, Plan, Source};
use plcd::services::mqtt::sparkplug_b::payload::metric::Value as Wire;
use plcd::services::mqtt::sparkplug_b::payload::{property_value, Metric as WireMetric};
use plcd::services::mqtt::sparkplug_b::Payload;
use plcd::value::{self, Calendar, Elem, Space, ValueType};
use prost::Message as _;

use crate::Bytes;

/// The program `main`: a variable of every IEC type plcd publishes, an enumeration of each
/// kind, a struct, an array, a reference (not published) and located variables.
pub const MAIN: &str = "TYPE Color : (Red, Green, Blue := 7); END_TYPE
TYPE Level : INT (Low := -1, High := 300); END_TYPE
TYPE Axis : STRUCT pos : REAL; on : BOOL; END_STRUCT END_TYPE
PROGRAM Main
VAR
    flag : BOOL;
    s8 : SINT;
    i16 : INT;
    i32 : DINT;
    i64 : LINT;
    u8 : USINT;
    u16 : UINT;
    u32 : UDINT;
    u64 : ULINT;
    b : BYTE;
    w : WORD;
    dw : DWORD;
    lw : LWORD;
    r : REAL := 1.5;
    lr : LREAL;
    t : TIME;
    lt : LTIME;
    tod1 : TOD;
    ltod1 : LTOD;
    d : DATE;
    dt1 : DT;
    ld : LDATE;
    ldt1 : LDT;
    c : CHAR;
    wc : WCHAR;
    s : STRING[12] := 'abc';
    ws : WSTRING[8];
    color : Color;
    level : Level;
    axis : Axis;
    buf : ARRAY[0..3] OF INT;
    ro : INT;
    p : REF_TO INT;
    word_at AT %D00300 : DINT;
    bit_at AT %M0020 : BOOL;
END_VAR
    i16 := i16;
END_PROGRAM
";

/// The program `cell`: a second device, read-only.
pub const CELL: &str = "PROGRAM Cell
VAR
    count : UDINT;
    temp : REAL;
    name : STRING := 'cell';
END_VAR
    count := count + 1;
END_PROGRAM
";

/// The config: a primary host, a store of 4 messages, deadbands, device ranges (writable
/// words and bits, read-only words), every variable of `main` writable but `ro`.
pub const CONFIG: &str = r#"
[mqtt]
group_id = "plant"
edge_node_id = "press7"
primary_host = "scada"
store_forward_messages = 4
writable = ["main.flag", "main.s8", "main.i16", "main.i32", "main.i64", "main.u8", "main.u16",
    "main.u32", "main.u64", "main.b", "main.w", "main.dw", "main.lw", "main.r", "main.lr",
    "main.t", "main.lt", "main.tod1", "main.ltod1", "main.d", "main.dt1", "main.ld", "main.ldt1",
    "main.c", "main.wc", "main.s", "main.ws", "main.color", "main.level", "main.axis",
    "main.buf", "main.word_at", "main.bit_at"]
[[mqtt.deadbands]]
variable = "main.r"
value = 0.5
[[mqtt.deadbands]]
variable = "main.i32"
value = 10
[[mqtt.ranges]]
device = "D00100"
count = 4
writable = true
[[mqtt.ranges]]
device = "M0000"
count = 8
writable = true
[[mqtt.ranges]]
device = "D00200"
count = 2
[[program]]
name = "main"
file = "main.st"
[[program]]
name = "cell"
file = "cell.st"
"#;

/// The second plan's devices (added to [`CONFIG`]): names made of levels (`main/axis/pos`).
pub const DEVICES: &str = r#"
[[mqtt.devices]]
name = "press"
variables = ["main.axis", "main.s", "main.i16", "main.color", "main.ldt1", "cell"]
[[mqtt.devices]]
name = "all"
variables = ["main"]
"#;

/// The remote I/O device of both plans (`[[remote]]`): the last device, `remote-pump`.
pub const REMOTE: &str = "pump";

/// What `op & 7` chooses: the node's NCMD; the DCMD of the first device, of the second, of the
/// last (the remote I/O device's, read-only), of a device the node has not; the primary
/// host's STATE, another host's; no message.
pub const TOPICS: [&str; 8] = [
    "NCMD",
    "DCMD first",
    "DCMD second",
    "DCMD remote",
    "DCMD nope",
    "STATE",
    "STATE other",
    "none",
];

/// `op`'s bits beside the topic.
pub const REFUSE: u8 = 0x08;
pub const COPY: u8 = 0x10;
pub const RECONNECT: u8 = 0x20;

/// The first byte's bits beside the plan: the edge keeps what its memory store has no room
/// for in a backlog (as on disk with `store_forward_dir`) of [`BACKLOG`] messages.
pub const OVERFLOW: u8 = 0x02;
pub const BACKLOG: usize = 3;

/// The remote I/O device's state of a copy's status byte (bits 3–4).
pub const REMOTE_STATES: [&str; 4] = ["starting", "online", "lost", "online"];

/// The two plans and what a copy is made of.
pub struct Fixture {
    pub plans: [Plan; 2],
    pub settings: Settings,
    /// Variable memory at RUN start.
    pub vars: Vec<u8>,
    /// The device words some metric reads, in order: a copy's bytes past `vars` go to them.
    pub words: Vec<usize>,
}

fn project(config_text: &str) -> Project {
    let config = plcd::config::parse(config_text, Path::new("plcd.toml")).expect("the config");
    project::from_config(config, |path: &Path| {
        Ok(if path.ends_with("cell.st") { CELL } else { MAIN }.to_string())
    })
    .expect("the project")
}

/// The plan of `project`, as the client makes it.
fn plan(project: &Project) -> Plan {
    let names = project.mqtt_names().expect("the [mqtt] names");
    let symbols = &project.variables.symbols;
    Plan::of(symbols, &project.config.mqtt, &names, TOTAL_WORDS as u16)
        .with_remotes(&[REMOTE.to_string()])
}

pub fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let by_instance = project(CONFIG);
        let listed = project(&format!("{CONFIG}{DEVICES}"));
        let plans = [plan(&by_instance), plan(&listed)];
        let config = &by_instance.config.mqtt;
        let settings = Settings {
            topics: Topics::new(&config.group_id, &config.edge_node_id),
            primary: config.primary_host.clone(),
            scan_rate_ms: config.sample_interval_ms,
            scan_rates: plcd::config::MqttConfig::SAMPLE_INTERVAL_MS,
            store_limit: config.store_forward_messages as usize,
        };
        let mut words = BTreeSet::new();
        for plan in &plans {
            for (_, m) in plan.all() {
                let Source::Variable { ty, at, .. } = &m.source else { continue };
                match at.space {
                    Space::Word => {
                        let first = at.offset as usize;
                        words.extend(first..first + (ty.bytes() as usize).div_ceil(2));
                    }
                    Space::Bit => {
                        words.insert(at.offset as usize / 16);
                    }
                    _ => {}
                }
            }
        }
        Fixture {
            plans,
            settings,
            vars: by_instance.variables.initial.to_vec(),
            words: words.into_iter().collect(),
        }
    })
}

/// A backlog in memory, of [`BACKLOG`] messages, the oldest dropped first: what the edge sees
/// of the disk's (`services::mqtt::store`).
#[derive(Default)]
struct Memory(VecDeque<Stored>);

impl Backlog for Memory {
    fn push(&mut self, stored: Stored) -> u64 {
        self.0.push_back(stored);
        let over = self.0.len().saturating_sub(BACKLOG);
        self.0.drain(..over);
        over as u64
    }

    fn pop(&mut self) -> Option<Stored> {
        self.0.pop_front()
    }

    fn len(&self) -> usize {
        self.0.len()
    }

    fn clear(&mut self) -> u64 {
        let n = self.0.len() as u64;
        self.0.clear();
        n
    }
}

/// What happened in a run, for the test that the seeds reach every kind of message.
pub type Seen = BTreeSet<&'static str>;

pub fn run(data: &[u8]) {
    steps(data, &mut Seen::new());
}

/// The edge node and what the checks remember of what it did.
struct Node<'f> {
    f: &'f Fixture,
    plan: &'f Plan,
    edge: Edge,
    connected: bool,
    /// The births of this connection are out.
    born: bool,
    /// The `seq` of the last message published.
    seq: Option<u64>,
    /// The `bdSeq` of the last will.
    bd_seq: u64,
    /// Each device's last birth or death was a death (or none since the NBIRTH).
    dead: Vec<bool>,
    /// The remote I/O device's last state said lost.
    lost: bool,
    /// The timestamp of the last historical message since the births.
    history: u64,
    now: u64,
    vars: Vec<u8>,
    words: Vec<u16>,
    status: Status,
    remote: RemoteState,
}

/// Runs `data` (the module docs say how it is read), noting in `seen` what happened.
pub fn steps(data: &[u8], seen: &mut Seen) {
    let f = fixture();
    let mut input = Bytes::new(data);
    let first = input.u8();
    let plan = &f.plans[usize::from(first & 1)];
    let mut edge = Edge::new(f.settings.clone(), plan.clone());
    if first & OVERFLOW != 0 {
        edge.set_overflow(Box::<Memory>::default());
    }
    let mut node = Node {
        f,
        plan,
        edge,
        connected: false,
        born: false,
        seq: None,
        bd_seq: 0,
        dead: vec![true; plan.devices.len()],
        lost: false,
        history: 0,
        now: 1_700_000_000_000,
        vars: f.vars.clone(),
        words: vec![0; TOTAL_WORDS as usize],
        status: Status { mode: "RUN".into(), ..Status::default() },
        remote: RemoteState { state: "online".into(), ..RemoteState::default() },
    };
    // Connected and born: a copy, the connection, the primary host online.
    node.copy(&[], 0, seen);
    node.connect(seen);
    let state = Topics::state(f.settings.primary.as_deref().expect("a primary host"));
    let births = node.edge.message(&state, br#"{"online": true}"#, node.now);
    node.apply(births, None, seen);
    assert!(node.edge.is_born(), "not born with the primary host online");
    while !input.is_empty() {
        let op = input.u8();
        let len = usize::from(input.u16());
        let payload = input.take(len);
        node.now += 7;
        if op & RECONNECT != 0 {
            if node.connected {
                node.edge.disconnected();
                (node.connected, node.born) = (false, false);
                seen.insert("connection lost");
            } else {
                node.connect(seen);
            }
        }
        if let Some(topic) = node.topic(op & 7) {
            if node.connected {
                let device = node.device_of(&topic);
                let malformed = node.edge.counters.malformed;
                let actions = node.edge.message(&topic, payload, node.now);
                if node.edge.counters.malformed > malformed {
                    seen.insert("malformed");
                }
                node.apply(actions, device.map(|d| (d, op & REFUSE != 0)), seen);
            }
            if let Ok(command) = Payload::decode(payload) {
                for wire in command.metrics.iter().filter_map(|m| m.value.as_ref()) {
                    written_for_every_type(wire);
                }
            }
        }
        if op & COPY != 0 {
            let at = usize::from(input.u16());
            let n = usize::from(input.u8());
            let bytes = input.take(n);
            let status = input.u8();
            let modes = ["RUN", "STOP", "ERROR", "PAUSE", "DEBUG"];
            node.status.mode = modes[usize::from(status % 8 % 5)].into();
            node.status.error =
                if status & 0x80 != 0 { format!("E{status}") } else { String::new() };
            node.status.scans += u64::from(status);
            node.status.scan_ms = f64::from(status) / 7.0;
            let remote = REMOTE_STATES[usize::from(status >> 3 & 3)];
            if remote == "lost" && node.remote.state != "lost" {
                node.remote.losses += 1;
            }
            node.remote.state = remote.into();
            node.remote.requests += u64::from(status & 7);
            node.remote.failures += u64::from(status >> 5 & 3);
            node.copy(bytes, at, seen);
        }
    }
}

impl Node<'_> {
    /// The topic `choice` stands for; `None`: no message.
    fn topic(&self, choice: u8) -> Option<String> {
        let topics = self.edge.topics();
        let devices = &self.plan.devices;
        Some(match choice {
            0 => topics.node("NCMD"),
            1 => topics.device("DCMD", &devices[0].name),
            2 => topics.device("DCMD", &devices[1].name),
            3 => topics.device("DCMD", &devices[devices.len() - 1].name),
            4 => topics.device("DCMD", "nope"),
            5 => Topics::state(self.edge.primary().expect("a primary host")),
            6 => Topics::state("other"),
            _ => return None,
        })
    }

    /// For a command topic, the device it names (`None` inside: the node).
    fn device_of(&self, topic: &str) -> Option<Option<usize>> {
        let topics = self.edge.topics();
        if topic == topics.node("NCMD") {
            return Some(None);
        }
        let name = topic.strip_prefix(&format!("{}/", topics.node("DCMD")))?;
        self.plan.devices.iter().position(|d| d.name == name).map(Some)
    }

    /// A new connection: the will, then what the CONNACK gives.
    fn connect(&mut self, seen: &mut Seen) {
        let will = self.edge.will();
        self.bd_seq = death(&will.topic, &will.payload, self.edge.topics());
        self.connected = true;
        self.born = false;
        let actions = self.edge.connected(self.now);
        self.apply(actions, None, seen);
        seen.insert("connected");
    }

    /// A copy of the PLC with `bytes` written into its image (variable memory, then the words
    /// the metrics read) from `at`, round; the remote I/O device's state first, as the client
    /// hands them.
    fn copy(&mut self, bytes: &[u8], at: usize, seen: &mut Seen) {
        let size = self.vars.len() + 2 * self.f.words.len();
        for (k, &b) in bytes.iter().enumerate() {
            let i = (at + k) % size;
            match i.checked_sub(self.vars.len()) {
                None => self.vars[i] = b,
                Some(j) => {
                    let word = &mut self.words[self.f.words[j / 2]];
                    let mut le = word.to_le_bytes();
                    le[j % 2] = b;
                    *word = u16::from_le_bytes(le);
                }
            }
        }
        self.now += 3;
        let mut actions = self.edge.remotes(vec![self.remote.clone()], self.now);
        self.lost = self.remote.state == "lost";
        let sample =
            Sample { at_ms: self.now, words: &self.words, vars: &self.vars, status: &self.status };
        let data = self.edge.sample(&sample);
        if data.iter().any(|a| matches!(a, Action::Publish(_))) && self.born {
            seen.insert("data");
        }
        actions.extend(data);
        if !self.connected && self.edge.stored() > 0 {
            seen.insert("stored");
        }
        if self.edge.stored() > self.f.settings.store_limit {
            seen.insert("overflowed");
        }
        self.apply(actions, None, seen);
    }

    /// Checks `actions` and carries them out as the client does: each publication checked,
    /// a `Set`'s writes refused by the request handler if `command` says so (its device and
    /// whether to refuse) once they are all carried out, the next broker on `NextServer` (and
    /// nothing after it).
    fn apply(
        &mut self,
        actions: Vec<Action>,
        command: Option<(Option<usize>, bool)>,
        seen: &mut Seen,
    ) {
        // After an NBIRTH: the DBIRTHs to come, in order.
        let mut dbirths: Option<VecDeque<usize>> = None;
        let mut refused = Vec::new();
        for action in actions {
            match action {
                Action::Publish(message) => {
                    assert!(self.connected, "published while not connected: {}", message.topic);
                    let payload = Payload::decode(&message.payload[..]).unwrap_or_else(|e| {
                        panic!("{}: not a Sparkplug payload: {e}", message.topic)
                    });
                    self.published(&message.topic, &payload, &mut dbirths, seen);
                }
                Action::Set { writes, metrics } => {
                    let (device, refuse) = command.expect("a Set not of a command");
                    assert!(!writes.is_empty(), "a Set of nothing");
                    assert_eq!(writes.len(), metrics.len(), "a Set's writes and metrics");
                    for (write, r) in writes.iter().zip(&metrics) {
                        assert_eq!(r.device, device, "a write of another device than the topic's");
                        self.check_write(write, self.metric(*r));
                    }
                    seen.insert(if device.is_some() { "DCMD set" } else { "NCMD set" });
                    if refuse {
                        refused.extend(metrics);
                    }
                }
                Action::NextServer(message) => {
                    assert!(self.connected, "the next server while not connected");
                    let bd_seq = death(&message.topic, &message.payload, self.edge.topics());
                    assert_eq!(bd_seq, self.bd_seq, "the NDEATH's bdSeq");
                    seen.insert("next server");
                    self.edge.disconnected();
                    (self.connected, self.born) = (false, false);
                    self.connect(seen);
                    break;
                }
                Action::ScanRate(ms) => {
                    let ncmd = command.is_some_and(|(d, _)| d.is_none());
                    assert!(ncmd, "a scan rate not of an NCMD");
                    assert!(self.f.settings.scan_rates.contains(&ms), "a scan rate of {ms} ms");
                    assert_eq!(self.edge.scan_rate_ms(), ms);
                    seen.insert("scan rate");
                }
            }
        }
        if let Some(left) = dbirths {
            assert!(left.is_empty(), "an NBIRTH without the DBIRTHs of {left:?}");
        }
        // The request handler's answer comes after: the client has carried out the rest.
        if !refused.is_empty() {
            let again = self.edge.refused(&refused, self.now);
            if !again.is_empty() {
                seen.insert("refused and sent again");
            }
            self.apply(again, None, seen);
        }
    }

    fn metric(&self, r: MetricRef) -> &Metric {
        match r.device {
            None => &self.plan.node[r.index],
            Some(d) => &self.plan.devices[d].metrics[r.index],
        }
    }

    /// A write of a `Set` to the metric `m`.
    fn check_write(&self, write: &plcd_ipc::NamedValue, m: &Metric) {
        assert!(m.writable, "a write of the read-only {}", m.name);
        let Source::Variable { name, ty, device, .. } = &m.source else {
            panic!("a write of {}, not a variable", m.name)
        };
        assert_eq!(&write.dev, name, "the write of metric {}", m.name);
        if *device {
            let n = write.value.as_i64();
            let n = n.unwrap_or_else(|| panic!("{}: {:?}", m.name, write.value));
            match ty {
                ValueType::Bool => assert!(n == 0 || n == 1, "bit {name} := {n}"),
                _ => assert!(i16::try_from(n).is_ok(), "word {name} := {n}"),
            }
            return;
        }
        let plcd_ipc::Value::Text(text) = &write.value else {
            panic!("{name}: not a text: {:?}", write.value)
        };
        read_back(ty, text);
    }

    /// A published message: what its topic and `seq` must be, and its metrics. `dbirths`: the
    /// DBIRTHs still to come after an NBIRTH of the same actions.
    fn published(
        &mut self,
        topic: &str,
        payload: &Payload,
        dbirths: &mut Option<VecDeque<usize>>,
        seen: &mut Seen,
    ) {
        let topics = self.edge.topics();
        let seq = payload.seq.unwrap_or_else(|| panic!("{topic}: no seq"));
        assert!(seq <= 255, "{topic}: seq {seq}");
        let stamp = payload.timestamp.unwrap_or_else(|| panic!("{topic}: no timestamp"));
        let device_named = |kind: &str| {
            self.plan.devices.iter().position(|d| topic == topics.device(kind, &d.name))
        };
        if topic == topics.node("NBIRTH") {
            assert_eq!(seq, 0, "an NBIRTH's seq");
            if let Some(left) = dbirths {
                assert!(left.is_empty(), "an NBIRTH without the DBIRTHs of {left:?}");
            }
            let bd = payload.metrics.iter().find(|m| m.name.as_deref() == Some("bdSeq"));
            let bd = bd.and_then(|m| m.value.clone());
            assert_eq!(bd, Some(Wire::LongValue(self.bd_seq)), "the NBIRTH's bdSeq");
            self.births(None, payload);
            if self.born {
                seen.insert("rebirth");
            }
            self.born = true;
            self.history = 0;
            self.dead.fill(true);
            // Every device, but the remote I/O device's while it is lost.
            let remote = self.plan.devices.len() - 1;
            let alive = (0..self.plan.devices.len()).filter(|&d| d != remote || !self.lost);
            *dbirths = Some(alive.collect());
        } else {
            let last = self.seq.unwrap_or_else(|| panic!("{topic} before an NBIRTH"));
            assert_eq!(seq, (last + 1) % 256, "{topic}: seq after {last}");
            assert!(self.born, "{topic} before the births");
            if let Some(d) = device_named("DBIRTH") {
                match dbirths {
                    Some(next) if !next.is_empty() => {
                        assert_eq!(next.pop_front(), Some(d), "DBIRTHs out of order")
                    }
                    // Born again alone: the remote I/O device back.
                    _ => {
                        assert!(self.is_remote(d) && !self.lost, "a DBIRTH of {d} alone");
                        assert!(self.dead[d], "a DBIRTH of the living device {d}");
                        seen.insert("remote back");
                    }
                }
                self.dead[d] = false;
                self.births(Some(d), payload);
            } else if let Some(d) = device_named("DDEATH") {
                assert!(self.is_remote(d) && self.lost, "a DDEATH of {d}");
                assert!(!self.dead[d], "a DDEATH of the dead device {d}");
                assert!(payload.metrics.is_empty(), "a DDEATH with metrics");
                self.dead[d] = true;
                seen.insert("remote lost");
            } else if topic == topics.node("NDATA") {
                self.data(None, payload, stamp, seen);
            } else if let Some(d) = device_named("DDATA") {
                assert!(!self.dead[d], "DDATA of the dead device {d}");
                self.data(Some(d), payload, stamp, seen);
            } else {
                panic!("published on {topic}");
            }
        }
        self.seq = Some(seq);
    }

    fn is_remote(&self, d: usize) -> bool {
        self.plan.devices[d].remote.is_some()
    }

    fn metrics_of(&self, device: Option<usize>) -> &[Metric] {
        match device {
            None => &self.plan.node,
            Some(d) => &self.plan.devices[d].metrics,
        }
    }

    /// A birth: every metric, in order, with its name, alias, data type, access and a value
    /// of its type (or null).
    fn births(&self, device: Option<usize>, payload: &Payload) {
        let metrics = self.metrics_of(device);
        assert_eq!(payload.metrics.len(), metrics.len(), "a birth of {device:?}");
        for (wire, m) in payload.metrics.iter().zip(metrics) {
            assert_eq!(wire.name.as_deref(), Some(m.name.as_str()));
            assert_eq!(wire.alias, Some(m.alias), "{}: alias", m.name);
            assert_eq!(wire.datatype, Some(m.datatype.code()), "{}: data type", m.name);
            let props = wire.properties.as_ref().expect("properties");
            assert_eq!(props.keys, ["readOnly"]);
            let read_only = props.values[0].value.clone();
            let expected = property_value::Value::BooleanValue(!m.writable);
            assert_eq!(read_only, Some(expected), "{}: readOnly", m.name);
            match &wire.value {
                Some(value) => of_type(m, value),
                None => assert_eq!(wire.is_null, Some(true), "{}: no value, not null", m.name),
            }
        }
    }

    /// A DATA message: metrics of the node or device by alias alone, each of its type; the
    /// historical ones (stored during an outage, sent after the births) in the order stored.
    fn data(&mut self, device: Option<usize>, payload: &Payload, stamp: u64, seen: &mut Seen) {
        let metrics = self.metrics_of(device);
        assert!(!payload.metrics.is_empty(), "a DATA message of no metric");
        let mut historical = None;
        for wire in &payload.metrics {
            assert_eq!(wire.name, None, "a DATA metric by name");
            let alias = wire.alias.expect("a DATA metric without an alias");
            let m = metrics.iter().find(|m| m.alias == alias);
            let m = m.unwrap_or_else(|| panic!("alias {alias} is no metric of {device:?}"));
            assert_eq!(wire.datatype, Some(m.datatype.code()), "{}: data type", m.name);
            of_type(m, wire.value.as_ref().unwrap_or_else(|| panic!("{}: no value", m.name)));
            let this = wire.is_historical == Some(true);
            assert!(historical.is_none_or(|h| h == this), "historical and live in one message");
            historical = Some(this);
        }
        if historical == Some(true) {
            assert!(
                stamp >= self.history,
                "history sent out of order: {stamp} after {}",
                self.history
            );
            self.history = stamp;
            seen.insert("history");
        }
    }
}

/// The `bdSeq` of an NDEATH (the will, or the next server's).
fn death(topic: &str, payload: &[u8], topics: &Topics) -> u64 {
    assert_eq!(topic, topics.node("NDEATH"));
    let payload = Payload::decode(payload).expect("an NDEATH payload");
    assert_eq!(payload.seq, None, "an NDEATH with a seq");
    let [WireMetric { name: Some(name), value: Some(Wire::LongValue(bd)), .. }] =
        &payload.metrics[..]
    else {
        panic!("an NDEATH of {:?}", payload.metrics)
    };
    assert_eq!(name, "bdSeq");
    assert!(*bd <= 255, "bdSeq {bd}");
    *bd
}

/// A value as its metric's data type has it: the field, and the range of a narrow type.
fn of_type(m: &Metric, value: &Wire) {
    let fits = match (m.datatype, value) {
        (DataType::Int8 | DataType::UInt8, Wire::IntValue(v)) => *v <= 0xFF,
        (DataType::Int16 | DataType::UInt16, Wire::IntValue(v)) => *v <= 0xFFFF,
        (DataType::Int32 | DataType::UInt32, Wire::IntValue(_)) => true,
        (DataType::Int64 | DataType::UInt64 | DataType::DateTime, Wire::LongValue(_)) => true,
        (DataType::Float, Wire::FloatValue(_)) => true,
        (DataType::Double, Wire::DoubleValue(_)) => true,
        (DataType::Boolean, Wire::BooleanValue(_)) => true,
        (DataType::String, Wire::StringValue(_)) => true,
        _ => false,
    };
    assert!(fits, "{} ({:?}): {value:?}", m.name, m.datatype);
}

/// The IEC types a command may write: one of each kind plcd publishes.
pub fn types() -> &'static [ValueType] {
    static TYPES: OnceLock<Vec<ValueType>> = OnceLock::new();
    TYPES.get_or_init(|| {
        let mut types = vec![ValueType::Bool];
        for e in [Elem::I8, Elem::I16, Elem::I32, Elem::I64] {
            types.push(ValueType::Signed(e));
        }
        for e in [Elem::U8, Elem::U16, Elem::U32, Elem::U64] {
            types.push(ValueType::Unsigned(e));
        }
        types.extend([ValueType::Real(Elem::F32), ValueType::Real(Elem::F64), ValueType::Time]);
        types.extend(Calendar::ALL.map(ValueType::Calendar));
        types.extend([ValueType::Char, ValueType::WChar]);
        types.extend([ValueType::String { cap: 80 }, ValueType::WString { cap: 80 }]);
        let values = |names: &[(&str, i64)]| -> Vec<(String, i64)> {
            names.iter().map(|(n, v)| (n.to_string(), *v)).collect()
        };
        types.push(ValueType::Enum {
            type_name: "Color".into(),
            values: values(&[("Red", 0), ("Green", 1), ("Blue", 7)]),
            base: Elem::I32,
        });
        types.push(ValueType::Enum {
            type_name: "Level".into(),
            values: values(&[("Low", -1), ("High", 300)]),
            base: Elem::I16,
        });
        types.push(ValueType::Enum {
            type_name: "Small".into(),
            values: values(&[("A", -128), ("B", 127)]),
            base: Elem::I8,
        });
        types
    })
}

/// `wire` written to a variable of every type: refused, or a text `set` reads back.
fn written_for_every_type(wire: &Wire) {
    for ty in types() {
        let datatype = DataType::of(ty).expect("a published type");
        let Ok(text) = metrics::written(ty, datatype, Some(wire)) else { continue };
        let Some(slot) = read_back(ty, &text) else { continue };
        // Published again and written back: the same text.
        let again = metrics::wire(datatype, &metrics::slot_value(ty, slot));
        let back = metrics::written(ty, datatype, Some(&again));
        assert_eq!(
            back.as_ref(),
            Ok(&text),
            "{ty:?}: {wire:?} written as {text}, published as {again:?}"
        );
    }
}

/// A text `set` takes for a variable of `ty`: read back by its parser to the same text; the
/// slot, for a type of one.
fn read_back(ty: &ValueType, text: &str) -> Option<u64> {
    let (back, slot) = match ty {
        ValueType::String { .. } => {
            (value::parse_string(text, u32::MAX).map(|b| value::format_string(&b)), None)
        }
        ValueType::WString { .. } => {
            (value::parse_wstring(text, u32::MAX).map(|u| value::format_wstring(&u)), None)
        }
        _ => match value::parse(ty, text) {
            Ok(slot) => (Ok(value::format(ty, slot)), Some(slot)),
            Err(e) => (Err(e), None),
        },
    };
    match (back, ty) {
        (Ok(back), _) => assert_eq!(back, text, "{ty:?}: read back"),
        // `set` refuses a number no value of the enumeration has.
        (Err(_), ValueType::Enum { values, .. }) => {
            let n: i64 = text.parse().unwrap_or_else(|_| panic!("{ty:?}: {text:?}"));
            assert!(values.iter().all(|(_, v)| *v != n), "{ty:?}: {text:?} refused");
        }
        (Err(e), _) => panic!("{ty:?}: {text:?} refused: {e}"),
    }
    slot
}

/// One step of an input: `op` (a topic of [`TOPICS`] and the bits [`REFUSE`], [`COPY`],
/// [`RECONNECT`]) and a message's payload, then, with [`COPY`], `copy`: where, what, the
/// status byte (a copy of nothing without it). What the seeds are written with.
pub fn step(input: &mut Vec<u8>, op: u8, payload: &[u8], copy: Option<(u16, &[u8], u8)>) {
    input.push(op);
    input.extend_from_slice(&(payload.len() as u16).to_be_bytes());
    input.extend_from_slice(payload);
    if op & COPY != 0 {
        let (at, bytes, status) = copy.unwrap_or((0, &[], 0));
        input.extend_from_slice(&at.to_be_bytes());
        input.push(bytes.len() as u8);
        input.extend_from_slice(bytes);
        input.push(status);
    }
}
