//! The typed stack machine of Structured Text, and of the instruction list's double-word and
//! real instructions: the memory spaces a typed value lives in, loaded and stored by
//! [`Pointer`], the evaluation stack, and the string operations.
//!
//! Every access is checked and none panics: a pointer outside its space, into the discard
//! space or of a garbage slot loads 0 and stores nothing; the evaluation stack is a ring of
//! [`EVAL_DEPTH`] slots, so a program that pops more than it pushed reads stale slots instead
//! of failing (the compiler checks every expression's depth, so a checked program never does).
//! Nothing here allocates.

use crate::device::{BitRef, Memory};
use crate::lang::ops::{Place, StrOp};
use crate::lang::EVAL_DEPTH;
use crate::value::{self, normalize, BinOp, Elem, OpError, Pointer, Scalar, Space, UnOp};
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

    /// The slots, for native code (which indexes them modulo [`EVAL_DEPTH`] itself).
    pub(super) fn slots_mut(&mut self) -> &mut [u64; EVAL_DEPTH] {
        &mut self.slots
    }

    /// The slots pushed and not popped, bottom first (an activation's stack starts at slot 0).
    pub(super) fn live(&self) -> &[u64] {
        &self.slots[..self.sp]
    }

    pub(super) fn clear(&mut self) {
        self.sp = 0;
    }

    /// Slots pushed and not popped (modulo the ring).
    pub(super) fn depth(&self) -> usize {
        self.sp
    }

    /// The index of the next free slot, for a loop that keeps it in a register and passes it
    /// to the `_at` methods; [`EvalStack::set_sp`] puts it back.
    pub(super) fn sp(&self) -> usize {
        self.sp
    }

    pub(super) fn set_sp(&mut self, sp: usize) {
        self.sp = sp & MASK;
    }

    #[inline(always)]
    pub(super) fn push_at(&mut self, sp: &mut usize, value: u64) {
        self.slots[*sp & MASK] = value;
        *sp = (*sp + 1) & MASK;
    }

    #[inline(always)]
    pub(super) fn pop_at(&self, sp: &mut usize) -> u64 {
        *sp = sp.wrapping_sub(1) & MASK;
        self.slots[*sp]
    }

    #[inline(always)]
    pub(super) fn top_at(&self, sp: usize) -> u64 {
        self.slots[sp.wrapping_sub(1) & MASK]
    }

    #[inline(always)]
    pub(super) fn set_top_at(&mut self, sp: usize, value: u64) {
        self.slots[sp.wrapping_sub(1) & MASK] = value;
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
        Place::Byte(n) => Pointer { space: Space::Byte, offset: n },
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

/// Whether `size` bytes at `p` (one scalar's words at a word device, one bit at a bit
/// device, one byte at a device byte) are inside its memory area: variable memory (`vars`
/// bytes), the frame area (`frame` bytes), device memory (`words` words).
pub(super) fn reaches(p: Pointer, size: u32, words: usize, vars: usize, frame: usize) -> bool {
    let offset = u64::from(p.offset);
    match p.space {
        Space::Var => offset + u64::from(size) <= vars as u64,
        Space::Frame => offset + u64::from(size) <= frame as u64,
        Space::Word => offset + u64::from(size.div_ceil(2).max(1)) <= words as u64,
        Space::Bit => offset / 16 < words as u64,
        Space::Byte => offset / 2 < words as u64,
        Space::Discard => false,
    }
}

/// The pointer a reference value holds, checked as `Op::Deref { size }` says.
pub(super) fn deref(
    reference: u64,
    size: u32,
    words: usize,
    vars: usize,
    frame: usize,
) -> Result<Pointer, u16> {
    let Some(p) = Pointer::from_reference(reference) else {
        return Err(super::ERR_REF_NULL);
    };
    let device = matches!(p.space, Space::Word | Space::Bit | Space::Byte);
    let ok = if size == 0 {
        !device && reaches(p, 0, words, vars, frame)
    } else {
        reaches(p, size, words, vars, frame)
    };
    if ok {
        Ok(p)
    } else {
        Err(super::ERR_REF_RANGE)
    }
}

/// The reference value `reference` moved by `n` bytes (`Op::RefAdd`).
pub(super) fn ref_add(reference: u64, n: u64) -> Result<u64, u16> {
    let space = Pointer::from_reference(reference).map(|p| p.space);
    if matches!(space, Some(Space::Word | Space::Bit | Space::Byte)) {
        return Err(super::ERR_REF_RANGE);
    }
    let offset = (reference as u32).wrapping_add(n as u32);
    Ok(reference >> 32 << 32 | u64::from(offset))
}

/// `a - b` for two reference values (`Op::RefDiff`): the `DINT` slot of the distance in bytes,
/// when both point into one memory area.
pub(super) fn ref_diff(a: u64, b: u64) -> Option<u64> {
    let (pa, pb) = (Pointer::from_reference(a)?, Pointer::from_reference(b)?);
    if pa.space != pb.space || pa.space == Space::Discard {
        return None;
    }
    let distance = i64::from(pa.offset) - i64::from(pb.offset);
    Some(distance as i32 as i64 as u64)
}

/// The `N` bytes at `at` of `buf`, if they are all inside it.
#[inline(always)]
fn le<const N: usize>(buf: &[u8], at: usize) -> Option<[u8; N]> {
    buf.get(at..at.checked_add(N)?).map(|b| b.try_into().unwrap_or([0; N]))
}

/// Loads the value of `elem` from the little-endian bytes at `offset` of `buf` (variable
/// memory or the frame), as a slot; 0 when they are not all inside it. One fixed-size read for
/// each type: this is the loop's own path for every load from a byte space.
#[inline(always)]
pub(super) fn load_bytes(buf: &[u8], offset: u32, elem: Elem) -> u64 {
    let at = offset as usize;
    // `as u64` from a signed type sign-extends, from an unsigned one zero-extends: the slot.
    match elem {
        Elem::Bool => le::<1>(buf, at).map_or(0, |b| u64::from(b[0] != 0)),
        Elem::I8 => le::<1>(buf, at).map_or(0, |b| b[0] as i8 as u64),
        Elem::U8 => le::<1>(buf, at).map_or(0, |b| u64::from(b[0])),
        Elem::I16 => le(buf, at).map_or(0, |b| i16::from_le_bytes(b) as u64),
        Elem::U16 => le(buf, at).map_or(0, |b| u64::from(u16::from_le_bytes(b))),
        Elem::I32 => le(buf, at).map_or(0, |b| i32::from_le_bytes(b) as u64),
        Elem::U32 | Elem::F32 => le(buf, at).map_or(0, |b| u64::from(u32::from_le_bytes(b))),
        Elem::I64 | Elem::U64 | Elem::F64 => le(buf, at).map_or(0, u64::from_le_bytes),
    }
}

/// Stores the slot `value` of `elem` as little-endian bytes at `offset` of `buf`; nothing when
/// they are not all inside it. A BOOL is 0 or 1 in memory whatever the slot held.
#[inline(always)]
pub(super) fn store_bytes(buf: &mut [u8], offset: u32, elem: Elem, value: u64) {
    fn put<const N: usize>(buf: &mut [u8], at: usize, bytes: [u8; N]) {
        if let Some(b) = at.checked_add(N).and_then(|end| buf.get_mut(at..end)) {
            b.copy_from_slice(&bytes);
        }
    }
    let at = offset as usize;
    match elem {
        Elem::Bool => put(buf, at, [u8::from(value != 0)]),
        Elem::I8 | Elem::U8 => put(buf, at, [value as u8]),
        Elem::I16 | Elem::U16 => put(buf, at, (value as u16).to_le_bytes()),
        Elem::I32 | Elem::U32 | Elem::F32 => put(buf, at, (value as u32).to_le_bytes()),
        Elem::I64 | Elem::U64 | Elem::F64 => put(buf, at, value.to_le_bytes()),
    }
}

/// [`load`] of the value at `at` in the current activation, with the byte spaces inline.
#[inline(always)]
pub(super) fn load_place(
    mem: &Memory,
    vars: &[u8],
    frame: &[u8],
    at: Place,
    base: u32,
    this: u64,
    elem: Elem,
) -> u64 {
    match at {
        Place::Var(offset) => load_bytes(vars, offset, elem),
        Place::Frame(offset) => load_bytes(frame, base.wrapping_add(offset), elem),
        _ => load_at(mem, vars, frame, pointer(at, base, this), elem),
    }
}

/// [`store`] at `at` in the current activation, with the byte spaces inline.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn store_place(
    mem: &mut Memory,
    vars: &mut [u8],
    frame: &mut [u8],
    at: Place,
    base: u32,
    this: u64,
    elem: Elem,
    value: u64,
) {
    match at {
        Place::Var(offset) => store_bytes(vars, offset, elem, value),
        Place::Frame(offset) => store_bytes(frame, base.wrapping_add(offset), elem, value),
        _ => store_at(mem, vars, frame, pointer(at, base, this), elem, value),
    }
}

