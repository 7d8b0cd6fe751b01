use super::*;
use crate::config::MqttConfig;
use crate::project::MqttNames;
use crate::symbols::Symbols;
use crate::value::{Elem, Pointer, Space, ValueType};
use std::collections::VecDeque;

/// Device `main`: `count` (INT at byte 0, writable), `temp` (REAL at byte 4, deadband 0.5),
/// `label` (STRING[10] at byte 8, read-only).
fn plan() -> Plan {
    let mut plan = Plan::of(&Symbols::default(), &MqttConfig::default(), &MqttNames::default(), 0);
    let mut alias = plan.node.len() as u64;
    let mut metric = |name: &str, ty: ValueType, offset: u32, writable: bool, deadband: f64| {
        alias += 1;
        Metric {
            name: name.into(),
            alias: alias - 1,
            datatype: DataType::of(&ty).unwrap(),
            source: Source::Variable {
                name: format!("main.{name}"),
                ty,
                at: Pointer { space: Space::Var, offset },
                device: false,
            },
            writable,
            deadband,
            range: None,
        }
    };
    let metrics = vec![
        metric("count", ValueType::Signed(Elem::I16), 0, true, 0.0),
        metric("temp", ValueType::Real(Elem::F32), 4, false, 0.5),
        metric("label", ValueType::String { cap: 10 }, 8, false, 0.0),
    ];
    plan.devices.push(metrics::Device { name: "main".into(), metrics, remote: None });
    plan
}

fn settings(primary: Option<&str>, store_limit: usize) -> Settings {
    Settings {
        topics: Topics::new("plant", "press7"),
        primary: primary.map(str::to_string),
        scan_rate_ms: 100,
        scan_rates: 10..=60_000,
        store_limit,
    }
}

/// Variable memory with `count`, `temp` and `label`.
fn vars(count: i16, temp: f32, label: &str) -> Vec<u8> {
    let mut vars = vec![0u8; 20];
    vars[0..2].copy_from_slice(&count.to_le_bytes());
    vars[4..8].copy_from_slice(&temp.to_le_bytes());
    vars[8..8 + label.len()].copy_from_slice(label.as_bytes());
    vars
}

fn status() -> Status {
    Status { mode: "RUN".into(), error: String::new(), scans: 7, scan_ms: 0.02 }
}

fn sample(edge: &mut Edge, vars: &[u8], at_ms: u64) -> Vec<Action> {
    let status = status();
    edge.sample(&Sample { at_ms, words: &[], vars, status: &status })
}

/// The published messages of `actions`, decoded.
fn published(actions: &[Action]) -> Vec<(String, Payload)> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::Publish(m) => Some((m.topic.clone(), Payload::decode(&m.payload[..]).unwrap())),
            _ => None,
        })
        .collect()
}

fn metric_named<'a>(payload: &'a Payload, name: &str) -> &'a WireMetric {
    payload
        .metrics
        .iter()
        .find(|m| m.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no {name}"))
}

/// An edge connected and born, after one copy.
fn born() -> Edge {
    let mut edge = Edge::new(settings(None, 100), plan());
    sample(&mut edge, &vars(5, 20.0, "abc"), 1_000);
    edge.will();
    edge.connected(1_001);
    edge
}

#[test]
fn each_connection_has_the_next_bd_seq_in_its_will_and_its_birth() {
    let mut edge = Edge::new(settings(None, 100), plan());
    sample(&mut edge, &vars(1, 20.0, ""), 0);
    for session in 0..300u64 {
        let will = edge.will();
        assert_eq!(will.topic, "spBv1.0/plant/NDEATH/press7");
        let death = Payload::decode(&will.payload[..]).unwrap();
        assert_eq!(death.seq, None, "an NDEATH has no seq");
        let bd_seq = metric_named(&death, "bdSeq");
        assert_eq!(bd_seq.value, Some(Wire::LongValue(session % 256)), "session {session}");
        assert_eq!(bd_seq.datatype, Some(DataType::Int64.code()));
        let births = published(&edge.connected(5));
        assert_eq!(births[0].0, "spBv1.0/plant/NBIRTH/press7");
        let birth_bd = metric_named(&births[0].1, "bdSeq");
        assert_eq!(birth_bd.value, bd_seq.value, "the birth carries its will's bdSeq");
        edge.disconnected();
    }
}

