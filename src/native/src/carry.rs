//! Which values of fixed places a Structured Text body's blocks receive in registers from the
//! blocks before them: found before the body's code is generated, used by `codegen`; and
//! where a pointer into variable memory may point ([`Reach`]), which both follow to know what
//! a store through it may change.
//!
//! Native code remembers in a register the value of each fixed place (a variable, a frame or
//! FB-instance member: [`Place`]) it stored or fetched, until a store may change it
//! ([`may_change`]). It writes a store through to memory at once, except in a loop
//! ([`in_loops`]) for a value that goes on in a register to the next blocks: that one is
//! written back where something else may read the place or the code leaves ([`unwritten`]). Inside a block that spares the loads of
//! variables used again; across blocks it spares the loads of a loop's variables at each round,
//! and the wait of each load for the store just before it. A block receives the value of a
//! place when every block that jumps to it holds it at its end: an intersection over the
//! predecessors, iterated to a fixed point over the body's blocks (the loops' back edges), as
//! for available expressions. A block outside any loop receives its integer values only
//! when they are few ([`JOIN_INTEGERS`]; floats always): there each is equal to memory, and
//! reloading it where used costs no more than the spill of one value too many held in
//! registers across the join. A block entered only from the dispatch (the body's start, the
//! return sites of machine calls) receives nothing; after a call compiled inline (`inline`),
//! the return site receives what the caller held but the callee may have changed
//! ([`callee_writes`]). The loader of a block that receives values loads them from memory, so
//! the dispatch may enter any block.
//!
//! The result is a hint: `codegen` loads from memory any value a jump must pass on that the
//! jumping block does not hold, so a block always receives what memory holds.

use std::ops::Range;

use plcd_core::lang::ops::{Op, Place};
use plcd_core::lang::Program;
use plcd_core::value::Elem;

use crate::analysis::{is_native, Analysis};

/// A fixed place fetched as `Elem`: the key of a value held in a register.
pub(crate) type Key = (Place, Elem);

/// True for the places whose values native code holds: those in variable memory, the frame
/// and the FB instance. Device memory is not held: a `Word`, a `Bit` and a `Byte` overlap in
/// ways their places do not show.
pub(crate) fn in_bytes(place: Place) -> bool {
    matches!(place, Place::Var(_) | Place::Frame(_) | Place::This(_))
}

/// True if a store of `bytes` bytes at fixed place `at` may change the value of `held`. An FB
/// instance (`This`) may be in variable memory or in a frame, anywhere, unless
/// `this_in_vars` (the code of a call compiled inline, whose caller knows its instance is in
/// variable memory): then it is not in the frame.
pub(crate) fn may_change(at: Place, bytes: u32, held: Key, this_in_vars: bool) -> bool {
    let range = |offset: u32, n: u32| u64::from(offset)..u64::from(offset) + u64::from(n);
    let overlaps = |a: u32, b: u32| {
        let (x, y) = (range(a, bytes), range(b, held.1.size()));
        x.start < y.end && y.start < x.end
    };
    match (at, held.0) {
        (Place::Var(a), Place::Var(b))
        | (Place::Frame(a), Place::Frame(b))
        | (Place::This(a), Place::This(b)) => overlaps(a, b),
        (Place::Word(_) | Place::Bit(_) | Place::Byte(_), _) => false,
        (Place::Var(_), Place::Frame(_)) | (Place::Frame(_), Place::Var(_)) => false,
        (Place::This(_), Place::Frame(_)) | (Place::Frame(_), Place::This(_)) => !this_in_vars,
        _ => true,
    }
}

/// Where a pointer into variable memory points, as far as a block's ops show: an offset from
/// `least` to `most` (an element of an array at a fixed place, a member of one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Reach {
    pub least: u64,
    pub most: u64,
}

impl Reach {
    /// The pointer to the variable at `offset`.
    pub fn at(offset: u32) -> Reach {
        Reach { least: u64::from(offset), most: u64::from(offset) }
    }

