//! The Structured Text workloads of the ST benches, shared by `benches/st_native.rs`
//! (criterion: time, beside the same logic in Rust) and `benches/counts.rs` (Valgrind:
//! instructions, the CI guard of BENCHMARKS.md): each workload's program (`benches/st/*.st`)
//! compiled as a project load compiles it, on its VM with the inputs it starts from, with or
//! without its native code attached, and one scan as the engine runs it ([`StCase`]).
//!
//! Included with `#[path]` by each bench; a bench uses only part of it (the guard reads no
//! variables), hence the `dead_code` allowance.
#![allow(dead_code)]

use std::hint::black_box;
use std::path::Path;

use plcd_core::st::{compile, parse_file, Compiled, Instance};
use plcd_core::value::{Elem, Pointer};
use plcd_core::vm::{ExecState, Exit, ManualClock, Vm};

/// The workloads, in the order the benches run them.
pub const WORKLOADS: [&str; 5] = ["bit", "int_loops", "pid", "sort", "state_machine"];

/// Workload `name` on the interpreter, ready for its first scan ([`StCase::with_native`]
/// attaches its native code).
pub fn case(name: &str) -> StCase {
    let st = |path, text| StCase::new(path, text);
    match name {
        "bit" => bit_st(),
        "int_loops" => st("int_loops.st", include_str!("../st/int_loops.st")),
        "pid" => st("pid.st", include_str!("../st/pid.st")),
        "sort" => st("sort.st", include_str!("../st/sort.st")),
        "state_machine" => st("state_machine.st", include_str!("../st/state_machine.st")),
        _ => panic!("no workload {name} (one of {WORKLOADS:?})"),
    }
}

/// Parses and compiles `files` (path, text) with one instance `main` of the PROGRAM in the
/// first file, as a project load does.
pub fn compile_files(files: &[(&str, &str)]) -> Compiled {
    let mut parsed = Vec::new();
    for (path, text) in files {
        let (file, diags) = parse_file(Path::new(path), text);
        assert!(diags.is_empty(), "{diags}");
        parsed.push(file);
    }
    let inst = Instance {
        name: "main",
        pou: None,
        file: Path::new(files[0].0),
        config: Path::new("plcd.toml"),
        line: 1,
        col: 1,
    };
    compile(&parsed, &[inst]).unwrap_or_else(|d| panic!("{d}"))
}

/// One compiled ST program on its VM.
pub struct StCase {
    pub c: Compiled,
    pub vm: Vm,
    pub state: ExecState,
    pub clock: ManualClock,
}

impl StCase {
    pub fn new(path: &str, source: &str) -> StCase {
        let c = compile_files(&[(path, source)]);
        let mut vm = Vm::for_programs(&c.programs);
        vm.set_variables(&c.variables);
        vm.reset_for_run(&plcd_core::device::RetainSet::default(), false);
        let state = ExecState::with_frame(c.programs[0].frame_bytes);
        StCase { c, vm, state, clock: ManualClock::new(0) }
    }

    /// The same program with its native code attached (`plcd_native`).
    pub fn with_native(mut self) -> StCase {
        let native = plcd_native::compile(&self.c.programs[0]).unwrap_or_else(|e| panic!("{e}"));
        self.c.programs[0].native = Some(native);
        self
    }

    // Not inlined, so that a profiler sees one scan as one call (`StCase::scan`).
    #[inline(never)]
    pub fn scan(&mut self) {
        self.state.restart();
        let exit = self.vm.run(&self.c.programs[0], &mut self.state, &self.clock, u64::MAX);
        debug_assert_eq!(exit, Exit::End);
        black_box(exit);
    }

    /// One scan that must end without an operation error.
    pub fn checked_scan(&mut self) {
        self.state.restart();
        let exit = self.vm.run(&self.c.programs[0], &mut self.state, &self.clock, u64::MAX);
        assert_eq!(exit, Exit::End, "the ST program did not run to END");
    }

    /// VM steps of one scan.
    pub fn steps_per_scan(&mut self) -> u64 {
        let before = self.vm.steps();
        self.scan();
        self.vm.steps() - before
    }

    pub fn at(&self, name: &str) -> (Pointer, Elem) {
        let name = format!("main.{name}");
        let s = self
            .c
            .variables
            .symbols
            .iter()
            .find(|s| s.name.eq_ignore_ascii_case(&name))
            .unwrap_or_else(|| panic!("no variable {name}"));
        (s.at, s.ty.elem())
    }

    /// A variable's slot (value.rs's encoding: signed sign-extended, REAL the f32 bits).
    pub fn slot(&self, name: &str) -> u64 {
        let (at, elem) = self.at(name);
        self.vm.read_value(at, elem)
    }

    pub fn set(&mut self, name: &str, slot: u64) {
        let (at, elem) = self.at(name);
        self.vm.write_value(at, elem, slot);
    }
}

/// Slots of native values, in the VM's encoding.
pub trait Slot {
    fn slot(self) -> u64;
}

impl Slot for bool {
    fn slot(self) -> u64 {
        u64::from(self)
    }
}

impl Slot for i16 {
    fn slot(self) -> u64 {
        self as i64 as u64
    }
}

impl Slot for i32 {
    fn slot(self) -> u64 {
        self as i64 as u64
    }
}

impl Slot for f32 {
    fn slot(self) -> u64 {
        u64::from(self.to_bits())
    }
}

/// `bit.st`'s inputs and the values both sides start from (the Rust side of `st_native`
/// too), and its sensors `s1`–`s8`.
pub const BIT_NAMES: [&str; 8] =
    ["start", "stop", "estop", "guard", "ready", "auto", "manual", "jog"];
pub const BIT_INPUTS: [bool; 8] = [true, false, false, true, true, true, false, false];
pub const BIT_SENSORS: [bool; 8] = [true, true, true, false, true, false, false, true];

/// `bit.st` with its inputs set ([`BIT_INPUTS`], [`BIT_SENSORS`]).
pub fn bit_st() -> StCase {
    let mut st = StCase::new("bit.st", include_str!("../st/bit.st"));
    for (name, on) in BIT_NAMES.iter().zip(BIT_INPUTS) {
        st.set(name, on.slot());
    }
    for (k, on) in BIT_SENSORS.iter().enumerate() {
        st.set(&format!("s{}", k + 1), on.slot());
    }
    st
}
