//! How the engine scales, all in virtual time through [`Engine`] (not the VM alone), each table
//! measured side by side in one run: `cargo bench --bench scaling`.
//!
//! 1. Scan time against program size: generated scan programs of 10³ … 10⁶ steps (bit logic
//!    for the most part, compares, moves, arithmetic, timers, counters, an edge contact),
//!    devices reused cyclically over fixed ranges so that the data touched stops growing at
//!    10⁴ steps and only the code grows beyond; ns per step against the caches.
//!    The same against a program of bit logic alone, on the interpreter and with its native
//!    code side by side, and the time each load takes (parse and compile, plcd-native).
//! 2. Task overhead: 8 cycle tasks (1 ms), 8 io tasks (edges on P0000–P0007 every 1 ms) and 8
//!    device tasks (conditions true at every END) driven like `plcd sim` drives the engine
//!    (`poll_time`, `input_edge`, `run`, a step clock), against the same scan program without
//!    tasks: wall time per virtual second and the extra per task activation.
//! 3. END processing: an almost empty scan (`NOP`, `END`) against the number of device tasks,
//!    DUTY clocks and watched output bits; the slope per item.
//!
//! The hand-rolled harness interleaves the cases of a table round by round (one warm-up and one
//! timed sample of each case per round), so drift on this shared machine hits them alike;
//! figures are medians (p90 beside them) of those samples. Writes the Markdown fragment
//! `target/bench-results/scaling.md`. Run without `--bench` (`cargo test --benches`), it only
//! checks itself on small cases and writes nothing. `SCALING_SIZES=1000,300000,…` replaces the
//! program sizes of table 1 (each at most about 4·10⁶: one `LOADP` per 64 steps, and a project
//! holds 65,536 edge-sensitive instructions).

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use plcd::bench::{write_fragment, Fragment};
use plcd::config;
use plcd::device::Address;
use plcd::engine::event::{Event, EventSink, Mode};
use plcd::engine::{Activity, Engine};
use plcd::io::simulated::SimulatedIo;
use plcd::lang::Op;
use plcd::project::{self, Project};
use plcd::vm::{Clock, StepClock};

use nix::time::{clock_gettime, ClockId};

const MS: u64 = 1_000_000;

/// Keeps no event, counts preemptions: the engine's cost without a trace writer's.
#[derive(Default)]
struct Null {
    preemptions: u64,
}

impl EventSink for Null {
    #[inline]
    fn event(&mut self, _t_ns: u64, event: Event) {
        self.preemptions += u64::from(matches!(event, Event::TaskPreempt { .. }));
    }
}

/// A project from a config text and programs by file name.
fn project(config_text: &str, programs: &[(String, String)]) -> Project {
    let config = config::parse(config_text, Path::new("scaling.toml"))
        .unwrap_or_else(|d| panic!("config:\n{d}\n{config_text}"));
    project::from_config(config, |path| {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        programs
            .iter()
            .find(|(file, _)| file == name)
            .map(|(_, source)| source.clone())
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, name.to_string()))
    })
    .unwrap_or_else(|d| panic!("project:\n{d}"))
}

fn program_entry(file: &str, task: &str) -> String {
    format!("[[program]]\nfile = \"{file}\"\ntask = \"{task}\"\n")
}

// ---------------------------------------------------------------------------------------------
// Sample statistics.

/// Median and p90 (nearest rank) of `samples`.
fn summary(samples: &[f64]) -> (f64, f64) {
    let mut s = samples.to_vec();
    s.sort_by(f64::total_cmp);
    let rank = |q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
    let median =
        if s.len() % 2 == 1 { s[s.len() / 2] } else { (s[s.len() / 2 - 1] + s[s.len() / 2]) / 2.0 };
    (median, rank(0.9))
}

/// Least-squares slope of `y` against `x`.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (sx, sy) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let num: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = points.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
    if den == 0.0 {
        0.0
    } else {
        num / den
    }
}

fn time(ns: f64) -> String {
    if ns >= 1e6 {
        format!("{:.3} ms", ns / 1e6)
    } else if ns >= 1e3 {
        format!("{:.2} µs", ns / 1e3)
    } else {
        format!("{ns:.1} ns")
    }
}

fn bytes(b: usize) -> String {
    if b >= 1 << 20 {
        format!("{:.1} MiB", b as f64 / f64::from(1 << 20))
    } else if b >= 1 << 10 {
        format!("{:.1} KiB", b as f64 / 1024.0)
    } else {
        format!("{b} B")
    }
}

/// Thousands separators.
fn count(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The data caches of CPU 0: `(level, bytes)`, from sysfs.
fn caches() -> Vec<(u32, usize)> {
    let mut out = Vec::new();
    for index in 0..8 {
        let dir = format!("/sys/devices/system/cpu/cpu0/cache/index{index}");
        let read = |f: &str| std::fs::read_to_string(format!("{dir}/{f}")).ok();
        let (Some(level), Some(size), Some(kind)) = (read("level"), read("size"), read("type"))
        else {
            break;
        };
        if kind.trim() == "Instruction" {
            continue;
        }
        let size = size.trim();
        let (digits, unit) =
            size.split_at(size.find(|c: char| !c.is_ascii_digit()).unwrap_or(size.len()));
        let Ok(n) = digits.parse::<usize>() else { continue };
        let mult = match unit {
            "K" => 1 << 10,
            "M" => 1 << 20,
            _ => 1,
        };
        if let Ok(level) = level.trim().parse() {
            out.push((level, n * mult));
        }
    }
    out
}

/// CPU time of this thread: unlike wall time, it stops while other processes of this shared
/// machine have the core, which a long sample (one 10⁶-step scan) can hardly avoid.
fn thread_cpu_ns() -> u64 {
    let t = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID).expect("thread CPU clock");
    t.tv_sec() as u64 * 1_000_000_000 + t.tv_nsec() as u64
}

// ---------------------------------------------------------------------------------------------
// A rig: one engine in RUN on a step clock, each call to `scan` one whole scan.

struct Rig {
    engine: Engine,
    io: SimulatedIo,
    clock: StepClock,
    sink: Null,
}

impl Rig {
    fn new(project: &Project, watch: &[Address], step_ns: u64) -> Rig {
        let mut engine = Engine::new(project, watch);
        let mut io = plcd::io::simulated::SimulatedIo::for_project(project, &[]);
        let mut sink = Null::default();
        engine.set_mode(Mode::Run, 0, &mut io, &mut sink);
        // `run` hands back after END processing: one call, one scan.
        engine.set_hold_at_end(true);
        let clock = StepClock { origin_ns: 0, origin_steps: engine.steps(), step_ns };
        Rig { engine, io, clock, sink }
    }

