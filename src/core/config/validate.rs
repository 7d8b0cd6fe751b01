//! Pass 2: ranges, the keys that belong to each task kind, and the cross-references between
//! sections, on everything pass 1 deserialized.
//!
//! Each check reports and moves on; a part with errors yields `None`, and a [`Config`] is built
//! only when every part is whole.

use std::collections::HashMap;
use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use toml::Spanned;

use super::raw::{
    Ctx, Failed, Located, RawCondition, RawControl, RawDoc, RawInput, RawIo, RawKind, RawOutput,
    RawPlc, RawProgram, RawRt, RawSim, RawSwitch, RawTask, RawTimers,
};
use super::wiring::{self, Place};
use super::{
    Backend, Config, ControlConfig, DeviceCondition, IoConfig, IoLine, PlcConfig, ProgramConfig,
    RtConfig, SimConfig, Sink, SwitchConfig, TaskConfig, TaskKind, TaskRef, TimerConfig,
};
use crate::device::{Address, Area};
use crate::diag::Diagnostic;

/// Pass 2. `None` if anything is wrong (and then `sink` says what).
pub(super) fn validate(doc: RawDoc, sink: &mut Sink) -> Option<Config> {
    let path = sink.path.to_path_buf();
    let gpio_inputs = gpio_inputs(&doc);
    let plc = doc.plc.and_then(|raw| plc(sink, raw));
    let sim = doc.sim.and_then(|raw| sim(sink, raw));
    let failed = &doc.failed.keys;
    let timers = doc.timers.and_then(|raw| timers(sink, raw, failed));
    let control = doc.control.and_then(|raw| control(sink, raw, &path));
    // [switch] before [io] consumes its entries: the switch's line must be none of theirs.
    let backend = doc
        .io
        .as_ref()
        .map(|io| io.value.backend)
        .filter(|_| !failed.iter().any(|k| k == "io.backend"));
    let wired = wired_lines(&doc.inputs, &doc.outputs);
    let switch_place = doc.switch.as_ref().map(|s| Place {
        at: s.value.line.as_ref().map_or(s.span.start, |line| line.span().start),
        subject: s.ctx.subject(),
    });
    let switch = switch(sink, doc.switch, backend, &wired, failed);
    let io = io(sink, doc.io, doc.inputs, doc.outputs, failed, &path);
    let rt = doc.rt.and_then(|raw| rt(sink, raw, failed));
    let retain = doc.retain.and_then(|raw| super::retain::validate(sink, raw, &path));
    // Programs may name a task whose entry has errors: that entry's own diagnostics say what
    // is wrong, so it still counts as defined.
    let task_names: Vec<String> = doc
        .tasks
        .iter()
        .map(|t| t.value.name.get_ref().clone())
        .chain(doc.failed.task_names.iter().cloned())
        .collect();
    let tasks = tasks(sink, doc.tasks, gpio_inputs.as_deref());
    let programs = programs(sink, doc.programs, &task_names, &doc.failed, &path);
    let modbus = super::modbus::validate(sink, doc.modbus);
    if let Some((io, inputs, outputs)) =
        io.as_ref().filter(|(io, ..)| io.backend == Backend::Gpiocdev)
    {
        let switch = switch.as_ref().and_then(Option::as_ref).zip(switch_place);
        let tasks = tasks.as_deref().unwrap_or_default();
        wiring::check(sink, io, (inputs, outputs), switch, tasks);
    }
    let io = io.map(|(io, ..)| io);
    Some(Config {
        path,
        plc: plc?,
        sim: sim?,
        timers: timers?,
        programs: programs?,
        tasks: tasks?,
        io: io?,
        rt: rt?,
        control: control?,
        switch: switch?,
        retain: retain?,
        modbus: modbus?,
    })
}

fn plc(sink: &mut Sink, raw: RawPlc) -> Option<PlcConfig> {
    let ctx = Ctx::Section("plc");
    let default = PlcConfig::default();
    let watchdog_ms = int_or(
        sink,
        &ctx,
        "watchdog_ms",
        raw.watchdog_ms,
        widen(PlcConfig::WATCHDOG_MS),
        default.watchdog_ms,
    );
    let scan_period_ms = int_or(
        sink,
        &ctx,
        "scan_period_ms",
        raw.scan_period_ms,
        widen(PlcConfig::SCAN_PERIOD_MS),
        default.scan_period_ms,
    );
    Some(PlcConfig {
        watchdog_ms: watchdog_ms?,
        on_fault: raw.on_fault,
        scan_period_ms: scan_period_ms?,
        continue_on_congestion: raw.continue_on_congestion,
    })
}

