//! VM speed: ns per executed instruction by category, each beside the same logic written
//! directly in Rust (the physical-limit baseline), and the scan time of a realistic
//! 10,000-step plant program.
//!
//! `cargo bench --bench vm` (criterion filters work: `cargo bench --bench vm -- bit`). After
//! criterion has run, the bench reads criterion's own medians back and writes the fragment
//! `target/bench-results/vm.md` for BENCHMARKS.md; a category whose result was not produced by
//! this run reads "not run".
//!
//! Every category is a generated program (`benches/common/il_workloads.rs`, shared with the
//! instruction-count guard `benches/counts.rs`) executed the way the engine executes a scan
//! (`ExecState::restart`, then `Vm::run` to `END`); its throughput is the number of
//! instructions the VM counted in one scan (`Vm::steps`). The native baseline executes the same
//! rungs as straight Rust code over a flat array of u16 words, with operand addresses taken
//! from a pre-resolved table (as the VM's ops carry them), without dispatch and without bounds
//! checks on device memory. Before measuring, the bench checks for every category that one
//! native scan leaves device memory exactly as one VM scan does.

use std::hint::black_box;
use std::time::{Duration, SystemTime};

use criterion::{Criterion, Throughput};
use plcd::bench::report::criterion_median_ns as median_ns;
use plcd::bench::{write_fragment, Fragment};
use plcd::device::{BitRef, WordRef};
use plcd::vm::Vm;

#[path = "common/il_workloads.rs"]
mod il;
use il::{
    bit, word, BitGroup, CmpGroup, CounterRef, Station, TcGroup, TimerRef, VmCase, Workload,
    STEP_NS, TOGGLE,
};

const COMMAND: &str = "cargo bench --bench vm";
/// The target of native code on bit logic, in ns per instruction (a Siemens S7-1518: 1 ns).
const BIT_NATIVE_TARGET: f64 = 0.3;

/// Device memory for the native code: the VM's layout, as a fixed array that a u16 index cannot
/// leave (so the native code has no bounds checks).
struct Words(Box<[u16; 65536]>);

impl Words {
    fn of(vm: &Vm) -> Words {
        let mut words: Box<[u16; 65536]> = vec![0; 65536].into_boxed_slice().try_into().unwrap();
        let image = vm.mem.words();
        words[..image.len()].copy_from_slice(image);
        Words(words)
    }
    #[inline(always)]
    fn bit(&self, b: BitRef) -> bool {
        self.0[b.word as usize] & b.mask != 0
    }
    #[inline(always)]
    fn set(&mut self, b: BitRef, on: bool) {
        let w = &mut self.0[b.word as usize];
        *w = if on { *w | b.mask } else { *w & !b.mask };
    }
    #[inline(always)]
    fn get(&self, w: WordRef) -> i16 {
        self.0[w.0 as usize] as i16
    }
    #[inline(always)]
    fn put(&mut self, w: WordRef, v: i16) {
        self.0[w.0 as usize] = v as u16;
    }
    /// Toggles input bits, as an input refresh would: the part sensors of the realistic
    /// program and the counter/timer inputs of `timers_counters`.
    fn toggle_inputs(&mut self) {
        for w in &mut self.0[..48] {
            *w ^= TOGGLE;
        }
    }
}

/// Fails the bench if one native scan does not leave memory exactly as one VM scan does. (For
/// timers this holds for the first scan, where no timer has seen time pass yet.)
fn check_same(workload: &Workload, scan: impl FnOnce(&mut Words)) {
    let mut case = VmCase::of(workload);
    let mut native = Words::of(&case.vm);
    case.scan();
    scan(&mut native);
    let image = case.vm.mem.words();
    if let Some(i) = (0..image.len()).find(|&i| image[i] != native.0[i]) {
        let name = workload.name;
        panic!("{name}: native and VM disagree at word {i}: {:#x} vs {:#x}", native.0[i], image[i]);
    }
}