#[test]
fn a_will_never_sent_gives_its_bd_seq_to_the_next() {
    let mut edge = Edge::new(settings(None, 100), plan());
    edge.will();
    edge.connected(1);
    edge.disconnected();
    // Three attempts that never reached the broker, then one that did.
    for _ in 0..3 {
        edge.will();
        edge.will_unsent();
    }
    let will = Payload::decode(&edge.will().payload[..]).unwrap();
    assert_eq!(metric_named(&will, "bdSeq").value, Some(Wire::LongValue(1)));
}

#[test]
fn a_birth_names_every_metric_with_its_alias_type_value_and_access() {
    let mut edge = Edge::new(settings(None, 100), plan());
    sample(&mut edge, &vars(5, 20.5, "abc"), 1_000);
    edge.will();
    let births = published(&edge.connected(1_234));
    assert_eq!(births.len(), 2, "NBIRTH and one DBIRTH");
    let (nbirth, dbirth) = (&births[0], &births[1]);
    assert_eq!(nbirth.1.seq, Some(0));
    assert_eq!(nbirth.1.timestamp, Some(1_234));
    assert_eq!(dbirth.0, "spBv1.0/plant/DBIRTH/press7/main");
    assert_eq!(dbirth.1.seq, Some(1));
    let names: Vec<&str> = nbirth.1.metrics.iter().filter_map(|m| m.name.as_deref()).collect();
    for name in [
        "bdSeq",
        "Node Control/Rebirth",
        "Node Control/Next Server",
        "Node Control/Scan Rate",
        "Status/Mode",
    ] {
        assert!(names.contains(&name), "{name} in {names:?}");
    }
    assert_eq!(metric_named(&nbirth.1, "Status/Mode").value, Some(Wire::StringValue("RUN".into())));
    assert_eq!(metric_named(&nbirth.1, "Node Control/Scan Rate").value, Some(Wire::LongValue(100)));
    let mut aliases: Vec<u64> =
        births.iter().flat_map(|(_, p)| p.metrics.iter().map(|m| m.alias.unwrap())).collect();
    let count = aliases.len();
    aliases.sort_unstable();
    aliases.dedup();
    assert_eq!(aliases.len(), count, "aliases unique across the node and its devices");
    let count = metric_named(&dbirth.1, "count");
    assert_eq!(count.datatype, Some(DataType::Int16.code()));
    assert_eq!(count.value, Some(Wire::IntValue(5)));
    let read_only = |m: &WireMetric| {
        let props = m.properties.as_ref().unwrap();
        assert_eq!(props.keys, ["readOnly"]);
        props.values[0].value.clone()
    };
    assert_eq!(read_only(count), Some(property_value::Value::BooleanValue(false)), "writable");
    let temp = metric_named(&dbirth.1, "temp");
    assert_eq!(read_only(temp), Some(property_value::Value::BooleanValue(true)));
    assert_eq!(temp.value, Some(Wire::FloatValue(20.5)));
    assert_eq!(metric_named(&dbirth.1, "label").value, Some(Wire::StringValue("abc".into())));
}

