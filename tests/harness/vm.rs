//! A scan loop for VM tests: one program, a hand-set clock, system requests recorded. The task
//! engine proper is [`super::engine`]; this is only enough to scan a program.

use std::path::Path;

use plcd::config::TimerConfig;
use plcd::device::Address;
use plcd::diag::Diagnostics;
use plcd::lang::{self, Context, Program};
use plcd::vm::{ExecState, Exit, ManualClock, Vm};

/// The time base of timer `n` under the default `[timers]`.
fn default_timer_base(n: u32) -> Option<u32> {
    TimerConfig::default().base_ms(n)
}

/// What the assembler knows of the project around a program: tasks 0..=23 exist, the default
/// timer bases, edge memory from 0.
pub fn context(is_init: bool) -> Context<'static> {
    static TASKS: [u8; 24] =
        [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23];
    Context { is_init, task_numbers: &TASKS, timer_base_ms: &default_timer_base, edge_base: 0 }
}

/// Assembles `source` as `test.il` of a scan program.
pub fn try_assemble(source: &str) -> Result<Program, Diagnostics> {
    lang::assemble("test", Path::new("test.il"), source, &context(false))
}

/// Assembles `source`, panicking with the diagnostics if it does not.
pub fn assemble(source: &str) -> Program {
    try_assemble(source).unwrap_or_else(|d| panic!("does not assemble:\n{d}"))
}

pub struct Rig {
    pub vm: Vm,
    pub program: Program,
    pub clock: ManualClock,
    pub state: ExecState,
    pub scans: u64,
    /// Every non-END exit of the last scan.
    pub exits: Vec<Exit>,
}

impl Rig {
    pub fn new(source: &str) -> Rig {
        let program = assemble(source);
        let vm = Vm::for_programs([&program]);
        Rig {
            vm,
            program,
            clock: ManualClock::new(0),
            state: ExecState::new(),
            scans: 0,
            exits: vec![],
        }
    }

    /// One scan at the clock's current time: flags, the program to END, END processing.
    pub fn scan(&mut self) -> &mut Rig {
        self.vm.begin_scan(self.scans == 0, self.clock.get());
        self.state.restart();
        self.exits.clear();
        loop {
            match self.vm.run(&self.program, &mut self.state, &self.clock, u64::MAX) {
                Exit::End => break,
                other => self.exits.push(other),
            }
        }
        self.vm.end_scan();
        self.scans += 1;
        self
    }

    /// Sets the clock to `ms`, then scans.
    pub fn scan_at_ms(&mut self, ms: u64) -> &mut Rig {
        self.clock.set(ms * 1_000_000);
        self.scan()
    }

    pub fn get(&self, device: &str) -> i32 {
        self.vm.mem.read(&Address::parse(device).unwrap())
    }

    pub fn set(&mut self, device: &str, value: i32) -> &mut Rig {
        self.vm.mem.write(&Address::parse(device).unwrap(), value);
        self
    }
}

/// A Structured Text program of hand-written typed ops (as the compiler would emit them), one
/// source line, for the tests of the typed VM.
pub fn typed_program(
    name: &str,
    code: Vec<lang::ops::Op>,
    consts: Vec<u64>,
    frame_bytes: u32,
) -> Program {
    let n = code.len();
    Program {
        name: name.into(),
        path: format!("{name}.st").into(),
        language: lang::Language::StructuredText,
        code: code.into(),
        consts: consts.into(),
        frame_bytes,
        regions: Box::new([]),
        lines: vec![1; n].into(),
        statements: Box::new([0]),
        edge_base: 0,
        edge_slots: 0,
        labels: Box::new([]),
        subroutines: Box::new([]),
        native: None,
        var_bools_canonical: false,
    }
}
