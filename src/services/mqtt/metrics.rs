//! The metrics of the edge node and of its devices (docs/MQTT.md, "Devices and metrics"):
//! which variable or status figure each metric is, its name, alias and Sparkplug data type,
//! which are writable; and IEC values as Sparkplug values, both ways — read out of a mirror's
//! copies of device and variable memory, and a host application's write turned into the text
//! `plcctl set` takes, so that every rule of `set` is decided by the request handler alone.

use std::collections::HashMap;

use super::sparkplug_b::payload::metric::Value as Wire;
use crate::config::{EuRange, MqttConfig, OpcuaDevices};
use crate::duration::ms_to_ns;
use crate::project::MqttNames;
use crate::symbols::{device_words_end, name_parts, Symbols};
use crate::value::{self, Elem, Pointer, Space, ValueType};
use crate::vm::Vm;

/// A Sparkplug B data type (the specification's numbers) of the types plcd publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataType {
    Int8 = 1,
    Int16 = 2,
    Int32 = 3,
    Int64 = 4,
    UInt8 = 5,
    UInt16 = 6,
    UInt32 = 7,
    UInt64 = 8,
    Float = 9,
    Double = 10,
    Boolean = 11,
    String = 12,
    DateTime = 13,
}

impl DataType {
    /// The number the payload carries.
    pub fn code(self) -> u32 {
        self as u32
    }

    /// The type a variable of `ty` is published as; `None`: not published (references).
    pub fn of(ty: &ValueType) -> Option<DataType> {
        Some(match ty {
            ValueType::Bool => DataType::Boolean,
            ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => elem_type(*e),
            ValueType::Enum { base, .. } => elem_type(*base),
            ValueType::Time => DataType::Double,
            ValueType::Calendar(calendar) => match calendar.kind() {
                value::CalendarKind::Tod => DataType::Double,
                value::CalendarKind::Date | value::CalendarKind::Dt => DataType::DateTime,
            },
            ValueType::Char | ValueType::WChar => DataType::String,
            ValueType::String { .. } | ValueType::WString { .. } => DataType::String,
            ValueType::Reference { .. } => return None,
        })
    }
}

fn elem_type(elem: Elem) -> DataType {
    match elem {
        Elem::Bool => DataType::Boolean,
        Elem::I8 => DataType::Int8,
        Elem::I16 => DataType::Int16,
        Elem::I32 => DataType::Int32,
        Elem::I64 => DataType::Int64,
        Elem::U8 => DataType::UInt8,
        Elem::U16 => DataType::UInt16,
        Elem::U32 => DataType::UInt32,
        Elem::U64 => DataType::UInt64,
        Elem::F32 => DataType::Float,
        Elem::F64 => DataType::Double,
    }
}

/// What a metric publishes.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A Structured Text variable (`name` its full name, as `plcctl get` names it) or, with
    /// `device`, a device of `[[mqtt.ranges]]` (`name` its address), read out of the copies.
    Variable { name: String, ty: ValueType, at: Pointer, device: bool },
    /// The session's `bdSeq`.
    BdSeq,
    /// `Node Control/Rebirth`.
    Rebirth,
    /// `Node Control/Next Server`.
    NextServer,
    /// `Node Control/Scan Rate`: the sampling interval, ms.
    ScanRate,
    /// `Status/Mode`.
    Mode,
    /// `Status/Error`.
    Error,
    /// `Status/Scans`.
    Scans,
    /// `Status/Scan Time`: the last scan, ms.
    ScanTime,
    /// A figure of remote I/O device `index` (of `[[remote]]`, in config order).
    Remote { index: usize, field: RemoteField },
}

/// The figures of a remote I/O device its Sparkplug device publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RemoteField {
    /// `starting`, `online`, `lost`.
    State,
    Requests,
    Failures,
    Losses,
}

