//! The retained Structured Text variables (docs/RETAIN.md): what the retain files store of them,
//! what a copy at a scan boundary takes of variable memory, and which variables of another
//! program are the same variable — the same name (case-insensitive) and the same type — so that
//! a changed program keeps exactly those.
//!
//! A variable is one **record**: an elementary leaf (a [`Symbol`] declared `RETAIN`, or inside a
//! retained instance, in variable memory), or a whole array (a [`crate::symbols::ArraySymbol`]
//! any of whose element's leaves is retained) with its bounds and the layout of its element's
//! retained part, so that a retained array costs its bytes and a few names, not a name per
//! element. A record's bytes in a copy and in the file are *packed*: a leaf's bytes; an array's
//! elements one after the other, each its retained leaves one after the other (an array whose
//! element is retained whole and without gaps, an array of `DINT`, is its memory as it is).

use crate::lang::Variables;
use crate::symbols::{ArraySymbol, Entry};
use crate::value::{Space, Symbol, ValueType};

/// How an array's type text starts (docs/RETAIN.md, "The file").
const ARRAY: &str = "ARRAY[";

/// One retained variable: a leaf, or an array whole; inside an array's element, one part of
/// the element's retained layout (its name, place and position relative to the element).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RetainedRecord {
    /// The full name with the spelling of its declarations: `main.count`, `main.t1.ET`,
    /// `main.buf` (an array, without indices); in an element, relative: `.x`, or `""`.
    pub name: String,
    /// The lowercase name, what matching compares (records of the program only).
    key: String,
    /// The type as [`type_text`] writes it (`DINT`, `STRING[20]`), an array's with its bounds
    /// and its element's layout: `ARRAY[1..10] OF INT`, `ARRAY[0..3] OF {.x@0:INT;.on@2:BOOL;@3}`.
    pub ty: String,
    /// Its byte offset in variable memory (relative to the element in an element). In a
    /// layout read from a file, the same as `pos`.
    pub at: u32,
    /// Its bytes in a copy and in the file: an array's, every element's retained bytes.
    pub len: u32,
    /// Its byte offset in a copy ([`RetainedVariables::copy`]); in an element, in the
    /// element's packed bytes.
    pub pos: u32,
    /// An array's bounds and element layout.
    array: Option<Box<ArrayLayout>>,
}

/// An array record's shape.
#[derive(Debug, Clone, PartialEq, Eq)]
struct ArrayLayout {
    /// `(lo, hi)` of each dimension, as declared.
    dims: Box<[(i64, i64)]>,
    /// Elements, at least one.
    count: u64,
    /// How far apart two elements are in variable memory (a layout read from a file:
    /// `bytes`).
    stride: u32,
    /// The retained parts of one element, in declaration order, packed from 0.
    parts: Box<[RetainedRecord]>,
    /// Packed bytes of one element: the sum of the parts' lengths.
    bytes: u32,
    /// The array's memory is its packed bytes (every element retained whole, without gaps):
    /// copied and compared as one run of bytes.
    dense: bool,
}

/// A program's retained variables, built once per engine (off the real-time path).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RetainedVariables {
    /// In declaration order, placed one after the other in a copy.
    records: Box<[RetainedRecord]>,
    /// Indices of `records`, sorted by key.
    by_key: Box<[u32]>,
    bytes: usize,
}

/// A retained variable as a retain file holds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SavedVariable {
    pub name: String,
    pub ty: String,
    pub bytes: Vec<u8>,
}

/// What a restore from saved variables does: the records it restores (whole, their
/// overlapping elements, or one element from a version 3 element record), the saved variables
/// it drops, the records that keep their initial value.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RestorePlan {
    pub restore: Vec<Restored>,
    /// Saved variables not restored, each with why: `main.old (DINT): not a RETAIN variable of
    /// the program`, `main.x (INT): now DINT`, one line for a whole array.
    pub dropped: Vec<String>,
    /// Names of retained records nothing was saved for (an array once, by its name).
    pub new: Vec<String>,
}

/// One saved variable restored into one record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Restored {
    /// The record's index in [`RetainedVariables::records`].
    pub record: usize,
    /// The saved variable's index.
    pub saved: usize,
    into: Target,
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Target {
    /// A leaf.
    Whole,
    /// An array saved whole: the indices both have, the saved bytes laid out so.
    Overlap(Box<ArrayLayout>),
    /// A version 3 file's record of one element's leaf (`main.buf[3]`), at this place of
    /// variable memory.
    Element(u32),
}

/// The text of a type as the retain files store it: the IEC name of an elementary type (`DINT`,
/// `UDINT`, `LREAL`, `TIME`), `STRING[n]`, an enumeration with its values (`Color(Red:=0,
/// Green:=1)`). Two types with the same text are stored the same way.
pub fn type_text(ty: &ValueType) -> String {
    match ty {
        ValueType::Enum { type_name, values, base } => {
            let values: Vec<String> = values.iter().map(|(n, v)| format!("{n}:={v}")).collect();
            // The base type is written when it is not the default DINT: `Code:INT(Ok:=0,…)`.
            let base = match base {
                crate::value::Elem::I32 => String::new(),
                e => format!(":{}", crate::value::type_name(&ValueType::Signed(*e))),
            };
            format!("{type_name}{base}({})", values.join(","))
        }
        other => crate::value::type_name(other),
    }
}

/// Whether a saved variable's type text and byte count agree: an array's text states its
/// bounds and its element's layout, which must parse and account for exactly `len` bytes; any
/// other type text is taken as it is (its length is checked against the program's at restore).
/// The decoder refuses a file where they do not agree: no writer writes one.
pub fn well_formed(ty: &str, len: usize) -> bool {
    !ty.starts_with(ARRAY) || parse_array(ty, len as u64).is_some()
}

/// A retained leaf of variable memory. A reference is not saved: its offset means nothing to
/// another layout of memory.
fn retained(s: &Symbol) -> bool {
    s.retain && s.at.space == Space::Var && !matches!(s.ty, ValueType::Reference { .. })
}

fn leaf_record(s: &Symbol) -> RetainedRecord {
    RetainedRecord {
        name: s.name.clone(),
        key: String::new(),
        ty: type_text(&s.ty),
        at: s.at.offset,
        len: s.ty.bytes(),
        pos: 0,
        array: None,
    }
}