/// Fails the bench if the program's native code (plcd-native) does not leave memory and the
/// step count exactly as the interpreter does, over a few scans with the category's inputs.
fn check_native_code(workload: &Workload) {
    let mut interpreted = VmCase::of(workload);
    let mut coded = VmCase::of(workload).with_native();
    for scan in 0..4 {
        interpreted.iteration();
        coded.iteration();
        let (a, b) = (interpreted.vm.mem.words(), coded.vm.mem.words());
        if let Some(i) = (0..a.len()).find(|&i| a[i] != b[i]) {
            let name = workload.name;
            panic!(
                "{name}: native code and the interpreter disagree after scan {scan} at word {i}: \
                 {:#x} vs {:#x}",
                b[i], a[i]
            );
        }
        assert_eq!(interpreted.vm.steps(), coded.vm.steps(), "{}: steps", workload.name);
    }
}

// ---------------------------------------------------------------------------------------------
// The Rust baseline of each category; the programs and operands: benches/common/il_workloads.rs

// bit

fn bit_native(w: &mut Words, groups: &[BitGroup]) {
    for g in groups {
        let [a, b, c, d] = g.a;
        let r = (w.bit(a) & w.bit(b)) | w.bit(c);
        w.set(d, r);
        let [a, b, c, d, e] = g.b;
        let r = ((!w.bit(a) & !w.bit(b)) | !w.bit(c)) & w.bit(d);
        if r {
            w.set(e, true);
        }
        let [a, b, c, d] = g.c;
        if (w.bit(a) | w.bit(b)) & !w.bit(c) {
            w.set(d, false);
        }
        let [a, b, c, d, e, f] = g.d;
        let r = w.bit(a) & w.bit(b) & !w.bit(c);
        w.set(d, r);
        let r = r & w.bit(e);
        w.set(f, r);
    }
}

// compare_arith

fn compare_arith_native(w: &mut Words, groups: &[CmpGroup]) {
    for g in groups {
        let [a, b, c, d, e] = g.a;
        if (w.get(a) >= w.get(b)) & (w.get(c) < 1000) {
            w.put(e, w.get(d));
        }
        let [a, b, c, d] = g.b;
        if (w.get(a) == 0) | (w.get(b) != w.get(c)) {
            w.put(d, w.get(a).wrapping_add(w.get(b)));
        }
        let [a, b, d, e] = g.c;
        if (w.get(a) > w.get(b)) & w.bit(g.cx) {
            w.put(d, w.get(a).wrapping_sub(7));
            w.put(e, w.get(b).wrapping_mul(3));
        }
        let [a, b, c, d, e] = g.d;
        if (w.get(a) <= w.get(b)) & !w.bit(g.dx) {
            w.put(d, w.get(c) / 5);
            w.put(e, w.get(e).wrapping_add(1));
        }
        let [a, d, e] = g.e;
        if w.get(a) != 100 {
            w.put(d, 42);
            w.put(e, w.get(e).wrapping_sub(1));
        }
    }
}

// timers_counters

/// Native timer and counter state, as a hand-written controller would keep it.
#[derive(Clone, Copy, Default)]
struct NTimer {
    elapsed: u64,
    last: u64,
    running: bool,
    prev: bool,
}

#[derive(Clone, Copy, PartialEq)]
enum TKind {
    Ton,
    Toff,
    Tmr,
    Tmon,
    Trtg,
}

#[inline(always)]
fn timer(
    kind: TKind,
    t: TimerRef,
    ts: &mut [NTimer],
    w: &mut Words,
    input: bool,
    preset: u16,
    now: u64,
) {
    let s = &mut ts[t.n];
    let preset_ns = u64::from(preset) * t.base_ns;
    let rising = input && !s.prev;
    s.prev = input;
    let ticks = |e: u64| (e / t.base_ns).min(u64::from(preset)) as u16;
    let run = |s: &mut NTimer| {
        if s.running {
            s.elapsed += now - s.last;
        } else {
            s.running = true;
            s.elapsed = 0;
        }
        s.last = now;
    };
    let down = |s: &mut NTimer| {
        let v = preset - ticks(s.elapsed);
        s.running &= v > 0;
        (v, v > 0)
    };
    let (value, done) = match kind {
        TKind::Ton if input => {
            run(s);
            s.elapsed = s.elapsed.min(preset_ns);
            let v = ticks(s.elapsed);
            (v, v >= preset)
        }
        TKind::Ton => {
            *s = NTimer::default();
            (0, false)
        }
        TKind::Tmr => {
            if input {
                if s.running {
                    s.elapsed += now - s.last;
                }
                s.running = true;
                s.last = now;
                s.elapsed = s.elapsed.min(preset_ns);
            } else {
                s.running = false;
            }
            let v = ticks(s.elapsed);
            (v, v >= preset)
        }
        TKind::Toff if input => {
            s.running = false;
            s.elapsed = 0;
            (preset, true)
        }
        TKind::Toff if w.bit(t.done) => {
            run(s);
            down(s)
        }
        TKind::Toff => (0, false),
        TKind::Tmon | TKind::Trtg => {
            if rising && (kind == TKind::Trtg || !s.running) {
                s.running = true;
                s.elapsed = 0;
                s.last = now;
            } else if s.running {
                s.elapsed += now - s.last;
                s.last = now;
            }
            if s.running {
                down(s)
            } else {
                (0, false)
            }
        }
    };
    w.put(t.value, value as i16);
    w.set(t.done, done);
}

