//! Which values of fixed places a Structured Text body's blocks receive in registers from the
//! blocks before them: found before the body's code is generated, used by `codegen`.
//!
//! Native code writes every store through to memory, and remembers in a register the value of
//! each fixed place (a variable, a frame or FB-instance member: [`Place`]) it stored or fetched,
//! until a store may change it ([`may_change`]). Inside a block that spares the loads of
//! variables used again; across blocks it spares the loads of a loop's variables at each round,
//! and the wait of each load for the store just before it. A block receives the value of a
//! place when every block that jumps to it holds it at its end: an intersection over the
//! predecessors, iterated to a fixed point over the body's blocks (the loops' back edges), as
//! for available expressions. A block entered only from the dispatch (the body's start, the
//! return sites) receives nothing; the loader of a block that receives values loads them from
//! memory, so the dispatch may enter any block.
//!
//! The result is a hint: `codegen` loads from memory any value a jump must pass on that the
//! jumping block does not hold, so a block always receives what memory holds.

use plcd_core::lang::ops::{Op, Place};
use plcd_core::lang::Program;
use plcd_core::value::Elem;

use crate::analysis::{is_native, Analysis};

/// A fixed place fetched as `Elem`: the key of a value held in a register.
pub(crate) type Key = (Place, Elem);

/// True for the places whose values native code holds: those in variable memory, the frame
/// and the FB instance. Device memory is not held: a `Word` and a `Bit` overlap in ways their
/// places do not show.
pub(crate) fn in_bytes(place: Place) -> bool {
    matches!(place, Place::Var(_) | Place::Frame(_) | Place::This(_))
}

/// True if a store of `bytes` bytes at fixed place `at` may change the value of `held`. An FB
/// instance (`This`) may be in variable memory or in a frame, anywhere.
pub(crate) fn may_change(at: Place, bytes: u32, held: Key) -> bool {
    let range = |offset: u32, n: u32| u64::from(offset)..u64::from(offset) + u64::from(n);
    let overlaps = |a: u32, b: u32| {
        let (x, y) = (range(a, bytes), range(b, held.1.size()));
        x.start < y.end && y.start < x.end
    };
    match (at, held.0) {
        (Place::Var(a), Place::Var(b))
        | (Place::Frame(a), Place::Frame(b))
        | (Place::This(a), Place::This(b)) => overlaps(a, b),
        (Place::Word(_) | Place::Bit(_), _) => false,
        (Place::Var(_), Place::Frame(_)) | (Place::Frame(_), Place::Var(_)) => false,
        _ => true,
    }
}

/// What the values held at the end of a block of `code` are, given those held at its start
/// (`held`, changed in place). Conservative beside `codegen`, which may keep more: a store
/// through a pointer or a copy forgets every value here.
fn through(code: &[Op], held: &mut Vec<Key>) {
    for op in code {
        match *op {
            Op::Fetch { elem, at } if in_bytes(at) && !held.contains(&(at, elem)) => {
                held.push((at, elem));
            }
            Op::Store { elem, at } => {
                held.retain(|&key| !may_change(at, elem.size(), key));
                if in_bytes(at) {
                    held.push((at, elem));
                }
            }
            Op::StoreInd(_) | Op::Copy(_) | Op::CallFn { .. } | Op::CallFb { .. } => held.clear(),
            _ => {}
        }
    }
}

/// What a block of `code` wants of the values it receives: the keys it fetches before
/// anything in it may change them, and the stores after which a key is not wanted from its
/// start by the blocks after it (`None`: a store through a pointer, a copy or a call, after
/// which every value is fetched again).
struct Wants {
    fetched: Vec<Key>,
    stores: Option<Vec<(Place, u32)>>,
}

fn wants(code: &[Op]) -> Wants {
    let mut fetched = Vec::new();
    let mut stores = Vec::new();
    for op in code {
        match *op {
            Op::Fetch { elem, at } if in_bytes(at) => {
                let key = (at, elem);
                let unchanged = !stores.iter().any(|&(place, bytes)| may_change(place, bytes, key));
                if unchanged && !fetched.contains(&key) {
                    fetched.push(key);
                }
            }
            Op::Store { elem, at } => stores.push((at, elem.size())),
            Op::StoreInd(_) | Op::Copy(_) | Op::CallFn { .. } | Op::CallFb { .. } => {
                return Wants { fetched, stores: None };
            }
            _ => {}
        }
    }
    Wants { fetched, stores: Some(stores) }
}

