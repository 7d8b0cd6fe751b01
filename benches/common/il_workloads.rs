//! The instruction-list workloads of the VM benches, shared by `benches/vm.rs` (criterion:
//! time, beside the same logic in Rust) and `benches/counts.rs` (Valgrind: instructions, the CI
//! guard of BENCHMARKS.md): each category's generated program, how its memory starts, whether
//! its inputs toggle before every scan, and one scan as the engine runs it ([`VmCase`]), on the
//! interpreter or with the program's native code attached. The
//! generators also return the rungs' operands, resolved, for the Rust baseline of `vm.rs`:
//! they come from the same random draws as the program text, so they are made together.
//!
//! Included with `#[path]` by each bench; a bench uses only part of it (the guard has no Rust
//! baseline and reads no operands), hence the `dead_code` allowance.
#![allow(dead_code)]

use std::hint::black_box;
use std::path::Path;

use plcd::device::{Address, BitRef, WordRef};
use plcd::lang::{self, Context, Program};
use plcd::vm::{ExecState, Exit, StepClock, Vm};

/// Virtual time one instruction costs, for the timers (a 10,000-step scan is 10 ms).
pub const STEP_NS: u64 = 1000;

// ---------------------------------------------------------------------------------------------
// Program text and operands

pub fn timer_base(n: u32) -> Option<u32> {
    Some(match n {
        0..=999 => 100,
        1000..=1499 => 10,
        _ => 1,
    })
}

pub fn base_ns(n: u32) -> u64 {
    u64::from(timer_base(n).unwrap()) * 1_000_000
}

pub fn assemble(source: &str) -> Program {
    let ctx =
        Context { is_init: false, task_numbers: &[], timer_base_ms: &timer_base, edge_base: 0 };
    match lang::assemble("bench", Path::new("bench.il"), source, &ctx) {
        Ok(program) => program,
        Err(diagnostics) => panic!("bench program does not assemble: {diagnostics:?}"),
    }
}

pub fn bit(text: &str) -> BitRef {
    Address::parse(text).unwrap().as_bit().unwrap()
}

pub fn word(text: &str) -> WordRef {
    Address::parse(text).unwrap().as_word().unwrap()
}

/// A small deterministic generator (xorshift), so every run benchmarks the same programs.
pub struct Rng(u32);

impl Rng {
    pub fn below(&mut self, n: u32) -> u32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        self.0 % n
    }
    /// A contact's device: an input P000–P063 or an internal M bit.
    pub fn input(&mut self) -> String {
        if self.below(2) == 0 {
            format!("P{:03}{:X}", self.below(64), self.below(16))
        } else {
            format!("M{:03}{:X}", self.below(256), self.below(16))
        }
    }
    /// An output: an M bit, or one of the outputs P064–P127.
    pub fn output(&mut self) -> String {
        if self.below(4) == 0 {
            format!("P{:03}{:X}", 64 + self.below(64), self.below(16))
        } else {
            format!("M{:03}{:X}", self.below(256), self.below(16))
        }
    }
    pub fn d(&mut self, n: u32) -> String {
        format!("D{:05}", self.below(n))
    }
}

/// Source text with one instruction a line.
#[derive(Default)]
pub struct Source(String);

impl Source {
    pub fn op(&mut self, line: impl AsRef<str>) {
        self.0.push_str(line.as_ref());
        self.0.push('\n');
    }
}

/// The input bits a toggling category flips before every scan, in P000–P047 (bits 0 and 8), as
/// an input refresh would: the part sensors of `realistic_10k` and the timer and counter inputs
/// of `timers_counters`.
pub const TOGGLE: u16 = 0x0101;

/// A category's program, how its memory starts, and whether its inputs toggle before every
/// scan. Each generator returns it with the operands of its rungs, resolved for the Rust
/// baseline of `benches/vm.rs`.
pub struct Workload {
    pub name: &'static str,
    pub source: String,
    pub init: fn(&mut Vm),
    /// Inputs toggle ([`TOGGLE`]) before every scan (VM and Rust baseline alike), so that
    /// timers and counters see edges and run.
    pub toggles: bool,
}

