//! The wiring plan of the gpiocdev backend: how `[[io.input]]`, `[[io.output]]`, `[switch]`
//! and the io tasks' contacts map onto the two GPIO line requests, the kernel's limits
//! included.
//!
//! A plan is pure data: which line offset is which P bit (or the key switch), with which
//! settings, in which request, and which lines detect which edges. `plcd check` checks the
//! kernel's limits while it validates a gpiocdev config (`check`, every violation located and
//! reported with the rest), and `plcd run` builds the plan from the validated config
//! ([`Config::wiring`]) and hands it to the backend, which only applies it to a chip. So a
//! config `plcd check` accepts never fails at `plcd run` for a reason the config alone shows;
//! what is left for `plcd run` needs the hardware (the chip, its line count and line names, who
//! holds a line, the driver's support for a setting).
//!
//! A line is an offset or a name ([`LineRef`]). The limits depend on how many lines there are
//! and with which settings, never on which offsets, so `plcd check` checks them without the
//! chip. A name becomes an offset only on the chip: `plcd run` reads the names of the chip's
//! lines and [`Config::wiring`] looks each name up among them ([`names`]) before it builds the
//! plan, and then checks what the config could not: that every name is there and on one line
//! only, and that no two entries (a name and an offset, or two names of one line) are the same
//! line. Every rule about offsets then holds for the resolved ones.
//!
//! The rules each key obeys on its own, which every backend shares, are checked where the key
//! is (the `io`, `switch` and `task` modules): devices are P bits, lines (as written) and
//! devices are unique across inputs, outputs and the switch, a gpiocdev switch has a line, an
//! io task's contact is an input line. The plan relies on them.

pub mod names;

use std::fmt;

use super::{Bias, Config, Edge, IoConfig, LineRef, Sink, SwitchConfig, TaskConfig, TaskKind};
use crate::device::{Address, Area};
pub use names::{NameHint, NEAR_NAMES_MAX};

/// The most lines one line request holds: `GPIO_V2_LINES_MAX` of the kernel's GPIO uAPI v2
/// (`include/uapi/linux/gpio.h`), which gpiocdev checks as `gpiocdev_uapi::NUM_LINES_MAX`.
/// The switch's line is one of the inputs.
pub const GPIO_V2_LINES_MAX: usize = 64;

/// The most attributes a line request's config carries: `GPIO_V2_LINE_NUM_ATTRS_MAX` of the
/// GPIO uAPI v2 (`struct gpio_v2_line_config`), `gpiocdev_uapi::v2::NUM_ATTRS_MAX`. The most
/// common flag combination is the request's default and takes none; every other distinct
/// combination of flags (direction, active-low, bias, edges) takes one, and so does every
/// distinct debounce period (gpiocdev's `Config::to_v2` counts them so).
pub const GPIO_V2_LINE_NUM_ATTRS_MAX: usize = 10;

/// The contacts P0000–P0007 that io tasks start on.
pub const CONTACTS: usize = 8;

/// A bit of the P image: `mem.io_image()[word] & mask`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageBit {
    pub word: u16,
    pub mask: u16,
}

impl ImageBit {
    /// The image bit of a P bit device; `None` for any other device (which the validator
    /// refuses).
    pub fn of(device: &Address) -> Option<ImageBit> {
        match (device.area, device.bit) {
            (Area::P, Some(bit)) if device.number < crate::device::layout::P_WORDS && bit < 16 => {
                Some(ImageBit { word: device.number as u16, mask: 1 << bit })
            }
            _ => None,
        }
    }
}

/// Where a device that is no P bit would go: nowhere (no word, no bit).
const NO_BIT: ImageBit = ImageBit { word: u16::MAX, mask: 0 };

/// An input line's offset and settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InputLine {
    pub offset: u32,
    pub active_low: bool,
    pub bias: Bias,
    /// 0: no debounce.
    pub debounce_us: u32,
}

/// Where an input line's value goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputSlot {
    /// A P bit: the device, and its place in the image.
    Bit { device: Address, bit: ImageBit },
    /// The key switch: no P bit; active is RUN.
    Switch,
}

/// One line of the input request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InputWire {
    pub line: InputLine,
    pub slot: InputSlot,
    /// The contact and the edges its tasks need, if any task starts on this line (never the
    /// switch).
    pub edge: Option<(u8, Edge)>,
}

impl InputWire {
    /// What the line is wired to, as messages name it.
    pub fn wire(&self) -> Wire {
        match self.slot {
            InputSlot::Bit { device, .. } => Wire::Device(device),
            InputSlot::Switch => Wire::Switch,
        }
    }
}

/// An output line's offset and settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputLine {
    pub offset: u32,
    pub active_low: bool,
}

/// One line of the output request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputWire {
    pub device: Address,
    pub line: OutputLine,
    pub bit: ImageBit,
}

/// The lines of both requests, each sorted by offset: that is the order of the kernel's
/// bitmaps and of gpiocdev's `Values`, so a refresh walks both side by side. The key switch's
/// line, if any, is among the inputs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Wiring {
    pub inputs: Vec<InputWire>,
    pub outputs: Vec<OutputWire>,
}

/// What a line is wired to, as messages name it.
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

