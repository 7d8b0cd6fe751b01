//! The retained Structured Text variables, leaf by leaf (docs/RETAIN.md): what the retain files
//! store of them (each leaf's declared name, type and bytes), what a copy at a scan boundary
//! takes of variable memory, and which leaves of another program are the same variable — the
//! same name (case-insensitive) and the same type — so that a changed program keeps exactly
//! those.
//!
//! A leaf is a [`Symbol`] declared `RETAIN` (or inside a retained instance) in variable memory:
//! an elementary variable, an array element, a struct member, an FB instance's variable.

use crate::lang::Variables;
use crate::symbols::Entry;
use crate::value::{Space, Symbol, ValueType};

/// One retained leaf.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RetainedLeaf {
    /// The full name with the spelling of its declarations: `main.count`, `main.t1.ET`.
    pub name: String,
    /// The lowercase name, what matching compares.
    key: String,
    /// The type as [`type_text`] writes it: `DINT`, `STRING[20]`, `Color(Red:=0,Green:=1)`.
    pub ty: String,
    /// Its byte offset in variable memory.
    pub at: u32,
    /// Its bytes.
    pub len: u32,
    /// Its byte offset in a copy ([`RetainedVariables::copy`]).
    pub pos: u32,
}

/// A program's retained leaves, built once per engine (off the real-time path).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RetainedVariables {
    /// In declaration order.
    leaves: Box<[RetainedLeaf]>,
    /// Indices of `leaves`, sorted by key.
    by_key: Box<[u32]>,
    /// The byte ranges of variable memory the leaves occupy, `(offset, len)`, increasing and
    /// merged: what a copy takes, range after range.
    ranges: Box<[(u32, u32)]>,
    bytes: usize,
}

/// A retained variable as a retain file holds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SavedVariable {
    pub name: String,
    pub ty: String,
    pub bytes: Vec<u8>,
}

/// What a restore from saved variables does: the leaves it restores, the saved variables it
/// drops, the leaves that keep their initial value.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RestorePlan {
    /// `(leaf index, saved index)`.
    pub restore: Vec<(usize, usize)>,
    /// Saved variables not restored, each with why: `main.old (DINT): not a RETAIN variable of
    /// the program`, `main.x (INT): now DINT`.
    pub dropped: Vec<String>,
    /// Names of retained leaves nothing was saved for.
    pub new: Vec<String>,
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

impl RetainedVariables {
    /// The retained leaves of `variables`.
    pub fn new(variables: &Variables) -> RetainedVariables {
        let size = variables.initial.len() as u64;
        // A reference is not saved: its offset means nothing to another layout of memory.
        let retained = |s: &Symbol| {
            s.retain && s.at.space == Space::Var && !matches!(s.ty, ValueType::Reference { .. })
        };
        // an array none of whose element's leaves is retained is not expanded
        let holds_retained = |e: &&Entry| match e {
            Entry::Leaf(s) => s.retain,
            Entry::Array(a) => a.element.iter().any(|s| s.retain),
        };
        let mut leaves: Vec<RetainedLeaf> = variables
            .symbols
            .entries()
            .iter()
            .filter(holds_retained)
            .flat_map(Entry::leaves)
            .filter(retained)
            .map(|s| RetainedLeaf {
                name: s.name.clone(),
                key: s.name.to_ascii_lowercase(),
                ty: type_text(&s.ty),
                at: s.at.offset,
                len: s.ty.bytes(),
                pos: 0,
            })
            .filter(|l| u64::from(l.at) + u64::from(l.len) <= size)
            .collect();
        let mut spans: Vec<(u32, u32)> = leaves.iter().map(|l| (l.at, l.at + l.len)).collect();
        spans.sort_unstable();
        let mut ranges: Vec<(u32, u32)> = Vec::new();
        for (start, end) in spans {
            match ranges.last_mut() {
                Some((o, l)) if *o + *l >= start => *l = (*l).max(end - *o),
                _ => ranges.push((start, end - start)),
            }
        }
        // The position of each range in a copy, then of each leaf.
        let mut starts = Vec::with_capacity(ranges.len());
        let mut pos = 0;
        for &(_, len) in &ranges {
            starts.push(pos);
            pos += len;
        }
        for leaf in &mut leaves {
            let r = ranges.partition_point(|&(o, _)| o <= leaf.at) - 1;
            leaf.pos = starts[r] + (leaf.at - ranges[r].0);
        }
        let mut by_key: Vec<u32> = (0..leaves.len() as u32).collect();
        by_key.sort_by(|&a, &b| leaves[a as usize].key.cmp(&leaves[b as usize].key));
        RetainedVariables {
            leaves: leaves.into_boxed_slice(),
            by_key: by_key.into_boxed_slice(),
            ranges: ranges.into_boxed_slice(),
            bytes: pos as usize,
        }
    }

    pub fn leaves(&self) -> &[RetainedLeaf] {
        &self.leaves
    }

    /// Bytes of a copy.
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    pub fn is_empty(&self) -> bool {
        self.leaves.is_empty()
    }

    /// Appends the retained bytes of variable memory `vars` to `into`, range after range.
    /// Allocates nothing when `into` has room for [`RetainedVariables::bytes`] more.
    pub fn copy(&self, vars: &[u8], into: &mut Vec<u8>) {
        for &(offset, len) in self.ranges.iter() {
            let (start, end) = (offset as usize, (offset + len) as usize);
            match vars.get(start..end) {
                Some(bytes) => into.extend_from_slice(bytes),
                None => into.resize(into.len() + len as usize, 0),
            }
        }
    }