fn sim(sink: &mut Sink, raw: RawSim) -> Option<SimConfig> {
    let ctx = Ctx::Section("sim");
    let step_ns =
        int_or(sink, &ctx, "step_ns", raw.step_ns, 1..=i64::MAX, SimConfig::default().step_ns);
    Some(SimConfig { step_ns: step_ns? })
}

/// One `[timers]` key after parsing: what it says and where, if it was written.
struct TimerKey {
    name: &'static str,
    /// The byte offset of the value, if the key was given.
    at: Option<usize>,
    /// As written, or the default's text.
    text: String,
    /// `None` if the value did not parse (already reported).
    range: Option<Option<RangeInclusive<u32>>>,
}

/// `failed`: malformed keys, already reported; their ranges are unknown, not the defaults.
fn timers(sink: &mut Sink, raw: RawTimers, failed: &[String]) -> Option<TimerConfig> {
    let ctx = Ctx::Section("timers");
    let default = TimerConfig::default();
    let keys = [
        ("ms100", raw.ms100, default.ms100),
        ("ms10", raw.ms10, default.ms10),
        ("ms1", raw.ms1, default.ms1),
    ];
    let keys: [TimerKey; 3] = keys.map(|(name, given, default)| match given {
        Some(given) => {
            let at = given.span().start;
            let text = given.into_inner();
            let range = timer_range(&text)
                .map_err(|e| sink.error(at, format!("{}: {e}", ctx.key(name))))
                .ok();
            TimerKey { name, at: Some(at), text, range }
        }
        None => {
            let text = default.as_ref().map_or_else(String::new, range_text);
            let malformed = failed.iter().any(|k| *k == ctx.key(name));
            TimerKey { name, at: None, text, range: (!malformed).then_some(default) }
        }
    });

    for (i, a) in keys.iter().enumerate() {
        for b in &keys[i + 1..] {
            let (Some(Some(ra)), Some(Some(rb))) = (&a.range, &b.range) else {
                continue;
            };
            if ra.start() > rb.end() || rb.start() > ra.end() {
                continue;
            }
            // Report at the later of the keys that were written (defaults never overlap).
            let (here, there) = if a.at > b.at { (a, b) } else { (b, a) };
            let Some(at) = here.at else { continue };
            let there_text = match there.at {
                Some(_) => format!("{:?}", there.text),
                None => format!("{:?} (its default)", there.text),
            };
            let message = format!(
                "{} {:?} overlaps {} {there_text}",
                ctx.key(here.name),
                here.text,
                ctx.key(there.name),
            );
            sink.error(at, message);
        }
    }

    let [ms100, ms10, ms1] = keys.map(|k| k.range);
    Some(TimerConfig { ms100: ms100?, ms10: ms10?, ms1: ms1? })
}

/// `"Txxxx-Tyyyy"` as an inclusive range of timer numbers, `""` as none.
fn timer_range(text: &str) -> Result<Option<RangeInclusive<u32>>, String> {
    if text.trim().is_empty() {
        return Ok(None);
    }
    let Some((first, last)) = text.split_once('-') else {
        return Err(format!("{text:?} is not a range \"Txxxx-Tyyyy\" (or \"\" for none)"));
    };
    let timer = |part: &str| {
        let part = part.trim();
        match Address::parse(part) {
            Ok(address) if address.area == Area::T => Ok(address.number),
            Ok(_) => {
                Err(format!("`{part}` is not a timer (T0000-T{:04})", TimerConfig::LAST_TIMER))
            }
            Err(e) => Err(e.to_string()),
        }
    };
    let (first, last) = (timer(first)?, timer(last)?);
    if first > last {
        return Err(format!("{text:?} is backwards: T{first:04} comes after T{last:04}"));
    }
    Ok(Some(first..=last))
}

fn range_text(range: &RangeInclusive<u32>) -> String {
    format!("T{:04}-T{:04}", range.start(), range.end())
}

