//! The gpiocdev backend: the P image's inputs and outputs, and the RUN/STOP key switch, on the
//! lines of one GPIO chip, through the Linux GPIO character device (uAPI v2).
//!
//! This module owns the chip lookup (a path, a `/dev` name or a chip label), the two line
//! requests, the mapping between line offsets and P bits, and the reading of edge events. What
//! [`open`] returns is split by thread: [`GpioIo`] for the scan (the [`Io`] trait),
//! [`GpioEdges`] for the event thread, [`GpioOutputs`] for the watchdog.
//!
//! Why it is built this way:
//! - **One request per direction.** All inputs are one line request, all outputs another, each
//!   with per-line settings (bias, active-low, debounce, edge). The kernel reads or writes every
//!   line of a request in one ioctl, so a refresh costs one syscall whatever the line count, and
//!   every input of a scan is sampled at the same instant (no skew between lines that a
//!   line-by-line loop would have).
//! - **The key switch is one more input line.** `[switch]`'s line is in the input request with
//!   its own bias, active-low and debounce, so the same get-values ioctl reads it; it maps to no
//!   P bit and detects no edges (the engine looks at it at each input refresh, which is as often
//!   as a mode change can take effect). It is read once at open too, so the position is known
//!   before the first scan.
//! - **One ioctl per refresh, no allocation.** The `Values` passed to gpiocdev are built at open
//!   with every requested offset in them: with a non-empty `Values`, gpiocdev converts to and
//!   from the kernel's bitmap on the stack. An ioctl error is counted and kept for the daemon to
//!   log; the scan never panics on I/O.
//! - **Active-low in the kernel.** Lines are requested with the `active_low` flag, so the values
//!   and the edges the kernel reports are already logical (a rising edge is OFF → ON of the
//!   device), as the engine expects.
//! - **Edge detection only where a task needs it.** Each edge-detecting line costs an interrupt
//!   per edge and a slot in the kernel's event FIFO; only the contacts P0000–P0007 that I/O
//!   tasks start on get it, with the kinds those tasks ask for (several tasks on one contact
//!   merge).
//! - **Kernel timestamps.** An edge carries the CLOCK_MONOTONIC time the kernel took in its
//!   interrupt handler, which is when the edge happened, not when the event thread got to it.
//! - **Sequence gaps.** When the event thread falls behind, the kernel's FIFO drops the oldest
//!   events. Each event carries its line's sequence number, so a gap tells how many edges were
//!   lost; they are counted and reported rather than silently missing. The per-line number is
//!   used, not the per-request one: the kernel numbers an edge in the hard interrupt but queues
//!   it from the line's interrupt thread, so events of different lines can be queued out of
//!   request order, while one line's events never are.
//!
//! The offset ↔ P-bit mapping, the edge merging and the sequence check are pure functions with
//! unit tests; everything that needs a chip is tested against the kernel's gpio-sim elsewhere.

use std::fmt;
use std::os::fd::{AsFd, BorrowedFd};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use gpiocdev::line::{
    Bias as LineBias, EdgeDetection, EdgeEvent, EdgeKind, EventClock, Value, Values,
};
use gpiocdev::{Chip, Request};

use super::{InputEdge, Io, SwitchPosition};
use crate::config::{Bias, Edge, IoConfig, IoLine, SwitchConfig};
use crate::device::layout::P_WORDS;
use crate::device::{Address, Area, Memory};

/// The most lines one kernel line request can hold (`GPIO_V2_LINES_MAX`).
pub const MAX_LINES_PER_REQUEST: usize = 64;

/// The most line settings a request can carry besides its default one
/// (`GPIO_V2_LINE_NUM_ATTRS_MAX`): each distinct combination of flags beyond the most common one,
/// and each distinct debounce period, takes one.
pub const MAX_EXTRA_SETTINGS: usize = 10;

/// Kernel FIFO slots per edge-detecting line: the kernel's own default per line. The user-space
/// buffer has as many, so one read can drain the whole FIFO.
const EVENTS_PER_EDGE_LINE: usize = 16;

/// The contacts P0000–P0007 that I/O tasks start on.
const CONTACTS: usize = 8;

/// What the daemon gets from opening the backend.
#[derive(Debug)]
pub struct Gpio {
    /// The scan's side: input and output refresh.
    pub io: GpioIo,
    /// The event thread's side; `None` when no I/O task needs an edge.
    pub edges: Option<GpioEdges>,
    /// The watchdog's side: forcing every output inactive.
    pub outputs: GpioOutputs,
}

/// Why the backend could not open, or an I/O operation failed.
#[derive(Debug, thiserror::Error)]
pub enum GpioError {
    #[error(
        "io.chip is not set: the gpiocdev backend needs a GPIO chip \
         (a path such as /dev/gpiochip0, or a chip label)"
    )]
    NoChip,

    #[error("GPIO chip `{asked}` not found; {}", ChipList(.available))]
    ChipNotFound {
        /// `io.chip` as written.
        asked: String,
        /// The chips the system has (empty when it has none, or /dev cannot be listed).
        available: Vec<ChipSummary>,
    },

    #[error(
        "GPIO chip label `{asked}` matches several chips ({}); name the chip by its path",
        ChipList(.matches)
    )]
    AmbiguousChip { asked: String, matches: Vec<ChipSummary> },

    #[error("cannot open GPIO chip `{chip}`: {source}")]
    ChipOpen {
        chip: Arc<str>,
        #[source]
        source: gpiocdev::Error,
    },

    #[error("an I/O task cannot start on contact {contact}: only P0000..P0007 (0..=7) can")]
    NotAContact { contact: u8 },

    #[error("an I/O task starts on {device}, but {device} is not an [[io.input]] line")]
    ContactNotWired { device: Address },

    #[error("{device} is not a P bit device, which is all a GPIO line can be wired to")]
    NotAPBit { device: Address },

    #[error("line {line} is wired to both {first} and {second}")]
    DuplicateLine { line: u32, first: Wire, second: Wire },

    #[error("[switch] has no line: the gpiocdev backend reads the RUN/STOP switch from a line")]
    SwitchNotWired,

    #[error("{count} {direction} lines configured, but one GPIO line request holds at most {max}")]
    TooManyLines { direction: LineDirection, count: usize, max: usize },

    #[error(
        "the {direction} lines need {needed} distinct line settings (combinations of active_low, \
         bias and edge, and debounce periods) besides the most common one; the kernel takes at \
         most {max} per request"
    )]
    TooManySettings { direction: LineDirection, needed: usize, max: usize },

    #[error(
        "GPIO chip {chip}: line {line} ({wire}) does not exist, the chip has {num_lines} lines"
    )]
    LineOutOfRange { chip: Arc<str>, line: u32, wire: Wire, num_lines: u32 },

    #[error("GPIO chip {chip}: line {line} ({wire}) is already in use{}", UsedBy(.consumer))]
    LineBusy { chip: Arc<str>, line: u32, wire: Wire, consumer: Option<String> },

    #[error("GPIO chip {chip}: requesting the {count} {direction} lines failed: {source}")]
    Request {
        chip: Arc<str>,
        direction: LineDirection,
        count: usize,
        #[source]
        source: gpiocdev::Error,
    },

    #[error("GPIO chip {chip}: {op} failed: {source}")]
    Io {
        chip: Arc<str>,
        op: IoOp,
        #[source]
        source: gpiocdev::Error,
    },
}

/// What a line is wired to, as errors name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wire {
    /// The P bit of an `[[io.input]]` or `[[io.output]]`.
    Device(Address),
    /// The RUN/STOP key switch of `[switch]`.
    Switch,
}

impl fmt::Display for Wire {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Wire::Device(device) => write!(f, "{device}"),
            Wire::Switch => f.write_str("the RUN/STOP switch"),
        }
    }
}