/// The record of an entry: a retained leaf's, or an array's holding a retained leaf.
fn record_of(entry: &Entry) -> Option<RetainedRecord> {
    match entry {
        Entry::Leaf(s) if retained(s) => Some(leaf_record(s)),
        Entry::Leaf(_) => None,
        Entry::Array(a) => array_record(a),
    }
}

/// The retained parts of an element's entries (names and places relative), packed from 0.
fn parts_of(entries: &[Entry]) -> Option<Vec<RetainedRecord>> {
    let mut parts = Vec::new();
    let mut pos = 0u32;
    for entry in entries {
        let Some(part) = record_of(entry) else { continue };
        let end = pos.checked_add(part.len)?;
        parts.push(RetainedRecord { pos, ..part });
        pos = end;
    }
    Some(parts)
}

/// The record of an array any of whose element's leaves is retained (`None` otherwise, or
/// if its bytes would not fit a file's u32).
fn array_record(a: &ArraySymbol) -> Option<RetainedRecord> {
    if a.at.space != Space::Var {
        return None;
    }
    let parts = parts_of(a.element.entries())?;
    let bytes = parts.iter().try_fold(0u32, |sum, p| sum.checked_add(p.len))?;
    let count = a.count();
    if parts.is_empty() || count == 0 || bytes == 0 {
        return None;
    }
    let len = u32::try_from(count.checked_mul(u64::from(bytes))?).ok()?;
    let dense = a.stride == bytes
        && parts.iter().all(|p| p.at == p.pos && p.array.as_ref().is_none_or(|l| l.dense));
    let ty = array_text(&a.dims, &parts, bytes);
    let layout = ArrayLayout {
        dims: a.dims.clone().into_boxed_slice(),
        count,
        stride: a.stride,
        parts: parts.into_boxed_slice(),
        bytes,
        dense,
    };
    Some(RetainedRecord {
        name: a.name.clone(),
        key: String::new(),
        ty,
        at: a.at.offset,
        len,
        pos: 0,
        array: Some(Box::new(layout)),
    })
}

/// `ARRAY[lo..hi,…] OF ` and the element: its one part's type when the element is one
/// unnamed leaf or array (`DINT`, `ARRAY[1..4] OF INT`), else `{name@pos:type;…;@bytes}`: each
/// retained part with its position in the element's packed bytes, then the element's size.
fn array_text(dims: &[(i64, i64)], parts: &[RetainedRecord], bytes: u32) -> String {
    let dims: Vec<String> = dims.iter().map(|(lo, hi)| format!("{lo}..{hi}")).collect();
    let element = match parts {
        [only] if only.name.is_empty() => only.ty.clone(),
        _ => {
            let parts: String =
                parts.iter().map(|p| format!("{}@{}:{};", p.name, p.pos, p.ty)).collect();
            format!("{{{parts}@{bytes}}}")
        }
    };
    format!("{ARRAY}{}] OF {element}", dims.join(","))
}

/// The layout an array's type text states, for `bytes` bytes; `None` unless the text is one
/// [`array_text`] can write and the bytes are exactly its elements'.
fn parse_array(text: &str, bytes: u64) -> Option<ArrayLayout> {
    let (dims_text, element) = text.strip_prefix(ARRAY)?.split_once("] OF ")?;
    let mut dims = Vec::new();
    let mut count = 1u64;
    for dim in dims_text.split(',') {
        let (lo, hi) = dim.split_once("..")?;
        let (lo, hi): (i64, i64) = (lo.parse().ok()?, hi.parse().ok()?);
        let len = u64::try_from(hi.checked_sub(lo)?.checked_add(1)?).ok()?;
        count = count.checked_mul(len)?;
        dims.push((lo, hi));
    }
    if count == 0 || bytes == 0 || bytes % count != 0 {
        return None;
    }
    let size = u32::try_from(bytes / count).ok()?;
    let parts = parse_element(element, size)?;
    Some(ArrayLayout {
        dims: dims.into_boxed_slice(),
        count,
        stride: size,
        parts,
        bytes: size,
        dense: true,
    })
}

/// The parts of an element's text of `bytes` packed bytes: `{name@pos:type;…;@bytes}`, the
/// positions from 0 and increasing, each part's bytes up to the next; or one unnamed part.
fn parse_element(text: &str, bytes: u32) -> Option<Box<[RetainedRecord]>> {
    let Some(inner) = text.strip_prefix('{') else {
        return Some(Box::new([saved_part("", text, 0, bytes)?]));
    };
    let inner = inner.strip_suffix('}')?;
    // `;` between parts, not those inside a nested array's element (within its braces)
    let mut items = Vec::new();
    let (mut depth, mut from) = (0usize, 0);
    for (i, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth = depth.checked_sub(1)?,
            ';' if depth == 0 => {
                items.push(&inner[from..i]);
                from = i + 1;
            }
            _ => {}
        }
    }
    let size: u32 = inner[from..].strip_prefix('@')?.parse().ok()?;
    if depth != 0 || size != bytes || items.is_empty() {
        return None;
    }
    let mut placed = Vec::with_capacity(items.len());
    for item in items {
        let (name, rest) = item.split_once('@')?;
        let (pos, ty) = rest.split_once(':')?;
        placed.push((name, pos.parse::<u32>().ok()?, ty));
    }
    let mut parts = Vec::with_capacity(placed.len());
    for (i, &(name, pos, ty)) in placed.iter().enumerate() {
        let end = placed.get(i + 1).map_or(bytes, |next| next.1);
        let expected = parts.last().map_or(0, |p: &RetainedRecord| p.pos + p.len);
        if pos != expected || end <= pos {
            return None;
        }
        parts.push(saved_part(name, ty, pos, end - pos)?);
    }
    Some(parts.into_boxed_slice())
}

/// A part of an element read from a file: its bytes are at its position (`at` = `pos`).
fn saved_part(name: &str, ty: &str, pos: u32, len: u32) -> Option<RetainedRecord> {
    let delimiter = |c: char| matches!(c, '{' | '}' | ';' | '@');
    if name.contains(delimiter) {
        return None;
    }
    let array = if ty.starts_with(ARRAY) {
        Some(Box::new(parse_array(ty, u64::from(len))?))
    } else if ty.is_empty() || ty.contains(delimiter) {
        return None;
    } else {
        None
    };
    let (name, ty) = (name.to_string(), ty.to_string());
    Some(RetainedRecord { name, key: String::new(), ty, at: pos, len, pos, array })
}

