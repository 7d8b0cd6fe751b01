//! The OPC UA server of `plcd run` (docs/OPCUA.md): SCADA, MES, historians and UaExpert browse,
//! read and subscribe to the PLC's status and its Structured Text variables by name.
//!
//! - [`access`]: who may open a session: anonymous as `[opcua] anonymous` says, user names from
//!   the users file, throttled per name;
//! - [`nodes`]: the address space's plan: node ids from the variables' full names, IEC types as
//!   OPC UA built-in types, values read out of a mirror's copies;
//! - [`server`]: the OPC UA stack (the `async-opcua` crate) on a small tokio runtime of its own
//!   threads, never real time, and the sampler thread that copies the variables at scan
//!   boundaries through a [`crate::drivers::real_time::mirror::Mirror`] of the whole variable
//!   memory and hands the changed values to the stack.
//!
//! The scan never waits for either: it copies the mirror at a scan boundary when the sampler
//! asks, at most once per `min_sampling_interval_ms`, with `try_lock` only and nothing
//! allocated (`tests/scan_no_alloc.rs`). This round serves reads, browsing and subscriptions to
//! anonymous and named sessions; writes, methods and the roles that decide them are not served
//! yet (docs/OPCUA.md, "Not yet").

pub mod access;
pub mod nodes;
pub mod server;

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
