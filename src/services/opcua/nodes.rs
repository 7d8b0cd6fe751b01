//! The address space's plan, independent of the OPC UA stack's node store: which node every
//! Structured Text variable becomes (its node id, its parent, its browse name, whether clients
//! may write it) (docs/OPCUA.md, "Node ids"). How its values look is [`super::values`]'s.
//!
//! Node ids are strings of the variable's full name as `plcctl get` names it
//! (`main.counter`, `main.axis.pos`, `main.buf[3]`), in plcd's namespace: they depend on the
//! names alone, so they are the same after a restart and in every project that keeps the name.

use std::collections::HashSet;

use opcua::types::DataTypeId;

use super::values::data_type;
use crate::config::EuRange;
use crate::project::OpcuaNames;
use crate::symbols::Symbols;
use crate::value::{Pointer, ValueType};

/// The status variables, `Status.<name>`, and their types.
pub const STATUS_NODES: [(&str, DataTypeId); 7] = [
    ("Mode", DataTypeId::String),
    ("ErrorCode", DataTypeId::String),
    ("ScanTimeLast", DataTypeId::Double),
    ("ScanTimeMin", DataTypeId::Double),
    ("ScanTimeMax", DataTypeId::Double),
    ("Scans", DataTypeId::UInt64),
    ("KeySwitch", DataTypeId::String),
];

/// The node id of the folder of the program instances.
pub const PROGRAMS: &str = "Programs";
/// The node id of the status folder; its variables are `Status.<name>`.
pub const STATUS: &str = "Status";
/// The node id of the PLC object under Objects.
pub const PLC: &str = "PLC";
/// The node id of the folder of the device ranges (`[[opcua.devices]]`); a device's is
/// `Devices.D00100`.
pub const DEVICES: &str = "Devices";

/// One variable node of a program's variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Leaf {
    /// Its node id's string: the variable's full name.
    pub id: String,
    /// The node id of the object it sits in.
    pub parent: String,
    /// Its browse and display name: the last part of the name (`pos`, `buf[3]`).
    pub browse: String,
    pub ty: ValueType,
    pub at: Pointer,
    /// `[opcua] writable` names it (or its `[[opcua.devices]]` range is writable): sessions of
    /// the operator role and up may write it.
    pub writable: bool,
    /// A device of `[[opcua.devices]]`, not a program's variable: written as a device.
    pub device: bool,
    /// `[[opcua.analog]]` gives it an engineering range: an analog item (OPC UA Part 8
    /// `AnalogItemType`) with an `EURange` property, which percent deadbands need.
    pub range: Option<EuRange>,
}

/// An object node: a program instance, a struct or FB instance, an array's element of structs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    pub id: String,
    pub parent: String,
    pub browse: String,
}

/// An array of elementary values as one variable (`main.table`, an `Int16[4]`; `main.grid`, an
/// `Int16[2,3]`; an array of arrays as the array of its dimensions), beside the variables of
/// its elements (`main.table[1]`, `main.grid[1,2]` …), which it is read from and written
/// through.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayNode {
    pub id: String,
    pub parent: String,
    pub browse: String,
    /// Its elements' indices in [`Plan::leaves`], in index order (row-major: the last index
    /// varies fastest, as OPC UA flattens a multi-dimensional array).
    pub elements: Vec<usize>,
    /// The length of each dimension: one for a one-dimensional array.
    pub dimensions: Vec<u32>,
    /// Every element writable.
    pub writable: bool,
}

/// The nodes of a project's variables.
#[derive(Debug, Default)]
pub struct Plan {
    /// Parents before their children.
    pub objects: Vec<Object>,
    pub leaves: Vec<Leaf>,
    pub arrays: Vec<ArrayNode>,
    /// Variables left out past `max_nodes`.
    pub left_out: usize,
    /// Variables not served at all: references (a place in memory means nothing to a client)
    /// and names whose node id another node has.
    pub unserved: usize,
}

