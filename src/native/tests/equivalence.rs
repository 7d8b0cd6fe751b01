//! Native code is the interpreter, to the step.
//!
//! What this pins: a Structured Text program with its native code attached
//! (`plcd_native::compile`) behaves exactly as the same program on the interpreter alone. Two
//! VMs run side by side, one with the plain programs and one with native code, with the same
//! setup (`Vm::for_programs`, `set_variables`, `reset_for_run`), the same clock and the same
//! step budgets; after every `Vm::run` call they must agree on
//! - the `Exit` (`End`, `Budget`, `OperationError { code, pc }`, `System`),
//! - the step count (`Vm::steps`),
//! - the activation (`ExecState`): the program counter, the evaluation stack's depth, the call
//!   depth, whether it is finished, and, read from its `Debug` form because they are private,
//!   the live slots of the evaluation stack, the live call frames, the frame base, the FB
//!   instance and the frame area's bytes,
//! - variable memory (`Vm::vars`) and device memory (`vm.mem.words()`, `_ERR` included).
//!
//! Every budget is tried: the whole scan at once (`u64::MAX`), 1, 2, 3, 5, 7, 13 and 100 steps a
//! call, and a varying budget (0 to 17, the same sequence on both sides); a budget that ends
//! inside a native block makes native code hand back to the interpreter, which is the path the
//! small budgets exercise. Under an emulator (the aarch64 suite under qemu-user) four of them:
//! see [`budgets`]. The run loop calls `run` again after `Budget`, `OperationError` and
//! `System` until `End`, as the task engine does.
//!
//! The programs:
//! 1. every source of the repository: each case of the conformance suite `tests/st/**` (as that
//!    suite builds it: the scan program `main` of a project of its own, the clock standing still
//!    during a scan and moving by the case's period between scans), each workload of
//!    `benches/st/`, and the example project `etc/plcd.toml` (its Structured Text programs in
//!    one VM, one after the other and by turns). Every mismatch of every case is reported at
//!    once, with the case's name;
//! 2. targeted programs, written here, for what native code does its own way: division and
//!    `MOD` by zero, the minimum / -1, array bounds, whole copies of arrays and structs between
//!    variable memory and frames, FB instances in a frame (`VAR_TEMP`: a FUNCTION cannot hold
//!    one), `VAR_IN_OUT` references into every space, calls inside expressions, a call chain as
//!    deep as the compiler allows and one as deep as the evaluation stack (deeper is refused by
//!    the compiler), located variables of
//!    every size, NaN comparisons and NaN bits, float-to-integer conversions, the float
//!    functions, shifts and rotations, strings and the clock (which native code leaves to the
//!    interpreter: mixed execution), programs preempting each other, frames smaller than a
//!    program needs, and an endless loop stopped by the budget;
//! 3. random programs (statements, loops, calls, FB instances, arrays, divisions by zero and
//!    indices out of range), from fixed seeds.
//!
//! Native code must also run: each program's native code is wrapped to count the steps it
//! executes itself, and the targeted programs require a share of them, so a code generator
//! that handed everything back to the interpreter would not pass for an equivalent one.

#[path = "../../../tests/harness/parallel.rs"]
mod parallel;

use std::cell::Cell;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use plcd_core::device::RetainSet;
use plcd_core::lang::native::{IlMemory, NativeCode, NativeExit, NativeMemory, NativeRegs};
use plcd_core::lang::{Language, Program, Variables};
use plcd_core::st::{compile, parse_file, Instance};
use plcd_core::value::Space;
use plcd_core::vm::{
    Clock, ExecState, Exit, StepClock, Vm, ERR_CALL_DEPTH, ERR_DIVIDE_BY_ZERO, ERR_INDEX_RANGE,
    ERR_REF_NULL, ERR_REF_RANGE,
};

const MS: u64 = 1_000_000;

/// The budgets every program runs with.
const BUDGETS: [Budget; 9] = [
    Budget::Fixed(u64::MAX),
    Budget::Fixed(1),
    Budget::Fixed(2),
    Budget::Fixed(3),
    Budget::Fixed(5),
    Budget::Fixed(7),
    Budget::Fixed(13),
    Budget::Fixed(100),
    Budget::Varying,
];

/// The budgets under an emulator (`PLCD_TEST_RUNNER` set: tests/cross/run-aarch64-tests): the
/// whole scan, a stop at every step (every instruction boundary of every block), one that
/// falls at other places of each block, and the varying one. Where a budget stops the code is
/// decided in the code generator's IR, which is the same for every processor, and the x86_64
/// suite tries all of [`BUDGETS`]; what differs on aarch64 is the machine code of each block,
/// which these four run through. The other five took more than half of this test's time
/// under qemu-user (the longest test of CI's aarch64 step, 268 s): 679 s with all nine against
/// 321 s with these four, run one after the other on a loaded machine.
const EMULATED_BUDGETS: [Budget; 4] =
    [Budget::Fixed(u64::MAX), Budget::Fixed(1), Budget::Fixed(7), Budget::Varying];

/// [`BUDGETS`], or [`EMULATED_BUDGETS`] when the tests run under an emulator.
fn budgets() -> &'static [Budget] {
    if std::env::var_os("PLCD_TEST_RUNNER").is_some_and(|runner| !runner.is_empty()) {
        &EMULATED_BUDGETS
    } else {
        &BUDGETS
    }
}

/// A scan that takes more steps than this has an endless loop.
const STEPS_PER_SCAN: u64 = 2_000_000;

/// A case (every budget of it) that runs longer than this hangs: native code that never
/// returns (a budget check lost), or a scan that creeps to [`STEPS_PER_SCAN`] one step a call.
/// The slowest case takes a few seconds here and under 30 s on aarch64 under qemu-user; the
/// cases of a list run on every core beside the other tests (`parallel::map`), and a machine
/// loaded by other builds made `benches/st/sort.st` pass 300 s under qemu-user once: the
/// limit leaves room for that, a hang still ends in bounded time.
const CASE_LIMIT: std::time::Duration = std::time::Duration::from_secs(600);

/// Ends the whole test process with a message naming `case` if it is still alive after
/// [`CASE_LIMIT`]: a call into native code cannot be interrupted, so only the process can end
/// it. Dropping the guard disarms it.
struct Deadline(#[allow(dead_code)] std::sync::mpsc::Sender<()>);

fn deadline(case: &str) -> Deadline {
    let (disarm, armed) = std::sync::mpsc::channel::<()>();
    let case = case.to_string();
    std::thread::spawn(move || {
        if let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = armed.recv_timeout(CASE_LIMIT) {
            // Straight to the process's stderr: the harness captures `eprintln!` of a test's
            // threads, and exiting would lose it.
            let _ = writeln!(
                std::io::stderr(),
                "equivalence: case {case:?} did not end within {CASE_LIMIT:?}: native code or the \
                 interpreter hangs; the test process stops here"
            );
            std::process::exit(101);
        }
    });
    Deadline(disarm)
}

// ---------------------------------------------------------------------------------------------
// The programs of a case

/// The programs of one case, run in order in each scan, and their variable memory.
struct Programs {
    name: String,
    programs: Vec<Program>,
    variables: Variables,
    frame_bytes: u32,
    /// The machine stack native code's calls may use, if not the default
    /// (`plcd_native::compile_with_stack`).
    native_stack: Option<u64>,
}

impl Programs {
    /// The project a `[[program]]` table describes (`config` is the config's text, `path` where
    /// it would be: program files are relative to it); its Structured Text programs.
    fn from_config(name: &str, config: &str, path: &Path) -> Programs {
        let config = plcd_core::config::parse(config, path)
            .unwrap_or_else(|d| panic!("{name}: config: {d}"));
        let project = plcd_core::project::from_config(config, |p| std::fs::read_to_string(p))
            .unwrap_or_else(|d| panic!("{name}: does not compile:\n{d}"));
        let frame_bytes = project.frame_bytes();
        let programs = project
            .programs
            .into_iter()
            .filter(|p| p.language == Language::StructuredText)
            .collect();
        Programs {
            name: name.to_string(),
            programs,
            variables: project.variables,
            frame_bytes,
            native_stack: None,
        }
    }

    /// One `.st` file as the scan program `main` of a project of its own, as the conformance
    /// suite builds its cases.
    fn st_file(name: &str, file: &Path, period_ns: u64) -> Programs {
        // a conformance case's own config sections (`[iec] preset`), as tests/st/README.md says
        let sections = std::fs::read_to_string(file.with_extension("toml")).unwrap_or_default();
        let config = format!(
            "[plc]\nwatchdog_ms = 1000\nscan_period_ms = {}\n[[program]]\nname = \"main\"\nfile = \"{}\"\n{sections}",
            (period_ns / MS).max(1),
            file.file_name().unwrap().to_str().unwrap()
        );
        Programs::from_config(name, &config, &file.with_extension("toml"))
    }

    /// Instruction-list `sources` (name, text), each a program of its own, assembled as a
    /// project assembles them (timers T0000-T0999 100 ms, T1000-T1499 10 ms, the rest 1 ms;
    /// edge memory after the previous program's).
    fn il(name: &str, sources: &[(&str, &str)]) -> Programs {
        let base = |n: u32| {
            Some(match n {
                0..=999 => 100,
                1000..=1499 => 10,
                _ => 1,
            })
        };
        let mut programs: Vec<Program> = Vec::new();
        for (program, source) in sources {
            let edge_base = programs.iter().map(|p| p.edge_slots).sum::<u32>();
            let ctx = plcd_core::lang::Context {
                is_init: false,
                task_numbers: &[],
                timer_base_ms: &base,
                edge_base,
            };
            let path = PathBuf::from(format!("{program}.il"));
            programs.push(
                plcd_core::lang::assemble(program, &path, source, &ctx)
                    .unwrap_or_else(|d| panic!("{name}: {program} does not assemble: {d:?}")),
            );
        }
        Programs {
            name: name.to_string(),
            programs,
            variables: Variables::default(),
            frame_bytes: 0,
            native_stack: None,
        }
    }

    /// `source`, compiled with one instance `main` of its PROGRAM.
    fn inline(name: &str, source: &str) -> Programs {
        Programs::instances(name, source, &[("main", None)])
    }

    /// `source`, compiled with the instances `(name, PROGRAM)` (`None`: its only PROGRAM), one
    /// program each, in that order.
    fn instances(name: &str, source: &str, instances: &[(&str, Option<&str>)]) -> Programs {
        let path = Path::new("inline.st");
        let (file, diags) = parse_file(path, source);
        assert!(diags.is_empty(), "{name}: {diags}");
        let instances: Vec<Instance> = instances
            .iter()
            .map(|&(name, pou)| Instance { name, pou, file: path, config: path, line: 1, col: 1 })
            .collect();
        let compiled =
            compile(&[file], &instances).unwrap_or_else(|d| panic!("{name}: {d}\n{source}"));
        let frame_bytes = compiled.programs.iter().map(|p| p.frame_bytes).max().unwrap_or(0);
        Programs {
            name: name.to_string(),
            programs: compiled.programs,
            variables: compiled.variables,
            frame_bytes,
            native_stack: None,
        }
    }

    /// The programs with native code attached, each counting the steps it executes into
    /// `native_steps`; an error for each program without native code.
    fn with_native(&self, native_steps: &Arc<AtomicU64>) -> Result<Vec<Program>, String> {
        self.programs
            .iter()
            .map(|program| {
                let code = match self.native_stack {
                    Some(bytes) => plcd_native::compile_with_stack(program, bytes),
                    None => plcd_native::compile_even_if_slower(program),
                }
                .map_err(|e| format!("{}: no native code: {e}", self.name))?;
                let mut program = program.clone();
                program.native = Some(Arc::new(Counted { code, steps: native_steps.clone() }));
                Ok(program)
            })
            .collect()
    }

    /// The name of the variable at byte `offset` of variable memory.
    fn variable_at(&self, offset: usize) -> String {
        self.variables
            .symbols
            .iter()
            .filter(|s| s.at.space == Space::Var && s.at.offset as usize <= offset)
            .max_by_key(|s| s.at.offset)
            .map_or_else(|| "?".to_string(), |s| s.name.clone())
    }
}

/// Native code that counts the steps it executes itself.
#[derive(Debug)]
struct Counted {
    code: Arc<dyn NativeCode>,
    steps: Arc<AtomicU64>,
}

impl NativeCode for Counted {
    fn run(
        &self,
        memory: &mut NativeMemory<'_>,
        il: Option<&mut IlMemory<'_>>,
        regs: &mut NativeRegs,
    ) -> NativeExit {
        let before = regs.left;
        let exit = self.code.run(memory, il, regs);
        self.steps.fetch_add(before.saturating_sub(regs.left), Ordering::Relaxed);
        exit
    }

    fn interpret_span(&self, pc: u32) -> u32 {
        self.code.interpret_span(pc)
    }
}

// ---------------------------------------------------------------------------------------------
// Running two VMs side by side

/// How many steps each `run` call gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Budget {
    Fixed(u64),
    /// 0 to 17 (a call with no budget returns `Budget` at once), from a fixed pseudo-random
    /// sequence.
    Varying,
}

/// The time of a scan: its start, plus `step_ns` for every step since the scan began (0: the
/// clock stands still during a scan, as in the conformance suite), or since its origin when
/// that lies a few steps into the scan (`Scans::origin_after`: the time stands still before).
/// On odd scans it says it is a `StepClock` (native code computes the time itself, as for
/// `plcd sim`), on even ones it does not (native code asks it, as for the daemon's clock):
/// both ways give the same times.
struct ScanClock {
    start_ns: Cell<u64>,
    /// The origin's step.
    start_steps: Cell<u64>,
    step_ns: u64,
    origin_after: u64,
    linear: Cell<bool>,
}

impl Clock for ScanClock {
    fn now_ns(&self, steps: u64) -> u64 {
        self.start_ns.get() + steps.saturating_sub(self.start_steps.get()) * self.step_ns
    }

    fn linear(&self) -> Option<StepClock> {
        self.linear.get().then(|| StepClock {
            origin_ns: self.start_ns.get(),
            origin_steps: self.start_steps.get(),
            step_ns: self.step_ns,
        })
    }
}

/// How a case runs.
#[derive(Debug, Clone, Copy)]
struct Scans {
    count: u64,
    period_ns: u64,
    /// The clock's cost of a step (0: it stands still during a scan).
    step_ns: u64,
    /// The clock's origin lies this many steps after the scan's start.
    origin_after: u64,
    /// Stop each scan after this many `run` calls (an endless loop), instead of at `END`.
    calls: Option<u64>,
    /// Compare the Structured Text part of the activation (`ExecState::st_activation`) after
    /// every this many calls that exit with `Budget` (always after the others): 1 for every
    /// call; more for the long workloads, whose frame areas are compared whole each time.
    inner_every: u64,
    /// The frame area's bytes, when not the programs' own (`Programs::frame_bytes`).
    frame_bytes: Option<u32>,
    /// Run the programs of a scan by turns, one `run` call each, as a task preempted by
    /// another at every budget's end would, instead of one after the other.
    interleave: bool,
}

impl Scans {
    fn new(count: u64) -> Scans {
        Scans {
            count,
            period_ns: MS,
            step_ns: 0,
            origin_after: 0,
            calls: None,
            inner_every: 1,
            frame_bytes: None,
            interleave: false,
        }
    }
}

/// One VM and its programs' activations.
struct Side<'a> {
    programs: &'a [Program],
    vm: Vm,
    states: Vec<ExecState>,
    clock: ScanClock,
}

impl<'a> Side<'a> {
    fn new(programs: &'a [Program], case: &Programs, scans: Scans) -> Side<'a> {
        let mut vm = Vm::for_programs(programs);
        vm.set_variables(&case.variables);
        vm.reset_for_run(&RetainSet::default(), false);
        let frame = scans.frame_bytes.unwrap_or(case.frame_bytes);
        let states = programs.iter().map(|_| ExecState::with_frame(frame)).collect();
        let step_ns = scans.step_ns;
        let clock = ScanClock {
            start_ns: Cell::new(0),
            start_steps: Cell::new(0),
            step_ns,
            origin_after: scans.origin_after,
            linear: Cell::new(false),
        };
        Side { programs, vm, states, clock }
    }

    fn begin_scan(&mut self, scan: u64, start_ns: u64) {
        self.clock.start_ns.set(start_ns);
        self.clock.linear.set(scan % 2 == 1);
        self.clock.start_steps.set(self.vm.steps() + self.clock.origin_after);
        self.vm.begin_scan(scan == 1, start_ns);
    }

    fn run(&mut self, program: usize, budget: u64) -> Exit {
        self.vm.run(&self.programs[program], &mut self.states[program], &self.clock, budget)
    }
}

/// What a case did on the interpreter, and the mismatches of native code.
#[derive(Default)]
struct Outcome {
    mismatches: Vec<String>,
    /// Steps executed on each side (the interpreter's), and of them by native code itself,
    /// with every budget.
    steps: u64,
    native_steps: u64,
    /// The same with the whole budget (`u64::MAX`) alone: native code's share when no budget
    /// cuts its blocks.
    whole_steps: u64,
    native_whole_steps: u64,
    /// The operation errors the interpreter raised, in order (all budgets).
    errors: Vec<u16>,
    /// Exits of the interpreter with the whole budget (`u64::MAX`), for the tests' own checks.
    exits: Vec<Exit>,
    /// The interpreter's VM at the end of the first budget, and the variables' symbols, for
    /// the tests' own checks of what the programs computed.
    vm: Option<Vm>,
    symbols: plcd_core::symbols::Symbols,
}

impl Outcome {
    fn assert_equivalent(&self) {
        assert!(
            self.mismatches.is_empty(),
            "{} mismatches:\n{}",
            self.mismatches.len(),
            self.mismatches.join("\n")
        );
    }

    /// The slot of variable `name` (`main.x`) at the end, on the interpreter.
    fn slot(&self, name: &str) -> u64 {
        let symbol = self.symbols.find(name);
        let symbol = symbol.unwrap_or_else(|| panic!("no variable {name}"));
        self.vm.as_ref().expect("a budget ran").read_value(symbol.at, symbol.ty.elem())
    }

    /// The number of operation errors `code` the interpreter raised with the whole budget.
    fn errors_with_whole_budget(&self, code: u16) -> usize {
        let raised = |e: &&Exit| matches!(e, Exit::OperationError { code: c, .. } if *c == code);
        self.exits.iter().filter(raised).count()
    }