/// [`load`], with the byte spaces inline.
#[inline(always)]
pub(super) fn load_at(mem: &Memory, vars: &[u8], frame: &[u8], p: Pointer, elem: Elem) -> u64 {
    match p.space {
        Space::Var => load_bytes(vars, p.offset, elem),
        Space::Frame => load_bytes(frame, p.offset, elem),
        _ => load(mem.words(), vars, frame, p, elem),
    }
}

/// [`store`], with the byte spaces inline.
#[inline(always)]
pub(super) fn store_at(
    mem: &mut Memory,
    vars: &mut [u8],
    frame: &mut [u8],
    p: Pointer,
    elem: Elem,
    value: u64,
) {
    match p.space {
        Space::Var => store_bytes(vars, p.offset, elem, value),
        Space::Frame => store_bytes(frame, p.offset, elem, value),
        _ => store(mem.words_mut(), vars, frame, p, elem, value),
    }
}

/// Loads the value of `elem` at `p`: little-endian bytes in variable memory and the frame,
/// words low word first in device memory (`words`; an 8-bit value in the low byte of its
/// word), a bit, a device byte (a half of its word).
///
/// Device memory comes as its words, never as `&mut Memory`: the interpreter keeps the words'
/// address and length in registers only while nothing it calls out of line could move them.
#[inline(never)]
pub(super) fn load(words: &[u16], vars: &[u8], frame: &[u8], p: Pointer, elem: Elem) -> u64 {
    match p.space {
        Space::Var => load_bytes(vars, p.offset, elem),
        Space::Frame => load_bytes(frame, p.offset, elem),
        Space::Word => {
            let start = p.offset as usize;
            let raw = match words.get(start..start + elem.words() as usize) {
                Some(ws) => ws.iter().rev().fold(0u64, |raw, &w| raw << 16 | u64::from(w)),
                None => 0,
            };
            normalize(elem, raw)
        }
        Space::Bit => {
            let word = words.get((p.offset / 16) as usize).copied().unwrap_or(0);
            normalize(elem, u64::from(word >> (p.offset % 16) & 1))
        }
        Space::Byte => {
            let word = words.get((p.offset / 2) as usize).copied().unwrap_or(0);
            normalize(elem, u64::from(word >> (8 * (p.offset % 2)) & 0xFF))
        }
        Space::Discard => 0,
    }
}