/// One `[rt]` priority after its range check.
struct RtPriority {
    name: &'static str,
    /// The byte offset of the value, if the key was given.
    at: Option<usize>,
    /// `None` if out of range or malformed (already reported).
    value: Option<u8>,
}

/// `failed`: malformed keys, already reported; their values are unknown, not the defaults.
fn rt(sink: &mut Sink, raw: RawRt, failed: &[String]) -> Option<RtConfig> {
    let ctx = Ctx::Section("rt");
    let default = RtConfig::default();
    let mut ok = true;
    let priorities = [
        ("scan_priority", raw.scan_priority, default.scan_priority),
        ("event_priority", raw.event_priority, default.event_priority),
        ("watchdog_priority", raw.watchdog_priority, default.watchdog_priority),
    ];
    let priorities = priorities.map(|(name, given, default)| match given {
        Some(given) => {
            let value = int(sink, &ctx, name, &given, widen(RtConfig::PRIORITY));
            RtPriority { name, at: Some(given.span().start), value }
        }
        None => {
            let malformed = failed.iter().any(|k| *k == ctx.key(name));
            RtPriority { name, at: None, value: (!malformed).then_some(default) }
        }
    });

    // scan < event < watchdog, between neighbours whose values are known (with the event
    // priority unknown, scan < watchdog still holds).
    let known: Vec<(&RtPriority, u8)> =
        priorities.iter().filter_map(|p| p.value.map(|v| (p, v))).collect();
    for pair in known.windows(2) {
        let [(low, low_value), (high, high_value)] = [pair[0], pair[1]];
        if high_value > low_value {
            continue;
        }
        ok = false;
        let given = |p: &RtPriority, value: u8| match p.at {
            Some(_) => format!("{} {value}", ctx.key(p.name)),
            None => format!("{} {value} (its default)", ctx.key(p.name)),
        };
        // Report at the later of the keys that were written (the defaults are in order).
        let (at, message) = if high.at > low.at {
            let message = format!("must be above {}", given(low, low_value));
            (high.at, format!("{} {message}", given(high, high_value)))
        } else {
            let message = format!("must be below {}", given(high, high_value));
            (low.at, format!("{} {message}", given(low, low_value)))
        };
        if let Some(at) = at {
            sink.error(at, message);
        }
    }

    let scan_cpus = cpus(sink, &ctx, "scan_cpus", raw.scan_cpus);
    let event_cpus = cpus(sink, &ctx, "event_cpus", raw.event_cpus);
    let watchdog_cpus = cpus(sink, &ctx, "watchdog_cpus", raw.watchdog_cpus);
    let cpu_dma_latency_us = match &raw.cpu_dma_latency_us {
        None => Some(default.cpu_dma_latency_us),
        Some(value) => {
            int::<i64>(sink, &ctx, "cpu_dma_latency_us", value, RtConfig::CPU_DMA_LATENCY)
                .map(|us| u32::try_from(us).ok())
        }
    };
    let [scan, event, watchdog] = priorities.map(|p| p.value);
    let rt = RtConfig {
        policy: raw.policy,
        scan_priority: scan?,
        event_priority: event?,
        watchdog_priority: watchdog?,
        scan_cpus: scan_cpus?,
        event_cpus: event_cpus?,
        watchdog_cpus: watchdog_cpus?,
        lock_memory: raw.lock_memory.unwrap_or(default.lock_memory),
        cpu_dma_latency_us: cpu_dma_latency_us?,
        require: raw.require,
    };
    ok.then_some(rt)
}

/// A CPU list of `[rt]`: each CPU in range and listed once, in the order written.
fn cpus(sink: &mut Sink, ctx: &Ctx, key: &str, raw: Option<Vec<Spanned<i64>>>) -> Option<Vec<u16>> {
    let mut ok = true;
    let mut cpus: Vec<u16> = Vec::new();
    for cpu in raw.unwrap_or_default() {
        let (value, at) = (*cpu.get_ref(), cpu.span().start);
        let Some(number) = u16::try_from(value).ok().filter(|n| RtConfig::CPU.contains(n)) else {
            let (first, last) = (RtConfig::CPU.start(), RtConfig::CPU.end());
            sink.error(at, format!("{}: CPU {value} out of range {first}..={last}", ctx.key(key)));
            ok = false;
            continue;
        };
        if cpus.contains(&number) {
            sink.error(at, format!("{}: CPU {number} is listed twice", ctx.key(key)));
            ok = false;
            continue;
        }
        cpus.push(number);
    }
    ok.then_some(cpus)
}