impl Plan {
    /// The plan of `symbols`, at most `max_nodes` variables, in declaration order; the
    /// variables `names` makes writable writable, those it gives an engineering range analog
    /// items ([`crate::project::Project::opcua_names`]).
    pub fn of(symbols: &Symbols, max_nodes: usize, names: &OpcuaNames) -> Plan {
        let mut plan = Plan::default();
        let mut taken: HashSet<String> =
            [PLC, PROGRAMS, STATUS, DEVICES].iter().map(|s| s.to_string()).collect();
        taken.extend(STATUS_NODES.iter().map(|(name, _)| status_id(name)));
        for symbol in symbols.iter() {
            if data_type(&symbol.ty).is_none() {
                plan.unserved += 1;
                continue;
            }
            if plan.leaves.len() >= max_nodes {
                plan.left_out += 1;
                continue;
            }
            let parts = split(&symbol.name);
            let Some((last, parents)) = parts.split_last() else {
                plan.unserved += 1;
                continue;
            };
            // A program instance named as one of plcd's own objects (`Status`, `PLC`,
            // `Programs`) would put its variables among the PLC's: not served.
            let reserved = [PLC, PROGRAMS, STATUS, DEVICES].iter().any(|r| parts[0] == *r);
            if reserved || taken.contains(&symbol.name) {
                plan.unserved += 1;
                continue;
            }
            let mut parent = PROGRAMS.to_string();
            let mut id = String::new();
            for part in parents {
                if !id.is_empty() {
                    id.push('.');
                }
                id.push_str(part);
                if taken.insert(id.clone()) {
                    let object =
                        Object { id: id.clone(), parent: parent.clone(), browse: part.to_string() };
                    plan.objects.push(object);
                }
                parent.clone_from(&id);
            }
            taken.insert(symbol.name.clone());
            plan.leaves.push(Leaf {
                id: symbol.name.clone(),
                parent,
                browse: last.to_string(),
                ty: symbol.ty.clone(),
                at: symbol.at,
                writable: names.writable.contains(&symbol.name),
                device: false,
                range: names.analog.get(&symbol.name).copied(),
            });
        }
        plan.arrays = arrays(&plan.leaves, &taken);
        plan
    }
}

impl Plan {
    /// The devices of `ranges` as variables of the `Devices` folder (after the program
    /// variables): a word an `INT`, a bit a `BOOL`, read from the device memory of the copy.
    pub fn with_devices(mut self, ranges: &[crate::config::OpcuaDevices]) -> Plan {
        for range in ranges {
            for address in range.addresses() {
                let Some((ty, at)) = address.served() else { continue };
                let name = address.to_string();
                self.leaves.push(Leaf {
                    id: device_id(&name),
                    parent: DEVICES.to_string(),
                    browse: name,
                    ty,
                    at,
                    writable: range.writable,
                    device: true,
                    range: None,
                });
            }
        }
        self
    }
}

/// The node id string of a device: `Devices.D00100`.
pub fn device_id(device: &str) -> String {
    format!("{DEVICES}.{device}")
}

/// An element's name split into its array's name and its indices: `grid[1,2]` and `aa[1][2]`
/// are `grid`, `aa` and `[1, 2]`.
fn element_indices(browse: &str) -> Option<(&str, Vec<i64>)> {
    let (base, index) = browse.strip_suffix(']')?.split_once('[')?;
    if base.is_empty() {
        return None;
    }
    let indices: Option<Vec<i64>> =
        index.split("][").flat_map(|part| part.split(',')).map(|i| i.parse().ok()).collect();
    Some((base, indices?))
}

