//! The instruction-list language (docs/LANGUAGE.md): parse → check → compile.
//!
//! [`parse`](parse::parse) splits text into tokens with columns, [`check`](check::check) resolves
//! mnemonics and operands and enforces every structural rule (collecting all errors),
//! [`compile`](compile::compile) resolves targets into the pre-decoded [`Program`] the VM runs.

pub mod check;
pub mod compile;
pub mod ops;
pub mod parse;

use std::path::{Path, PathBuf};

pub use check::{Context, DutySite};
pub use ops::Op;

use crate::diag::Diagnostics;

/// Nesting limit of `LOAD` blocks and of `MPUSH` within one rung.
pub const RUNG_STACK_DEPTH: usize = 16;
/// Nesting limit of `FOR … NEXT`, checked statically per routine and again at run time (a
/// `CALL` inside a loop can nest deeper).
pub const LOOP_DEPTH: usize = 16;
/// Nesting limit of `CALL`, checked at run time (error 4210H).
pub const CALL_DEPTH: usize = 16;

/// An executable program.
#[derive(Debug, Clone)]
pub struct Program {
    pub name: String,
    pub path: PathBuf,
    pub code: Box<[Op]>,
    /// The source line of each instruction.
    pub lines: Box<[u32]>,
    /// This program's edge memory is `edge_base .. edge_base + edge_slots`.
    pub edge_base: u32,
    pub edge_slots: u32,
    /// `LABEL n` instructions: `(n, pc)`, sorted by pc. A label number may appear once per
    /// routine, so the same `n` can occur more than once.
    pub labels: Box<[(u32, u32)]>,
    /// `SBRT n` instructions: `(n, pc)`, sorted by pc.
    pub subroutines: Box<[(u32, u32)]>,
}

impl Program {
    /// The source line of the instruction at `pc`.
    pub fn line_of(&self, pc: usize) -> u32 {
        self.lines.get(pc).copied().unwrap_or(0)
    }
}

/// Assembles one program text: every diagnostic of the file, or the program.
pub fn assemble(
    name: &str,
    path: &Path,
    source: &str,
    ctx: &Context<'_>,
) -> Result<Program, Diagnostics> {
    assemble_with_duty_sites(name, path, source, ctx).0
}

/// [`assemble`], also returning the file's DUTY instructions (even when it has errors), for
/// the rules that count DUTY across a project.
pub fn assemble_with_duty_sites(
    name: &str,
    path: &Path,
    source: &str,
    ctx: &Context<'_>,
) -> (Result<Program, Diagnostics>, Vec<DutySite>) {
    let lines = parse::parse(source);
    let last_line = source.lines().count() as u32;
    let (checked, duty_sites) = check::check(path, &lines, last_line, ctx);
    let program = checked.map(|checked| compile::compile(name, path, checked, ctx.edge_base));
    (program, duty_sites)
}
