//! The typed stack machine of Structured Text, and of the instruction list's double-word and
//! real instructions: the memory spaces a typed value lives in, loaded and stored by
//! [`Pointer`], the evaluation stack, and the string operations.
//!
//! Every access is checked and none panics: a pointer outside its space, into the discard
//! space or of a garbage slot loads 0 and stores nothing; the evaluation stack is a ring of
//! [`EVAL_DEPTH`] slots, so a program that pops more than it pushed reads stale slots instead
//! of failing (the compiler checks every expression's depth, so a checked program never does).
//! Nothing here allocates.

use crate::device::{BitRef, Memory, WordRef};
use crate::lang::ops::{Place, StrOp};
use crate::lang::EVAL_DEPTH;
use crate::value::{normalize, Elem, Pointer, Scalar, Space};
use std::fmt::Write as _;

const _: () = assert!(EVAL_DEPTH.is_power_of_two(), "the evaluation stack is a masked ring");
const MASK: usize = EVAL_DEPTH - 1;

/// An activation's evaluation stack: a ring of slots and the index of the next free one.
#[derive(Debug, Clone)]
pub(super) struct EvalStack {
    slots: [u64; EVAL_DEPTH],
    sp: usize,
}

impl EvalStack {
    pub(super) const fn new() -> EvalStack {
        EvalStack { slots: [0; EVAL_DEPTH], sp: 0 }
    }

    pub(super) fn clear(&mut self) {
        self.sp = 0;
    }

    /// Slots pushed and not popped (modulo the ring).
    pub(super) fn depth(&self) -> usize {
        self.sp
    }