/// An entry of the config that wires a line, as the errors of [`Config::wiring`] name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Entry {
    /// An `[[io.input]]`, by its device.
    Input(Address),
    /// An `[[io.output]]`, by its device.
    Output(Address),
    /// `[switch]`.
    Switch,
}

impl Entry {
    /// What the entry's line is wired to.
    pub fn wire(self) -> Wire {
        match self {
            Entry::Input(device) | Entry::Output(device) => Wire::Device(device),
            Entry::Switch => Wire::Switch,
        }
    }
}

/// As `plcd check` names entries: `io.input "P0000"`, `io.output "P0040"`, `[switch]`.
impl fmt::Display for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Entry::Input(device) => write!(f, "io.input \"{device}\""),
            Entry::Output(device) => write!(f, "io.output \"{device}\""),
            Entry::Switch => f.write_str("[switch]"),
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

/// Why a plan cannot be made: a request the kernel would refuse (`at` is the line that does not
/// fit: the first one past the limit, counting the inputs in file order and the switch's line
/// last), or a line name the chip does not resolve to one line of its own.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WiringError {
    #[error("{entry}: no line of the chip is named {name:?}; {hint}")]
    NoSuchName { entry: Entry, name: String, hint: NameHint },

    #[error(
        "{entry}: line name {name:?} is shared by lines {} of the chip: give the line's offset \
         instead",
        Offsets(.offsets)
    )]
    SharedName { entry: Entry, name: String, offsets: Vec<u32> },

    #[error(
        "{} (line {}) and {} (line {}) are the same line, offset {offset} of the chip",
        .second.0, .second.1, .first.0, .first.1
    )]
    SameLine { offset: u32, first: (Entry, LineRef), second: (Entry, LineRef) },

    #[error("{count} {direction} lines configured, but one GPIO line request holds at most {max}")]
    TooManyLines { direction: LineDirection, count: usize, max: usize, at: Wire },

    #[error(
        "the {direction} lines need {needed} distinct line settings (combinations of active_low, \
         bias and edge, and debounce periods) besides the most common one; the kernel takes at \
         most {max} per request"
    )]
    TooManySettings { direction: LineDirection, needed: usize, max: usize, at: Wire },
}

impl WiringError {
    /// The line the error is reported at.
    pub fn at(&self) -> Wire {
        match self {
            WiringError::TooManyLines { at, .. } | WiringError::TooManySettings { at, .. } => *at,
            WiringError::NoSuchName { entry, .. } | WiringError::SharedName { entry, .. } => {
                entry.wire()
            }
            WiringError::SameLine { second, .. } => second.0.wire(),
        }
    }
}

/// Offsets as a list: `33, 37 and 50`.
struct Offsets<'a>(&'a [u32]);

impl fmt::Display for Offsets<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, offset) in self.0.iter().enumerate() {
            match i {
                0 => {}
                _ if i + 1 == self.0.len() => f.write_str(" and ")?,
                _ => f.write_str(", ")?,
            }
            write!(f, "{offset}")?;
        }
        Ok(())
    }
}

impl Config {
    /// Whether a `line` of `[[io.input]]`, `[[io.output]]` or `[switch]` is a name: then the
    /// plan needs the names of the chip's lines.
    pub fn uses_line_names(&self) -> bool {
        let io = self.io.inputs.iter().chain(&self.io.outputs).map(|l| &l.line);
        let switch = self.switch.iter().filter_map(|s| s.line.as_ref());
        io.chain(switch).any(|line| line.name().is_some())
    }

    /// The gpiocdev backend's plan for this config's `[io]` lines, `[switch]` and io tasks, on
    /// a chip whose lines are named `chip_names` (by offset; `""` for a line without a name).
    /// Every name is looked up there first; the names of the chip are needed only when
    /// [`Config::uses_line_names`], and `&[]` will do otherwise.
    ///
    /// Errors: a name no line of the chip has, or several have, or two entries that are one
    /// line once their names are resolved (all of these only a chip can show), and the limits
    /// of the kernel, which for a gpiocdev config that [`super::parse`] returned hold already
    /// (parsing reported them).
    pub fn wiring(&self, chip_names: &[String]) -> Result<Wiring, Vec<WiringError>> {
        Wiring::new(&self.io, self.switch.as_ref(), &edge_contacts(&self.tasks), chip_names)
    }
}

/// The contacts (0..=7 for P0000..=P0007) that io tasks start on, with the edge each task
/// wants, in task order.
pub(super) fn edge_contacts(tasks: &[TaskConfig]) -> Vec<(u8, Edge)> {
    tasks
        .iter()
        .filter_map(|t| match &t.kind {
            TaskKind::Io { contact, edge } => Some((contact.bit.unwrap_or(0), *edge)),
            _ => None,
        })
        .collect()
}

/// Where a wired entry of the config is, for [`check`]'s diagnostics.
#[derive(Debug, Clone)]
pub(super) struct Place {
    /// The byte offset to report at.
    pub at: usize,
    /// What the entry is called (`io.input "P0000"`, `[switch]`).
    pub subject: String,
}

