//! The typed operations native code calls out for instead of inlining them (the float
//! functions, shifts and rotations, the float-to-integer conversions): each is the core's own
//! operation of `plcd_core::value`, so that native code computes them as the interpreter
//! does, to the bit. Operations and types cross the call as their indices in the core's
//! tables (`BinOp::ALL`, `UnOp::ALL`, `Elem::ALL`).

use plcd_core::value::{self, BinOp, Elem, UnOp};

pub(crate) fn elem_index(elem: Elem) -> i64 {
    Elem::ALL.iter().position(|&e| e == elem).unwrap_or(0) as i64
}

pub(crate) fn binary_index(op: BinOp) -> i64 {
    BinOp::ALL.iter().position(|&o| o == op).unwrap_or(0) as i64
}

pub(crate) fn unary_index(op: UnOp) -> i64 {
    UnOp::ALL.iter().position(|&o| o == op).unwrap_or(0) as i64
}

fn elem(index: u64) -> Elem {
    Elem::ALL.get(index as usize).copied().unwrap_or(Elem::U64)
}

/// `a op b`; only called for the operations that cannot fail on `elem` (a failed one gives 0).
pub(crate) extern "C" fn binary(op: u64, elem_index: u64, a: u64, b: u64) -> u64 {
    let op = BinOp::ALL.get(op as usize).copied().unwrap_or(BinOp::Add);
    value::binary(op, elem(elem_index), a, b).unwrap_or(0)
}

/// `op a`.
pub(crate) extern "C" fn unary(op: u64, elem_index: u64, a: u64) -> u64 {
    let op = UnOp::ALL.get(op as usize).copied().unwrap_or(UnOp::Neg);
    value::unary(op, elem(elem_index), a)
}

/// `a` converted from `from` to `to`.
pub(crate) extern "C" fn convert(from: u64, to: u64, a: u64) -> u64 {
    value::convert(elem(from), elem(to), a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tables_name_every_operation_once() {
        for (index, op) in UnOp::ALL.iter().enumerate() {
            assert_eq!(unary_index(*op), index as i64);
        }
        for (index, op) in BinOp::ALL.iter().enumerate() {
            assert_eq!(binary_index(*op), index as i64);
        }
        for (index, e) in Elem::ALL.iter().enumerate() {
            assert_eq!(elem_index(*e), index as i64);
        }
    }
}