#[test]
fn a_birth_carries_a_variable_s_engineering_range() {
    let ranges = [("main.temp".to_string(), crate::config::EuRange { low: -20.0, high: 150.0 })];
    let mut edge =
        Edge::new(settings(None, 100), plan().with_ranges(&ranges.into_iter().collect()));
    sample(&mut edge, &vars(5, 20.0, "abc"), 1);
    edge.will();
    let births = published(&edge.connected(2));
    let temp = metric_named(&births[1].1, "temp").properties.clone().unwrap();
    assert_eq!(temp.keys, ["readOnly", "engLow", "engHigh"]);
    let values: Vec<_> = temp.values.iter().map(|v| v.value.clone()).collect();
    assert_eq!(
        values[1..],
        [
            Some(property_value::Value::DoubleValue(-20.0)),
            Some(property_value::Value::DoubleValue(150.0))
        ]
    );
    let count = metric_named(&births[1].1, "count").properties.clone().unwrap();
    assert_eq!(count.keys, ["readOnly"], "no range, no engineering properties");
}

#[test]
fn births_wait_for_the_first_copy_of_the_plc() {
    let mut edge = Edge::new(settings(None, 100), plan());
    edge.will();
    assert!(edge.connected(1).is_empty(), "no values to carry yet");
    let births = published(&sample(&mut edge, &vars(5, 20.0, "abc"), 2));
    assert_eq!(births.len(), 2);
    assert_eq!(metric_named(&births[1].1, "count").value, Some(Wire::IntValue(5)));
}

#[test]
fn data_carries_the_changes_alone_by_alias_with_the_next_seq() {
    let mut edge = born();
    assert!(
        published(&sample(&mut edge, &vars(5, 20.0, "abc"), 1_100))
            .iter()
            .all(|(t, _)| t.contains("NDATA")),
        "no device change"
    );
    let data = published(&sample(&mut edge, &vars(6, 20.0, "abc"), 1_200));
    let ddata: Vec<_> =
        data.iter().filter(|(t, _)| t == "spBv1.0/plant/DDATA/press7/main").collect();
    assert_eq!(ddata.len(), 1);
    let payload = &ddata[0].1;
    assert_eq!(payload.metrics.len(), 1, "count alone changed");
    let m = &payload.metrics[0];
    assert_eq!((m.name.as_deref(), m.value.clone()), (None, Some(Wire::IntValue(6))), "by alias");
    assert_eq!(m.alias, Some(edge.plan().devices[0].metrics[0].alias));
    assert_eq!((m.timestamp, payload.timestamp), (Some(1_200), Some(1_200)), "the copy's time");
    assert!(payload.seq.unwrap() >= 2, "after the births");
}

#[test]
fn a_deadband_holds_back_small_changes() {
    let mut edge = born();
    let moved = |actions: &[Action]| published(actions).iter().any(|(t, _)| t.contains("DDATA"));
    assert!(!moved(&sample(&mut edge, &vars(5, 20.4, "abc"), 2)), "0.4 under the deadband");
    assert!(moved(&sample(&mut edge, &vars(5, 20.6, "abc"), 3)), "0.6 from the last sent");
    assert!(!moved(&sample(&mut edge, &vars(5, 20.9, "abc"), 4)), "0.3 from the last sent");
}

#[test]
fn sequence_numbers_wrap_after_255() {
    let mut edge = born();
    let mut seqs = Vec::new();
    for k in 0..300 {
        for (topic, payload) in published(&sample(&mut edge, &vars(k as i16 + 10, 20.0, "abc"), k))
        {
            if topic.contains("DDATA") {
                seqs.push(payload.seq.unwrap());
            }
        }
    }
    assert!(seqs.iter().all(|&s| s <= 255));
    for pair in seqs.windows(2) {
        assert!(pair[1] == (pair[0] + 1) % 256 || pair[1] == (pair[0] + 2) % 256, "{pair:?}");
    }
    assert!(seqs.contains(&255) && seqs.contains(&0));
}

