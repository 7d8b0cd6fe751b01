//! The project configuration (docs/CONFIG.md): a TOML file parsed into typed, range-checked
//! structs.
//!
//! This module owns the config file's keys, their defaults and their ranges, and every
//! diagnostic about them. It does not read programs: [`ProgramConfig::resolved`] says where a
//! program is, and loading it is the project loader's job.
//!
//! [`parse`] is pure: text in, [`Config`] or [`Diagnostics`] out (`plcd::files` reads the file).
//! Parsing runs in two passes so that one mistake does not hide the next:
//!
//! 1. `raw`: the TOML text becomes a syntax tree with byte spans, and each section and each
//!    `[[…]]` entry is deserialized on its own. serde stops at the first error (unknown key,
//!    wrong type, bad enum value), so a table is tried again without the bad key until it
//!    deserializes: every bad key is reported. A section then goes on with that key's
//!    default; an entry with a bad key is left out of pass 2;
//! 2. `validate`: ranges, kind-specific keys and cross-references (task numbers and names,
//!    program tasks, I/O lines, the order of the `[rt]` priorities) are checked on everything
//!    that deserialized.
//!
//! Every error of both passes is reported, in file order. A document with TOML syntax errors
//! stops after pass 1: what the parser recovered may not be what was meant, and checking it
//! would mostly report consequences of the syntax error.

mod modbus;
mod raw;
mod retain;
mod validate;
pub mod wiring;

#[cfg(test)]
mod tests;

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::device::Address;
use crate::diag::{Diagnostic, Diagnostics};
pub use retain::{Restart, RetainArea, RetainConfig, RetainRange};

pub use modbus::{ModbusConfig, ModbusRange, ModbusTable};

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
    /// `[modbus]`: the Modbus TCP server (off unless `listen` is given) and its map.
    pub modbus: ModbusConfig,
}

impl Config {
    /// The contacts (0..=7 for P0000..=P0007) that io tasks start on, with the edge each task
    /// wants, in task order: the edges an I/O backend must report.
    pub fn edge_contacts(&self) -> Vec<(u8, Edge)> {
        wiring::edge_contacts(&self.tasks)
    }
}

/// `[plc]`: the scan and what happens when it fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlcConfig {
    /// `watchdog_ms`: the scan watchdog in ms, 10..=1000 (the XGB setting range); default 200.
    pub watchdog_ms: u32,
    /// `on_fault`: the outputs on a stopping error, `"clear"` (default) or `"hold"`.
    pub on_fault: OnFault,
    /// `scan_period_ms`: 0 (default) runs the scan free; N starts a new scan every N ms.
    /// Range 0..=1000: a period longer than the longest watchdog would leave outputs
    /// unrefreshed longer than any scan may take, which is never what a PLC wants.
    pub scan_period_ms: u32,
    /// `continue_on_congestion`: keep running when a task exceeds its `max_exec_ms`
    /// (the Hitachi "continued operation" setting); default false (stop with an error).
    pub continue_on_congestion: bool,
}

impl PlcConfig {
    pub const WATCHDOG_MS: RangeInclusive<u32> = 10..=1000;
    pub const SCAN_PERIOD_MS: RangeInclusive<u32> = 0..=1000;
}

impl Default for PlcConfig {
    fn default() -> Self {
        PlcConfig {
            watchdog_ms: 200,
            on_fault: OnFault::Clear,
            scan_period_ms: 0,
            continue_on_congestion: false,
        }
    }
}

/// `plc.on_fault`: the outputs after a stopping error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OnFault {
    /// `"clear"`: every output OFF (default).
    #[default]
    Clear,
    /// `"hold"`: outputs keep their last state.
    Hold,
}

/// `[sim]`: the virtual clock of `plcd sim`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimConfig {
    /// `step_ns`: virtual ns one executed instruction costs; at least 1, default 1000.
    pub step_ns: u64,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig { step_ns: 1000 }
    }
}

