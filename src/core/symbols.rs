//! The named variables of a project's Structured Text, as a table that costs about the number
//! of declarations rather than the number of scalar leaves.
//!
//! Tools name every scalar leaf of every variable (`main.pid.out`, `main.buf[3]`,
//! `main.a[1,2].x`, `main.m[1][2]`): `--watch`, `plcctl get/set/watch/list`, the trace, the
//! retain file, online change. A table with one [`Symbol`] per leaf made an
//! `ARRAY[1..1000000] OF BYTE` a million symbols (about 135 bytes each with their names), so
//! that loading a project cost over a hundred times its memory. [`Symbols`] holds instead:
//!
//! - a scalar variable (or a leaf outside any array) as one [`Symbol`], as before;
//! - an array of anything as one [`ArraySymbol`]: its name, its dimensions, the place of its
//!   first element, the stride between elements, and the leaves of ONE element as a nested
//!   [`Symbols`] whose names are relative (`""` for an array of scalars, `.x` for a struct's
//!   member, `[2].y` inside a nested array) and whose places are relative to the element's
//!   start. An array inside the element is again one entry, so an array of structs holding
//!   arrays (TcUnit's test results) is a handful of entries.
//!
//! What reads it:
//! - [`Symbols::find`] looks a leaf up by its full name, case-insensitive and blind to
//!   whitespace like before: the indices are parsed and must be spelled as the expanded name
//!   spells them (`main.a[1,2]`, `main.m[1][2]`, `-1`; not `main.a[01]`), so exactly the names
//!   that worked with one symbol per leaf still work, and no others;
//! - [`Symbols::iter`] expands every leaf lazily, by value, in the order the one-symbol-per-leaf
//!   table had (declaration order; an array's elements in row-major order, each element's
//!   leaves in turn), for the consumers that need them all (listings, the retain file);
//! - [`Symbols::len`] counts the leaves without expanding them, [`Symbols::entries`] are the
//!   entries themselves (online change matches an array as a whole by index range);
//! - [`Symbols::may_start_with`] expands only the entries a prefix may name (watching
//!   `main.pid` expands no array elsewhere);
//! - [`Symbols::holding`] finds the leaf that holds a place (what a reference points to): the
//!   element's index comes from the offset.
//!
//! An array whose element has a leaf that is not placed relative to the element (an FB's
//! variable that `VAR_CONFIG` binds to a device) stays expanded, one [`Symbol`] per leaf: the
//! compiler decides ([`Symbols::push`] or [`Symbols::push_array`]).

use crate::value::{Pointer, Space, Symbol};

/// Every named leaf of a project's variables (see the [module](mod@self) documentation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Symbols {
    entries: Vec<Entry>,
    /// The leaves the entries expand to.
    leaves: usize,
}

/// One entry of [`Symbols`]: a leaf, or an array of leaves.
#[derive(Debug, Clone, PartialEq)]
pub enum Entry {
    Leaf(Symbol),
    Array(ArraySymbol),
}

/// An array of any type, one entry for all its elements.
#[derive(Debug, Clone, PartialEq)]
pub struct ArraySymbol {
    /// The array's name with the spelling of its declaration (`main.buf`; relative inside an
    /// element: `.inner`, or `""` for an array of arrays).
    pub name: String,
    /// `(lo, hi)` of each dimension, as declared.
    pub dims: Vec<(i64, i64)>,
    /// The place of the first element.
    pub at: Pointer,
    /// How far apart two elements are, in the units of `at.space` (bytes of variable memory,
    /// words of a device).
    pub stride: u32,
    /// The leaves of one element, placed from the element's start, their names relative.
    pub element: Symbols,
}

impl Entry {
    /// The name of the entry: the leaf's, or the array's (without indices).
    pub fn name(&self) -> &str {
        match self {
            Entry::Leaf(symbol) => &symbol.name,
            Entry::Array(array) => &array.name,
        }
    }

    /// The leaves of this entry alone, as [`Symbols::iter`] yields them.
    pub fn leaves(&self) -> Iter<'_> {
        Iter { stack: vec![Frame::list(std::slice::from_ref(self))] }
    }
}

impl ArraySymbol {
    /// How many elements the array has.
    pub fn count(&self) -> u64 {
        self.dims.iter().map(|&(lo, hi)| (hi - lo + 1).max(0) as u64).product()
    }