/// Stores `value` (a slot of `elem`) at `p`; see [`load`]. An 8-bit value at a word device
/// writes the whole word, the value sign- or zero-extended to 16 bits; at a device byte, its
/// low 8 bits into that half of the word, the other half kept.
#[inline(never)]
pub(super) fn store(
    words: &mut [u16],
    vars: &mut [u8],
    frame: &mut [u8],
    p: Pointer,
    elem: Elem,
    value: u64,
) {
    match p.space {
        Space::Var => store_bytes(vars, p.offset, elem, value),
        Space::Frame => store_bytes(frame, p.offset, elem, value),
        Space::Word => {
            // A BOOL is 0 or 1 whatever the slot held.
            let value = if elem == Elem::Bool { u64::from(value != 0) } else { value };
            let n = elem.words();
            let end = u64::from(p.offset) + u64::from(n);
            if end <= words.len() as u64 {
                for i in 0..n {
                    words[(p.offset + i) as usize] = (value >> (16 * i)) as u16;
                }
            }
        }
        Space::Bit => {
            if let Some(word) = words.get_mut((p.offset / 16) as usize) {
                let mask = 1u16 << (p.offset % 16);
                *word = if value != 0 { *word | mask } else { *word & !mask };
            }
        }
        Space::Byte => {
            if let Some(word) = words.get_mut((p.offset / 2) as usize) {
                let shift = 8 * (p.offset % 2);
                let byte = (value as u16 & 0xFF) << shift;
                *word = *word & !(0xFF << shift) | byte;
            }
        }
        Space::Discard => {}
    }
}

