//! The address space in the stack's node store: built from a [`Plan`] at start (the PLC object,
//! its methods, the status and program folders, every served variable), and changed from one
//! plan to the next when the running project changes ([`change`]).

use opcua::nodes::{AccessLevel, MethodBuilder, ObjectBuilder, VariableBuilder};
use opcua::server::SubscriptionCache;
use opcua::types::{
    Argument, DataTypeId, DataValue, EnumValueType, ExtensionObject, LocalizedText, NodeId,
    ObjectId, QualifiedName, Range, StatusCode, UAString, VariableTypeId, Variant,
};

use super::manager::PlcManager;
use super::nodes::{self, ArrayNode, Changes, Leaf, Object, Plan, STATUS_NODES};
use super::values;
use crate::value::ValueType;

pub fn id(ns: u16, text: &str) -> NodeId {
    NodeId::new(ns, text.to_string())
}

/// Objects/PLC, its methods, its Status and Programs folders, the status variables and the
/// plan's nodes; the variables read-only but for the writable ones.
pub fn populate(manager: &PlcManager, ns: u16, plan: &Plan) {
    let mut space = manager.address_space().write();
    let plc = id(ns, nodes::PLC);
    let name = |text: &str| QualifiedName::new(ns, text);
    ObjectBuilder::new(&plc, name(nodes::PLC), nodes::PLC)
        .organized_by(ObjectId::ObjectsFolder)
        .insert(&mut *space);
    for (method, _) in super::access::METHODS {
        let browse = method.trim_start_matches("PLC.");
        let node = id(ns, method);
        let mut builder = MethodBuilder::new(&node, name(browse), browse)
            .component_of(plc.clone())
            .executable(true)
            .user_executable(true);
        if browse == "Reset" {
            let cold = Argument {
                name: UAString::from("Cold"),
                data_type: DataTypeId::Boolean.into(),
                value_rank: -1,
                array_dimensions: None,
                description: LocalizedText::new(
                    "",
                    "true: a cold restart (clears the retained memory too); false: warm",
                ),
            };
            builder = builder.input_args(&mut *space, &id(ns, "PLC.Reset.InputArguments"), &[cold]);
        }
        builder.insert(&mut *space);
    }
    for folder in [nodes::STATUS, nodes::PROGRAMS, nodes::DEVICES] {
        ObjectBuilder::new(&id(ns, folder), name(folder), folder)
            .is_folder()
            .organized_by(plc.clone())
            .insert(&mut *space);
    }
    let read_only = AccessLevel::CURRENT_READ;
    let status_folder = id(ns, nodes::STATUS);
    for (label, ty) in STATUS_NODES.iter() {
        VariableBuilder::new(&id(ns, &nodes::status_id(label)), name(label), *label)
            .has_type_definition(VariableTypeId::BaseDataVariableType)
            .data_type(*ty)
            .value(initial(*ty))
            .access_level(read_only)
            .user_access_level(read_only)
            .organized_by(status_folder.clone())
            .insert(&mut *space);
    }
    drop(space);
    add(manager, ns, &plan.objects, &plan.leaves);
    add_arrays(manager, ns, &plan.arrays, &plan.leaves);
}

/// Adds the array variables of `arrays` (their elements in `leaves`): an array of the elements'
/// type, of the array's dimensions (its ValueRank their number).
fn add_arrays(manager: &PlcManager, ns: u16, arrays: &[ArrayNode], leaves: &[Leaf]) {
    let mut space = manager.address_space().write();
    for array in arrays {
        let first = &leaves[array.elements[0]];
        let Some(ty) = values::data_type(&first.ty) else { continue };
        let access = if array.writable {
            AccessLevel::CURRENT_READ | AccessLevel::CURRENT_WRITE
        } else {
            AccessLevel::CURRENT_READ
        };
        let len = array.elements.len();
        let initial: Vec<Variant> = (0..len).map(|_| initial(ty)).collect();
        let Some(value) = values::array(initial, &array.dimensions) else { continue };
        VariableBuilder::new(
            &id(ns, &array.id),
            QualifiedName::new(ns, array.browse.as_str()),
            array.browse.as_str(),
        )
        .has_type_definition(VariableTypeId::BaseDataVariableType)
        .data_type(ty)
        .value_rank(array.dimensions.len() as i32)
        .array_dimensions(&array.dimensions)
        .value(value)
        .access_level(access)
        .user_access_level(access)
        .organized_by(id(ns, &array.parent))
        .insert(&mut *space);
    }
}

