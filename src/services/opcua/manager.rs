//! plcd's node manager in the OPC UA stack: the address space in memory (values handed over by
//! the sampler, read and subscribed by the stack), and the two services that act on the PLC:
//!
//! - **Write**: the values of one Write request, checked against each node's access level (the
//!   config's `writable`, the session's role) and type here, go to the request handler as one
//!   `set` through the in-process door ([`crate::drivers::real_time::door`]): applied together
//!   at one scan boundary, under every rule of `plcctl set`, and answered once applied (or
//!   refused, with the status code that says why: [`status_of`]);
//! - **Call**: the PLC's methods `Run`, `Stop` and `Reset` (`Cold`: a cold restart) as the
//!   control socket's `run`, `stop` and `reset`, under the same mode and key-switch rules.
//!
//! Neither waits on a runtime worker for anything but its answer, which arrives on the control
//! thread and is handed over through a oneshot channel, within [`ANSWER_WAIT`].

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use async_trait::async_trait;
use opcua::server::address_space::{AddressSpace, NodeType};
use opcua::server::authenticator::UserToken;
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{
    InMemoryNodeManagerImpl, InMemoryNodeManagerImplBuilder,
};
use opcua::server::node_manager::{
    MethodCall, ParsedReadValueId, RequestContext, ServerContext, WriteNode,
};
use opcua::server::CreateMonitoredItem;
use opcua::sync::RwLock;
use opcua::types::{
    AttributeId, DataValue, Identifier, NodeId, NumericRange, StatusCode, TimestampsToReturn,
    Variant,
};
use plcd_ipc::{ErrorKind, NamedValue, Outcome, Reply, Request};

use super::access::Access;
use super::values;
use crate::drivers::real_time::door::{Caller, LocalDoor};
use crate::value::ValueType;

/// How long a write or a method call waits for its answer: longer than the request handler's
/// own wait for the scan thread (10 s), so that its answer, not this, says what went wrong.
pub const ANSWER_WAIT: Duration = Duration::from_secs(12);

/// A writable variable: one element (its leaf's index in the sampler's order) or an array's
/// elements (each with its node id's string, row-major), and the type of each.
#[derive(Debug, Clone)]
pub struct Target {
    pub ty: ValueType,
    pub elements: Vec<(String, usize)>,
    /// An array variable's dimensions: its value, or the part of it an index range selects,
    /// is written element by element.
    pub dimensions: Option<Vec<u32>>,
    /// A device of `[[opcua.devices]]` (its element's name is the device's): written as a
    /// device, a word's signed value or a bit's 0 or 1.
    pub device: bool,
}

/// Leaves whose last value the sampler is to forget, so that it hands the next copy's value
/// over even if it equals the one it handed over before a write replaced it in the address
/// space.
#[derive(Debug, Default)]
pub struct Forget {
    /// Every leaf (after more writes than `leaves` keeps).
    pub all: bool,
    pub leaves: Vec<usize>,
}

impl Forget {
    /// Leaves kept one by one, at most; past it, all are forgotten at once.
    const MAX: usize = 4096;

    fn add(&mut self, leaf: usize) {
        if self.leaves.len() >= Self::MAX {
            self.all = true;
            self.leaves.clear();
        }
        if !self.all {
            self.leaves.push(leaf);
        }
    }
}

/// What the node manager is built with.
pub struct PlcNodesBuilder {
    pub namespace: NamespaceMetadata,
    /// The writable variables by their node ids' strings.
    pub targets: Targets,
    pub door: LocalDoor,
    pub forget: Arc<Mutex<Forget>>,
}

impl InMemoryNodeManagerImplBuilder for PlcNodesBuilder {
    type Impl = PlcNodes;

    fn build(mut self, context: ServerContext, address_space: &mut AddressSpace) -> PlcNodes {
        {
            let mut type_tree = context.type_tree.write();
            self.namespace.namespace_index =
                type_tree.namespaces_mut().add_namespace(&self.namespace.namespace_uri);
        }
        address_space.add_namespace(&self.namespace.namespace_uri, self.namespace.namespace_index);
        PlcNodes {
            namespace: self.namespace,
            targets: self.targets,
            door: self.door,
            forget: self.forget,
        }
    }
}

