//! What a program's ops need from native code, found before any is generated: the depth of
//! the evaluation stack at each instruction (relative to the activation: a FUNCTION or
//! FUNCTION_BLOCK body starts at 0), the instructions where native code can be entered, and
//! the blocks between them.
//!
//! The evaluation stack lives in machine registers inside a block, so its depth at each
//! instruction must be known when the code is generated: the Structured Text compiler leaves
//! the same depth on every path to an instruction, and a program where that does not hold is
//! refused here (it runs on the interpreter).

use plcd_core::lang::ops::{Op, Place};
use plcd_core::lang::{Program, EVAL_DEPTH};
use plcd_core::value::{BinOp, Elem};

/// The analysis of one program.
pub(crate) struct Analysis {
    /// The evaluation stack's depth before each instruction; `None` where no path from an
    /// entry reaches.
    pub depth: Vec<Option<u32>>,
    /// The instructions native code can be entered at, sorted: the program's start, every
    /// FUNCTION and FUNCTION_BLOCK body, every jump target, every instruction after a jump, a
    /// call or a return, every instruction native code hands to the interpreter and the one
    /// after it. A block runs from one to the next.
    pub leaders: Vec<u32>,
    /// The deepest evaluation stack.
    pub max_depth: u32,
    /// Bytes of variable memory and words of device memory the fixed operands reach: native
    /// code runs only when the memory is at least that large.
    pub vars_end: u64,
    pub words_end: u64,
    /// The body (program, FUNCTION or FUNCTION_BLOCK: its first instruction) each instruction
    /// belongs to.
    pub owner: Vec<Option<u32>>,
    /// Each body's first instruction, with what it needs and where its calls return. Each
    /// body is a generated function of its own, in this order (`Analysis::function_of`).
    pub bodies: std::collections::BTreeMap<u32, Body>,
    /// The bodies' first instructions, in the order of their functions.
    pub functions: Vec<u32>,
    /// The leaders of each function's body, as indices into `leaders`, by function.
    pub function_leaders: Vec<Vec<usize>>,
}

/// A body (the program's, a FUNCTION's or a FUNCTION_BLOCK's): how far its operands reach into
/// its frame and its FB instance, and the instructions its calls return to.
#[derive(Debug, Default)]
pub(crate) struct Body {
    pub frame_end: u64,
    /// An operand of the body is in its frame, or an address in it is taken.
    pub uses_frame: bool,
    pub this_end: u64,
    pub return_sites: Vec<u32>,
}

/// True if native code executes `op` itself; the others (the clock, strings, system requests,
/// the integer power and the difference of two pointers, which can fail) go to the
/// interpreter.
pub(crate) fn is_native(op: &Op) -> bool {
    match op {
        Op::Now | Op::Utc | Op::Str { .. } | Op::System(_) | Op::RefDiff => false,
        Op::Bin { op: BinOp::Expt, elem } => elem.is_float(),
        _ => true,
    }
}

/// True if control does not go on to the next instruction after `op` (or may not).
fn ends_block(op: &Op) -> bool {
    matches!(
        op,
        Op::Goto(_)
            | Op::GotoIf { .. }
            | Op::CallFn { .. }
            | Op::CallFb { .. }
            | Op::Return
            | Op::End
    )
}

/// The bytes of variable memory (`Var`) or words of device memory (`Word`, `Bit`, `Byte`) a
/// fixed operand reaches, as `(vars_end, words_end)`.
fn reach(at: Place, elem: Elem) -> (u64, u64) {
    match at {
        Place::Var(offset) => (u64::from(offset) + u64::from(elem.size()), 0),
        Place::Word(w) => (0, u64::from(w.0) + u64::from(elem.words())),
        Place::Bit(b) => (0, u64::from(b.word) + 1),
        Place::Byte(n) => (0, u64::from(n / 2) + 1),
        Place::Frame(_) | Place::This(_) => (0, 0),
    }
}

