//! Writes the seeds of the `mqtt` fuzz target (`tests/fuzz/corpus/mqtt/`), each file named by
//! what it holds (`tests/fuzz/run --keep` names the files of the corpus it minimises by their
//! SHA-1 instead):
//!
//!     cargo run -p plcd-fuzz --example mqtt-seeds -- tests/fuzz/corpus/mqtt
//!
//! Commands as a host application sends them (Sparkplug B payloads encoded with the schema's
//! types, by alias and by name as the target's births give them), written with the target's
//! own encoding of steps (`targets::mqtt::step`), so that they stay valid when the target's
//! project changes: run it again then.

use std::path::Path;

use plcd::services::mqtt::metrics::{self, DataType, Metric, Plan, Source};
use plcd::services::mqtt::sparkplug_b::payload::metric::Value as Wire;
use plcd::services::mqtt::sparkplug_b::payload::Metric as WireMetric;
use plcd::services::mqtt::sparkplug_b::Payload;
use plcd::value::ValueType;
use plcd_fuzz::targets::mqtt::{fixture, step, COPY, OVERFLOW, RECONNECT, REFUSE};
use prost::Message as _;

// The topics of `op & 7` (targets::mqtt::TOPICS).
const NCMD: u8 = 0;
const DCMD_FIRST: u8 = 1;
const DCMD_SECOND: u8 = 2;
const DCMD_REMOTE: u8 = 3;
const DCMD_NOPE: u8 = 4;
const STATE: u8 = 5;
const STATE_OTHER: u8 = 6;
const NONE: u8 = 7;

// A copy's status byte: the remote I/O device online or lost (targets::mqtt::REMOTE_STATES).
const ONLINE: u8 = 1 << 3;
const LOST: u8 = 2 << 3;

fn payload(metrics: Vec<WireMetric>) -> Vec<u8> {
    Payload { timestamp: Some(1_700_000_000_000), metrics, seq: Some(0), ..Payload::default() }
        .encode_to_vec()
}

fn by_alias(m: &Metric, value: Wire) -> WireMetric {
    WireMetric { alias: Some(m.alias), value: Some(value), ..WireMetric::default() }
}

fn by_name(m: &Metric, value: Wire) -> WireMetric {
    WireMetric {
        name: Some(m.name.clone()),
        datatype: Some(m.datatype.code()),
        value: Some(value),
        ..WireMetric::default()
    }
}

/// The metric called `name` of the node (`None`) or of device `device`.
fn named<'p>(plan: &'p Plan, device: Option<usize>, name: &str) -> &'p Metric {
    let metrics = match device {
        None => &plan.node,
        Some(d) => &plan.devices[d].metrics,
    };
    metrics.iter().find(|m| m.name == name).unwrap_or_else(|| panic!("no metric {name}"))
}

/// A value of `m`'s type, as a host application writes it: the slot 1 published (a string
/// `hi`, a `CHAR` `x`).
fn value_of(m: &Metric) -> Wire {
    let Source::Variable { ty, .. } = &m.source else { return Wire::BooleanValue(true) };
    match ty {
        ValueType::String { .. } | ValueType::WString { .. } => Wire::StringValue("hi".into()),
        ValueType::Char | ValueType::WChar => Wire::StringValue("x".into()),
        ValueType::Enum { values, .. } => {
            let v = values.last().map_or(0, |(_, v)| *v);
            metrics::wire(m.datatype, &metrics::slot_value(ty, v as u64))
        }
        _ => metrics::wire(m.datatype, &metrics::slot_value(ty, 1)),
    }
}