/// The metrics of a remote I/O device's Sparkplug device, in alias order.
const REMOTE_METRICS: [(&str, DataType, RemoteField); 4] = [
    ("State", DataType::String, RemoteField::State),
    ("Requests", DataType::UInt64, RemoteField::Requests),
    ("Failures", DataType::UInt64, RemoteField::Failures),
    ("Losses", DataType::UInt64, RemoteField::Losses),
];

/// The Sparkplug device of remote I/O device `name`: `remote-NAME`.
pub fn remote_device(name: &str) -> String {
    format!("remote-{name}")
}

/// One metric.
#[derive(Debug, Clone, PartialEq)]
pub struct Metric {
    pub name: String,
    pub alias: u64,
    pub datatype: DataType,
    pub source: Source,
    /// A command may write it.
    pub writable: bool,
    /// A number's change smaller than this is not published (0: every change).
    pub deadband: f64,
    /// The engineering range `[[opcua.analog]]` gives the variable: its birth carries it as
    /// the properties `engLow` and `engHigh`.
    pub range: Option<EuRange>,
}

/// A Sparkplug device: a program instance or a `[[mqtt.devices]]` entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Device {
    pub name: String,
    pub metrics: Vec<Metric>,
    /// A remote I/O device's (its index in `[[remote]]`): it dies while the device is lost.
    pub remote: Option<usize>,
}

/// The metrics of a project.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Plan {
    /// The edge node's own: `bdSeq`, node control, status, device ranges.
    pub node: Vec<Metric>,
    pub devices: Vec<Device>,
    /// Variables left out past `max_metrics`.
    pub left_out: usize,
    /// Variables not published: references, and located variables past the copied words.
    pub unserved: usize,
}

/// The node metrics before the device ranges, in alias order.
const NODE_METRICS: [(&str, DataType, Source, bool); 8] = [
    ("bdSeq", DataType::Int64, Source::BdSeq, false),
    ("Node Control/Rebirth", DataType::Boolean, Source::Rebirth, true),
    ("Node Control/Next Server", DataType::Boolean, Source::NextServer, true),
    ("Node Control/Scan Rate", DataType::Int64, Source::ScanRate, true),
    ("Status/Mode", DataType::String, Source::Mode, false),
    ("Status/Error", DataType::String, Source::Error, false),
    ("Status/Scans", DataType::UInt64, Source::Scans, false),
    ("Status/Scan Time", DataType::Double, Source::ScanTime, false),
];

impl Plan {
    /// The metrics of `symbols` for a node whose copies hold `words` device words: one device
    /// per program instance, or the devices `names` lists ([`crate::project::Project::mqtt_names`]);
    /// at most `config.max_metrics` variables.
    pub fn of(symbols: &Symbols, config: &MqttConfig, names: &MqttNames, words: u16) -> Plan {
        let mut plan = Plan::default();
        let mut alias = 0u64;
        let mut next = || {
            alias += 1;
            alias - 1
        };
        for (name, datatype, source, writable) in NODE_METRICS {
            let metric = Metric {
                name: name.into(),
                alias: next(),
                datatype,
                source,
                writable,
                deadband: 0.0,
                range: None,
            };
            plan.node.push(metric);
        }
        for range in &config.ranges {
            plan.node.extend(range_metrics(range, &mut next));
        }
        let max = config.max_metrics as usize;
        let mut count = 0usize;
        let mut add =
            |plan: &mut Plan, device: usize, metric_name: String, symbol: &value::Symbol| {
                let Some(datatype) = DataType::of(&symbol.ty) else {
                    plan.unserved += 1;
                    return;
                };
                if device_words_end(&symbol.ty, symbol.at).is_some_and(|end| end > words) {
                    plan.unserved += 1;
                    return;
                }
                if count >= max {
                    plan.left_out += 1;
                    return;
                }
                count += 1;
                plan.devices[device].metrics.push(Metric {
                    name: metric_name,
                    alias: next(),
                    datatype,
                    source: Source::Variable {
                        name: symbol.name.clone(),
                        ty: symbol.ty.clone(),
                        at: symbol.at,
                        device: false,
                    },
                    writable: names.writable.contains(&symbol.name),
                    deadband: names.deadbands.get(&symbol.name).copied().unwrap_or(0.0),
                    range: None,
                });
            };
        if names.devices.is_empty() {
            // One device per program instance, in declaration order.
            let mut devices: HashMap<String, usize> = HashMap::new();
            for symbol in symbols.iter() {
                let parts = name_parts(&symbol.name);
                let Some((instance, rest)) = parts.split_first() else { continue };
                if rest.is_empty() {
                    plan.unserved += 1;
                    continue;
                }
                let device = *devices.entry(instance.to_string()).or_insert_with(|| {
                    plan.devices.push(Device {
                        name: instance.to_string(),
                        metrics: Vec::new(),
                        remote: None,
                    });
                    plan.devices.len() - 1
                });
                add(&mut plan, device, rest.join("/"), &symbol);
            }
        } else {
            let by_name: HashMap<String, value::Symbol> =
                symbols.iter().map(|s| (s.name.clone(), s)).collect();
            for (name, variables) in &names.devices {
                plan.devices.push(Device { name: name.clone(), metrics: Vec::new(), remote: None });
                let device = plan.devices.len() - 1;
                for variable in variables {
                    if let Some(symbol) = by_name.get(variable) {
                        add(&mut plan, device, name_parts(variable).join("/"), symbol);
                    }
                }
            }
        }
        plan
    }

