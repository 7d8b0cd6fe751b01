//! The same test bodies against every I/O backend: the in-process sim backend (always) and the
//! gpiocdev backend on the kernel's gpio-sim (where it is available: root and the module;
//! `tests/qemu/run-gpiosim` runs these in a VM with such a kernel), each wired by line offsets
//! and by line names (on gpio-sim, a chip with named lines found by its label). Then line names
//! the chip lacks or shares, the RUN/STOP key switch's line settings and errors, and the daemon
//! itself on gpio-sim, end to end.
#[macro_use]
mod harness;

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use plcd::config::{self, Config};
use plcd::device::{Address, Memory};
use plcd::drivers::real_time::sys;
use plcd::io::faults::FieldFaults;
use plcd::io::gpio::{self, Gpio};
use plcd::io::simulated::SimulatedIo;
use plcd::io::{InputEdge, Io, SwitchPosition};

use harness::daemon::Project;

/// The wiring every body uses: inputs P0000 (line 0, an io-task contact), P0001 (line 1),
/// outputs P0040 (line 8), P0041 (line 9).
const WIRING: &str = r#"
[[io.input]]
device = "P0000"
line = 0
[[io.input]]
device = "P0001"
line = 1
[[io.output]]
device = "P0040"
line = 8
[[io.output]]
device = "P0041"
line = 9
"#;

/// The names the rigs wired by name give their chip's 16 lines, by offset: Raspberry Pi header
/// names, in an order unlike their numbers, so that a name taken for its digits would miss.
const LINE_NAMES: [&str; 16] = [
    "GPIO17", "GPIO27", "GPIO22", "GPIO10", "GPIO9", "GPIO11", "GPIO0", "GPIO1", "GPIO23",
    "GPIO24", "GPIO25", "GPIO8", "GPIO5", "GPIO6", "GPIO12", "GPIO13",
];

/// [`WIRING`] by the lines' names ([`LINE_NAMES`]): the same offsets.
const NAMED_WIRING: &str = r#"
[[io.input]]
device = "P0000"
line = "GPIO17"
[[io.input]]
device = "P0001"
line = "GPIO27"
[[io.output]]
device = "P0040"
line = "GPIO23"
[[io.output]]
device = "P0041"
line = "GPIO24"
"#;

/// How a rig's config names its lines.
#[derive(Clone, Copy, PartialEq)]
enum Lines {
    /// By offset ([`WIRING`]), the chip by its path.
    Offsets,
    /// By name ([`NAMED_WIRING`], the switch's `"GPIO5"`), the chip by its label.
    Names,
}

impl Lines {
    fn wiring(self) -> &'static str {
        match self {
            Lines::Offsets => WIRING,
            Lines::Names => NAMED_WIRING,
        }
    }

    /// A line's offset on the rigs' chip, as written in the config.
    fn offset(line: &config::LineRef) -> u32 {
        match line {
            config::LineRef::Offset(offset) => *offset,
            config::LineRef::Name(name) => {
                LINE_NAMES.iter().position(|n| n == name).unwrap() as u32
            }
        }
    }
}

/// The key switch of the rigs: line 12 on gpiocdev; on sim it starts at STOP, as the gpio-sim
/// line does (gpio-sim pulls a line down until told otherwise).
const SWITCH_LINE: u32 = 12;

fn switch_section(backend: &str) -> String {
    switch_section_by(backend, Lines::Offsets)
}

fn switch_section_by(backend: &str, lines: Lines) -> String {
    match (backend, lines) {
        ("gpiocdev", Lines::Offsets) => format!("[switch]\nline = {SWITCH_LINE}\n"),
        ("gpiocdev", Lines::Names) => {
            format!("[switch]\nline = {:?}\n", LINE_NAMES[SWITCH_LINE as usize])
        }
        _ => "[switch]\nposition = \"stop\"\n".to_string(),
    }
}

