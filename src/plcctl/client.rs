//! A client of the daemon's control socket: connect, send one request, read its one answer,
//! and turn everything that can go wrong on the way into one [`ClientError`].
//!
//! The framing and the types are those of [`plcd_ipc`]; this module adds
//! timeouts, checks the protocol version and the kind of the reply, and keeps the `ok` value
//! as the daemon sent it (fields this build does not know included) for `--json`.

use std::io::{self, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::sys::socket::{self, sockopt, AddressFamily, SockFlag, SockType, UnixAddr};
use nix::sys::time::TimeVal;

use plcd_core::duration::format_ns;
use plcd_ipc::{self as protocol, ErrorKind, Failure, Reply, Request, RequestLine};

use super::{EXIT_DAEMON_ERROR, EXIT_PROTOCOL, EXIT_UNREACHABLE};

/// The longest answer line accepted. A status of thousands of tasks is far below it; more
/// means the peer is not a plcd.
pub const MAX_RESPONSE_BYTES: usize = 16 * 1024 * 1024;

/// How much of a malformed answer an error quotes.
const QUOTE_BYTES: usize = 200;

/// A connection to the daemon. Requests are answered in order, one at a time.
#[derive(Debug)]
pub struct Client {
    stream: UnixStream,
    path: PathBuf,
    timeout: Duration,
    /// Bytes read past the end of the last answer line.
    pending: Vec<u8>,
}

/// A successful answer: the typed reply, and the value of `ok` exactly as received.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    pub reply: Reply,
    pub raw: serde_json::Value,
}

/// Everything a request can end with but a reply. [`ClientError::exit_code`] sorts them into
/// "the daemon said no" (1), "no daemon to talk to" (3) and "not a daemon we understand" (4).
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The socket could not be connected to (missing, nobody listening, not allowed, …).
    #[error("cannot connect to {}: {}", path.display(), connect_reason(source))]
    Connect { path: PathBuf, source: io::Error },
    /// The daemon did not accept the connection in time (its listen queue is full).
    #[error("cannot connect to {}: the daemon did not accept the connection within {}",
        path.display(), format_ns(duration_ns(*timeout)))]
    ConnectTimeout { path: PathBuf, timeout: Duration },
    /// The request could not be sent, or the answer did not come, in time.
    #[error("no answer from the daemon at {} within {}", path.display(),
        format_ns(duration_ns(*timeout)))]
    Timeout { path: PathBuf, timeout: Duration },
    /// Reading or writing the connection failed (other than the daemon closing it).
    #[error("talking to the daemon at {}: {source}", path.display())]
    Io { path: PathBuf, source: io::Error },
    /// The connection ended before a complete answer line.
    #[error("the daemon at {} closed the connection without answering", path.display())]
    Closed { path: PathBuf },
    /// The answer is not a response line of this protocol.
    #[error("the daemon's answer is not a valid response: {reason}")]
    Malformed { reason: String, line: String },
    /// The daemon speaks another protocol version, or refused ours.
    #[error("{}", version_text(*theirs))]
    Version { theirs: u64, message: Option<String> },
    /// A valid response, but not of the kind the request is answered with.
    #[error("the daemon answered `{request}` with a `{reply}` reply")]
    UnexpectedReply { request: &'static str, reply: &'static str },
    /// The daemon answered with an error. `raw` is the `error` object as received.
    #[error("{}: {}", kind_text(failure.kind), failure.message)]
    Daemon { failure: Failure, raw: serde_json::Value },
}

impl ClientError {
    /// 1: the daemon answered with an error; 3: the daemon cannot be reached (no socket,
    /// refused, not allowed, timed out); 4: the peer does not speak this protocol (garbage,
    /// another version, closed before answering, an unexpected reply).
    pub fn exit_code(&self) -> u8 {
        match self {
            ClientError::Daemon { .. } => EXIT_DAEMON_ERROR,
            ClientError::Connect { .. }
            | ClientError::ConnectTimeout { .. }
            | ClientError::Timeout { .. }
            | ClientError::Io { .. } => EXIT_UNREACHABLE,
            ClientError::Closed { .. }
            | ClientError::Malformed { .. }
            | ClientError::Version { .. }
            | ClientError::UnexpectedReply { .. } => EXIT_PROTOCOL,
        }
    }