/// Pass 2 of a gpiocdev config: builds the plan of what validated and reports every limit it
/// exceeds, at the first line past the limit. `inputs` and `outputs` are where the entries of
/// `io` are, in its order; `switch` is the validated `[switch]` and where its line is.
///
/// What did not validate is left out (a section with errors, or every io task when one has
/// errors): that never makes a request look bigger than it is, so nothing is reported that
/// the complete config would not have; what it hides is reported once the rest is fixed.
pub(super) fn check(
    sink: &mut Sink,
    io: &IoConfig,
    places: (&[Place], &[Place]),
    switch: Option<(&SwitchConfig, Place)>,
    tasks: &[TaskConfig],
) {
    let errors =
        limits(io, switch.as_ref().map(|(s, _)| *s), &contact_edges(&edge_contacts(tasks)));
    let (inputs, outputs) = places;
    for error in errors {
        let place = match error.at() {
            Wire::Switch => switch.as_ref().map(|(_, place)| place),
            Wire::Device(device) => {
                let input = io.inputs.iter().position(|l| l.device == device);
                let output = io.outputs.iter().position(|l| l.device == device);
                input.and_then(|i| inputs.get(i)).or_else(|| output.and_then(|i| outputs.get(i)))
            }
        };
        if let Some(place) = place {
            sink.error(place.at, format!("{}: {error}", place.subject));
        }
    }
}

impl Wiring {
    /// The plan, or every error that prevents it.
    ///
    /// `chip_names`: the names of the chip's lines by offset, where each name is looked up.
    /// `switch`'s line (if set) is one more input, with the switch's own settings, mapped to
    /// no P bit and detecting no edge. `edge_contacts`: the contacts io tasks start on and the
    /// edge each needs; several tasks on one contact merge, and edge detection is enabled only
    /// on those input lines. The per-key rules are the validator's (see the module doc): a
    /// device that is no P bit maps to no image bit, a contact that is no input line to no line.
    fn new(
        io: &IoConfig,
        switch: Option<&SwitchConfig>,
        edge_contacts: &[(u8, Edge)],
        chip_names: &[String],
    ) -> Result<Wiring, Vec<WiringError>> {
        let edges = contact_edges(edge_contacts);
        let switch = switch.and_then(|s| Some((s, s.line.as_ref()?)));

        // Every line's offset, in file order (the switch last); a name the chip does not
        // resolve is an error and no offset.
        let mut errors = Vec::new();
        let mut resolve = |entry: Entry, line: &LineRef| match line {
            LineRef::Offset(offset) => Some(*offset),
            LineRef::Name(name) => match names::lookup(name, chip_names) {
                Ok(offset) => Some(offset),
                Err(names::Lookup::Missing(hint)) => {
                    errors.push(WiringError::NoSuchName { entry, name: name.clone(), hint });
                    None
                }
                Err(names::Lookup::Shared(offsets)) => {
                    errors.push(WiringError::SharedName { entry, name: name.clone(), offsets });
                    None
                }
            },
        };
        let input_offsets: Vec<Option<u32>> =
            io.inputs.iter().map(|l| resolve(Entry::Input(l.device), &l.line)).collect();
        let output_offsets: Vec<Option<u32>> =
            io.outputs.iter().map(|l| resolve(Entry::Output(l.device), &l.line)).collect();
        let switch_offset = switch.and_then(|(_, line)| resolve(Entry::Switch, line));

        // One line, one entry: what the config checked as written, for the resolved offsets.
        let resolved = (io.inputs.iter().zip(&input_offsets))
            .map(|(l, o)| (Entry::Input(l.device), &l.line, *o))
            .chain(
                (io.outputs.iter().zip(&output_offsets))
                    .map(|(l, o)| (Entry::Output(l.device), &l.line, *o)),
            )
            .chain(switch.map(|(_, line)| (Entry::Switch, line, switch_offset)));
        let mut seen: Vec<(u32, Entry, &LineRef)> = Vec::new();
        for (entry, line, offset) in resolved {
            let Some(offset) = offset else { continue };
            match seen.iter().find(|(o, ..)| *o == offset) {
                Some(&(_, first, first_line)) => errors.push(WiringError::SameLine {
                    offset,
                    first: (first, first_line.clone()),
                    second: (entry, line.clone()),
                }),
                None => seen.push((offset, entry, line)),
            }
        }

        errors.extend(limits(io, switch.map(|(s, _)| s), &edges));
        if !errors.is_empty() {
            return Err(errors);
        }

        // No error: every line has its offset.
        let mut inputs = Vec::with_capacity(io.inputs.len() + 1);
        for (line, offset) in io.inputs.iter().zip(input_offsets) {
            let settings = InputLine {
                offset: offset.unwrap_or_default(),
                active_low: line.active_low,
                bias: line.bias,
                debounce_us: line.debounce_us,
            };
            inputs.push(InputWire {
                line: settings,
                slot: InputSlot::Bit {
                    device: line.device,
                    bit: ImageBit::of(&line.device).unwrap_or(NO_BIT),
                },
                edge: input_edge(&line.device, &edges),
            });
        }
        if let (Some((switch, _)), Some(offset)) = (switch, switch_offset) {
            let settings = InputLine {
                offset,
                active_low: switch.active_low,
                bias: switch.bias,
                debounce_us: switch.debounce_us,
            };
            inputs.push(InputWire { line: settings, slot: InputSlot::Switch, edge: None });
        }
        let mut outputs: Vec<OutputWire> = (io.outputs.iter().zip(output_offsets))
            .map(|(line, offset)| OutputWire {
                device: line.device,
                line: OutputLine {
                    offset: offset.unwrap_or_default(),
                    active_low: line.active_low,
                },
                bit: ImageBit::of(&line.device).unwrap_or(NO_BIT),
            })
            .collect();
        inputs.sort_by_key(|i| i.line.offset);
        outputs.sort_by_key(|o| o.line.offset);
        Ok(Wiring { inputs, outputs })
    }

