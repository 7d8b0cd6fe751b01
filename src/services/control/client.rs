//! One admitted connection of the control server: its bytes in and out and the protocol's
//! framing — lines in ([`protocol::parse_request`]), one response line out per request — with
//! the bounds that keep one client from costing the others: at most the request limit of
//! unread input, at most [`MAX_OUTPUT_BYTES`] of unsent answers, one request outstanding, and
//! a deadline for idling (or, once it is being closed, for reading its last answer).
//!
//! What a request *does* belongs to the [`Handler`]; when to read, write and close is the poll
//! loop's ([`super::server`]).

use std::io::{self, Read};
use std::os::fd::AsRawFd;
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::poll::PollFlags;
use nix::sys::socket::{self, MsgFlags};

use super::{Caller, ClientId, Handler, Peer};
use plcd_ipc::{self as protocol, ErrorKind, ResponseLine};

/// The most answer bytes kept for a client that does not read them; past this it is dropped
/// (a status line is a few KiB, so only a client that stopped reading gets here).
const MAX_OUTPUT_BYTES: usize = 4 << 20;
/// How long a connection being closed (after `too_long`) may take to read its last line.
const LINGER: Duration = Duration::from_secs(2);

/// Why a connection ends.
pub(super) type Close = &'static str;

/// One admitted connection.
#[derive(Debug)]
pub(super) struct Client {
    pub(super) stream: UnixStream,
    pub(super) peer: Peer,
    /// Received bytes not yet taken as lines: at most the request limit.
    input: Vec<u8>,
    /// Answer bytes the socket did not take yet: at most [`MAX_OUTPUT_BYTES`].
    output: Vec<u8>,
    /// A request was handed to the handler and its answer has not come.
    pub(super) outstanding: bool,
    /// The peer sends nothing more (it shut down its side, or closed).
    eof: bool,
    /// Close once the output is flushed (after `too_long`).
    closing: bool,
    /// When it is closed for idling (or, closing, for not reading its last line). None while
    /// a request is outstanding.
    pub(super) deadline: Option<Instant>,
}

impl Client {
    /// A new connection; `deadline`: when it is closed if it sends nothing.
    pub(super) fn new(stream: UnixStream, peer: Peer, deadline: Option<Instant>) -> Client {
        Client {
            stream,
            peer,
            input: Vec::new(),
            output: Vec::new(),
            outstanding: false,
            eof: false,
            closing: false,
            deadline,
        }
    }

    pub(super) fn wants_read(&self) -> bool {
        !self.outstanding && !self.eof && !self.closing
    }

    pub(super) fn interest(&self) -> PollFlags {
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
    pub(super) fn answer(
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
    pub(super) fn read(&mut self, limit: usize, scratch: &mut [u8]) -> Result<(), Close> {
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
    pub(super) fn flush(&mut self) -> Result<(), Close> {
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
    pub(super) fn pump(
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
                Ok(request) => match handler.request(
                    id,
                    &Caller::Socket { uid: self.peer.uid, pid: self.peer.pid },
                    request,
                ) {
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
    pub(super) fn finished(&self) -> bool {
        (self.eof || self.closing) && !self.outstanding && self.output.is_empty()
    }
}