    /// The index text of element `k` (row-major, from 0): `[3]`, `[1,2]`.
    pub fn index_text(&self, k: u64) -> String {
        index_text(&self.dims, k)
    }

    /// The offset of element `k` from the first.
    fn element_offset(&self, k: u64) -> u32 {
        (k as u32).wrapping_mul(self.stride)
    }

    /// Element `k` for the index text at the start of `given` (whitespace removed), and what
    /// follows it: the indices spelled as [`ArraySymbol::index_text`] spells them, in bounds.
    fn parse_index<'g>(&self, given: &'g str) -> Option<(u64, &'g str)> {
        parse_index(&self.dims, given)
    }
}

impl Symbols {
    /// A leaf.
    pub fn push(&mut self, symbol: Symbol) {
        self.entries.push(Entry::Leaf(symbol));
        self.leaves += 1;
    }

    /// An array, all its elements at once.
    pub fn push_array(&mut self, array: ArraySymbol) {
        self.leaves += (array.count() as usize).saturating_mul(array.element.len());
        self.entries.push(Entry::Array(array));
    }

    /// How many leaves there are (what [`Symbols::iter`] yields), without expanding them.
    pub fn len(&self) -> usize {
        self.leaves
    }

    pub fn is_empty(&self) -> bool {
        self.leaves == 0
    }

    /// The entries: what the table costs.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// Every leaf, by value, in declaration order.
    pub fn iter(&self) -> Iter<'_> {
        Iter { stack: vec![Frame::list(&self.entries)] }
    }

    /// The leaves whose names may start with `prefix` (case-insensitive, whitespace ignored),
    /// in declaration order: the leaves of every entry whose name starts with `prefix` or
    /// begins it (a leaf's name starts with its entry's), so that an array elsewhere is not
    /// expanded. A superset: the caller tests each leaf's name.
    pub fn may_start_with<'a>(&'a self, prefix: &'a str) -> impl Iterator<Item = Symbol> + 'a {
        let prefix: String = prefix.chars().filter(|c| !c.is_whitespace()).collect();
        self.entries
            .iter()
            .filter(move |e| {
                let name = e.name();
                strip_name(&prefix, name).is_some() || strip_name(name, &prefix).is_some()
            })
            .flat_map(Entry::leaves)
    }

    /// The leaf named `name` (case-insensitive, whitespace ignored), with its full name as
    /// declared.
    pub fn find(&self, name: &str) -> Option<Symbol> {
        let given: String = name.chars().filter(|c| !c.is_whitespace()).collect();
        self.find_in(&given, "", 0)
    }

    fn find_in(&self, given: &str, prefix: &str, base: u32) -> Option<Symbol> {
        for entry in &self.entries {
            match entry {
                Entry::Leaf(s) if names_match(&s.name, given) => {
                    return Some(placed(s, prefix, base));
                }
                Entry::Leaf(_) => {}
                Entry::Array(a) => {
                    let Some(rest) = strip_name(&a.name, given) else { continue };
                    let Some((k, rest)) = a.parse_index(rest) else { continue };
                    let prefix = format!("{prefix}{}{}", a.name, a.index_text(k));
                    let base = base.wrapping_add(a.at.offset).wrapping_add(a.element_offset(k));
                    if let Some(found) = a.element.find_in(rest, &prefix, base) {
                        return Some(found);
                    }
                }
            }
        }
        None
    }

    /// The name of the leaf nearest `given` (lowercase, whitespace removed) by
    /// case-insensitive edit distance, at most `limit` apart, with the distance: the first in
    /// declaration order at the least distance. Of an array, only one element is looked at:
    /// the one whose index `given` writes after about the array's name, else the first, so that
    /// a misspelled name costs a leaf per entry, not per element (a 10^7-element array would
    /// spell 10^7 names).
    pub fn closest(&self, given: &str, limit: usize) -> Option<(usize, String)> {
        let mut best = None;
        self.closest_in(given, limit, "", &mut best);
        best
    }

    fn closest_in(
        &self,
        given: &str,
        limit: usize,
        prefix: &str,
        best: &mut Option<(usize, String)>,
    ) {
        for entry in &self.entries {
            match entry {
                Entry::Leaf(s) => {
                    let name = format!("{prefix}{}", s.name);
                    if name.len().abs_diff(given.len()) > limit {
                        continue;
                    }
                    let distance = edit_distance(name.as_bytes(), given.as_bytes());
                    if distance <= limit && best.as_ref().is_none_or(|(d, _)| distance < *d) {
                        *best = Some((distance, name));
                    }
                }
                Entry::Array(a) => {
                    let head = format!("{prefix}{}", a.name);
                    // the index `given` writes where the array's name, misspelled by at
                    // most `limit`, would end
                    let from = head.len().saturating_sub(limit);
                    let k = given
                        .get(from..)
                        .and_then(|tail| tail.find('[').filter(|&at| at <= 2 * limit))
                        .and_then(|at| a.parse_index(&given[from + at..]))
                        .map_or(0, |(k, _)| k);
                    let prefix = format!("{head}{}", a.index_text(k));
                    a.element.closest_in(given, limit, &prefix, best);
                }
            }
        }
    }

    /// The first leaf (in declaration order) of `space` whose bytes hold `offset`.
    pub fn holding(&self, space: Space, offset: u32) -> Option<Symbol> {
        self.holding_in(space, offset, "", 0)
    }

    fn holding_in(&self, space: Space, offset: u32, prefix: &str, base: u32) -> Option<Symbol> {
        for entry in &self.entries {
            match entry {
                Entry::Leaf(s) => {
                    let start = base.wrapping_add(s.at.offset);
                    if s.at.space == space && start <= offset && offset - start < s.ty.bytes() {
                        return Some(placed(s, prefix, base));
                    }
                }
                Entry::Array(a) => {
                    let start = base.wrapping_add(a.at.offset);
                    if a.at.space != space || offset < start || a.stride == 0 {
                        continue;
                    }
                    let k = u64::from((offset - start) / a.stride);
                    if k >= a.count() {
                        continue;
                    }
                    let prefix = format!("{prefix}{}{}", a.name, a.index_text(k));
                    let base = start.wrapping_add(a.element_offset(k));
                    if let Some(found) = a.element.holding_in(space, offset, &prefix, base) {
                        return Some(found);
                    }
                }
            }
        }
        None
    }
}

