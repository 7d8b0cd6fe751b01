//! The instruction list as native code: which instructions are compiled, where native code can
//! be entered and how far the budget is checked ([`Analysis`]); the code itself is
//! [`codegen`]'s.
//!
//! What is compiled: contacts on bits, edge contacts and compare contacts (`LOAD`, `AND NOT`,
//! `LOADP`, `LOAD>=`, …), the block and `MPUSH` stacks, `NOT`, the coils (`OUT`, `OUT NOT`,
//! `OUTP`, `SET`, `RST`, `FF`), `MOV`, `ADD`/`SUB`/`MUL`/`DIV` (a division by zero is the
//! interpreter's), `INC`/`DEC` and their `P` forms, `CALL`/`RET`, `LABEL`, `JMP`, `NOP` and
//! `END`, the timers, the counters and their `RST` (on the VM's own states, the time computed
//! from the step count for `plcd sim`'s clock and asked of the clock for the others).
//! Everything else — the double-word and real instructions, `FOR`/`NEXT`/`BREAK`, `DUTY` and
//! the system requests — the interpreter executes, one instruction at a time, and native code
//! goes on after it.
//!
//! A block runs from one leader to the next: at most [`MAX_BLOCK`] instructions, so that a
//! budget smaller than the whole program still leaves most of it to native code. A block
//! checks once that the budget covers it, and hands itself whole to the interpreter if not.

pub(crate) mod codegen;

use plcd_core::device::{counter_done, counter_value, timer_done, timer_value, BitRef, WordRef};
use plcd_core::lang::ops::{Op, Src};

/// The longest block: a budget check every this many instructions at most.
pub(crate) const MAX_BLOCK: usize = 256;

/// Instructions of one compiled function, at most: a program is compiled in pieces of this
/// size, each its own function. Cranelift's time and memory grow faster than the function
/// (10^5 instructions in one function: 1.5 s and 300 MB), and a piece's are freed before the
/// next is compiled; a jump between pieces goes through [`Code::run`](crate::code::Code).
pub(crate) const PIECE: usize = 4096;

/// Instructions compiled, at most: a longer program's rest is left to the interpreter, so
/// that a load takes bounded time whatever the program's size (BENCHMARKS.md has the
/// figures).
pub(crate) const MAX_COMPILED: usize = 65_536;

/// Native code for a program in which more than one instruction in this many is the
/// interpreter's would be slower than the interpreter alone: each hand-over costs about 200
/// machine instructions (leaving the native function, entering the interpreter's loop and back),
/// a compiled instruction saves 15 to 35 (`benches/counts`: `timers_counters`, a third of its
/// instructions timers and counters, ran 4× the instructions with native code when those were
/// handed over).
pub(crate) const HANDOVER_EVERY: usize = 16;

/// Native code for a program whose compiled part is less than one instruction in this many
/// of the whole (a program longer than [`MAX_COMPILED`] times this) would not be faster than
/// the interpreter alone: the rest is interpreted whatever happens, and the compiled part,
/// streamed out of the caches by the interpreted rest every scan, runs from cold code at
/// about the interpreter's speed (BENCHMARKS.md, the scaling section: 10^6 steps of bit logic
/// 1.08 ns a step with native code attached against 0.94 on the interpreter alone; from 5·10^5
/// steps on, even either way; 3·10^5 steps, where the compiled part is more than a fifth,
/// 2-15 % faster).
pub(crate) const COMPILED_SHARE_MIN: usize = 8;

/// The analysis of one instruction-list program.
pub(crate) struct Analysis {
    /// The instructions native code can be entered at, sorted: the start, every jump target
    /// of any instruction, the instruction after a jump or an `END`, every instruction the
    /// interpreter executes and the one after it, and one every [`MAX_BLOCK`] instructions.
    pub leaders: Vec<u32>,
    /// Words of device memory the compiled instructions reach: native code runs only when
    /// device memory has at least that many.
    pub words_end: u64,
    /// Instructions compiled: those from here on are the interpreter's.
    pub compiled: usize,
    /// Instructions of the program, compiled or not.
    pub instructions: usize,
    /// The pieces, each compiled as a function of its own: ranges of `leaders`, in order.
    pub pieces: Vec<std::ops::Range<usize>>,
    /// Instructions of the compiled part that the interpreter executes.
    pub handed_over: usize,
    /// Slots of edge memory, timer numbers and counter numbers the compiled instructions
    /// reach, as the ends of their ranges: native code runs only when the VM has that many.
    pub edges_end: u64,
    pub timers_end: u64,
    pub counters_end: u64,
    /// Each piece's dispatch table: for each instruction of the piece's range (from its first
    /// leader to the next piece's), the index of its block in the piece, or the piece's
    /// number of blocks if it is no leader. The code reads it where it lives, so that entering
    /// at a program counter, and `RET`, are one load and one indirect jump.
    pub dispatch: Vec<Box<[u16]>>,
    /// The subroutines compiled as functions of their own, after the pieces: a `CALL` of one
    /// is a machine call, and its `RET` a machine return, which the processor predicts (a
    /// return through the dispatch is an indirect jump to one of every caller's return
    /// addresses). Sorted by `CALL` target.
    pub subroutines: Vec<Subroutine>,
    /// The main routine's end, its `END`: the instructions before it run at call depth 0
    /// always (a `CALL` targets a `SBRT` after `END`, a `RET` returns to its caller's routine,
    /// a `JMP` stays in its own: docs/LANGUAGE.md, "Flow"), so a `CALL` among them needs no
    /// check of the depth and pushes the first frame.
    pub main_end: u32,
}

