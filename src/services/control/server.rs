//! The control socket server: it owns the Unix socket file (choosing its path, replacing a
//! stale one, its mode and group, removing it on drop), the connections (who may connect, how
//! many, how much each may send and keep unread, how long each may idle) and the framing of
//! the protocol (lines in, [`protocol::parse_request`], one response line out per request).
//! What a request *does* belongs to the [`Handler`].
//!
//! One thread, non-blocking sockets and one `poll` loop: no client can make the server wait,
//! whether it sends slowly, never reads, sends garbage or holds a request that the daemon
//! answers only at the next END. Each client has at most one request outstanding; its further
//! lines stay unread (in its buffer and then in the kernel's) until the answer comes, which
//! bounds what one client can queue up.

use std::collections::BTreeMap;
use std::fs;
use std::io::{self, Read};
use std::os::fd::{AsFd, AsRawFd};
use std::os::unix::fs::{DirBuilderExt, FileTypeExt, MetadataExt, PermissionsExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, PollTimeout};
use nix::sys::eventfd::{EfdFlags, EventFd};
use nix::sys::socket::{
    self, sockopt, AddressFamily, Backlog, MsgFlags, SockFlag, SockType, UnixAddr,
};
use nix::unistd::{Gid, Group};

use super::{ClientId, Handler, Peer};
use crate::config::ControlConfig;
use plcd_ipc::{self as protocol, ErrorKind, ResponseLine};

/// The most answer bytes kept for a client that does not read them; past this it is dropped
/// (a status line is a few KiB, so only a client that stopped reading gets here).
const MAX_OUTPUT_BYTES: usize = 4 << 20;
/// The most read from one client per wake, so that one fast sender cannot starve the others.
const READ_CHUNK: usize = 64 * 1024;
/// How long a connection being closed (after `too_long`) may take to read its last line.
const LINGER: Duration = Duration::from_secs(2);
/// How long accepting pauses when the process is out of descriptors: the listener stays
/// readable, and polling it meanwhile would spin.
const ACCEPT_PAUSE: Duration = Duration::from_millis(100);
/// The most connections accepted per wake, for the same fairness as [`READ_CHUNK`].
const ACCEPTS_PER_WAKE: usize = 64;
const BACKLOG: i32 = 64;

/// Why the server could not start, or had to stop. Each names what it was working on.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("control socket: {call} {path}: {source}", path = .path.display())]
    Io {
        path: PathBuf,
        call: &'static str,
        #[source]
        source: io::Error,
    },
    #[error("control socket {path}: another plcd serves it", path = .path.display())]
    InUse { path: PathBuf },
    #[error(
        "control socket {path}: the file exists and is not a socket; it is left alone",
        path = .path.display()
    )]
    NotASocket { path: PathBuf },
    #[error("control socket directory {dir}: {reason}", dir = .dir.display())]
    UnsafeDir { dir: PathBuf, reason: String },
    #[error("control socket group \"{group}\" does not exist")]
    UnknownGroup { group: String },
    #[error("control socket group \"{group}\": {source}")]
    GroupLookup {
        group: String,
        #[source]
        source: Errno,
    },
    #[error("no control socket path could be used: {}", join(.tried))]
    NoPath { tried: Vec<ServerError> },
    #[error("control server: {call}: {source}")]
    Serve {
        call: &'static str,
        #[source]
        source: Errno,
    },
}

fn join(errors: &[ServerError]) -> String {
    errors.iter().map(ToString::to_string).collect::<Vec<_>>().join("; ")
}

fn io_error<'a>(path: &'a Path, call: &'static str) -> impl FnOnce(Errno) -> ServerError + 'a {
    move |errno| ServerError::Io { path: path.to_path_buf(), call, source: errno.into() }
}

/// Makes [`ControlServer::serve`] return. Send + Clone: any thread may hold one.
#[derive(Debug, Clone)]
pub struct Stopper(Arc<EventFd>);

impl Stopper {
    /// Makes `serve` return promptly (also if it is called later: the request is kept until
    /// `serve` sees it).
    pub fn stop(&self) {
        // The counter would need 2^64 - 1 stops to fill; nothing else can fail here.
        let _ = self.0.write(1);
    }
}

/// Who may connect: root, the daemon's user, and members of one group.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Policy {
    daemon_uid: u32,
    allowed_gid: u32,
}

impl Policy {
    /// Whether `peer` is admitted. `supplementary` gives the peer's supplementary groups; it is
    /// only called when the cheaper checks did not decide (it reads /proc).
    fn admits(&self, peer: &Peer, supplementary: impl FnOnce() -> Vec<u32>) -> bool {
        peer.uid == 0
            || peer.uid == self.daemon_uid
            || peer.gid == self.allowed_gid
            || supplementary().contains(&self.allowed_gid)
    }
}

/// The `Groups:` line of a `/proc/<pid>/status`.
fn parse_groups(status: &str) -> Vec<u32> {
    status
        .lines()
        .find_map(|line| line.strip_prefix("Groups:"))
        .map(|list| list.split_whitespace().filter_map(|g| g.parse().ok()).collect())
        .unwrap_or_default()
}

