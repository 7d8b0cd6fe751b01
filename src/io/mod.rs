//! The I/O backends: where the P image's inputs come from and its outputs go, each behind the
//! core's [`Io`] trait (re-exported here with the key switch and edge types).
//!
//! - [`simulated`]: the in-process field (`[io] backend = "sim"`, the default): inputs set by
//!   a stimulus, outputs kept as last published;
//! - [`gpio`]: the lines of a GPIO chip through the Linux GPIO character device
//!   (`backend = "gpiocdev"`);
//! - [`gate`]: the output gate between the scan thread and the watchdog thread, which any
//!   backend's outputs pass;
//! - [`faults`]: failures of the field's I/O paths, counted for the supervisor to log;
//! - [`serial`]: serial ports opened with a Modbus RTU line's settings;
//! - [`remote`]: Modbus TCP and RTU devices polled as remote I/O (`[[remote]]`).

pub mod faults;
pub mod gate;
pub mod gpio;
pub mod remote;
pub mod serial;
pub mod simulated;

pub use plcd_core::io::{InputEdge, Io, SwitchPosition};
