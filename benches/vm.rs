//! ns per executed instruction: (a) 10,000 steps of bit logic (LOAD/AND/OR/OUT on M and P),
//! (b) a mixed program (compares, MOV/ADD, timers, counters, CALL).
//!
//! `cargo bench --bench vm`; figures go to BENCHMARKS.md. Throughput is reported per executed
//! instruction (criterion's "elem/s"), counted by the VM itself.

use std::fmt::Write;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use plcd::lang::{self, Context, Program};
use plcd::vm::{ExecState, Exit, StepClock, Vm};

fn timer_base(n: u32) -> Option<u32> {
    Some(match n {
        0..=999 => 100,
        1000..=1499 => 10,
        _ => 1,
    })
}

fn assemble(source: &str) -> Program {
    let ctx =
        Context { is_init: false, task_numbers: &[], timer_base_ms: &timer_base, edge_base: 0 };
    lang::assemble("bench", Path::new("bench.il"), source, &ctx).expect("bench program assembles")
}

/// 2,500 rungs of LOAD/AND/OR/OUT over M and P: 10,000 steps, plus END.
fn bit_logic() -> String {
    let mut s = String::new();
    for i in 0..2500u32 {
        let a = i % 256;
        let b = (i * 7) % 128;
        let c = (i * 13) % 256;
        let d = (i * 31 + 5) % 256;
        writeln!(s, "LOAD M{a:03}{:X}", i % 16).unwrap();
        writeln!(s, "AND P{b:03}{:X}", (i / 16) % 16).unwrap();
        writeln!(s, "OR M{c:03}{:X}", (i / 3) % 16).unwrap();
        writeln!(s, "OUT M{d:03}{:X}", (i / 5) % 16).unwrap();
    }
    s.push_str("END\n");
    s
}

/// A plant-like mix: compares, moves and arithmetic, timers, counters and a subroutine call.
fn mixed() -> String {
    let mut s = String::new();
    for i in 0..400u32 {
        let d = i * 4;
        writeln!(s, "LOAD>= D{:05} 5", d).unwrap();
        writeln!(s, "AND M{:03}{:X}", i % 256, i % 16).unwrap();
        writeln!(s, "MOV D{:05} D{:05}", d + 1, d + 2).unwrap();
        writeln!(s, "ADD D{:05} 1 D{:05}", d + 2, d + 3).unwrap();
        writeln!(s, "LOAD M{:03}{:X}", (i + 1) % 256, i % 16).unwrap();
        writeln!(s, "TON T{:04} 10", 1500 + i).unwrap();
        writeln!(s, "CTU C{:04} 5", i).unwrap();
        // Always true: the CALL below runs on every rung.
        writeln!(s, "LOAD>= D{:05} D{:05}", d, d + 1).unwrap();
        writeln!(s, "CALL 1").unwrap();
    }
    s.push_str("END\nSBRT 1\nINC D20000\nLOAD= D20000 0\nOUT M2000\nRET\n");
    s
}

fn scan(vm: &mut Vm, program: &Program, state: &mut ExecState, clock: &StepClock) {
    state.restart();
    let exit = vm.run(program, state, clock, u64::MAX);
    debug_assert_eq!(exit, Exit::End);
    black_box(exit);
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("vm");
    group
        .sample_size(30)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    for (name, source) in [("bit_logic_10k", bit_logic()), ("mixed", mixed())] {
        let program = assemble(&source);
        let mut vm = Vm::for_programs([&program]);
        let mut state = ExecState::new();
        let clock = StepClock { origin_ns: 0, origin_steps: 0, step_ns: 1000 };
        // Half the inputs ON so both branches of the logic are taken.
        for w in 0..64 {
            vm.mem.io_image_mut()[w] = 0x5A5A;
        }
        let before = vm.steps();
        scan(&mut vm, &program, &mut state, &clock);
        let steps = vm.steps() - before;
        eprintln!("{name}: {} instructions, {steps} executed per scan", program.code.len());
        group.throughput(Throughput::Elements(steps));
        group.bench_function(name, |b| b.iter(|| scan(&mut vm, &program, &mut state, &clock)));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