    /// One scan as a driver runs it: time-driven work first, then the scan to its END
    /// processing (tasks that END requests included).
    #[inline]
    fn scan(&mut self) {
        let now = self.clock.now_ns(self.engine.steps());
        self.engine.poll_time(now, &mut self.io, &mut self.sink);
        let activity = self.engine.run(&self.clock, &mut self.io, &mut self.sink, u64::MAX);
        debug_assert_eq!(activity, Activity::Busy);
        black_box(activity);
    }

    /// Sets the inputs P0000–P003F to 0x5A5A (half of the generated programs' input bits ON),
    /// runs one scan and returns the steps it executed.
    fn set_inputs_and_scan(&mut self) -> u64 {
        for w in 0..64 {
            self.engine.write(&Address::parse(&format!("P{w:03}")).unwrap(), 0x5A5A);
        }
        let before = self.engine.steps();
        self.scan();
        self.engine.steps() - before
    }

    /// Wall ns per scan over `n` scans.
    fn time_scans(&mut self, n: u32) -> f64 {
        self.time_scans_cpu(n).0
    }

    /// Wall ns and this thread's CPU ns per scan over `n` scans.
    fn time_scans_cpu(&mut self, n: u32) -> (f64, f64) {
        let cpu = thread_cpu_ns();
        let start = Instant::now();
        for _ in 0..n {
            self.scan();
        }
        let wall = start.elapsed().as_nanos() as f64;
        let cpu = (thread_cpu_ns() - cpu) as f64;
        (wall / f64::from(n), cpu / f64::from(n))
    }
}

// ---------------------------------------------------------------------------------------------
// 1. Scan time against program size.

/// What a generated scan program uses.
struct Generated {
    source: String,
    /// Distinct device words read or written (bits by their word), T and C values included.
    words: BTreeSet<(char, u32)>,
    timers: BTreeSet<u32>,
    counters: BTreeSet<u32>,
}

/// M words the generator may use; M240–M255 are left to the harness's own rungs.
const GEN_M_WORDS: u32 = 240;
/// Data, timers and counters are reused cyclically over these ranges: 32 steps a block, all
/// ranges are covered by about 10⁴ steps.
const GEN_D_WORDS: u32 = 1024;
const GEN_TIMERS: u32 = 256;
const GEN_COUNTERS: u32 = 256;
/// Output bits P0400–P040F: a fixed watch list of 16 bits at every size.
const GEN_OUTPUTS: u32 = 16;
/// The project of a generated scan program (table 1 and its bit-logic twin).
const SCAN_CONFIG: &str = "[plc]\nwatchdog_ms = 1000\n[[program]]\nfile = \"scan.il\"\n";

impl Generated {
    /// An empty program of `steps` steps to come.
    fn with_capacity(steps: usize) -> Generated {
        Generated {
            source: String::with_capacity(steps * 14),
            words: BTreeSet::new(),
            timers: BTreeSet::new(),
            counters: BTreeSet::new(),
        }
    }

    /// The next M bit of a scattered walk over them (an odd multiplier is a permutation).
    fn next_m(&mut self, walk: &mut u32) -> String {
        let bit = walk.wrapping_mul(2_654_435_761) % (GEN_M_WORDS * 16);
        *walk += 1;
        self.words.insert(('M', bit / 16));
        format!("M{:03}{:X}", bit / 16, bit % 16)
    }

    /// The next of the inputs P0000–P03FF, half of them ON (set by the harness).
    fn next_input(&mut self, walk: &mut u32) -> String {
        let bit = walk.wrapping_mul(40_503) % (64 * 16);
        *walk += 1;
        self.words.insert(('P', bit / 16));
        format!("P{:03}{:X}", bit / 16, bit % 16)
    }

    /// The steps after the last whole block of 32, up to `steps` in all: LOAD/OUT pairs, a NOP
    /// if one step is left over, and `END`.
    fn finish(mut self, steps: usize) -> Generated {
        let rest = ((steps - 1) % 32) as u32;
        for i in 0..rest / 2 {
            let (a, b) = (i % GEN_M_WORDS, (i * 7 + 3) % GEN_M_WORDS);
            self.words.insert(('M', a));
            self.words.insert(('M', b));
            let _ =
                writeln!(self.source, "LOAD M{a:03}{:X}\nOUT M{b:03}{:X}", i % 16, (i + 5) % 16);
        }
        if rest % 2 == 1 {
            self.source.push_str("NOP\n");
        }
        self.source.push_str("END\n");
        self
    }

    /// A scan program of exactly `steps` executed instructions, `END` included (`steps` ≥ 1).
    /// Blocks of 32 steps: 22 of bit logic in five rungs (LOAD, AND, OR, AND NOT, OR LOAD, OUT
    /// on M and P), a compare with a MOV, an ADD, a TON, a CTU on the timer's contact, and a
    /// LOADP (every other block; LOAD in the others) with an INC. Every instruction executes
    /// every scan (no jumps).
    fn scan_program(steps: usize) -> Generated {
        let mut g = Generated::with_capacity(steps);
        let (mut m_walk, mut p_walk) = (0u32, 0u32);
        for b in 0..((steps - 1) / 32) as u32 {
            let m: Vec<String> = (0..21).map(|_| g.next_m(&mut m_walk)).collect();
            let (p1, p2) = (g.next_input(&mut p_walk), g.next_input(&mut p_walk));
            let out = b % GEN_OUTPUTS;
            g.words.insert(('P', 40 + out / 16));
            let d = |k: u32| (b * 4 + k) % GEN_D_WORDS;
            for k in 0..4 {
                g.words.insert(('D', d(k)));
            }
            let t = 1500 + b % GEN_TIMERS;
            let c = b % GEN_COUNTERS;
            g.timers.insert(t);
            g.counters.insert(c);
            g.words.insert(('T', t));
            g.words.insert(('C', c));
            let _ = write!(
                g.source,
                "LOAD {}\nAND {p1}\nOR {}\nOUT {}\n\
                 LOAD {}\nAND NOT {}\nOUT P040{out:X}\n\
                 LOAD {}\nAND {}\nLOAD {}\nAND {}\nOR LOAD\nOUT {}\n\
                 LOAD NOT {p2}\nOR {}\nAND {}\nOUT {}\n\
                 LOAD {}\nAND {}\nOUT {}\nAND NOT {}\nOUT {}\n\
                 LOAD>= D{:05} 100\nMOV D{:05} D{:05}\n\
                 LOAD {}\nADD D{:05} 1 D{:05}\n\
                 LOAD {}\nTON T{t:04} 10\n\
                 LOAD T{t:04}\nCTU C{c:04} 100\n\
                 {} {}\nINC D{:05}\n",
                m[0],
                m[1],
                m[2],
                m[3],
                m[4],
                m[5],
                m[6],
                m[7],
                m[8],
                m[9],
                m[10],
                m[11],
                m[12],
                m[13],
                m[14],
                m[15],
                m[16],
                m[17],
                d(0),
                d(1),
                d(2),
                m[18],
                d(3),
                d(3),
                m[19],
                if b % 2 == 0 { "LOADP" } else { "LOAD" },
                m[20],
                d(0),
            );
        }
        g.finish(steps)
    }

