//! Op building: a line whose mnemonic and operand count are right becomes its [`Op`], every
//! operand resolved ([`super::operand`]), the checks that need the project around it made
//! (timer time bases, `DI n`/`EI n` task numbers, `INIT_DONE` only in the init task), and an
//! edge-memory slot given to each edge-sensitive instruction.

use super::mnemonic::Mnemonic;
use super::operand::{self, bit, counter, dest, number, wide_dest, word, Kind, Operand};
use super::{Checker, DutySite, MAX_EDGE_SLOTS};
use crate::lang::ops::{Combine, EdgeSlot, Op, Src, SystemRequest, Wide, WideConv};
use crate::lang::parse::Token;

impl Checker<'_, '_> {
    /// The next edge-memory slot, for an edge-sensitive instruction.
    fn slot(&mut self) -> EdgeSlot {
        let slot = self.next_slot;
        self.next_slot += 1;
        // Out-of-range slots are reported once at the end; keep going with a wrapped value.
        (slot % MAX_EDGE_SLOTS) as EdgeSlot
    }

    /// A double-word operand, its constant kept among the program's constants; `None` when the
    /// operand was wrong (reported), or when there are more constants than a `Wide` can index
    /// (reported here).
    fn wide(&mut self, operand: Option<Operand>, line: u32, col: u32) -> Option<Wide> {
        match operand? {
            Operand::WideWord(w) | Operand::WideDest(w) => Some(Wide::Word(w)),
            Operand::Word(Src::Word(w)) => Some(Wide::Word(w)),
            Operand::Word(Src::Const(c)) => self.constant(u64::from(c), line, col),
            Operand::WideConst(slot) => self.constant(slot, line, col),
            _ => None,
        }
    }

    fn constant(&mut self, slot: u64, line: u32, col: u32) -> Option<Wide> {
        if let Some(&index) = self.const_index.get(&slot) {
            return Some(Wide::Const(index));
        }
        let Ok(index) = u16::try_from(self.consts.len()) else {
            self.error(line, col, "more than 65536 different double-word and real constants");
            return None;
        };
        self.consts.push(slot);
        self.const_index.insert(slot, index);
        Some(Wide::Const(index))
    }

    /// Resolves operands and builds the op; `None` when an operand was wrong (reported).
    pub(super) fn build(
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
            match operand::resolve(token, kind, name) {
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
            M::DMov { pulse, real } => {
                let value = if real { Kind::RWord } else { Kind::DWord };
                let s = get(self, 0, value);
                let d = wide_dest(get(self, 1, Kind::DWordOut));
                let s = self.wide(s, line, operands[0].col);
                let pulse = pulse.then(|| self.slot());
                Some(Op::DMov { s: s?, d: d?, pulse })
            }
            M::DArith { op, pulse, real } => {
                let value = if real { Kind::RWord } else { Kind::DWord };
                let a = get(self, 0, value);
                let b = get(self, 1, value);
                let d = wide_dest(get(self, 2, Kind::DWordOut));
                let a = self.wide(a, line, operands[0].col);
                let b = self.wide(b, line, operands[1].col);
                let pulse = pulse.then(|| self.slot());
                let (a, b, d) = (a?, b?, d?);
                Some(if real {
                    Op::RArith { op, a, b, d, pulse }
                } else {
                    Op::DArith { op, a, b, d, pulse }
                })
            }
            M::DStep { up, pulse } => {
                let d = wide_dest(get(self, 0, Kind::DWordOut));
                let pulse = pulse.then(|| self.slot());
                Some(Op::DStep { d: d?, up, pulse })
            }
            M::DCompare { how, op, real } => {
                let value = if real { Kind::RWord } else { Kind::DWord };
                let a = get(self, 0, value);
                let b = get(self, 1, value);
                let a = self.wide(a, line, operands[0].col);
                let b = self.wide(b, line, operands[1].col);
                let (a, b) = (a?, b?);
                Some(if real {
                    Op::RCompare { op, a, b, how }
                } else {
                    Op::DCompare { op, a, b, how }
                })
            }
            M::Convert { conv, pulse } => {
                let source = match conv {
                    WideConv::IntToDint | WideConv::IntToReal => Kind::Word,
                    WideConv::RealToInt | WideConv::RealToDint => Kind::RWord,
                    WideConv::DintToInt | WideConv::DintToReal => Kind::DWord,
                };
                let s = get(self, 0, source);
                let out = if conv.to_one_word() { Kind::WordOut } else { Kind::DWordOut };
                let d = match get(self, 1, out) {
                    Some(Operand::Dest(d) | Operand::WideDest(d)) => Some(d),
                    _ => None,
                };
                let s = self.wide(s, line, operands[0].col);
                let pulse = pulse.then(|| self.slot());
                Some(Op::Convert { conv, s: s?, d: d?, pulse })
            }
        };
        if ok {
            op
        } else {
            None
        }
    }

    /// Reports a project that uses more edge memory than there is, once every line is built.
    pub(super) fn check_edge_slots(&mut self, last_line: u32) {
        if self.next_slot > MAX_EDGE_SLOTS {
            self.error(
                last_line,
                1,
                format!("the project uses more than {MAX_EDGE_SLOTS} edge-sensitive instructions"),
            );
        }
    }
}
