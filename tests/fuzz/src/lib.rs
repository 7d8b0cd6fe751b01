//! The fuzz targets of plcd: one function per input plcd parses from outside, each taking the
//! bytes AFL++ made and running them through the same code the daemon runs, then checking what
//! must hold (not only that nothing panicked). A broken invariant panics, which AFL++ counts as
//! a crash and keeps.
//!
//! - `il`: an instruction-list program, assembled with its project and, if accepted, run for a
//!   few scans in virtual time (twice: the runs must agree event for event).
//! - `st`: a Structured Text program, the same way.
//! - `twincat`: a TwinCAT `.TcPOU` file (XML around Structured Text), the same way.
//! - `plcproj`: a TwinCAT `.plcproj` file, its namespaces read alone and as the project files
//!   of a library folder and of a `.TcPOU` program that names the library's block by them.
//! - `config`: a `plcd.toml`, and, if accepted, its project (with stand-in programs) run.
//! - `stimulus`: an inputs file, and, if accepted, played into a project.
//! - `retain`: a retained-memory file: either restored exactly as written or refused.
//! - `control`: a session of control-protocol lines, through the socket server and the
//!   request handler of `plcd run` to a running scan thread.
//! - `modbus_tcp`: a byte stream to the Modbus TCP server: MBAP framing, then each PDU against
//!   a device image; every answer well-formed and naming its request.
//! - `modbus_rtu`: a byte stream with its timing to the Modbus RTU server's framer, then each
//!   frame as the server handles it.
//! - `remote`: an answer to the remote I/O client's request (TCP or RTU), checked as the poller
//!   checks it; whatever it accepts holds exactly the values the frame carries.
//! - `users`: a users file: rejected with located diagnostics that quote no hash, or accepted
//!   with every user as its line says and each removable alone.
//! - `mqtt`: messages to the Sparkplug B edge node (its NCMD, its devices' DCMD, the primary
//!   host's STATE) with any payload, between copies of the PLC of any bytes, through the
//!   protocol's state machine (`services::mqtt::edge`): everything it publishes a well-formed
//!   Sparkplug message in its order and sequence, every write it asks for a writable
//!   variable's, and every value a command carries converted by `metrics::written` for every
//!   IEC type into a refusal or a text `plcctl set` reads back.
//! - `opcua`: a byte stream to the OPC UA server: the stack's framing, secure channel (the None
//!   policy) and decoding, with plcd's limits; every request round-trips through the stack's
//!   encoding, and every value a Write or a Call carries is converted by plcd's
//!   `values::written` for every IEC type into a refusal or a text `plcctl set` reads back.
//!
//! Where an input must describe several things (a request and its answer, bytes and the gaps
//! between them), [`Bytes`] takes them off the front of the input, so that every input is
//! valid and AFL++'s mutations stay meaningful.

pub mod targets;

use std::path::Path;

use plcd::diag::Diagnostics;

/// A target: its name (the corpus directory, the `plcd-fuzz` argument) and its body.
pub struct Target {
    pub name: &'static str,
    pub run: fn(&[u8]),
}

/// Every target, in the order of the module docs.
pub const TARGETS: &[Target] = &[
    Target { name: "il", run: targets::il::run },
    Target { name: "st", run: targets::st::run },
    Target { name: "twincat", run: targets::twincat::run },
    Target { name: "plcproj", run: targets::plcproj::run },
    Target { name: "config", run: targets::config::run },
    Target { name: "stimulus", run: targets::stimulus::run },
    Target { name: "retain", run: targets::retain::run },
    Target { name: "control", run: targets::control::run },
    Target { name: "modbus_tcp", run: targets::modbus_tcp::run },
    Target { name: "modbus_rtu", run: targets::modbus_rtu::run },
    Target { name: "remote", run: targets::remote::run },
    Target { name: "users", run: targets::users::run },
    Target { name: "mqtt", run: targets::mqtt::run },
    #[cfg(feature = "opcua")]
    Target { name: "opcua", run: targets::opcua::run },
];

/// The target called `name`.
pub fn target(name: &str) -> Option<&'static Target> {
    TARGETS.iter().find(|t| t.name == name)
}

/// Builds what target `name` keeps for all its inputs, before AFL++'s fork server starts
/// (`afl::fuzz!` defers it to its first input): each child process the fork server makes
/// inherits it, where built in a child's first input its edges were counted in that input
/// alone and AFL++ took them for unstable (the `mqtt` target's compiled project: a stability
/// of 32 % without this). Only fixtures that start no thread: a child has no thread of its
/// parent's.
pub fn prepare(name: &str) {
    if name == "mqtt" {
        targets::mqtt::fixture();
    }
}

/// Checks that every diagnostic points into a text: a line within `text`'s (or the line after
/// the last, for "missing at the end") and a column from 1, or `0:0` for the file as a whole;
/// and a message. `text` is the file `path` holds; diagnostics of other files are not checked.
pub fn assert_located(diags: &Diagnostics, path: &Path, text: &str) {
    assert!(!diags.is_empty(), "an error without a diagnostic");
    let lines = text.split('\n').count() as u32;
    for d in diags.iter() {
        assert!(!d.message.trim().is_empty(), "a diagnostic without a message: {d:?}");
        // `path:0:0` is the file as a whole (docs/CONFIG.md).
        if d.path != path || (d.line, d.col) == (0, 0) {
            continue;
        }
        assert!(
            d.line >= 1 && d.line <= lines + 1,
            "line {} of a {lines}-line text: {d:?}",
            d.line
        );
        assert!(d.col >= 1, "column 0: {d:?}");
    }
}

/// Takes typed values off the front of a fuzz input; past its end, zeros.
pub struct Bytes<'a> {
    rest: &'a [u8],
}

impl<'a> Bytes<'a> {
    pub fn new(data: &'a [u8]) -> Bytes<'a> {
        Bytes { rest: data }
    }

    pub fn u8(&mut self) -> u8 {
        match self.rest.split_first() {
            Some((&b, rest)) => {
                self.rest = rest;
                b
            }
            None => 0,
        }
    }

    pub fn u16(&mut self) -> u16 {
        u16::from_be_bytes([self.u8(), self.u8()])
    }

    pub fn bool(&mut self) -> bool {
        self.u8() & 1 == 1
    }

    /// Up to `n` bytes.
    pub fn take(&mut self, n: usize) -> &'a [u8] {
        let (taken, rest) = self.rest.split_at(n.min(self.rest.len()));
        self.rest = rest;
        taken
    }

    /// Everything left.
    pub fn rest(&mut self) -> &'a [u8] {
        std::mem::take(&mut self.rest)
    }

    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }
}