/// A GPIO chip as the "not found" errors list it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChipSummary {
    /// The device name (`gpiochip0`).
    pub name: String,
    /// The chip's label; `None` if the chip could not be opened to read it.
    pub label: Option<String>,
}

impl fmt::Display for ChipSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.label.as_deref() {
            Some("") => write!(f, "{} (no label)", self.name),
            Some(label) => write!(f, "{} ({label})", self.name),
            None => write!(f, "{} (label unreadable)", self.name),
        }
    }
}

struct ChipList<'a>(&'a [ChipSummary]);

impl fmt::Display for ChipList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return f.write_str("this system has no GPIO chips");
        }
        f.write_str("chips on this system: ")?;
        for (i, chip) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{chip}")?;
        }
        Ok(())
    }
}

struct UsedBy<'a>(&'a Option<String>);

impl fmt::Display for UsedBy<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(consumer) => write!(f, " by `{consumer}`"),
            None => f.write_str(" by another consumer"),
        }
    }
}

/// Which of the two requests.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineDirection {
    Input,
    Output,
}

impl fmt::Display for LineDirection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LineDirection::Input => "input",
            LineDirection::Output => "output",
        })
    }
}

/// The operation an I/O error happened in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IoOp {
    ReadInputs,
    WriteOutputs,
    ForceInactive,
    ReadEdges,
    ChipInfo,
    LineInfo { line: u32 },
}

impl fmt::Display for IoOp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            IoOp::ReadInputs => f.write_str("reading the inputs"),
            IoOp::WriteOutputs => f.write_str("writing the outputs"),
            IoOp::ForceInactive => f.write_str("forcing the outputs inactive"),
            IoOp::ReadEdges => f.write_str("reading edge events"),
            IoOp::ChipInfo => f.write_str("reading the chip info"),
            IoOp::LineInfo { line } => write!(f, "reading the info of line {line}"),
        }
    }
}

// ----------------------------------------------------------------------------------------------
// Opening
// ----------------------------------------------------------------------------------------------

/// Opens the chip and requests the lines.
///
/// `switch`: the `[switch]` config, whose `line` is requested as one more input (and must be
/// set). `edge_contacts`: the contacts (0..=7, P0000..P0007) that I/O tasks start on and the
/// edge each needs; several tasks on one contact merge. Edge detection is enabled only on those
/// input lines. `consumer`: the consumer label the kernel shows for the lines ("plcd").
///
/// No line is requested when there is nothing to request in a direction. Outputs start
/// inactive. The switch is read once before this returns.
pub fn open(
    config: &IoConfig,
    switch: Option<&SwitchConfig>,
    edge_contacts: &[(u8, Edge)],
    consumer: &str,
) -> Result<Gpio, GpioError> {
    let asked = config.chip.as_deref().ok_or(GpioError::NoChip)?;
    let plan = Plan::new(config, switch, edge_contacts)?;
    let found = find_chip(asked)?;
    for (line, wire) in plan.lines() {
        found.check_line(line, wire)?;
    }

    let input_offsets: Vec<u32> = plan.inputs.iter().map(|i| i.line.offset).collect();
    let output_offsets: Vec<u32> = plan.outputs.iter().map(|o| o.line.line).collect();
    let inputs = if plan.inputs.is_empty() {
        None
    } else {
        Some(Arc::new(request_inputs(&found, &plan.inputs, consumer)?))
    };
    let outputs = if plan.outputs.is_empty() {
        None
    } else {
        Some(Arc::new(OutputShared {
            chip: found.name.clone(),
            request: request_outputs(&found, &plan.outputs, consumer)?,
            inactive: Values::from_offsets(&output_offsets),
        }))
    };

    let edge_lines = plan.edge_lines();
    let edges = match &inputs {
        Some(request) if edge_lines > 0 => Some(GpioEdges::new(
            found.name.clone(),
            request.clone(),
            EdgeMap::new(&plan.inputs),
            EVENTS_PER_EDGE_LINE * edge_lines,
        )),
        _ => None,
    };
    // Values holding every offset of their request: gpiocdev then never grows them, and
    // their order (sorted offsets) is the order of the plan's bits.
    let mut inputs = inputs.map(|request| InputSide {
        request,
        values: Values::from_offsets(&input_offsets),
        slots: plan.inputs.iter().map(|i| i.slot).collect(),
    });
    let mut switch = None;
    if let Some(side) = inputs.as_mut().filter(|_| plan.has_switch()) {
        side.request.values(&mut side.values).map_err(|source| GpioError::Io {
            chip: found.name.clone(),
            op: IoOp::ReadInputs,
            source,
        })?;
        switch = switch_position(&side.slots, &side.values);
    }
    let io = GpioIo {
        chip: found.name.clone(),
        inputs,
        switch,
        outputs: outputs.clone().map(|shared| OutputSide {
            shared,
            values: Values::from_offsets(&output_offsets),
            bits: plan.outputs.iter().map(|o| o.bit).collect(),
        }),
        io_errors: 0,
        last_error: None,
    };
    Ok(Gpio { io, edges, outputs: GpioOutputs { shared: outputs } })
}

fn request_inputs(
    found: &FoundChip,
    inputs: &[InputPlan],
    consumer: &str,
) -> Result<Request, GpioError> {
    let mut builder = Request::builder();
    builder.on_chip(found.path.as_path()).with_consumer(consumer);
    let edge_lines = inputs.iter().filter(|i| i.edge.is_some()).count();
    if edge_lines > 0 {
        builder.with_kernel_event_buffer_size((EVENTS_PER_EDGE_LINE * edge_lines) as u32);
    }
    for input in inputs {
        // with_line selects just this line: what follows configures it alone.
        // `bias = "disabled"` is asked for explicitly, so that a pull left on by firmware or
        // a previous user does not linger on a line the config says has none.
        builder.with_line(input.line.offset).as_input().with_bias(line_bias(input.line.bias));
        if input.line.active_low {
            builder.as_active_low();
        }
        if input.line.debounce_us > 0 {
            builder.with_debounce_period(Duration::from_micros(input.line.debounce_us.into()));
        }
        if let Some((_, edge)) = input.edge {
            // Monotonic is the kernel's default; named because InputEdge::stamp_ns is defined
            // on it.
            builder
                .with_edge_detection(edge_detection(edge))
                .with_event_clock(EventClock::Monotonic);
        }
    }
    builder.request().map_err(|source| {
        found.request_error(
            LineDirection::Input,
            inputs.iter().map(|i| (i.line.offset, i.wire())),
            source,
        )
    })
}

fn request_outputs(
    found: &FoundChip,
    outputs: &[OutputPlan],
    consumer: &str,
) -> Result<Request, GpioError> {
    let mut builder = Request::builder();
    builder.on_chip(found.path.as_path()).with_consumer(consumer);
    for output in outputs {
        builder.with_line(output.line.line).as_output(Value::Inactive);
        if output.line.active_low {
            builder.as_active_low();
        }
    }
    builder.request().map_err(|source| {
        found.request_error(
            LineDirection::Output,
            outputs.iter().map(|o| (o.line.line, Wire::Device(o.line.device))),
            source,
        )
    })
}

fn line_bias(bias: Bias) -> LineBias {
    match bias {
        Bias::Disabled => LineBias::Disabled,
        Bias::PullUp => LineBias::PullUp,
        Bias::PullDown => LineBias::PullDown,
    }
}

fn edge_detection(edge: Edge) -> EdgeDetection {
    match edge {
        Edge::Rising => EdgeDetection::RisingEdge,
        Edge::Falling => EdgeDetection::FallingEdge,
        Edge::Both => EdgeDetection::BothEdges,
    }
}

/// The chip `io.chip` names, opened.
struct FoundChip {
    chip: Chip,
    path: PathBuf,
    /// How errors name the chip: `gpiochip0 (label)`.
    name: Arc<str>,
    num_lines: u32,
}