#[derive(Clone, Copy, Default)]
struct NCounter {
    prev: bool,
    loaded: bool,
}

#[derive(Clone, Copy)]
enum CKind {
    Ctu,
    Ctd,
    Ctr,
}

#[inline(always)]
fn counter(
    kind: CKind,
    c: CounterRef,
    cs: &mut [NCounter],
    w: &mut Words,
    input: bool,
    preset: u16,
) {
    let s = &mut cs[c.n];
    let rising = input && !s.prev;
    s.prev = input;
    let mut v = w.get(c.value) as u16;
    let done = match kind {
        CKind::Ctu => {
            v = v.saturating_add(rising as u16);
            v >= preset
        }
        CKind::Ctd => {
            if !s.loaded {
                s.loaded = true;
                v = preset;
            }
            v = v.saturating_sub(rising as u16);
            v == 0
        }
        CKind::Ctr => {
            if rising {
                v = if v >= preset { 0 } else { v + 1 };
            }
            v >= preset
        }
    };
    w.put(c.value, v as i16);
    w.set(c.done, done);
}

struct TcState {
    timers: Vec<NTimer>,
    counters: Vec<NCounter>,
    now: u64,
}

fn timers_counters_native(w: &mut Words, st: &mut TcState, groups: &[TcGroup]) {
    let now = st.now;
    let (ts, cs) = (&mut st.timers[..], &mut st.counters[..]);
    for g in groups {
        let (x, y) = (&g.x, &g.y);
        let [t0, t1, t2, t3, t4] = g.timers;
        let [c0, c1, c2] = g.counters;
        let r = w.bit(x[0]) & w.bit(y[0]);
        timer(TKind::Ton, t0, ts, w, r, 50, now);
        let r = w.bit(t0.done) & !w.bit(y[1]);
        w.set(g.out, r);
        let r = w.bit(x[1]) & w.bit(y[2]);
        counter(CKind::Ctu, c0, cs, w, r, 100);
        if w.bit(c0.done) | w.bit(y[3]) {
            w.put(c0.value, 0);
            w.set(c0.done, false);
        }
        let r = !w.bit(x[2]) & w.bit(y[4]);
        timer(TKind::Toff, t1, ts, w, r, 20, now);
        let r = w.bit(x[3]) & w.bit(y[5]);
        counter(CKind::Ctd, c1, cs, w, r, 5);
        let r = w.bit(x[4]) & w.bit(y[6]);
        timer(TKind::Tmr, t2, ts, w, r, 100, now);
        let r = w.bit(x[5]) & w.bit(y[7]);
        timer(TKind::Tmon, t3, ts, w, r, 30, now);
        let r = w.bit(x[6]) & w.bit(y[8]);
        counter(CKind::Ctr, c2, cs, w, r, 7);
        let r = w.bit(x[7]) & w.bit(y[9]);
        timer(TKind::Trtg, t4, ts, w, r, 30, now);
    }
}

// call

/// The devices of the subroutines (`il::SUBROUTINES`), resolved.
struct Subs {
    b: [BitRef; 18],
    d: [WordRef; 7],
}

