//! plcd-ipc: the control protocol between `plcctl` (or any client: a script, an HMI gateway)
//! and the daemon's control socket (docs/CONTROL.md). It is the only thing both sides share,
//! and it depends on nothing but serde: types and framing, no I/O, so that a client builds
//! without the daemon.
//!
//! # Framing
//!
//! A Unix stream socket carrying JSON Lines: the client writes one request object on one line
//! (`\n`-terminated, at most [`MAX_REQUEST_BYTES`] by default), the daemon answers with exactly
//! one response line, in order. A client may send its next request once it has the answer.
//!
//! # Versioning
//!
//! Every line carries `"v"`: the protocol version, [`VERSION`]. The daemon answers a request
//! of another version with an error of kind `version` (and its own version in the line), so
//! that an old `plcctl` talking to a new daemon fails clearly instead of misreading fields.
//! Within one version, fields are only ever added; readers ignore fields they do not know.
//!
//! ```text
//! → {"v":1,"cmd":"get","devices":["D00010","P0040","main.t1.ET"]}
//! ← {"v":1,"ok":{"kind":"values","scan":1234,"values":[{"dev":"D00010","value":7},{"dev":"P0040","value":1},{"dev":"main.t1.ET","value":"T#1s500ms","type":"TIME"}]}}
//! → {"v":1,"cmd":"run"}
//! ← {"v":1,"error":{"kind":"refused","message":"the RUN/STOP switch is at RUN: …"}}
//! ```

#![forbid(unsafe_code)]

use serde::{Deserialize, Serialize};

/// The protocol version this build speaks.
pub const VERSION: u32 = 1;

/// The default upper bound of one request line, newline included.
pub const MAX_REQUEST_BYTES: usize = 64 * 1024;

/// One request line: the version and the request.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RequestLine {
    pub v: u32,
    #[serde(flatten)]
    pub request: Request,
}

impl RequestLine {
    pub fn new(request: Request) -> RequestLine {
        RequestLine { v: VERSION, request }
    }
}

/// What a client asks for. Tagged by `"cmd"`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "cmd", rename_all = "snake_case")]
pub enum Request {
    /// Mode, error, scan figures, task figures, forces, debug state: [`Reply::Status`].
    Status,
    /// RUN (also out of DEBUG, keeping device memory). [`Reply::Mode`].
    Run,
    /// STOP. [`Reply::Mode`].
    Stop,
    /// Clears a latched error and goes to STOP; `cold` also clears retained memory.
    /// [`Reply::Mode`].
    Reset {
        #[serde(default)]
        cold: bool,
    },
    /// Current values, from a snapshot taken at a scan boundary after the request. Each entry
    /// is a device or a Structured Text variable name (`main.pid.out`, `main.buf[3]`, a global);
    /// a struct, array, FB or program instance stands for each of its variables. Values come in
    /// this order. [`Reply::Values`].
    Get { devices: Vec<String> },
    /// Writes devices and variables at the next END processing, all at the same one.
    /// [`Reply::Written`].
    Set { writes: Vec<NamedValue> },
    /// Forces a P bit (`dev` a P bit, or a BOOL variable located at one): a forced input
    /// overrides the refreshed image, a forced output overrides the program. [`Reply::Forces`].
    Force { dev: String, value: i32 },
    /// Removes the force of one device (or of the BOOL variable located at it).
    /// [`Reply::Forces`].
    Unforce { dev: String },
    /// Removes every force. [`Reply::Forces`].
    UnforceAll,
    /// The force table. [`Reply::Forces`].
    Forces,
    /// Validates the project at `config` (an absolute path the daemon can read); in STOP
    /// replaces the running project, with `online` in RUN at an END boundary keeping device
    /// memory, refused with the reasons when the layout changed. [`Reply::Loaded`].
    Load {
        config: String,
        #[serde(default)]
        online: bool,
    },
    /// DEBUG mode (XGB §5.2): the program runs only by `step` and `continue`. [`Reply::Debug`].
    Debug,
    /// In DEBUG, paused before an instruction: runs to the next statement of that task on
    /// another line (calls are stepped over); paused between two scans, or with `scan`: to the
    /// end of the current or the next scan. A breakpoint on the way stops it first. Answered
    /// once execution is paused again: [`Reply::Debug`].
    Step {
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        scan: bool,
    },
    /// In DEBUG: runs until a breakpoint is reached. [`Reply::Debug`].
    Continue,
    /// Sets a breakpoint: `PROGRAM:LINE`, `FILE:LINE` (a Structured Text file: wherever its
    /// code runs), `PROGRAM:LABEL n`, `LINE` or `LABEL n` (the program may be left out when
    /// only one program fits). [`Reply::Debug`].
    Break { at: String },
    /// Removes a breakpoint, or all of them when `at` is absent. [`Reply::Debug`].
    Unbreak {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        at: Option<String>,
    },
}