/// The supplementary groups of process `pid`, empty when they cannot be read. SO_PEERCRED has
/// only the primary group; the pid is the one that connected, so a process that exited (and a
/// recycled pid) is possible but can only be refused: the answer then is "not a member".
fn supplementary_groups(pid: i32) -> Vec<u32> {
    if pid <= 0 {
        return Vec::new();
    }
    fs::read_to_string(format!("/proc/{pid}/status")).map(|s| parse_groups(&s)).unwrap_or_default()
}

/// A default socket path and how its directory is made.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Candidate {
    path: PathBuf,
    /// The mode of the directory when it has to be created.
    dir_mode: u32,
    /// In a world-writable place (/tmp): the directory must be ours and closed to others, or
    /// anyone could have prepared it to take over the socket.
    private: bool,
}

/// [`protocol::default_socket_paths`], in order, with how to make each directory.
fn default_candidates(uid: u32, xdg_runtime_dir: Option<&str>) -> Vec<Candidate> {
    protocol::default_socket_paths(uid, xdg_runtime_dir)
        .into_iter()
        .map(|path| {
            let path = PathBuf::from(path);
            let private = path.starts_with("/tmp");
            Candidate { path, dir_mode: if private { 0o750 } else { 0o755 }, private }
        })
        .collect()
}

/// Whether a failure at one default path means "try the next": the path is not ours to use
/// (no permission, a read-only or missing directory). Anything else (another plcd serving it,
/// a file in the way) is a real problem that a fallback would only hide.
fn falls_through(error: &ServerError) -> bool {
    const NEXT: [i32; 5] = [libc::EACCES, libc::EPERM, libc::EROFS, libc::ENOENT, libc::ENOTDIR];
    match error {
        ServerError::Io { source, .. } => source.raw_os_error().is_some_and(|e| NEXT.contains(&e)),
        _ => false,
    }
}

/// Tries `attempt` on each candidate in order until one works or fails for a reason that is
/// not [`falls_through`]. Returns the result and the index of the candidate used.
fn first_usable<T>(
    candidates: &[Candidate],
    mut attempt: impl FnMut(&Candidate) -> Result<T, ServerError>,
) -> Result<(T, usize), ServerError> {
    let mut tried = Vec::new();
    for (index, candidate) in candidates.iter().enumerate() {
        match attempt(candidate) {
            Ok(value) => return Ok((value, index)),
            Err(e) if falls_through(&e) => {
                log::debug!("{e}; trying the next default path");
                tried.push(e);
            }
            Err(e) => return Err(e),
        }
    }
    Err(ServerError::NoPath { tried })
}

/// Creates the directory of a default path when missing, and checks a private one.
fn prepare_dir(candidate: &Candidate) -> Result<(), ServerError> {
    let Some(dir) = candidate.path.parent() else { return Ok(()) };
    let io = |call: &'static str| {
        move |source: io::Error| ServerError::Io { path: dir.to_path_buf(), call, source }
    };
    match fs::DirBuilder::new().mode(candidate.dir_mode).create(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(io("mkdir")(e)),
    }
    if candidate.private {
        let meta = fs::symlink_metadata(dir).map_err(io("stat"))?;
        let euid = nix::unistd::geteuid().as_raw();
        let unsafe_dir = |reason: String| ServerError::UnsafeDir { dir: dir.to_path_buf(), reason };
        if !meta.file_type().is_dir() {
            return Err(unsafe_dir("not a directory (a symlink?)".into()));
        }
        if meta.uid() != euid {
            return Err(unsafe_dir(format!("owned by uid {}, not by uid {euid}", meta.uid())));
        }
        if meta.mode() & 0o022 != 0 {
            return Err(unsafe_dir(format!(
                "writable by others (mode {:o})",
                meta.mode() & 0o7777
            )));
        }
    }
    Ok(())
}

/// A bound and listening socket, and the identity of its file.
struct Bound {
    listener: UnixListener,
    identity: (u64, u64),
}

/// What a connect to an existing socket file says about it.
enum Probe {
    /// Something accepts on it.
    Live,
    /// Nothing listens: left behind by a process that died.
    Stale,
    /// The file went away meanwhile.
    Gone,
}

fn probe(path: &Path) -> Result<Probe, ServerError> {
    let flags = SockFlag::SOCK_CLOEXEC | SockFlag::SOCK_NONBLOCK;
    let fd = socket::socket(AddressFamily::Unix, SockType::Stream, flags, None)
        .map_err(io_error(path, "socket"))?;
    let addr = UnixAddr::new(path).map_err(io_error(path, "connect"))?;
    // Non-blocking: a live server with a full backlog answers EAGAIN instead of making us wait.
    match socket::connect(fd.as_raw_fd(), &addr) {
        Ok(()) | Err(Errno::EAGAIN) | Err(Errno::EINPROGRESS) => Ok(Probe::Live),
        Err(Errno::ECONNREFUSED) => Ok(Probe::Stale),
        Err(Errno::ENOENT) => Ok(Probe::Gone),
        Err(errno) => Err(io_error(path, "connect")(errno)),
    }
}