/// A subroutine's own function: the blocks reachable from its first instruction without
/// passing a `RET` (a `CALL` in it goes on after the call). Control that leaves them (into code
/// past the compiled part, or a jump out of the subroutine) leaves the function for the VM,
/// which goes on in the piece that holds the place, as it does after any stop inside one.
pub(crate) struct Subroutine {
    /// The `CALL` target: the instruction after `SBRT n`.
    pub target: u32,
    /// The blocks, as indices into [`Analysis::leaders`], sorted.
    pub blocks: Vec<usize>,
    /// Its instructions, if a `CALL` of it is compiled inline: at most [`INLINE_MAX`] and no
    /// `CALL` among them.
    pub inline: Option<usize>,
}

/// Instructions of a subroutine compiled inline at its calls, at most: a call costs about 40
/// machine instructions more than the subroutine's own work (the machine call, its function's
/// entry and exit, the registers spilled around it), inline a few (the call depth's check: the
/// frame is pushed only on the paths that leave native code from inside the subroutine).
const INLINE_MAX: usize = 32;

/// Instructions of one subroutine's function, at most (as a piece's, for the same reason): a
/// longer subroutine is called through the dispatch.
const SUBROUTINE_MAX: usize = PIECE;

/// True if native code executes `op` itself.
pub(crate) fn is_native(op: &Op) -> bool {
    matches!(
        op,
        Op::Load(_)
            | Op::LoadNot(_)
            | Op::LoadPush(_)
            | Op::LoadNotPush(_)
            | Op::And(_)
            | Op::AndNot(_)
            | Op::Or(_)
            | Op::OrNot(_)
            | Op::Compare { .. }
            | Op::AndLoad
            | Op::OrLoad
            | Op::MPush
            | Op::MLoad
            | Op::MPop
            | Op::Not
            | Op::Out(_)
            | Op::OutNot(_)
            | Op::Set(_)
            | Op::Rst(_)
            | Op::EdgeContact { .. }
            | Op::OutPulse { .. }
            | Op::FlipFlop { .. }
            | Op::Mov { .. }
            | Op::Arith { .. }
            | Op::Step { .. }
            | Op::Timer { .. }
            | Op::RstTimer(_)
            | Op::Counter { .. }
            | Op::CounterUpDown { .. }
            | Op::RstCounter(_)
            | Op::Call { .. }
            | Op::Ret
            | Op::Jmp { .. }
            | Op::Label
            | Op::Nop
            | Op::End
    )
}

/// True if control may not go on to the next instruction after `op`.
fn ends_block(op: &Op) -> bool {
    matches!(op, Op::Jmp { .. } | Op::End | Op::Call { .. } | Op::Ret)
}

/// The words of device memory `op` reads or writes, as the end of their range.
fn reach(op: &Op) -> u64 {
    let src = |s: &Src| match s {
        Src::Word(w) => u64::from(w.0) + 1,
        Src::Const(_) => 0,
    };
    let bit = |b: &BitRef| u64::from(b.word) + 1;
    let word = |w: WordRef| u64::from(w.0) + 1;
    let timer = |n: u16| word(timer_value(n)).max(bit(&timer_done(n)));
    let counter = |n: u16| word(counter_value(n)).max(bit(&counter_done(n)));
    match op {
        Op::Load(b)
        | Op::LoadNot(b)
        | Op::LoadPush(b)
        | Op::LoadNotPush(b)
        | Op::And(b)
        | Op::AndNot(b)
        | Op::Or(b)
        | Op::OrNot(b)
        | Op::Out(b)
        | Op::OutNot(b)
        | Op::Set(b)
        | Op::Rst(b)
        | Op::EdgeContact { bit: b, .. }
        | Op::OutPulse { bit: b, .. }
        | Op::FlipFlop { bit: b, .. } => bit(b),
        Op::Compare { a, b, .. } => src(a).max(src(b)),
        Op::Mov { s, d, .. } => src(s).max(word(*d)),
        Op::Arith { a, b, d, .. } => src(a).max(src(b)).max(word(*d)),
        Op::Step { d, .. } => word(*d),
        Op::Timer { timer: n, preset, .. } => timer(*n).max(src(preset)),
        Op::RstTimer(n) => timer(*n),
        Op::Counter { counter: n, preset, .. } => counter(*n).max(src(preset)),
        Op::CounterUpDown { counter: n, up, down, preset } => {
            counter(*n).max(src(preset)).max(bit(up)).max(bit(down))
        }
        Op::RstCounter(n) => counter(*n),
        _ => 0,
    }
}