    /// An element of the array of `len` elements `stride` bytes apart that starts here
    /// ([`Op::Index`], which leaves native code for an index outside it); `None` for an empty
    /// array or past `u32::MAX`.
    pub fn element(self, len: u32, stride: u32) -> Option<Reach> {
        let last = u64::from(len.checked_sub(1)?) * u64::from(stride);
        Some(Reach { least: self.least, most: self.most + last }).filter(Reach::fits)
    }

    /// `n` bytes further ([`Op::Offset`]: a member).
    pub fn member(self, n: u32) -> Option<Reach> {
        Some(Reach { least: self.least + u64::from(n), most: self.most + u64::from(n) })
            .filter(Reach::fits)
    }

    /// A store of `bytes` bytes here, as the store at a fixed place that covers every byte it
    /// may change.
    pub fn store(self, bytes: u32) -> (Place, u32) {
        let span = self.most - self.least + u64::from(bytes);
        (Place::Var(self.least as u32), span.min(u64::from(u32::MAX)) as u32)
    }

    fn fits(&self) -> bool {
        self.most <= u64::from(u32::MAX)
    }
}

/// What one op does to the values of fixed places.
enum Effect {
    /// A fetch from a fixed place.
    Fetch(Key),
    /// A store at a fixed place: its value is held after it.
    Store(Place, Elem),
    /// A store through a pointer the ops show the reach of: what it may change, as a fixed
    /// place and a number of bytes.
    Changes(Place, u32),
    /// A store through any pointer, a copy to one, a call: every value may change.
    Forgets,
    /// An inlined call: what its callee may change ([`Writes::changes`]), as fixed places.
    ChangesAll(Vec<(Place, u32)>),
    Nothing,
}

/// Where a pointer on the evaluation stack points, as `codegen` knows it: into variable
/// memory ([`Reach`]), or at a fixed offset into the frame.
#[derive(Clone, Copy)]
enum Target {
    Vars(Reach),
    Frame(u32),
}

/// The effects of a block's ops in order. The pointers a store goes through are followed on
/// the evaluation stack from where the block makes them ([`Op::AddrOf`], [`Op::Index`],
/// [`Op::Offset`], [`Op::Dup`]), as `codegen` follows them: a store through any other pointer
/// forgets every value, and so does a call, unless it is inlined (`inlined`; `start`: the first
/// op's pc).
fn effects<'c>(
    code: &'c [Op],
    start: usize,
    inlined: &'c [(u32, &'c Writes)],
    this_in_vars: bool,
) -> impl Iterator<Item = Effect> + 'c {
    // The slots the block pushed; a slot below them (pushed before the block) is unknown.
    let mut stack: Vec<Option<Target>> = Vec::new();
    // The places the block stored a pointer it follows at (a temporary holding an FB instance's
    // address for its call), still unchanged: fetched again, it is followed on.
    let mut saved: Vec<(Place, Target)> = Vec::new();
    code.iter().enumerate().map(move |(k, op)| {
        let pc = (start + k) as u32;
        let effect = effect(op, pc, inlined, &mut stack, &saved);
        let unchanged = |saved: &mut Vec<(Place, Target)>, at: Place, bytes: u32| {
            saved.retain(|&(place, _)| !may_change(at, bytes, (place, Elem::U64), this_in_vars));
        };
        match &effect {
            Effect::Store(at, elem) => {
                unchanged(&mut saved, *at, elem.size());
                if let (Some(Some(target)), 8) = (stack.pop(), elem.size()) {
                    saved.push((*at, target));
                }
            }
            Effect::Changes(at, bytes) => unchanged(&mut saved, *at, *bytes),
            Effect::ChangesAll(changes) => {
                for &(at, bytes) in changes {
                    unchanged(&mut saved, at, bytes);
                }
            }
            Effect::Forgets => saved.clear(),
            Effect::Fetch(_) | Effect::Nothing => {}
        }
        effect
    })
}