/// `raw` cut to the width of `elem` and extended, as `value` wraps an operation's result (a
/// `Bool` keeps bit 0: a 1-bit unsigned integer).
#[inline(always)]
fn wrapped(elem: Elem, raw: u64) -> u64 {
    if elem == Elem::Bool {
        raw & 1
    } else {
        normalize(elem, raw)
    }
}

/// [`value::binary`] with its commonest operations inline: integer `+ - * / MOD` and the
/// bitwise and logical operations, REAL and LREAL `+ - *`; the others through it. The results are
/// `value::binary`'s to the bit (tested below).
#[inline(always)]
pub(super) fn binary(op: BinOp, elem: Elem, a: u64, b: u64) -> Result<u64, OpError> {
    macro_rules! float {
        ($t:ty, $bits:ty) => {{
            let (x, y) = (<$t>::from_bits(a as $bits), <$t>::from_bits(b as $bits));
            let r = match op {
                BinOp::Add => x + y,
                BinOp::Sub => x - y,
                BinOp::Mul => x * y,
                _ => return value::binary(op, elem, a, b),
            };
            Ok(u64::from(r.to_bits()))
        }};
    }
    match elem {
        Elem::F32 => float!(f32, u32),
        Elem::F64 => float!(f64, u64),
        _ => {
            let r = match op {
                BinOp::Add => a.wrapping_add(b),
                BinOp::Sub => a.wrapping_sub(b),
                BinOp::Mul => a.wrapping_mul(b),
                BinOp::Div | BinOp::Mod if wrapped(elem, b) == 0 => {
                    return Err(OpError::DivideByZero)
                }
                BinOp::Div if elem.is_signed() => (a as i64).wrapping_div(b as i64) as u64,
                BinOp::Div => a / b,
                BinOp::Mod if elem.is_signed() => (a as i64).wrapping_rem(b as i64) as u64,
                BinOp::Mod => a % b,
                BinOp::And => a & b,
                BinOp::Or => a | b,
                BinOp::Xor => a ^ b,
                _ => return value::binary(op, elem, a, b),
            };
            Ok(wrapped(elem, r))
        }
    }
}

/// [`value::unary`] with the integer and logical `NOT` and the integer negation inline.
#[inline(always)]
pub(super) fn unary(op: UnOp, elem: Elem, a: u64) -> u64 {
    match (op, elem) {
        (_, Elem::F32 | Elem::F64) => value::unary(op, elem, a),
        (UnOp::Not, _) => wrapped(elem, !a),
        (UnOp::Neg, _) => wrapped(elem, a.wrapping_neg()),
        _ => value::unary(op, elem, a),
    }
}