/// The categories, in the order the benches run them.
pub const CATEGORIES: [&str; 5] =
    ["bit", "compare_arith", "timers_counters", "call", "realistic_10k"];

/// The VM of category `name`, ready for its first scan.
pub fn case(name: &str) -> VmCase {
    let workload = match name {
        "bit" => bit_category().0,
        "compare_arith" => compare_arith_category().0,
        "timers_counters" => timers_counters_category().0,
        "call" => call_category().0,
        "realistic_10k" => realistic_category().0,
        _ => panic!("no category {name} (one of {CATEGORIES:?})"),
    };
    VmCase::of(&workload)
}

/// One VM executing one category's program.
pub struct VmCase {
    pub program: Program,
    pub vm: Vm,
    pub state: ExecState,
    pub clock: StepClock,
    /// The category's inputs toggle before every scan ([`Workload::toggles`]).
    pub toggles: bool,
}

impl VmCase {
    pub fn of(workload: &Workload) -> VmCase {
        let program = assemble(&workload.source);
        let mut vm = Vm::for_programs([&program]);
        (workload.init)(&mut vm);
        let clock = StepClock { origin_ns: 0, origin_steps: 0, step_ns: STEP_NS };
        VmCase { program, vm, state: ExecState::new(), clock, toggles: workload.toggles }
    }

    /// The same program with its native code attached (`plcd_native`), even where a project
    /// load would leave it to the interpreter (`plcd_native::Error::Slower`: `timers_counters`,
    /// `call`, `realistic_10k`): the figures show what native code costs there.
    #[cfg(feature = "native")]
    pub fn with_native(mut self) -> VmCase {
        let native =
            plcd_native::compile_even_if_slower(&self.program).unwrap_or_else(|e| panic!("{e}"));
        self.program.native = Some(native);
        self
    }

    /// What one iteration of the criterion bench measures: the inputs toggled if the category
    /// toggles them, then one scan.
    pub fn iteration(&mut self) {
        if self.toggles {
            self.toggle_inputs();
        }
        self.scan();
    }

    // Not inlined, so that a profiler sees one scan as one call (`VmCase::scan`).
    #[inline(never)]
    pub fn scan(&mut self) {
        self.state.restart();
        let exit = self.vm.run(&self.program, &mut self.state, &self.clock, u64::MAX);
        debug_assert_eq!(exit, Exit::End);
        black_box(exit);
    }

    pub fn toggle_inputs(&mut self) {
        for w in &mut self.vm.mem.io_image_mut()[..48] {
            *w ^= TOGGLE;
        }
    }

    /// Instructions executed by one scan.
    pub fn steps_per_scan(&mut self) -> u64 {
        let before = self.vm.steps();
        self.scan();
        self.vm.steps() - before
    }
}

/// Random contents for P, M and D00000–D09999 (the plant's state when the scan runs).
pub fn randomize(vm: &mut Vm, seed: u32) {
    let mut rng = Rng(seed);
    for w in vm.mem.io_image_mut() {
        *w = rng.below(65536) as u16;
    }
    for m in 0..256 {
        vm.mem.set_word(word(&format!("M{m:03}")), rng.below(65536) as u16);
    }
    for d in 0..10_000 {
        vm.mem.set_word(word(&format!("D{d:05}")), (rng.below(4001) as i32 - 2000) as u16);
    }
}

// ---------------------------------------------------------------------------------------------
// bit: LOAD / LOAD NOT / AND / AND NOT / OR / OR NOT / OUT / SET / RST on M and P

/// The operands of one group of four rungs (19 steps).
pub struct BitGroup {
    pub a: [BitRef; 4],
    pub b: [BitRef; 5],
    pub c: [BitRef; 4],
    pub d: [BitRef; 6],
}

