//! The control socket server: one thread, non-blocking sockets and one `poll` loop that
//! accepts connections (admitting, or answering `denied` or `busy` and closing), reads and
//! writes the admitted ones, hands their requests to the [`Handler`] and delivers its late
//! answers, and closes the connections that hung up, misbehaved or idled past their deadline.
//!
//! No client can make the server wait, whether it sends slowly, never reads, sends garbage or
//! holds a request that the daemon answers only at the next END. Each client has at most one
//! request outstanding; its further lines stay unread (in its buffer and then in the kernel's)
//! until the answer comes, which bounds what one client can queue up.
//!
//! The rooms around the loop: `socket` places the socket file (path, directory, mode, group,
//! stale sockets, removal), `access` decides who is admitted, and `client` holds one
//! connection's buffers, framing and bounds.
//!
//! The loop also serves the in-process door ([`crate::drivers::real_time::door`]): the requests of this process's
//! other services go to the same handler, each under an id of its own, and their answers to the
//! callback they came with. With `[control] enabled = false` and a service that needs the door,
//! the server runs without a socket ([`ControlServer::local_only`]).

use std::collections::BTreeMap;
use std::io;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::poll::{PollFd, PollFlags, PollTimeout};
use nix::sys::eventfd::{EfdFlags, EventFd};
use nix::sys::socket::{self, sockopt, MsgFlags};

use super::access::{supplementary_groups, Policy};
use super::client::{Client, Close};
use super::socket::{self as socket_file, SocketFile};
use super::{ClientId, Handler, Peer};
use crate::config::ControlConfig;
use crate::drivers::real_time::door::{LocalInbox, Reply};
use plcd_ipc::{self as protocol, ErrorKind, ResponseLine};

/// The most read from one client per wake, so that one fast sender cannot starve the others.
const READ_CHUNK: usize = 64 * 1024;
/// How long accepting pauses when the process is out of descriptors: the listener stays
/// readable, and polling it meanwhile would spin.
const ACCEPT_PAUSE: Duration = Duration::from_millis(100);
/// The most connections accepted per wake, for the same fairness as [`READ_CHUNK`].
const ACCEPTS_PER_WAKE: usize = 64;
/// The in-process door's requests get ids from here up, apart from the socket's clients'.
const FIRST_LOCAL_ID: ClientId = 1 << 63;
/// The in-process door's requests parked for a scan boundary at once, at most: past it a
/// request is answered `busy` (the services bound their own requests too).
pub const MAX_LOCAL_OUTSTANDING: usize = 256;

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

pub(super) fn io_error<'a>(
    path: &'a Path,
    call: &'static str,
) -> impl FnOnce(Errno) -> ServerError + 'a {
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

/// The in-process door's parked requests: where each answer goes.
#[derive(Default)]
struct Locals(BTreeMap<ClientId, Reply>);

impl std::fmt::Debug for Locals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} parked", self.0.len())
    }
}

const GONE: PollFlags = PollFlags::POLLHUP.union(PollFlags::POLLERR);

/// The control socket server. See the module docs.
#[derive(Debug)]
pub struct ControlServer {
    /// Removes the socket file when the server is dropped; first, so that the file goes before
    /// the rest is torn down. `None`: the in-process door alone.
    socket: Option<SocketFile>,
    stop: Arc<EventFd>,
    policy: Policy,
    max_clients: usize,
    max_request: usize,
    idle: Option<Duration>,
    clients: BTreeMap<ClientId, Client>,
    next_id: ClientId,
    accept_paused_until: Option<Instant>,
    /// The in-process door, if a service uses it.
    local: Option<LocalInbox>,
    /// The door's requests parked until the handler answers them.
    locals: Locals,
    next_local: ClientId,
}

impl ControlServer {
    /// Binds the socket of `config` (`config.socket` is already resolved against the config
    /// file's directory when set): exactly that path, or the first usable default path.
    pub fn bind(config: &ControlConfig) -> Result<ControlServer, ServerError> {
        let group = config.group.as_deref().map(socket_file::resolve_group).transpose()?;
        let euid = nix::unistd::geteuid().as_raw();
        let bound = socket_file::bind(config.socket.as_deref(), euid, group)?;
        let stop = EventFd::from_flags(EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC)
            .map_err(io_error(&bound.path, "eventfd"))?;
        let allowed_gid = group.unwrap_or_else(nix::unistd::getegid).as_raw();
        Ok(ControlServer {
            socket: Some(SocketFile::new(bound)),
            stop: Arc::new(stop),
            policy: Policy { daemon_uid: euid, allowed_gid },
            max_clients: config.max_clients.max(1) as usize,
            max_request: config.max_request_bytes.max(1) as usize,
            idle: (config.idle_timeout_s > 0)
                .then(|| Duration::from_secs(u64::from(config.idle_timeout_s))),
            clients: BTreeMap::new(),
            next_id: 1,
            accept_paused_until: None,
            local: None,
            locals: Locals::default(),
            next_local: FIRST_LOCAL_ID,
        })
    }

