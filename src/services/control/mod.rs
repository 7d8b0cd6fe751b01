//! The control socket of the daemon: the Unix socket server that carries the protocol `plcctl`
//! speaks (the `plcd-ipc` crate), and the interface between that server and whatever answers
//! the requests ([`Handler`]: the daemon's [`crate::daemon::requests`], or a test's fake).
//!
//! - [`server`]: the server and its poll loop: accepting, reading, writing, handing requests
//!   to the [`Handler`] and delivering its answers, closing;
//! - `socket`: where the socket file lives (the path and its fallbacks, the directory, a stale
//!   socket), its mode 0660 and group, and its removal when the server goes;
//! - `access`: who may connect (root, the daemon's user, one group);
//! - `client`: one connection: its buffers, the line framing, the bounds and deadlines.
//!
//! The server also takes the requests of this process's other services (the OPC UA server's
//! writes and methods) from the in-process door ([`crate::drivers::real_time::door`]), and
//! hands them to the same handler, under the same rules.
//!
//! Nothing here runs on a real-time thread. The server never waits for the scan thread: a
//! request the daemon cannot answer at once (it is applied at the next END) is answered later,
//! through [`Handler::completions`], while the server goes on serving the other clients.

mod access;
mod client;
pub mod server;
mod socket;

use std::os::fd::BorrowedFd;
use std::time::Duration;

pub use crate::drivers::real_time::door::Caller;
use plcd_ipc::{Request, ResponseLine};

/// A connection of the control server, unique for the server's lifetime.
pub type ClientId = u64;

/// The credentials of a connected peer, from `SO_PEERCRED`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Peer {
    pub pid: i32,
    pub uid: u32,
    pub gid: u32,
}

/// What answers the requests of admitted clients.
pub trait Handler {
    /// A request from `client`, sent by `caller`. `Some`: the answer, sent at once. `None`: the answer comes
    /// later through [`Handler::completions`]; until then the server reads nothing more from
    /// that client (one outstanding request per client bounds what can queue up).
    fn request(
        &mut self,
        client: ClientId,
        caller: &Caller,
        request: Request,
    ) -> Option<ResponseLine>;
    /// Appends the answers that became ready. Called when [`Handler::wake_fd`] is readable and
    /// at least every [`Handler::tick`] while answers are outstanding. It must drain the wake
    /// fd, or the server's poll returns at once again.
    fn completions(&mut self, ready: &mut Vec<(ClientId, ResponseLine)>);
    /// Becomes readable when completions may be ready.
    fn wake_fd(&self) -> Option<BorrowedFd<'_>>;
    /// The longest the server may sleep while an answer is outstanding.
    fn tick(&self) -> Duration;
    /// `client` disconnected; an outstanding answer for it is to be dropped.
    fn gone(&mut self, client: ClientId);
}