    /// With the whole budget, at least `percent` % of the steps ran as native code.
    fn assert_native_share(&self, name: &str, percent: u64) {
        assert!(
            self.native_whole_steps * 100 >= self.whole_steps * percent,
            "{name}: only {} of {} steps ran as native code",
            self.native_whole_steps,
            self.whole_steps
        );
    }
}

/// Runs `case` on both sides with every budget of `budgets`.
fn compare(case: &Programs, scans: Scans, budgets: &[Budget]) -> Outcome {
    let _deadline = deadline(&case.name);
    let native_steps = Arc::new(AtomicU64::new(0));
    let native_programs = match case.with_native(&native_steps) {
        Ok(native) => native,
        Err(e) => return Outcome { mismatches: vec![e], ..Outcome::default() },
    };
    let mut outcome = Outcome { symbols: case.variables.symbols.clone(), ..Outcome::default() };
    for &budget in budgets {
        let (steps, native) = (outcome.steps, native_steps.load(Ordering::Relaxed));
        match compare_with(case, &native_programs, scans, budget, &mut outcome) {
            Ok(vm) => {
                outcome.vm.get_or_insert(vm);
            }
            Err(mismatch) => {
                outcome.mismatches.push(format!("{} [budget {budget:?}] {mismatch}", case.name))
            }
        }
        if budget == Budget::Fixed(u64::MAX) {
            outcome.whole_steps += outcome.steps - steps;
            outcome.native_whole_steps += native_steps.load(Ordering::Relaxed) - native;
        }
    }
    outcome.native_steps = native_steps.load(Ordering::Relaxed);
    outcome
}

/// One budget: the interpreter's VM at the end, or the first mismatch (after it the two sides
/// differ anyway).
fn compare_with(
    case: &Programs,
    native: &[Program],
    scans: Scans,
    budget: Budget,
    outcome: &mut Outcome,
) -> Result<Vm, String> {
    let mut run = Run {
        case,
        scans,
        budget,
        plain: Side::new(&case.programs, case, scans),
        fast: Side::new(native, case, scans),
        // A linear congruential generator for the varying budget.
        seed: 0x2545_f491_4f6c_dd1d,
        scan_steps: vec![0; case.programs.len()],
        outcome,
    };
    for scan in 1..=scans.count {
        let start_ns = (scan - 1) * scans.period_ns;
        run.plain.begin_scan(scan, start_ns);
        run.fast.begin_scan(scan, start_ns);
        let programs = case.programs.len();
        if scans.interleave {
            // Preemption: one call of each unfinished program in turn.
            for program in 0..programs {
                run.restart(program);
            }
            let mut done = vec![false; programs];
            let mut call = 0;
            while done.contains(&false) {
                call += 1;
                for (program, done) in done.iter_mut().enumerate() {
                    if !*done {
                        *done = run.call(scan, program, call)?;
                    }
                }
            }
        } else {
            for program in 0..programs {
                run.restart(program);
                let mut call = 0;
                while !run.call(scan, program, call + 1)? {
                    call += 1;
                }
            }
        }
        run.plain.vm.end_scan();
        run.fast.vm.end_scan();
    }
    Ok(run.plain.vm)
}

/// Both sides of one budget.
struct Run<'c, 'o> {
    case: &'c Programs,
    scans: Scans,
    budget: Budget,
    plain: Side<'c>,
    fast: Side<'c>,
    seed: u64,
    /// Steps of each program in the scan under way.
    scan_steps: Vec<u64>,
    outcome: &'o mut Outcome,
}

impl Run<'_, '_> {
    fn restart(&mut self, program: usize) {
        self.plain.states[program].restart();
        self.fast.states[program].restart();
        self.scan_steps[program] = 0;
    }

    /// Call `call` of `program` in `scan` on both sides, compared: whether the program is done
    /// with the scan (`End`, or as many calls as the scans allow).
    fn call(&mut self, scan: u64, program: usize, call: u64) -> Result<bool, String> {
        let steps = match self.budget {
            Budget::Fixed(n) => n,
            Budget::Varying => {
                self.seed = self.seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                (self.seed >> 33) % 18
            }
        };
        let before = self.plain.vm.steps();
        let a = self.plain.run(program, steps);
        let b = self.fast.run(program, steps);
        let after = self.plain.vm.steps();
        self.outcome.steps += after - before;
        self.scan_steps[program] += after - before;
        if let Exit::OperationError { code, .. } = a {
            self.outcome.errors.push(code);
        }
        if self.budget == Budget::Fixed(u64::MAX) {
            self.outcome.exits.push(a);
        }
        let at = || {
            let name = &self.case.programs[program].name;
            format!("scan {scan}, program {name}, call {call} (after step {after})")
        };
        let inner = a != Exit::Budget || call.is_multiple_of(self.scans.inner_every);
        if let Some(what) = difference(self.case, &self.plain, &self.fast, program, (a, b), inner) {
            return Err(format!("{}: {what}", at()));
        }
        if self.scan_steps[program] > STEPS_PER_SCAN {
            return Err(format!("{}: the scan does not end", at()));
        }
        Ok(a == Exit::End || self.scans.calls.is_some_and(|calls| call >= calls))
    }
}

/// What differs between the interpreter (`a`) and native code (`b`) after a `run` call of
/// `program` that exited with `exits`.
fn difference(
    case: &Programs,
    a: &Side,
    b: &Side,
    program: usize,
    exits: (Exit, Exit),
    inner: bool,
) -> Option<String> {
    let (sa, sb) = (&a.states[program], &b.states[program]);
    let pair = |what: &str, x: &dyn std::fmt::Debug, y: &dyn std::fmt::Debug| {
        format!("{what}: interpreter {x:?}, native {y:?}")
    };
    if exits.0 != exits.1 {
        return Some(pair("exit", &exits.0, &exits.1));
    }
    if a.vm.steps() != b.vm.steps() {
        return Some(pair("steps", &a.vm.steps(), &b.vm.steps()));
    }
    if sa.pc() != sb.pc() {
        return Some(pair("pc", &sa.pc(), &sb.pc()));
    }
    if sa.eval_depth() != sb.eval_depth() {
        return Some(pair("evaluation stack depth", &sa.eval_depth(), &sb.eval_depth()));
    }
    if sa.call_depth() != sb.call_depth() {
        return Some(pair("call depth", &sa.call_depth(), &sb.call_depth()));
    }
    if sa.is_finished() != sb.is_finished() {
        return Some(pair("finished", &sa.is_finished(), &sb.is_finished()));
    }
    if a.vm.vars() != b.vm.vars() {
        let (x, y) = (a.vm.vars(), b.vm.vars());
        let at = (0..x.len()).find(|&i| x.get(i) != y.get(i)).unwrap_or(0);
        let end = (at + 8).min(x.len()).min(y.len());
        return Some(format!(
            "variable memory at byte {at} ({}): interpreter {:02x?}, native {:02x?}",
            case.variable_at(at),
            &x[at..end],
            &y[at..end]
        ));
    }
    let (x, y) = (a.vm.mem.words(), b.vm.mem.words());
    if x != y {
        let at = (0..x.len()).find(|&i| x[i] != y[i]).unwrap_or(0);
        return Some(format!(
            "device memory at word {at}: interpreter {:#06x}, native {:#06x}",
            x[at], y[at]
        ));
    }
    if !inner {
        return None;
    }
    // The instruction list's timers, counters and edge memory (Structured Text's live in
    // variable memory, compared above), at the end of each scan: they persist from scan to
    // scan, so a difference made anywhere shows there, and comparing them after every call
    // doubled the time of these tests.
    let il = case.programs[program].language == Language::InstructionList;
    if il && exits.0 == Exit::End {
        let (x, y) = (a.vm.device_states(), b.vm.device_states());
        if let Some(n) = x.0.iter().zip(y.0).position(|(p, q)| p != q) {
            return Some(pair(&format!("timer {n}"), &x.0[n], &y.0[n]));
        }
        if let Some(n) = x.1.iter().zip(y.1).position(|(p, q)| p != q) {
            return Some(pair(&format!("counter {n}"), &x.1[n], &y.1[n]));
        }
        if let Some(n) = x.2.iter().zip(y.2).position(|(p, q)| p != q) {
            return Some(pair(&format!("edge slot {n}"), &x.2[n], &y.2[n]));
        }
    }
    let (la, lb) = (sa.il_activation(), sb.il_activation());
    if la != lb {
        return Some(pair("instruction-list registers", &la, &lb));
    }
    let (ia, ib) = (sa.st_activation(), sb.st_activation());
    if ia.eval != ib.eval {
        return Some(pair("evaluation stack", &ia.eval, &ib.eval));
    }
    if ia.calls != ib.calls {
        return Some(pair("call frames", &ia.calls, &ib.calls));
    }
    if (ia.base, ia.this) != (ib.base, ib.this) {
        return Some(pair("frame base and FB instance", &(ia.base, ia.this), &(ib.base, ib.this)));
    }
    if ia.frame != ib.frame {
        let at = ia.frame.iter().zip(ib.frame).position(|(x, y)| x != y).unwrap_or(0);
        let end = (at + 8).min(ia.frame.len()).min(ib.frame.len());
        return Some(format!(
            "frame area at byte {at}: interpreter {:?}, native {:?}",
            &ia.frame[at..end],
            &ib.frame[at..end]
        ));
    }
    None
}

// ---------------------------------------------------------------------------------------------
// 1. Every Structured Text source of the repository

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The scan period of a conformance case: the `at <period>` of its `.expect` (1 ms without),
/// and the last scan it checks.
fn expect_of(case: &Path) -> (u64, u64) {
    let text = std::fs::read_to_string(case.with_extension("expect")).unwrap_or_default();
    let mut period = MS;
    let mut last = 1;
    for line in text.lines() {
        let Some(rest) = line.trim().strip_prefix("after ") else { continue };
        let when = rest.split(':').next().unwrap_or("");
        let mut words = when.split_whitespace();
        if let Some(n) = words.next().and_then(|n| n.parse::<u64>().ok()) {
            last = last.max(n);
        }
        if let (Some("scans"), Some("at"), Some(p)) = (words.next(), words.next(), words.next()) {
            period = plcd_core::duration::parse_duration(p).unwrap_or(MS);
        }
    }
    (period, last)
}

fn conformance_cases() -> Vec<PathBuf> {
    let mut cases = Vec::new();
    let root = repository().join("tests/st");
    for area in std::fs::read_dir(&root).expect("tests/st") {
        let area = area.unwrap().path();
        if !area.is_dir() {
            continue;
        }
        for entry in std::fs::read_dir(&area).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "st") {
                cases.push(path);
            }
        }
    }
    cases.sort();
    cases
}

/// Runs every case and fails with every mismatch of all of them.
fn check_all(cases: Vec<(Programs, Scans)>) {
    let mut mismatches = Vec::new();
    let (mut steps, mut native_steps, mut whole, mut native_whole) = (0, 0, 0, 0);
    // The cases are independent: on every core (under qemu-user the conformance cases alone
    // took minutes one after the other).
    for outcome in parallel::map(&cases, |(case, scans)| compare(case, *scans, budgets())) {
        mismatches.extend(outcome.mismatches);
        steps += outcome.steps;
        native_steps += outcome.native_steps;
        whole += outcome.whole_steps;
        native_whole += outcome.native_whole_steps;
    }
    eprintln!(
        "{} cases: {steps} steps, {native_steps} of them native; with the whole budget {whole}, \
         {native_whole} native",
        cases.len()
    );
    assert!(mismatches.is_empty(), "{} mismatches:\n{}", mismatches.len(), mismatches.join("\n"));
}

#[test]
fn every_conformance_case_runs_the_same_natively() {
    let files = conformance_cases();
    assert!(files.len() >= 60, "only {} conformance cases", files.len());
    let root = repository();
    let cases = files
        .iter()
        .map(|file| {
            let name = file.strip_prefix(&root).unwrap_or(file).display().to_string();
            let (period_ns, last) = expect_of(file);
            let case = Programs::st_file(&name, file, period_ns);
            (case, Scans { period_ns, ..Scans::new(last.max(12)) })
        })
        .collect();
    check_all(cases);
}

#[test]
fn every_bench_workload_runs_the_same_natively() {
    let dir = repository().join("benches/st");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("benches/st")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "st"))
        .collect();
    files.sort();
    assert!(files.len() >= 5, "only {} workloads", files.len());
    let cases = files
        .iter()
        .map(|file| {
            let name = format!("benches/st/{}", file.file_name().unwrap().to_string_lossy());
            (Programs::st_file(&name, file, MS), Scans { inner_every: 13, ..Scans::new(3) })
        })
        .collect();
    check_all(cases);
}

#[test]
fn the_example_project_runs_the_same_natively() {
    let path = repository().join("etc/plcd.toml");
    let text = std::fs::read_to_string(&path).expect("etc/plcd.toml");
    let case = Programs::from_config("etc/plcd.toml", &text, &path);
    assert!(case.programs.len() >= 2, "the example project's ST programs: level and tank");
    let scans = Scans { period_ns: 10 * MS, ..Scans::new(20) };
    // One after the other, and by turns (the tank's task preempting the level's).
    let interleaved = Programs::from_config("etc/plcd.toml (by turns)", &text, &path);
    check_all(vec![(case, scans), (interleaved, Scans { interleave: true, ..scans })]);
}

// ---------------------------------------------------------------------------------------------
// 2. Targeted programs: what native code does its own way

/// Runs `source` with every budget for `scans` and fails on any mismatch, or when native code
/// ran less than `share` % of the steps with the whole budget.
fn targeted(name: &str, source: &str, scans: Scans, share: u64) -> Outcome {
    let case = Programs::inline(name, source);
    let outcome = compare(&case, scans, budgets());
    eprintln!(
        "{name}: {} steps with the whole budget, {} native",
        outcome.whole_steps, outcome.native_whole_steps
    );
    outcome.assert_equivalent();
    outcome.assert_native_share(name, share);
    outcome
}

/// The slot of a REAL variable as an `f32`.
fn real(outcome: &Outcome, name: &str) -> f32 {
    f32::from_bits(outcome.slot(name) as u32)
}

#[test]
fn division_and_mod_by_zero_give_0_and_3400h() {
    let source = "
PROGRAM Main
VAR
    zi : INT; zd : DINT; zl : LINT; zu : UDINT; zr : REAL; zlr : LREAL;
    zs : SINT; zus : USINT; zui : UINT; zul : ULINT;
    a : INT := 100; ad : DINT := -100000; al : LINT := 5000000000; au : UDINT := 4000000000;
    ar : REAL := 2.5; alr : LREAL := -7.25;
    qi, mi, ei, ki : INT; qd, md, ed : DINT; ql, ml : LINT; qu, mu : UDINT;
    qr, er, nr : REAL; qlr, elr : LREAL;
    qs : SINT; qus : USINT; qui : UINT; qul : ULINT;
    n : INT;
END_VAR
    n := n + 1;
    zi := 0;
    qi := a / zi;
    mi := a MOD zi;
    ei := 7 + a / zi * 3 - (a MOD zi);
    qd := ad / zd;
    md := ad MOD zd;
    ed := ad - 1 + (ad / zd);
    ql := al / zl;
    ml := al MOD zl;
    qu := au / zu;
    mu := au MOD zu;
    qr := ar / zr;
    er := 1.5 + ar / zr * 2.0;
    qlr := alr / zlr;
    elr := alr - alr / zlr;
    qs := SINT#-5 / zs;
    qus := USINT#200 / zus;
    qui := UINT#60000 MOD zui;
    qul := ULINT#18000000000000000000 / zul;
    zr := -0.0;
    nr := ar / zr;
    zr := 0.0;
    zi := n;
    ki := a / zi + a MOD zi;
END_PROGRAM
";
    let scans = Scans::new(3);
    // After an error native code resumes only at the next block: a small share.
    let outcome = targeted("division by zero", source, scans, 5);
    assert_eq!(outcome.errors_with_whole_budget(ERR_DIVIDE_BY_ZERO), 20 * 3);
    for zero in ["qi", "mi", "qd", "md", "ql", "ml", "qu", "mu", "qlr", "qs", "qus", "qui", "qul"] {
        assert_eq!(outcome.slot(&format!("main.{zero}")), 0, "{zero}");
    }
    assert_eq!(outcome.slot("main.ei") as i16, 7);
    assert_eq!(outcome.slot("main.ed") as i32, -100001);
    assert_eq!((real(&outcome, "main.qr"), real(&outcome, "main.er")), (0.0, 1.5));
    assert_eq!(f64::from_bits(outcome.slot("main.elr")), -7.25);
    assert_eq!(real(&outcome, "main.nr"), 0.0, "-0.0 is a zero divisor");
    assert_eq!(outcome.slot("main.ki") as i16, 100 / 3 + 100 % 3);
}

#[test]
fn the_minimum_divided_by_minus_1_wraps() {
    let source = "
PROGRAM Main
VAR
    lmin, lm1, lq, lr, lc, le : LINT;
    dmin, dm1, dq, dr : DINT;
    imin, im1, iq, ir : INT;
    smin, sm1, sq, sr : SINT;
END_VAR
    lmin := -9223372036854775807;
    lmin := lmin - 1;
    lm1 := -1;
    lq := lmin / lm1;
    lr := lmin MOD lm1;
    lc := lmin / -1 + lmin MOD -1;
    le := 3 + lmin / lm1 * 2;
    dmin := -2147483647 - 1;
    dm1 := -1;
    dq := dmin / dm1;
    dr := dmin MOD dm1;
    imin := -32767 - 1;
    im1 := -1;
    iq := imin / im1;
    ir := imin MOD im1;
    smin := -127 - 1;
    sm1 := -1;
    sq := smin / sm1;
    sr := smin MOD sm1;
END_PROGRAM
";
    let outcome = targeted("minimum / -1", source, Scans::new(2), 90);
    assert!(outcome.errors.is_empty());
    assert_eq!(outcome.slot("main.lq") as i64, i64::MIN);
    assert_eq!(outcome.slot("main.lr"), 0);
    assert_eq!(outcome.slot("main.lc") as i64, i64::MIN);
    assert_eq!(outcome.slot("main.le") as i64, 3);
    assert_eq!(outcome.slot("main.dq") as i64, i64::from(i32::MIN));
    assert_eq!(outcome.slot("main.iq") as i64, i64::from(i16::MIN));
    assert_eq!(outcome.slot("main.sq") as i64, i64::from(i8::MIN));
    assert_eq!(outcome.slot("main.dr") | outcome.slot("main.ir") | outcome.slot("main.sr"), 0);
}

/// An index found inside its range in one block is not checked again in the block only it
/// leads to (`a[j - 1]` after `IF a[j - 1] ...`), but every other index there is: one a
/// little different (`j`, `j - 2`, `j - 1` into a shorter array), and the same one after the
/// IF's two ways meet. (When the IF's own index is outside, its error is raised and the
/// condition reads 0, so the block after it runs and must raise it again.)
#[test]
fn ranges_found_in_one_block_serve_the_next_only_for_the_same_index() {
    let source = "
PROGRAM Main
VAR
    a : ARRAY [0..9] OF DINT := [0, 1, 2, 3, 4, 5, 6, 7, 8, 9];
    short : ARRAY [0..4] OF DINT;
    j, n : INT;
    r1, r2, r3, r4, r5 : DINT;
END_VAR
    n := n + 1;
    (* j runs 10, 11, 0, 1, ...: a[j] is outside for j = 10, a[j - 2] for j = 0 and 1,
       short[j - 1] for j > 5 *)
    j := (n + 9) MOD 12;
    IF a[j - 1] >= 0 THEN
        r1 := a[j - 1];
        r2 := a[j];
        r3 := a[j - 2];
        r4 := short[j - 1];
    END_IF;
    r5 := a[j - 1];
END_PROGRAM
";
    let outcome = targeted("ranges across blocks", source, Scans::new(12), 80);
    // j: 10, 11, 0, 1, 2, ..., 9 over the 12 scans; an element outside reads 0 and the scan
    // goes on, so the IF's condition holds even when its own index is outside.
    // j = 10: a[j], short[j - 1]                                         2
    // j = 11: a[j - 1] in the IF and twice after it, a[j], short[j - 1]  5
    // j = 0: a[j - 1] in the IF and twice after it, a[j - 2], short      5
    // j = 1: a[j - 2]                                                    1
    // j = 6..9: short[j - 1]                                             4
    assert_eq!(outcome.errors_with_whole_budget(ERR_INDEX_RANGE), 17);
    assert!(outcome.errors.iter().all(|&e| e == ERR_INDEX_RANGE));
}