#[test]
fn changes_while_offline_are_stored_and_sent_after_the_births_in_order_as_history() {
    let mut edge = born();
    edge.disconnected();
    for (k, count) in [7i16, 8, 9].into_iter().enumerate() {
        assert!(
            published(&sample(&mut edge, &vars(count, 20.0, "abc"), 2_000 + k as u64)).is_empty()
        );
    }
    assert_eq!(edge.stored(), 3);
    edge.will();
    let out = published(&edge.connected(3_000));
    let topics: Vec<&str> = out.iter().map(|(t, _)| t.as_str()).collect();
    assert_eq!(topics[..2], ["spBv1.0/plant/NBIRTH/press7", "spBv1.0/plant/DBIRTH/press7/main"]);
    let history: Vec<&Payload> = out[2..].iter().map(|(_, p)| p).collect();
    let values: Vec<_> = history.iter().map(|p| p.metrics[0].value.clone()).collect();
    assert_eq!(values, [Some(Wire::IntValue(7)), Some(Wire::IntValue(8)), Some(Wire::IntValue(9))]);
    assert!(history.iter().all(|p| p.metrics[0].is_historical == Some(true)));
    let stamps: Vec<_> = history.iter().map(|p| p.timestamp.unwrap()).collect();
    assert_eq!(stamps, [2_000, 2_001, 2_002], "stamped when they changed");
    let seqs: Vec<_> = out.iter().map(|(_, p)| p.seq.unwrap()).collect();
    assert_eq!(seqs, [0, 1, 2, 3, 4], "seq goes on from the births");
    assert_eq!(edge.stored(), 0);
}

#[test]
fn the_store_is_bounded_and_drops_the_oldest() {
    let mut edge = Edge::new(settings(None, 2), plan());
    sample(&mut edge, &vars(0, 20.0, ""), 0);
    edge.will();
    edge.connected(1);
    edge.disconnected();
    for count in 1..=5 {
        sample(&mut edge, &vars(count, 20.0, ""), count as u64);
    }
    assert_eq!(edge.stored(), 2);
    assert_eq!((edge.counters.stored, edge.counters.dropped), (5, 3));
    edge.will();
    let out = published(&edge.connected(10));
    let values: Vec<_> = out[2..].iter().map(|(_, p)| p.metrics[0].value.clone()).collect();
    assert_eq!(values, [Some(Wire::IntValue(4)), Some(Wire::IntValue(5))], "the newest kept");
}

fn command(edge: &mut Edge, topic: &str, metrics: Vec<WireMetric>) -> Vec<Action> {
    let payload = Payload { timestamp: Some(9), metrics, seq: Some(0), ..Payload::default() };
    edge.message(topic, &payload.encode_to_vec(), 5_000)
}

fn by_alias(alias: u64, value: Wire) -> WireMetric {
    WireMetric { alias: Some(alias), value: Some(value), ..WireMetric::default() }
}

fn by_name(name: &str, value: Wire) -> WireMetric {
    WireMetric { name: Some(name.into()), value: Some(value), ..WireMetric::default() }
}

const DCMD: &str = "spBv1.0/plant/DCMD/press7/main";
const NCMD: &str = "spBv1.0/plant/NCMD/press7";

#[test]
fn a_write_of_a_writable_metric_becomes_one_set() {
    let mut edge = born();
    let alias = edge.plan().devices[0].metrics[0].alias;
    let actions = command(&mut edge, DCMD, vec![by_alias(alias, Wire::IntValue((-3i32) as u32))]);
    let [Action::Set { writes, metrics }] = actions.as_slice() else { panic!("{actions:?}") };
    assert_eq!(writes, &[NamedValue::write("main.count", plcd_ipc::Value::Text("-3".into()))]);
    assert_eq!(metrics, &[MetricRef { device: Some(0), index: 0 }]);
    // By name too.
    let actions = command(&mut edge, DCMD, vec![by_name("count", Wire::IntValue(4))]);
    assert!(matches!(actions.as_slice(), [Action::Set { .. }]), "{actions:?}");
}

