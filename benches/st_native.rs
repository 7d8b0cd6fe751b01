//! Structured Text against native Rust: five workloads written once in ST (`benches/st/*.st`)
//! and once as plain Rust, measured side by side — the ST on the interpreter alone and with
//! its native code (`plcd-native`), as a project load attaches it — and the compile time of a
//! 10,000-line ST project, without and with native code.
//!
//! `cargo bench --bench st_native` (criterion filters work: `cargo bench --bench st_native --
//! pid`). After criterion has run, the bench reads criterion's medians back and writes the
//! fragment `target/bench-results/st_native.md` for BENCHMARKS.md; a figure this run did not
//! produce reads "not run".
//!
//! The ST side (`benches/common/st_workloads.rs`, shared with the instruction-count guard
//! `benches/counts.rs`) is the real path: `st::parse_file` and `st::compile` (as a project load
//! does), a `Vm` with the compiled variable image, and each iteration one scan as the engine
//! executes it (`ExecState::restart`, then `Vm::run` to `END`), once as compiled and once with
//! the program's native code attached (`plcd_native::compile`). The Rust side is the same logic over a
//! struct holding the same variables, each iteration one call of its `scan` through
//! `black_box(&mut state)`, so the compiler can neither fold the inputs nor drop the outputs.
//! Before measuring, the bench runs each ST side and the Rust side for `CHECK_SCANS` scans and
//! checks that every variable the workload computes holds the same value on both (REALs bit
//! for bit).
//!
//! Beside them, a third column: each workload compiled as OpenPLC compiles a project, by
//! matiec's `iec2c` to C and then by gcc -O2, and run as OpenPLC's runtime runs a program
//! (`benches/matiec/`: `setup` builds iec2c from its source, `run.rs` builds and runs each
//! workload). Its variables after each of `CHECK_SCANS` scans must be the VM's, scan for scan
//! (REALs bit for bit); its time is the median of its own batches of scans, timed by the C
//! harness. When iec2c cannot be built, the column reads "not run" with the reason.

use std::hint::black_box;
use std::time::{Duration, SystemTime};

use criterion::{BenchmarkGroup, Criterion};
use plcd::bench::report::criterion_median_ns;
use plcd::bench::{write_fragment, Fragment};

#[path = "matiec/run.rs"]
mod matiec;
#[path = "common/st_workloads.rs"]
mod st;
use st::{compile_files, Slot, StCase, BIT_INPUTS, BIT_SENSORS};

const COMMAND: &str = "cargo bench --bench st_native";
/// Scans both sides run before their variables are compared.
const CHECK_SCANS: usize = 300;
/// The targets of issue 28: Structured Text (with its native code) within this factor of Rust
/// on every workload, and at least as fast as matiec + gcc -O2 (the matiec column).
const TARGET_RATIO: f64 = 2.0;
/// The target for the 10,000-line project, in seconds (with native code).
const TARGET_COMPILE_S: f64 = 0.5;

// ---------------------------------------------------------------------------------------------
// The comparison of both sides (the ST side: benches/common/st_workloads.rs)

/// Collects the mismatches between the VM's variables and the native values.
#[derive(Default)]
struct Compare(Vec<String>);

impl Compare {
    fn var(&mut self, st: &StCase, name: &str, native: impl Slot) {
        let (vm, native) = (st.slot(name), native.slot());
        if vm != native {
            self.0.push(format!("{name}: VM {vm:#x}, native {native:#x}"));
        }
    }

    fn done(self, workload: &str) {
        assert!(
            self.0.is_empty(),
            "{workload}: the VM and native disagree after {CHECK_SCANS} scans:\n{}",
            self.0.join("\n")
        );
    }
}

// ---------------------------------------------------------------------------------------------
// bit: rungs on BOOL variables (benches/st/bit.st)