/// The program of `source`, a file named `file` whose PROGRAM `main` is its only instance,
/// compiled, and its analysis: where the units of the stages after the analysis (`carry`,
/// `codegen`) start from.
#[cfg(test)]
pub(crate) fn analysed_test_program(file: &str, source: &str) -> (Program, Analysis) {
    use plcd_core::st::{compile, parse_file, Instance};
    let path = std::path::Path::new(file);
    let (file, diags) = parse_file(path, source);
    assert!(diags.is_empty(), "{diags}");
    let main = Instance { name: "main", pou: None, file: path, config: path, line: 1, col: 1 };
    let program = compile(&[file], &[main]).unwrap_or_else(|d| panic!("{d}")).programs.remove(0);
    let analysis = analyse(&program).expect("analysed");
    (program, analysis)
}

pub(crate) fn analyse(program: &Program) -> Result<Analysis, String> {
    let code = &program.code;
    let len = code.len();
    let mut depth: Vec<Option<u32>> = vec![None; len + 1];
    let mut leaders = vec![0u32];
    let mut work = vec![(0usize, 0u32)];
    let mut max_depth = 0;
    let mut vars_end = 0;
    let mut words_end = 0;
    while let Some((pc, d)) = work.pop() {
        if pc > len {
            return Err(format!("a jump to {pc}, past the end of the code"));
        }
        match depth[pc] {
            Some(known) if known == d => continue,
            Some(known) => {
                return Err(format!(
                    "the evaluation stack is {known} and {d} deep at instruction {pc}"
                ))
            }
            None => depth[pc] = Some(d),
        }
        let Some(op) = code.get(pc) else {
            continue; // the end of the code: the interpreter ends the program there
        };
        let (pops, pushes) =
            op.stack_effect().ok_or_else(|| format!("{op:?} is not an op of Structured Text"))?;
        let after = d
            .checked_sub(pops)
            .ok_or_else(|| format!("instruction {pc} pops more than the stack holds"))?
            + pushes;
        max_depth = max_depth.max(after).max(d);
        if max_depth as usize >= EVAL_DEPTH {
            return Err(format!("instruction {pc} needs {max_depth} slots of evaluation stack"));
        }
        if let Op::Fetch { elem, at } | Op::Store { elem, at } = op {
            let (v, w) = reach(*at, *elem);
            vars_end = vars_end.max(v);
            words_end = words_end.max(w);
        }
        let next = pc + 1;
        if !is_native(op) {
            leaders.extend([pc as u32, next as u32]);
        }
        if ends_block(op) {
            leaders.push(next as u32);
        }
        match *op {
            Op::Goto(target) => {
                leaders.push(target);
                work.push((target as usize, after));
            }
            Op::GotoIf { target, .. } => {
                leaders.push(target);
                work.extend([(target as usize, after), (next, after)]);
            }
            Op::CallFn { target, .. } | Op::CallFb { target, .. } => {
                leaders.push(target);
                work.extend([(target as usize, 0), (next, after)]);
            }
            Op::Return if d != 0 => {
                return Err(format!("RETURN at instruction {pc} leaves {d} slots on the stack"))
            }
            Op::Return | Op::End => {}
            _ => work.push((next, after)),
        }
    }
    leaders.retain(|&pc| (pc as usize) < len && depth[pc as usize].is_some());
    leaders.sort_unstable();
    leaders.dedup();
    depth.truncate(len);
    let (owner, bodies) = bodies(code)?;
    let functions: Vec<u32> = bodies.keys().copied().collect();
    let mut function_leaders = vec![Vec::new(); functions.len()];
    for (index, &leader) in leaders.iter().enumerate() {
        let body = owner[leader as usize].and_then(|start| functions.binary_search(&start).ok());
        if let Some(function) = body {
            function_leaders[function].push(index);
        }
    }
    Ok(Analysis {
        depth,
        leaders,
        max_depth,
        vars_end,
        words_end,
        owner,
        bodies,
        functions,
        function_leaders,
    })
}

/// The body of each instruction (its first instruction).
type Owners = Vec<Option<u32>>;
/// Each body by its first instruction.
type Bodies = std::collections::BTreeMap<u32, Body>;