/// plcd's node manager as the stack holds it.
pub type PlcManager = opcua::server::node_manager::memory::InMemoryNodeManager<PlcNodes>;

/// The writable variables by their node ids' strings: replaced when the running project
/// changes ([`super::follow`]).
pub type Targets = Arc<std::sync::RwLock<HashMap<String, Target>>>;

/// The node manager. See the module docs.
pub struct PlcNodes {
    namespace: NamespaceMetadata,
    targets: Targets,
    door: LocalDoor,
    forget: Arc<Mutex<Forget>>,
}

/// One value of a Write request that passed the checks: where it is in the request, and the
/// variable's name and value as `set` takes them.
struct Checked {
    index: usize,
    /// The leaf written, with what `set` takes for it; `None` for an array variable's own
    /// entry, whose elements come as entries of their own.
    write: Option<(usize, NamedValue)>,
    /// The node and the value it holds once applied.
    node: NodeId,
    value: Held,
}

/// What a node holds once a write is applied.
enum Held {
    /// The value written.
    Whole(Variant),
    /// An array variable written through an index range: these of its elements (row-major
    /// positions) now hold these values; the others keep theirs.
    Part(Vec<(usize, Variant)>),
}

impl PlcNodes {
    /// The writable variable `node` is, if it is one.
    fn target(&self, node: &NodeId) -> Option<Target> {
        if node.namespace != self.namespace.namespace_index {
            return None;
        }
        let Identifier::String(id) = &node.identifier else { return None };
        let targets = self.targets.read().unwrap_or_else(|e| e.into_inner());
        targets.get(id.as_ref()).cloned()
    }

    /// `request` through the door for the session of `token`: its reply, or the status code
    /// of its refusal.
    async fn ask(&self, token: &UserToken, request: Request) -> Result<Reply, StatusCode> {
        let what = request.name();
        let (tx, rx) = tokio::sync::oneshot::channel();
        let reply = Box::new(move |line| {
            // The caller may have given up (ANSWER_WAIT): the answer then goes nowhere.
            let _ = tx.send(line);
        });
        let caller = Caller::Service(Access::caller(token));
        if let Err(full) = self.door.submit(request, caller, reply) {
            log::warn!("opcua: {what} refused: {full}");
            return Err(StatusCode::BadTooManyOperations);
        }
        let line = match tokio::time::timeout(ANSWER_WAIT, rx).await {
            Ok(Ok(line)) => line,
            // The control thread dropped it: the daemon is stopping.
            Ok(Err(_)) => return Err(StatusCode::BadShutdown),
            Err(_) => {
                log::warn!("opcua: {what}: no answer within {} s", ANSWER_WAIT.as_secs());
                return Err(StatusCode::BadTimeout);
            }
        };
        match line.outcome {
            Outcome::Ok(reply) => Ok(reply),
            Outcome::Error(failure) => {
                log::info!(
                    "opcua: {what} for {} refused: {}",
                    Access::caller(token),
                    failure.message
                );
                Err(status_of(failure.kind))
            }
        }
    }
}

/// The status code of a request the handler refused, by the kind of its refusal.
pub fn status_of(kind: ErrorKind) -> StatusCode {
    match kind {
        // the mode rules, the key switch, a latched error
        ErrorKind::Refused => StatusCode::BadInvalidState,
        // a value `set` does not take: out of the type's range, a STRING too long
        ErrorKind::Invalid => StatusCode::BadOutOfRange,
        // a load under way, too many requests waiting
        ErrorKind::Busy => StatusCode::BadResourceUnavailable,
        ErrorKind::Unavailable => StatusCode::BadTimeout,
        ErrorKind::Denied => StatusCode::BadUserAccessDenied,
        ErrorKind::BadRequest | ErrorKind::TooLong | ErrorKind::Version => {
            StatusCode::BadInternalError
        }
    }
}