/// The effect of `op` at `pc` on the values held, the pointers on `stack` followed through it
/// (a `Store` leaves its value on the stack, for `effects` to pop).
fn effect(
    op: &Op,
    pc: u32,
    inlined: &[(u32, &Writes)],
    stack: &mut Vec<Option<Target>>,
    saved: &[(Place, Target)],
) -> Effect {
    if let Some(&(_, writes)) = inlined.iter().find(|&&(at, _)| at == pc) {
        let instance = match op {
            Op::CallFb { .. } => stack.pop().flatten(),
            _ => None,
        };
        return inlined_effect(writes, instance);
    }
    let mut pop = || stack.pop().flatten();
    let (effect, pushed) = match *op {
        Op::Fetch { elem, at } if in_bytes(at) => {
            let pointer = saved.iter().find(|&&(place, _)| place == at).map(|&(_, t)| t);
            (Effect::Fetch((at, elem)), pointer.filter(|_| elem.size() == 8))
        }
        Op::Store { elem, at } => return Effect::Store(at, elem),
        Op::AddrOf(Place::Var(offset)) => (Effect::Nothing, Some(Target::Vars(Reach::at(offset)))),
        Op::AddrOf(Place::Frame(offset)) => (Effect::Nothing, Some(Target::Frame(offset))),
        Op::Index { len, stride, .. } => {
            pop();
            let element = match pop() {
                Some(Target::Vars(reach)) => reach.element(len, stride).map(Target::Vars),
                _ => None,
            };
            stack.push(element);
            return Effect::Nothing;
        }
        Op::Offset(n) => {
            let member = match pop() {
                Some(Target::Vars(reach)) => reach.member(n).map(Target::Vars),
                Some(Target::Frame(offset)) => offset.checked_add(n).map(Target::Frame),
                None => None,
            };
            stack.push(member);
            return Effect::Nothing;
        }
        Op::Dup => {
            let top = pop();
            stack.extend([top, top]);
            return Effect::Nothing;
        }
        Op::StoreInd(elem) => return through_pointer(stack, elem.size()),
        Op::Copy(n) => return through_pointer(stack, n),
        Op::CallFn { .. } | Op::CallFb { .. } => (Effect::Forgets, None),
        _ => (Effect::Nothing, None),
    };
    let (popped, pushes) = op.stack_effect().unwrap_or((0, 0));
    for _ in 0..popped {
        pop();
    }
    for _ in 0..pushes {
        stack.push(pushed);
    }
    effect
}

/// What an inlined callee may store to, seen from its caller ([`callee_writes`]).
#[derive(Default)]
pub(crate) struct Writes {
    /// It stores into its FB instance, within this many bytes from its start (0: it does not,
    /// or it is a FUNCTION).
    pub instance: u64,
    /// Fixed places it stores at, in the caller's terms (its frame's at the caller's offsets),
    /// with their sizes.
    pub fixed: Vec<(Place, u32)>,
    /// It stores through a pointer it does not follow: anything may change.
    pub anywhere: bool,
}

impl Writes {
    /// The fixed places (with their sizes) the callee may change, its instance's bytes where
    /// `instance` places that many bytes from its start; `None`: anything may change (a store
    /// through a pointer it does not follow, or into an instance nobody knows the place of).
    pub fn changes(
        &self,
        instance: impl FnOnce(u32) -> Option<(Place, u32)>,
    ) -> Option<Vec<(Place, u32)>> {
        if self.anywhere {
            return None;
        }
        let mut changes = self.fixed.clone();
        if self.instance > 0 {
            changes.push(instance(self.instance.min(u64::from(u32::MAX)) as u32)?);
        }
        Some(changes)
    }
}