#[derive(Default)]
struct Bits {
    start: bool,
    stop: bool,
    estop: bool,
    guard: bool,
    ready: bool,
    auto: bool,
    manual: bool,
    jog: bool,
    s: [bool; 8],
    run: bool,
    fault: bool,
    m: [bool; 6],
    q: [bool; 8],
    s1_before: bool,
    s1_rise: bool,
    flip: bool,
}

impl Bits {
    fn new() -> Bits {
        let [start, stop, estop, guard, ready, auto, manual, jog] = BIT_INPUTS;
        Bits {
            start,
            stop,
            estop,
            guard,
            ready,
            auto,
            manual,
            jog,
            s: BIT_SENSORS,
            ..Bits::default()
        }
    }

    #[inline(never)]
    fn scan(&mut self) {
        let [s1, s2, s3, s4, s5, s6, s7, s8] = self.s;
        self.run = (self.start | self.run) & !self.stop & !self.estop & self.guard;
        self.fault = self.estop | (self.fault & !self.ready);
        let m1 = self.run & self.auto & !self.manual;
        let m2 = self.run & self.manual & self.jog;
        let m3 = (s1 & s2) | (s3 & !s4);
        let m4 = (s5 | s6) & !(s7 ^ s8);
        let m5 = m1 & (m3 | m4);
        let m6 = m2 | (m1 & !m3);
        self.m = [m1, m2, m3, m4, m5, m6];
        self.s1_rise = s1 & !self.s1_before;
        self.s1_before = s1;
        let q1 = m5 & !self.fault;
        let q2 = m6 & !self.fault;
        let q3 = (q1 | q2) & self.ready;
        if self.s1_rise & self.run {
            self.flip = !self.flip;
        }
        let q4 = self.flip & !self.fault;
        let mut q5 = self.q[4];
        if s2 & s3 {
            q5 = true;
        }
        if s4 | self.fault {
            q5 = false;
        }
        let q6 = (s1 & s2 & s3) | (s4 & s5 & s6) | (s7 & s8);
        let q7 = !(q1 | q2 | q3) & self.auto;
        let q8 = (q6 ^ q7) | (m4 & !m5);
        self.q = [q1, q2, q3, q4, q5, q6, q7, q8];
    }
}

fn bit_compare(st: &StCase, n: &Bits) {
    let mut c = Compare::default();
    c.var(st, "run", n.run);
    c.var(st, "fault", n.fault);
    c.var(st, "s1_before", n.s1_before);
    c.var(st, "s1_rise", n.s1_rise);
    c.var(st, "flip", n.flip);
    for (k, &m) in n.m.iter().enumerate() {
        c.var(st, &format!("m{}", k + 1), m);
    }
    for (k, &q) in n.q.iter().enumerate() {
        c.var(st, &format!("q{}", k + 1), q);
    }
    c.done("bit");
}

// ---------------------------------------------------------------------------------------------
// int_loops: nested FOR loops of DINT arithmetic (benches/st/int_loops.st)

struct IntLoops {
    n: i32,
    m: i32,
    i: i32,
    j: i32,
    acc: i32,
    odd: i32,
    total: i32,
}

impl IntLoops {
    fn new() -> IntLoops {
        IntLoops { n: 100, m: 10, i: 0, j: 0, acc: 0, odd: 0, total: 0 }
    }

    #[inline(never)]
    fn scan(&mut self) {
        self.acc = 0;
        self.odd = 0;
        // A FOR loop leaves its variable at the first value past the bound (docs/ST.md).
        self.i = 1;
        while self.i <= self.n {
            self.j = 1;
            while self.j <= self.m {
                let r = self.i.wrapping_mul(self.j) % 7;
                self.acc = self.acc.wrapping_add(r).wrapping_sub(self.j);
                self.j += 1;
            }
            if self.acc % 2 != 0 {
                self.odd += 1;
            }
            self.i += 1;
        }
        self.total = self.total.wrapping_add(self.acc).wrapping_add(self.odd);
    }
}

