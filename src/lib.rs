//! plcd: a real-time soft-PLC runtime for Linux.
//!
//! This crate is the imperative shell around the pure core (the `plcd-core` crate, whose
//! modules are re-exported here under their own names): the I/O backends, the two drivers of
//! the one task engine, the services, the daemon and the `plcd` commands. Its modules are
//! declared below bottom up, one layer after the other; each imports only from layers below its
//! own. The layer table is docs/ARCHITECTURE.md, and `tests/architecture.rs` enforces it.
//!
//! The control protocol is a crate of its own (`plcd-ipc`), and so is its client (`plcctl`,
//! over `plcd-ipc` and `plcd-core` alone): neither needs this crate to build.
#![deny(unsafe_code)]

// The pure core.
pub use plcd_core::{
    config, device, diag, duration, engine, lang, project, st, stats, stimulus, symbols, timestamp,
    users, value, vm,
};

// The edge of the process.
pub mod files;
pub mod io;

// The drivers.
pub mod drivers;

// The services.
pub mod services;

// The supervisors.
pub mod bench;
pub mod daemon;

// The commands.
pub mod commands;