/// The body of each instruction, found from each body's start along the jumps (not into
/// calls), and what each body needs. Every jump stays in its body: code is never shared.
fn bodies(code: &[Op]) -> Result<(Owners, Bodies), String> {
    let mut bodies = std::collections::BTreeMap::<u32, Body>::new();
    bodies.insert(0, Body::default());
    for (pc, op) in code.iter().enumerate() {
        if let Op::CallFn { target, .. } | Op::CallFb { target, .. } = *op {
            bodies.entry(target).or_default().return_sites.push(pc as u32 + 1);
        }
    }
    let mut owner: Vec<Option<u32>> = vec![None; code.len()];
    for (&start, body) in bodies.iter_mut() {
        let mut work = vec![start as usize];
        while let Some(pc) = work.pop() {
            let Some(op) = code.get(pc) else { continue };
            match owner[pc] {
                Some(known) if known == start => continue,
                Some(known) => {
                    return Err(format!("instruction {pc} is in the bodies at {known} and {start}"))
                }
                None => owner[pc] = Some(start),
            }
            let reach = |elem: &Elem, offset: &u32| u64::from(*offset) + u64::from(elem.size());
            match op {
                Op::Fetch { elem, at: Place::Frame(o) }
                | Op::Store { elem, at: Place::Frame(o) } => {
                    body.frame_end = body.frame_end.max(reach(elem, o));
                    body.uses_frame = true;
                }
                Op::AddrOf(Place::Frame(_)) => body.uses_frame = true,
                Op::Fetch { elem, at: Place::This(o) } | Op::Store { elem, at: Place::This(o) } => {
                    body.this_end = body.this_end.max(reach(elem, o));
                }
                _ => {}
            }
            match *op {
                Op::Goto(target) => work.push(target as usize),
                Op::GotoIf { target, .. } => work.extend([target as usize, pc + 1]),
                Op::Return | Op::End => {}
                _ => work.push(pc + 1),
            }
        }
    }
    Ok((owner, bodies))
}

/// What each block is for the step budget and the dispatch, by leader index.
#[derive(Default)]
pub(crate) struct BlockRoles {
    /// [`Analysis::budget_checks`].
    pub checks: Vec<(bool, u64)>,
    /// [`Analysis::dispatched`].
    pub dispatched: Vec<bool>,
}

impl Analysis {
    /// Both roles of every block.
    pub fn block_roles(&self, code: &[Op]) -> BlockRoles {
        let checks = self.budget_checks(code);
        let dispatched = self.dispatched(code, &checks);
        BlockRoles { checks, dispatched }
    }

    /// The block that starts at `leaders[index]`: its instructions run to the next leader, or
    /// to the first that ends a block, whichever comes first; an instruction the interpreter
    /// executes is a block of its own.
    pub fn block(&self, code: &[Op], index: usize) -> std::ops::Range<usize> {
        crate::blocks::block(&self.leaders, code.len(), code, index, |op| {
            ends_block(op) || !is_native(op)
        })
    }

    /// Where control goes after the last instruction of the native block at `leaders[index]`:
    /// a jump's target, the next instruction when it may go on (a call's return site
    /// included), nothing after a `RETURN` or `END`.
    pub fn successors(&self, code: &[Op], index: usize) -> Vec<u32> {
        let range = self.block(code, index);
        let end = range.end as u32;
        match code[range.end - 1] {
            Op::Goto(target) => vec![target],
            Op::GotoIf { target, .. } => vec![target, end],
            Op::Return | Op::End => vec![],
            _ => vec![end],
        }
    }