/// A live gpio-sim chip of 16 lines labelled `label`, its lines named [`LINE_NAMES`].
fn named_sim(label: &str) -> gpiosim::Sim {
    let mut bank = gpiosim::Bank::new(16, label);
    for (offset, name) in (0..).zip(LINE_NAMES) {
        bank.name(offset, name);
    }
    gpiosim::builder()
        .with_bank(&bank)
        .live()
        .unwrap_or_else(|e| panic!("gpio-sim chip {label:?} does not go live: {e}"))
}

fn addr(text: &str) -> Address {
    Address::parse(text).unwrap()
}

/// A backend and the field it is wired to.
trait Rig {
    fn io(&mut self) -> &mut dyn Io;
    /// Drives input `line` high or low, as a sensor would.
    fn drive(&mut self, line: u32, high: bool);
    /// The level of output `line` as the field sees it.
    fn level(&self, line: u32) -> bool;
    /// Edges of the io-task contacts reported since the last call, waiting up to `wait` for
    /// the first.
    fn edges(&mut self, wait: Duration) -> Vec<InputEdge>;
    /// The watchdog's safe state: every output off.
    fn safe_outputs(&self);
    /// Turns the RUN/STOP key switch, as an operator would.
    fn turn_switch(&mut self, position: SwitchPosition);
}

/// The rigs' config: [`WIRING`], an io task on P0000, and `extra` (a `[switch]`).
fn rig_config(backend: &str, chip: Option<&str>, extra: &str) -> Config {
    rig_config_with(WIRING, backend, chip, extra)
}

/// The rigs' config with `wiring` for [`WIRING`].
fn rig_config_with(wiring: &str, backend: &str, chip: Option<&str>, extra: &str) -> Config {
    let chip = chip.map(|c| format!("chip = \"{c}\"\n")).unwrap_or_default();
    let text = format!(
        "[[program]]\nfile = \"main.il\"\n[[task]]\nname = \"edge\"\nkind = \"io\"\n\
         number = 8\npriority = 2\ncontact = \"P0000\"\nedge = \"both\"\n\
         [io]\nbackend = \"{backend}\"\n{chip}{wiring}{extra}"
    );
    config::parse(&text, Path::new("rig.toml")).expect("config")
}

/// Opens the gpiocdev backend on `config`.
fn open(config: &Config, consumer: &str) -> Result<Gpio, gpio::GpioError> {
    gpio::open(config, consumer, Arc::default())
}

struct SimRig {
    io: SimulatedIo,
    lines: Vec<(u32, Address)>,
    pending: Vec<InputEdge>,
}

impl SimRig {
    /// The sim backend on the rigs' wiring by `lines`: the sim backend wires devices, not
    /// lines, so names and offsets alike only tell the rig which device a line is.
    fn new(lines: Lines) -> SimRig {
        let config = rig_config_with(lines.wiring(), "sim", None, &switch_section("sim"));
        let io = &config.io;
        let inputs: Vec<Address> = io.inputs.iter().map(|l| l.device).collect();
        let lines = io
            .inputs
            .iter()
            .chain(&io.outputs)
            .map(|l| (Lines::offset(&l.line), l.device))
            .collect();
        let switch = config.switch.as_ref().map(|s| s.position);
        SimRig { io: SimulatedIo::new(&inputs, &[0], switch), lines, pending: Vec::new() }
    }

    fn device(&self, line: u32) -> Address {
        self.lines.iter().find(|(l, _)| *l == line).unwrap().1
    }
}

impl Rig for SimRig {
    fn io(&mut self) -> &mut dyn Io {
        &mut self.io
    }
    fn drive(&mut self, line: u32, high: bool) {
        let device = self.device(line);
        let edges: Vec<_> = self.io.set_input(&device, i32::from(high)).collect();
        for e in edges {
            self.pending.push(InputEdge {
                contact: e.contact,
                rising: e.rising,
                stamp_ns: sys::now_ns(),
            });
        }
    }
    fn level(&self, line: u32) -> bool {
        self.io.field().output_bit(&self.device(line))
    }
    fn edges(&mut self, _wait: Duration) -> Vec<InputEdge> {
        std::mem::take(&mut self.pending)
    }
    fn safe_outputs(&self) {
        self.io.field().clear_outputs();
    }
    fn turn_switch(&mut self, position: SwitchPosition) {
        assert!(self.io.field().set_switch(position), "the sim rig has a switch");
    }
}

