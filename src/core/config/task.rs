//! `[[task]]`: the interrupt tasks (cycle, io and device), their numbers, priorities and
//! start conditions.

use std::collections::HashMap;
use std::ops::RangeInclusive;

use serde::Deserialize;
use toml::Spanned;

use super::common::{int, start, widen, Ctx, Located};
use super::io::Backend;
use super::{RawDoc, Sink};
use crate::device::{Address, Area};
use crate::diag::Diagnostic;

/// One `[[task]]`: an interrupt task of the XGB task table. Every key except `max_exec_ms`
/// and the keys of other kinds is required.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskConfig {
    /// `name`: unique, not empty, and neither `init` nor `scan` (in any case).
    pub name: String,
    /// `number`: unique; cycle 0..=7, io 8..=15, device 16..=23.
    pub number: u8,
    /// `priority`: 2 (highest) ..= 7 (lowest).
    pub priority: u8,
    /// `kind` and the keys of that kind.
    pub kind: TaskKind,
    /// `max_exec_ms`: the congestion limit, 1..=4294967295; default none.
    pub max_exec_ms: Option<u32>,
    /// Line of the `[[task]]` header in the config.
    pub line: u32,
    /// Column of the `[[task]]` header.
    pub col: u32,
}

impl TaskConfig {
    pub const PRIORITY: RangeInclusive<u8> = 2..=7;
}

/// `kind` of a task and the start condition that goes with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TaskKind {
    /// `kind = "cycle"`: runs every `interval_ms` (1..=4294967295).
    Cycle { interval_ms: u32 },
    /// `kind = "io"`: runs on an `edge` of the input `contact` (P0000..=P0007).
    Io { contact: Address, edge: Edge },
    /// `kind = "device"`: runs when `condition` holds on `device`, checked after each scan.
    Device { device: Address, condition: DeviceCondition },
}

/// `edge` of an io task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Edge {
    Rising,
    Falling,
    Both,
}

/// `condition` (and `value`) of a device task. The first five need a bit device, the others a
/// word device and a `value` in -32768..=32767, compared as a signed 16-bit number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceCondition {
    Rising,
    Falling,
    Transition,
    On,
    Off,
    Greater(i16),
    GreaterEq(i16),
    Less(i16),
    LessEq(i16),
}

/// Every number a task may have, whatever its kind (`DI n`, `EI n` name one).
pub const TASK_NUMBERS: std::ops::RangeInclusive<i64> = 0..=23;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawKind {
    Cycle,
    Io,
    Device,
}

impl RawKind {
    /// As written in the config.
    pub fn text(self) -> &'static str {
        match self {
            Self::Cycle => "cycle",
            Self::Io => "io",
            Self::Device => "device",
        }
    }

    /// The task numbers of this kind (XGB: cycle 0–7, I/O 8–15, internal device 16–23).
    pub fn numbers(self) -> std::ops::RangeInclusive<i64> {
        match self {
            Self::Cycle => 0..=7,
            Self::Io => 8..=15,
            Self::Device => 16..=23,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum RawCondition {
    Rising,
    Falling,
    Transition,
    On,
    Off,
    #[serde(rename = ">")]
    Greater,
    #[serde(rename = ">=")]
    GreaterEq,
    #[serde(rename = "<")]
    Less,
    #[serde(rename = "<=")]
    LessEq,
}

impl RawCondition {
    /// True for the conditions on a word device, which compare with `value`.
    pub fn is_word(self) -> bool {
        matches!(self, Self::Greater | Self::GreaterEq | Self::Less | Self::LessEq)
    }

    /// As written in the config.
    pub fn text(self) -> &'static str {
        match self {
            Self::Rising => "rising",
            Self::Falling => "falling",
            Self::Transition => "transition",
            Self::On => "on",
            Self::Off => "off",
            Self::Greater => ">",
            Self::GreaterEq => ">=",
            Self::Less => "<",
            Self::LessEq => "<=",
        }
    }
}

/// A `[[task]]` with the keys of every kind; `validate` checks which belong.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTask {
    pub name: Spanned<String>,
    pub kind: Spanned<RawKind>,
    pub number: Spanned<i64>,
    pub priority: Spanned<i64>,
    pub interval_ms: Option<Spanned<i64>>,
    pub contact: Option<Spanned<String>>,
    pub edge: Option<Spanned<Edge>>,
    pub device: Option<Spanned<String>>,
    pub condition: Option<Spanned<RawCondition>>,
    pub value: Option<Spanned<i64>>,
    pub max_exec_ms: Option<Spanned<i64>>,
}

