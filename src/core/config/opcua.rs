//! `[opcua]`: the OPC UA server of `plcd run` (docs/OPCUA.md): what it listens on, the security
//! it offers, the limits it enforces and where its certificates live.
//!
//! ```toml
//! [opcua]
//! listen = "127.0.0.1:4840"      # no listen: no server (the default)
//! security_policies = ["Basic256Sha256"]
//! anonymous = "none"
//! writable = ["main.setpoint", "main.recipe"]
//!
//! [[opcua.devices]]              # device ranges, as the Modbus map chooses them
//! device = "D00100"
//! count = 16
//!
//! [[opcua.analog]]               # an EURange, for percent deadbands
//! variable = "main.temperature"
//! low = 0.0
//! high = 150.0
//! ```
//!
//! The keys' ranges and defaults are the constants of [`OpcuaConfig`]; the server
//! (`services::opcua`) hands them to the OPC UA stack's own limits where it has them.

use std::collections::BTreeSet;
use std::net::SocketAddr;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, resolve, widen, Ctx};
use super::Sink;
use crate::device::{Address, Area};
use crate::diag::Diagnostic;

/// `[opcua]`: off unless `listen` is given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpcuaConfig {
    /// `listen`: the IP address and TCP port to serve, `"127.0.0.1:4840"`; port 0 takes any
    /// free port (the log names it). Default `None`: no server.
    pub listen: Option<SocketAddr>,
    /// `endpoint_host`: the host name in the endpoint URL (`opc.tcp://HOST:PORT/`), not empty;
    /// default `None`: the IP address of `listen`.
    pub endpoint_host: Option<String>,
    /// `security_policies`: the policies offered, each with Sign and SignAndEncrypt (`None`
    /// with no message security at all), in the order written, no duplicates, at least one;
    /// default [`OpcuaConfig::DEFAULT_POLICIES`].
    pub security_policies: Vec<OpcuaPolicy>,
    /// `anonymous`: what a session without a user identity may do; default
    /// [`Anonymous::None`].
    pub anonymous: Anonymous,
    /// `max_sessions`: sessions at once, [`OpcuaConfig::MAX_SESSIONS`]; default 10.
    pub max_sessions: u32,
    /// `max_subscriptions_per_session`: [`OpcuaConfig::MAX_SUBSCRIPTIONS`]; default 10.
    pub max_subscriptions_per_session: u32,
    /// `max_monitored_items_per_session`: [`OpcuaConfig::MAX_MONITORED_ITEMS`]; default
    /// 10000. Each subscription may hold this divided by `max_subscriptions_per_session`
    /// (at least 1), so that no session holds more.
    pub max_monitored_items_per_session: u32,
    /// `max_request_bytes`: the longest message a client may send (or be sent), all its
    /// chunks together, [`OpcuaConfig::MAX_REQUEST_BYTES`]; default 4 MiB.
    pub max_request_bytes: u32,
    /// `max_connections`: TCP connections at once, from all addresses,
    /// [`OpcuaConfig::MAX_CONNECTIONS`]; default 20. One more is closed at once.
    pub max_connections: u32,
    /// `max_connections_per_address`: TCP connections at once from one IP address,
    /// [`OpcuaConfig::MAX_CONNECTIONS`]; default 10.
    pub max_connections_per_address: u32,
    /// `max_requests_per_second`: messages one connection may send a second, and at once,
    /// [`OpcuaConfig::MAX_REQUESTS_PER_SECOND`]; default 200. A client that sends more is cut
    /// off.
    pub max_requests_per_second: u32,
    /// `io_timeout_ms`: how long a chunk begun may take to arrive whole, and a client to take
    /// what the server sends, [`OpcuaConfig::IO_TIMEOUT_MS`]; default 10000. Past it the client
    /// is cut off.
    pub io_timeout_ms: u32,
    /// `min_sampling_interval_ms`: the shortest sampling and publishing interval granted, and
    /// how often the variables are copied at a scan boundary while a client is connected,
    /// [`OpcuaConfig::MIN_SAMPLING_INTERVAL_MS`]; default 100.
    pub min_sampling_interval_ms: u32,
    /// `max_nodes`: the variables served at most, [`OpcuaConfig::MAX_NODES`]; default 10000.
    /// Beyond it the rest are left out and the log says how many.
    pub max_nodes: u32,
    /// `pki_dir`: the server's certificate and key, the trusted and the rejected client
    /// certificates, resolved against the config file's directory; default `None`:
    /// `opcua-pki` in the retain directory (`[retain] dir`, else `$STATE_DIRECTORY`).
    pub pki_dir: Option<PathBuf>,
    /// `writable`: the variables sessions of the operator role and up may write, by name as
    /// `plcctl set` names them (a struct, an FB instance or an array stands for all its
    /// variables), at most [`OpcuaConfig::MAX_WRITABLE`]; default none: everything read-only.
    /// Checked against the programs when the project is built
    /// (`crate::project::Project::opcua_names`).
    pub writable: Vec<WritableName>,
    /// `[[opcua.devices]]`: device ranges served beside the variables, in the order written;
    /// default none.
    pub devices: Vec<OpcuaDevices>,
    /// `[[opcua.analog]]`: numeric variables served as analog items, with the range of values
    /// they are expected to take (their `EURange`), in the order written, at most
    /// [`OpcuaConfig::MAX_ANALOG`]; default none. Checked against the programs when the project
    /// is built (`crate::project::Project::opcua_names`).
    pub analog: Vec<OpcuaAnalog>,
}

