//! Online change: new programs swapped in at a scan boundary of a running PLC, without losing a
//! scan and without touching device memory, timers, counters, DUTY clocks or the task figures.
//!
//! The work is split the way the threads are. [`prepare`] runs off the real-time path: it checks
//! that the new project is compatible with the running one (the same tasks, none of the sections
//! [`crate::config::Config::refused_sections`] names for an online change) and builds the new
//! engine and the plan for its edge memory. [`Engine::take_over`] runs on the scan thread at a
//! scan boundary: it moves the running state into the new engine by swapping and copying,
//! allocating nothing.
//!
//! Edge memory is the one piece of state that belongs to instructions rather than devices. A
//! program whose code is unchanged keeps its slots. In a changed program an edge instruction
//! must neither fire because of the change nor miss a real edge later, so each slot starts as
//! if the instruction had already executed in the previous scan with the state of now: a
//! contact edge (`LOADP`/`LOADN`/…) remembers the contact's current value; a rung edge
//! (`OUTP`, `FF`, `MOVP`, `DUTY`, …) remembers "ON" for rising and "OFF" for falling, so it
//! first fires at a transition that happens after the change.

use std::collections::HashMap;

use crate::config::{ProjectChange, TaskConfig, TaskKind};
use crate::device::Address;
use crate::lang::ops::{EdgeMemory, Op};
use crate::lang::Variables;
use crate::project::Project;
use crate::symbols::{ArraySymbol, Entry};
use crate::value::{Space, Symbol, ValueType};
use crate::vm::EdgeInit;

use super::mode::ModeState;
use super::scan::Phase;
use super::task::State;
use super::{Engine, Refusal};

/// A prepared online change: the new engine and the initial state of its edge memory.
pub struct OnlineChange {
    pub engine: Box<Engine>,
    pub edges: Box<[EdgeInit]>,
}

/// Why the new project cannot replace the running one online, one reason per entry.
pub fn incompatibilities(old: &Project, new: &Project) -> Vec<String> {
    let (a, b) = (&old.config, &new.config);
    let mut reasons = Vec::new();
    for name in a.refused_sections(b, ProjectChange::Online) {
        reasons.push(format!("{name} changed; it can only change with the PLC in STOP"));
    }
    for task in &a.tasks {
        match b.tasks.iter().find(|t| t.name == task.name) {
            None => reasons.push(format!("task \"{}\" is removed", task.name)),
            Some(new_task) => {
                let changed = task_changes(task, new_task);
                if !changed.is_empty() {
                    reasons.push(format!(
                        "task \"{}\" changed ({}); tasks can only change with the PLC in STOP",
                        task.name,
                        changed.join(", ")
                    ));
                }
            }
        }
    }
    for task in &b.tasks {
        if !a.tasks.iter().any(|t| t.name == task.name) {
            reasons.push(format!("task \"{}\" is added", task.name));
        }
    }
    if reasons.is_empty() && a.tasks.iter().map(|t| &t.name).ne(b.tasks.iter().map(|t| &t.name)) {
        reasons.push("the [[task]] order changed (it decides ties between requests)".into());
    }
    reasons
}

fn task_changes(a: &TaskConfig, b: &TaskConfig) -> Vec<&'static str> {
    let mut changed = Vec::new();
    if a.number != b.number {
        changed.push("number");
    }
    if a.priority != b.priority {
        changed.push("priority");
    }
    if a.max_exec_ms != b.max_exec_ms {
        changed.push("max_exec_ms");
    }
    match (&a.kind, &b.kind) {
        (TaskKind::Cycle { .. }, TaskKind::Cycle { .. })
        | (TaskKind::Io { .. }, TaskKind::Io { .. })
        | (TaskKind::Device { .. }, TaskKind::Device { .. }) => {
            if a.kind != b.kind {
                changed.push("its start condition");
            }
        }
        _ => changed.push("kind"),
    }
    changed
}

/// Checks `new` against the running project `old` and builds what the scan thread needs to
/// swap it in. Runs off the real-time path.
pub fn prepare(
    old: &Project,
    new: &Project,
    watch: &[Address],
) -> Result<OnlineChange, Vec<String>> {
    let reasons = incompatibilities(old, new);
    if !reasons.is_empty() {
        return Err(reasons);
    }
    let mut edges = Vec::new();
    for program in &new.programs {
        let unchanged =
            old.programs.iter().find(|p| p.name == program.name && p.code == program.code);
        match unchanged {
            Some(before) => {
                edges.extend((0..program.edge_slots).map(|i| EdgeInit::Keep(before.edge_base + i)))
            }
            None => {
                let first = edges.len();
                edges.resize(first + program.edge_slots as usize, EdgeInit::Value(false));
                for op in program.code.iter() {
                    if let Some((slot, init)) = fresh_edge(op) {
                        edges[first + (u32::from(slot) - program.edge_base) as usize] = init;
                    }
                }
            }
        }
    }
    let mut engine = Box::new(Engine::new(new, watch));
    engine.kept_variables = kept_variables(&old.variables, &new.variables);
    // the running programs the new project no longer has: their instances' FB_exit runs
    engine.finish.removed = (0..old.programs.len() as u16)
        .filter(|&i| !new.programs.iter().any(|p| p.name == old.programs[usize::from(i)].name))
        .collect();
    engine.finish.copies = super::finish::copied_instances(old, new);
    engine.finish.global_copies = super::finish::copied_globals(old, new);
    engine.finish.added = super::finish::added_instances(old, new);
    Ok(OnlineChange { engine, edges: edges.into_boxed_slice() })
}

