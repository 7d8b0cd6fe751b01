//! Structured Text compiler: resolves names and types across every file of a project, checks
//! (every error at once), lays out variable memory and generates VM code.

use std::path::Path;

use super::ast;
use crate::diag::Diagnostics;
use crate::lang::{Program, Variables};

/// One `[[program]]` of Structured Text: the instance to create.
#[derive(Debug, Clone, Copy)]
pub struct Instance<'a> {
    /// The instance name, the prefix of its variables (`main` → `main.speed`).
    pub name: &'a str,
    /// The PROGRAM to instantiate; `None` when its file declares exactly one.
    pub pou: Option<&'a str>,
    /// The `.st` file the `[[program]]` names.
    pub file: &'a Path,
    /// Where the `[[program]]` is in the config, for diagnostics about `pou`.
    pub config: &'a Path,
    pub line: u32,
    pub col: u32,
}

/// A compiled project's Structured Text.
#[derive(Debug, Clone)]
pub struct Compiled {
    /// One program per instance, in the order given.
    pub programs: Vec<Program>,
    pub variables: Variables,
}

/// Compiles every instance against the declarations of all `files`.
pub fn compile(files: &[ast::File], instances: &[Instance<'_>]) -> Result<Compiled, Diagnostics> {
    let _ = (files, instances);
    unimplemented!("compiler helper")
}