    /// The lines to print after the message: a refused load's diagnostics, the daemon's own
    /// words on a version mismatch, the start of a malformed answer.
    pub fn details(&self) -> Vec<String> {
        match self {
            ClientError::Daemon { failure, .. } => failure.details.clone(),
            ClientError::Version { message: Some(message), .. } => vec![message.clone()],
            ClientError::Malformed { line, .. } => vec![format!("the answer: {line}")],
            _ => Vec::new(),
        }
    }

    /// True when the connection was found closed: for an idempotent request (a `get`), a new
    /// connection may be tried.
    pub fn is_closed(&self) -> bool {
        matches!(self, ClientError::Closed { .. })
    }
}

impl Client {
    /// Connects to the control socket at `path`. `timeout` bounds the connection, and then the
    /// sending of each request and the wait for its answer.
    pub fn connect(path: impl AsRef<Path>, timeout: Duration) -> Result<Client, ClientError> {
        let path = path.as_ref().to_path_buf();
        let connect_error = |source: io::Error| ClientError::Connect { path: path.clone(), source };
        let timeout = timeout.max(Duration::from_micros(1));
        let fd =
            socket::socket(AddressFamily::Unix, SockType::Stream, SockFlag::SOCK_CLOEXEC, None)
                .map_err(|e| connect_error(e.into()))?;
        // A blocking connect to a Unix socket waits while the listener's queue is full, for at
        // most SO_SNDTIMEO, and then fails with EAGAIN.
        socket::setsockopt(&fd, sockopt::SendTimeout, &timeval(timeout))
            .map_err(|e| connect_error(e.into()))?;
        let addr = UnixAddr::new(path.as_path()).map_err(|e| connect_error(e.into()))?;
        loop {
            match socket::connect(std::os::fd::AsRawFd::as_raw_fd(&fd), &addr) {
                Ok(()) => break,
                Err(Errno::EINTR) => continue,
                Err(Errno::EAGAIN) => return Err(ClientError::ConnectTimeout { path, timeout }),
                Err(e) => return Err(connect_error(e.into())),
            }
        }
        let stream = UnixStream::from(fd);
        Ok(Client { stream, path, timeout, pending: Vec::new() })
    }

    /// The socket's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sends `request` and returns its reply. An error answer is [`ClientError::Daemon`].
    pub fn request(&mut self, request: &Request) -> Result<Reply, ClientError> {
        self.exchange(request).map(|answer| answer.reply)
    }

    /// [`Client::request`], keeping the `ok` value as the daemon sent it.
    pub fn exchange(&mut self, request: &Request) -> Result<Answer, ClientError> {
        let deadline = Instant::now() + self.timeout;
        let line = protocol::to_line(&RequestLine::new(request.clone()));
        let sent = self.send(&line, deadline);
        // A daemon that refuses a request may answer and close before it has read all of it
        // (a line over its limit): the answer is worth more than the failed write.
        let answer = match (sent, self.receive(deadline)) {
            (_, Ok(answer)) => answer,
            (Err(e), Err(_)) | (Ok(()), Err(e)) => return Err(e),
        };
        let answer = parse_response(&answer)?;
        let expected = expected_reply(request);
        let got = reply_kind(&answer.reply);
        if got != expected {
            return Err(ClientError::UnexpectedReply { request: request.name(), reply: got });
        }
        Ok(answer)
    }

    fn send(&mut self, line: &[u8], deadline: Instant) -> Result<(), ClientError> {
        let mut rest = line;
        while !rest.is_empty() {
            let left = self.left(deadline)?;
            self.stream.set_write_timeout(Some(left)).map_err(|e| self.io(e))?;
            match self.stream.write(rest) {
                Ok(0) => return Err(ClientError::Closed { path: self.path.clone() }),
                Ok(n) => rest = &rest[n..],
                Err(e) => match e.kind() {
                    io::ErrorKind::Interrupted => {}
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut => {
                        return Err(self.timed_out())
                    }
                    io::ErrorKind::BrokenPipe | io::ErrorKind::ConnectionReset => {
                        return Err(ClientError::Closed { path: self.path.clone() })
                    }
                    _ => return Err(self.io(e)),
                },
            }
        }
        Ok(())
    }

