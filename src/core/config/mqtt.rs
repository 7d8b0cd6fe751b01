//! `[mqtt]`: the MQTT Sparkplug B edge node of `plcd run` (docs/MQTT.md): the brokers it
//! connects to, who it is in Sparkplug's namespace, its login and TLS files, what it publishes
//! and how often, and what a command may write.
//!
//! ```toml
//! [mqtt]
//! brokers = ["mqtts://broker.plant.example", "mqtt://10.0.0.5:1883"]   # none: no edge node
//! group_id = "press-shop"
//! edge_node_id = "press7"
//! username = "press7"
//! password_file = "mqtt.password"   # relative to the config file
//! ca_file = "broker-ca.pem"
//! writable = ["main.setpoint"]
//!
//! [[mqtt.devices]]                  # else one device per program instance
//! name = "press"
//! variables = ["main.axis", "main.setpoint"]
//!
//! [[mqtt.deadbands]]                # DATA only past this change
//! variable = "main.pressure"
//! value = 0.5
//!
//! [[mqtt.ranges]]                   # device ranges as node metrics, as [[opcua.devices]]
//! device = "D00100"
//! count = 16
//! ```
//!
//! The keys' ranges and defaults are the constants of [`MqttConfig`]. The names of `writable`,
//! `[[mqtt.devices]]` and `[[mqtt.deadbands]]` are checked against the programs when the project
//! is built (`crate::project::Project::mqtt_names`).

use std::collections::BTreeSet;
use std::fmt;
use std::net::Ipv6Addr;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, resolve, widen, Ctx};
use super::opcua::{
    at_most, device_range, entry_variable, writable_names, Number, OpcuaDevices, RawDevices,
    WritableName,
};
use super::Sink;

/// `[mqtt]`: the Sparkplug B edge node (docs/MQTT.md); off unless `brokers` is given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MqttConfig {
    /// `brokers`: the brokers' URLs, tried in order, `mqtt://HOST[:PORT]` (TCP, default port
    /// 1883) or `mqtts://HOST[:PORT]` (TLS, default port 8883), an IPv6 host in brackets; at
    /// most [`MqttConfig::MAX_BROKERS`], each once. Default empty: no edge node.
    pub brokers: Vec<BrokerUrl>,
    /// `group_id`: the Sparkplug group ([`MqttConfig::MAX_ID_BYTES`], none of `/`, `+`, `#`);
    /// required with `brokers`, else default `""`.
    pub group_id: String,
    /// `edge_node_id`: this edge node in its group, by the rules of `group_id`; required with
    /// `brokers`, else default `""`.
    pub edge_node_id: String,
    /// `client_id`: the MQTT client identifier, not empty, at most
    /// [`MqttConfig::MAX_ID_BYTES`]; default `None`: `plcd-GROUP-NODE`
    /// ([`MqttConfig::client_id_or_default`]).
    pub client_id: Option<String>,
    /// `username`: the broker's login, not empty; default `None`: none.
    pub username: Option<String>,
    /// `password_file`: the password is its first line, read at start; resolved against the
    /// config file's directory; needs `username`. Default `None`: no password.
    pub password_file: Option<PathBuf>,
    /// `ca_file`: PEM certificates the broker's is checked against, resolved against the
    /// config file's directory; default `None`: the system's certificates. For `mqtts://`
    /// brokers only.
    pub ca_file: Option<PathBuf>,
    /// `client_cert`: the PEM certificate plcd shows a broker that asks for one, resolved so;
    /// with `client_key` or not at all; for `mqtts://` brokers only. Default `None`.
    pub client_cert: Option<PathBuf>,
    /// `client_key`: the PEM private key of `client_cert`, resolved so. Default `None`.
    pub client_key: Option<PathBuf>,
    /// `keep_alive_s`: the MQTT keep alive, [`MqttConfig::KEEP_ALIVE_S`]; default 30.
    pub keep_alive_s: u16,
    /// `sample_interval_ms`: how often the metrics are copied at a scan boundary and compared
    /// with what was sent (the node's scan rate), [`MqttConfig::SAMPLE_INTERVAL_MS`]; default
    /// 100.
    pub sample_interval_ms: u32,
    /// `primary_host`: the primary host application's id, by the rules of `group_id`: births
    /// and data only while its STATE says online. Default `None`: no primary host.
    pub primary_host: Option<String>,
    /// `max_metrics`: the variables published at most, [`MqttConfig::MAX_METRICS`]; default
    /// 10000. Beyond it the rest are left out and the log says how many.
    pub max_metrics: u32,
    /// `writable`: the variables a command (NCMD, DCMD) may write, by name as `plcctl set`
    /// names them (a struct, an FB instance or an array stands for all its variables), each
    /// once (case-insensitive), at most [`MqttConfig::MAX_WRITABLE`]; default none: every
    /// metric read-only.
    pub writable: Vec<WritableName>,
    /// `[[mqtt.devices]]`: the Sparkplug devices, in the order written, names unique
    /// (case-insensitive). Default none: one device per program instance.
    pub devices: Vec<MqttDevice>,
    /// `[[mqtt.deadbands]]`: numeric variables sent only when they moved by at least their
    /// deadband, at most [`MqttConfig::MAX_DEADBANDS`], each variable once; default none.
    pub deadbands: Vec<MqttDeadband>,
    /// `[[mqtt.ranges]]`: device ranges published as node metrics, with the rules of
    /// `[[opcua.devices]]`; default none.
    pub ranges: Vec<OpcuaDevices>,
    /// `store_forward_messages`: DATA messages kept while disconnected,
    /// [`MqttConfig::STORE_FORWARD_MESSAGES`]; default 10000. 0: none kept.
    pub store_forward_messages: u32,
    /// `store_forward_dir`: where DATA messages go on disk when `store_forward_messages` are
    /// kept in memory already, resolved against the config file's directory; emptied at each
    /// start (its messages' aliases belong to the births of the run that stored them). Default
    /// `None`: memory only.
    pub store_forward_dir: Option<PathBuf>,
    /// `store_forward_disk_bytes`: what the messages in `store_forward_dir` may take, the
    /// oldest dropped first, [`MqttConfig::STORE_FORWARD_DISK_BYTES`]; default 64 MiB.
    pub store_forward_disk_bytes: u64,
    /// `reconnect_min_ms`: the first wait before connecting again,
    /// [`MqttConfig::RECONNECT_MS`]; default 500.
    pub reconnect_min_ms: u32,
    /// `reconnect_max_ms`: the longest wait, [`MqttConfig::RECONNECT_MS`] and not below
    /// `reconnect_min_ms`; default 30000.
    pub reconnect_max_ms: u32,
    /// `max_message_bytes`: the largest command (NCMD, DCMD) or STATE payload taken,
    /// [`MqttConfig::MAX_MESSAGE_BYTES`]; default 262144 (256 KiB).
    pub max_message_bytes: u32,
}