/// The lengths of the dimensions of an array whose elements, in order, have `indices`: `None`
/// unless they are every index of those dimensions, row-major, each once.
fn dimensions_of(indices: &[Vec<i64>]) -> Option<Vec<u32>> {
    let first = indices.first()?;
    let mut dims = Vec::with_capacity(first.len());
    for d in 0..first.len() {
        let hi = indices.iter().map(|i| i[d]).max()?;
        dims.push(u32::try_from(hi - first[d] + 1).ok()?);
    }
    let count: u64 = dims.iter().map(|&d| u64::from(d)).product();
    if count != indices.len() as u64 {
        return None;
    }
    // Element k of a row-major array: its index in each dimension from k.
    let row_major = indices.iter().enumerate().all(|(k, index)| {
        let mut rest = k as u64;
        (0..dims.len()).rev().all(|d| {
            let len = u64::from(dims[d]);
            let at = first[d] + (rest % len) as i64;
            rest /= len;
            index[d] == at
        })
    });
    row_major.then_some(dims)
}

/// The arrays of elementary values among `leaves`: runs of consecutive leaves of one parent
/// named `base[indices]` with as many indices each, of one type, holding every index of their
/// dimensions in row-major order; `taken` are the node ids in use.
fn arrays(leaves: &[Leaf], taken: &HashSet<String>) -> Vec<ArrayNode> {
    struct Run<'a> {
        base: &'a str,
        elements: Vec<usize>,
        indices: Vec<Vec<i64>>,
    }
    let mut arrays: Vec<ArrayNode> = Vec::new();
    let close = |run: Option<Run>, arrays: &mut Vec<ArrayNode>| {
        let Some(Run { base, elements, indices }) = run else { return };
        let Some(dimensions) = dimensions_of(&indices) else { return };
        let first = &leaves[elements[0]];
        let id = if first.parent == PROGRAMS {
            base.to_string()
        } else {
            format!("{}.{base}", first.parent)
        };
        if taken.contains(&id) {
            return;
        }
        arrays.push(ArrayNode {
            id,
            parent: first.parent.clone(),
            browse: base.to_string(),
            writable: elements.iter().all(|&e| leaves[e].writable),
            elements,
            dimensions,
        });
    };
    let mut run: Option<Run> = None;
    for (i, leaf) in leaves.iter().enumerate() {
        let named = element_indices(&leaf.browse);
        let continues = match (&run, &named) {
            (Some(r), Some((base, index))) => {
                let last = &leaves[*r.elements.last().unwrap_or(&i)];
                r.base == *base
                    && r.indices[0].len() == index.len()
                    && last.parent == leaf.parent
                    && last.ty == leaf.ty
                    && r.elements.last() == Some(&(i - 1))
            }
            _ => false,
        };
        if continues {
            if let (Some(r), Some((_, index))) = (&mut run, named) {
                r.elements.push(i);
                r.indices.push(index);
            }
            continue;
        }
        close(run.take(), &mut arrays);
        run = named.map(|(base, index)| Run { base, elements: vec![i], indices: vec![index] });
    }
    close(run, &mut arrays);
    arrays
}

/// What changes in the address space from one plan to the next (a reload, a `plcctl load`, an
/// online change): the nodes of the names both plans have stay as they are, so a client's node
/// ids and subscriptions of a variable the new project keeps go on working.
#[derive(Debug, Default, PartialEq)]
pub struct Changes {
    /// Variables gone, or changed in their OPC UA type or in being writable (they come back in
    /// `add_leaves`).
    pub remove_leaves: Vec<String>,
    /// Objects gone, children before their parents.
    pub remove_objects: Vec<String>,
    /// New objects, parents before their children.
    pub add_objects: Vec<Object>,
    pub add_leaves: Vec<Leaf>,
    /// Array variables gone or changed (length, type, writable), and new ones (with the new
    /// plan's element indices).
    pub remove_arrays: Vec<String>,
    pub add_arrays: Vec<ArrayNode>,
}

