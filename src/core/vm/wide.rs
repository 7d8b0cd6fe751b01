//! The string operations on `WSTRING`s, and the conversions between `STRING` and `WSTRING`.
//!
//! A `WSTRING[n]` is stored as CODESYS and TwinCAT store it: n UTF-16 code units of 2 bytes
//! (little-endian, as every value in variable memory) and a 2-byte NUL after the last one,
//! 2(n+1) bytes. The operations a STRING has too are `typed::unit_op`'s, on units of 2 bytes;
//! this module owns the conversions (to and from values, between STRING and WSTRING) and the
//! clients' reads and writes. Positions and counts are in code units. Like the STRING operations, nothing here allocates and no access panics:
//! a pointer outside its space reads an empty string and writes nothing.

use super::typed::{self, EvalStack, MAX_CHARS};
use crate::lang::ops::StrOp;
use crate::value::{Pointer, Space};

/// The most code units a WSTRING holds (as a STRING, at most 255 characters).
const MAX_UNITS: usize = MAX_CHARS;

/// The bytes of the code units of the WSTRING at `p` (2 a unit, without the NUL), borrowed.
fn units<'a>(vars: &'a [u8], frame: &'a [u8], p: Pointer) -> &'a [u8] {
    typed::units(vars, frame, p, 2)
}

/// The code units of `bytes` (as [`units`] gives them), in order.
fn code_units(bytes: &[u8]) -> impl Iterator<Item = u16> + '_ {
    bytes.chunks_exact(2).map(|u| u16::from_le_bytes([u[0], u[1]]))
}

/// Writes `n` code units, made by `unit(i)`, as the whole WSTRING at `p`.
fn write_units(
    vars: &mut [u8],
    frame: &mut [u8],
    p: Pointer,
    n: usize,
    unit: impl Fn(usize) -> u16,
) {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return,
    };
    let start = p.offset as usize;
    if let Some(room) = buf.get_mut(start..start + 2 * n + 2) {
        for i in 0..n {
            room[2 * i..2 * i + 2].copy_from_slice(&unit(i).to_le_bytes());
        }
        room[2 * n..].fill(0);
    }
}

/// The Windows-1252 byte of a code unit; `?` for a unit Windows-1252 has no character for (a
/// character outside it, half of a surrogate pair), as CODESYS converts.
fn narrow_unit(unit: u16) -> u8 {
    char::from_u32(u32::from(unit)).and_then(crate::value::encode_char).unwrap_or(b'?')
}

/// Executes a string operation on WSTRINGs, or a conversion between STRING and WSTRING;
/// `cap` is the destination's capacity in characters.
#[inline(never)]
pub(super) fn string_op(
    stack: &mut EvalStack,
    vars: &mut [u8],
    frame: &mut [u8],
    op: StrOp,
    cap: u16,
) {
    let cap = usize::from(cap).min(MAX_UNITS);
    let ptr = |slot: u64| Pointer::from_slot(slot);
    match op {
        StrOp::FromValue(scalar) => {
            let (v, dst) = (stack.pop(), ptr(stack.pop()));
            let text = typed::scalar_text(scalar, v);
            // the text of a number is ASCII: each byte is its code unit
            let n = text.len().min(cap);
            write_units(vars, frame, dst, n, |i| u16::from(text[i]));
        }
        StrOp::ToValue(scalar) => {
            let s = ptr(stack.pop());
            let mut text = [0u8; MAX_UNITS];
            let mut n = 0;
            for (slot, unit) in text.iter_mut().zip(code_units(units(vars, frame, s))) {
                // the text of a number is ASCII; any other character makes it no number
                *slot = if unit < 0x80 { unit as u8 } else { b'?' };
                n += 1;
            }
            let text = std::str::from_utf8(&text[..n]).unwrap_or("");
            stack.push(crate::value::scalar_from_text(scalar, text).unwrap_or(0));
        }
        StrOp::Widen => {
            let (src, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let mut bytes = [0u8; MAX_UNITS];
            let chars = typed::string_bytes(vars, frame, src);
            let n = chars.len().min(cap).min(MAX_UNITS);
            // copied first: the source may overlap the destination
            bytes[..n].copy_from_slice(&chars[..n]);
            write_units(vars, frame, dst, n, |i| crate::value::decode_byte(bytes[i]) as u32 as u16);
        }
        StrOp::Narrow => {
            let (src, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let mut bytes = [0u8; MAX_UNITS];
            let mut n = 0;
            for (slot, unit) in bytes.iter_mut().zip(code_units(units(vars, frame, src))) {
                *slot = narrow_unit(unit);
                n += 1;
            }
            let n = n.min(cap);
            let buf = match dst.space {
                Space::Var => vars,
                Space::Frame => frame,
                _ => return,
            };
            let start = dst.offset as usize;
            if let Some(room) = buf.get_mut(start..start + n + 1) {
                room[..n].copy_from_slice(&bytes[..n]);
                room[n] = 0;
            }
        }
        _ => typed::unit_op(stack, vars, frame, op, cap, 2),
    }
}

/// The bytes of the code units of the WSTRING at `p` in variable memory, borrowed (for the
/// snapshot clients read, taken on the scan thread without allocating).
pub(super) fn wstring_bytes(vars: &[u8], p: Pointer) -> &[u8] {
    units(vars, &[], p)
}

/// The code units of the WSTRING at `p` in variable memory, for tools.
pub(super) fn wstring_units(vars: &[u8], p: Pointer) -> Vec<u16> {
    code_units(units(vars, &[], p)).collect()
}

/// Writes the code units `bytes` (2 a unit, little-endian; cut to `cap` units) as the WSTRING
/// at `p` in variable memory, for tools. Allocates nothing.
pub(super) fn write_wstring_bytes(vars: &mut [u8], p: Pointer, cap: u32, bytes: &[u8]) {
    if p.space != Space::Var {
        return;
    }
    let n = (bytes.len() / 2).min(cap as usize).min(MAX_UNITS);
    write_units(vars, &mut [], p, n, |i| u16::from_le_bytes([bytes[2 * i], bytes[2 * i + 1]]));
}
