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
use opcua::server::node_manager::{MethodCall, RequestContext, ServerContext, WriteNode};
use opcua::sync::RwLock;
use opcua::types::{AttributeId, DataValue, Identifier, NodeId, NumericRange, StatusCode, Variant};
use plcd_ipc::{ErrorKind, NamedValue, Outcome, Reply, Request};

use super::access::Access;
use super::values;
use crate::drivers::real_time::door::{Caller, LocalDoor};
use crate::value::ValueType;

/// How long a write or a method call waits for its answer: longer than the request handler's
/// own wait for the scan thread (10 s), so that its answer, not this, says what went wrong.
pub const ANSWER_WAIT: Duration = Duration::from_secs(12);

/// A writable variable: one element (its leaf's index in the sampler's order) or an array's
/// elements (each with its node id's string), and the type of each.
#[derive(Debug, Clone)]
pub struct Target {
    pub ty: ValueType,
    pub elements: Vec<(String, usize)>,
    /// An array variable: a value of `elements.len()` values written element by element.
    pub array: bool,
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
    value: Variant,
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
                    (AttributeId::Value, Some(_)) if value.index_range != NumericRange::None => {
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
                        Some(variant) => check(target, index, &value.node_id, variant)
                            .map(|entries| checked.extend(entries)),
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
            let now = DataValue::new_now(c.value.clone());
            node.set_data_value(now.clone());
            context
                .subscriptions
                .notify_data_change([(now, &c.node, AttributeId::Value)].into_iter());
        }
    }
}

/// The entries of a write of `variant` to `target` (the node `node`, item `index` of the
/// request): one for a variable; for an array variable, one per element (the value must hold
/// them all) and one for the array node itself.
fn check(
    target: &Target,
    index: usize,
    node: &NodeId,
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
            value: value.clone(),
        })
    };
    if !target.array {
        return target.elements.iter().map(|element| entry(element, variant)).collect();
    }
    let Variant::Array(array) = variant else { return Err(StatusCode::BadTypeMismatch) };
    if array.values.len() != target.elements.len() {
        // The whole array or nothing: its length is the declared one.
        return Err(StatusCode::BadOutOfRange);
    }
    let mut entries: Vec<Checked> = target
        .elements
        .iter()
        .zip(&array.values)
        .map(|(element, value)| entry(element, value))
        .collect::<Result<_, _>>()?;
    entries.push(Checked { index, write: None, node: node.clone(), value: variant.clone() });
    Ok(entries)
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