#[async_trait]
impl InMemoryNodeManagerImpl for PlcNodes {
    async fn init(&self, _address_space: &mut AddressSpace, _context: ServerContext) {}

    fn name(&self) -> &str {
        "plcd"
    }

    fn namespaces(&self) -> Vec<NamespaceMetadata> {
        vec![self.namespace.clone()]
    }

    /// Values as the stack reads them, except an index range of several dimensions, which
    /// the stack would read as a list of one-dimensional ranges: it selects the sub-array.
    async fn read_values(
        &self,
        context: &RequestContext,
        address_space: &RwLock<AddressSpace>,
        nodes: &[&ParsedReadValueId],
        max_age: f64,
        timestamps_to_return: TimestampsToReturn,
    ) -> Vec<DataValue> {
        let space = address_space.read();
        nodes
            .iter()
            .map(|&node| {
                let NumericRange::MultipleRanges(_) = node.index_range else {
                    return space.read(context, node, max_age, timestamps_to_return);
                };
                let whole = ParsedReadValueId { index_range: NumericRange::None, ..node.clone() };
                let mut value = space.read(context, &whole, max_age, timestamps_to_return);
                match value.value.take() {
                    Some(Variant::Array(array)) => match sub_array(&array, &node.index_range) {
                        Ok(part) => value.value = Some(part),
                        Err(status) => value.status = Some(status),
                    },
                    // Not an array: the stack's answer (a STRING's range is one-dimensional).
                    _ => return space.read(context, node, max_age, timestamps_to_return),
                }
                value
            })
            .collect()
    }

    /// Monitored items as the stack creates them, except one with an index range of several
    /// dimensions: the stack would sample it as a list of one-dimensional ranges, so it is
    /// refused (`BadIndexRangeInvalid`); the whole array, or a read, gives the part.
    async fn create_value_monitored_items(
        &self,
        context: &RequestContext,
        address_space: &RwLock<AddressSpace>,
        items: &mut [&mut &mut CreateMonitoredItem],
    ) {
        let to_read: Vec<_> = items.iter().map(|item| item.item_to_monitor()).collect();
        let values =
            self.read_values(context, address_space, &to_read, 0.0, TimestampsToReturn::Both).await;
        for (value, item) in values.into_iter().zip(items.iter_mut()) {
            if let NumericRange::MultipleRanges(_) = item.item_to_monitor().index_range {
                item.set_status(StatusCode::BadIndexRangeInvalid);
                continue;
            }
            if value.status() != StatusCode::BadAttributeIdInvalid {
                item.set_initial_value(value);
            }
            item.set_status(StatusCode::Good);
        }
    }