    /// The plan with the engineering ranges of `ranges` (variables by full name, as
    /// [`crate::project::Project::opcua_names`] gives those of `[[opcua.analog]]`) on their
    /// metrics.
    pub fn with_ranges(mut self, ranges: &std::collections::BTreeMap<String, EuRange>) -> Plan {
        for device in &mut self.devices {
            for metric in &mut device.metrics {
                if let Source::Variable { name, device: false, .. } = &metric.source {
                    metric.range = ranges.get(name).copied();
                }
            }
        }
        self
    }

    /// The plan with a Sparkplug device for each remote I/O device of `remotes` (the
    /// `[[remote]]` names, in config order) after the others: `remote-NAME`, with its state
    /// and counters, which dies while the device is lost.
    pub fn with_remotes(mut self, remotes: &[String]) -> Plan {
        let mut alias = self.all().map(|(_, m)| m.alias + 1).max().unwrap_or(0);
        for (index, name) in remotes.iter().enumerate() {
            let metrics = REMOTE_METRICS
                .iter()
                .map(|&(metric, datatype, field)| {
                    alias += 1;
                    Metric {
                        name: metric.into(),
                        alias: alias - 1,
                        datatype,
                        source: Source::Remote { index, field },
                        writable: false,
                        deadband: 0.0,
                        range: None,
                    }
                })
                .collect();
            self.devices.push(Device { name: remote_device(name), metrics, remote: Some(index) });
        }
        self
    }

    /// Every metric, the node's then each device's, with its device (`None`: the node).
    pub fn all(&self) -> impl Iterator<Item = (Option<usize>, &Metric)> {
        let node = self.node.iter().map(|m| (None, m));
        let devices = self
            .devices
            .iter()
            .enumerate()
            .flat_map(|(d, dev)| dev.metrics.iter().map(move |m| (Some(d), m)));
        node.chain(devices)
    }

