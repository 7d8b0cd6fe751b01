//! The control socket server over real sockets, against a fake handler: framing, deferred
//! answers, malformed input, bounds, the socket file, and who may connect.
//!
//! Nothing here sleeps to synchronise: clients read with socket timeouts, the fake reports what
//! it saw through a channel, and a deferred answer is released by writing to its eventfd.
//! The few checks that something does *not* happen wait a short, fixed time for it.

mod harness;

use std::collections::VecDeque;
use std::fs;
use std::io::{self, BufRead, BufReader, Write};
use std::net::Shutdown;
use std::os::fd::{AsFd, BorrowedFd};
use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use nix::sys::eventfd::{EfdFlags, EventFd};
use plcd::config::ControlConfig;
use plcd::services::control::server::{ControlServer, ServerError, Stopper};
use plcd::services::control::{Caller, ClientId, Handler};
use plcd_ipc::{
    self, DebugState, ErrorKind, ModeName, NamedValue, Outcome, Reply, Request, ResponseLine,
};

use harness::nobody::{self, NOBODY};
use harness::tempdir::TempDir;

/// The loose bound for anything that must happen "promptly".
const WAIT: Duration = Duration::from_secs(5);
/// How long a check that something does not happen waits for it.
const QUIET: Duration = Duration::from_millis(200);

/// A test's directory, which every user can reach (the peer tests connect as uid 65534).
fn dir(name: &str) -> TempDir {
    TempDir::for_everyone(&format!("control-{name}"))
}

/// The socket of a test's directory, and a control config serving it.
trait SocketDir {
    fn socket(&self) -> PathBuf;
    fn config(&self) -> ControlConfig;
}

impl SocketDir for TempDir {
    fn socket(&self) -> PathBuf {
        self.join("plcd.sock")
    }

    fn config(&self) -> ControlConfig {
        ControlConfig { socket: Some(self.socket()), ..ControlConfig::default() }
    }
}

/// What the fake handler saw.
#[derive(Debug, PartialEq, Eq)]
enum Seen {
    Deferred(ClientId),
    Gone(ClientId),
}

/// Answers `status` and `get` at once, defers `step` until released, refuses the rest.
struct Fake {
    /// With a wake fd: the test writes N to it to release N deferred answers.
    release: Arc<EventFd>,
    /// Without one: the test sets this, and the next `completions` answers everything.
    release_flag: Arc<AtomicBool>,
    use_wake_fd: bool,
    pending: VecDeque<ClientId>,
    seen: mpsc::Sender<Seen>,
}

impl Handler for Fake {
    fn request(
        &mut self,
        client: ClientId,
        _caller: &Caller,
        request: Request,
    ) -> Option<ResponseLine> {
        match request {
            Request::Status => Some(ResponseLine::ok(Reply::Mode { mode: ModeName::Run })),
            Request::Get { devices } => {
                let values = devices
                    .into_iter()
                    .enumerate()
                    .map(|(i, dev)| NamedValue::device(dev, i as i32))
                    .collect();
                Some(ResponseLine::ok(Reply::Values { scan: client, values }))
            }
            Request::Step { .. } => {
                self.pending.push_back(client);
                let _ = self.seen.send(Seen::Deferred(client));
                None
            }
            other => Some(ResponseLine::error(
                ErrorKind::Refused,
                format!("{} is not faked", other.name()),
            )),
        }
    }

    fn completions(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>) {
        let released = if self.use_wake_fd {
            self.release.read().unwrap_or(0)
        } else if self.release_flag.swap(false, Ordering::SeqCst) {
            u64::MAX
        } else {
            0
        };
        for _ in 0..released {
            let Some(client) = self.pending.pop_front() else { break };
            // The answer names its client, so that a test sees who got whose.
            let state = DebugState { scan: client, ..DebugState::default() };
            ready.push((client, ResponseLine::ok(Reply::Debug(state))));
        }
    }

    fn wake_fd(&self) -> Option<BorrowedFd<'_>> {
        self.use_wake_fd.then(|| self.release.as_fd())
    }

    fn tick(&self) -> Duration {
        // With a wake fd, a long tick: the test shows the wake fd alone is enough.
        if self.use_wake_fd {
            Duration::from_secs(3600)
        } else {
            Duration::from_millis(20)
        }
    }

    fn gone(&mut self, client: ClientId) {
        self.pending.retain(|&c| c != client);
        let _ = self.seen.send(Seen::Gone(client));
    }
}