/// `[control]`.
fn control(sink: &mut Sink, raw: RawControl, config: &Path) -> Option<ControlConfig> {
    let ctx = Ctx::Section("control");
    let default = ControlConfig::default();
    let max_clients = int_or(
        sink,
        &ctx,
        "max_clients",
        raw.max_clients,
        widen(ControlConfig::MAX_CLIENTS),
        default.max_clients,
    );
    let max_request_bytes = int_or(
        sink,
        &ctx,
        "max_request_bytes",
        raw.max_request_bytes,
        widen(ControlConfig::MAX_REQUEST_BYTES),
        default.max_request_bytes,
    );
    let idle_timeout_s = int_or(
        sink,
        &ctx,
        "idle_timeout_s",
        raw.idle_timeout_s,
        0..=i64::from(u32::MAX),
        default.idle_timeout_s,
    );
    let socket = match raw.socket {
        None => Some(None),
        Some(socket) if socket.get_ref().trim().is_empty() => {
            sink.error(socket.span().start, format!("{} must not be empty", ctx.key("socket")));
            None
        }
        Some(socket) => {
            let resolved = resolve(config, socket.get_ref());
            let bytes = resolved.as_os_str().len();
            if bytes > ControlConfig::MAX_SOCKET_PATH {
                let message = format!(
                    "{} {:?} is {bytes} bytes long as resolved ({}); a Unix socket path holds \
                     at most {}",
                    ctx.key("socket"),
                    socket.get_ref(),
                    resolved.display(),
                    ControlConfig::MAX_SOCKET_PATH,
                );
                sink.error(socket.span().start, message);
                None
            } else {
                Some(Some(resolved))
            }
        }
    };
    let group = match raw.group {
        None => Some(None),
        Some(group) if group.get_ref().trim().is_empty() => {
            sink.error(group.span().start, format!("{} must not be empty", ctx.key("group")));
            None
        }
        Some(group) => Some(Some(group.into_inner())),
    };
    Some(ControlConfig {
        enabled: raw.enabled.unwrap_or(default.enabled),
        socket: socket?,
        group: group?,
        max_clients: max_clients?,
        max_request_bytes: max_request_bytes?,
        idle_timeout_s: idle_timeout_s?,
    })
}

/// A line of `[[io.input]]` or `[[io.output]]` as written: its offset, where the offset is,
/// and what the entry is called.
struct WiredLine {
    line: i64,
    at: usize,
    subject: String,
}

/// The lines of the `[[io.input]]` and `[[io.output]]` entries that deserialized.
fn wired_lines(inputs: &[Located<RawInput>], outputs: &[Located<RawOutput>]) -> Vec<WiredLine> {
    let inputs = inputs.iter().map(|e| (&e.ctx, &e.value.line));
    let outputs = outputs.iter().map(|e| (&e.ctx, &e.value.line));
    inputs
        .chain(outputs)
        .map(|(ctx, line)| WiredLine {
            line: *line.get_ref(),
            at: line.span().start,
            subject: ctx.subject(),
        })
        .collect()
}