    /// The metrics published.
    pub fn len(&self) -> usize {
        self.node.len() + self.devices.iter().map(|d| d.metrics.len()).sum::<usize>()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The byte ranges of variable memory the metrics are read from: what the scan thread
    /// copies for the node.
    pub fn variable_bytes(&self) -> crate::drivers::real_time::mirror::ServedBytes {
        let pieces = self.all().filter_map(|(_, metric)| match &metric.source {
            Source::Variable { ty, at, .. } if at.space == Space::Var => {
                Some((at.offset, ty.bytes()))
            }
            _ => None,
        });
        crate::drivers::real_time::mirror::byte_ranges(pieces, 64)
    }
}

/// The node metrics of one `[[mqtt.ranges]]` entry: `Devices/D00100` a word as an Int16, a
/// bit as a Boolean.
fn range_metrics(range: &OpcuaDevices, next: &mut impl FnMut() -> u64) -> Vec<Metric> {
    let mut metrics = Vec::new();
    for address in range.addresses() {
        let Some((ty, at)) = address.served() else { continue };
        let name = address.to_string();
        let datatype = DataType::of(&ty).unwrap_or(DataType::Int16);
        metrics.push(Metric {
            name: format!("Devices/{name}"),
            alias: next(),
            datatype,
            source: Source::Variable { name, ty, at, device: true },
            writable: range.writable,
            deadband: 0.0,
            range: None,
        });
    }
    metrics
}

/// A metric's value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Bool(bool),
    /// Int8 … Int64.
    Int(i64),
    /// UInt8 … UInt64.
    UInt(u64),
    Float(f32),
    Double(f64),
    Text(String),
    /// Milliseconds since 1970.
    DateTime(u64),
}

impl Value {
    /// As a number, for deadbands.
    fn number(&self) -> Option<f64> {
        match self {
            Value::Int(v) => Some(*v as f64),
            Value::UInt(v) => Some(*v as f64),
            Value::Float(v) => Some(f64::from(*v)),
            Value::Double(v) => Some(*v),
            _ => None,
        }
    }

    /// Whether `self`, the value last sent, and `new` differ enough to send `new`: any change
    /// (of the bits, for a REAL: a NaN that stays NaN is no change), by at least `deadband` for
    /// a number with one.
    pub fn changed(&self, new: &Value, deadband: f64) -> bool {
        match (self, new) {
            (Value::Float(a), Value::Float(b)) if a.to_bits() == b.to_bits() => false,
            (Value::Double(a), Value::Double(b)) if a.to_bits() == b.to_bits() => false,
            _ if deadband > 0.0 => match (self.number(), new.number()) {
                (Some(a), Some(b)) if a.is_finite() && b.is_finite() => (b - a).abs() >= deadband,
                _ => self != new,
            },
            _ => self != new,
        }
    }
}

/// The payload's value field of `value` for a metric of `datatype`: Int8 … Int32 and UInt8 …
/// UInt32 in the 32-bit field, the signed ones as the two's complement of their own width (an
/// Int8 -1 is 255, as Sparkplug 3.0 and its Python host library have it), Int64, UInt64 and
/// DateTime in the 64-bit one.
pub fn wire(datatype: DataType, value: &Value) -> Wire {
    let small = matches!(
        datatype,
        DataType::Int8
            | DataType::Int16
            | DataType::Int32
            | DataType::UInt8
            | DataType::UInt16
            | DataType::UInt32
    );
    match value {
        Value::Bool(b) => Wire::BooleanValue(*b),
        Value::Int(v) if datatype == DataType::Int8 => Wire::IntValue(u32::from(*v as u8)),
        Value::Int(v) if datatype == DataType::Int16 => Wire::IntValue(u32::from(*v as u16)),
        Value::Int(v) if small => Wire::IntValue(*v as i32 as u32),
        Value::Int(v) => Wire::LongValue(*v as u64),
        Value::UInt(v) if small => Wire::IntValue(*v as u32),
        Value::UInt(v) => Wire::LongValue(*v),
        Value::Float(v) => Wire::FloatValue(*v),
        Value::Double(v) => Wire::DoubleValue(*v),
        Value::Text(s) => Wire::StringValue(s.clone()),
        Value::DateTime(ms) => Wire::LongValue(*ms),
    }
}

/// The value of a variable of type `ty` at `at`, read out of copies of device memory (`words`,
/// from word 0) and variable memory (`vars`).
pub fn read(ty: &ValueType, at: Pointer, words: &[u16], vars: &[u8]) -> Value {
    match Vm::text_in(ty, vars, at) {
        Some(text) => Value::Text(text),
        None => slot_value(ty, Vm::read_value_in(words, vars, at, ty.elem())),
    }
}