    /// Every line of both requests with what it is wired to: inputs, then outputs.
    pub fn lines(&self) -> impl Iterator<Item = (u32, Wire)> + '_ {
        let inputs = self.inputs.iter().map(|i| (i.line.offset, i.wire()));
        inputs.chain(self.outputs.iter().map(|o| (o.line.offset, Wire::Device(o.device))))
    }

    /// How many input lines detect edges.
    pub fn edge_lines(&self) -> usize {
        self.inputs.iter().filter(|i| i.edge.is_some()).count()
    }

    /// Whether the key switch's line is among the inputs.
    pub fn has_switch(&self) -> bool {
        self.inputs.iter().any(|i| i.slot == InputSlot::Switch)
    }
}

/// Every limit of the kernel the requests of these lines would exceed, reported at the first
/// line past it (the inputs in file order, the switch's line last). The limits depend on how
/// many lines there are and on their settings, not on their offsets, so names need no chip
/// here.
fn limits(
    io: &IoConfig,
    switch: Option<&SwitchConfig>,
    edges: &[Option<Edge>; CONTACTS],
) -> Vec<WiringError> {
    let mut inputs: Vec<(Wire, Settings)> = io
        .inputs
        .iter()
        .map(|l| {
            let edge = input_edge(&l.device, edges).map(|(_, e)| e);
            (Wire::Device(l.device), Settings::input(l.active_low, l.bias, edge, l.debounce_us))
        })
        .collect();
    if let Some(switch) = switch.filter(|s| s.line.is_some()) {
        let settings = Settings::input(switch.active_low, switch.bias, None, switch.debounce_us);
        inputs.push((Wire::Switch, settings));
    }
    let outputs: Vec<(Wire, Settings)> = io
        .outputs
        .iter()
        .map(|l| (Wire::Device(l.device), Settings::output(l.active_low)))
        .collect();

    let mut errors = Vec::new();
    for (direction, lines) in [(LineDirection::Input, inputs), (LineDirection::Output, outputs)] {
        if lines.len() > GPIO_V2_LINES_MAX {
            errors.push(WiringError::TooManyLines {
                direction,
                count: lines.len(),
                max: GPIO_V2_LINES_MAX,
                at: lines[GPIO_V2_LINES_MAX].0,
            });
        }
        let settings: Vec<Settings> = lines.iter().map(|(_, s)| *s).collect();
        let needed = extra_settings(&settings);
        if needed > GPIO_V2_LINE_NUM_ATTRS_MAX {
            let first_over = (1..=settings.len())
                .find(|&n| extra_settings(&settings[..n]) > GPIO_V2_LINE_NUM_ATTRS_MAX)
                .unwrap_or(settings.len());
            errors.push(WiringError::TooManySettings {
                direction,
                needed,
                max: GPIO_V2_LINE_NUM_ATTRS_MAX,
                at: lines[first_over - 1].0,
            });
        }
    }
    errors
}

/// The contact and the edge its tasks need, for an input line wired to `device`: `None` unless
/// the device is a contact some io task starts on.
fn input_edge(device: &Address, edges: &[Option<Edge>; CONTACTS]) -> Option<(u8, Edge)> {
    let contact = contact_of(device)?;
    edges[contact as usize].map(|edge| (contact, edge))
}

/// The contact (0..=7) a device is, if it is one of P0000..P0007.
pub fn contact_of(device: &Address) -> Option<u8> {
    match (device.area, device.number, device.bit) {
        (Area::P, 0, Some(bit)) if (bit as usize) < CONTACTS => Some(bit),
        _ => None,
    }
}

/// The edge a line must detect for two tasks that need `a` and `b`.
pub fn merge_edge(a: Edge, b: Edge) -> Edge {
    if a == b {
        a
    } else {
        Edge::Both
    }
}

impl Config {
    /// The edges the field must report, per contact P0000..=P0007: what the io tasks start on,
    /// merged per contact. A driver sets its field up for these once, when it opens it (the
    /// GPIO line request's edge detection, the simulated field's edge mask), which is why a
    /// change of them takes a restart ([`super::ProjectChange`]).
    pub fn edge_detection(&self) -> [Option<Edge>; CONTACTS] {
        contact_edges(&self.edge_contacts())
    }
}

/// Per contact, the edges its tasks need (merged), or `None` if no task starts on it. A
/// contact beyond P0007 starts no task (the validator refuses it).
fn contact_edges(edge_contacts: &[(u8, Edge)]) -> [Option<Edge>; CONTACTS] {
    let mut edges = [None; CONTACTS];
    for &(contact, edge) in edge_contacts {
        if let Some(slot) = edges.get_mut(contact as usize) {
            *slot = Some(slot.map_or(edge, |have| merge_edge(have, edge)));
        }
    }
    edges
}