    async fn write(
        &self,
        context: &RequestContext,
        address_space: &RwLock<AddressSpace>,
        nodes_to_write: &mut [&mut WriteNode],
    ) -> Result<(), StatusCode> {
        let mut checked = Vec::new();
        {
            let mut space = address_space.write();
            let type_tree = context.type_tree.read();
            for (index, node) in nodes_to_write.iter_mut().enumerate() {
                let value = node.value();
                // Only the values of the variables the config makes writable: any other
                // attribute or variable is not writable, for every session (the stack itself
                // looks at the session's access level alone).
                let target = match value.attribute_id {
                    AttributeId::Value => self.target(&value.node_id),
                    _ => None,
                };
                if target.is_none() {
                    let known = space.find(&value.node_id).is_some();
                    node.set_status(if known {
                        StatusCode::BadNotWritable
                    } else {
                        StatusCode::BadNodeIdUnknown
                    });
                    continue;
                }
                // The session's role (the authenticator's effective user access level) and the
                // value's type.
                if let Err(status) = space.validate_node_write(context, value, &*type_tree) {
                    node.set_status(status);
                    continue;
                }
                let status = match (value.attribute_id, &target) {
                    // An index range selects elements of an array; a substring of a STRING or
                    // some bits of a word are not written alone.
                    (AttributeId::Value, Some(t))
                        if t.dimensions.is_none() && value.index_range.has_range() =>
                    {
                        Err(StatusCode::BadWriteNotSupported)
                    }
                    // plcd keeps values, not their status: a value written as bad is refused.
                    // Timestamps a client sends (asyncua and others always do) are ignored: a
                    // value is stamped with the time it was applied.
                    (AttributeId::Value, Some(_))
                        if value.value.status.is_some_and(|s| !s.is_good()) =>
                    {
                        Err(StatusCode::BadWriteNotSupported)
                    }
                    (AttributeId::Value, Some(target)) => match &value.value.value {
                        None => Err(StatusCode::BadTypeMismatch),
                        Some(variant) => {
                            check(target, index, &value.node_id, &value.index_range, variant)
                                .map(|entries| checked.extend(entries))
                        }
                    },
                    _ => Err(StatusCode::BadNotWritable),
                };
                if let Err(status) = status {
                    node.set_status(status);
                }
            }
        }
        if checked.is_empty() {
            return Ok(());
        }
        let writes =
            checked.iter().filter_map(|c| c.write.as_ref().map(|(_, w)| w.clone())).collect();
        let status = match self.ask(&context.token, Request::Set { writes }).await {
            Ok(_) => StatusCode::Good,
            Err(status) => status,
        };
        for c in &checked {
            nodes_to_write[c.index].set_status(status);
        }
        if status.is_good() {
            self.written(context, address_space, &checked);
        }
        Ok(())
    }

    async fn call(
        &self,
        context: &RequestContext,
        _address_space: &RwLock<AddressSpace>,
        methods_to_call: &mut [&mut &mut MethodCall],
    ) -> Result<(), StatusCode> {
        for method in methods_to_call {
            let Identifier::String(id) = &method.method_id().identifier else {
                method.set_status(StatusCode::BadMethodInvalid);
                continue;
            };
            let request = match id.as_ref() {
                "PLC.Run" => Request::Run,
                "PLC.Stop" => Request::Stop,
                "PLC.Reset" => match method.arguments() {
                    [Variant::Boolean(cold)] => Request::Reset { cold: *cold },
                    [_] => {
                        method.set_argument_error(vec![StatusCode::BadTypeMismatch]);
                        method.set_status(StatusCode::BadInvalidArgument);
                        continue;
                    }
                    _ => {
                        method.set_status(StatusCode::BadArgumentsMissing);
                        continue;
                    }
                },
                _ => {
                    method.set_status(StatusCode::BadMethodInvalid);
                    continue;
                }
            };
            match self.ask(&context.token, request).await {
                Ok(_) => {
                    method.set_outputs(Vec::new());
                    method.set_status(StatusCode::Good);
                }
                Err(status) => method.set_status(status),
            }
        }
        Ok(())
    }
}

impl PlcNodes {
    /// After the scan boundary that applied them: the written values in the address space and
    /// to the subscriptions, and the sampler told to hand the next copy's values over whatever
    /// it handed over before (the program may have changed them since).
    fn written(
        &self,
        context: &RequestContext,
        address_space: &RwLock<AddressSpace>,
        checked: &[Checked],
    ) {
        {
            let mut forget = self.forget.lock().unwrap_or_else(|e| e.into_inner());
            for (leaf, _) in checked.iter().filter_map(|c| c.write.as_ref()) {
                forget.add(*leaf);
            }
        }
        let mut space = address_space.write();
        for c in checked {
            let Some(NodeType::Variable(node)) = space.find_mut(&c.node) else { continue };
            let value = match &c.value {
                Held::Whole(value) => value.clone(),
                Held::Part(elements) => match node.value(
                    TimestampsToReturn::Neither,
                    &NumericRange::None,
                    &opcua::types::DataEncoding::Binary,
                    0.0,
                ) {
                    DataValue { value: Some(Variant::Array(mut array)), .. } => {
                        for (position, value) in elements {
                            if let Some(slot) = array.values.get_mut(*position) {
                                *slot = value.clone();
                            }
                        }
                        Variant::Array(array)
                    }
                    // No value yet: the next copy brings the whole array (its written
                    // elements are forgotten by the sampler).
                    _ => continue,
                },
            };
            let now = DataValue::new_now(value);
            node.set_data_value(now.clone());
            context
                .subscriptions
                .notify_data_change([(now, &c.node, AttributeId::Value)].into_iter());
        }
    }
}