/// The Structured Text variables an online change keeps: each leaf of the new project whose
/// name (case-insensitive) and type are those of a leaf of the old, as `(old offset, new
/// offset, bytes)` in variable memory. Any other starts from its initial value.
///
/// An array whose element is declared the same in both (the same leaves at the same places)
/// is matched as a whole: each element of the new bounds that the old bounds have keeps its
/// leaves, neighbouring ones in one copy, without naming them; any other entry is matched
/// leaf by leaf by name.
pub fn kept_variables(old: &Variables, new: &Variables) -> Box<[(u32, u32, u32)]> {
    let entry_name = |entry: &Entry| entry.name().to_ascii_lowercase();
    let old_entries: HashMap<String, &Entry> =
        old.symbols.entries().iter().map(|e| (entry_name(e), e)).collect();
    let mut kept = Vec::new();
    for entry in new.symbols.entries() {
        match (entry, old_entries.get(&entry_name(entry))) {
            (Entry::Leaf(symbol), Some(Entry::Leaf(before))) => {
                kept.extend(kept_leaf(before, symbol));
            }
            // no leaf of the old is named as a new leaf outside an array, or as a whole array
            (Entry::Leaf(symbol), None) if !symbol.name.contains('[') => {}
            (Entry::Leaf(_), Some(Entry::Array(_))) | (Entry::Array(_), Some(Entry::Leaf(_))) => {}
            (Entry::Array(array), Some(Entry::Array(before)))
                if before.dims.len() == array.dims.len() && before.element == array.element =>
            {
                keep_elements(before, array, &mut kept);
            }
            (entry, _) => {
                // Every leaf's name starts with its entry's: an old entry shares a leaf with
                // this one only if one's name starts with the other's (an array named alike,
                // the old leaves of an array once expanded element by element).
                let name = entry_name(entry);
                let by_name: HashMap<String, Symbol> = old
                    .symbols
                    .entries()
                    .iter()
                    .filter(|old| {
                        let old = entry_name(old);
                        old.starts_with(&name) || name.starts_with(&old)
                    })
                    .flat_map(Entry::leaves)
                    .map(|s| (s.name.to_ascii_lowercase(), s))
                    .collect();
                for symbol in entry.leaves() {
                    if let Some(before) = by_name.get(&symbol.name.to_ascii_lowercase()) {
                        kept.extend(kept_leaf(before, &symbol));
                    }
                }
            }
        }
    }
    kept.into_boxed_slice()
}

/// `(old offset, new offset, bytes)` if `symbol` keeps the value of `before`, its namesake.
fn kept_leaf(before: &Symbol, symbol: &Symbol) -> Option<(u32, u32, u32)> {
    let in_vars = |s: &Symbol| s.at.space == Space::Var;
    // A reference is not kept: its offset is one of the old layout of memory.
    let reference = matches!(symbol.ty, ValueType::Reference { .. });
    (before.ty == symbol.ty && in_vars(before) && in_vars(symbol) && !reference)
        .then(|| (before.at.offset, symbol.at.offset, symbol.ty.bytes()))
}

/// The kept leaves of `array`, whose element is declared as `before`'s: each element whose
/// indices are in both bounds, the leaves of one element kept as [`kept_leaf`] keeps them.
fn keep_elements(before: &ArraySymbol, array: &ArraySymbol, kept: &mut Vec<(u32, u32, u32)>) {
    if before.at.space != Space::Var || array.at.space != Space::Var {
        return;
    }
    let places: Vec<(u32, u32)> = array
        .element
        .iter()
        .filter(|s| s.at.space == Space::Var && !matches!(s.ty, ValueType::Reference { .. }))
        .map(|s| (s.at.offset, s.ty.bytes()))
        .collect();
    let mut indices: Vec<i64> = array.dims.iter().map(|d| d.0).collect();
    for k in 0..array.count() {
        let mut old_k = Some(0u64);
        for (&i, &(lo, hi)) in indices.iter().zip(&before.dims) {
            old_k = old_k.filter(|_| lo <= i && i <= hi).map(|k| k * (hi - lo + 1) as u64);
            old_k = old_k.map(|k| k + (i - lo) as u64);
        }
        if let Some(old_k) = old_k {
            let from = before.at.offset.wrapping_add((old_k as u32).wrapping_mul(before.stride));
            let to = array.at.offset.wrapping_add((k as u32).wrapping_mul(array.stride));
            for &(at, len) in &places {
                let (from, to) = (from.wrapping_add(at), to.wrapping_add(at));
                match kept.last_mut() {
                    // the next bytes in both: one copy
                    Some((f, t, l)) if *f + *l == from && *t + *l == to => *l += len,
                    _ => kept.push((from, to, len)),
                }
            }
        }
        for d in (0..indices.len()).rev() {
            if indices[d] < array.dims[d].1 {
                indices[d] += 1;
                break;
            }
            indices[d] = array.dims[d].0;
        }
    }
}