/// A server serving a [`Fake`] on a thread.
struct Running {
    path: PathBuf,
    stopper: Stopper,
    release: Arc<EventFd>,
    release_flag: Arc<AtomicBool>,
    seen: mpsc::Receiver<Seen>,
    done: mpsc::Receiver<()>,
    thread: Option<JoinHandle<(ControlServer, Result<(), ServerError>)>>,
}

fn start(config: &ControlConfig) -> Running {
    start_with(config, true)
}

fn start_with(config: &ControlConfig, use_wake_fd: bool) -> Running {
    let mut server = ControlServer::bind(config).expect("binds");
    let release =
        Arc::new(EventFd::from_flags(EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC).unwrap());
    let release_flag = Arc::new(AtomicBool::new(false));
    let (seen_tx, seen) = mpsc::channel();
    let (done_tx, done) = mpsc::channel();
    let mut fake = Fake {
        release: Arc::clone(&release),
        release_flag: Arc::clone(&release_flag),
        use_wake_fd,
        pending: VecDeque::new(),
        seen: seen_tx,
    };
    let path = server.path().expect("a socket").to_path_buf();
    let stopper = server.stopper();
    let thread = std::thread::spawn(move || {
        let result = server.serve(&mut fake);
        let _ = done_tx.send(());
        (server, result)
    });
    Running { path, stopper, release, release_flag, seen, done, thread: Some(thread) }
}

impl Running {
    fn connect(&self) -> Client {
        Client::connect(&self.path)
    }

    /// Releases `n` deferred answers (wake fd mode).
    fn release(&self, n: u64) {
        self.release.write(n).unwrap();
    }

    fn next_seen(&self) -> Seen {
        self.seen.recv_timeout(WAIT).expect("the handler saw something")
    }

    fn deferred(&self) -> ClientId {
        match self.next_seen() {
            Seen::Deferred(id) => id,
            other => panic!("expected a deferred request, the handler saw {other:?}"),
        }
    }