impl Plan {
    /// The changes from this plan to `new`.
    pub fn changes_to(&self, new: &Plan) -> Changes {
        use std::collections::HashMap;
        // The same node: the same OPC UA type (an enumeration: the same names too, which its
        // node carries), as writable, with the same engineering range, in the same object.
        let names = |l: &Leaf| match &l.ty {
            ValueType::Enum { values, .. } => Some(values.clone()),
            _ => None,
        };
        let same = |a: &Leaf, b: &Leaf| {
            data_type(&a.ty) == data_type(&b.ty)
                && names(a) == names(b)
                && a.writable == b.writable
                && a.range == b.range
                && a.parent == b.parent
        };
        let old_leaves: HashMap<&str, &Leaf> =
            self.leaves.iter().map(|l| (l.id.as_str(), l)).collect();
        let new_leaves: HashMap<&str, &Leaf> =
            new.leaves.iter().map(|l| (l.id.as_str(), l)).collect();
        let old_objects: HashSet<&str> = self.objects.iter().map(|o| o.id.as_str()).collect();
        let new_objects: HashSet<&str> = new.objects.iter().map(|o| o.id.as_str()).collect();
        let mut remove_objects: Vec<&Object> =
            self.objects.iter().filter(|o| !new_objects.contains(o.id.as_str())).collect();
        // Parents come before their children in a plan: reversed, children first.
        remove_objects.reverse();
        let array_key = |plan: &Plan, a: &ArrayNode| {
            let first = &plan.leaves[a.elements[0]];
            (a.id.clone(), a.dimensions.clone(), data_type(&first.ty), names(first), a.writable)
        };
        let old_arrays: HashSet<_> = self.arrays.iter().map(|a| array_key(self, a)).collect();
        let new_arrays: HashSet<_> = new.arrays.iter().map(|a| array_key(new, a)).collect();
        Changes {
            remove_arrays: self
                .arrays
                .iter()
                .filter(|a| !new_arrays.contains(&array_key(self, a)))
                .map(|a| a.id.clone())
                .collect(),
            add_arrays: new
                .arrays
                .iter()
                .filter(|a| !old_arrays.contains(&array_key(new, a)))
                .cloned()
                .collect(),
            remove_leaves: self
                .leaves
                .iter()
                .filter(|l| !new_leaves.get(l.id.as_str()).is_some_and(|n| same(l, n)))
                .map(|l| l.id.clone())
                .collect(),
            remove_objects: remove_objects.into_iter().map(|o| o.id.clone()).collect(),
            add_objects: new
                .objects
                .iter()
                .filter(|o| !old_objects.contains(o.id.as_str()))
                .cloned()
                .collect(),
            add_leaves: new
                .leaves
                .iter()
                .filter(|l| !old_leaves.get(l.id.as_str()).is_some_and(|o| same(o, l)))
                .cloned()
                .collect(),
        }
    }
}

/// The last device word a located leaf reads, plus one; `None` for a leaf in variable memory.
pub fn device_end(leaf: &Leaf) -> Option<u16> {
    crate::symbols::device_words_end(&leaf.ty, leaf.at)
}

/// The node id string of a status variable: `Status.Mode`.
pub fn status_id(name: &str) -> String {
    format!("{STATUS}.{name}")
}