fn int_loops_compare(st: &StCase, n: &IntLoops) {
    let mut c = Compare::default();
    c.var(st, "i", n.i);
    c.var(st, "j", n.j);
    c.var(st, "acc", n.acc);
    c.var(st, "odd", n.odd);
    c.var(st, "total", n.total);
    c.done("int_loops");
}

// ---------------------------------------------------------------------------------------------
// pid: 100 REAL PID function block instances, each with its plant (benches/st/pid.st)

#[derive(Clone, Copy)]
struct PidCtl {
    sp: f32,
    pv: f32,
    kp: f32,
    ki: f32,
    kd: f32,
    dt: f32,
    lo: f32,
    hi: f32,
    out: f32,
    integral: f32,
    prev_err: f32,
}

impl PidCtl {
    const NEW: PidCtl = PidCtl {
        sp: 0.0,
        pv: 0.0,
        kp: 1.2,
        ki: 0.3,
        kd: 0.05,
        dt: 0.01,
        lo: 0.0,
        hi: 100.0,
        out: 0.0,
        integral: 0.0,
        prev_err: 0.0,
    };

    #[inline(always)]
    fn call(&mut self) {
        let err = self.sp - self.pv;
        self.integral += self.ki * err * self.dt;
        if self.integral > self.hi {
            self.integral = self.hi;
        } else if self.integral < self.lo {
            self.integral = self.lo;
        }
        let d = (err - self.prev_err) / self.dt;
        self.prev_err = err;
        self.out = self.kp * err + self.integral + self.kd * d;
        if self.out > self.hi {
            self.out = self.hi;
        } else if self.out < self.lo {
            self.out = self.lo;
        }
    }
}

struct Pid {
    loops: [PidCtl; 100],
    pv: [f32; 100],
    sp: f32,
    gain: f32,
}

impl Pid {
    fn new() -> Pid {
        Pid { loops: [PidCtl::NEW; 100], pv: [0.0; 100], sp: 50.0, gain: 0.05 }
    }

    #[inline(never)]
    fn scan(&mut self) {
        for i in 0..100 {
            let pid = &mut self.loops[i];
            pid.sp = self.sp;
            pid.pv = self.pv[i];
            pid.call();
            self.pv[i] = self.pv[i] + (pid.out - self.pv[i]) * self.gain;
        }
    }
}

fn pid_compare(st: &StCase, n: &Pid) {
    let mut c = Compare::default();
    for (k, (l, pv)) in n.loops.iter().zip(n.pv).enumerate() {
        let i = k + 1;
        c.var(st, &format!("pv[{i}]"), pv);
        c.var(st, &format!("loops[{i}].out"), l.out);
        c.var(st, &format!("loops[{i}].integral"), l.integral);
        c.var(st, &format!("loops[{i}].prev_err"), l.prev_err);
    }
    c.done("pid");
}

// ---------------------------------------------------------------------------------------------
// sort: 100 DINTs from a generator, insertion-sorted (benches/st/sort.st)

struct Sort {
    a: [i32; 100],
    seed: i32,
}

impl Sort {
    fn new() -> Sort {
        Sort { a: [0; 100], seed: 12345 }
    }

    #[inline(never)]
    fn scan(&mut self) {
        let mut x = self.seed;
        for v in &mut self.a {
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            *v = (x / 65536) % 32768;
        }
        self.seed = x;
        for i in 1..self.a.len() {
            let key = self.a[i];
            let mut j = i;
            while j > 0 {
                if self.a[j - 1] <= key {
                    break;
                }
                self.a[j] = self.a[j - 1];
                j -= 1;
            }
            self.a[j] = key;
        }
    }
}

fn sort_compare(st: &StCase, n: &Sort) {
    let mut c = Compare::default();
    c.var(st, "seed", n.seed);
    for (i, &v) in n.a.iter().enumerate() {
        c.var(st, &format!("a[{i}]"), v);
    }
    c.done("sort");
    assert!(n.a.windows(2).all(|w| w[0] <= w[1]), "sort: the native array is not sorted");
}