/// A slot (as the VM stores a value of `ty`) as its metric value.
pub fn slot_value(ty: &ValueType, slot: u64) -> Value {
    match ty {
        ValueType::Bool => Value::Bool(slot != 0),
        ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => elem_value(*e, slot),
        ValueType::Enum { base, .. } => elem_value(*base, slot),
        // Nanoseconds, published in milliseconds.
        ValueType::Time => Value::Double(slot as i64 as f64 / 1e6),
        ValueType::Calendar(calendar) => {
            let long = calendar.is_long();
            match calendar.kind() {
                value::CalendarKind::Tod if long => Value::Double(slot as f64 / 1e6),
                value::CalendarKind::Tod => Value::Double(f64::from(slot as u32)),
                _ if long => Value::DateTime(slot / 1_000_000),
                _ => Value::DateTime(u64::from(slot as u32) * 1000),
            }
        }
        ValueType::Char => Value::Text(value::decode_byte(slot as u8).to_string()),
        ValueType::WChar => {
            let c = char::decode_utf16([slot as u16]).next().and_then(Result::ok);
            Value::Text(c.unwrap_or('\u{FFFD}').to_string())
        }
        ValueType::String { .. } | ValueType::WString { .. } | ValueType::Reference { .. } => {
            Value::Text(String::new())
        }
    }
}

fn elem_value(elem: Elem, slot: u64) -> Value {
    match elem {
        Elem::Bool => Value::Bool(slot != 0),
        Elem::I8 => Value::Int(i64::from(slot as i8)),
        Elem::I16 => Value::Int(i64::from(slot as i16)),
        Elem::I32 => Value::Int(i64::from(slot as i32)),
        Elem::I64 => Value::Int(slot as i64),
        Elem::U8 => Value::UInt(u64::from(slot as u8)),
        Elem::U16 => Value::UInt(u64::from(slot as u16)),
        Elem::U32 => Value::UInt(u64::from(slot as u32)),
        Elem::U64 => Value::UInt(slot),
        Elem::F32 => Value::Float(f32::from_bits(slot as u32)),
        Elem::F64 => Value::Double(f64::from_bits(slot)),
    }
}

/// Why a written metric value was not taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    #[error("no value, or a value of another data type than its birth gave ({0:?})")]
    TypeMismatch(DataType),
    #[error("{0} is out of range of the variable's type")]
    OutOfRange(String),
}

/// The value a host application writes to a variable of type `ty` (published as `datatype`),
/// as the text `plcctl set` takes for it (what `plcctl get` shows).
pub fn written(ty: &ValueType, datatype: DataType, wire: Option<&Wire>) -> Result<String, Refusal> {
    let wire = wire.ok_or(Refusal::TypeMismatch(datatype))?;
    let written = match wire {
        Wire::StringValue(text) => value::text_written(ty, text)
            .map(|written| written.map_err(|_| Refusal::OutOfRange(format!("{text:?}")))),
        _ => None,
    };
    match written {
        Some(text) => text,
        None => Ok(value::format(ty, wire_slot(ty, datatype, wire)?)),
    }
}