impl FoundChip {
    fn new(chip: Chip) -> Result<FoundChip, GpioError> {
        let info = chip.info().map_err(|source| GpioError::Io {
            chip: chip.name().into(),
            op: IoOp::ChipInfo,
            source,
        })?;
        let summary = ChipSummary { name: chip.name(), label: Some(info.label) };
        Ok(FoundChip {
            path: chip.path().to_path_buf(),
            name: summary.to_string().into(),
            num_lines: info.num_lines,
            chip,
        })
    }

    /// The line exists and nobody holds it. Checking `used` before requesting names the
    /// other consumer, which the request's EBUSY would not.
    fn check_line(&self, line: u32, wire: Wire) -> Result<(), GpioError> {
        if line >= self.num_lines {
            return Err(GpioError::LineOutOfRange {
                chip: self.name.clone(),
                line,
                wire,
                num_lines: self.num_lines,
            });
        }
        let info = self.chip.line_info(line).map_err(|source| GpioError::Io {
            chip: self.name.clone(),
            op: IoOp::LineInfo { line },
            source,
        })?;
        if info.used {
            return Err(self.busy(line, wire, info.consumer));
        }
        Ok(())
    }

    fn busy(&self, line: u32, wire: Wire, consumer: String) -> GpioError {
        GpioError::LineBusy {
            chip: self.name.clone(),
            line,
            wire,
            consumer: (!consumer.is_empty()).then_some(consumer),
        }
    }

    /// A failed request. EBUSY means a line was taken since [`FoundChip::check_line`]: find
    /// which one, to name it and its consumer.
    fn request_error(
        &self,
        direction: LineDirection,
        lines: impl ExactSizeIterator<Item = (u32, Wire)>,
        source: gpiocdev::Error,
    ) -> GpioError {
        let count = lines.len();
        if is_errno(&source, libc::EBUSY) {
            for (line, wire) in lines {
                if let Ok(info) = self.chip.line_info(line) {
                    if info.used {
                        return self.busy(line, wire, info.consumer);
                    }
                }
            }
        }
        GpioError::Request { chip: self.name.clone(), direction, count, source }
    }
}

/// Finds the chip `asked` names: a path if it starts with '/', else a name under /dev
/// (`gpiochip0`) or a chip label.
fn find_chip(asked: &str) -> Result<FoundChip, GpioError> {
    let open_error = |source| GpioError::ChipOpen { chip: asked.into(), source };
    if asked.starts_with('/') {
        return match Chip::from_path(asked) {
            Ok(chip) => FoundChip::new(chip),
            Err(e) if is_errno(&e, libc::ENOENT) => Err(GpioError::ChipNotFound {
                asked: asked.to_string(),
                available: list_chips().into_iter().map(|(_, summary, _)| summary).collect(),
            }),
            Err(e) => Err(open_error(e)),
        };
    }
    if !asked.is_empty() && !asked.contains('/') {
        // A name that is a GPIO chip under /dev but cannot be opened is that chip's error
        // (permissions, usually), not a reason to look further.
        if let Ok(path) = gpiocdev::chip::is_chip(format!("/dev/{asked}")) {
            return Chip::from_path(path).map_err(open_error).and_then(FoundChip::new);
        }
    }
    let chips = list_chips();
    let mut matches: Vec<(Chip, ChipSummary)> = Vec::new();
    let mut available = Vec::with_capacity(chips.len());
    for (chip, summary, kernel_name) in chips {
        let hit = summary.label.as_deref() == Some(asked) || kernel_name.as_deref() == Some(asked);
        if let (true, Some(chip)) = (hit, chip) {
            matches.push((chip, summary.clone()));
        }
        available.push(summary);
    }
    if matches.len() > 1 {
        return Err(GpioError::AmbiguousChip {
            asked: asked.to_string(),
            matches: matches.into_iter().map(|(_, summary)| summary).collect(),
        });
    }
    match matches.pop() {
        Some((chip, _)) => FoundChip::new(chip),
        None => Err(GpioError::ChipNotFound { asked: asked.to_string(), available }),
    }
}

/// Every GPIO chip of the system, opened if it can be, with its summary and kernel name.
/// Listing is best effort: a system without GPIO support (or without /dev) has no chips.
fn list_chips() -> Vec<(Option<Chip>, ChipSummary, Option<String>)> {
    let paths = gpiocdev::chip::chips().unwrap_or_default();
    paths
        .into_iter()
        .map(|path| {
            let name = path
                .file_name()
                .map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
            let chip = Chip::from_path(&path).ok();
            let info = chip.as_ref().and_then(|c| c.info().ok());
            let kernel_name = info.as_ref().map(|i| i.name.clone());
            (chip, ChipSummary { name, label: info.map(|i| i.label) }, kernel_name)
        })
        .collect()
}

/// Whether a gpiocdev error is the OS error `code`. gpiocdev keeps the errno of a failed ioctl
/// inside a uAPI error type this crate cannot name; its message is exactly the OS error's, so
/// compare messages. Only used while opening: it allocates.
fn is_errno(error: &gpiocdev::Error, code: i32) -> bool {
    match error {
        gpiocdev::Error::Os(errno) => errno.0 == code,
        gpiocdev::Error::Uapi(_, inner) => {
            inner.to_string() == std::io::Error::from_raw_os_error(code).to_string()
        }
        _ => false,
    }
}

// ----------------------------------------------------------------------------------------------
// The plan: which line is which P bit (or the key switch), and which lines detect edges. Pure.
// ----------------------------------------------------------------------------------------------

/// A bit of the P image: `mem.io_image()[word] & mask`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct ImageBit {
    word: u16,
    mask: u16,
}

impl ImageBit {
    fn of(device: &Address) -> Result<ImageBit, GpioError> {
        match (device.area, device.bit) {
            (Area::P, Some(bit)) if device.number < P_WORDS && bit < 16 => {
                Ok(ImageBit { word: device.number as u16, mask: 1 << bit })
            }
            _ => Err(GpioError::NotAPBit { device: *device }),
        }
    }
}

/// An input line's offset and settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct InputLine {
    offset: u32,
    active_low: bool,
    bias: Bias,
    debounce_us: u32,
}

/// Where an input line's value goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum InputSlot {
    /// A P bit: the device, and its place in the image.
    Bit { device: Address, bit: ImageBit },
    /// The key switch: no P bit; active is RUN.
    Switch,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct InputPlan {
    line: InputLine,
    slot: InputSlot,
    /// The contact and the edges its tasks need, if any task starts on this line (never the
    /// switch).
    edge: Option<(u8, Edge)>,
}