    /// A scan program of exactly `steps` executed instructions, `END` included, of bit logic
    /// alone (what native code compiles whole): blocks of 32 steps in seven rungs of LOAD,
    /// AND, OR, AND NOT, OR NOT, OR LOAD and OUT on the M and P bits of
    /// [`Generated::scan_program`], the same walk over them.
    fn bit_program(steps: usize) -> Generated {
        let mut g = Generated::with_capacity(steps);
        let (mut m_walk, mut p_walk) = (0u32, 0u32);
        for b in 0..((steps - 1) / 32) as u32 {
            let ms: Vec<String> = (0..24).map(|_| g.next_m(&mut m_walk)).collect();
            let p: Vec<String> = (0..3).map(|_| g.next_input(&mut p_walk)).collect();
            let out = b % GEN_OUTPUTS;
            g.words.insert(('P', 40 + out / 16));
            let _ = write!(
                g.source,
                "LOAD {}\nAND {}\nOR {}\nOUT {}\n\
                 LOAD {}\nAND NOT {}\nOUT P040{out:X}\n\
                 LOAD {}\nAND {}\nLOAD {}\nAND {}\nOR LOAD\nOUT {}\n\
                 LOAD NOT {}\nOR {}\nAND {}\nOUT {}\n\
                 LOAD {}\nAND {}\nOUT {}\nAND NOT {}\nOUT {}\n\
                 LOAD {}\nAND {}\nOR NOT {}\nOUT {}\n\
                 LOAD {}\nAND NOT {}\nOR {}\nAND {}\nOUT {}\nOUT {}\n",
                ms[0],
                p[0],
                ms[1],
                ms[2],
                ms[3],
                ms[4],
                ms[5],
                ms[6],
                ms[7],
                ms[8],
                ms[9],
                p[1],
                ms[10],
                ms[11],
                ms[12],
                ms[13],
                ms[14],
                ms[15],
                ms[16],
                ms[17],
                ms[18],
                p[2],
                ms[19],
                ms[20],
                ms[21],
                ms[22],
                ms[23],
                ms[0],
                ms[5],
                ms[9],
            );
        }
        g.finish(steps)
    }

    /// Bytes of device memory the program touches: its words, plus the VM's state of each
    /// timer (about 24 bytes: elapsed and last time, flags) and counter (about 8), private
    /// types whose sizes are estimated here.
    fn data_bytes(&self) -> usize {
        self.words.len() * 2 + self.timers.len() * 24 + self.counters.len() * 8
    }
}

struct SizeRow {
    steps: u64,
    code_bytes: usize,
    data_bytes: usize,
    median: f64,
    p90: f64,
    cpu_median: f64,
    cpu_p90: f64,
    cpu_min: f64,
}

fn scan_sizes(sizes: &[usize], rounds: usize) -> Vec<SizeRow> {
    let mut cases = Vec::new();
    for &size in sizes {
        let started = Instant::now();
        let generated = Generated::scan_program(size);
        let project = project(SCAN_CONFIG, &[("scan.il".into(), generated.source.clone())]);
        let code = &project.programs[0].code;
        let code_bytes = code.len() * std::mem::size_of::<Op>();
        // The daemon's and the simulator's watch list: every output bit the program writes.
        let watch = project.output_bits();
        assert_eq!(watch.len(), GEN_OUTPUTS.min((size / 32) as u32) as usize);
        // 100 ns a step: 10⁶ steps are 100 ms of virtual time, within the watchdog.
        let mut rig = Rig::new(&project, &watch, 100);
        let steps = rig.set_inputs_and_scan();
        assert_eq!(steps, size as u64, "every instruction executes once a scan");
        // About 10⁵ steps a sample, at least one scan.
        let batch = (100_000 / size).max(1) as u32;
        eprintln!(
            "scaling: {size} steps: generated and loaded in {:.2} s, {} a sample",
            started.elapsed().as_secs_f64(),
            batch
        );
        cases.push((rig, steps, code_bytes, generated.data_bytes(), batch, Vec::new()));
    }
    for _ in 0..rounds {
        for (rig, _, _, _, batch, samples) in &mut cases {
            rig.scan(); // warm-up: the code back into the caches after the other cases
            samples.push(rig.time_scans_cpu(*batch));
        }
    }
    cases
        .into_iter()
        .map(|(_, steps, code_bytes, data_bytes, _, samples)| {
            let wall: Vec<f64> = samples.iter().map(|s| s.0).collect();
            let cpu: Vec<f64> = samples.iter().map(|s| s.1).collect();
            let ((median, p90), (cpu_median, cpu_p90)) = (summary(&wall), summary(&cpu));
            let cpu_min = cpu.iter().copied().fold(f64::MAX, f64::min);
            SizeRow { steps, code_bytes, data_bytes, median, p90, cpu_median, cpu_p90, cpu_min }
        })
        .collect()
}