/// Removes a stale socket at `path`; refuses a live one and anything that is not a socket.
fn clear_stale(path: &Path) -> Result<(), ServerError> {
    let meta = match fs::symlink_metadata(path) {
        Ok(meta) => meta,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(source) => return Err(ServerError::Io { path: path.into(), call: "stat", source }),
    };
    if !meta.file_type().is_socket() {
        return Err(ServerError::NotASocket { path: path.into() });
    }
    match probe(path)? {
        Probe::Live => Err(ServerError::InUse { path: path.into() }),
        Probe::Gone => Ok(()),
        Probe::Stale => {
            log::info!("removing the stale control socket {}", path.display());
            match fs::remove_file(path) {
                Ok(()) => Ok(()),
                Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
                Err(source) => Err(ServerError::Io { path: path.into(), call: "unlink", source }),
            }
        }
    }
}

/// Binds a socket at exactly `path`: mode 0660, group `group`, listening.
fn bind_path(path: &Path, group: Option<Gid>) -> Result<Bound, ServerError> {
    clear_stale(path)?;
    let flags = SockFlag::SOCK_CLOEXEC | SockFlag::SOCK_NONBLOCK;
    let fd = socket::socket(AddressFamily::Unix, SockType::Stream, flags, None)
        .map_err(io_error(path, "socket"))?;
    let addr = UnixAddr::new(path).map_err(io_error(path, "bind"))?;
    match socket::bind(fd.as_raw_fd(), &addr) {
        Ok(()) => {}
        // Another daemon bound it between our probe and now.
        Err(Errno::EADDRINUSE) => return Err(ServerError::InUse { path: path.into() }),
        Err(errno) => return Err(io_error(path, "bind")(errno)),
    }
    // The file is ours from here on: remove it again if the rest fails.
    let finish = || -> Result<(u64, u64), ServerError> {
        let io = |call: &'static str| {
            move |source: io::Error| ServerError::Io { path: path.to_path_buf(), call, source }
        };
        let meta = fs::symlink_metadata(path).map_err(io("stat"))?;
        // Mode and group before listen(): until then a connect is refused, so no client ever
        // sees the socket with the mode the umask gave it.
        fs::set_permissions(path, fs::Permissions::from_mode(0o660)).map_err(io("chmod"))?;
        if let Some(gid) = group {
            std::os::unix::fs::lchown(path, None, Some(gid.as_raw())).map_err(io("chown"))?;
        }
        let backlog = Backlog::new(BACKLOG).unwrap_or(Backlog::MAXCONN);
        socket::listen(&fd, backlog).map_err(|e| io("listen")(e.into()))?;
        Ok((meta.dev(), meta.ino()))
    };
    match finish() {
        Ok(identity) => Ok(Bound { listener: UnixListener::from(fd), identity }),
        Err(e) => {
            let _ = fs::remove_file(path);
            Err(e)
        }
    }
}

/// Binds the first usable default path, creating its directory when needed.
fn bind_default(
    candidates: &[Candidate],
    group: Option<Gid>,
) -> Result<(Bound, PathBuf), ServerError> {
    let (bound, index) = first_usable(candidates, |candidate| {
        prepare_dir(candidate)?;
        bind_path(&candidate.path, group)
    })?;
    let path = candidates[index].path.clone();
    if index > 0 {
        let skipped: Vec<String> =
            candidates[..index].iter().map(|c| c.path.display().to_string()).collect();
        log::info!(
            "control socket at {} ({} could not be used)",
            path.display(),
            skipped.join(", ")
        );
    }
    Ok((bound, path))
}

fn resolve_group(name: &str) -> Result<Gid, ServerError> {
    match Group::from_name(name) {
        Ok(Some(group)) => Ok(group.gid),
        Ok(None) => Err(ServerError::UnknownGroup { group: name.into() }),
        Err(source) => Err(ServerError::GroupLookup { group: name.into(), source }),
    }
}

/// One admitted connection.
#[derive(Debug)]
struct Client {
    stream: UnixStream,
    peer: Peer,
    /// Received bytes not yet taken as lines: at most the request limit.
    input: Vec<u8>,
    /// Answer bytes the socket did not take yet: at most [`MAX_OUTPUT_BYTES`].
    output: Vec<u8>,
    /// A request was handed to the handler and its answer has not come.
    outstanding: bool,
    /// The peer sends nothing more (it shut down its side, or closed).
    eof: bool,
    /// Close once the output is flushed (after `too_long`).
    closing: bool,
    /// When it is closed for idling (or, closing, for not reading its last line). None while
    /// a request is outstanding.
    deadline: Option<Instant>,
}

/// Why a connection ends.
type Close = &'static str;

impl Client {
    fn wants_read(&self) -> bool {
        !self.outstanding && !self.eof && !self.closing
    }

    fn interest(&self) -> PollFlags {
        let mut events = PollFlags::empty();
        if self.wants_read() {
            events |= PollFlags::POLLIN;
        }
        if !self.output.is_empty() {
            events |= PollFlags::POLLOUT;
        }
        events
    }