/// [`value::convert`] with the integer-to-integer conversions inline (they wrap).
#[inline(always)]
pub(super) fn convert(from: Elem, to: Elem, a: u64) -> u64 {
    if from.is_float() || to.is_float() || to == Elem::Bool {
        value::convert(from, to, a)
    } else {
        normalize(to, a)
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

/// The characters of the string at `p`: up to its first NUL, as CODESYS and TwinCAT store a
/// STRING (so that code walking it through a pointer finds its characters where they expect),
/// at most 255 and cut to the bytes there are; empty outside variable memory and the frame.
fn chars<'a>(vars: &'a [u8], frame: &'a [u8], p: Pointer) -> &'a [u8] {
    units(vars, frame, p, 1)
}

/// The most characters a STRING holds, and code units a WSTRING holds.
pub(super) const MAX_CHARS: usize = 255;

/// The bytes of the characters of a string of `width`-byte units (1: a STRING, 2: a
/// WSTRING's UTF-16 code units) at `p`, up to its first NUL unit: at most [`MAX_CHARS`] units,
/// cut to the whole units there are; empty outside variable memory and the frame.
pub(super) fn units<'a>(vars: &'a [u8], frame: &'a [u8], p: Pointer, width: usize) -> &'a [u8] {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return &[],
    };
    let Some(rest) = buf.get(p.offset as usize..) else { return &[] };
    let whole = rest.len().min(width * MAX_CHARS) / width;
    let len = rest.chunks_exact(width).take(whole).position(|u| u.iter().all(|&b| b == 0));
    &rest[..width * len.unwrap_or(whole)]
}

/// Writes the NUL unit after the first `len` units of the string of `width`-byte units at `p`
/// (a `STRING[n]` or `WSTRING[n]` has room for it after n of them).
fn set_len(vars: &mut [u8], frame: &mut [u8], p: Pointer, len: usize, width: usize) {
    let buf = match p.space {
        Space::Var => vars,
        Space::Frame => frame,
        _ => return,
    };
    let at = p.offset as usize + width * len;
    if let Some(nul) = buf.get_mut(at..at + width) {
        nul.fill(0);
    }
}

/// Writes units `from .. from + n` of the string at `src` into the string at `dst` from its
/// unit `at`, units of `width` bytes, by `memmove` (the two may be the same string).
#[allow(clippy::too_many_arguments)]
fn put(
    vars: &mut [u8],
    frame: &mut [u8],
    dst: Pointer,
    at: usize,
    src: Pointer,
    from: usize,
    n: usize,
    width: usize,
) {
    let d = dst.offset as u64 + (width * at) as u64;
    let s = src.offset as u64 + (width * from) as u64;
    if n == 0 || d > u64::from(u32::MAX) || s > u64::from(u32::MAX) {
        return;
    }
    let d = Pointer { space: dst.space, offset: d as u32 };
    let s = Pointer { space: src.space, offset: s as u32 };
    copy(vars, frame, d, s, width * n);
}

/// A count or position operand of a string operation, as a non-negative length.
fn count(slot: u64) -> usize {
    (slot as i64).clamp(0, MAX_CHARS as i64) as usize
}

/// The values of the units of `bytes` (as [`units`] gives them), in order: a STRING's bytes, a
/// WSTRING's code units (little-endian).
fn unit_values(bytes: &[u8], width: usize) -> impl Iterator<Item = u16> + '_ {
    bytes.chunks_exact(width).map(|u| match *u {
        [b] => u16::from(b),
        [lo, hi, ..] => u16::from_le_bytes([lo, hi]),
        [] => 0,
    })
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
    let cap = usize::from(cap).min(MAX_CHARS);
    let ptr = |slot: u64| Pointer::from_slot(slot);
    match op {
        StrOp::FromValue(scalar) => {
            let (v, dst) = (stack.pop(), ptr(stack.pop()));
            let text = scalar_text(scalar, v);
            write_chars(vars, frame, dst, &text[..text.len().min(cap)]);
        }
        StrOp::ToValue(scalar) => {
            let s = ptr(stack.pop());
            let text = std::str::from_utf8(chars(vars, frame, s)).unwrap_or("");
            stack.push(crate::value::scalar_from_text(scalar, text).unwrap_or(0));
        }
        // conversions to and from WSTRING: the wide operations' module owns them
        StrOp::Widen | StrOp::Narrow => super::wide::string_op(stack, vars, frame, op, cap as u16),
        _ => unit_op(stack, vars, frame, op, cap, 1),
    }
}

/// The operations the same on a STRING and a WSTRING, on units of `width` bytes: positions,
/// counts and lengths in units; `cap` the destination's capacity in units. The conversions
/// to and from values and between the two kinds do nothing here.
pub(super) fn unit_op(
    stack: &mut EvalStack,
    vars: &mut [u8],
    frame: &mut [u8],
    op: StrOp,
    cap: usize,
    width: usize,
) {
    let ptr = |slot: u64| Pointer::from_slot(slot);
    let len = |vars: &[u8], frame: &[u8], p| units(vars, frame, p, width).len() / width;
    let put = |vars: &mut [u8], frame: &mut [u8], dst, at, src, from, n| {
        put(vars, frame, dst, at, src, from, n, width)
    };
    let set_len = |vars: &mut [u8], frame: &mut [u8], p, n| set_len(vars, frame, p, n, width);
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
            let p = (stack.pop() as i64).clamp(1, MAX_CHARS as i64 + 1) as usize;
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
            let (a, b) = (units(vars, frame, a, width), units(vars, frame, b, width));
            // whole units only: a WSTRING's match at an odd byte would straddle two characters
            let at = match b.len() {
                0 => 0,
                n => a.windows(n).step_by(width).position(|w| w == b).map_or(0, |i| i + 1),
            };
            stack.push(at as u64);
        }
        StrOp::Compare => {
            let (b, a) = (ptr(stack.pop()), ptr(stack.pop()));
            // by unit value: a WSTRING's bytes are little-endian, comparing them would misorder
            let (a, b) = (units(vars, frame, a, width), units(vars, frame, b, width));
            let order = unit_values(a, width).cmp(unit_values(b, width));
            stack.push(order as i8 as i64 as u64);
        }
        StrOp::FromValue(_) | StrOp::ToValue(_) | StrOp::Widen | StrOp::Narrow => {}
    }
}