// ---------------------------------------------------------------------------------------------
// state_machine: 32 batch stations, a CASE on an enumeration each (benches/st/state_machine.st)

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[repr(i32)]
enum Phase {
    Idle,
    Filling,
    Heating,
    Draining,
    Fault,
}

#[derive(Clone, Copy)]
struct Station {
    start: bool,
    level: i16,
    temp: i16,
    valve_in: bool,
    heater: bool,
    valve_out: bool,
    alarm: bool,
    phase: Phase,
    ticks: i16,
    batches: i32,
}

impl Station {
    const NEW: Station = Station {
        start: false,
        level: 0,
        temp: 0,
        valve_in: false,
        heater: false,
        valve_out: false,
        alarm: false,
        phase: Phase::Idle,
        ticks: 0,
        batches: 0,
    };

    #[inline(always)]
    fn call(&mut self) {
        self.ticks = self.ticks.wrapping_add(1);
        match self.phase {
            Phase::Idle => {
                self.valve_in = false;
                self.heater = false;
                self.valve_out = false;
                if self.start {
                    self.phase = Phase::Filling;
                    self.ticks = 0;
                }
            }
            Phase::Filling => {
                self.valve_in = true;
                if self.level >= 800 {
                    self.valve_in = false;
                    self.phase = Phase::Heating;
                    self.ticks = 0;
                } else if self.ticks > 50 {
                    self.phase = Phase::Fault;
                }
            }
            Phase::Heating => {
                self.heater = self.temp < 70;
                if self.temp >= 70 && self.ticks >= 5 {
                    self.heater = false;
                    self.phase = Phase::Draining;
                    self.ticks = 0;
                }
            }
            Phase::Draining => {
                self.valve_out = true;
                if self.level <= 100 {
                    self.valve_out = false;
                    self.phase = Phase::Idle;
                    self.batches = self.batches.wrapping_add(1);
                }
            }
            Phase::Fault => {
                self.alarm = true;
                self.valve_in = false;
                self.heater = false;
                self.valve_out = false;
                if !self.start {
                    self.alarm = false;
                    self.phase = Phase::Idle;
                }
            }
        }
    }
}

struct Machines {
    st: [Station; 32],
    level: [i16; 32],
    temp: [i16; 32],
}

impl Machines {
    fn new() -> Machines {
        Machines { st: [Station::NEW; 32], level: [0; 32], temp: [0; 32] }
    }

    #[inline(never)]
    fn scan(&mut self) {
        for i in 0..32 {
            let s = &mut self.st[i];
            s.start = !s.alarm;
            s.level = self.level[i];
            s.temp = self.temp[i];
            s.call();
            if s.valve_in {
                self.level[i] = self.level[i].wrapping_add(10).wrapping_add(i as i16);
            }
            if s.valve_out {
                self.level[i] = self.level[i].wrapping_sub(20);
            }
            if s.heater {
                self.temp[i] = self.temp[i].wrapping_add(3);
            } else if self.temp[i] > 20 {
                self.temp[i] = self.temp[i].wrapping_sub(1);
            }
        }
    }
}

fn state_machine_compare(st: &StCase, n: &Machines) {
    let mut c = Compare::default();
    for (i, s) in n.st.iter().enumerate() {
        c.var(st, &format!("level[{i}]"), n.level[i]);
        c.var(st, &format!("temp[{i}]"), n.temp[i]);
        c.var(st, &format!("st[{i}].phase"), s.phase as i32);
        c.var(st, &format!("st[{i}].ticks"), s.ticks);
        c.var(st, &format!("st[{i}].batches"), s.batches);
        c.var(st, &format!("st[{i}].alarm"), s.alarm);
        c.var(st, &format!("st[{i}].valve_in"), s.valve_in);
        c.var(st, &format!("st[{i}].heater"), s.heater);
        c.var(st, &format!("st[{i}].valve_out"), s.valve_out);
    }
    c.done("state_machine");
    let batches: i32 = n.st.iter().map(|s| s.batches).sum();
    assert!(batches > 0, "state_machine: no batch completed in {CHECK_SCANS} scans");
}