    /// Queues one answer; a completed request restarts the idle time.
    fn answer(
        &mut self,
        line: &ResponseLine,
        now: Instant,
        idle: Option<Duration>,
    ) -> Result<(), Close> {
        let bytes = protocol::to_line(line);
        if self.output.len() + bytes.len() > MAX_OUTPUT_BYTES {
            return Err("it does not read its answers");
        }
        self.output.extend_from_slice(&bytes);
        self.deadline = idle.map(|idle| now + idle);
        Ok(())
    }

    /// Reads one chunk, never past `limit` bytes of input.
    fn read(&mut self, limit: usize, scratch: &mut [u8]) -> Result<(), Close> {
        let room = limit.saturating_sub(self.input.len()).min(scratch.len());
        if room == 0 {
            return Ok(());
        }
        match self.stream.read(&mut scratch[..room]) {
            Ok(0) => self.eof = true,
            Ok(n) => self.input.extend_from_slice(&scratch[..n]),
            Err(e)
                if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted) => {}
            Err(_) => return Err("read failed (reset)"),
        }
        Ok(())
    }

    /// Sends what the socket takes now.
    fn flush(&mut self) -> Result<(), Close> {
        while !self.output.is_empty() {
            // MSG_NOSIGNAL: a peer that hung up must not kill the daemon with SIGPIPE.
            let flags = MsgFlags::MSG_NOSIGNAL | MsgFlags::MSG_DONTWAIT;
            match socket::send(self.stream.as_raw_fd(), &self.output, flags) {
                Ok(n) => drop(self.output.drain(..n)),
                Err(Errno::EAGAIN) => break,
                Err(Errno::EINTR) => {}
                Err(_) => return Err("hung up"),
            }
        }
        Ok(())
    }

    /// Takes the complete lines in the input as requests, in order, until one is outstanding.
    fn pump(
        &mut self,
        id: ClientId,
        handler: &mut impl Handler,
        limit: usize,
        now: Instant,
        idle: Option<Duration>,
    ) -> Result<(), Close> {
        while !self.outstanding && !self.closing {
            let Some(end) = self.input.iter().position(|&b| b == b'\n') else {
                if self.input.len() >= limit {
                    // `limit` bytes and no newline: the line is longer than allowed. The
                    // rest of it is never read: the connection ends after this answer.
                    let message = format!("the request line is longer than {limit} bytes");
                    self.answer(&ResponseLine::error(ErrorKind::TooLong, message), now, idle)?;
                    self.input = Vec::new();
                    self.closing = true;
                    self.deadline = Some(now + LINGER);
                } else if self.eof {
                    // A half line at EOF: the client never finished it.
                    self.input = Vec::new();
                }
                break;
            };
            let mut line: Vec<u8> = self.input.drain(..=end).collect();
            line.pop();
            if line.last() == Some(&b'\r') {
                line.pop();
            }
            if line.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            match protocol::parse_request(&line) {
                Err(failure) => self.answer(&ResponseLine::failure(failure), now, idle)?,
                Ok(request) => match handler.request(id, &self.peer, request) {
                    Some(response) => self.answer(&response, now, idle)?,
                    None => {
                        self.outstanding = true;
                        self.deadline = None;
                    }
                },
            }
        }
        Ok(())
    }

    /// Whether it has nothing left to do: the peer sends no more, and every answer is out.
    fn finished(&self) -> bool {
        (self.eof || self.closing) && !self.outstanding && self.output.is_empty()
    }
}

/// One answer, best effort, on a connection that is closed right after (busy, denied): it is
/// new, so its send buffer is empty and a short line fits.
fn send_once(stream: &UnixStream, line: &ResponseLine) {
    let flags = MsgFlags::MSG_NOSIGNAL | MsgFlags::MSG_DONTWAIT;
    let _ = socket::send(stream.as_raw_fd(), &protocol::to_line(line), flags);
}

/// The poll timeout until `deadline`, rounded up to whole ms so that it does not wake early.
fn timeout_until(now: Instant, deadline: Option<Instant>) -> PollTimeout {
    match deadline {
        None => PollTimeout::NONE,
        Some(deadline) => {
            let ms = deadline.saturating_duration_since(now).as_nanos().div_ceil(1_000_000);
            PollTimeout::try_from(ms).unwrap_or(PollTimeout::MAX)
        }
    }
}

fn revents(fd: &PollFd) -> PollFlags {
    fd.revents().unwrap_or(PollFlags::empty())
}

const GONE: PollFlags = PollFlags::POLLHUP.union(PollFlags::POLLERR);

/// The control socket server. See the module docs.
#[derive(Debug)]
pub struct ControlServer {
    listener: UnixListener,
    path: PathBuf,
    /// Device and inode of the socket file we created, to remove only that one.
    identity: (u64, u64),
    stop: Arc<EventFd>,
    policy: Policy,
    max_clients: usize,
    max_request: usize,
    idle: Option<Duration>,
    clients: BTreeMap<ClientId, Client>,
    next_id: ClientId,
    accept_paused_until: Option<Instant>,
}