struct GpioRig {
    sim: gpiosim::Sim,
    gpio: Gpio,
}

impl GpioRig {
    /// A chip labelled `name`: by `Lines::Offsets` an unnamed one opened by its path, by
    /// `Lines::Names` one with named lines ([`LINE_NAMES`]) opened by its label.
    fn new(name: &str, lines: Lines) -> GpioRig {
        let (sim, chip) = match lines {
            Lines::Offsets => {
                let sim = gpiosim::builder()
                    .with_bank(&gpiosim::Bank::new(16, name))
                    .live()
                    .unwrap_or_else(|e| panic!("gpio-sim chip does not go live: {e}"));
                let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
                (sim, path)
            }
            Lines::Names => (named_sim(name), name.to_string()),
        };
        let switch = switch_section_by("gpiocdev", lines);
        let config = rig_config_with(lines.wiring(), "gpiocdev", Some(&chip), &switch);
        let gpio = open(&config, "plcd-test").expect("the backend opens");
        GpioRig { sim, gpio }
    }
}

impl Rig for GpioRig {
    fn io(&mut self) -> &mut dyn Io {
        &mut self.gpio.io
    }
    fn drive(&mut self, line: u32, high: bool) {
        let level = if high { gpiosim::Level::High } else { gpiosim::Level::Low };
        self.sim.chips()[0].set_pull(line, level).unwrap();
    }
    fn level(&self, line: u32) -> bool {
        self.sim.chips()[0].get_level(line).unwrap() == gpiosim::Level::High
    }
    fn edges(&mut self, wait: Duration) -> Vec<InputEdge> {
        let mut out = Vec::new();
        let edges = self.gpio.edges.as_mut().expect("edge detection on P0000");
        let deadline = Instant::now() + wait;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if !sys::wait_readable(&[edges.as_fd()], Some(left.as_nanos() as u64)).unwrap() {
                return out;
            }
            edges.read(&mut |e| out.push(e)).unwrap();
            // Whatever else is already queued, without waiting again.
            if !sys::wait_readable(&[edges.as_fd()], Some(1_000_000)).unwrap() {
                return out;
            }
        }
    }
    fn safe_outputs(&self) {
        self.gpio.outputs.set_all_inactive().unwrap();
    }
    fn turn_switch(&mut self, position: SwitchPosition) {
        self.drive(SWITCH_LINE, position == SwitchPosition::Run);
    }
}

// The bodies.

fn inputs_follow_the_field(rig: &mut dyn Rig) {
    let mut mem = Memory::new();
    mem.write(&addr("P0040"), 1);
    rig.drive(1, true);
    rig.io().refresh_inputs(&mut mem);
    assert_eq!(mem.read(&addr("P0001")), 1);
    assert_eq!(mem.read(&addr("P0000")), 0);
    assert_eq!(mem.read(&addr("P0040")), 1, "an input refresh leaves the outputs alone");
    rig.drive(1, false);
    rig.drive(0, true);
    rig.io().refresh_inputs(&mut mem);
    assert_eq!((mem.read(&addr("P0000")), mem.read(&addr("P0001"))), (1, 0));
}

fn outputs_reach_the_field(rig: &mut dyn Rig) {
    let mut mem = Memory::new();
    mem.write(&addr("P0041"), 1);
    rig.io().refresh_outputs(&mem);
    assert!(!rig.level(8) && rig.level(9));
    mem.write(&addr("P0040"), 1);
    mem.write(&addr("P0041"), 0);
    rig.io().refresh_outputs(&mem);
    assert!(rig.level(8) && !rig.level(9));
    rig.safe_outputs();
    assert!(!rig.level(8) && !rig.level(9), "the safe state switches everything off");
}

