//! The daemon's shell around the real-time driver: supervision from the main thread (signals,
//! reloads, statistics), the service manager and the log.

pub mod logging;
pub mod notify;
pub mod report;
pub mod requests;
pub mod supervisor;