/// One `[[opcua.analog]]` entry: a variable (or a struct, FB instance or array standing for its
/// numeric variables) and its engineering range.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpcuaAnalog {
    /// `variable`: by name, as `plcctl get` names it; required.
    pub variable: WritableName,
    /// `low`, `high`: finite, `low` below `high`; required.
    pub range: EuRange,
}

/// An analog item's engineering range (OPC UA Part 8 `EURange`): what a percent deadband is a
/// percentage of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EuRange {
    pub low: f64,
    pub high: f64,
}

// Both ends are finite numbers (the config refuses NaN): equality is total.
impl Eq for EuRange {}

/// One `[[opcua.devices]]` entry: `count` consecutive devices of one area from `device`, words
/// (`D00100`, `M010`) or bits (`M0100`, `D00100.3`) as `device` is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OpcuaDevices {
    /// `device`: the first device, of P, M, K or D; required.
    pub first: Address,
    /// `count`: how many devices, [`OpcuaConfig::MAX_DEVICES`], within the area; required.
    pub count: u32,
    /// `writable`: sessions of the operator role and up may write them; default false.
    pub writable: bool,
}

impl OpcuaDevices {
    /// The devices, in order.
    pub fn addresses(&self) -> impl Iterator<Item = Address> + '_ {
        let first = self.first;
        (0..self.count).map(move |k| match first.bit {
            None => Address { number: first.number + k, ..first },
            Some(bit) => {
                let index = first.number * 16 + u32::from(bit) + k;
                Address { number: index / 16, bit: Some((index % 16) as u8), ..first }
            }
        })
    }
}

/// A name of `opcua.writable`, `[[opcua.analog]]`, `mqtt.writable`, `[[mqtt.devices]]` or
/// `[[mqtt.deadbands]]`, with where it is written for the project's diagnostics.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct WritableName {
    pub name: String,
    pub line: u32,
    pub col: u32,
}

/// An OPC UA security policy `security_policies` may name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
pub enum OpcuaPolicy {
    /// No signing, no encryption: everything, the session's identity included, in clear.
    None,
    Basic256Sha256,
    #[serde(rename = "Aes128_Sha256_RsaOaep")]
    Aes128Sha256RsaOaep,
    #[serde(rename = "Aes256_Sha256_RsaPss")]
    Aes256Sha256RsaPss,
}

impl OpcuaPolicy {
    /// The name as the config and OPC UA write it.
    pub fn as_str(self) -> &'static str {
        match self {
            OpcuaPolicy::None => "None",
            OpcuaPolicy::Basic256Sha256 => "Basic256Sha256",
            OpcuaPolicy::Aes128Sha256RsaOaep => "Aes128_Sha256_RsaOaep",
            OpcuaPolicy::Aes256Sha256RsaPss => "Aes256_Sha256_RsaPss",
        }
    }
}

/// `opcua.anonymous`: what a session without a user identity may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Anonymous {
    /// `"none"` (default): no anonymous session at all.
    #[default]
    None,
    /// `"viewer"`: anonymous sessions browse, read and subscribe.
    Viewer,
    /// `"operator"`: anonymous sessions also write the `writable` variables and call RUN,
    /// STOP and reset: for a closed network where the channel's certificate is the access
    /// control.
    Operator,
}

impl Anonymous {
    /// The role of an anonymous session; `None`: no anonymous session.
    pub fn role(self) -> Option<crate::users::Role> {
        match self {
            Anonymous::None => None,
            Anonymous::Viewer => Some(crate::users::Role::Viewer),
            Anonymous::Operator => Some(crate::users::Role::Operator),
        }
    }
}