impl Request {
    /// The `cmd` tag, for logs.
    pub fn name(&self) -> &'static str {
        match self {
            Request::Status => "status",
            Request::Run => "run",
            Request::Stop => "stop",
            Request::Reset { .. } => "reset",
            Request::Get { .. } => "get",
            Request::Set { .. } => "set",
            Request::Force { .. } => "force",
            Request::Unforce { .. } => "unforce",
            Request::UnforceAll => "unforce_all",
            Request::Forces => "forces",
            Request::Load { .. } => "load",
            Request::Debug => "debug",
            Request::Step { .. } => "step",
            Request::Continue => "continue",
            Request::Break { .. } => "break",
            Request::Unbreak { .. } => "unbreak",
        }
    }
}

/// One response line: the version and either `ok` or `error`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResponseLine {
    pub v: u32,
    #[serde(flatten)]
    pub outcome: Outcome,
}

impl ResponseLine {
    pub fn ok(reply: Reply) -> ResponseLine {
        ResponseLine { v: VERSION, outcome: Outcome::Ok(reply) }
    }

    pub fn error(kind: ErrorKind, message: impl Into<String>) -> ResponseLine {
        ResponseLine::failure(Failure::new(kind, message))
    }

    pub fn failure(failure: Failure) -> ResponseLine {
        ResponseLine { v: VERSION, outcome: Outcome::Error(failure) }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    Ok(Reply),
    Error(Failure),
}

/// Why a request failed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Failure {
    pub kind: ErrorKind,
    /// One sentence for a human.
    pub message: String,
    /// Every diagnostic behind it (`path:line:col: error: …` of a refused load, the reasons an
    /// online change is refused), one per entry.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub details: Vec<String>,
}

impl Failure {
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Failure {
        Failure { kind, message: message.into(), details: Vec::new() }
    }

    pub fn with_details(mut self, details: Vec<String>) -> Failure {
        self.details = details;
        self
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorKind {
    /// Not a JSON object, not valid UTF-8, or an unknown `cmd`.
    BadRequest,
    /// The line exceeded the daemon's request limit; the connection is closed after this.
    TooLong,
    /// The request's `v` is not the daemon's [`VERSION`].
    Version,
    /// A device, value, breakpoint or project that is not valid.
    Invalid,
    /// Valid, but not allowed now: the mode rules, a latched error, an incompatible online
    /// change, a mode the command needs.
    Refused,
    /// Too many clients or queued commands; try again.
    Busy,
    /// The peer's credentials are not allowed (root, the daemon's user, or the socket's group).
    Denied,
    /// The daemon could not do it (it is shutting down, the scan thread did not answer).
    Unavailable,
}

/// A device and a value: bits are 0/1, words their signed 16-bit value.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceValue {
    pub dev: String,
    pub value: i32,
}

/// A value of a device or of a variable of any type, as the `plcd sim` trace writes it:
/// a JSON number for integers, bit strings, reals and devices (`BOOL` and bits as 0 or 1); a
/// string for `TIME` (an IEC literal, `"T#1s500ms"`), an enumeration (its value's name), a
/// `STRING` (its characters) and a real that is not finite (`"NaN"`, `"inf"`, `"-inf"`).
///
/// Written by a client, a number or a string is read against the variable's type: `5`, `"5"`,
/// `"16#FF"`, `"TRUE"`, `1.5`, `"T#2s"`, `"Running"`, and for a `STRING` its text (an IEC
/// literal in single quotes, `"'a$'b'"`, is unescaped). A device takes a JSON integer.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Value {
    Number(serde_json::Number),
    Text(String),
}