/// `[timers]`: the time base of each timer number.
///
/// Each key is `"Txxxx-Tyyyy"` (inclusive, within T0000..=T2047, first <= last) or `""` for no
/// timers of that base. A key not given keeps its default; the ranges must not overlap. Timer
/// numbers no range covers have no base ([`TimerConfig::base_ms`] is `None`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimerConfig {
    /// `ms100`: the 100 ms timers; default T0000..=T0999.
    pub ms100: Option<RangeInclusive<u32>>,
    /// `ms10`: the 10 ms timers; default T1000..=T1499.
    pub ms10: Option<RangeInclusive<u32>>,
    /// `ms1`: the 1 ms timers; default T1500..=T2047.
    pub ms1: Option<RangeInclusive<u32>>,
}

impl TimerConfig {
    /// The highest timer number (T2047).
    pub const LAST_TIMER: u32 = 2047;

    /// The base of timer `timer` in ms (100, 10 or 1), or `None` if no range covers it.
    pub fn base_ms(&self, timer: u32) -> Option<u32> {
        [(&self.ms100, 100), (&self.ms10, 10), (&self.ms1, 1)]
            .into_iter()
            .find(|(range, _)| range.as_ref().is_some_and(|r| r.contains(&timer)))
            .map(|(_, base)| base)
    }
}

impl Default for TimerConfig {
    fn default() -> Self {
        TimerConfig { ms100: Some(0..=999), ms10: Some(1000..=1499), ms1: Some(1500..=2047) }
    }
}

/// One `[[program]]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProgramConfig {
    /// `name`: unique among programs; default the stem of `file` (`main` for `main.il`).
    pub name: String,
    /// `file`: the instruction-list file, as written. Required, no default.
    pub file: PathBuf,
    /// `file` relative to the config file's directory (unchanged if absolute).
    pub resolved: PathBuf,
    /// `task`: `"init"`, `"scan"` (default) or the name of a `[[task]]`.
    pub task: TaskRef,
    /// Line of the `file` value in the config, for diagnostics about the program file.
    pub line: u32,
    /// Column of the `file` value.
    pub col: u32,
}

/// The task a program runs in.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum TaskRef {
    /// `"init"`: the initialization task, until `INIT_DONE`.
    Init,
    /// `"scan"`: the scan program.
    Scan,
    /// A `[[task]]` by name.
    Named(String),
}

impl TaskRef {
    /// The name as written in the config and shown in traces.
    pub fn name(&self) -> &str {
        match self {
            TaskRef::Init => "init",
            TaskRef::Scan => "scan",
            TaskRef::Named(name) => name,
        }
    }
}

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

/// `[io]`: where the P image's inputs come from and its outputs go.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct IoConfig {
    /// `backend`: `"sim"` (default, in-process) or `"gpiocdev"` (Linux GPIO character device).
    pub backend: Backend,
    /// `chip`: the GPIO chip, a path (`/dev/gpiochip0`) or a label; required for gpiocdev,
    /// ignored by sim. Default none.
    pub chip: Option<String>,
    /// `[[io.input]]`, in file order. Devices and lines are unique across inputs and outputs.
    pub inputs: Vec<IoLine>,
    /// `[[io.output]]`, in file order (`bias` and `debounce_us` are not allowed).
    pub outputs: Vec<IoLine>,
    /// `stimulus`: a CSV of input changes (docs/SIMULATION.md) for the sim backend, resolved relative
    /// to the config file; default none. An error with gpiocdev, whose inputs are the lines.
    pub stimulus: Option<PathBuf>,
    /// `stimulus_loop`: replay the stimulus from the start when it ends; default false.
    pub stimulus_loop: bool,
}

/// `io.backend`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    #[default]
    Sim,
    Gpiocdev,
}

