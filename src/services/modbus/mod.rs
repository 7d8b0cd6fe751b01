//! The Modbus TCP and RTU servers of `plcd run` (docs/MODBUS.md): HMIs, SCADA systems and
//! Node-RED read and write device memory through a configured register map (`[modbus]`), over
//! TCP (`listen`) or a serial line (`[modbus.rtu]`), or both.
//!
//! - [`map`]: Modbus addresses of the four tables to device bits and words, resolved once;
//! - [`pdu`]: one request to one response, every function code and exception, behind the
//!   [`pdu::Plc`] trait;
//! - [`server`]: the listener and connection threads (not real time), and the [`pdu::Plc`] of
//!   the running driver: reads from a [`crate::drivers::real_time::mirror::Mirror`] captured at a scan
//!   boundary, writes as [`crate::drivers::real_time::Command::Words`] applied at one;
//! - [`rtu`]: the serial line's framing and its thread, answering through [`pdu`] too.
//!
//! Frames are decoded and encoded by the `modbus-core` crate; the servers add the MBAP
//! framing on a blocking socket, the RTU framing on a serial port, the checks the crate leaves
//! to the application (quantities, byte counts, exact lengths, the map) and the bounds.

pub mod map;
pub mod pdu;
pub mod rtu;
pub mod server;

pub use map::Map;
pub use server::{ModbusLinks, ModbusServer, RunningServer};

/// Why the Modbus server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ModbusError {
    #[error("cannot listen on {addr} ([modbus] listen): {source}")]
    Bind {
        addr: std::net::SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot open {} ([modbus.rtu] port): {}", .0.port.display(), .0.source)]
    Serial(crate::io::serial::SerialError),
    #[error("cannot start the modbus thread: {source}")]
    Spawn {
        #[source]
        source: std::io::Error,
    },
    #[error("modbus server: {0}")]
    Sys(String),
}