impl OpcuaConfig {
    pub const DEFAULT_POLICIES: [OpcuaPolicy; 3] = [
        OpcuaPolicy::Basic256Sha256,
        OpcuaPolicy::Aes128Sha256RsaOaep,
        OpcuaPolicy::Aes256Sha256RsaPss,
    ];
    pub const MAX_SESSIONS: RangeInclusive<u32> = 1..=1000;
    pub const MAX_SUBSCRIPTIONS: RangeInclusive<u32> = 1..=1000;
    pub const MAX_MONITORED_ITEMS: RangeInclusive<u32> = 1..=1_000_000;
    /// 64 KiB (the smallest buffer the stack negotiates) .. 64 MiB.
    pub const MAX_REQUEST_BYTES: RangeInclusive<u32> = 65_536..=67_108_864;
    pub const MIN_SAMPLING_INTERVAL_MS: RangeInclusive<u32> = 10..=60_000;
    pub const MAX_CONNECTIONS: RangeInclusive<u32> = 1..=10_000;
    pub const MAX_REQUESTS_PER_SECOND: RangeInclusive<u32> = 1..=100_000;
    pub const IO_TIMEOUT_MS: RangeInclusive<u32> = 100..=600_000;
    pub const MAX_NODES: RangeInclusive<u32> = 1..=1_000_000;
    /// Names `writable` may list.
    pub const MAX_WRITABLE: usize = 10_000;
    /// Devices one `[[opcua.devices]]` entry may serve.
    pub const MAX_DEVICES: RangeInclusive<u32> = 1..=4096;
    /// `[[opcua.analog]]` entries.
    pub const MAX_ANALOG: usize = 10_000;

    /// The monitored items one subscription may hold: the session's share.
    pub fn monitored_items_per_subscription(&self) -> u32 {
        (self.max_monitored_items_per_session / self.max_subscriptions_per_session).max(1)
    }
}

impl Default for OpcuaConfig {
    fn default() -> Self {
        OpcuaConfig {
            listen: None,
            endpoint_host: None,
            security_policies: Self::DEFAULT_POLICIES.to_vec(),
            anonymous: Anonymous::None,
            max_sessions: 10,
            max_subscriptions_per_session: 10,
            max_monitored_items_per_session: 10_000,
            max_request_bytes: 4 * 1024 * 1024,
            max_connections: 20,
            max_connections_per_address: 10,
            max_requests_per_second: 200,
            io_timeout_ms: 10_000,
            min_sampling_interval_ms: 100,
            max_nodes: 10_000,
            pki_dir: None,
            writable: Vec::new(),
            devices: Vec::new(),
            analog: Vec::new(),
        }
    }
}

/// `[opcua]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOpcua {
    pub listen: Option<Spanned<String>>,
    pub endpoint_host: Option<Spanned<String>>,
    pub security_policies: Option<Spanned<Vec<Spanned<OpcuaPolicy>>>>,
    #[serde(default)]
    pub anonymous: Anonymous,
    pub max_sessions: Option<Spanned<i64>>,
    pub max_subscriptions_per_session: Option<Spanned<i64>>,
    pub max_monitored_items_per_session: Option<Spanned<i64>>,
    pub max_request_bytes: Option<Spanned<i64>>,
    pub max_connections: Option<Spanned<i64>>,
    pub max_connections_per_address: Option<Spanned<i64>>,
    pub max_requests_per_second: Option<Spanned<i64>>,
    pub io_timeout_ms: Option<Spanned<i64>>,
    pub min_sampling_interval_ms: Option<Spanned<i64>>,
    pub max_nodes: Option<Spanned<i64>>,
    pub pki_dir: Option<Spanned<String>>,
    pub writable: Option<Spanned<Vec<Spanned<String>>>>,
    pub devices: Option<Vec<Spanned<RawDevices>>>,
    pub analog: Option<Spanned<Vec<Spanned<RawAnalog>>>>,
}

/// `[[opcua.analog]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawAnalog {
    pub variable: Spanned<String>,
    pub low: Spanned<Number>,
    pub high: Spanned<Number>,
}

/// A number as TOML writes it: `0` or `0.0`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(untagged)]
pub(super) enum Number {
    Integer(i64),
    Float(f64),
}

impl Number {
    pub(super) fn value(self) -> f64 {
        match self {
            Number::Integer(i) => i as f64,
            Number::Float(f) => f,
        }
    }
}