impl InputPlan {
    fn wire(&self) -> Wire {
        match self.slot {
            InputSlot::Bit { device, .. } => Wire::Device(device),
            InputSlot::Switch => Wire::Switch,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct OutputPlan {
    line: IoLine,
    bit: ImageBit,
}

/// The lines of both requests, each sorted by offset: that is the order of the kernel's
/// bitmaps and of gpiocdev's `Values`, so refresh walks both side by side. The key switch's
/// line, if any, is among the inputs.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Plan {
    inputs: Vec<InputPlan>,
    outputs: Vec<OutputPlan>,
}

impl Plan {
    fn new(
        config: &IoConfig,
        switch: Option<&SwitchConfig>,
        edge_contacts: &[(u8, Edge)],
    ) -> Result<Plan, GpioError> {
        let edges = contact_edges(edge_contacts)?;
        let switch_line = match switch {
            Some(switch) => Some(switch.line.ok_or(GpioError::SwitchNotWired)?),
            None => None,
        };
        let devices = config.inputs.iter().chain(&config.outputs);
        let wires = devices.map(|l| (l.line, Wire::Device(l.device)));
        check_unique_lines(wires.chain(switch_line.map(|line| (line, Wire::Switch))))?;

        let mut wired = [false; CONTACTS];
        let mut inputs = Vec::with_capacity(config.inputs.len() + 1);
        for line in &config.inputs {
            let contact = contact_of(&line.device);
            if let Some(c) = contact {
                wired[c as usize] = true;
            }
            let edge = contact.and_then(|c| edges[c as usize].map(|e| (c, e)));
            let slot = InputSlot::Bit { device: line.device, bit: ImageBit::of(&line.device)? };
            let settings = InputLine {
                offset: line.line,
                active_low: line.active_low,
                bias: line.bias,
                debounce_us: line.debounce_us,
            };
            inputs.push(InputPlan { line: settings, slot, edge });
        }
        if let Some(c) = (0..CONTACTS).find(|&c| edges[c].is_some() && !wired[c]) {
            return Err(GpioError::ContactNotWired { device: contact_device(c as u8) });
        }
        if let (Some(switch), Some(offset)) = (switch, switch_line) {
            let settings = InputLine {
                offset,
                active_low: switch.active_low,
                bias: switch.bias,
                debounce_us: switch.debounce_us,
            };
            inputs.push(InputPlan { line: settings, slot: InputSlot::Switch, edge: None });
        }
        let mut outputs = Vec::with_capacity(config.outputs.len());
        for line in &config.outputs {
            outputs.push(OutputPlan { line: *line, bit: ImageBit::of(&line.device)? });
        }
        inputs.sort_by_key(|i| i.line.offset);
        outputs.sort_by_key(|o| o.line.line);

        for (direction, count) in
            [(LineDirection::Input, inputs.len()), (LineDirection::Output, outputs.len())]
        {
            if count > MAX_LINES_PER_REQUEST {
                return Err(GpioError::TooManyLines {
                    direction,
                    count,
                    max: MAX_LINES_PER_REQUEST,
                });
            }
        }
        let needed = extra_settings(&inputs);
        if needed > MAX_EXTRA_SETTINGS {
            return Err(GpioError::TooManySettings {
                direction: LineDirection::Input,
                needed,
                max: MAX_EXTRA_SETTINGS,
            });
        }
        Ok(Plan { inputs, outputs })
    }

    fn lines(&self) -> impl Iterator<Item = (u32, Wire)> + '_ {
        let inputs = self.inputs.iter().map(|i| (i.line.offset, i.wire()));
        inputs.chain(self.outputs.iter().map(|o| (o.line.line, Wire::Device(o.line.device))))
    }

    fn edge_lines(&self) -> usize {
        self.inputs.iter().filter(|i| i.edge.is_some()).count()
    }

    fn has_switch(&self) -> bool {
        self.inputs.iter().any(|i| i.slot == InputSlot::Switch)
    }
}

/// The contact (0..=7) a device is, if it is one of P0000..P0007.
fn contact_of(device: &Address) -> Option<u8> {
    match (device.area, device.number, device.bit) {
        (Area::P, 0, Some(bit)) if (bit as usize) < CONTACTS => Some(bit),
        _ => None,
    }
}

fn contact_device(contact: u8) -> Address {
    Address { area: Area::P, number: 0, bit: Some(contact) }
}

/// The edge a line must detect for two tasks that need `a` and `b`.
fn merge_edge(a: Edge, b: Edge) -> Edge {
    if a == b {
        a
    } else {
        Edge::Both
    }
}

/// Per contact, the edges its tasks need (merged), or `None` if no task starts on it.
fn contact_edges(edge_contacts: &[(u8, Edge)]) -> Result<[Option<Edge>; CONTACTS], GpioError> {
    let mut edges = [None; CONTACTS];
    for &(contact, edge) in edge_contacts {
        let slot = edges.get_mut(contact as usize).ok_or(GpioError::NotAContact { contact })?;
        *slot = Some(slot.map_or(edge, |have| merge_edge(have, edge)));
    }
    Ok(edges)
}

fn check_unique_lines(lines: impl Iterator<Item = (u32, Wire)>) -> Result<(), GpioError> {
    let mut seen: Vec<(u32, Wire)> = Vec::new();
    for (line, wire) in lines {
        if let Some(&(_, first)) = seen.iter().find(|(l, _)| *l == line) {
            return Err(GpioError::DuplicateLine { line, first, second: wire });
        }
        seen.push((line, wire));
    }
    Ok(())
}

/// How many line settings the input request needs besides its default, counted the way the
/// kernel (and gpiocdev, building the request) counts them: one per distinct flag combination
/// beyond the first, one per distinct debounce period.
fn extra_settings(inputs: &[InputPlan]) -> usize {
    let mut flags: Vec<(bool, Bias, Option<Edge>)> = Vec::new();
    let mut debounces: Vec<u32> = Vec::new();
    for input in inputs {
        let f = (input.line.active_low, input.line.bias, input.edge.map(|(_, e)| e));
        if !flags.contains(&f) {
            flags.push(f);
        }
        let d = input.line.debounce_us;
        if d > 0 && !debounces.contains(&d) {
            debounces.push(d);
        }
    }
    flags.len().saturating_sub(1) + debounces.len()
}

/// Copies line values (in offset order) into their P bits; other bits are left alone. Returns
/// the key switch's position if it is among the lines.
fn apply_inputs(image: &mut [u16], slots: &[InputSlot], values: &Values) -> Option<SwitchPosition> {
    let mut switch = None;
    for (slot, lv) in slots.iter().zip(values.iter()) {
        match slot {
            InputSlot::Bit { bit, .. } => {
                if let Some(word) = image.get_mut(bit.word as usize) {
                    if lv.value == Value::Active {
                        *word |= bit.mask;
                    } else {
                        *word &= !bit.mask;
                    }
                }
            }
            InputSlot::Switch => switch = Some(position(lv.value)),
        }
    }
    switch
}

/// The key switch's position in line values (in offset order), if it is among the lines.
fn switch_position(slots: &[InputSlot], values: &Values) -> Option<SwitchPosition> {
    let mut lines = slots.iter().zip(values.iter());
    lines.find(|(slot, _)| **slot == InputSlot::Switch).map(|(_, lv)| position(lv.value))
}

/// The switch's line is active at RUN (`active_low` is applied by the kernel).
fn position(value: Value) -> SwitchPosition {
    match value {
        Value::Active => SwitchPosition::Run,
        Value::Inactive => SwitchPosition::Stop,
    }
}

/// Sets each output's value (in offset order) from its P bit.
fn collect_outputs(image: &[u16], bits: &[ImageBit], values: &mut Values) {
    for (bit, lv) in bits.iter().zip(values.iter_mut()) {
        let on = image.get(bit.word as usize).is_some_and(|word| word & bit.mask != 0);
        lv.value = Value::from(on);
    }
}

// ----------------------------------------------------------------------------------------------
// Scan side
// ----------------------------------------------------------------------------------------------

/// The scan's side of the backend: refreshes the P image from and to the lines.
#[derive(Debug)]
pub struct GpioIo {
    chip: Arc<str>,
    inputs: Option<InputSide>,
    /// The key switch as last read (at open, then at each input refresh); `None`: no switch.
    switch: Option<SwitchPosition>,
    outputs: Option<OutputSide>,
    io_errors: u64,
    last_error: Option<GpioError>,
}

#[derive(Debug)]
struct InputSide {
    request: Arc<Request>,
    /// Every input offset, sorted; gpiocdev fills in the values.
    values: Values,
    /// Where each entry of `values` goes: a P bit or the key switch.
    slots: Box<[InputSlot]>,
}

#[derive(Debug)]
struct OutputSide {
    shared: Arc<OutputShared>,
    values: Values,
    bits: Box<[ImageBit]>,
}

impl GpioIo {
    /// How errors name the chip.
    pub fn chip(&self) -> &str {
        &self.chip
    }

