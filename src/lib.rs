//! plcd: a real-time soft-PLC runtime.
//!
//! - [`config`]: the project file (TOML) parsed into typed, range-checked structs;
//! - [`device`]: device memory, its fixed layout and its address syntax;
//! - [`diag`]: located diagnostics, all reported at once.
#![deny(unsafe_code)]

pub mod config;
pub mod device;
pub mod diag;
