//! TwinCAT's task information for Tc2_System (docs/ST.md, "Task information"): when the project
//! compiles the library's `TwinCAT_SystemInfoVarList` (`[st] system_libraries`), the engine
//! writes into its variables what a TwinCAT program reads there, from its own task table:
//! at each task's start the task's entry of `_TaskInfo` (its runs, first run, period, previous
//! execution time, name), and before each stretch of a task's code the index
//! `GETCURTASKINDEX` answers, so that a task preempted and resumed reads its own again.
//!
//! At the end of each task run it reports the messages the run logged with `ADSLOGSTR` and
//! its kin (`<Tc2_System>/adslog.st` queues at most 32 of them a run and counts the rest) to
//! the event sink, borrowed from variable memory, and empties the queue.
//!
//! The places are found once, by name, when the engine is built; writing them is a few stores
//! into variable memory, without allocation.

use crate::project::Project;
use crate::value::{Elem, Pointer, Symbol, ValueType};
use crate::vm::Vm;

use super::event::{EventSink, TaskId};

/// The places of one task's `_TaskInfo[i]`.
#[derive(Debug, Clone, Copy)]
struct TaskPlaces {
    cycle_count: Pointer,
    first_cycle: Pointer,
    cycle_time: Pointer,
    last_exec_time: Pointer,
    task_name: Option<(Pointer, u32)>,
}

/// The queue of ADS log messages `ADSLOGSTR` fills (`<Tc2_System>/adslog.st`).
#[derive(Debug, Clone)]
struct LogPlaces {
    count: Pointer,
    dropped: Pointer,
    /// Each entry's `msgCtrlMask` and `text`.
    entries: Box<[(Pointer, Pointer)]>,
}

/// Where the engine writes the task information and reads the messages; built only when the
/// library declares them.
#[derive(Debug, Clone)]
pub(super) struct SystemInfo {
    /// `__TC2_CURRENT_TASK`: the running task's index (its id + 1).
    current: Pointer,
    /// Indexed by task id.
    tasks: Box<[Option<TaskPlaces>]>,
    log: Option<LogPlaces>,
}

impl SystemInfo {
    /// The places of the library's variables in `project`, for `task_count` tasks; `None` when
    /// the project does not compile `Tc2_System`.
    pub(super) fn of(project: &Project, task_count: usize) -> Option<Box<SystemInfo>> {
        let symbols = &project.variables.symbols;
        let find = |name: &str| -> Option<Symbol> { symbols.find(name) };
        let current = find("__TC2_CURRENT_TASK")?.at;
        let tasks = (0..task_count)
            .map(|id| {
                let field = |f: &str| find(&format!("_TaskInfo[{}].{f}", id + 1));
                let name = field("TaskName").and_then(|s| match s.ty {
                    ValueType::String { cap } => Some((s.at, cap)),
                    _ => None,
                });
                Some(TaskPlaces {
                    cycle_count: field("CycleCount")?.at,
                    first_cycle: field("FirstCycle")?.at,
                    cycle_time: field("CycleTime")?.at,
                    last_exec_time: field("LastExecTime")?.at,
                    task_name: name,
                })
            })
            .collect();
        let log = (|| {
            let entry = |k: usize| {
                let mask = find(&format!("__TC2_LOG[{k}].msgCtrlMask"))?.at;
                Some((mask, find(&format!("__TC2_LOG[{k}].text"))?.at))
            };
            let entries: Box<[_]> = (0..).map_while(entry).collect();
            let count = find("__TC2_LOG_COUNT")?.at;
            Some(LogPlaces { count, dropped: find("__TC2_LOG_DROPPED")?.at, entries })
        })();
        Some(Box::new(SystemInfo { current, tasks, log }))
    }

    /// Task `id` starts a run: its entry counts it (from the count in variable memory, which
    /// a RUN start sets back to 0, so the first run after it is the first cycle), with the
    /// execution time of its previous run (`previous_ns`) and its period (`period_ns`, 0 for an
    /// event task).
    #[inline(never)]
    pub(super) fn task_started(
        &self,
        vm: &mut Vm,
        id: usize,
        name: &str,
        period_ns: u64,
        previous_ns: u64,
    ) {
        let Some(Some(at)) = self.tasks.get(id) else { return };
        let count = vm.read_value(at.cycle_count, Elem::U32).wrapping_add(1) & 0xFFFF_FFFF;
        vm.write_value(at.cycle_count, Elem::U32, count);
        vm.write_value(at.first_cycle, Elem::Bool, u64::from(count == 1));
        let units = |ns: u64| (ns / 100).min(u64::from(u32::MAX));
        vm.write_value(at.last_exec_time, Elem::U32, units(previous_ns));
        if count == 1 {
            vm.write_value(at.cycle_time, Elem::U32, units(period_ns));
            if let Some((place, cap)) = at.task_name {
                vm.write_string(place, cap, name.as_bytes());
            }
        }
    }

    /// Task `id`'s code runs now. Out of line, so that `Engine::run`'s loop grows by a test
    /// and a call only (its code layout is measured: BENCHMARKS.md).
    #[inline(never)]
    pub(super) fn running(&self, vm: &mut Vm, id: usize) {
        vm.write_value(self.current, Elem::U8, (id as u64 + 1) & 0xFF);
    }

    /// Task `task`'s run ended: the messages it logged go to `sink`, with the count of those
    /// beyond the cap, and the queue is emptied for the next run.
    #[inline(never)]
    pub(super) fn task_ended(
        &self,
        vm: &mut Vm,
        now: u64,
        task: TaskId,
        sink: &mut impl EventSink,
    ) {
        let Some(log) = &self.log else { return };
        let count = vm.read_value(log.count, Elem::U32) as usize;
        let dropped = vm.read_value(log.dropped, Elem::U32) as u32;
        if count == 0 && dropped == 0 {
            return;
        }
        for &(mask, text) in log.entries.iter().take(count) {
            let mask = vm.read_value(mask, Elem::U32) as u32;
            sink.message(now, task, mask, vm.string_bytes(text));
        }
        if dropped > 0 {
            sink.messages_dropped(now, task, dropped);
        }
        vm.write_value(log.count, Elem::U32, 0);
        vm.write_value(log.dropped, Elem::U32, 0);
    }
}