/// Two elements laid out the same: the same parts in the same order, each of the same name
/// (case-insensitive), position and type (a nested array: of the same bounds).
fn same_element(a: &ArrayLayout, b: &ArrayLayout) -> bool {
    a.bytes == b.bytes
        && a.parts.len() == b.parts.len()
        && a.parts.iter().zip(b.parts.iter()).all(|(p, q)| {
            p.name.eq_ignore_ascii_case(&q.name)
                && (p.pos, p.len) == (q.pos, q.len)
                && match (&p.array, &q.array) {
                    (None, None) => p.ty == q.ty,
                    (Some(x), Some(y)) => x.dims == y.dims && same_element(x, y),
                    _ => false,
                }
        })
}

/// Whether two arrays of the same element have an index in common.
fn overlapping(a: &ArrayLayout, b: &ArrayLayout) -> bool {
    a.dims.len() == b.dims.len()
        && a.dims
            .iter()
            .zip(b.dims.iter())
            .all(|(&(alo, ahi), &(blo, bhi))| alo.max(blo) <= ahi.min(bhi))
}

/// Pairs of byte runs `(to, from, len)`, consecutive ones merged where they continue each
/// other on both sides: what a copy between two layouts of the same data does, in as few
/// calls as its contiguity allows. Allocates nothing.
struct Runs<F: FnMut(u32, u32, u32)> {
    to: u64,
    from: u64,
    len: u64,
    emit: F,
}

impl<F: FnMut(u32, u32, u32)> Runs<F> {
    fn new(emit: F) -> Runs<F> {
        Runs { to: 0, from: 0, len: 0, emit }
    }

    fn push(&mut self, to: u64, from: u64, len: u64) {
        if self.len > 0 && self.to + self.len == to && self.from + self.len == from {
            self.len += len;
        } else {
            self.flush();
            (self.to, self.from, self.len) = (to, from, len);
        }
    }

    fn flush(&mut self) {
        if self.len > 0 {
            // Offsets within variable memory or a record's bytes, both under 4 GiB.
            (self.emit)(self.to as u32, self.from as u32, self.len as u32);
            self.len = 0;
        }
    }
}

/// The runs that copy the elements `a` (at `a_at`) and `b` (at `b_at`) have in common — the
/// same indices, per dimension — from `b`'s place to `a`'s; their elements laid out the same
/// ([`same_element`]). Row by row (a row: the last dimension's common indices, one run when
/// both are dense); the indices of a row's first element are computed from the row's number,
/// without an index vector.
fn overlap<F: FnMut(u32, u32, u32)>(
    a: &ArrayLayout,
    a_at: u64,
    b: &ArrayLayout,
    b_at: u64,
    runs: &mut Runs<F>,
) {
    if !overlapping(a, b) {
        return;
    }
    let n = a.dims.len();
    let common = |d: usize| (a.dims[d].0.max(b.dims[d].0), a.dims[d].1.min(b.dims[d].1));
    let length = |(lo, hi): (i64, i64)| (hi - lo + 1) as u64;
    let row = length(common(n - 1));
    let rows: u64 = (0..n - 1).map(|d| length(common(d))).product();
    for r in 0..rows {
        let (mut ka, mut kb, mut ma, mut mb, mut rest) = (0u64, 0u64, 1u64, 1u64, r);
        for d in (0..n).rev() {
            let (lo, hi) = common(d);
            let i = if d == n - 1 {
                lo
            } else {
                let i = lo + (rest % length((lo, hi))) as i64;
                rest /= length((lo, hi));
                i
            };
            ka += (i - a.dims[d].0) as u64 * ma;
            kb += (i - b.dims[d].0) as u64 * mb;
            ma *= length(a.dims[d]);
            mb *= length(b.dims[d]);
        }
        let (sa, sb) = (u64::from(a.stride), u64::from(b.stride));
        if a.dense && b.dense {
            runs.push(a_at + ka * sa, b_at + kb * sb, row * u64::from(a.bytes));
            continue;
        }
        for i in 0..row {
            let (ea, eb) = (a_at + (ka + i) * sa, b_at + (kb + i) * sb);
            for (p, q) in a.parts.iter().zip(b.parts.iter()) {
                let (pa, qb) = (ea + u64::from(p.at), eb + u64::from(q.at));
                match (&p.array, &q.array) {
                    (Some(x), Some(y)) => overlap(x, pa, y, qb, runs),
                    _ => runs.push(pa, qb, u64::from(p.len)),
                }
            }
        }
    }
}

/// Where a record's bytes end in variable memory (past its last element's last part).
fn extent(r: &RetainedRecord, base: u64) -> u64 {
    let at = base + u64::from(r.at);
    match &r.array {
        None => at + u64::from(r.len),
        Some(a) => {
            let last = at + (a.count - 1) * u64::from(a.stride);
            a.parts.iter().map(|p| extent(p, last)).max().unwrap_or(last)
        }
    }
}

/// One run of variable memory a copy appends, merged with the next one that continues it.
struct Span {
    from: u64,
    len: u64,
}

impl Span {
    fn push(&mut self, from: u64, len: u64, vars: &[u8], into: &mut Vec<u8>) {
        if self.len > 0 && self.from + self.len == from {
            self.len += len;
        } else {
            self.flush(vars, into);
            (self.from, self.len) = (from, len);
        }
    }

    fn flush(&mut self, vars: &[u8], into: &mut Vec<u8>) {
        let (start, len) = (self.from as usize, self.len as usize);
        match vars.get(start..start + len) {
            Some(bytes) => into.extend_from_slice(bytes),
            None => into.resize(into.len() + len, 0),
        }
        self.len = 0;
    }
}

/// Appends `r`'s packed bytes (at `base` in memory) through `span`.
fn append(r: &RetainedRecord, base: u64, vars: &[u8], span: &mut Span, into: &mut Vec<u8>) {
    let at = base + u64::from(r.at);
    match &r.array {
        Some(a) if !a.dense => {
            for k in 0..a.count {
                let element = at + k * u64::from(a.stride);
                for part in a.parts.iter() {
                    append(part, element, vars, span, into);
                }
            }
        }
        _ => span.push(at, u64::from(r.len), vars, into),
    }
}