/// A broker of `brokers`: `mqtt://HOST[:PORT]` or `mqtts://HOST[:PORT]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrokerUrl {
    /// `mqtts://`: TLS.
    pub tls: bool,
    /// A host name or an IP address, an IPv6 address without its brackets.
    pub host: String,
    /// The TCP port, the scheme's default when the URL has none.
    pub port: u16,
}

impl BrokerUrl {
    /// The port of `mqtt://` when the URL gives none.
    pub const MQTT_PORT: u16 = 1883;
    /// The port of `mqtts://` when the URL gives none.
    pub const MQTTS_PORT: u16 = 8883;

    /// `mqtt://HOST[:PORT]` or `mqtts://HOST[:PORT]` (the scheme in any case): a host name or
    /// IPv4 address (letters, digits, `-`, `.`, `_`) or an IPv6 address in brackets, a port
    /// 1..=65535; nothing else (no user, no path). `None` if it is not one.
    pub fn parse(text: &str) -> Option<BrokerUrl> {
        let (scheme, rest) = text.split_once("://")?;
        let tls = match scheme.to_ascii_lowercase().as_str() {
            "mqtt" => false,
            "mqtts" => true,
            _ => return None,
        };
        let (host, port) = match rest.strip_prefix('[') {
            Some(bracketed) => {
                let (address, after) = bracketed.split_once(']')?;
                address.parse::<Ipv6Addr>().ok()?;
                let port = match after {
                    "" => None,
                    _ => Some(after.strip_prefix(':')?),
                };
                (address, port)
            }
            None => match rest.split_once(':') {
                Some((host, port)) => (host, Some(port)),
                None => (rest, None),
            },
        };
        let name_char = |c: char| c.is_ascii_alphanumeric() || matches!(c, '-' | '.' | '_');
        if host.is_empty() || !(host.contains(':') || host.chars().all(name_char)) {
            return None;
        }
        let port = match port {
            None if tls => Self::MQTTS_PORT,
            None => Self::MQTT_PORT,
            Some(digits) if digits.bytes().all(|b| b.is_ascii_digit()) => {
                digits.parse::<u16>().ok().filter(|&p| p != 0)?
            }
            Some(_) => return None,
        };
        Some(BrokerUrl { tls, host: host.to_string(), port })
    }

    /// The same broker: the same scheme and port, the host in any case.
    fn same(&self, other: &BrokerUrl) -> bool {
        self.tls == other.tls
            && self.port == other.port
            && self.host.eq_ignore_ascii_case(&other.host)
    }
}

impl fmt::Display for BrokerUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let scheme = if self.tls { "mqtts" } else { "mqtt" };
        if self.host.contains(':') {
            write!(f, "{scheme}://[{}]:{}", self.host, self.port)
        } else {
            write!(f, "{scheme}://{}:{}", self.host, self.port)
        }
    }
}

/// One `[[mqtt.devices]]` entry: a Sparkplug device and the variables it publishes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MqttDevice {
    /// `name`: the device id, by the rules of `group_id`; required.
    pub name: String,
    /// `variables`: by name as `plcctl get` names them (a struct, an FB instance or an array
    /// stands for all its variables), at least one, at most
    /// [`MqttConfig::MAX_DEVICE_VARIABLES`], each once; required. Checked against the
    /// programs when the project is built.
    pub variables: Vec<WritableName>,
}

/// One `[[mqtt.deadbands]]` entry: a numeric variable (or a struct, FB instance or array
/// standing for its numeric variables) and how far it must move before it is sent again.
#[derive(Debug, Clone, PartialEq)]
pub struct MqttDeadband {
    /// `variable`: by name, as `plcctl get` names it; required.
    pub variable: WritableName,
    /// `value`: a finite number, at least 0, in the variable's unit; required.
    pub value: f64,
}

// The value is a finite number (the config refuses NaN): equality is total.
impl Eq for MqttDeadband {}

impl MqttConfig {
    /// URLs `brokers` may list.
    pub const MAX_BROKERS: usize = 16;
    /// The longest `group_id`, `edge_node_id`, `primary_host`, device name and `client_id`.
    pub const MAX_ID_BYTES: usize = 256;
    pub const KEEP_ALIVE_S: RangeInclusive<u16> = 5..=3600;
    pub const SAMPLE_INTERVAL_MS: RangeInclusive<u32> = 10..=60_000;
    pub const MAX_METRICS: RangeInclusive<u32> = 1..=100_000;
    /// Names `writable` may list.
    pub const MAX_WRITABLE: usize = 10_000;
    /// Names one `[[mqtt.devices]]` entry's `variables` may list.
    pub const MAX_DEVICE_VARIABLES: usize = 10_000;
    /// `[[mqtt.deadbands]]` entries.
    pub const MAX_DEADBANDS: usize = 10_000;
    pub const STORE_FORWARD_MESSAGES: RangeInclusive<u32> = 0..=1_000_000;
    /// 64 KiB .. 64 GiB.
    pub const STORE_FORWARD_DISK_BYTES: RangeInclusive<u64> = 65_536..=68_719_476_736;
    /// `reconnect_min_ms` and `reconnect_max_ms`.
    pub const RECONNECT_MS: RangeInclusive<u32> = 100..=600_000;
    /// 1 KiB .. 16 MiB.
    pub const MAX_MESSAGE_BYTES: RangeInclusive<u32> = 1024..=16_777_216;