/// The text of a scalar value, on the stack: a `*_TO_STRING` conversion allocates nothing.
struct TextBuf {
    bytes: [u8; 96],
    len: usize,
}

/// The text of `v`, a value of type `scalar`, as `<T>_TO_STRING` writes it (ASCII), on the stack.
pub(super) fn scalar_text(scalar: Scalar, v: u64) -> impl std::ops::Deref<Target = [u8]> {
    let mut text = TextBuf::default();
    // The longest text of a scalar (a TIME, an LREAL) is far below the buffer's size: writing
    // cannot fail.
    let _ = match scalar {
        Scalar::Bool => text.write_str(if v != 0 { "TRUE" } else { "FALSE" }),
        _ => crate::value::write_scalar(&mut text, scalar, v),
    };
    text
}

impl std::ops::Deref for TextBuf {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
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
    if let Some(room) = buf.get_mut(start..start + text.len() + 1) {
        room[..text.len()].copy_from_slice(text);
        room[text.len()] = 0;
    }
}

/// The text of the string at `p` (variable memory only, for tools).
pub(super) fn string_text(vars: &[u8], p: Pointer) -> Vec<u8> {
    chars(vars, &[], p).to_vec()
}

/// The characters of the STRING at `p`, borrowed (for the conversion to WSTRING).
pub(super) fn string_bytes<'a>(vars: &'a [u8], frame: &'a [u8], p: Pointer) -> &'a [u8] {
    chars(vars, frame, p)
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
    if let Some(b) = vars.get_mut(start..start + n + 1) {
        b[..n].copy_from_slice(&text[..n]);
        b[n] = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UN_OPS: [UnOp; 3] = [UnOp::Neg, UnOp::Not, UnOp::Abs];

    fn reference(space: Space, offset: u32) -> u64 {
        Pointer { space, offset }.to_slot() + crate::value::REF_TAG
    }

    #[test]
    fn a_dereference_is_checked_against_its_area() {
        use super::super::{ERR_REF_NULL, ERR_REF_RANGE};
        let (words, vars, frame) = (100, 64, 32);
        let deref = |r, size| deref(r, size, words, vars, frame);
        assert_eq!(deref(0, 2), Err(ERR_REF_NULL));
        // NULL moved stays NULL
        assert_eq!(deref(ref_add(0, 8).unwrap(), 2), Err(ERR_REF_NULL));
        assert_eq!(
            deref(reference(Space::Var, 62), 2),
            Ok(Pointer { space: Space::Var, offset: 62 })
        );
        // crossing the end of the area for the access's width
        assert_eq!(deref(reference(Space::Var, 63), 2), Err(ERR_REF_RANGE));
        assert_eq!(deref(reference(Space::Var, 64), 1), Err(ERR_REF_RANGE));
        assert_eq!(
            deref(reference(Space::Frame, 24), 8),
            Ok(Pointer { space: Space::Frame, offset: 24 })
        );
        assert_eq!(deref(reference(Space::Frame, 25), 8), Err(ERR_REF_RANGE));
        // a path may start at the end of the area; its end is checked by `CheckRef`
        assert!(deref(reference(Space::Var, 64), 0).is_ok());
        assert_eq!(deref(reference(Space::Var, 65), 0), Err(ERR_REF_RANGE));
        // device words: a DINT takes 2 words, an 8-bit value 1
        assert!(deref(reference(Space::Word, 98), 4).is_ok());
        assert_eq!(deref(reference(Space::Word, 99), 4), Err(ERR_REF_RANGE));
        assert!(deref(reference(Space::Word, 99), 1).is_ok());
        assert!(deref(reference(Space::Bit, 1599), 1).is_ok());
        assert_eq!(deref(reference(Space::Bit, 1600), 1), Err(ERR_REF_RANGE));
        assert!(deref(reference(Space::Byte, 199), 1).is_ok());
        assert_eq!(deref(reference(Space::Byte, 200), 1), Err(ERR_REF_RANGE));
        assert_eq!(deref(reference(Space::Byte, 0), 0), Err(ERR_REF_RANGE));
        // no member or element into device memory
        assert_eq!(deref(reference(Space::Word, 0), 0), Err(ERR_REF_RANGE));
        // the discard pointer and garbage spaces go nowhere
        assert_eq!(deref(reference(Space::Discard, 0), 1), Err(ERR_REF_RANGE));
        assert_eq!(deref(7 << 32, 1), Err(ERR_REF_RANGE));
        assert!(reaches(Pointer { space: Space::Var, offset: 60 }, 4, words, vars, frame));
        assert!(!reaches(Pointer { space: Space::Var, offset: 61 }, 4, words, vars, frame));
    }

    #[test]
    fn a_pointer_difference_needs_one_area() {
        let (a, b) = (reference(Space::Var, 10), reference(Space::Var, 16));
        assert_eq!(ref_diff(b, a), Some(6));
        assert_eq!(ref_diff(a, b), Some(-6i64 as u64));
        assert_eq!(ref_diff(a, reference(Space::Frame, 10)), None);
        assert_eq!(ref_diff(a, 0), None);
        assert_eq!(ref_diff(0, 0), None);
        assert_eq!(ref_diff(reference(Space::Word, 3), reference(Space::Word, 1)), Some(2));
        let discard = reference(Space::Discard, 0);
        assert_eq!(ref_diff(discard, discard), None);
    }

    #[test]
    fn pointer_arithmetic_stays_in_its_area() {
        use super::super::ERR_REF_RANGE;
        let r = reference(Space::Var, 10);
        assert_eq!(ref_add(r, 6), Ok(reference(Space::Var, 16)));
        assert_eq!(ref_add(r, (-4i64) as u64), Ok(reference(Space::Var, 6)));
        // below 0 the offset wraps within 32 bits: the same area, far outside it
        assert_eq!(ref_add(r, (-11i64) as u64), Ok(reference(Space::Var, u32::MAX)));
        // however large, n never carries into the area
        assert_eq!(
            ref_add(reference(Space::Frame, 0), u64::from(u32::MAX) + 1),
            Ok(reference(Space::Frame, 0))
        );
        assert_eq!(ref_add(reference(Space::Word, 5), 2), Err(ERR_REF_RANGE));
        assert_eq!(ref_add(reference(Space::Byte, 5), 1), Err(ERR_REF_RANGE));
        assert_eq!(ref_add(reference(Space::Bit, 5), 0), Err(ERR_REF_RANGE));
    }

    /// Slots of every kind: small, extreme, garbage in the high bits, float bit patterns
    /// (NaN, infinities, signed zeros, subnormals).
    fn slots() -> Vec<u64> {
        let mut v = vec![0, 1, 2, 7, u64::MAX, 0x80, 0xFF, 0x8000, 0xFFFF, 0x8000_0000];
        v.extend([0xFFFF_FFFF, 1 << 63, (1 << 63) - 1, 0x1234_5678_9ABC_DEF0]);
        v.extend(
            [-1.5f32, 0.1, -0.0, f32::NAN, f32::INFINITY, f32::MIN_POSITIVE / 2.0]
                .map(|x| u64::from(x.to_bits())),
        );
        v.extend([-1.5f64, 0.1, -0.0, f64::NAN, f64::NEG_INFINITY, 1e300].map(f64::to_bits));
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..40 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            v.push(x);
        }
        v
    }

    #[test]
    fn the_inline_operations_are_value_s_to_the_bit() {
        let slots = slots();
        for elem in Elem::ALL {
            // Slots as the VM holds them: normalized, and raw (a bad program's garbage).
            let values: Vec<u64> = slots.iter().flat_map(|&s| [normalize(elem, s), s]).collect();
            for &a in &values {
                for op in UN_OPS {
                    assert_eq!(
                        unary(op, elem, a),
                        value::unary(op, elem, a),
                        "{op:?} {elem:?} {a:#x}"
                    );
                }
                for to in Elem::ALL {
                    let (fast, slow) = (convert(elem, to, a), value::convert(elem, to, a));
                    assert_eq!(fast, slow, "{elem:?} → {to:?} {a:#x}");
                }
                for &b in &values {
                    for op in BinOp::ALL {
                        let (fast, slow) = (binary(op, elem, a, b), value::binary(op, elem, a, b));
                        assert_eq!(fast, slow, "{op:?} {elem:?} {a:#x} {b:#x}");
                    }
                }
            }
        }
    }

    /// The bytes of a value read as the slot the VM gives it: zero-extended little-endian,
    /// normalized.
    fn reference_load(buf: &[u8], offset: u32, elem: Elem) -> u64 {
        let (start, size) = (offset as usize, elem.size() as usize);
        match buf.get(start..start + size) {
            Some(b) => {
                let mut le = [0u8; 8];
                le[..size].copy_from_slice(b);
                normalize(elem, u64::from_le_bytes(le))
            }
            None => 0,
        }
    }

    #[test]
    fn a_device_byte_is_one_half_of_its_word() {
        let at = |offset| Pointer { space: Space::Byte, offset };
        let mut words = [0x1234u16, 0xABCD];
        let (mut vars, mut frame) = ([0u8; 0], [0u8; 0]);
        // byte 2n is the low half of word n, byte 2n + 1 the high half
        assert_eq!(load(&words, &vars, &frame, at(0), Elem::U8), 0x34);
        assert_eq!(load(&words, &vars, &frame, at(1), Elem::U8), 0x12);
        assert_eq!(load(&words, &vars, &frame, at(3), Elem::U8), 0xAB);
        // a SINT is sign-extended from its byte
        assert_eq!(load(&words, &vars, &frame, at(3), Elem::I8), 0xAB_u8 as i8 as u64);
        // a store writes its half alone, the value cut to 8 bits
        store(&mut words, &mut vars, &mut frame, at(1), Elem::U8, 0x7F);
        assert_eq!(words, [0x7F34, 0xABCD]);
        store(&mut words, &mut vars, &mut frame, at(2), Elem::I8, -1i64 as u64);
        assert_eq!(words, [0x7F34, 0xABFF]);
        store(&mut words, &mut vars, &mut frame, at(0), Elem::U8, 0x1_00);
        assert_eq!(words, [0x7F00, 0xABFF]);
        // outside device memory: 0, and nothing written
        assert_eq!(load(&words, &vars, &frame, at(4), Elem::U8), 0);
        store(&mut words, &mut vars, &mut frame, at(4), Elem::U8, 0xFF);
        store(&mut words, &mut vars, &mut frame, at(u32::MAX), Elem::U8, 0xFF);
        assert_eq!(words, [0x7F00, 0xABFF]);
        assert_eq!(pointer(Place::Byte(7), 0, 0), at(7));
    }

    #[test]
    fn byte_loads_and_stores_keep_the_layout_and_stay_inside() {
        let slots = slots();
        let image: Vec<u8> = (0..24u8).map(|i| i.wrapping_mul(97) ^ 0xA5).collect();
        for elem in Elem::ALL {
            let size = elem.size();
            for offset in [0, 1, 5, 24 - size, 25 - size, 24, u32::MAX - 3, u32::MAX] {
                let got = load_bytes(&image, offset, elem);
                assert_eq!(got, reference_load(&image, offset, elem), "{elem:?} at {offset}");
                for &v in &slots {
                    let mut buf = image.clone();
                    store_bytes(&mut buf, offset, elem, v);
                    let mut want = image.clone();
                    let start = offset as usize;
                    if let Some(b) = want.get_mut(start..start.saturating_add(size as usize)) {
                        let v = if elem == Elem::Bool { u64::from(v != 0) } else { v };
                        b.copy_from_slice(&v.to_le_bytes()[..size as usize]);
                    }
                    assert_eq!(buf, want, "{elem:?} {v:#x} at {offset}");
                    if start + size as usize <= buf.len() {
                        let back = load_bytes(&buf, offset, elem);
                        let v = if elem == Elem::Bool { u64::from(v != 0) } else { v };
                        assert_eq!(back, normalize(elem, v), "{elem:?} {v:#x} back");
                    }
                }
            }
        }
    }
}