/// What a project load does with table 1's mixed program (its native code is declined: it
/// would hand too many instructions to the interpreter), in words for the report.
fn native_declined() -> String {
    let generated = Generated::scan_program(1_000);
    let project = project(SCAN_CONFIG, &[("scan.il".into(), generated.source)]);
    match plcd_native::compile(&project.programs[0]) {
        Err(plcd_native::Error::Slower { interpreted, instructions, .. }) => format!(
            "A project load leaves this mixed program on the interpreter: its native code would \
             hand {interpreted} of its {instructions} instructions (TON, CTU, LOADP, INC) to the \
             interpreter one at a time, slower than interpreting it all (plcd-native's \
             `Error::Slower`), so these figures are the ones it runs at."
        ),
        Ok(_) => "A project load attaches native code to this mixed program; these figures are \
                  the interpreter's."
            .into(),
        Err(e) => {
            format!("Native code for this mixed program: {e}; these figures are the interpreter's.")
        }
    }
}

/// One size of the bit-logic program, on the interpreter and with its native code.
struct NativeRow {
    steps: u64,
    /// Parse and compile (the VM's ops), seconds: a project load without native code.
    load_s: f64,
    /// plcd-native's compilation of the same program (`plcd_native::attach`), seconds.
    native_s: f64,
    /// Whether a project load attaches that native code (it declines it for a program mostly
    /// past the compiled part, `plcd_native::Error::Slower`).
    attached: bool,
    interpreter_cpu: f64,
    native_cpu: f64,
    interpreter_min: f64,
    native_min: f64,
}

/// Table 1b: [`Generated::bit_program`] at each size, loaded once as the interpreter runs it
/// and once with its native code attached (as a project load does, or as it would if it did
/// not decline it: the figures say why it does), both rigs sampled side by side round by
/// round; and the time each load took.
fn native_sizes(sizes: &[usize], rounds: usize) -> Vec<NativeRow> {
    let mut cases = Vec::new();
    for &size in sizes {
        let source = Generated::bit_program(size).source;
        let started = Instant::now();
        let interpreted = project(SCAN_CONFIG, &[("scan.il".into(), source)]);
        let load_s = started.elapsed().as_secs_f64();
        let mut native = interpreted.clone();
        let started = Instant::now();
        let errors = plcd_native::attach(&mut native);
        let native_s = started.elapsed().as_secs_f64();
        assert!(errors.is_empty(), "native code for {size} steps: {errors:?}");
        let attached = native.programs[0].native.is_some();
        if !attached {
            native.programs[0].native = Some(
                plcd_native::compile_even_if_slower(&native.programs[0])
                    .expect("native code for a long program"),
            );
        }
        let watch = interpreted.output_bits();
        let mut rigs = [Rig::new(&interpreted, &watch, 100), Rig::new(&native, &watch, 100)];
        let steps = rigs.each_mut().map(Rig::set_inputs_and_scan);
        assert_eq!(steps, [size as u64; 2], "every instruction executes once a scan, on both");
        let batch = (100_000 / size).max(1) as u32;
        eprintln!(
            "scaling: {size} steps of bit logic: loaded in {load_s:.2} s, native code in \
             {native_s:.2} s"
        );
        cases.push((rigs, load_s, native_s, attached, batch, [Vec::new(), Vec::new()]));
    }
    for _ in 0..rounds {
        for (rigs, _, _, _, batch, samples) in &mut cases {
            for (rig, samples) in rigs.iter_mut().zip(samples.iter_mut()) {
                rig.scan();
                samples.push(rig.time_scans_cpu(*batch).1);
            }
        }
    }
    let mut rows = Vec::new();
    for ((_, load_s, native_s, attached, _, [interpreter, native]), &size) in
        cases.into_iter().zip(sizes)
    {
        let min = |s: &[f64]| s.iter().copied().fold(f64::MAX, f64::min);
        rows.push(NativeRow {
            steps: size as u64,
            load_s,
            native_s,
            attached,
            interpreter_cpu: summary(&interpreter).0,
            native_cpu: summary(&native).0,
            interpreter_min: min(&interpreter),
            native_min: min(&native),
        });
    }
    rows
}

// ---------------------------------------------------------------------------------------------
// 2. Task overhead.

const STEP_NS: u64 = 1000;
/// The scan program of part 2: about 10³ steps, 1 ms of virtual time at 1 µs a step.
const TASK_SCAN_STEPS: usize = 1000;

#[derive(Debug, Clone, Copy)]
struct TaskMix {
    cycle: bool,
    io: bool,
    device: bool,
}

impl TaskMix {
    fn name(self) -> &'static str {
        match (self.cycle, self.io, self.device) {
            (false, false, false) => "none (same scan program)",
            (true, false, false) => "8 cycle (1 ms)",
            (false, true, false) => "8 io (edge every 1 ms)",
            (false, false, true) => "8 device (true at every END)",
            (true, true, true) => "8 cycle + 8 io + 8 device",
            _ => "mixed",
        }
    }
}

/// The project of part 2: the scan program toggles M2550 at every scan (a `transition`
/// condition); each task runs a 5-step program of its own.
fn task_project(mix: TaskMix) -> Project {
    let mut config = String::from("[plc]\nwatchdog_ms = 1000\n");
    config += &format!("[sim]\nstep_ns = {STEP_NS}\n");
    config += "[[program]]\nfile = \"scan.il\"\n";
    let scan = format!(
        "LOAD NOT M2550\nOUT M2550\n{}",
        Generated::scan_program(TASK_SCAN_STEPS - 2).source
    );
    let mut programs = vec![("scan.il".to_string(), scan)];
    let mut tasks = String::new();
    let mut add = |kind: &str, i: u32, number: u32, priority: u32, keys: String| {
        let name = format!("{kind}{i}");
        let file = format!("{name}.il");
        config += &program_entry(&file, &name);
        let _ = write!(
            tasks,
            "[[task]]\nname = \"{name}\"\nkind = \"{kind}\"\nnumber = {number}\n\
             priority = {priority}\n{keys}"
        );
        let source = format!(
            "LOAD M241{n:X}\nOR M242{n:X}\nOUT M243{n:X}\nINC D{:05}\nEND\n",
            3000 + number,
            n = number % 16
        );
        programs.push((file, source));
    };
    for i in 0..8 {
        if mix.cycle {
            add("cycle", i, i, 3, "interval_ms = 1\n".into());
        }
        if mix.io {
            add("io", i, 8 + i, 2, format!("contact = \"P000{i}\"\nedge = \"both\"\n"));
        }
        if mix.device {
            // Four kinds of condition, each true at every END.
            let keys = match i % 4 {
                0 => "device = \"SM400\"\ncondition = \"on\"\n".to_string(),
                1 => "device = \"SM401\"\ncondition = \"off\"\n".to_string(),
                2 => "device = \"M2550\"\ncondition = \"transition\"\n".to_string(),
                _ => "device = \"D00100\"\ncondition = \">=\"\nvalue = -32768\n".to_string(),
            };
            add("device", i, 16 + i, 4, keys);
        }
    }
    config += &tasks;
    project(&config, &programs)
}