    /// Whether the edge node runs: `brokers` lists any.
    pub fn enabled(&self) -> bool {
        !self.brokers.is_empty()
    }

    /// `client_id`, else `plcd-GROUP-NODE`.
    pub fn client_id_or_default(&self) -> String {
        match &self.client_id {
            Some(id) => id.clone(),
            None => format!("plcd-{}-{}", self.group_id, self.edge_node_id),
        }
    }
}

impl Default for MqttConfig {
    fn default() -> Self {
        MqttConfig {
            brokers: Vec::new(),
            group_id: String::new(),
            edge_node_id: String::new(),
            client_id: None,
            username: None,
            password_file: None,
            ca_file: None,
            client_cert: None,
            client_key: None,
            keep_alive_s: 30,
            sample_interval_ms: 100,
            primary_host: None,
            max_metrics: 10_000,
            writable: Vec::new(),
            devices: Vec::new(),
            deadbands: Vec::new(),
            ranges: Vec::new(),
            store_forward_messages: 10_000,
            store_forward_dir: None,
            store_forward_disk_bytes: 64 * 1024 * 1024,
            reconnect_min_ms: 500,
            reconnect_max_ms: 30_000,
            max_message_bytes: 262_144,
        }
    }
}

/// `[mqtt]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMqtt {
    pub brokers: Option<Spanned<Vec<Spanned<String>>>>,
    pub group_id: Option<Spanned<String>>,
    pub edge_node_id: Option<Spanned<String>>,
    pub client_id: Option<Spanned<String>>,
    pub username: Option<Spanned<String>>,
    pub password_file: Option<Spanned<String>>,
    pub ca_file: Option<Spanned<String>>,
    pub client_cert: Option<Spanned<String>>,
    pub client_key: Option<Spanned<String>>,
    pub keep_alive_s: Option<Spanned<i64>>,
    pub sample_interval_ms: Option<Spanned<i64>>,
    pub primary_host: Option<Spanned<String>>,
    pub max_metrics: Option<Spanned<i64>>,
    pub writable: Option<Spanned<Vec<Spanned<String>>>>,
    pub devices: Option<Vec<Spanned<RawDevice>>>,
    pub deadbands: Option<Spanned<Vec<Spanned<RawDeadband>>>>,
    pub ranges: Option<Vec<Spanned<RawDevices>>>,
    pub store_forward_messages: Option<Spanned<i64>>,
    pub store_forward_dir: Option<Spanned<String>>,
    pub store_forward_disk_bytes: Option<Spanned<i64>>,
    pub reconnect_min_ms: Option<Spanned<i64>>,
    pub reconnect_max_ms: Option<Spanned<i64>>,
    pub max_message_bytes: Option<Spanned<i64>>,
}

/// `[[mqtt.devices]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDevice {
    pub name: Spanned<String>,
    pub variables: Spanned<Vec<Spanned<String>>>,
}

/// `[[mqtt.deadbands]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDeadband {
    pub variable: Spanned<String>,
    pub value: Spanned<Number>,
}

/// The `[mqtt]` edge node's refusal of a device range of another area than P, M, K and D.
const MQTT_AREAS: &str =
    "the MQTT edge node publishes ranges of P, M, K and D devices (the system's are its Status \
     metrics)";

/// A Sparkplug id (`key` of `ctx`): not empty, at most [`MqttConfig::MAX_ID_BYTES`], and, as
/// it is a level of the topics, none of `/`, `+`, `#` or a control character when `topic`.
/// Kept as written.
fn id(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    value: &Spanned<String>,
    topic: bool,
) -> Option<String> {
    let text = value.get_ref();
    let at = value.span().start;
    if text.trim().is_empty() {
        sink.error(at, format!("{} must not be empty", ctx.key(key)));
        return None;
    }
    if text.len() > MqttConfig::MAX_ID_BYTES {
        let message = format!(
            "{} is {} bytes, at most {}",
            ctx.key(key),
            text.len(),
            MqttConfig::MAX_ID_BYTES
        );
        sink.error(at, message);
        return None;
    }
    let bad = text.chars().find(|&c| matches!(c, '/' | '+' | '#') || c.is_control());
    if let Some(c) = bad.filter(|_| topic) {
        let message = format!(
            "{} {text:?} holds `{}`: a Sparkplug id is a level of the MQTT topics, without `/`, \
             `+`, `#` or control characters",
            ctx.key(key),
            c.escape_debug()
        );
        sink.error(at, message);
        return None;
    }
    Some(text.clone())
}