impl ControlServer {
    /// Binds the socket of `config` (`config.socket` is already resolved against the config
    /// file's directory when set): exactly that path, or the first usable default path.
    pub fn bind(config: &ControlConfig) -> Result<ControlServer, ServerError> {
        let group = config.group.as_deref().map(resolve_group).transpose()?;
        let euid = nix::unistd::geteuid().as_raw();
        let (bound, path) = match &config.socket {
            Some(path) => (bind_path(path, group)?, path.clone()),
            None => {
                let xdg = std::env::var("XDG_RUNTIME_DIR").ok();
                bind_default(&default_candidates(euid, xdg.as_deref()), group)?
            }
        };
        let stop = EventFd::from_flags(EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC)
            .map_err(io_error(&path, "eventfd"))?;
        let allowed_gid = group.unwrap_or_else(nix::unistd::getegid).as_raw();
        Ok(ControlServer {
            listener: bound.listener,
            path,
            identity: bound.identity,
            stop: Arc::new(stop),
            policy: Policy { daemon_uid: euid, allowed_gid },
            max_clients: config.max_clients.max(1) as usize,
            max_request: config.max_request_bytes.max(1) as usize,
            idle: (config.idle_timeout_s > 0)
                .then(|| Duration::from_secs(u64::from(config.idle_timeout_s))),
            clients: BTreeMap::new(),
            next_id: 1,
            accept_paused_until: None,
        })
    }

    /// The socket's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A handle whose [`Stopper::stop`] makes [`ControlServer::serve`] return promptly.
    pub fn stopper(&self) -> Stopper {
        Stopper(Arc::clone(&self.stop))
    }

    /// Serves until stopped. Client misbehaviour only ever ends that client's connection; an
    /// error here is the server's own (poll or accept failing for a reason no client causes).
    pub fn serve(&mut self, handler: &mut impl Handler) -> Result<(), ServerError> {
        let mut scratch = vec![0u8; READ_CHUNK];
        let mut events: Vec<(ClientId, PollFlags)> = Vec::new();
        loop {
            let now = Instant::now();
            let outstanding = self.clients.values().any(|c| c.outstanding);
            let timeout = timeout_until(now, self.next_deadline(now, outstanding, handler.tick()));
            if self.accept_paused_until.is_some_and(|until| now >= until) {
                self.accept_paused_until = None;
            }
            events.clear();
            let (stopped, acceptable, woken) = {
                let mut fds = Vec::with_capacity(self.clients.len() + 3);
                let listen = if self.accept_paused_until.is_none() {
                    PollFlags::POLLIN
                } else {
                    PollFlags::empty()
                };
                fds.push(PollFd::new(self.stop.as_fd(), PollFlags::POLLIN));
                fds.push(PollFd::new(self.listener.as_fd(), listen));
                let wake = handler.wake_fd();
                let has_wake = wake.is_some();
                if let Some(fd) = wake {
                    fds.push(PollFd::new(fd, PollFlags::POLLIN));
                }
                let first_client = fds.len();
                fds.extend(
                    self.clients.values().map(|c| PollFd::new(c.stream.as_fd(), c.interest())),
                );
                match nix::poll::poll(&mut fds, timeout) {
                    Ok(_) => {}
                    Err(Errno::EINTR) => continue,
                    Err(source) => return Err(ServerError::Serve { call: "poll", source }),
                }
                for (id, fd) in self.clients.keys().zip(&fds[first_client..]) {
                    if !revents(fd).is_empty() {
                        events.push((*id, revents(fd)));
                    }
                }
                (
                    !revents(&fds[0]).is_empty(),
                    !revents(&fds[1]).is_empty(),
                    has_wake && !revents(&fds[2]).is_empty(),
                )
            };
            if stopped {
                let _ = self.stop.read();
                return Ok(());
            }
            let now = Instant::now();
            // Clients first: a slot freed by a hang-up is free for a connection in the same wake.
            for &(id, revents) in &events {
                self.service(id, revents, handler, &mut scratch, now);
            }
            if woken || outstanding {
                self.complete(handler, now);
            }
            if acceptable {
                self.accept(handler, &mut scratch, now)?;
            }
            self.expire(now);
        }
    }

    /// The earliest time the loop must wake without an event.
    fn next_deadline(&self, now: Instant, outstanding: bool, tick: Duration) -> Option<Instant> {
        let clients = self.clients.values().filter_map(|c| c.deadline);
        let tick = outstanding.then(|| now + tick);
        clients.chain(tick).chain(self.accept_paused_until).min()
    }

    /// Handles the poll events of one client.
    fn service(
        &mut self,
        id: ClientId,
        revents: PollFlags,
        handler: &mut impl Handler,
        scratch: &mut [u8],
        now: Instant,
    ) {
        let (limit, idle) = (self.max_request, self.idle);
        let Some(client) = self.clients.get_mut(&id) else { return };
        let result = (|| {
            // Read before looking at a hang-up: what a client sent before it closed was sent,
            // and is handled (its answers go nowhere).
            if client.wants_read() && revents.intersects(PollFlags::POLLIN | GONE) {
                client.read(limit, scratch)?;
                client.pump(id, handler, limit, now, idle)?;
            }
            client.flush()?;
            if revents.intersects(GONE) && !client.wants_read() {
                return Err("hung up");
            }
            Ok(())
        })();
        self.settle(id, result, handler);
    }