pub fn bit_category() -> (Workload, Vec<BitGroup>) {
    let mut rng = Rng(0x1234_5678);
    let mut s = Source::default();
    let mut groups = Vec::new();
    for _ in 0..526 {
        let a: [String; 4] = [rng.input(), rng.input(), rng.input(), rng.output()];
        s.op(format!("LOAD {}", a[0]));
        s.op(format!("AND {}", a[1]));
        s.op(format!("OR {}", a[2]));
        s.op(format!("OUT {}", a[3]));
        let b: [String; 5] = [rng.input(), rng.input(), rng.input(), rng.input(), rng.output()];
        s.op(format!("LOAD NOT {}", b[0]));
        s.op(format!("AND NOT {}", b[1]));
        s.op(format!("OR NOT {}", b[2]));
        s.op(format!("AND {}", b[3]));
        s.op(format!("SET {}", b[4]));
        let c: [String; 4] = [rng.input(), rng.input(), rng.input(), rng.output()];
        s.op(format!("LOAD {}", c[0]));
        s.op(format!("OR {}", c[1]));
        s.op(format!("AND NOT {}", c[2]));
        s.op(format!("RST {}", c[3]));
        let d: [String; 6] =
            [rng.input(), rng.input(), rng.input(), rng.output(), rng.input(), rng.output()];
        s.op(format!("LOAD {}", d[0]));
        s.op(format!("AND {}", d[1]));
        s.op(format!("AND NOT {}", d[2]));
        s.op(format!("OUT {}", d[3]));
        s.op(format!("AND {}", d[4]));
        s.op(format!("OUT {}", d[5]));
        groups.push(BitGroup {
            a: a.each_ref().map(|t| bit(t)),
            b: b.each_ref().map(|t| bit(t)),
            c: c.each_ref().map(|t| bit(t)),
            d: d.each_ref().map(|t| bit(t)),
        });
    }
    s.op("END");
    let workload =
        Workload { name: "bit", source: s.0, init: |vm| randomize(vm, 1), toggles: false };
    (workload, groups)
}

// ---------------------------------------------------------------------------------------------
// compare_arith: compare contacts, MOV, ADD, SUB, MUL, DIV, INC, DEC on D words

/// The operands of one group of five rungs (17 steps).
pub struct CmpGroup {
    /// `LOAD>= a b`, `AND< c 1000`, `MOV d e`.
    pub a: [WordRef; 5],
    /// `LOAD= a 0`, `OR<> b c`, `ADD a b d`.
    pub b: [WordRef; 4],
    /// `LOAD> a b`, `AND x`, `SUB a 7 d`, `MUL b 3 e`.
    pub c: [WordRef; 4],
    pub cx: BitRef,
    /// `LOAD<= a b`, `AND NOT x`, `DIV c 5 d`, `INC e`.
    pub d: [WordRef; 5],
    pub dx: BitRef,
    /// `LOAD<> a 100`, `MOV 42 d`, `DEC e`.
    pub e: [WordRef; 3],
}