fn contact_edges_are_stamped(rig: &mut dyn Rig) {
    let _ = rig.edges(Duration::from_millis(10));
    let before = sys::now_ns();
    rig.drive(0, true);
    let rising = rig.edges(Duration::from_secs(2));
    rig.drive(0, false);
    let falling = rig.edges(Duration::from_secs(2));
    let after = sys::now_ns();
    assert_eq!(rising.len(), 1, "{rising:?}");
    assert_eq!(falling.len(), 1, "{falling:?}");
    assert!(rising[0].rising && !falling[0].rising);
    assert_eq!((rising[0].contact, falling[0].contact), (0, 0));
    for e in rising.iter().chain(&falling) {
        assert!(before <= e.stamp_ns && e.stamp_ns <= after, "stamp {e:?} in [{before}, {after}]");
    }
    assert!(rising[0].stamp_ns <= falling[0].stamp_ns);
    rig.drive(1, true);
    assert!(rig.edges(Duration::from_millis(50)).is_empty(), "P0001 is no io-task contact");
}

/// Refreshes the inputs until the switch reads `want` (the kernel debounces the contact, 10 ms
/// by default; the sim field is at once).
fn refresh_until_switch(rig: &mut dyn Rig, mem: &mut Memory, want: SwitchPosition) {
    let start = Instant::now();
    loop {
        rig.io().refresh_inputs(mem);
        if rig.io().switch() == Some(want) {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(2), "the switch never read {want:?}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn the_switch_follows_the_field(rig: &mut dyn Rig) {
    let mut mem = Memory::new();
    let _ = rig.edges(Duration::from_millis(10));
    assert_eq!(rig.io().switch(), Some(SwitchPosition::Stop), "known before the first refresh");
    let mut last = SwitchPosition::Stop;
    for position in [SwitchPosition::Run, SwitchPosition::Stop, SwitchPosition::Run] {
        rig.turn_switch(position);
        assert_eq!(rig.io().switch(), Some(last), "the switch as of the last refresh");
        refresh_until_switch(rig, &mut mem, position);
        assert!(mem.io_image().iter().all(|&w| w == 0), "the switch is no P bit");
        last = position;
    }
    // The inputs still refresh with it, in the same read.
    rig.drive(1, true);
    rig.turn_switch(SwitchPosition::Stop);
    refresh_until_switch(rig, &mut mem, SwitchPosition::Stop);
    assert_eq!(mem.read(&addr("P0001")), 1);
    assert!(rig.edges(Duration::from_millis(50)).is_empty(), "the switch detects no edges");
}

macro_rules! on_every_backend {
    ($($body:ident),*) => {
        mod sim_backend {
            use super::Lines;
            $(#[test] fn $body() { super::$body(&mut super::SimRig::new(Lines::Offsets)); })*
        }
        mod sim_backend_by_names {
            use super::Lines;
            $(#[test] fn $body() { super::$body(&mut super::SimRig::new(Lines::Names)); })*
        }
        mod gpiocdev_backend {
            use super::Lines;
            $(#[test] fn $body() {
                require_gpiosim!();
                let label = concat!("plcd-", stringify!($body));
                super::$body(&mut super::GpioRig::new(label, Lines::Offsets));
            })*
        }
        mod gpiocdev_backend_by_names {
            use super::Lines;
            $(#[test] fn $body() {
                require_gpiosim!();
                // The label is the only way to the chip: unique per test, and at most the 31
                // bytes the kernel reports of a label.
                let label = concat!("n-", stringify!($body));
                super::$body(&mut super::GpioRig::new(label, Lines::Names));
            })*
        }
    };
}

on_every_backend!(
    inputs_follow_the_field,
    outputs_reach_the_field,
    contact_edges_are_stamped,
    the_switch_follows_the_field
);

#[test]
fn a_line_held_by_another_process_is_named() {
    require_gpiosim!();
    let rig = GpioRig::new("plcd-busy", Lines::Offsets);
    let path = rig.sim.chips()[0].dev_path().to_str().unwrap().to_string();
    let config = rig_config("gpiocdev", Some(&path), "");
    let error = open(&config, "plcd-second").unwrap_err().to_string();
    assert!(error.contains("line 0") && error.contains("P0000"), "{error}");
    assert!(error.contains("plcd-test"), "names the other consumer: {error}");
}

#[test]
fn a_chip_that_goes_away_fails_refreshes_that_are_counted_not_fatal() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(16, "plcd-gone")).live().unwrap();
    let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
    let faults = Arc::new(FieldFaults::default());
    let mut gpio = gpio::open(&rig_config("gpiocdev", Some(&path), ""), "plcd", faults.clone())
        .expect("the backend opens");
    let mut mem = Memory::new();
    gpio.io.refresh_inputs(&mut mem);
    gpio.io.refresh_outputs(&mem);
    assert_eq!(faults.input_reads.state().count, 0);
    assert_eq!(faults.output_writes.state().count, 0);
    // The chip is unplugged under the open line requests: every ioctl on them fails from now on.
    drop(sim);
    mem.write(&addr("P0001"), 1);
    for _ in 0..3 {
        gpio.io.refresh_inputs(&mut mem);
        gpio.io.refresh_outputs(&mem);
    }
    let (reads, writes) = (faults.input_reads.state(), faults.output_writes.state());
    assert!(reads.failing && reads.count == 3 && reads.errno != 0, "{reads:?}");
    assert!(writes.failing && writes.count == 3 && writes.errno != 0, "{writes:?}");
    assert_eq!(mem.read(&addr("P0001")), 1, "a failed read leaves the inputs as they were");
}