/// The edge slot `op` uses, if any.
fn edge_slot(op: &Op) -> Option<u16> {
    match *op {
        Op::EdgeContact { slot, .. } | Op::OutPulse { slot, .. } | Op::FlipFlop { slot, .. } => {
            Some(slot)
        }
        Op::Mov { pulse, .. } | Op::Arith { pulse, .. } | Op::Step { pulse, .. } => pulse,
        _ => None,
    }
}

/// Where control may go from `op` besides the next instruction.
fn targets(op: &Op) -> Option<u32> {
    match *op {
        Op::Jmp { target } | Op::Call { target } => Some(target),
        Op::For { end, .. } => Some(end),
        Op::Next { body } => Some(body),
        _ => None,
    }
}

pub(crate) fn analyse(code: &[Op]) -> Analysis {
    let compiled = code.len().min(MAX_COMPILED);
    let mut leaders = vec![0u32];
    let mut words_end = 0;
    let mut handed_over = 0;
    let (mut edges_end, mut timers_end, mut counters_end) = (0u64, 0u64, 0u64);
    for (pc, op) in code.iter().enumerate() {
        if let Some(target) = targets(op) {
            leaders.push(target);
        }
        if pc >= compiled {
            continue;
        }
        if !is_native(op) {
            leaders.extend([pc as u32, pc as u32 + 1]);
            handed_over += 1;
        } else {
            words_end = words_end.max(reach(op));
            if let Some(slot) = edge_slot(op) {
                edges_end = edges_end.max(u64::from(slot) + 1);
            }
            match *op {
                Op::Timer { timer: n, .. } | Op::RstTimer(n) => {
                    timers_end = timers_end.max(u64::from(n) + 1);
                }
                Op::Counter { counter: n, .. }
                | Op::CounterUpDown { counter: n, .. }
                | Op::RstCounter(n) => counters_end = counters_end.max(u64::from(n) + 1),
                _ => {}
            }
        }
        if ends_block(op) {
            leaders.push(pc as u32 + 1);
        }
    }
    leaders.retain(|&pc| (pc as usize) < compiled);
    leaders.sort_unstable();
    leaders.dedup();
    // No block longer than MAX_BLOCK.
    let mut all = Vec::with_capacity(leaders.len() + compiled / MAX_BLOCK);
    for (i, &leader) in leaders.iter().enumerate() {
        let next = leaders.get(i + 1).map_or(compiled as u32, |&n| n);
        let mut at = leader;
        while at < next {
            all.push(at);
            at = at.saturating_add(MAX_BLOCK as u32);
        }
    }
    // Pieces of whole blocks, each at most PIECE instructions from its first leader.
    let mut pieces = Vec::new();
    let mut first = 0;
    for index in 1..=all.len() {
        let at = all.get(index).map_or(u32::MAX, |&pc| pc);
        if index == all.len() || (at - all[first]) as usize > PIECE - MAX_BLOCK {
            pieces.push(first..index);
            first = index;
        }
    }
    let dispatch = pieces
        .iter()
        .enumerate()
        .map(|(index, piece)| {
            let low = all[piece.start] as usize;
            let high = pieces.get(index + 1).map_or(compiled, |next| all[next.start] as usize);
            let mut table = vec![piece.len() as u16; high - low];
            for (block, &leader) in all[piece.clone()].iter().enumerate() {
                table[leader as usize - low] = block as u16;
            }
            table.into_boxed_slice()
        })
        .collect();
    let mut analysis = Analysis {
        subroutines: Vec::new(),
        dispatch,
        leaders: all,
        words_end,
        compiled,
        instructions: code.len(),
        pieces,
        handed_over,
        edges_end,
        timers_end,
        counters_end,
        main_end: code.iter().position(|op| matches!(op, Op::End)).unwrap_or(0) as u32,
    };
    analysis.subroutines = subroutines(code, &analysis);
    analysis
}