/// An order of keys, so that two sets of them compare equal when they hold the same keys.
fn rank((place, elem): Key) -> (u8, u32, u8) {
    let (space, offset) = match place {
        Place::Var(offset) => (0, offset),
        Place::Frame(offset) => (1, offset),
        Place::This(offset) => (2, offset),
        Place::Word(word) => (3, u32::from(word.0)),
        Place::Bit(bit) => (4, u32::from(bit.word) << 16 | u32::from(bit.mask)),
    };
    (space, offset, elem as u8)
}

/// The values each of a body's blocks receives, by the block's index in `leaders` (the
/// body's leaders, as indices into [`Analysis::leaders`]).
pub(crate) fn carried(program: &Program, analysis: &Analysis, leaders: &[usize]) -> Vec<Vec<Key>> {
    let code = &program.code;
    let index_of =
        |pc: u32| leaders.binary_search_by_key(&pc, |&leader| analysis.leaders[leader]).ok();
    let blocks: Vec<_> = leaders.iter().map(|&leader| analysis.block(code, leader)).collect();
    // The jumps between the body's blocks; a block the interpreter runs ends native code.
    let mut predecessors = vec![Vec::new(); blocks.len()];
    let mut successors = vec![Vec::new(); blocks.len()];
    for (from, range) in blocks.iter().enumerate() {
        if !is_native(&code[range.start]) {
            continue;
        }
        let end = range.end as u32;
        let targets = match code[range.end - 1] {
            Op::Goto(target) => vec![target],
            Op::GotoIf { target, .. } => vec![target, end],
            Op::Return | Op::End => vec![],
            _ => vec![end],
        };
        for to in targets.into_iter().filter_map(index_of) {
            predecessors[to].push(from);
            successors[from].push(to);
        }
    }
    // Backwards, as liveness: the keys some path from each block's start fetches before they
    // may change. A value nobody wants is not passed on (it would only take a register).
    let wants: Vec<Wants> = blocks
        .iter()
        .map(|range| {
            if is_native(&code[range.start]) {
                wants(&code[range.clone()])
            } else {
                Wants { fetched: Vec::new(), stores: None }
            }
        })
        .collect();
    let mut wanted: Vec<Vec<Key>> = wants.iter().map(|w| w.fetched.clone()).collect();
    let mut changed = true;
    while changed {
        changed = false;
        for index in (0..blocks.len()).rev() {
            let Some(stores) = &wants[index].stores else { continue };
            for &to in &successors[index] {
                for k in 0..wanted[to].len() {
                    let key = wanted[to][k];
                    let kept = !stores.iter().any(|&(place, bytes)| may_change(place, bytes, key));
                    if kept && !wanted[index].contains(&key) {
                        wanted[index].push(key);
                        changed = true;
                    }
                }
            }
        }
    }
    // Every place the body fetches or stores: what a block with predecessors may receive before
    // the iteration narrows it.
    let mut all: Vec<Key> = Vec::new();
    for op in blocks.iter().flat_map(|range| &code[range.clone()]) {
        if let Op::Fetch { elem, at } | Op::Store { elem, at } = *op {
            if in_bytes(at) && !all.contains(&(at, elem)) {
                all.push((at, elem));
            }
        }
    }
    all.sort_by_key(|&key| rank(key));
    let mut into: Vec<Vec<Key>> = predecessors
        .iter()
        .map(|from| if from.is_empty() { Vec::new() } else { all.clone() })
        .collect();
    let mut out: Vec<Vec<Key>> = vec![all; blocks.len()];
    let mut changed = true;
    while changed {
        changed = false;
        for index in 0..blocks.len() {
            if let Some((&first, rest)) = predecessors[index].split_first() {
                let mut held = out[first].clone();
                for &other in rest {
                    held.retain(|key| out[other].contains(key));
                }
                into[index] = held;
            }
            let mut held = into[index].clone();
            let range = &blocks[index];
            if is_native(&code[range.start]) {
                through(&code[range.clone()], &mut held);
            } else {
                held.clear();
            }
            held.sort_by_key(|&key| rank(key));
            if held != out[index] {
                out[index] = held;
                changed = true;
            }
        }
    }
    for (held, wanted) in into.iter_mut().zip(&wanted) {
        held.retain(|key| wanted.contains(key));
    }
    into
}
