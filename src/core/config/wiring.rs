//! The wiring plan of the gpiocdev backend: how `[[io.input]]`, `[[io.output]]`, `[switch]`
//! and the io tasks' contacts map onto the two GPIO line requests, the kernel's limits
//! included.
//!
//! A plan is pure data: which line offset is which P bit (or the key switch), with which
//! settings, in which request, and which lines detect which edges. `plcd check` builds it while
//! it validates a gpiocdev config (`check`, every violation located and reported with the
//! rest), and `plcd run` builds the same plan from the validated config ([`Config::wiring`])
//! and hands it to the backend, which only applies it to a chip. So a config `plcd check`
//! accepts never fails at `plcd run` for a reason the config alone shows; what is left for
//! `plcd run` needs the hardware (the chip, its line count, who holds a line, the driver's
//! support for a setting).
//!
//! The rules each key obeys on its own, which every backend shares, are checked where the key
//! is (the `io`, `switch` and `task` modules): devices are P bits, lines and
//! devices are unique across inputs, outputs and the switch, a gpiocdev switch has a line, an
//! io task's contact is an input line. The plan relies on them.

use std::fmt;

use super::{Bias, Config, Edge, IoConfig, IoLine, Sink, SwitchConfig, TaskConfig, TaskKind};
use crate::device::{Address, Area};

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

/// One line of the output request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OutputWire {
    pub line: IoLine,
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

/// A request the kernel would refuse. `at` is the line that does not fit: the first one past
/// the limit, counting the inputs in file order and the switch's line last.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WiringError {
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
        }
    }
}

impl Config {
    /// The gpiocdev backend's plan for this config's `[io]` lines, `[switch]` and io tasks.
    /// For a gpiocdev config that [`super::parse`] returned this is always `Ok`: parsing
    /// reported its errors already.
    pub fn wiring(&self) -> Result<Wiring, Vec<WiringError>> {
        Wiring::new(&self.io, self.switch.as_ref(), &edge_contacts(&self.tasks))
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
    let Err(errors) = Wiring::new(io, switch.as_ref().map(|(s, _)| *s), &edge_contacts(tasks))
    else {
        return;
    };
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
    /// The plan, or every limit of the kernel it exceeds.
    ///
    /// `switch`'s line (if set) is one more input, with the switch's own settings, mapped to
    /// no P bit and detecting no edge. `edge_contacts`: the contacts io tasks start on and the
    /// edge each needs; several tasks on one contact merge, and edge detection is enabled only
    /// on those input lines. The per-key rules are the validator's (see the module doc): a
    /// device that is no P bit maps to no image bit, a contact that is no input line to no line.
    fn new(
        io: &IoConfig,
        switch: Option<&SwitchConfig>,
        edge_contacts: &[(u8, Edge)],
    ) -> Result<Wiring, Vec<WiringError>> {
        let edges = contact_edges(edge_contacts);
        let mut inputs = Vec::with_capacity(io.inputs.len() + 1);
        for line in &io.inputs {
            let contact = contact_of(&line.device);
            let edge = contact.and_then(|c| edges[c as usize].map(|e| (c, e)));
            let bit = ImageBit::of(&line.device).unwrap_or(NO_BIT);
            let settings = InputLine {
                offset: line.line,
                active_low: line.active_low,
                bias: line.bias,
                debounce_us: line.debounce_us,
            };
            inputs.push(InputWire {
                line: settings,
                slot: InputSlot::Bit { device: line.device, bit },
                edge,
            });
        }
        if let Some((switch, offset)) = switch.and_then(|s| Some((s, s.line?))) {
            let settings = InputLine {
                offset,
                active_low: switch.active_low,
                bias: switch.bias,
                debounce_us: switch.debounce_us,
            };
            inputs.push(InputWire { line: settings, slot: InputSlot::Switch, edge: None });
        }
        let outputs: Vec<OutputWire> = io
            .outputs
            .iter()
            .map(|line| OutputWire {
                line: *line,
                bit: ImageBit::of(&line.device).unwrap_or(NO_BIT),
            })
            .collect();

        // In file order (the switch last), so that an error names the first line past a limit.
        let mut errors = Vec::new();
        let output_settings: Vec<Settings> = outputs.iter().map(Settings::output).collect();
        let input_settings: Vec<Settings> = inputs.iter().map(Settings::input).collect();
        let output_wires = outputs.iter().map(|o| Wire::Device(o.line.device));
        for (direction, wires, settings) in [
            (
                LineDirection::Input,
                inputs.iter().map(InputWire::wire).collect::<Vec<_>>(),
                &input_settings,
            ),
            (LineDirection::Output, output_wires.collect(), &output_settings),
        ] {
            if wires.len() > GPIO_V2_LINES_MAX {
                errors.push(WiringError::TooManyLines {
                    direction,
                    count: wires.len(),
                    max: GPIO_V2_LINES_MAX,
                    at: wires[GPIO_V2_LINES_MAX],
                });
            }
            let needed = extra_settings(settings);
            if needed > GPIO_V2_LINE_NUM_ATTRS_MAX {
                let first_over = (1..=settings.len())
                    .find(|&n| extra_settings(&settings[..n]) > GPIO_V2_LINE_NUM_ATTRS_MAX)
                    .unwrap_or(settings.len());
                errors.push(WiringError::TooManySettings {
                    direction,
                    needed,
                    max: GPIO_V2_LINE_NUM_ATTRS_MAX,
                    at: wires[first_over - 1],
                });
            }
        }
        if !errors.is_empty() {
            return Err(errors);
        }
        inputs.sort_by_key(|i| i.line.offset);
        let mut outputs = outputs;
        outputs.sort_by_key(|o| o.line.line);
        Ok(Wiring { inputs, outputs })
    }

    /// Every line of both requests with what it is wired to: inputs, then outputs.
    pub fn lines(&self) -> impl Iterator<Item = (u32, Wire)> + '_ {
        let inputs = self.inputs.iter().map(|i| (i.line.offset, i.wire()));
        inputs.chain(self.outputs.iter().map(|o| (o.line.line, Wire::Device(o.line.device))))
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
    fn input(input: &InputWire) -> Settings {
        let line = &input.line;
        Settings {
            flags: (true, line.active_low, line.bias, input.edge.map(|(_, e)| e)),
            debounce_us: line.debounce_us,
        }
    }

    /// Outputs are requested inactive, with no bias, debounce or edge: only active-low varies.
    /// (All-inactive initial values take no attribute either.)
    fn output(output: &OutputWire) -> Settings {
        Settings { flags: (false, output.line.active_low, Bias::Disabled, None), debounce_us: 0 }
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
        config(text).wiring().unwrap()
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
        let outputs: Vec<_> = plan.outputs.iter().map(|o| (o.line.line, o.bit)).collect();
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
            extra_settings(&plan(&with_ten).inputs.iter().map(Settings::input).collect::<Vec<_>>()),
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
}