    /// Closes `id` if it failed or has nothing left to do.
    fn settle(&mut self, id: ClientId, result: Result<(), Close>, handler: &mut impl Handler) {
        let Some(client) = self.clients.get(&id) else { return };
        let why = match result {
            Err(why) => why,
            Ok(()) if client.finished() => "done",
            Ok(()) => return,
        };
        self.close(id, why, handler);
    }

    fn close(&mut self, id: ClientId, why: Close, handler: &mut impl Handler) {
        if let Some(client) = self.clients.remove(&id) {
            log::debug!("control client {id} (pid {}) closed: {why}", client.peer.pid);
            if client.outstanding {
                handler.gone(id);
            }
        }
    }

    /// Delivers the answers that became ready, and goes on with those clients' next lines.
    fn complete(&mut self, handler: &mut impl Handler, now: Instant) {
        let mut ready = Vec::new();
        handler.completions(&mut ready);
        let (limit, idle) = (self.max_request, self.idle);
        for (id, response) in ready {
            let Some(client) = self.clients.get_mut(&id) else {
                // It hung up; the handler was told through gone().
                continue;
            };
            if !client.outstanding {
                log::warn!("control: an answer for client {id}, which has no request open");
                continue;
            }
            client.outstanding = false;
            let result = client
                .answer(&response, now, idle)
                .and_then(|()| client.pump(id, handler, limit, now, idle))
                .and_then(|()| client.flush());
            self.settle(id, result, handler);
        }
    }

    /// Accepts the pending connections: admits, or answers `denied` or `busy` and closes.
    fn accept(
        &mut self,
        handler: &mut impl Handler,
        scratch: &mut [u8],
        now: Instant,
    ) -> Result<(), ServerError> {
        for _ in 0..ACCEPTS_PER_WAKE {
            let stream = match self.listener.accept() {
                Ok((stream, _)) => stream,
                Err(e) => match e.raw_os_error().map(Errno::from_raw) {
                    Some(Errno::EAGAIN) => return Ok(()),
                    Some(Errno::EINTR | Errno::ECONNABORTED | Errno::EPROTO) => continue,
                    Some(Errno::EMFILE | Errno::ENFILE | Errno::ENOBUFS | Errno::ENOMEM) => {
                        log::warn!("control socket: accept: {e}; pausing");
                        self.accept_paused_until = Some(now + ACCEPT_PAUSE);
                        return Ok(());
                    }
                    errno => {
                        let source = errno.unwrap_or(Errno::EIO);
                        return Err(ServerError::Serve { call: "accept", source });
                    }
                },
            };
            self.admit(stream, handler, scratch, now);
        }
        Ok(())
    }

    fn admit(
        &mut self,
        stream: UnixStream,
        handler: &mut impl Handler,
        scratch: &mut [u8],
        now: Instant,
    ) {
        let creds = match socket::getsockopt(&stream, sockopt::PeerCredentials) {
            Ok(creds) => creds,
            Err(e) => {
                log::warn!("control socket: SO_PEERCRED: {e}; connection closed");
                return;
            }
        };
        let peer = Peer { pid: creds.pid(), uid: creds.uid(), gid: creds.gid() };
        if !self.policy.admits(&peer, || supplementary_groups(peer.pid)) {
            log::warn!(
                "control socket: refused pid {} uid {} gid {}: not root, uid {} or group {}",
                peer.pid,
                peer.uid,
                peer.gid,
                self.policy.daemon_uid,
                self.policy.allowed_gid
            );
            let message = format!(
                "uid {} is not allowed to use this socket (only root, uid {} and members of \
                 group {} are)",
                peer.uid, self.policy.daemon_uid, self.policy.allowed_gid
            );
            send_once(&stream, &ResponseLine::error(ErrorKind::Denied, message));
            return;
        }
        if self.clients.len() >= self.max_clients {
            // A client that just hung up may not have been seen yet: look before refusing.
            self.reap(handler, scratch, now);
        }
        if self.clients.len() >= self.max_clients {
            log::warn!(
                "control socket: {} clients connected; refused pid {} uid {}",
                self.clients.len(),
                peer.pid,
                peer.uid
            );
            let message = format!("{} clients are connected, the most allowed", self.max_clients);
            send_once(&stream, &ResponseLine::error(ErrorKind::Busy, message));
            return;
        }
        if let Err(e) = stream.set_nonblocking(true) {
            log::warn!("control socket: O_NONBLOCK: {e}; connection closed");
            return;
        }
        let id = self.next_id;
        self.next_id += 1;
        log::debug!("control client {id}: pid {} uid {} gid {}", peer.pid, peer.uid, peer.gid);
        let client = Client {
            stream,
            peer,
            input: Vec::new(),
            output: Vec::new(),
            outstanding: false,
            eof: false,
            closing: false,
            deadline: self.idle.map(|idle| now + idle),
        };
        self.clients.insert(id, client);
    }

