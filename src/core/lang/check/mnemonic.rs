//! The mnemonics table: a line's first one or two words (`LOAD NOT`, `AND LOAD`, `LOAD>=` …)
//! resolved into a [`Mnemonic`], with what each one means for its rung ([`RungRole`]) and the
//! names of the operands it takes, for the messages that count or name them.

use crate::lang::ops::{ArithOp, CmpOp, Combine, CounterKind, TimerKind, WideConv};
use crate::lang::parse::Token;

/// The mnemonics, after joining two-word forms (`LOAD NOT`, `AND LOAD` …).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Mnemonic {
    Contact {
        how: Combine,
        negate: bool,
    },
    Edge {
        how: Combine,
        rising: bool,
    },
    Compare {
        how: Combine,
        op: CmpOp,
    },
    AndLoad,
    OrLoad,
    MPush,
    MLoad,
    MPop,
    Not,
    Out,
    OutNot,
    OutPulse {
        rising: bool,
    },
    Set,
    Rst,
    FlipFlop,
    Timer(TimerKind),
    Counter(CounterKind),
    CounterUpDown,
    Mov {
        pulse: bool,
    },
    Arith {
        op: ArithOp,
        pulse: bool,
    },
    Step {
        up: bool,
        pulse: bool,
    },
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
    /// `DMOV` (`real`: `RMOV`, which takes a real constant).
    DMov {
        pulse: bool,
        real: bool,
    },
    /// `DADD` … (`real`: `RADD` …).
    DArith {
        op: ArithOp,
        pulse: bool,
        real: bool,
    },
    /// `DINC` (`up`), `DDEC`.
    DStep {
        up: bool,
        pulse: bool,
    },
    /// `LOADD= a b` … (`real`: `LOADR=` …).
    DCompare {
        how: Combine,
        op: CmpOp,
        real: bool,
    },
    /// `I2D`, `D2I`, `I2R`, `R2I`, `D2R`, `R2D`.
    Convert {
        conv: WideConv,
        pulse: bool,
    },
}

/// How an instruction relates to the rung it stands in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum RungRole {
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

pub(super) fn mnemonic_of(tokens: &[Token<'_>]) -> Option<(Mnemonic, usize)> {
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
        if let Some(rest) = first.strip_prefix(prefix) {
            if let Some(op) = compare_op(rest) {
                return Some((M::Compare { how, op }, 1));
            }
            for (kind, real) in [('D', false), ('R', true)] {
                if let Some(op) = rest.strip_prefix(kind).and_then(compare_op) {
                    return Some((M::DCompare { how, op, real }, 1));
                }
            }
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
        _ => return wide_mnemonic(&first).map(|m| (m, 1)),
    };
    Some((m, 1))
}

/// The double-word, real and conversion instructions, each with its `P` form.
fn wide_mnemonic(upper: &str) -> Option<Mnemonic> {
    use Mnemonic as M;
    let (base, pulse) = match upper.strip_suffix('P') {
        Some(base) => (base, true),
        None => (upper, false),
    };
    let arith = |name: &str| match name {
        "ADD" => Some(ArithOp::Add),
        "SUB" => Some(ArithOp::Sub),
        "MUL" => Some(ArithOp::Mul),
        "DIV" => Some(ArithOp::Div),
        _ => None,
    };
    Some(match base {
        "DMOV" => M::DMov { pulse, real: false },
        "RMOV" => M::DMov { pulse, real: true },
        "DINC" => M::DStep { up: true, pulse },
        "DDEC" => M::DStep { up: false, pulse },
        "I2D" => M::Convert { conv: WideConv::IntToDint, pulse },
        "D2I" => M::Convert { conv: WideConv::DintToInt, pulse },
        "I2R" => M::Convert { conv: WideConv::IntToReal, pulse },
        "R2I" => M::Convert { conv: WideConv::RealToInt, pulse },
        "D2R" => M::Convert { conv: WideConv::DintToReal, pulse },
        "R2D" => M::Convert { conv: WideConv::RealToDint, pulse },
        _ => {
            let (kind, name) = base.split_at_checked(1)?;
            let op = arith(name)?;
            match kind {
                "D" => M::DArith { op, pulse, real: false },
                "R" => M::DArith { op, pulse, real: true },
                _ => return None,
            }
        }
    })
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
    pub(super) fn rung_role(self) -> RungRole {
        use Mnemonic as M;
        match self {
            M::Contact { how: Combine::Load { .. }, .. }
            | M::Edge { how: Combine::Load { .. }, .. }
            | M::Compare { how: Combine::Load { .. }, .. }
            | M::DCompare { how: Combine::Load { .. }, .. } => RungRole::Start,
            M::Contact { .. }
            | M::Edge { .. }
            | M::Compare { .. }
            | M::DCompare { .. }
            | M::Not => RungRole::Combine,
            M::AndLoad | M::OrLoad | M::MPush | M::MLoad | M::MPop => RungRole::Stack,
            M::Label | M::Next | M::End | M::Sbrt | M::Ret => RungRole::Boundary,
            M::Nop => RungRole::Neutral,
            M::For => RungRole::ActThenBoundary,
            _ => RungRole::Act,
        }
    }

    /// The operand names, for messages and counts.
    pub(super) fn operands(self) -> &'static [&'static str] {
        use Mnemonic as M;
        match self {
            M::Contact { .. } | M::Edge { .. } => &["bit device"],
            M::Compare { .. } | M::DCompare { .. } => &["first value", "second value"],
            M::Out | M::OutNot | M::OutPulse { .. } | M::Set | M::FlipFlop => &["bit device"],
            M::Rst => &["bit device, timer or counter"],
            M::Timer(_) => &["timer", "preset"],
            M::Counter(_) => &["counter", "preset"],
            M::CounterUpDown => &["counter", "up input", "down input", "preset"],
            M::Mov { .. } | M::DMov { .. } | M::Convert { .. } => &["source", "destination"],
            M::Arith { .. } | M::DArith { .. } => &["first value", "second value", "destination"],
            M::Step { .. } | M::DStep { .. } => &["destination"],
            M::Call | M::Sbrt => &["subroutine number"],
            M::Jmp | M::Label => &["label number"],
            M::For => &["repeat count"],
            M::Duty => &["ON scans n1", "OFF scans n2", "clock relay"],
            _ => &[],
        }
    }
}