    /// The number of refreshes that failed since open.
    pub fn io_errors(&self) -> u64 {
        self.io_errors
    }

    /// The last refresh error, if one happened since the last call; for the daemon to log
    /// (outside the scan, since logging allocates).
    pub fn take_error(&mut self) -> Option<GpioError> {
        self.last_error.take()
    }

    fn record(&mut self, op: IoOp, source: gpiocdev::Error) {
        self.io_errors = self.io_errors.saturating_add(1);
        // An Arc clone and a move: the error path does not allocate either.
        self.last_error = Some(GpioError::Io { chip: self.chip.clone(), op, source });
    }
}

impl Io for GpioIo {
    /// One get-values ioctl for all inputs and the key switch. On an error the P bits and the
    /// switch keep their last values.
    fn refresh_inputs(&mut self, mem: &mut Memory) {
        let Some(inputs) = &mut self.inputs else { return };
        match inputs.request.values(&mut inputs.values) {
            Ok(()) => {
                let switch = apply_inputs(mem.io_image_mut(), &inputs.slots, &inputs.values);
                if switch.is_some() {
                    self.switch = switch;
                }
            }
            Err(e) => self.record(IoOp::ReadInputs, e),
        }
    }

    /// One set-values ioctl for all outputs.
    fn refresh_outputs(&mut self, mem: &Memory) {
        let Some(outputs) = &mut self.outputs else { return };
        collect_outputs(mem.io_image(), &outputs.bits, &mut outputs.values);
        if let Err(e) = outputs.shared.request.set_values(&outputs.values) {
            self.record(IoOp::WriteOutputs, e);
        }
    }

    /// The key switch as read at the last input refresh (or at open, before the first).
    fn switch(&self) -> Option<SwitchPosition> {
        self.switch
    }

    fn is_input(&self, bit: crate::device::BitRef) -> bool {
        self.inputs.as_ref().is_some_and(|inputs| {
            inputs.slots.iter().any(|slot| {
                matches!(slot, InputSlot::Bit { bit: b, .. } if b.word == bit.word && b.mask & bit.mask != 0)
            })
        })
    }
}

// ----------------------------------------------------------------------------------------------
// Watchdog side
// ----------------------------------------------------------------------------------------------

/// The output request and the all-inactive values, shared by the scan and the watchdog.
/// `gpiocdev::Request` is `Sync` (a `File`, a `Vec` and an `Arc<RwLock<_>>`; its value calls
/// take `&self`), and the kernel serializes set-values on one request.
#[derive(Debug)]
struct OutputShared {
    chip: Arc<str>,
    request: Request,
    inactive: Values,
}

/// A handle the watchdog thread uses to force every output inactive. Cheap to clone.
#[derive(Debug, Clone)]
pub struct GpioOutputs {
    shared: Option<Arc<OutputShared>>,
}

impl GpioOutputs {
    /// Sets every output line inactive in one set-values ioctl; no allocation. Does nothing
    /// when there are no outputs.
    ///
    /// The scan may publish outputs again afterwards: stopping it is the caller's business.
    pub fn set_all_inactive(&self) -> Result<(), GpioError> {
        let Some(shared) = &self.shared else { return Ok(()) };
        shared.request.set_values(&shared.inactive).map_err(|source| GpioError::Io {
            chip: shared.chip.clone(),
            op: IoOp::ForceInactive,
            source,
        })
    }
}

// ----------------------------------------------------------------------------------------------
// Event side
// ----------------------------------------------------------------------------------------------

/// The event thread's side: the input request's edge events, as [`InputEdge`]s.
#[derive(Debug)]
pub struct GpioEdges {
    chip: Arc<str>,
    request: Arc<Request>,
    /// Raw kernel events, read in place.
    buf: Box<[u64]>,
    /// The size of one event in `buf`.
    event_words: usize,
    map: EdgeMap,
}

impl GpioEdges {
    fn new(chip: Arc<str>, request: Arc<Request>, map: EdgeMap, capacity: usize) -> GpioEdges {
        let event_words = request.edge_event_u64_size();
        let buf = vec![0; event_words * capacity.max(1)].into_boxed_slice();
        GpioEdges { chip, request, buf, event_words, map }
    }

    /// The input request's fd, readable when edge events are waiting (for epoll).
    pub fn as_fd(&self) -> BorrowedFd<'_> {
        self.request.as_fd()
    }

    /// Reads every edge event available now and hands each to `on_edge`, in the kernel's order.
    /// Call it when the fd is readable: the first read does not check and would block on an
    /// empty FIFO; later reads happen only if the buffer came back full and more are waiting.
    /// No allocation.
    ///
    /// Returns the number of edges handed on. Edges the kernel dropped (its FIFO overflowed)
    /// are added to [`GpioEdges::lost_edges`]; compare it before and after to log them.
    pub fn read(&mut self, on_edge: &mut impl FnMut(InputEdge)) -> Result<usize, GpioError> {
        let error = |op, source| GpioError::Io { chip: self.chip.clone(), op, source };
        let mut delivered = 0;
        loop {
            let words = self
                .request
                .read_edge_events_into_slice(&mut self.buf)
                .map_err(|e| error(IoOp::ReadEdges, e))?;
            for raw in self.buf[..words].chunks_exact(self.event_words) {
                let event = self
                    .request
                    .edge_event_from_slice(raw)
                    .map_err(|e| error(IoOp::ReadEdges, e))?;
                if let Some(edge) = self.map.edge(&event) {
                    on_edge(edge);
                    delivered += 1;
                }
            }
            if words < self.buf.len() {
                break;
            }
            if !self.request.has_edge_event().map_err(|e| error(IoOp::ReadEdges, e))? {
                break;
            }
        }
        Ok(delivered)
    }

    /// Edges the kernel dropped since open, known from gaps in the line sequence numbers.
    pub fn lost_edges(&self) -> u64 {
        self.map.lost
    }
}

/// Turns kernel edge events into [`InputEdge`]s and watches their sequence numbers. Pure.
#[derive(Debug, Clone, PartialEq, Eq)]
struct EdgeMap {
    /// (line offset, contact) of each edge-detecting line.
    lines: Box<[(u32, u8)]>,
    /// The last line sequence number seen per contact; the kernel counts from 0, so the first
    /// event is 1.
    last_seqno: [u32; CONTACTS],
    lost: u64,
}

impl EdgeMap {
    fn new(inputs: &[InputPlan]) -> EdgeMap {
        EdgeMap {
            lines: inputs.iter().filter_map(|i| i.edge.map(|(c, _)| (i.line.offset, c))).collect(),
            last_seqno: [0; CONTACTS],
            lost: 0,
        }
    }

    /// The edge an event reports, counting the events lost before it on its line. `None` for
    /// a line that does not detect edges (the kernel never sends one).
    fn edge(&mut self, event: &EdgeEvent) -> Option<InputEdge> {
        let &(_, contact) = self.lines.iter().find(|(offset, _)| *offset == event.offset)?;
        let last = self.last_seqno.get_mut(contact as usize)?;
        match check_seq(*last, event.line_seqno) {
            Seq::InOrder { lost } => {
                *last = event.line_seqno;
                self.lost = self.lost.saturating_add(u64::from(lost));
            }
            // Still an edge the kernel saw; just not one that moves the sequence on.
            Seq::Stale => {}
        }
        Some(InputEdge {
            contact,
            rising: event.kind == EdgeKind::Rising,
            stamp_ns: event.timestamp_ns,
        })
    }
}

/// Where a sequence number stands against the last one seen on its line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Seq {
    /// Newer than `last`; `lost` events were dropped in between.
    InOrder { lost: u32 },
    /// Not newer than `last` (a repeat, or older): nothing to count.
    Stale,
}