#[test]
fn a_write_of_a_read_only_unknown_or_mistyped_metric_is_refused_and_its_value_sent_again() {
    let mut edge = born();
    let temp = edge.plan().devices[0].metrics[1].alias;
    let count = edge.plan().devices[0].metrics[0].alias;
    let actions = command(&mut edge, DCMD, vec![by_alias(temp, Wire::FloatValue(99.0))]);
    let data = published(&actions);
    assert!(!actions.iter().any(|a| matches!(a, Action::Set { .. })), "read-only");
    assert_eq!(data.len(), 1, "{actions:?}");
    assert_eq!(data[0].1.metrics[0].value, Some(Wire::FloatValue(20.0)), "what the PLC holds");
    let actions = command(&mut edge, DCMD, vec![by_alias(count, Wire::StringValue("x".into()))]);
    assert!(!actions.iter().any(|a| matches!(a, Action::Set { .. })), "a string to an INT");
    let actions = command(&mut edge, DCMD, vec![by_alias(count, Wire::IntValue(70_000))]);
    assert!(!actions.iter().any(|a| matches!(a, Action::Set { .. })), "beyond an INT");
    assert!(command(&mut edge, DCMD, vec![by_alias(999, Wire::IntValue(1))]).is_empty(), "unknown");
    assert!(
        command(&mut edge, "spBv1.0/plant/DCMD/press7/nope", vec![]).is_empty(),
        "no such device"
    );
    assert_eq!(edge.counters.refused, 5);
    assert!(edge.message(DCMD, b"\xff\xff\xff", 1).is_empty());
    assert_eq!(edge.counters.malformed, 1);
}

#[test]
fn the_request_handler_s_refusal_sends_the_value_again() {
    let mut edge = born();
    let actions = edge.refused(&[MetricRef { device: Some(0), index: 0 }], 7);
    let data = published(&actions);
    assert_eq!(data[0].0, "spBv1.0/plant/DDATA/press7/main");
    assert_eq!(data[0].1.metrics[0].value, Some(Wire::IntValue(5)));
}

#[test]
fn rebirth_sends_every_birth_again_with_seq_from_0_and_the_same_bd_seq() {
    let mut edge = born();
    sample(&mut edge, &vars(42, 20.0, "abc"), 2);
    let rebirth = edge.plan().node.iter().find(|m| m.source == Source::Rebirth).unwrap().alias;
    let out =
        published(&command(&mut edge, NCMD, vec![by_alias(rebirth, Wire::BooleanValue(true))]));
    assert_eq!(out.len(), 2);
    assert_eq!(out[0].1.seq, Some(0));
    assert_eq!(metric_named(&out[0].1, "bdSeq").value, Some(Wire::LongValue(0)));
    assert_eq!(metric_named(&out[1].1, "count").value, Some(Wire::IntValue(42)), "current values");
    let none = command(&mut edge, NCMD, vec![by_alias(rebirth, Wire::BooleanValue(false))]);
    assert!(none.is_empty(), "false asks nothing");
}

#[test]
fn next_server_and_scan_rate() {
    let mut edge = born();
    let next = edge.plan().node.iter().find(|m| m.source == Source::NextServer).unwrap().alias;
    let actions = command(&mut edge, NCMD, vec![by_alias(next, Wire::BooleanValue(true))]);
    let [Action::NextServer(death)] = actions.as_slice() else { panic!("{actions:?}") };
    assert_eq!(death.topic, "spBv1.0/plant/NDEATH/press7");
    let rate = edge.plan().node.iter().find(|m| m.source == Source::ScanRate).unwrap().alias;
    let actions = command(&mut edge, NCMD, vec![by_alias(rate, Wire::LongValue(250))]);
    assert!(actions.contains(&Action::ScanRate(250)), "{actions:?}");
    assert_eq!(edge.scan_rate_ms(), 250);
    let actions = command(&mut edge, NCMD, vec![by_alias(rate, Wire::LongValue(5))]);
    assert!(!actions.iter().any(|a| matches!(a, Action::ScanRate(_))), "below 10 ms");
    assert_eq!(edge.scan_rate_ms(), 250);
}

