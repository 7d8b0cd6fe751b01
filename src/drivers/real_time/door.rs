//! The in-process door to the daemon's request handler: services that act on the PLC for their
//! own users (the OPC UA server's writes and its RUN/STOP/reset methods) hand it the same
//! [`Request`]s `plcctl` sends, and get the same answers, decided by the same rules (the mode
//! rules, the key switch, which devices a client may write) in one place: the request handler
//! behind the control server (`services::control`), which takes them from the door's inbox.
//! They never touch the command queue themselves.
//!
//! The door is bounded ([`LocalDoor::submit`] refuses past [`MAX_WAITING`] requests not yet
//! taken), never blocks its caller, and wakes the control server's poll loop through an
//! eventfd. The answer comes back through the callback the request came with, called on the
//! control thread once the handler answers (at once, or after the scan boundary that applied
//! it); a callback must only hand the answer on (a channel's send), never wait.

use std::collections::VecDeque;
use std::os::fd::{AsFd, BorrowedFd};
use std::sync::{Arc, Mutex};

use nix::sys::eventfd::{EfdFlags, EventFd};
use plcd_ipc::{Request, ResponseLine};

/// Requests submitted and not yet taken by the control server, at most.
pub const MAX_WAITING: usize = 64;

/// Who sent a request, for the handler's log line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Caller {
    /// A client of the control socket, by its credentials.
    Socket { uid: u32, pid: i32 },
    /// A service of this process for one of its users: `opcua user "alice"`.
    Service(String),
}

impl std::fmt::Display for Caller {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Caller::Socket { uid, pid } => write!(f, "uid {uid} (pid {pid})"),
            Caller::Service(who) => f.write_str(who),
        }
    }
}

/// Where an answer goes: called once, on the control thread.
pub type Reply = Box<dyn FnOnce(ResponseLine) + Send>;

/// One submitted request.
pub struct Submitted {
    pub request: Request,
    pub caller: Caller,
    pub reply: Reply,
}

/// The door was full: [`MAX_WAITING`] requests wait to be taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{MAX_WAITING} requests of this process's services are waiting for the control thread")]
pub struct DoorFull;

struct Shared {
    queue: Mutex<VecDeque<Submitted>>,
    wake: EventFd,
}

/// The services' end: cheap to clone, one per service.
#[derive(Clone)]
pub struct LocalDoor(Arc<Shared>);

/// The control server's end.
pub struct LocalInbox(Arc<Shared>);

impl std::fmt::Debug for LocalInbox {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("LocalInbox")
    }
}

/// A door and its inbox.
pub fn door() -> std::io::Result<(LocalDoor, LocalInbox)> {
    let wake = EventFd::from_flags(EfdFlags::EFD_NONBLOCK | EfdFlags::EFD_CLOEXEC)?;
    let shared = Arc::new(Shared { queue: Mutex::new(VecDeque::new()), wake });
    Ok((LocalDoor(Arc::clone(&shared)), LocalInbox(shared)))
}

impl LocalDoor {
    /// Hands `request` to the control thread; `reply` gets its answer. Never blocks.
    pub fn submit(&self, request: Request, caller: Caller, reply: Reply) -> Result<(), DoorFull> {
        {
            let mut queue = self.0.queue.lock().unwrap_or_else(|e| e.into_inner());
            if queue.len() >= MAX_WAITING {
                return Err(DoorFull);
            }
            queue.push_back(Submitted { request, caller, reply });
        }
        // A full counter (2^64 - 2 wakes unread) still leaves the fd readable: nothing lost.
        let _ = self.0.wake.write(1);
        Ok(())
    }
}

impl LocalInbox {
    /// Readable when requests were submitted.
    pub fn fd(&self) -> BorrowedFd<'_> {
        self.0.wake.as_fd()
    }

    /// Every request submitted so far, oldest first; clears the wake.
    pub fn take(&self) -> Vec<Submitted> {
        let _ = self.0.wake.read();
        let mut queue = self.0.queue.lock().unwrap_or_else(|e| e.into_inner());
        queue.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plcd_ipc::Reply as Answer;

    fn nothing() -> Reply {
        Box::new(|_| {})
    }

    #[test]
    fn requests_come_out_in_order_and_the_door_is_bounded() {
        let (door, inbox) = door().unwrap();
        let caller = Caller::Service("opcua user \"alice\"".into());
        for _ in 0..MAX_WAITING {
            door.submit(Request::Status, caller.clone(), nothing()).unwrap();
        }
        assert_eq!(door.submit(Request::Run, caller.clone(), nothing()), Err(DoorFull));
        let taken = inbox.take();
        assert_eq!(taken.len(), MAX_WAITING);
        assert!(taken.iter().all(|s| s.request == Request::Status));
        assert!(inbox.take().is_empty(), "taken once");
        let (tx, rx) = std::sync::mpsc::channel();
        let reply: Reply = Box::new(move |line| tx.send(line).unwrap());
        door.submit(Request::Stop, caller, reply).unwrap();
        for s in inbox.take() {
            assert_eq!(s.request, Request::Stop);
            (s.reply)(ResponseLine::ok(Answer::Written { scan: 1, count: 1 }));
        }
        assert!(rx.try_recv().is_ok(), "the answer reached the caller's callback");
    }

    #[test]
    fn a_caller_says_who_it_is() {
        assert_eq!(Caller::Socket { uid: 0, pid: 12 }.to_string(), "uid 0 (pid 12)");
        assert_eq!(Caller::Service("opcua anonymous".into()).to_string(), "opcua anonymous");
    }
}