/// `[switch]`: `Some(None)` when there is none, `None` on errors. `backend` is `None` when
/// it is unknown (malformed, already reported): the keys that depend on it are not checked.
fn switch(
    sink: &mut Sink,
    raw: Option<Located<RawSwitch>>,
    backend: Option<Backend>,
    wired: &[WiredLine],
    failed: &[String],
) -> Option<Option<SwitchConfig>> {
    let Some(Located { span, ctx, value: raw }) = raw else {
        return Some(None);
    };
    let default = SwitchConfig::default();
    let mut ok = true;
    let debounce_us = int_or(
        sink,
        &ctx,
        "debounce_us",
        raw.debounce_us,
        widen(SwitchConfig::DEBOUNCE_US),
        default.debounce_us,
    );
    let line = match &raw.line {
        Some(line) if backend == Some(Backend::Sim) => {
            let message = format!(
                "{} is for the gpiocdev backend: the sim backend simulates the switch \
                 (`position`, and `SWITCH` lines of a stimulus)",
                ctx.key("line")
            );
            sink.error(line.span().start, message);
            ok = false;
            None
        }
        Some(line) => match int::<u32>(sink, &ctx, "line", line, 0..=i64::from(u32::MAX)) {
            Some(offset) => {
                ok &= switch_line_is_free(sink, &ctx, offset, line.span().start, wired);
                Some(offset)
            }
            None => {
                ok = false;
                None
            }
        },
        // A malformed line is reported already, not missing.
        None if backend == Some(Backend::Gpiocdev)
            && !failed.iter().any(|k| *k == ctx.key("line")) =>
        {
            let message = format!(
                "{} is required for the gpiocdev backend: the input line that is active at RUN",
                ctx.key("line")
            );
            sink.error(span.start, message);
            ok = false;
            None
        }
        None => None,
    };
    let position = match raw.position {
        Some(position) if backend == Some(Backend::Gpiocdev) => {
            let message = format!(
                "{} is for the sim backend: the gpiocdev backend reads the switch from its line",
                ctx.key("position")
            );
            sink.error(position.span().start, message);
            ok = false;
            default.position
        }
        Some(position) => position.into_inner(),
        None => default.position,
    };
    let switch = SwitchConfig {
        line,
        active_low: raw.active_low,
        bias: raw.bias,
        debounce_us: debounce_us?,
        position,
    };
    ok.then_some(Some(switch))
}

/// The switch's line is no `[[io.input]]` or `[[io.output]]` line. As among those entries,
/// the later one in the file is reported, naming the other.
fn switch_line_is_free(
    sink: &mut Sink,
    ctx: &Ctx,
    offset: u32,
    at: usize,
    wired: &[WiredLine],
) -> bool {
    let mut free = true;
    for w in wired.iter().filter(|w| w.line == i64::from(offset)) {
        let (at, message) = if w.at > at {
            (w.at, format!("{}: line {offset} is already used by {}", w.subject, ctx.subject()))
        } else {
            (at, format!("{} {offset} is already used by {}", ctx.key("line"), w.subject))
        };
        sink.error(at, message);
        free = false;
    }
    free
}

/// `file` relative to the config file's directory (unchanged if absolute).
pub(super) fn resolve(config: &Path, file: &str) -> PathBuf {
    match config.parent() {
        Some(dir) => dir.join(file),
        None => PathBuf::from(file),
    }
}

fn programs(
    sink: &mut Sink,
    raw: Vec<Located<RawProgram>>,
    task_names: &[String],
    failed: &Failed,
    config: &Path,
) -> Option<Vec<ProgramConfig>> {
    let mut ok = true;
    // A failed entry or an undefined task may have been meant as the scan program: then
    // "no scan program" would be a consequence, not news.
    let mut maybe_scan = failed.program;
    let mut names: HashMap<String, u32> = HashMap::new();
    let mut programs = Vec::new();
    for program in raw {
        let Located { ctx, value: raw, .. } = program;
        let file_span = raw.file.span();
        let file_at = file_span.start;
        let file = raw.file.into_inner();
        if file.trim().is_empty() {
            sink.error(file_at, format!("{} must not be empty", ctx.key("file")));
            ok = false;
            continue;
        }
        let name = match raw.name {
            Some(name) => name,
            None => {
                let stem = Path::new(&file).file_stem().unwrap_or_default();
                Spanned::new(file_span, stem.to_string_lossy().into_owned())
            }
        };
        if name.get_ref().trim().is_empty() {
            sink.error(name.span().start, format!("{} must not be empty", ctx.key("name")));
            ok = false;
            continue;
        }
        let (line, col) = Diagnostic::line_col(sink.text, file_at);
        if let Some(first) = names.get(name.get_ref()) {
            let message = format!(
                "{}: name {:?} is already used by the program at line {first}",
                ctx.subject(),
                name.get_ref()
            );
            sink.error(name.span().start, message);
            ok = false;
        } else {
            names.insert(name.get_ref().clone(), line);
        }

        let task = match raw.task {
            None => TaskRef::Scan,
            Some(task) => match task.get_ref().as_str() {
                "init" => TaskRef::Init,
                "scan" => TaskRef::Scan,
                named if task_names.iter().any(|t| t == named) => TaskRef::Named(named.to_string()),
                named => {
                    let message = format!(
                        "{} {named:?} is not defined: expected \"init\", \"scan\" or the name of a [[task]]",
                        ctx.key("task"),
                    );
                    sink.error(task.span().start, message);
                    ok = false;
                    maybe_scan = true;
                    continue;
                }
            },
        };
        let resolved = resolve(config, &file);
        programs.push(ProgramConfig {
            name: name.into_inner(),
            file: PathBuf::from(file),
            resolved,
            task,
            line,
            col,
        });
    }
    if !maybe_scan && !programs.iter().any(|p| p.task == TaskRef::Scan) {
        sink.error_file(
            "no [[program]] runs in the scan task: a PLC needs a scan program \
             (a [[program]] with task = \"scan\", the default)",
        );
        ok = false;
    }
    ok.then_some(programs)
}