/// The subroutines that get functions of their own: every compiled `CALL` target whose blocks
/// (see [`Subroutine`]) are at most [`SUBROUTINE_MAX`] instructions.
fn subroutines(code: &[Op], analysis: &Analysis) -> Vec<Subroutine> {
    let compiled = analysis.compiled;
    let mut targets: Vec<u32> = code[..compiled]
        .iter()
        .filter_map(|op| match *op {
            Op::Call { target } if (target as usize) < compiled => Some(target),
            _ => None,
        })
        .collect();
    targets.sort_unstable();
    targets.dedup();
    let index_of = |pc: usize| analysis.leaders.binary_search(&(pc as u32)).ok();
    targets
        .into_iter()
        .filter_map(|target| {
            let first = index_of(target as usize)?;
            let mut blocks = vec![first];
            let mut seen = std::collections::HashSet::from([first]);
            let (mut size, mut calls) = (0, false);
            let mut next = 0;
            while let Some(&index) = blocks.get(next) {
                next += 1;
                let range = analysis.block(code, index);
                size += range.len();
                calls |= code[range.clone()].iter().any(|op| matches!(op, Op::Call { .. }));
                if size > SUBROUTINE_MAX {
                    return None;
                }
                let last = &code[range.end - 1];
                let successors: &[usize] = match *last {
                    // The interpreter's instruction: the VM goes on after it.
                    _ if !is_native(&code[range.start]) => &[],
                    Op::Ret | Op::End => &[],
                    Op::Jmp { target } => &[target as usize, range.end],
                    _ => &[range.end],
                };
                for &pc in successors {
                    if let Some(successor) = index_of(pc).filter(|_| pc < compiled) {
                        if seen.insert(successor) {
                            blocks.push(successor);
                        }
                    }
                }
            }
            blocks.sort_unstable();
            let inline = (size <= INLINE_MAX && !calls).then_some(size);
            Some(Subroutine { target, blocks, inline })
        })
        .collect()
}

impl Analysis {
    /// The subroutine function of the `CALL` target `target`, as its index in
    /// [`Analysis::subroutines`].
    pub fn subroutine_at(&self, target: u32) -> Option<usize> {
        self.subroutines.binary_search_by_key(&target, |s| s.target).ok()
    }

    /// The instructions of the block at `leaders[index]`: to the next leader, or to the first
    /// that ends a block; an instruction the interpreter executes is a block of its own.
    pub fn block(&self, code: &[Op], index: usize) -> std::ops::Range<usize> {
        crate::blocks::block(&self.leaders, self.compiled, code, index, |op| {
            ends_block(op) || !is_native(op)
        })
    }

    /// Whether native code would be faster than the interpreter: few enough hand-overs in
    /// the compiled part ([`HANDOVER_EVERY`]), and a compiled part large enough a share of
    /// the program ([`COMPILED_SHARE_MIN`]).
    pub fn worth_compiling(&self) -> bool {
        self.handed_over * HANDOVER_EVERY <= self.compiled
            && self.compiled * COMPILED_SHARE_MIN >= self.instructions
    }

    /// Instructions the interpreter executes: those of the compiled part it is handed, and
    /// every one past it.
    pub fn interpreted(&self) -> usize {
        self.handed_over + (self.instructions - self.compiled)
    }

    /// The piece whose range of instructions holds `pc` (the last for any pc past them): its
    /// dispatch runs `pc` if it is a leader, and hands it to the interpreter if not.
    pub fn piece_holding(&self, pc: u32) -> usize {
        if self.pieces.len() <= 1 {
            return 0;
        }
        let after = self.pieces.partition_point(|piece| self.leaders[piece.start] <= pc);
        after.saturating_sub(1)
    }