pub fn compare_arith_category() -> (Workload, Vec<CmpGroup>) {
    let mut rng = Rng(0x0BAD_CAFE);
    let mut s = Source::default();
    let mut groups = Vec::new();
    let n = 10_000;
    for _ in 0..588 {
        let a: [String; 5] = std::array::from_fn(|_| rng.d(n));
        s.op(format!("LOAD>= {} {}", a[0], a[1]));
        s.op(format!("AND< {} 1000", a[2]));
        s.op(format!("MOV {} {}", a[3], a[4]));
        let b: [String; 4] = std::array::from_fn(|_| rng.d(n));
        s.op(format!("LOAD= {} 0", b[0]));
        s.op(format!("OR<> {} {}", b[1], b[2]));
        s.op(format!("ADD {} {} {}", b[0], b[1], b[3]));
        let c: [String; 4] = std::array::from_fn(|_| rng.d(n));
        let cx = rng.input();
        s.op(format!("LOAD> {} {}", c[0], c[1]));
        s.op(format!("AND {cx}"));
        s.op(format!("SUB {} 7 {}", c[0], c[2]));
        s.op(format!("MUL {} 3 {}", c[1], c[3]));
        let d: [String; 5] = std::array::from_fn(|_| rng.d(n));
        let dx = rng.input();
        s.op(format!("LOAD<= {} {}", d[0], d[1]));
        s.op(format!("AND NOT {dx}"));
        s.op(format!("DIV {} 5 {}", d[2], d[3]));
        s.op(format!("INC {}", d[4]));
        let e: [String; 3] = std::array::from_fn(|_| rng.d(n));
        s.op(format!("LOAD<> {} 100", e[0]));
        s.op(format!("MOV 42 {}", e[1]));
        s.op(format!("DEC {}", e[2]));
        groups.push(CmpGroup {
            a: a.each_ref().map(|t| word(t)),
            b: b.each_ref().map(|t| word(t)),
            c: c.each_ref().map(|t| word(t)),
            cx: bit(&cx),
            d: d.each_ref().map(|t| word(t)),
            dx: bit(&dx),
            e: e.each_ref().map(|t| word(t)),
        });
    }
    s.op("END");
    let workload = Workload {
        name: "compare_arith",
        source: s.0,
        init: |vm| randomize(vm, 2),
        toggles: false,
    };
    (workload, groups)
}

/// A native timer: its state, done bit, current value and time base.
#[derive(Clone, Copy)]
pub struct TimerRef {
    pub n: usize,
    pub done: BitRef,
    pub value: WordRef,
    pub base_ns: u64,
}

impl TimerRef {
    pub fn new(n: u32) -> TimerRef {
        TimerRef {
            n: n as usize,
            done: bit(&format!("T{n:04}")),
            value: word(&format!("T{n:04}")),
            base_ns: base_ns(n),
        }
    }
}

#[derive(Clone, Copy)]
pub struct CounterRef {
    pub n: usize,
    pub done: BitRef,
    pub value: WordRef,
}

impl CounterRef {
    pub fn new(n: u32) -> CounterRef {
        CounterRef {
            n: n as usize,
            done: bit(&format!("C{n:04}")),
            value: word(&format!("C{n:04}")),
        }
    }
}

/// The operands of one group of ten 3-step rungs (30 steps): `LOAD x; AND y; <timer or
/// counter>`, except the rung on the TON's contact (`LOAD T; AND NOT y; OUT out`) and the
/// counter reset (`LOAD C; OR y; RST C`).
pub struct TcGroup {
    pub x: [BitRef; 8],
    pub y: [BitRef; 10],
    pub out: BitRef,
    /// TON 50, TOFF 20, TMR 100, TMON 30, TRTG 30.
    pub timers: [TimerRef; 5],
    /// CTU 100, CTD 5, CTR 7.
    pub counters: [CounterRef; 3],
}