impl Subs {
    fn new() -> Subs {
        let b = [
            "P0100", "M2000", "M2001", "M2002", "P0101", "M2003", "M2004", "P0102", "M2005",
            "M2006", "M2007", "M2008", "P0103", "M2009", "M200A", "M200B", "P0104", "M200C",
        ];
        Subs { b: b.map(bit), d: std::array::from_fn(|i| word(&format!("D{:05}", 20_000 + i))) }
    }
}

#[inline(never)]
fn sub0(w: &mut Words, s: &Subs) {
    let r = w.bit(s.b[0]) & w.bit(s.b[1]);
    w.set(s.b[2], r);
}
#[inline(never)]
fn sub1(w: &mut Words, s: &Subs) {
    let r = (w.bit(s.b[3]) | w.bit(s.b[4])) & !w.bit(s.b[5]);
    w.set(s.b[6], r);
}
#[inline(never)]
fn sub2(w: &mut Words, s: &Subs) {
    if w.get(s.d[0]) >= w.get(s.d[1]) {
        w.put(s.d[3], w.get(s.d[2]));
    }
}
#[inline(never)]
fn sub3(w: &mut Words, s: &Subs) {
    if w.bit(s.b[7]) {
        w.put(s.d[5], w.get(s.d[4]).wrapping_add(1));
    }
}
#[inline(never)]
fn sub4(w: &mut Words, s: &Subs) {
    if w.bit(s.b[8]) & w.bit(s.b[9]) & w.bit(s.b[10]) {
        w.set(s.b[11], true);
    }
}
#[inline(never)]
fn sub5(w: &mut Words, s: &Subs) {
    if !w.bit(s.b[12]) {
        w.set(s.b[13], false);
    }
}
#[inline(never)]
fn sub6(w: &mut Words, s: &Subs) {
    let r = w.bit(s.b[14]);
    w.set(s.b[15], r);
    let r = r & w.bit(s.b[16]);
    w.set(s.b[17], r);
}
#[inline(never)]
fn sub7(w: &mut Words, s: &Subs) {
    w.put(s.d[6], w.get(s.d[6]).wrapping_add(1));
}

fn call_native(w: &mut Words, subs: &Subs, groups: &[[BitRef; 8]]) {
    for g in groups {
        if w.bit(g[0]) {
            sub0(w, subs);
        }
        if w.bit(g[1]) {
            sub1(w, subs);
        }
        if w.bit(g[2]) {
            sub2(w, subs);
        }
        if w.bit(g[3]) {
            sub3(w, subs);
        }
        if w.bit(g[4]) {
            sub4(w, subs);
        }
        if w.bit(g[5]) {
            sub5(w, subs);
        }
        if w.bit(g[6]) {
            sub6(w, subs);
        }
        if w.bit(g[7]) {
            sub7(w, subs);
        }
    }
}

// realistic_10k

struct Globals {
    estop_ok: BitRef,
    auto: BitRef,
    reset: BitRef,
    lamp_test: BitRef,
    t1s: BitRef,
    horn: BitRef,
    alarms: WordRef,
}

impl Globals {
    fn new() -> Globals {
        Globals {
            estop_ok: bit("M2500"),
            auto: bit("M2501"),
            reset: bit("M2502"),
            lamp_test: bit("M2503"),
            t1s: bit("_T1S"),
            horn: bit("M2510"),
            alarms: word("D30000"),
        }
    }
}

#[inline(never)]
fn alarm_handler(w: &mut Words, g: &Globals) {
    w.put(g.alarms, w.get(g.alarms).wrapping_add(1));
    if w.get(g.alarms) >= 30000 {
        w.put(g.alarms, 0);
    }
    let r = w.bit(g.t1s);
    w.set(g.horn, r);
}