/// The `brokers` list checked: URLs, each once, at most [`MqttConfig::MAX_BROKERS`].
fn brokers(
    sink: &mut Sink,
    ctx: &Ctx,
    list: Spanned<Vec<Spanned<String>>>,
) -> Option<Vec<BrokerUrl>> {
    let mut ok = true;
    let at = list.span().start;
    let list = list.into_inner();
    if list.len() > MqttConfig::MAX_BROKERS {
        let message = format!(
            "{} lists {} URLs, at most {}",
            ctx.key("brokers"),
            list.len(),
            MqttConfig::MAX_BROKERS
        );
        sink.error(at, message);
        ok = false;
    }
    let mut urls: Vec<BrokerUrl> = Vec::new();
    for url in list {
        let text = url.get_ref().trim();
        match BrokerUrl::parse(text) {
            None => {
                let message = format!(
                    "{}: {text:?} is not a broker URL: mqtt://HOST[:PORT] (TCP, port {} by \
                     default) or mqtts://HOST[:PORT] (TLS, port {}), an IPv6 host in brackets",
                    ctx.key("brokers"),
                    BrokerUrl::MQTT_PORT,
                    BrokerUrl::MQTTS_PORT
                );
                sink.error(url.span().start, message);
                ok = false;
            }
            Some(broker) if urls.iter().any(|u| u.same(&broker)) => {
                let message = format!("{}: {broker} is listed twice", ctx.key("brokers"));
                sink.error(url.span().start, message);
                ok = false;
            }
            Some(broker) => urls.push(broker),
        }
    }
    ok.then_some(urls)
}

/// The `[[mqtt.devices]]` entries checked: a name by the id rules, each once (case-insensitive),
/// and at least one variable, each once.
fn devices(sink: &mut Sink, raw: Vec<Spanned<RawDevice>>) -> Option<Vec<MqttDevice>> {
    let ctx = Ctx::Section("mqtt.devices");
    let mut ok = true;
    let mut devices = Vec::new();
    let mut seen = BTreeSet::new();
    for entry in raw {
        let entry = entry.into_inner();
        let name = id(sink, &ctx, "name", &entry.name, true);
        let name = name.filter(|name| {
            let first = seen.insert(name.to_lowercase());
            if !first {
                let message = format!("{} {name:?} is listed twice", ctx.key("name"));
                sink.error(entry.name.span().start, message);
            }
            first
        });
        let at = entry.variables.span().start;
        let key = ctx.key("variables");
        let variables =
            writable_names(sink, &key, entry.variables, MqttConfig::MAX_DEVICE_VARIABLES);
        if variables.as_ref().is_some_and(Vec::is_empty) {
            sink.error(at, format!("{key} must list at least one variable"));
            ok = false;
            continue;
        }
        match (name, variables) {
            (Some(name), Some(variables)) => devices.push(MqttDevice { name, variables }),
            _ => ok = false,
        }
    }
    ok.then_some(devices)
}

/// The `[[mqtt.deadbands]]` entries checked: a variable named once, a finite value, at least 0.
fn deadbands(
    sink: &mut Sink,
    raw: Spanned<Vec<Spanned<RawDeadband>>>,
) -> Option<Vec<MqttDeadband>> {
    let ctx = Ctx::Section("mqtt.deadbands");
    let raw = at_most(sink, "mqtt.deadbands", raw, MqttConfig::MAX_DEADBANDS)?;
    let mut ok = true;
    let mut entries = Vec::new();
    let mut seen = BTreeSet::new();
    for entry in raw {
        let entry = entry.into_inner();
        let variable = entry_variable(sink, &ctx, &entry.variable, &mut seen);
        let value = entry.value.get_ref().value();
        if !(value.is_finite() && value >= 0.0) {
            let message =
                format!("{} {value} must be a finite number, at least 0", ctx.key("value"));
            sink.error(entry.value.span().start, message);
            ok = false;
            continue;
        }
        match variable {
            Some(variable) => entries.push(MqttDeadband { variable, value }),
            None => ok = false,
        }
    }
    ok.then_some(entries)
}

/// A file key (`password_file`): not empty, resolved against the config file's directory.
fn file(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    value: &Option<Spanned<String>>,
    config: &Path,
) -> Option<Option<PathBuf>> {
    match value {
        None => Some(None),
        Some(path) if path.get_ref().trim().is_empty() => {
            sink.error(path.span().start, format!("{} must not be empty", ctx.key(key)));
            None
        }
        Some(path) => Some(Some(resolve(config, path.get_ref()))),
    }
}

