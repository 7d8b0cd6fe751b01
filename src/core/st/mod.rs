//! Structured Text (IEC 61131-3), docs/ST.md: parse → check → compile into
//! [`Program`](crate::lang::Program)s of the same VM the instruction list runs on.
//!
//! - [`ast`]: the syntax tree;
//! - [`syntax`]: text → tree, with every syntax error of a file;
//! - [`sfc`]: a POU's Sequential Function Chart, as parsed;
//! - [`twincat`]: TwinCAT's `.TcPOU`/`.TcDUT`/`.TcGVL`/`.TcIO` files → ST text on the same lines;
//! - [`plcproj`]: TwinCAT's `.plcproj` project files → the namespaces they name;
//! - [`dialect`]: the CODESYS/TwinCAT habits accepted beyond the standard, and `strict`;
//! - [`iec_check`]: what `plcd check` shows of the `[iec]` layout (the layouts are
//!   [`crate::device::iec`]'s);
//! - [`libraries`]: the system libraries plcd ships (`Tc2_System`, …), as ST sources;
//! - [`configuration`]: a `CONFIGURATION`'s tasks and program instances → the project's;
//! - [`compile`](mod@compile): trees of all the project's `.st` files → one program per `[[program]]`
//!   instance, the variable memory's layout and initial image, and every variable by name.

pub mod ast;
pub mod compile;
pub mod configuration;
pub mod dialect;
pub mod iec_check;
pub mod libraries;
pub mod plcproj;
pub mod sfc;
pub mod syntax;
pub mod twincat;

pub use compile::{
    compile, compile_configured, compile_in_namespaces, compile_project, compile_with, Compiled,
    ConfigBindings, Instance,
};
pub use syntax::{parse_file, parse_file_with};
