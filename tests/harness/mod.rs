//! The test suite's one harness, included by each test that needs it with `mod harness;`:
//!
//! - [`tempdir`]: scratch directories, removed on drop;
//! - [`nobody`]: running a program as uid 65534, from a copy that user can reach;
//! - [`skip`]: visible skips, failures where a `PLCD_REQUIRE_*` variable says so;
//! - [`log`]: a process's log, and waiting for another process's events;
//! - [`runner`]: the built programs started through an emulator (`PLCD_TEST_RUNNER`) when the
//!   tests are cross-built;
//! - [`daemon`]: a project directory, the real `plcd run` on it, `plcctl` against it;
//! - [`engine`]: the engine in virtual time on a project from literal texts, with a field;
//! - [`vm`]: one program scanned by the VM alone, and the assembler's context;
//! - [`golden`]: golden files compared, or rewritten with `PLCD_BLESS=1`;
//! - [`modbus`]: Modbus PDUs built and taken apart by hand;
//! - [`parallel`]: one test's independent cases run on every core;
//! - [`gpiosim`]: whether the kernel's gpio-sim is here, and `require_gpiosim!` (include the
//!   harness with `#[macro_use]` to use it).
//!
//! `tempdir`, `nobody` and `runner` need nothing of plcd: the plcctl package's test includes
//! those three files alone.

// Every test crate compiles the whole harness and uses the part it needs: what one crate leaves
// unused another uses, so dead code is expected here, and only here.
#![allow(dead_code)]

pub mod daemon;
pub mod engine;
pub mod golden;
#[macro_use]
pub mod gpiosim;
pub mod log;
pub mod modbus;
pub mod nobody;
pub mod parallel;
pub mod runner;
pub mod skip;
pub mod tempdir;
pub mod vm;