    /// Instructions from `pc` to the next leader after it (the interpreter's share); in the
    /// last block, to the end of the compiled code (a subroutine's `RET` there returns into
    /// compiled code); past it, all of them.
    pub fn span(&self, pc: u32) -> u32 {
        crate::blocks::span(&self.leaders, self.compiled, pc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plcd_core::device::BitRef;

    fn bit(word: u16) -> BitRef {
        BitRef { word, mask: 1 }
    }

    #[test]
    fn leaders_cut_long_runs_and_surround_what_the_interpreter_runs() {
        let mut code = vec![Op::Load(bit(1)); 600];
        code[300] = Op::For { count: Src::Const(2), end: 301 };
        code.push(Op::End);
        let a = analyse(&code);
        assert_eq!(a.leaders, vec![0, 256, 300, 301, 557]);
        assert_eq!(a.words_end, 2);
        assert_eq!(a.block(&code, 0), 0..256);
        assert_eq!(a.block(&code, 2), 300..301);
        assert_eq!(a.block(&code, 4), 557..601);
        assert_eq!(a.span(5), 251);
        assert_eq!(a.span(600), 1);
        assert_eq!(a.span(601), u32::MAX);
        assert_eq!(a.pieces, vec![0..5]);
        let table = &a.dispatch[0];
        assert_eq!(table.len(), 601);
        assert_eq!((table[0], table[256], table[300], table[301], table[557]), (0, 1, 2, 3, 4));
        assert_eq!((table[1], table[299], table[600]), (5, 5, 5), "no leader: the block count");
        assert_eq!(a.piece_holding(557), 0);
        assert_eq!(a.piece_holding(601), 0);
    }

    #[test]
    fn a_subroutine_function_has_the_blocks_reachable_before_its_ret() {
        let code = vec![
            Op::Load(bit(1)),
            Op::Call { target: 4 },
            Op::Out(bit(2)),
            Op::End,
            // subroutine 1: a jump over one instruction, a call of subroutine 2
            Op::Load(bit(1)),
            Op::Jmp { target: 7 },
            Op::Out(bit(3)),
            Op::Call { target: 10 },
            Op::Ret,
            Op::Nop,
            // subroutine 2: one block
            Op::Out(bit(4)),
            Op::Ret,
        ];
        let a = analyse(&code);
        assert_eq!(a.leaders, vec![0, 2, 4, 6, 7, 8, 9, 10]);
        let subs: Vec<_> =
            a.subroutines.iter().map(|s| (s.target, s.blocks.clone(), s.inline)).collect();
        // 9, after the RET, is not reached; the CALL at 7 goes on at 8. Subroutine 1 calls,
        // so it is not inlined.
        assert_eq!(subs, vec![(4, vec![2, 3, 4, 5], None), (10, vec![7], Some(2))]);
        assert_eq!(a.subroutine_at(10), Some(1));
        assert_eq!(a.subroutine_at(2), None);
    }

    #[test]
    fn a_subroutine_longer_than_a_piece_is_called_through_the_dispatch() {
        let mut code = vec![Op::Load(bit(1)), Op::Call { target: 3 }, Op::End];
        code.extend(std::iter::repeat_n(Op::Out(bit(3)), SUBROUTINE_MAX));
        code.push(Op::Ret);
        assert!(analyse(&code).subroutines.is_empty());
        code.remove(3);
        assert_eq!(analyse(&code).subroutines.len(), 1, "exactly SUBROUTINE_MAX instructions");
    }

    #[test]
    fn a_long_program_is_compiled_in_pieces_and_up_to_a_limit() {
        let mut code = vec![Op::Out(bit(3)); 100_000];
        code.push(Op::End);
        let a = analyse(&code);
        assert_eq!(a.compiled, MAX_COMPILED);
        assert_eq!(a.leaders.len(), MAX_COMPILED / MAX_BLOCK);
        assert_eq!(a.pieces.len(), MAX_COMPILED / PIECE);
        for piece in &a.pieces {
            let (start, last) = (a.leaders[piece.start], a.leaders[piece.end - 1]);
            assert!((last - start) as usize + MAX_BLOCK <= PIECE, "{piece:?}");
        }
        let covered: usize = a.dispatch.iter().map(|table| table.len()).sum();
        assert_eq!(covered, MAX_COMPILED, "the tables cover the compiled instructions once");
        assert_eq!(a.piece_holding(4095), 0);
        assert_eq!(a.piece_holding(4096), 1);
        assert_eq!(a.piece_holding(u32::MAX), 15);
        assert_eq!(a.span(MAX_COMPILED as u32), u32::MAX);
        assert!(a.worth_compiling());
        assert_eq!(a.interpreted(), 100_001 - MAX_COMPILED);
    }

    #[test]
    fn a_program_mostly_past_the_compiled_part_is_left_to_the_interpreter() {
        let mut code = vec![Op::Out(bit(3)); MAX_COMPILED * COMPILED_SHARE_MIN - 1];
        code.push(Op::End);
        assert!(analyse(&code).worth_compiling(), "exactly one instruction in 8 compiled");
        code.insert(0, Op::Out(bit(3)));
        let a = analyse(&code);
        assert!(!a.worth_compiling(), "less than one instruction in 8 compiled");
        assert_eq!(a.interpreted(), MAX_COMPILED * (COMPILED_SHARE_MIN - 1) + 1);
    }
}
