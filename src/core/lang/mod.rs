//! The instruction-list language (docs/LANGUAGE.md): parse → check → compile.
//!
//! [`parse`](parse::parse) splits text into tokens with columns, [`check`](check::check) resolves
//! mnemonics and operands and enforces every structural rule (collecting all errors),
//! [`compile`](compile::compile) resolves targets into the pre-decoded [`Program`] the VM runs.

pub mod check;
pub mod compile;
pub mod native;
pub mod ops;
pub mod parse;

use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use check::{Context, DutySite};
pub use ops::{Op, Place};

use crate::symbols::Symbols;
use crate::value::{Elem, Pointer, Space};

use crate::diag::Diagnostics;

/// Nesting limit of `LOAD` blocks and of `MPUSH` within one rung.
pub const RUNG_STACK_DEPTH: usize = 16;
/// Nesting limit of `FOR … NEXT`, checked statically per routine and again at run time (a
/// `CALL` inside a loop can nest deeper).
pub const LOOP_DEPTH: usize = 16;
/// Nesting limit of `CALL`, checked at run time (error 4210H).
pub const CALL_DEPTH: usize = 16;

/// Slots of a task's evaluation stack for Structured Text expressions; the compiler refuses an
/// expression that needs more.
pub const EVAL_DEPTH: usize = 64;
/// Nesting limit of Structured Text FUNCTION and FUNCTION_BLOCK calls (recursion is refused),
/// checked when the program is compiled.
pub const ST_CALL_DEPTH: usize = 32;

/// The language a program was written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Language {
    InstructionList,
    StructuredText,
}

/// An executable program.
#[derive(Debug, Clone)]
pub struct Program {
    /// The instance name (the `[[program]]`'s `name`).
    pub name: String,
    pub path: PathBuf,
    pub language: Language,
    pub code: Box<[Op]>,
    /// Wide constants of `Op::PushConst` and of the IL double-word and real instructions.
    pub consts: Box<[u64]>,
    /// Bytes of frame area the program needs (Structured Text: the deepest chain of calls'
    /// locals and temporaries); 0 for the instruction list.
    pub frame_bytes: u32,
    /// Code compiled from other files than `path` (a FUNCTION declared in another `.st` file):
    /// `(first pc, file)` of each stretch, sorted by pc. A stretch runs to the next one; code
    /// before the first is from `path`.
    pub regions: Box<[(u32, PathBuf)]>,
    /// The source line of each instruction.
    pub lines: Box<[u32]>,
    /// The first instruction of each statement, sorted: where a breakpoint set at a line stops
    /// and where `step` stops going line by line. Every instruction of the instruction list;
    /// in Structured Text each statement, each `ELSIF` condition, the `UNTIL` test, the
    /// increment of a `FOR` loop and the `END_*` of each POU.
    pub statements: Box<[u32]>,
    /// This program's edge memory is `edge_base .. edge_base + edge_slots`.
    pub edge_base: u32,
    pub edge_slots: u32,
    /// `LABEL n` instructions: `(n, pc)`, sorted by pc. A label number may appear once per
    /// routine, so the same `n` can occur more than once.
    pub labels: Box<[(u32, u32)]>,
    /// `SBRT n` instructions: `(n, pc)`, sorted by pc.
    pub subroutines: Box<[(u32, u32)]>,
    /// Machine code compiled from `code`, which the VM runs in its place where it can
    /// ([`native`]); attached by the shell after the project is compiled, `None` to interpret
    /// only.
    pub native: Option<std::sync::Arc<dyn native::NativeCode>>,
    /// Every `BOOL` in variable memory holds 0 or 1, so that native code may read one as it is
    /// instead of testing it for nonzero: the compiler proved that no code of the project writes
    /// another type's bytes over a `BOOL` there (`st::compile::bool_bytes`), and the engine
    /// rewrites the `BOOL`s this program reads ([`bool_variables`]) after it copies bytes in
    /// from elsewhere (retained values, online change). Always `false` for the instruction list,
    /// which reads no variable memory.
    pub var_bools_canonical: bool,
}

impl Program {
    /// The source line of the instruction at `pc`.
    pub fn line_of(&self, pc: usize) -> u32 {
        self.lines.get(pc).copied().unwrap_or(0)
    }

