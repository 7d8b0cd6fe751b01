//! The same test bodies against every I/O backend: the in-process sim backend (always) and the
//! gpiocdev backend on the kernel's gpio-sim (where it is available: root and the module;
//! `tests/vm/run-gpiosim` runs these in a VM with such a kernel). Then the daemon itself on
//! gpio-sim, end to end.
#[macro_use]
mod common_gpiosim;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use plcd::config::{self, Edge, IoConfig};
use plcd::device::{Address, Memory};
use plcd::io::gpio::{self, Gpio};
use plcd::io::sim::SimIo;
use plcd::io::{InputEdge, Io};
use plcd::rt::sys;

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
}

fn io_config(backend: &str, chip: Option<&str>) -> IoConfig {
    let chip = chip.map(|c| format!("chip = \"{c}\"\n")).unwrap_or_default();
    let text = format!(
        "[[program]]\nfile = \"main.il\"\n[[task]]\nname = \"edge\"\nkind = \"io\"\n\
         number = 8\npriority = 2\ncontact = \"P0000\"\nedge = \"both\"\n\
         [io]\nbackend = \"{backend}\"\n{chip}{WIRING}"
    );
    config::parse(&text, Path::new("rig.toml")).expect("config").io
}

struct SimRig {
    io: SimIo,
    lines: Vec<(u32, Address)>,
    pending: Vec<InputEdge>,
}

impl SimRig {
    fn new() -> SimRig {
        let config = io_config("sim", None);
        let inputs: Vec<Address> = config.inputs.iter().map(|l| l.device).collect();
        let lines =
            config.inputs.iter().chain(&config.outputs).map(|l| (l.line, l.device)).collect();
        SimRig { io: SimIo::new(&inputs, &[0], None), lines, pending: Vec::new() }
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
}

struct GpioRig {
    sim: gpiosim::Sim,
    gpio: Gpio,
}

impl GpioRig {
    fn new(name: &str) -> GpioRig {
        let sim = gpiosim::builder()
            .with_bank(&gpiosim::Bank::new(16, name))
            .live()
            .unwrap_or_else(|e| panic!("gpio-sim chip does not go live: {e}"));
        let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
        let config = io_config("gpiocdev", Some(&path));
        let gpio = gpio::open(&config, &[(0, Edge::Both)], "plcd-test").expect("the backend opens");
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

macro_rules! on_every_backend {
    ($($body:ident),*) => {
        mod sim_backend {
            $(#[test] fn $body() { super::$body(&mut super::SimRig::new()); })*
        }
        mod gpiocdev_backend {
            $(#[test] fn $body() {
                require_gpiosim!();
                super::$body(&mut super::GpioRig::new(concat!("plcd-", stringify!($body))));
            })*
        }
    };
}

on_every_backend!(inputs_follow_the_field, outputs_reach_the_field, contact_edges_are_stamped);

#[test]
fn a_line_held_by_another_process_is_named() {
    require_gpiosim!();
    let rig = GpioRig::new("plcd-busy");
    let path = rig.sim.chips()[0].dev_path().to_str().unwrap().to_string();
    let config = io_config("gpiocdev", Some(&path));
    let error = gpio::open(&config, &[(0, Edge::Both)], "plcd-second").unwrap_err().to_string();
    assert!(error.contains("line 0") && error.contains("P0000"), "{error}");
    assert!(error.contains("plcd-test"), "names the other consumer: {error}");
}

#[test]
fn a_line_beyond_the_chip_is_named() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(4, "plcd-small")).live().unwrap();
    let path = sim.chips()[0].dev_path().to_str().unwrap().to_string();
    let error =
        gpio::open(&io_config("gpiocdev", Some(&path)), &[], "plcd").unwrap_err().to_string();
    assert!(error.contains("line 8") && error.contains("P0040"), "{error}");
}

/// The daemon binary: cargo's when this test runs on the build machine, `/bin/plcd` in the VM.
fn plcd_binary() -> String {
    let built = env!("CARGO_BIN_EXE_plcd");
    if Path::new(built).exists() {
        built.to_string()
    } else {
        "/bin/plcd".to_string()
    }
}

#[test]
fn the_daemon_drives_gpio_lines_and_counts_edges_by_interrupt() {
    require_gpiosim!();
    let sim = gpiosim::builder().with_bank(&gpiosim::Bank::new(16, "plcd-daemon")).live().unwrap();
    let chip = &sim.chips()[0];
    let dir = std::env::temp_dir().join(format!("plcd-gpiosim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let config = format!(
        "[plc]\nscan_period_ms = 2\n\
         [[program]]\nfile = \"main.il\"\n[[program]]\nfile = \"count.il\"\ntask = \"count\"\n\
         [[task]]\nname = \"count\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
         contact = \"P0000\"\nedge = \"rising\"\n\
         [io]\nbackend = \"gpiocdev\"\nchip = \"{}\"\n{WIRING}",
        chip.dev_path().display()
    );
    std::fs::write(dir.join("plcd.toml"), config).unwrap();
    // P0040 follows P0001; P0041 comes on at the third counted edge.
    std::fs::write(dir.join("main.il"), "LOAD P0001\nOUT P0040\nLOAD>= D00000 3\nOUT P0041\nEND\n")
        .unwrap();
    std::fs::write(dir.join("count.il"), "INC D00000\nEND\n").unwrap();
    let mut child = Command::new(plcd_binary())
        .args(["run", "--config"])
        .arg(dir.join("plcd.toml"))
        .stderr(Stdio::inherit())
        .spawn()
        .expect("plcd starts");
    let wait_level = |line: u32, high: bool| {
        let start = Instant::now();
        while (chip.get_level(line).unwrap() == gpiosim::Level::High) != high {
            assert!(start.elapsed() < Duration::from_secs(20), "line {line} never went {high}");
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    // Wait for RUN: the scan copies P0001 to P0040.
    chip.set_pull(1, gpiosim::Level::High).unwrap();
    wait_level(8, true);
    for _ in 0..3 {
        assert!(!chip.get_level(9).unwrap().eq(&gpiosim::Level::High), "P0041 before 3 edges");
        chip.set_pull(0, gpiosim::Level::High).unwrap();
        std::thread::sleep(Duration::from_millis(20));
        chip.set_pull(0, gpiosim::Level::Low).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    wait_level(9, true);
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::SIGTERM,
    )
    .unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    assert_eq!(chip.get_level(8).unwrap(), gpiosim::Level::Low, "outputs off after SIGTERM");
    assert_eq!(chip.get_level(9).unwrap(), gpiosim::Level::Low);
    let _ = std::fs::remove_dir_all(&dir);
}