impl Value {
    /// The integer, if the value is one that fits an `i64`.
    pub fn as_i64(&self) -> Option<i64> {
        match self {
            Value::Number(n) => n.as_i64(),
            Value::Text(_) => None,
        }
    }

    /// The value as text: a number as JSON writes it, a string as it is.
    pub fn text(&self) -> std::borrow::Cow<'_, str> {
        match self {
            Value::Number(n) => std::borrow::Cow::Owned(n.to_string()),
            Value::Text(t) => std::borrow::Cow::Borrowed(t),
        }
    }
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text())
    }
}

impl From<i32> for Value {
    fn from(n: i32) -> Value {
        Value::Number(n.into())
    }
}

impl From<i64> for Value {
    fn from(n: i64) -> Value {
        Value::Number(n.into())
    }
}

impl From<u64> for Value {
    fn from(n: u64) -> Value {
        Value::Number(n.into())
    }
}

impl From<&str> for Value {
    fn from(text: &str) -> Value {
        Value::Text(text.to_string())
    }
}

/// A device or a variable and its value: what `get` answers and `set` writes. A device's value
/// is a JSON integer (bits 0/1, words their signed 16-bit value) and it has no `type`; a
/// variable's value is typed ([`Value`]) and, in answers, `type` names its type (`DINT`,
/// `STRING[80]`, `TIME`, an enumeration's name).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct NamedValue {
    /// The device or the variable's full name (answers give a variable the spelling of its
    /// declaration).
    pub dev: String,
    pub value: Value,
    #[serde(rename = "type", default, skip_serializing_if = "Option::is_none")]
    pub ty: Option<String>,
}

impl NamedValue {
    /// A device's value (no type).
    pub fn device(dev: impl Into<String>, value: i32) -> NamedValue {
        NamedValue { dev: dev.into(), value: value.into(), ty: None }
    }

    /// A value to write (the daemon knows the type).
    pub fn write(dev: impl Into<String>, value: Value) -> NamedValue {
        NamedValue { dev: dev.into(), value, ty: None }
    }
}

/// A successful answer. Tagged by `"kind"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Reply {
    Status(Box<Status>),
    /// The mode after the command.
    Mode {
        mode: ModeName,
    },
    /// Values of the requested devices and variables, in request order (a prefix expanded in
    /// place), as of the END of scan `scan`.
    Values {
        scan: u64,
        values: Vec<NamedValue>,
    },
    /// The writes were applied at the END of scan `scan`.
    Written {
        scan: u64,
        count: usize,
    },
    /// The force table after the command.
    Forces {
        forces: Vec<DeviceValue>,
    },
    /// The project was validated and swapped in.
    Loaded {
        online: bool,
        programs: usize,
        tasks: usize,
        mode: ModeName,
    },
    /// The debugger's state after the command.
    Debug(DebugState),
}

/// The operating mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum ModeName {
    Run,
    Stop,
    Error,
    Debug,
}

impl ModeName {
    pub fn as_str(self) -> &'static str {
        match self {
            ModeName::Run => "RUN",
            ModeName::Stop => "STOP",
            ModeName::Error => "ERROR",
            ModeName::Debug => "DEBUG",
        }
    }
}

/// The position of the RUN/STOP key switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum SwitchName {
    Run,
    Stop,
}