// ---------------------------------------------------------------------------------------------
// The matiec column (benches/matiec/)

/// The slot plcd's VM holds where matiec, scanning the same program, holds `matiec`: the same,
/// but for the FOR loops' control variables, which IEC 61131-3 leaves to the implementation
/// once a loop is done: matiec's FOR stops at the bound it reached, plcd's one step past it
/// (docs/ST.md), and these loops step by 1.
fn vm_slot_for_matiec(workload: &str, var: &str, matiec: u64) -> u64 {
    match (workload, var) {
        ("int_loops", "i" | "j") => matiec.wrapping_add(1),
        _ => matiec,
    }
}

/// Compares matiec's variables after each scan with the VM's, scan for scan.
fn matiec_compare(workload: &str, run: &matiec::Run) {
    let mut vm = st::case(workload);
    for (k, scan) in run.scans.iter().enumerate() {
        vm.checked_scan();
        let mut mismatches = Vec::new();
        for (var, slot) in scan {
            let (vm_slot, expected) = (vm.slot(var), vm_slot_for_matiec(workload, var, *slot));
            if vm_slot != expected {
                mismatches.push(format!("{var}: VM {vm_slot:#x}, matiec {slot:#x}"));
            }
        }
        assert!(
            mismatches.is_empty(),
            "{workload}: the VM and matiec disagree after scan {}:\n{}",
            k + 1,
            mismatches.join("\n")
        );
    }
}

/// Workload `name` with matiec, once iec2c is `ready`: its time per scan, or why it was not
/// run. Values that differ from the VM's fail the bench.
fn bench_matiec(name: &str, ready: &Result<(), String>) -> Result<f64, String> {
    ready.clone()?;
    let run = matiec::run_workload(name, CHECK_SCANS)?;
    matiec_compare(name, &run);
    Ok(run.ns_per_scan)
}

// ---------------------------------------------------------------------------------------------
// Measurement

/// A workload: its name, the VM steps one scan executed, and matiec's time per scan (or why
/// there is none).
struct Workload {
    name: &'static str,
    steps: u64,
    matiec: Result<f64, String>,
}

fn configure<'a>(
    c: &'a mut Criterion,
    name: &str,
) -> BenchmarkGroup<'a, criterion::measurement::WallTime> {
    let mut group = c.benchmark_group(format!("st_{name}"));
    group
        .sample_size(40)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    group
}

/// One workload (its ST side: [`st::case`]): both sides run `CHECK_SCANS` scans and `compare`
/// checks them; then fresh copies of both are measured side by side in one criterion group;
/// and matiec's build of it is checked and timed ([`bench_matiec`]).
fn bench_workload<N>(
    c: &mut Criterion,
    matiec: &Result<(), String>,
    name: &'static str,
    native: impl Fn() -> N,
    scan: fn(&mut N),
    compare: fn(&StCase, &N),
) -> Workload {
    let st = || st::case(name);
    let (mut vm, mut nat) = (st(), native());
    for _ in 0..CHECK_SCANS {
        vm.checked_scan();
        scan(&mut nat);
    }
    compare(&vm, &nat);
    let (mut jit, mut nat) = (st().with_native(), native());
    for _ in 0..CHECK_SCANS {
        jit.checked_scan();
        scan(&mut nat);
    }
    compare(&jit, &nat);

    let (mut vm, mut nat) = (st(), native());
    let mut jit = st().with_native();
    let steps = vm.steps_per_scan();
    let mut group = configure(c, name);
    group.bench_function("interpreter", |b| b.iter(|| vm.scan()));
    group.bench_function("compiled", |b| b.iter(|| jit.scan()));
    group.bench_function("rust", |b| b.iter(|| scan(black_box(&mut nat))));
    group.finish();
    Workload { name, steps, matiec: bench_matiec(name, matiec) }
}