/// One line's part in its request's attributes: its flags (the kernel's
/// `GPIO_V2_LINE_FLAG_*`: direction, active-low, bias, edges) and its debounce period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Settings {
    flags: (bool, bool, Bias, Option<Edge>),
    debounce_us: u32,
}

impl Settings {
    fn input(active_low: bool, bias: Bias, edge: Option<Edge>, debounce_us: u32) -> Settings {
        Settings { flags: (true, active_low, bias, edge), debounce_us }
    }

    /// Outputs are requested inactive, with no bias, debounce or edge: only active-low varies.
    /// (All-inactive initial values take no attribute either.)
    fn output(active_low: bool) -> Settings {
        Settings { flags: (false, active_low, Bias::Disabled, None), debounce_us: 0 }
    }
}

/// How many attributes a request with these lines needs besides its default flags, counted
/// the way the kernel (and gpiocdev, building the request) counts them: one per distinct flag
/// combination beyond the first, one per distinct debounce period.
fn extra_settings(lines: &[Settings]) -> usize {
    let mut flags: Vec<(bool, bool, Bias, Option<Edge>)> = Vec::new();
    let mut debounces: Vec<u32> = Vec::new();
    for line in lines {
        if !flags.contains(&line.flags) {
            flags.push(line.flags);
        }
        let d = line.debounce_us;
        if d > 0 && !debounces.contains(&d) {
            debounces.push(d);
        }
    }
    flags.len().saturating_sub(1) + debounces.len()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::config::parse;

    const GPIO: &str = "[io]\nbackend = \"gpiocdev\"\nchip = \"gpiochip0\"\n";
    const SCAN: &str = "[[program]]\nfile = \"main.il\"\n";

    fn addr(s: &str) -> Address {
        Address::parse(s).unwrap()
    }

    fn config(text: &str) -> Config {
        parse(&format!("{SCAN}{text}"), Path::new("plcd.toml"))
            .unwrap_or_else(|d| panic!("unexpected errors:\n{d}"))
    }

    fn errors(text: &str) -> Vec<String> {
        match parse(&format!("{SCAN}{text}"), Path::new("plcd.toml")) {
            Ok(c) => panic!("expected errors, got {:#?}", c.io),
            Err(d) => d.iter().map(|d| format!("{}:{}: {}", d.line, d.col, d.message)).collect(),
        }
    }

    /// `[[io.input]]` (or output) entries of `device` on `line`, with `extra` keys.
    fn entry(kind: &str, device: &str, line: u32, extra: &str) -> String {
        format!("[[io.{kind}]]\ndevice = \"{device}\"\nline = {line}\n{extra}")
    }

    fn io_task(name: &str, number: u8, contact: &str, edge: &str) -> String {
        format!(
            "[[task]]\nname = \"{name}\"\nkind = \"io\"\nnumber = {number}\npriority = 2\n\
             contact = \"{contact}\"\nedge = \"{edge}\"\n"
        )
    }

    /// The device of the n-th of many inputs: P0100, P0101, …
    fn nth(n: u32) -> String {
        format!("P{:03}{:X}", 10 + n / 16, n % 16)
    }

    fn plan(text: &str) -> Wiring {
        config(text).wiring(&[]).unwrap()
    }

    fn settings(input: &InputWire) -> Settings {
        let line = &input.line;
        Settings::input(line.active_low, line.bias, input.edge.map(|(_, e)| e), line.debounce_us)
    }

    fn bit(device: &str) -> InputSlot {
        InputSlot::Bit { device: addr(device), bit: ImageBit::of(&addr(device)).unwrap() }
    }

    #[test]
    fn the_uapi_limits() {
        // include/uapi/linux/gpio.h: GPIO_V2_LINES_MAX 64, GPIO_V2_LINE_NUM_ATTRS_MAX 10.
        assert_eq!((GPIO_V2_LINES_MAX, GPIO_V2_LINE_NUM_ATTRS_MAX), (64, 10));
    }

    #[test]
    fn image_bits_of_p_devices() {
        assert_eq!(ImageBit::of(&addr("P0000")), Some(ImageBit { word: 0, mask: 1 }));
        assert_eq!(ImageBit::of(&addr("P0040")), Some(ImageBit { word: 4, mask: 1 }));
        assert_eq!(ImageBit::of(&addr("P000F")), Some(ImageBit { word: 0, mask: 0x8000 }));
        assert_eq!(ImageBit::of(&addr("P127F")), Some(ImageBit { word: 127, mask: 0x8000 }));
        assert_eq!(ImageBit::of(&addr("M0000")), None);
        assert_eq!(ImageBit::of(&addr("P004")), None);
    }

    #[test]
    fn contacts_are_p0000_to_p0007() {
        assert_eq!(contact_of(&addr("P0000")), Some(0));
        assert_eq!(contact_of(&addr("P0007")), Some(7));
        assert_eq!(contact_of(&addr("P0008")), None);
        assert_eq!(contact_of(&addr("P0010")), None);
        assert_eq!(contact_of(&addr("M0000")), None);
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
            (8, Edge::Rising),
        ]);
        assert_eq!(
            edges,
            [Some(Edge::Both), None, Some(Edge::Falling), None, None, Some(Edge::Both), None, None]
        );
    }

    #[test]
    fn lines_are_sorted_by_offset_with_their_bits() {
        let plan = plan(&format!(
            "{GPIO}{}{}{}{}{}",
            entry("input", "P0001", 9, ""),
            entry("input", "P0000", 2, ""),
            entry("input", "P0023", 5, ""),
            entry("output", "P0041", 7, ""),
            entry("output", "P0040", 3, ""),
        ));
        let inputs: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.slot)).collect();
        let at = |device: &str, word, mask| InputSlot::Bit {
            device: addr(device),
            bit: ImageBit { word, mask },
        };
        assert_eq!(
            inputs,
            [(2, at("P0000", 0, 1)), (5, at("P0023", 2, 1 << 3)), (9, at("P0001", 0, 1 << 1))]
        );
        let outputs: Vec<_> = plan.outputs.iter().map(|o| (o.line.offset, o.bit)).collect();
        assert_eq!(
            outputs,
            [(3, ImageBit { word: 4, mask: 1 }), (7, ImageBit { word: 4, mask: 1 << 1 })]
        );
        assert_eq!(plan.edge_lines(), 0);
        assert!(!plan.has_switch());
    }

    #[test]
    fn edge_detection_only_on_task_contacts() {
        let plan = plan(&format!(
            "{GPIO}{}{}{}{}{}{}{}",
            entry("input", "P0000", 10, ""),
            entry("input", "P0001", 11, ""),
            entry("input", "P0002", 12, ""),
            entry("input", "P0008", 13, ""),
            io_task("a", 8, "P0002", "rising"),
            io_task("b", 9, "P0000", "falling"),
            io_task("c", 10, "P0002", "falling"),
        ));
        let edges: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.edge)).collect();
        assert_eq!(
            edges,
            [(10, Some((0, Edge::Falling))), (11, None), (12, Some((2, Edge::Both))), (13, None)]
        );
        assert_eq!(plan.edge_lines(), 2);
    }

    #[test]
    fn the_switch_is_an_input_line_without_a_bit_or_an_edge() {
        let plan = plan(&format!(
            "{GPIO}{}{}{}{}[switch]\nline = 6\nactive_low = true\nbias = \"pull-up\"\n\
             debounce_us = 5000\n",
            entry("input", "P0000", 10, ""),
            entry("input", "P0001", 2, ""),
            entry("output", "P0040", 3, ""),
            io_task("edge", 8, "P0000", "both"),
        ));
        let inputs: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.slot, i.edge)).collect();
        assert_eq!(
            inputs,
            [
                (2, bit("P0001"), None),
                (6, InputSlot::Switch, None),
                (10, bit("P0000"), Some((0, Edge::Both))),
            ]
        );
        assert_eq!(
            plan.inputs[1].line,
            InputLine { offset: 6, active_low: true, bias: Bias::PullUp, debounce_us: 5_000 }
        );
        assert!(plan.has_switch());
        assert_eq!(plan.edge_lines(), 1);
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
        let alone = super::tests::plan(&format!("{GPIO}[switch]\nline = 0\n"));
        assert_eq!(alone.inputs.len(), 1);
        assert!(alone.has_switch());
    }

    #[test]
    fn a_request_holds_at_most_64_lines() {
        let inputs: String = (0..65).map(|n| entry("input", &nth(n), n, "")).collect();
        let first_64: String = (0..64).map(|n| entry("input", &nth(n), n, "")).collect();
        assert_eq!(plan(&format!("{GPIO}{first_64}")).inputs.len(), 64);
        // The 65th entry starts at line 2 + 3 + 64 × 3 + 1 of the file.
        assert_eq!(
            errors(&format!("{GPIO}{inputs}")),
            ["198:1: io.input \"P0140\": 65 input lines configured, but one GPIO line request \
              holds at most 64"]
        );
        // The switch's line is one of them, counted last.
        assert_eq!(
            errors(&format!("{GPIO}{first_64}[switch]\nline = 100\n")),
            ["199:8: [switch]: 65 input lines configured, but one GPIO line request holds at \
              most 64"]
        );
        let outputs: String = (0..70).map(|n| entry("output", &nth(n), n, "")).collect();
        assert_eq!(
            errors(&format!("{GPIO}{outputs}")),
            ["198:1: io.output \"P0140\": 70 output lines configured, but one GPIO line request \
              holds at most 64"]
        );
        // The sim backend requests no lines.
        config(&inputs);
    }

    #[test]
    fn distinct_settings_are_counted_like_the_kernel() {
        let mut inputs = String::new();
        // 2 active levels × 3 biases = 6 flag combinations (5 beyond the first).
        for (n, (active_low, bias)) in [false, true]
            .into_iter()
            .flat_map(|a| ["disabled", "pull-up", "pull-down"].map(|b| (a, b)))
            .enumerate()
        {
            let extra = format!("active_low = {active_low}\nbias = \"{bias}\"\n");
            inputs += &entry("input", &format!("P010{n:X}"), n as u32, &extra);
        }
        // Five debounce periods, one of them twice: 5 more.
        for (n, us) in [100, 200, 300, 400, 500, 500].into_iter().enumerate() {
            let extra = format!("debounce_us = {us}\n");
            inputs += &entry("input", &format!("P011{n:X}"), 20 + n as u32, &extra);
        }
        let with_ten = format!("{GPIO}{inputs}");
        assert_eq!(
            extra_settings(&plan(&with_ten).inputs.iter().map(settings).collect::<Vec<_>>()),
            10
        );

        // The switch's settings count like any line's: its flags are among the above, its
        // debounce period (by default 10 ms) is new.
        assert_eq!(
            errors(&format!("{with_ten}[switch]\nline = 50\n")),
            ["61:8: [switch]: the input lines need 11 distinct line settings (combinations of \
              active_low, bias and edge, and debounce periods) besides the most common one; the \
              kernel takes at most 10 per request"]
        );
        plan(&format!("{with_ten}[switch]\nline = 50\ndebounce_us = 500\n"));

        // An edge on a contact is one more flag combination: 11 is too many, reported at the
        // input line that detects it.
        let contact = entry("input", "P0000", 40, "");
        plan(&format!("{with_ten}{contact}"));
        let task = io_task("edge", 8, "P0000", "rising");
        assert_eq!(
            errors(&format!("{with_ten}{contact}{task}")),
            ["60:1: io.input \"P0000\": the input lines need 11 distinct line settings \
              (combinations of active_low, bias and edge, and debounce periods) besides the most \
              common one; the kernel takes at most 10 per request"]
        );
    }

    #[test]
    fn every_limit_is_reported_at_once_with_the_other_errors() {
        let inputs: String = (0..65).map(|n| entry("input", &nth(n), n, "")).collect();
        let outputs: String =
            (0..65).map(|n| entry("output", &nth(n + 100), n + 100, "")).collect();
        let errs = errors(&format!("[plc]\nwatchdog_ms = 5\n{GPIO}{inputs}{outputs}"));
        assert_eq!(errs.len(), 3, "{errs:#?}");
        assert!(errs[0].starts_with("4:15: plc.watchdog_ms 5 out of range"), "{}", errs[0]);
        assert!(errs[1]
            .ends_with("65 input lines configured, but one GPIO line request holds at most 64"));
        assert!(errs[2]
            .ends_with("65 output lines configured, but one GPIO line request holds at most 64"));
    }

    #[test]
    fn line_and_device_rules_are_the_entries_own() {
        // Checked where the keys are, with the sim backend too; the plan relies on them.
        assert_eq!(
            errors(&format!(
                "{GPIO}{}{}",
                entry("input", "P0000", 4, ""),
                entry("output", "P0040", 4, "")
            )),
            ["11:8: io.output \"P0040\": line 4 is already used by io.input \"P0000\""]
        );
        assert_eq!(
            errors(&format!("{GPIO}{}[switch]\nline = 4\n", entry("input", "P0000", 4, ""))),
            ["10:8: switch.line 4 is already used by io.input \"P0000\""]
        );
    }

    /// A chip of `n` lines named `GPIO<offset>`, with some lines renamed.
    fn chip(n: u32, renamed: &[(u32, &str)]) -> Vec<String> {
        (0..n)
            .map(|o| match renamed.iter().find(|(r, _)| *r == o) {
                Some((_, name)) => name.to_string(),
                None => format!("GPIO{o}"),
            })
            .collect()
    }

    fn named_entry(kind: &str, device: &str, name: &str) -> String {
        format!("[[io.{kind}]]\ndevice = \"{device}\"\nline = \"{name}\"\n")
    }

    fn wiring_errors(text: &str, chip: &[String]) -> Vec<String> {
        match config(text).wiring(chip) {
            Ok(plan) => panic!("expected errors, got {plan:#?}"),
            Err(errors) => errors.iter().map(ToString::to_string).collect(),
        }
    }

    #[test]
    fn names_become_the_offsets_of_the_chips_lines() {
        // Names and offsets mixed, on a chip whose names are not its offsets.
        let chip = chip(16, &[(2, "START"), (9, "LAMP"), (12, "KEY")]);
        let config = config(&format!(
            "{GPIO}{}{}{}{}[switch]\nline = \"KEY\"\n{}",
            named_entry("input", "P0000", "GPIO5"),
            named_entry("input", "P0001", "START"),
            entry("output", "P0041", 7, ""),
            named_entry("output", "P0040", "LAMP"),
            io_task("edge", 8, "P0000", "rising"),
        ));
        assert!(config.uses_line_names());
        let plan = config.wiring(&chip).unwrap();
        let inputs: Vec<_> = plan.inputs.iter().map(|i| (i.line.offset, i.slot, i.edge)).collect();
        assert_eq!(
            inputs,
            [
                (2, bit("P0001"), None),
                (5, bit("P0000"), Some((0, Edge::Rising))),
                (12, InputSlot::Switch, None)
            ]
        );
        let outputs: Vec<_> = plan.outputs.iter().map(|o| (o.line.offset, o.device)).collect();
        assert_eq!(outputs, [(7, addr("P0041")), (9, addr("P0040"))]);
        // Without names, the chip's names are not needed.
        let plain = super::tests::config(&format!("{GPIO}{}", entry("input", "P0000", 3, "")));
        assert!(!plain.uses_line_names());
        assert_eq!(plain.wiring(&[]).unwrap().inputs[0].line.offset, 3);
    }

    #[test]
    fn a_name_the_chip_lacks_is_named_with_the_near_ones() {
        let chip = chip(28, &[(0, "ID_SDA"), (1, "ID_SCL")]);
        let text = format!(
            "{GPIO}{}{}[switch]\nline = \"gpio22\"\n",
            named_entry("input", "P0000", "GPIO71"),
            named_entry("output", "P0040", "GPIO17"),
        );
        assert_eq!(
            wiring_errors(&text, &chip),
            [
                "io.input \"P0000\": no line of the chip is named \"GPIO71\"; near names: \
                 \"GPIO17\" (line 17), \"GPIO7\" (line 7), \"GPIO11\" (line 11), \"GPIO21\" \
                 (line 21), \"GPIO2\" (line 2)",
                "[switch]: no line of the chip is named \"gpio22\"; near names: \"GPIO22\" (line \
                 22), \"GPIO2\" (line 2), \"GPIO12\" (line 12), \"GPIO20\" (line 20), \"GPIO21\" \
                 (line 21)",
            ]
        );
        // On a chip without names, every name is missing.
        assert_eq!(
            wiring_errors(&text, &vec![String::new(); 8]),
            [
                "io.input \"P0000\": no line of the chip is named \"GPIO71\"; none of the chip's \
                 8 lines has a name: give the line's offset",
                "io.output \"P0040\": no line of the chip is named \"GPIO17\"; none of the chip's \
                 8 lines has a name: give the line's offset",
                "[switch]: no line of the chip is named \"gpio22\"; none of the chip's 8 lines \
                 has a name: give the line's offset",
            ]
        );
    }

    #[test]
    fn a_name_of_several_lines_is_refused_with_their_offsets() {
        let chip = chip(8, &[(3, "-"), (5, "-"), (6, "-")]);
        assert_eq!(
            wiring_errors(&format!("{GPIO}{}", named_entry("input", "P0000", "-")), &chip),
            ["io.input \"P0000\": line name \"-\" is shared by lines 3, 5 and 6 of the chip: give \
              the line's offset instead"]
        );
        let two = super::tests::chip(8, &[(3, "X"), (5, "X")]);
        let err = wiring_errors(&format!("{GPIO}{}", named_entry("output", "P0040", "X")), &two);
        assert!(err[0].contains("is shared by lines 3 and 5 of the chip"), "{err:?}");
        // An offset on the same chip is fine.
        config(&format!("{GPIO}{}", entry("input", "P0000", 5, ""))).wiring(&chip).unwrap();
    }

    #[test]
    fn two_entries_on_one_line_once_resolved_are_named_both() {
        let chip = chip(16, &[]);
        // A name and an offset: the config cannot tell, the chip can.
        let text = format!(
            "{GPIO}{}{}",
            entry("input", "P0000", 4, ""),
            named_entry("output", "P0040", "GPIO4")
        );
        assert_eq!(
            wiring_errors(&text, &chip),
            ["io.output \"P0040\" (line \"GPIO4\") and io.input \"P0000\" (line 4) are the same \
              line, offset 4 of the chip"]
        );
        // The switch, by name, on an input's offset.
        let text = format!("{GPIO}{}[switch]\nline = \"GPIO9\"\n", entry("input", "P0000", 9, ""));
        assert_eq!(
            wiring_errors(&text, &chip),
            ["[switch] (line \"GPIO9\") and io.input \"P0000\" (line 9) are the same line, offset 9 \
              of the chip"]
        );
        let err = WiringError::SameLine {
            offset: 9,
            first: (Entry::Input(addr("P0000")), LineRef::Offset(9)),
            second: (Entry::Switch, LineRef::Name("GPIO9".into())),
        };
        assert_eq!(err.at(), Wire::Switch);
    }

    #[test]
    fn the_limits_need_no_chip_and_come_with_the_names_errors() {
        // 65 inputs by name: too many for one request, which `plcd check` tells without a chip.
        let named = |n: u32| named_entry("input", &nth(n), &format!("GPIO{n}"));
        let inputs: String = (0..65).map(named).collect();
        assert_eq!(
            errors(&format!("{GPIO}{inputs}")),
            ["198:1: io.input \"P0140\": 65 input lines configured, but one GPIO line request \
              holds at most 64"]
        );
        // A config that did not come from parsing whole: a missing name, and the limit.
        let first_64: String = (0..64).map(named).collect();
        let mut config = config(&format!("{GPIO}{first_64}"));
        let mut extra = config.io.inputs[0].clone();
        extra.device = addr(&nth(64));
        extra.line = LineRef::Name("GPIO99".into());
        config.io.inputs.push(extra);
        let errs: Vec<String> =
            config.wiring(&chip(64, &[])).unwrap_err().iter().map(ToString::to_string).collect();
        assert_eq!(errs.len(), 2, "{errs:#?}");
        assert!(
            errs[0].starts_with("io.input \"P0140\": no line of the chip is named \"GPIO99\"; "),
            "{errs:#?}"
        );
        assert_eq!(
            errs[1],
            "65 input lines configured, but one GPIO line request holds at most 64"
        );
    }

    #[test]
    fn entries_are_named_as_check_names_them() {
        assert_eq!(Entry::Input(addr("P0000")).to_string(), "io.input \"P0000\"");
        assert_eq!(Entry::Output(addr("P0040")).to_string(), "io.output \"P0040\"");
        assert_eq!(Entry::Switch.to_string(), "[switch]");
        assert_eq!(Entry::Output(addr("P0040")).wire(), Wire::Device(addr("P0040")));
    }
}