#[test]
fn a_line_beyond_the_chip_is_named() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(4, "plcd-small")).live().unwrap();
    let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
    let error = open(&rig_config("gpiocdev", Some(&path), ""), "plcd").unwrap_err().to_string();
    assert!(error.contains("line 8") && error.contains("P0040"), "{error}");
}

#[test]
fn the_kernel_takes_a_plan_at_its_limits() {
    // What `plcd check` accepts at the edge of GPIO_V2_LINES_MAX and
    // GPIO_V2_LINE_NUM_ATTRS_MAX, the kernel takes: 64 input lines (the switch's among them)
    // whose settings need 10 attributes besides the request's default flags.
    let mut text = String::from(
        "[[program]]\nfile = \"main.il\"\n[[task]]\nname = \"edge\"\nkind = \"io\"\n\
         number = 8\npriority = 2\ncontact = \"P0000\"\nedge = \"both\"\n\
         [io]\nbackend = \"gpiocdev\"\nchip = \"CHIP\"\n[switch]\nline = 63\n",
    );
    // 2 active levels × 3 biases, and the edge on P0000: 6 flag combinations besides the
    // default; 3 debounce periods and the switch's 10 ms default: 4 more.
    let biases = ["disabled", "pull-up", "pull-down"];
    for n in 0..63u32 {
        let device = format!("P{:03}{:X}", n / 16, n % 16);
        let (active_low, bias) = ((n % 6) >= 3, biases[n as usize % 3]);
        let debounce = [0, 100, 200, 300][n as usize % 4];
        text += &format!(
            "[[io.input]]\ndevice = \"{device}\"\nline = {n}\nactive_low = {active_low}\n\
             bias = \"{bias}\"\ndebounce_us = {debounce}\n"
        );
    }
    let plan = config::parse(&text, Path::new("limits.toml")).expect("at the limits");
    assert_eq!(plan.wiring(&[]).unwrap().inputs.len(), 64);
    // One more debounce period is one attribute too many: refused by the config already.
    let over = text.replacen("debounce_us = 0\n", "debounce_us = 500\n", 1);
    let errors = config::parse(&over, Path::new("limits.toml")).unwrap_err().to_string();
    assert!(errors.contains("the input lines need 11 distinct line settings"), "{errors}");

    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(128, "plcd-limits")).live().unwrap();
    let text = text.replace("CHIP", sim.chips()[0].dev_path().to_str().unwrap());
    let config = config::parse(&text, Path::new("limits.toml")).unwrap();
    let gpio = open(&config, "plcd-test").expect("the kernel takes the plan");
    assert!(gpio.edges.is_some());
}