fn bench_workloads(c: &mut Criterion, matiec: &Result<(), String>) -> Vec<Workload> {
    let m = matiec;
    vec![
        bench_workload(c, m, "bit", Bits::new, Bits::scan, bit_compare),
        bench_workload(c, m, "int_loops", IntLoops::new, IntLoops::scan, int_loops_compare),
        bench_workload(c, m, "pid", Pid::new, Pid::scan, pid_compare),
        bench_workload(c, m, "sort", Sort::new, Sort::scan, sort_compare),
        bench_workload(c, m, "state_machine", Machines::new, Machines::scan, state_machine_compare),
    ]
}

// ---------------------------------------------------------------------------------------------
// Compile time: a generated 10,000-line project

/// A project of `lines` lines (at least) in two files, as a plant's code might look: a library
/// of enumerations, structs, function blocks (a CASE sequence, timers, REAL scaling, alarms)
/// and functions, and a program that instantiates every block in arrays and calls each in a
/// FOR loop.
fn project(lines: usize) -> (String, String) {
    let mut lib = String::new();
    let mut blocks = 0;
    // The program: 8 lines, and 3 for each block.
    let main_lines = |blocks: usize| 8 + 3 * blocks;
    // One unit: an enumeration, a struct, a function and a function block, about 70 lines.
    while lib.lines().count() + main_lines(blocks) < lines {
        let k = blocks;
        lib.push_str(&format!(
            "TYPE\n    Step{k} : (Wait{k}, Run{k}, Hold{k}, Done{k});\n    Rec{k} : STRUCT\n        \
             raw : INT;\n        scaled : REAL;\n        ok : BOOL;\n    END_STRUCT;\nEND_TYPE\n\n"
        ));
        lib.push_str(&format!(
            "FUNCTION Scale{k} : REAL\nVAR_INPUT\n    raw : INT;\n    lo, hi : REAL;\nEND_VAR\n    \
             Scale{k} := lo + (hi - lo) * INT_TO_REAL(LIMIT(0, raw, 27648)) / 27648.0;\n\
             END_FUNCTION\n\n"
        ));
        lib.push_str(&format!(
            "FUNCTION_BLOCK Unit{k}\nVAR_INPUT\n    go : BOOL;\n    raw : INT;\n    limit : REAL := \
             {k}.5;\nEND_VAR\nVAR_OUTPUT\n    busy, alarm : BOOL;\n    count : DINT;\nEND_VAR\nVAR\n    \
             step : Step{k} := Wait{k};\n    rec : Rec{k};\n    delay : TON;\n    history : ARRAY \
             [0..7] OF REAL;\n    n, j : INT;\nEND_VAR\n    rec.raw := raw;\n    rec.scaled := \
             Scale{k}(raw := raw, lo := 0.0, hi := 100.0);\n    rec.ok := rec.scaled <= limit;\n    \
             delay(IN := step = Run{k}, PT := T#{k}ms);\n    CASE step OF\n        Wait{k}:\n            \
             IF go AND rec.ok THEN\n                step := Run{k};\n            END_IF;\n        \
             Run{k}:\n            busy := TRUE;\n            IF NOT rec.ok THEN\n                step \
             := Hold{k};\n            ELSIF delay.Q THEN\n                step := Done{k};\n            \
             END_IF;\n        Hold{k}:\n            alarm := TRUE;\n            IF rec.ok THEN\n                \
             alarm := FALSE;\n                step := Run{k};\n            END_IF;\n        Done{k}:\n            \
             busy := FALSE;\n            count := count + 1;\n            step := Wait{k};\n    \
             END_CASE;\n    history[n MOD 8] := rec.scaled;\n    n := n + 1;\n    \
             FOR j := 0 TO 7 DO\n        rec.scaled := MAX(rec.scaled, history[j]);\n    \
             END_FOR;\nEND_FUNCTION_BLOCK\n\n"
        ));
        blocks += 1;
    }
    let mut main = String::from("PROGRAM Plant\nVAR\n    i : INT;\n    total : DINT;\n");
    for k in 0..blocks {
        main.push_str(&format!("    u{k} : ARRAY [1..4] OF Unit{k};\n"));
    }
    main.push_str("    raw : ARRAY [1..4] OF INT;\nEND_VAR\n    FOR i := 1 TO 4 DO\n");
    for k in 0..blocks {
        main.push_str(&format!(
            "        u{k}[i](go := i MOD 2 = 0, raw := raw[i]);\n        total := total + u{k}[i].count;\n"
        ));
    }
    main.push_str("    END_FOR;\nEND_PROGRAM\n");
    (main, lib)
}

