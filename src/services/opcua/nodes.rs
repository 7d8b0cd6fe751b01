//! The address space's plan, independent of the OPC UA stack's node store: which node every
//! Structured Text variable becomes (its node id, its parent, its browse name), which OPC UA
//! built-in type an IEC type is served as, and a value read out of a mirror's copy of device and
//! variable memory as that type (docs/OPCUA.md, "Node ids" and "Types").
//!
//! Node ids are strings of the variable's full name as `plcctl get` names it
//! (`main.counter`, `main.axis.pos`, `main.buf[3]`), in plcd's namespace: they depend on the
//! names alone, so they are the same after a restart and in every project that keeps the name.

use std::collections::HashSet;

use opcua::types::{DataTypeId, DateTime, Variant};

use crate::symbols::Symbols;
use crate::value::{self, Elem, Pointer, ValueType};
use crate::vm::Vm;

/// The node id of the folder of the program instances.
pub const PROGRAMS: &str = "Programs";
/// The node id of the status folder; its variables are `Status.<name>`.
pub const STATUS: &str = "Status";
/// The node id of the PLC object under Objects.
pub const PLC: &str = "PLC";

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
}

/// An object node: a program instance, a struct or FB instance, an array's element of structs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Object {
    pub id: String,
    pub parent: String,
    pub browse: String,
}

/// The nodes of a project's variables.
#[derive(Debug, Default)]
pub struct Plan {
    /// Parents before their children.
    pub objects: Vec<Object>,
    pub leaves: Vec<Leaf>,
    /// Variables left out past `max_nodes`.
    pub left_out: usize,
    /// Variables not served at all: references (a place in memory means nothing to a client)
    /// and names whose node id another node has.
    pub unserved: usize,
}

impl Plan {
    /// The plan of `symbols`, at most `max_nodes` variables, in declaration order.
    pub fn of(symbols: &Symbols, max_nodes: usize) -> Plan {
        let mut plan = Plan::default();
        let mut taken: HashSet<String> =
            [PLC, PROGRAMS, STATUS].iter().map(|s| s.to_string()).collect();
        taken.extend(super::server::STATUS_NODES.iter().map(|(name, _)| status_id(name)));
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
            if taken.contains(&symbol.name) {
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
            });
        }
        plan
    }
}

/// The node id string of a status variable: `Status.Mode`.
pub fn status_id(name: &str) -> String {
    format!("{STATUS}.{name}")
}