/// The index text of element `k` (row-major, from 0) of an array of dimensions `dims`
/// (`(lo, hi)` each): `[3]`, `[1,2]`. The one spelling of element names, which
/// [`Symbols::find`] parses back.
pub fn index_text(dims: &[(i64, i64)], k: u64) -> String {
    let mut indices = vec![0i64; dims.len()];
    let mut rest = k;
    for (d, &(lo, hi)) in dims.iter().enumerate().rev() {
        let len = (hi - lo + 1).max(1) as u64;
        indices[d] = lo + (rest % len) as i64;
        rest /= len;
    }
    let text: Vec<String> = indices.iter().map(i64::to_string).collect();
    format!("[{}]", text.join(","))
}

/// Element `k` (row-major, from 0) of an array of dimensions `dims` for the index text at the
/// start of `given` (whitespace removed), and what follows it: the indices spelled as
/// [`index_text`] spells them, in bounds. The retain files' element names of version 3
/// (`main.buf[3]`) are read back with it.
pub fn parse_index<'g>(dims: &[(i64, i64)], given: &'g str) -> Option<(u64, &'g str)> {
    let mut rest = given.strip_prefix('[')?;
    let mut k = 0u64;
    for (d, &(lo, hi)) in dims.iter().enumerate() {
        let last = d + 1 == dims.len();
        let end = rest.find(if last { ']' } else { ',' })?;
        let text = &rest[..end];
        let index: i64 = text.parse().ok()?;
        if index.to_string() != text || index < lo || index > hi {
            return None;
        }
        k = k * (hi - lo + 1) as u64 + (index - lo) as u64;
        rest = &rest[end + 1..];
    }
    Some((k, rest))
}

/// Levenshtein distance, `a` compared case-insensitively with the lowercase `b`.
pub(crate) fn edit_distance(a: &[u8], b: &[u8]) -> usize {
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, &x) in a.iter().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &y) in b.iter().enumerate() {
            let above = row[j + 1];
            let cost = usize::from(x.to_ascii_lowercase() != y);
            row[j + 1] = (diagonal + cost).min(above + 1).min(row[j] + 1);
            diagonal = above;
        }
    }
    row[b.len()]
}

/// `s` of an element whose name starts `prefix` and whose place starts at `base`.
fn placed(s: &Symbol, prefix: &str, base: u32) -> Symbol {
    Symbol {
        name: format!("{prefix}{}", s.name),
        at: Pointer { space: s.at.space, offset: base.wrapping_add(s.at.offset) },
        ..s.clone()
    }
}