/// Checks a line sequence number against the last one seen (0 before the first event: the
/// kernel's numbering starts at 1). The numbers are u32 and wrap; a step of more than half the
/// range is taken as going backwards.
fn check_seq(last: u32, seqno: u32) -> Seq {
    let step = seqno.wrapping_sub(last);
    if step == 0 || step > u32::MAX / 2 {
        Seq::Stale
    } else {
        Seq::InOrder { lost: step - 1 }
    }
}

// The scan, event and watchdog threads each own one part; the watchdog's is shared.
const _: fn() = || {
    fn send<T: Send>() {}
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Request>();
    send_sync::<GpioOutputs>();
    send::<GpioIo>();
    send::<GpioEdges>();
    send::<GpioError>();
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Backend;

    fn addr(s: &str) -> Address {
        Address::parse(s).unwrap()
    }

    fn line(device: &str, line: u32) -> IoLine {
        IoLine {
            device: addr(device),
            line,
            active_low: false,
            bias: Bias::Disabled,
            debounce_us: 0,
        }
    }

    fn config(inputs: Vec<IoLine>, outputs: Vec<IoLine>) -> IoConfig {
        IoConfig {
            backend: Backend::Gpiocdev,
            chip: Some("gpiochip0".into()),
            inputs,
            outputs,
            ..IoConfig::default()
        }
    }

    fn switch(line: u32) -> SwitchConfig {
        SwitchConfig { line: Some(line), ..SwitchConfig::default() }
    }

    fn bit(device: &str) -> InputSlot {
        InputSlot::Bit { device: addr(device), bit: ImageBit::of(&addr(device)).unwrap() }
    }

    fn values(offsets: &[u32], active: &[u32]) -> Values {
        let mut values = Values::from_offsets(offsets);
        for &offset in active {
            values.set(offset, Value::Active);
        }
        values
    }

    fn event(offset: u32, line_seqno: u32, kind: EdgeKind, timestamp_ns: u64) -> EdgeEvent {
        EdgeEvent { timestamp_ns, kind, offset, seqno: line_seqno, line_seqno }
    }

    // --- plan ---

    #[test]
    fn image_bits_of_p_devices() {
        assert_eq!(ImageBit::of(&addr("P0000")).unwrap(), ImageBit { word: 0, mask: 1 });
        assert_eq!(ImageBit::of(&addr("P0040")).unwrap(), ImageBit { word: 4, mask: 1 });
        assert_eq!(ImageBit::of(&addr("P000F")).unwrap(), ImageBit { word: 0, mask: 0x8000 });
        assert_eq!(ImageBit::of(&addr("P127F")).unwrap(), ImageBit { word: 127, mask: 0x8000 });
        assert!(matches!(ImageBit::of(&addr("M0000")), Err(GpioError::NotAPBit { .. })));
        assert!(matches!(ImageBit::of(&addr("P004")), Err(GpioError::NotAPBit { .. })));
    }

    #[test]
    fn contacts_are_p0000_to_p0007() {
        assert_eq!(contact_of(&addr("P0000")), Some(0));
        assert_eq!(contact_of(&addr("P0007")), Some(7));
        assert_eq!(contact_of(&addr("P0008")), None);
        assert_eq!(contact_of(&addr("P0010")), None);
        assert_eq!(contact_of(&addr("M0000")), None);
        assert_eq!(contact_device(3), addr("P0003"));
    }

    #[test]
    fn edges_of_several_tasks_on_one_contact_merge() {
        assert_eq!(merge_edge(Edge::Rising, Edge::Rising), Edge::Rising);
        assert_eq!(merge_edge(Edge::Rising, Edge::Falling), Edge::Both);
        assert_eq!(merge_edge(Edge::Falling, Edge::Both), Edge::Both);
        let edges = contact_edges(&[
            (0, Edge::Rising),
            (2, Edge::Falling),
            (0, Edge::Falling),
            (2, Edge::Falling),
            (5, Edge::Both),
            (5, Edge::Rising),
        ])
        .unwrap();
        assert_eq!(
            edges,
            [Some(Edge::Both), None, Some(Edge::Falling), None, None, Some(Edge::Both), None, None]
        );
        assert!(matches!(
            contact_edges(&[(8, Edge::Rising)]),
            Err(GpioError::NotAContact { contact: 8 })
        ));
    }

    #[test]
    fn lines_are_sorted_by_offset_with_their_bits() {
        let cfg = config(
            vec![line("P0001", 9), line("P0000", 2), line("P0023", 5)],
            vec![line("P0041", 7), line("P0040", 3)],
        );
        let plan = Plan::new(&cfg, None, &[]).unwrap();
        let inputs: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.slot)).collect();
        let at = |device: &str, word, mask| InputSlot::Bit {
            device: addr(device),
            bit: ImageBit { word, mask },
        };
        assert_eq!(
            inputs,
            [(2, at("P0000", 0, 1)), (5, at("P0023", 2, 1 << 3)), (9, at("P0001", 0, 1 << 1))]
        );
        let outputs: Vec<_> = plan.outputs.iter().map(|o| (o.line.line, o.bit)).collect();
        assert_eq!(
            outputs,
            [(3, ImageBit { word: 4, mask: 1 }), (7, ImageBit { word: 4, mask: 1 << 1 })]
        );
        assert_eq!(plan.edge_lines(), 0);
    }

    #[test]
    fn edge_detection_only_on_task_contacts() {
        let cfg = config(
            vec![line("P0000", 10), line("P0001", 11), line("P0002", 12), line("P0008", 13)],
            vec![],
        );
        let plan =
            Plan::new(&cfg, None, &[(2, Edge::Rising), (0, Edge::Falling), (2, Edge::Falling)])
                .unwrap();
        let edges: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.edge)).collect();
        assert_eq!(
            edges,
            [(10, Some((0, Edge::Falling))), (11, None), (12, Some((2, Edge::Both))), (13, None)]
        );
        assert_eq!(plan.edge_lines(), 2);
        let map = EdgeMap::new(&plan.inputs);
        assert_eq!(&*map.lines, &[(10, 0), (12, 2)]);
    }

    #[test]
    fn a_task_contact_must_be_an_input_line() {
        let cfg = config(vec![line("P0000", 1)], vec![line("P0003", 2)]);
        let err = Plan::new(&cfg, None, &[(3, Edge::Rising)]).unwrap_err();
        assert!(matches!(err, GpioError::ContactNotWired { device } if device == addr("P0003")));
        assert_eq!(
            err.to_string(),
            "an I/O task starts on P0003, but P0003 is not an [[io.input]] line"
        );
    }

    #[test]
    fn a_line_is_wired_once() {
        let cfg = config(vec![line("P0000", 4)], vec![line("P0040", 4)]);
        let err = Plan::new(&cfg, None, &[]).unwrap_err();
        assert_eq!(err.to_string(), "line 4 is wired to both P0000 and P0040");
        let cfg = config(vec![line("P0000", 4)], vec![line("P0040", 5)]);
        let err = Plan::new(&cfg, Some(&switch(5)), &[]).unwrap_err();
        assert_eq!(err.to_string(), "line 5 is wired to both P0040 and the RUN/STOP switch");
    }

    #[test]
    fn the_switch_is_an_input_line_without_a_bit_or_an_edge() {
        let cfg = config(vec![line("P0000", 10), line("P0001", 2)], vec![line("P0040", 3)]);
        let mut sw = switch(6);
        sw.active_low = true;
        sw.bias = Bias::PullUp;
        sw.debounce_us = 5_000;
        let plan = Plan::new(&cfg, Some(&sw), &[(0, Edge::Both)]).unwrap();
        let inputs: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.slot, i.edge)).collect();
        assert_eq!(
            inputs,
            [
                (2, bit("P0001"), None),
                (6, InputSlot::Switch, None),
                (10, bit("P0000"), Some((0, Edge::Both))),
            ]
        );
        let settings = plan.inputs[1].line;
        assert_eq!(
            settings,
            InputLine { offset: 6, active_low: true, bias: Bias::PullUp, debounce_us: 5_000 }
        );
        assert!(plan.has_switch());
        assert_eq!(plan.edge_lines(), 1);
        assert_eq!(EdgeMap::new(&plan.inputs).lines.as_ref(), &[(10, 0)]);
        let lines: Vec<_> = plan.lines().collect();
        assert_eq!(
            lines,
            [
                (2, Wire::Device(addr("P0001"))),
                (6, Wire::Switch),
                (10, Wire::Device(addr("P0000"))),
                (3, Wire::Device(addr("P0040"))),
            ]
        );
        // A switch alone is an input request of one line.
        let plan = Plan::new(&config(vec![], vec![]), Some(&switch(0)), &[]).unwrap();
        assert_eq!(plan.inputs.len(), 1);
        assert!(!Plan::new(&config(vec![], vec![]), None, &[]).unwrap().has_switch());
    }

    #[test]
    fn a_switch_needs_a_line() {
        let err =
            Plan::new(&config(vec![], vec![]), Some(&SwitchConfig::default()), &[]).unwrap_err();
        assert!(matches!(err, GpioError::SwitchNotWired), "{err:?}");
        assert_eq!(
            err.to_string(),
            "[switch] has no line: the gpiocdev backend reads the RUN/STOP switch from a line"
        );
    }

    #[test]
    fn a_request_holds_at_most_64_lines() {
        let inputs: Vec<_> =
            (0..65).map(|n| line(&format!("P{:03}{:X}", 10 + n / 16, n % 16), n)).collect();
        assert!(Plan::new(&config(inputs[..64].to_vec(), vec![]), None, &[]).is_ok());
        let err =
            Plan::new(&config(inputs[..64].to_vec(), vec![]), Some(&switch(100)), &[]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "65 input lines configured, but one GPIO line request holds at most 64",
            "the switch's line is one of them"
        );
        let err = Plan::new(&config(inputs, vec![]), None, &[]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "65 input lines configured, but one GPIO line request holds at most 64"
        );
    }

    #[test]
    fn distinct_settings_are_counted_like_the_kernel() {
        let mut inputs = Vec::new();
        // Line settings: 2 active levels × 3 biases = 6 flag combinations (5 beyond the first).
        for (n, (active_low, bias)) in [false, true]
            .into_iter()
            .flat_map(|a| [Bias::Disabled, Bias::PullUp, Bias::PullDown].map(|b| (a, b)))
            .enumerate()
        {
            let mut l = line(&format!("P010{n:X}"), n as u32);
            l.active_low = active_low;
            l.bias = bias;
            inputs.push(l);
        }
        // Five debounce periods, one of them twice: 5 more.
        for (n, us) in [100, 200, 300, 400, 500, 500].into_iter().enumerate() {
            let mut l = line(&format!("P011{n:X}"), 20 + n as u32);
            l.debounce_us = us;
            inputs.push(l);
        }
        let plan = Plan::new(&config(inputs.clone(), vec![]), None, &[]).unwrap();
        assert_eq!(extra_settings(&plan.inputs), 10);
        // The switch's settings count like any line's: its flags are among the above, its
        // debounce period (by default 10 ms) is new.
        let plan = Plan::new(&config(inputs.clone(), vec![]), Some(&switch(50)), &[]);
        assert!(matches!(plan, Err(GpioError::TooManySettings { needed: 11, max: 10, .. })));
        let quiet = SwitchConfig { debounce_us: 500, ..switch(50) };
        let plan = Plan::new(&config(inputs.clone(), vec![]), Some(&quiet), &[]).unwrap();
        assert_eq!(extra_settings(&plan.inputs), 10);

        // An edge on a contact is one more flag combination: 11 is too many.
        inputs.push(line("P0000", 40));
        assert_eq!(
            extra_settings(&Plan::new(&config(inputs.clone(), vec![]), None, &[]).unwrap().inputs),
            10
        );
        let err = Plan::new(&config(inputs, vec![]), None, &[(0, Edge::Rising)]).unwrap_err();
        assert!(matches!(err, GpioError::TooManySettings { needed: 11, max: 10, .. }));
    }

    // --- refresh mapping ---

    #[test]
    fn inputs_write_their_bits_only() {
        let cfg = config(vec![line("P0001", 9), line("P0000", 2), line("P0023", 5)], vec![]);
        let plan = Plan::new(&cfg, None, &[]).unwrap();
        let slots: Vec<_> = plan.inputs.iter().map(|i| i.slot).collect();
        let mut image = [0u16; P_WORDS as usize];
        image[0] = 0b1000_0001; // P0000 (an input, will go OFF) and P0007 (not an input)
        image[4] = 1; // P0040, an output
        let switch = apply_inputs(&mut image, &slots, &values(&[2, 5, 9], &[5, 9]));
        assert_eq!(image[0], 0b1000_0010);
        assert_eq!(image[2], 0b1000);
        assert_eq!(image[4], 1);
        assert_eq!(switch, None);
    }

    #[test]
    fn the_switch_line_is_read_with_the_inputs_into_no_bit() {
        let cfg = config(vec![line("P0001", 9), line("P0000", 2)], vec![]);
        let plan = Plan::new(&cfg, Some(&switch(4)), &[]).unwrap();
        let slots: Vec<_> = plan.inputs.iter().map(|i| i.slot).collect();
        let mut image = [0u16; P_WORDS as usize];
        let active = values(&[2, 4, 9], &[4]);
        assert_eq!(apply_inputs(&mut image, &slots, &active), Some(SwitchPosition::Run));
        assert_eq!(switch_position(&slots, &active), Some(SwitchPosition::Run));
        assert!(image.iter().all(|&w| w == 0), "no P bit for the switch: {:?}", &image[..1]);
        let inactive = values(&[2, 4, 9], &[2, 9]);
        assert_eq!(apply_inputs(&mut image, &slots, &inactive), Some(SwitchPosition::Stop));
        assert_eq!(switch_position(&slots, &inactive), Some(SwitchPosition::Stop));
        assert_eq!(image[0], 0b11);
        assert_eq!(switch_position(&slots[..0], &values(&[], &[])), None);
    }

    #[test]
    fn outputs_take_their_bits() {
        let cfg = config(vec![], vec![line("P0041", 7), line("P0040", 3), line("P127F", 1)]);
        let plan = Plan::new(&cfg, None, &[]).unwrap();
        let bits: Vec<_> = plan.outputs.iter().map(|o| o.bit).collect();
        let mut image = [0u16; P_WORDS as usize];
        image[4] = 0b10;
        image[127] = 0x8000;
        let mut v = values(&[1, 3, 7], &[3]);
        collect_outputs(&image, &bits, &mut v);
        assert_eq!(v.get(1), Some(Value::Active));
        assert_eq!(v.get(3), Some(Value::Inactive));
        assert_eq!(v.get(7), Some(Value::Active));
    }

    // --- edge events ---

    #[test]
    fn sequence_numbers() {
        // The first event of a line is 1.
        assert_eq!(check_seq(0, 1), Seq::InOrder { lost: 0 });
        // The FIFO overflowed before the first read.
        assert_eq!(check_seq(0, 4), Seq::InOrder { lost: 3 });
        assert_eq!(check_seq(7, 8), Seq::InOrder { lost: 0 });
        assert_eq!(check_seq(7, 10), Seq::InOrder { lost: 2 });
        // Wrapping around u32.
        assert_eq!(check_seq(u32::MAX, 0), Seq::InOrder { lost: 0 });
        assert_eq!(check_seq(u32::MAX - 1, 1), Seq::InOrder { lost: 2 });
        // A repeat or an older number.
        assert_eq!(check_seq(7, 7), Seq::Stale);
        assert_eq!(check_seq(7, 6), Seq::Stale);
        assert_eq!(check_seq(1, u32::MAX), Seq::Stale);
    }

    #[test]
    fn events_become_input_edges_and_gaps_count_per_line() {
        let cfg = config(vec![line("P0000", 10), line("P0002", 12), line("P0010", 3)], vec![]);
        let plan = Plan::new(&cfg, None, &[(0, Edge::Both), (2, Edge::Rising)]).unwrap();
        let mut map = EdgeMap::new(&plan.inputs);

        let edge = map.edge(&event(10, 1, EdgeKind::Rising, 1_000)).unwrap();
        assert_eq!(edge, InputEdge { contact: 0, rising: true, stamp_ns: 1_000 });
        let edge = map.edge(&event(10, 2, EdgeKind::Falling, 2_000)).unwrap();
        assert_eq!(edge, InputEdge { contact: 0, rising: false, stamp_ns: 2_000 });
        assert_eq!(map.lost, 0);

        // Line 12 starts its own count: its first event is not a gap after line 10's.
        map.edge(&event(12, 1, EdgeKind::Rising, 3_000)).unwrap();
        assert_eq!(map.lost, 0);
        // Two of line 12's edges were dropped.
        let edge = map.edge(&event(12, 4, EdgeKind::Rising, 4_000)).unwrap();
        assert_eq!(edge.contact, 2);
        assert_eq!(map.lost, 2);
        // A late event of line 10 is still delivered, and counts nothing.
        assert!(map.edge(&event(10, 2, EdgeKind::Falling, 2_500)).is_some());
        assert_eq!(map.lost, 2);
        // A line without edge detection, or unknown: nothing.
        assert_eq!(map.edge(&event(3, 1, EdgeKind::Rising, 5_000)), None);
        assert_eq!(map.last_seqno, [2, 0, 4, 0, 0, 0, 0, 0]);
    }

    // --- opening, without GPIO hardware ---

    #[test]
    fn a_chip_is_required() {
        let mut cfg = config(vec![line("P0000", 1)], vec![]);
        cfg.chip = None;
        assert!(matches!(open(&cfg, None, &[], "plcd"), Err(GpioError::NoChip)));
    }

    #[test]
    fn a_missing_chip_path_names_what_was_asked() {
        let mut cfg = config(vec![line("P0000", 1)], vec![line("P0040", 2)]);
        cfg.chip = Some("/dev/gpiochip-does-not-exist".into());
        let err = open(&cfg, None, &[(0, Edge::Rising)], "plcd").unwrap_err();
        let GpioError::ChipNotFound { asked, .. } = &err else { panic!("{err:?}") };
        assert_eq!(asked, "/dev/gpiochip-does-not-exist");
        assert!(err
            .to_string()
            .starts_with("GPIO chip `/dev/gpiochip-does-not-exist` not found; "));
    }

    #[test]
    fn a_label_that_matches_no_chip_names_what_was_asked() {
        let mut cfg = config(vec![line("P0000", 1)], vec![]);
        cfg.chip = Some("plcd-no-such-chip-label".into());
        let err = open(&cfg, None, &[], "plcd").unwrap_err();
        let GpioError::ChipNotFound { asked, .. } = &err else { panic!("{err:?}") };
        assert_eq!(asked, "plcd-no-such-chip-label");
        assert!(err.to_string().starts_with("GPIO chip `plcd-no-such-chip-label` not found; "));
    }

    #[test]
    fn a_path_that_is_not_a_chip_is_an_open_error() {
        let mut cfg = config(vec![line("P0000", 1)], vec![]);
        cfg.chip = Some("/dev/null".into());
        let err = open(&cfg, None, &[], "plcd").unwrap_err();
        assert!(
            matches!(&err, GpioError::ChipOpen { chip, .. } if &**chip == "/dev/null"),
            "{err:?}"
        );
        assert!(err.to_string().starts_with("cannot open GPIO chip `/dev/null`: "), "{err}");
    }

    #[test]
    fn config_errors_come_before_the_chip() {
        let mut cfg = config(vec![line("P0001", 1)], vec![]);
        cfg.chip = Some("/dev/gpiochip-does-not-exist".into());
        let err = open(&cfg, None, &[(0, Edge::Rising)], "plcd").unwrap_err();
        assert!(matches!(err, GpioError::ContactNotWired { .. }), "{err:?}");
        let err = open(&cfg, Some(&switch(1)), &[], "plcd").unwrap_err();
        assert!(matches!(err, GpioError::DuplicateLine { .. }), "{err:?}");
    }

    #[test]
    fn messages_read_well_in_a_log() {
        let chips = vec![
            ChipSummary { name: "gpiochip0".into(), label: Some("pinctrl-bcm2711".into()) },
            ChipSummary { name: "gpiochip1".into(), label: None },
            ChipSummary { name: "gpiochip2".into(), label: Some(String::new()) },
        ];
        let err = GpioError::ChipNotFound { asked: "gpio-sim.0".into(), available: chips };
        assert_eq!(
            err.to_string(),
            "GPIO chip `gpio-sim.0` not found; chips on this system: gpiochip0 (pinctrl-bcm2711), \
             gpiochip1 (label unreadable), gpiochip2 (no label)"
        );
        let err = GpioError::ChipNotFound { asked: "/dev/gpiochip0".into(), available: vec![] };
        assert_eq!(
            err.to_string(),
            "GPIO chip `/dev/gpiochip0` not found; this system has no GPIO chips"
        );
        let chip: Arc<str> = "gpiochip0 (pinctrl-bcm2711)".into();
        let err = GpioError::LineOutOfRange {
            chip: chip.clone(),
            line: 58,
            wire: Wire::Device(addr("P0040")),
            num_lines: 58,
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 58 (P0040) does not exist, the chip has \
             58 lines"
        );
        let err = GpioError::LineBusy {
            chip: chip.clone(),
            line: 4,
            wire: Wire::Device(addr("P0003")),
            consumer: Some("gpio-keys".into()),
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 4 (P0003) is already in use by `gpio-keys`"
        );
        let err = GpioError::LineBusy {
            chip: chip.clone(),
            line: 4,
            wire: Wire::Device(addr("P0003")),
            consumer: None,
        };
        assert!(err.to_string().ends_with("is already in use by another consumer"));
        let err = GpioError::LineBusy {
            chip: chip.clone(),
            line: 5,
            wire: Wire::Switch,
            consumer: Some("gpio-keys".into()),
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 5 (the RUN/STOP switch) is already in use \
             by `gpio-keys`"
        );
        let err = GpioError::LineOutOfRange {
            chip: chip.clone(),
            line: 58,
            wire: Wire::Switch,
            num_lines: 58,
        };
        assert_eq!(
            err.to_string(),
            "GPIO chip gpiochip0 (pinctrl-bcm2711): line 58 (the RUN/STOP switch) does not exist, \
             the chip has 58 lines"
        );
        let err = GpioError::Io {
            chip,
            op: IoOp::ReadInputs,
            source: std::io::Error::from_raw_os_error(libc::ENODEV).into(),
        };
        assert!(err
            .to_string()
            .starts_with("GPIO chip gpiochip0 (pinctrl-bcm2711): reading the inputs failed: "));
        assert!(std::error::Error::source(&err).is_some());
    }

    #[test]
    fn errno_of_a_gpiocdev_error() {
        let busy: gpiocdev::Error = std::io::Error::from_raw_os_error(libc::EBUSY).into();
        assert!(is_errno(&busy, libc::EBUSY));
        assert!(!is_errno(&busy, libc::ENOENT));
        assert!(!is_errno(&gpiocdev::Error::NoGpioChips(), libc::EBUSY));
    }

    #[test]
    fn no_outputs_means_nothing_to_force() {
        assert!(GpioOutputs { shared: None }.set_all_inactive().is_ok());
    }
}