fn realistic_native(w: &mut Words, tc: &mut TcState, g: &Globals, stations: &mut [Station]) {
    let now = tc.now;
    let (ts, cs) = (&mut tc.timers[..], &mut tc.counters[..]);
    for st in stations {
        let (i, o, a, b, t, d) = (st.i, st.o, st.a, st.b, st.t, st.d);
        let r = (w.bit(i[0]) | w.bit(a[0])) & !w.bit(i[1]) & w.bit(g.estop_ok) & !w.bit(a[15]);
        w.set(a[0], r);
        timer(TKind::Ton, t[0], ts, w, w.bit(a[0]), 30, now);
        let run = w.bit(a[0]);
        w.set(o[0], run & !w.bit(t[0].done));
        w.set(o[1], run & w.bit(t[0].done));
        if w.bit(i[2]) | w.bit(i[3]) {
            w.set(a[15], true);
        }
        if w.bit(g.reset) & !w.bit(i[2]) & !w.bit(i[3]) {
            w.set(a[15], false);
        }
        let r = (w.bit(a[15]) & w.bit(g.t1s)) | w.bit(g.lamp_test);
        w.set(o[2], r);
        let r = ((w.bit(i[4]) & w.bit(i[5])) | (w.bit(i[6]) & !w.bit(i[7]))) & w.bit(a[0]);
        w.set(a[1], r);
        w.set(o[3], w.bit(a[1]));
        let part = w.bit(i[8]);
        let rising = part & !st.edge[0];
        st.edge[0] = part;
        counter(CKind::Ctu, st.c, cs, w, rising & w.bit(a[1]), 100);
        w.set(a[2], w.bit(st.c.done));
        if w.bit(a[2]) & w.bit(g.reset) {
            w.put(st.c.value, 0);
            w.set(st.c.done, false);
        }
        w.put(d[1], w.get(d[0]));
        w.put(d[2], w.get(d[1]).wrapping_sub(800));
        w.put(d[3], w.get(d[2]).wrapping_mul(10));
        w.put(d[4], w.get(d[3]) / 32);
        w.set(a[3], w.get(d[4]) >= w.get(d[5]));
        w.set(a[4], (w.get(d[4]) < w.get(d[6])) & w.bit(a[0]));
        timer(TKind::Ton, t[1], ts, w, w.bit(a[3]) | w.bit(a[4]), 20, now);
        if w.bit(t[1].done) {
            w.set(b[1], true);
        }
        if w.bit(g.reset) & !w.bit(a[3]) {
            w.set(b[1], false);
        }
        timer(TKind::Toff, t[2], ts, w, w.bit(a[0]), 50, now);
        w.set(o[4], w.bit(t[2].done));
        let conveying = w.bit(a[1]);
        if conveying & !st.edge[1] {
            w.put(d[7], w.get(d[7]).wrapping_add(1));
        }
        st.edge[1] = conveying;
        if w.get(d[7]) >= 10000 {
            w.put(d[7], 0);
        }
        let auto = w.bit(g.auto);
        w.set(b[2], auto & w.bit(a[0]) & !w.bit(b[1]));
        w.set(b[3], auto & w.bit(a[2]));
        w.set(b[4], auto & !w.bit(a[0]));
        w.set(o[5], w.bit(b[2]) & w.bit(i[9]) & !w.bit(i[10]));
        let r = ((w.bit(b[2]) & w.bit(i[10])) | w.bit(o[6])) & !w.bit(i[11]);
        w.set(o[6], r);
        timer(TKind::Ton, t[3], ts, w, w.bit(a[1]) & w.bit(i[12]), 50, now);
        if w.bit(t[3].done) {
            w.set(a[15], true);
        }
        w.set(b[5], w.bit(a[0]) & !w.bit(a[15]));
        w.set(o[7], w.bit(b[5]));
        if w.bit(b[1]) {
            alarm_handler(w, g);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Measurement

struct Category {
    name: &'static str,
    /// Instructions the VM executes in one scan.
    steps: u64,
    /// The target in ns per instruction: 3 for bit logic, 6 for the mixed categories.
    target: f64,
}

fn configure<'a>(
    c: &'a mut Criterion,
    name: &str,
    steps: u64,
) -> criterion::BenchmarkGroup<'a, criterion::measurement::WallTime> {
    let mut group = c.benchmark_group(name);
    group
        .sample_size(40)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .throughput(Throughput::Elements(steps));
    group
}

/// One category, with its target in ns per instruction: one scan of the VM and of `check` must
/// leave the same memory, then the VM and `native` (given the steps of a scan) are measured
/// side by side in one criterion group. When the category's inputs toggle, they toggle before
/// every scan on both sides; the native side's clock is advanced by the caller's closure.
fn bench_category(
    c: &mut Criterion,
    workload: &Workload,
    target: f64,
    check: impl FnOnce(&mut Words),
    mut native: impl FnMut(&mut Words, u64),
) -> Category {
    check_same(workload, check);
    check_native_code(workload);
    let mut case = VmCase::of(workload);
    let mut coded = VmCase::of(workload).with_native();
    let mut words = Words::of(&case.vm);
    let steps = case.steps_per_scan();
    let mut group = configure(c, workload.name, steps);
    group.bench_function("vm", |b| b.iter(|| case.iteration()));
    group.bench_function("native_code", |b| b.iter(|| coded.iteration()));
    if workload.toggles {
        group.bench_function("native", |b| {
            b.iter(|| {
                words.toggle_inputs();
                native(black_box(&mut words), steps)
            })
        });
    } else {
        group.bench_function("native", |b| b.iter(|| native(black_box(&mut words), steps)));
    }
    group.finish();
    Category { name: workload.name, steps, target }
}

fn bench_all(c: &mut Criterion) -> Vec<Category> {
    let fresh_tc = || TcState {
        timers: vec![NTimer::default(); 2048],
        counters: vec![NCounter::default(); 2048],
        now: 0,
    };
    let mut categories = Vec::new();

    let (workload, groups) = il::bit_category();
    categories.push(bench_category(
        c,
        &workload,
        3.0,
        |w| bit_native(w, &groups),
        |w, _| bit_native(w, black_box(&groups)),
    ));

    let (workload, groups) = il::compare_arith_category();
    categories.push(bench_category(
        c,
        &workload,
        6.0,
        |w| compare_arith_native(w, &groups),
        |w, _| compare_arith_native(w, black_box(&groups)),
    ));

    let (workload, groups) = il::timers_counters_category();
    let mut tc = fresh_tc();
    categories.push(bench_category(
        c,
        &workload,
        6.0,
        |w| timers_counters_native(w, &mut fresh_tc(), &groups),
        |w, steps| {
            tc.now += steps * STEP_NS;
            timers_counters_native(w, &mut tc, black_box(&groups))
        },
    ));

    let (workload, groups) = il::call_category();
    let subs = Subs::new();
    categories.push(bench_category(
        c,
        &workload,
        6.0,
        |w| call_native(w, &subs, &groups),
        |w, _| call_native(w, &subs, black_box(&groups)),
    ));

    let (workload, mut stations) = il::realistic_category();
    let globals = Globals::new();
    let check_stations = stations.clone();
    let mut tc = fresh_tc();
    categories.push(bench_category(
        c,
        &workload,
        6.0,
        |w| realistic_native(w, &mut fresh_tc(), &globals, &mut check_stations.clone()),
        |w, steps| {
            tc.now += steps * STEP_NS;
            realistic_native(w, &mut tc, &globals, black_box(&mut stations))
        },
    ));

    for c in &categories {
        eprintln!("{}: {} instructions executed per scan", c.name, c.steps);
    }
    categories
}

// ---------------------------------------------------------------------------------------------
// The fragment for BENCHMARKS.md

fn report(categories: &[Category], since: SystemTime) {
    let not_run = || "not run".to_string();
    let mut rows = Vec::new();
    let (mut bit_interpreter, mut bit_code) = (None, None);
    for c in categories {
        let per = |id: &str| median_ns(c.name, id, since).map(|ns| ns / c.steps as f64);
        let (vm, code, rust) = (per("vm"), per("native_code"), per("native"));
        if c.name == "bit" {
            (bit_interpreter, bit_code) = (vm, code);
        }
        let ratio = |a: Option<f64>| match (a, rust) {
            (Some(a), Some(r)) => format!("{:.1}×", a / r),
            _ => not_run(),
        };
        let met = |ok: bool| if ok { "met" } else { "missed" };
        let mut targets = match vm {
            Some(v) => format!("interpreter ≤ {} ns: {}", c.target, met(v <= c.target)),
            None => format!("interpreter ≤ {} ns", c.target),
        };
        if let (Some(code), Some(rust)) = (code, rust) {
            targets.push_str(&format!("; native code ≤ 2× of Rust: {}", met(code <= 2.0 * rust)));
            if c.name == "bit" {
                targets.push_str(&format!(
                    ", ≤ {BIT_NATIVE_TARGET} ns: {}",
                    met(code <= BIT_NATIVE_TARGET)
                ));
            }
        }
        rows.push(vec![
            format!("`{}`", c.name),
            c.steps.to_string(),
            vm.map_or_else(not_run, |v| format!("{v:.2}")),
            code.map_or_else(not_run, |v| format!("{v:.2}")),
            rust.map_or_else(not_run, |v| format!("{v:.2}")),
            ratio(vm),
            ratio(code),
            targets,
        ]);
    }
    let mut f = Fragment::new(COMMAND);
    f.line(
        "ns/instr: criterion's median scan time divided by the instructions the VM executed in \
         that scan (the same count on the interpreter and with native code); the Rust column \
         divides the Rust scan time by the same count. The three were measured side by side \
         in this run.\n",
    );
    f.table(
        &[
            "category",
            "executed per scan",
            "ns/instr interpreter",
            "ns/instr native code",
            "ns/instr Rust",
            "interpreter/Rust",
            "native code/Rust",
            "targets",
        ],
        &rows,
    );
    let anchors = [
        ("LS XBC E-type", 670.0),
        ("Mitsubishi FX5U", 34.0),
        ("Siemens S7-1516", 10.0),
        ("Siemens S7-1518", 1.0),
    ];
    let rows: Vec<Vec<String>> = anchors
        .iter()
        .map(|&(plc, ns)| {
            let cmp = |plcd: Option<f64>| match plcd {
                Some(b) if b <= ns => format!("{:.1}× faster", ns / b),
                Some(b) => format!("{:.1}× slower", b / ns),
                None => not_run(),
            };
            vec![plc.to_string(), format!("{ns}"), cmp(bit_interpreter), cmp(bit_code)]
        })
        .collect();
    f.table(
        &["PLC", "ns per bit instruction", "plcd `bit`, interpreter", "plcd `bit`, native code"],
        &rows,
    );
    for paragraph in HOW {
        f.line(*paragraph).line("");
    }
    if let Err(e) = write_fragment("vm", &f) {
        eprintln!("cannot write the fragment: {e}");
    }
}

/// How the VM gets there, for the fragment.
const HOW: &[&str] = &[
    "How: each source instruction is one pre-decoded 16-byte `Op` (`repr(u8)`, operands \
     resolved to word indices and masks); the interpreter is one `match` compiled to a jump \
     table, run in chunks bounded by the step budget and the end of the code, so an instruction \
     costs one byte load, one indirect jump and one end test besides its own work.",
    "The rung result, the block and MPUSH stacks and the budget stay in registers; device \
     memory is a `&mut` parameter of its own, so the word array's address and length stay in \
     registers too, and timers and counters never touch memory themselves (the loop reads \
     their inputs and writes their results), so nothing the loop calls can move the words.",
    "No branch depends on device data: outputs, SET/RST and data instructions always store (the \
     old value when the rung is OFF) and compares evaluate through a truth table. What is left \
     per instruction is the dispatch and a bounds check on each device access.",
    "Native code: the program compiled by plcd-native (Cranelift) as a project load does, \
     timers, counters, edges and calls included (it would be attached even where a load \
     leaves a program to the interpreter; none of these five is such a program). Before \
     measuring, the bench checks that four scans leave memory and the step count exactly as \
     on the interpreter.",
    "Rust: the same rungs as straight Rust over a flat u16 array, operands from a \
     pre-resolved table, no dispatch, no bounds checks on device memory; timers and counters \
     as hand-written state machines. Before measuring, the bench checks that one Rust scan \
     leaves memory exactly as one VM scan.",
];

fn main() {
    let since = SystemTime::now();
    let mut c = Criterion::default().configure_from_args();
    let categories = bench_all(&mut c);
    c.final_summary();
    // `cargo bench` passes --bench; `cargo test --benches` does not, and `--test` (run each
    // benchmark once) and `--list` measure nothing.
    let args: Vec<String> = std::env::args().collect();
    let measured = |a: &String| a == "--bench";
    let probe = |a: &String| a == "--test" || a == "--list";
    if args.iter().any(measured) && !args.iter().any(probe) {
        report(&categories, since);
    }
}
