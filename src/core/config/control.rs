//! `[control]`: the daemon's control socket.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, resolve, widen, Ctx};
use super::Sink;

/// `[control]`: the daemon's control socket (`plcctl`, scripts, HMI gateways).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ControlConfig {
    /// `enabled`: serve the control socket; default true.
    pub enabled: bool,
    /// `socket`: the socket's path, resolved against the config file's directory when relative
    /// (this is the resolved path; an absolute one is kept), not empty, at most
    /// [`ControlConfig::MAX_SOCKET_PATH`] bytes; default `None`: `/run/plcd/plcd.sock`, or the
    /// fallbacks of `plcd_ipc::default_socket_paths` when that cannot be
    /// created.
    pub socket: Option<PathBuf>,
    /// `group`: the group that may connect (the socket is 0660, owned by the daemon's user and
    /// this group), not empty; default `None`: the daemon's own group.
    pub group: Option<String>,
    /// `max_clients`: connections served at once, 1..=1024; default 64. More are refused with
    /// a `busy` error.
    pub max_clients: u32,
    /// `max_request_bytes`: the longest request line, 256..=1048576; default 65536. A longer
    /// line is answered with `too_long` and the connection closed.
    pub max_request_bytes: u32,
    /// `idle_timeout_s`: a connection that sends no complete request for this long is closed,
    /// 0..=4294967295 s, 0 = never; default 300.
    pub idle_timeout_s: u32,
}

impl ControlConfig {
    pub const MAX_CLIENTS: RangeInclusive<u32> = 1..=1024;
    pub const MAX_REQUEST_BYTES: RangeInclusive<u32> = 256..=1_048_576;
    /// The longest path a Unix socket address holds (`sun_path` is 108 bytes with its NUL).
    pub const MAX_SOCKET_PATH: usize = 107;
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig {
            enabled: true,
            socket: None,
            group: None,
            max_clients: 64,
            max_request_bytes: 65_536,
            idle_timeout_s: 300,
        }
    }
}

/// `[control]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawControl {
    pub enabled: Option<bool>,
    pub socket: Option<Spanned<String>>,
    pub group: Option<Spanned<String>>,
    pub max_clients: Option<Spanned<i64>>,
    pub max_request_bytes: Option<Spanned<i64>>,
    pub idle_timeout_s: Option<Spanned<i64>>,
}

/// `[control]`.
pub(super) fn validate(sink: &mut Sink, raw: RawControl, config: &Path) -> Option<ControlConfig> {
    let ctx = Ctx::Section("control");
    let default = ControlConfig::default();
    let max_clients = int_or(
        sink,
        &ctx,
        "max_clients",
        raw.max_clients,
        widen(ControlConfig::MAX_CLIENTS),
        default.max_clients,
    );
    let max_request_bytes = int_or(
        sink,
        &ctx,
        "max_request_bytes",
        raw.max_request_bytes,
        widen(ControlConfig::MAX_REQUEST_BYTES),
        default.max_request_bytes,
    );
    let idle_timeout_s = int_or(
        sink,
        &ctx,
        "idle_timeout_s",
        raw.idle_timeout_s,
        0..=i64::from(u32::MAX),
        default.idle_timeout_s,
    );
    let socket = match raw.socket {
        None => Some(None),
        Some(socket) if socket.get_ref().trim().is_empty() => {
            sink.error(socket.span().start, format!("{} must not be empty", ctx.key("socket")));
            None
        }
        Some(socket) => {
            let resolved = resolve(config, socket.get_ref());
            let bytes = resolved.as_os_str().len();
            if bytes > ControlConfig::MAX_SOCKET_PATH {
                let message = format!(
                    "{} {:?} is {bytes} bytes long as resolved ({}); a Unix socket path holds \
                     at most {}",
                    ctx.key("socket"),
                    socket.get_ref(),
                    resolved.display(),
                    ControlConfig::MAX_SOCKET_PATH,
                );
                sink.error(socket.span().start, message);
                None
            } else {
                Some(Some(resolved))
            }
        }
    };
    let group = match raw.group {
        None => Some(None),
        Some(group) if group.get_ref().trim().is_empty() => {
            sink.error(group.span().start, format!("{} must not be empty", ctx.key("group")));
            None
        }
        Some(group) => Some(Some(group.into_inner())),
    };
    Some(ControlConfig {
        enabled: raw.enabled.unwrap_or(default.enabled),
        socket: socket?,
        group: group?,
        max_clients: max_clients?,
        max_request_bytes: max_request_bytes?,
        idle_timeout_s: idle_timeout_s?,
    })
}