/// The `[[opcua.analog]]` entries checked: a variable named once, finite ends, `low` below
/// `high`.
fn analog(sink: &mut Sink, raw: Spanned<Vec<Spanned<RawAnalog>>>) -> Option<Vec<OpcuaAnalog>> {
    let ctx = Ctx::Section("opcua.analog");
    let mut ok = true;
    let mut entries: Vec<OpcuaAnalog> = Vec::new();
    let raw = at_most(sink, "opcua.analog", raw, OpcuaConfig::MAX_ANALOG)?;
    let mut seen = BTreeSet::new();
    for entry in raw {
        let entry = entry.into_inner();
        let Some(variable) = entry_variable(sink, &ctx, &entry.variable, &mut seen) else {
            ok = false;
            continue;
        };
        let (low, high) = (entry.low.get_ref().value(), entry.high.get_ref().value());
        let mut finite = true;
        for (key, value, span) in
            [("low", low, entry.low.span()), ("high", high, entry.high.span())]
        {
            if !value.is_finite() {
                sink.error(span.start, format!("{} {value} is not a finite number", ctx.key(key)));
                finite = false;
            }
        }
        if !finite {
            ok = false;
            continue;
        }
        if low >= high {
            let message = format!(
                "{} {low} must be below high {high} (the range a percent deadband is a percentage of)",
                ctx.key("low")
            );
            sink.error(entry.low.span().start, message);
            ok = false;
            continue;
        }
        entries.push(OpcuaAnalog { variable, range: EuRange { low, high } });
    }
    ok.then_some(entries)
}

/// The entries of an array of tables that names variables (`[[opcua.analog]]`, `section`), if
/// there are at most `max` of them; else an error at the array.
pub(super) fn at_most<T>(
    sink: &mut Sink,
    section: &str,
    raw: Spanned<Vec<T>>,
    max: usize,
) -> Option<Vec<T>> {
    let at = raw.span().start;
    let raw = raw.into_inner();
    if raw.len() > max {
        let message = format!(
            "{section}: {} entries, at most {max}: name a struct, an FB instance or an array for \
             all its variables",
            raw.len(),
        );
        sink.error(at, message);
        return None;
    }
    Some(raw)
}

/// The `variable` of one entry of an array of tables (`[[opcua.analog]]`), trimmed, with
/// where it is written: an error if it is empty or `seen` (lower-cased) has it already.
pub(super) fn entry_variable(
    sink: &mut Sink,
    ctx: &Ctx,
    name: &Spanned<String>,
    seen: &mut BTreeSet<String>,
) -> Option<WritableName> {
    let text = name.get_ref().trim();
    let (line, col) = Diagnostic::line_col(sink.text, name.span().start);
    if text.is_empty() {
        sink.error(name.span().start, format!("{} is empty", ctx.key("variable")));
        return None;
    }
    if !seen.insert(text.to_ascii_lowercase()) {
        let message = format!("{} `{text}` is listed twice", ctx.key("variable"));
        sink.error(name.span().start, message);
        return None;
    }
    Some(WritableName { name: text.to_string(), line, col })
}

/// A list of variable names (`opcua.writable`, of `key`), trimmed, each once
/// (case-insensitive), at most `max`; every error reported, and then `None`.
pub(super) fn writable_names(
    sink: &mut Sink,
    key: &str,
    list: Spanned<Vec<Spanned<String>>>,
    max: usize,
) -> Option<Vec<WritableName>> {
    let mut ok = true;
    let at = list.span().start;
    let list = list.into_inner();
    if list.len() > max {
        let message = format!(
            "{key} lists {} names, at most {max}: name a struct, an FB instance or an array for \
             all its variables",
            list.len(),
        );
        sink.error(at, message);
        ok = false;
    }
    let mut names: Vec<WritableName> = Vec::new();
    let mut seen = BTreeSet::new();
    for name in list {
        let (line, col) = Diagnostic::line_col(sink.text, name.span().start);
        let text = name.get_ref().trim();
        if text.is_empty() {
            sink.error(name.span().start, format!("{key}: a name is empty"));
            ok = false;
        } else if !seen.insert(text.to_ascii_lowercase()) {
            sink.error(name.span().start, format!("{key}: `{text}` is listed twice"));
            ok = false;
        } else {
            names.push(WritableName { name: text.to_string(), line, col });
        }
    }
    ok.then_some(names)
}

