//! The string operations on `WSTRING`s, and the conversions between `STRING` and `WSTRING`.
//!
//! A `WSTRING[n]` is stored as CODESYS and TwinCAT store it: n UTF-16 code units of 2 bytes
//! (little-endian, as every value in variable memory) and a 2-byte NUL after the last one,
//! 2(n+1) bytes. The operations mirror `typed::string_op` unit for unit; positions and counts
//! are in code units. Like the STRING operations, nothing here allocates and no access panics:
//! a pointer outside its space reads an empty string and writes nothing.

use super::typed::{copy, EvalStack};
use crate::lang::ops::StrOp;
use crate::value::{Pointer, Scalar, Space};
use std::fmt::Write as _;

/// The most code units a WSTRING holds (as a STRING, at most 255 characters).
const MAX_UNITS: usize = 255;

/// The bytes of the code units of the WSTRING at `p` (2 a unit, without the NUL), borrowed.
fn units<'a>(vars: &'a [u8], frame: &'a [u8], p: Pointer) -> &'a [u8] {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return &[],
    };
    let Some(rest) = buf.get(p.offset as usize..) else { return &[] };
    let rest = &rest[..rest.len().min(2 * MAX_UNITS) & !1];
    let len = rest.chunks_exact(2).position(|u| u == [0, 0]).unwrap_or(rest.len() / 2);
    &rest[..2 * len]
}

/// The code units of `bytes` (as [`units`] gives them), in order.
fn code_units(bytes: &[u8]) -> impl Iterator<Item = u16> + '_ {
    bytes.chunks_exact(2).map(|u| u16::from_le_bytes([u[0], u[1]]))
}

/// Writes the 2-byte NUL after the first `len` units of the WSTRING at `p`.
fn set_len(vars: &mut [u8], frame: &mut [u8], p: Pointer, len: usize) {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return,
    };
    let at = p.offset as usize + 2 * len;
    if let Some(nul) = buf.get_mut(at..at + 2) {
        nul.fill(0);
    }
}

/// Writes units `from .. from + n` of the WSTRING at `src` into the one at `dst` from its unit
/// `at`, by `memmove` (the two may be the same string).
fn put(
    vars: &mut [u8],
    frame: &mut [u8],
    dst: Pointer,
    at: usize,
    src: Pointer,
    from: usize,
    n: usize,
) {
    let (d, s) = (dst.offset as u64 + 2 * at as u64, src.offset as u64 + 2 * from as u64);
    if n == 0 || d > u64::from(u32::MAX) || s > u64::from(u32::MAX) {
        return;
    }
    let d = Pointer { space: dst.space, offset: d as u32 };
    let s = Pointer { space: src.space, offset: s as u32 };
    copy(vars, frame, d, s, 2 * n);
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

/// A count or position operand, as a non-negative length.
fn count(slot: u64) -> usize {
    (slot as i64).clamp(0, MAX_UNITS as i64) as usize
}

/// The Windows-1252 byte of a code unit; `?` for a unit Windows-1252 has no character for (a
/// character outside it, half of a surrogate pair), as CODESYS converts.
fn narrow_unit(unit: u16) -> u8 {
    char::from_u32(u32::from(unit)).and_then(crate::value::encode_char).unwrap_or(b'?')
}

/// The text of a scalar, on the stack (as `typed`'s, for `*_TO_WSTRING`).
struct TextBuf {
    bytes: [u8; 96],
    len: usize,
}

impl std::fmt::Write for TextBuf {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let end = self.len + s.len();
        let room = self.bytes.get_mut(self.len..end).ok_or(std::fmt::Error)?;
        room.copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
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
    let len = |vars: &[u8], frame: &[u8], p| units(vars, frame, p).len() / 2;
    match op {
        StrOp::Move => {
            let (src, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let n = len(vars, frame, src).min(cap);
            put(vars, frame, dst, 0, src, 0, n);
            set_len(vars, frame, dst, n);
        }
        StrOp::Len => {
            let s = ptr(stack.pop());
            stack.push(len(vars, frame, s) as u64);
        }
        StrOp::Left | StrOp::Right => {
            let n = count(stack.pop());
            let (s, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let l = len(vars, frame, s);
            let k = n.min(l);
            let from = if op == StrOp::Left { 0 } else { l - k };
            let k = k.min(cap);
            put(vars, frame, dst, 0, s, from, k);
            set_len(vars, frame, dst, k);
        }
        StrOp::Mid => {
            let p = (stack.pop() as i64).clamp(1, MAX_UNITS as i64 + 1) as usize;
            let n = count(stack.pop());
            let (s, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let l = len(vars, frame, s);
            let from = (p - 1).min(l);
            let k = n.min(l - from).min(cap);
            put(vars, frame, dst, 0, s, from, k);
            set_len(vars, frame, dst, k);
        }
        StrOp::Concat => {
            let (b, a, dst) = (ptr(stack.pop()), ptr(stack.pop()), ptr(stack.pop()));
            let la = len(vars, frame, a).min(cap);
            let lb = len(vars, frame, b).min(cap - la);
            // `b` first when it is the destination itself: writing `a` first would overwrite it.
            if b == dst {
                put(vars, frame, dst, la, b, 0, lb);
                put(vars, frame, dst, 0, a, 0, la);
            } else {
                put(vars, frame, dst, 0, a, 0, la);
                put(vars, frame, dst, la, b, 0, lb);
            }
            set_len(vars, frame, dst, la + lb);
        }
        StrOp::Find => {
            let (b, a) = (ptr(stack.pop()), ptr(stack.pop()));
            let (a, b) = (units(vars, frame, a), units(vars, frame, b));
            // whole units only: a match at an odd byte offset would straddle two characters
            let at = match b.len() {
                0 => 0,
                n => a.windows(n).step_by(2).position(|w| w == b).map_or(0, |i| i + 1),
            };
            stack.push(at as u64);
        }
        StrOp::Compare => {
            let (b, a) = (ptr(stack.pop()), ptr(stack.pop()));
            // by code unit value: bytes are little-endian, so comparing them would misorder
            let order = code_units(units(vars, frame, a)).cmp(code_units(units(vars, frame, b)));
            stack.push(order as i8 as i64 as u64);
        }
        StrOp::FromValue(scalar) => {
            let (v, dst) = (stack.pop(), ptr(stack.pop()));
            let mut text = TextBuf { bytes: [0; 96], len: 0 };
            // The longest text of a scalar is far below the buffer's size: writing cannot fail.
            let _ = match scalar {
                Scalar::Bool => text.write_str(if v != 0 { "TRUE" } else { "FALSE" }),
                _ => crate::value::write_scalar(&mut text, scalar, v),
            };
            // the text of a number is ASCII: each byte is its code unit
            let n = text.len.min(cap);
            write_units(vars, frame, dst, n, |i| u16::from(text.bytes[i]));
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
            let chars = super::typed::string_bytes(vars, frame, src);
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