/// The entries of a write of `variant` to `target` (the node `node`, item `index` of the
/// request): one for a variable; for an array variable, one per element `range` selects (all
/// without one; the value must hold them all, in the selection's shape) and one for the array
/// node itself.
fn check(
    target: &Target,
    index: usize,
    node: &NodeId,
    range: &NumericRange,
    variant: &Variant,
) -> Result<Vec<Checked>, StatusCode> {
    let entry = |(name, leaf): &(String, usize), value: &Variant| {
        let write = if target.device {
            let word = match value {
                Variant::Int16(v) => i32::from(*v),
                Variant::Boolean(b) => i32::from(*b),
                _ => return Err(StatusCode::BadTypeMismatch),
            };
            NamedValue::device(name.clone(), word)
        } else {
            NamedValue::write(name.clone(), values::written(&target.ty, value)?)
        };
        let id = if target.device { super::nodes::device_id(name) } else { name.clone() };
        Ok(Checked {
            index,
            write: Some((*leaf, write)),
            node: NodeId::new(node.namespace, id),
            value: Held::Whole(value.clone()),
        })
    };
    let Some(dimensions) = &target.dimensions else {
        return target.elements.iter().map(|element| entry(element, variant)).collect();
    };
    let (positions, shape) = selected(dimensions, range)?;
    let Variant::Array(array) = variant else { return Err(StatusCode::BadTypeMismatch) };
    if array.values.len() != positions.len() {
        // The whole selection or nothing: its length is the declared one.
        return Err(StatusCode::BadOutOfRange);
    }
    // Dimensions, when the value has its own, are the selection's (a flat value of the
    // right length is taken row-major).
    if array.dimensions.as_ref().is_some_and(|d| d.len() > 1 && *d != shape) {
        return Err(StatusCode::BadTypeMismatch);
    }
    let mut entries: Vec<Checked> = positions
        .iter()
        .zip(&array.values)
        .map(|(&position, value)| entry(&target.elements[position], value))
        .collect::<Result<_, _>>()?;
    let value = if range.has_range() {
        Held::Part(positions.into_iter().zip(array.values.iter().cloned()).collect())
    } else {
        Held::Whole(variant.clone())
    };
    entries.push(Checked { index, write: None, node: node.clone(), value });
    Ok(entries)
}

/// The elements of an array of `dimensions` that `range` selects, as row-major positions,
/// and the selection's own dimensions. One index or `first:last` per dimension (OPC UA's
/// indices count from 0 whatever the array's declared bounds); a selection past the array's
/// end is refused whole (a write is not cut to fit).
fn selected(
    dimensions: &[u32],
    range: &NumericRange,
) -> Result<(Vec<usize>, Vec<u32>), StatusCode> {
    let bounds: Vec<(u32, u32)> = match range {
        NumericRange::None => dimensions.iter().map(|&d| (0, d.saturating_sub(1))).collect(),
        NumericRange::Index(_) | NumericRange::Range(..) => vec![bound(range)?],
        NumericRange::MultipleRanges(ranges) => {
            ranges.iter().map(bound).collect::<Result<_, _>>()?
        }
    };
    if bounds.len() != dimensions.len() {
        return Err(StatusCode::BadIndexRangeInvalid);
    }
    if bounds.iter().zip(dimensions).any(|(&(_, last), &d)| last >= d) {
        return Err(StatusCode::BadIndexRangeNoData);
    }
    let shape: Vec<u32> = bounds.iter().map(|&(first, last)| last - first + 1).collect();
    // Row-major: the last dimension varies fastest.
    let mut positions = vec![0usize];
    for (&(first, last), &d) in bounds.iter().zip(dimensions) {
        positions = positions
            .iter()
            .flat_map(|&p| (first..=last).map(move |i| p * d as usize + i as usize))
            .collect();
    }
    Ok((positions, shape))
}