impl ArrayLayout {
    /// The leaf part named by `rest` (`[3]`, `[1,2].x`, `[2].m[1]`: the indices and the
    /// element's relative name, as version 3 spelled an element's name) of this array at
    /// `at`, and its place in memory.
    fn locate<'a>(&'a self, rest: &str, at: u64) -> Option<(u64, &'a RetainedRecord)> {
        let (k, rest) = crate::symbols::parse_index(&self.dims, rest)?;
        let element = at + k * u64::from(self.stride);
        for part in self.parts.iter() {
            let n = part.name.len();
            match &part.array {
                None if part.name.eq_ignore_ascii_case(rest) => {
                    return Some((element + u64::from(part.at), part));
                }
                None => {}
                Some(inner) => {
                    let head = rest.get(..n).is_some_and(|h| h.eq_ignore_ascii_case(&part.name));
                    if head && rest[n..].starts_with('[') {
                        let found = inner.locate(&rest[n..], element + u64::from(part.at));
                        if found.is_some() {
                            return found;
                        }
                    }
                }
            }
        }
        None
    }
}

impl RetainedVariables {
    /// The retained records of `variables`: a record per retained leaf outside arrays, one per
    /// array holding a retained leaf.
    pub fn new(variables: &Variables) -> RetainedVariables {
        let size = variables.initial.len() as u64;
        let mut records = Vec::new();
        let mut pos = 0u32;
        for entry in variables.symbols.entries() {
            let Some(record) = record_of(entry) else { continue };
            if extent(&record, 0) > size {
                continue;
            }
            let Some(end) = pos.checked_add(record.len) else { continue };
            let key = record.name.to_ascii_lowercase();
            records.push(RetainedRecord { key, pos, ..record });
            pos = end;
        }
        let mut by_key: Vec<u32> = (0..records.len() as u32).collect();
        by_key.sort_by(|&a, &b| records[a as usize].key.cmp(&records[b as usize].key));
        RetainedVariables {
            records: records.into_boxed_slice(),
            by_key: by_key.into_boxed_slice(),
            bytes: pos as usize,
        }
    }

    /// The records, in declaration order.
    pub fn records(&self) -> &[RetainedRecord] {
        &self.records
    }

    /// Bytes of a copy.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Appends the retained bytes of variable memory `vars` to `into`, record after record,
    /// each packed. Allocates nothing when `into` has room for [`RetainedVariables::bytes`]
    /// more.
    pub fn copy(&self, vars: &[u8], into: &mut Vec<u8>) {
        let mut span = Span { from: 0, len: 0 };
        for record in self.records.iter() {
            append(record, 0, vars, &mut span, into);
        }
        span.flush(vars, into);
    }