/// What one virtual second of a [`TaskMix`] did.
struct Run {
    wall_ns: f64,
    steps: u64,
    scans: u64,
    /// Task runs by kind: cycle, io, device.
    activations: [u64; 3],
    preemptions: u64,
}

/// Runs `project` for `duration_ns` of virtual time as `plcd sim` does (`sim::simulate`: the
/// same loop, the same default watch list of every output bit a program writes), with the
/// stimulus generated on the fly: P0000–P0007 all toggle every 1 ms, half a millisecond after
/// each cycle deadline. The engine is built before the clock starts.
fn drive(project: &Project, duration_ns: u64) -> Run {
    let mut engine = Engine::new(project, &project.output_bits());
    let mut io = plcd::io::simulated::SimulatedIo::for_project(project, &[]);
    let field = io.field();
    let p000 = Address::parse("P000").unwrap();
    let mut sink = Null::default();
    let mut clock = StepClock { origin_ns: 0, origin_steps: engine.steps(), step_ns: STEP_NS };
    let mut next_edge = MS / 2;
    let mut level = 0;
    let start = Instant::now();
    engine.set_mode(Mode::Run, 0, &mut io, &mut sink);
    loop {
        let now = clock.now_ns(engine.steps());
        while next_edge <= now {
            level ^= 0xFF;
            for edge in field.set_input(&p000, level) {
                engine.input_edge(edge.contact, edge.rising, now, now, &mut sink);
            }
            next_edge += MS;
        }
        engine.poll_time(now, &mut io, &mut sink);
        if now >= duration_ns {
            break;
        }
        let next_event = |engine: &Engine, now: u64| {
            next_edge.min(duration_ns).min(engine.next_wakeup(now).unwrap_or(u64::MAX)).max(now + 1)
        };
        let until = next_event(&engine, now);
        let steps = (until - now).div_ceil(STEP_NS).max(1);
        if engine.run(&clock, &mut io, &mut sink, steps) == Activity::Idle {
            let after = clock.now_ns(engine.steps());
            let until = next_event(&engine, after);
            clock.rebase(until, engine.steps());
        }
    }
    let wall_ns = start.elapsed().as_nanos() as f64;
    let mut activations = [0; 3];
    for (name, stats) in engine.task_names().iter().zip(engine.all_task_stats()) {
        let kind = ["cycle", "io", "device"].iter().position(|k| name.starts_with(k));
        if let Some(k) = kind {
            activations[k] += stats.runs;
        }
    }
    assert_eq!(engine.mode(), Mode::Run);
    let (steps, scans) = (engine.steps(), engine.scan_stats().count);
    Run { wall_ns, steps, scans, activations, preemptions: sink.preemptions }
}

struct TaskRow {
    mix: TaskMix,
    steps: u64,
    scans: u64,
    activations: [u64; 3],
    preemptions: u64,
    wall: f64,
    p90: f64,
}