/// `status`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// The daemon's version.
    pub version: String,
    /// The config file the running project came from.
    pub config: String,
    /// `"sim"` or `"gpiocdev"`.
    pub backend: String,
    pub uptime_ms: u64,
    pub mode: ModeName,
    /// The latched error of ERROR mode, or the last operation error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorInfo>,
    /// The key switch, when one is configured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub switch: Option<SwitchName>,
    /// Whether remote RUN/STOP/DEBUG are accepted now (no switch, or the switch at STOP).
    pub remote_allowed: bool,
    pub scan: ScanFigures,
    pub tasks: Vec<TaskFigures>,
    /// Input edges lost (kernel sequence gaps, a full queue).
    pub lost_edges: u64,
    /// Cycle timer expirations that came while the previous one was still unread.
    pub missed_timer_expirations: u64,
    /// Times the watchdog thread had to make the outputs safe.
    pub watchdog_trips: u64,
    /// Forced devices.
    pub forces: Vec<DeviceValue>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub debug: Option<DebugState>,
    /// The remote I/O devices (`[[remote]]`), in config order; absent when there are none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub remotes: Vec<RemoteFigures>,
    /// The Sparkplug B edge node (`[mqtt]`); absent when it is off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mqtt: Option<MqttFigures>,
}

/// The Sparkplug B edge node's state and counters since start.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MqttFigures {
    /// `spBv1.0/GROUP/NODE`.
    pub node: String,
    /// The broker connected to, or tried.
    pub broker: String,
    /// `connecting`, `waiting` (connected; no copy of the PLC yet, or the primary host
    /// offline) or `born`.
    pub state: String,
    /// Connections the brokers took.
    pub connects: u64,
    /// Connection attempts that failed and connections lost.
    pub failures: u64,
    /// NBIRTHs (each connect, each rebirth).
    pub births: u64,
    /// NDATA and DDATA published live.
    pub data: u64,
    /// DATA messages waiting for the next connection now.
    pub queued: u64,
    /// DATA messages lost: the store full, the metrics changed before they went, the client's
    /// queue full.
    pub dropped: u64,
    /// Commands taken.
    pub commands: u64,
    /// Writes refused (not writable, unknown, wrong type, or by the request handler).
    pub refused: u64,
    /// Commands and STATE messages that were not understood or too long.
    pub malformed: u64,
    /// The connection failure under way, as logged; absent while a broker is connected.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_error: Option<String>,
}

/// One remote I/O device's figures since start.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RemoteFigures {
    pub name: String,
    /// `tcp HOST:PORT` or `rtu PORT`.
    pub transport: String,
    /// `starting` (not every read table read yet), `online`, `lost`.
    pub state: String,
    /// Exchanges tried.
    pub requests: u64,
    /// Exchanges that failed.
    pub failures: u64,
    /// Failures by kind (`timeout`, `exception`, `wrong_unit`, `wrong_transaction`,
    /// `bad_crc`, `garbage`, `connect`, `closed`, `io`), the kinds seen only.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<(String, u64)>,
    /// Answers that came after their request had timed out, dropped.
    pub late: u64,
    /// Writes that succeeded.
    pub writes: u64,
    /// Times the device was lost.
    pub losses: u64,
    /// The last failure, as logged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_error: Option<String>,
    /// How long ago the last failure was, ms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_error_age_ms: Option<u64>,
    /// Round trips of answered exchanges.
    pub round_trip: Percentiles,
}

/// An error as the PLC reports it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ErrorInfo {
    /// `WDT`, `CONGESTION`, or an operation error code such as `3405H`.
    pub code: String,
    pub detail: String,
}

/// Scan time, in ns.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ScanFigures {
    /// Scans since RUN started.
    pub count: u64,
    pub cur_ns: u64,
    pub min_ns: u64,
    pub max_ns: u64,
    pub p50_ns: u64,
    pub p99_ns: u64,
}

/// Percentiles of a histogram, in ns (upper bucket edges, never optimistic).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Percentiles {
    pub p50_ns: u64,
    pub p99_ns: u64,
    pub p999_ns: u64,
    pub max_ns: u64,
}

/// One task's figures since RUN.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TaskFigures {
    pub name: String,
    /// `scan`, `init`, `cycle`, `io`, `device`.
    pub kind: String,
    pub runs: u64,
    pub ignored: u64,
    pub overruns: u64,
    /// From the start condition to the first instruction.
    pub latency: Percentiles,
    /// Own execution time per run.
    pub exec: Percentiles,
}