/// Whether `given` names `declared`: case-insensitive, whitespace ignored on both sides.
pub fn names_match(declared: &str, given: &str) -> bool {
    strip_name(declared, given).is_some_and(|rest| rest.chars().all(char::is_whitespace))
}

/// What follows `declared` at the start of `given` (case-insensitive, whitespace ignored).
fn strip_name<'g>(declared: &str, given: &'g str) -> Option<&'g str> {
    let mut rest = given;
    for want in declared.chars().filter(|c| !c.is_whitespace()) {
        rest = rest.trim_start();
        let mut chars = rest.chars();
        let got = chars.next()?;
        if !got.eq_ignore_ascii_case(&want) {
            return None;
        }
        rest = chars.as_str();
    }
    Some(rest.trim_start())
}

impl From<Vec<Symbol>> for Symbols {
    fn from(symbols: Vec<Symbol>) -> Symbols {
        symbols.into_iter().collect()
    }
}

impl FromIterator<Symbol> for Symbols {
    fn from_iter<I: IntoIterator<Item = Symbol>>(iter: I) -> Symbols {
        let mut symbols = Symbols::default();
        for symbol in iter {
            symbols.push(symbol);
        }
        symbols
    }
}

impl<'a> IntoIterator for &'a Symbols {
    type Item = Symbol;
    type IntoIter = Iter<'a>;

    fn into_iter(self) -> Iter<'a> {
        self.iter()
    }
}

/// Every leaf of a [`Symbols`], by value ([`Symbols::iter`]).
#[derive(Debug)]
pub struct Iter<'a> {
    stack: Vec<Frame<'a>>,
}

