//! The project configuration (docs/CONFIG.md): a TOML file parsed into typed, range-checked
//! structs.
//!
//! This module owns the config file's keys, their defaults and their ranges, and every
//! diagnostic about them. It does not read programs: [`ProgramConfig::resolved`] says where a
//! program is, and loading it is the project loader's job.
//!
//! The config is split by section, one file each (`plc`, `sim`, `timers`, `program`, `task`,
//! `io`, `rt`, `control`, `switch`, `retain`, `modbus`, `opcua`, `mqtt`, `remote`, `st`, `iec`, `users`): its typed struct with the
//! key's defaults and ranges, its raw form as serde reads it, and its checks. How the wiring
//! maps onto GPIO line requests, the kernel's limits included, is [`wiring`]. What every
//! section shares is `common`, and `serial` the keys of a serial line that `[modbus.rtu]` and
//! `[[remote]]` share; this file drives the two passes over all of them.
//!
//! [`parse`] is pure: text in, [`Config`] or [`Diagnostics`] out (`plcd::files` reads the file).
//! Parsing runs in two passes so that one mistake does not hide the next:
//!
//! 1. `read`: the TOML text becomes a syntax tree with byte spans, and each section and each
//!    `[[…]]` entry is deserialized on its own. serde stops at the first error (unknown key,
//!    wrong type, bad enum value), so a table is tried again without the bad key until it
//!    deserializes: every bad key is reported. A section then goes on with that key's
//!    default; an entry with a bad key is left out of pass 2;
//! 2. `validate`: ranges, kind-specific keys and cross-references (task numbers and names,
//!    program tasks, I/O lines, the order of the `[rt]` priorities, the gpiocdev line requests)
//!    are checked on everything that deserialized.
//!
//! Every error of both passes is reported, in file order. A document with TOML syntax errors
//! stops after pass 1: what the parser recovered may not be what was meant, and checking it
//! would mostly report consequences of the syntax error.

mod change;
mod common;
mod control;
mod iec;
mod io;
mod modbus;
mod mqtt;
mod opcua;
mod plc;
mod program;
mod remote;
mod retain;
mod rt;
mod serial;
mod sim;
mod st;
mod switch;
mod system_libraries;
mod task;
mod timers;
mod users;
pub mod wiring;

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::diag::{Diagnostic, Diagnostics};
use common::{entries, peek_str, section, Ctx, Located};
use control::RawControl;
use io::{RawInput, RawIo, RawOutput};
use plc::RawPlc;
use program::RawProgram;
use rt::RawRt;
use sim::RawSim;
use switch::RawSwitch;
use task::RawTask;
use timers::RawTimers;
use wiring::Place;

/// The literal tests (`tests.rs`) take every name of this module, addresses included.
#[cfg(test)]
use crate::device::Address;

pub use change::ProjectChange;
pub use control::ControlConfig;
pub use iec::{IecAddress, IecConfig, IecVariable};
pub use io::{Backend, Bias, IoConfig, IoLine, LineRef, LINE_NAME_MAX};
pub use modbus::{ModbusConfig, ModbusRange, ModbusRtuConfig, ModbusTable};
pub use mqtt::{BrokerUrl, MqttConfig, MqttDeadband, MqttDevice};
pub use opcua::{
    Anonymous, EuRange, OpcuaAnalog, OpcuaConfig, OpcuaDevices, OpcuaPolicy, WritableName,
};
pub use plc::{OnFault, PlcConfig};
pub use program::{Language, ProgramConfig, TaskRef};
pub use remote::{
    OnLoss, RemoteDevice, RemoteRead, RemoteStatusBit, RemoteTable, RemoteTransport, RemoteWrite,
    WriteOn,
};
pub use retain::{Restart, RetainArea, RetainConfig, RetainRange};
pub use rt::{RtConfig, RtPolicy};
pub use serial::{Parity, SerialLine};
pub use sim::SimConfig;
pub use st::{
    is_namespace, is_plcproj, is_st_source, is_twincat_source, LibraryFile, StConfig,
    DEFAULT_HEAP_BYTES, DEFAULT_VARIABLE_MEMORY_BYTES, VARIABLE_MEMORY_BYTES_RANGE,
};
pub use switch::SwitchConfig;
pub use system_libraries::{SystemLibraries, SystemLibrary};
pub use task::{DeviceCondition, Edge, TaskConfig, TaskKind, TASK_NUMBERS};
pub use timers::TimerConfig;
pub use users::UsersConfig;