/// The slot (as the VM stores it) of a value written to a variable of type `ty`: the inverse
/// of [`slot_value`]. Integers are taken from either field, within the type's range; a signed
/// one in the 32-bit field as the two's complement of its own width (an Int8 -1 as 255) or, as
/// some hosts send it, of 32 bits.
fn wire_slot(ty: &ValueType, datatype: DataType, wire: &Wire) -> Result<u64, Refusal> {
    let mismatch = Refusal::TypeMismatch(datatype);
    let width = match ty {
        ValueType::Signed(e) | ValueType::Enum { base: e, .. } => e.size() * 8,
        _ => 32,
    };
    let integer = |signed: bool| -> Option<i128> {
        match (wire, signed) {
            (Wire::IntValue(v), true) if width < 32 && i128::from(*v) < (1i128 << width) => {
                let shift = 64 - width;
                Some(i128::from(((u64::from(*v) << shift) as i64) >> shift))
            }
            (Wire::IntValue(v), true) => Some(i128::from(*v as i32)),
            (Wire::IntValue(v), false) => Some(i128::from(*v)),
            (Wire::LongValue(v), true) => Some(i128::from(*v as i64)),
            (Wire::LongValue(v), false) => Some(i128::from(*v)),
            _ => None,
        }
    };
    let elem = match ty {
        ValueType::Bool => Elem::Bool,
        ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => *e,
        ValueType::Enum { base, .. } => *base,
        ValueType::Time => {
            let ms = double(wire).ok_or(mismatch)?;
            return ms_to_ns(ms).map(|ns| ns as u64).ok_or(Refusal::OutOfRange(ms.to_string()));
        }
        ValueType::Calendar(calendar) => {
            return calendar_slot(*calendar, wire).ok_or(mismatch)?;
        }
        _ => return Err(mismatch),
    };
    let slot = match elem {
        Elem::Bool => match wire {
            Wire::BooleanValue(b) => u64::from(*b),
            _ => return Err(mismatch),
        },
        Elem::F32 => match wire {
            Wire::FloatValue(v) => u64::from(v.to_bits()),
            _ => return Err(mismatch),
        },
        Elem::F64 => match wire {
            Wire::DoubleValue(v) => v.to_bits(),
            Wire::FloatValue(v) => f64::from(*v).to_bits(),
            _ => return Err(mismatch),
        },
        Elem::I8 | Elem::I16 | Elem::I32 | Elem::I64 => {
            let v = integer(true).ok_or(mismatch)?;
            let bits = elem.size() * 8;
            let (lo, hi) = (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1);
            if !(lo..=hi).contains(&v) {
                return Err(Refusal::OutOfRange(v.to_string()));
            }
            v as i64 as u64
        }
        Elem::U8 | Elem::U16 | Elem::U32 | Elem::U64 => {
            let v = integer(false).ok_or(mismatch)?;
            let bits = elem.size() * 8;
            if v >= (1i128 << bits) {
                return Err(Refusal::OutOfRange(v.to_string()));
            }
            v as u64
        }
    };
    Ok(slot)
}

fn double(wire: &Wire) -> Option<f64> {
    match wire {
        Wire::DoubleValue(v) => Some(*v),
        Wire::FloatValue(v) => Some(f64::from(*v)),
        _ => None,
    }
}