pub fn timers_counters_category() -> (Workload, Vec<TcGroup>) {
    let mut rng = Rng(0x5EED_0001);
    let mut s = Source::default();
    let mut groups = Vec::new();
    for g in 0..333u32 {
        let tn: [u32; 5] = std::array::from_fn(|i| 5 * g + i as u32);
        let cn: [u32; 3] = std::array::from_fn(|i| 3 * g + i as u32);
        let [t0, t1, t2, t3, t4] = tn.map(|n| format!("T{n:04}"));
        let [c0, c1, c2] = cn.map(|n| format!("C{n:04}"));
        // Timer and counter rungs start with an input that toggles every scan (bit 0 or 8 of
        // P000–P047), so that they see edges.
        let mut x = || format!("P{:03}{}", rng.below(48), ["0", "8"][rng.below(2) as usize]);
        let x: [String; 8] = std::array::from_fn(|_| x());
        let y: [String; 10] = std::array::from_fn(|_| rng.input());
        let out = rng.output();
        let [x0, x1, x2, x3, x4, x5, x6, x7] = &x;
        let [y0, y1, y2, y3, y4, y5, y6, y7, y8, y9] = &y;
        for line in [
            format!("LOAD {x0}\nAND {y0}\nTON {t0} 50"),
            format!("LOAD {t0}\nAND NOT {y1}\nOUT {out}"),
            format!("LOAD {x1}\nAND {y2}\nCTU {c0} 100"),
            format!("LOAD {c0}\nOR {y3}\nRST {c0}"),
            format!("LOAD NOT {x2}\nAND {y4}\nTOFF {t1} 20"),
            format!("LOAD {x3}\nAND {y5}\nCTD {c1} 5"),
            format!("LOAD {x4}\nAND {y6}\nTMR {t2} 100"),
            format!("LOAD {x5}\nAND {y7}\nTMON {t3} 30"),
            format!("LOAD {x6}\nAND {y8}\nCTR {c2} 7"),
            format!("LOAD {x7}\nAND {y9}\nTRTG {t4} 30"),
        ] {
            s.op(line);
        }
        groups.push(TcGroup {
            x: x.each_ref().map(|t| bit(t)),
            y: y.each_ref().map(|t| bit(t)),
            out: bit(&out),
            timers: tn.map(TimerRef::new),
            counters: cn.map(CounterRef::new),
        });
    }
    s.op("END");
    let workload = Workload {
        name: "timers_counters",
        source: s.0,
        init: |vm| randomize(vm, 3),
        toggles: true,
    };
    (workload, groups)
}

// ---------------------------------------------------------------------------------------------
// call: `LOAD x; CALL n` to eight small subroutines

pub const SUBROUTINES: &str = "\
SBRT 0\nLOAD P0100\nAND M2000\nOUT M2001\nRET\n\
SBRT 1\nLOAD M2002\nOR P0101\nAND NOT M2003\nOUT M2004\nRET\n\
SBRT 2\nLOAD>= D20000 D20001\nMOV D20002 D20003\nRET\n\
SBRT 3\nLOAD P0102\nADD D20004 1 D20005\nRET\n\
SBRT 4\nLOAD M2005\nAND M2006\nAND M2007\nSET M2008\nRET\n\
SBRT 5\nLOAD NOT P0103\nRST M2009\nRET\n\
SBRT 6\nLOAD M200A\nOUT M200B\nAND P0104\nOUT M200C\nRET\n\
SBRT 7\nLOAD SM400\nINC D20006\nRET\n";

pub fn call_category() -> (Workload, Vec<[BitRef; 8]>) {
    let mut rng = Rng(0xCA11_0001);
    let mut s = Source::default();
    let mut groups = Vec::new();
    for _ in 0..213 {
        let conditions: [String; 8] = std::array::from_fn(|_| rng.input());
        for (n, x) in conditions.iter().enumerate() {
            s.op(format!("LOAD {x}"));
            s.op(format!("CALL {n}"));
        }
        groups.push(conditions.each_ref().map(|t| bit(t)));
    }
    s.op("END");
    s.op(SUBROUTINES);
    let workload =
        Workload { name: "call", source: s.0, init: |vm| randomize(vm, 4), toggles: false };
    (workload, groups)
}

// ---------------------------------------------------------------------------------------------
// realistic_10k: 99 stations of a plant, 101 steps each, and an alarm subroutine

pub const STATIONS: u32 = 99;

/// The devices of one station: inputs P(s mod 48), outputs P(64 + s mod 48), internal relays
/// M(2s) and M(2s+1), timers T(4s)…, counter C(s), data D(20s)….
pub struct StationText {
    pub i: u32,
    pub o: u32,
    pub a: u32,
    pub b: u32,
    pub t: u32,
    pub c: u32,
    pub d: u32,
}

