//! Program structure, followed line by line: the rungs (where one starts and ends, the LOAD
//! block stack and the `MPUSH` stack), the routines (the main program up to `END`, the
//! `SBRT … RET` blocks after it), `LABEL`s and the `JMP`s and `CALL`s that name them, and
//! `FOR … NEXT` nesting. Jumps and calls are resolved once the whole file is read.

use super::mnemonic::{Mnemonic, RungRole};
use super::{Checked, Checker, Link};
use crate::lang::ops::{Combine, Op};
use crate::lang::parse::Token;
use crate::lang::{LOOP_DEPTH, RUNG_STACK_DEPTH};

/// Which routine an instruction belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Region {
    Main,
    /// After `END`, outside any `SBRT … RET`.
    AfterEnd,
    /// Inside `SBRT n`, the routine's index.
    Sbrt(usize),
}

/// The current rung: none open, open (contacts so far), or acted on (outputs so far).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum RungState {
    Idle,
    Open,
    Acted,
}

/// A `FOR` waiting for its `NEXT`.
pub(super) struct OpenFor {
    index: usize,
    line: u32,
    col: u32,
    id: usize,
}

impl Checker<'_, '_> {
    /// Follows rungs, routines, labels and loops.
    pub(super) fn structure(
        &mut self,
        mnemonic: Mnemonic,
        op: Option<Op>,
        line: u32,
        col: u32,
        operands: &[Token<'_>],
    ) {
        use Mnemonic as M;
        let number = operands.first().and_then(|t| t.text.parse::<u32>().ok());
        // Routines first: what may stand where.
        match mnemonic {
            M::Sbrt => {
                self.close_rung(line);
                if let Some((n, l, _)) = self.sbrt_open {
                    self.error(
                        line,
                        col,
                        format!("`SBRT` inside `SBRT {n}` (line {l}): end it with `RET` first"),
                    );
                } else if self.region == Region::Main {
                    self.error(
                        line,
                        col,
                        "`SBRT` before `END`: subroutines follow the main program's `END`",
                    );
                }
                if let Some(n) = number {
                    if let Some(first) = self.sbrt_lines.get(&n) {
                        self.error(
                            line,
                            col,
                            format!("duplicate `SBRT {n}` (first at line {first})"),
                        );
                    } else {
                        self.sbrt_lines.insert(n, line);
                        self.subroutines.insert(n, self.out.len());
                    }
                    self.sbrt_open = Some((n, line, col));
                }
                self.region = Region::Sbrt(self.routines);
                self.routines += 1;
            }
            M::Ret => {
                self.close_rung(line);
                if self.sbrt_open.is_none() {
                    self.error(line, col, "`RET` outside a subroutine");
                }
                self.close_fors();
                self.sbrt_open = None;
                if self.seen_end {
                    self.region = Region::AfterEnd;
                }
            }
            M::End => {
                self.close_rung(line);
                if self.sbrt_open.is_some() || self.region != Region::Main {
                    self.error(
                        line,
                        col,
                        "`END` may appear only once, at the end of the main program",
                    );
                } else {
                    self.close_fors();
                }
                self.seen_end = true;
                if self.region == Region::Main {
                    self.region = Region::AfterEnd;
                }
            }
            _ if self.region == Region::AfterEnd => {
                self.error(line, col, "instruction after `END` outside a `SBRT … RET` block");
            }
            _ => {}
        }

        let routine = match self.region {
            Region::Main | Region::AfterEnd => 0,
            Region::Sbrt(r) => r,
        };
        let loop_id = self.fors.last().map_or(0, |f| f.id);

        // Rungs.
        let mut op = op;
        match mnemonic.rung_role() {
            RungRole::Start => {
                match self.rung {
                    RungState::Open => {
                        self.depth += 1;
                        if self.depth > RUNG_STACK_DEPTH {
                            self.error(
                                line,
                                col,
                                format!(
                                    "more than {RUNG_STACK_DEPTH} nested LOAD blocks in one rung"
                                ),
                            );
                        }
                        op = op.map(push_variant);
                    }
                    RungState::Idle | RungState::Acted => {
                        self.close_rung(line);
                    }
                }
                self.rung = RungState::Open;
            }
            RungRole::Combine => {
                if self.rung == RungState::Idle {
                    self.rung = RungState::Open;
                }
            }
            RungRole::Stack => match mnemonic {
                M::AndLoad | M::OrLoad => {
                    if self.depth == 0 {
                        self.error(line, col, "`AND LOAD`/`OR LOAD` without a LOAD block to merge");
                    } else {
                        self.depth -= 1;
                    }
                }
                M::MPush => {
                    self.mpush_lines.push(line);
                    if self.mpush_lines.len() > RUNG_STACK_DEPTH {
                        self.error(
                            line,
                            col,
                            format!("more than {RUNG_STACK_DEPTH} nested `MPUSH`"),
                        );
                    }
                }
                M::MLoad if self.mpush_lines.is_empty() => {
                    self.error(line, col, "`MLOAD` without a preceding `MPUSH`");
                }
                M::MPop if self.mpush_lines.is_empty() => {
                    self.error(line, col, "`MPOP` without a preceding `MPUSH`");
                }
                M::MPop => {
                    self.mpush_lines.pop();
                }
                _ => {}
            },
            RungRole::Act | RungRole::ActThenBoundary => {
                if self.depth > 0 {
                    self.error(line, col, format!(
                        "unbalanced block stack: {} LOAD block(s) not merged by `AND LOAD`/`OR LOAD` before this instruction",
                        self.depth
                    ));
                    self.depth = 0;
                }
                self.rung = RungState::Acted;
                if mnemonic.rung_role() == RungRole::ActThenBoundary {
                    self.close_rung(line);
                }
            }
            RungRole::Boundary => {
                if !matches!(mnemonic, M::Sbrt | M::Ret | M::End) {
                    self.close_rung(line);
                }
            }
            RungRole::Neutral => {}
        }

        // Labels, jumps, calls and loops.
        let index = self.out.len();
        let mut link = None;
        match mnemonic {
            M::Label => {
                if let Some(n) = number {
                    if let Some(first) = self.label_lines.get(&(routine, n)) {
                        self.error(
                            line,
                            col,
                            format!("duplicate `LABEL {n}` (first at line {first})"),
                        );
                    } else {
                        self.label_lines.insert((routine, n), line);
                        self.labels.insert((routine, n), (index, loop_id));
                    }
                }
            }
            M::Jmp => {
                if let Some(n) = number {
                    let at = operands[0].col;
                    self.jumps.push((n, line, at, routine, loop_id));
                    link = Some(Link::Jmp { routine, label: n });
                }
            }
            M::Call => {
                if let Some(n) = number {
                    self.calls.push((n, line, operands[0].col));
                    link = Some(Link::Call(n));
                }
            }
            M::For => {
                if self.fors.len() >= LOOP_DEPTH {
                    self.error(line, col, format!("`FOR` nested deeper than {LOOP_DEPTH}"));
                }
                self.fors.push(OpenFor { index, line, col, id: self.next_for_id });
                self.next_for_id += 1;
                link = Some(Link::For { next: usize::MAX });
            }
            M::Next => match self.fors.pop() {
                Some(open) => {
                    link = Some(Link::Next { for_: open.index });
                    if let Some(Checked { link: Some(Link::For { next }), .. }) =
                        self.out.get_mut(open.index)
                    {
                        *next = index;
                    }
                }
                None => self.error(line, col, "`NEXT` without `FOR`"),
            },
            M::Break if self.fors.is_empty() => {
                self.error(line, col, "`BREAK` outside a `FOR … NEXT` loop");
            }
            _ => {}
        }
        if let Some(op) = op {
            // A FOR whose op failed still occupies its index so NEXT can point at it.
            self.out.push(Checked { op, line, link });
        } else if matches!(mnemonic, M::For) {
            self.out.push(Checked { op: Op::Nop, line, link });
        }
    }

    /// Ends the current rung: every MPUSH must have been popped, every block merged.
    fn close_rung(&mut self, line: u32) {
        if let Some(&open) = self.mpush_lines.first() {
            self.error(open, 1, "`MPUSH` is never popped by `MPOP` before the rung ends");
        }
        if self.depth > 0 && self.rung == RungState::Open {
            let depth = self.depth;
            self.error(
                line,
                1,
                format!(
                    "unbalanced block stack: {depth} LOAD block(s) not merged before the rung ends"
                ),
            );
        }
        self.mpush_lines.clear();
        self.depth = 0;
        self.rung = RungState::Idle;
    }

    fn close_fors(&mut self) {
        for open in std::mem::take(&mut self.fors) {
            self.error(open.line, open.col, "`FOR` without `NEXT`");
        }
    }

    /// The end of the file: the last rung and the open blocks end, and every jump and call
    /// must have found its target.
    pub(super) fn finish_structure(&mut self, last_line: u32) {
        self.close_rung(last_line);
        self.close_fors();
        if let Some((n, line, col)) = self.sbrt_open {
            self.error(line, col, format!("`SBRT {n}` without `RET`"));
        }
        if !self.seen_end {
            self.error(last_line.max(1), 1, "the program has no `END`");
        }
        for (n, line, col, routine, loop_id) in std::mem::take(&mut self.jumps) {
            match self.labels.get(&(routine, n)) {
                Some(&(_, label_loop)) if label_loop != loop_id => {
                    self.error(
                        line,
                        col,
                        format!("`JMP {n}` jumps into or out of a `FOR … NEXT` loop"),
                    );
                }
                Some(_) => {}
                None if self.labels.keys().any(|(_, l)| *l == n) => {
                    self.error(line, col, format!("`JMP {n}`: `LABEL {n}` is in another routine"));
                }
                None => self.error(line, col, format!("`JMP {n}`: no `LABEL {n}` in this routine")),
            }
        }
        for (n, line, col) in std::mem::take(&mut self.calls) {
            if !self.subroutines.contains_key(&n) {
                self.error(line, col, format!("`CALL {n}`: no `SBRT {n}` in this file"));
            }
        }
    }
}

/// The form of a rung-opening instruction that opens a nested block instead.
fn push_variant(op: Op) -> Op {
    match op {
        Op::Load(b) => Op::LoadPush(b),
        Op::LoadNot(b) => Op::LoadNotPush(b),
        Op::EdgeContact { bit, rising, slot, .. } => {
            Op::EdgeContact { bit, rising, how: Combine::Load { push: true }, slot }
        }
        Op::Compare { op, a, b, .. } => Op::Compare { op, a, b, how: Combine::Load { push: true } },
        Op::DCompare { op, a, b, .. } => {
            Op::DCompare { op, a, b, how: Combine::Load { push: true } }
        }
        Op::RCompare { op, a, b, .. } => {
            Op::RCompare { op, a, b, how: Combine::Load { push: true } }
        }
        other => other,
    }
}
