//! The `plcd` subcommands, one file each; `main.rs` only parses arguments and dispatches.

pub mod bench;
pub mod check;
pub mod run;
pub mod sim;
pub mod user;
