//! IEC values as OPC UA values, both ways: which built-in type an IEC type is served as, a
//! value read out of a mirror's copies of device and variable memory as that type, and a value
//! a client writes as the text `plcctl set` takes (docs/OPCUA.md, "Types").
//!
//! A write goes through the request handler as a `set` does, so that every rule of `set` (the
//! type's range, a `STRING`'s length and characters, an enumeration's values) is decided in one
//! place; here a variant only becomes that text, through the same formatting `plcctl get`
//! answers with, which `set` reads back exactly.

use opcua::types::{DataTypeId, DateTime, StatusCode, Variant};

use crate::duration::ms_to_ns;
use crate::value::{self, Elem, Pointer, ValueType};
use crate::vm::Vm;

/// OPC UA's DateTime counts 100 ns ticks from 1601-01-01; plcd's calendar from 1970-01-01.
const TICKS_1601_TO_1970: i64 = 116_444_736_000_000_000;

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
    match Vm::text_in(ty, vars, at) {
        Some(text) => Variant::from(text),
        None => slot_variant(ty, Vm::read_value_in(words, vars, at, ty.elem())),
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
            let ticks = (ns / 100).saturating_add(TICKS_1601_TO_1970);
            Variant::DateTime(Box::new(DateTime::from(ticks)))
        }
    }
}

/// An array variable's value: `elements` (each as [`read`] gives it, row-major) as one OPC UA
/// array of `dimensions` (one: a one-dimensional array, without dimensions of its own); `None`
/// without elements, if they are not all of one type or not as many as the dimensions hold.
pub fn array(elements: Vec<Variant>, dimensions: &[u32]) -> Option<Variant> {
    let scalar = elements.first()?.scalar_type_id()?;
    let array = match dimensions {
        [_] => opcua::types::Array::new(scalar, elements).ok()?,
        _ => opcua::types::Array::new_multi(scalar, elements, dimensions).ok()?,
    };
    Some(Variant::Array(Box::new(array)))
}

/// The name of an enumeration's value as served (its integer in `variant`), as `plcctl get`
/// shows it (the number when no value has it); `None` for a variable of another type.
pub fn enum_text(ty: &ValueType, variant: &Variant) -> Option<String> {
    let ValueType::Enum { base, .. } = ty else { return None };
    Some(value::format(ty, elem_slot(*base, variant).ok()?))
}

/// The value a client writes to a variable of type `ty`, as the text `plcctl set` takes for it
/// (what `plcctl get` shows). `BadTypeMismatch`: a variant of another type than [`data_type`]
/// serves `ty` as; `BadOutOfRange`: a value no variable of the type can hold (a `TIME` beyond
/// ±292 years, a `TOD` past midnight, a date before 1970, a character a `STRING` cannot
/// store). What `set` itself refuses (a `STRING` too long, a number no enumeration value has)
/// it refuses with its reason.
pub fn written(ty: &ValueType, variant: &Variant) -> Result<plcd_ipc::Value, StatusCode> {
    let written = match variant {
        Variant::String(text) => value::text_written(ty, text.as_ref()),
        _ => None,
    };
    let text = match written {
        Some(text) => text.map_err(|_| StatusCode::BadOutOfRange)?,
        None => value::format(ty, variant_slot(ty, variant)?),
    };
    Ok(plcd_ipc::Value::Text(text))
}

