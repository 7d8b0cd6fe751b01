//! Check: tokens into typed instructions, and every rule a program must follow.
//!
//! Each line is resolved on its own (mnemonic, operand count, operand kinds, ranges, write
//! protection); then the program's structure is followed line by line: rungs and their block and
//! MPUSH stacks, the main routine up to `END` and the `SBRT … RET` blocks after it, labels and
//! jumps, `FOR … NEXT` nesting. Errors are collected, never returned early, so a user sees every
//! mistake of a file in one run.

use std::collections::HashMap;
use std::path::Path;

use super::ops::{
    ArithOp, CmpOp, Combine, CounterKind, EdgeSlot, Op, Src, SystemRequest, TimerKind,
};
use super::parse::{SourceLine, Token};
use super::{LOOP_DEPTH, RUNG_STACK_DEPTH};
use crate::device::{Address, Area, BitRef, WordRef, Writer, WORD_VALUES};
use crate::diag::{Diagnostic, Diagnostics};

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
}

/// Hardest limit of edge memory: slots are 16-bit.
const MAX_EDGE_SLOTS: u32 = u16::MAX as u32 + 1;

/// The mnemonics, after joining two-word forms (`LOAD NOT`, `AND LOAD` …).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mnemonic {
    Contact { how: Combine, negate: bool },
    Edge { how: Combine, rising: bool },
    Compare { how: Combine, op: CmpOp },
    AndLoad,
    OrLoad,
    MPush,
    MLoad,
    MPop,
    Not,
    Out,
    OutNot,
    OutPulse { rising: bool },
    Set,
    Rst,
    FlipFlop,
    Timer(TimerKind),
    Counter(CounterKind),
    CounterUpDown,
    Mov { pulse: bool },
    Arith { op: ArithOp, pulse: bool },
    Step { up: bool, pulse: bool },
    Call,
    Sbrt,
    Ret,
    Jmp,
    Label,
    For,
    Next,
    Break,
    Di,
    Ei,
    Wdt,
    InitDone,
    Stop,
    Iorf,
    End,
    Nop,
    Duty,
}

/// How an instruction relates to the rung it stands in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RungRole {
    /// `LOAD …`: opens a rung, or a nested block inside an open one.
    Start,
    /// `AND`, `OR`, `NOT`, compare and edge contacts that combine with the rung result.
    Combine,
    /// Acts on the rung result (outputs, timers, data, jumps …).
    Act,
    /// Ends the rung before and after it (`LABEL`, `NEXT`, `END`, `SBRT`, `RET`).
    Boundary,
    /// Acts on the rung result, then ends the rung (`FOR`).
    ActThenBoundary,
    /// Stack instructions, checked separately.
    Stack,
    /// `NOP`: no effect on the rung.
    Neutral,
}