/// One `[[io.input]]` or `[[io.output]]`: a P bit wired to a GPIO line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IoLine {
    /// `device`: a P bit (P0000..=P127F); required.
    pub device: Address,
    /// `line`: the line offset on the chip, 0..=4294967295; required.
    pub line: u32,
    /// `active_low`: the device is ON when the line is low; default false.
    pub active_low: bool,
    /// `bias`: inputs only, `"disabled"` (default), `"pull-up"` or `"pull-down"`.
    pub bias: Bias,
    /// `debounce_us`: inputs only, 0..=4294967295 µs; default 0 (none).
    pub debounce_us: u32,
}

/// `bias` of an input line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Bias {
    #[default]
    Disabled,
    PullUp,
    PullDown,
}

/// `[rt]`: the real-time threads of `plcd run` (checked by every command, used only by
/// `plcd run`; `plcd sim` and `plcd check` start no real-time threads).
///
/// The three priorities must rise strictly: `scan_priority < event_priority <
/// watchdog_priority`, so the watchdog can always preempt a runaway scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtConfig {
    /// `policy`: `"fifo"` (default: SCHED_FIFO) or `"other"` (SCHED_OTHER, no real time).
    pub policy: RtPolicy,
    /// `scan_priority`: SCHED_FIFO priority of the scan thread, 1..=99 and below
    /// `event_priority`; default 80.
    pub scan_priority: u8,
    /// `event_priority`: of the event thread (timers, GPIO edges), 1..=99 and above
    /// `scan_priority`; default 85.
    pub event_priority: u8,
    /// `watchdog_priority`: of the watchdog thread, 1..=99 and above `event_priority`;
    /// default 90.
    pub watchdog_priority: u8,
    /// `scan_cpus`: CPU numbers the scan thread may run on (0..=1023, no duplicates);
    /// default empty = any CPU.
    pub scan_cpus: Vec<u16>,
    /// `event_cpus`: the same for the event thread.
    pub event_cpus: Vec<u16>,
    /// `watchdog_cpus`: the same for the watchdog thread.
    pub watchdog_cpus: Vec<u16>,
    /// `lock_memory`: mlockall(MCL_CURRENT|MCL_FUTURE) at start; default true.
    pub lock_memory: bool,
    /// `cpu_dma_latency_us`: a CPU wake-up latency to request from the kernel's PM QoS
    /// (`/dev/cpu_dma_latency`, held while the driver runs, with policy fifo) so that idle CPUs
    /// stay in shallow states, as cyclictest does by default; 0..=2000000000; default -1
    /// (`None`): no request, the idle states are the system's.
    pub cpu_dma_latency_us: Option<u32>,
    /// `require`: refuse to start when real-time scheduling or memory locking is not
    /// permitted; default false (warn once and run without).
    pub require: bool,
}

impl RtConfig {
    /// The SCHED_FIFO priorities of Linux.
    pub const PRIORITY: RangeInclusive<u8> = 1..=99;
    /// The CPU numbers a CPU list may hold (a `cpu_set_t` has 1024).
    pub const CPU: RangeInclusive<u16> = 0..=1023;
    /// `cpu_dma_latency_us`: -1 (no request) or the kernel's PM QoS range in µs.
    pub const CPU_DMA_LATENCY: RangeInclusive<i64> = -1..=2_000_000_000;
}

impl Default for RtConfig {
    fn default() -> Self {
        RtConfig {
            policy: RtPolicy::Fifo,
            scan_priority: 80,
            event_priority: 85,
            watchdog_priority: 90,
            scan_cpus: Vec::new(),
            event_cpus: Vec::new(),
            watchdog_cpus: Vec::new(),
            lock_memory: true,
            cpu_dma_latency_us: None,
            require: false,
        }
    }
}