    /// Where each block checks the step budget, and for how many instructions (by leader
    /// index): `Some(n)` at a block that checks that `n` instructions are left (the longest
    /// path of native instructions from it to the next check), `None` at a block that does not
    /// (every path into it passed a check that covered it). A block checks when a jump goes
    /// back to it (a loop), when a call enters it or returns to it (the callee spent budget),
    /// and when the dispatch enters it (its loader checks); paths forward from a check are
    /// covered by it. So a loop checks once a round
    /// and straight-line code with IFs once, and the budget still ends exactly where the
    /// interpreter's would: a check that fails hands the block to the interpreter.
    pub fn budget_checks(&self, code: &[Op]) -> Vec<(bool, u64)> {
        let index_of = |pc: u32| self.leaders.binary_search(&pc).ok();
        let mut checkpoint = vec![false; self.leaders.len()];
        let mut successors = vec![Vec::new(); self.leaders.len()];
        // The loop fills `checkpoint` of other blocks than its own: an index, not an iterator.
        #[allow(clippy::needless_range_loop)]
        for index in 0..self.leaders.len() {
            let range = self.block(code, index);
            let Some(last) = code.get(range.end.wrapping_sub(1)) else { continue };
            if !is_native(&code[range.start]) {
                continue;
            }
            if let Op::CallFn { target, .. } | Op::CallFb { target, .. } = *last {
                for entered in [target, range.end as u32] {
                    if let Some(entered) = index_of(entered) {
                        checkpoint[entered] = true;
                    }
                }
                continue;
            }
            for target in self.successors(code, index) {
                let Some(to) = index_of(target) else { continue };
                if target <= range.start as u32 {
                    checkpoint[to] = true;
                } else {
                    successors[index].push(to);
                }
            }
        }
        let mut need = vec![0u64; self.leaders.len()];
        for index in (0..self.leaders.len()).rev() {
            let range = self.block(code, index);
            if !is_native(&code[range.start]) {
                continue;
            }
            let after = successors[index]
                .iter()
                .filter(|&&to| !checkpoint[to])
                .map(|&to| need[to])
                .max()
                .unwrap_or(0);
            need[index] = range.len() as u64 + after;
        }
        checkpoint.into_iter().zip(need).collect()
    }

    /// Which blocks the dispatch enters (by leader index), given [`Analysis::budget_checks`]:
    /// those the VM may ask native code to go on at — a body's start, a block that checks the
    /// budget (native code stops there when the budget is short, and the interpreter hands
    /// back there), a call's return site, the block after one the interpreter runs — and
    /// every block that more than one jump, or none, reaches. `codegen` adds the blocks after
    /// one whose code may hand an instruction to the interpreter (a pointer outside variable
    /// memory). The VM stopped at any other block (at the end of a budget, a breakpoint)
    /// interprets on to one of those.
    ///
    /// A block reached by one jump only and not from the dispatch has one predecessor: the
    /// values it uses are those of the block before it, not merges with what a loader reads
    /// from memory, so Cranelift finds what both compute (`j - 1`, its range check, the
    /// element it indexes) and computes it once.
    pub fn dispatched(&self, code: &[Op], checks: &[(bool, u64)]) -> Vec<bool> {
        let index_of = |pc: u32| self.leaders.binary_search(&pc).ok();
        let mut jumps_in = vec![0u32; self.leaders.len()];
        let mut entered = vec![false; self.leaders.len()];
        for &body in self.bodies.keys() {
            if let Some(index) = index_of(body) {
                entered[index] = true;
            }
        }
        for index in 0..self.leaders.len() {
            let range = self.block(code, index);
            let Some(last) = code.get(range.end.wrapping_sub(1)) else { continue };
            let end = range.end as u32;
            if !is_native(&code[range.start]) {
                // The interpreter runs this block and hands back after it.
                if let Some(after) = index_of(end) {
                    entered[after] = true;
                }
                continue;
            }
            if let Op::CallFn { .. } | Op::CallFb { .. } = *last {
                if let Some(after) = index_of(end) {
                    entered[after] = true;
                }
                continue;
            }
            for to in self.successors(code, index).into_iter().filter_map(index_of) {
                jumps_in[to] += 1;
            }
        }
        (0..self.leaders.len()).map(|i| entered[i] || checks[i].0 || jumps_in[i] != 1).collect()
    }

    /// The generated function that holds `pc`: its body's (the first for an instruction of
    /// no body, whose dispatch hands it to the interpreter).
    #[inline]
    pub fn function_of(&self, pc: u32) -> usize {
        if self.functions.len() == 1 {
            return 0;
        }
        self.owner
            .get(pc as usize)
            .copied()
            .flatten()
            .and_then(|start| self.functions.binary_search(&start).ok())
            .unwrap_or(0)
    }

    /// Instructions from `pc` to the next leader after it (the interpreter's share).
    pub fn span(&self, pc: u32) -> u32 {
        crate::blocks::span(&self.leaders, self.depth.len(), pc)
    }
}