#[test]
fn with_a_primary_host_births_wait_for_it_online_and_its_going_moves_on() {
    let mut edge = Edge::new(settings(Some("scada"), 100), plan());
    sample(&mut edge, &vars(1, 20.0, ""), 0);
    edge.will();
    assert!(edge.connected(1).is_empty(), "no birth before the host's STATE");
    let state = "spBv1.0/STATE/scada";
    assert!(edge
        .message("spBv1.0/STATE/other", br#"{"online": true, "timestamp": 1}"#, 2)
        .is_empty());
    let births = published(&edge.message(state, br#"{"online": true, "timestamp": 1}"#, 2));
    assert_eq!(births.len(), 2);
    assert!(edge.is_born());
    let actions = edge.message(state, br#"{"online": false, "timestamp": 3}"#, 3);
    assert!(matches!(actions.as_slice(), [Action::NextServer(_)]), "{actions:?}");
    assert!(!edge.is_born());
    assert_eq!(host_online(b"ONLINE"), Some(true), "Sparkplug 2.2's form");
    assert_eq!(host_online(b"nonsense"), None);
}

#[test]
fn a_new_project_kills_the_devices_it_drops_and_is_born_again() {
    let mut edge = born();
    let mut new = plan();
    new.devices[0].name = "cell".into();
    let out = published(&edge.replan(new, 9));
    let topics: Vec<&str> = out.iter().map(|(t, _)| t.as_str()).collect();
    assert_eq!(
        topics,
        [
            "spBv1.0/plant/DDEATH/press7/main",
            "spBv1.0/plant/NBIRTH/press7",
            "spBv1.0/plant/DBIRTH/press7/cell"
        ]
    );
}

/// A backlog in memory, for the tests.
#[derive(Default)]
struct Overflow(VecDeque<Stored>);

impl Backlog for Overflow {
    fn push(&mut self, stored: Stored) -> u64 {
        self.0.push_back(stored);
        0
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

#[test]
fn what_the_memory_has_no_room_for_overflows_and_goes_first() {
    let mut edge = Edge::new(settings(None, 2), plan());
    edge.set_overflow(Box::<Overflow>::default());
    sample(&mut edge, &vars(0, 20.0, ""), 0);
    edge.will();
    edge.connected(1);
    edge.disconnected();
    for count in 1..=5 {
        sample(&mut edge, &vars(count, 20.0, ""), count as u64);
    }
    assert_eq!((edge.stored(), edge.counters.dropped), (5, 0), "none lost");
    edge.will();
    let out = published(&edge.connected(10));
    let values: Vec<_> = out[2..].iter().map(|(_, p)| p.metrics[0].value.clone()).collect();
    let expected: Vec<_> = (1..=5).map(|v| Some(Wire::IntValue(v))).collect();
    assert_eq!(values, expected, "the overflow's (older) first, then the memory's");
    assert_eq!(edge.stored(), 0);
    // A new project: what is stored is dropped, overflow too.
    edge.disconnected();
    for count in 6..=9 {
        sample(&mut edge, &vars(count, 20.0, ""), count as u64);
    }
    edge.replan(plan(), 20);
    assert_eq!((edge.stored(), edge.counters.dropped), (0, 4));
}

fn remote(state: &str, requests: u64) -> RemoteState {
    RemoteState { state: state.into(), requests, failures: 0, losses: u64::from(state == "lost") }
}

#[test]
fn a_lost_remote_device_dies_and_is_born_again_when_it_is_back() {
    let mut edge = Edge::new(settings(None, 100), plan().with_remotes(&["rack".into()]));
    assert!(edge.remotes(vec![remote("online", 1)], 0).is_empty());
    sample(&mut edge, &vars(5, 20.0, "abc"), 1);
    edge.will();
    let births = published(&edge.connected(2));
    let topics: Vec<&str> = births.iter().map(|(t, _)| t.as_str()).collect();
    assert_eq!(topics[2], "spBv1.0/plant/DBIRTH/press7/remote-rack");
    assert_eq!(metric_named(&births[2].1, "State").value, Some(Wire::StringValue("online".into())));
    let death = published(&edge.remotes(vec![remote("lost", 9)], 3));
    assert_eq!(death.len(), 1);
    assert_eq!(death[0].0, "spBv1.0/plant/DDEATH/press7/remote-rack");
    assert!(death[0].1.seq.is_some(), "a DDEATH has a seq");
    let data = published(&sample(&mut edge, &vars(6, 20.0, "abc"), 4));
    assert!(data.iter().all(|(t, _)| !t.contains("remote-rack")), "nothing from a dead device");
    // Born again while it is lost: no DBIRTH for it.
    edge.disconnected();
    edge.will();
    let births = published(&edge.connected(5));
    assert!(births.iter().all(|(t, _)| !t.contains("remote-rack")), "{births:?}");
    let back = published(&edge.remotes(vec![remote("online", 20)], 6));
    assert_eq!(back.len(), 1);
    assert_eq!(back[0].0, "spBv1.0/plant/DBIRTH/press7/remote-rack");
    assert_eq!(metric_named(&back[0].1, "Requests").value, Some(Wire::LongValue(20)));
    assert_eq!(metric_named(&back[0].1, "Losses").value, Some(Wire::LongValue(0)));
}

/// Found by the `mqtt` fuzz target: a refused write to a lost remote device's metric sent its
/// value again in a DDATA after the device's DDEATH.
#[test]
fn a_command_to_a_lost_remote_device_sends_nothing_of_it() {
    let mut edge = Edge::new(settings(None, 100), plan().with_remotes(&["rack".into()]));
    edge.remotes(vec![remote("online", 1)], 0);
    sample(&mut edge, &vars(5, 20.0, "abc"), 1);
    edge.will();
    edge.connected(2);
    let death = published(&edge.remotes(vec![remote("lost", 9)], 3));
    assert_eq!(death[0].0, "spBv1.0/plant/DDEATH/press7/remote-rack");
    let dcmd = "spBv1.0/plant/DCMD/press7/remote-rack";
    let actions = command(&mut edge, dcmd, vec![by_name("State", Wire::StringValue("on".into()))]);
    assert!(actions.is_empty(), "nothing of a dead device: {actions:?}");
    assert_eq!(edge.counters.refused, 1, "refused all the same");
}

/// Found by the `mqtt` fuzz target: what an outage stored of a remote device that was lost by
/// the next births went out after them, a DDATA of a device without its DBIRTH.
#[test]
fn what_was_stored_of_a_remote_device_lost_since_is_not_sent() {
    let mut edge = Edge::new(settings(None, 100), plan().with_remotes(&["rack".into()]));
    edge.remotes(vec![remote("online", 1)], 0);
    sample(&mut edge, &vars(5, 20.0, "abc"), 1);
    edge.will();
    edge.connected(2);
    edge.disconnected();
    edge.remotes(vec![remote("online", 2)], 3);
    sample(&mut edge, &vars(5, 20.0, "abc"), 3);
    assert_eq!(edge.stored(), 1, "the rack's requests");
    edge.remotes(vec![remote("lost", 2)], 4);
    sample(&mut edge, &vars(5, 20.0, "abc"), 4);
    edge.will();
    let out = published(&edge.connected(5));
    let topics: Vec<&str> = out.iter().map(|(t, _)| t.as_str()).collect();
    assert_eq!(topics, ["spBv1.0/plant/NBIRTH/press7", "spBv1.0/plant/DBIRTH/press7/main"]);
    assert_eq!(edge.counters.dropped, 1);
}
