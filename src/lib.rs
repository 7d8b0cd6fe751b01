//! plcd: a real-time soft-PLC runtime.
//!
//! The crate is layered the way the PLC works:
//! - [`config`]: the project file (TOML) parsed into typed, range-checked structs;
//! - [`lang`]: the instruction-list language, parse → check → compile into [`lang::Program`];
//! - [`device`]: device memory, its fixed layout and its address syntax;
//! - [`vm`]: executes compiled programs one instruction at a time, resumable between any two;
//! - [`project`]: a config and all its programs, loaded and checked together;
//! - [`engine`]: the task engine, pure and clock-injected: what runs when;
//! - [`io`]: I/O backends behind one trait;
//! - [`modbus`]: the Modbus TCP server and its register map;
//! - [`bench`]: measuring all of it on the machine it runs on (`plcd bench`, BENCHMARKS.md).
#![deny(unsafe_code)]

pub mod bench;
pub mod commands;
pub mod config;
pub mod control;
pub mod daemon;
pub mod device;
pub mod diag;
pub mod engine;
pub mod io;
pub mod lang;
pub mod modbus;
pub mod plcctl;
pub mod project;
pub mod retain;
pub mod rt;
pub mod sim;
pub mod stats;
pub mod vm;