    /// The bytes of `record` in a copy.
    pub fn record_in<'c>(&self, record: &RetainedRecord, copy: &'c [u8]) -> &'c [u8] {
        let (start, end) = (record.pos as usize, (record.pos + record.len) as usize);
        copy.get(start..end).unwrap_or_default()
    }

    /// Calls `same(new, old, len)` for runs of bytes of `self`'s variables that `old` has too
    /// — a leaf of the same name (case-insensitive) and type; the elements of an array of the
    /// same name and element layout at the indices both have — `new` and `old` their offsets
    /// in the two variable memories; consecutive runs merged. Allocates nothing (a
    /// replacement engine calls it on the scan thread).
    pub fn for_each_same(&self, old: &RetainedVariables, same: impl FnMut(u32, u32, u32)) {
        let mut runs = Runs::new(same);
        let (mut i, mut j) = (0, 0);
        while i < self.by_key.len() && j < old.by_key.len() {
            let a = &self.records[self.by_key[i] as usize];
            let b = &old.records[old.by_key[j] as usize];
            match a.key.cmp(&b.key) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    match (&a.array, &b.array) {
                        (None, None) if a.ty == b.ty && a.len == b.len => {
                            runs.push(u64::from(a.at), u64::from(b.at), u64::from(a.len))
                        }
                        (Some(x), Some(y)) if same_element(x, y) => {
                            overlap(x, u64::from(a.at), y, u64::from(b.at), &mut runs)
                        }
                        _ => {}
                    }
                    i += 1;
                    j += 1;
                }
            }
        }
        runs.flush();
    }

    /// The record named `name` (case-insensitive).
    fn find(&self, name: &str) -> Option<usize> {
        self.find_key(&name.to_ascii_lowercase())
    }

    fn find_key(&self, key: &str) -> Option<usize> {
        let at = self.by_key.binary_search_by(|&i| self.records[i as usize].key.as_str().cmp(key));
        Some(self.by_key[at.ok()?] as usize)
    }

    /// The array record holding the element leaf a version 3 file names `name`
    /// (`main.buf[3]`, `main.pts[1,2].x`), the leaf's place in memory and the leaf.
    fn element(&self, name: &str) -> Option<(usize, u32, &RetainedRecord)> {
        let key = name.to_ascii_lowercase();
        for (bracket, _) in key.match_indices('[') {
            let Some(i) = self.find_key(&key[..bracket]) else { continue };
            let record = &self.records[i];
            let Some(array) = &record.array else { continue };
            if let Some((at, leaf)) = array.locate(&name[bracket..], u64::from(record.at)) {
                return Some((i, u32::try_from(at).ok()?, leaf));
            }
        }
        None
    }

    /// What restoring `saved` (a retain file's variables) into these records does: a saved
    /// leaf is restored into the leaf of the same name (case-insensitive), type and byte
    /// length; a saved array into the array of the same name and element layout, at the
    /// indices both have (per dimension); a version 3 file's element leaf (`main.buf[3]`) into
    /// that element of the array, if it has the index, a leaf of that name, type and length;
    /// any other is dropped; a record nothing is restored into keeps its initial value.
    pub fn plan_restore(&self, saved: &[SavedVariable]) -> RestorePlan {
        let mut plan = RestorePlan::default();
        let mut restored = vec![false; self.records.len()];
        let now = |var: &SavedVariable, ty: &str| format!("{} ({}): now {ty}", var.name, var.ty);
        let lengths = |var: &SavedVariable, len: u32| {
            format!("{} ({}): {} bytes saved, {len} declared", var.name, var.ty, var.bytes.len())
        };
        for (s, var) in saved.iter().enumerate() {
            let Some(i) = self.find(&var.name) else {
                // Element records (version 3) are not checked for duplicates: no writer wrote
                // one twice, and a second one would restore the same place again.
                match self.element(&var.name) {
                    Some((i, at, leaf))
                        if leaf.ty == var.ty && leaf.len as usize == var.bytes.len() =>
                    {
                        restored[i] = true;
                        plan.restore.push(Restored {
                            record: i,
                            saved: s,
                            into: Target::Element(at),
                        });
                    }
                    Some((_, _, leaf)) if leaf.ty != var.ty => {
                        plan.dropped.push(now(var, &leaf.ty))
                    }
                    Some((_, _, leaf)) => plan.dropped.push(lengths(var, leaf.len)),
                    None => plan.dropped.push(format!(
                        "{} ({}): not a RETAIN variable of the program",
                        var.name, var.ty
                    )),
                }
                continue;
            };
            let record = &self.records[i];
            if restored[i] {
                plan.dropped.push(format!("{} ({}): saved twice", var.name, var.ty));
                continue;
            }
            let into = match &record.array {
                None if record.ty != var.ty => Err(now(var, &record.ty)),
                None if record.len as usize != var.bytes.len() => Err(lengths(var, record.len)),
                None => Ok(Target::Whole),
                Some(array) => match parse_array(&var.ty, var.bytes.len() as u64) {
                    Some(was) if same_element(array, &was) && overlapping(array, &was) => {
                        Ok(Target::Overlap(Box::new(was)))
                    }
                    Some(was) if same_element(array, &was) => Err(format!(
                        "{} ({}): no index in common with {}",
                        var.name, var.ty, record.ty
                    )),
                    _ => Err(now(var, &record.ty)),
                },
            };
            match into {
                Ok(into) => {
                    restored[i] = true;
                    plan.restore.push(Restored { record: i, saved: s, into });
                }
                Err(why) => plan.dropped.push(why),
            }
        }
        plan.new = (self.records.iter().zip(&restored))
            .filter(|(_, done)| !**done)
            .map(|(record, _)| record.name.clone())
            .collect();
        plan
    }

    /// Carries out `plan` (made by [`RetainedVariables::plan_restore`] from `saved`):
    /// `write(at, bytes)` for each run of bytes to restore at offset `at` of variable memory.
    pub fn restore(
        &self,
        plan: &RestorePlan,
        saved: &[SavedVariable],
        mut write: impl FnMut(u32, &[u8]),
    ) {
        for r in &plan.restore {
            let (Some(record), Some(var)) = (self.records.get(r.record), saved.get(r.saved)) else {
                continue;
            };
            let bytes = &var.bytes[..];
            match &r.into {
                Target::Whole => write(record.at, bytes),
                Target::Element(at) => write(*at, bytes),
                Target::Overlap(was) => {
                    let Some(array) = &record.array else { continue };
                    let mut runs = Runs::new(|to, from, len| {
                        let (from, len) = (from as usize, len as usize);
                        if let Some(bytes) = bytes.get(from..from + len) {
                            write(to, bytes);
                        }
                    });
                    overlap(array, u64::from(record.at), was, 0, &mut runs);
                    runs.flush();
                }
            }
        }
    }
}