fn mnemonic_of(tokens: &[Token<'_>]) -> Option<(Mnemonic, usize)> {
    use Mnemonic as M;
    let first = tokens[0].text.to_ascii_uppercase();
    let second = tokens.get(1).map(|t| t.text.to_ascii_uppercase());
    let load = Combine::Load { push: false };
    let two = |m| Some((m, 2));
    match (first.as_str(), second.as_deref()) {
        ("LOAD", Some("NOT")) => return two(M::Contact { how: load, negate: true }),
        ("AND", Some("NOT")) => return two(M::Contact { how: Combine::And, negate: true }),
        ("OR", Some("NOT")) => return two(M::Contact { how: Combine::Or, negate: true }),
        ("OUT", Some("NOT")) => return two(M::OutNot),
        ("AND", Some("LOAD")) => return two(M::AndLoad),
        ("OR", Some("LOAD")) => return two(M::OrLoad),
        _ => {}
    }
    for (prefix, how) in [("LOAD", load), ("AND", Combine::And), ("OR", Combine::Or)] {
        if let Some(op) = first.strip_prefix(prefix).and_then(compare_op) {
            return Some((M::Compare { how, op }, 1));
        }
    }
    let m = match first.as_str() {
        "LOAD" => M::Contact { how: load, negate: false },
        "AND" => M::Contact { how: Combine::And, negate: false },
        "OR" => M::Contact { how: Combine::Or, negate: false },
        "LOADP" => M::Edge { how: load, rising: true },
        "LOADN" => M::Edge { how: load, rising: false },
        "ANDP" => M::Edge { how: Combine::And, rising: true },
        "ANDN" => M::Edge { how: Combine::And, rising: false },
        "ORP" => M::Edge { how: Combine::Or, rising: true },
        "ORN" => M::Edge { how: Combine::Or, rising: false },
        "MPUSH" => M::MPush,
        "MLOAD" => M::MLoad,
        "MPOP" => M::MPop,
        "NOT" => M::Not,
        "OUT" => M::Out,
        "OUTP" => M::OutPulse { rising: true },
        "OUTN" => M::OutPulse { rising: false },
        "SET" => M::Set,
        "RST" => M::Rst,
        "FF" => M::FlipFlop,
        "TON" => M::Timer(TimerKind::Ton),
        "TOFF" => M::Timer(TimerKind::Toff),
        "TMR" => M::Timer(TimerKind::Tmr),
        "TMON" => M::Timer(TimerKind::Tmon),
        "TRTG" => M::Timer(TimerKind::Trtg),
        "CTU" => M::Counter(CounterKind::Ctu),
        "CTD" => M::Counter(CounterKind::Ctd),
        "CTR" => M::Counter(CounterKind::Ctr),
        "CTUD" => M::CounterUpDown,
        "MOV" => M::Mov { pulse: false },
        "MOVP" => M::Mov { pulse: true },
        "ADD" => M::Arith { op: ArithOp::Add, pulse: false },
        "ADDP" => M::Arith { op: ArithOp::Add, pulse: true },
        "SUB" => M::Arith { op: ArithOp::Sub, pulse: false },
        "SUBP" => M::Arith { op: ArithOp::Sub, pulse: true },
        "MUL" => M::Arith { op: ArithOp::Mul, pulse: false },
        "MULP" => M::Arith { op: ArithOp::Mul, pulse: true },
        "DIV" => M::Arith { op: ArithOp::Div, pulse: false },
        "DIVP" => M::Arith { op: ArithOp::Div, pulse: true },
        "INC" => M::Step { up: true, pulse: false },
        "INCP" => M::Step { up: true, pulse: true },
        "DEC" => M::Step { up: false, pulse: false },
        "DECP" => M::Step { up: false, pulse: true },
        "CALL" => M::Call,
        "SBRT" => M::Sbrt,
        "RET" => M::Ret,
        "JMP" => M::Jmp,
        "LABEL" => M::Label,
        "FOR" => M::For,
        "NEXT" => M::Next,
        "BREAK" => M::Break,
        "DI" => M::Di,
        "EI" => M::Ei,
        "WDT" => M::Wdt,
        "INIT_DONE" => M::InitDone,
        "STOP" => M::Stop,
        "IORF" => M::Iorf,
        "END" => M::End,
        "NOP" => M::Nop,
        "DUTY" => M::Duty,
        _ => return None,
    };
    Some((m, 1))
}

fn compare_op(s: &str) -> Option<CmpOp> {
    Some(match s {
        "=" => CmpOp::Eq,
        "<>" => CmpOp::Ne,
        ">" => CmpOp::Gt,
        ">=" => CmpOp::Ge,
        "<" => CmpOp::Lt,
        "<=" => CmpOp::Le,
        _ => return None,
    })
}

impl Mnemonic {
    fn rung_role(self) -> RungRole {
        use Mnemonic as M;
        match self {
            M::Contact { how: Combine::Load { .. }, .. }
            | M::Edge { how: Combine::Load { .. }, .. }
            | M::Compare { how: Combine::Load { .. }, .. } => RungRole::Start,
            M::Contact { .. } | M::Edge { .. } | M::Compare { .. } | M::Not => RungRole::Combine,
            M::AndLoad | M::OrLoad | M::MPush | M::MLoad | M::MPop => RungRole::Stack,
            M::Label | M::Next | M::End | M::Sbrt | M::Ret => RungRole::Boundary,
            M::Nop => RungRole::Neutral,
            M::For => RungRole::ActThenBoundary,
            _ => RungRole::Act,
        }
    }

    /// The operand names, for messages and counts.
    fn operands(self) -> &'static [&'static str] {
        use Mnemonic as M;
        match self {
            M::Contact { .. } | M::Edge { .. } => &["bit device"],
            M::Compare { .. } => &["first value", "second value"],
            M::Out | M::OutNot | M::OutPulse { .. } | M::Set | M::FlipFlop => &["bit device"],
            M::Rst => &["bit device, timer or counter"],
            M::Timer(_) => &["timer", "preset"],
            M::Counter(_) => &["counter", "preset"],
            M::CounterUpDown => &["counter", "up input", "down input", "preset"],
            M::Mov { .. } => &["source", "destination"],
            M::Arith { .. } => &["first value", "second value", "destination"],
            M::Step { .. } => &["destination"],
            M::Call | M::Sbrt => &["subroutine number"],
            M::Jmp | M::Label => &["label number"],
            M::For => &["repeat count"],
            M::Duty => &["ON scans n1", "OFF scans n2", "clock relay"],
            _ => &[],
        }
    }
}