/// What the body of `function`, called with its frame `frame` bytes after the caller's
/// (`fb`: as a FUNCTION_BLOCK, with an instance of its own), may store to: its stores, and its
/// stores through pointers followed as [`effects`] follows them, block by block.
pub(crate) fn callee_writes(
    program: &Program,
    analysis: &Analysis,
    function: usize,
    frame: u32,
    fb: bool,
) -> Writes {
    let code = &program.code;
    let mut writes = Writes::default();
    let change = |writes: &mut Writes, at: Place, bytes: u32| match at {
        Place::This(offset) if fb => {
            let end = u64::from(offset) + u64::from(bytes);
            writes.instance = writes.instance.max(end);
        }
        Place::Frame(offset) => match offset.checked_add(frame) {
            Some(offset) => writes.fixed.push((Place::Frame(offset), bytes)),
            None => writes.anywhere = true,
        },
        place => writes.fixed.push((place, bytes)),
    };
    for &leader in &analysis.function_leaders[function] {
        let range = analysis.block(code, leader);
        for effect in effects(&code[range.clone()], range.start, &[], false) {
            match effect {
                Effect::Store(at, elem) => change(&mut writes, at, elem.size()),
                Effect::Changes(at, bytes) => change(&mut writes, at, bytes),
                Effect::Forgets | Effect::ChangesAll(_) => writes.anywhere = true,
                Effect::Fetch(_) | Effect::Nothing => {}
            }
        }
    }
    writes
}

/// What an inlined call with the FB instance `instance` (where the block knows it) may change.
fn inlined_effect(writes: &Writes, instance: Option<Target>) -> Effect {
    let changes = writes.changes(|bytes| match instance? {
        Target::Vars(reach) => Some(reach.store(bytes)),
        Target::Frame(offset) => Some((Place::Frame(offset), bytes)),
    });
    changes.map_or(Effect::Forgets, Effect::ChangesAll)
}

/// A store of `bytes` bytes through the pointer under the value on top of `stack` (both
/// popped): what it may change.
fn through_pointer(stack: &mut Vec<Option<Target>>, bytes: u32) -> Effect {
    stack.pop();
    match stack.pop().flatten() {
        Some(Target::Vars(reach)) => {
            let (place, bytes) = reach.store(bytes);
            Effect::Changes(place, bytes)
        }
        Some(Target::Frame(offset)) => Effect::Changes(Place::Frame(offset), bytes),
        None => Effect::Forgets,
    }
}

/// What the values held at the end of a block of `code` are, given those held at its start
/// (`held`, changed in place). Conservative beside `codegen`, which may keep more (the value
/// of a pointer variable it fetched again).
fn through(
    code: &[Op],
    start: usize,
    inlined: &[(u32, &Writes)],
    this_in_vars: bool,
    held: &mut Vec<Key>,
) {
    let may_change = |at, bytes, key| may_change(at, bytes, key, this_in_vars);
    for effect in effects(code, start, inlined, this_in_vars) {
        match effect {
            Effect::Fetch(key) if !held.contains(&key) => held.push(key),
            Effect::Store(at, elem) => {
                held.retain(|&key| !may_change(at, elem.size(), key));
                if in_bytes(at) {
                    held.push((at, elem));
                }
            }
            Effect::Changes(at, bytes) => held.retain(|&key| !may_change(at, bytes, key)),
            Effect::ChangesAll(changes) => {
                for (at, bytes) in changes {
                    held.retain(|&key| !may_change(at, bytes, key));
                }
            }
            Effect::Forgets => held.clear(),
            Effect::Fetch(_) | Effect::Nothing => {}
        }
    }
}

/// What a block of `code` wants of the values it receives: the keys it fetches before
/// anything in it may change them, and the stores after which a key is not wanted from its
/// start by the blocks after it (`None`: a store through a pointer it cannot follow, a copy
/// to one, or a call, after which every value is fetched again).
struct Wants {
    fetched: Vec<Key>,
    stores: Option<Vec<(Place, u32)>>,
}

