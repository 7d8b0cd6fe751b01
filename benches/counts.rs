//! The CI guard of the VM's speed: the machine instructions one scan of each workload executes,
//! counted by Valgrind's Callgrind through gungraun, on every category of `benches/vm.rs`
//! (instruction list) and every workload of `benches/st_native.rs` (Structured Text), each on
//! the interpreter and with its native code (plcd-native, Cranelift) attached. A count does not
//! depend on the machine's load, so a change of a few percent shows where criterion's times on
//! a shared VM drift by ±10 % (BENCHMARKS.md, "Instruction counts: the CI guard"). What counts
//! cannot see is where the code lies (the same instructions, slower across a fetch window):
//! that is `benches/layout`'s.
//!
//! Run it with `benches/counts/check`, which builds this with the bench profile (the one of
//! `cargo bench`, the release profile's code generation), compares the counts with
//! `benches/counts/baseline.toml` and fails on a regression; `--bless` rewrites the baseline.
//! `cargo bench --bench counts` alone prints gungraun's own report.
//!
//! The workloads are the criterion benches' own (`benches/common/`), built and scanned the same
//! way: `ExecState::restart`, then `Vm::run` to `END`, the inputs toggled first where the
//! category toggles them. Each benchmark is one process under Callgrind: its setup (generating
//! or compiling the program, Cranelift included, and one warm-up scan) is not counted; only the
//! benchmark function, one scan, is (gungraun's `--toggle-collect` on it). The teardown prints
//! the VM steps of the counted scan on stdout (`steps <function> <workload> <n>`, a line the
//! check reads; gungraun shows it with `--nocapture=stdout`), so the check can divide.

use gungraun::{
    library_benchmark, library_benchmark_group, main, Callgrind, LibraryBenchmarkConfig,
};

#[path = "common/il_workloads.rs"]
mod il;
#[path = "common/st_workloads.rs"]
mod st;

/// A workload between its setup and its teardown.
struct Measured<C> {
    name: &'static str,
    case: C,
    /// The VM's step count before the counted scan.
    steps_before: u64,
}

/// Prints the steps of the counted scan for the check (see the module doc).
fn print_steps(function: &str, name: &str, steps: u64) {
    println!("steps {function} {name} {steps}");
}

// ---------------------------------------------------------------------------------------------
// The instruction list on the interpreter (benches/vm.rs) and with its native code

fn il_measured(name: &'static str, mut case: il::VmCase) -> Measured<il::VmCase> {
    // The warm-up scan: timers start, edges and the memory settle as in criterion's warm-up.
    case.iteration();
    let steps_before = case.vm.steps();
    Measured { name, case, steps_before }
}

fn il_setup(name: &'static str) -> Measured<il::VmCase> {
    il_measured(name, il::case(name))
}

fn il_teardown(m: Measured<il::VmCase>) {
    print_steps("il_interpreter", m.name, m.case.vm.steps() - m.steps_before);
}

#[library_benchmark]
#[bench::bit(args = ("bit"), setup = il_setup, teardown = il_teardown)]
#[bench::compare_arith(args = ("compare_arith"), setup = il_setup, teardown = il_teardown)]
#[bench::timers_counters(args = ("timers_counters"), setup = il_setup, teardown = il_teardown)]
#[bench::call(args = ("call"), setup = il_setup, teardown = il_teardown)]
#[bench::realistic_10k(args = ("realistic_10k"), setup = il_setup, teardown = il_teardown)]
fn il_interpreter(mut m: Measured<il::VmCase>) -> Measured<il::VmCase> {
    m.case.iteration();
    m
}

fn il_native_setup(name: &'static str) -> Measured<il::VmCase> {
    il_measured(name, il::case(name).with_native())
}

fn il_native_teardown(m: Measured<il::VmCase>) {
    print_steps("il_native", m.name, m.case.vm.steps() - m.steps_before);
}

#[library_benchmark]
#[bench::bit(args = ("bit"), setup = il_native_setup, teardown = il_native_teardown)]
#[bench::compare_arith(
    args = ("compare_arith"),
    setup = il_native_setup,
    teardown = il_native_teardown
)]
#[bench::timers_counters(
    args = ("timers_counters"),
    setup = il_native_setup,
    teardown = il_native_teardown
)]
#[bench::call(args = ("call"), setup = il_native_setup, teardown = il_native_teardown)]
#[bench::realistic_10k(
    args = ("realistic_10k"),
    setup = il_native_setup,
    teardown = il_native_teardown
)]
fn il_native(mut m: Measured<il::VmCase>) -> Measured<il::VmCase> {
    m.case.iteration();
    m
}

// ---------------------------------------------------------------------------------------------
// Structured Text on the interpreter and with its native code (benches/st_native.rs)

fn st_measured(name: &'static str, mut case: st::StCase) -> Measured<st::StCase> {
    // The warm-up scan, as in criterion's warm-up.
    case.scan();
    let steps_before = case.vm.steps();
    Measured { name, case, steps_before }
}

fn st_setup(name: &'static str) -> Measured<st::StCase> {
    st_measured(name, st::case(name))
}

fn st_native_setup(name: &'static str) -> Measured<st::StCase> {
    st_measured(name, st::case(name).with_native())
}

fn st_teardown(m: Measured<st::StCase>) {
    print_steps("st_interpreter", m.name, m.case.vm.steps() - m.steps_before);
}

fn st_native_teardown(m: Measured<st::StCase>) {
    print_steps("st_native", m.name, m.case.vm.steps() - m.steps_before);
}

#[library_benchmark]
#[bench::bit(args = ("bit"), setup = st_setup, teardown = st_teardown)]
#[bench::int_loops(args = ("int_loops"), setup = st_setup, teardown = st_teardown)]
#[bench::pid(args = ("pid"), setup = st_setup, teardown = st_teardown)]
#[bench::sort(args = ("sort"), setup = st_setup, teardown = st_teardown)]
#[bench::state_machine(args = ("state_machine"), setup = st_setup, teardown = st_teardown)]
fn st_interpreter(mut m: Measured<st::StCase>) -> Measured<st::StCase> {
    m.case.scan();
    m
}

#[library_benchmark]
#[bench::bit(args = ("bit"), setup = st_native_setup, teardown = st_native_teardown)]
#[bench::int_loops(args = ("int_loops"), setup = st_native_setup, teardown = st_native_teardown)]
#[bench::pid(args = ("pid"), setup = st_native_setup, teardown = st_native_teardown)]
#[bench::sort(args = ("sort"), setup = st_native_setup, teardown = st_native_teardown)]
#[bench::state_machine(
    args = ("state_machine"),
    setup = st_native_setup,
    teardown = st_native_teardown
)]
fn st_native(mut m: Measured<st::StCase>) -> Measured<st::StCase> {
    m.case.scan();
    m
}

library_benchmark_group!(name = vm; benchmarks = il_interpreter, il_native, st_interpreter, st_native);

main!(
    // Instructions are the measure; the cache simulation would only slow the run.
    config = LibraryBenchmarkConfig::default().tool(Callgrind::with_args(["--cache-sim=no"]));
    library_benchmark_groups = vm
);
