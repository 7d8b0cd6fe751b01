//! Pass 1: TOML text to loosely typed sections.
//!
//! The document is parsed into toml's spanned syntax tree, then every section and every
//! `[[…]]` entry is deserialized separately, so that a serde error (unknown key, wrong type,
//! bad enum value) is reported for that section or entry and the rest is still checked.
//! Numbers are read as `i64` and ranges are left to `validate`, which words them uniformly.

use std::ops::Range;

use serde::de::{DeserializeOwned, IgnoredAny};
use serde::Deserialize;
use toml::de::{DeTable, DeValue, ValueDeserializer};
use toml::Spanned;

use super::{Backend, Bias, Edge, OnFault, RtPolicy, Sink};
use crate::io::SwitchPosition;

/// What a diagnostic is about: a section (`plc`) or one entry of an array of tables
/// (`task "fast"`, `io.input #2`).
#[derive(Debug, Clone)]
pub(super) enum Ctx {
    Section(&'static str),
    Entry(String),
}

impl Ctx {
    /// The thing as a whole: `[plc]`, `task "fast"`.
    pub fn subject(&self) -> String {
        match self {
            Ctx::Section(name) => format!("[{name}]"),
            Ctx::Entry(entry) => entry.clone(),
        }
    }

    /// One of its keys: `plc.watchdog_ms`, `task "fast": priority`.
    pub fn key(&self, key: &str) -> String {
        match self {
            Ctx::Section(name) => format!("{name}.{key}"),
            Ctx::Entry(entry) => format!("{entry}: {key}"),
        }
    }
}

/// A deserialized table with the span of its header and what it is called in messages.
#[derive(Debug)]
pub(super) struct Located<T> {
    pub span: Range<usize>,
    pub ctx: Ctx,
    pub value: T,
}

/// The document after pass 1.
///
/// A section that could not be deserialized at all is `None`; one with malformed keys is
/// deserialized without them (so they take their defaults) and the keys are noted in
/// [`Failed::keys`]. An entry of an array of tables with any error is missing from its list
/// and noted in [`Failed`]. Either way pass 2 can avoid reporting what pass 1 already
/// explained (a program's task "undefined" because the task's entry had a typo).
#[derive(Debug, Default)]
pub(super) struct RawDoc {
    pub plc: Option<RawPlc>,
    pub sim: Option<RawSim>,
    pub timers: Option<RawTimers>,
    /// `[io]` without its arrays; the span is the `[io]` header (empty if there is none).
    pub io: Option<Located<RawIo>>,
    pub programs: Vec<Located<RawProgram>>,
    pub tasks: Vec<Located<RawTask>>,
    pub inputs: Vec<Located<RawInput>>,
    pub outputs: Vec<Located<RawOutput>>,
    pub rt: Option<RawRt>,
    pub control: Option<RawControl>,
    /// `[switch]`: `None` when the document has none (and when it is not a table, which is
    /// reported); the span is its header.
    pub switch: Option<Located<RawSwitch>>,
    pub retain: Option<super::retain::RawRetain>,
    /// `[modbus]` and its tables; `None` when the document has none.
    pub modbus: Option<super::modbus::RawModbusDoc>,
    pub failed: Failed,
}

/// Entries that did not deserialize.
#[derive(Debug, Default)]
pub(super) struct Failed {
    /// The malformed keys of sections, dotted (`io.chip`).
    pub keys: Vec<String>,
    /// The `name` of each failed `[[task]]`, where it was a string.
    pub task_names: Vec<String>,
    /// Some `[[program]]` failed (it may have been the scan program).
    pub program: bool,
    /// Some `[[io.input]]` failed (it may have been an io task's contact).
    pub input: bool,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlc {
    pub watchdog_ms: Option<Spanned<i64>>,
    #[serde(default)]
    pub on_fault: OnFault,
    pub scan_period_ms: Option<Spanned<i64>>,
    #[serde(default)]
    pub continue_on_congestion: bool,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSim {
    pub step_ns: Option<Spanned<i64>>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRt {
    #[serde(default)]
    pub policy: RtPolicy,
    pub scan_priority: Option<Spanned<i64>>,
    pub event_priority: Option<Spanned<i64>>,
    pub watchdog_priority: Option<Spanned<i64>>,
    pub scan_cpus: Option<Vec<Spanned<i64>>>,
    pub event_cpus: Option<Vec<Spanned<i64>>>,
    pub watchdog_cpus: Option<Vec<Spanned<i64>>>,
    pub lock_memory: Option<bool>,
    pub cpu_dma_latency_us: Option<Spanned<i64>>,
    #[serde(default)]
    pub require: bool,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawControl {
    pub enabled: Option<bool>,
    pub socket: Option<Spanned<String>>,
    pub group: Option<Spanned<String>>,
    pub max_clients: Option<Spanned<i64>>,
    pub max_request_bytes: Option<Spanned<i64>>,
    pub idle_timeout_s: Option<Spanned<i64>>,
}

/// `[switch]` with the keys of both backends; `validate` checks which belong.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSwitch {
    pub line: Option<Spanned<i64>>,
    #[serde(default)]
    pub active_low: bool,
    #[serde(default)]
    pub bias: Bias,
    pub debounce_us: Option<Spanned<i64>>,
    pub position: Option<Spanned<SwitchPosition>>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTimers {
    pub ms100: Option<Spanned<String>>,
    pub ms10: Option<Spanned<String>>,
    pub ms1: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawProgram {
    pub name: Option<Spanned<String>>,
    pub file: Spanned<String>,
    pub task: Option<Spanned<String>>,
}

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

/// `[io]` without `input` and `output`, which are read entry by entry; they are declared here
/// only so that an unknown key's message lists them among the expected ones.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawIo {
    #[serde(default)]
    pub backend: Backend,
    pub chip: Option<Spanned<String>>,
    pub stimulus: Option<Spanned<String>>,
    #[serde(default)]
    pub stimulus_loop: bool,
    #[serde(rename = "input")]
    _input: Option<IgnoredAny>,
    #[serde(rename = "output")]
    _output: Option<IgnoredAny>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInput {
    pub device: Spanned<String>,
    pub line: Spanned<i64>,
    #[serde(default)]
    pub active_low: bool,
    #[serde(default)]
    pub bias: Bias,
    pub debounce_us: Option<Spanned<i64>>,
}

/// An output line. `bias` and `debounce_us` are accepted here only to be rejected by
/// `validate` with a clearer message than serde's "unknown field".
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOutput {
    pub device: Spanned<String>,
    pub line: Spanned<i64>,
    #[serde(default)]
    pub active_low: bool,
    pub bias: Option<Spanned<IgnoredAny>>,
    pub debounce_us: Option<Spanned<IgnoredAny>>,
}

const TOP_LEVEL: &str =
    "`plc`, `sim`, `timers`, `program`, `task`, `io`, `rt`, `control`, `switch`, `retain`, `modbus`";

/// Pass 1. `None` if the TOML itself is malformed (the syntax errors are in `sink`).
pub(super) fn read(text: &str, sink: &mut Sink) -> Option<RawDoc> {
    let (root, syntax_errors) = DeTable::parse_recoverable(text);
    if !syntax_errors.is_empty() {
        for error in syntax_errors {
            let span = error.span().unwrap_or(0..0);
            let mut message = error.message().to_string();
            // toml does not say which key is duplicated; the span does.
            if message == "duplicate key" {
                if let Some(key) = text.get(span.clone()) {
                    message = format!("duplicate key `{}`", key.trim());
                }
            }
            sink.error(span.start, message);
        }
        return None;
    }

    let mut doc = RawDoc::default();
    let mut sections = Sections::default();
    for (key, value) in root.into_inner() {
        let slot = match key.get_ref().as_ref() {
            "plc" => &mut sections.plc,
            "sim" => &mut sections.sim,
            "timers" => &mut sections.timers,
            "io" => &mut sections.io,
            "program" => &mut sections.program,
            "task" => &mut sections.task,
            "rt" => &mut sections.rt,
            "control" => &mut sections.control,
            "switch" => &mut sections.switch,
            "retain" => &mut sections.retain,
            "modbus" => &mut sections.modbus,
            other => {
                let message = format!("unknown key `{other}`, expected one of {TOP_LEVEL}");
                sink.error(key.span().start, message);
                continue;
            }
        };
        *slot = Some(value);
    }

    let failed = &mut doc.failed.keys;
    doc.plc = section(sink, sections.plc, "plc", failed);
    doc.sim = section(sink, sections.sim, "sim", failed);
    doc.timers = section(sink, sections.timers, "timers", failed);
    doc.programs = entries(sink, sections.program, "program", |table| {
        // A program without a name goes by its default name, its file's stem.
        peek_str(table, "name").or_else(|| {
            let file = peek_str(table, "file")?;
            let stem = std::path::Path::new(&file).file_stem()?;
            Some(stem.to_string_lossy().into_owned())
        })
    })
    .into_iter()
    .filter_map(|entry| entry.map_err(|_| doc.failed.program = true).ok())
    .collect();
    doc.tasks = entries(sink, sections.task, "task", |table| peek_str(table, "name"))
        .into_iter()
        .filter_map(|entry| entry.map_err(|name| doc.failed.task_names.extend(name)).ok())
        .collect();
    read_io(sink, sections.io, &mut doc);
    doc.rt = section(sink, sections.rt, "rt", &mut doc.failed.keys);
    doc.control = section(sink, sections.control, "control", &mut doc.failed.keys);
    doc.switch = sections.switch.and_then(|value| {
        let span = value.span();
        let value = section(sink, Some(value), "switch", &mut doc.failed.keys)?;
        Some(Located { span, ctx: Ctx::Section("switch"), value })
    });
    doc.retain = section(sink, sections.retain, "retain", &mut doc.failed.keys);
    doc.modbus = super::modbus::read(sink, sections.modbus);
    Some(doc)
}

/// The top-level values, before deserializing.
#[derive(Default)]
struct Sections<'i> {
    plc: Option<Spanned<DeValue<'i>>>,
    sim: Option<Spanned<DeValue<'i>>>,
    timers: Option<Spanned<DeValue<'i>>>,
    io: Option<Spanned<DeValue<'i>>>,
    program: Option<Spanned<DeValue<'i>>>,
    task: Option<Spanned<DeValue<'i>>>,
    rt: Option<Spanned<DeValue<'i>>>,
    control: Option<Spanned<DeValue<'i>>>,
    switch: Option<Spanned<DeValue<'i>>>,
    retain: Option<Spanned<DeValue<'i>>>,
    modbus: Option<Spanned<DeValue<'i>>>,
}

fn read_io(sink: &mut Sink, io: Option<Spanned<DeValue<'_>>>, doc: &mut RawDoc) {
    let Some(io) = io else {
        let (span, ctx) = (0..0, Ctx::Section("io"));
        doc.io = Some(Located { span, ctx, value: RawIo::default() });
        return;
    };
    let span = io.span();
    let DeValue::Table(mut table) = io.into_inner() else {
        sink.error(span.start, "`io` must be a table, written [io]");
        doc.failed.input = true;
        return;
    };
    let input = table.remove("input");
    let output = table.remove("output");
    let io = Spanned::new(span.clone(), DeValue::Table(table));
    doc.io = section(sink, Some(io), "io", &mut doc.failed.keys).map(|value| Located {
        span,
        ctx: Ctx::Section("io"),
        value,
    });
    let device = |table: &DeTable| peek_str(table, "device");
    doc.inputs = entries(sink, input, "io.input", device)
        .into_iter()
        .filter_map(|entry| entry.map_err(|_| doc.failed.input = true).ok())
        .collect();
    doc.outputs =
        entries(sink, output, "io.output", device).into_iter().filter_map(Result::ok).collect();
}

/// A top-level table: its default when absent, `None` when it cannot be deserialized. Its
/// malformed keys are left out (taking their defaults) and noted in `failed` as `name.key`.
pub(super) fn section<T: DeserializeOwned + Default>(
    sink: &mut Sink,
    value: Option<Spanned<DeValue<'_>>>,
    name: &'static str,
    failed: &mut Vec<String>,
) -> Option<T> {
    let Some(value) = value else {
        return Some(T::default());
    };
    let span = value.span();
    match value.into_inner() {
        DeValue::Table(table) => {
            let (value, removed) = deserialize(sink, table, span, &Ctx::Section(name))?;
            failed.extend(removed.into_iter().map(|key| format!("{name}.{key}")));
            Some(value)
        }
        _ => {
            sink.error(span.start, format!("`{name}` must be a table, written [{name}]"));
            None
        }
    }
}

/// An array of tables, entry by entry. A failed entry is `Err` with its peeked name.
///
/// `name_of` peeks at an entry's raw table for what to call it in messages (`task "fast"`);
/// without one the entry is called by its position (`task #2`).
pub(super) fn entries<T: DeserializeOwned>(
    sink: &mut Sink,
    value: Option<Spanned<DeValue<'_>>>,
    name: &str,
    name_of: impl Fn(&DeTable) -> Option<String>,
) -> Vec<Result<Located<T>, Option<String>>> {
    let Some(value) = value else {
        return Vec::new();
    };
    let not_an_array = format!("`{name}` must be an array of tables, written [[{name}]]");
    let span = value.span();
    let DeValue::Array(array) = value.into_inner() else {
        sink.error(span.start, not_an_array);
        return vec![Err(None)];
    };
    let mut out = Vec::new();
    for (index, entry) in array.into_iter().enumerate() {
        let span = entry.span();
        let DeValue::Table(table) = entry.into_inner() else {
            sink.error(span.start, not_an_array.clone());
            out.push(Err(None));
            continue;
        };
        let peeked = name_of(&table);
        let ctx = match &peeked {
            Some(entry_name) => Ctx::Entry(format!("{name} {entry_name:?}")),
            None => Ctx::Entry(format!("{name} #{}", index + 1)),
        };
        out.push(match deserialize(sink, table, span.clone(), &ctx) {
            Some((value, removed)) if removed.is_empty() => Ok(Located { span, ctx, value }),
            _ => Err(peeked),
        });
    }
    out
}

fn peek_str(table: &DeTable, key: &str) -> Option<String> {
    table.get(key).and_then(|v| v.get_ref().as_str()).map(str::to_string)
}

/// Deserializes a table, reporting every bad key rather than only the first.
///
/// serde stops at the first error, so after each error the key it is about is taken out and
/// the table is tried again, until it deserializes (the value and the keys taken out) or an
/// error is about no key in particular, such as a missing key (`None`).
fn deserialize<T: DeserializeOwned>(
    sink: &mut Sink,
    mut table: DeTable<'_>,
    span: Range<usize>,
    ctx: &Ctx,
) -> Option<(T, Vec<String>)> {
    let mut removed: Vec<String> = Vec::new();
    loop {
        let attempt = Spanned::new(span.clone(), DeValue::Table(table.clone()));
        let error = match T::deserialize(ValueDeserializer::from(attempt)) {
            Ok(value) => return Some((value, removed)),
            Err(error) => error,
        };
        let at = error.span().unwrap_or(span.clone());
        let message = tidy(error.message());
        // A required key taken out for being malformed is not missing as well.
        if removed.iter().any(|key| message == format!("missing key `{key}`")) {
            return None;
        }
        // serde's messages name the unexpected type or value, not the key: the span does.
        let key = table
            .iter()
            .find(|(k, v)| v.span().contains(&at.start) || k.span() == at)
            .map(|(k, _)| k.get_ref().to_string());
        let message = match &key {
            // "unknown key `x`" and "missing key `x`" name the key already.
            _ if message.contains("key `") => format!("{}: {message}", ctx.subject()),
            Some(key) => format!("{}: {message}", ctx.key(key)),
            None => format!("{}: {message}", ctx.subject()),
        };
        let unknown = message.contains("unknown key `");
        sink.error(at.start, message);
        let key = key?;
        table.remove(key.as_str());
        // An unknown key carries nothing the rest depends on: the entry is still checked.
        if !unknown {
            removed.push(key);
        }
    }
}

/// serde's wording for users who write TOML, not Rust.
fn tidy(message: &str) -> String {
    let message = message.lines().next().unwrap_or_default();
    [
        ("unknown field `", "unknown key `"),
        ("missing field `", "missing key `"),
        ("expected i64", "expected an integer"),
        ("wanted string or table", "expected a string"),
    ]
    .iter()
    .fold(message.to_string(), |m, (from, to)| m.replace(from, to))
}
