//! Measuring plcd on the machine it runs on: what `plcd bench` runs and what the bench binaries
//! under `benches/` share.
//!
//! Every figure of BENCHMARKS.md is written by a command of the repo as a Markdown fragment
//! into `target/bench-results/NAME.md`; `benches/refresh` runs them all and splices each
//! fragment into BENCHMARKS.md between `<!-- BEGIN NAME -->` and `<!-- END NAME -->`.

pub mod realtime;
pub mod report;

pub use report::{machine, write_fragment, Fragment};