    /// Reads up to and including the next newline; returns the line without it.
    fn receive(&mut self, deadline: Instant) -> Result<Vec<u8>, ClientError> {
        let mut searched = 0;
        loop {
            if let Some(end) = self.pending[searched..].iter().position(|&b| b == b'\n') {
                let end = searched + end;
                let mut line: Vec<u8> = self.pending.drain(..=end).collect();
                line.pop();
                return Ok(line);
            }
            searched = self.pending.len();
            if self.pending.len() > MAX_RESPONSE_BYTES {
                return Err(ClientError::Malformed {
                    reason: format!("no end of line within {MAX_RESPONSE_BYTES} bytes"),
                    line: quote(&self.pending),
                });
            }
            let left = self.left(deadline)?;
            self.stream.set_read_timeout(Some(left)).map_err(|e| self.io(e))?;
            let mut chunk = [0u8; 8192];
            match self.stream.read(&mut chunk) {
                Ok(0) if self.pending.is_empty() => {
                    return Err(ClientError::Closed { path: self.path.clone() })
                }
                Ok(0) => {
                    return Err(ClientError::Malformed {
                        reason: "the connection closed in the middle of the line".into(),
                        line: quote(&self.pending),
                    })
                }
                Ok(n) => self.pending.extend_from_slice(&chunk[..n]),
                Err(e) => match e.kind() {
                    io::ErrorKind::Interrupted => {}
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut => {
                        return Err(self.timed_out())
                    }
                    io::ErrorKind::ConnectionReset | io::ErrorKind::BrokenPipe => {
                        return Err(ClientError::Closed { path: self.path.clone() })
                    }
                    _ => return Err(self.io(e)),
                },
            }
        }
    }

    /// The time left before `deadline`, or the timeout error.
    fn left(&self, deadline: Instant) -> Result<Duration, ClientError> {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            Err(self.timed_out())
        } else {
            Ok(left)
        }
    }

    fn timed_out(&self) -> ClientError {
        ClientError::Timeout { path: self.path.clone(), timeout: self.timeout }
    }

    fn io(&self, source: io::Error) -> ClientError {
        ClientError::Io { path: self.path.clone(), source }
    }
}

/// Parses one answer line (without its newline).
pub fn parse_response(line: &[u8]) -> Result<Answer, ClientError> {
    let malformed = |reason: String| ClientError::Malformed { reason, line: quote(line) };
    let value: serde_json::Value =
        serde_json::from_slice(line).map_err(|e| malformed(format!("not JSON ({e})")))?;
    let serde_json::Value::Object(mut object) = value else {
        return Err(malformed("not a JSON object".into()));
    };
    let Some(v) = object.get("v").and_then(serde_json::Value::as_u64) else {
        return Err(malformed("no protocol version \"v\"".into()));
    };
    let error = object.remove("error");
    if v != u64::from(protocol::VERSION) {
        let message = error
            .as_ref()
            .and_then(|e| e.get("message"))
            .and_then(serde_json::Value::as_str)
            .map(str::to_string);
        return Err(ClientError::Version { theirs: v, message });
    }
    match (object.remove("ok"), error) {
        (Some(ok), None) => {
            let reply = serde_json::from_value::<Reply>(ok.clone())
                .map_err(|e| malformed(format!("not a reply: {e}")))?;
            Ok(Answer { reply, raw: ok })
        }
        (None, Some(error)) => {
            let failure = serde_json::from_value::<Failure>(error.clone())
                .map_err(|e| malformed(format!("not an error: {e}")))?;
            if failure.kind == ErrorKind::Version {
                return Err(ClientError::Version { theirs: v, message: Some(failure.message) });
            }
            Err(ClientError::Daemon { failure, raw: error })
        }
        (Some(_), Some(_)) => Err(malformed("both \"ok\" and \"error\"".into())),
        (None, None) => Err(malformed("neither \"ok\" nor \"error\"".into())),
    }
}

/// The `kind` of a reply, as on the wire.
pub fn reply_kind(reply: &Reply) -> &'static str {
    match reply {
        Reply::Status(_) => "status",
        Reply::Mode { .. } => "mode",
        Reply::Values { .. } => "values",
        Reply::Written { .. } => "written",
        Reply::Forces { .. } => "forces",
        Reply::Loaded { .. } => "loaded",
        Reply::Debug(_) => "debug",
    }
}

/// The `kind` of the reply a request is answered with (see [`Request`]).
pub fn expected_reply(request: &Request) -> &'static str {
    match request {
        Request::Status => "status",
        Request::Run | Request::Stop | Request::Reset { .. } => "mode",
        Request::Get { .. } => "values",
        Request::Set { .. } => "written",
        Request::Force { .. } | Request::Unforce { .. } | Request::UnforceAll | Request::Forces => {
            "forces"
        }
        Request::Load { .. } => "loaded",
        Request::Debug
        | Request::Step { .. }
        | Request::Continue
        | Request::Break { .. }
        | Request::Unbreak { .. } => "debug",
    }
}