/// The part of `array` that `range` selects (see [`selected`]), with its own dimensions.
fn sub_array(array: &opcua::types::Array, range: &NumericRange) -> Result<Variant, StatusCode> {
    let dimensions = match &array.dimensions {
        Some(dimensions) => dimensions.clone(),
        None => vec![array.values.len() as u32],
    };
    let (positions, shape) = selected(&dimensions, range)?;
    // An array of dimensions that do not hold its values is none of plcd's: refused, not read.
    let values: Vec<Variant> = positions
        .iter()
        .map(|&p| array.values.get(p).cloned().ok_or(StatusCode::BadInternalError))
        .collect::<Result<_, _>>()?;
    let part = match shape.as_slice() {
        [_] => opcua::types::Array::new(array.value_type, values),
        _ => opcua::types::Array::new_multi(array.value_type, values, shape),
    };
    part.map(|part| Variant::Array(Box::new(part))).map_err(|_| StatusCode::BadInternalError)
}

/// One dimension's `(first, last)` index of a range.
fn bound(range: &NumericRange) -> Result<(u32, u32), StatusCode> {
    match *range {
        NumericRange::Index(i) => Ok((i, i)),
        NumericRange::Range(first, last) if first < last => Ok((first, last)),
        _ => Err(StatusCode::BadIndexRangeInvalid),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_have_the_status_code_that_says_why() {
        assert_eq!(status_of(ErrorKind::Refused), StatusCode::BadInvalidState);
        assert_eq!(status_of(ErrorKind::Invalid), StatusCode::BadOutOfRange);
        assert_eq!(status_of(ErrorKind::Busy), StatusCode::BadResourceUnavailable);
        assert_eq!(status_of(ErrorKind::Unavailable), StatusCode::BadTimeout);
    }

    fn range(text: &str) -> NumericRange {
        NumericRange::new(text).unwrap()
    }

    #[test]
    fn an_index_range_selects_row_major_positions_and_a_shape() {
        // A 2 x 3 array: positions 0 1 2 / 3 4 5.
        assert_eq!(selected(&[2, 3], &NumericRange::None), Ok(((0..6).collect(), vec![2, 3])));
        assert_eq!(selected(&[2, 3], &range("1,0:1")), Ok((vec![3, 4], vec![1, 2])));
        assert_eq!(selected(&[2, 3], &range("0:1,2")), Ok((vec![2, 5], vec![2, 1])));
        assert_eq!(selected(&[5], &range("1:3")), Ok((vec![1, 2, 3], vec![3])));
        assert_eq!(selected(&[5], &range("4")), Ok((vec![4], vec![1])));
        assert_eq!(selected(&[2, 2, 2], &range("1,1,0:1")), Ok((vec![6, 7], vec![1, 1, 2])));
    }

    #[test]
    fn an_index_range_of_the_wrong_rank_or_past_the_end_is_refused() {
        assert_eq!(selected(&[2, 3], &range("1")), Err(StatusCode::BadIndexRangeInvalid));
        assert_eq!(selected(&[5], &range("1,2")), Err(StatusCode::BadIndexRangeInvalid));
        assert_eq!(selected(&[5], &range("3:5")), Err(StatusCode::BadIndexRangeNoData));
        assert_eq!(selected(&[2, 3], &range("0,3")), Err(StatusCode::BadIndexRangeNoData));
    }

    fn ints(values: &[i16]) -> Vec<Variant> {
        values.iter().map(|&v| Variant::Int16(v)).collect()
    }

    fn grid() -> Target {
        let elements = (0..6).map(|i| (format!("main.grid[{},{}]", i / 3 + 1, i % 3 + 1), i));
        Target {
            ty: ValueType::Signed(crate::value::Elem::I16),
            elements: elements.collect(),
            dimensions: Some(vec![2, 3]),
            device: false,
        }
    }

    fn array_of(values: &[i16], dimensions: &[u32]) -> Variant {
        let scalar = opcua::types::VariantScalarTypeId::Int16;
        let array = match dimensions {
            [] => opcua::types::Array::new(scalar, ints(values)),
            _ => opcua::types::Array::new_multi(scalar, ints(values), dimensions.to_vec()),
        };
        Variant::Array(Box::new(array.unwrap()))
    }

    fn names(entries: &[Checked]) -> Vec<String> {
        entries.iter().filter_map(|c| c.write.as_ref().map(|(_, w)| w.dev.clone())).collect()
    }

    #[test]
    fn a_part_of_an_array_is_written_element_by_element() {
        let node = NodeId::new(2, "main.grid");
        let entries = check(&grid(), 0, &node, &range("1,1:2"), &array_of(&[7, 8], &[1, 2]));
        let entries = entries.unwrap();
        assert_eq!(names(&entries), ["main.grid[2,2]", "main.grid[2,3]"]);
        let Held::Part(held) = &entries.last().unwrap().value else { panic!("a part") };
        assert_eq!(held, &[(4, Variant::Int16(7)), (5, Variant::Int16(8))]);
        // A flat value of the selection's length is taken row-major.
        let flat = check(&grid(), 0, &node, &range("0:1,0"), &array_of(&[1, 2], &[]));
        assert_eq!(names(&flat.unwrap()), ["main.grid[1,1]", "main.grid[2,1]"]);
        // The whole array, with its dimensions.
        let whole = check(&grid(), 0, &node, &NumericRange::None, &array_of(&[0; 6], &[2, 3]));
        assert_eq!(whole.unwrap().len(), 7, "six elements and the array node");
    }

    #[test]
    fn a_part_of_another_shape_or_length_is_refused() {
        let node = NodeId::new(2, "main.grid");
        let wrong_shape = check(&grid(), 0, &node, &range("1,0:1"), &array_of(&[1, 2], &[2, 1]));
        assert_eq!(wrong_shape.err(), Some(StatusCode::BadTypeMismatch));
        let too_short = check(&grid(), 0, &node, &range("1,0:2"), &array_of(&[1, 2], &[]));
        assert_eq!(too_short.err(), Some(StatusCode::BadOutOfRange));
        let scalar = check(&grid(), 0, &node, &range("1,1"), &Variant::Int16(1));
        assert_eq!(scalar.err(), Some(StatusCode::BadTypeMismatch));
        let past = check(&grid(), 0, &node, &range("2,0"), &array_of(&[1], &[]));
        assert_eq!(past.err(), Some(StatusCode::BadIndexRangeNoData));
    }

    #[test]
    fn a_read_of_several_dimensions_is_the_sub_array() {
        let Variant::Array(array) = array_of(&[0, 1, 2, 3, 4, 5], &[2, 3]) else { panic!() };
        let part = sub_array(&array, &range("0:1,1:2")).unwrap();
        assert_eq!(part, array_of(&[1, 2, 4, 5], &[2, 2]));
        let row = sub_array(&array, &range("1,0:2")).unwrap();
        assert_eq!(row, array_of(&[3, 4, 5], &[1, 3]));
        assert_eq!(sub_array(&array, &range("2,0")), Err(StatusCode::BadIndexRangeNoData));
    }

    #[test]
    fn past_its_bound_forget_forgets_everything() {
        let mut forget = Forget::default();
        forget.add(3);
        assert_eq!((forget.all, forget.leaves.as_slice()), (false, &[3][..]));
        for leaf in 0..Forget::MAX {
            forget.add(leaf);
        }
        assert!(forget.all && forget.leaves.is_empty());
        forget.add(9);
        assert!(forget.leaves.is_empty(), "all: nothing kept one by one");
    }
}