    /// The bytes of `leaf` in a copy.
    pub fn leaf_in<'c>(&self, leaf: &RetainedLeaf, copy: &'c [u8]) -> &'c [u8] {
        let (start, end) = (leaf.pos as usize, (leaf.pos + leaf.len) as usize);
        copy.get(start..end).unwrap_or_default()
    }

    /// Calls `same(new, old)` for each leaf of `self` that `old` has too: the same name
    /// (case-insensitive) and type. Allocates nothing (a replacement engine calls it on the
    /// scan thread).
    pub fn for_each_same(
        &self,
        old: &RetainedVariables,
        mut same: impl FnMut(&RetainedLeaf, &RetainedLeaf),
    ) {
        let (mut i, mut j) = (0, 0);
        while i < self.by_key.len() && j < old.by_key.len() {
            let a = &self.leaves[self.by_key[i] as usize];
            let b = &old.leaves[old.by_key[j] as usize];
            match a.key.cmp(&b.key) {
                std::cmp::Ordering::Less => i += 1,
                std::cmp::Ordering::Greater => j += 1,
                std::cmp::Ordering::Equal => {
                    if a.ty == b.ty && a.len == b.len {
                        same(a, b);
                    }
                    i += 1;
                    j += 1;
                }
            }
        }
    }

    /// The leaf named `name` (case-insensitive).
    fn find(&self, name: &str) -> Option<usize> {
        let key = name.to_ascii_lowercase();
        let at = self.by_key.binary_search_by(|&i| self.leaves[i as usize].key.cmp(&key)).ok()?;
        Some(self.by_key[at] as usize)
    }

    /// What restoring `saved` (a retain file's variables) into these leaves does: a saved
    /// variable is restored into the leaf of the same name (case-insensitive) and type, with
    /// the leaf's byte length; any other is dropped; a leaf nothing is restored into keeps its
    /// initial value.
    pub fn plan_restore(&self, saved: &[SavedVariable]) -> RestorePlan {
        let mut plan = RestorePlan::default();
        let mut restored = vec![false; self.leaves.len()];
        for (s, var) in saved.iter().enumerate() {
            match self.find(&var.name) {
                Some(i) if restored[i] => {
                    plan.dropped.push(format!("{} ({}): saved twice", var.name, var.ty))
                }
                Some(i) => {
                    let leaf = &self.leaves[i];
                    if leaf.ty == var.ty && leaf.len as usize == var.bytes.len() {
                        restored[i] = true;
                        plan.restore.push((i, s));
                    } else if leaf.ty != var.ty {
                        plan.dropped.push(format!("{} ({}): now {}", var.name, var.ty, leaf.ty));
                    } else {
                        plan.dropped.push(format!(
                            "{} ({}): {} bytes saved, {} declared",
                            var.name,
                            var.ty,
                            var.bytes.len(),
                            leaf.len
                        ));
                    }
                }
                None => plan.dropped.push(format!(
                    "{} ({}): not a RETAIN variable of the program",
                    var.name, var.ty
                )),
            }
        }
        plan.new = (self.leaves.iter().zip(&restored))
            .filter(|(_, done)| !**done)
            .map(|(leaf, _)| leaf.name.clone())
            .collect();
        plan
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

    #[test]
    fn leaves_ranges_and_positions() {
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
        let names: Vec<&str> = r.leaves().iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["main.b", "main.a", "main.s", "main.p"], "declaration order");
        assert_eq!(&*r.ranges, &[(4, 4), (10, 6), (40, 1)]);
        assert_eq!(r.bytes(), 11);
        let pos: Vec<u32> = r.leaves().iter().map(|l| l.pos).collect();
        assert_eq!(pos, [4, 0, 6, 10]);
        let mut vars: Vec<u8> = (0..64).collect();
        vars[40] = 99;
        let mut copy = Vec::with_capacity(r.bytes());
        r.copy(&vars, &mut copy);
        assert_eq!(copy, [4, 5, 6, 7, 10, 11, 12, 13, 14, 15, 99]);
        assert_eq!(r.leaf_in(&r.leaves()[2], &copy), &[12, 13, 14, 15]);
        assert_eq!(r.leaves()[2].ty, "STRING[3]");
    }

    #[test]
    fn a_wstring_is_kept_whole_and_its_length_is_its_type() {
        let v = variables(vec![symbol("main.w", ValueType::WString { cap: 3 }, 20, true)]);
        let r = RetainedVariables::new(&v);
        // 3 code units and the 2-byte NUL: 8 bytes; another length is another type
        assert_eq!(&*r.ranges, &[(20, 8)]);
        assert_eq!(r.leaves()[0].ty, "WSTRING[3]");
    }

    #[test]
    fn references_are_not_saved() {
        let pointer = ValueType::Reference { type_name: "POINTER TO INT".into() };
        let v = variables(vec![
            symbol("main.n", ValueType::Signed(Elem::I16), 0, true),
            symbol("main.p", pointer, 8, true),
        ]);
        let r = RetainedVariables::new(&v);
        let names: Vec<&str> = r.leaves().iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["main.n"]);
        assert_eq!(&*r.ranges, &[(0, 2)]);
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
        let mut pairs = Vec::new();
        new.for_each_same(&old, |n, o| pairs.push((n.name.clone(), o.at, n.at)));
        assert_eq!(pairs, [("MAIN.Count".to_string(), 0, 20)]);

        let saved: Vec<SavedVariable> = old
            .leaves()
            .iter()
            .map(|l| SavedVariable {
                name: l.name.clone(),
                ty: l.ty.clone(),
                bytes: vec![1; l.len as usize],
            })
            .collect();
        let plan = new.plan_restore(&saved);
        assert_eq!(plan.restore, [(1, 0)]);
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
}
