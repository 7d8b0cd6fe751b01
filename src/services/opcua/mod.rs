//! The OPC UA server of `plcd run` (docs/OPCUA.md): SCADA, MES, historians and UaExpert browse,
//! read, subscribe to and write the PLC's status and its Structured Text variables by name, and
//! call its RUN, STOP and reset methods.
//!
//! - [`access`]: who may open a session (anonymous as `[opcua] anonymous` says, user names from
//!   the users file, throttled per name) and what its role lets it do;
//! - [`nodes`]: the address space's plan: node ids from the variables' full names, which are
//!   writable;
//! - [`values`]: IEC values as OPC UA values, read out of a mirror's copies and written back as
//!   the text `plcctl set` takes;
//! - [`manager`]: plcd's node manager in the stack: writes and method calls, handed to the
//!   request handler through the control server's in-process door, as `plcctl`'s are;
//! - [`space`]: the address space in the stack's node store, built from a plan and changed
//!   from one plan to the next;
//! - [`status`]: the figures of the daemon's status answer (percentiles, health counters, tasks,
//!   remote devices), asked through the door once per sampling interval;
//! - [`follow`]: the plans of the engines the daemon queues (a reload, a load, an online
//!   change), so that the address space follows the running project;
//! - [`front`]: the public socket in front of the stack: connections admitted per address,
//!   messages bounded whole and in rate, stalled clients cut off, each logged once per address;
//! - [`server`]: the OPC UA stack (the `async-opcua` crate) on a small tokio runtime of its own
//!   threads, never real time, and the sampler thread that copies the variables at scan
//!   boundaries through a [`crate::drivers::real_time::mirror::Mirror`] of the whole variable
//!   memory and hands the changed values to the stack.
//!
//! The scan never waits for either: it copies the mirror at a scan boundary when the sampler
//! asks, at most once per `min_sampling_interval_ms`, with `try_lock` only and nothing
//! allocated (`tests/scan_no_alloc.rs`); writes and method calls reach the PLC through the
//! command queue, at a scan boundary, as `plcctl`'s do. What is not served yet is listed in
//! docs/OPCUA.md, "Not yet".

pub mod access;
pub mod follow;
pub mod front;
pub mod manager;
pub mod nodes;
pub mod server;
pub mod space;
pub mod status;
pub mod values;

pub use server::{OpcuaServer, RunningOpcua};

/// Why the OPC UA server could not start.
#[derive(Debug, thiserror::Error)]
pub enum OpcuaError {
    #[error("cannot listen on {addr} ([opcua] listen): {source}")]
    Bind {
        addr: std::net::SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "no directory for the server's certificate: set [opcua] pki_dir, [retain] dir, or run \
         under systemd's StateDirectory= ($STATE_DIRECTORY)"
    )]
    NoPkiDir,
    #[error("cannot prepare {} ([opcua] pki_dir): {source}", .dir.display())]
    Pki {
        dir: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "no server certificate and key in {} ([opcua] pki_dir): they could be neither read nor \
         created",
        .dir.display()
    )]
    Certificate { dir: std::path::PathBuf },
    #[error("cannot listen on the loopback interface for the OPC UA stack: {source}")]
    Loopback {
        #[source]
        source: std::io::Error,
    },
    #[error("cannot start the OPC UA runtime: {source}")]
    Runtime {
        #[source]
        source: std::io::Error,
    },
    #[error("the OPC UA stack refused its configuration: {0}")]
    Stack(String),
    #[error("cannot start the opcua sampler thread: {source}")]
    Spawn {
        #[source]
        source: std::io::Error,
    },
}