    /// Services at once the clients that hung up, without waiting.
    fn reap(&mut self, handler: &mut impl Handler, scratch: &mut [u8], now: Instant) {
        let hung_up: Vec<(ClientId, PollFlags)> = {
            let mut fds: Vec<PollFd> = self
                .clients
                .values()
                .map(|c| PollFd::new(c.stream.as_fd(), c.interest()))
                .collect();
            if nix::poll::poll(&mut fds, PollTimeout::ZERO).is_err() {
                return;
            }
            self.clients
                .keys()
                .zip(&fds)
                .filter(|(_, fd)| revents(fd).intersects(GONE))
                .map(|(id, fd)| (*id, revents(fd)))
                .collect()
        };
        for (id, revents) in hung_up {
            self.service(id, revents, handler, scratch, now);
        }
    }

    /// Closes the connections whose deadline passed.
    fn expire(&mut self, now: Instant) {
        let expired: Vec<ClientId> = self
            .clients
            .iter()
            .filter(|(_, c)| c.deadline.is_some_and(|d| d <= now))
            .map(|(id, _)| *id)
            .collect();
        for id in expired {
            if let Some(client) = self.clients.remove(&id) {
                log::debug!("control client {id} (pid {}) closed: idle", client.peer.pid);
            }
        }
    }
}