/// A full name's parts: split at the dots outside brackets (`main.a[1,2].x` is `main`,
/// `a[1,2]`, `x`).
pub fn split(name: &str) -> Vec<&str> {
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

/// The OPC UA built-in type an IEC type is served as; `None`: not served (references).
pub fn data_type(ty: &ValueType) -> Option<DataTypeId> {
    Some(match ty {
        ValueType::Bool => DataTypeId::Boolean,
        ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => elem_type(*e),
        ValueType::Enum { base, .. } => elem_type(*base),
        ValueType::Time => DataTypeId::Duration,
        ValueType::Calendar(calendar) => match calendar.kind() {
            value::CalendarKind::Tod => DataTypeId::Duration,
            value::CalendarKind::Date | value::CalendarKind::Dt => DataTypeId::DateTime,
        },
        ValueType::Char | ValueType::WChar => DataTypeId::String,
        ValueType::String { .. } | ValueType::WString { .. } => DataTypeId::String,
        ValueType::Reference { .. } => return None,
    })
}

fn elem_type(elem: Elem) -> DataTypeId {
    match elem {
        Elem::Bool => DataTypeId::Boolean,
        Elem::I8 => DataTypeId::SByte,
        Elem::I16 => DataTypeId::Int16,
        Elem::I32 => DataTypeId::Int32,
        Elem::I64 => DataTypeId::Int64,
        Elem::U8 => DataTypeId::Byte,
        Elem::U16 => DataTypeId::UInt16,
        Elem::U32 => DataTypeId::UInt32,
        Elem::U64 => DataTypeId::UInt64,
        Elem::F32 => DataTypeId::Float,
        Elem::F64 => DataTypeId::Double,
    }
}

/// The value of a variable of type `ty` at `at`, read out of copies of device memory (`words`,
/// from word 0) and variable memory (`vars`), as its OPC UA type ([`data_type`]).
pub fn read(ty: &ValueType, at: Pointer, words: &[u16], vars: &[u8]) -> Variant {
    match ty {
        ValueType::String { .. } => Variant::from(value::decode_str(Vm::string_bytes_in(vars, at))),
        ValueType::WString { .. } => {
            let bytes = Vm::wstring_bytes_in(vars, at);
            let units = bytes.chunks_exact(2).map(|u| u16::from_le_bytes([u[0], u[1]]));
            let text: String = char::decode_utf16(units).map(|c| c.unwrap_or('\u{FFFD}')).collect();
            Variant::from(text)
        }
        _ => slot_variant(ty, Vm::read_value_in(words, vars, at, ty.elem())),
    }
}

/// A slot (as the VM stores a value of `ty`) as its OPC UA value.
pub fn slot_variant(ty: &ValueType, slot: u64) -> Variant {
    match ty {
        ValueType::Bool => Variant::from(slot != 0),
        ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => {
            elem_variant(*e, slot)
        }
        ValueType::Enum { base, .. } => elem_variant(*base, slot),
        // Nanoseconds, served as OPC UA's Duration: milliseconds in a Double.
        ValueType::Time => Variant::Double(slot as i64 as f64 / 1e6),
        ValueType::Calendar(calendar) => calendar_variant(*calendar, slot),
        ValueType::Char => Variant::from(value::decode_byte(slot as u8).to_string()),
        ValueType::WChar => {
            let c = char::decode_utf16([slot as u16]).next().and_then(Result::ok);
            Variant::from(c.unwrap_or('\u{FFFD}').to_string())
        }
        ValueType::String { .. } | ValueType::WString { .. } | ValueType::Reference { .. } => {
            Variant::Empty
        }
    }
}

fn elem_variant(elem: Elem, slot: u64) -> Variant {
    match elem {
        Elem::Bool => Variant::Boolean(slot != 0),
        Elem::I8 => Variant::SByte(slot as i8),
        Elem::I16 => Variant::Int16(slot as i16),
        Elem::I32 => Variant::Int32(slot as i32),
        Elem::I64 => Variant::Int64(slot as i64),
        Elem::U8 => Variant::Byte(slot as u8),
        Elem::U16 => Variant::UInt16(slot as u16),
        Elem::U32 => Variant::UInt32(slot as u32),
        Elem::U64 => Variant::UInt64(slot),
        Elem::F32 => Variant::Float(f32::from_bits(slot as u32)),
        Elem::F64 => Variant::Double(f64::from_bits(slot)),
    }
}

/// `DATE` and `DT` (seconds since 1970; their long forms nanoseconds) as a DateTime; `TOD`
/// (milliseconds since midnight; `LTOD` nanoseconds) as a Duration in milliseconds.
fn calendar_variant(calendar: value::Calendar, slot: u64) -> Variant {
    let ns = if calendar.is_long() {
        slot as i64
    } else {
        match calendar.kind() {
            value::CalendarKind::Tod => (slot as u32 as i64).saturating_mul(1_000_000),
            value::CalendarKind::Date | value::CalendarKind::Dt => {
                (slot as u32 as i64).saturating_mul(1_000_000_000)
            }
        }
    };
    match calendar.kind() {
        value::CalendarKind::Tod => Variant::Double(ns as f64 / 1e6),
        value::CalendarKind::Date | value::CalendarKind::Dt => {
            // OPC UA's DateTime counts 100 ns ticks from 1601-01-01.
            const TICKS_1601_TO_1970: i64 = 116_444_736_000_000_000;
            let ticks = (ns / 100).saturating_add(TICKS_1601_TO_1970);
            Variant::DateTime(Box::new(DateTime::from(ticks)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::{Space, Symbol};

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
        let plan = Plan::of(&symbols, 100);
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
        assert_eq!(Plan::of(&fewer, 100).leaves[0].id, "main.axis.pos");
    }

    #[test]
    fn max_nodes_leaves_the_rest_out_and_counts_them() {
        let mut symbols = Symbols::default();
        for i in 0..5 {
            symbols.push(symbol(&format!("main.v{i}"), ValueType::Bool, i));
        }
        let plan = Plan::of(&symbols, 3);
        assert_eq!((plan.leaves.len(), plan.left_out), (3, 2));
    }

    #[test]
    fn a_status_node_id_is_not_taken_by_a_variable() {
        let mut symbols = Symbols::default();
        symbols.push(symbol("Status.Mode", ValueType::Bool, 0));
        symbols.push(symbol("Status.other", ValueType::Bool, 1));
        let plan = Plan::of(&symbols, 10);
        assert_eq!(plan.unserved, 1);
        assert_eq!(plan.leaves.len(), 1);
        assert_eq!(plan.leaves[0].id, "Status.other");
        // Its object would be the status folder's id: it hangs under the folder it names.
        assert!(plan.objects.is_empty());
        assert_eq!(plan.leaves[0].parent, "Status");
    }

    #[test]
    fn iec_types_map_to_opc_ua_built_in_types() {
        use ValueType as T;
        let cases = [
            (T::Bool, DataTypeId::Boolean),
            (T::Signed(Elem::I8), DataTypeId::SByte),
            (T::Signed(Elem::I16), DataTypeId::Int16),
            (T::Signed(Elem::I32), DataTypeId::Int32),
            (T::Signed(Elem::I64), DataTypeId::Int64),
            (T::Unsigned(Elem::U8), DataTypeId::Byte),
            (T::Unsigned(Elem::U16), DataTypeId::UInt16),
            (T::Unsigned(Elem::U32), DataTypeId::UInt32),
            (T::Unsigned(Elem::U64), DataTypeId::UInt64),
            (T::Real(Elem::F32), DataTypeId::Float),
            (T::Real(Elem::F64), DataTypeId::Double),
            (T::String { cap: 10 }, DataTypeId::String),
            (T::WString { cap: 10 }, DataTypeId::String),
            (T::Time, DataTypeId::Duration),
            (T::Calendar(value::Calendar::Dt), DataTypeId::DateTime),
            (T::Calendar(value::Calendar::Tod), DataTypeId::Duration),
            (T::Enum { type_name: "E".into(), values: vec![], base: Elem::I16 }, DataTypeId::Int16),
        ];
        for (ty, expected) in cases {
            assert_eq!(data_type(&ty), Some(expected), "{ty:?}");
        }
        assert_eq!(data_type(&T::Reference { type_name: "REF_TO INT".into() }), None);
    }

    #[test]
    fn slots_become_their_opc_ua_values() {
        use ValueType as T;
        assert_eq!(slot_variant(&T::Bool, 1), Variant::Boolean(true));
        assert_eq!(slot_variant(&T::Signed(Elem::I16), 0xFFFF), Variant::Int16(-1));
        assert_eq!(slot_variant(&T::Unsigned(Elem::U64), u64::MAX), Variant::UInt64(u64::MAX));
        assert_eq!(slot_variant(&T::Real(Elem::F32), 2.5f32.to_bits().into()), Variant::Float(2.5));
        assert_eq!(slot_variant(&T::Time, 1_500_000_000), Variant::Double(1500.0), "T#1s500ms");
        let mode = T::Enum { type_name: "M".into(), values: vec![], base: Elem::I32 };
        assert_eq!(slot_variant(&mode, 5), Variant::Int32(5), "an enumeration as its integer");
        assert_eq!(slot_variant(&T::Char, u64::from(b'A')), Variant::from("A".to_string()));
        // DT#1970-01-02-00:00:00: one day of seconds after 1970.
        let Variant::DateTime(dt) = slot_variant(&T::Calendar(value::Calendar::Dt), 86_400) else {
            panic!("a DateTime")
        };
        assert_eq!(dt.as_chrono().timestamp(), 86_400);
    }

    #[test]
    fn values_are_read_out_of_the_copies() {
        let mut vars = vec![0u8; 16];
        vars[0..4].copy_from_slice(&42i32.to_le_bytes());
        // A STRING's characters up to their NUL.
        vars[4..7].copy_from_slice(b"abc");
        let at = |offset| Pointer { space: Space::Var, offset };
        assert_eq!(read(&ValueType::Signed(Elem::I32), at(0), &[], &vars), Variant::Int32(42));
        assert_eq!(
            read(&ValueType::String { cap: 8 }, at(4), &[], &vars),
            Variant::from("abc".to_string())
        );
        // A located variable reads its device words, low word first.
        let word = Pointer { space: Space::Word, offset: 1 };
        assert_eq!(
            read(&ValueType::Signed(Elem::I32), word, &[0, 0x5678, 0x1234], &vars),
            Variant::Int32(0x1234_5678)
        );
    }
}