/// The project's files, checked once: it compiles, and has at least 10,000 lines.
fn ten_thousand_lines() -> (String, String, usize) {
    let (main, lib) = project(10_000);
    let lines = main.lines().count() + lib.lines().count();
    assert!(lines >= 10_000, "the generated project has {lines} lines");
    let c = compile_files(&[("main.st", &main), ("lib.st", &lib)]);
    assert!(c.programs[0].code.len() > 10_000, "{} ops", c.programs[0].code.len());
    (main, lib, lines)
}

fn bench_compile(c: &mut Criterion) -> usize {
    let (main, lib, lines) = ten_thousand_lines();
    let mut group = c.benchmark_group("st_compile");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(8));
    group.bench_function("10k_lines", |b| {
        b.iter(|| compile_files(black_box(&[("main.st", &main), ("lib.st", &lib)])))
    });
    group.bench_function("10k_lines_native", |b| {
        b.iter(|| {
            let c = compile_files(black_box(&[("main.st", &main), ("lib.st", &lib)]));
            plcd_native::compile(&c.programs[0]).unwrap_or_else(|e| panic!("{e}"))
        })
    });
    group.finish();
    lines
}

// ---------------------------------------------------------------------------------------------
// The fragment for BENCHMARKS.md

fn time(ns: f64) -> String {
    match ns {
        ns if ns >= 1e6 => format!("{:.1} ms", ns / 1e6),
        ns if ns >= 1e3 => format!("{:.2} µs", ns / 1e3),
        ns => format!("{ns:.0} ns"),
    }
}