/// The slot (as the VM stores it) of a variant written to a variable of type `ty`: the inverse
/// of [`slot_variant`].
fn variant_slot(ty: &ValueType, variant: &Variant) -> Result<u64, StatusCode> {
    let out_of_range = StatusCode::BadOutOfRange;
    match ty {
        ValueType::Bool => match variant {
            Variant::Boolean(b) => Ok(u64::from(*b)),
            _ => Err(StatusCode::BadTypeMismatch),
        },
        ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => {
            elem_slot(*e, variant)
        }
        ValueType::Enum { base, .. } => elem_slot(*base, variant),
        ValueType::Time => {
            let Variant::Double(ms) = variant else { return Err(StatusCode::BadTypeMismatch) };
            ms_to_ns(*ms).map(|ns| ns as u64).ok_or(out_of_range)
        }
        ValueType::Calendar(calendar) => match (calendar.kind(), variant) {
            (value::CalendarKind::Tod, Variant::Double(ms)) => {
                let ns = ms_to_ns(*ms).filter(|ns| (0..86_400_000_000_000).contains(ns));
                let ns = ns.ok_or(out_of_range)?;
                Ok(if calendar.is_long() { ns as u64 } else { (ns / 1_000_000) as u64 })
            }
            (value::CalendarKind::Date | value::CalendarKind::Dt, Variant::DateTime(at)) => {
                let ns = at
                    .checked_ticks()
                    .checked_sub(TICKS_1601_TO_1970)
                    .and_then(|ticks| ticks.checked_mul(100))
                    .ok_or(out_of_range)?;
                if calendar.is_long() {
                    // Unsigned from 1970: a date before it is no value of the type.
                    u64::try_from(ns).map_err(|_| out_of_range)
                } else {
                    let seconds = ns.div_euclid(1_000_000_000);
                    u32::try_from(seconds).map(u64::from).map_err(|_| out_of_range)
                }
            }
            _ => Err(StatusCode::BadTypeMismatch),
        },
        ValueType::Char
        | ValueType::WChar
        | ValueType::String { .. }
        | ValueType::WString { .. }
        | ValueType::Reference { .. } => Err(StatusCode::BadTypeMismatch),
    }
}