/// The initial state of a changed program's edge slot: as if the instruction had executed in
/// the previous scan with the state of now. A rung edge remembers the state it waits to leave
/// (ON for a rising edge, OFF for a falling one), so it fires at the first real transition.
fn fresh_edge(op: &Op) -> Option<(u16, EdgeInit)> {
    op.edge_memory().map(|(slot, memory)| match memory {
        EdgeMemory::Contact(bit) => (slot, EdgeInit::FromBit(bit)),
        EdgeMemory::Rung { rising } => (slot, EdgeInit::Value(rising)),
    })
}

impl Engine {
    /// Scan thread, at a scan boundary: this (new, prepared) engine takes over the running
    /// state of `old` — mode, device memory, timers, counters, DUTY clocks, task states and
    /// figures, forces, the key switch — with its edge memory set up by `edges`. Breakpoints
    /// are cleared (they named the old programs). Allocates nothing.
    pub fn take_over(&mut self, old: &mut Engine, edges: &[EdgeInit]) -> Result<(), Refusal> {
        if old.phase() != Phase::Idle || !old.stack.is_empty() {
            return Err(Refusal::MidScan);
        }
        let copies = std::mem::take(&mut self.finish.copies);
        let global_copies = std::mem::take(&mut self.finish.global_copies);
        let now = old.scan_start_ns;
        if old.running() {
            let removed = std::mem::take(&mut self.finish.removed);
            old.finish_removed(&removed, now);
            self.finish.removed = removed;
            // the instances whose declaration changed, as CODESYS: FB_exit(bInCopyCode :=
            // TRUE) on the old copy, FB_init(bInCopyCode := TRUE) on the new, the values
            // carried over, then FB_reinit
            // the global instances likewise, after the PROGRAMs' at each phase
            old.copy_phase(&copies, true, 1, now);
            old.copy_globals_phase(&global_copies, true, 1, now);
            self.copy_phase(&copies, false, 2, now);
            self.copy_globals_phase(&global_copies, false, 2, now);
        }
        self.vm.take_over(&mut old.vm, edges);
        self.vm.keep_variables(&old.vm, &self.kept_variables);
        self.vm.canonicalize_bools(&self.bool_variables);
        if old.running() {
            let added = std::mem::take(&mut self.finish.added);
            self.init_added(&added, now);
            self.finish.added = added;
            self.copy_phase(&copies, false, 3, now);
            self.copy_globals_phase(&global_copies, false, 3, now);
        }
        self.finish.copies = copies;
        self.finish.global_copies = global_copies;
        for (new, old) in self.tasks.iter_mut().zip(old.tasks.iter_mut()) {
            new.kind = old.kind.clone();
            new.state = match old.state {
                State::Pending { at_ns } => State::Pending { at_ns },
                _ => State::Idle,
            };
            new.occurred_ns = old.occurred_ns;
            new.starts = old.starts;
            std::mem::swap(&mut new.stats, &mut old.stats);
        }
        self.mode = match old.mode {
            ModeState::Debug(running, session) => {
                ModeState::Debug(running, session.without_places())
            }
            mode => mode,
        };
        self.run_start_ns = old.run_start_ns;
        self.scan_start_ns = old.scan_start_ns;
        self.watchdog_start_ns = old.watchdog_start_ns;
        self.next_scan_ns = old.next_scan_ns;
        self.next_stop_refresh_ns = old.next_stop_refresh_ns;
        std::mem::swap(&mut self.scan, &mut old.scan);
        self.forces = old.forces.clone();
        // Breakpoints name instructions of the old programs: neither engine keeps them.
        std::mem::swap(&mut self.debugger, &mut old.debugger);
        self.debugger.clear();
        // Whether there is a switch at all is the new config's to say.
        if let (Some(switch), Some(old)) = (&mut self.switch, old.switch) {
            *switch = old;
        }
        self.last_operation_error = None;
        // The running engine's retained memory is this one's now: the next RUN start is warm.
        self.retained = old.retained;
        self.sample_watches_quietly();
        Ok(())
    }
}