fn report(workloads: &[Workload], lines: usize, since: SystemTime) {
    let not_run = || "not run".to_string();
    let ratio = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => Some(a / b),
        _ => None,
    };
    let mut rows = Vec::new();
    for w in workloads {
        let group = format!("st_{}", w.name);
        let interpreter = criterion_median_ns(&group, "interpreter", since);
        let compiled = criterion_median_ns(&group, "compiled", since);
        let rust = criterion_median_ns(&group, "rust", since);
        let matiec = w.matiec.as_ref().ok().copied();
        let verdict = |r: Option<f64>, at_most: f64| match r {
            Some(r) if r <= at_most => ": met",
            Some(_) => ": missed",
            None => "",
        };
        let target = format!(
            "≤ {TARGET_RATIO}× of Rust{}; ≤ matiec{}",
            verdict(ratio(compiled, rust), TARGET_RATIO),
            verdict(ratio(compiled, matiec), 1.0)
        );
        let times = |r: Option<f64>| r.map_or_else(not_run, |r| format!("{r:.1}×"));
        rows.push(vec![
            format!("`{}`", w.name),
            w.steps.to_string(),
            interpreter.map_or_else(not_run, time),
            compiled.map_or_else(not_run, time),
            rust.map_or_else(not_run, time),
            matiec.map_or_else(not_run, time),
            times(ratio(interpreter, rust)),
            times(ratio(compiled, rust)),
            times(ratio(compiled, matiec)),
            target,
        ]);
    }
    let mut f = Fragment::new(COMMAND);
    f.line(
        "Criterion's median time of one scan of each workload: the ST program on the \
         interpreter, the same with its native code (plcd-native), and the Rust, measured side \
         by side in this run; VM steps: the ops one scan executes (the same on both). \
         matiec + gcc -O2: the same program compiled as OpenPLC compiles a project (matiec's \
         iec2c with OpenPLC's flags, then gcc -O2 with matiec's C library) and run as \
         OpenPLC's runtime runs it (config_run__ once a cycle), the median of 301 batches of \
         at least 1 ms each, timed by its C harness (benches/matiec/harness.c) in this run; \
         its variables equal the VM's after each of the first 300 scans (REALs bit for bit; \
         int_loops' FOR variables i and j aside, which matiec leaves at the bound and plcd one \
         past it). pid and state_machine are compiled from benches/matiec/, the same program \
         without arrays of function block instances, which matiec does not have.\n",
    );
    f.table(
        &[
            "workload",
            "VM steps per scan",
            "interpreter",
            "native code",
            "Rust",
            "matiec + gcc -O2",
            "interpreter/Rust",
            "native code/Rust",
            "native code/matiec",
            "target",
        ],
        &rows,
    );
    // Each reason once (a failed set-up is every workload's), with the workloads it stopped.
    let mut stopped: Vec<(&str, Vec<String>)> = Vec::new();
    for w in workloads {
        if let Err(why) = &w.matiec {
            let name = format!("`{}`", w.name);
            match stopped.iter_mut().find(|(reason, _)| reason == why) {
                Some((_, names)) => names.push(name),
                None => stopped.push((why, vec![name])),
            }
        }
    }
    for (why, names) in stopped {
        f.line(format!("\nmatiec, {}: not run ({why})\n", names.join(", ")));
    }
    let compile = criterion_median_ns("st_compile", "10k_lines", since);
    let with_native = criterion_median_ns("st_compile", "10k_lines_native", since);
    let verdict = |ns: f64| if ns / 1e9 < TARGET_COMPILE_S { "met" } else { "missed" };
    let row = |what: &str, median: Option<f64>| {
        vec![
            what.to_string(),
            lines.to_string(),
            median.map_or_else(not_run, time),
            median.map_or_else(
                || format!("< {TARGET_COMPILE_S} s"),
                |ns| format!("< {TARGET_COMPILE_S} s: {}", verdict(ns)),
            ),
        ]
    };
    f.table(
        &["project (`project` in benches/st_native.rs)", "lines", "median", "target"],
        &[row("parse + compile", compile), row("parse + compile + native code", with_native)],
    );
    if let Err(e) = write_fragment("st_native", &f) {
        eprintln!("cannot write the fragment: {e}");
    }
}

fn main() {
    let since = SystemTime::now();
    // `cargo bench` passes --bench; `cargo test --benches` does not, and `--test` (run each
    // benchmark once) and `--list` measure nothing, nor need iec2c built.
    let args: Vec<String> = std::env::args().collect();
    let measured = |a: &String| a == "--bench";
    let probe = |a: &String| a == "--test" || a == "--list";
    let measuring = args.iter().any(measured) && !args.iter().any(probe);
    let matiec = if measuring { matiec::setup() } else { Err("not measuring".to_string()) };
    let mut c = Criterion::default().configure_from_args();
    let workloads = bench_workloads(&mut c, &matiec);
    let lines = bench_compile(&mut c);
    c.final_summary();
    for w in &workloads {
        let matiec =
            w.matiec.as_ref().map_or_else(|why| format!("not run ({why})"), |&ns| time(ns));
        eprintln!("{}: {} VM steps per scan; matiec + gcc -O2: {matiec}", w.name, w.steps);
    }
    if measuring {
        report(&workloads, lines, since);
    }
}
