//! The CI guard of the VM's speed: the machine instructions one scan of each workload executes,
//! counted by Valgrind's Callgrind, on every category of `benches/vm.rs` (instruction list) and
//! every workload of `benches/st_native.rs` (Structured Text), each on the interpreter and with
//! its native code (plcd-native, Cranelift) attached. A count does not depend on the machine's
//! load, so a change of a few percent shows where criterion's times on a shared VM drift by
//! ±10 % (BENCHMARKS.md, "Instruction counts: the CI guard"). What counts cannot see is where
//! the code lies (the same instructions, slower across a fetch window): that is
//! `benches/layout`'s.
//!
//! `benches/counts/check` builds this with the bench profile (the one of `cargo bench`, the
//! release profile's code generation) and runs it once for each workload under Callgrind,
//! compares the counts with `benches/counts/baseline.toml` and fails on a regression; `--bless`
//! rewrites the baseline.
//!
//! `counts FUNCTION WORKLOAD` (FUNCTION one of [`FUNCTIONS`], WORKLOAD one of the bench's) sets
//! the workload up as the criterion benches do (`benches/common/`: generating or compiling the
//! program, Cranelift included, and one warm-up scan), then runs one scan in
//! [`counted_il_scan`] or [`counted_st_scan`] — `ExecState::restart`, then `Vm::run` to `END`,
//! the inputs toggled first where the category toggles them — and prints the VM steps of that
//! scan (`steps FUNCTION WORKLOAD N`). The check runs it with Callgrind's collection off at the
//! start and toggled on and off by those two functions, so only the scan is counted. Without
//! arguments (`cargo bench --bench counts`, `cargo test --benches`) it runs every workload so,
//! uncounted, and prints their steps; `counts list` prints each FUNCTION WORKLOAD pair, the
//! runs the check makes.

#[path = "common/il_workloads.rs"]
mod il;
#[path = "common/st_workloads.rs"]
mod st;

/// The counted functions: each language on the interpreter and with its native code.
const FUNCTIONS: [&str; 4] = ["il_interpreter", "il_native", "st_interpreter", "st_native"];
/// One scan of an instruction-list workload: the one function Callgrind counts for `il_*`
/// (`--toggle-collect`, benches/counts/check). Not inlined, so that it exists to be toggled.
#[inline(never)]
fn counted_il_scan(case: &mut il::VmCase) {
    case.iteration();
}

/// One scan of a Structured Text workload: the one function Callgrind counts for `st_*`.
#[inline(never)]
fn counted_st_scan(case: &mut st::StCase) {
    case.scan();
}

/// Sets `workload` up for `function`, runs the warm-up scan and the counted one; returns the
/// VM steps of the counted scan.
fn measure(function: &str, workload: &str) -> u64 {
    match function {
        "il_interpreter" | "il_native" => {
            let mut case = il::case(workload);
            if function == "il_native" {
                case = case.with_native();
            }
            // The warm-up scan: timers start, edges and the memory settle as in criterion's
            // warm-up.
            case.iteration();
            let before = case.vm.steps();
            counted_il_scan(std::hint::black_box(&mut case));
            case.vm.steps() - before
        }
        "st_interpreter" | "st_native" => {
            let mut case = st::case(workload);
            if function == "st_native" {
                case = case.with_native();
            }
            case.scan();
            let before = case.vm.steps();
            counted_st_scan(std::hint::black_box(&mut case));
            case.vm.steps() - before
        }
        _ => panic!("no function {function} (one of {FUNCTIONS:?})"),
    }
}

fn workloads(function: &str) -> &'static [&'static str] {
    if function.starts_with("il_") {
        &il::CATEGORIES
    } else {
        &st::WORKLOADS
    }
}

fn main() {
    // `cargo bench` and `cargo test --benches` add their own flags (`--bench`, `--list`, …).
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let every = || FUNCTIONS.iter().flat_map(|f| workloads(f).iter().map(move |w| (*f, *w)));
    let runs: Vec<(&str, &str)> = match args.as_slice() {
        [list] if list == "list" => {
            for (function, workload) in every() {
                println!("{function} {workload}");
            }
            return;
        }
        [function, workload] => vec![(function, workload)],
        [] => every().collect(),
        _ => {
            eprintln!("usage: counts [list | FUNCTION WORKLOAD]");
            std::process::exit(2);
        }
    };
    for (function, workload) in runs {
        let steps = measure(function, workload);
        println!("steps {function} {workload} {steps}");
    }
}
