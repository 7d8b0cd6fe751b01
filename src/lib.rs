//! plcd: a real-time soft-PLC runtime for Linux.
//!
//! The crate is the imperative shell around the pure core (the `plcd-core` crate, whose
//! modules are re-exported here under their own names). It is built in layers, bottom up; a
//! module imports only from layers below its own (never from a sibling of its layer), and
//! `tests/architecture.rs` fails when one does. docs/ARCHITECTURE.md draws the layers and the
//! data flow.
//!
//! | layer | modules | what they own |
//! |---|---|---|
//! | 0 core (`plcd-core`) | [`diag`] [`duration`] [`timestamp`] [`device`] [`config`] [`lang`] [`vm`] [`project`] [`io`]'s trait [`engine`] [`stimulus`] [`stats`] | what a PLC decides: no threads, files, sockets, `nix` or `gpiocdev` |
//! | 1 edge of the process | [`io`] (backends: [`io::simulated`], [`io::gpio`], [`io::gate`]), [`files`] | the field's lines, the project's files |
//! | 2 drivers | [`drivers::virtual_time`], [`drivers::real_time`] | feed the engine events and time: virtual (`plcd sim`) or real (`plcd run`) |
//! | 3 services | [`services::control`], [`services::modbus`], [`services::retain`] | the world around a running driver: the control socket, Modbus TCP, retained memory on disk |
//! | 4 supervisors | [`daemon`], [`bench`] | run a real-time driver with its services: `plcd run`, `plcd bench` |
//! | 5 commands | [`commands`] | one file per `plcd` subcommand; `src/main.rs` only parses arguments |
//!
//! The control protocol is its own crate (`plcd-ipc`), and so is its client (`plcctl`, over
//! `plcd-ipc` and `plcd-core` alone): neither needs this crate to build.
#![deny(unsafe_code)]

// Layer 0: the pure core.
pub use plcd_core::{
    config, device, diag, duration, engine, lang, project, stats, stimulus, timestamp, vm,
};

// Layer 1: the edge of the process.
pub mod files;
pub mod io;

// Layer 2: the drivers.
pub mod drivers;

// Layer 3: the services.
pub mod services;

// Layer 4: the supervisors.
pub mod bench;
pub mod daemon;

// Layer 5: the commands.
pub mod commands;