fn wants(code: &[Op], start: usize, inlined: &[(u32, &Writes)], this_in_vars: bool) -> Wants {
    let may_change = |at, bytes, key| may_change(at, bytes, key, this_in_vars);
    let mut fetched = Vec::new();
    let mut stores = Vec::new();
    for effect in effects(code, start, inlined, this_in_vars) {
        match effect {
            Effect::Fetch(key) => {
                let unchanged = !stores.iter().any(|&(place, bytes)| may_change(place, bytes, key));
                if unchanged && !fetched.contains(&key) {
                    fetched.push(key);
                }
            }
            Effect::Store(at, elem) => stores.push((at, elem.size())),
            Effect::Changes(at, bytes) => stores.push((at, bytes)),
            Effect::ChangesAll(changes) => stores.extend(changes),
            Effect::Forgets => return Wants { fetched, stores: None },
            Effect::Nothing => {}
        }
    }
    Wants { fetched, stores: Some(stores) }
}

/// At most this many values of integers (BOOLs, pointers) go on in registers into a block
/// outside any loop ([`carried`]): a block that would receive more receives none of them.
/// REALs and LREALs are not counted: they take float registers, of which x86-64 has 16, none
/// saved by the callee.
///
/// Outside a loop every store is written through at once, so a value received there is one
/// memory holds too: receiving it spares one load where it is used, for a register held across
/// the join and every block before that use. Once the values held outnumber the free registers
/// (x86-64 has 14 general ones, of which the body's pointers, its budget and the expressions'
/// temporaries take most), the register allocator spills them to the stack, a store and a load
/// for the load spared, or takes callee-saved registers, each saved and restored on every call.
/// `bit` (benches/st/bit.st: 24 rungs and three IFs) carried 15 BOOLs across its joins: 22
/// spill moves and 5 callee-saved registers a scan, against a load each where used. A few
/// values (a CASE's selector and counters in `state_machine`) still go on in registers.
pub(crate) const JOIN_INTEGERS: usize = 4;

/// An order of keys, so that two sets of them compare equal when they hold the same keys.
fn rank((place, elem): Key) -> (u8, u32, u8) {
    let (space, offset) = match place {
        Place::Var(offset) => (0, offset),
        Place::Frame(offset) => (1, offset),
        Place::This(offset) => (2, offset),
        Place::Word(word) => (3, u32::from(word.0)),
        Place::Bit(bit) => (4, u32::from(bit.word) << 16 | u32::from(bit.mask)),
        Place::Byte(n) => (5, n),
    };
    (space, offset, elem as u8)
}

/// A body's blocks (`leaders`, as indices into [`Analysis::leaders`]) and the jumps between
/// them, by their indices in `leaders`: found once for [`carried`], [`unwritten`] and
/// [`in_loops`]. A block the interpreter runs ends native code: it jumps nowhere.
pub(crate) struct Jumps {
    pub blocks: Vec<Range<usize>>,
    pub successors: Vec<Vec<usize>>,
    pub predecessors: Vec<Vec<usize>>,
}

impl Jumps {
    pub fn of(program: &Program, analysis: &Analysis, leaders: &[usize]) -> Jumps {
        let code = &program.code;
        let index_of =
            |pc: u32| leaders.binary_search_by_key(&pc, |&leader| analysis.leaders[leader]).ok();
        let blocks: Vec<_> = leaders.iter().map(|&leader| analysis.block(code, leader)).collect();
        let mut predecessors = vec![Vec::new(); blocks.len()];
        let mut successors = vec![Vec::new(); blocks.len()];
        for (from, range) in blocks.iter().enumerate() {
            if !is_native(&code[range.start]) {
                continue;
            }
            for to in analysis.successors(code, leaders[from]).into_iter().filter_map(index_of) {
                predecessors[to].push(from);
                successors[from].push(to);
            }
        }
        Jumps { blocks, successors, predecessors }
    }
}