#[derive(Debug)]
enum Frame<'a> {
    /// Entries in turn; their names follow `prefix`, their places `base`.
    List { entries: &'a [Entry], next: usize, prefix: String, base: u32 },
    /// An array's elements in turn.
    Elements { array: &'a ArraySymbol, next: u64, prefix: String, base: u32 },
}

impl<'a> Frame<'a> {
    /// Top-level entries: their names and places as they are.
    fn list(entries: &'a [Entry]) -> Frame<'a> {
        Frame::List { entries, next: 0, prefix: String::new(), base: 0 }
    }
}

impl Iterator for Iter<'_> {
    type Item = Symbol;

    fn next(&mut self) -> Option<Symbol> {
        loop {
            let pushed = match self.stack.last_mut()? {
                Frame::List { entries, next, prefix, base } => match entries.get(*next) {
                    None => None,
                    Some(entry) => {
                        *next += 1;
                        match entry {
                            Entry::Leaf(s) => return Some(placed(s, prefix, *base)),
                            Entry::Array(array) => Some(Frame::Elements {
                                array,
                                next: 0,
                                prefix: format!("{prefix}{}", array.name),
                                base: base.wrapping_add(array.at.offset),
                            }),
                        }
                    }
                },
                Frame::Elements { array, next, prefix, base } => {
                    if *next >= array.count() {
                        None
                    } else {
                        let k = *next;
                        *next += 1;
                        Some(Frame::List {
                            entries: &array.element.entries,
                            next: 0,
                            prefix: format!("{prefix}{}", array.index_text(k)),
                            base: base.wrapping_add(array.element_offset(k)),
                        })
                    }
                }
            };
            match pushed {
                Some(frame) => self.stack.push(frame),
                None => {
                    self.stack.pop();
                }
            }
        }
    }
}

/// A full name's parts, split at the dots outside brackets: `main.a[1,2].x` is `main`,
/// `a[1,2]`, `x` (the services name their nodes and metrics by them).
pub fn name_parts(name: &str) -> Vec<&str> {
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0usize, 0usize);
    for (i, c) in name.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth = depth.saturating_sub(1),
            '.' if depth == 0 => {
                parts.push(&name[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&name[start..]);
    parts.retain(|p| !p.is_empty());
    parts
}

/// The last device word a located variable of type `ty` at `at` reads, plus one; `None` for a
/// variable in variable memory (a service's copy of device memory must reach it).
pub fn device_words_end(ty: &crate::value::ValueType, at: Pointer) -> Option<u16> {
    let end = match at.space {
        Space::Word => at.offset + ty.elem().words(),
        Space::Bit => at.offset / 16 + 1,
        Space::Byte => at.offset / 2 + 1,
        Space::Var | Space::Frame | Space::Discard => return None,
    };
    Some(end.min(u32::from(u16::MAX)) as u16)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::{Elem, ValueType};

    fn leaf(name: &str, offset: u32, ty: ValueType) -> Symbol {
        let at = Pointer { space: Space::Var, offset };
        Symbol { name: name.into(), ty, at, retain: false, constant: false }
    }

    /// `main.n : INT` at 0, then `main.a : ARRAY[1..3, -1..0] OF STRUCT x : INT; m :
    /// ARRAY[1..2] OF BYTE END_STRUCT` at 2 (4 bytes an element), then `main.z` at 26.
    fn table() -> Symbols {
        let mut element = Symbols::default();
        element.push(leaf(".x", 0, ValueType::Signed(Elem::I16)));
        let mut inner = Symbols::default();
        inner.push(leaf("", 0, ValueType::Unsigned(Elem::U8)));
        element.push_array(ArraySymbol {
            name: ".m".into(),
            dims: vec![(1, 2)],
            at: Pointer { space: Space::Var, offset: 2 },
            stride: 1,
            element: inner,
        });
        let mut symbols = Symbols::default();
        symbols.push(leaf("main.n", 0, ValueType::Signed(Elem::I16)));
        symbols.push_array(ArraySymbol {
            name: "main.a".into(),
            dims: vec![(1, 3), (-1, 0)],
            at: Pointer { space: Space::Var, offset: 2 },
            stride: 4,
            element,
        });
        symbols.push(leaf("main.z", 26, ValueType::Bool));
        symbols
    }

    #[test]
    fn iterates_every_leaf_in_declaration_order() {
        let symbols = table();
        let all: Vec<(String, u32)> = symbols.iter().map(|s| (s.name, s.at.offset)).collect();
        assert_eq!(all.len(), symbols.len());
        assert_eq!(symbols.len(), 1 + 6 * 3 + 1);
        assert_eq!(all[0], ("main.n".into(), 0));
        assert_eq!(all[1], ("main.a[1,-1].x".into(), 2));
        assert_eq!(all[2], ("main.a[1,-1].m[1]".into(), 4));
        assert_eq!(all[3], ("main.a[1,-1].m[2]".into(), 5));
        assert_eq!(all[4], ("main.a[1,0].x".into(), 6));
        assert_eq!(all[18], ("main.a[3,0].m[2]".into(), 25));
        assert_eq!(all[19], ("main.z".into(), 26));
    }

    #[test]
    fn finds_exactly_the_names_the_expansion_has() {
        let symbols = table();
        for s in symbols.iter() {
            assert_eq!(symbols.find(&s.name).as_ref(), Some(&s), "{}", s.name);
            let shouted = s.name.to_ascii_uppercase().replace('[', " [ ");
            assert_eq!(symbols.find(&shouted).map(|f| f.name), Some(s.name));
        }
        for wrong in
            ["main.a[01,0].x", "main.a[4,0].x", "main.a[1,1].x", "main.a[1].x", "main.a[1,0]"]
        {
            assert_eq!(symbols.find(wrong), None, "{wrong}");
        }
        assert_eq!(symbols.find("main.a[+1,0].x"), None);
        assert_eq!(symbols.find("main.a[1,0].m[2]x"), None);
    }

    #[test]
    fn expands_only_the_entries_a_prefix_may_name() {
        let symbols = table();
        let names = |prefix| -> Vec<String> {
            symbols.may_start_with(prefix).map(|s| s.name).collect::<Vec<_>>()
        };
        assert_eq!(names("main.z"), ["main.z"]);
        assert_eq!(names("MAIN.A [2,0]").len(), 18, "the whole array, which holds it");
        assert_eq!(names("main").len(), symbols.len());
        assert!(names("other").is_empty());
    }

    #[test]
    fn finds_the_leaf_holding_a_place() {
        let symbols = table();
        for s in symbols.iter() {
            assert_eq!(symbols.holding(Space::Var, s.at.offset).map(|f| f.name), Some(s.name));
        }
        assert_eq!(
            symbols.holding(Space::Var, 7).map(|f| f.name).as_deref(),
            Some("main.a[1,0].x")
        );
        assert_eq!(symbols.holding(Space::Var, 27), None);
        assert_eq!(symbols.holding(Space::Word, 0), None);
    }
}