/// The devices of `[[io.input]]` when the gpiocdev backend must wire io-task contacts, or
/// `None` when that cannot or need not be checked (sim backend, or inputs with errors).
fn gpio_inputs(doc: &RawDoc) -> Option<Vec<Address>> {
    let io = doc.io.as_ref()?;
    let backend_unknown = doc.failed.keys.iter().any(|k| k == "io.backend");
    if io.value.backend != Backend::Gpiocdev || doc.failed.input || backend_unknown {
        return None;
    }
    doc.inputs.iter().map(|input| Address::parse(input.value.device.get_ref()).ok()).collect()
}

fn tasks(
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

fn io(
    sink: &mut Sink,
    raw: Option<Located<RawIo>>,
    inputs: Vec<Located<RawInput>>,
    outputs: Vec<Located<RawOutput>>,
    failed: &[String],
    config: &Path,
) -> Option<(IoConfig, Vec<Place>, Vec<Place>)> {
    let mut ok = raw.is_some();
    let mut config_io = IoConfig::default();
    if let Some(Located { span, ctx, value: raw }) = raw {
        config_io.backend = raw.backend;
        config_io.stimulus_loop = raw.stimulus_loop;
        match raw.chip {
            Some(chip) if chip.get_ref().trim().is_empty() => {
                sink.error(chip.span().start, format!("{} must not be empty", ctx.key("chip")));
                ok = false;
            }
            Some(chip) => config_io.chip = Some(chip.into_inner()),
            // A malformed chip is reported already, not missing.
            None if raw.backend == Backend::Gpiocdev && !failed.iter().any(|k| k == "io.chip") => {
                let message = format!("{} is required for the gpiocdev backend", ctx.key("chip"));
                sink.error(span.start, message);
                ok = false;
            }
            None => {}
        }
        match raw.stimulus {
            // Inputs come from the chip's lines: a stimulus would be silently unused.
            Some(file) if raw.backend == Backend::Gpiocdev => {
                let message = format!(
                    "{} is for the sim backend: the gpiocdev backend reads its inputs from the \
                     chip's lines",
                    ctx.key("stimulus")
                );
                sink.error(file.span().start, message);
                ok = false;
            }
            Some(file) if file.get_ref().trim().is_empty() => {
                sink.error(file.span().start, format!("{} must not be empty", ctx.key("stimulus")));
                ok = false;
            }
            Some(file) => config_io.stimulus = Some(resolve(config, file.get_ref())),
            None => {}
        }
    }

    // Inputs and outputs share the P image and the chip, so devices and lines are unique
    // across both; the later one in the file is the one reported.
    let mut wired: Vec<Wired> = Vec::new();
    for input in inputs {
        let Located { span, ctx, value: raw } = input;
        let debounce_us = match &raw.debounce_us {
            Some(value) => int(sink, &ctx, "debounce_us", value, 0..=i64::from(u32::MAX)),
            None => Some(0),
        };
        let line = io_line(sink, &ctx, &raw.device, &raw.line, raw.active_low);
        match (line, debounce_us) {
            (Some(line), Some(debounce_us)) => wired.push(Wired {
                at: span.start,
                line: IoLine { bias: raw.bias, debounce_us, ..line },
                input: true,
                device_at: raw.device.span().start,
                line_at: raw.line.span().start,
                ctx,
            }),
            _ => ok = false,
        }
    }
    for output in outputs {
        let Located { span, ctx, value: raw } = output;
        for (key, value) in [("bias", &raw.bias), ("debounce_us", &raw.debounce_us)] {
            if let Some(value) = value {
                let message = format!("{}: {key} is only for inputs", ctx.subject());
                sink.error(value.span().start, message);
                ok = false;
            }
        }
        match io_line(sink, &ctx, &raw.device, &raw.line, raw.active_low) {
            Some(line) => wired.push(Wired {
                at: span.start,
                line,
                input: false,
                device_at: raw.device.span().start,
                line_at: raw.line.span().start,
                ctx,
            }),
            None => ok = false,
        }
    }

    wired.sort_by_key(|w| w.at);
    let mut devices: HashMap<Address, &Wired> = HashMap::new();
    let mut offsets: HashMap<u32, &Wired> = HashMap::new();
    for w in &wired {
        if let Some(first) = devices.insert(w.line.device, w) {
            let message = format!(
                "{}: device {} is already used by {}",
                w.ctx.subject(),
                w.line.device,
                first.ctx.subject()
            );
            sink.error(w.device_at, message);
            devices.insert(w.line.device, first);
            ok = false;
        }
        if let Some(first) = offsets.insert(w.line.line, w) {
            let message = format!(
                "{}: line {} is already used by {}",
                w.ctx.subject(),
                w.line.line,
                first.ctx.subject()
            );
            sink.error(w.line_at, message);
            offsets.insert(w.line.line, first);
            ok = false;
        }
    }
    let (mut inputs, mut outputs) = (Vec::new(), Vec::new());
    for w in wired {
        let place = Place { at: w.at, subject: w.ctx.subject() };
        if w.input {
            config_io.inputs.push(w.line);
            inputs.push(place);
        } else {
            config_io.outputs.push(w.line);
            outputs.push(place);
        }
    }
    ok.then_some((config_io, inputs, outputs))
}

/// A valid `[[io.input]]` or `[[io.output]]`, with what the uniqueness checks report.
struct Wired {
    /// Where its header is, for file order.
    at: usize,
    line: IoLine,
    input: bool,
    device_at: usize,
    line_at: usize,
    ctx: Ctx,
}

/// The keys inputs and outputs share: a P bit and a line offset.
fn io_line(
    sink: &mut Sink,
    ctx: &Ctx,
    device: &Spanned<String>,
    line: &Spanned<i64>,
    active_low: bool,
) -> Option<IoLine> {
    let address = match Address::parse(device.get_ref()) {
        Ok(address) if address.area == Area::P && address.bit.is_some() => Some(address),
        Ok(_) => {
            let message = format!(
                "{} {:?} is not a P bit (P0000..=P127F)",
                ctx.key("device"),
                device.get_ref()
            );
            sink.error(device.span().start, message);
            None
        }
        Err(e) => {
            sink.error(device.span().start, format!("{}: {e}", ctx.key("device")));
            None
        }
    };
    let offset = int(sink, ctx, "line", line, 0..=i64::from(u32::MAX));
    Some(IoLine {
        device: address?,
        line: offset?,
        active_low,
        bias: Default::default(),
        debounce_us: 0,
    })
}

/// `value` if it is within `range` (and so fits `T`); otherwise reports it, naming the key.
pub(super) fn int<T: TryFrom<i64>>(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    value: &Spanned<i64>,
    range: RangeInclusive<i64>,
) -> Option<T> {
    let v = *value.get_ref();
    if range.contains(&v) {
        if let Ok(v) = T::try_from(v) {
            return Some(v);
        }
    }
    let message = if *range.end() == i64::MAX {
        format!("{} {v} must be at least {}", ctx.key(key), range.start())
    } else {
        format!("{} {v} out of range {}..={}", ctx.key(key), range.start(), range.end())
    };
    sink.error(value.span().start, message);
    None
}

/// [`int`] for an optional key with a default.
pub(super) fn int_or<T: TryFrom<i64>>(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    value: Option<Spanned<i64>>,
    range: RangeInclusive<i64>,
    default: T,
) -> Option<T> {
    match value {
        Some(value) => int(sink, ctx, key, &value, range),
        None => Some(default),
    }
}

pub(super) fn widen<T: Copy + Into<i64>>(range: RangeInclusive<T>) -> RangeInclusive<i64> {
    (*range.start()).into()..=(*range.end()).into()
}

fn start<T>(value: &Option<Spanned<T>>) -> Option<usize> {
    value.as_ref().map(|v| v.span().start)
}