/// `[control]`: the daemon's control socket (`plcctl`, scripts, HMI gateways).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ControlConfig {
    /// `enabled`: serve the control socket; default true.
    pub enabled: bool,
    /// `socket`: the socket's path, resolved against the config file's directory when relative
    /// (this is the resolved path; an absolute one is kept), not empty, at most
    /// [`ControlConfig::MAX_SOCKET_PATH`] bytes; default `None`: `/run/plcd/plcd.sock`, or the
    /// fallbacks of `plcd_ipc::default_socket_paths` when that cannot be
    /// created.
    pub socket: Option<PathBuf>,
    /// `group`: the group that may connect (the socket is 0660, owned by the daemon's user and
    /// this group), not empty; default `None`: the daemon's own group.
    pub group: Option<String>,
    /// `max_clients`: connections served at once, 1..=1024; default 64. More are refused with
    /// a `busy` error.
    pub max_clients: u32,
    /// `max_request_bytes`: the longest request line, 256..=1048576; default 65536. A longer
    /// line is answered with `too_long` and the connection closed.
    pub max_request_bytes: u32,
    /// `idle_timeout_s`: a connection that sends no complete request for this long is closed,
    /// 0..=4294967295 s, 0 = never; default 300.
    pub idle_timeout_s: u32,
}

impl ControlConfig {
    pub const MAX_CLIENTS: RangeInclusive<u32> = 1..=1024;
    pub const MAX_REQUEST_BYTES: RangeInclusive<u32> = 256..=1_048_576;
    /// The longest path a Unix socket address holds (`sun_path` is 108 bytes with its NUL).
    pub const MAX_SOCKET_PATH: usize = 107;
}

impl Default for ControlConfig {
    fn default() -> Self {
        ControlConfig {
            enabled: true,
            socket: None,
            group: None,
            max_clients: 64,
            max_request_bytes: 65_536,
            idle_timeout_s: 300,
        }
    }
}

/// `[switch]`: a RUN/STOP key switch (XGB §5.2.3). With the switch at RUN the PLC runs and
/// remote RUN/STOP/DEBUG are refused; at STOP the PLC is stopped and remote mode changes are
/// accepted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SwitchConfig {
    /// `line`: the input line (offset on the `[io]` chip, 0..=4294967295) that is active when
    /// the switch is at RUN. Required with the gpiocdev backend, not allowed with the sim
    /// backend; not the line of any `[[io.input]]` or `[[io.output]]`. The line is no P bit.
    pub line: Option<u32>,
    /// `active_low`: the line is active when low; default false. Unused by the sim backend.
    pub active_low: bool,
    /// `bias`: `"pull-up"`, `"pull-down"` or `"disabled"` (default). Unused by the sim backend.
    pub bias: Bias,
    /// `debounce_us`: the kernel's debounce period for the contact, 0..=1000000 µs (0: none);
    /// default 10000. Unused by the sim backend.
    pub debounce_us: u32,
    /// `position`: sim backend only (an error with gpiocdev): where the simulated switch
    /// starts, `"run"` (default) or `"stop"`; stimulus lines `SWITCH, RUN|STOP` move it.
    pub position: crate::io::SwitchPosition,
}

impl SwitchConfig {
    pub const DEBOUNCE_US: RangeInclusive<u32> = 0..=1_000_000;
}

impl Default for SwitchConfig {
    fn default() -> Self {
        SwitchConfig {
            line: None,
            active_low: false,
            bias: Bias::Disabled,
            debounce_us: 10_000,
            position: crate::io::SwitchPosition::Run,
        }
    }
}

/// `rt.policy`: the scheduling policy of the real-time threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RtPolicy {
    /// `"fifo"`: SCHED_FIFO with the configured priorities (default).
    #[default]
    Fifo,
    /// `"other"`: SCHED_OTHER, the normal time-sharing policy; the priorities are not used.
    Other,
}

/// Parses and validates a config. Pure: `path` only names the file in diagnostics and is the
/// base of relative program and stimulus paths. On error, every diagnostic, in file order.
pub fn parse(text: &str, path: &Path) -> Result<Config, Diagnostics> {
    let mut sink = Sink::new(text, path);
    let config = raw::read(text, &mut sink).and_then(|doc| validate::validate(doc, &mut sink));
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
