//! The daemon's contact with its host: the service manager and the log.

pub mod logging;
pub mod notify;