pub(super) fn validate(
    sink: &mut Sink,
    raw: Vec<Located<RawTask>>,
    gpio_inputs: Option<&[Address]>,
) -> Option<Vec<TaskConfig>> {
    let mut ok = true;
    let mut names: HashMap<String, u32> = HashMap::new();
    let mut numbers: HashMap<i64, String> = HashMap::new();
    let mut tasks = Vec::new();
    for task in raw {
        let (line, col) = Diagnostic::line_col(sink.text, task.span.start);
        let name = check_task_name(sink, &task, line, &mut names);
        let number = check_task_number(sink, &task, &mut numbers);
        let (ctx, raw) = (&task.ctx, &task.value);
        let priority = int(sink, ctx, "priority", &raw.priority, widen(TaskConfig::PRIORITY));
        let kind = task_kind(sink, &task, gpio_inputs);
        let max_exec_ms = match &raw.max_exec_ms {
            Some(value) => int(sink, ctx, "max_exec_ms", value, 1..=i64::from(u32::MAX)).map(Some),
            None => Some(None),
        };
        match (name, number, priority, kind, max_exec_ms) {
            (Some(name), Some(number), Some(priority), Some(kind), Some(max_exec_ms)) => {
                tasks.push(TaskConfig { name, number, priority, kind, max_exec_ms, line, col })
            }
            _ => ok = false,
        }
    }
    ok.then_some(tasks)
}

/// The devices of `[[io.input]]` when the gpiocdev backend must wire io-task contacts, or
/// `None` when that cannot or need not be checked (sim backend, or inputs with errors).
pub(super) fn gpio_inputs(doc: &RawDoc) -> Option<Vec<Address>> {
    let io = doc.io.as_ref()?;
    let backend_unknown = doc.failed.keys.iter().any(|k| k == "io.backend");
    if io.value.backend != Backend::Gpiocdev || doc.failed.input || backend_unknown {
        return None;
    }
    doc.inputs.iter().map(|input| Address::parse(input.value.device.get_ref()).ok()).collect()
}

fn check_task_name(
    sink: &mut Sink,
    task: &Located<RawTask>,
    line: u32,
    names: &mut HashMap<String, u32>,
) -> Option<String> {
    let (ctx, name) = (&task.ctx, &task.value.name);
    let at = name.span().start;
    let text = name.get_ref();
    if text.trim().is_empty() {
        sink.error(at, format!("{} must not be empty", ctx.key("name")));
        return None;
    }
    if ["init", "scan"].iter().any(|r| text.eq_ignore_ascii_case(r)) {
        let message =
            format!("{}: the name {text:?} is reserved for the built-in task", ctx.subject());
        sink.error(at, message);
        return None;
    }
    if let Some(first) = names.get(text) {
        let message = format!("{}: name already used by the task at line {first}", ctx.subject());
        sink.error(at, message);
        return None;
    }
    names.insert(text.clone(), line);
    Some(text.clone())
}

fn check_task_number(
    sink: &mut Sink,
    task: &Located<RawTask>,
    numbers: &mut HashMap<i64, String>,
) -> Option<u8> {
    let (ctx, raw) = (&task.ctx, &task.value);
    let kind = *raw.kind.get_ref();
    let range = kind.numbers();
    let value = *raw.number.get_ref();
    let at = raw.number.span().start;
    if !range.contains(&value) {
        let message = format!(
            "{} {value} out of range {}..={} for a {} task",
            ctx.key("number"),
            range.start(),
            range.end(),
            kind.text(),
        );
        sink.error(at, message);
        return None;
    }
    if let Some(first) = numbers.get(&value) {
        let message = format!("{} {value} is already used by {first}", ctx.key("number"));
        sink.error(at, message);
        return None;
    }
    numbers.insert(value, ctx.subject());
    u8::try_from(value).ok()
}

