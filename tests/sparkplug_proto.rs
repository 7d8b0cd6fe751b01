//! The Sparkplug B payload types decode what the specification's field numbers encode. That
//! they are what prost-build generates from `src/services/mqtt/sparkplug_b.proto` is checked by
//! the workspace member `tests/sparkplug` (`tests/sparkplug/tests/schema.rs`).

/// The field numbers of the specification's schema (Sparkplug 3.0, "Sparkplug B Payload
/// Definition"), written out here apart from the schema file: a payload encoded with them
/// decodes into the generated types field for field.
#[cfg(feature = "mqtt")]
#[test]
fn the_field_numbers_are_the_specification_s() {
    use plcd::services::mqtt::sparkplug_b::payload::{metric, Metric};
    use plcd::services::mqtt::sparkplug_b::Payload;
    use prost::Message;
    // Payload: timestamp 1, metrics 2, seq 3. Metric: name 1, alias 2, timestamp 3, datatype 4,
    // is_historical 5, int_value 10, double_value 13, string_value 15.
    let key = |field: u8, wire: u8| (field << 3) | wire;
    let mut metric_bytes = vec![key(1, 2), 1, b'x', key(2, 0), 7, key(3, 0), 9, key(4, 0), 3];
    metric_bytes.extend([key(5, 0), 1, key(10, 0), 42]);
    let mut bytes = vec![key(1, 0), 5, key(2, 2), metric_bytes.len() as u8];
    bytes.extend(&metric_bytes);
    bytes.extend([key(3, 0), 200, 1]);
    let payload = Payload::decode(&bytes[..]).unwrap();
    assert_eq!((payload.timestamp, payload.seq), (Some(5), Some(200)));
    let expected = Metric {
        name: Some("x".into()),
        alias: Some(7),
        timestamp: Some(9),
        datatype: Some(3),
        is_historical: Some(true),
        value: Some(metric::Value::IntValue(42)),
        ..Metric::default()
    };
    assert_eq!(payload.metrics, [expected]);
    let double = [key(13, 1), 0, 0, 0, 0, 0, 0, 0xF8, 0x3F];
    let m = Metric::decode(&double[..]).unwrap();
    assert_eq!(m.value, Some(metric::Value::DoubleValue(1.5)));
    let text = [key(15, 2), 2, b'o', b'k'];
    assert_eq!(
        Metric::decode(&text[..]).unwrap().value,
        Some(metric::Value::StringValue("ok".into()))
    );
}
