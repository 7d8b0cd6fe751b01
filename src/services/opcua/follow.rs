//! Following the running project: when a reload (SIGHUP), a `plcctl load` or an online change
//! replaces the engine, the address space becomes the new project's, keeping the nodes of the
//! variables both projects have (same name, same OPC UA type, as writable as before): a
//! client's node ids, subscriptions and tag lists of those go on working.
//!
//! The daemon announces each engine it queues, with its project, before the scan thread takes
//! it ([`Following::announce`]); the plan of its variables is made then, on the daemon's
//! thread. The sampler recognises the engine in a mirror copy by its layout (the `Arc` of its
//! retained variables, which every engine has its own of) and changes the address space to the
//! announced plan ([`Following::plan_of`], then `space::change`). A queued engine the scan
//! thread refuses is never copied; its plan is dropped after [`KEPT`] newer ones. The mirror
//! learns the announced engine's bytes at once ([`Mirror::serve_also`]), so that even its first
//! copies take the served variables' bytes only, not its whole variable memory.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use super::nodes::{self, Plan};
use crate::drivers::real_time::mirror::{byte_ranges, Mirror, ServedBytes};
use crate::project::OpcuaNames;
use crate::symbols::Symbols;
use crate::vm::retained::RetainedVariables;

/// Plans kept for engines announced and not yet seen in a copy.
pub const KEPT: usize = 4;

/// The plans of the engines the daemon announced.
pub struct Following {
    max_nodes: usize,
    /// `[[opcua.devices]]`: the same in every plan.
    devices: Vec<crate::config::OpcuaDevices>,
    /// The device words the mirror copies: a located variable past them is not served.
    words: u16,
    plans: Mutex<VecDeque<(Arc<RetainedVariables>, Arc<Plan>)>>,
    /// The server's mirror, told each announced engine's bytes.
    mirror: Arc<Mirror>,
}

/// The bytes of variable memory `plan`'s variables are read from: what the scan thread copies
/// for the server, instead of the whole memory (docs/OPCUA.md, "Off the scan path").
pub fn variable_bytes(plan: &Plan) -> ServedBytes {
    use crate::value::Space;
    let pieces = plan
        .leaves
        .iter()
        .filter(|leaf| leaf.at.space == Space::Var)
        .map(|leaf| (leaf.at.offset, leaf.ty.bytes()));
    // Pieces closer than 64 bytes are copied as one.
    byte_ranges(pieces, 64)
}

impl Following {
    pub fn new(
        max_nodes: usize,
        words: u16,
        devices: Vec<crate::config::OpcuaDevices>,
        mirror: Arc<Mirror>,
    ) -> Following {
        Following { max_nodes, devices, words, plans: Mutex::new(VecDeque::new()), mirror }
    }

    /// The plan of `symbols` for a server whose mirror copies `words` device words: at most
    /// `max_nodes` variables, the located ones within the copy; `names` as
    /// [`crate::project::Project::opcua_names`] gives them.
    pub fn plan(&self, symbols: &Symbols, names: &OpcuaNames) -> Plan {
        let mut plan = Plan::of(symbols, self.max_nodes, names).with_devices(&self.devices);
        let before = plan.leaves.len();
        plan.leaves.retain(|leaf| nodes::device_end(leaf).is_none_or(|end| end <= self.words));
        plan.unserved += before - plan.leaves.len();
        plan
    }

    /// An engine the daemon is about to queue: `layout` is its
    /// [`crate::engine::Engine::retained_variables`], `symbols` and `names` its project's.
    pub fn announce(&self, layout: &Arc<RetainedVariables>, symbols: &Symbols, names: &OpcuaNames) {
        let plan = Arc::new(self.plan(symbols, names));
        self.mirror.serve_also(layout, variable_bytes(&plan));
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        if plans.len() >= KEPT {
            plans.pop_front();
        }
        plans.push_back((Arc::clone(layout), plan));
    }

    /// The plan announced for the engine of `layout`, taken: it is announced once, seen once.
    pub fn plan_of(&self, layout: &Arc<RetainedVariables>) -> Option<Arc<Plan>> {
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        let at = plans.iter().position(|(l, _)| Arc::ptr_eq(l, layout))?;
        plans.remove(at).map(|(_, plan)| plan)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::{Elem, Pointer, Space, Symbol, ValueType};

    fn symbols(names: &[(&str, Space, u32)]) -> Symbols {
        let mut symbols = Symbols::default();
        for (name, space, offset) in names {
            symbols.push(Symbol {
                name: name.to_string(),
                ty: ValueType::Signed(Elem::I16),
                at: Pointer { space: *space, offset: *offset },
                retain: false,
                constant: false,
            });
        }
        symbols
    }

    fn following() -> (Following, Arc<Mirror>) {
        let mirror = Arc::new(Mirror::with_all_variables(std::iter::empty()));
        (Following::new(100, 10, Vec::new(), Arc::clone(&mirror)), mirror)
    }

    #[test]
    fn an_announced_engine_s_bytes_are_told_to_the_mirror_at_once() {
        let (following, mirror) = following();
        let layout = Arc::new(RetainedVariables::default());
        let names = symbols(&[("main.a", Space::Var, 100), ("main.w", Space::Word, 3)]);
        following.announce(&layout, &names, &OpcuaNames::default());
        let image = mirror.lock();
        let (served, bytes) = image.served.last().expect("told");
        assert!(Arc::ptr_eq(served, &layout));
        let expected = std::iter::once(100..102).collect::<Vec<_>>();
        assert_eq!(&bytes[..], &expected[..], "the variable's bytes, not the device word's");
    }

    #[test]
    fn an_engine_is_found_by_its_layout_once_and_old_announcements_go() {
        let (following, _) = following();
        let layouts: Vec<Arc<RetainedVariables>> =
            (0..=KEPT).map(|_| Arc::new(RetainedVariables::default())).collect();
        let names = symbols(&[("main.a", Space::Var, 0)]);
        for layout in &layouts {
            following.announce(layout, &names, &OpcuaNames::default());
        }
        assert!(following.plan_of(&layouts[0]).is_none(), "dropped after {KEPT} newer ones");
        let plan = following.plan_of(&layouts[KEPT]).expect("announced");
        assert_eq!(plan.leaves[0].id, "main.a");
        assert!(following.plan_of(&layouts[KEPT]).is_none(), "taken once");
        assert!(following.plan_of(&Arc::new(RetainedVariables::default())).is_none());
    }

    #[test]
    fn a_located_variable_past_the_copied_words_is_not_served() {
        let (following, _) = following();
        let names = symbols(&[
            ("main.in_copy", Space::Word, 9),
            ("main.past", Space::Word, 10),
            ("main.var", Space::Var, 0),
        ]);
        let plan = following.plan(&names, &OpcuaNames::default());
        let ids: Vec<&str> = plan.leaves.iter().map(|l| l.id.as_str()).collect();
        assert_eq!(ids, ["main.in_copy", "main.var"]);
        assert_eq!(plan.unserved, 1);
    }
}