/// Adds `objects` (parents first) and the variables of `leaves` to the address space; a leaf
/// read-only unless it is writable.
fn add(manager: &PlcManager, ns: u16, objects: &[Object], leaves: &[Leaf]) {
    let mut space = manager.address_space().write();
    let name = |text: &str| QualifiedName::new(ns, text);
    for object in objects {
        ObjectBuilder::new(&id(ns, &object.id), name(&object.browse), object.browse.as_str())
            .organized_by(id(ns, &object.parent))
            .insert(&mut *space);
    }
    let read_write = AccessLevel::CURRENT_READ | AccessLevel::CURRENT_WRITE;
    for leaf in leaves {
        let Some(ty) = values::data_type(&leaf.ty) else { continue };
        let access = if leaf.writable { read_write } else { AccessLevel::CURRENT_READ };
        let node = id(ns, &leaf.id);
        let builder = VariableBuilder::new(&node, name(&leaf.browse), leaf.browse.as_str())
            .data_type(ty)
            .value(initial(ty))
            .access_level(access)
            .user_access_level(access)
            .organized_by(id(ns, &leaf.parent));
        if let Some(range) = leaf.range {
            // An analog item (OPC UA Part 8): its EURange is what a percent deadband is a
            // percentage of (the stack reads it when a monitored item asks for one).
            builder.has_type_definition(VariableTypeId::AnalogItemType).insert(&mut *space);
            let eu_range = Range { low: range.low, high: range.high };
            VariableBuilder::new(
                &id(ns, &eu_range_id(&leaf.id)),
                QualifiedName::new(0, "EURange"),
                "EURange",
            )
            .data_type(DataTypeId::Range)
            .value(ExtensionObject::from_message(eu_range))
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .has_type_definition(VariableTypeId::PropertyType)
            .property_of(node)
            .insert(&mut *space);
            continue;
        }
        let ValueType::Enum { values, .. } = &leaf.ty else {
            builder.has_type_definition(VariableTypeId::BaseDataVariableType).insert(&mut *space);
            continue;
        };
        // An enumeration: a MultiStateValueDiscrete variable (OPC UA Part 8), its value the
        // integer, its names in EnumValues and the current one in ValueAsText.
        builder
            .has_type_definition(VariableTypeId::MultiStateValueDiscreteType)
            .insert(&mut *space);
        let names: Vec<ExtensionObject> = values
            .iter()
            .map(|(name, value)| {
                ExtensionObject::from_message(EnumValueType {
                    value: *value,
                    display_name: LocalizedText::new("", name),
                    description: LocalizedText::null(),
                })
            })
            .collect();
        let enum_values = id(ns, &enum_values_id(&leaf.id));
        VariableBuilder::new(&enum_values, QualifiedName::new(0, "EnumValues"), "EnumValues")
            .data_type(DataTypeId::EnumValueType)
            .value_rank(1)
            .value(names)
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .has_type_definition(VariableTypeId::PropertyType)
            .property_of(node.clone())
            .insert(&mut *space);
        VariableBuilder::new(
            &id(ns, &value_as_text_id(&leaf.id)),
            QualifiedName::new(0, "ValueAsText"),
            "ValueAsText",
        )
        .data_type(DataTypeId::LocalizedText)
        .value(LocalizedText::new("", ""))
        .access_level(AccessLevel::CURRENT_READ)
        .user_access_level(AccessLevel::CURRENT_READ)
        .has_type_definition(VariableTypeId::PropertyType)
        .property_of(node)
        .insert(&mut *space);
    }
}

/// The node id of an analog item's EURange property.
pub fn eu_range_id(leaf: &str) -> String {
    format!("{leaf}.EURange")
}

/// The node id of an enumeration variable's EnumValues property.
pub fn enum_values_id(leaf: &str) -> String {
    format!("{leaf}.EnumValues")
}

/// The node id of an enumeration variable's ValueAsText property: the sampler keeps it.
pub fn value_as_text_id(leaf: &str) -> String {
    format!("{leaf}.ValueAsText")
}

/// Changes the address space from one plan to the next: the removed variables' subscribers get
/// a last value with `BadNodeIdUnknown`, then the nodes go; the new ones come with a value of
/// their type until the next copy. The nodes of the variables both plans have are not touched.
pub fn change(
    manager: &PlcManager,
    subscriptions: &SubscriptionCache,
    ns: u16,
    changes: &Changes,
    new: &Plan,
) {
    let gone: Vec<NodeId> = changes.remove_leaves.iter().map(|leaf| id(ns, leaf)).collect();
    let last = DataValue::new_now_status(Variant::Empty, StatusCode::BadNodeIdUnknown);
    let values = gone.iter().map(|node| (node, None, last.clone()));
    if let Err(status) = manager.set_values(subscriptions, values) {
        log::warn!("opcua: the removed variables' subscribers not told: {status}");
    }
    {
        let mut space = manager.address_space().write();
        for (node, leaf) in gone.iter().zip(&changes.remove_leaves) {
            space.delete(node, true);
            // An enumeration's or an analog item's properties (absent for other variables).
            space.delete(&id(ns, &enum_values_id(leaf)), true);
            space.delete(&id(ns, &value_as_text_id(leaf)), true);
            space.delete(&id(ns, &eu_range_id(leaf)), true);
        }
        for array in &changes.remove_arrays {
            space.delete(&id(ns, array), true);
        }
        for object in &changes.remove_objects {
            space.delete(&id(ns, object), true);
        }
    }
    add(manager, ns, &changes.add_objects, &changes.add_leaves);
    add_arrays(manager, ns, &changes.add_arrays, &new.leaves);
}

/// A value of the type until the first copy.
pub fn initial(ty: DataTypeId) -> Variant {
    match ty {
        DataTypeId::Boolean => Variant::Boolean(false),
        DataTypeId::SByte => Variant::SByte(0),
        DataTypeId::Byte => Variant::Byte(0),
        DataTypeId::Int16 => Variant::Int16(0),
        DataTypeId::UInt16 => Variant::UInt16(0),
        DataTypeId::Int32 => Variant::Int32(0),
        DataTypeId::UInt32 => Variant::UInt32(0),
        DataTypeId::Int64 => Variant::Int64(0),
        DataTypeId::UInt64 => Variant::UInt64(0),
        DataTypeId::Float => Variant::Float(0.0),
        DataTypeId::Double | DataTypeId::Duration => Variant::Double(0.0),
        DataTypeId::String => Variant::from(String::new()),
        _ => Variant::Empty,
    }
}