/// Samples of `duration_ms` of virtual time (short, so that most of them run undisturbed on
/// this shared machine), scaled to a virtual second.
fn task_overhead(rounds: usize, duration_ms: u64) -> Vec<TaskRow> {
    let duration_ns = duration_ms * MS;
    let per_second = 1000 / duration_ms;
    let none = TaskMix { cycle: false, io: false, device: false };
    let mixes = [
        none,
        TaskMix { cycle: true, ..none },
        TaskMix { io: true, ..none },
        TaskMix { device: true, ..none },
        TaskMix { cycle: true, io: true, device: true },
    ];
    let projects: Vec<Project> = mixes.iter().map(|&m| task_project(m)).collect();
    let mut samples = vec![Vec::new(); mixes.len()];
    let mut figures = Vec::new();
    for round in 0..=rounds {
        for (i, project) in projects.iter().enumerate() {
            let run = drive(project, duration_ns);
            if round == 0 {
                // Warm-up round; its counts are those of every round (virtual time is exact).
                figures.push((run.steps, run.scans, run.activations, run.preemptions));
            } else {
                assert_eq!((run.steps, run.activations), (figures[i].0, figures[i].2));
                samples[i].push(run.wall_ns);
            }
        }
    }
    mixes
        .iter()
        .zip(samples)
        .zip(figures)
        .map(|((&mix, samples), (steps, scans, activations, preemptions))| {
            let (wall, p90) = summary(&samples);
            TaskRow {
                mix,
                steps: steps * per_second,
                scans: scans * per_second,
                activations: activations.map(|a| a * per_second),
                preemptions: preemptions * per_second,
                wall: wall * per_second as f64,
                p90: p90 * per_second as f64,
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// 3. END processing.

/// An END-processing case: `NOP`, `END` as the scan program, and what END has to do.
#[derive(Debug, Clone, Copy)]
enum EndCase {
    /// Device tasks whose condition never holds: sampled at every END, never run.
    DeviceSampled(u32),
    /// Device tasks whose condition holds at every END: sampled, requested, run (`NOP`, `END`).
    DeviceRun(u32),
    /// DUTY clocks running (started by the init program, never executed again).
    Duty(u32),
    /// Watched output bits, compared at every output refresh (the sim's and daemon's watch
    /// list is every output bit a program writes).
    Watched(u32),
}

fn end_project(case: EndCase) -> (Project, Vec<Address>) {
    let mut config = String::from("[plc]\nwatchdog_ms = 1000\n[[program]]\nfile = \"scan.il\"\n");
    let mut programs = vec![("scan.il".to_string(), "NOP\nEND\n".to_string())];
    let mut watch = Vec::new();
    match case {
        EndCase::DeviceSampled(n) | EndCase::DeviceRun(n) => {
            let run = matches!(case, EndCase::DeviceRun(_));
            let mut tasks = String::new();
            for i in 0..n {
                let name = format!("device{i}");
                config += &program_entry(&format!("{name}.il"), &name);
                // Bit and word conditions alike; M0000 and D00000 stay 0.
                let keys = match (run, i % 2) {
                    (false, 0) => "device = \"M0000\"\ncondition = \"rising\"\n",
                    (false, _) => "device = \"D00000\"\ncondition = \">\"\nvalue = 0\n",
                    (true, 0) => "device = \"SM400\"\ncondition = \"on\"\n",
                    (true, _) => "device = \"D00000\"\ncondition = \"<=\"\nvalue = 0\n",
                };
                let _ = write!(
                    tasks,
                    "[[task]]\nname = \"{name}\"\nkind = \"device\"\nnumber = {}\n\
                     priority = 4\n{keys}",
                    16 + i
                );
                programs.push((format!("{name}.il"), "NOP\nEND\n".to_string()));
            }
            config += &tasks;
        }
        EndCase::Duty(n) => {
            config += &program_entry("init.il", "init");
            let mut init = String::new();
            for channel in 0..n {
                let _ = writeln!(init, "LOAD SM400\nDUTY 2 3 SM42{channel}");
            }
            init += "LOAD SM400\nINIT_DONE\nEND\n";
            programs.push(("init.il".to_string(), init));
        }
        EndCase::Watched(n) => {
            watch = (0..n)
                .map(|i| Address::parse(&format!("P{:03}{:X}", i / 16, i % 16)).unwrap())
                .collect();
        }
    }
    (project(&config, &programs), watch)
}

struct EndRow {
    case: EndCase,
    median: f64,
    p90: f64,
}

fn end_processing(cases: &[EndCase], rounds: usize, batch: u32) -> Vec<EndRow> {
    let mut rigs: Vec<(Rig, Vec<f64>)> = cases
        .iter()
        .map(|&case| {
            let (project, watch) = end_project(case);
            let mut rig = Rig::new(&project, &watch, 100);
            // The init task's scan (it starts the DUTY clocks), then two scan program's.
            for _ in 0..3 {
                rig.scan();
            }
            if let EndCase::Duty(n) = case {
                for channel in 0..n {
                    let sd = Address::parse(&format!("SD833{channel}")).unwrap();
                    assert_eq!(rig.engine.vm().mem.read(&sd), 3, "DUTY clock {channel} runs");
                }
            }
            (rig, Vec::new())
        })
        .collect();
    for _ in 0..rounds {
        for (rig, samples) in &mut rigs {
            rig.time_scans(batch / 10); // warm-up
            samples.push(rig.time_scans(batch));
        }
    }
    for ((rig, _), case) in rigs.iter().zip(cases) {
        // Each case does what it says.
        let scans = rig.engine.scan_count();
        let runs: u64 = rig.engine.all_task_stats().skip(2).map(|s| s.runs).sum();
        match *case {
            EndCase::DeviceRun(n) => assert_eq!(runs, u64::from(n) * scans, "{case:?}"),
            _ => assert_eq!(runs, 0, "{case:?}"),
        }
    }
    rigs.into_iter()
        .zip(cases)
        .map(|((_, samples), &case)| {
            let (median, p90) = summary(&samples);
            EndRow { case, median, p90 }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.iter().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let full = args.iter().any(|a| a == "--bench");
    let started = Instant::now();

    let mut sizes: Vec<usize> =
        if full { vec![1_000, 10_000, 100_000, 1_000_000, 4_000_000] } else { vec![1_000, 10_000] };
    if let Ok(list) = std::env::var("SCALING_SIZES") {
        sizes = list.split(',').map(|s| s.trim().parse().expect("SCALING_SIZES")).collect();
    }
    let sizes = scan_sizes(&sizes, if full { 400 } else { 3 });
    eprintln!("scaling: program sizes done at {:.1} s", started.elapsed().as_secs_f64());
    let declined = native_declined();
    let native_sizes_list: &[usize] =
        if full { &[1_000, 10_000, 100_000, 300_000, 1_000_000] } else { &[1_000, 10_000] };
    let natives = native_sizes(native_sizes_list, if full { 200 } else { 3 });
    eprintln!("scaling: native code sizes done at {:.1} s", started.elapsed().as_secs_f64());

    let tasks = task_overhead(if full { 600 } else { 1 }, if full { 100 } else { 20 });
    eprintln!("scaling: task overhead done at {:.1} s", started.elapsed().as_secs_f64());

    let mut cases = Vec::new();
    for n in [0, 1, 4, 8] {
        cases.push(EndCase::DeviceSampled(n));
    }
    for n in [1, 4, 8] {
        cases.push(EndCase::DeviceRun(n));
    }
    for n in [0, 1, 4, 5] {
        cases.push(EndCase::Duty(n));
    }
    for n in [0, 16, 256, 2048] {
        cases.push(EndCase::Watched(n));
    }
    let ends = end_processing(&cases, if full { 300 } else { 2 }, if full { 2000 } else { 20 });
    eprintln!("scaling: END processing done at {:.1} s", started.elapsed().as_secs_f64());

    let fragment = report(&sizes, &declined, &natives, &tasks, &ends);
    if full {
        write_fragment("scaling", &fragment).expect("writing the fragment");
    } else {
        println!("{}", fragment.as_str());
    }
}

/// The count an [`EndCase`] has, if it belongs to a row of the END table.
type CountOf = fn(EndCase) -> Option<u32>;

/// The smallest cache level that holds `b` bytes, or "DRAM".
fn fits_in(caches: &[(u32, usize)], b: usize) -> String {
    caches.iter().find(|(_, size)| b <= *size).map_or("DRAM".into(), |(l, _)| format!("L{l}"))
}

fn report(
    sizes: &[SizeRow],
    declined: &str,
    natives: &[NativeRow],
    tasks: &[TaskRow],
    ends: &[EndRow],
) -> Fragment {
    let mut f = Fragment::new("cargo bench --bench scaling");
    let caches = caches();
    let cache_text: Vec<String> =
        caches.iter().map(|(level, size)| format!("L{level} {}", bytes(*size))).collect();
    let op = std::mem::size_of::<Op>();
    f.line(format!(
        "Hand-rolled harness: the cases of each table interleaved round by round (a warm-up and \
         a timed sample of each per round), median and p90 of the samples. Data caches of \
         CPU 0 (sysfs): {}; `size_of::<Op>()` = {op} bytes.\n",
        cache_text.join(", "),
    ));

    // 1. Program size.
    f.line(format!(
        "**Scan time against program size**: one scan through `Engine::run` (input refresh, the \
         program, END processing, output refresh; {GEN_OUTPUTS} watched outputs), 100 ns of \
         virtual time a step. Blocks of 32 steps: 22 bit logic (LOAD, AND, OR, AND NOT, OR LOAD, \
         OUT), LOAD>= + MOV, ADD, TON, CTU, LOADP (LOAD in every other block) + INC; devices \
         reused cyclically ({GEN_M_WORDS} M words, {GEN_D_WORDS} D words, {GEN_TIMERS} timers, \
         {GEN_COUNTERS} counters), so the data touched stops growing at 10⁴ steps and only the \
         code grows. Code bytes = instructions × {op}. Each sample is timed on the wall clock \
         and on the thread's CPU clock: on this shared 2-core machine a sample of one long scan \
         is seldom left alone for its whole length, so the wall figures of the large sizes \
         include other processes' time slices and ns/step is taken from CPU time (which still \
         counts the time the hypervisor gives this VM's CPU to others, and suffers neighbours' \
         use of L3 and memory bandwidth: the minimum shows the program alone).\n"
    ));
    let per_step: Vec<f64> = sizes.iter().map(|r| r.cpu_median / r.steps as f64).collect();
    let base = per_step.first().copied().unwrap_or(1.0);
    let rows: Vec<Vec<String>> = sizes
        .iter()
        .zip(&per_step)
        .map(|(r, &ns)| {
            let exp = (r.steps as f64).log10();
            vec![
                if exp.fract() == 0.0 { format!("10^{exp}") } else { count(r.steps) },
                count(r.steps),
                bytes(r.code_bytes),
                fits_in(&caches, r.code_bytes + r.data_bytes),
                bytes(r.data_bytes),
                format!("{} / {}", time(r.median), time(r.p90)),
                format!("{} / {}", time(r.cpu_median), time(r.cpu_p90)),
                format!("**{ns:.2}**"),
                format!("{:.2}", r.cpu_min / r.steps as f64),
                format!("{:.2}×", ns / base),
            ]
        })
        .collect();
    f.table(
        &[
            "size",
            "steps",
            "code bytes",
            "code + data fit in",
            "data touched",
            "scan wall: median / p90",
            "scan CPU: median / p90",
            "ns/step (CPU median)",
            "ns/step (CPU min)",
            "median ns/step vs first",
        ],
        &rows,
    );
    let (lo, hi) =
        per_step.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    let largest = sizes.last().map_or(0, |r| r.code_bytes);
    let mut levels: Vec<String> =
        sizes.iter().map(|r| fits_in(&caches, r.code_bytes + r.data_bytes)).collect();
    levels.dedup();
    levels.retain(|l| l != "L1");
    let levels_beyond_l1 = match levels.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last} alike", rest.join(", ")),
        Some((last, _)) => last.clone(),
        None => "L1".into(),
    };
    let flat = hi / lo < 1.25;
    let mins: Vec<f64> = sizes.iter().map(|r| r.cpu_min / r.steps as f64).collect();
    let (min_lo, min_hi) =
        mins.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    let min_flat = min_hi / min_lo < 1.25;
    let mut text = format!(
        "Median ns/step stays within {lo:.2}–{hi:.2} (largest/smallest {:.2}), the minimum \
         within {min_lo:.2}–{min_hi:.2} ({:.2}), from {} to {} steps, while code and data grow \
         from L1 to {} ({} of code{}): {}. ",
        hi / lo,
        min_hi / min_lo,
        count(sizes.first().map_or(0, |r| r.steps)),
        count(sizes.last().map_or(0, |r| r.steps)),
        fits_in(&caches, largest),
        bytes(largest),
        if largest > caches.iter().map(|c| c.1).max().unwrap_or(0) {
            ", more than the last level holds"
        } else {
            "; L3 is shared with the rest of the machine"
        },
        match (flat, min_flat) {
            (true, true) => "linear, no cliff",
            (false, true) => "linear when undisturbed; the medians of the largest sizes rise",
            _ => "not flat",
        },
    );
    text += &format!(
        "Every instruction executes once a scan and in order, so the code is one sequential \
         stream of {op} bytes a step, {:.1} GB/s at {lo:.2} ns/step, and the data (≤ {}) stays \
         in L1. ",
        op as f64 / lo,
        bytes(sizes.iter().map(|r| r.data_bytes).max().unwrap_or(0)),
    );
    if min_flat {
        text += &format!(
            "The hardware prefetcher keeps ahead of such a stream from {levels_beyond_l1}: \
             the cache sizes leave no mark of their own. "
        );
    }
    if !flat && min_flat {
        text += "What raises the medians of the sizes whose code streams from L3 or memory is \
                 the rest of this shared machine (other processes' use of L3 and memory \
                 bandwidth, the hypervisor); the sizes that fit L1 and L2 do not feel it. ";
    } else if !min_flat {
        text += "Where ns/step rises, compare the level the code last fitted in: a rise that \
                 is not at a cache boundary is this shared machine's load. ";
    }
    text += "The smallest size carries the fixed cost of a scan (input refresh, END \
             processing, output refresh: the first row of the END table) over fewer steps.\n";
    f.line(text);
    f.line(format!("{declined}\n"));

    // 1b. Bit logic, interpreter and native code.
    f.line(format!(
        "**Bit logic on the interpreter and with native code, and the load time**: the same \
         harness on a program of bit logic alone (blocks of 32 steps in seven rungs of LOAD, \
         AND, OR, AND NOT, OR NOT, OR LOAD, OUT over the same M and P bits), loaded twice: as \
         the interpreter runs it, and with its native code attached as a project load \
         attaches it; the two sampled side by side round by round. Load: parsing and compiling \
         to the VM's ops; native code: `plcd_native::attach` on the loaded project (Cranelift; \
         the first {} instructions in pieces, the rest left to the interpreter, \
         docs/LANGUAGE.md; a load declines native code whose compiled part is less than an \
         eighth of the program, measured here all the same). ns/step from the thread's CPU \
         time.\n",
        count(plcd_native::IL_MAX_COMPILED as u64)
    ));
    let rows: Vec<Vec<String>> = natives
        .iter()
        .map(|r| {
            let exp = (r.steps as f64).log10();
            let per = |ns: f64| ns / r.steps as f64;
            vec![
                if exp.fract() == 0.0 { format!("10^{exp}") } else { count(r.steps) },
                count(r.steps),
                format!("{:.3} s", r.load_s),
                format!("{:.3} s", r.native_s),
                count(r.steps.min(plcd_native::IL_MAX_COMPILED as u64)),
                if r.attached { "yes" } else { "no: declined" }.into(),
                format!("{:.2}", per(r.interpreter_cpu)),
                format!("**{:.2}**", per(r.native_cpu)),
                format!("{:.2}×", r.interpreter_cpu / r.native_cpu),
                format!("{:.2} / {:.2}", per(r.interpreter_min), per(r.native_min)),
            ]
        })
        .collect();
    f.table(
        &[
            "size",
            "steps",
            "load",
            "native code",
            "steps compiled",
            "a load attaches it",
            "ns/step interpreter",
            "ns/step native code",
            "interpreter/native",
            "ns/step min: interpreter / native",
        ],
        &rows,
    );

    // 2. Tasks.
    f.line(format!(
        "**Task overhead**: the engine driven exactly as `plcd sim` drives it (`poll_time`, \
         `input_edge`, `run`, a step clock of {STEP_NS} ns a step, the simulator's default watch \
         list, events to a null sink); a scan program of {TASK_SCAN_STEPS} steps, \
         scan_period_ms = 0, so every variant executes the same number of steps per virtual \
         second and the extra wall time is the engine's work for the activations. Cycle tasks \
         priority 3 at 1 ms, io tasks priority 2 on both edges of P0000–P0007 (all toggled \
         every 1 ms), device tasks priority 4 (`on`, `off`, `transition`, `>=`, true at every \
         END); each task a 5-step program. Samples of 100 ms of virtual time, scaled to 1 s.\n"
    ));
    let base = &tasks[0];
    let rows: Vec<Vec<String>> = tasks
        .iter()
        .map(|r| {
            let total: u64 = r.activations.iter().sum();
            let extra = r.wall - base.wall;
            vec![
                r.mix.name().to_string(),
                count(r.activations[0]),
                count(r.activations[1]),
                count(r.activations[2]),
                count(r.preemptions),
                count(r.scans),
                count(r.steps),
                time(r.wall),
                time(r.p90),
                if total == 0 { "—".into() } else { time(extra) },
                if total == 0 {
                    "—".into()
                } else {
                    format!("**{:.0} ns**", extra / total as f64)
                },
            ]
        })
        .collect();
    f.table(
        &[
            "tasks",
            "cycle runs/s",
            "io runs/s",
            "device runs/s",
            "preemptions/s",
            "scans/s",
            "steps/s",
            "wall per virtual s",
            "p90",
            "extra wall",
            "overhead per activation",
        ],
        &rows,
    );
    let per = |r: &TaskRow| {
        let total: u64 = r.activations.iter().sum();
        (r.wall - base.wall) / total.max(1) as f64
    };
    if let [_, cycle, io, device, all] = tasks {
        f.line(format!(
            "Each activation costs the engine {:.0} ns (cycle), {:.0} ns (io), {:.0} ns (device) \
             beyond the instructions it executes: the request and its event, the dispatch over \
             all tasks, start and end with their histograms, the VM entered and left, the watch \
             list compared at the task's end, and for cycle and io tasks the driver's extra \
             wake-up (`poll_time`, `next_wakeup` over all tasks). With all 24 tasks: {:.0} ns, \
             the difference being {} preemptions/s (io tasks at priority 2 preempt cycle tasks \
             and the scan, cycle tasks the scan) and 26 tasks instead of 10 to look through at \
             every dispatch. In `plcd sim` that is {:.0} % of the wall time at {} activations a \
             virtual second; in real time, {} of CPU a second ({:.2} %).\n",
            per(cycle),
            per(io),
            per(device),
            per(all),
            count(all.preemptions),
            (all.wall - base.wall) / all.wall * 100.0,
            count(all.activations.iter().sum()),
            time(all.wall - base.wall),
            (all.wall - base.wall) / 1e9 * 100.0,
        ));
    }

    // 3. END.
    f.line(
        "**END processing**: the scan program `NOP`, `END`; one whole scan through `Engine::run` \
         (2 steps in the VM, input refresh, END processing, output refresh), 2,000 scans a \
         sample. Device conditions that never hold are sampled only; those that hold request \
         their task, which runs (`NOP`, `END`) before the next scan. DUTY clocks are started by \
         the init program and switched at every END. Watched bits are compared at every output \
         refresh (the simulator and the daemon watch every output bit a program writes).\n",
    );
    let groups: [(&str, &str, CountOf); 4] =
        [
            ("device tasks, condition false (sampled only)", "device task", |c| match c {
                EndCase::DeviceSampled(n) => Some(n),
                _ => None,
            }),
            ("device tasks, condition true (sampled, requested, run)", "device task run", |c| {
                match c {
                    EndCase::DeviceRun(n) | EndCase::DeviceSampled(n @ 0) => Some(n),
                    _ => None,
                }
            }),
            ("DUTY clocks running", "DUTY clock", |c| match c {
                EndCase::Duty(n) => Some(n),
                _ => None,
            }),
            ("watched output bits", "watched bit", |c| match c {
                EndCase::Watched(n) => Some(n),
                _ => None,
            }),
        ];
    let mut rows = Vec::new();
    let mut slopes = Vec::new();
    for (label, item, pick) in groups {
        let points: Vec<(f64, f64, f64)> = ends
            .iter()
            .filter_map(|r| pick(r.case).map(|n| (f64::from(n), r.median, r.p90)))
            .collect();
        let s = slope(&points.iter().map(|&(x, y, _)| (x, y)).collect::<Vec<_>>());
        slopes.push(format!("{s:.1} ns per {item}"));
        let join = |v: Vec<String>| v.join(" / ");
        rows.push(vec![
            label.to_string(),
            join(points.iter().map(|p| p.0.to_string()).collect()),
            join(points.iter().map(|p| time(p.1)).collect()),
            join(points.iter().map(|p| time(p.2)).collect()),
            format!("**{s:.1} ns**"),
        ]);
    }
    f.table(&["END has", "count", "scan median", "scan p90", "slope per item"], &rows);
    f.line(format!(
        "Slopes (least squares over the medians): {}. A scan with nothing to do at END costs \
         {}: input refresh, scan start, 2 instructions, END, output refresh. A device condition \
         that does not hold is a few ns of sampling; one that holds adds its task's \
         activation. DUTY clocks are next to free. The watch list is the one END cost that \
         grows with the program (one entry per output bit written; 16 bits a P word written \
         with MOV). At most 8 device tasks (numbers 16–23) and 5 DUTY clocks (FX5) can be \
         configured.",
        slopes.join(", "),
        time(ends.first().map_or(0.0, |r| r.median)),
    ));
    f
}