/// Which routine an instruction belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Region {
    Main,
    /// After `END`, outside any `SBRT … RET`.
    AfterEnd,
    /// Inside `SBRT n`, the routine's index.
    Sbrt(usize),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RungState {
    Idle,
    Open,
    Acted,
}

struct OpenFor {
    index: usize,
    line: u32,
    col: u32,
    id: usize,
}

struct Checker<'a, 'c> {
    path: &'a Path,
    ctx: &'a Context<'c>,
    diags: Diagnostics,
    out: Vec<Checked>,
    next_slot: u32,
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
    duty_sites: Vec<DutySite>,
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
        duty_sites: Vec::new(),
    };
    for line in lines {
        c.line(line);
    }
    c.finish(last_line);
    let duty_sites = std::mem::take(&mut c.duty_sites);
    if c.diags.is_empty() {
        let labels = c.labels.iter().map(|(k, (index, _))| (*k, *index)).collect();
        let checked = CheckedProgram {
            instructions: c.out,
            labels,
            subroutines: c.subroutines,
            edge_slots: c.next_slot - ctx.edge_base,
        };
        (Ok(checked), duty_sites)
    } else {
        c.diags.0.sort_by_key(|d| (d.line, d.col));
        (Err(c.diags), duty_sites)
    }
}

/// A resolved operand.
enum Operand {
    Bit(BitRef),
    Word(Src),
    Dest(WordRef),
    Timer(u16),
    Counter(u16),
    Number(u32),
    /// `RST` on a timer or counter.
    ResetTarget(Op),
}

impl<'a, 'c> Checker<'a, 'c> {
    fn error(&mut self, line: u32, col: u32, message: impl Into<String>) {
        self.diags.push(Diagnostic::new(self.path, line, col, message));
    }

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