impl StationText {
    pub fn new(s: u32) -> StationText {
        StationText { i: s % 48, o: 64 + s % 48, a: 2 * s, b: 2 * s + 1, t: 4 * s, c: s, d: 20 * s }
    }
    pub fn i(&self, n: u32) -> String {
        format!("P{:03}{n:X}", self.i)
    }
    pub fn o(&self, n: u32) -> String {
        format!("P{:03}{n:X}", self.o)
    }
    pub fn a(&self, n: u32) -> String {
        format!("M{:03}{n:X}", self.a)
    }
    pub fn b(&self, n: u32) -> String {
        format!("M{:03}{n:X}", self.b)
    }
    pub fn t(&self, n: u32) -> String {
        format!("T{:04}", self.t + n)
    }
    pub fn c(&self) -> String {
        format!("C{:04}", self.c)
    }
    pub fn d(&self, n: u32) -> String {
        format!("D{:05}", self.d + n)
    }

    /// The device a placeholder of [`STATION`] names: `i`, `o`, `a` or `b` and a hex bit, `t`
    /// and a timer, `d` and a word, or `c`.
    pub fn device(&self, name: &str) -> String {
        let (kind, n) = name.split_at(1);
        let n = u32::from_str_radix(n, 16).unwrap_or(0);
        match kind {
            "i" => self.i(n),
            "o" => self.o(n),
            "a" => self.a(n),
            "b" => self.b(n),
            "t" => self.t(n),
            "d" => self.d(n),
            "c" => self.c(),
            _ => panic!("unknown placeholder {{{name}}}"),
        }
    }

    /// The station's 101 steps: [`STATION`] with its placeholders replaced.
    pub fn emit(&self, s: &mut Source) {
        let mut rest = STATION;
        while let Some(open) = rest.find('{') {
            let close = open + rest[open..].find('}').expect("placeholders are closed");
            s.0.push_str(&rest[..open]);
            s.0.push_str(&self.device(&rest[open + 1..close]));
            rest = &rest[close + 1..];
        }
        s.0.push_str(rest);
    }
}

/// One station of the realistic program, a rung a line (`{i0}` is the station's input bit 0,
/// `{af}` its internal relay A bit F, `{t0}` its first timer…; see [`StationText::device`]).
pub const STATION: &str = "\
; motor: seal-in with stop, E-stop and fault interlocks
LOAD {i0}\nOR {a0}\nAND NOT {i1}\nAND M2500\nAND NOT {af}\nOUT {a0}
; star/delta start
LOAD {a0}\nTON {t0} 30
LOAD {a0}\nMPUSH\nAND NOT {t0}\nOUT {o0}\nMPOP\nAND {t0}\nOUT {o1}
; fault latch and reset
LOAD {i2}\nOR {i3}\nSET {af}
LOAD M2502\nAND NOT {i2}\nAND NOT {i3}\nRST {af}
; fault lamp: blinking, or lamp test
LOAD {af}\nAND _T1S\nOR M2503\nOUT {o2}
; conveyor: two paths
LOAD {i4}\nAND {i5}\nLOAD {i6}\nAND NOT {i7}\nOR LOAD\nAND {a0}\nOUT {a1}
LOAD {a1}\nOUT {o3}
; part counter and batch
LOADP {i8}\nAND {a1}\nCTU {c} 100
LOAD {c}\nOUT {a2}
LOAD {a2}\nAND M2502\nRST {c}
; analog input scaling and limits
LOAD SM400\nMOV {d0} {d1}\nSUB {d1} 800 {d2}\nMUL {d2} 10 {d3}\nDIV {d3} 32 {d4}
LOAD>= {d4} {d5}\nOUT {a3}
LOAD< {d4} {d6}\nAND {a0}\nOUT {a4}
LOAD {a3}\nOR {a4}\nTON {t1} 20
LOAD {t1}\nSET {b1}
LOAD M2502\nAND NOT {a3}\nRST {b1}
; fan run-on
LOAD {a0}\nTOFF {t2} 50
LOAD {t2}\nOUT {o4}
; cycle count
LOAD {a1}\nINCP {d7}
LOAD>= {d7} 10000\nMOV 0 {d7}
; auto mode branches
LOAD M2501\nMPUSH\nAND {a0}\nAND NOT {b1}\nOUT {b2}
MLOAD\nAND {a2}\nOUT {b3}
MPOP\nAND NOT {a0}\nOUT {b4}
; valves
LOAD {b2}\nAND {i9}\nAND NOT {ia}\nOUT {o5}
LOAD {b2}\nAND {ia}\nOR {o6}\nAND NOT {ib}\nOUT {o6}
; jam: conveyor running and sensor blocked for 5 s
LOAD {a1}\nAND {ic}\nTON {t3} 50
LOAD {t3}\nSET {af}
; status
LOAD {a0}\nAND NOT {af}\nOUT {b5}
LOAD {b5}\nOUT {o7}
; alarm handler
LOAD {b1}\nCALL 1
";