/// A whole, valid configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Config {
    /// The config file, as given to [`parse`].
    pub path: PathBuf,
    /// `[plc]`.
    pub plc: PlcConfig,
    /// `[sim]`.
    pub sim: SimConfig,
    /// `[timers]`.
    pub timers: TimerConfig,
    /// `[[program]]`, in file order (several programs of one task run in this order). At least
    /// one of them runs in the scan task.
    pub programs: Vec<ProgramConfig>,
    /// `[[task]]`, in file order. Names and numbers are unique.
    pub tasks: Vec<TaskConfig>,
    /// `[io]`, `[[io.input]]` and `[[io.output]]`.
    pub io: IoConfig,
    /// `[rt]`.
    pub rt: RtConfig,
    /// `[control]`: the control socket.
    pub control: ControlConfig,
    /// `[switch]`: the RUN/STOP key switch; `None` when not configured (remote mode changes
    /// are then always accepted).
    pub switch: Option<SwitchConfig>,
    /// `[retain]`: retained memory (docs/RETAIN.md).
    pub retain: RetainConfig,
    /// `[modbus]`: the Modbus TCP server (off unless `listen` is given), the RTU server
    /// (`[modbus.rtu]`, off unless given) and the map both serve.
    pub modbus: ModbusConfig,
    /// `[opcua]`: the OPC UA server (off unless `listen` is given).
    pub opcua: OpcuaConfig,
    /// `[mqtt]`: the MQTT Sparkplug B edge node (off unless `brokers` is given).
    pub mqtt: MqttConfig,
    /// `[st]`: the Structured Text declaration files.
    pub st: StConfig,
    /// `[iec]`: what the direct addresses of Structured Text (`%IX0.0`) name.
    pub iec: IecConfig,
    /// `[[remote]]`: Modbus devices polled as remote I/O, in file order. Names are unique.
    pub remotes: Vec<RemoteDevice>,
    /// `[users]`: the users file of the network services (docs/USERS.md).
    pub users: UsersConfig,
}

impl Config {
    /// The contacts (0..=7 for P0000..=P0007) that io tasks start on, with the edge each task
    /// wants, in task order: the edges an I/O backend must report.
    pub fn edge_contacts(&self) -> Vec<(u8, Edge)> {
        wiring::edge_contacts(&self.tasks)
    }
}

/// Parses and validates a config. Pure: `path` only names the file in diagnostics and is the
/// base of relative program and stimulus paths. On error, every diagnostic, in file order.
pub fn parse(text: &str, path: &Path) -> Result<Config, Diagnostics> {
    let mut sink = Sink::new(text, path);
    let config = read(text, &mut sink).and_then(|doc| validate(doc, &mut sink));
    match config {
        Some(config) if sink.diags.is_empty() => Ok(config),
        _ => Err(sink.finish()),
    }
}

/// Collects the diagnostics of one parse, locating byte offsets in the text.
struct Sink<'a> {
    text: &'a str,
    path: &'a Path,
    diags: Vec<Diagnostic>,
}

impl<'a> Sink<'a> {
    fn new(text: &'a str, path: &'a Path) -> Self {
        Sink { text, path, diags: Vec::new() }
    }

    /// An error at byte `offset` of the text.
    fn error(&mut self, offset: usize, message: impl Into<String>) {
        let (line, col) = Diagnostic::line_col(self.text, offset);
        self.diags.push(Diagnostic::new(self.path, line, col, message));
    }

    /// An error about the file as a whole (line 0).
    fn error_file(&mut self, message: impl Into<String>) {
        self.diags.push(Diagnostic::new(self.path, 0, 0, message));
    }

    /// The diagnostics in file order. The passes find them section by section (and the TOML
    /// tree iterates its keys sorted), so order is restored here; the sort is stable, so
    /// several errors at one place keep the order they were found in.
    fn finish(mut self) -> Diagnostics {
        self.diags.sort_by_key(|d| (d.line, d.col));
        self.diags.dedup();
        Diagnostics(self.diags)
    }
}

/// The document after pass 1.
///
/// A section that could not be deserialized at all is `None`; one with malformed keys is
/// deserialized without them (so they take their defaults) and the keys are noted in
/// [`Failed::keys`]. An entry of an array of tables with any error is missing from its list
/// and noted in [`Failed`]. Either way pass 2 can avoid reporting what pass 1 already
/// explained (a program's task "undefined" because the task's entry had a typo).
#[derive(Debug, Default)]
struct RawDoc {
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
    pub retain: Option<retain::RawRetain>,
    /// `[modbus]` and its tables; `None` when the document has none.
    pub modbus: Option<modbus::RawModbusDoc>,
    pub opcua: Option<opcua::RawOpcua>,
    pub mqtt: Option<mqtt::RawMqtt>,
    /// `[[remote]]` and the tables of each.
    pub remotes: remote::RawRemotes,
    pub st: Option<st::RawSt>,
    pub iec: Option<iec::RawIec>,
    pub users: Option<users::RawUsers>,
    pub failed: Failed,
}

/// Entries that did not deserialize.
#[derive(Debug, Default)]
struct Failed {
    /// The malformed keys of sections, dotted (`io.chip`).
    pub keys: Vec<String>,
    /// The `name` of each failed `[[task]]`, where it was a string.
    pub task_names: Vec<String>,
    /// Some `[[program]]` failed (it may have been the scan program).
    pub program: bool,
    /// Some `[[io.input]]` failed (it may have been an io task's contact).
    pub input: bool,
}

const TOP_LEVEL: &str = "`plc`, `sim`, `timers`, `program`, `task`, `io`, `rt`, `control`, \
                         `switch`, `retain`, `modbus`, `opcua`, `mqtt`, `st`, `iec`, `remote`, \
                         `users`";