/// An error kind as a human reads it: `bad request`, `refused`.
pub fn kind_text(kind: ErrorKind) -> &'static str {
    match kind {
        ErrorKind::BadRequest => "bad request",
        ErrorKind::TooLong => "request too long",
        ErrorKind::Version => "protocol version",
        ErrorKind::Invalid => "invalid",
        ErrorKind::Refused => "refused",
        ErrorKind::Busy => "busy",
        ErrorKind::Denied => "denied",
        ErrorKind::Unavailable => "unavailable",
    }
}

fn version_text(theirs: u64) -> String {
    let ours = protocol::VERSION;
    if theirs == u64::from(ours) {
        format!("the daemon does not accept protocol version {ours}")
    } else {
        format!("the daemon speaks protocol version {theirs}, this plcctl speaks {ours}")
    }
}

fn connect_reason(error: &io::Error) -> String {
    match Errno::from_raw(error.raw_os_error().unwrap_or(0)) {
        Errno::ENOENT => "no such socket (is plcd running?)".into(),
        Errno::ECONNREFUSED => {
            "connection refused (nothing listens on it: is plcd running?)".into()
        }
        Errno::EACCES | Errno::EPERM => {
            "permission denied (root, the daemon's user and the socket's group may connect)".into()
        }
        Errno::ENAMETOOLONG => "the path is too long for a Unix socket".into(),
        _ => error.to_string(),
    }
}

fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

fn timeval(d: Duration) -> TimeVal {
    let micros = d.as_micros().max(1);
    let secs = (micros / 1_000_000).min(i64::MAX as u128 / 2) as i64;
    TimeVal::new(secs as _, (micros % 1_000_000) as _)
}

/// The start of a line, lossily decoded, for an error message.
fn quote(bytes: &[u8]) -> String {
    let text = String::from_utf8_lossy(&bytes[..bytes.len().min(QUOTE_BYTES)]);
    let mut text = text.escape_debug().to_string();
    if bytes.len() > QUOTE_BYTES {
        text.push('…');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use plcd_ipc::ModeName;

    #[test]
    fn responses() {
        let ok = parse_response(br#"{"v":1,"ok":{"kind":"mode","mode":"RUN","new":1}}"#).unwrap();
        assert_eq!(ok.reply, Reply::Mode { mode: ModeName::Run });
        assert_eq!(ok.raw["new"], 1, "unknown fields are kept for --json");

        let err = parse_response(br#"{"v":1,"error":{"kind":"refused","message":"no"}}"#);
        let err = err.unwrap_err();
        assert_eq!(err.exit_code(), 1);
        assert_eq!(err.to_string(), "refused: no");

        for (line, code) in [
            (&br#"{"v":2,"error":{"kind":"version","message":"speak 2"}}"#[..], 4),
            (br#"{"v":1,"error":{"kind":"version","message":"x"}}"#, 4),
            (br#"{"v":2,"ok":{"kind":"mode","mode":"RUN"}}"#, 4),
            (b"hello", 4),
            (b"[1]", 4),
            (br#"{"ok":{"kind":"mode","mode":"RUN"}}"#, 4),
            (br#"{"v":1}"#, 4),
            (br#"{"v":1,"ok":{"kind":"nonsense"}}"#, 4),
        ] {
            let e = parse_response(line).unwrap_err();
            assert_eq!(e.exit_code(), code, "{}", String::from_utf8_lossy(line));
        }
        let e = parse_response(br#"{"v":2,"error":{"kind":"version","message":"speak 2"}}"#);
        let e = e.unwrap_err();
        assert_eq!(e.to_string(), "the daemon speaks protocol version 2, this plcctl speaks 1");
        assert_eq!(e.details(), ["speak 2"]);
    }

    #[test]
    fn every_request_expects_a_reply_kind() {
        assert_eq!(expected_reply(&Request::Reset { cold: true }), "mode");
        assert_eq!(expected_reply(&Request::UnforceAll), "forces");
        assert_eq!(expected_reply(&Request::Unbreak { at: None }), "debug");
    }

    #[test]
    fn quotes_are_bounded() {
        let long = vec![b'x'; 1000];
        assert_eq!(quote(&long).chars().count(), QUOTE_BYTES + 1);
        assert_eq!(quote(b"a\"b\n"), "a\\\"b\\n");
    }
}