/// The values each of a body's blocks receives, by the block's index in its [`Jumps`];
/// `inlined`: its calls compiled
/// inline (their pcs), whose blocks go on after them knowing what their callees may change;
/// `this_in_vars` as for [`may_change`]; `in_loop`: [`in_loops`], outside which a block
/// receives at most [`JOIN_INTEGERS`] integer values.
pub(crate) fn carried(
    program: &Program,
    jumps: &Jumps,
    inlined: &[(u32, &Writes)],
    this_in_vars: bool,
    in_loop: &[bool],
) -> Vec<Vec<Key>> {
    let code = &program.code;
    let Jumps { blocks, successors, predecessors } = jumps;
    // Backwards, as liveness: the keys some path from each block's start fetches before they
    // may change. A value nobody wants is not passed on (it would only take a register).
    let wants: Vec<Wants> = blocks
        .iter()
        .map(|range| {
            if is_native(&code[range.start]) {
                wants(&code[range.clone()], range.start, inlined, this_in_vars)
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
                    let kept = !stores
                        .iter()
                        .any(|&(place, bytes)| may_change(place, bytes, key, this_in_vars));
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
                if !in_loop[index] {
                    // (A block outside loops is on no cycle of jumps: what it receives depends
                    // on the blocks before it only, and the iteration still ends.)
                    held.retain(|key| wanted[index].contains(key));
                    let integers = held.iter().filter(|key| !key.1.is_float()).count();
                    if integers > JOIN_INTEGERS {
                        held.retain(|key| key.1.is_float());
                    }
                }
                into[index] = held;
            }
            let mut held = into[index].clone();
            let range = &blocks[index];
            if is_native(&code[range.start]) {
                through(&code[range.clone()], range.start, inlined, this_in_vars, &mut held);
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

/// For each of a body's blocks (its [`Jumps`]), the values it receives
/// (`carried`, [`carried`]'s result) that a block before it may have stored and not written
/// to memory yet: `codegen` keeps a store in a loop (`in_loop`, [`in_loops`]) in a register
/// while the value goes on in one to the next blocks, and writes it back where something else
/// may read the place. Forwards, as
/// reaching definitions: a block passes on what it received unwritten and what it stores,
/// except after a call (the code writes every value back before one); over-approximated
/// (a write-back inside a block is not followed), which only costs a store of a value memory
/// holds already.
pub(crate) fn unwritten(
    program: &Program,
    jumps: &Jumps,
    carried: &[Vec<Key>],
    in_loop: &[bool],
) -> Vec<Vec<Key>> {
    let code = &program.code;
    let Jumps { blocks, successors, .. } = jumps;
    let mut stores: Vec<Option<Vec<Key>>> = vec![None; blocks.len()];
    for (from, range) in blocks.iter().enumerate() {
        if !is_native(&code[range.start]) {
            continue;
        }
        let ends_in_call = matches!(code[range.end - 1], Op::CallFn { .. } | Op::CallFb { .. });
        if !ends_in_call {
            let mut keys = Vec::new();
            // (Outside a loop, stores are written at once.)
            let deferred = if in_loop[from] { &code[range.clone()] } else { &[] };
            for op in deferred {
                if let Op::Store { elem, at } = *op {
                    if in_bytes(at) && !keys.contains(&(at, elem)) {
                        keys.push((at, elem));
                    }
                }
            }
            stores[from] = Some(keys);
        }
    }
    let mut into: Vec<Vec<Key>> = vec![Vec::new(); blocks.len()];
    let mut changed = true;
    while changed {
        changed = false;
        for from in 0..blocks.len() {
            let Some(stored) = &stores[from] else { continue };
            let out: Vec<Key> = into[from].iter().chain(stored).copied().collect();
            for &to in &successors[from] {
                for &key in &out {
                    if carried[to].contains(&key) && !into[to].contains(&key) {
                        into[to].push(key);
                        changed = true;
                    }
                }
            }
        }
    }
    into
}

/// For each of a body's blocks (its [`Jumps`]): whether it lies inside a loop,
/// between a jump back and the block it jumps to (Structured Text's loops are compiled so).
/// `codegen` keeps a store in a register only there, where the loop's next round may store
/// the place again: elsewhere a value held until it is written back only keeps a register
/// busy.
pub(crate) fn in_loops(jumps: &Jumps) -> Vec<bool> {
    let n = jumps.blocks.len();
    // +1 where a loop starts, -1 after where it ends.
    let mut delta = vec![0i64; n + 1];
    for (from, successors) in jumps.successors.iter().enumerate() {
        for &to in successors.iter().filter(|&&to| to <= from) {
            delta[to] += 1;
            delta[from + 1] -= 1;
        }
    }
    let mut depth = 0;
    (0..n)
        .map(|index| {
            depth += delta[index];
            depth > 0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analysed_test_program;

    /// The blocks of the PROGRAM of `source` (its only body) that several blocks jump to: in a
    /// loop or not, and the values each receives, as (integers, floats).
    fn joins(source: &str) -> Vec<(bool, usize, usize)> {
        let (program, analysis) = analysed_test_program("carry.st", source);
        assert_eq!(analysis.functions.len(), 1, "one body");
        let jumps = Jumps::of(&program, &analysis, &analysis.function_leaders[0]);
        let in_loop = in_loops(&jumps);
        let carried = carried(&program, &jumps, &[], false, &in_loop);
        (0..jumps.blocks.len())
            .filter(|&index| jumps.predecessors[index].len() > 1)
            .map(|index| {
                let floats = carried[index].iter().filter(|key| key.1.is_float()).count();
                (in_loop[index], carried[index].len() - floats, floats)
            })
            .collect()
    }

    /// `n` variables of `ty` fetched before an IF and after it, in a loop or not.
    fn across_an_if(ty: &str, n: usize, in_a_loop: bool) -> String {
        let names: Vec<String> = (0..n).map(|k| format!("v{k}")).collect();
        let (op, zero) = if ty == "BOOL" { ("AND", "FALSE") } else { ("+", "0") };
        let sum = names.join(&format!(" {op} "));
        let body = format!("x := {sum}; IF x = {zero} THEN x := {zero}; END_IF; x := {sum};");
        let body = if in_a_loop { format!("FOR i := 1 TO 10 DO {body} END_FOR;") } else { body };
        format!(
            "PROGRAM Main VAR {names} : {ty}; x : {ty}; i : INT; END_VAR {body} END_PROGRAM",
            names = names.join(", ")
        )
    }

    #[test]
    fn a_join_outside_loops_receives_a_few_integers_or_none() {
        // (x is stored again before it is fetched: not received.)
        let few = joins(&across_an_if("BOOL", JOIN_INTEGERS, false));
        assert_eq!(few, vec![(false, JOIN_INTEGERS, 0)]);
        let many = joins(&across_an_if("BOOL", JOIN_INTEGERS + 1, false));
        assert_eq!(many, vec![(false, 0, 0)], "one more than JOIN_INTEGERS: none");
        let dints = joins(&across_an_if("DINT", 8, false));
        assert_eq!(dints, vec![(false, 0, 0)]);
    }

    #[test]
    fn a_join_outside_loops_receives_every_float() {
        assert_eq!(joins(&across_an_if("REAL", 8, false)), vec![(false, 0, 8)]);
        assert_eq!(joins(&across_an_if("LREAL", 8, false)), vec![(false, 0, 8)]);
    }

    #[test]
    fn a_join_in_a_loop_receives_every_value() {
        let joins = joins(&across_an_if("BOOL", 8, true));
        assert!(joins.contains(&(true, 9, 0)), "the BOOLs and i: {joins:?}");
    }
}
