//! Check: tokens into typed instructions, and every rule a program must follow.
//!
//! Each line is resolved on its own (mnemonic, operand count, operand kinds, ranges, write
//! protection); then the program's structure is followed line by line: rungs and their block and
//! MPUSH stacks, the main routine up to `END` and the `SBRT … RET` blocks after it, labels and
//! jumps, `FOR … NEXT` nesting. Errors are collected, never returned early, so a user sees every
//! mistake of a file in one run.
//!
//! The rooms: `mnemonic` (the table of mnemonics), `operand` (one operand resolved and checked,
//! the operand count, constants), `build` (a line into its op, edge-memory slots), `structure`
//! (rungs, routines, labels, jumps, calls, loops). This file holds what they share: the
//! checker's state, the line-by-line walk, and what the checker gives `compile`.

mod build;
mod mnemonic;
mod operand;
mod structure;

use std::collections::HashMap;
use std::path::Path;

use super::ops::Op;
use super::parse::SourceLine;
use crate::diag::{Diagnostic, Diagnostics};
use mnemonic::mnemonic_of;
pub use operand::parse_constant;
use structure::{OpenFor, Region, RungState};

/// What the checker needs to know about the project around a program.
pub struct Context<'a> {
    /// True for programs of the initialization task, the only ones where `INIT_DONE` is allowed.
    pub is_init: bool,
    /// The configured task numbers, for `DI n` / `EI n`.
    pub task_numbers: &'a [u8],
    /// The time base of a timer number in ms (100, 10 or 1), from `[timers]`.
    pub timer_base_ms: &'a dyn Fn(u32) -> Option<u32>,
    /// The first edge-memory slot this program may use.
    pub edge_base: u32,
}

/// A jump or call target still named by its number; `compile` resolves it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Link {
    /// `JMP n` in routine `routine`.
    Jmp {
        routine: usize,
        label: u32,
    },
    Call(u32),
    For {
        next: usize,
    },
    Next {
        for_: usize,
    },
}

/// One checked instruction.
#[derive(Debug, Clone)]
pub struct Checked {
    pub op: Op,
    pub line: u32,
    pub link: Option<Link>,
}

/// A DUTY instruction's destination, for the project-wide DUTY rules.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DutySite {
    pub channel: u8,
    pub line: u32,
    pub col: u32,
}

/// The checker's result for a program that has no errors.
#[derive(Debug, Clone)]
pub struct CheckedProgram {
    pub instructions: Vec<Checked>,
    /// `LABEL n` → instruction index, per routine (`0` main, `1..` the SBRTs in order).
    pub labels: HashMap<(usize, u32), usize>,
    /// `SBRT n` → index of the `SBRT` instruction.
    pub subroutines: HashMap<u32, usize>,
    pub edge_slots: u32,
    /// The constants of the double-word and real instructions (`Program::consts`).
    pub consts: Vec<u64>,
}

/// Hardest limit of edge memory: slots are 16-bit.
const MAX_EDGE_SLOTS: u32 = u16::MAX as u32 + 1;

/// The checker's state while it walks one file.
struct Checker<'a, 'c> {
    path: &'a Path,
    ctx: &'a Context<'c>,
    diags: Diagnostics,
    /// The instructions so far; a line that failed leaves none (except `FOR`, see `structure`).
    out: Vec<Checked>,
    // Op building: the next edge-memory slot, and the DUTY instructions.
    next_slot: u32,
    duty_sites: Vec<DutySite>,
    /// The double-word and real constants, each once, and where each is.
    consts: Vec<u64>,
    const_index: HashMap<u64, u16>,
    // Structure.
    region: Region,
    routines: usize,
    sbrt_open: Option<(u32, u32, u32)>,
    seen_end: bool,
    rung: RungState,
    depth: usize,
    mpush_lines: Vec<u32>,
    fors: Vec<OpenFor>,
    next_for_id: usize,
    labels: HashMap<(usize, u32), (usize, usize)>,
    label_lines: HashMap<(usize, u32), u32>,
    /// `JMP n` sites: label number, line, column, routine, enclosing loop.
    jumps: Vec<(u32, u32, u32, usize, usize)>,
    subroutines: HashMap<u32, usize>,
    sbrt_lines: HashMap<u32, u32>,
    calls: Vec<(u32, u32, u32)>,
}

/// Checks a parsed program. `path` names the file in diagnostics. The DUTY sites come back
/// whether or not the program has errors, so the project-wide DUTY rules can still be checked.
pub fn check(
    path: &Path,
    lines: &[SourceLine<'_>],
    last_line: u32,
    ctx: &Context<'_>,
) -> (Result<CheckedProgram, Diagnostics>, Vec<DutySite>) {
    let mut c = Checker {
        path,
        ctx,
        diags: Diagnostics::default(),
        out: Vec::new(),
        next_slot: ctx.edge_base,
        duty_sites: Vec::new(),
        consts: Vec::new(),
        const_index: HashMap::new(),
        region: Region::Main,
        routines: 1,
        sbrt_open: None,
        seen_end: false,
        rung: RungState::Idle,
        depth: 0,
        mpush_lines: Vec::new(),
        fors: Vec::new(),
        next_for_id: 1,
        labels: HashMap::new(),
        label_lines: HashMap::new(),
        jumps: Vec::new(),
        subroutines: HashMap::new(),
        sbrt_lines: HashMap::new(),
        calls: Vec::new(),
    };
    for line in lines {
        c.line(line);
    }
    c.finish_structure(last_line);
    c.check_edge_slots(last_line);
    let duty_sites = std::mem::take(&mut c.duty_sites);
    if c.diags.is_empty() {
        let labels = c.labels.iter().map(|(k, (index, _))| (*k, *index)).collect();
        let checked = CheckedProgram {
            instructions: c.out,
            labels,
            subroutines: c.subroutines,
            edge_slots: c.next_slot - ctx.edge_base,
            consts: c.consts,
        };
        (Ok(checked), duty_sites)
    } else {
        c.diags.0.sort_by_key(|d| (d.line, d.col));
        (Err(c.diags), duty_sites)
    }
}

impl<'a, 'c> Checker<'a, 'c> {
    fn error(&mut self, line: u32, col: u32, message: impl Into<String>) {
        self.diags.push(Diagnostic::new(self.path, line, col, message));
    }

    /// One line: its mnemonic and operand count, its op, then its place in the structure.
    fn line(&mut self, source: &SourceLine<'_>) {
        let line = source.line;
        let head = &source.tokens[0];
        let Some((mnemonic, used)) = mnemonic_of(&source.tokens) else {
            self.error(line, head.col, format!("unknown mnemonic `{}`", head.text));
            return;
        };
        let name = source.tokens[..used]
            .iter()
            .map(|t| t.text.to_ascii_uppercase())
            .collect::<Vec<_>>()
            .join(" ");
        let operands = &source.tokens[used..];
        if !self.operand_count_ok(mnemonic, &name, operands, line, head.col) {
            // Still follow the structure, so that one typo does not hide later errors.
            self.structure(mnemonic, None, line, head.col, operands);
            return;
        }
        let op = self.build(mnemonic, &name, operands, line, head.col);
        self.structure(mnemonic, op, line, head.col, operands);
    }
}