#[test]
fn array_indices_out_of_bounds_give_3402h() {
    let source = "
TYPE Pt : STRUCT x, y : INT; END_STRUCT; END_TYPE
PROGRAM Main
VAR
    a : ARRAY [1..5] OF INT := [1, 2, 3, 4, 5];
    m : ARRAY [1..3, -2..2] OF DINT;
    mm : ARRAY [0..1] OF ARRAY [0..2] OF INT;
    s : ARRAY [0..3] OF Pt;
    big : ARRAY [0..99] OF LREAL;
    i, j : INT;
    k : LINT;
    r1, r2, r3, r4, r5 : INT;
    rd : DINT;
    n : INT;
END_VAR
    n := n + 1;
    i := 5 + n;
    r1 := a[i];
    a[i] := 77;
    i := 0 - n;
    r2 := a[i] + 10;
    a[i] := a[1] + a[i];
    j := 3;
    m[2, j] := 5;
    m[n, 2 - n] := n;
    rd := m[n, 0] + m[n + 3, j - 5] * 2;
    s[n + 1].x := 9;
    r3 := s[n + 2].y + s[n].x;
    k := 9223372036854775807;
    r4 := a[k];
    big[n * 30] := 1.5;
    mm[n - 1][n] := n;
    r5 := mm[1][n + 1] + mm[n][0];
    FOR i := 1 TO 6 DO
        a[i] := a[i] + i;
    END_FOR;
END_PROGRAM
";
    let outcome = targeted("index range", source, Scans::new(4), 30);
    assert!(outcome.errors_with_whole_budget(ERR_INDEX_RANGE) >= 4 * 8);
    assert!(outcome.errors.iter().all(|&e| e == ERR_INDEX_RANGE));
    assert_eq!(outcome.slot("main.r1"), 0);
    assert_eq!(outcome.slot("main.r2"), 10);
}

#[test]
fn references_run_natively_and_fail_as_on_the_interpreter() {
    // A STRING walked through a pointer as OSCAT does, a REF_TO into a function's frame, a
    // linked list; then NULL (2822H), a pointer past variable memory and one into device
    // memory moved (2820H), which native code leaves to the interpreter.
    let source = "
TYPE Node : STRUCT v : INT; next : POINTER TO Node; END_STRUCT; END_TYPE
FUNCTION Sum : DINT
VAR_INPUT s : STRING; END_VAR
VAR pt : POINTER TO ARRAY [1..255] OF BYTE; i : INT; local : DINT; r : REF_TO DINT; END_VAR
    pt := ADR(s);
    r := REF(local);
    FOR i := 1 TO LEN(s) DO
        r^ := r^ + BYTE_TO_DINT(pt^[i]);
    END_FOR;
    Sum := local;
END_FUNCTION
PROGRAM Main
VAR
    text : STRING[20] := 'abc';
    total : DINT;
    nodes : ARRAY [0..2] OF Node := [(v := 1), (v := 2), (v := 3)];
    it : POINTER TO Node;
    walked, n, bad, far : INT;
    none : REF_TO INT;
    level AT %D00010 : INT;
    dp : POINTER TO INT;
    moved_null : BOOL;
    distance, no_distance : DINT;
END_VAR
    n := n + 1;
    total := Sum(text);
    nodes[0].next := ADR(nodes[1]);
    nodes[1].next := ADR(nodes[2]);
    walked := 0;
    it := ADR(nodes[0]);
    WHILE it <> NULL DO
        walked := walked * 10 + it^.v;
        it^.v := it^.v + 1;
        it := it^.next;
    END_WHILE;
    bad := none^ + n;
    dp := ADR(nodes[0].v) + 16#7FFFFFF0;
    far := dp^;
    dp := ADR(level);
    dp^ := n;
    dp := dp + 2;
    moved_null := dp = NULL;
    distance := ADR(nodes[2]) - ADR(nodes[0]);
    no_distance := ADR(nodes[2]) - dp;
END_PROGRAM
";
    let outcome = targeted("references", source, Scans::new(3), 70);
    assert_eq!(outcome.errors_with_whole_budget(ERR_REF_NULL), 3);
    assert_eq!(outcome.errors_with_whole_budget(ERR_REF_RANGE), 3 * 3);
    assert_eq!(outcome.slot("main.total"), 97 + 98 + 99);
    // each scan walks 1-2-3 once more incremented: 123, 234, 345
    assert_eq!(outcome.slot("main.walked"), 345);
    assert_eq!(outcome.slot("main.bad"), 3, "NULL reads 0");
    assert_eq!(outcome.slot("main.far"), 0);
    assert_eq!(outcome.slot("main.moved_null"), 1);
    // a Node is an INT and a pointer: 10 bytes
    assert_eq!(outcome.slot("main.distance"), 20);
    assert_eq!(outcome.slot("main.no_distance"), 0);
}

#[test]
fn arrays_and_structs_are_copied_whole_between_variables_and_frames() {
    let source = "
TYPE
    Small : STRUCT
        a : INT;
        b : REAL;
        c : BOOL;
        d : ARRAY [0..3] OF DINT;
    END_STRUCT;
    Big : STRUCT
        s : ARRAY [0..9] OF Small;
        n : LINT;
    END_STRUCT;
END_TYPE

FUNCTION Pass : Small
VAR_INPUT x : Small; END_VAR
VAR tmp : Small; END_VAR
    tmp := x;
    tmp.a := tmp.a + 1;
    tmp.d[3] := tmp.d[2] * 2;
    Pass := tmp;
END_FUNCTION

FUNCTION PassBig : Big
VAR_INPUT x : Big; END_VAR
VAR tmp : Big; other : Big; END_VAR
    tmp := x;
    tmp.n := tmp.n + 1;
    tmp.s[3].a := 42;
    other := tmp;
    other.s[0] := Pass(other.s[3]);
    PassBig := other;
END_FUNCTION

FUNCTION Swap : BOOL
VAR_IN_OUT p, q : Big; END_VAR
VAR t : Big; END_VAR
    t := p;
    p := q;
    q := t;
    Swap := TRUE;
END_FUNCTION

FUNCTION SwapSmall : BOOL
VAR_IN_OUT p, q : ARRAY [0..3] OF INT; END_VAR
VAR t : ARRAY [0..3] OF INT; END_VAR
    t := p;
    p := q;
    q := t;
    SwapSmall := TRUE;
END_FUNCTION

PROGRAM Main
VAR
    s1, s2 : Small;
    b1, b2 : Big;
    arr1, arr2 : ARRAY [0..99] OF INT;
    short1, short2 : ARRAY [0..3] OF INT;
    ok : BOOL;
    n : INT;
END_VAR
    n := n + 1;
    s1.a := n;
    s1.d[2] := n * 3;
    s2 := Pass(s1);
    b1.n := n;
    b1.s[9] := s2;
    b2 := PassBig(b1);
    ok := Swap(b1, b2);
    arr1[n] := n;
    arr2 := arr1;
    short1[n MOD 4] := n;
    short2 := short1;
    ok := SwapSmall(short1, short2) AND ok;
    b1.s[n MOD 10] := b2.s[(n + 1) MOD 10];
END_PROGRAM
";
    let outcome = targeted("whole copies", source, Scans::new(5), 90);
    assert!(outcome.errors.is_empty());
    assert_eq!(outcome.slot("main.s2.a"), 6);
    assert_eq!(outcome.slot("main.s2.d[3]") as i32, 30);
    assert_eq!(outcome.slot("main.b1.s[3].a"), 42, "b1 holds PassBig's result after the swap");
    assert_eq!(outcome.slot("main.arr2[5]"), 5);
}