    fn operand_count_ok(
        &mut self,
        mnemonic: Mnemonic,
        name: &str,
        operands: &[Token<'_>],
        line: u32,
        col: u32,
    ) -> bool {
        let expected = mnemonic.operands();
        let (min, max) = match mnemonic {
            Mnemonic::Di | Mnemonic::Ei => (0, 1),
            _ => (expected.len(), expected.len()),
        };
        if (min..=max).contains(&operands.len()) {
            return true;
        }
        let wanted = match (min, max) {
            (0, 0) => "no operands".to_string(),
            (0, 1) => "no operand or a task number".to_string(),
            (n, _) => {
                format!("{n} operand{} ({})", if n == 1 { "" } else { "s" }, expected.join(", "))
            }
        };
        let at = operands.get(max).map_or(col, |t| t.col);
        self.error(line, at, format!("`{name}` takes {wanted}, found {}", operands.len()));
        false
    }

    fn slot(&mut self) -> EdgeSlot {
        let slot = self.next_slot;
        self.next_slot += 1;
        // Out-of-range slots are reported once at the end; keep going with a wrapped value.
        (slot % MAX_EDGE_SLOTS) as EdgeSlot
    }

    /// Resolves operands and builds the op; `None` when an operand was wrong (reported).
    fn build(
        &mut self,
        mnemonic: Mnemonic,
        name: &str,
        operands: &[Token<'_>],
        line: u32,
        col: u32,
    ) -> Option<Op> {
        use Mnemonic as M;
        let mut ok = true;
        let mut get = |this: &mut Self, index: usize, kind: Kind| -> Option<Operand> {
            let token = &operands[index];
            match this.operand(token, kind, name) {
                Ok(operand) => Some(operand),
                Err(message) => {
                    this.error(line, token.col, message);
                    ok = false;
                    None
                }
            }
        };
        let op = match mnemonic {
            M::Contact { how, negate } => {
                let bit = bit(get(self, 0, Kind::Bit));
                match (how, negate) {
                    (Combine::Load { .. }, false) => bit.map(Op::Load),
                    (Combine::Load { .. }, true) => bit.map(Op::LoadNot),
                    (Combine::And, false) => bit.map(Op::And),
                    (Combine::And, true) => bit.map(Op::AndNot),
                    (Combine::Or, false) => bit.map(Op::Or),
                    (Combine::Or, true) => bit.map(Op::OrNot),
                }
            }
            M::Edge { how, rising } => bit(get(self, 0, Kind::Bit)).map(|bit| Op::EdgeContact {
                bit,
                rising,
                how,
                slot: self.slot(),
            }),
            M::Compare { how, op } => {
                let a = word(get(self, 0, Kind::Word));
                let b = word(get(self, 1, Kind::Word));
                Some(Op::Compare { op, a: a?, b: b?, how })
            }
            M::AndLoad => Some(Op::AndLoad),
            M::OrLoad => Some(Op::OrLoad),
            M::MPush => Some(Op::MPush),
            M::MLoad => Some(Op::MLoad),
            M::MPop => Some(Op::MPop),
            M::Not => Some(Op::Not),
            M::Out => bit(get(self, 0, Kind::BitOut)).map(Op::Out),
            M::OutNot => bit(get(self, 0, Kind::BitOut)).map(Op::OutNot),
            M::OutPulse { rising } => bit(get(self, 0, Kind::BitOut)).map(|bit| Op::OutPulse {
                bit,
                rising,
                slot: self.slot(),
            }),
            M::Set => bit(get(self, 0, Kind::BitOut)).map(Op::Set),
            M::Rst => match get(self, 0, Kind::ResetTarget) {
                Some(Operand::Bit(b)) => Some(Op::Rst(b)),
                Some(Operand::ResetTarget(op)) => Some(op),
                _ => None,
            },
            M::FlipFlop => {
                bit(get(self, 0, Kind::BitOut)).map(|bit| Op::FlipFlop { bit, slot: self.slot() })
            }
            M::Timer(kind) => {
                let timer = match get(self, 0, Kind::Timer) {
                    Some(Operand::Timer(t)) => Some(t),
                    _ => None,
                };
                let preset = word(get(self, 1, Kind::Word));
                let timer = timer?;
                let Some(base) = (self.ctx.timer_base_ms)(u32::from(timer)) else {
                    self.error(
                        line,
                        operands[0].col,
                        format!("T{timer:04} has no time base: no range of [timers] covers it"),
                    );
                    return None;
                };
                Some(Op::Timer { kind, timer, preset: preset?, base_ms: base as u16 })
            }
            M::Counter(kind) => {
                let counter = counter(get(self, 0, Kind::Counter));
                let preset = word(get(self, 1, Kind::Word));
                Some(Op::Counter { kind, counter: counter?, preset: preset? })
            }
            M::CounterUpDown => {
                let counter = counter(get(self, 0, Kind::Counter));
                let up = bit(get(self, 1, Kind::Bit));
                let down = bit(get(self, 2, Kind::Bit));
                let preset = word(get(self, 3, Kind::Word));
                Some(Op::CounterUpDown { counter: counter?, up: up?, down: down?, preset: preset? })
            }
            M::Mov { pulse } => {
                let s = word(get(self, 0, Kind::Word));
                let d = dest(get(self, 1, Kind::WordOut));
                let pulse = pulse.then(|| self.slot());
                Some(Op::Mov { s: s?, d: d?, pulse })
            }
            M::Arith { op, pulse } => {
                let a = word(get(self, 0, Kind::Word));
                let b = word(get(self, 1, Kind::Word));
                let d = dest(get(self, 2, Kind::WordOut));
                let pulse = pulse.then(|| self.slot());
                Some(Op::Arith { op, a: a?, b: b?, d: d?, pulse })
            }
            M::Step { up, pulse } => {
                let d = dest(get(self, 0, Kind::WordOut));
                let pulse = pulse.then(|| self.slot());
                Some(Op::Step { d: d?, up, pulse })
            }
            // Targets are resolved by `compile`; the number is kept in the link.
            M::Call | M::Sbrt | M::Jmp | M::Label => {
                number(get(self, 0, Kind::Number(9999)))?;
                Some(match mnemonic {
                    M::Call => Op::Call { target: 0 },
                    M::Jmp => Op::Jmp { target: 0 },
                    M::Label => Op::Label,
                    _ => Op::Nop,
                })
            }
            M::Ret => Some(Op::Ret),
            M::For => word(get(self, 0, Kind::Word)).map(|count| Op::For { count, end: 0 }),
            M::Next => Some(Op::Next { body: 0 }),
            M::Break => Some(Op::Break),
            M::Di | M::Ei => {
                let task = match operands.first() {
                    Some(_) => Some(number(get(self, 0, Kind::Number(23)))? as u8),
                    None => None,
                };
                if let Some(n) = task {
                    if !self.ctx.task_numbers.contains(&n) {
                        self.error(
                            line,
                            operands[0].col,
                            format!("`{name} {n}`: no task has number {n} in the configuration"),
                        );
                        return None;
                    }
                }
                Some(Op::System(if mnemonic == M::Di {
                    SystemRequest::DisableTasks(task)
                } else {
                    SystemRequest::EnableTasks(task)
                }))
            }
            M::Wdt => Some(Op::System(SystemRequest::ResetWatchdog)),
            M::InitDone => {
                if !self.ctx.is_init {
                    self.error(
                        line,
                        col,
                        "`INIT_DONE` is allowed only in a program of the init task",
                    );
                    return None;
                }
                Some(Op::System(SystemRequest::InitDone))
            }
            M::Stop => Some(Op::System(SystemRequest::Stop)),
            M::Iorf => Some(Op::System(SystemRequest::RefreshIo)),
            M::End => Some(Op::End),
            M::Nop => Some(Op::Nop),
            M::Duty => {
                let n1 = word(get(self, 0, Kind::DutyScans));
                let n2 = word(get(self, 1, Kind::DutyScans));
                let relay = get(self, 2, Kind::DutyRelay);
                let channel = match relay {
                    Some(Operand::Number(channel)) => channel as u8,
                    _ => return None,
                };
                self.duty_sites.push(DutySite { channel, line, col: operands[2].col });
                Some(Op::Duty { channel, n1: n1?, n2: n2?, slot: self.slot() })
            }
        };
        if ok {
            op
        } else {
            None
        }
    }

    fn operand(&self, token: &Token<'_>, kind: Kind, name: &str) -> Result<Operand, String> {
        let text = token.text;
        if let Kind::Number(max) = kind {
            return match text.parse::<u32>() {
                Ok(n) if n <= max => Ok(Operand::Number(n)),
                _ => Err(format!("`{name}` needs a number 0..={max}, found `{text}`")),
            };
        }
        if let Some(value) = parse_constant(text)? {
            return match kind {
                Kind::Word => Ok(Operand::Word(Src::Const(value as u16))),
                Kind::DutyScans if (0..=32767).contains(&value) => {
                    Ok(Operand::Word(Src::Const(value as u16)))
                }
                Kind::DutyScans => {
                    Err(format!("DUTY scan count {value} is outside 0..=32767 (3405H)"))
                }
                _ => Err(format!("`{name}` needs a device here, found constant `{text}`")),
            };
        }
        let address = Address::parse(text).map_err(|e| e.to_string())?;
        match kind {
            Kind::Bit => address.as_bit().map(Operand::Bit).map_err(|e| e.to_string()),
            Kind::BitOut => {
                let bit = address.as_bit().map_err(|e| e.to_string())?;
                if !address.writable_by(Writer::ProgramBit) {
                    return Err(read_only(&address));
                }
                Ok(Operand::Bit(bit))
            }
            Kind::ResetTarget => match address.area {
                Area::T => Ok(Operand::ResetTarget(Op::RstTimer(address.number as u16))),
                Area::C => Ok(Operand::ResetTarget(Op::RstCounter(address.number as u16))),
                _ => self.operand(token, Kind::BitOut, name),
            },
            Kind::Word | Kind::DutyScans => {
                address.as_word().map(|w| Operand::Word(Src::Word(w))).map_err(|e| e.to_string())
            }
            Kind::WordOut => {
                let w = address.as_word().map_err(|e| e.to_string())?;
                if !address.writable_by(Writer::ProgramWord) {
                    return Err(read_only(&address));
                }
                Ok(Operand::Dest(w))
            }
            Kind::Timer if address.area == Area::T => Ok(Operand::Timer(address.number as u16)),
            Kind::Timer => Err(format!("`{name}` needs a timer T0000-T2047, found `{text}`")),
            Kind::Counter if address.area == Area::C => Ok(Operand::Counter(address.number as u16)),
            Kind::Counter => Err(format!("`{name}` needs a counter C0000-C2047, found `{text}`")),
            Kind::DutyRelay => match address.duty_channel() {
                Some(channel) => Ok(Operand::Number(channel as u32)),
                None => Err(format!(
                    "DUTY clock relay `{text}` is not one of SM420-SM424, SM8330-SM8334 (2820H)"
                )),
            },
            Kind::Number(_) => unreachable!("handled above"),
        }
    }

    /// Follows rungs, routines, labels and loops.
    fn structure(
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

    fn finish(&mut self, last_line: u32) {
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
        if self.next_slot > MAX_EDGE_SLOTS {
            self.error(
                last_line,
                1,
                format!("the project uses more than {MAX_EDGE_SLOTS} edge-sensitive instructions"),
            );
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Bit,
    BitOut,
    ResetTarget,
    Word,
    WordOut,
    Timer,
    Counter,
    Number(u32),
    DutyScans,
    DutyRelay,
}

fn read_only(address: &Address) -> String {
    let owner = match address.area {
        Area::T => "timer contacts belong to their timer instruction",
        Area::C => "counter contacts belong to their counter instruction",
        Area::SM if address.is_duty_relay() => "DUTY clock relays are switched by DUTY",
        Area::SM | Area::SD | Area::F => "system devices are maintained by the PLC",
        _ => "read-only",
    };
    format!("`{address}` is read-only: {owner}")
}

fn bit(o: Option<Operand>) -> Option<BitRef> {
    match o {
        Some(Operand::Bit(b)) => Some(b),
        _ => None,
    }
}

fn word(o: Option<Operand>) -> Option<Src> {
    match o {
        Some(Operand::Word(s)) => Some(s),
        _ => None,
    }
}

fn dest(o: Option<Operand>) -> Option<WordRef> {
    match o {
        Some(Operand::Dest(d)) => Some(d),
        _ => None,
    }
}

fn counter(o: Option<Operand>) -> Option<u16> {
    match o {
        Some(Operand::Counter(c)) => Some(c),
        _ => None,
    }
}

fn number(o: Option<Operand>) -> Option<u32> {
    match o {
        Some(Operand::Number(n)) => Some(n),
        _ => None,
    }
}

fn push_variant(op: Op) -> Op {
    match op {
        Op::Load(b) => Op::LoadPush(b),
        Op::LoadNot(b) => Op::LoadNotPush(b),
        Op::EdgeContact { bit, rising, slot, .. } => {
            Op::EdgeContact { bit, rising, how: Combine::Load { push: true }, slot }
        }
        Op::Compare { op, a, b, .. } => Op::Compare { op, a, b, how: Combine::Load { push: true } },
        other => other,
    }
}

/// Parses a constant: decimal `-32768..=65535` or hex `h0`..=`hFFFF`. `Ok(None)` when the text
/// is not a constant at all (a device, then).
pub fn parse_constant(text: &str) -> Result<Option<i32>, String> {
    let bytes = text.as_bytes();
    let is_decimal = bytes.first().is_some_and(|b| b.is_ascii_digit() || *b == b'-' || *b == b'+');
    if is_decimal {
        return match text.parse::<i32>() {
            Ok(v) if WORD_VALUES.contains(&v) => Ok(Some(v)),
            _ => Err(format!("constant `{text}` is not a 16-bit value ({WORD_VALUES:?})")),
        };
    }
    if let Some(hex) = text.strip_prefix(['h', 'H']) {
        if !hex.is_empty() && hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return match u32::from_str_radix(hex, 16) {
                Ok(v) if v <= 0xFFFF => Ok(Some(v as i32)),
                _ => Err(format!("constant `{text}` is not a 16-bit value (h0000..=hFFFF)")),
            };
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constants() {
        assert_eq!(parse_constant("100"), Ok(Some(100)));
        assert_eq!(parse_constant("-5"), Ok(Some(-5)));
        assert_eq!(parse_constant("h00FF"), Ok(Some(255)));
        assert_eq!(parse_constant("HFFFF"), Ok(Some(65535)));
        assert_eq!(parse_constant("M0000"), Ok(None));
        assert!(parse_constant("70000").is_err());
        assert!(parse_constant("h10000").is_err());
        assert!(parse_constant("12ab").is_err());
    }
}