/// Pass 1. `None` if the TOML itself is malformed (the syntax errors are in `sink`).
fn read(text: &str, sink: &mut Sink) -> Option<RawDoc> {
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
            "opcua" => &mut sections.opcua,
            "mqtt" => &mut sections.mqtt,
            "st" => &mut sections.st,
            "iec" => &mut sections.iec,
            "remote" => &mut sections.remote,
            "users" => &mut sections.users,
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
    io::read(sink, sections.io, &mut doc);
    doc.rt = section(sink, sections.rt, "rt", &mut doc.failed.keys);
    doc.control = section(sink, sections.control, "control", &mut doc.failed.keys);
    doc.switch = sections.switch.and_then(|value| {
        let span = value.span();
        let value = section(sink, Some(value), "switch", &mut doc.failed.keys)?;
        Some(Located { span, ctx: Ctx::Section("switch"), value })
    });
    doc.retain = section(sink, sections.retain, "retain", &mut doc.failed.keys);
    doc.modbus = modbus::read(sink, sections.modbus);
    doc.opcua = section(sink, sections.opcua, "opcua", &mut doc.failed.keys);
    doc.mqtt = section(sink, sections.mqtt, "mqtt", &mut doc.failed.keys);
    doc.st = section(sink, sections.st, "st", &mut doc.failed.keys);
    doc.iec = iec::read(sink, sections.iec, &mut doc.failed.keys);
    doc.remotes = remote::read(sink, sections.remote);
    doc.users = section(sink, sections.users, "users", &mut doc.failed.keys);
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
    opcua: Option<Spanned<DeValue<'i>>>,
    mqtt: Option<Spanned<DeValue<'i>>>,
    st: Option<Spanned<DeValue<'i>>>,
    iec: Option<Spanned<DeValue<'i>>>,
    remote: Option<Spanned<DeValue<'i>>>,
    users: Option<Spanned<DeValue<'i>>>,
}

/// Pass 2. `None` if anything is wrong (and then `sink` says what).
fn validate(doc: RawDoc, sink: &mut Sink) -> Option<Config> {
    let path = sink.path.to_path_buf();
    let gpio_inputs = task::gpio_inputs(&doc);
    let plc = doc.plc.and_then(|raw| plc::validate(sink, raw));
    let sim = doc.sim.and_then(|raw| sim::validate(sink, raw));
    let failed = &doc.failed.keys;
    let timers = doc.timers.and_then(|raw| timers::validate(sink, raw, failed));
    let control = doc.control.and_then(|raw| control::validate(sink, raw, &path));
    // [switch] before [io] consumes its entries: the switch's line must be none of theirs.
    let backend = doc
        .io
        .as_ref()
        .map(|io| io.value.backend)
        .filter(|_| !failed.iter().any(|k| k == "io.backend"));
    let wired = io::wired_lines(&doc.inputs, &doc.outputs);
    // [[remote]] before [io] and [modbus] consume their entries: remote reads must write no
    // P bit of the local I/O, and no port is both polled and served.
    let neighbours = remote::Neighbours {
        io_bits: remote::io_bits(&doc.inputs, &doc.outputs)
            .into_iter()
            .chain(remote::contact_bits(&doc.tasks))
            .collect(),
        rtu_server: modbus::rtu_port(doc.modbus.as_ref()),
    };
    let remotes = remote::validate(sink, doc.remotes, &neighbours);
    let switch_place = doc.switch.as_ref().map(|s| Place {
        at: s.value.line.as_ref().map_or(s.span.start, |line| line.span().start),
        subject: s.ctx.subject(),
    });
    let switch = switch::validate(sink, doc.switch, backend, &wired, failed);
    let io = io::validate(sink, doc.io, doc.inputs, doc.outputs, failed, &path);
    let rt = doc.rt.and_then(|raw| rt::validate(sink, raw, failed));
    let retain = doc.retain.and_then(|raw| retain::validate(sink, raw, &path));
    // Programs may name a task whose entry has errors: that entry's own diagnostics say what
    // is wrong, so it still counts as defined.
    let task_names: Vec<String> = doc
        .tasks
        .iter()
        .map(|t| t.value.name.get_ref().clone())
        .chain(doc.failed.task_names.iter().cloned())
        .collect();
    let tasks = task::validate(sink, doc.tasks, gpio_inputs.as_deref());
    let programs = program::validate(sink, doc.programs, &task_names, &doc.failed, &path);
    let modbus = modbus::validate(sink, doc.modbus);
    let opcua = doc.opcua.and_then(|raw| opcua::validate(sink, raw, &path));
    let mqtt = doc.mqtt.and_then(|raw| mqtt::validate(sink, raw, &path));
    let st = st::validate(sink, doc.st.unwrap_or_default(), &path);
    let iec = doc.iec.and_then(|raw| iec::validate(sink, raw));
    let users = doc.users.and_then(|raw| users::validate(sink, raw, &path));
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
        opcua: opcua?,
        mqtt: mqtt?,
        st: st?,
        iec: iec?,
        remotes: remotes?,
        users: users?,
    })
}
