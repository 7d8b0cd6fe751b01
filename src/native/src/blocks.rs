//! Blocks and the interpreter's share, from a program's leaders: the same rules for both
//! languages' analyses (`analysis` for Structured Text, `il` for the instruction list), which
//! differ only in which instructions end a block.

use std::ops::Range;

use plcd_core::lang::ops::Op;

/// The instructions of the block at `leaders[index]`: to the next leader (or to `end` after
/// the last), or through the first instruction for which `ends` holds.
pub(crate) fn block(
    leaders: &[u32],
    end: usize,
    code: &[Op],
    index: usize,
    ends: impl Fn(&Op) -> bool,
) -> Range<usize> {
    let start = leaders[index] as usize;
    let limit = leaders.get(index + 1).map_or(end, |&pc| pc as usize);
    let mut at = start;
    while at < limit {
        let op = &code[at];
        at += 1;
        if ends(op) {
            break;
        }
    }
    start..at
}

/// Instructions from `pc` to the next leader after it (the interpreter's share); in the last
/// block, to `end` (an instruction there may jump or return into code before it); past `end`,
/// all of them.
pub(crate) fn span(leaders: &[u32], end: usize, pc: u32) -> u32 {
    let next = leaders.partition_point(|&leader| leader <= pc);
    match leaders.get(next) {
        Some(&leader) => leader - pc,
        None if (pc as usize) < end => end as u32 - pc,
        None => u32::MAX,
    }
}