/// `[[opcua.devices]]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDevices {
    pub device: Spanned<String>,
    pub count: Spanned<i64>,
    pub writable: Option<Spanned<bool>>,
}

/// The OPC UA server's refusal of a device range of another area than P, M, K and D.
const OPCUA_AREAS: &str =
    "the OPC UA server serves ranges of P, M, K and D devices (the system's are in its Status \
     folder)";

/// One entry of device ranges (`[[opcua.devices]]`, `section`) checked: P, M, K or D (else
/// the error says `areas`), within its area, writable only where a client may write.
pub(super) fn device_range(
    sink: &mut Sink,
    section: &'static str,
    areas: &str,
    raw: &Spanned<RawDevices>,
) -> Option<OpcuaDevices> {
    let ctx = Ctx::Section(section);
    let raw = raw.get_ref();
    let at = raw.device.span().start;
    let first = match Address::parse(raw.device.get_ref()) {
        Ok(first) => first,
        Err(e) => {
            sink.error(at, format!("{}: {e}", ctx.key("device")));
            return None;
        }
    };
    if !matches!(first.area, Area::P | Area::M | Area::K | Area::D) {
        let message = format!("{}: {first}: {areas}", ctx.key("device"));
        sink.error(at, message);
        return None;
    }
    let count = *raw.count.get_ref();
    if !(i64::from(*OpcuaConfig::MAX_DEVICES.start())..=i64::from(*OpcuaConfig::MAX_DEVICES.end()))
        .contains(&count)
    {
        let message = format!(
            "{} {count} out of range {}..={}",
            ctx.key("count"),
            OpcuaConfig::MAX_DEVICES.start(),
            OpcuaConfig::MAX_DEVICES.end()
        );
        sink.error(raw.count.span().start, message);
        return None;
    }
    let count = count as u32;
    let words = first.area.word_count();
    let (start, room) = match first.bit {
        None => (first.number, words),
        Some(bit) => (first.number * 16 + u32::from(bit), words * 16),
    };
    if start + count > room {
        let message = format!(
            "{} {count} from {first} runs past the end of its area ({}): at most {}",
            ctx.key("count"),
            first.area.range_text(),
            room - start
        );
        sink.error(raw.count.span().start, message);
        return None;
    }
    let writable = raw.writable.as_ref().is_some_and(|w| *w.get_ref());
    Some(OpcuaDevices { first, count, writable })
}