impl Drop for ControlServer {
    /// Removes the socket file, unless it is no longer ours (another daemon that found it
    /// stale replaced it, or someone put something else there).
    fn drop(&mut self) {
        if let Ok(meta) = fs::symlink_metadata(&self.path) {
            if (meta.dev(), meta.ino()) == self.identity {
                let _ = fs::remove_file(&self.path);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const POLICY: Policy = Policy { daemon_uid: 990, allowed_gid: 985 };

    fn peer(uid: u32, gid: u32) -> Peer {
        Peer { pid: 4242, uid, gid }
    }

    #[test]
    fn root_the_daemons_user_and_the_group_are_admitted() {
        let none = Vec::new;
        assert!(POLICY.admits(&peer(0, 0), none));
        assert!(POLICY.admits(&peer(0, 1000), none));
        assert!(POLICY.admits(&peer(990, 1000), none));
        assert!(POLICY.admits(&peer(1000, 985), none));
        assert!(POLICY.admits(&peer(1000, 1000), || vec![4, 985, 27]));
    }

    #[test]
    fn others_are_refused() {
        assert!(!POLICY.admits(&peer(1000, 1000), Vec::new));
        assert!(!POLICY.admits(&peer(1000, 1000), || vec![4, 24, 27]));
        assert!(!POLICY.admits(&peer(65534, 65534), || vec![65534]));
        // The daemon's gid is not its uid.
        assert!(!POLICY.admits(&peer(985, 990), Vec::new));
    }

    #[test]
    fn supplementary_groups_are_read_only_when_needed() {
        let never = || -> Vec<u32> { panic!("read /proc although the uid decided") };
        assert!(POLICY.admits(&peer(0, 7), never));
        assert!(POLICY.admits(&peer(990, 7), never));
        assert!(POLICY.admits(&peer(7, 985), never));
    }

    #[test]
    fn the_groups_line_is_parsed() {
        let status = "Name:\tplcctl\nUid:\t1000\t1000\t1000\t1000\nGid:\t1000\t1000\t1000\t1000\n\
                      Groups:\t4 24 27 985 \nNStgid:\t1\n";
        assert_eq!(parse_groups(status), [4, 24, 27, 985]);
        assert_eq!(parse_groups("Name:\tx\nGroups:\t\nPid:\t3\n"), Vec::<u32>::new());
        assert_eq!(parse_groups("Name:\tx\n"), Vec::<u32>::new());
        assert_eq!(parse_groups("Groups:\t4 junk 5\n"), [4, 5]);
    }

    #[test]
    fn our_own_supplementary_groups_are_found() {
        let ours: Vec<u32> =
            nix::unistd::getgroups().unwrap().into_iter().map(|g| g.as_raw()).collect();
        let mut read = supplementary_groups(std::process::id() as i32);
        read.sort_unstable();
        let mut ours = ours;
        ours.sort_unstable();
        ours.dedup();
        assert_eq!(read, ours);
        assert!(supplementary_groups(0).is_empty());
        assert!(supplementary_groups(-1).is_empty());
    }

    #[test]
    fn default_candidates_follow_the_protocols_order() {
        let c = default_candidates(1000, Some("/run/user/1000"));
        let paths: Vec<&Path> = c.iter().map(|c| c.path.as_path()).collect();
        assert_eq!(
            paths,
            [
                Path::new("/run/plcd/plcd.sock"),
                Path::new("/run/user/1000/plcd.sock"),
                Path::new("/tmp/plcd-1000/plcd.sock")
            ]
        );
        assert_eq!((c[0].dir_mode, c[0].private), (0o755, false));
        assert_eq!((c[1].dir_mode, c[1].private), (0o755, false));
        assert_eq!((c[2].dir_mode, c[2].private), (0o750, true));
        assert_eq!(default_candidates(0, None).len(), 2);
    }

    fn io(path: &str, errno: Errno) -> ServerError {
        ServerError::Io { path: path.into(), call: "bind", source: errno.into() }
    }

    #[test]
    fn a_path_we_may_not_use_falls_through_to_the_next() {
        let candidates = default_candidates(1000, Some("/run/user/1000"));
        for errno in [Errno::EACCES, Errno::EPERM, Errno::EROFS, Errno::ENOENT, Errno::ENOTDIR] {
            let mut tried = Vec::new();
            let (value, index) = first_usable(&candidates, |c| {
                tried.push(c.path.clone());
                if tried.len() < 3 {
                    Err(io("x", errno))
                } else {
                    Ok("bound")
                }
            })
            .unwrap();
            assert_eq!((value, index), ("bound", 2), "{errno}");
            assert_eq!(tried, candidates.iter().map(|c| c.path.clone()).collect::<Vec<_>>());
        }
        // The first that works is taken.
        let (_, index) = first_usable(&candidates, |_| Ok(())).unwrap();
        assert_eq!(index, 0);
    }

    #[test]
    fn a_real_problem_stops_the_search() {
        let candidates = default_candidates(1000, Some("/run/user/1000"));
        for error in [
            ServerError::InUse { path: "/run/plcd/plcd.sock".into() },
            ServerError::NotASocket { path: "/run/plcd/plcd.sock".into() },
            io("/run/plcd/plcd.sock", Errno::ENAMETOOLONG),
            io("/run/plcd/plcd.sock", Errno::EADDRINUSE),
        ] {
            let text = error.to_string();
            let mut error = Some(error);
            let mut calls = 0;
            let result: Result<((), usize), _> = first_usable(&candidates, |_| {
                calls += 1;
                Err(error.take().unwrap())
            });
            assert_eq!(result.unwrap_err().to_string(), text);
            assert_eq!(calls, 1);
        }
    }

    #[test]
    fn when_no_path_works_every_reason_is_named() {
        let candidates = default_candidates(1000, None);
        let error =
            first_usable::<()>(&candidates, |c| Err(io(c.path.to_str().unwrap(), Errno::EACCES)))
                .unwrap_err();
        let text = error.to_string();
        assert!(text.contains("/run/plcd/plcd.sock") && text.contains("/tmp/plcd-1000"), "{text}");
        assert!(matches!(error, ServerError::NoPath { tried } if tried.len() == 2));
    }

    /// A scratch directory under /tmp, removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(name: &str) -> Scratch {
            let dir = std::env::temp_dir()
                .join(format!("plcd-server-unit-{name}-{}", std::process::id()));
            let _ = fs::remove_dir_all(&dir);
            fs::create_dir_all(&dir).unwrap();
            Scratch(dir)
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn binding_falls_back_past_a_directory_that_cannot_be_made() {
        let scratch = Scratch::new("fallback");
        let candidates = [
            // mkdir under a /proc directory that does not exist: ENOENT, even as root.
            Candidate {
                path: "/proc/plcd-no-such-dir/run/plcd.sock".into(),
                dir_mode: 0o755,
                private: false,
            },
            Candidate { path: scratch.0.join("run/plcd.sock"), dir_mode: 0o750, private: true },
        ];
        let (bound, path) = bind_default(&candidates, None).unwrap();
        assert_eq!(path, candidates[1].path);
        let dir = fs::metadata(scratch.0.join("run")).unwrap();
        assert_eq!(dir.mode() & 0o777, 0o750 & !current_umask());
        let sock = fs::symlink_metadata(&path).unwrap();
        assert!(sock.file_type().is_socket());
        assert_eq!(sock.mode() & 0o777, 0o660);
        assert_eq!((sock.dev(), sock.ino()), bound.identity);
    }

    #[test]
    fn a_private_directory_open_to_others_is_refused() {
        let scratch = Scratch::new("private");
        let dir = scratch.0.join("open");
        fs::create_dir(&dir).unwrap();
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o777)).unwrap();
        let candidate = Candidate { path: dir.join("plcd.sock"), dir_mode: 0o750, private: true };
        let error = bind_default(std::slice::from_ref(&candidate), None).err().unwrap();
        assert!(matches!(error, ServerError::UnsafeDir { .. }), "{error}");
        assert!(error.to_string().contains("writable by others"), "{error}");
        assert!(!candidate.path.exists());
    }

    fn current_umask() -> u32 {
        let status = fs::read_to_string("/proc/self/status").unwrap();
        status
            .lines()
            .find_map(|l| l.strip_prefix("Umask:"))
            .map(|m| u32::from_str_radix(m.trim(), 8).unwrap())
            .unwrap_or(0o022)
    }

    #[test]
    fn the_poll_timeout_rounds_up() {
        let now = Instant::now();
        assert_eq!(timeout_until(now, None), PollTimeout::NONE);
        assert_eq!(timeout_until(now, Some(now)), PollTimeout::ZERO);
        let t = timeout_until(now, Some(now + Duration::from_micros(1500)));
        assert_eq!(i32::from(t), 2);
        let past = now.checked_sub(Duration::from_secs(1)).unwrap_or(now);
        assert_eq!(timeout_until(now, Some(past)), PollTimeout::ZERO);
    }
}