/// The kind's own keys, present and in range, and no key of another kind.
fn task_kind(
    sink: &mut Sink,
    task: &Located<RawTask>,
    gpio_inputs: Option<&[Address]>,
) -> Option<TaskKind> {
    let (ctx, raw) = (&task.ctx, &task.value);
    let kind = *raw.kind.get_ref();
    let mut ok = true;

    // Keys that belong to another kind.
    let owned = [
        ("interval_ms", start(&raw.interval_ms), RawKind::Cycle),
        ("contact", start(&raw.contact), RawKind::Io),
        ("edge", start(&raw.edge), RawKind::Io),
        ("device", start(&raw.device), RawKind::Device),
        ("condition", start(&raw.condition), RawKind::Device),
    ];
    for (key, at, owner) in owned {
        if let (Some(at), true) = (at, owner != kind) {
            let message = format!("{}: {key} is only for {} tasks", ctx.subject(), owner.text());
            sink.error(at, message);
            ok = false;
        }
    }
    let word_condition = raw.condition.as_ref().is_some_and(|c| c.get_ref().is_word());
    if let (Some(value), false) = (&raw.value, word_condition) {
        let message = format!(
            "{}: value is only for device tasks with a word condition (>, >=, <, <=)",
            ctx.subject()
        );
        sink.error(value.span().start, message);
        ok = false;
    }

    let mut missing = |key: &str, what: &str| {
        let message = format!("{}: {what} needs `{key}`", ctx.subject());
        sink.error(task.span.start, message);
    };
    let kind = match kind {
        RawKind::Cycle => {
            let Some(interval) = &raw.interval_ms else {
                missing("interval_ms", "a cycle task");
                return None;
            };
            let interval_ms = int(sink, ctx, "interval_ms", interval, 1..=i64::from(u32::MAX))?;
            TaskKind::Cycle { interval_ms }
        }
        RawKind::Io => {
            let (Some(contact), Some(edge)) = (&raw.contact, &raw.edge) else {
                if raw.contact.is_none() {
                    missing("contact", "an io task");
                }
                if raw.edge.is_none() {
                    missing("edge", "an io task");
                }
                return None;
            };
            let contact = io_contact(sink, ctx, contact, gpio_inputs)?;
            TaskKind::Io { contact, edge: *edge.get_ref() }
        }
        RawKind::Device => {
            let (Some(device), Some(condition)) = (&raw.device, &raw.condition) else {
                if raw.device.is_none() {
                    missing("device", "a device task");
                }
                if raw.condition.is_none() {
                    missing("condition", "a device task");
                }
                return None;
            };
            let (device, condition) = device_condition(sink, task, device, *condition.get_ref())?;
            TaskKind::Device { device, condition }
        }
    };
    ok.then_some(kind)
}

/// An io task's contact: P0000..=P0007, and wired when the backend is gpiocdev.
fn io_contact(
    sink: &mut Sink,
    ctx: &Ctx,
    contact: &Spanned<String>,
    gpio_inputs: Option<&[Address]>,
) -> Option<Address> {
    let at = contact.span().start;
    let address = match Address::parse(contact.get_ref()) {
        Ok(address)
            if address.area == Area::P
                && address.number == 0
                && address.bit.is_some_and(|b| b <= 7) =>
        {
            address
        }
        Ok(_) => {
            let message = format!(
                "{} {:?} must be one of P0000..=P0007",
                ctx.key("contact"),
                contact.get_ref()
            );
            sink.error(at, message);
            return None;
        }
        Err(e) => {
            sink.error(at, format!("{}: {e}", ctx.key("contact")));
            return None;
        }
    };
    if gpio_inputs.is_some_and(|inputs| !inputs.contains(&address)) {
        let message = format!(
            "{}: contact {address} is not wired: add an [[io.input]] with device = \"{address}\" \
             (the gpiocdev backend could never start the task)",
            ctx.subject()
        );
        sink.error(at, message);
        return None;
    }
    Some(address)
}

/// A device task's condition: bit conditions on a bit device, word conditions on a word device
/// with a `value` that fits a signed 16-bit word.
fn device_condition(
    sink: &mut Sink,
    task: &Located<RawTask>,
    device: &Spanned<String>,
    condition: RawCondition,
) -> Option<(Address, DeviceCondition)> {
    let (ctx, raw) = (&task.ctx, &task.value);
    let address = match Address::parse(device.get_ref()) {
        Ok(address) => address,
        Err(e) => {
            sink.error(device.span().start, format!("{}: {e}", ctx.key("device")));
            return None;
        }
    };
    let fits =
        if condition.is_word() { address.as_word().map(drop) } else { address.as_bit().map(drop) };
    if let Err(e) = fits {
        let message = format!("{}: condition {:?}: {e}", ctx.subject(), condition.text());
        sink.error(device.span().start, message);
        return None;
    }
    let bit_condition = match condition {
        RawCondition::Rising => Some(DeviceCondition::Rising),
        RawCondition::Falling => Some(DeviceCondition::Falling),
        RawCondition::Transition => Some(DeviceCondition::Transition),
        RawCondition::On => Some(DeviceCondition::On),
        RawCondition::Off => Some(DeviceCondition::Off),
        _ => None,
    };
    if let Some(bit_condition) = bit_condition {
        return Some((address, bit_condition));
    }
    let Some(value) = &raw.value else {
        let message = format!("{}: condition {:?} needs `value`", ctx.subject(), condition.text());
        sink.error(task.span.start, message);
        return None;
    };
    let value = int(sink, ctx, "value", value, widen(i16::MIN..=i16::MAX))?;
    let word_condition = match condition {
        RawCondition::Greater => DeviceCondition::Greater(value),
        RawCondition::GreaterEq => DeviceCondition::GreaterEq(value),
        RawCondition::Less => DeviceCondition::Less(value),
        _ => DeviceCondition::LessEq(value),
    };
    Some((address, word_condition))
}
