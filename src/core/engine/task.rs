//! The tasks as the engine keeps them: what starts each one (its [`Kind`]), where it stands
//! ([`State`]), its programs and execution state, and its figures ([`TaskStats`]). Built once
//! from the config; the schedule moves them between states, nothing here decides when.

use crate::config::{Config, DeviceCondition, Edge, TaskKind as ConfigTaskKind, TaskRef};
use crate::device::{BitRef, Memory, WordRef};
use crate::stats::Histogram;
use crate::vm::ExecState;

use super::event::{INIT, SCAN};
use super::schedule::Starts;
use super::NS_PER_MS;

/// Priority of the scan program: below every task (2..=7).
const SCAN_PRIORITY: u8 = 8;

/// A device a condition or a watch reads, resolved once so that reading it is a load.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Sample {
    Bit(BitRef),
    Word(WordRef),
}

/// What starts a task, with the state its start condition moves through: a cycle task's next
/// deadline, a device task's sample at the previous END.
#[derive(Debug, Clone)]
pub(super) enum Kind {
    Scan,
    Init,
    Cycle { interval_ns: u64, next_ns: u64 },
    Io { contact: u8, edge: Edge },
    Device { sample: Sample, when: DeviceCondition, previous: i32 },
}

/// Where a task stands. Invariant: a task is on the engine's stack exactly while `Active`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum State {
    /// Neither requested nor started.
    Idle,
    /// Requested at `at_ns` (ties of the same instant go by task id, which is config order).
    Pending { at_ns: u64 },
    /// Started and not finished (executing or preempted).
    Active { preempted: bool },
}

/// Figures kept per task, without allocation.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TaskStats {
    pub runs: u64,
    pub ignored: u64,
    /// Cycle deadlines that found the task running or waiting.
    pub overruns: u64,
    /// From the start condition (cycle deadline, the edge's timestamp, the END that sampled a
    /// device condition) to the task's first instruction.
    pub start_latency: Histogram,
    /// The part of `start_latency` before the engine learned of the start condition: how late
    /// the driver woke up for a cycle deadline, the edge's way through the event path. The
    /// rest is the engine's own: dispatch, and waiting for higher-priority tasks.
    pub notice_latency: Histogram,
    /// The task's own execution time per run, from first instruction to END, without the time
    /// higher-priority tasks took while it was preempted.
    pub exec_time: Histogram,
}

/// A task: its start condition, priority and programs, where it stands, and its figures.
/// `current`, `exec`, `used_ns` and `congested` describe the run under way, set afresh when it
/// begins.
#[derive(Debug, Clone)]
pub(super) struct Task {
    pub(super) name: String,
    pub(super) kind: Kind,
    pub(super) priority: u8,
    pub(super) number: Option<u8>,
    pub(super) programs: Box<[u16]>,
    pub(super) current: usize,
    pub(super) exec: ExecState,
    pub(super) state: State,
    /// When the start condition of the pending request occurred.
    pub(super) occurred_ns: u64,
    /// Whether `DI n` holds this task's starts.
    pub(super) starts: Starts,
    pub(super) max_exec_ns: Option<u64>,
    pub(super) used_ns: u64,
    pub(super) congested: bool,
    pub(super) stats: TaskStats,
}

impl Task {
    fn new(name: &str, kind: Kind, priority: u8, number: Option<u8>, programs: Vec<u16>) -> Task {
        Task {
            name: name.to_string(),
            kind,
            priority,
            number,
            programs: programs.into_boxed_slice(),
            current: 0,
            exec: ExecState::new(),
            state: State::Idle,
            occurred_ns: 0,
            starts: Starts::Enabled,
            max_exec_ns: None,
            used_ns: 0,
            congested: false,
            stats: TaskStats::default(),
        }
    }
}

/// A device's value as conditions and watches see it: a bit 0 or 1, a word signed.
#[inline]
pub(super) fn read_sample(mem: &Memory, sample: Sample) -> i32 {
    match sample {
        Sample::Bit(bit) => i32::from(mem.bit(bit)),
        Sample::Word(word) => i32::from(mem.word(word) as i16),
    }
}

/// The engine's tasks by [`TaskId`](super::event::TaskId): the scan program, the init task,
/// then the `[[task]]`s in config order, each with the indices of its programs.
pub(super) fn tasks_of(config: &Config) -> Vec<Task> {
    let programs_of = |task: &TaskRef| -> Vec<u16> {
        config
            .programs
            .iter()
            .enumerate()
            .filter(|(_, p)| &p.task == task)
            .map(|(i, _)| i as u16)
            .collect()
    };
    let names = task_names(config);
    let mut tasks = vec![
        Task::new(
            &names[SCAN as usize],
            Kind::Scan,
            SCAN_PRIORITY,
            None,
            programs_of(&TaskRef::Scan),
        ),
        Task::new(&names[INIT as usize], Kind::Init, 1, None, programs_of(&TaskRef::Init)),
    ];
    for task in &config.tasks {
        let kind = match &task.kind {
            ConfigTaskKind::Cycle { interval_ms } => {
                Kind::Cycle { interval_ns: u64::from(*interval_ms) * NS_PER_MS, next_ns: 0 }
            }
            ConfigTaskKind::Io { contact, edge } => {
                Kind::Io { contact: contact.bit.unwrap_or(0), edge: *edge }
            }
            ConfigTaskKind::Device { device, condition } => {
                let sample = match device.as_bit() {
                    Ok(bit) if is_bit_condition(condition) => Sample::Bit(bit),
                    _ => Sample::Word(device.as_word().expect("validated by the config")),
                };
                Kind::Device { sample, when: *condition, previous: 0 }
            }
        };
        let name = TaskRef::Named(task.name.clone());
        let mut t =
            Task::new(&task.name, kind, task.priority, Some(task.number), programs_of(&name));
        t.max_exec_ns = task.max_exec_ms.map(|ms| u64::from(ms) * NS_PER_MS);
        tasks.push(t);
    }
    tasks
}

/// Task names by [`TaskId`](super::event::TaskId): the scan program, the init task, then the `[[task]]`s in config
/// order (also the order of ties between requests of the same instant).
pub fn task_names(config: &Config) -> Vec<String> {
    let mut names = vec![TaskRef::Scan.name().to_string(), TaskRef::Init.name().to_string()];
    names.extend(config.tasks.iter().map(|t| t.name.clone()));
    names
}

fn is_bit_condition(condition: &DeviceCondition) -> bool {
    matches!(
        condition,
        DeviceCondition::Rising
            | DeviceCondition::Falling
            | DeviceCondition::Transition
            | DeviceCondition::On
            | DeviceCondition::Off
    )
}