    /// True if `pc` is the first instruction of a statement (see [`Program::statements`]).
    pub fn starts_statement(&self, pc: u32) -> bool {
        self.statements.binary_search(&pc).is_ok()
    }

    /// The source file of the instruction at `pc`.
    pub fn file_of(&self, pc: usize) -> &Path {
        let after = self.regions.partition_point(|(start, _)| *start as usize <= pc);
        match after.checked_sub(1) {
            Some(i) => &self.regions[i].1,
            None => &self.path,
        }
    }
}

/// The variable memory of a project's Structured Text programs (their instances, the FB
/// instances inside them, the globals): its contents at RUN start, what a warm restart keeps,
/// the located variables' initial values, and every variable by name.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Variables {
    /// The memory's contents at RUN start; its length is the memory's size. Shared: the VM
    /// that runs the project and every clone of it read this one copy (a TcUnit project's
    /// is 78 MB).
    pub initial: Arc<[u8]>,
    /// `(offset, len)` of the `RETAIN` variables' bytes, kept over a warm restart.
    pub retained: Box<[(u32, u32)]>,
    /// `(offset, len)` of the `PERSISTENT` variables' bytes (among `retained`), kept over a
    /// cold reset too.
    pub persistent: Box<[(u32, u32)]>,
    /// Located variables with an initial value: written to their devices at RUN start, after
    /// the device areas are cleared.
    pub located_init: Box<[(Place, Elem, u64)]>,
    /// Every variable's leaves, in declaration order, an array one entry
    /// ([`crate::symbols`]).
    pub symbols: Symbols,
    /// Each reference type of the variables (`REF_TO Axis`, as [`ValueType::Reference`]
    /// names it) with the leaves of what it points to, placed from the start of the target
    /// (`""` for an `INT`, `.pos` for a struct's member): what `main.r^` and `main.p^.pos`
    /// name ([`crate::project::Through`]).
    ///
    /// [`ValueType::Reference`]: crate::value::ValueType::Reference
    pub referents: Vec<(String, Symbols)>,
    /// The access paths of `VAR_ACCESS`: names clients give a variable or a device.
    pub access: Vec<AccessPath>,
}

/// A `VAR_ACCESS` entry (IEC 61131-3 access path, docs/ST.md): the name under which clients
/// reach a variable or a device, and whether they may write it.
#[derive(Debug, Clone, PartialEq)]
pub struct AccessPath {
    /// As declared (`count`).
    pub name: String,
    /// What it names, as clients would name it otherwise: a variable (`main.n`, `main.fb.q`,
    /// `g`) or a device (`P0001`).
    pub target: String,
    /// `READ_WRITE`: clients may write it; `READ_ONLY` (the default) is read only.
    pub read_write: bool,
}

/// The variable-memory offsets of the `BOOL`s `program`'s code reads or writes by their fixed
/// place, which its native code reads as they are when [`Program::var_bools_canonical`] (none
/// otherwise): the bytes the engine rewrites to 0 or 1 after copying variable memory in from
/// elsewhere. Sorted, each once.
pub fn bool_variables(program: &Program) -> Vec<u32> {
    if !program.var_bools_canonical {
        return Vec::new();
    }
    let mut offsets: Vec<u32> = program
        .code
        .iter()
        .filter_map(|op| match *op {
            ops::Op::Fetch { elem: Elem::Bool, at: ops::Place::Var(offset) }
            | ops::Op::Store { elem: Elem::Bool, at: ops::Place::Var(offset) } => Some(offset),
            _ => None,
        })
        .collect();
    offsets.sort_unstable();
    offsets.dedup();
    offsets
}

/// What the reference value `slot` points to, as tools show it: the variable of `symbols` at
/// that place (`main.buf[2]`; `main.s+3` inside one, a STRING's character), else
/// [`crate::device::format_reference`]'s text (`NULL`, `D00100`, `vars+120` for memory no
/// named variable holds: a FUNCTION's frame, a constant).
pub fn reference_text(symbols: &Symbols, slot: u64) -> String {
    if let Some(p) = Pointer::from_reference(slot).filter(|p| p.space == Space::Var) {
        if let Some(s) = symbols.holding(Space::Var, p.offset) {
            return match p.offset - s.at.offset {
                0 => s.name,
                inside => format!("{}+{inside}", s.name),
            };
        }
    }
    crate::device::format_reference(slot)
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