/// `names` for a log line: all of them up to `most`, then how many more.
pub fn list_names(names: &[String], most: usize) -> String {
    let mut text = names.iter().take(most).cloned().collect::<Vec<_>>().join(", ");
    if names.len() > most {
        text.push_str(&format!(" and {} more", names.len() - most));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::symbols::Symbols;
    use crate::value::{Elem, Pointer};

    fn symbol(name: &str, ty: ValueType, offset: u32, retain: bool) -> Symbol {
        Symbol {
            name: name.into(),
            ty,
            at: Pointer { space: Space::Var, offset },
            retain,
            constant: false,
        }
    }

    fn variables(symbols: Vec<Symbol>) -> Variables {
        Variables { initial: vec![0; 64].into(), symbols: symbols.into(), ..Variables::default() }
    }

    fn array(name: &str, dims: &[(i64, i64)], at: u32, stride: u32, element: Symbols) -> Entry {
        let at = Pointer { space: Space::Var, offset: at };
        Entry::Array(ArraySymbol { name: name.into(), dims: dims.into(), at, stride, element })
    }

    fn of(leaves: Vec<Symbol>) -> Symbols {
        leaves.into()
    }

    fn with(entries: Vec<Entry>, size: usize) -> RetainedVariables {
        let mut symbols = Symbols::default();
        for entry in entries {
            match entry {
                Entry::Leaf(s) => symbols.push(s),
                Entry::Array(a) => symbols.push_array(a),
            }
        }
        RetainedVariables::new(&Variables {
            initial: vec![0; size].into(),
            symbols,
            ..Variables::default()
        })
    }

    fn int(name: &str, at: u32, retain: bool) -> Symbol {
        symbol(name, ValueType::Signed(Elem::I16), at, retain)
    }

    fn dint(name: &str, at: u32) -> Symbol {
        symbol(name, ValueType::Signed(Elem::I32), at, true)
    }

    /// `ARRAY[dims] OF DINT` at `at`.
    fn dints(name: &str, dims: &[(i64, i64)], at: u32) -> Entry {
        array(name, dims, at, 4, of(vec![dint("", 0)]))
    }

    /// `ARRAY[dims] OF` a block of 6 bytes: `.x : INT` retained at 0, `.y : INT` not at 2,
    /// `.s : STRING[1]` retained at 4.
    fn blocks(name: &str, dims: &[(i64, i64)], at: u32) -> Entry {
        let s = symbol(".s", ValueType::String { cap: 1 }, 4, true);
        array(name, dims, at, 6, of(vec![int(".x", 0, true), int(".y", 2, false), s]))
    }

    /// Every `same(new, old, len)` call.
    fn runs(new: &RetainedVariables, old: &RetainedVariables) -> Vec<(u32, u32, u32)> {
        let mut calls = Vec::new();
        new.for_each_same(old, |n, o, len| calls.push((n, o, len)));
        calls
    }

    #[test]
    fn records_positions_and_the_copy() {
        let v = variables(vec![
            symbol("main.b", ValueType::Signed(Elem::I16), 10, true),
            symbol("main.a", ValueType::Signed(Elem::I32), 4, true),
            symbol("main.x", ValueType::Signed(Elem::I32), 0, false),
            symbol("main.s", ValueType::String { cap: 3 }, 12, true),
            symbol("main.p", ValueType::Bool, 40, true),
            Symbol {
                at: Pointer { space: Space::Word, offset: 4992 },
                ..symbol("main.d", ValueType::Signed(Elem::I16), 0, true)
            },
        ]);
        let r = RetainedVariables::new(&v);
        let names: Vec<&str> = r.records().iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["main.b", "main.a", "main.s", "main.p"], "declaration order");
        assert_eq!(r.bytes(), 11);
        let pos: Vec<u32> = r.records().iter().map(|l| l.pos).collect();
        assert_eq!(pos, [0, 2, 6, 10], "packed in declaration order");
        let mut vars: Vec<u8> = (0..64).collect();
        vars[40] = 99;
        let mut copy = Vec::with_capacity(r.bytes());
        r.copy(&vars, &mut copy);
        assert_eq!(copy, [10, 11, 4, 5, 6, 7, 12, 13, 14, 15, 99]);
        assert_eq!(r.record_in(&r.records()[2], &copy), &[12, 13, 14, 15]);
        assert_eq!(r.records()[2].ty, "STRING[3]");
    }

    #[test]
    fn a_wstring_is_kept_whole_and_its_length_is_its_type() {
        let v = variables(vec![symbol("main.w", ValueType::WString { cap: 3 }, 20, true)]);
        let r = RetainedVariables::new(&v);
        // 3 code units and the 2-byte NUL: 8 bytes; another length is another type
        assert_eq!((r.bytes(), r.records()[0].len), (8, 8));
        assert_eq!(r.records()[0].ty, "WSTRING[3]");
    }

    #[test]
    fn references_are_not_saved() {
        let pointer = ValueType::Reference { type_name: "POINTER TO INT".into() };
        let v = variables(vec![
            symbol("main.n", ValueType::Signed(Elem::I16), 0, true),
            symbol("main.p", pointer, 8, true),
        ]);
        let r = RetainedVariables::new(&v);
        let names: Vec<&str> = r.records().iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["main.n"]);
        assert_eq!(r.bytes(), 2);
    }

    #[test]
    fn type_texts() {
        assert_eq!(type_text(&ValueType::Unsigned(Elem::U32)), "UDINT");
        assert_eq!(type_text(&ValueType::Real(Elem::F64)), "LREAL");
        assert_eq!(type_text(&ValueType::Time), "TIME");
        let color = ValueType::Enum {
            type_name: "Color".into(),
            values: vec![("Red".into(), 0), ("Green".into(), 5)],
            base: Elem::I32,
        };
        assert_eq!(type_text(&color), "Color(Red:=0,Green:=5)");
        let code = ValueType::Enum {
            type_name: "Color".into(),
            values: vec![("Red".into(), 0), ("Green".into(), 5)],
            base: Elem::I16,
        };
        assert_eq!(type_text(&code), "Color:INT(Red:=0,Green:=5)");
    }

    #[test]
    fn the_same_variable_is_the_same_name_and_type() {
        let old = RetainedVariables::new(&variables(vec![
            symbol("main.count", ValueType::Signed(Elem::I32), 0, true),
            symbol("main.renamed", ValueType::Signed(Elem::I32), 4, true),
            symbol("main.retyped", ValueType::Signed(Elem::I16), 8, true),
            symbol("main.gone", ValueType::Bool, 10, true),
        ]));
        let new = RetainedVariables::new(&variables(vec![
            symbol("main.fresh", ValueType::Bool, 0, true),
            symbol("MAIN.Count", ValueType::Signed(Elem::I32), 20, true),
            symbol("main.renamed2", ValueType::Signed(Elem::I32), 4, true),
            symbol("main.retyped", ValueType::Signed(Elem::I32), 8, true),
        ]));
        assert_eq!(runs(&new, &old), [(20, 0, 4)]);

        let saved: Vec<SavedVariable> = old
            .records()
            .iter()
            .map(|l| SavedVariable {
                name: l.name.clone(),
                ty: l.ty.clone(),
                bytes: vec![1; l.len as usize],
            })
            .collect();
        let plan = new.plan_restore(&saved);
        let restored: Vec<(usize, usize)> =
            plan.restore.iter().map(|r| (r.record, r.saved)).collect();
        assert_eq!(restored, [(1, 0)]);
        assert_eq!(
            plan.dropped,
            [
                "main.renamed (DINT): not a RETAIN variable of the program",
                "main.retyped (INT): now DINT",
                "main.gone (BOOL): not a RETAIN variable of the program",
            ]
        );
        assert_eq!(plan.new, ["main.fresh", "main.renamed2", "main.retyped"]);
        assert_eq!(list_names(&plan.new, 2), "main.fresh, main.renamed2 and 1 more");
    }

    #[test]
    fn an_array_is_one_record_of_its_elements_retained_bytes() {
        let r = with(
            vec![
                dints("main.buf", &[(1, 4)], 0),
                Entry::Leaf(int("main.n", 16, true)),
                blocks("main.pts", &[(0, 1), (1, 2)], 20),
                array("main.off", &[(1, 2)], 44, 2, of(vec![int("", 0, false)])),
            ],
            64,
        );
        let texts: Vec<(&str, &str, u32, u32)> =
            r.records().iter().map(|r| (r.name.as_str(), r.ty.as_str(), r.pos, r.len)).collect();
        assert_eq!(
            texts,
            [
                ("main.buf", "ARRAY[1..4] OF DINT", 0, 16),
                ("main.n", "INT", 16, 2),
                ("main.pts", "ARRAY[0..1,1..2] OF {.x@0:INT;.s@2:STRING[1];@4}", 18, 16),
            ],
            "an array none of whose leaves is retained is no record"
        );
        let vars: Vec<u8> = (0..64).collect();
        let mut copy = Vec::with_capacity(r.bytes());
        r.copy(&vars, &mut copy);
        assert_eq!(r.record_in(&r.records()[0], &copy), (0..16).collect::<Vec<u8>>());
        let pts: Vec<u8> = (0..4u8).flat_map(|k| [0, 1, 4, 5].map(|b| 20 + 6 * k + b)).collect();
        assert_eq!(r.record_in(&r.records()[2], &copy), pts, ".y is not retained");
        assert_eq!(copy.len(), r.bytes());
        // the texts state the layouts: they parse back to them
        for record in r.records() {
            assert!(well_formed(&record.ty, record.len as usize), "{}", record.ty);
            if let Some(a) = &record.array {
                let parsed = parse_array(&record.ty, u64::from(record.len)).unwrap();
                assert!(same_element(a, &parsed) && a.dims == parsed.dims, "{}", record.ty);
            }
        }
    }

    #[test]
    fn arrays_of_arrays_and_arrays_inside_elements() {
        let inner = |name: &str, at: u32| array(name, &[(1, 2)], at, 2, of(vec![int("", 0, true)]));
        let mut element = Symbols::default();
        element.push(int(".x", 0, true));
        let Entry::Array(m) = inner(".m", 2) else { unreachable!() };
        element.push_array(m);
        let mut rows = Symbols::default();
        let Entry::Array(row) = inner("", 0) else { unreachable!() };
        rows.push_array(row);
        let r = with(
            vec![
                array("main.a", &[(1, 3)], 0, 6, element),
                array("main.mm", &[(0, 1)], 20, 4, rows),
            ],
            64,
        );
        let texts: Vec<&str> = r.records().iter().map(|r| r.ty.as_str()).collect();
        assert_eq!(
            texts,
            [
                "ARRAY[1..3] OF {.x@0:INT;.m@2:ARRAY[1..2] OF INT;@6}",
                "ARRAY[0..1] OF ARRAY[1..2] OF INT"
            ]
        );
        assert!(r.records().iter().all(|r| r.array.as_ref().unwrap().dense));
        let vars: Vec<u8> = (0..64).collect();
        let mut copy = Vec::new();
        r.copy(&vars, &mut copy);
        assert_eq!(copy, (0..18).chain(20..28).collect::<Vec<u8>>());
        // a version 3 file's element names find their places
        let at = |name: &str| r.element(name).map(|(i, at, leaf)| (i, at, leaf.ty.clone()));
        assert_eq!(at("main.a[2].m[2]"), Some((0, 6 + 4, "INT".into())));
        assert_eq!(at("MAIN.A[3].X"), Some((0, 12, "INT".into())));
        assert_eq!(at("main.mm[1][2]"), Some((1, 20 + 4 + 2, "INT".into())));
        for wrong in ["main.a[4].x", "main.a[1].m[3]", "main.a[1]", "main.mm[1]", "main.a[01].x"] {
            assert_eq!(at(wrong), None, "{wrong}");
        }
        for record in r.records() {
            let parsed = parse_array(&record.ty, u64::from(record.len)).unwrap();
            assert!(same_element(record.array.as_ref().unwrap(), &parsed), "{}", record.ty);
        }
    }

    #[test]
    fn malformed_array_texts_are_refused() {
        for (text, len) in [
            ("ARRAY[1..4] OF DINT", 15),
            ("ARRAY[1..4] OF DINT", 0),
            ("ARRAY[4..1] OF DINT", 16),
            ("ARRAY[] OF DINT", 16),
            ("ARRAY[1..4]OF DINT", 16),
            ("ARRAY[1..4] OF ", 16),
            ("ARRAY[-9223372036854775808..9223372036854775807] OF BYTE", 16),
            ("ARRAY[1..4294967296,1..4294967296] OF BYTE", 16),
            ("ARRAY[1..2] OF {.x@1:INT;@2}", 4),
            ("ARRAY[1..2] OF {.x@0:INT;.y@0:INT;@4}", 8),
            ("ARRAY[1..2] OF {.x@0:INT;@3}", 4),
            ("ARRAY[1..2] OF {@2}", 4),
            ("ARRAY[1..2] OF {.x@0:INT;@2", 4),
            ("ARRAY[1..2] OF {.x@0:INT}", 4),
            ("ARRAY[1..2] OF {.x@0:}INT;@2}", 4),
            ("ARRAY[1..2] OF {.x0:INT;@2}", 4),
            ("ARRAY[1..2] OF {.x@0:ARRAY[1..3] OF INT;@2}", 4),
            ("ARRAY[1..2] OF {.x@0:ARRAY[1..2] OF {.y@0:INT;@2};@4}}", 8),
            ("ARRAY[1..2] OF D;NT", 8),
        ] {
            assert!(!well_formed(text, len), "{text} ({len} bytes) accepted");
        }
        assert!(well_formed("ARRAY[-2..-1] OF {.x@0:ARRAY[1..2] OF {.y@0:INT;@2};@4}", 8));
        assert!(well_formed("DINT", 3), "a leaf's length is the program's to check");
    }

    #[test]
    fn the_same_array_keeps_the_elements_both_have() {
        let old =
            with(vec![dints("main.buf", &[(1, 4)], 0), dints("main.m", &[(1, 2), (1, 3)], 16)], 64);
        // grown and shifted, another place; a row more and a column shifted; the name shouted
        let new = with(
            vec![dints("MAIN.BUF", &[(0, 5)], 100), dints("main.m", &[(1, 3), (2, 4)], 200)],
            300,
        );
        assert_eq!(runs(&new, &old), [(104, 0, 16), (200, 16 + 4, 8), (212, 16 + 16, 8)]);
        // shrunk: the indices that remain
        let small = with(vec![dints("main.buf", &[(3, 3)], 0)], 4);
        assert_eq!(runs(&small, &old), [(0, 8, 4)]);
        // no index in common, or another element: nothing
        let apart = with(vec![dints("main.buf", &[(5, 9)], 0)], 64);
        assert_eq!(runs(&apart, &old), []);
        let ints = with(vec![array("main.buf", &[(1, 4)], 0, 2, of(vec![int("", 0, true)]))], 64);
        assert_eq!(runs(&ints, &old), []);
        let flat = with(vec![dints("main.m", &[(1, 6)], 0)], 64);
        assert_eq!(runs(&flat, &old), [], "other dimensions");
    }

    #[test]
    fn an_array_of_blocks_keeps_its_retained_leaves_wherever_they_moved() {
        let old = with(vec![blocks("main.pts", &[(1, 3)], 0)], 64);
        assert_eq!(runs(&old, &old), [(0, 0, 2), (4, 4, 4), (10, 10, 4), (16, 16, 2)]);
        // another stride (a member not retained grew) and a member renamed in case: the same
        // retained layout; elements 2..3 kept
        let s = symbol(".S", ValueType::String { cap: 1 }, 8, true);
        let element = of(vec![int(".X", 0, true), dint(".y", 2), s]);
        let mut moved = with(vec![array("main.pts", &[(2, 5)], 100, 10, element)], 200);
        assert_eq!(moved.records()[0].ty, "ARRAY[2..5] OF {.X@0:INT;.y@2:DINT;.S@6:STRING[1];@8}");
        assert_eq!(runs(&moved, &old), [], ".y is retained now: another layout");
        let element = of(vec![
            int(".X", 0, true),
            int(".y", 2, false),
            symbol(".S", ValueType::String { cap: 1 }, 8, true),
        ]);
        moved = with(vec![array("main.pts", &[(2, 5)], 100, 10, element)], 200);
        assert_eq!(runs(&moved, &old), [(100, 6, 2), (108, 10, 4), (118, 16, 2)]);
    }

    /// Writes a plan into `memory`.
    fn restore_into(
        r: &RetainedVariables,
        saved: &[SavedVariable],
        memory: &mut [u8],
    ) -> RestorePlan {
        let plan = r.plan_restore(saved);
        r.restore(&plan, saved, |at, bytes| {
            memory[at as usize..at as usize + bytes.len()].copy_from_slice(bytes)
        });
        plan
    }

    fn saved(name: &str, ty: &str, bytes: impl IntoIterator<Item = u8>) -> SavedVariable {
        SavedVariable { name: name.into(), ty: ty.into(), bytes: bytes.into_iter().collect() }
    }

    #[test]
    fn a_saved_array_restores_the_indices_both_have_or_is_dropped_in_one_line() {
        let r = with(vec![dints("main.buf", &[(0, 2)], 8), blocks("main.pts", &[(1, 2)], 20)], 64);
        let file = [
            saved("main.buf", "ARRAY[1..4] OF DINT", 1..=16),
            saved("Main.Pts", "ARRAY[2..3] OF {.x@0:INT;.s@2:STRING[1];@4}", 31..=38),
        ];
        let mut memory = vec![0u8; 64];
        let plan = restore_into(&r, &file, &mut memory);
        assert!(plan.dropped.is_empty() && plan.new.is_empty(), "{plan:?}");
        assert_eq!(plan.restore.len(), 2);
        assert_eq!(&memory[8..20], &[0, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8], "buf[1], buf[2]");
        assert_eq!(&memory[20..26], &[0; 6], "pts[1] kept its initial value");
        assert_eq!(&memory[26..32], &[31, 32, 0, 0, 33, 34], "pts[2]: .x and .s, .y untouched");

        let other = [
            saved("main.buf", "ARRAY[1..4] OF INT", 1..=8),
            saved("main.pts", "ARRAY[5..6] OF {.x@0:INT;.s@2:STRING[1];@4}", 1..=8),
            saved("main.gone", "ARRAY[1..2] OF INT", 1..=4),
        ];
        let plan = restore_into(&r, &other, &mut [0u8; 64]);
        assert!(plan.restore.is_empty());
        assert_eq!(
            plan.dropped,
            [
                "main.buf (ARRAY[1..4] OF INT): now ARRAY[0..2] OF DINT",
                "main.pts (ARRAY[5..6] OF {.x@0:INT;.s@2:STRING[1];@4}): no index in common with \
                 ARRAY[1..2] OF {.x@0:INT;.s@2:STRING[1];@4}",
                "main.gone (ARRAY[1..2] OF INT): not a RETAIN variable of the program",
            ]
        );
        assert_eq!(plan.new, ["main.buf", "main.pts"], "each array once");
        let twice =
            [saved("main.buf", "ARRAY[0..0] OF DINT", 1..=4), saved("main.buf", "DINT", 1..=4)];
        let plan = r.plan_restore(&twice);
        assert_eq!(plan.dropped, ["main.buf (DINT): saved twice"]);
        let leaf = [saved("main.buf", "DINT", 1..=4)];
        assert_eq!(r.plan_restore(&leaf).dropped, ["main.buf (DINT): now ARRAY[0..2] OF DINT"]);
    }

    #[test]
    fn a_version_3_files_element_records_restore_into_their_elements() {
        let r = with(vec![dints("main.buf", &[(0, 2)], 8), blocks("main.pts", &[(1, 2)], 20)], 64);
        let file = [
            saved("main.buf[1]", "DINT", 1..=4),
            saved("main.buf[3]", "DINT", 5..=8),
            saved("main.pts[2].x", "INT", [9, 10]),
            saved("MAIN.PTS[2].S", "STRING[1]", [11, 0]),
            saved("main.pts[1].x", "DINT", 1..=4),
            saved("main.pts[1].s", "STRING[1]", [1, 2, 3]),
            saved("main.pts[1].y", "INT", [1, 2]),
        ];
        let mut memory = vec![0u8; 64];
        let plan = restore_into(&r, &file, &mut memory);
        assert_eq!(plan.restore.len(), 3);
        assert_eq!(&memory[8..20], &[0, 0, 0, 0, 1, 2, 3, 4, 0, 0, 0, 0]);
        assert_eq!(&memory[26..32], &[9, 10, 0, 0, 11, 0]);
        assert_eq!(
            plan.dropped,
            [
                "main.buf[3] (DINT): not a RETAIN variable of the program",
                "main.pts[1].x (DINT): now INT",
                "main.pts[1].s (STRING[1]): 3 bytes saved, 2 declared",
                "main.pts[1].y (INT): not a RETAIN variable of the program",
            ]
        );
        assert!(plan.new.is_empty(), "both arrays got elements: {:?}", plan.new);
    }
}
