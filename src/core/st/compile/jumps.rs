//! CODESYS's jumps in Structured Text (docs/ST.md, "Jumps and labels"): `label:` before a
//! statement and `JMP label;`, which IEC 61131-3 has in IL only.
//!
//! Before a body is checked, [`Ctx::resolve_jumps`] walks its statements once and binds each
//! `JMP` to its label, reporting an unknown label, a label declared twice, and a jump into a
//! statement list the jump is not in (into the body of an IF, CASE, FOR, WHILE or REPEAT from
//! outside it, which would skip the FOR's start or enter a loop nothing entered). A jump to a
//! label of its own statement list or of one around it — forward, backward, out of loops and
//! IFs — is accepted. The code generator compiles a label to nothing and a jump to a `Goto`
//! ([`Labels`]): a backward jump is a loop like WHILE's, charged to the step budget in the
//! interpreter and in native code alike, so an endless one ends the scan at the watchdog.

use std::collections::HashMap;

use crate::st::ast::{Ident, Span, Stmt, StmtKind};

use super::ctx::{suggest, Ctx};

/// The labels and jumps of the bodies checked so far, by the file and place they are written
/// at.
#[derive(Debug, Default)]
pub struct JumpTable {
    /// Each label's number (unique in the compilation).
    labels: HashMap<(usize, Span), u32>,
    /// Each jump's label number, and whether the label is before the jump (a loop).
    jumps: HashMap<(usize, Span), (u32, bool)>,
    next: u32,
}

impl JumpTable {
    /// The number of the label written at `span` of `file`.
    pub fn label(&self, file: usize, span: Span) -> Option<u32> {
        self.labels.get(&(file, span)).copied()
    }

    /// The label number of the `JMP` written at `span` of `file` and whether it jumps
    /// backward; `None` for one whose error was reported.
    pub fn jump(&self, file: usize, span: Span) -> Option<(u32, bool)> {
        self.jumps.get(&(file, span)).copied()
    }
}

/// A statement list of the body: what holds it, for messages (`None`: the body itself).
struct Block {
    holder: Option<(&'static str, u32)>,
}

struct LabelSite<'b> {
    name: &'b Ident,
    /// The statement lists it is in, outermost first.
    chain: Vec<usize>,
    order: usize,
}

struct JumpSite<'b> {
    label: &'b Ident,
    span: Span,
    chain: Vec<usize>,
    order: usize,
}

#[derive(Default)]
struct Walk<'b> {
    blocks: Vec<Block>,
    chain: Vec<usize>,
    order: usize,
    labels: Vec<LabelSite<'b>>,
    jumps: Vec<JumpSite<'b>>,
}

impl<'b> Walk<'b> {
    fn list(&mut self, stmts: &'b [Stmt], holder: Option<(&'static str, u32)>) {
        self.blocks.push(Block { holder });
        self.chain.push(self.blocks.len() - 1);
        for s in stmts {
            self.order += 1;
            let line = s.span.line;
            match &s.kind {
                StmtKind::Label(name) => self.labels.push(LabelSite {
                    name,
                    chain: self.chain.clone(),
                    order: self.order,
                }),
                StmtKind::Jump(label) => self.jumps.push(JumpSite {
                    label,
                    span: s.span,
                    chain: self.chain.clone(),
                    order: self.order,
                }),
                StmtKind::If { branches, otherwise } => {
                    for (_, body) in branches {
                        self.list(body, Some(("IF", line)));
                    }
                    if let Some((_, body)) = otherwise {
                        self.list(body, Some(("IF", line)));
                    }
                }
                StmtKind::Case { arms, otherwise, .. } => {
                    for arm in arms {
                        self.list(&arm.body, Some(("CASE", line)));
                    }
                    if let Some((_, body)) = otherwise {
                        self.list(body, Some(("CASE", line)));
                    }
                }
                StmtKind::For { body, .. } => self.list(body, Some(("FOR", line))),
                StmtKind::While { body, .. } => self.list(body, Some(("WHILE", line))),
                StmtKind::Repeat { body, .. } => self.list(body, Some(("REPEAT", line))),
                _ => {}
            }
        }
        self.chain.pop();
    }
}

impl<'a> Ctx<'a> {
    /// Binds every `JMP` of the body `stmts` (of `file`) to its label, in [`Ctx::jumps`], and
    /// reports each label declared twice, each unknown label and each jump into a statement
    /// list it is not in.
    pub(super) fn resolve_jumps(&mut self, stmts: &[Stmt], file: usize) {
        let mut walk = Walk::default();
        walk.list(stmts, None);
        if walk.labels.is_empty() && walk.jumps.is_empty() {
            return;
        }
        let mut by_name: HashMap<String, usize> = HashMap::new();
        for (i, site) in walk.labels.iter().enumerate() {
            let key = site.name.name.to_ascii_lowercase();
            if let Some(&first) = by_name.get(&key) {
                let line = walk.labels[first].name.span.line;
                let msg = format!("label `{}` is already declared at line {line}", site.name.name);
                self.error(file, site.name.span, msg);
                continue;
            }
            by_name.insert(key, i);
            self.jumps.labels.insert((file, site.name.span), self.jumps.next + i as u32);
        }
        for jump in &walk.jumps {
            let Some(&i) = by_name.get(&jump.label.name.to_ascii_lowercase()) else {
                let names = walk.labels.iter().map(|l| l.name.name.as_str());
                let hint = suggest(&jump.label.name, names);
                let msg = format!("no label `{}` in this body{hint}", jump.label.name);
                self.error(file, jump.label.span, msg);
                continue;
            };
            let label = &walk.labels[i];
            // the outermost statement list around the label that the jump is not in
            let entered = label.chain.iter().find(|b| !jump.chain.contains(b));
            if let Some(holder) = entered.and_then(|&b| walk.blocks[b].holder) {
                let (what, line) = holder;
                let msg = format!(
                    "`JMP {}` goes into the {what} at line {line}: a jump goes to a label of its own statement list or of one around it",
                    jump.label.name
                );
                self.error(file, jump.label.span, msg);
                continue;
            }
            let backward = label.order < jump.order;
            self.jumps.jumps.insert((file, jump.span), (self.jumps.next + i as u32, backward));
        }
        self.jumps.next += walk.labels.len() as u32;
    }
}

/// The code generator's side: where each label of the body being compiled is, and the
/// forward jumps waiting for theirs.
#[derive(Debug, Default)]
pub struct Labels {
    at: HashMap<u32, u32>,
    waiting: Vec<(usize, u32)>,
}

impl Labels {
    /// Label `label` is at `pc`: the jumps to patch with it, the forward jumps emitted so far.
    pub fn place(&mut self, label: u32, pc: u32) -> Vec<usize> {
        self.at.insert(label, pc);
        let (ready, waiting) = self.waiting.drain(..).partition(|(_, l)| *l == label);
        self.waiting = waiting;
        ready.into_iter().map(|(op, _)| op).collect()
    }

    /// Where a backward jump to `label` goes (placed before it in this body).
    pub fn before(&self, label: u32) -> Option<u32> {
        self.at.get(&label).copied()
    }

    /// A forward jump, the op at `op`, waiting for `label`.
    pub fn wait(&mut self, op: usize, label: u32) {
        self.waiting.push((op, label));
    }
}