    /// A server of the in-process door alone, without a socket (`[control] enabled = false`).
    pub fn local_only(inbox: LocalInbox) -> Result<ControlServer, ServerError> {
        let stop = EventFd::from_flags(EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC)
            .map_err(|source| ServerError::Serve { call: "eventfd", source })?;
        let euid = nix::unistd::geteuid().as_raw();
        Ok(ControlServer {
            socket: None,
            stop: Arc::new(stop),
            policy: Policy { daemon_uid: euid, allowed_gid: nix::unistd::getegid().as_raw() },
            max_clients: 0,
            max_request: 0,
            idle: None,
            clients: BTreeMap::new(),
            next_id: 1,
            accept_paused_until: None,
            local: Some(inbox),
            locals: Locals::default(),
            next_local: FIRST_LOCAL_ID,
        })
    }

    /// Serves the in-process door `inbox` too.
    pub fn with_local(mut self, inbox: LocalInbox) -> ControlServer {
        self.local = Some(inbox);
        self
    }

    /// The socket's path; `None` for a server of the in-process door alone.
    pub fn path(&self) -> Option<&Path> {
        self.socket.as_ref().map(SocketFile::path)
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
            let outstanding =
                !self.locals.0.is_empty() || self.clients.values().any(|c| c.outstanding);
            let timeout = timeout_until(now, self.next_deadline(now, outstanding, handler.tick()));
            if self.accept_paused_until.is_some_and(|until| now >= until) {
                self.accept_paused_until = None;
            }
            events.clear();
            let (stopped, acceptable, woken, submitted) = {
                let mut fds = Vec::with_capacity(self.clients.len() + 4);
                let listen = if self.accept_paused_until.is_none() {
                    PollFlags::POLLIN
                } else {
                    PollFlags::empty()
                };
                fds.push(PollFd::new(self.stop.as_fd(), PollFlags::POLLIN));
                // The index of each optional fd in `fds`.
                fn at<'f>(fds: &mut Vec<PollFd<'f>>, fd: Option<BorrowedFd<'f>>) -> Option<usize> {
                    fd.map(|fd| {
                        fds.push(PollFd::new(fd, PollFlags::POLLIN));
                        fds.len() - 1
                    })
                }
                let listener = at(&mut fds, self.socket.as_ref().map(|s| s.listener().as_fd()));
                if let Some(i) = listener {
                    fds[i].set_events(listen);
                }
                let wake = at(&mut fds, handler.wake_fd());
                let local = at(&mut fds, self.local.as_ref().map(LocalInbox::fd));
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
                let ready = |i: Option<usize>| i.is_some_and(|i| !revents(&fds[i]).is_empty());
                (!revents(&fds[0]).is_empty(), ready(listener), ready(wake), ready(local))
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
            if submitted {
                self.take_local(handler);
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

    /// Hands the in-process door's requests to the handler; answers at once what it answers
    /// at once, and parks the rest until [`ControlServer::complete`] has their answers.
    fn take_local(&mut self, handler: &mut impl Handler) {
        let Some(local) = &self.local else { return };
        for submitted in local.take() {
            if self.locals.0.len() >= MAX_LOCAL_OUTSTANDING {
                let message = format!(
                    "{MAX_LOCAL_OUTSTANDING} requests of this process's services wait for the \
                     scan thread; try again"
                );
                (submitted.reply)(ResponseLine::error(ErrorKind::Busy, message));
                continue;
            }
            let id = self.next_local;
            self.next_local += 1;
            match handler.request(id, &submitted.caller, submitted.request) {
                Some(response) => (submitted.reply)(response),
                None => {
                    self.locals.0.insert(id, submitted.reply);
                }
            }
        }
    }

    /// Delivers the answers that became ready, and goes on with those clients' next lines.
    fn complete(&mut self, handler: &mut impl Handler, now: Instant) {
        let mut ready = Vec::new();
        handler.completions(&mut ready);
        let (limit, idle) = (self.max_request, self.idle);
        for (id, response) in ready {
            if let Some(reply) = self.locals.0.remove(&id) {
                reply(response);
                continue;
            }
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
            let Some(socket) = &self.socket else { return Ok(()) };
            let stream = match socket.listener().accept() {
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
        self.clients.insert(id, Client::new(stream, peer, self.idle.map(|idle| now + idle)));
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

#[cfg(test)]
mod tests {
    use super::*;

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