fn elem_slot(elem: Elem, variant: &Variant) -> Result<u64, StatusCode> {
    Ok(match (elem, variant) {
        (Elem::Bool, Variant::Boolean(v)) => u64::from(*v),
        (Elem::I8, Variant::SByte(v)) => *v as u64,
        (Elem::I16, Variant::Int16(v)) => *v as u64,
        (Elem::I32, Variant::Int32(v)) => *v as u64,
        (Elem::I64, Variant::Int64(v)) => *v as u64,
        (Elem::U8, Variant::Byte(v)) => u64::from(*v),
        (Elem::U16, Variant::UInt16(v)) => u64::from(*v),
        (Elem::U32, Variant::UInt32(v)) => u64::from(*v),
        (Elem::U64, Variant::UInt64(v)) => *v,
        (Elem::F32, Variant::Float(v)) => u64::from(v.to_bits()),
        (Elem::F64, Variant::Double(v)) => v.to_bits(),
        _ => return Err(StatusCode::BadTypeMismatch),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let at = |offset| Pointer { space: value::Space::Var, offset };
        assert_eq!(read(&ValueType::Signed(Elem::I32), at(0), &[], &vars), Variant::Int32(42));
        assert_eq!(
            read(&ValueType::String { cap: 8 }, at(4), &[], &vars),
            Variant::from("abc".to_string())
        );
        // A located variable reads its device words, low word first.
        let word = Pointer { space: value::Space::Word, offset: 1 };
        assert_eq!(
            read(&ValueType::Signed(Elem::I32), word, &[0, 0x5678, 0x1234], &vars),
            Variant::Int32(0x1234_5678)
        );
    }

    /// Every type: a value served, written back, becomes the text `set` reads to the same slot.
    #[test]
    fn a_value_read_and_written_back_is_the_same_value() {
        use ValueType as T;
        let mode = T::Enum {
            type_name: "MODE".into(),
            values: vec![("IDLE".into(), 0), ("RUN".into(), 5)],
            base: Elem::I32,
        };
        let cases: Vec<(ValueType, u64)> = vec![
            (T::Bool, 1),
            (T::Signed(Elem::I8), (-5i8) as u8 as u64),
            (T::Signed(Elem::I16), 0xFFFF),
            (T::Signed(Elem::I32), (-70_000i32) as u32 as u64),
            (T::Signed(Elem::I64), i64::MIN as u64),
            (T::Unsigned(Elem::U8), 200),
            (T::Unsigned(Elem::U16), 65_535),
            (T::Unsigned(Elem::U32), u64::from(u32::MAX)),
            (T::Unsigned(Elem::U64), u64::MAX),
            (T::Real(Elem::F32), u64::from(0.1f32.to_bits())),
            (T::Real(Elem::F64), (-1.0e-300f64).to_bits()),
            (T::Time, (-1_500_000_123i64) as u64),
            (T::Calendar(value::Calendar::Tod), 45_296_789),
            (T::Calendar(value::Calendar::Dt), 1_764_590_400),
            (T::Calendar(value::Calendar::Date), 1_764_547_200),
            (T::Char, u64::from(value::encode_char('ä').unwrap())),
            (T::WChar, u64::from('€' as u16)),
            (mode, 5),
        ];
        for (ty, slot) in cases {
            let variant = slot_variant(&ty, slot);
            let text = written(&ty, &variant).unwrap_or_else(|e| panic!("{ty:?}: {e}"));
            let back = value::parse(&ty, &text.text()).unwrap_or_else(|e| panic!("{ty:?}: {e}"));
            let same = |slot| value::normalize(ty.elem(), slot);
            assert_eq!(same(back), same(slot), "{ty:?}: {variant:?} written as {text}");
        }
    }

    #[test]
    fn an_enumeration_s_value_has_its_name() {
        let mode = ValueType::Enum {
            type_name: "MODE".into(),
            values: vec![("IDLE".into(), 0), ("RUN".into(), 5)],
            base: Elem::I32,
        };
        assert_eq!(enum_text(&mode, &Variant::Int32(5)).as_deref(), Some("RUN"));
        assert_eq!(enum_text(&mode, &Variant::Int32(7)).as_deref(), Some("7"), "no name");
        assert_eq!(enum_text(&ValueType::Bool, &Variant::Boolean(true)), None);
    }

    #[test]
    fn strings_are_written_as_literals_set_reads_back() {
        let text = Variant::from("it's $5 ä".to_string());
        let written = written(&ValueType::String { cap: 20 }, &text).unwrap().text().into_owned();
        let bytes = value::parse_string(&written, 20).unwrap();
        assert_eq!(value::decode_str(&bytes), "it's $5 ä");
        let wide = super::written(&ValueType::WString { cap: 20 }, &text).unwrap();
        let units = value::parse_wstring(&wide.text(), 20).unwrap();
        assert_eq!(String::from_utf16(&units).unwrap(), "it's $5 ä");
    }

    #[test]
    fn a_write_of_the_wrong_type_or_beyond_the_type_is_refused() {
        use ValueType as T;
        let mismatch = Err(StatusCode::BadTypeMismatch);
        assert_eq!(written(&T::Signed(Elem::I16), &Variant::Int32(5)), mismatch);
        assert_eq!(written(&T::Bool, &Variant::Byte(1)), mismatch);
        assert_eq!(written(&T::String { cap: 4 }, &Variant::Int16(1)), mismatch);
        let range = Err(StatusCode::BadOutOfRange);
        assert_eq!(written(&T::Time, &Variant::Double(f64::NAN)), range);
        assert_eq!(written(&T::Time, &Variant::Double(1e300)), range);
        let tod = T::Calendar(value::Calendar::Tod);
        assert_eq!(written(&tod, &Variant::Double(86_400_000.0)), range, "past midnight");
        assert_eq!(written(&T::Char, &Variant::from("ab".to_string())), range);
        assert_eq!(written(&T::Char, &Variant::from("\u{3042}".to_string())), range, "not 1252");
        assert_eq!(written(&T::String { cap: 4 }, &Variant::from("\u{3042}".to_string())), range);
    }

    #[test]
    fn a_date_before_1970_is_out_of_range_of_every_calendar_type() {
        // The calendar types count from 1970 unsigned: a second before is no value of them,
        // for the long ones too (it was stored wrapped, as a date in 2554).
        let at = |ticks: i64| Variant::DateTime(Box::new(DateTime::from(ticks)));
        let second = 10_000_000;
        for calendar in value::Calendar::ALL {
            if calendar.kind() == value::CalendarKind::Tod {
                continue;
            }
            let ty = ValueType::Calendar(calendar);
            let before = at(TICKS_1601_TO_1970 - second);
            assert_eq!(written(&ty, &before), Err(StatusCode::BadOutOfRange), "{ty:?}");
            let epoch = written(&ty, &at(TICKS_1601_TO_1970)).expect("1970-01-01 is a value");
            let plcd_ipc::Value::Text(text) = epoch else { panic!("a text") };
            assert_eq!(value::parse(&ty, &text), Ok(0), "{ty:?}: {text}");
        }
    }
}