fn seeds() -> Vec<(&'static str, Vec<u8>)> {
    let f = fixture();
    let [plan, listed] = &f.plans;
    let mut seeds = Vec::new();
    let mut seed = |name: &'static str, which: u8, build: &dyn Fn(&mut Vec<u8>)| {
        let mut input = vec![which];
        build(&mut input);
        seeds.push((name, input));
    };
    let rebirth = named(plan, None, "Node Control/Rebirth");
    let rate = named(plan, None, "Node Control/Scan Rate");
    let next = named(plan, None, "Node Control/Next Server");
    let online = br#"{"online": true, "timestamp": 1700000000000}"#;
    let offline = br#"{"online": false, "timestamp": 1700000000001}"#;

    // A rebirth by alias, then one by name.
    seed("ncmd-rebirth", 0, &|i| {
        step(i, NCMD, &payload(vec![by_alias(rebirth, Wire::BooleanValue(true))]), None);
        step(i, NCMD, &payload(vec![by_name(rebirth, Wire::BooleanValue(true))]), None);
    });
    // A scan rate by name, one too small by alias, then copies.
    seed("ncmd-scan-rate", 0, &|i| {
        step(i, NCMD | COPY, &payload(vec![by_name(rate, Wire::LongValue(250))]), None);
        step(i, NCMD, &payload(vec![by_alias(rate, Wire::LongValue(5))]), None);
        step(i, NONE | COPY, &[], Some((0, &[1, 2, 3, 4, 5, 6, 7, 8], 0)));
    });
    // The next server, then the primary host online again.
    seed("ncmd-next-server", 0, &|i| {
        step(i, NCMD, &payload(vec![by_alias(next, Wire::BooleanValue(true))]), None);
        step(i, STATE, online, None);
    });
    // Every writable metric of device `main` written by alias, the request handler taking
    // them; then refusing them, and a copy after.
    let every = [
        ("dcmd-every-type-by-alias", DCMD_FIRST),
        ("dcmd-every-type-refused", DCMD_FIRST | REFUSE | COPY),
    ];
    for (name, op) in every {
        let writes = plan.devices[0].metrics.iter().map(|m| by_alias(m, value_of(m))).collect();
        let command = payload(writes);
        seed(name, 0, &|i| step(i, op, &command, Some((4, &[0xFF; 16], 1))));
    }
    // By name, with values a host application may send otherwise: an Int8 sign-extended to
    // 32 bits, a string too long, an INT out of range, a string to a number.
    let main = Some(0);
    let s8 = named(plan, main, "s8");
    let s = named(plan, main, "s");
    let i16 = named(plan, main, "i16");
    let pos = named(plan, main, "axis/pos");
    let odd = payload(vec![
        by_name(s8, Wire::IntValue(0xFFFF_FFFF)),
        by_name(s, Wire::StringValue("a string longer than twelve".into())),
        by_name(i16, Wire::IntValue(70_000)),
        by_name(pos, Wire::StringValue("1.5".into())),
        by_name(named(plan, main, "ro"), Wire::IntValue(1)),
    ]);
    seed("dcmd-odd-values-by-name", 0, &|i| step(i, DCMD_FIRST | REFUSE, &odd, None));
    // The device ranges, node metrics: a word and a bit, and a read-only word.
    let ranges = payload(vec![
        by_name(named(plan, None, "Devices/D00100"), Wire::IntValue(0xFFFF)),
        by_alias(named(plan, None, "Devices/M0003"), Wire::BooleanValue(true)),
        by_alias(named(plan, None, "Devices/D00201"), Wire::IntValue(3)),
    ]);
    seed("ncmd-device-ranges", 0, &|i| step(i, NCMD | COPY, &ranges, Some((0, &[], 2))));
    // The read-only device `cell` written by alias.
    let count = named(plan, Some(1), "count");
    seed("dcmd-read-only-device", 0, &|i| {
        step(i, DCMD_SECOND, &payload(vec![by_alias(count, Wire::IntValue(9))]), None)
    });
    // The primary host: offline and online in Sparkplug 3.0's JSON and 2.2's words, another
    // host, a STATE that is neither.
    seed("state", 0, &|i| {
        step(i, STATE, offline, None);
        step(i, NONE | COPY, &[], Some((8, &[9; 8], 0)));
        step(i, STATE, online, None);
        step(i, STATE, b"OFFLINE", None);
        step(i, STATE, b"ONLINE", None);
        step(i, STATE_OTHER, offline, None);
        step(i, STATE, b"{\"online\": 1}", None);
    });
    // The connection lost: copies stored, then sent after the births as history.
    seed("connection-lost-history", 0, &|i| {
        step(i, NONE | RECONNECT | COPY, &[], Some((0, &[1; 8], 0)));
        step(i, NONE | COPY, &[], Some((0, &[2; 8], 3)));
        step(i, NONE | RECONNECT, &[], None);
        step(i, STATE, online, None);
        step(i, NONE | COPY, &[], Some((0, &[3; 8], 0)));
    });
    // Garbage: a payload that is no Sparkplug message, on every topic; a command to no
    // device.
    seed("garbage", 0, &|i| {
        for op in [NCMD, DCMD_FIRST, DCMD_REMOTE, DCMD_NOPE, STATE] {
            step(i, op, b"\xff\xff\xff\x12\x05garbage", None);
        }
        step(i, DCMD_NOPE, &payload(vec![by_alias(rebirth, Wire::BooleanValue(true))]), None);
    });
    // The devices of `[[mqtt.devices]]`: names of levels, by name and by alias.
    let press = Some(0);
    let writes = payload(vec![
        by_name(named(listed, press, "main/axis/pos"), Wire::FloatValue(2.5)),
        by_name(named(listed, press, "main/color"), Wire::IntValue(7)),
        by_alias(named(listed, press, "main/ldt1"), Wire::LongValue(1_700_000_000_123)),
        by_alias(named(listed, press, "main/s"), Wire::StringValue("ok".into())),
    ]);
    seed("devices-dcmd-by-name-and-alias", 1, &|i| {
        step(i, DCMD_FIRST | COPY, &writes, Some((0, &[0x41; 12], 0)))
    });
    let all = 1;
    let writes =
        listed.devices[all].metrics.iter().map(|m| by_name(m, value_of(m))).collect::<Vec<_>>();
    let writes = payload(writes);
    seed("devices-dcmd-every-type-by-name", 1, &|i| step(i, DCMD_SECOND | REFUSE, &writes, None));
    // A type mismatch of every kind written to `main.lr` (an LREAL) and `main.ldt1`.
    let lr = named(plan, main, "lr");
    let kinds = [
        Wire::IntValue(1),
        Wire::LongValue(u64::MAX),
        Wire::FloatValue(f32::NAN),
        Wire::DoubleValue(-0.0),
        Wire::BooleanValue(false),
        Wire::StringValue("NaN".into()),
        Wire::BytesValue(vec![1, 2]),
    ];
    let mixed = kinds.iter().map(|v| by_alias(lr, v.clone())).collect();
    let mixed = payload(mixed);
    seed("dcmd-every-wire-kind", 0, &|i| step(i, DCMD_FIRST, &mixed, None));
    // The remote I/O device lost (its DDEATH), written to while lost, then back (its
    // DBIRTH); a rebirth while it is lost.
    let remote = Some(plan.devices.len() - 1);
    let state = named(plan, remote, "State");
    let requests = named(plan, remote, "Requests");
    seed("remote-lost-and-back", 0, &|i| {
        step(i, NONE | COPY, &[], Some((0, &[], LOST)));
        step(
            i,
            DCMD_REMOTE,
            &payload(vec![by_name(state, Wire::StringValue("online".into()))]),
            None,
        );
        step(i, NCMD, &payload(vec![by_alias(rebirth, Wire::BooleanValue(true))]), None);
        step(i, NONE | COPY, &[], Some((0, &[7; 4], ONLINE | 3)));
        step(i, DCMD_REMOTE, &payload(vec![by_alias(requests, Wire::LongValue(1))]), None);
    });
    // The store's overflow: more copies during an outage than the memory holds (4) and the
    // backlog (3), then the births and the history, the backlog's first.
    seed("overflow", OVERFLOW, &|i| {
        step(i, NONE | RECONNECT, &[], None);
        for k in 1..=9u8 {
            step(i, NONE | COPY, &[], Some((0, &[k; 4], ONLINE)));
        }
        step(i, NONE | RECONNECT, &[], None);
        step(i, STATE, online, None);
    });
    let ldt = named(plan, main, "ldt1");
    assert_eq!(ldt.datatype, DataType::DateTime);
    seeds
}

fn main() {
    let dir = std::env::args().nth(1).expect("usage: mqtt-seeds DIR");
    let dir = Path::new(&dir);
    std::fs::create_dir_all(dir).expect("the directory");
    for (name, seed) in seeds() {
        std::fs::write(dir.join(name), &seed).expect("a seed");
        println!("{name}: {} bytes", seed.len());
    }
}
