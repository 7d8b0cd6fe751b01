//! Compile: a checked program into its executable form — jump, call and loop targets resolved
//! to program-counter values, source lines kept beside the code for diagnostics and debugging.

use std::path::Path;

use super::check::{CheckedProgram, Link};
use super::ops::Op;
use super::Program;

/// Lowers a program the checker accepted. Cannot fail: every target was checked to exist.
pub fn compile(name: &str, path: &Path, checked: CheckedProgram, edge_base: u32) -> Program {
    let mut code = Vec::with_capacity(checked.instructions.len());
    let mut lines = Vec::with_capacity(checked.instructions.len());
    for instruction in &checked.instructions {
        let op = match (instruction.op, instruction.link) {
            (Op::Jmp { .. }, Some(Link::Jmp { routine, label })) => {
                Op::Jmp { target: checked.labels[&(routine, label)] as u32 }
            }
            (Op::Call { .. }, Some(Link::Call(n))) => {
                Op::Call { target: checked.subroutines[&n] as u32 + 1 }
            }
            (Op::For { count, .. }, Some(Link::For { next })) => {
                Op::For { count, end: next as u32 + 1 }
            }
            (Op::Next { .. }, Some(Link::Next { for_ })) => Op::Next { body: for_ as u32 + 1 },
            (op, _) => op,
        };
        code.push(op);
        lines.push(instruction.line);
    }
    let sorted = |mut pairs: Vec<(u32, u32)>| {
        pairs.sort_by_key(|&(_, pc)| pc);
        pairs.into_boxed_slice()
    };
    let labels = sorted(checked.labels.iter().map(|(&(_, n), &pc)| (n, pc as u32)).collect());
    let subroutines = sorted(checked.subroutines.iter().map(|(&n, &pc)| (n, pc as u32)).collect());
    Program {
        name: name.to_string(),
        path: path.to_path_buf(),
        language: super::Language::InstructionList,
        code: code.into_boxed_slice(),
        consts: checked.consts.into_boxed_slice(),
        frame_bytes: 0,
        regions: Box::new([]),
        statements: (0..lines.len() as u32).collect(),
        lines: lines.into_boxed_slice(),
        edge_base,
        edge_slots: checked.edge_slots,
        labels,
        subroutines,
        native: None,
        var_bools_canonical: false,
    }
}