/// A calendar type's slot from its published form: milliseconds since midnight (a Double) for
/// `TOD`, milliseconds since 1970 (a DateTime) for the others. `None`: a value of another
/// field; `Some(Err)`: out of the type's range.
fn calendar_slot(calendar: value::Calendar, wire: &Wire) -> Option<Result<u64, Refusal>> {
    let long = calendar.is_long();
    Some(match calendar.kind() {
        value::CalendarKind::Tod => {
            let ms = double(wire)?;
            match ms_to_ns(ms).filter(|ns| (0..86_400_000_000_000).contains(ns)) {
                Some(ns) if long => Ok(ns as u64),
                Some(ns) => Ok((ns / 1_000_000) as u64),
                None => Err(Refusal::OutOfRange(ms.to_string())),
            }
        }
        value::CalendarKind::Date | value::CalendarKind::Dt => {
            let Wire::LongValue(ms) = wire else { return None };
            if long {
                ms.checked_mul(1_000_000).ok_or(Refusal::OutOfRange(ms.to_string()))
            } else {
                u32::try_from(ms / 1000)
                    .map(u64::from)
                    .map_err(|_| Refusal::OutOfRange(ms.to_string()))
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::Calendar;

    #[test]
    fn iec_types_have_their_sparkplug_types() {
        use ValueType as T;
        let cases = [
            (T::Bool, DataType::Boolean),
            (T::Signed(Elem::I8), DataType::Int8),
            (T::Signed(Elem::I16), DataType::Int16),
            (T::Signed(Elem::I32), DataType::Int32),
            (T::Signed(Elem::I64), DataType::Int64),
            (T::Unsigned(Elem::U8), DataType::UInt8),
            (T::Unsigned(Elem::U16), DataType::UInt16),
            (T::Unsigned(Elem::U32), DataType::UInt32),
            (T::Unsigned(Elem::U64), DataType::UInt64),
            (T::Real(Elem::F32), DataType::Float),
            (T::Real(Elem::F64), DataType::Double),
            (T::String { cap: 8 }, DataType::String),
            (T::WString { cap: 8 }, DataType::String),
            (T::Char, DataType::String),
            (T::Time, DataType::Double),
            (T::Calendar(Calendar::Tod), DataType::Double),
            (T::Calendar(Calendar::Dt), DataType::DateTime),
            (T::Calendar(Calendar::LDate), DataType::DateTime),
            (T::Enum { type_name: "E".into(), values: vec![], base: Elem::I32 }, DataType::Int32),
        ];
        for (ty, expected) in cases {
            assert_eq!(DataType::of(&ty), Some(expected), "{ty:?}");
        }
        assert_eq!(DataType::of(&T::Reference { type_name: "REF_TO INT".into() }), None);
        assert_eq!(DataType::Boolean.code(), 11, "the specification's numbers");
        assert_eq!(DataType::DateTime.code(), 13);
    }

    #[test]
    fn signed_values_travel_as_their_twos_complement() {
        let int = Value::Int(-1);
        assert_eq!(wire(DataType::Int8, &int), Wire::IntValue(0xFF), "its own width");
        assert_eq!(wire(DataType::Int16, &Value::Int(-2)), Wire::IntValue(0xFFFE));
        assert_eq!(
            wire(DataType::Int32, &Value::Int(i64::from(i32::MIN))),
            Wire::IntValue(0x8000_0000)
        );
        assert_eq!(wire(DataType::Int64, &int), Wire::LongValue(u64::MAX));
        assert_eq!(wire(DataType::UInt16, &Value::UInt(65_535)), Wire::IntValue(65_535));
        assert_eq!(wire(DataType::UInt64, &Value::UInt(u64::MAX)), Wire::LongValue(u64::MAX));
        assert_eq!(
            wire(DataType::DateTime, &Value::DateTime(86_400_000)),
            Wire::LongValue(86_400_000)
        );
    }

    #[test]
    fn slots_become_metric_values() {
        use ValueType as T;
        assert_eq!(slot_value(&T::Signed(Elem::I16), 0xFFFF), Value::Int(-1));
        assert_eq!(slot_value(&T::Time, 1_500_000_000), Value::Double(1500.0), "T#1s500ms in ms");
        assert_eq!(slot_value(&T::Calendar(Calendar::Dt), 86_400), Value::DateTime(86_400_000));
        assert_eq!(
            slot_value(&T::Calendar(Calendar::LDt), 86_400_000_000_000),
            Value::DateTime(86_400_000)
        );
        assert_eq!(
            slot_value(&T::Calendar(Calendar::Tod), 45_296_789),
            Value::Double(45_296_789.0)
        );
        assert_eq!(slot_value(&T::Char, u64::from(b'A')), Value::Text("A".into()));
    }

    /// Every type: a value published, written back, becomes the text `set` reads to the same slot.
    #[test]
    fn a_value_published_and_written_back_is_the_same_value() {
        use ValueType as T;
        let mode =
            T::Enum { type_name: "M".into(), values: vec![("RUN".into(), 5)], base: Elem::I32 };
        let cases: Vec<(ValueType, u64)> = vec![
            (T::Bool, 1),
            (T::Signed(Elem::I8), (-5i8) as u8 as u64),
            (T::Signed(Elem::I16), 0xFFFF),
            (T::Signed(Elem::I32), (-70_000i32) as u32 as u64),
            (T::Signed(Elem::I64), i64::MIN as u64),
            (T::Unsigned(Elem::U8), 200),
            (T::Unsigned(Elem::U16), 65_535),
            (T::Unsigned(Elem::U32), u64::from(u32::MAX)),
            (T::Unsigned(Elem::U64), u64::MAX),
            (T::Real(Elem::F32), u64::from(0.1f32.to_bits())),
            (T::Real(Elem::F64), (-1.0e-300f64).to_bits()),
            (T::Time, (-1_500_000_000i64) as u64),
            (T::Calendar(Calendar::Tod), 45_296_789),
            (T::Calendar(Calendar::LTod), 45_296_789_000_000),
            (T::Calendar(Calendar::Dt), 1_764_590_400),
            (T::Calendar(Calendar::Date), 1_764_547_200),
            (T::Calendar(Calendar::LDt), 1_764_590_400_123_000_000),
            (T::Char, u64::from(value::encode_char('ä').unwrap())),
            (T::WChar, u64::from('€' as u16)),
            (mode, 5),
        ];
        for (ty, slot) in cases {
            let datatype = DataType::of(&ty).unwrap();
            let wire = wire(datatype, &slot_value(&ty, slot));
            let text =
                written(&ty, datatype, Some(&wire)).unwrap_or_else(|e| panic!("{ty:?}: {e}"));
            let back = value::parse(&ty, &text).unwrap_or_else(|e| panic!("{ty:?}: {e}"));
            let same = |slot| value::normalize(ty.elem(), slot);
            assert_eq!(same(back), same(slot), "{ty:?}: {wire:?} written as {text}");
        }
    }

    #[test]
    fn a_write_of_another_type_or_out_of_range_is_refused() {
        use ValueType as T;
        let int = T::Signed(Elem::I16);
        let refused = written(&int, DataType::Int16, Some(&Wire::BooleanValue(true)));
        assert_eq!(refused, Err(Refusal::TypeMismatch(DataType::Int16)));
        assert_eq!(
            written(&int, DataType::Int16, None),
            Err(Refusal::TypeMismatch(DataType::Int16))
        );
        let big = written(&int, DataType::Int16, Some(&Wire::IntValue(70_000)));
        assert_eq!(big, Err(Refusal::OutOfRange("70000".into())));
        let sint = T::Signed(Elem::I8);
        assert_eq!(
            written(&sint, DataType::Int8, Some(&Wire::IntValue(0xFF))).as_deref(),
            Ok("-1")
        );
        let java = Wire::IntValue(0xFFFF_FFFF);
        assert_eq!(written(&sint, DataType::Int8, Some(&java)).as_deref(), Ok("-1"), "32-bit form");
        let byte = T::Unsigned(Elem::U8);
        assert!(written(&byte, DataType::UInt8, Some(&Wire::IntValue(256))).is_err());
        assert_eq!(
            written(&byte, DataType::UInt8, Some(&Wire::LongValue(255))).as_deref(),
            Ok("255")
        );
        assert!(written(&T::Time, DataType::Double, Some(&Wire::DoubleValue(f64::NAN))).is_err());
        let tod = T::Calendar(Calendar::Tod);
        assert!(written(&tod, DataType::Double, Some(&Wire::DoubleValue(86_400_000.0))).is_err());
        assert!(written(&T::Char, DataType::String, Some(&Wire::StringValue("ab".into()))).is_err());
    }

    #[test]
    fn deadbands_hold_back_small_changes_of_numbers_only() {
        let a = Value::Double(10.0);
        assert!(!a.changed(&Value::Double(10.4), 0.5));
        assert!(a.changed(&Value::Double(10.5), 0.5));
        assert!(a.changed(&Value::Double(10.1), 0.0));
        assert!(!Value::Double(f64::NAN).changed(&Value::Double(f64::NAN), 0.0), "NaN stays NaN");
        assert!(Value::Double(1.0).changed(&Value::Double(f64::NAN), 5.0), "to NaN is a change");
        assert!(Value::Int(3).changed(&Value::Int(5), 2.0));
        assert!(!Value::Int(3).changed(&Value::Int(4), 2.0));
        assert!(Value::Text("a".into()).changed(&Value::Text("b".into()), 2.0));
    }
}
