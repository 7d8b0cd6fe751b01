//! The services around a running real-time driver, each on threads of its own that never make
//! the scan wait: they reach the PLC only through the driver's queues, mirrors and snapshots,
//! at scan boundaries.
//!
//! - [`control`]: the control socket that `plcctl` and scripts talk to (the protocol is the
//!   `plcd-ipc` crate); what the requests do is the daemon's ([`crate::daemon::requests`]);
//! - [`modbus`]: the Modbus TCP server and its register map;
//! - `mqtt` (with the `mqtt` feature; its protocol alone with `sparkplug`): the Sparkplug B edge
//!   node, its metrics and its sampler;
//! - `opcua` (with the `opcua` feature): the OPC UA server, its address space and its sampler;
//! - [`retain`]: retained memory on disk: the generation files, the writer thread, restore at
//!   start.

pub mod control;
pub mod modbus;
#[cfg(feature = "sparkplug")]
pub mod mqtt;
#[cfg(feature = "opcua")]
pub mod opcua;
pub mod retain;