/// The error of opening the rigs' config wired by names, with `P0000`'s line named `p0000` and
/// `[switch]` as given, on `sim`'s chip (by its path).
fn named_open_error(sim: &gpiosim::Sim, p0000: &str, switch: &str) -> String {
    let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
    let wiring = NAMED_WIRING.replacen("\"GPIO17\"", &format!("{p0000:?}"), 1);
    let config = rig_config_with(&wiring, "gpiocdev", Some(&path), switch);
    let error = open(&config, "plcd-test").expect_err("names the chip cannot resolve");
    // Nothing was requested: the names are resolved first.
    let chip = gpiocdev::Chip::from_path(sim.chips()[0].dev_path()).unwrap();
    for offset in 0..16 {
        assert!(!chip.line_info(offset).unwrap().used, "line {offset} requested: {error}");
    }
    error.to_string()
}

#[test]
fn a_line_name_the_chip_lacks_stops_the_start_with_the_near_names() {
    require_gpiosim!();
    let sim = named_sim("plcd-no-such-name");
    let path = sim.chips()[0].dev_path().display().to_string();
    let error = named_open_error(&sim, "GPIO71", "");
    assert_eq!(
        error,
        format!(
            "GPIO chip {path} (plcd-no-such-name): io.input \"P0000\": no line of the chip is \
             named \"GPIO71\"; near names: \"GPIO17\" (line 0), \"GPIO11\" (line 5), \"GPIO1\" \
             (line 7), \"GPIO27\" (line 1), \"GPIO22\" (line 2)"
        )
    );
    // Another case: the kernel's name first. Every bad entry at once, the switch's too.
    let error = named_open_error(&sim, "gpio17", "[switch]\nline = \"GPIO55\"\n");
    assert!(error.contains("named \"gpio17\"; near names: \"GPIO17\" (line 0)"), "{error}");
    assert!(error.contains("; [switch]: no line of the chip is named \"GPIO55\"; "), "{error}");
}

#[test]
fn a_line_name_two_lines_share_is_refused_with_their_offsets() {
    require_gpiosim!();
    let mut bank = gpiosim::Bank::new(16, "plcd-shared-name");
    for (offset, name) in (0..).zip(LINE_NAMES) {
        bank.name(offset, name);
    }
    bank.name(3, "BUTTON").name(13, "BUTTON");
    let sim = gpiosim::builder().with_bank(&bank).live().unwrap();
    let error = named_open_error(&sim, "BUTTON", "");
    assert!(
        error.ends_with(
            "io.input \"P0000\": line name \"BUTTON\" is shared by lines 3 and 13 of the chip: \
             give the line's offset instead"
        ),
        "{error}"
    );
}

#[test]
fn a_name_and_an_offset_of_one_line_are_refused_naming_both() {
    require_gpiosim!();
    let sim = named_sim("plcd-name-and-offset");
    // The switch by offset 0, which is P0000's "GPIO17".
    let error = named_open_error(&sim, "GPIO17", "[switch]\nline = 0\n");
    assert!(
        error.ends_with(
            "[switch] (line 0) and io.input \"P0000\" (line \"GPIO17\") are the same line, \
             offset 0 of the chip"
        ),
        "{error}"
    );
}

#[test]
fn a_chip_without_line_names_says_so() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(16, "plcd-unnamed")).live().unwrap();
    let error = named_open_error(&sim, "GPIO17", "");
    assert!(
        error.contains(
            "io.input \"P0000\": no line of the chip is named \"GPIO17\"; none of the chip's 16 \
             lines has a name: give the line's offset"
        ),
        "{error}"
    );
}

