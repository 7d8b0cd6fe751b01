//! plcd-core: the pure core of plcd, the layer everything else stands on.
//!
//! It decides everything a PLC decides (what a program means, what runs when, what a device
//! holds) and touches nothing outside the process: no threads, files, sockets or clocks of its
//! own. Time comes in as numbers from an injected [`vm::Clock`], the field through the
//! [`io::Io`] trait, files as text. The two drivers of the `plcd` crate (virtual time for
//! `plcd sim`, real time for `plcd run`) feed this same engine; docs/ARCHITECTURE.md draws the
//! layers.
//!
//! The modules (docs/ARCHITECTURE.md ranks them: each imports only modules below its own):
//! - [`diag`]: located diagnostics (`path:line:col: error: message`), all reported at once;
//! - [`duration`], [`timestamp`]: how durations and time stamps are written;
//! - [`stats`]: allocation-free histograms for latencies and execution times;
//! - [`device`]: device memory, its fixed layout, the address syntax, which devices are
//!   retained and who may write which;
//! - [`io`]: the field as the engine sees it (the [`io::Io`] trait);
//! - [`config`]: the project's TOML config parsed into typed, range-checked structs;
//! - [`lang`]: the instruction-list language, parse → check → compile into [`lang::Program`];
//! - [`vm`]: executes compiled programs one instruction at a time, resumable between any two;
//! - [`symbols`]: every named leaf of the variables, an array one entry whatever its size;
//! - [`project`]: a config and all its programs, checked together;
//! - [`engine`]: the task engine: what runs when;
//! - [`stimulus`]: the simulation inputs file (timed device changes), parsed;
//! - [`users`]: the users of the network services, their password hashes and roles, and login
//!   throttling.
#![forbid(unsafe_code)]

pub mod clock;
pub mod config;
pub mod device;
pub mod diag;
pub mod duration;
pub mod engine;
pub mod io;
pub mod lang;
pub mod project;
pub mod st;
pub mod stats;
pub mod stimulus;
pub mod symbols;
pub mod timestamp;
pub mod users;
pub mod value;
pub mod vm;