/// The debugger (DEBUG mode).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct DebugState {
    /// Where execution waits: before an instruction at a breakpoint, or `None` between two
    /// scans (or while running under `continue`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paused_at: Option<Location>,
    /// True while `continue` runs and no breakpoint was reached yet.
    pub running: bool,
    /// Scans completed since RUN.
    pub scan: u64,
    /// The breakpoints, as `PROGRAM:LINE` (instruction list) or `FILE:LINE` (Structured Text).
    pub breakpoints: Vec<String>,
}

/// An instruction in a program.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Location {
    pub program: String,
    pub line: u32,
    /// The name of the source file `line` is in, for Structured Text (whose program may run
    /// code of other files); empty for the instruction list, whose line is the program's.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub file: String,
    /// The task executing it.
    pub task: String,
    /// The source line, as written.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
    /// The devices the line names, with their values at the pause.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub devices: Vec<DeviceValue>,
}

/// Parses one line as a request. The error is the failure to send back.
pub fn parse_request(line: &[u8]) -> Result<Request, Failure> {
    let text = std::str::from_utf8(line)
        .map_err(|_| Failure::new(ErrorKind::BadRequest, "the request is not UTF-8"))?;
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        Failure::new(ErrorKind::BadRequest, format!("the request is not JSON: {e}"))
    })?;
    let v = value.get("v").and_then(serde_json::Value::as_u64);
    match v {
        Some(v) if v == u64::from(VERSION) => {}
        Some(v) => {
            return Err(Failure::new(
                ErrorKind::Version,
                format!("protocol version {v} is not supported; this daemon speaks {VERSION}"),
            ))
        }
        None => {
            return Err(Failure::new(
                ErrorKind::BadRequest,
                "the request has no protocol version \"v\"",
            ))
        }
    }
    serde_json::from_value::<RequestLine>(value)
        .map(|line| line.request)
        .map_err(|e| Failure::new(ErrorKind::BadRequest, format!("bad request: {e}")))
}

/// One line of JSON, newline included.
pub fn to_line<T: Serialize>(value: &T) -> Vec<u8> {
    let mut line = serde_json::to_vec(value).expect("protocol types always serialize");
    line.push(b'\n');
    line
}