#[test]
fn lines_by_name_are_requested_at_their_offsets() {
    require_gpiosim!();
    let label = "plcd-named-offsets";
    let sim = named_sim(label);
    let config = rig_config_with(
        NAMED_WIRING,
        "gpiocdev",
        Some(label),
        &switch_section_by("gpiocdev", Lines::Names),
    );
    let _gpio = open(&config, "plcd-named").expect("the backend opens by label and names");
    let chip = gpiocdev::Chip::from_path(sim.chips()[0].dev_path()).unwrap();
    let used: Vec<(u32, gpiocdev::line::Direction)> = (0..16)
        .map(|o| chip.line_info(o).unwrap())
        .filter(|info| info.used && info.consumer == "plcd-named")
        .map(|info| (info.offset, info.direction))
        .collect();
    use gpiocdev::line::Direction::{Input, Output};
    assert_eq!(used, [(0, Input), (1, Input), (8, Output), (9, Output), (12, Input)]);
}

/// The chip's path and the gpiocdev rig config with `[switch]` as given.
fn switch_config(sim: &gpiosim::Sim, switch: &str) -> Config {
    let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
    rig_config("gpiocdev", Some(&path), switch)
}

#[test]
fn the_switch_line_is_an_input_with_its_settings() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(16, "plcd-switch")).live().unwrap();
    let config = switch_config(
        &sim,
        "[switch]\nline = 12\nactive_low = true\nbias = \"pull-up\"\ndebounce_us = 2000\n",
    );
    let mut gpio = open(&config, "plcd-test").expect("the backend opens");
    let chip = gpiocdev::Chip::from_path(sim.chips()[0].dev_path()).unwrap();
    let info = chip.line_info(SWITCH_LINE).unwrap();
    assert!(info.used && info.consumer == "plcd-test", "{info:?}");
    assert_eq!(info.direction, gpiocdev::line::Direction::Input);
    assert!(info.active_low, "{info:?}");
    assert_eq!(info.bias, Some(gpiocdev::line::Bias::PullUp));
    assert_eq!(info.edge_detection, None, "the switch detects no edges");
    assert_eq!(info.debounce_period, Some(Duration::from_micros(2000)));
    // Pulled up by its bias, active low: inactive, STOP, read at open.
    assert_eq!(gpio.io.switch(), Some(SwitchPosition::Stop));
    let mut mem = Memory::new();
    sim.chips()[0].set_pull(SWITCH_LINE, gpiosim::Level::Low).unwrap();
    let start = Instant::now();
    while gpio.io.switch() != Some(SwitchPosition::Run) {
        assert!(start.elapsed() < Duration::from_secs(2), "low never read as RUN");
        std::thread::sleep(Duration::from_millis(1));
        gpio.io.refresh_inputs(&mut mem);
    }
    // The default debounce is 10 ms.
    drop(gpio);
    let gpio = open(&switch_config(&sim, "[switch]\nline = 12\n"), "plcd-test").unwrap();
    let info = chip.line_info(SWITCH_LINE).unwrap();
    assert_eq!(info.debounce_period, Some(Duration::from_millis(10)));
    assert!(!info.active_low);
    drop(gpio);
}

#[test]
fn a_switch_line_held_by_another_process_is_named() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(16, "plcd-sw-busy")).live().unwrap();
    let _held = gpiocdev::Request::builder()
        .on_chip(sim.chips()[0].dev_path())
        .with_consumer("key-holder")
        .with_line(SWITCH_LINE)
        .as_input()
        .request()
        .unwrap();
    let error = open(&switch_config(&sim, &switch_section("gpiocdev")), "plcd").unwrap_err();
    let error = error.to_string();
    assert!(error.contains("line 12 (the RUN/STOP switch)"), "{error}");
    assert!(error.contains("key-holder"), "names the other consumer: {error}");
    assert!(error.contains("plcd-sw-busy"), "names the chip: {error}");
}

#[test]
fn a_switch_line_beyond_the_chip_is_named() {
    require_gpiosim!();
    let sim =
        gpiosim::builder().with_bank(&gpiosim::Bank::new(12, "plcd-sw-small")).live().unwrap();
    let error = open(&switch_config(&sim, &switch_section("gpiocdev")), "plcd").unwrap_err();
    let error = error.to_string();
    assert!(error.contains("line 12 (the RUN/STOP switch) does not exist"), "{error}");
    assert!(error.contains("the chip has 12 lines"), "{error}");
}