#[test]
fn fb_instances_in_a_frame_and_in_out_parameters() {
    let source = "
FUNCTION_BLOCK Acc
VAR_INPUT in : INT; END_VAR
VAR_OUTPUT total : DINT; END_VAR
VAR_IN_OUT log : ARRAY [0..3] OF INT; END_VAR
VAR_TEMP edge : R_TRIG; c : CTU; END_VAR
    edge(CLK := in > 0);
    c(CU := edge.Q, PV := 2);
    c(CU := FALSE);
    c(CU := TRUE);
    total := total + in + c.CV;
    log[in MOD 4] := log[in MOD 4] + 1;
END_FUNCTION_BLOCK

FUNCTION Bump : INT
VAR_IN_OUT x : INT; arr : ARRAY [0..3] OF INT; END_VAR
VAR_INPUT inc : INT; END_VAR
    x := x + inc;
    arr[x MOD 4] := arr[x MOD 4] + x;
    Bump := x * 2;
END_FUNCTION

FUNCTION Twice : INT
VAR_IN_OUT y : INT; arr : ARRAY [0..3] OF INT; END_VAR
    Twice := Bump(y, arr, 1) + Bump(y, arr, 2);
END_FUNCTION

PROGRAM Main
VAR
    accs : ARRAY [1..3] OF Acc;
    lg : ARRAY [0..3] OF INT;
    i, n, v, w : INT;
    t : DINT;
END_VAR
VAR_TEMP
    pt : TP;
    tr : R_TRIG;
    inner : Acc;
END_VAR
    n := n + 1;
    FOR i := 1 TO 4 DO
        accs[i](in := i * n, log := lg);
        t := t + accs[i].total;
    END_FOR;
    inner(in := n, log := lg);
    t := t + inner.total;
    tr(CLK := n MOD 2 = 0);
    pt(IN := tr.Q, PT := T#2ms);
    w := Twice(v, lg) + Bump(lg[n MOD 4], lg, n);
END_PROGRAM
";
    let outcome = targeted("FB instances in a frame", source, Scans::new(6), 50);
    assert_eq!(outcome.errors_with_whole_budget(ERR_INDEX_RANGE), 2 * 6, "accs[4], twice");
    assert_eq!(outcome.slot("main.v"), 18);
}

/// `G`, `F`, `H` called inside expressions, in arguments of each other and in array indices:
/// the caller has values on the evaluation stack across each call, and a division by zero in
/// `H` raises its error while two callers wait.
#[test]
fn calls_inside_expressions_keep_the_callers_stack() {
    let source = "
FUNCTION G : DINT
VAR_INPUT x : DINT; END_VAR
    G := x * 3 - 1;
END_FUNCTION

FUNCTION F : DINT
VAR_INPUT x : DINT; y : DINT := 2; END_VAR
VAR t : DINT; END_VAR
    t := x + y;
    F := t * G(t) - G(x + G(y));
END_FUNCTION

FUNCTION H : LREAL
VAR_INPUT a, b : LREAL; END_VAR
    H := a / b + SQRT(ABS(a));
END_FUNCTION

PROGRAM Main
VAR
    a : DINT := 2;
    b : DINT := -3;
    c : DINT := 5;
    r, i : DINT;
    arr : ARRAY [0..4] OF DINT := [1, 2, 3, 4, 5];
    l : LREAL;
    deep : DINT;
END_VAR
    r := a + F(b * G(c)) - F(x := G(a), y := F(c)) * G(F(G(b)));
    i := i + 1;
    arr[ABS(G(i)) MOD 5] := F(arr[i MOD 5]) + arr[ABS(F(i)) MOD 5];
    l := H(LREAL#1.5 + H(2.0, DINT_TO_LREAL(r)), H(3.0, 0.0)) + H(4.0, 2.0);
    deep := a + (b * (c - (a + (b * (c - (a + (b * (c - (a + G(b * (c + F(a))))))))))));
END_PROGRAM
";
    let outcome = targeted("calls in expressions", source, Scans::new(3), 60);
    assert_eq!(outcome.errors_with_whole_budget(ERR_DIVIDE_BY_ZERO), 3);
}

/// A chain of FUNCTION calls as deep as the compiler allows (32), each waiting with values on
/// the stack.
/// Native code keeps the value of a variable it stored or fetched for the fetches after it in
/// the same straight run, and forgets it at a store that may change it: through an array
/// element in variable memory or in the frame, by a whole copy, or by a call.
#[test]
fn values_kept_in_registers_are_forgotten_when_a_store_may_change_them() {
    let source = "
FUNCTION Poke : INT
VAR_IN_OUT x : INT; END_VAR
    x := x + 10;
    Poke := x;
END_FUNCTION

PROGRAM Main
VAR
    a : ARRAY [1..4] OF INT;
    r : ARRAY [1..4] OF REAL;
    b1, b2 : ARRAY [1..2] OF INT;
    n, i, y, z, w, p, q : INT;
    f, g : REAL;
    on : BOOL;
END_VAR
VAR_TEMP
    t : ARRAY [0..3] OF INT;
    k : INT;
END_VAR
    n := n + 1;
    i := 2;
    a[2] := 5;
    a[i] := a[2] + 7;
    y := a[2];
    f := 1.5;
    r[2] := 0.25;
    r[i] := f * 2.0;
    g := r[2] + f;
    t[1] := 3;
    k := t[1];
    t[i - 1] := k + 1;
    z := t[1];
    b1[1] := 9;
    b2[1] := 1;
    b2 := b1;
    w := b2[1];
    p := n;
    q := p + Poke(p) + p;
    on := y > 10;
    on := NOT on OR on;
END_PROGRAM
";
    let outcome = targeted("values kept in registers", source, Scans::new(3), 90);
    assert!(outcome.errors.is_empty());
    assert_eq!(outcome.slot("main.y"), 12, "a[2] after a[i] := 12 with i = 2");
    assert_eq!(real(&outcome, "main.g"), 4.5, "r[2] after r[i] := 3.0");
    assert_eq!(outcome.slot("main.z"), 4, "t[1] after t[i - 1] := 4");
    assert_eq!(outcome.slot("main.w"), 9, "b2[1] after b2 := b1");
    assert_eq!(outcome.slot("main.q"), 3 + 13 + 13, "p before and after Poke(p)");
    assert_eq!(outcome.slot("main.on"), 1);
}

/// Native code passes the values of variables from block to block in registers (a loop's
/// counter and sums, a variable stored before an IF and read after it), and fetches them again
/// after a store that may change them in another block: through an array element, through a
/// VAR_IN_OUT, by a copy, by a call, by a function block writing its instance; REALs and
/// BOOLs too. Every budget stops it inside these loops.
#[test]
fn values_carried_between_blocks_are_fetched_again_after_a_store_may_change_them() {
    let source = "
FUNCTION Bump : INT
VAR_IN_OUT x : INT; END_VAR
    x := x + 100;
    Bump := 1;
END_FUNCTION

FUNCTION_BLOCK Acc
VAR_INPUT step : INT; END_VAR
VAR_OUTPUT total : INT; END_VAR
    total := total + step;
    IF total > 50 THEN
        total := total - 50;
    END_IF;
END_FUNCTION_BLOCK

PROGRAM Main
VAR
    a : ARRAY [1..4] OF INT;
    b1, b2 : ARRAY [1..2] OF INT;
    acc : Acc;
    n, i, j, s, s2, v, w, c, hits : INT;
    f, g : REAL;
    on, seen : BOOL;
END_VAR
    n := n + 1;
    s := 0;
    f := 0.5;
    on := FALSE;
    FOR i := 1 TO 4 DO
        a[i] := i * n;
        s := s + a[i];
        f := f * 1.5 + 0.25;
        IF s > 6 THEN
            on := NOT on;
        END_IF;
    END_FOR;
    v := 7;
    FOR i := 1 TO 3 DO
        a[1] := v;
        j := 1;
        a[j] := a[j] + 1;
        v := a[1] + v;
    END_FOR;
    w := 2;
    WHILE w < 40 DO
        c := c + Bump(w);
        IF w > 20 THEN
            w := w + 1;
        END_IF;
    END_WHILE;
    b1[1] := n;
    s2 := 0;
    FOR i := 1 TO 2 DO
        b2[1] := i;
        s2 := s2 + b2[1];
        b2 := b1;
        s2 := s2 + b2[1];
    END_FOR;
    FOR i := 1 TO 5 DO
        acc(step := i * 7);
        hits := hits + acc.total;
    END_FOR;
    g := 0.0;
    seen := FALSE;
    REPEAT
        g := g + f;
        IF g > 20.0 THEN
            seen := TRUE;
        END_IF;
    UNTIL seen END_REPEAT;
END_PROGRAM
";
    let outcome = targeted("values carried between blocks", source, Scans::new(4), 85);
    assert!(outcome.errors.is_empty());
    assert_eq!(outcome.slot("main.s"), 4 * 10, "s after the first loop of the fourth scan");
    assert_eq!(outcome.slot("main.v"), 7 + 8 + 16 + 32, "v through a[1] and a[j]");
    assert_eq!(outcome.slot("main.w"), 102 + 1, "w through Bump's VAR_IN_OUT");
    assert_eq!(outcome.slot("main.s2"), 1 + 4 + 2 + 4, "s2 through the copy b2 := b1");
}

/// A store through an element of an array at a fixed place forgets only the values of the
/// array's bytes (the values of other variables stay in registers): every element it may reach
/// is fetched again after it, its first and its last, a member of a struct element, a
/// struct element copied whole, in the same block and in the blocks after it.
#[test]
fn a_store_into_an_array_forgets_the_values_of_its_elements_only() {
    let source = "
TYPE Cell : STRUCT a : INT; b : DINT; END_STRUCT; END_TYPE

PROGRAM Main
VAR
    before : INT;
    c : ARRAY [0..3] OF Cell;
    after : INT;
    one : Cell;
    d : ARRAY [1..3] OF SINT;
    i, n, first, last, member, whole, kept, k, looped : DINT;
END_VAR
    n := n + 1;
    before := 11;
    after := 22;
    c[0].a := 1;
    c[3].b := 2;
    d[1] := 3;
    d[3] := 4;
    first := INT_TO_DINT(c[0].a);
    last := c[3].b;
    i := 0;
    c[i].a := 100 + DINT_TO_INT(n);
    first := INT_TO_DINT(c[0].a + before);
    i := 3;
    c[i].b := 200 + n;
    last := c[3].b + INT_TO_DINT(after);
    one.a := 5;
    one.b := 300 + n;
    member := c[3].b;
    c[i] := one;
    whole := c[3].b + INT_TO_DINT(c[3].a + after);
    member := SINT_TO_DINT(d[3]);
    i := 3;
    d[i] := 44;
    kept := INT_TO_DINT(before + after) + SINT_TO_DINT(d[1]);
    member := member + SINT_TO_DINT(d[3]);
    looped := 0;
    FOR k := 0 TO 3 DO
        c[3].a := 7;
        looped := looped + INT_TO_DINT(c[3].a);
        c[k].a := 1000;
        looped := looped + INT_TO_DINT(c[3].a + before);
    END_FOR;
END_PROGRAM
";
    let outcome = targeted("a store into an array", source, Scans::new(3), 90);
    assert!(outcome.errors.is_empty());
    assert_eq!(outcome.slot("main.first"), 103 + 11, "c[0].a after c[i].a := 103 with i = 0");
    assert_eq!(outcome.slot("main.last"), 203 + 22, "c[3].b after c[i].b := 203 with i = 3");
    assert_eq!(outcome.slot("main.whole"), 303 + 5 + 22, "c[3] after c[i] := one with i = 3");
    assert_eq!(outcome.slot("main.kept"), 11 + 22 + 3);
    assert_eq!(outcome.slot("main.member"), 4 + 44, "d[3] before and after d[i] := 44");
    assert_eq!(outcome.slot("main.looped"), 3 * (7 + 7 + 11) + 7 + 1000 + 11);
}

#[test]
fn stores_kept_in_registers_in_a_loop_are_written_before_anything_reads_them() {
    // In a loop native code keeps a stored variable in a register and writes it back only
    // where something else may read the place: a read through a pointer, a store through one,
    // a member of another width over the same bytes, a call, the way out of the loop, and
    // every stop of the budget (compared at each).
    let source = "
TYPE U4 : UNION dw : DWORD; b : ARRAY [0..3] OF BYTE; END_UNION; END_TYPE

VAR_GLOBAL g : DINT; END_VAR

FUNCTION ReadGlobal : DINT
    ReadGlobal := g;
END_FUNCTION

PROGRAM Main
VAR
    acc, k, through, called, by_byte, exited : DINT;
    u : U4;
    p : POINTER TO DINT;
    arr : ARRAY [0..3] OF DINT;
END_VAR
    acc := 0;
    through := 0;
    called := 0;
    by_byte := 0;
    p := ADR(acc);
    FOR k := 1 TO 5 DO
        acc := acc + k;
        through := through + p^;
        p^ := p^ + 100;
        acc := acc - 100;
        g := g + k;
        called := called + ReadGlobal();
        u.dw := DINT_TO_DWORD(k * 16#01010101);
        by_byte := by_byte + BYTE_TO_DINT(u.b[1]);
        arr[k MOD 4] := acc;
        IF k = 4 THEN
            EXIT;
        END_IF;
    END_FOR;
    exited := acc;
END_PROGRAM
";
    let outcome = targeted("stores kept in registers", source, Scans::new(3), 80);
    assert!(outcome.errors.is_empty());
    // k = 1 to 4 (EXIT at 4): acc 1, 3, 6, 10.
    assert_eq!(outcome.slot("main.exited"), 10);
    assert_eq!(outcome.slot("main.through"), 1 + 3 + 6 + 10, "p^ reads acc as just stored");
    // g grows by 1 + 2 + 3 + 4 a scan: in the third scan 21, 23, 26, 30.
    assert_eq!(outcome.slot("g"), 30);
    assert_eq!(outcome.slot("main.called"), 21 + 23 + 26 + 30, "the call reads g as stored");
    // Byte 1 of k * 16#01010101 is k.
    assert_eq!(outcome.slot("main.by_byte"), 1 + 2 + 3 + 4);
    assert_eq!(outcome.slot("main.arr[0]"), 10);
    assert_eq!(outcome.slot("main.arr[3]"), 6);
}

#[test]
fn counted_loops_stop_where_the_interpreter_does_at_every_budget() {
    // FOR loops of many shapes, with every budget from 1 to 160 steps a call: the budget's end
    // falls at every place of each loop's first and last rounds, where native code checks
    // it once a round (a loop's first block). The loops: a bound whose variable the body
    // changes (FOR evaluated it once), nested loops, a step of -1, no round, an empty body, a
    // division by zero in round `zero_at`, an EXIT, bounds at the ends of DINT, INT, USINT and
    // UDINT (the counter wraps after the last round), a counter the body writes, stores into
    // an array's elements, and an index out of bounds in the last round.
    let source = "
PROGRAM Main
VAR
    n : DINT := 6;
    i, j, k, acc, sum, nested, down, empty, q, exited, big, small, written, wide : DINT;
    zero_at : DINT := 2;
    si : INT; us : USINT; ud : UDINT;
    arr : ARRAY [0..9] OF DINT;
    last, e : INT := 9;
END_VAR
    sum := 0;
    FOR i := 1 TO n DO
        sum := sum + i * 3;
        n := n - 1;
    END_FOR;
    n := 6;
    nested := 0;
    FOR i := 1 TO 4 DO
        FOR j := i TO 5 DO
            nested := nested + i * j;
        END_FOR;
    END_FOR;
    down := 0;
    FOR i := 10 TO -3 BY -1 DO
        down := down + i;
    END_FOR;
    FOR i := 1 TO 0 DO
        empty := empty + 100;
    END_FOR;
    FOR i := 1 TO 7 DO
    END_FOR;
    empty := empty + i;
    q := 0;
    FOR j := 1 TO 6 DO
        q := q + 60 / (j - zero_at);
    END_FOR;
    zero_at := zero_at MOD 6 + 1;
    exited := 0;
    FOR j := 1 TO 100 DO
        exited := exited + j;
        IF exited > 20 THEN
            EXIT;
        END_IF;
    END_FOR;
    big := 0;
    FOR i := 2147483643 TO 2147483647 DO
        big := big + i MOD 10;
    END_FOR;
    FOR k := -2147483644 TO -2147483648 BY -1 DO
        small := small + 1;
    END_FOR;
    acc := 0;
    FOR si := 32763 TO 32767 DO
        acc := acc + si;
    END_FOR;
    FOR us := 251 TO 255 DO
        acc := acc + us;
    END_FOR;
    wide := 0;
    FOR ud := 4294967292 TO 4294967295 DO
        wide := wide + 1;
    END_FOR;
    written := 0;
    FOR k := 1 TO 10 DO
        written := written + k;
        k := k + 1;
    END_FOR;
    FOR e := 0 TO 9 DO
        arr[e] := arr[e] + e;
    END_FOR;
    FOR e := 0 TO last + 1 DO
        arr[e] := arr[e] - 1;
    END_FOR;
END_PROGRAM
";
    let case = Programs::inline("counted loops", source);
    let every = if budgets().len() == BUDGETS.len() { 1 } else { 7 };
    let budgets: Vec<Budget> = [Budget::Fixed(u64::MAX), Budget::Varying]
        .into_iter()
        .chain((1..=160).step_by(every).map(Budget::Fixed))
        .collect();
    let outcome = compare(&case, Scans::new(3), &budgets);
    outcome.assert_equivalent();
    outcome.assert_native_share("counted loops", 80);
    let slot = |name: &str| outcome.slot(&format!("main.{name}")) as i32;
    assert_eq!(slot("sum"), 3 * (1 + 2 + 3 + 4 + 5 + 6), "the bound is n as it was");
    assert_eq!(slot("nested"), (1..=4).flat_map(|i| (i..=5).map(move |j| i * j)).sum::<i32>());
    assert_eq!(slot("down"), (-3..=10).sum::<i32>());
    assert_eq!(slot("empty"), 3 * 8, "the counter one past 7 after each scan's empty loop");
    // Scan 3: the zero in round 4 (zero_at 2, 3, 4 in scans 1 to 3).
    assert_eq!(slot("q"), -20 - 30 - 60 + 60 + 30, "60 / (j - 4) for j = 1 to 6 but 4");
    assert_eq!(slot("exited"), 1 + 2 + 3 + 4 + 5 + 6);
    assert_eq!(slot("big"), 3 + 4 + 5 + 6 + 7);
    assert_eq!(slot("i"), i32::MIN, "the counter wrapped past the last round");
    assert_eq!((slot("small"), slot("k") as i16), (3 * 5, 11));
    assert_eq!(slot("acc"), (32763..=32767).sum::<i32>() + (251..=255).sum::<i32>());
    assert_eq!(slot("wide"), 4);
    assert_eq!(slot("written"), 1 + 3 + 5 + 7 + 9);
    // Whole budget, each scan: one division by zero, and `arr[10]` out of bounds twice (read,
    // then written).
    assert_eq!(outcome.errors_with_whole_budget(ERR_DIVIDE_BY_ZERO), 3);
    assert_eq!(outcome.errors_with_whole_budget(ERR_INDEX_RANGE), 2 * 3);
    assert_eq!((slot("arr[0]"), slot("arr[3]"), slot("arr[9]")), (-3, 6, 24));
}

/// A chain of `depth` FUNCTIONs, each calling the next inside an expression, and a PROGRAM
/// calling the first twice.
fn function_chain(depth: usize) -> String {
    let mut source = String::new();
    for k in 1..=depth {
        let body = if k == depth {
            format!("F{k} := x + {k};")
        } else {
            format!("t := x * 2 + {k};\n    F{k} := t + F{}(t MOD 1000) * 3 - {k};", k + 1)
        };
        let _ = write!(
            source,
            "FUNCTION F{k} : DINT\nVAR_INPUT x : DINT; END_VAR\nVAR t : DINT; END_VAR\n    \
             {body}\nEND_FUNCTION\n\n"
        );
    }
    source.push_str(
        "PROGRAM Main\nVAR n, r : DINT; END_VAR\n    n := n + 1;\n    r := 5 + F1(n) * 2 - F1(r MOD 7);\nEND_PROGRAM\n",
    );
    source
}

#[test]
fn a_deep_call_chain() {
    let outcome = targeted("deep call chain", &function_chain(32), Scans::new(3), 90);
    assert!(outcome.errors.is_empty());
}

/// Native code's calls stop where its machine stack is spent, and the interpreter makes the
/// call there: the same chain with less and less stack runs the same, with less of it native.
#[test]
fn a_deep_call_chain_on_a_short_machine_stack() {
    let source = function_chain(12);
    let mut case = Programs::inline("short machine stack", &source);
    let mut native = Vec::new();
    // 0: no call native; 4 KiB and a little more: the helpers' reserve and a few frames.
    for bytes in [0, 4_600, 5_000, 6_000, 64 << 10] {
        case.native_stack = Some(bytes);
        let outcome = compare(&case, Scans::new(3), budgets());
        outcome.assert_equivalent();
        native.push((bytes, outcome.native_whole_steps));
    }
    eprintln!("native steps by machine stack: {native:?}");
    assert!(native.windows(2).all(|w| w[0].1 <= w[1].1), "{native:?}");
    assert!(native[0].1 < native[native.len() - 1].1, "{native:?}");
}

#[test]
fn located_variables_of_every_size() {
    let source = "
PROGRAM Main
VAR
    w AT %MW5 : INT := -3;
    uw AT %M006 : UINT;
    sb AT %D00010 : SINT;
    ub AT %D00011 : BYTE;
    us AT %D00012 : USINT := 200;
    d AT %D00020 : DINT := 16#12345678;
    alias AT %D00020 : INT;
    ud AT %MD30 : UDINT;
    r AT %D00040 : REAL := 1.5;
    lr AT %D00050 : LREAL := -2.25;
    li AT %ML40 : LINT;
    lw AT %D00060 : LWORD;
    ew AT %D00065 : WORD;
    bm AT %MX1.2 : BOOL;
    bp AT %QX4.6 : BOOL;
    bd AT %D00070.F : BOOL;
    bi AT %IX0.1 : BOOL;
    bk AT %M0123 : BOOL;
    arr AT %D00100 : ARRAY [0..7] OF INT;
    darr AT %D00120 : ARRAY [0..3] OF DINT;
    bits AT %M0200 : ARRAY [0..19] OF BOOL;
    n, i : INT;
    x : DINT;
END_VAR
    n := n + 1;
    w := w * 2 + n;
    uw := uw + 1000;
    sb := sb - 50;
    ub := ROL(ub, 1) XOR 16#5A;
    us := us + 30;
    d := d + DINT#65536 * INT_TO_DINT(n);
    alias := alias + 1;
    ud := ud - 1;
    r := r * -1.5;
    lr := lr * lr;
    li := li - 1000000007;
    lw := ROL(lw, 3) XOR 16#F0F0;
    ew.3 := NOT ew.3;
    ew := ew XOR SHL(ew, 4) XOR 16#100;
    bm := NOT bm;
    bp := bm AND n MOD 3 = 0;
    bd := NOT bd;
    bi := n MOD 2 = 0;
    bk := bi OR bd;
    arr[n MOD 8] := arr[(n + 1) MOD 8] + n;
    darr[n MOD 4] := darr[(n + 3) MOD 4] - d;
    bits[n MOD 20] := NOT bits[(n + 19) MOD 20];
    FOR i := 0 TO 7 DO
        x := x + arr[i] + SINT_TO_DINT(sb) + BYTE_TO_DINT(ub);
    END_FOR;
END_PROGRAM
";
    let outcome = targeted("located variables", source, Scans::new(6), 50);
    assert!(outcome.errors.is_empty());
}

/// IEC byte addresses (`%QB1`): each a half of a device word, which native code reads and
/// writes without the other half, at a fixed place, at an index and through a reference.
#[test]
fn device_bytes_keep_their_neighbour() {
    let source = "
FUNCTION Twice : BOOL
VAR_IN_OUT
    x : SINT;
END_VAR
    x := x * 2;
    Twice := TRUE;
END_FUNCTION

PROGRAM Main
VAR
    lo AT %QB0 : BYTE;
    hi AT %QB1 : BYTE;
    s AT %QB3 : SINT;
    bits AT %QX2.0 : ARRAY [0..7] OF BOOL;
    word AT %D13024 : WORD;
    next AT %D13025 : WORD;
    m AT %QB5 : USINT := 250;
    arr AT %IB8 : ARRAY [0..4] OF BYTE;
    r : REF_TO BYTE;
    n, i : INT;
    sum : UDINT;
    ok : BOOL;
END_VAR
    n := n + 1;
    lo := lo + 16#11;
    hi := ROL(hi, 1) XOR 16#A5;
    bits[n MOD 8] := NOT bits[n MOD 8];
    s := s - 7;
    ok := Twice(x := s);
    m := m + 3;
    arr[n MOD 5] := arr[(n + 4) MOD 5] + INT_TO_BYTE(n);
    r := REF(arr[n MOD 5]);
    r^ := r^ XOR hi;
    hi.%X0 := n MOD 2 = 0;
    FOR i := 0 TO 4 DO
        sum := sum + BYTE_TO_UDINT(arr[i]) + WORD_TO_UDINT(word) + WORD_TO_UDINT(next);
    END_FOR;
END_PROGRAM
";
    // an element at an index and a reference into device memory are the interpreter's (as
    // for device words): the fixed places are native code's
    let outcome = targeted("device bytes", source, Scans::new(6), 30);
    assert!(outcome.errors.is_empty());
    // %QB0 and %QB1 are the halves of D13024 (openplc's %QB area): 6 scans of +16#11 in the
    // low one
    assert_eq!(outcome.slot("main.word") & 0xFF, 6 * 0x11);
    assert_eq!(outcome.slot("main.word") >> 8, outcome.slot("main.hi"));
}

/// Every comparison of REAL and LREAL with a NaN operand (and infinities): all FALSE but `<>`.
#[test]
fn comparisons_with_nan() {
    let operands = ["nan", "nan2", "one", "inf", "ninf", "zero"];
    let ops = ["=", "<>", "<", "<=", ">", ">="];
    let mut body = String::new();
    let mut count = 0;
    for prefix in ["", "l"] {
        for a in operands {
            for b in operands {
                for op in ops {
                    let _ = writeln!(body, "    c[{count}] := {prefix}{a} {op} {prefix}{b};");
                    count += 1;
                }
            }
        }
    }
    let source = format!(
        "
PROGRAM Main
VAR
    m1 : REAL := -1.0; big : REAL := 3.0E38; one : REAL := 1.0; zero : REAL;
    nan, nan2, inf, ninf, mn, mx, lim : REAL;
    lm1 : LREAL := -1.0; lbig : LREAL := 1.0E308; lone : LREAL := 1.0; lzero : LREAL;
    lnan, lnan2, linf, lninf, lmn : LREAL;
    c : ARRAY [0..{last}] OF BOOL;
    b1, b2, b3, b4 : BOOL;
    i : INT;
END_VAR
    nan := SQRT(m1);
    inf := big * 10.0;
    ninf := -inf;
    nan2 := inf + ninf;
    lnan := LN(lm1);
    linf := lbig * 10.0;
    lninf := -linf;
    lnan2 := linf - linf;
{body}
    mn := MIN(nan, one);
    mx := MAX(one, nan);
    lim := LIMIT(zero, nan, one);
    lmn := MIN(lone, lnan);
    b1 := REAL_TO_BOOL(nan);
    b2 := NOT (nan >= zero);
    b3 := nan = nan OR nan <> zero;
    b4 := LREAL_TO_BOOL(lnan) AND lnan <> lnan;
    i := 0;
    IF nan < one THEN
        i := 1;
    ELSIF nan > one THEN
        i := 2;
    ELSE
        i := 3;
    END_IF;
    WHILE lnan <> lnan AND i < 10 DO
        i := i + 1;
    END_WHILE;
END_PROGRAM
",
        last = count - 1
    );
    let outcome = targeted("NaN comparisons", &source, Scans::new(2), 90);
    assert_eq!(outcome.slot("main.i"), 10);
    // `nan <> nan` holds, `nan = nan` does not.
    assert_eq!((outcome.slot("main.c[0]"), outcome.slot("main.c[1]")), (0, 1));
}

/// REAL and LREAL to every integer width: NaN, infinities, out of range, ties, the largest
/// values below a tie; and the 64-bit integers to REAL and LREAL.
#[test]
fn float_to_integer_conversions() {
    let reals = [
        "0.5",
        "1.5",
        "2.5",
        "-0.5",
        "-1.5",
        "-2.5",
        "0.49999997",
        "-0.49999997",
        "127.5",
        "-128.5",
        "255.5",
        "32767.5",
        "-32768.5",
        "65535.5",
        "2147483647.0",
        "-2147483648.0",
        "4294967295.0",
        "9.3E18",
        "-9.3E18",
        "1.8E19",
        "3.4E38",
        "-3.4E38",
        "1.0E-45",
        "-0.0",
        "16777217.0",
        "100.4",
    ];
    let lreals = [
        "0.49999999999999994",
        "-0.49999999999999994",
        "2147483647.5",
        "-2147483648.5",
        "4294967295.5",
        "4294967296.0",
        "9223372036854775807.0",
        "-9223372036854775808.0",
        "18446744073709551615.0",
        "1.0E300",
        "-1.0E300",
        "4503599627370496.5",
        "2.5",
        "-3.5",
        "9007199254740993.0",
        "5.0E-324",
    ];
    // The special values are set at run time: NaN and the infinities have no literal.
    let (nr, nl) = (reals.len() + 3, lreals.len() + 3);
    let list = |xs: &[&str]| xs.join(", ");
    let source = format!(
        "
PROGRAM Main
VAR
    rv : ARRAY [0..{rl}] OF REAL := [{r}];
    lv : ARRAY [0..{ll}] OF LREAL := [{l}];
    i8 : ARRAY [0..{ll}] OF SINT; u8 : ARRAY [0..{ll}] OF USINT;
    i16 : ARRAY [0..{ll}] OF INT; u16 : ARRAY [0..{ll}] OF UINT;
    i32 : ARRAY [0..{ll}] OF DINT; u32 : ARRAY [0..{ll}] OF UDINT;
    i64 : ARRAY [0..{ll}] OF LINT; u64 : ARRAY [0..{ll}] OF ULINT;
    t32 : ARRAY [0..{ll}] OF DINT; w16 : ARRAY [0..{ll}] OF WORD;
    li : ARRAY [0..{ll}] OF LINT; lu : ARRAY [0..{ll}] OF ULINT;
    lt : ARRAY [0..{ll}] OF DINT;
    back, back2 : ARRAY [0..7] OF REAL; lback : ARRAY [0..7] OF LREAL;
    m1 : REAL := -1.0; big : REAL := 3.0E38;
    lm1 : LREAL := -1.0; lbig : LREAL := 1.0E308;
    ints : ARRAY [0..7] OF LINT := [9223372036854775807, -9223372036854775807, 16777217,
        36028797018963967, -36028797018963969, 0, 1, 9007199254740993];
    uints : ARRAY [0..7] OF ULINT := [18446744073709551615, 9223372036854775808, 16777217,
        18446744073709550592, 18446744073709549568, 0, 1, 9007199254740993];
    demoted : ARRAY [0..{ll}] OF REAL;
    i : INT;
END_VAR
    rv[{r0}] := SQRT(m1);
    rv[{r0} + 1] := big * 10.0;
    rv[{r0} + 2] := -(big * 10.0);
    lv[{l0}] := SQRT(lm1);
    lv[{l0} + 1] := lbig * 10.0;
    lv[{l0} + 2] := -(lbig * 10.0);
    FOR i := 0 TO {rl} DO
        i8[i] := REAL_TO_SINT(rv[i]);
        u8[i] := REAL_TO_USINT(rv[i]);
        i16[i] := REAL_TO_INT(rv[i]);
        u16[i] := REAL_TO_UINT(rv[i]);
        i32[i] := REAL_TO_DINT(rv[i]);
        u32[i] := REAL_TO_UDINT(rv[i]);
        i64[i] := REAL_TO_LINT(rv[i]);
        u64[i] := REAL_TO_ULINT(rv[i]);
        t32[i] := TRUNC(rv[i]);
        w16[i] := REAL_TO_WORD(rv[i]);
    END_FOR;
    FOR i := 0 TO {ll} DO
        li[i] := LREAL_TO_LINT(lv[i]);
        lu[i] := LREAL_TO_ULINT(lv[i]);
        lt[i] := TRUNC(lv[i]) + LREAL_TO_DINT(lv[i]) - UDINT_TO_DINT(LREAL_TO_UDINT(lv[i]));
        demoted[i] := LREAL_TO_REAL(lv[i]);
    END_FOR;
    FOR i := 0 TO 7 DO
        back[i] := LINT_TO_REAL(ints[i]);
        back2[i] := ULINT_TO_REAL(uints[i]);
        lback[i] := LINT_TO_LREAL(ints[i]) + ULINT_TO_LREAL(uints[i]);
    END_FOR;
END_PROGRAM
",
        rl = nr - 1,
        ll = nl.max(nr) - 1,
        r = list(&reals),
        l = list(&lreals),
        r0 = reals.len(),
        l0 = lreals.len(),
    );
    let outcome = targeted("float to integer", &source, Scans::new(2), 90);
    assert!(outcome.errors.is_empty());
    assert_eq!(outcome.slot("main.i16[2]") as i16, 3, "2.5 rounds away from zero");
    assert_eq!(outcome.slot(&format!("main.i32[{}]", reals.len())), 0, "NaN gives 0");
}

#[test]
fn float_functions_and_selections() {
    let inputs =
        ["-1.0", "0.0", "-0.0", "0.5", "2.0", "1.0E30", "-1.0E30", "3.14159", "-2.7", "1.0"];
    let funcs = ["SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "ABS"];
    let n = inputs.len() + 3;
    let mut body = String::new();
    for (k, f) in funcs.iter().enumerate() {
        let _ = writeln!(
            body,
            "            r[{k}, i] := {f}(x[i]);\n            l[{k}, i] := {f}(lx[i]);"
        );
    }
    let m = funcs.len();
    let source = format!(
        "
PROGRAM Main
VAR
    x : ARRAY [0..{last}] OF REAL := [{inputs}];
    lx : ARRAY [0..{last}] OF LREAL;
    r : ARRAY [0..{m}, 0..{last}] OF REAL;
    l : ARRAY [0..{m}, 0..{last}] OF LREAL;
    p, q : ARRAY [0..{last}, 0..{last}] OF REAL;
    lp : ARRAY [0..{last}, 0..{last}] OF LREAL;
    t : ARRAY [0..{last}] OF DINT;
    big : REAL := 3.0E38;
    i, j, k : INT;
    mi, ma, li, se, mu, mu2 : INT;
    md : DINT; mr, lr2, sr : REAL; ml : LREAL;
    a : INT := -7; b : INT := 12; c : INT := 3;
    ia : INT := -32767;
END_VAR
    x[{base}] := big * 10.0;
    x[{base} + 1] := -(big * 10.0);
    x[{base} + 2] := SQRT(x[0]);
    k := k + 1;
    (* The functions in the first two scans, the selections in all. *)
    IF k <= 2 THEN
        FOR i := 0 TO {last} DO
            lx[i] := REAL_TO_LREAL(x[i]) * INT_TO_LREAL(k);
{body}
            r[{m}, i] := x[i] ** 2.0;
            l[{m}, i] := EXPT(lx[i], 0.5);
            t[i] := TRUNC(x[i]) + TRUNC(lx[i] * 3.0);
            FOR j := 0 TO {last} DO
                p[i, j] := EXPT(x[i], x[j]);
                q[i, j] := MIN(x[i], x[j]) + MAX(x[j], x[i]) - LIMIT(x[j], x[i], 2.0);
                lp[i, j] := lx[i] ** lx[j];
            END_FOR;
        END_FOR;
    END_IF;
    mi := MIN(a, b, c, k);
    ma := MAX(a * 2, b, c - k);
    li := LIMIT(a, k * 5, b);
    se := SEL(k MOD 2 = 0, a, b) + SEL(TRUE, 1, 2);
    mu := MUX(k MOD 4, a, b, c);
    mu2 := MUX(k - 1, 10, 20, 30, 40, 50);
    md := MAX(DINT#-5, INT_TO_DINT(a) * 100000, DINT#7);
    mr := LIMIT(-1.5, INT_TO_REAL(k) * 0.75, 2.25);
    lr2 := SEL(k > 2, x[3], x[4]);
    sr := MUX(k MOD 3, x[0], x[5], x[9]);
    ml := MIN(lx[3], lx[5], lx[6]);
    ia := ABS(ia - k);
END_PROGRAM
",
        last = n - 1,
        inputs = inputs.join(", "),
        base = inputs.len(),
    );
    let outcome = targeted("float functions", &source, Scans::new(6), 90);
    // MUX(k MOD 4, …) with three inputs: K = 3 at the third scan; MUX(k - 1, …five) at the
    // sixth.
    assert_eq!(outcome.errors_with_whole_budget(ERR_INDEX_RANGE), 2);
    assert!(outcome.errors.iter().all(|&e| e == ERR_INDEX_RANGE));
}

#[test]
fn shifts_and_rotations() {
    let counts = [0, 1, 3, 7, 8, 9, 15, 16, 17, 31, 32, 33, 63, 64, 65, 1000, -1, -8, -65];
    let n = counts.len();
    let source = format!(
        "
PROGRAM Main
VAR
    cs : ARRAY [0..{last}] OF DINT := [{counts}];
    b : BYTE := 16#A5; w : WORD := 16#8421; d : DWORD := 16#80000001;
    l : LWORD := 16#8000_0000_0000_0003;
    rb : ARRAY [0..3, 0..{last}] OF BYTE;
    rw : ARRAY [0..3, 0..{last}] OF WORD;
    rd : ARRAY [0..3, 0..{last}] OF DWORD;
    rl : ARRAY [0..3, 0..{last}] OF LWORD;
    ru : ARRAY [0..3, 0..{last}] OF LWORD;
    u : UDINT;
    i : INT;
END_VAR
    FOR i := 0 TO {last} DO
        rb[0, i] := SHL(b, cs[i]);
        rb[1, i] := SHR(b, cs[i]);
        rb[2, i] := ROL(b, cs[i]);
        rb[3, i] := ROR(b, cs[i]);
        rw[0, i] := SHL(w, cs[i]);
        rw[1, i] := SHR(w, cs[i]);
        rw[2, i] := ROL(w, cs[i]);
        rw[3, i] := ROR(w, cs[i]);
        rd[0, i] := SHL(d, cs[i]);
        rd[1, i] := SHR(d, cs[i]);
        rd[2, i] := ROL(d, cs[i]);
        rd[3, i] := ROR(d, cs[i]);
        rl[0, i] := SHL(l, cs[i]);
        rl[1, i] := SHR(l, cs[i]);
        rl[2, i] := ROL(l, cs[i]);
        rl[3, i] := ROR(l, cs[i]);
        u := DINT_TO_UDINT(cs[i]);
        ru[0, i] := SHL(l, u) OR SHR(l, u);
        ru[1, i] := ROL(l, u) XOR ROR(l, u);
        ru[2, i] := ROL(WORD_TO_LWORD(w), u) AND NOT ROR(l, u);
        ru[3, i] := DWORD_TO_LWORD(ROL(d, u)) XOR BYTE_TO_LWORD(ROR(b, u));
    END_FOR;
    b := ROL(b, 1);
    w := ROR(w, 3) XOR SHL(w, 1);
    d := ROL(d, 5) XOR 1;
    l := ROR(l, 7) OR SHR(l, 60);
END_PROGRAM
",
        last = n - 1,
        counts = counts.map(|c| c.to_string()).join(", "),
    );
    let outcome = targeted("shifts", &source, Scans::new(3), 90);
    assert!(outcome.errors.is_empty());
}

/// EN and ENO (calls skipped, ENO stored and bound, a declared EN returning at entry), edge
/// inputs, and CODESYS's arithmetic on bit strings and shifts of integers: branches around
/// calls and the entries of bodies, all in native code.
#[test]
fn en_eno_edges_and_codesys_arithmetic() {
    let source = "
FUNCTION Scale : INT
VAR_INPUT x : INT; END_VAR
VAR_OUTPUT rest : INT; END_VAR
    Scale := x / 3;
    rest := x MOD 3;
    IF x < 0 THEN ENO := FALSE; END_IF;
END_FUNCTION

FUNCTION_BLOCK Count
VAR_INPUT up : BOOL R_EDGE; down : BOOL F_EDGE; step : WORD := 1; END_VAR
VAR_OUTPUT n : WORD; falls : INT; END_VAR
    IF up THEN n := n + step; END_IF;
    IF down THEN falls := falls + 1; END_IF;
    IF n > 16#FFF0 THEN ENO := FALSE; END_IF;
END_FUNCTION_BLOCK

FUNCTION_BLOCK Own
VAR_INPUT EN : BOOL; k : INT; END_VAR
VAR_OUTPUT ENO : BOOL; total : DINT; END_VAR
    total := total + k;
END_FUNCTION_BLOCK

PROGRAM Main
VAR
    scan : INT;
    i : INT;
    cs : ARRAY [0..3] OF Count;
    own : Own;
    q, r : ARRAY [0..7] OF INT;
    ok : ARRAY [0..7] OF BOOL;
    enos : ARRAY [0..3] OF BOOL;
    acc : DWORD := 16#1234;
    b : BYTE := 7;
    sh : ARRAY [0..3] OF INT;
    lim : INT;
    fl : REAL;
END_VAR
    scan := scan + 1;
    FOR i := 0 TO 7 DO
        q[i] := Scale(EN := (i + scan) MOD 3 <> 0, x := (i - 3) * scan, rest => r[i], ENO => ok[i]);
    END_FOR;
    FOR i := 0 TO 3 DO
        cs[i](EN := i <> scan MOD 4, up := (scan + i) MOD 2 = 0, down := (scan + i) MOD 3 = 0,
              step := INT_TO_WORD(i * 1000), ENO => enos[i]);
        sh[i] := SHR(INT#-1000 * scan, i) + ROL(i - scan, i * 5);
    END_FOR;
    own(EN := scan MOD 2 = 1, k := scan);
    acc := acc * b + cs[1].n - DINT_TO_SINT(scan) + q[2];
    b := b + 3;
    fl := b * INT_TO_REAL(scan) / 4.0;
    lim := LIMIT(EN := scan > 2, MN := 0, IN := q[7], MX := 10) + ADD(EN := FALSE, IN1 := 1, IN2 := 2);
END_PROGRAM
";
    let outcome = targeted("en/eno", source, Scans::new(6), 90);
    assert!(outcome.errors.is_empty());
}

/// Strings run on the interpreter inside native code: mixed execution, with arithmetic
/// around each string operation.
#[test]
fn strings_mixed_with_native_code() {
    let source = "
FUNCTION Tag : STRING[20]
VAR_INPUT s : STRING[10]; n : INT; END_VAR
VAR t : STRING[20]; END_VAR
    t := CONCAT(LEFT(s, n), '-', INT_TO_STRING(n * 7));
    Tag := t;
END_FUNCTION

PROGRAM Main
VAR
    a : STRING := 'hello world';
    b : STRING[8];
    c : STRING;
    n, l, f : INT;
    eq : BOOL;
    v : DINT;
    r : REAL;
    names : ARRAY [0..2] OF STRING[12] := ['alpha', 'beta', 'gamma'];
END_VAR
    n := n + 1;
    b := MID(a, n, 2);
    c := CONCAT(b, Tag('abcdef', n MOD 7), RIGHT(a, n));
    l := LEN(c) * 3 + n;
    f := FIND(c, 'o') + l;
    eq := b < c AND l > 5;
    v := STRING_TO_DINT(INT_TO_STRING(l * 100)) + 1;
    r := STRING_TO_REAL('2.5') * INT_TO_REAL(n);
    a := REPLACE(a, INT_TO_STRING(n), 1, n MOD 11 + 1);
    c := INSERT(c, 'x', n);
    c := DELETE(c, 2, 1);
    names[n MOD 3] := CONCAT(names[(n + 1) MOD 3], LEFT(b, 1));
    IF names[0] = names[1] OR LEN(names[2]) > 10 THEN
        names[2] := 'reset';
    END_IF;
END_PROGRAM
";
    let outcome = targeted("strings", source, Scans::new(12), 20);
    assert!(outcome.errors.is_empty());
}

/// TON, TOF and TP read the clock (`Now`, executed by the interpreter); with a clock that
/// charges every step, their times show the exact step at which each call read it.
#[test]
fn timers_read_the_clock_at_the_same_step() {
    let source = "
PROGRAM Main
VAR
    n : INT;
    on_delay : TON;
    off_delay : TOF;
    pulse : TP;
    bank : ARRAY [0..3] OF TON;
    i : INT;
    et : DINT;
    times : ARRAY [0..3] OF TIME;
END_VAR
    n := n + 1;
    on_delay(IN := n MOD 7 <> 0, PT := T#3ms);
    off_delay(IN := n MOD 5 = 0, PT := T#2ms500us);
    pulse(IN := n MOD 4 = 1, PT := T#1ms700us);
    FOR i := 0 TO 3 DO
        bank[i](IN := n > i, PT := T#1ms * (i + 1));
        times[i] := bank[i].ET + on_delay.ET;
        et := et + TIME_TO_DINT(bank[i].ET) * 2 + n;
    END_FOR;
END_PROGRAM
";
    targeted("timers", source, Scans::new(20), 20);
    // 50 µs a step: a timer's ET depends on the step of its call.
    let stepped = Scans { step_ns: 50_000, ..Scans::new(20) };
    let outcome = targeted("timers on a stepping clock", source, stepped, 20);
    assert!(outcome.slot("main.bank[0].ET").is_multiple_of(50_000));
}

/// An endless loop stopped by the budget: each `Budget` exit at the same step and pc, the
/// loop's state the same, whether the loop is in the program or in a function it calls.
#[test]
fn an_endless_loop_stops_at_the_same_step_for_any_budget() {
    let source = "
FUNCTION Spin : DINT
VAR_INPUT start : DINT; END_VAR
VAR k, x : DINT; END_VAR
    x := start;
    REPEAT
        FOR k := 1 TO 3 DO
            x := x * 3 + k;
        END_FOR;
        x := x MOD 100003;
    UNTIL x < 0 END_REPEAT;
    Spin := x;
END_FUNCTION

PROGRAM Main
VAR
    x, y : DINT;
    r : REAL := 1.0;
    arr : ARRAY [0..7] OF DINT;
END_VAR
    WHILE TRUE DO
        x := x + 1;
        y := y * 3 + x;
        r := r * 1.5 + DINT_TO_REAL(y MOD 7);
        arr[x MOD 8] := arr[(x + 1) MOD 8] + y;
        IF x > 5000 THEN
            y := Spin(y);
        END_IF;
    END_WHILE;
END_PROGRAM
";
    let case = Programs::inline("endless loop", source);
    let budgets = [Budget::Fixed(1000), Budget::Fixed(997), Budget::Fixed(13), Budget::Varying];
    let scans = Scans { calls: Some(200), ..Scans::new(1) };
    let outcome = compare(&case, scans, &budgets);
    outcome.assert_equivalent();
    // 200 calls of 1000 steps: the loop entered Spin, which never returns.
    let vm = outcome.vm.as_ref().expect("ran");
    assert_eq!(vm.steps(), 200 * 1000);
    assert!(outcome.native_steps > 100_000, "{} native steps", outcome.native_steps);
    assert!(outcome.errors.is_empty());
}

/// An endless loop made of CODESYS jumps (`JMP` back to a label, in the program and in a
/// function it calls) stops at the same step for any budget, as WHILE's does: a backward jump
/// is charged to the step budget natively too.
#[test]
fn an_endless_jmp_loop_stops_at_the_same_step_for_any_budget() {
    let source = "
FUNCTION Spin : DINT
VAR_INPUT start : DINT; END_VAR
VAR x : DINT; END_VAR
    x := start;
again:
    x := (x * 3 + 1) MOD 100003;
    IF x >= 0 THEN
        JMP again;
    END_IF;
    Spin := x;
END_FUNCTION

PROGRAM Main
VAR
    x, y : DINT;
END_VAR
top:
    x := x + 1;
    y := y * 3 + x;
    IF x > 5000 THEN
        y := Spin(y);
    END_IF;
    JMP top;
END_PROGRAM
";
    let case = Programs::inline("endless jmp loop", source);
    let budgets = [Budget::Fixed(1000), Budget::Fixed(997), Budget::Fixed(13), Budget::Varying];
    let scans = Scans { calls: Some(200), ..Scans::new(1) };
    let outcome = compare(&case, scans, &budgets);
    outcome.assert_equivalent();
    // 200 calls of 1000 steps: the loop entered Spin, which never returns.
    let vm = outcome.vm.as_ref().expect("ran");
    assert_eq!(vm.steps(), 200 * 1000);
    assert!(outcome.native_steps > 100_000, "{} native steps", outcome.native_steps);
    assert!(outcome.errors.is_empty());
}

/// Arithmetic on two different NaNs (of both signs, with a payload, a signaling one): which
/// operand's NaN an operation returns is the processor's choice by operand order (x86-64: the
/// first), so native code must keep the interpreter's order; the bits land in variable memory.
///
/// In a release build the interpreter's `+` and `*` return the second operand's NaN (LLVM
/// commutes them), native code the first's: `nan + mnan` with `nan` = SQRT(-1.0) (16#FFC00000)
/// and `mnan` = -nan gives 16#7FC00000 on the interpreter and 16#FFC00000 natively (REAL and
/// LREAL alike; `-` and `/` agree). So this test only runs in a debug build, where the
/// interpreter keeps the order.
#[test]
#[cfg_attr(
    not(debug_assertions),
    ignore = "release build: the interpreter's + and * return the second NaN operand, native code the first"
)]
fn arithmetic_on_different_nans_keeps_the_bits() {
    let ops = ["+", "-", "*", "/"];
    let pairs = [("nan", "mnan"), ("mnan", "nan"), ("pr", "nan"), ("mnan", "pr"), ("sr", "one")];
    let mut body = String::new();
    let mut k = 0;
    for prefix in ["", "l"] {
        for (a, b) in pairs {
            for op in ops {
                let _ = writeln!(body, "    {prefix}r[{k}] := {prefix}{a} {op} {prefix}{b};");
                k += 1;
            }
            let _ = writeln!(body, "    {prefix}r[{k}] := MIN({prefix}{a}, {prefix}{b});");
            let _ = writeln!(body, "    {prefix}r[{}] := MAX({prefix}{a}, {prefix}{b});", k + 1);
            let _ = writeln!(body, "    {prefix}r[{}] := -{prefix}{a} + ABS({prefix}{b});", k + 2);
            k += 3;
        }
    }
    let source = format!(
        "
PROGRAM Main
VAR
    m1 : REAL := -1.0; one : REAL := 1.0;
    nan, mnan : REAL;
    pn AT %D00300 : DWORD := 16#7FC12345;
    pr AT %D00300 : REAL;
    sn AT %D00302 : DWORD := 16#7F800001;
    sr AT %D00302 : REAL;
    lm1 : LREAL := -1.0; lone : LREAL := 1.0;
    lnan, lmnan : LREAL;
    lpn AT %D00310 : LWORD := 16#7FF8_0000_0001_2345;
    lpr AT %D00310 : LREAL;
    lsn AT %D00314 : LWORD := 16#7FF0_0000_0000_0001;
    lsr AT %D00314 : LREAL;
    r : ARRAY [0..{k}] OF REAL;
    lr : ARRAY [0..{k}] OF LREAL;
    widened : LREAL;
    narrowed : REAL;
END_VAR
    nan := SQRT(m1);
    mnan := -nan;
    lnan := SQRT(lm1);
    lmnan := -lnan;
{body}
    widened := REAL_TO_LREAL(pr) + REAL_TO_LREAL(sr);
    narrowed := LREAL_TO_REAL(lpr) * LREAL_TO_REAL(lsr);
END_PROGRAM
"
    );
    let outcome = targeted("NaN bits", &source, Scans::new(2), 90);
    assert!(outcome.errors.is_empty());
}

/// A frame area smaller than the program needs (the engine never gives one, but `Vm::run`
/// takes any): native code leaves every access outside it to the interpreter, which reads 0
/// and writes nothing there. (No loop on a frame variable: it would never end.)
#[test]
fn a_frame_smaller_than_the_program_needs() {
    let source = "
TYPE Small : STRUCT a : INT; d : ARRAY [0..3] OF DINT; END_STRUCT; END_TYPE
FUNCTION Inner : DINT
VAR_INPUT x : DINT; s : Small; END_VAR
VAR t : ARRAY [0..7] OF DINT; u : Small; END_VAR
    t[x MOD 8] := x * 2;
    u := s;
    u.d[1] := t[x MOD 8] + u.a;
    Inner := u.d[1] + t[(x + 1) MOD 8];
END_FUNCTION
FUNCTION Outer : DINT
VAR_INPUT x : DINT; END_VAR
VAR s : Small; k : DINT; END_VAR
    s.a := 3;
    k := x MOD 3;
    Outer := Inner(x + k, s) * (k + 1);
    Outer := Outer + Inner(x - k, s) * 2;
END_FUNCTION
PROGRAM Main
VAR n, r : DINT; keep : Small; END_VAR
VAR_TEMP trig : R_TRIG; END_VAR
    n := n + 1;
    r := 1 + Outer(n) * 2;
    trig(CLK := n MOD 2 = 0);
    keep.d[n MOD 4] := r;
END_PROGRAM
";
    let case = Programs::inline("small frame", source);
    for frame in [0, 3, case.frame_bytes / 2, case.frame_bytes - 1, case.frame_bytes + 5] {
        let scans = Scans { frame_bytes: Some(frame), ..Scans::new(3) };
        let outcome = compare(&case, scans, budgets());
        outcome.assert_equivalent();
    }
}

/// A call made with `held` values on the evaluation stack, into a FUNCTION whose expression
/// needs `m + 1` more. Up to the stack's 64 slots the two agree; past them the ring would wrap
/// (the interpreter's callee overwriting its caller's first slots, where native code keeps
/// them in registers: 67 against 66 when this test found it), so the compiler refuses the
/// program (tests/golden/st/call-chain-stack-too-deep).
fn call_chain(held: usize, m: usize) -> String {
    format!(
        "
FUNCTION F : DINT
VAR_INPUT x : DINT; END_VAR
    F := {callee}x{close_callee};
END_FUNCTION

PROGRAM Main
VAR a : DINT := 1; r : DINT; END_VAR
    r := {caller}F(a){close_caller};
END_PROGRAM
",
        callee = "x + (".repeat(m),
        caller = "a + (".repeat(held),
        close_callee = ")".repeat(m),
        close_caller = ")".repeat(held),
    )
}

#[test]
fn a_call_chain_as_deep_as_the_evaluation_stack() {
    // 38 held, 26 in the callee: all 64 slots.
    targeted("evaluation stack full", &call_chain(38, 25), Scans::new(2), 90);
}

#[test]
fn a_call_chain_deeper_than_the_evaluation_stack_is_refused() {
    let source = call_chain(40, 25);
    let (file, diags) = parse_file(Path::new("inline.st"), &source);
    assert!(diags.is_empty(), "{diags}");
    let path = Path::new("inline.st");
    let main = Instance { name: "main", pou: None, file: path, config: path, line: 1, col: 1 };
    let Err(refused) = compile(&[file], &[main]) else { panic!("a 66-slot chain is refused") };
    assert!(
        refused.to_string().contains("needs 66 evaluation stack slots with its calls (limit 64)"),
        "{refused}"
    );
}

/// `VAR_IN_OUT` references into every space: variable memory, a caller's frame, a word device,
/// a bit device, an array element of each; bits of a referenced word.
#[test]
fn in_out_references_into_every_space() {
    let source = "
FUNCTION Bump : INT
VAR_IN_OUT x : INT; flag : BOOL; END_VAR
VAR_INPUT inc : INT; END_VAR
    x := x + inc;
    x.3 := NOT x.3;
    flag := NOT flag OR x.0;
    Bump := x * 2;
END_FUNCTION

FUNCTION Local : INT
VAR_INPUT start : INT; END_VAR
VAR loc : INT; f : BOOL; arr : ARRAY [0..3] OF INT; END_VAR
    loc := start;
    Local := Bump(loc, f, 5) + Bump(arr[start MOD 4], f, loc);
    Local := Local + loc + arr[start MOD 4] + BOOL_TO_INT(f);
END_FUNCTION

PROGRAM Main
VAR
    v : INT;
    b : BOOL;
    w AT %MW7 : INT;
    mb AT %MX3.4 : BOOL;
    pb AT %QX5.1 : BOOL;
    words AT %D00400 : ARRAY [0..3] OF INT;
    bits AT %M0400 : ARRAY [0..7] OF BOOL;
    vars : ARRAY [0..3] OF INT;
    n, r : INT;
END_VAR
    n := n + 1;
    r := Bump(v, b, n) + Bump(w, mb, n * 2);
    r := r + Bump(words[n MOD 4], bits[n MOD 8], 3) + Bump(vars[n MOD 4], pb, -1);
    r := r + Local(n);
END_PROGRAM
";
    let outcome = targeted("in-out references", source, Scans::new(5), 40);
    assert!(outcome.errors.is_empty());
}

/// Programs that share globals, run by turns one `run` call each (a task preempted at every
/// budget's end): native code reads what another program wrote between two of its calls,
/// and leaves in memory everything the other reads.
#[test]
fn programs_preempting_each_other_share_globals() {
    let source = "
VAR_GLOBAL
    shared : ARRAY [0..7] OF DINT;
    turn : DINT;
    total : LREAL;
END_VAR

FUNCTION Mix : DINT
VAR_INPUT k : DINT; END_VAR
    shared[k MOD 8] := shared[(k + 1) MOD 8] + k;
    Mix := shared[k MOD 8] * 2 + turn;
END_FUNCTION

PROGRAM Producer
VAR i : DINT; sum : DINT; END_VAR
    FOR i := 0 TO 15 DO
        turn := turn + 1;
        sum := sum + Mix(i) - shared[(i + 3) MOD 8];
        total := total + DINT_TO_LREAL(sum) * 0.5;
    END_FOR;
END_PROGRAM

PROGRAM Consumer
VAR i : DINT; seen : ARRAY [0..7] OF DINT; last : LREAL; END_VAR
    FOR i := 7 TO 0 BY -1 DO
        seen[i] := shared[i] + turn * Mix(i + turn);
        turn := turn * 3 MOD 1000;
        last := total - DINT_TO_LREAL(seen[i]);
    END_FOR;
END_PROGRAM
";
    let instances = [("producer", Some("Producer")), ("consumer", Some("Consumer"))];
    let case = Programs::instances("preemption", source, &instances);
    for interleave in [false, true] {
        let outcome = compare(&case, Scans { interleave, ..Scans::new(4) }, budgets());
        outcome.assert_equivalent();
        outcome.assert_native_share("preemption", 90);
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Random programs: statements, loops, calls, FB instances, arrays

/// A small deterministic generator (xorshift), so that a failing program is found again from
/// its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    fn pick<'a>(&mut self, xs: &[&'a str]) -> &'a str {
        xs[self.below(xs.len() as u64) as usize]
    }
}

/// Random well-typed Structured Text: DINT, REAL and BOOL expressions over variables, array
/// elements (indices may fall outside), FUNCTION results and FB outputs; divisions that may be
/// by zero; assignments, IF, CASE, bounded FOR and WHILE loops, FB calls.
struct Gen<'r> {
    rng: &'r mut Rng,
    /// The DINT, REAL and BOOL names the current POU may read; of them, the first
    /// `writable` of each it may also write (the others are inputs or loop counters).
    dints: Vec<&'static str>,
    reals: Vec<&'static str>,
    bools: Vec<&'static str>,
    writable: (usize, usize),
    /// Whether the POU may call F1, F2 and the FB instances.
    calls: (bool, bool, bool),
    /// Free loop counters.
    counters: Vec<&'static str>,
}

impl Gen<'_> {
    fn dint(&mut self, depth: u32) -> String {
        let leaf = depth == 0 || self.rng.below(3) == 0;
        if leaf {
            return match self.rng.below(4) {
                0 => format!("{}", self.rng.below(21) as i64 - 10),
                1 => format!("arr[{}]", self.rng.below(8)),
                _ => self.rng.pick(&self.dints).to_string(),
            };
        }
        let d = depth - 1;
        match self.rng.below(12) {
            0..=3 => {
                let op = self.rng.pick(&["+", "-", "*", "/", "MOD", "+", "-"]);
                let (a, b) = (self.dint(d), self.dint(d));
                if op == "/" || op == "MOD" {
                    // A divisor with a variable: a constant 0 is refused by the compiler.
                    let var = self.rng.pick(&self.dints);
                    format!("({a} {op} ({b} - {var}))")
                } else {
                    format!("({a} {op} {b})")
                }
            }
            4 => format!("arr[{}]", self.index(d)),
            5 => format!("REAL_TO_DINT({})", self.real(d)),
            6 => format!("SEL({}, {}, {})", self.boolean(d), self.dint(d), self.dint(d)),
            7 => format!("{}({}, {})", self.rng.pick(&["MAX", "MIN"]), self.dint(d), self.dint(d)),
            8 if self.calls.0 => format!("F1({}, {})", self.dint(d), self.dint(d)),
            9 if self.calls.2 => format!("fbs[{}].out", self.rng.below(3)),
            10 => format!("ABS({})", self.dint(d)),
            _ => format!("-{}", self.dint(d)),
        }
    }

    /// An index of `arr`, now and then outside its bounds; never a constant (the compiler
    /// refuses a constant one outside).
    fn index(&mut self, depth: u32) -> String {
        let var = self.rng.pick(&self.dints);
        format!("({} + {var}) MOD 9", self.dint(depth))
    }

    fn real(&mut self, depth: u32) -> String {
        let leaf = depth == 0 || self.rng.below(3) == 0;
        if leaf {
            return match self.rng.below(3) {
                0 => format!("{}.{}", self.rng.below(20) as i64 - 10, self.rng.below(100)),
                _ => self.rng.pick(&self.reals).to_string(),
            };
        }
        let d = depth - 1;
        match self.rng.below(8) {
            0..=2 => {
                let op = self.rng.pick(&["+", "-", "*", "/"]);
                let (a, b) = (self.real(d), self.real(d));
                if op == "/" {
                    let var = self.rng.pick(&self.reals);
                    format!("({a} / ({b} - {var}))")
                } else {
                    format!("({a} {op} {b})")
                }
            }
            3 => format!("DINT_TO_REAL({})", self.dint(d)),
            4 if self.calls.1 => format!("F2({}, {})", self.real(d), self.dint(d)),
            5 => format!("SQRT(ABS({}))", self.real(d)),
            6 => format!("LIMIT(-100.0, {}, 100.0)", self.real(d)),
            _ => format!("-{}", self.real(d)),
        }
    }

    fn boolean(&mut self, depth: u32) -> String {
        let leaf = depth == 0 || self.rng.below(3) == 0;
        if leaf {
            return self.rng.pick(&self.bools).to_string();
        }
        let d = depth - 1;
        let cmp = ["<", "<=", ">", ">=", "=", "<>"];
        match self.rng.below(6) {
            0 | 1 => format!("({} {} {})", self.dint(d), self.rng.pick(&cmp), self.dint(d)),
            2 => format!("({} {} {})", self.real(d), self.rng.pick(&cmp), self.real(d)),
            3 => format!("NOT {}", self.boolean(d)),
            _ => {
                let op = self.rng.pick(&["AND", "OR", "XOR"]);
                format!("({} {op} {})", self.boolean(d), self.boolean(d))
            }
        }
    }

    fn statements(&mut self, count: u64, depth: u32, indent: usize, out: &mut String) {
        for _ in 0..count {
            self.statement(depth, indent, out);
        }
    }

    fn statement(&mut self, depth: u32, indent: usize, out: &mut String) {
        let pad = " ".repeat(indent);
        let nested = depth > 0;
        match self.rng.below(12) {
            0 | 1 => {
                let target = self.rng.pick(&self.dints[..self.writable.0]);
                let _ = writeln!(out, "{pad}{target} := {};", self.dint(3));
            }
            2 => {
                let _ = writeln!(out, "{pad}arr[{}] := {};", self.index(2), self.dint(3));
            }
            3 => {
                let target = self.rng.pick(&self.reals[..self.writable.1]);
                let _ = writeln!(out, "{pad}{target} := {};", self.real(3));
            }
            4 => {
                let target = self.rng.pick(&self.bools);
                let _ = writeln!(out, "{pad}{target} := {};", self.boolean(3));
            }
            5 if nested => {
                let _ = writeln!(out, "{pad}IF {} THEN", self.boolean(2));
                let n = 1 + self.rng.below(3);
                self.statements(n, depth - 1, indent + 4, out);
                if self.rng.below(2) == 0 {
                    let _ = writeln!(out, "{pad}ELSIF {} THEN", self.boolean(2));
                    self.statement(depth - 1, indent + 4, out);
                }
                let _ = writeln!(out, "{pad}ELSE");
                self.statement(depth - 1, indent + 4, out);
                let _ = writeln!(out, "{pad}END_IF;");
            }
            6 if nested => {
                let _ = writeln!(out, "{pad}CASE {} MOD 4 OF", self.dint(2));
                for label in ["0", "1, 2", "-3..-1"] {
                    let _ = writeln!(out, "{pad}    {label}:");
                    self.statement(depth - 1, indent + 8, out);
                }
                let _ = writeln!(out, "{pad}ELSE");
                self.statement(depth - 1, indent + 4, out);
                let _ = writeln!(out, "{pad}END_CASE;");
            }
            7 if nested && !self.counters.is_empty() => {
                let i = self.counters.pop().expect("a counter");
                let (from, to) = (self.rng.below(4) as i64 - 1, self.rng.below(6));
                let by = self.rng.pick(&["", " BY 2", " BY -1"]);
                let _ = writeln!(out, "{pad}FOR {i} := {from} TO {to}{by} DO");
                self.dints.push(i);
                let n = 1 + self.rng.below(3);
                self.statements(n, depth - 1, indent + 4, out);
                if self.rng.below(4) == 0 {
                    let _ = writeln!(out, "{pad}    IF {} THEN EXIT; END_IF;", self.boolean(1));
                }
                self.dints.pop();
                self.counters.push(i);
                let _ = writeln!(out, "{pad}END_FOR;");
            }
            8 if nested && !self.counters.is_empty() => {
                let w = self.counters.pop().expect("a counter");
                let _ = writeln!(out, "{pad}{w} := 0;");
                let _ = writeln!(out, "{pad}WHILE {w} < 4 AND {} DO", self.boolean(2));
                let _ = writeln!(out, "{pad}    {w} := {w} + 1;");
                let n = 1 + self.rng.below(2);
                self.statements(n, depth - 1, indent + 4, out);
                if self.rng.below(4) == 0 {
                    let _ = writeln!(out, "{pad}    IF {} THEN CONTINUE; END_IF;", self.boolean(1));
                }
                let _ = writeln!(out, "{pad}END_WHILE;");
                self.counters.push(w);
            }
            9 if self.calls.2 => {
                // Always inside: an instance out of range is the discard one, whose loop
                // counter reads 0 for ever (the targeted tests call one).
                let var = self.rng.pick(&self.dints);
                let index = format!("(({} + {var}) MOD 3 + 3) MOD 3", self.dint(1));
                let (input, k) = (self.dint(2), self.real(2));
                let _ = writeln!(out, "{pad}fbs[{index}](in := {input}, k := {k});");
            }
            _ => {
                let target = self.rng.pick(&self.dints[..self.writable.0]);
                let _ = writeln!(out, "{pad}{target} := {target} + {};", self.dint(2));
            }
        }
    }
}

/// The random program of `seed`: two FUNCTIONs, a FUNCTION_BLOCK and a PROGRAM that uses
/// them.
fn random_program(seed: u64) -> String {
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut out = String::new();
    // `dints` and `reals`: the writable names first, then the inputs.
    let pou = |rng: &mut Rng,
               (dints, reals, writable): (&[&'static str], &[&'static str], (usize, usize)),
               bools: &[&'static str],
               calls,
               counters: &[&'static str],
               statements: u64,
               out: &mut String| {
        let mut g = Gen {
            rng,
            dints: dints.to_vec(),
            reals: reals.to_vec(),
            bools: bools.to_vec(),
            writable,
            calls,
            counters: counters.to_vec(),
        };
        g.statements(statements, 3, 4, out);
    };
    out.push_str(
        "VAR_GLOBAL\n    arr : ARRAY [0..7] OF DINT := [3, -1, 4, 1, -5, 9, 2, -6];\nEND_VAR\n\n\
         FUNCTION F1 : DINT\nVAR_INPUT x, y : DINT; END_VAR\nVAR t : DINT; q : REAL; b : BOOL; \
         w : DINT; END_VAR\n",
    );
    let names = (&["t", "x", "y"][..], &["q"][..], (1, 1));
    pou(&mut rng, names, &["b"], (false, false, false), &["w"], 3, &mut out);
    let _ = writeln!(out, "    F1 := t + x - y;\nEND_FUNCTION\n");
    out.push_str(
        "FUNCTION F2 : REAL\nVAR_INPUT x : REAL; k : DINT; END_VAR\nVAR r : REAL; c, w : DINT; \
         b : BOOL; END_VAR\n",
    );
    let names = (&["c", "k"][..], &["r", "x"][..], (1, 1));
    pou(&mut rng, names, &["b"], (true, false, false), &["w"], 3, &mut out);
    let _ = writeln!(out, "    F2 := r + x * 0.5;\nEND_FUNCTION\n");
    out.push_str(
        "FUNCTION_BLOCK Fb\nVAR_INPUT in : DINT; k : REAL; END_VAR\nVAR_OUTPUT out : DINT; \
         END_VAR\nVAR acc : DINT; q : REAL; b : BOOL; i, w : DINT; END_VAR\n",
    );
    let names = (&["out", "acc", "in"][..], &["q", "k"][..], (2, 1));
    pou(&mut rng, names, &["b"], (true, true, false), &["i", "w"], 4, &mut out);
    let _ = writeln!(out, "    out := out + acc MOD 1000;\nEND_FUNCTION_BLOCK\n");
    out.push_str(
        "PROGRAM Main\nVAR\n    d0, d1, d2 : DINT;\n    d3 : DINT := 7;\n    r0 : REAL := 1.5;\n    \
         r1 : REAL;\n    b0 : BOOL := TRUE;\n    b1 : BOOL;\n    fbs : ARRAY [0..2] OF Fb;\n    \
         i, j, w : DINT;\nEND_VAR\n",
    );
    let names = (&["d0", "d1", "d2", "d3"][..], &["r0", "r1"][..], (4, 2));
    pou(&mut rng, names, &["b0", "b1"], (true, true, true), &["i", "j", "w"], 8, &mut out);
    out.push_str("END_PROGRAM\n");
    out
}

/// Runs the random programs of seeds `seeds` on both sides; every mismatch, with the seed and
/// the program.
fn check_random(seeds: std::ops::Range<u64>) {
    let budgets = [
        Budget::Fixed(u64::MAX),
        Budget::Fixed(1),
        Budget::Fixed(3),
        Budget::Fixed(7),
        Budget::Varying,
    ];
    let mut failures = Vec::new();
    for seed in seeds {
        let source = random_program(seed);
        let case = Programs::inline(&format!("random program {seed}"), &source);
        let outcome = compare(&case, Scans::new(3), &budgets);
        if !outcome.mismatches.is_empty() {
            failures.push(format!("{}\n{source}", outcome.mismatches.join("\n")));
        }
    }
    assert!(failures.is_empty(), "{} programs differ:\n{}", failures.len(), failures.join("\n"));
}

/// Seeds 0 to 9 (each program takes some 0.2 s to compile in a debug build);
/// `PLCD_RANDOM_PROGRAMS=FIRST..END` runs others (e.g. `0..5000` with `--release`). Seeds 0 to
/// 9000 ran clean, but for seed 149 in a release build: a `+` or `*` on two NaNs of different
/// signs, as in `arithmetic_on_different_nans_keeps_the_bits`.
#[test]
fn random_programs_run_the_same_natively() {
    let seeds = std::env::var("PLCD_RANDOM_PROGRAMS").ok().and_then(|range| {
        let (first, end) = range.split_once("..")?;
        Some(first.trim().parse().ok()?..end.trim().parse().ok()?)
    });
    check_random(seeds.unwrap_or(0..10));
}

/// `plcd_native::attach` compiles every program of a project, in either language, but the
/// instruction-list programs native code would make slower, which it does not report: more
/// than one instruction in 16 the interpreter's (init.il: `INIT_DONE`, one of 4).
#[test]
fn attach_compiles_every_program_of_the_example_project() {
    let path = repository().join("etc/plcd.toml");
    let text = std::fs::read_to_string(&path).expect("etc/plcd.toml");
    let config = plcd_core::config::parse(&text, &path).expect("the example config");
    let mut project = plcd_core::project::from_config(config, |p| std::fs::read_to_string(p))
        .expect("the example project");
    let errors = plcd_native::attach(&mut project);
    assert_eq!(errors, []);
    for program in &project.programs {
        assert_eq!(program.native.is_some(), program.name != "init", "{}", program.name);
    }
    let init = project.programs.iter().find(|p| p.name == "init").unwrap();
    let slower = plcd_native::compile(init);
    assert!(
        matches!(slower, Err(plcd_native::Error::Slower { interpreted: 1, instructions: 4, .. })),
        "{slower:?}"
    );
    assert!(plcd_native::compile_even_if_slower(init).is_ok());
}

/// The Structured Text part of an activation the comparison reads holds what is live: the
/// caller's slots during a call, the call frame, the frame area (an activation that showed
/// less would let the comparison pass on nothing).
#[test]
fn the_activation_compared_holds_every_live_part() {
    let source = "
FUNCTION F : DINT
VAR_INPUT x : DINT; END_VAR
VAR t : ARRAY [0..3] OF DINT; END_VAR
    t[1] := x * 2;
    F := t[1] + 1;
END_FUNCTION
PROGRAM Main
VAR a : DINT := 5; r : DINT; END_VAR
    r := a + (a * F(a));
END_PROGRAM
";
    let case = Programs::inline("debug form", source);
    let mut side = Side::new(&case.programs, &case, Scans::new(1));
    side.begin_scan(1, 0);
    side.states[0].restart();
    // Step until inside F with values on the caller's stack.
    while side.states[0].call_depth() == 0 {
        assert_eq!(side.run(0, 1), Exit::Budget);
    }
    let state = &side.states[0];
    let inner = state.st_activation();
    assert_eq!(inner.frame.len(), case.frame_bytes as usize);
    assert_eq!(inner.calls.len(), 1);
    assert!(state.eval_depth() >= 2, "a and a on the caller's stack");
    assert_eq!(inner.eval.len(), state.eval_depth());
    assert_eq!(inner.calls[0].base, 0, "called from the program's frame");
    assert!(inner.calls[0].return_pc > 0, "F returns into Main");
    assert_eq!(inner.eval[..2], [5, 5], "a and a, waiting for F(a)");
}

// ---------------------------------------------------------------------------------------------
// 4. The instruction list
//
// The same comparison for instruction-list programs (plcd_native::il): every instruction of
// docs/LANGUAGE.md, the repository's instruction-list programs, and random programs. The
// programs read and change their own inputs (a counter in D00000 whose bits feed the
// contacts), so each scan takes other paths than the last.

/// Runs instruction-list `sources` for `count` scans, the clock charging `step_ns` a step,
/// with every budget; requires `share` % of the steps to run as native code.
fn il_case(name: &str, sources: &[(&str, &str)], count: u64, step_ns: u64, share: u64) -> Outcome {
    let case = Programs::il(name, sources);
    let scans = Scans { step_ns, ..Scans::new(count) };
    let outcome = compare(&case, scans, budgets());
    outcome.assert_equivalent();
    outcome.assert_native_share(name, share);
    outcome
}

/// Every instruction of docs/LANGUAGE.md but the system ones that stop a task (`STOP`,
/// `INIT_DONE`, `IORF`, `DI`, `EI`: `System` exits, tested below), with operands that make
/// each take both of its paths over the scans.
const EVERY_INSTRUCTION: &str = "\
    LOAD _ON\nINC D00000\n\
    LOAD D00000.0\nAND NOT D00000.1\nOR D00000.2\nOR NOT D00000.3\nOUT M0000\nOUT NOT M0001\n\
    LOAD NOT D00000.1\nLOAD D00000.2\nAND D00000.3\nOR LOAD\nLOAD D00000.4\nOR NOT D00000.0\nAND LOAD\nOUT M0002\n\
    LOAD D00000.1\nMPUSH\nAND D00000.2\nOUT M0003\nMLOAD\nAND NOT D00000.3\nOUT M0004\nMPOP\nNOT\nOUT M0005\n\
    LOAD= D00000 7\nOR< D00000 3\nAND<> D00000 5\nOUT M0006\n\
    LOAD> D00000 9\nAND>= D00000 12\nOR<= D00001 -4\nOUT M0007\n\
    LOAD M0000\nLOAD< D00001 D00000\nAND LOAD\nSET M0008\nLOAD M0001\nRST M0008\n\
    LOAD D00000.0\nMOV D00000 D00002\nADD D00002 30000 D00003\nSUB D00003 -7 D00004\nMUL D00000 -1234 D00005\n\
    LOAD D00000.1\nINC D00006\nDEC D00007\nMOV -5 D00001\n\
    LOAD D00000.2\nDIV D00005 D00000 D00008\nLOAD D00000.3\nDIV D00000 0 D00009\nDIVP D00000 0 D00017\n\
    LOADP D00000.1\nANDP D00000.0\nORP D00000.2\nOUT M0009\nLOADN D00000.1\nANDN D00000.2\nORN D00000.3\nOUT M000A\n\
    LOAD D00000.1\nOUTP M000B\nOUTN M000C\nFF M000D\n\
    LOAD D00000.2\nMOVP D00000 D00010\nADDP D00010 1 D00011\nSUBP D00011 2 D00012\nMULP D00012 3 D00013\nDIVP D00013 2 D00014\nINCP D00015\nDECP D00016\n\
    LOAD D00000.1\nTON T1500 3\nTOFF T1501 2\nTMR T1502 4\nTMON T1503 2\nTRTG T1504 3\n\
    LOAD T1502\nRST T1502\nLOAD D00000.3\nMOV 1 T1500\nMOV 1 T1501\nMOV 3 T1503\n\
    LOAD D00000.0\nTRTG T1505 20\nTMON T1506 20\nLOAD D00000.2\nTOFF T1507 1\n\
    LOAD D00000.0\nCTU C0000 3\nCTD C0001 2\nCTR C0002 4\nLOAD D00000.2\nCTUD C0003 D00000.0 D00000.1 3\n\
    LOAD C0000\nRST C0000\n\
    LOAD D00000.1\nDMOV 100000 D00020\nDADD D00020 D00020 D00022\nDSUB D00022 7 D00024\nDMUL D00024 -3 D00026\nDDIV D00026 D00000 D00028\nDINC D00030\nDDEC D00032\n\
    LOAD D00000.3\nRMOV 1.5 D00040\nRADD D00040 D00040 D00042\nRSUB D00042 0.25 D00044\nRMUL D00044 D00040 D00046\nRDIV D00046 D00048 D00050\n\
    LOAD D00000.0\nI2D D00001 D00052\nD2I D00020 D00054\nI2R D00000 D00056\nR2I D00040 D00058\nD2R D00022 D00060\nR2D D00042 D00062\n\
    LOAD D00000.2\nDMOVP D00020 D00064\nDINCP D00066\nI2DP D00000 D00068\n\
    LOADD>= D00020 100000\nANDD< D00022 D00020\nORD= D00024 7\nOUT M000E\n\
    LOADR> D00040 1.0\nANDR<> D00042 3.0\nORR<= D00044 D00040\nOUT M000F\n\
    LOAD D00000.0\nCALL 1\nLOAD D00000.1\nJMP 2\nINC D00070\nLABEL 2\nOUT M0010\n\
    LOAD D00000.2\nFOR 3\nINC D00071\nLOAD>= D00071 D00000\nBREAK\nNEXT\n\
    LOAD _ON\nDUTY 2 3 SM420\nLOAD SM420\nOUT M0011\nLOAD D00000.3\nWDT\nNOP\nEND\n\
    SBRT 1\nINC D00072\nLOAD D00072.0\nCALL 2\nRET\nSBRT 2\nDEC D00073\nRET\n";

#[test]
fn every_instruction_list_instruction_runs_the_same_natively() {
    // 65 % of the steps are native code: rungs of contacts, edges, coils, data, timers,
    // counters and calls; the rest (double words, reals, loops, DUTY) is the interpreter's.
    let outcome = il_case("every instruction", &[("main", EVERY_INSTRUCTION)], 24, 1_000_000, 65);
    let vm = outcome.vm.as_ref().unwrap();
    let word = |d: &str| vm.mem.read(&plcd_core::device::Address::parse(d).unwrap());
    // The scans counted, and `DIV D00000 0` failed in every scan with bit 3 of the count set.
    assert_eq!(word("D00000"), 24);
    assert!(outcome.errors_with_whole_budget(ERR_DIVIDE_BY_ZERO) >= 9, "{:?}", outcome.errors);
}

/// The five timers, each on inputs of several periods (every scan, every other, every fourth,
/// and twice in a scan with different inputs, which makes edges within a scan), with constant
/// presets, presets from a word that changes, presets of 0 and the three time bases; their
/// current values written by the program now and then, their `RST`, and their contacts
/// read: each starts, counts, finishes, stays idle, restarts and is reset, and goes on from a
/// written value, with every budget.
const TIMERS: &str = "\
    LOAD _ON\nINC D00000\n\
    LOAD D00000.3\nMOV 4 D00001\nLOAD NOT D00000.3\nMOV 2 D00001\n\
    LOAD D00000.0\nTON T1500 3\nTOFF T1501 3\nTMR T1502 5\nTMON T1503 3\nTRTG T1504 3\n\
    LOAD D00000.2\nTON T1505 D00001\nTOFF T1506 D00001\nTMR T1507 D00001\nTMON T1508 D00001\nTRTG T1509 D00001\n\
    LOAD D00000.1\nAND NOT D00000.3\nTON T1000 2\nTOFF T1001 1\nTMR T1002 2\nTMON T1003 1\nTRTG T1004 2\n\
    LOAD D00000.1\nTON T0000 1\nTOFF T0001 1\nTMR T0002 1\nTMON T0003 1\nTRTG T0004 1\n\
    LOAD D00000.1\nTON T1510 0\nTOFF T1511 0\nTMR T1512 0\nTMON T1513 0\nTRTG T1514 0\n\
    LOAD T1500\nOR T1501\nAND NOT T1503\nOUT M0000\nLOAD T1504\nAND T1002\nOUT M0001\n\
    LOAD D00000.2\nAND D00000.0\nMOV 1 T1500\nMOV 2 T1501\nMOV 4 T1502\nMOV 1 T1503\nMOV 2 T1504\n\
    LOAD D00000.1\nAND NOT D00000.2\nMOV 9 T1505\nMOV 9 T1506\nMOV 9 T1507\nMOV 9 T1508\nMOV 9 T1509\n\
    LOAD D00000.3\nAND D00000.1\nRST T1500\nRST T1501\nRST T1502\nRST T1503\nRST T1504\n\
    LOAD NOT D00000.0\nAND D00000.1\nTON T1500 3\nTOFF T1501 3\nTMR T1502 5\nTMON T1503 3\nTRTG T1504 3\n\
    LOAD T1505\nOR T1506\nOR T1507\nOR T1508\nOR T1509\nOUT M0002\n\
    END\n";

#[test]
fn every_timer_starts_counts_finishes_and_is_reset_the_same_natively() {
    // The clock: standing still in a scan; a millisecond a step (a tick of the 1 ms timers a
    // step, and a scan longer than the period: the time goes back at the next scan's start);
    // 100 µs and 30 µs a step, with the clock's origin a few steps into the scan (the timers
    // before it read the scan's start).
    for (step_ns, origin_after) in [(0, 0), (MS, 0), (100_000, 7), (30_000, 40), (MS, 13)] {
        let case = Programs::il("timers", &[("main", TIMERS)]);
        let scans = Scans { step_ns, origin_after, ..Scans::new(40) };
        let outcome = compare(&case, scans, budgets());
        assert!(
            outcome.mismatches.is_empty(),
            "{step_ns} ns a step, origin after {origin_after}:\n{}",
            outcome.mismatches.join("\n")
        );
        outcome.assert_native_share(&case.name, 95);
    }
}

#[test]
fn system_requests_stop_native_code_where_the_interpreter_stops() {
    let source = "LOAD _ON\nINC D00000\nLOAD D00000.0\nOUT M0000\nSTOP\nLOAD D00000.1\nIORF\nOUT M0001\nEND\n";
    il_case("system requests", &[("main", source)], 6, 0, 40);
}

#[test]
fn the_repository_instruction_list_programs_run_the_same_natively() {
    let root = repository();
    let read = |path: &str| std::fs::read_to_string(root.join(path)).unwrap();
    for (name, files, share) in [
        (
            "etc/programs",
            &[
                "etc/programs/main.il",
                "etc/programs/blink.il",
                "etc/programs/count.il",
                "etc/programs/batch.il",
            ][..],
            50,
        ),
        (
            "benches/projects/minute",
            &["benches/projects/minute/scan.il", "benches/projects/minute/tick.il"][..],
            95,
        ),
        ("benches/projects/bits10k", &["benches/projects/bits10k/scan.il"][..], 95),
    ] {
        let sources: Vec<(String, String)> = files
            .iter()
            .map(|f| (Path::new(f).file_stem().unwrap().to_str().unwrap().to_string(), read(f)))
            .collect();
        let sources: Vec<(&str, &str)> =
            sources.iter().map(|(n, s)| (n.as_str(), s.as_str())).collect();
        il_case(name, &sources, 5, 1_000, share);
    }
}

#[test]
fn a_jump_back_stops_at_the_same_step_for_any_budget() {
    // An endless loop of native code (LABEL, JMP back): only the budget stops it.
    let source = "LOAD _ON\nLABEL 1\nINC D00000\nLOAD _ON\nJMP 1\nEND\n";
    let case = Programs::il("endless", &[("main", source)]);
    let scans = Scans { calls: Some(40), ..Scans::new(2) };
    let outcome = compare(&case, scans, &budgets()[1..]);
    outcome.assert_equivalent();
    assert!(
        outcome.native_steps * 2 > outcome.steps,
        "{} of {}",
        outcome.native_steps,
        outcome.steps
    );
}

/// Instruction-list subroutines are machine calls of functions of their own, nested as deep
/// as `CALL` allows (one call deeper is an operation error, raised inside them); where the
/// machine stack is spent, a call goes through the dispatch instead: from a piece by a jump,
/// from a subroutine's function by leaving for the VM. Every stack size runs the same.
#[test]
fn instruction_list_calls_on_a_short_machine_stack() {
    // Scan n calls subroutine 1, which calls itself until D00002 reaches n: deeper each scan,
    // until the 17th call is one too many. Subroutine 2, called from 1 and from main, jumps
    // inside itself and calls 3 from two places. Subroutines 3 and 4 are compiled inline; 4 ends
    // on a rung of its own, and its caller goes on with the rung of the call.
    let source = "\
        LOAD _ON\nINC D00000\nMOV 0 D00002\nCALL 1\nLOAD D00000.0\nCALL 2\nOUT M0000\n\
        LOAD D00000.0\nCALL 4\nAND D00000.1\nOUT M0001\nEND\n\
        SBRT 1\nINC D00002\nLOAD D00000.1\nCALL 2\nLOAD< D00002 D00000\nCALL 1\nINC D00004\nRET\n\
        SBRT 2\nINC D00005\nLOAD D00005.0\nJMP 7\nCALL 3\nLABEL 7\nLOAD _ON\nCALL 3\nRET\n\
        SBRT 3\nDEC D00006\nLOAD D00006.1\nJMP 8\nINC D00007\nLABEL 8\nDEC D00007\nRET\n\
        SBRT 4\nLOAD D00000.2\nINC D00008\nRET\n";
    let mut case = Programs::il("short machine stack, instruction list", &[("main", source)]);
    for bytes in [None, Some(0), Some(4_400), Some(4_800), Some(6_000)] {
        case.native_stack = bytes;
        let outcome = compare(&case, Scans::new(20), budgets());
        outcome.assert_equivalent();
        outcome.assert_native_share("instruction-list calls", 80);
        let vm = outcome.vm.as_ref().unwrap();
        let word = |d: &str| vm.mem.read(&plcd_core::device::Address::parse(d).unwrap());
        assert_eq!(word("D00000"), 20, "{bytes:?}");
        assert!(outcome.errors_with_whole_budget(ERR_CALL_DEPTH) >= 3, "{:?}", outcome.errors);
    }
}

/// An inlined subroutine's call pushes its frame only where the code leaves from inside it: a
/// stop there (the budget spent at any of its instructions, a division by zero, an instruction
/// the interpreter runs) leaves the frame and the call depth as the interpreter has them, and
/// the VM's `RET` returns with them. Subroutine 1 is compiled inline at each of its calls: from
/// the program with an `MPUSH` pending, inside a loop (the frame keeps the loop depth), and
/// from subroutine 2's function (one call deeper).
#[test]
fn a_stop_inside_an_inlined_subroutine_leaves_its_frame_pushed() {
    // D00001 is 0 when D00000.2 is set: then subroutine 1's DIV fails if D00000.1 is set too.
    // Its DMOV (the interpreter's) runs when D00010 is even.
    let source = "\
        LOAD _ON\nINC D00000\nMOV D00000 D00001\nLOAD D00000.2\nMOV 0 D00001\n\
        LOAD D00000.0\nMPUSH\nAND NOT D00000.3\nCALL 1\nMPOP\nOUT M0000\n\
        LOAD _ON\nFOR 2\nLOAD D00000.3\nOR _ON\nCALL 1\nNEXT\n\
        LOAD _ON\nCALL 2\nEND\n\
        SBRT 1\nINC D00010\nLOAD D00000.1\nDIV D00010 D00001 D00011\nLOAD D00010.0\nJMP 5\n\
        DMOV D00010 D00020\nLABEL 5\nINC D00012\nRET\n\
        SBRT 2\nINC D00013\nLOAD D00000.0\nMPUSH\nCALL 1\nMPOP\nOUT M0001\nRET\n";
    let outcome = il_case("stops inside inlined calls", &[("main", source)], 16, 0, 50);
    let vm = outcome.vm.as_ref().unwrap();
    let word = |d: &str| vm.mem.read(&plcd_core::device::Address::parse(d).unwrap());
    // Subroutine 1 runs twice a scan in the loop, and in the odd scans from subroutine 2 and,
    // but for scans 9 to 15, from the program.
    assert_eq!(word("D00010"), 2 * 16 + 8 + 4);
    assert!(outcome.errors_with_whole_budget(ERR_DIVIDE_BY_ZERO) >= 8, "{:?}", outcome.errors);
}

/// A random instruction-list program from `seed`: rungs of contacts (nested blocks, MPUSH
/// branches, compare contacts), coils and data instructions, now and then an edge, a timer, a
/// counter, a division, a forward jump, a loop or a subroutine call.
fn random_il_program(seed: u64) -> String {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move |n: u64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state % n
    };
    let bit = |next: &mut dyn FnMut(u64) -> u64| match next(4) {
        0 => format!("D00000.{:X}", next(16)),
        1 => format!("M00{}{:X}", next(4), next(16)),
        2 => format!("P00{}{:X}", next(8), next(16)),
        _ => format!("M01{}{:X}", next(2), next(16)),
    };
    let src = |next: &mut dyn FnMut(u64) -> u64| match next(3) {
        0 => format!("D{:05}", next(8)),
        1 => format!("{}", next(200) as i64 - 100),
        _ => "D00000".to_string(),
    };
    let mut out = String::from("LOAD _ON\nINC D00000\nADD D00000 D00001 D00001\n");
    let mut labels = 0;
    let mut timers = 0;
    for _ in 0..30 {
        // The rung's condition.
        let contact = |n: u64| ["LOAD", "LOAD NOT"][n as usize];
        out += &format!("{} {}\n", contact(next(2)), bit(&mut next));
        for _ in 0..next(4) {
            match next(7) {
                0 => out += &format!("AND {}\n", bit(&mut next)),
                1 => out += &format!("AND NOT {}\n", bit(&mut next)),
                2 => out += &format!("OR {}\n", bit(&mut next)),
                3 => out += &format!("OR NOT {}\n", bit(&mut next)),
                4 => {
                    let op = ["=", "<>", ">", ">=", "<", "<="][next(6) as usize];
                    let how = ["AND", "OR"][next(2) as usize];
                    out += &format!("{how}{op} {} {}\n", src(&mut next), src(&mut next));
                }
                5 => {
                    out += &format!("LOAD {}\nOR NOT {}\n", bit(&mut next), bit(&mut next));
                    out += ["AND LOAD\n", "OR LOAD\n"][next(2) as usize];
                }
                _ => out += &format!("ANDP {}\n", bit(&mut next)),
            }
        }
        // What it drives.
        let d = |next: &mut dyn FnMut(u64) -> u64| format!("D{:05}", 1 + next(7));
        match next(14) {
            0 => out += &format!("OUT {}\n", bit(&mut next)),
            1 => out += &format!("OUT NOT {}\nSET {}\n", bit(&mut next), bit(&mut next)),
            2 => out += &format!("RST {}\nNOT\nOUT {}\n", bit(&mut next), bit(&mut next)),
            3 => {
                out += &format!("MPUSH\nAND {}\nOUT {}\nMLOAD\n", bit(&mut next), bit(&mut next));
                out += &format!(
                    "AND NOT {}\nOUT {}\nMPOP\nMOV {} {}\n",
                    bit(&mut next),
                    bit(&mut next),
                    src(&mut next),
                    d(&mut next)
                );
            }
            4 => {
                let op = ["ADD", "SUB", "MUL", "DIV", "ADDP"][next(5) as usize];
                out += &format!("{op} {} {} {}\n", src(&mut next), src(&mut next), d(&mut next));
            }
            5 => out += &format!("INC {}\nDEC {}\n", d(&mut next), d(&mut next)),
            6 if timers < 8 => {
                let timer = ["TON", "TOFF", "TMR", "TMON", "TRTG"][next(5) as usize];
                let counter = ["CTU", "CTD", "CTR"][next(3) as usize];
                let (t, preset) = (1500 + timers, 1 + next(5));
                out += &format!("{timer} T{t:04} {preset}\n{counter} C{timers:04} 3\n");
                if next(2) == 0 {
                    out += &format!("LOAD D00000.{:X}\nRST T{t:04}\nRST C{timers:04}\n", next(16));
                }
                timers += 1;
            }
            7 => {
                labels += 1;
                out +=
                    &format!("JMP {labels}\nINC D00009\nOUT {}\nLABEL {labels}\n", bit(&mut next));
            }
            8 => out += "FOR 3\nINC D00010\nADD D00010 D00000 D00011\nCALL 2\nNEXT\n",
            9 => out += ["CALL 1\n", "CALL 2\n", "CALL 3\n"][next(3) as usize],
            10 => {
                let (a, b, c) = (bit(&mut next), bit(&mut next), bit(&mut next));
                out += &format!("OUTP {a}\nOUTN {b}\nFF {c}\n");
            }
            11 => {
                let (a, b) = (d(&mut next), d(&mut next));
                out += &format!("INCP {a}\nMOVP {} {b}\n", src(&mut next));
                out += &format!("DIVP {} {} {}\n", src(&mut next), src(&mut next), d(&mut next));
            }
            _ => {
                out += &format!("OUT {}\nMOV {} {}\n", bit(&mut next), src(&mut next), d(&mut next))
            }
        }
    }
    // Subroutine 2 calls 1, and itself while D00010 counts through values with bit 0 set:
    // calls deeper than CALL_DEPTH (an operation error) on some scans.
    out += "END\nSBRT 1\nLOAD D00000.0\nINC D00012\nMUL D00012 3 D00013\nRET\n";
    out += "SBRT 2\nLOADP D00000.2\nCALL 1\nINC D00014\nLOAD D00010.0\nAND D00000.3\nCALL 2\nRET\n";
    // Subroutine 3 has a loop of its own, left by BREAK on some scans.
    out += "SBRT 3\nFOR 3\nINC D00015\nLOAD D00015.2\nBREAK\nNEXT\nRET\n";
    out
}

#[test]
fn random_instruction_list_programs_run_the_same_natively() {
    for seed in 0..40 {
        let source = random_il_program(seed);
        let case = Programs::il(&format!("random IL {seed}"), &[("main", &source)]);
        let outcome = compare(&case, Scans { step_ns: 1_000_000, ..Scans::new(6) }, budgets());
        assert!(outcome.mismatches.is_empty(), "{}\n{source}", outcome.mismatches.join("\n"));
        // 79-95 % for these seeds: every rung but its edges, timers, counters, divisions,
        // loops and calls.
        outcome.assert_native_share(&case.name, 70);
    }
}

/// `rungs` rungs of bit logic over the scan counter's bits and M bits, with labels every 300
/// rungs, a forward jump past two labels in between (from one piece of native code into
/// another), and at the end a jump back to the first label, taken twice a scan.
fn long_il_program(rungs: usize) -> String {
    let mut out = String::from("LOAD _ON\nINC D00000\nMOV 0 D00002\nLABEL 1000\n");
    for i in 0..rungs {
        let m = |k: usize| format!("M{:03}{:X}", (i * 7 + k) % 256, (i + k) % 16);
        out += &format!("LOAD D00000.{:X}\nAND NOT {}\nOR {}\nOUT {}\n", i % 4, m(1), m(2), m(3));
        if i % 300 == 0 {
            out += &format!("LABEL {}\n", i / 300);
        }
        if i % 300 == 150 && i + 450 < rungs {
            out += &format!("LOAD D00000.0\nJMP {}\n", i / 300 + 2);
        }
    }
    out += "LOAD< D00002 3\nINC D00002\nLOAD< D00002 3\nJMP 1000\nEND\n";
    out
}

#[test]
fn long_programs_run_the_same_across_pieces() {
    // 2,000 rungs: about 8,000 steps, two pieces and a half of native code. (A program longer
    // than is compiled: il::tests; its compile time in debug builds is minutes.)
    // Budgets of a few steps would make tens of thousands of calls, each comparing the whole
    // device memory: the short programs above try those.
    let source = long_il_program(2_000);
    let case = Programs::il("long", &[("main", &source)]);
    let budgets = [
        Budget::Fixed(u64::MAX),
        Budget::Fixed(13),
        Budget::Fixed(100),
        Budget::Fixed(4_099),
        Budget::Varying,
    ];
    let outcome = compare(&case, Scans::new(2), &budgets);
    outcome.assert_equivalent();
    outcome.assert_native_share("long", 95);
}

// 3. The constructs of issue 29 targeted: the conformance cases of tests/st/{oop,sfc,refs,
//    calendar,strings,structs,statements} run above at every budget; these check the share of
//    their steps native code runs itself, so that a construct that silently fell back to the
//    interpreter fails here.

/// Methods called on an instance, through an interface (dispatch by the type tag), with
/// `SUPER^`, a property and a method's `VAR_INST`: all native (100 % when written).
#[test]
fn methods_through_interfaces_run_natively() {
    let source = "
INTERFACE ICount
METHOD Add : DINT
VAR_INPUT delta : DINT; END_VAR
END_METHOD
END_INTERFACE
FUNCTION_BLOCK Base IMPLEMENTS ICount
VAR n : DINT; END_VAR
METHOD Add : DINT
VAR_INPUT delta : DINT; END_VAR
VAR_INST calls : DINT; END_VAR
    calls := calls + 1; n := n + delta; Add := n;
END_METHOD
PROPERTY Count : DINT
GET Count := n; END_GET
END_PROPERTY
END_FUNCTION_BLOCK
FUNCTION_BLOCK Twice EXTENDS Base
METHOD Add : DINT
VAR_INPUT delta : DINT; END_VAR
    Add := SUPER^.Add(2 * delta);
END_METHOD
END_FUNCTION_BLOCK
PROGRAM Main
VAR b : Base; t : Twice; i : ICount; k, total, j : DINT; END_VAR
    k := k + 1;
    FOR j := 1 TO 5 DO
        IF (k + j) MOD 2 = 0 THEN i := b; ELSE i := t; END_IF;
        total := total + i.Add(j) + t.Add(1) + b.Count;
    END_FOR;
END_PROGRAM
";
    let outcome = targeted("methods", source, Scans::new(12), 95);
    assert!(outcome.errors.is_empty());
}

/// A chart with step-timed qualifiers and actions, run as its evolution is compiled: step
/// blocks, action controls and the actions' bodies; only the steps' readings of the clock
/// (`__NOW`) are the interpreter's (98 % native when written).
#[test]
fn charts_run_natively() {
    let source = "
PROGRAM Main
VAR k, bumps, pulses : DINT; go : BOOL; lamp, late : BOOL; END_VAR
    INITIAL_STEP Idle: Count(N); END_STEP
    STEP Fill: Count(N); lamp(N); Bump(L, T#2ms); late(D, T#1ms); Pulse(P1); END_STEP
    STEP Drain: Count(N); Bump(N); END_STEP
    TRANSITION FROM Idle TO Fill := go; END_TRANSITION
    TRANSITION FROM Fill TO Drain := NOT go; END_TRANSITION
    TRANSITION FROM Drain TO Idle := Drain.T >= T#1ms; END_TRANSITION
ACTION Bump:
    bumps := bumps + 1;
END_ACTION
ACTION Pulse:
    pulses := pulses + 1;
END_ACTION
ACTION Count:
    k := k + 1;
    go := k MOD 6 < 3;
END_ACTION
END_PROGRAM
";
    let outcome = targeted("chart", source, Scans::new(24), 90);
    assert!(outcome.errors.is_empty());
}

/// A union written through one member and read through another, `AND_THEN` / `OR_ELSE`
/// skipping a division by zero, a jump, and date and time-of-day arithmetic.
#[test]
fn unions_short_circuits_jumps_and_dates_run_natively() {
    let source = "
TYPE U : UNION dw : DWORD; b : ARRAY [0..3] OF BYTE; r : REAL; END_UNION END_TYPE
PROGRAM Main
VAR
    k, z, q : DINT; u : U; hit : BOOL; x : BYTE;
    tod1 : TOD := TOD#23:59:59; day : DATE := D#2024-02-28; span : TIME; stamp : DT;
END_VAR
    k := k + 1;
    u.dw := DINT_TO_DWORD(k * 16#01010101);
    x := u.b[0] XOR u.b[3];
    IF z <> 0 AND_THEN k / z > 1 THEN q := 1; END_IF;
    hit := z = 0 OR_ELSE k / z > 1;
    IF k MOD 3 = 0 THEN JMP skip; END_IF;
    q := q + 1;
skip:
    tod1 := tod1 + T#1s;
    stamp := DT#2024-02-28-12:00:00 + DINT_TO_TIME(k * 1000);
    day := DT_TO_DATE(stamp);
    span := stamp - DT#2024-02-28-00:00:00;
END_PROGRAM
";
    let outcome = targeted("unions_jumps_dates", source, Scans::new(12), 95);
    assert!(outcome.errors.is_empty(), "AND_THEN and OR_ELSE skipped the division");
}

/// Native code checks the memory a run gives it against what it reaches without a check (the
/// variables and device words of its fixed operands, the instruction list's edge slots), and
/// leaves a run on memory too small to the interpreter with the registers untouched; on memory
/// large enough it runs the program to `END`.
#[test]
fn native_code_refuses_memory_smaller_than_it_reaches() {
    use plcd_core::lang::native::{IlFrame, RawSlice, StFrame};
    use plcd_core::lang::{CALL_DEPTH, EVAL_DEPTH, ST_CALL_DEPTH};
    use plcd_core::value::Pointer;

    const START: NativeRegs = NativeRegs {
        pc: 0,
        st_depth: 0,
        base: 0,
        error: 0,
        this: Pointer::DISCARD.to_slot(),
        left: 1_000,
        sp: 0,
        rung: 1,
        blocks: 0,
        branches: 0,
        il_depth: 0,
        loop_depth: 0,
    };
    let words_len = plcd_core::device::Memory::new().words().len();
    // One run on `vars` bytes of variable memory, `words` device words and, for the
    // instruction list, its state with `edges` edge slots (`None`: no state at all).
    let run = |code: &dyn NativeCode, vars: usize, words: usize, edges: Option<usize>| {
        let (mut vars, mut words) = (vec![0u8; vars], vec![0u16; words]);
        let (mut eval, mut calls) = ([0u64; EVAL_DEPTH], [StFrame::default(); ST_CALL_DEPTH]);
        let mut il_calls = [IlFrame::default(); CALL_DEPTH];
        let mut edges = edges.map(|n| vec![false; n]);
        let (mut timers, mut counters) = (vec![0u64; 4096], vec![0u64; 4096]);
        let clock = plcd_core::vm::ManualClock::new(0);
        let mut il = edges.as_mut().map(|edges| IlMemory {
            calls: &mut il_calls,
            edges,
            counters: RawSlice::new(&mut counters),
            timers: RawSlice::new(&mut timers),
            clock: &clock,
            stop: 1_000,
        });
        let mut memory = NativeMemory::new(&mut vars, &mut words, &mut [], &mut eval, &mut calls);
        let mut regs = START;
        let exit = code.run(&mut memory, il.as_mut(), &mut regs);
        (exit, regs)
    };

    let st = Programs::inline(
        "sizes",
        "PROGRAM Main\nVAR a, b : DINT; END_VAR\n    b := a + 1;\nEND_PROGRAM\n",
    );
    let code = plcd_native::compile_even_if_slower(&st.programs[0]).unwrap();
    let need = st.variables.initial.len();
    assert!(need >= 8, "two DINTs: {need} bytes");
    assert_eq!(run(&*code, need - 1, words_len, None), (NativeExit::Interpret, START));
    let (exit, regs) = run(&*code, need, words_len, None);
    assert_eq!(exit, NativeExit::End);
    assert!(regs.left < START.left, "it ran: {regs:?}");

    let il = Programs::il("sizes", &[("main", "LOADP M0000\nOUT M0001\nEND\n")]);
    let program = &il.programs[0];
    let code = plcd_native::compile_even_if_slower(program).unwrap();
    let edges = (program.edge_base + program.edge_slots) as usize;
    assert!(edges >= 1);
    assert_eq!(run(&*code, 0, words_len, None), (NativeExit::Interpret, START));
    assert_eq!(run(&*code, 0, words_len, Some(edges - 1)), (NativeExit::Interpret, START));
    assert_eq!(run(&*code, 0, 0, Some(edges)), (NativeExit::Interpret, START));
    let (exit, regs) = run(&*code, 0, words_len, Some(edges));
    assert_eq!(exit, NativeExit::End);
    assert!(regs.left < START.left, "it ran: {regs:?}");
}