/// Pass 2 of `[mqtt]`; `config` is the config file, for the files' paths.
pub(super) fn validate(sink: &mut Sink, raw: RawMqtt, config: &Path) -> Option<MqttConfig> {
    let ctx = Ctx::Section("mqtt");
    let default = MqttConfig::default();
    let mut ok = true;
    let brokers_at = raw.brokers.as_ref().map(|b| b.span().start);
    let brokers = match raw.brokers {
        None => Some(Vec::new()),
        Some(list) => brokers(sink, &ctx, list),
    };
    // Written (so possibly wrong), the edge node is on: its ids are required.
    let on = brokers_at.filter(|_| brokers.as_ref().is_none_or(|b| !b.is_empty()));
    let required = |sink: &mut Sink, key: &str, value: &Option<Spanned<String>>| match (value, on) {
        (Some(value), _) => id(sink, &ctx, key, value, true).ok_or(()),
        (None, Some(at)) => {
            let message = format!("{} is required with `brokers`", ctx.key(key));
            sink.error(at, message);
            Err(())
        }
        (None, None) => Ok(String::new()),
    };
    let group_id = required(sink, "group_id", &raw.group_id);
    let edge_node_id = required(sink, "edge_node_id", &raw.edge_node_id);
    let optional = |sink: &mut Sink, key: &str, value: &Option<Spanned<String>>, topic| match value
    {
        None => Some(None),
        Some(value) => id(sink, &ctx, key, value, topic).map(Some),
    };
    let client_id = optional(sink, "client_id", &raw.client_id, false);
    let primary_host = optional(sink, "primary_host", &raw.primary_host, true);
    let username = match &raw.username {
        Some(name) if name.get_ref().trim().is_empty() => {
            sink.error(name.span().start, format!("{} must not be empty", ctx.key("username")));
            None
        }
        name => Some(name.as_ref().map(|n| n.get_ref().clone())),
    };
    let password_file = file(sink, &ctx, "password_file", &raw.password_file, config);
    if let (Some(password), None) = (&raw.password_file, &raw.username) {
        let message =
            format!("{} needs `username`: a password is for a login", ctx.key("password_file"));
        sink.error(password.span().start, message);
        ok = false;
    }
    let ca_file = file(sink, &ctx, "ca_file", &raw.ca_file, config);
    let client_cert = file(sink, &ctx, "client_cert", &raw.client_cert, config);
    let client_key = file(sink, &ctx, "client_key", &raw.client_key, config);
    let pairs = [
        ("client_cert", &raw.client_cert, "client_key", &raw.client_key),
        ("client_key", &raw.client_key, "client_cert", &raw.client_cert),
    ];
    for (key, given, other, paired) in pairs {
        if let (Some(given), None) = (given, paired) {
            let message = format!(
                "{} needs `{other}`: a client certificate goes with its private key",
                ctx.key(key)
            );
            sink.error(given.span().start, message);
            ok = false;
        }
    }
    let plain = brokers.as_ref().is_some_and(|b| !b.is_empty() && !b.iter().any(|b| b.tls));
    let tls_files = [
        ("ca_file", &raw.ca_file),
        ("client_cert", &raw.client_cert),
        ("client_key", &raw.client_key),
    ];
    for (key, value) in tls_files.into_iter().filter(|_| plain) {
        if let Some(value) = value {
            let message =
                format!("{} is for TLS, and no broker of `brokers` is mqtts://", ctx.key(key));
            sink.error(value.span().start, message);
            ok = false;
        }
    }
    let range = |sink: &mut Sink, key, value, range, default| {
        int_or::<u32>(sink, &ctx, key, value, widen(range), default)
    };
    let keep_alive_s = int_or::<u16>(
        sink,
        &ctx,
        "keep_alive_s",
        raw.keep_alive_s,
        widen(MqttConfig::KEEP_ALIVE_S),
        default.keep_alive_s,
    );
    let sample_interval_ms = range(
        sink,
        "sample_interval_ms",
        raw.sample_interval_ms,
        MqttConfig::SAMPLE_INTERVAL_MS,
        default.sample_interval_ms,
    );
    let max_metrics =
        range(sink, "max_metrics", raw.max_metrics, MqttConfig::MAX_METRICS, default.max_metrics);
    let store_forward_messages = range(
        sink,
        "store_forward_messages",
        raw.store_forward_messages,
        MqttConfig::STORE_FORWARD_MESSAGES,
        default.store_forward_messages,
    );
    let store_forward_dir = file(sink, &ctx, "store_forward_dir", &raw.store_forward_dir, config);
    let store_forward_disk_bytes = int_or::<u64>(
        sink,
        &ctx,
        "store_forward_disk_bytes",
        raw.store_forward_disk_bytes,
        {
            let bytes = &MqttConfig::STORE_FORWARD_DISK_BYTES;
            (*bytes.start() as i64)..=(*bytes.end() as i64)
        },
        default.store_forward_disk_bytes,
    );
    let (min_at, max_at) = (raw.reconnect_min_ms.as_ref(), raw.reconnect_max_ms.as_ref());
    let min_at = min_at.map(|v| v.span().start);
    let max_at = max_at.map(|v| v.span().start);
    let reconnect_min_ms = range(
        sink,
        "reconnect_min_ms",
        raw.reconnect_min_ms,
        MqttConfig::RECONNECT_MS,
        default.reconnect_min_ms,
    );
    let reconnect_max_ms = range(
        sink,
        "reconnect_max_ms",
        raw.reconnect_max_ms,
        MqttConfig::RECONNECT_MS,
        default.reconnect_max_ms,
    );
    if let (Some(min), Some(max), Some(at)) =
        (reconnect_min_ms, reconnect_max_ms, max_at.or(min_at))
    {
        if max < min {
            let message =
                format!("{} {max} is below reconnect_min_ms {min}", ctx.key("reconnect_max_ms"));
            sink.error(at, message);
            ok = false;
        }
    }
    let max_message_bytes = range(
        sink,
        "max_message_bytes",
        raw.max_message_bytes,
        MqttConfig::MAX_MESSAGE_BYTES,
        default.max_message_bytes,
    );
    let writable = match raw.writable {
        None => Some(Vec::new()),
        Some(list) => writable_names(sink, &ctx.key("writable"), list, MqttConfig::MAX_WRITABLE),
    };
    let devices = devices(sink, raw.devices.unwrap_or_default());
    let deadbands = match raw.deadbands {
        None => Some(Vec::new()),
        Some(raw) => deadbands(sink, raw),
    };
    let mut ranges = Vec::new();
    for raw in raw.ranges.iter().flatten() {
        match device_range(sink, "mqtt.ranges", MQTT_AREAS, raw) {
            Some(range) => ranges.push(range),
            None => ok = false,
        }
    }
    let mqtt = MqttConfig {
        brokers: brokers?,
        group_id: group_id.ok()?,
        edge_node_id: edge_node_id.ok()?,
        client_id: client_id?,
        username: username?,
        password_file: password_file?,
        ca_file: ca_file?,
        client_cert: client_cert?,
        client_key: client_key?,
        keep_alive_s: keep_alive_s?,
        sample_interval_ms: sample_interval_ms?,
        primary_host: primary_host?,
        max_metrics: max_metrics?,
        writable: writable?,
        devices: devices?,
        deadbands: deadbands?,
        ranges,
        store_forward_messages: store_forward_messages?,
        store_forward_dir: store_forward_dir?,
        store_forward_disk_bytes: store_forward_disk_bytes?,
        reconnect_min_ms: reconnect_min_ms?,
        reconnect_max_ms: reconnect_max_ms?,
        max_message_bytes: max_message_bytes?,
    };
    ok.then_some(mqtt)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::parse;

    const PROGRAM: &str = "[[program]]\nfile = \"main.il\"\n";
    const ON: &str =
        "[mqtt]\nbrokers = [\"mqtt://broker\"]\ngroup_id = \"g\"\nedge_node_id = \"n\"\n";

    fn mqtt(section: &str) -> MqttConfig {
        let text = format!("{PROGRAM}{section}");
        match parse(&text, Path::new("/p/plcd.toml")) {
            Ok(config) => config.mqtt,
            Err(e) => panic!("{e}"),
        }
    }

    fn errors(section: &str) -> Vec<String> {
        let text = format!("{PROGRAM}{section}");
        match parse(&text, Path::new("/p/plcd.toml")) {
            Ok(_) => panic!("accepted: {section}"),
            Err(diagnostics) => diagnostics.iter().map(|d| d.to_string()).collect(),
        }
    }

    /// The one error of `section`, without its file and place.
    fn error(section: &str) -> String {
        let errors = errors(section);
        assert_eq!(errors.len(), 1, "{errors:?}");
        errors[0].split_once(": error: ").unwrap().1.to_string()
    }

    #[test]
    fn off_by_default() {
        let off = mqtt("");
        assert_eq!(off, MqttConfig::default());
        assert!(!off.enabled());
        assert_eq!((off.keep_alive_s, off.sample_interval_ms, off.max_metrics), (30, 100, 10_000));
        assert_eq!((off.reconnect_min_ms, off.reconnect_max_ms), (500, 30_000));
        assert_eq!((off.store_forward_messages, off.max_message_bytes), (10_000, 262_144));
        assert_eq!(off.client_id_or_default(), "plcd--");
        let empty = mqtt("[mqtt]\nbrokers = []\nwritable = [\"main.x\"]\n");
        assert!(!empty.enabled(), "no broker, no edge node, no ids needed");
        assert_eq!(empty.writable[0].name, "main.x");
    }

    #[test]
    fn every_key_is_read() {
        let config = mqtt(
            "[mqtt]\nbrokers = [\"mqtts://b1.example\", \"mqtt://10.0.0.5:1884\", \
             \"MQTTS://[::1]\"]\ngroup_id = \"press shop\"\nedge_node_id = \"press7\"\n\
             client_id = \"any/thing+#\"\nusername = \"u\"\npassword_file = \"pw\"\n\
             ca_file = \"/etc/ca.pem\"\nclient_cert = \"c.pem\"\nclient_key = \"k.pem\"\n\
             keep_alive_s = 5\nsample_interval_ms = 60000\nprimary_host = \"scada\"\n\
             max_metrics = 1\nstore_forward_messages = 0\nreconnect_min_ms = 100\n\
             reconnect_max_ms = 100\nmax_message_bytes = 1024\n",
        );
        assert!(config.enabled());
        let urls: Vec<String> = config.brokers.iter().map(|b| b.to_string()).collect();
        assert_eq!(urls, ["mqtts://b1.example:8883", "mqtt://10.0.0.5:1884", "mqtts://[::1]:8883"]);
        assert_eq!(config.brokers[2], BrokerUrl { tls: true, host: "::1".into(), port: 8883 });
        assert_eq!(
            (config.group_id.as_str(), config.edge_node_id.as_str()),
            ("press shop", "press7")
        );
        assert_eq!(config.client_id_or_default(), "any/thing+#", "a client id is no topic level");
        assert_eq!(config.username.as_deref(), Some("u"));
        assert_eq!(config.password_file, Some(PathBuf::from("/p/pw")), "relative to the config");
        assert_eq!(config.ca_file, Some(PathBuf::from("/etc/ca.pem")));
        assert_eq!(config.client_cert, Some(PathBuf::from("/p/c.pem")));
        assert_eq!(config.client_key, Some(PathBuf::from("/p/k.pem")));
        assert_eq!(
            (config.keep_alive_s, config.sample_interval_ms, config.max_metrics),
            (5, 60_000, 1)
        );
        assert_eq!(config.primary_host.as_deref(), Some("scada"));
        assert_eq!((config.store_forward_messages, config.max_message_bytes), (0, 1024));
        assert_eq!((config.reconnect_min_ms, config.reconnect_max_ms), (100, 100));
        let default_id = mqtt(ON);
        assert_eq!(default_id.client_id_or_default(), "plcd-g-n");
        assert_eq!(
            default_id.brokers,
            [BrokerUrl { tls: false, host: "broker".into(), port: 1883 }]
        );
    }

    #[test]
    fn broker_urls() {
        let parsed = |text: &str| BrokerUrl::parse(text).map(|b| b.to_string());
        assert_eq!(parsed("mqtt://h").as_deref(), Some("mqtt://h:1883"));
        assert_eq!(
            parsed("mqtts://h_1.example:65535").as_deref(),
            Some("mqtts://h_1.example:65535")
        );
        assert_eq!(parsed("mqtt://[fe80::1]:1").as_deref(), Some("mqtt://[fe80::1]:1"));
        for bad in [
            "tcp://h",
            "ssl://h:8883",
            "h:1883",
            "mqtt://",
            "mqtt://:1883",
            "mqtt://h:",
            "mqtt://h:0",
            "mqtt://h:65536",
            "mqtt://h:+1",
            "mqtt://h/",
            "mqtt://h:1883/x",
            "mqtt://u@h",
            "mqtt://::1",
            "mqtt://[::1",
            "mqtt://[h]:1",
            "mqtt://[::1]x",
            "mqtt://h h",
        ] {
            assert_eq!(parsed(bad), None, "{bad}");
        }
    }

    #[test]
    fn brokers_are_urls_each_once() {
        assert_eq!(
            errors("[mqtt]\nbrokers = [\"tcp://b\"]\ngroup_id = \"g\"\nedge_node_id = \"n\"\n"),
            ["/p/plcd.toml:4:12: error: mqtt.brokers: \"tcp://b\" is not a broker URL: \
              mqtt://HOST[:PORT] (TCP, port 1883 by default) or mqtts://HOST[:PORT] (TLS, port \
              8883), an IPv6 host in brackets"]
        );
        assert_eq!(
            error("[mqtt]\nbrokers = [\"mqtt://B\", \"mqtt://b:1883\"]\ngroup_id = \"g\"\nedge_node_id = \"n\"\n"),
            "mqtt.brokers: mqtt://b:1883 is listed twice"
        );
        mqtt("[mqtt]\nbrokers = [\"mqtt://b\", \"mqtts://b\"]\ngroup_id = \"g\"\nedge_node_id = \"n\"\n");
        let many: Vec<String> =
            (0..=MqttConfig::MAX_BROKERS).map(|i| format!("\"mqtt://b{i}\"")).collect();
        assert_eq!(
            error(&format!(
                "[mqtt]\nbrokers = [{}]\ngroup_id = \"g\"\nedge_node_id = \"n\"\n",
                many.join(", ")
            )),
            "mqtt.brokers lists 17 URLs, at most 16"
        );
    }

    #[test]
    fn ids_are_required_with_brokers_and_are_topic_levels() {
        assert_eq!(
            errors("[mqtt]\nbrokers = [\"mqtt://b\"]\n"),
            [
                "/p/plcd.toml:4:11: error: mqtt.group_id is required with `brokers`",
                "/p/plcd.toml:4:11: error: mqtt.edge_node_id is required with `brokers`",
            ]
        );
        assert_eq!(
            error(&format!("{ON}primary_host = \"a/b\"\n")),
            "mqtt.primary_host \"a/b\" holds `/`: a Sparkplug id is a level of the MQTT topics, \
             without `/`, `+`, `#` or control characters"
        );
        let on = "[mqtt]\nbrokers = [\"mqtt://b\"]\nedge_node_id = \"n\"\n";
        assert!(error(&format!("{on}group_id = \"a+\"\n")).contains("holds `+`"));
        assert!(error(&format!("{on}group_id = \"#\"\n")).contains("holds `#`"));
        assert!(error(&format!("{on}group_id = \"a\\tb\"\n")).contains("holds `\\t`"));
        assert_eq!(error(&format!("{on}group_id = \" \"\n")), "mqtt.group_id must not be empty");
        let long = "x".repeat(MqttConfig::MAX_ID_BYTES + 1);
        assert_eq!(
            error(&format!("{on}group_id = \"{long}\"\n")),
            "mqtt.group_id is 257 bytes, at most 256"
        );
        assert_eq!(error(&format!("{ON}client_id = \"\"\n")), "mqtt.client_id must not be empty");
        assert_eq!(error(&format!("{ON}username = \"\"\n")), "mqtt.username must not be empty");
    }

    #[test]
    fn login_and_tls_files() {
        assert_eq!(
            error(&format!("{ON}password_file = \"pw\"\n")),
            "mqtt.password_file needs `username`: a password is for a login"
        );
        assert_eq!(
            error("[mqtt]\nbrokers = [\"mqtts://b\"]\ngroup_id = \"g\"\nedge_node_id = \"n\"\nclient_key = \"k\"\n"),
            "mqtt.client_key needs `client_cert`: a client certificate goes with its private key"
        );
        assert_eq!(
            error("[mqtt]\nclient_cert = \"c\"\n"),
            "mqtt.client_cert needs `client_key`: a client certificate goes with its private key"
        );
        assert_eq!(
            error(&format!("{ON}ca_file = \"ca.pem\"\n")),
            "mqtt.ca_file is for TLS, and no broker of `brokers` is mqtts://"
        );
        assert_eq!(error("[mqtt]\nca_file = \"\"\n"), "mqtt.ca_file must not be empty");
        assert_eq!(mqtt("[mqtt]\nca_file = \"ca.pem\"\n").ca_file, Some("/p/ca.pem".into()), "off");
    }

    #[test]
    fn numbers_in_range_and_reconnect_in_order() {
        assert_eq!(
            errors(
                "[mqtt]\nkeep_alive_s = 4\nsample_interval_ms = 60001\nmax_metrics = 0\n\
                 store_forward_messages = -1\nreconnect_min_ms = 99\nreconnect_max_ms = 600001\n\
                 max_message_bytes = 1023\n"
            ),
            [
                "/p/plcd.toml:4:16: error: mqtt.keep_alive_s 4 out of range 5..=3600",
                "/p/plcd.toml:5:22: error: mqtt.sample_interval_ms 60001 out of range 10..=60000",
                "/p/plcd.toml:6:15: error: mqtt.max_metrics 0 out of range 1..=100000",
                "/p/plcd.toml:7:26: error: mqtt.store_forward_messages -1 out of range 0..=1000000",
                "/p/plcd.toml:8:20: error: mqtt.reconnect_min_ms 99 out of range 100..=600000",
                "/p/plcd.toml:9:20: error: mqtt.reconnect_max_ms 600001 out of range 100..=600000",
                "/p/plcd.toml:10:21: error: mqtt.max_message_bytes 1023 out of range 1024..=16777216",
            ]
        );
        assert_eq!(
            errors("[mqtt]\nreconnect_min_ms = 1000\nreconnect_max_ms = 999\n"),
            ["/p/plcd.toml:5:20: error: mqtt.reconnect_max_ms 999 is below reconnect_min_ms 1000"]
        );
        assert_eq!(
            errors("[mqtt]\nreconnect_min_ms = 40000\n"),
            ["/p/plcd.toml:4:20: error: mqtt.reconnect_max_ms 30000 is below reconnect_min_ms 40000"],
            "at the one written"
        );
        assert!(error("[mqtt]\nport = 1883\n").contains("[mqtt]: unknown key `port`"));
    }

    #[test]
    fn writable_names_keep_their_place() {
        let config = mqtt("[mqtt]\nwritable = [\"main.setpoint\", \" main.recipe \"]\n");
        let names: Vec<(&str, u32, u32)> =
            config.writable.iter().map(|w| (w.name.as_str(), w.line, w.col)).collect();
        assert_eq!(names, [("main.setpoint", 4, 13), ("main.recipe", 4, 30)], "trimmed");
        assert_eq!(
            error("[mqtt]\nwritable = [\"main.a\", \"MAIN.A\"]\n"),
            "mqtt.writable: `MAIN.A` is listed twice"
        );
        assert_eq!(error("[mqtt]\nwritable = [\" \"]\n"), "mqtt.writable: a name is empty");
        let many: Vec<String> =
            (0..=MqttConfig::MAX_WRITABLE).map(|i| format!("\"main.v{i}\"")).collect();
        assert!(error(&format!("[mqtt]\nwritable = [{}]\n", many.join(", ")))
            .contains("mqtt.writable lists 10001 names, at most 10000"));
    }

    #[test]
    fn devices_have_unique_names_and_variables() {
        let config = mqtt(
            "[[mqtt.devices]]\nname = \"press\"\nvariables = [\"main.axis\", \"main.speed\"]\n\
             [[mqtt.devices]]\nname = \"oven\"\nvariables = [\"main.axis\"]\n",
        );
        let devices: Vec<(&str, Vec<&str>)> = config
            .devices
            .iter()
            .map(|d| (d.name.as_str(), d.variables.iter().map(|v| v.name.as_str()).collect()))
            .collect();
        assert_eq!(
            devices,
            [("press", vec!["main.axis", "main.speed"]), ("oven", vec!["main.axis"])]
        );
        assert_eq!(
            error(
                "[[mqtt.devices]]\nname = \"a\"\nvariables = [\"main.x\"]\n\
                 [[mqtt.devices]]\nname = \"A\"\nvariables = [\"main.y\"]\n"
            ),
            "mqtt.devices.name \"A\" is listed twice"
        );
        assert_eq!(
            error("[[mqtt.devices]]\nname = \"a\"\nvariables = []\n"),
            "mqtt.devices.variables must list at least one variable"
        );
        assert_eq!(
            error("[[mqtt.devices]]\nname = \"a\"\nvariables = [\"main.x\", \"Main.X\"]\n"),
            "mqtt.devices.variables: `Main.X` is listed twice"
        );
        assert!(error("[[mqtt.devices]]\nname = \"a/b\"\nvariables = [\"main.x\"]\n")
            .starts_with("mqtt.devices.name \"a/b\" holds `/`"));
        assert!(error("[[mqtt.devices]]\nname = \"a\"\n").contains("missing key `variables`"));
    }

    #[test]
    fn deadbands_are_finite_and_not_negative() {
        let config = mqtt(
            "[[mqtt.deadbands]]\nvariable = \"main.p\"\nvalue = 0\n\
             [[mqtt.deadbands]]\nvariable = \"main.t\"\nvalue = 0.5\n",
        );
        let read: Vec<(&str, f64, u32)> = config
            .deadbands
            .iter()
            .map(|d| (d.variable.name.as_str(), d.value, d.variable.line))
            .collect();
        assert_eq!(read, [("main.p", 0.0, 4), ("main.t", 0.5, 7)]);
        assert_eq!(
            error("[[mqtt.deadbands]]\nvariable = \"main.p\"\nvalue = -0.1\n"),
            "mqtt.deadbands.value -0.1 must be a finite number, at least 0"
        );
        assert!(error("[[mqtt.deadbands]]\nvariable = \"main.p\"\nvalue = nan\n")
            .contains("value NaN must be a finite number"));
        assert_eq!(
            error(
                "[[mqtt.deadbands]]\nvariable = \"main.p\"\nvalue = 1\n\
                 [[mqtt.deadbands]]\nvariable = \"MAIN.P\"\nvalue = 2\n"
            ),
            "mqtt.deadbands.variable `MAIN.P` is listed twice"
        );
        assert_eq!(
            error("[[mqtt.deadbands]]\nvariable = \"\"\nvalue = 1\n"),
            "mqtt.deadbands.variable is empty"
        );
        let many: String = (0..=MqttConfig::MAX_DEADBANDS)
            .map(|i| format!("[[mqtt.deadbands]]\nvariable = \"main.v{i}\"\nvalue = 1\n"))
            .collect();
        assert!(error(&many).starts_with("mqtt.deadbands: 10001 entries, at most 10000: "));
    }

    #[test]
    fn ranges_follow_the_rules_of_opcua_devices() {
        let config = mqtt(
            "[[mqtt.ranges]]\ndevice = \"D00100\"\ncount = 2\nwritable = true\n\
             [[mqtt.ranges]]\ndevice = \"M000F\"\ncount = 1\n",
        );
        let names: Vec<Vec<String>> = config
            .ranges
            .iter()
            .map(|range| range.addresses().map(|a| a.to_string()).collect())
            .collect();
        assert_eq!(names, [vec!["D00100", "D00101"], vec!["M000F"]]);
        assert_eq!(config.ranges.iter().map(|r| r.writable).collect::<Vec<_>>(), [true, false]);
        assert_eq!(
            error("[[mqtt.ranges]]\ndevice = \"T0005\"\ncount = 1\n"),
            "mqtt.ranges.device: T0005: the MQTT edge node publishes ranges of P, M, K and D \
             devices (the system's are its Status metrics)"
        );
        assert_eq!(
            error("[[mqtt.ranges]]\ndevice = \"D0\"\ncount = 0\n"),
            "mqtt.ranges.count 0 out of range 1..=4096"
        );
    }
}