/// The daemon binary: cargo's when this test runs on the build machine, `/bin/plcd` in the VM.
#[test]
fn the_daemon_drives_gpio_lines_and_counts_edges_by_interrupt() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(16, "plcd-daemon")).live().unwrap();
    let chip = &sim.chips()[0];
    let config = format!(
        "[plc]\nscan_period_ms = 2\n\
         [[program]]\nfile = \"main.il\"\n[[program]]\nfile = \"count.il\"\ntask = \"count\"\n\
         [[task]]\nname = \"count\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
         contact = \"P0000\"\nedge = \"rising\"\n\
         [control]\nsocket = \"plcd.sock\"\n\
         [io]\nbackend = \"gpiocdev\"\nchip = \"{}\"\n{WIRING}",
        chip.dev_path().display()
    );
    // P0040 follows P0001; P0041 comes on at the third counted edge.
    let project = Project::new(
        "gpiosim-daemon",
        &[
            ("plcd.toml", &config),
            ("main.il", "LOAD P0001\nOUT P0040\nLOAD>= D00000 3\nOUT P0041\nEND\n"),
            ("count.il", "INC D00000\nEND\n"),
        ],
    );
    let daemon = project.start();
    let high = |line: u32| chip.get_level(line).unwrap() == gpiosim::Level::High;
    // RUN: the scan copies P0001 to P0040.
    chip.set_pull(1, gpiosim::Level::High).unwrap();
    daemon.wait("P0040 (line 8) to follow P0001", || high(8));
    for edge in 1..=3 {
        assert!(!high(9), "P0041 before 3 edges");
        chip.set_pull(0, gpiosim::Level::High).unwrap();
        // The counting task ran when P0041's condition moved, or, before the third edge, when
        // the count did: read it back through the control socket.
        daemon.wait("the edge to be counted", || {
            let out = project.plcctl(&["--json", "get", "D00000"]);
            String::from_utf8_lossy(&out.stdout).contains(&format!("\"value\":{edge}"))
        });
        chip.set_pull(0, gpiosim::Level::Low).unwrap();
    }
    daemon.wait("P0041 (line 9) on at the third edge", || high(9));
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "{}", log.join("\n"));
    assert!(!high(8) && !high(9), "outputs off after SIGTERM");
}

#[test]
fn the_daemon_does_not_start_on_a_line_name_the_chip_lacks() {
    require_gpiosim!();
    let label = "plcd-daemon-names";
    let sim = named_sim(label);
    let config = format!(
        "[[program]]\nfile = \"main.il\"\n[control]\nsocket = \"plcd.sock\"\n\
         [io]\nbackend = \"gpiocdev\"\nchip = \"{label}\"\n{}",
        NAMED_WIRING.replace("\"GPIO24\"", "\"GPIO42\"")
    );
    let project = Project::new(
        "gpiosim-daemon-names",
        &[("plcd.toml", &config), ("main.il", "LOAD P0001\nOUT P0040\nEND\n")],
    );
    // `plcd check` has nothing against it: only the chip knows its names.
    let check = std::process::Command::new(harness::daemon::plcd_binary())
        .args(["check", "--config"])
        .arg(project.config())
        .output()
        .unwrap();
    assert!(check.status.success(), "{}", String::from_utf8_lossy(&check.stderr));
    let (code, log) = project.start().finish();
    let log = log.join("\n");
    assert_ne!(code, 0, "{log}");
    let path = sim.chips()[0].dev_path().display().to_string();
    assert!(
        log.contains(&format!(
            "GPIO chip {path} ({label}): io.output \"P0041\": no line of the chip is named \
             \"GPIO42\"; near names: \"GPIO24\" (line 9), \"GPIO22\" (line 2)"
        )),
        "{log}"
    );
}