/// A full name's parts ([`crate::symbols::name_parts`]).
pub fn split(name: &str) -> Vec<&str> {
    crate::symbols::name_parts(name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// The names of a config whose `writable` lists `names`.
    fn writing(names: &BTreeSet<String>) -> OpcuaNames {
        OpcuaNames { writable: names.clone(), ..OpcuaNames::default() }
    }
    use crate::value::{Elem, Space, Symbol};

    fn symbol(name: &str, ty: ValueType, offset: u32) -> Symbol {
        Symbol {
            name: name.into(),
            ty,
            at: Pointer { space: Space::Var, offset },
            retain: false,
            constant: false,
        }
    }

    #[test]
    fn names_split_at_dots_outside_brackets() {
        assert_eq!(split("main.counter"), ["main", "counter"]);
        assert_eq!(split("main.a[1,2].x"), ["main", "a[1,2]", "x"]);
        assert_eq!(split("main.m[1][2]"), ["main", "m[1][2]"]);
        assert_eq!(split("gvl.t[a.b]"), ["gvl", "t[a.b]"], "a dot inside brackets stays");
    }

    #[test]
    fn node_ids_are_the_full_names_under_objects_of_their_prefixes() {
        let mut symbols = Symbols::default();
        symbols.push(symbol("main.counter", ValueType::Signed(Elem::I32), 0));
        symbols.push(symbol("main.axis.pos", ValueType::Real(Elem::F64), 8));
        symbols.push(symbol("main.axis.ok", ValueType::Bool, 16));
        symbols.push(symbol("main.p", ValueType::Reference { type_name: "REF_TO INT".into() }, 24));
        symbols.push(symbol("other.buf[1]", ValueType::Unsigned(Elem::U8), 32));
        let plan = Plan::of(&symbols, 100, &OpcuaNames::default());
        let ids: Vec<(&str, &str, &str)> = plan
            .leaves
            .iter()
            .map(|l| (l.id.as_str(), l.parent.as_str(), l.browse.as_str()))
            .collect();
        assert_eq!(
            ids,
            [
                ("main.counter", "main", "counter"),
                ("main.axis.pos", "main.axis", "pos"),
                ("main.axis.ok", "main.axis", "ok"),
                ("other.buf[1]", "other", "buf[1]"),
            ]
        );
        let objects: Vec<(&str, &str)> =
            plan.objects.iter().map(|o| (o.id.as_str(), o.parent.as_str())).collect();
        assert_eq!(
            objects,
            [("main", "Programs"), ("main.axis", "main"), ("other", "Programs")],
            "each object once, its parent before it"
        );
        assert_eq!((plan.unserved, plan.left_out), (1, 0), "the reference is not served");
        // The same names give the same ids, whatever else the project holds.
        let mut fewer = Symbols::default();
        fewer.push(symbol("main.axis.pos", ValueType::Real(Elem::F64), 0));
        assert_eq!(Plan::of(&fewer, 100, &OpcuaNames::default()).leaves[0].id, "main.axis.pos");
    }

    #[test]
    fn a_new_plan_keeps_the_nodes_of_the_names_it_keeps() {
        let plan = |list: &[(&str, ValueType, bool)]| {
            let mut symbols = Symbols::default();
            let mut writable = BTreeSet::new();
            for (i, (name, ty, w)) in list.iter().enumerate() {
                symbols.push(symbol(name, ty.clone(), 8 * i as u32));
                if *w {
                    writable.insert(name.to_string());
                }
            }
            Plan::of(&symbols, 100, &writing(&writable))
        };
        let int = ValueType::Signed(Elem::I16);
        let old = plan(&[
            ("main.kept", int.clone(), false),
            ("main.axis.pos", ValueType::Real(Elem::F64), false),
            ("main.retyped", int.clone(), false),
            ("main.now_writable", int.clone(), false),
            ("main.gone", int.clone(), false),
            ("main.text", ValueType::String { cap: 10 }, false),
        ]);
        let new = plan(&[
            ("main.text", ValueType::String { cap: 80 }, false),
            ("main.kept", int.clone(), false),
            ("main.retyped", ValueType::Signed(Elem::I32), false),
            ("main.now_writable", int.clone(), true),
            ("main.added", int.clone(), false),
            ("other.x.y", int.clone(), false),
        ]);
        let changes = old.changes_to(&new);
        assert_eq!(
            changes.remove_leaves,
            ["main.axis.pos", "main.retyped", "main.now_writable", "main.gone"],
            "a STRING's new length and a new place keep the node: the type served is the same"
        );
        assert_eq!(changes.remove_objects, ["main.axis"]);
        let added: Vec<&str> = changes.add_objects.iter().map(|o| o.id.as_str()).collect();
        assert_eq!(added, ["other", "other.x"], "parents first");
        let added: Vec<&str> = changes.add_leaves.iter().map(|l| l.id.as_str()).collect();
        assert_eq!(added, ["main.retyped", "main.now_writable", "main.added", "other.x.y"]);
        assert_eq!(new.changes_to(&new), Changes::default(), "the same plan changes nothing");
    }

    #[test]
    fn arrays_of_values_are_array_variables_too() {
        let int = ValueType::Signed(Elem::I16);
        let mut symbols = Symbols::default();
        let names = [
            "main.buf[1]",
            "main.buf[2]",
            "main.buf[3]",
            "main.grid[1,1]",
            "main.grid[1,2]",
            "main.grid[1,3]",
            "main.grid[2,1]",
            "main.grid[2,2]",
            "main.grid[2,3]",
            "main.slots[1].n",
            "main.slots[2].n",
            "main.m[1][0]",
            "main.m[1][1]",
            "main.m[2][0]",
            "main.m[2][1]",
            "main.alone[0]",
            "main.cut[1,1]",
            "main.cut[1,2]",
            "main.cut[2,1]",
            "other.buf[5]",
            "other.buf[6]",
        ];
        for (i, name) in names.iter().enumerate() {
            symbols.push(symbol(name, int.clone(), 2 * i as u32));
        }
        let writable = BTreeSet::from(["main.buf[1]".to_string(), "main.buf[2]".to_string()]);
        let plan = Plan::of(&symbols, 100, &writing(&writable));
        // (id, browse name, elements, dimensions, writable)
        type Seen<'a> = (&'a str, &'a str, Vec<usize>, &'a [u32], bool);
        let arrays: Vec<Seen> = plan
            .arrays
            .iter()
            .map(|a| {
                let (id, browse) = (a.id.as_str(), a.browse.as_str());
                assert_eq!(a.parent, id.split('.').next().unwrap());
                (id, browse, a.elements.clone(), a.dimensions.as_slice(), a.writable)
            })
            .collect();
        assert_eq!(
            arrays,
            [
                ("main.buf", "buf", vec![0, 1, 2], &[3][..], false),
                ("main.grid", "grid", (3..9).collect(), &[2, 3][..], false),
                ("main.m", "m", (11..15).collect(), &[2, 2][..], false),
                ("main.alone", "alone", vec![15], &[1][..], false),
                ("other.buf", "buf", vec![19, 20], &[2][..], false),
            ],
            "not the arrays of structs, nor one missing an element (max_nodes); writable if all are"
        );
        let all = BTreeSet::from(["other.buf[5]".to_string(), "other.buf[6]".to_string()]);
        assert!(Plan::of(&symbols, 100, &writing(&all)).arrays[4].writable);
        // A changed length, or a changed shape of as many elements, replaces the array's node.
        let mut shorter = Symbols::default();
        shorter.push(symbol("main.buf[1]", int.clone(), 0));
        shorter.push(symbol("main.buf[2]", int.clone(), 2));
        for (i, name) in ["main.grid[1,1]", "main.grid[1,2]", "main.grid[2,1]", "main.grid[2,2]"]
            .iter()
            .chain(&["main.grid[3,1]", "main.grid[3,2]"])
            .enumerate()
        {
            shorter.push(symbol(name, int.clone(), 10 + 2 * i as u32));
        }
        let changes = Plan::of(&symbols, 100, &writing(&writable)).changes_to(&Plan::of(
            &shorter,
            100,
            &writing(&writable),
        ));
        assert!(changes.remove_arrays.contains(&"main.buf".to_string()));
        assert!(changes.remove_arrays.contains(&"main.grid".to_string()), "2x3 to 3x2");
        let added: Vec<&[u32]> =
            changes.add_arrays.iter().map(|a| a.dimensions.as_slice()).collect();
        assert_eq!(added, [&[2][..], &[3, 2][..]]);
    }

    #[test]
    fn device_ranges_are_variables_of_the_devices_folder() {
        use crate::config::OpcuaDevices;
        use crate::device::Address;
        let ranges = [
            OpcuaDevices { first: Address::parse("D00100").unwrap(), count: 2, writable: true },
            OpcuaDevices { first: Address::parse("M000F").unwrap(), count: 2, writable: false },
        ];
        let plan = Plan::of(&Symbols::default(), 10, &OpcuaNames::default()).with_devices(&ranges);
        let leaves: Vec<(&str, &str, &ValueType, Pointer, bool, bool)> = plan
            .leaves
            .iter()
            .map(|l| (l.id.as_str(), l.browse.as_str(), &l.ty, l.at, l.writable, l.device))
            .collect();
        let d = crate::device::layout::D;
        let m = crate::device::layout::M;
        let word = |offset| Pointer { space: Space::Word, offset };
        let bit = |offset| Pointer { space: Space::Bit, offset };
        let int = ValueType::Signed(Elem::I16);
        assert_eq!(
            leaves,
            [
                ("Devices.D00100", "D00100", &int, word(d + 100), true, true),
                ("Devices.D00101", "D00101", &int, word(d + 101), true, true),
                ("Devices.M000F", "M000F", &ValueType::Bool, bit(m * 16 + 15), false, true),
                ("Devices.M0010", "M0010", &ValueType::Bool, bit(m * 16 + 16), false, true),
            ]
        );
    }

    #[test]
    fn the_writable_names_and_no_other_are_writable() {
        let mut symbols = Symbols::default();
        symbols.push(symbol("main.setpoint", ValueType::Signed(Elem::I16), 0));
        symbols.push(symbol("main.level", ValueType::Signed(Elem::I16), 2));
        let writable = BTreeSet::from(["main.setpoint".to_string()]);
        let plan = Plan::of(&symbols, 10, &writing(&writable));
        let flags: Vec<(&str, bool)> =
            plan.leaves.iter().map(|l| (l.id.as_str(), l.writable)).collect();
        assert_eq!(flags, [("main.setpoint", true), ("main.level", false)]);
    }

    #[test]
    fn an_engineering_range_makes_an_analog_item_and_its_change_a_new_node() {
        use crate::config::EuRange;
        let mut symbols = Symbols::default();
        symbols.push(symbol("main.temp", ValueType::Real(Elem::F32), 0));
        symbols.push(symbol("main.level", ValueType::Signed(Elem::I16), 4));
        let ranged = |high: f64| OpcuaNames {
            analog: [("main.temp".to_string(), EuRange { low: 0.0, high })].into(),
            ..OpcuaNames::default()
        };
        let plan = Plan::of(&symbols, 10, &ranged(150.0));
        let ranges: Vec<_> = plan.leaves.iter().map(|l| (l.id.as_str(), l.range)).collect();
        let range = Some(EuRange { low: 0.0, high: 150.0 });
        assert_eq!(ranges, [("main.temp", range), ("main.level", None)]);
        // A changed range is a changed node (its property and type definition go with it).
        let changes = plan.changes_to(&Plan::of(&symbols, 10, &ranged(200.0)));
        assert_eq!(changes.remove_leaves, ["main.temp"]);
        assert!(plan.changes_to(&Plan::of(&symbols, 10, &ranged(150.0))).remove_leaves.is_empty());
    }

    #[test]
    fn max_nodes_leaves_the_rest_out_and_counts_them() {
        let mut symbols = Symbols::default();
        for i in 0..5 {
            symbols.push(symbol(&format!("main.v{i}"), ValueType::Bool, i));
        }
        let plan = Plan::of(&symbols, 3, &OpcuaNames::default());
        assert_eq!((plan.leaves.len(), plan.left_out), (3, 2));
    }

    #[test]
    fn a_program_named_as_plcds_own_objects_is_not_served() {
        let mut symbols = Symbols::default();
        symbols.push(symbol("Status.Mode", ValueType::Bool, 0));
        symbols.push(symbol("Status.other", ValueType::Bool, 1));
        symbols.push(symbol("PLC.x", ValueType::Bool, 2));
        symbols.push(symbol("main.x", ValueType::Bool, 3));
        let plan = Plan::of(&symbols, 10, &OpcuaNames::default());
        assert_eq!(plan.unserved, 3);
        let ids: Vec<&str> = plan.leaves.iter().map(|l| l.id.as_str()).collect();
        assert_eq!(ids, ["main.x"]);
    }
}