/// Pass 2 of `[opcua]`; `config` is the config file, for `pki_dir`.
pub(super) fn validate(sink: &mut Sink, raw: RawOpcua, config: &Path) -> Option<OpcuaConfig> {
    let ctx = Ctx::Section("opcua");
    let default = OpcuaConfig::default();
    let mut ok = true;
    let listen = match raw.listen {
        None => None,
        Some(listen) => match listen.get_ref().trim().parse::<SocketAddr>() {
            Ok(addr) => Some(addr),
            Err(_) => {
                sink.error(
                    listen.span().start,
                    format!(
                        "{} {:?} is not an IP address and port (\"127.0.0.1:4840\", \
                         \"0.0.0.0:4840\", \"[::1]:4840\"); leave it out to turn the server off",
                        ctx.key("listen"),
                        listen.get_ref()
                    ),
                );
                ok = false;
                None
            }
        },
    };
    let endpoint_host = match raw.endpoint_host {
        None => None,
        Some(host) => {
            let text = host.get_ref().trim();
            if text.is_empty() || text.contains(['/', ' ', ':']) {
                let message = format!(
                    "{} {:?} must be a host name or IPv4 address, without port or path",
                    ctx.key("endpoint_host"),
                    host.get_ref()
                );
                sink.error(host.span().start, message);
                ok = false;
            }
            Some(text.to_string())
        }
    };
    let mut security_policies = Vec::new();
    match raw.security_policies {
        None => security_policies = default.security_policies.clone(),
        Some(list) => {
            let at = list.span().start;
            for policy in list.into_inner() {
                if security_policies.contains(policy.get_ref()) {
                    let message = format!(
                        "{}: {} is listed twice",
                        ctx.key("security_policies"),
                        policy.get_ref().as_str()
                    );
                    sink.error(policy.span().start, message);
                    ok = false;
                } else {
                    security_policies.push(*policy.get_ref());
                }
            }
            if security_policies.is_empty() && ok {
                let message = format!(
                    "{} must list at least one policy; leave `listen` out to turn the server off",
                    ctx.key("security_policies")
                );
                sink.error(at, message);
                ok = false;
            }
        }
    }
    let range = |sink: &mut Sink, key, value, range, default| {
        int_or::<u32>(sink, &ctx, key, value, widen(range), default)
    };
    let max_sessions = range(
        sink,
        "max_sessions",
        raw.max_sessions,
        OpcuaConfig::MAX_SESSIONS,
        default.max_sessions,
    );
    let max_subscriptions_per_session = range(
        sink,
        "max_subscriptions_per_session",
        raw.max_subscriptions_per_session,
        OpcuaConfig::MAX_SUBSCRIPTIONS,
        default.max_subscriptions_per_session,
    );
    let max_monitored_items_per_session = range(
        sink,
        "max_monitored_items_per_session",
        raw.max_monitored_items_per_session,
        OpcuaConfig::MAX_MONITORED_ITEMS,
        default.max_monitored_items_per_session,
    );
    let max_request_bytes = range(
        sink,
        "max_request_bytes",
        raw.max_request_bytes,
        OpcuaConfig::MAX_REQUEST_BYTES,
        default.max_request_bytes,
    );
    let max_connections = range(
        sink,
        "max_connections",
        raw.max_connections,
        OpcuaConfig::MAX_CONNECTIONS,
        default.max_connections,
    );
    let max_connections_per_address = range(
        sink,
        "max_connections_per_address",
        raw.max_connections_per_address,
        OpcuaConfig::MAX_CONNECTIONS,
        default.max_connections_per_address,
    );
    let max_requests_per_second = range(
        sink,
        "max_requests_per_second",
        raw.max_requests_per_second,
        OpcuaConfig::MAX_REQUESTS_PER_SECOND,
        default.max_requests_per_second,
    );
    let io_timeout_ms = range(
        sink,
        "io_timeout_ms",
        raw.io_timeout_ms,
        OpcuaConfig::IO_TIMEOUT_MS,
        default.io_timeout_ms,
    );
    let min_sampling_interval_ms = range(
        sink,
        "min_sampling_interval_ms",
        raw.min_sampling_interval_ms,
        OpcuaConfig::MIN_SAMPLING_INTERVAL_MS,
        default.min_sampling_interval_ms,
    );
    let max_nodes =
        range(sink, "max_nodes", raw.max_nodes, OpcuaConfig::MAX_NODES, default.max_nodes);
    let pki_dir = match raw.pki_dir {
        None => None,
        Some(dir) if dir.get_ref().trim().is_empty() => {
            sink.error(dir.span().start, format!("{} must not be empty", ctx.key("pki_dir")));
            ok = false;
            None
        }
        Some(dir) => Some(resolve(config, dir.get_ref())),
    };
    let writable = match raw.writable {
        None => Vec::new(),
        Some(list) => writable_names(sink, &ctx.key("writable"), list, OpcuaConfig::MAX_WRITABLE)
            .unwrap_or_else(|| {
                ok = false;
                Vec::new()
            }),
    };
    let mut device_ranges = Vec::new();
    for raw in raw.devices.iter().flatten() {
        match device_range(sink, "opcua.devices", OPCUA_AREAS, raw) {
            Some(range) => device_ranges.push(range),
            None => ok = false,
        }
    }
    let analog_entries = match raw.analog {
        None => Some(Vec::new()),
        Some(raw) => analog(sink, raw),
    };
    let opcua = OpcuaConfig {
        listen,
        endpoint_host,
        security_policies,
        anonymous: raw.anonymous,
        max_sessions: max_sessions?,
        max_subscriptions_per_session: max_subscriptions_per_session?,
        max_monitored_items_per_session: max_monitored_items_per_session?,
        max_request_bytes: max_request_bytes?,
        max_connections: max_connections?,
        max_connections_per_address: max_connections_per_address?,
        max_requests_per_second: max_requests_per_second?,
        io_timeout_ms: io_timeout_ms?,
        min_sampling_interval_ms: min_sampling_interval_ms?,
        max_nodes: max_nodes?,
        pki_dir,
        writable,
        devices: device_ranges,
        analog: analog_entries?,
    };
    ok.then_some(opcua)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::parse;

    const PROGRAM: &str = "[[program]]\nfile = \"main.il\"\n";

    fn opcua(section: &str) -> OpcuaConfig {
        let text = format!("{PROGRAM}{section}");
        match parse(&text, Path::new("/p/plcd.toml")) {
            Ok(config) => config.opcua,
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

    #[test]
    fn off_by_default_with_secure_defaults() {
        let off = opcua("");
        assert_eq!(off, OpcuaConfig::default());
        assert_eq!(off.listen, None);
        assert_eq!(opcua("[opcua]\nmax_sessions = 3\n").listen, None, "no listen: off");
        assert_eq!(off.anonymous, Anonymous::None);
        assert_eq!(off.security_policies, OpcuaConfig::DEFAULT_POLICIES);
        assert!(!off.security_policies.contains(&OpcuaPolicy::None), "None only if listed");
        assert_eq!(
            (off.max_sessions, off.max_subscriptions_per_session, off.min_sampling_interval_ms),
            (10, 10, 100)
        );
        assert_eq!((off.max_nodes, off.max_monitored_items_per_session), (10_000, 10_000));
        assert_eq!((off.max_connections, off.max_connections_per_address), (20, 10));
        assert_eq!((off.max_requests_per_second, off.io_timeout_ms), (200, 10_000));
        assert_eq!(off.monitored_items_per_subscription(), 1000);
    }

    #[test]
    fn every_key_is_read() {
        let config = opcua(
            "[opcua]\nlisten = \"127.0.0.1:0\"\nendpoint_host = \"plc1.example\"\n\
             security_policies = [\"None\", \"Aes256_Sha256_RsaPss\"]\nanonymous = \"viewer\"\n\
             max_sessions = 2\nmax_subscriptions_per_session = 3\n\
             max_monitored_items_per_session = 10\nmax_request_bytes = 65536\n\
             min_sampling_interval_ms = 10\nmax_nodes = 5\npki_dir = \"pki\"\n\
             max_connections = 7\nmax_connections_per_address = 3\n\
             max_requests_per_second = 50\nio_timeout_ms = 250\n",
        );
        assert_eq!((config.max_connections, config.max_connections_per_address), (7, 3));
        assert_eq!((config.max_requests_per_second, config.io_timeout_ms), (50, 250));
        assert_eq!(config.listen, Some("127.0.0.1:0".parse().unwrap()));
        assert_eq!(config.endpoint_host.as_deref(), Some("plc1.example"));
        assert_eq!(config.security_policies, [OpcuaPolicy::None, OpcuaPolicy::Aes256Sha256RsaPss]);
        assert_eq!(config.anonymous, Anonymous::Viewer);
        assert_eq!((config.max_sessions, config.max_subscriptions_per_session), (2, 3));
        assert_eq!(config.monitored_items_per_subscription(), 3, "10 / 3 subscriptions");
        assert_eq!((config.max_request_bytes, config.min_sampling_interval_ms), (65536, 10));
        assert_eq!(config.max_nodes, 5);
        assert_eq!(config.pki_dir, Some(PathBuf::from("/p/pki")), "relative to the config");
    }

    #[test]
    fn analog_ranges_take_integers_and_floats_in_their_order() {
        let config = opcua(
            "[[opcua.analog]]\nvariable = \" main.temp \"\nlow = -20\nhigh = 150.5\n\
             [[opcua.analog]]\nvariable = \"main.level\"\nlow = 0.0\nhigh = 1\n",
        );
        let read: Vec<(&str, f64, f64, u32)> = config
            .analog
            .iter()
            .map(|a| (a.variable.name.as_str(), a.range.low, a.range.high, a.variable.line))
            .collect();
        // Lines of the whole file: PROGRAM's two, then each table's header.
        assert_eq!(read, [("main.temp", -20.0, 150.5, 4), ("main.level", 0.0, 1.0, 8)]);
        assert!(OpcuaConfig::default().analog.is_empty(), "none by default");
    }

    #[test]
    fn writable_names_keep_their_place_and_anonymous_may_operate() {
        let config = opcua(
            "[opcua]\nanonymous = \"operator\"\nwritable = [\"main.setpoint\", \" main.recipe \"]\n",
        );
        assert_eq!(config.anonymous, Anonymous::Operator);
        assert_eq!(config.anonymous.role(), Some(crate::users::Role::Operator));
        assert_eq!(Anonymous::None.role(), None);
        let names: Vec<(&str, u32, u32)> =
            config.writable.iter().map(|w| (w.name.as_str(), w.line, w.col)).collect();
        assert_eq!(names, [("main.setpoint", 5, 13), ("main.recipe", 5, 30)], "trimmed");
        assert!(opcua("").writable.is_empty(), "read-only by default");
        let many: Vec<String> =
            (0..=OpcuaConfig::MAX_WRITABLE).map(|i| format!("\"main.v{i}\"")).collect();
        let too_many = errors(&format!("[opcua]\nwritable = [{}]\n", many.join(", ")));
        assert_eq!(too_many.len(), 1, "{too_many:?}");
        assert!(too_many[0].contains("opcua.writable lists 10001 names, at most 10000"));
    }

    #[test]
    fn device_ranges_are_words_or_bits_within_their_area() {
        let config = opcua(
            "[opcua]\n[[opcua.devices]]\ndevice = \"D00100\"\ncount = 2\nwritable = true\n\
             [[opcua.devices]]\ndevice = \"M000E\"\ncount = 3\n",
        );
        let names: Vec<Vec<String>> = config
            .devices
            .iter()
            .map(|range| range.addresses().map(|a| a.to_string()).collect())
            .collect();
        assert_eq!(names, [vec!["D00100", "D00101"], vec!["M000E", "M000F", "M0010"]]);
        assert_eq!(
            config.devices.iter().map(|d| d.writable).collect::<Vec<_>>(),
            [true, false],
            "read-only by default"
        );
        let last = opcua("[opcua]\n[[opcua.devices]]\ndevice = \"D32767\"\ncount = 1\n");
        assert_eq!(last.devices[0].addresses().last().unwrap().to_string(), "D32767");
        let errors = errors(
            "[opcua]\n[[opcua.devices]]\ndevice = \"T0005\"\ncount = 1\n\
             [[opcua.devices]]\ndevice = \"D32767\"\ncount = 2\n\
             [[opcua.devices]]\ndevice = \"D0\"\ncount = 0\n\
             [[opcua.devices]]\ndevice = \"X1\"\ncount = 1\n",
        );
        assert_eq!(errors.len(), 4, "{errors:?}");
        assert!(errors[0].contains("T0005: the OPC UA server serves ranges of P, M, K and D"));
        assert!(errors[1].contains("count 2 from D32767 runs past the end of its area"));
        assert!(errors[2].contains("opcua.devices.count 0 out of range 1..=4096"));
        assert!(errors[3].contains("opcua.devices.device: `X1` is not a device address"));
    }

    #[test]
    fn errors_name_the_key() {
        assert_eq!(
            errors(
                "[opcua]\nlisten = \"localhost:4840\"\nmax_sessions = 0\n\
                 min_sampling_interval_ms = 5\nmax_request_bytes = 100\nmax_nodes = 0\n\
                 max_subscriptions_per_session = 1001\nmax_monitored_items_per_session = 0\n"
            ),
            [
                "/p/plcd.toml:4:10: error: opcua.listen \"localhost:4840\" is not an IP address and \
                 port (\"127.0.0.1:4840\", \"0.0.0.0:4840\", \"[::1]:4840\"); leave it out to \
                 turn the server off",
                "/p/plcd.toml:5:16: error: opcua.max_sessions 0 out of range 1..=1000",
                "/p/plcd.toml:6:28: error: opcua.min_sampling_interval_ms 5 out of range 10..=60000",
                "/p/plcd.toml:7:21: error: opcua.max_request_bytes 100 out of range 65536..=67108864",
                "/p/plcd.toml:8:13: error: opcua.max_nodes 0 out of range 1..=1000000",
                "/p/plcd.toml:9:33: error: opcua.max_subscriptions_per_session 1001 out of range \
                 1..=1000",
                "/p/plcd.toml:10:35: error: opcua.max_monitored_items_per_session 0 out of range \
                 1..=1000000",
            ]
        );
        let policy = errors("[opcua]\nsecurity_policies = [\"Basic128Rsa15\"]\n");
        assert!(
            policy[0].contains("opcua.security_policies") && policy[0].contains("Basic128Rsa15"),
            "{policy:?}"
        );
        assert_eq!(
            errors("[opcua]\nsecurity_policies = [\"None\", \"None\"]\n"),
            ["/p/plcd.toml:4:30: error: opcua.security_policies: None is listed twice"]
        );
        assert!(errors("[opcua]\nsecurity_policies = []\n")[0]
            .contains("opcua.security_policies must list at least one policy"));
        assert!(errors("[opcua]\nanonymous = \"guest\"\n")[0].contains("opcua.anonymous"));
        assert!(errors("[opcua]\npki_dir = \" \"\n")[0].contains("opcua.pki_dir must not be empty"));
        assert!(errors("[opcua]\nendpoint_host = \"a:1\"\n")[0].contains("opcua.endpoint_host"));
        assert!(errors("[opcua]\nport = 4840\n")[0].contains("[opcua]: unknown key `port`"));
    }
}
