//! Which calls of a Structured Text body are compiled inline, decided before its code is
//! generated, so that `carry`'s analysis and `codegen` follow one plan; and what each inlined
//! call may change, in its caller's places (a call compiled as a machine call may change
//! anything).
//!
//! A call is inlined when its callee is small ([`INLINE_CALLEE`] instructions), all native,
//! calls nothing (no nesting, no recursion), and the body's inlined instructions stay within
//! [`INLINE_BUDGET`]: each inlined call compiles its callee's body once more, which costs
//! compile time and code size.

use plcd_core::lang::ops::Op;
use plcd_core::lang::Program;

use crate::analysis::{is_native, Analysis};
use crate::carry::{callee_writes, Writes};

/// Instructions of one callee's body compiled inline at a call, at most.
pub(crate) const INLINE_CALLEE: usize = 128;
/// Instructions of callees compiled inline into one function, at most.
pub(crate) const INLINE_BUDGET: usize = 1024;

/// A call compiled inline: the call instruction's `pc`, the callee's generated `function`.
pub(crate) struct Inlined {
    pub pc: u32,
    pub function: usize,
    pub writes: Writes,
}

/// The calls of the body at `body` (its leaders `leaders`) compiled inline, in code order.
pub(crate) fn plan(
    program: &Program,
    analysis: &Analysis,
    body: u32,
    leaders: &[usize],
) -> Vec<Inlined> {
    let code = &program.code;
    let mut inlined = 0;
    let mut plan = Vec::new();
    for &leader in leaders {
        let range = analysis.block(code, leader);
        let (target, frame, fb) = match range.end.checked_sub(1).and_then(|last| code.get(last)) {
            Some(&Op::CallFn { target, frame }) => (target, frame, false),
            Some(&Op::CallFb { target, frame }) => (target, frame, true),
            _ => continue,
        };
        if target == body {
            continue;
        }
        let Ok(function) = analysis.functions.binary_search(&target) else { continue };
        let Some(size) = inlinable(program, analysis, function) else { continue };
        if inlined + size > INLINE_BUDGET {
            continue;
        }
        inlined += size;
        let writes = callee_writes(program, analysis, function, frame, fb);
        plan.push(Inlined { pc: range.end as u32 - 1, function, writes });
    }
    plan
}

/// The size of `function`'s body if it may be inlined: all native, no call, no `END`, at most
/// [`INLINE_CALLEE`] instructions.
fn inlinable(program: &Program, analysis: &Analysis, function: usize) -> Option<usize> {
    let code = &program.code;
    let mut size = 0;
    for &leader in &analysis.function_leaders[function] {
        let range = analysis.block(code, leader);
        size += range.len();
        let calls = code[range.clone()]
            .iter()
            .any(|op| matches!(op, Op::CallFn { .. } | Op::CallFb { .. } | Op::End));
        if calls || !is_native(&code[range.start]) || size > INLINE_CALLEE {
            return None;
        }
    }
    Some(size)
}