pub const ALARM_SUBROUTINE: &str = "\
SBRT 1
LOAD _ON\nINC D30000
LOAD>= D30000 30000\nMOV 0 D30000
LOAD _T1S\nOUT M2510
RET
";

/// One station's devices, resolved.
#[derive(Clone)]
pub struct Station {
    pub i: [BitRef; 13],
    pub o: [BitRef; 8],
    pub a: [BitRef; 16],
    pub b: [BitRef; 6],
    pub t: [TimerRef; 4],
    pub c: CounterRef,
    pub d: [WordRef; 8],
    /// Edge memory of the station's `LOADP` and `INCP`.
    pub edge: [bool; 2],
}

impl Station {
    pub fn new(s: &StationText) -> Station {
        Station {
            i: std::array::from_fn(|n| bit(&s.i(n as u32))),
            o: std::array::from_fn(|n| bit(&s.o(n as u32))),
            a: std::array::from_fn(|n| bit(&s.a(n as u32))),
            b: std::array::from_fn(|n| bit(&s.b(n as u32))),
            t: std::array::from_fn(|n| TimerRef::new(s.t + n as u32)),
            c: CounterRef::new(s.c),
            d: std::array::from_fn(|n| word(&s.d(n as u32))),
            edge: [false; 2],
        }
    }
}

pub fn realistic_category() -> (Workload, Vec<Station>) {
    let mut s = Source::default();
    let mut stations = Vec::new();
    for n in 0..STATIONS {
        let text = StationText::new(n);
        text.emit(&mut s);
        stations.push(Station::new(&text));
    }
    s.op("END");
    s.op(ALARM_SUBROUTINE);
    let workload =
        Workload { name: "realistic_10k", source: s.0, init: realistic_init, toggles: true };
    (workload, stations)
}

/// Plant state: random inputs; E-stop OK and auto mode ON, reset and lamp test OFF; raw analog
/// values 0–4000 with high limit 900 and low limit 0 (some stations go into alarm).
pub fn realistic_init(vm: &mut Vm) {
    randomize(vm, 0xFAC7_0001);
    let mut rng = Rng(0xFAC7_0002);
    for m in 0..=255 {
        vm.mem.set_word(word(&format!("M{m:03}")), 0);
    }
    for (flag, on) in [("M2500", true), ("M2501", true), ("M2502", false), ("M2503", false)] {
        vm.mem.set_bit(bit(flag), on);
    }
    for n in 0..STATIONS {
        let st = StationText::new(n);
        vm.mem.set_word(word(&st.d(0)), rng.below(4001) as u16);
        vm.mem.set_word(word(&st.d(5)), 900);
        vm.mem.set_word(word(&st.d(6)), 0);
    }
}