    #[inline(always)]
    pub(super) fn push(&mut self, value: u64) {
        self.slots[self.sp & MASK] = value;
        self.sp = (self.sp + 1) & MASK;
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> u64 {
        self.sp = self.sp.wrapping_sub(1) & MASK;
        self.slots[self.sp]
    }

    #[inline(always)]
    pub(super) fn top(&self) -> u64 {
        self.slots[self.sp.wrapping_sub(1) & MASK]
    }

    #[inline(always)]
    pub(super) fn set_top(&mut self, value: u64) {
        self.slots[self.sp.wrapping_sub(1) & MASK] = value;
    }
}

/// The pointer to a [`Place`] in the current activation (`base`: its frame's start, `this`: its
/// FB instance).
#[inline(always)]
pub(super) fn pointer(at: Place, base: u32, this: u64) -> Pointer {
    match at {
        Place::Var(offset) => Pointer { space: Space::Var, offset },
        Place::Frame(offset) => Pointer { space: Space::Frame, offset: base.wrapping_add(offset) },
        Place::This(offset) => moved(Pointer::from_slot(this), offset),
        Place::Word(w) => Pointer { space: Space::Word, offset: u32::from(w.0) },
        Place::Bit(b) => bit_pointer(b),
    }
}

/// A bit device as a pointer into [`Space::Bit`]: `word * 16 + bit` (the lowest bit of a mask
/// that is not a single bit).
pub(super) fn bit_pointer(b: BitRef) -> Pointer {
    let bit = b.mask.trailing_zeros().min(15);
    Pointer { space: Space::Bit, offset: u32::from(b.word) * 16 + bit }
}

/// `p` moved by `n` units of its space.
#[inline(always)]
pub(super) fn moved(p: Pointer, n: u32) -> Pointer {
    Pointer { space: p.space, offset: p.offset.wrapping_add(n) }
}

/// The bytes of a value in a byte space, if they are all inside it.
#[inline(always)]
fn bytes(buf: &[u8], offset: u32, size: usize) -> Option<&[u8]> {
    let start = offset as usize;
    buf.get(start..start + size)
}

/// Loads the value of `elem` at `p`: little-endian bytes in variable memory and the frame,
/// words low word first in device memory (an 8-bit value in the low byte of its word), a bit.
#[inline(never)]
pub(super) fn load(mem: &Memory, vars: &[u8], frame: &[u8], p: Pointer, elem: Elem) -> u64 {
    let raw = match p.space {
        Space::Var | Space::Frame => {
            let buf = if p.space == Space::Var { vars } else { frame };
            let size = elem.size() as usize;
            match bytes(buf, p.offset, size) {
                Some(b) => {
                    let mut le = [0u8; 8];
                    le[..size].copy_from_slice(b);
                    u64::from_le_bytes(le)
                }
                None => 0,
            }
        }
        Space::Word => {
            let words = mem.words();
            let start = p.offset as usize;
            match words.get(start..start + elem.words() as usize) {
                Some(ws) => ws.iter().rev().fold(0u64, |raw, &w| raw << 16 | u64::from(w)),
                None => 0,
            }
        }
        Space::Bit => {
            let word = mem.words().get((p.offset / 16) as usize).copied().unwrap_or(0);
            u64::from(word >> (p.offset % 16) & 1)
        }
        Space::Discard => 0,
    };
    normalize(elem, raw)
}

/// Stores `value` (a slot of `elem`) at `p`; see [`load`]. An 8-bit value at a word device
/// writes the whole word, the value sign- or zero-extended to 16 bits.
#[inline(never)]
pub(super) fn store(
    mem: &mut Memory,
    vars: &mut [u8],
    frame: &mut [u8],
    p: Pointer,
    elem: Elem,
    value: u64,
) {
    // A BOOL is 0 or 1 in memory whatever the slot held.
    let value = if elem == Elem::Bool { u64::from(value != 0) } else { value };
    match p.space {
        Space::Var | Space::Frame => {
            let buf = if p.space == Space::Var { vars } else { frame };
            let size = elem.size() as usize;
            let start = p.offset as usize;
            if let Some(b) = buf.get_mut(start..start + size) {
                b.copy_from_slice(&value.to_le_bytes()[..size]);
            }
        }
        Space::Word => {
            let n = elem.words();
            let end = u64::from(p.offset) + u64::from(n);
            if end <= mem.words().len() as u64 {
                for i in 0..n {
                    mem.set_word(WordRef((p.offset + i) as u16), (value >> (16 * i)) as u16);
                }
            }
        }
        Space::Bit => {
            let word = p.offset / 16;
            if (word as usize) < mem.words().len() {
                let bit = BitRef { word: word as u16, mask: 1 << (p.offset % 16) };
                mem.set_bit(bit, value != 0);
            }
        }
        Space::Discard => {}
    }
}

/// Copies `n` bytes from `src` to `dst` (variable memory or the frame; overlapping ranges as by
/// `memmove`); nothing when either range is not wholly inside its space.
pub(super) fn copy(vars: &mut [u8], frame: &mut [u8], dst: Pointer, src: Pointer, n: usize) {
    let (d, s) = (dst.offset as usize, src.offset as usize);
    match (dst.space, src.space) {
        (Space::Var, Space::Var) => within(vars, d, s, n),
        (Space::Frame, Space::Frame) => within(frame, d, s, n),
        (Space::Var, Space::Frame) => across(vars, d, frame, s, n),
        (Space::Frame, Space::Var) => across(frame, d, vars, s, n),
        _ => {}
    }
}

fn within(buf: &mut [u8], d: usize, s: usize, n: usize) {
    if s + n <= buf.len() && d + n <= buf.len() {
        buf.copy_within(s..s + n, d);
    }
}

fn across(to: &mut [u8], d: usize, from: &[u8], s: usize, n: usize) {
    if let (Some(to), Some(from)) = (to.get_mut(d..d + n), from.get(s..s + n)) {
        to.copy_from_slice(from);
    }
}

/// The characters of the string at `p` (its length byte, cut to the bytes there are); empty
/// outside variable memory and the frame.
fn chars<'a>(vars: &'a [u8], frame: &'a [u8], p: Pointer) -> &'a [u8] {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return &[],
    };
    let start = p.offset as usize;
    let Some(&len) = buf.get(start) else { return &[] };
    let end = (start + 1 + len as usize).min(buf.len());
    &buf[start + 1..end]
}

fn set_len(vars: &mut [u8], frame: &mut [u8], p: Pointer, len: usize) {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return,
    };
    if let Some(b) = buf.get_mut(p.offset as usize) {
        *b = len as u8;
    }
}

/// Writes characters `from .. from + n` of the string at `src` into the string at `dst` from
/// its character `at`, by `memmove` (the two may be the same string).
fn put(
    vars: &mut [u8],
    frame: &mut [u8],
    dst: Pointer,
    at: usize,
    src: Pointer,
    from: usize,
    n: usize,
) {
    if n == 0 {
        return;
    }
    let d = Pointer { space: dst.space, offset: (dst.offset as usize + 1 + at) as u32 };
    let s = Pointer { space: src.space, offset: (src.offset as usize + 1 + from) as u32 };
    if (dst.offset as usize + 1 + at) as u64 <= u64::from(u32::MAX)
        && (src.offset as usize + 1 + from) as u64 <= u64::from(u32::MAX)
    {
        copy(vars, frame, d, s, n);
    }
}

/// A count or position operand of a string operation, as a non-negative length.
fn count(slot: u64) -> usize {
    (slot as i64).clamp(0, 255) as usize
}

