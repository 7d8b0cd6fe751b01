//! The Structured Text compiler: one golden case per diagnostic (tests/golden/st), and
//! programs compiled and run on the VM, their variables read by name.

use std::fs;
use std::path::{Path, PathBuf};

use plcd_core::lang::Program;
use plcd_core::st::{compile, parse_file, Compiled, Instance};
use plcd_core::value::{Elem, Pointer, ValueType};
use plcd_core::vm::{ExecState, Exit, ManualClock, Vm};

/// Compiles `src` as `main.st` with one instance `main`.
fn try_build(src: &str) -> Result<Compiled, String> {
    let (file, diags) = parse_file(Path::new("main.st"), src);
    if !diags.is_empty() {
        return Err(diags.to_string());
    }
    let inst = Instance {
        name: "main",
        pou: None,
        file: Path::new("main.st"),
        config: Path::new("plcd.toml"),
        line: 1,
        col: 1,
    };
    compile(&[file], &[inst]).map_err(|d| d.to_string())
}

fn build(src: &str) -> Compiled {
    try_build(src).unwrap_or_else(|e| panic!("{e}"))
}

fn errors(src: &str) -> String {
    match try_build(src) {
        Ok(_) => String::new(),
        Err(e) => e,
    }
}

/// A compiled project on a VM.
struct Run {
    c: Compiled,
    vm: Vm,
    state: ExecState,
    clock: ManualClock,
    exits: Vec<Exit>,
}

impl Run {
    fn new(src: &str) -> Run {
        let c = build(src);
        let mut vm = Vm::for_programs(&c.programs);
        vm.set_variables(&c.variables);
        let frame = c.programs.iter().map(|p| p.frame_bytes).max().unwrap_or(0);
        Run {
            c,
            vm,
            state: ExecState::with_frame(frame),
            clock: ManualClock::new(0),
            exits: Vec::new(),
        }
    }

    fn program(&self) -> &Program {
        &self.c.programs[0]
    }

    /// One scan: runs to `End`, collecting operation errors.
    fn scan(&mut self) {
        self.state.restart();
        let program = self.c.programs[0].clone();
        for _ in 0..100_000 {
            match self.vm.run(&program, &mut self.state, &self.clock, 1_000_000) {
                Exit::End => return,
                e => self.exits.push(e),
            }
            if self.exits.len() > 1000 {
                panic!("no END");
            }
        }
    }

    fn sym(&self, name: &str) -> (Pointer, ValueType) {
        let s = self
            .c
            .variables
            .symbols
            .iter()
            .find(|s| s.name.eq_ignore_ascii_case(name))
            .unwrap_or_else(|| panic!("no symbol {name}"));
        (s.at, s.ty.clone())
    }

    fn raw(&self, name: &str) -> (u64, Elem) {
        let (at, ty) = self.sym(name);
        let elem = match ty {
            ValueType::Bool => Elem::Bool,
            ValueType::Signed(e) | ValueType::Unsigned(e) | ValueType::Real(e) => e,
            ValueType::Time => Elem::I64,
            ValueType::Enum { .. } => Elem::I32,
            ValueType::String { .. } => panic!("{name} is a string"),
        };
        (self.vm.read_value(at, elem), elem)
    }

    fn int(&self, name: &str) -> i128 {
        let (v, e) = self.raw(name);
        match e {
            Elem::I8 | Elem::I16 | Elem::I32 | Elem::I64 => v as i64 as i128,
            Elem::F32 | Elem::F64 => panic!("{name} is a real"),
            _ => v as i128,
        }
    }

    fn real(&self, name: &str) -> f64 {
        let (v, e) = self.raw(name);
        match e {
            Elem::F32 => f64::from(f32::from_bits(v as u32)),
            Elem::F64 => f64::from_bits(v),
            _ => panic!("{name} is not a real"),
        }
    }

    fn string(&self, name: &str) -> String {
        let (at, _) = self.sym(name);
        String::from_utf8_lossy(&self.vm.read_string(at)).into_owned()
    }

    fn errors(&self) -> Vec<u16> {
        self.exits
            .iter()
            .filter_map(|e| match e {
                Exit::OperationError { code, .. } => Some(*code),
                _ => None,
            })
            .collect()
    }
}

/// Runs `body` once in a PROGRAM with `vars` declared.
fn once(vars: &str, body: &str) -> Run {
    let src = format!("PROGRAM main\nVAR\n{vars}\nEND_VAR\n{body}\nEND_PROGRAM\n");
    let mut r = Run::new(&src);
    r.scan();
    r
}

#[test]
fn smoke() {
    let r = once("x : INT; y : DINT := 7;", "x := 3 + 4 * 2; y := y * x;");
    assert_eq!(r.int("main.x"), 11);
    assert_eq!(r.int("main.y"), 77);
}