    /// Stops the server and returns it (still owning its socket file).
    fn stop(mut self) -> ControlServer {
        self.stopper.stop();
        self.done.recv_timeout(WAIT).expect("serve() returns promptly after stop()");
        let (server, result) = self.thread.take().unwrap().join().unwrap();
        result.expect("serve() ends without an error");
        server
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stopper.stop();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// A line-reading client with socket timeouts.
struct Client {
    reader: BufReader<UnixStream>,
}

impl Client {
    fn connect(path: &Path) -> Client {
        let stream = UnixStream::connect(path).expect("connects");
        stream.set_read_timeout(Some(WAIT)).unwrap();
        stream.set_write_timeout(Some(WAIT)).unwrap();
        Client { reader: BufReader::new(stream) }
    }

    fn stream(&self) -> &UnixStream {
        self.reader.get_ref()
    }

    fn send(&mut self, bytes: &[u8]) {
        self.reader.get_mut().write_all(bytes).expect("the server takes the request");
    }

    fn recv(&mut self) -> ResponseLine {
        let mut line = String::new();
        match self.reader.read_line(&mut line) {
            Ok(0) => panic!("the server closed the connection instead of answering"),
            Ok(_) => {}
            Err(e) => panic!("no answer: {e}"),
        }
        assert!(line.ends_with('\n'), "a whole line: {line:?}");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("not a response line: {e}: {line:?}"))
    }

    fn request(&mut self, line: &str) -> ResponseLine {
        self.send(format!("{line}\n").as_bytes());
        self.recv()
    }

    /// The server closes the connection (within [`WAIT`]) without sending anything more.
    fn expect_closed(&mut self) {
        let mut line = String::new();
        match self.reader.read_line(&mut line) {
            Ok(0) => {}
            Ok(_) => panic!("expected the connection closed, got {line:?}"),
            Err(e) if e.kind() == io::ErrorKind::ConnectionReset => {}
            Err(e) => panic!("expected the connection closed: {e}"),
        }
    }

    /// Nothing arrives for [`QUIET`].
    fn expect_nothing(&mut self) {
        self.stream().set_read_timeout(Some(QUIET)).unwrap();
        let mut line = String::new();
        match self.reader.read_line(&mut line) {
            Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {}
            other => panic!("expected nothing yet, got {other:?} {line:?}"),
        }
        assert!(line.is_empty(), "a partial line arrived: {line:?}");
        self.stream().set_read_timeout(Some(WAIT)).unwrap();
    }
}

const STATUS: &str = r#"{"v":1,"cmd":"status"}"#;
const STEP: &str = r#"{"v":1,"cmd":"step"}"#;

fn error_kind(response: &ResponseLine) -> Option<ErrorKind> {
    match &response.outcome {
        Outcome::Ok(_) => None,
        Outcome::Error(failure) => Some(failure.kind),
    }
}

fn error_message(response: &ResponseLine) -> String {
    match &response.outcome {
        Outcome::Error(failure) => failure.message.clone(),
        Outcome::Ok(reply) => panic!("expected an error, got {reply:?}"),
    }
}

fn assert_status_ok(response: &ResponseLine) {
    assert_eq!(response, &ResponseLine::ok(Reply::Mode { mode: ModeName::Run }));
}

fn debug_for(response: &ResponseLine) -> u64 {
    match &response.outcome {
        Outcome::Ok(Reply::Debug(state)) => state.scan,
        other => panic!("expected a deferred (debug) answer, got {other:?}"),
    }
}

fn values(response: &ResponseLine) -> Vec<String> {
    match &response.outcome {
        Outcome::Ok(Reply::Values { values, .. }) => values.iter().map(|v| v.dev.clone()).collect(),
        other => panic!("expected values, got {other:?}"),
    }
}

/// A fresh client still gets a correct answer.
fn assert_unharmed(running: &Running) {
    assert_status_ok(&running.connect().request(STATUS));
}

// ---------------------------------------------------------------------------------------------
// Requests and answers

#[test]
fn a_request_is_answered() {
    let dir = dir("round-trip");
    let running = start(&dir.config());
    let response = running.connect().request(STATUS);
    assert_eq!(response.v, plcd_ipc::VERSION);
    assert_status_ok(&response);
}

#[test]
fn pipelined_lines_are_answered_in_order_and_blank_lines_ignored() {
    let dir = dir("pipelined");
    let running = start(&dir.config());
    let mut client = running.connect();
    // One write: CRLF, blank and whitespace-only lines mixed in.
    client.send(
        b"{\"v\":1,\"cmd\":\"get\",\"devices\":[\"A\"]}\r\n\n   \r\n\
          {\"v\":1,\"cmd\":\"get\",\"devices\":[\"B\"]}\n\
          {\"v\":1,\"cmd\":\"status\"}\n",
    );
    assert_eq!(values(&client.recv()), ["A"]);
    assert_eq!(values(&client.recv()), ["B"]);
    assert_status_ok(&client.recv());
    // No answer was queued for the blank lines: the next answer is the next request's.
    let refused = client.request(r#"{"v":1,"cmd":"stop"}"#);
    assert_eq!(error_kind(&refused), Some(ErrorKind::Refused));
}

#[test]
fn a_deferred_answer_does_not_hold_up_other_clients() {
    let dir = dir("deferred");
    let running = start(&dir.config());
    let mut a = running.connect();
    // A status pipelined behind the step must wait for the step's answer.
    a.send(format!("{STEP}\n{STATUS}\n").as_bytes());
    let a_id = running.deferred();

    let mut b = running.connect();
    assert_status_ok(&b.request(STATUS));
    assert_eq!(values(&b.request(r#"{"v":1,"cmd":"get","devices":["X","Y"]}"#)), ["X", "Y"]);
    a.expect_nothing();

    running.release(1);
    assert_eq!(debug_for(&a.recv()), a_id);
    assert_status_ok(&a.recv());
    // A deferred request of B after A's: each gets its own answer.
    b.send(format!("{STEP}\n").as_bytes());
    let b_id = running.deferred();
    assert_ne!(a_id, b_id);
    running.release(1);
    assert_eq!(debug_for(&b.recv()), b_id);
}

#[test]
fn deferred_answers_are_collected_every_tick_without_a_wake_fd() {
    let dir = dir("tick");
    let running = start_with(&dir.config(), false);
    let mut a = running.connect();
    a.send(format!("{STEP}\n").as_bytes());
    let a_id = running.deferred();
    running.release_flag.store(true, Ordering::SeqCst);
    assert_eq!(debug_for(&a.recv()), a_id);
}

#[test]
fn the_handler_is_told_when_a_client_with_an_outstanding_request_hangs_up() {
    let dir = dir("gone");
    let running = start(&dir.config());
    // A client without an outstanding request leaves: nothing to tell.
    let mut quiet = running.connect();
    assert_status_ok(&quiet.request(STATUS));
    drop(quiet);

    let mut a = running.connect();
    a.send(format!("{STEP}\n").as_bytes());
    let a_id = running.deferred();
    drop(a);
    assert_eq!(running.next_seen(), Seen::Gone(a_id));

    // Releasing now finds nothing to answer, and the server goes on.
    running.release(1);
    assert_unharmed(&running);
    assert!(running.seen.try_recv().is_err(), "gone() once, for the one with a request");
}

#[test]
fn a_client_that_shuts_down_its_side_still_gets_its_answers() {
    let dir = dir("half-close");
    let running = start(&dir.config());
    let mut a = running.connect();
    a.send(format!("{STATUS}\n{STEP}\n").as_bytes());
    a.stream().shutdown(Shutdown::Write).unwrap();
    assert_status_ok(&a.recv());
    let a_id = running.deferred();
    running.release(1);
    assert_eq!(debug_for(&a.recv()), a_id);
    a.expect_closed();
}

#[test]
fn stop_makes_serve_return() {
    let dir = dir("stop");
    let running = start(&dir.config());
    let mut idle = running.connect();
    assert_status_ok(&idle.request(STATUS));
    let server = running.stop();
    // The connections end with the server's serving; the file stays until the server drops.
    assert!(dir.socket().exists());
    drop(server);
    idle.expect_closed();
}

// ---------------------------------------------------------------------------------------------
// Malformed input

#[test]
fn malformed_lines_are_answered_and_the_connection_kept() {
    let dir = dir("malformed");
    let running = start(&dir.config());
    let mut client = running.connect();
    for (line, kind) in [
        (&b"\xff\xfe{\"v\":1,\"cmd\":\"status\"}"[..], ErrorKind::BadRequest),
        (b"status", ErrorKind::BadRequest),
        (b"{\"v\":1,\"cmd\":\"format_disk\"}", ErrorKind::BadRequest),
        (b"{\"cmd\":\"status\"}", ErrorKind::BadRequest),
        (b"{\"v\":1,\"cmd\":\"get\",\"devices\":\"D0\"}", ErrorKind::BadRequest),
        (b"{\"v\":2,\"cmd\":\"status\"}", ErrorKind::Version),
        (b"{\"v\":99999999999,\"cmd\":\"status\"}", ErrorKind::Version),
    ] {
        let mut bytes = line.to_vec();
        bytes.push(b'\n');
        client.send(&bytes);
        let response = client.recv();
        assert_eq!(error_kind(&response), Some(kind), "{}", String::from_utf8_lossy(line));
        // The daemon's version, so that an old client can tell.
        assert_eq!(response.v, plcd_ipc::VERSION);
        assert_status_ok(&client.request(STATUS));
    }
}

/// xorshift64: a fixed sequence, so that a failure reproduces.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        self.0 = x;
        x
    }
}

#[test]
fn random_bytes_are_answered_with_errors_or_dropped() {
    let dir = dir("random");
    let running = start(&dir.config());
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    for round in 0..300 {
        let len = 1 + (rng.next() % 4096) as usize;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                let r = rng.next();
                // Enough newlines to make many lines, some `{`, `"` and `\r` to reach the
                // JSON parser's deeper paths.
                match r % 32 {
                    0 => b'\n',
                    1 => b'{',
                    2 => b'"',
                    3 => b'\r',
                    _ => (r >> 8) as u8,
                }
            })
            .collect();
        let mut client = running.connect();
        client.send(&bytes);
        if round % 3 == 0 {
            // Hang up without reading.
            continue;
        }
        client.stream().shutdown(Shutdown::Write).unwrap();
        let lines = bytes.iter().filter(|&&b| b == b'\n').count();
        let mut answers = 0;
        loop {
            let mut line = String::new();
            match client.reader.read_line(&mut line) {
                Ok(0) => break,
                Ok(_) => {}
                Err(e) => panic!("round {round}: {e}"),
            }
            let response: ResponseLine = serde_json::from_str(&line)
                .unwrap_or_else(|e| panic!("round {round}: {e}: {line:?}"));
            assert!(error_kind(&response).is_some(), "round {round}: {line:?}");
            answers += 1;
        }
        assert!(answers <= lines, "round {round}: {answers} answers to {lines} lines");
    }
    assert_unharmed(&running);
}

#[test]
fn a_line_over_the_limit_is_answered_too_long_and_the_connection_closed() {
    let dir = dir("too-long");
    let running = start(&dir.config());
    let mut client = running.connect();
    let mut line = vec![b'x'; 1 << 20];
    line.push(b'\n');
    // The server stops reading at its limit and closes: the write may fail (EPIPE).
    let _ = client.reader.get_mut().write_all(&line);
    let response = client.recv();
    assert_eq!(error_kind(&response), Some(ErrorKind::TooLong));
    assert!(error_message(&response).contains("65536"), "{response:?}");
    client.expect_closed();
    assert_unharmed(&running);
}

#[test]
fn the_limit_counts_the_newline() {
    let dir = dir("limit");
    let config = ControlConfig { max_request_bytes: 256, ..dir.config() };
    let running = start(&config);
    // A status request padded with spaces to exactly 256 bytes, newline included: accepted.
    let padded = |total: usize| {
        let mut line = STATUS.as_bytes().to_vec();
        line.resize(total - 1, b' ');
        line.push(b'\n');
        line
    };
    let mut client = running.connect();
    client.send(&padded(256));
    assert_status_ok(&client.recv());
    client.send(&padded(257));
    assert_eq!(error_kind(&client.recv()), Some(ErrorKind::TooLong));
    client.expect_closed();
    assert_unharmed(&running);
}

#[test]
fn half_a_request_then_hang_up_is_discarded() {
    let dir = dir("half-line");
    let running = start(&dir.config());
    // Shut down after a request without its newline: the server closes without answering or
    // handling it.
    let mut a = running.connect();
    a.send(STEP.as_bytes());
    a.stream().shutdown(Shutdown::Write).unwrap();
    a.expect_closed();
    // Hang up fully after half a line.
    let mut b = running.connect();
    b.send(&STEP.as_bytes()[..STEP.len() - 1]);
    drop(b);
    assert_unharmed(&running);
    assert!(running.seen.try_recv().is_err(), "a half line never reaches the handler");
}

// ---------------------------------------------------------------------------------------------
// Bounds

#[test]
fn one_client_more_than_max_clients_is_told_busy() {
    let dir = dir("busy");
    let config = ControlConfig { max_clients: 2, ..dir.config() };
    let running = start(&config);
    let mut a = running.connect();
    let mut b = running.connect();
    assert_status_ok(&a.request(STATUS));
    assert_status_ok(&b.request(STATUS));
    let mut c = running.connect();
    let response = c.recv();
    assert_eq!(error_kind(&response), Some(ErrorKind::Busy));
    c.expect_closed();
    // A slot freed by a hang-up is free at once.
    drop(a);
    assert_unharmed(&running);
    assert_status_ok(&b.request(STATUS));
}

#[test]
fn an_idle_connection_is_closed_but_not_one_waiting_for_an_answer() {
    let dir = dir("idle");
    let config = ControlConfig { idle_timeout_s: 1, ..dir.config() };
    let running = start(&config);
    let mut waiting = running.connect();
    waiting.send(format!("{STEP}\n").as_bytes());
    let waiting_id = running.deferred();

    let mut idle = running.connect();
    assert_status_ok(&idle.request(STATUS));
    let answered = Instant::now();
    idle.expect_closed();
    let after = answered.elapsed();
    assert!(after >= Duration::from_millis(500) && after < WAIT, "closed after {after:?}");

    // Idle longer than the timeout, but with a request outstanding: still connected.
    waiting.expect_nothing();
    running.release(1);
    assert_eq!(debug_for(&waiting.recv()), waiting_id);
    // Answered, it is idle again.
    waiting.expect_closed();
}

#[test]
fn a_client_that_does_not_read_its_answers_is_dropped() {
    let dir = dir("no-reader");
    let running = start(&dir.config());
    let mut client = running.connect();
    // ~10 KiB requests with ~25 KiB answers, never read: the answers pass the server's output
    // bound long before 2000 of them.
    let devices: Vec<String> = (0..1000).map(|i| format!("D{i:05}")).collect();
    let request = plcd_ipc::to_line(&plcd_ipc::RequestLine::new(Request::Get { devices }));
    let mut failed = None;
    for _ in 0..2000 {
        if let Err(e) = client.reader.get_mut().write_all(&request) {
            failed = Some(e);
            break;
        }
    }
    let error = failed.expect("the server drops a client that does not read");
    assert!(
        matches!(error.kind(), io::ErrorKind::BrokenPipe | io::ErrorKind::ConnectionReset),
        "dropped, not stalled: {error}"
    );
    assert_unharmed(&running);
}

// ---------------------------------------------------------------------------------------------
// The socket file

#[test]
fn the_socket_is_0660() {
    let dir = dir("mode");
    let server = ControlServer::bind(&dir.config()).unwrap();
    assert_eq!(server.path(), Some(dir.socket().as_path()));
    let meta = fs::symlink_metadata(dir.socket()).unwrap();
    assert!(meta.file_type().is_socket());
    assert_eq!(meta.mode() & 0o7777, 0o660);
}

#[test]
fn the_socket_gets_the_configured_group() {
    let dir = dir("group");
    // As root, a group we are not in shows the chown; otherwise only our own group can be set.
    let group = if nix::unistd::geteuid().is_root() {
        nix::unistd::Group::from_gid(nix::unistd::Gid::from_raw(65534)).ok().flatten()
    } else {
        None
    };
    let group = group
        .or_else(|| nix::unistd::Group::from_gid(nix::unistd::getegid()).ok().flatten())
        .expect("a group to use");
    let config = ControlConfig { group: Some(group.name.clone()), ..dir.config() };
    let _server = ControlServer::bind(&config).unwrap();
    let meta = fs::symlink_metadata(dir.socket()).unwrap();
    assert_eq!(meta.gid(), group.gid.as_raw());
    assert_eq!(meta.mode() & 0o7777, 0o660);
}

#[test]
fn an_unknown_group_is_an_error_naming_it() {
    let dir = dir("no-group");
    let config = ControlConfig { group: Some("plcd-no-such-group".into()), ..dir.config() };
    let error = ControlServer::bind(&config).unwrap_err();
    assert!(matches!(error, ServerError::UnknownGroup { .. }), "{error}");
    assert!(error.to_string().contains("plcd-no-such-group"), "{error}");
    assert!(!dir.socket().exists(), "nothing created");
}

#[test]
fn a_stale_socket_is_replaced() {
    let dir = dir("stale");
    // A listener that went away leaves its file behind (std does not unlink it).
    drop(UnixListener::bind(dir.socket()).unwrap());
    assert!(fs::symlink_metadata(dir.socket()).unwrap().file_type().is_socket());
    let running = start(&dir.config());
    assert_unharmed(&running);
}

#[test]
fn a_live_socket_is_not_taken_over() {
    let dir = dir("live");
    let running = start(&dir.config());
    let error = ControlServer::bind(&dir.config()).unwrap_err();
    assert!(matches!(error, ServerError::InUse { .. }), "{error}");
    let text = error.to_string();
    assert!(text.contains("another plcd") && text.contains(&*dir.socket().to_string_lossy()));
    // The first server still has its socket.
    assert_unharmed(&running);
}

#[test]
fn a_file_in_the_way_is_left_alone() {
    let dir = dir("regular");
    fs::write(dir.socket(), "keep me").unwrap();
    let error = ControlServer::bind(&dir.config()).unwrap_err();
    assert!(matches!(error, ServerError::NotASocket { .. }), "{error}");
    assert!(error.to_string().contains(&*dir.socket().to_string_lossy()), "{error}");
    assert_eq!(fs::read_to_string(dir.socket()).unwrap(), "keep me");
}

#[test]
fn a_configured_path_has_no_fallback() {
    let dir = dir("no-fallback");
    let missing = dir.join("no-such-dir/plcd.sock");
    let error =
        ControlServer::bind(&ControlConfig { socket: Some(missing.clone()), ..dir.config() })
            .unwrap_err();
    assert!(matches!(error, ServerError::Io { call: "bind", .. }), "{error}");
    assert!(error.to_string().contains(&*missing.to_string_lossy()), "{error}");
    // Longer than sun_path: also named.
    let long = dir.join("x".repeat(120));
    let error = ControlServer::bind(&ControlConfig { socket: Some(long.clone()), ..dir.config() })
        .unwrap_err();
    assert!(error.to_string().contains(&*long.to_string_lossy()), "{error}");
}

#[test]
fn the_socket_file_is_removed_on_drop_but_only_ours() {
    let dir = dir("drop");
    let server = ControlServer::bind(&dir.config()).unwrap();
    assert!(dir.socket().exists());
    drop(server);
    assert!(!dir.socket().exists(), "removed on drop");

    let server = ControlServer::bind(&dir.config()).unwrap();
    fs::remove_file(dir.socket()).unwrap();
    fs::write(dir.socket(), "someone else's").unwrap();
    drop(server);
    assert_eq!(fs::read_to_string(dir.socket()).unwrap(), "someone else's");
}

// ---------------------------------------------------------------------------------------------
// Who may connect

/// Set in the environment of [`child_client_mode`]: the socket to ask `status` on.
const CHILD: &str = "PLCD_CONTROL_TEST_CLIENT";

/// Not a test of its own, so ignored: the process the peer tests start as another user, a copy
/// of this test binary running only this function. It connects to the socket [`CHILD`] names,
/// asks for `status` and prints `ANSWER ` and the answer line, or what went wrong.
#[test]
#[ignore = "run by the peer tests as uid 65534, with the socket in PLCD_CONTROL_TEST_CLIENT"]
fn child_client_mode() {
    let Some(path) = std::env::var_os(CHILD) else { return };
    let answer = (|| -> io::Result<String> {
        let mut stream = UnixStream::connect(&path)?;
        stream.set_read_timeout(Some(WAIT))?;
        // A refused peer is answered at once and the connection closed, so the request may
        // meet a closed socket (EPIPE): what matters then is the answer already sent.
        let written = stream.write_all(format!("{STATUS}\n").as_bytes());
        let mut line = String::new();
        BufReader::new(stream).read_line(&mut line)?;
        match written {
            Err(e) if line.is_empty() => Err(e),
            _ => Ok(line),
        }
    })();
    match answer {
        Ok(line) => println!("ANSWER {}", line.trim_end()),
        Err(e) => println!("ANSWER failed: {e}"),
    }
}

/// Runs [`child_client_mode`] as uid 65534 with primary group `gid` and no supplementary
/// groups, and returns its answer.
fn ask_as_nobody(path: &Path, gid: u32) -> ResponseLine {
    let copy = nobody::Copy::of(&std::env::current_exe().unwrap());
    let output = nobody::output(
        copy.command(gid)
            .args(["child_client_mode", "--exact", "--ignored", "--nocapture", "--test-threads=1"])
            .env(CHILD, path),
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout
        .lines()
        // The harness prints "test child_client_mode ... " on the same line.
        .find_map(|l| l.split_once("ANSWER ").map(|(_, answer)| answer))
        .unwrap_or_else(|| {
            panic!("no answer from the child: {stdout}{}", String::from_utf8_lossy(&output.stderr))
        });
    serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}: {line:?}"))
}

#[test]
fn a_peer_that_is_not_allowed_is_refused() {
    if let Some(reason) = nobody::unavailable() {
        return harness::skip::skip(None, &reason);
    }
    let dir = dir("denied");
    let running = start(&dir.config());
    // Open the file to everyone: only the peer check stands in the way.
    fs::set_permissions(dir.socket(), fs::Permissions::from_mode(0o666)).unwrap();
    let response = ask_as_nobody(&dir.socket(), NOBODY);
    assert_eq!(error_kind(&response), Some(ErrorKind::Denied), "{response:?}");
    assert!(error_message(&response).contains("uid 65534 is not allowed"), "{response:?}");
    assert_unharmed(&running);
}

#[test]
fn a_peer_in_the_configured_group_is_admitted() {
    if let Some(reason) = nobody::unavailable() {
        return harness::skip::skip(None, &reason);
    }
    let Ok(Some(group)) = nix::unistd::Group::from_gid(nix::unistd::Gid::from_raw(NOBODY)) else {
        return harness::skip::skip(None, "no group 65534 on this machine");
    };
    let dir = dir("group-peer");
    let running = start(&ControlConfig { group: Some(group.name), ..dir.config() });
    // The file is 0660 root:<group>: the group may connect, and the policy admits it.
    assert_status_ok(&ask_as_nobody(&dir.socket(), NOBODY));
    drop(running);
}