/// Executes a string operation on the stack; `cap` is the destination's capacity.
#[inline(never)]
pub(super) fn string_op(
    stack: &mut EvalStack,
    vars: &mut [u8],
    frame: &mut [u8],
    op: StrOp,
    cap: u16,
) {
    let cap = usize::from(cap).min(255);
    let ptr = |slot: u64| Pointer::from_slot(slot);
    match op {
        StrOp::Move => {
            let (src, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let n = chars(vars, frame, src).len().min(cap);
            put(vars, frame, dst, 0, src, 0, n);
            set_len(vars, frame, dst, n);
        }
        StrOp::Len => {
            let s = ptr(stack.pop());
            stack.push(chars(vars, frame, s).len() as u64);
        }
        StrOp::Left | StrOp::Right => {
            let n = count(stack.pop());
            let (s, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let len = chars(vars, frame, s).len();
            let k = n.min(len);
            let from = if op == StrOp::Left { 0 } else { len - k };
            let k = k.min(cap);
            put(vars, frame, dst, 0, s, from, k);
            set_len(vars, frame, dst, k);
        }
        StrOp::Mid => {
            let p = (stack.pop() as i64).clamp(1, 256) as usize;
            let n = count(stack.pop());
            let (s, dst) = (ptr(stack.pop()), ptr(stack.pop()));
            let len = chars(vars, frame, s).len();
            let from = (p - 1).min(len);
            let k = n.min(len - from).min(cap);
            put(vars, frame, dst, 0, s, from, k);
            set_len(vars, frame, dst, k);
        }
        StrOp::Concat => {
            let (b, a, dst) = (ptr(stack.pop()), ptr(stack.pop()), ptr(stack.pop()));
            let la = chars(vars, frame, a).len().min(cap);
            let lb = chars(vars, frame, b).len().min(cap - la);
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
            let (a, b) = (chars(vars, frame, a), chars(vars, frame, b));
            let at = match b.len() {
                0 => 0,
                n => a.windows(n).position(|w| w == b).map_or(0, |i| i + 1),
            };
            stack.push(at as u64);
        }
        StrOp::Compare => {
            let (b, a) = (ptr(stack.pop()), ptr(stack.pop()));
            let order = chars(vars, frame, a).cmp(chars(vars, frame, b));
            stack.push(order as i8 as i64 as u64);
        }
        StrOp::FromValue(scalar) => {
            let (v, dst) = (stack.pop(), ptr(stack.pop()));
            let mut text = TextBuf::default();
            // The longest text of a scalar (a TIME, an LREAL) is far below the buffer's size:
            // writing cannot fail.
            let _ = match scalar {
                Scalar::Bool => text.write_str(if v != 0 { "TRUE" } else { "FALSE" }),
                _ => crate::value::write_scalar(&mut text, scalar, v),
            };
            write_chars(vars, frame, dst, &text.bytes[..text.len.min(cap)]);
        }
        StrOp::ToValue(scalar) => {
            let s = ptr(stack.pop());
            let text = std::str::from_utf8(chars(vars, frame, s)).unwrap_or("");
            stack.push(crate::value::scalar_from_text(scalar, text).unwrap_or(0));
        }
    }
}

/// The text of a scalar value, on the stack: a `*_TO_STRING` conversion allocates nothing.
struct TextBuf {
    bytes: [u8; 96],
    len: usize,
}

impl Default for TextBuf {
    fn default() -> Self {
        TextBuf { bytes: [0; 96], len: 0 }
    }
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

/// Writes `text` as the whole string at `p` (the caller cut it to the capacity).
fn write_chars(vars: &mut [u8], frame: &mut [u8], p: Pointer, text: &[u8]) {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return,
    };
    let start = p.offset as usize;
    if let Some(room) = buf.get_mut(start + 1..start + 1 + text.len()) {
        room.copy_from_slice(text);
        buf[start] = text.len() as u8;
    }
}

/// The text of the string at `p` (variable memory only, for tools).
pub(super) fn string_text(vars: &[u8], p: Pointer) -> Vec<u8> {
    chars(vars, &[], p).to_vec()
}

/// The characters of the string at `p` in variable memory, borrowed.
pub(super) fn string_chars(vars: &[u8], p: Pointer) -> &[u8] {
    chars(vars, &[], p)
}

/// Writes `text` (cut to `cap`) as the string at `p` in variable memory, for tools.
pub(super) fn write_string_bytes(vars: &mut [u8], p: Pointer, cap: u32, text: &[u8]) {
    if p.space != Space::Var {
        return;
    }
    let n = text.len().min(cap as usize).min(255);
    let start = p.offset as usize;
    if let Some(b) = vars.get_mut(start..start + 1 + n) {
        b[0] = n as u8;
        b[1..].copy_from_slice(&text[..n]);
    }
}