/// Where the daemon puts its socket when `[control] socket` is not set, and where `plcctl`
/// looks without `--socket`: `/run/plcd/plcd.sock` (the systemd service's runtime directory),
/// or, for a daemon that cannot create that (not root, no service), `$XDG_RUNTIME_DIR/plcd.sock`
/// and then `/tmp/plcd-$UID/plcd.sock`. The first is the one to use; the others are fallbacks
/// in this order.
pub fn default_socket_paths(uid: u32, xdg_runtime_dir: Option<&str>) -> Vec<String> {
    let mut paths = vec!["/run/plcd/plcd.sock".to_string()];
    if let Some(dir) = xdg_runtime_dir.filter(|d| !d.is_empty()) {
        paths.push(format!("{dir}/plcd.sock"));
    }
    paths.push(format!("/tmp/plcd-{uid}/plcd.sock"));
    paths
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip_request(request: Request) {
        let line = to_line(&RequestLine::new(request.clone()));
        assert_eq!(line.last(), Some(&b'\n'));
        assert!(!line[..line.len() - 1].contains(&b'\n'), "one line");
        assert_eq!(parse_request(&line[..line.len() - 1]), Ok(request));
    }

    #[test]
    fn every_request_round_trips() {
        for request in [
            Request::Status,
            Request::Run,
            Request::Stop,
            Request::Reset { cold: false },
            Request::Reset { cold: true },
            Request::Get { devices: vec!["D00010".into(), "P0040".into()] },
            Request::Set { writes: vec![NamedValue::device("D00001", -5)] },
            Request::Set {
                writes: vec![
                    NamedValue::write("main.t", Value::from("T#2s")),
                    NamedValue::write(
                        "main.r",
                        Value::Number(serde_json::Number::from_f64(1.5).unwrap()),
                    ),
                    NamedValue::write("main.big", Value::from(u64::MAX)),
                    NamedValue::write("main.small", Value::from(i64::MIN)),
                ],
            },
            Request::Get { devices: vec!["main.m[1,2]".into(), "total".into()] },
            Request::Force { dev: "P0000".into(), value: 1 },
            Request::Unforce { dev: "P0000".into() },
            Request::UnforceAll,
            Request::Forces,
            Request::Load { config: "/etc/plcd/plcd.toml".into(), online: true },
            Request::Debug,
            Request::Step { scan: false },
            Request::Step { scan: true },
            Request::Continue,
            Request::Break { at: "main:12".into() },
            Request::Unbreak { at: Some("main:12".into()) },
            Request::Unbreak { at: None },
        ] {
            round_trip_request(request);
        }
    }

    #[test]
    fn the_wire_format_is_pinned() {
        assert_eq!(
            String::from_utf8(to_line(&RequestLine::new(Request::Get {
                devices: vec!["D00010".into()]
            })))
            .unwrap(),
            "{\"v\":1,\"cmd\":\"get\",\"devices\":[\"D00010\"]}\n"
        );
        assert_eq!(
            String::from_utf8(to_line(&ResponseLine::ok(Reply::Mode { mode: ModeName::Run })))
                .unwrap(),
            "{\"v\":1,\"ok\":{\"kind\":\"mode\",\"mode\":\"RUN\"}}\n"
        );
        assert_eq!(
            String::from_utf8(to_line(&ResponseLine::error(ErrorKind::Refused, "no"))).unwrap(),
            "{\"v\":1,\"error\":{\"kind\":\"refused\",\"message\":\"no\"}}\n"
        );
    }

    #[test]
    fn defaults_and_unknown_fields() {
        assert_eq!(parse_request(br#"{"v":1,"cmd":"reset"}"#), Ok(Request::Reset { cold: false }));
        assert_eq!(
            parse_request(br#"{"v":1,"cmd":"status","from":"a newer client"}"#),
            Ok(Request::Status)
        );
    }

    #[test]
    fn every_reply_round_trips() {
        let status = Status {
            version: "0.1.0".into(),
            config: "/etc/plcd/plcd.toml".into(),
            backend: "sim".into(),
            uptime_ms: 1234,
            mode: ModeName::Error,
            error: Some(ErrorInfo { code: "WDT".into(), detail: "scan 3".into() }),
            switch: Some(SwitchName::Stop),
            remote_allowed: true,
            scan: ScanFigures { count: 3, cur_ns: 1, min_ns: 1, max_ns: 2, p50_ns: 1, p99_ns: 2 },
            tasks: vec![TaskFigures {
                name: "fast".into(),
                kind: "cycle".into(),
                runs: 10,
                ignored: 1,
                overruns: 1,
                latency: Percentiles { p50_ns: 1, p99_ns: 2, p999_ns: 3, max_ns: 4 },
                exec: Percentiles::default(),
            }],
            lost_edges: 0,
            missed_timer_expirations: 0,
            watchdog_trips: 1,
            forces: vec![DeviceValue { dev: "P0000".into(), value: 1 }],
            debug: Some(DebugState {
                paused_at: Some(Location {
                    program: "main".into(),
                    line: 3,
                    file: String::new(),
                    task: "scan".into(),
                    source: "LOAD P0000".into(),
                    devices: vec![DeviceValue { dev: "P0000".into(), value: 0 }],
                }),
                running: false,
                scan: 7,
                breakpoints: vec!["main:3".into()],
            }),
            remotes: vec![RemoteFigures {
                name: "rack1".into(),
                transport: "tcp 127.0.0.1:1502".into(),
                state: "lost".into(),
                requests: 10,
                failures: 2,
                faults: vec![("timeout".into(), 2)],
                late: 1,
                writes: 3,
                losses: 1,
                last_error: Some("read of coils 0..=7: no answer in time".into()),
                last_error_age_ms: Some(1500),
                round_trip: Percentiles { p50_ns: 1, p99_ns: 2, p999_ns: 3, max_ns: 4 },
            }],
            mqtt: Some(MqttFigures {
                node: "spBv1.0/plant/press7".into(),
                broker: "mqtt://127.0.0.1:1883".into(),
                state: "born".into(),
                connects: 2,
                failures: 1,
                births: 3,
                data: 100,
                queued: 0,
                dropped: 4,
                commands: 5,
                refused: 1,
                malformed: 0,
                last_error: Some("connection refused".into()),
            }),
        };
        for reply in [
            Reply::Status(Box::new(status)),
            Reply::Mode { mode: ModeName::Debug },
            Reply::Values { scan: 9, values: vec![NamedValue::device("D00000", 3)] },
            Reply::Values {
                scan: 9,
                values: vec![
                    NamedValue {
                        dev: "main.t1.ET".into(),
                        value: "T#1s500ms".into(),
                        ty: Some("TIME".into()),
                    },
                    NamedValue {
                        dev: "main.r".into(),
                        value: Value::Number(serde_json::Number::from_f64(0.1).unwrap()),
                        ty: Some("REAL".into()),
                    },
                    NamedValue {
                        dev: "main.r2".into(),
                        value: "NaN".into(),
                        ty: Some("LREAL".into()),
                    },
                    NamedValue {
                        dev: "main.u".into(),
                        value: u64::MAX.into(),
                        ty: Some("ULINT".into()),
                    },
                    NamedValue {
                        dev: "main.s".into(),
                        value: "it's".into(),
                        ty: Some("STRING[80]".into()),
                    },
                ],
            },
            Reply::Written { scan: 9, count: 1 },
            Reply::Forces { forces: vec![] },
            Reply::Loaded { online: true, programs: 2, tasks: 1, mode: ModeName::Run },
            Reply::Debug(DebugState::default()),
        ] {
            let line = to_line(&ResponseLine::ok(reply.clone()));
            let back: ResponseLine = serde_json::from_slice(&line).unwrap();
            assert_eq!(back, ResponseLine::ok(reply));
        }
        let mut failure = ResponseLine::error(ErrorKind::Invalid, "2 errors");
        if let Outcome::Error(f) = &mut failure.outcome {
            f.details = vec!["a.il:1:1: error: x".into(), "a.il:2:1: error: y".into()];
        }
        let back: ResponseLine = serde_json::from_slice(&to_line(&failure)).unwrap();
        assert_eq!(back, failure);
    }

    #[test]
    fn values_keep_the_integer_form_of_devices() {
        // The form of the first clients: a device and a JSON integer, no type.
        assert_eq!(
            parse_request(br#"{"v":1,"cmd":"set","writes":[{"dev":"D00001","value":-5}]}"#),
            Ok(Request::Set { writes: vec![NamedValue::device("D00001", -5)] })
        );
        let reply = Reply::Values { scan: 3, values: vec![NamedValue::device("D00010", 7)] };
        assert_eq!(
            serde_json::to_string(&reply).unwrap(),
            r#"{"kind":"values","scan":3,"values":[{"dev":"D00010","value":7}]}"#
        );
        let old: Reply = serde_json::from_str(
            r#"{"kind":"values","scan":3,"values":[{"dev":"D00010","value":-7}],"more":1}"#,
        )
        .unwrap();
        assert_eq!(old, Reply::Values { scan: 3, values: vec![NamedValue::device("D00010", -7)] });
    }

    #[test]
    fn typed_values_on_the_wire() {
        let line = |values: Vec<NamedValue>| {
            serde_json::to_string(&Reply::Values { scan: 1, values }).unwrap()
        };
        let typed = |dev: &str, value: Value, ty: &str| NamedValue {
            dev: dev.into(),
            value,
            ty: Some(ty.into()),
        };
        let real = |x: f64| Value::Number(serde_json::Number::from_f64(x).unwrap());
        assert_eq!(
            line(vec![
                typed("main.t", "T#1s500ms".into(), "TIME"),
                typed("main.r", real(0.1), "REAL"),
                typed("main.x", real(1.0), "LREAL"),
                typed("main.n", "-inf".into(), "REAL"),
                typed("main.u", u64::MAX.into(), "ULINT"),
                typed("main.i", i64::MIN.into(), "LINT"),
                typed("main.mode", "Running".into(), "Mode"),
                typed("main.s", "a\"b".into(), "STRING[10]"),
            ]),
            concat!(
                r#"{"kind":"values","scan":1,"values":["#,
                r#"{"dev":"main.t","value":"T#1s500ms","type":"TIME"},"#,
                r#"{"dev":"main.r","value":0.1,"type":"REAL"},"#,
                r#"{"dev":"main.x","value":1.0,"type":"LREAL"},"#,
                r#"{"dev":"main.n","value":"-inf","type":"REAL"},"#,
                r#"{"dev":"main.u","value":18446744073709551615,"type":"ULINT"},"#,
                r#"{"dev":"main.i","value":-9223372036854775808,"type":"LINT"},"#,
                r#"{"dev":"main.mode","value":"Running","type":"Mode"},"#,
                r#"{"dev":"main.s","value":"a\"b","type":"STRING[10]"}]}"#
            )
        );
        // Numbers and strings both parse, whatever the field order.
        let parsed = parse_request(
            br#"{"v":1,"cmd":"set","writes":[{"value":2.5,"dev":"main.r"},{"dev":"main.t","value":"T#2s"},{"dev":"main.u","value":18446744073709551615}]}"#,
        )
        .unwrap();
        let Request::Set { writes } = parsed else { panic!("{parsed:?}") };
        assert_eq!(writes[0].value, real(2.5));
        assert_eq!(writes[0].value.text(), "2.5");
        assert_eq!(writes[1].value, Value::from("T#2s"));
        assert_eq!(writes[2].value, Value::from(u64::MAX));
        assert_eq!(writes[2].value.as_i64(), None);
        assert_eq!(Value::from(-3).as_i64(), Some(-3));
        assert_eq!(Value::from(7).to_string(), "7");
        // Neither a number nor a string.
        let kind = |b: &[u8]| parse_request(b).unwrap_err().kind;
        assert_eq!(
            kind(br#"{"v":1,"cmd":"set","writes":[{"dev":"a","value":true}]}"#),
            ErrorKind::BadRequest
        );
        assert_eq!(
            kind(br#"{"v":1,"cmd":"set","writes":[{"dev":"a","value":[1]}]}"#),
            ErrorKind::BadRequest
        );
    }

    #[test]
    fn bad_requests_are_answered_not_panicked_on() {
        let kind = |bytes: &[u8]| parse_request(bytes).unwrap_err().kind;
        assert_eq!(kind(b"\xff\xfe"), ErrorKind::BadRequest);
        assert_eq!(kind(b"status"), ErrorKind::BadRequest);
        assert_eq!(kind(b"[1,2]"), ErrorKind::BadRequest);
        assert_eq!(kind(br#"{"cmd":"status"}"#), ErrorKind::BadRequest);
        assert_eq!(kind(br#"{"v":2,"cmd":"status"}"#), ErrorKind::Version);
        assert_eq!(kind(br#"{"v":1,"cmd":"format_disk"}"#), ErrorKind::BadRequest);
        assert_eq!(kind(br#"{"v":1,"cmd":"get","devices":"D0"}"#), ErrorKind::BadRequest);
        assert_eq!(kind(br#"{"v":1,"cmd":"get","devices":[1e999]}"#), ErrorKind::BadRequest);
    }

    #[test]
    fn socket_paths() {
        assert_eq!(
            default_socket_paths(1000, Some("/run/user/1000")),
            ["/run/plcd/plcd.sock", "/run/user/1000/plcd.sock", "/tmp/plcd-1000/plcd.sock"]
        );
        assert_eq!(
            default_socket_paths(0, Some("")),
            ["/run/plcd/plcd.sock", "/tmp/plcd-0/plcd.sock"]
        );
    }
}
