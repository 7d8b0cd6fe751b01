//! The Structured Text compiler: one golden case per diagnostic (tests/golden/st), and
//! programs compiled and run on the VM, their variables read by name.

use std::fs;
use std::path::{Path, PathBuf};

use plcd_core::st::dialect::Dialect;
use plcd_core::st::{compile_with, parse_file, Compiled, Instance};
use plcd_core::value::{Elem, Pointer, ValueType};
use plcd_core::vm::{ExecState, Exit, ManualClock, Vm};

/// Compiles `src` as `main.st` with one instance `main`.
fn try_build(src: &str) -> Result<Compiled, String> {
    try_build_pou(src, None)
}

fn try_build_pou(src: &str, pou: Option<&str>) -> Result<Compiled, String> {
    try_build_with(src, pou, Dialect::default())
}

fn try_build_with(src: &str, pou: Option<&str>, dialect: Dialect) -> Result<Compiled, String> {
    let (file, diags) = parse_file(Path::new("main.st"), src);
    if !diags.is_empty() {
        return Err(diags.to_string());
    }
    let inst = Instance {
        name: "main",
        pou,
        file: Path::new("main.st"),
        config: Path::new("plcd.toml"),
        line: 2,
        col: 8,
    };
    compile_with(&[file], &[inst], dialect).map_err(|d| d.to_string())
}

/// The project of `dir`'s `plcd.toml` (its text `toml`), its paths relative to `dir`.
fn configured_project(dir: &Path, toml: &str) -> Result<(), String> {
    let config =
        plcd_core::config::parse(toml, Path::new("plcd.toml")).map_err(|d| d.to_string())?;
    plcd_core::project::from_config(config, |path| fs::read_to_string(dir.join(path)))
        .map(|_| ())
        .map_err(|d| d.to_string())
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
        vm.reset_for_run(&plcd_core::device::RetainSet::default(), false);
        let frame = c.programs.iter().map(|p| p.frame_bytes).max().unwrap_or(0);
        Run {
            c,
            vm,
            state: ExecState::with_frame(frame),
            clock: ManualClock::new(0),
            exits: Vec::new(),
        }
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
            ValueType::Calendar(cal) => cal.elem(),
            ValueType::Enum { base, .. } => base,
            ValueType::Char => Elem::U8,
            ValueType::WChar => Elem::U16,
            ValueType::String { .. } | ValueType::WString { .. } => panic!("{name} is a string"),
            ValueType::Reference { .. } => Elem::U64,
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
        plcd_core::value::decode_str(&self.vm.read_string(at))
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

#[test]
fn precedence_and_operators() {
    let r = once(
        "a : INT; b : INT; c : BOOL; d : BOOL; e : BOOL; f : REAL; g : INT; h : BOOL; w : WORD; m : INT; n : INT;",
        "a := 2 + 3 * 4 - 10 / 3;      (* 2 + 12 - 3 = 11 *)
         b := -2 * -3 + 7 MOD 4;       (* 6 + 3 = 9 *)
         c := 1 < 2 AND 3 > 4 OR TRUE XOR FALSE;  (* (F) OR (T) = T *)
         d := NOT TRUE OR 2 = 2 AND 3 <> 3;        (* F OR (T AND F) = F *)
         e := 2 ** 3 = 8.0;
         f := 2.0 ** 10.0;
         g := (2 + 3) * 4;
         h := 5 >= 5 AND 4 <= 3 = FALSE;         (* T AND ((4<=3)=F) = T *)
         w := 16#F0F0 AND 16#FF00 OR 16#000F;    (* F000 OR 000F = F00F *)
         m := -7 MOD 2;
         n := -7 / 2;",
    );
    assert_eq!(r.int("main.a"), 11);
    assert_eq!(r.int("main.b"), 9);
    assert_eq!(r.int("main.c"), 1);
    assert_eq!(r.int("main.d"), 0);
    assert_eq!(r.int("main.e"), 1);
    assert_eq!(r.real("main.f"), 1024.0);
    assert_eq!(r.int("main.g"), 20);
    assert_eq!(r.int("main.h"), 1);
    assert_eq!(r.int("main.w"), 0xF00F);
    assert_eq!(r.int("main.m"), -1);
    assert_eq!(r.int("main.n"), -3);
}

#[test]
fn runtime_operators_on_variables() {
    let r = once(
        "x : INT := 7; y : INT := -3; s : SINT := 100; u : USINT := 250; q : INT; p : INT; o : SINT; v : USINT;
         l : LINT := 9000000000; k : LINT; z : DINT; t : BOOL; bw : BYTE := 16#0F; nb : BYTE; rr : LREAL; i : INT := 0;",
        "q := x / y; p := x MOD y; o := s + s; v := u + 10; k := l * 2; z := x * y - y;
         t := x > y AND NOT (x = y); nb := NOT bw; rr := INT_TO_LREAL(x) / 2.0;",
    );
    assert_eq!(r.int("main.q"), -2);
    assert_eq!(r.int("main.p"), 1);
    assert_eq!(r.int("main.o"), -56); // 200 wraps in SINT
    assert_eq!(r.int("main.v"), 4); // 260 wraps in USINT
    assert_eq!(r.int("main.k"), 18_000_000_000);
    assert_eq!(r.int("main.z"), -18);
    assert_eq!(r.int("main.t"), 1);
    assert_eq!(r.int("main.nb"), 0xF0);
    assert_eq!(r.real("main.rr"), 3.5);
}

#[test]
fn integer_wrap() {
    let r = once(
        "a : INT := 32767; b : DINT := -2147483648; c : UINT := 0; d : SINT := -128; e : UDINT := 4294967295;",
        "a := a + 1; b := b - 1; c := c - 1; d := -d; e := e + 2;",
    );
    assert_eq!(r.int("main.a"), -32768);
    assert_eq!(r.int("main.b"), 2147483647);
    assert_eq!(r.int("main.c"), 65535);
    assert_eq!(r.int("main.d"), -128);
    assert_eq!(r.int("main.e"), 1);
}

#[test]
fn if_elsif_else() {
    let src = "x : INT; r1 : INT; r2 : INT; r3 : INT;";
    let r = once(
        src,
        "x := 5;
         IF x > 10 THEN r1 := 1; ELSIF x > 3 THEN r1 := 2; ELSE r1 := 3; END_IF;
         IF x < 0 THEN r2 := 1; ELSIF x = 0 THEN r2 := 2; ELSE r2 := 3; END_IF;
         IF TRUE THEN r3 := 7; END_IF;",
    );
    assert_eq!(r.int("main.r1"), 2);
    assert_eq!(r.int("main.r2"), 3);
    assert_eq!(r.int("main.r3"), 7);
}

#[test]
fn case_values_ranges_and_else() {
    let r = once(
        "i : INT; a : INT; b : INT; c : INT; d : INT;",
        "i := 4; CASE i OF 1: a := 10; 2, 3: a := 20; 4..6: a := 30; ELSE a := 40; END_CASE;
         i := 9; CASE i OF 1: b := 10; 4..6: b := 30; ELSE b := 40; END_CASE;
         i := -2; CASE i OF -5..-1: c := 1; 0: c := 2; END_CASE;
         i := 3; CASE i * 2 OF 6: d := 66; END_CASE;",
    );
    assert_eq!(r.int("main.a"), 30);
    assert_eq!(r.int("main.b"), 40);
    assert_eq!(r.int("main.c"), 1);
    assert_eq!(r.int("main.d"), 66);
}

#[test]
fn enumerations_inline_and_declared() {
    let src = "TYPE Color : (Red, Green := 5, Blue); END_TYPE
TYPE Mode : INT (Off, Auto := 10) := Auto; END_TYPE
PROGRAM main
VAR c : Color; d : Color := Blue; m : Mode; s : (Idle, Busy); n : INT; k : INT; END_VAR
  CASE d OF Red: n := 1; Green: n := 2; Blue: n := 3; END_CASE;
  IF m = Mode#Auto THEN k := 1; END_IF;
  s := Busy;
  c := Color#Green;
END_PROGRAM";
    let mut r = Run::new(src);
    r.scan();
    assert_eq!(r.int("main.n"), 3);
    assert_eq!(r.int("main.k"), 1);
    assert_eq!(r.int("main.c"), 5);
    assert_eq!(r.int("main.d"), 6);
    assert_eq!(r.int("main.s"), 1);
}

#[test]
fn for_loops_count_up_down_and_stop_at_the_type_end() {
    let r = once(
        "i : INT; s : INT; t : INT; u : INT; k : SINT; n : INT; j : INT; st : INT := 3; e : INT;",
        "FOR i := 1 TO 10 DO s := s + i; END_FOR;
         FOR i := 10 TO 1 BY -3 DO t := t * 10 + i; END_FOR;  (* 10 7 4 1 *)
         FOR k := 120 TO 127 DO n := n + 1; END_FOR;          (* no wrap: 8 times *)
         FOR i := 0 TO 20 BY st DO u := u + 1; END_FOR;        (* 0 3 .. 18: 7 times *)
         FOR j := 5 TO 1 DO e := 99; END_FOR;",
    );
    assert_eq!(r.int("main.s"), 55);
    assert_eq!(r.int("main.t"), ((10 * 10 + 7) * 10 + 4) * 10 + 1);
    assert_eq!(r.int("main.n"), 8);
    // Past the bound the variable takes the first value that fails the test, with
    // wrap-around: 127 + 1 in a SINT is -128; 18 + 3 is 21.
    assert_eq!(r.int("main.k"), -128);
    assert_eq!(r.int("main.u"), 7);
    assert_eq!(r.int("main.i"), 21);
    assert_eq!(r.int("main.e"), 0);
    assert_eq!(r.int("main.j"), 5);
}

/// CODESYS's assignment inside an expression is checked as a statement's: the value of
/// `r := i` is a REAL, which an INT takes only converted (CODESYS's documentation calls
/// `int_var := real_var1 := int_var` an incorrect assignment), a CONSTANT is not written, an
/// instance's output is not written from outside. TwinCAT's FOR in an element counts in a
/// fixed place of the POU's own variable only.
#[test]
fn habits_of_statements_keep_the_statements_rules() {
    let program = |vars: &str, body: &str| {
        errors(&format!(
            "FUNCTION_BLOCK Fb VAR_OUTPUT q : INT; END_VAR END_FUNCTION_BLOCK
PROGRAM main
VAR {vars} END_VAR
VAR CONSTANT K : INT := 3; END_VAR
{body}
END_PROGRAM"
        ))
    };
    let e = program("i : INT; r : REAL;", "i := r := i;");
    assert!(e.contains("`REAL` cannot be assigned to `INT`"), "{e}");
    let e = program("i : INT;", "i := K := 4;");
    assert!(e.contains("`K` is CONSTANT"), "{e}");
    let e = program("i : INT; f : Fb;", "i := (f.q := 1) + 1;");
    assert!(e.contains("`q` is a VAR_OUTPUT of `Fb`"), "{e}");
    let e = program("a : ARRAY [1..2] OF INT; n : INT := 1;", "FOR a[n] := 0 TO 1 DO END_FOR;");
    assert!(e.contains("element at constant indices"), "{e}");
    // a constant index out of the bounds is that error only
    let e = program("a : ARRAY [1..2] OF INT;", "FOR a[K] := 0 TO 1 DO END_FOR;");
    assert!(e.contains("index 3 is out of the bounds `1..2`") && e.lines().count() == 1, "{e}");
    let e = program("a : ARRAY [1..2] OF REAL;", "FOR a[1] := 0 TO 1 DO END_FOR;");
    assert!(e.contains("must be an integer, not `REAL`"), "{e}");
    assert_eq!(program("a : ARRAY [1..2] OF INT; b : BOOL;", "FOR a[2] := 0 TO 1 DO END_FOR;"), "");
}

#[test]
fn while_repeat_exit_continue() {
    let r = once(
        "i : INT; a : INT; b : INT; c : INT; d : INT;",
        "i := 0; WHILE i < 10 DO i := i + 1; IF i MOD 2 = 0 THEN CONTINUE; END_IF; a := a + i; END_WHILE;
         i := 0; REPEAT i := i + 1; b := b + 2; UNTIL i >= 5 END_REPEAT;
         i := 0; WHILE TRUE DO i := i + 1; IF i = 7 THEN EXIT; END_IF; END_WHILE; c := i;
         FOR i := 1 TO 100 DO IF i > 4 THEN EXIT; END_IF; d := d + i; END_FOR;",
    );
    assert_eq!(r.int("main.a"), 1 + 3 + 5 + 7 + 9);
    assert_eq!(r.int("main.b"), 10);
    assert_eq!(r.int("main.c"), 7);
    assert_eq!(r.int("main.d"), 10);
}

#[test]
fn return_in_a_program_ends_the_scan() {
    let r = once("a : INT; b : INT;", "a := 1; IF a = 1 THEN RETURN; END_IF; b := 2;");
    assert_eq!(r.int("main.a"), 1);
    assert_eq!(r.int("main.b"), 0);
}

#[test]
fn arrays_structs_and_copies() {
    let src = "TYPE Point : STRUCT x : INT := 1; y : REAL := 2.5; END_STRUCT; END_TYPE
PROGRAM main
VAR
  a : ARRAY [1..5] OF INT := [10, 20, 3(7)];
  b : ARRAY [1..5] OF INT;
  m : ARRAY [-1..1, 0..2] OF DINT;
  p : Point; q : Point; ps : ARRAY [0..2] OF Point;
  i : INT; j : INT; s : DINT; t : INT;
END_VAR
  b := a;
  b[2] := 99;
  FOR i := -1 TO 1 DO FOR j := 0 TO 2 DO m[i, j] := i * 10 + j; END_FOR; END_FOR;
  s := m[1, 2] + m[-1, 0];
  q := p; q.x := 5;
  ps[1] := q; ps[2].y := 7.0;
  i := 3; t := a[i] + a[i - 2];
END_PROGRAM";
    let mut r = Run::new(src);
    r.scan();
    assert_eq!(r.int("main.b[1]"), 10);
    assert_eq!(r.int("main.b[2]"), 99);
    assert_eq!(r.int("main.a[2]"), 20);
    assert_eq!(r.int("main.b[5]"), 7);
    assert_eq!(r.int("main.m[0,1]"), 1);
    assert_eq!(r.int("main.s"), 12 - 10);
    assert_eq!(r.int("main.q.x"), 5);
    assert_eq!(r.int("main.p.x"), 1);
    assert_eq!(r.real("main.q.y"), 2.5);
    assert_eq!(r.int("main.ps[1].x"), 5);
    assert_eq!(r.real("main.ps[2].y"), 7.0);
    assert_eq!(r.int("main.ps[0].x"), 1);
    assert_eq!(r.int("main.t"), 7 + 10);
}

#[test]
fn bit_access_reads_and_writes() {
    let r = once(
        "w : WORD := 16#0008; b : BOOL; c : BOOL; i : INT := 2; d : DINT := -1;",
        "b := w.3; c := w.4; w.0 := TRUE; w.3 := FALSE; w.15 := b; d.31 := FALSE;",
    );
    assert_eq!(r.int("main.b"), 1);
    assert_eq!(r.int("main.c"), 0);
    assert_eq!(r.int("main.w"), 0x8001);
    assert_eq!(r.int("main.d"), 0x7FFF_FFFF);
}

#[test]
fn division_by_zero_and_index_out_of_range_raise_errors_without_harm() {
    let r = once(
        "a : ARRAY [0..3] OF INT; guard : INT := 55; x : INT := 10; z : INT; q : INT; i : INT := 4; r : REAL; f : REAL := 1.0;",
        "q := x / z; a[i] := 7; i := -1; a[i] := 8; x := a[i]; r := f / 0.0;",
    );
    assert_eq!(r.int("main.q"), 0);
    assert_eq!(r.int("main.guard"), 55);
    assert_eq!(r.int("main.x"), 0);
    for k in 0..4 {
        assert_eq!(r.int(&format!("main.a[{k}]")), 0);
    }
    assert_eq!(r.errors(), vec![0x3400, 0x3402, 0x3402, 0x3402, 0x3400]);
}

#[test]
fn user_functions_with_locals_outputs_and_in_out() {
    let src = "FUNCTION Sq : DINT
VAR_INPUT x : DINT; END_VAR
VAR t : DINT := 1; END_VAR
  t := t + x * x;   (* t starts from 1 at every call *)
  Sq := t - 1;
END_FUNCTION
FUNCTION Swap : BOOL
VAR_IN_OUT a : INT; b : INT; END_VAR
VAR t : INT; END_VAR
  t := a; a := b; b := t; Swap := TRUE;
END_FUNCTION
FUNCTION Split : INT
VAR_INPUT v : INT; END_VAR
VAR_OUTPUT hi : INT; lo : INT; END_VAR
  hi := v / 100; lo := v MOD 100; Split := v;
END_FUNCTION
PROGRAM main
VAR a : DINT; b : DINT; x : INT := 1; y : INT := 2; ok : BOOL; h : INT; l : INT; n : DINT; END_VAR
  a := Sq(3) + Sq(x := 4);
  b := Sq(Sq(2));
  ok := Swap(x, y);
  Split(v := 1234, hi => h, lo => l);
  n := Sq(Sq(1) + Sq(2)) + 1;
END_PROGRAM";
    let mut r = Run::new(src);
    r.scan();
    assert_eq!(r.int("main.a"), 25);
    assert_eq!(r.int("main.b"), 16);
    assert_eq!(r.int("main.x"), 2);
    assert_eq!(r.int("main.y"), 1);
    assert_eq!(r.int("main.ok"), 1);
    assert_eq!(r.int("main.h"), 12);
    assert_eq!(r.int("main.l"), 34);
    assert_eq!(r.int("main.n"), 26);
}

#[test]
fn function_blocks_keep_state_across_scans() {
    let src = "FUNCTION_BLOCK Counter
VAR_INPUT up : BOOL; step : INT := 1; END_VAR
VAR_OUTPUT count : INT; END_VAR
VAR edge : R_TRIG; END_VAR
  edge(CLK := up);
  IF edge.Q THEN count := count + step; END_IF;
END_FUNCTION_BLOCK
PROGRAM main
VAR c1 : Counter; c2 : Counter := (step := 10); cs : ARRAY [0..1] OF Counter; n : INT; m : INT; k : INT; in : BOOL; i : INT; END_VAR
  in := NOT in;
  c1(up := in, count => n);
  c2(up := in);
  m := c2.count;
  FOR i := 0 TO 1 DO cs[i](up := in, step := i + 1); END_FOR;
  k := cs[1].count;
END_PROGRAM";
    let mut r = Run::new(src);
    for _ in 0..5 {
        r.scan();
    }
    // in: T F T F T → three rising edges
    assert_eq!(r.int("main.n"), 3);
    assert_eq!(r.int("main.m"), 30);
    assert_eq!(r.int("main.k"), 6);
    assert_eq!(r.int("main.cs[0].count"), 3);
    assert_eq!(r.int("main.c1.edge.was_high"), 1);
}

#[test]
fn ton_times_with_the_clock() {
    let src = "PROGRAM main
VAR t : TON; go : BOOL; q : BOOL; et : TIME; END_VAR
  t(IN := go, PT := T#100ms, Q => q, ET => et);
END_PROGRAM";
    let mut r = Run::new(src);
    r.scan();
    assert_eq!(r.int("main.q"), 0);
    let (at, _) = r.sym("main.go");
    r.vm.write_value(at, Elem::Bool, 1);
    r.scan();
    r.clock.advance(60_000_000);
    r.scan();
    assert_eq!(r.int("main.q"), 0);
    assert_eq!(r.int("main.et"), 60_000_000);
    r.clock.advance(50_000_000);
    r.scan();
    assert_eq!(r.int("main.q"), 1);
    assert_eq!(r.int("main.et"), 100_000_000);
}

#[test]
fn functions_are_reentrant_across_two_exec_states() {
    let src = "FUNCTION Slow : DINT
VAR_INPUT n : DINT; END_VAR
VAR acc : DINT; i : DINT; END_VAR
  FOR i := 1 TO n DO acc := acc + i; END_FOR;
  Slow := acc;
END_FUNCTION
PROGRAM main
VAR a : DINT; b : DINT; END_VAR
  a := Slow(100);
  b := Slow(10);
END_PROGRAM";
    let c = build(src);
    let program = c.programs[0].clone();
    let mut vm = Vm::for_programs(&c.programs);
    vm.set_variables(&c.variables);
    let mut s1 = ExecState::with_frame(program.frame_bytes);
    let mut s2 = ExecState::with_frame(program.frame_bytes);
    let clock = ManualClock::new(0);
    // interleave two activations a few steps at a time
    let (mut d1, mut d2) = (false, false);
    while !(d1 && d2) {
        if !d1 {
            d1 = vm.run(&program, &mut s1, &clock, 7) == Exit::End;
        }
        if !d2 {
            d2 = vm.run(&program, &mut s2, &clock, 5) == Exit::End;
        }
    }
    let sym = |n: &str| c.variables.symbols.iter().find(|s| s.name == n).unwrap().at;
    assert_eq!(vm.read_value(sym("main.a"), Elem::I32), 5050);
    assert_eq!(vm.read_value(sym("main.b"), Elem::I32), 55);
}

#[test]
fn an_endless_while_spends_the_budget() {
    let c = build(
        "PROGRAM main VAR i : DINT; END_VAR WHILE TRUE DO i := i + 1; END_WHILE; END_PROGRAM",
    );
    let program = c.programs[0].clone();
    let mut vm = Vm::for_programs(&c.programs);
    vm.set_variables(&c.variables);
    let mut s = ExecState::with_frame(program.frame_bytes);
    let clock = ManualClock::new(0);
    for _ in 0..50 {
        assert_eq!(vm.run(&program, &mut s, &clock, 1000), Exit::Budget);
    }
}

#[test]
fn globals_externals_constants_and_located_variables() {
    let src = "VAR_GLOBAL g : INT := 5; limit : INT := 3; END_VAR
VAR_GLOBAL CONSTANT K : INT := 7; END_VAR
VAR_GLOBAL out AT %QX1.2 : BOOL; w AT %D00100 : DINT := 70000; END_VAR
PROGRAM main
VAR_EXTERNAL g : INT; END_VAR
VAR a : INT; b : ARRAY [0..K] OF INT; in AT %IW3 : INT; m AT %MW2 : WORD; x AT %P0040 : BOOL; END_VAR
  a := g + K + limit;
  g := g + 1;
  out := TRUE;
  w := w + 1;
  m := 16#1234;
  x := NOT x;
END_PROGRAM";
    let mut r = Run::new(src);
    r.scan();
    assert_eq!(r.int("main.a"), 15);
    assert_eq!(r.int("g"), 6);
    assert_eq!(r.int("out"), 1);
    assert_eq!(r.int("w"), 70001);
    assert_eq!(r.int("main.m"), 0x1234);
    assert_eq!(r.c.variables.located_init.len(), 1);
    let (at, _) = r.sym("out");
    assert_eq!(at.space, plcd_core::value::Space::Bit);
    // %QX1.2: byte 1 of the %QX image (from P064) is the high half of P064, bit 8 + 2
    assert_eq!(at.offset, 64 * 16 + 8 + 2);
    assert!(r.c.variables.symbols.iter().any(|s| s.name == "main.b[7]"));
}

#[test]
fn strings() {
    let r = once(
        "s : STRING := 'Hello'; t : STRING[10]; u : STRING; n : INT; p : INT; l : STRING; c : BOOL; d : STRING;",
        "t := CONCAT(s, ', world!');
         n := LEN(s);
         p := FIND(t, 'wor');
         l := LEFT(s, 2);
         u := MID(s, 3, 2);
         c := s = 'Hello' AND s < 'Help';
         d := CONCAT(RIGHT(s, 2), LEFT(s, 1), 'x');",
    );
    assert_eq!(r.string("main.t"), "Hello, wor");
    assert_eq!(r.int("main.n"), 5);
    assert_eq!(r.int("main.p"), 8);
    assert_eq!(r.string("main.l"), "He");
    assert_eq!(r.string("main.u"), "ell");
    assert_eq!(r.int("main.c"), 1);
    assert_eq!(r.string("main.d"), "loHx");
}

/// Each `tests/golden/st/<case>/main.st` reports exactly the diagnostic lines of its
/// `expected.stderr` (the final `plcd.toml: N error(s)` line is the binary's, left out here;
/// a `warning-` case compiles and warns);
/// `PLCD_BLESS=1` rewrites the expected files that differ.
#[test]
fn golden_diagnostics() {
    let bless = std::env::var_os("PLCD_BLESS").is_some_and(|v| v == "1");
    let mut failures = Vec::new();
    let mut cases: Vec<PathBuf> = fs::read_dir("tests/golden/st")
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    cases.sort();
    assert!(!cases.is_empty());
    for dir in &cases {
        let src = fs::read_to_string(dir.join("main.st")).unwrap();
        let toml = fs::read_to_string(dir.join("plcd.toml")).unwrap_or_default();
        if toml.lines().any(|l| l.starts_with("library = ")) {
            // a project of several files: golden_diagnostics checks it through `plcd check`
            continue;
        }
        let pou = toml
            .lines()
            .find_map(|l| l.strip_prefix("pou = "))
            .map(|v| v.trim_matches('"').to_string());
        let strict = toml.lines().any(|l| l.trim() == "strict = true");
        let heap_bytes = toml
            .lines()
            .find_map(|l| l.trim().strip_prefix("heap_bytes = ")?.parse().ok())
            .unwrap_or(Dialect::default().heap_bytes);
        let variable_memory_bytes = toml
            .lines()
            .find_map(|l| l.trim().strip_prefix("variable_memory_bytes = ")?.parse().ok())
            .unwrap_or(Dialect::default().variable_memory_bytes);
        let dialect = Dialect { strict, heap_bytes, variable_memory_bytes, ..Dialect::default() };
        // a `warning-` case compiles, with its one warning
        let warning = dir.file_name().is_some_and(|n| n.to_string_lossy().starts_with("warning-"));
        let actual = if warning {
            match try_build_with(&src, pou.as_deref(), dialect) {
                Ok(compiled) => compiled.warnings.iter().map(|w| format!("{w}\n")).collect(),
                Err(errors) => errors,
            }
        } else if src.to_ascii_uppercase().contains("CONFIGURATION") || toml.contains("[iec.") {
            // A configuration's instances are the project's, and the config's `[iec.variables]`
            // and `[iec.addresses]` the config's: loaded as `plcd check` does.
            configured_project(dir, &toml).err().unwrap_or_default()
        } else {
            try_build_with(&src, pou.as_deref(), dialect).err().unwrap_or_default()
        };
        let count = actual.lines().count();
        if count != 1 {
            failures.push(format!("{}: {count} diagnostics:\n{actual}", dir.display()));
            continue;
        }
        let expected_path = dir.join("expected.stderr");
        let expected = fs::read_to_string(&expected_path).unwrap_or_default();
        let expected_lines: String = expected
            .lines()
            .filter(|l| !l.starts_with("plcd.toml: "))
            .map(|l| format!("{l}\n"))
            .collect();
        if expected_lines != actual {
            if bless {
                let count = if warning { "" } else { "plcd.toml: 1 error(s)\n" };
                fs::write(&expected_path, format!("{actual}{count}")).unwrap();
                eprintln!("PLCD_BLESS: rewrote {}", expected_path.display());
            } else {
                failures.push(format!(
                    "{}:\n--- expected\n{expected_lines}--- actual\n{actual}",
                    dir.display()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn standard_functions() {
    let r = once(
        "a : INT; b : REAL; c : LREAL; d : DINT; e : DINT; f : INT; g : INT; h : WORD; i : BYTE; j : BYTE; k : INT;
         l : DINT; m : DINT; n : DINT; o : BOOL; p : INT; q : REAL; s : DINT; t : DINT; u : TIME; v : REAL; w : INT;
         x : LREAL; y : BYTE; z : INT; neg : INT := -5; big : LREAL := 2.5; gsel : BOOL := TRUE; k3 : INT := 2;",
        "a := ABS(neg);                  (* 5 *)
         b := SQRT(16.0);                (* 4 *)
         c := EXPT(2.0, 3);               (* 8 *)
         d := ADD(1, 2, 3, 4);            (* 10 *)
         e := MUL(2, 3, 4) - SUB(10, 4);  (* 24 - 6 = 18 *)
         f := DIV(17, 5) * 10 + 17 MOD 5; (* 32; MOD(…), AND(…) are keywords to the parser *)
         g := MAX(3, neg, 9, 4) + MIN(3, neg);   (* 9 - 5 = 4 *)
         h := SHL(WORD#16#00F0, 4);       (* 16#0F00 *)
         i := ROL(BYTE#16#81, 1);         (* 16#03 *)
         j := ROR(BYTE#16#81, 1);         (* 16#C0 *)
         k := LIMIT(0, 150, 100);         (* 100 *)
         l := SEL(gsel, 10, 20);           (* 20 *)
         m := MUX(k3, 100, 200, 300, 400); (* 300 *)
         n := TRUNC(-2.7);                (* -2 *)
         o := MAX(FALSE, TRUE);          (* TRUE *)
         p := REAL_TO_INT(2.5) + REAL_TO_INT(-2.5);  (* 3 + -3 = 0 *)
         q := INT_TO_REAL(neg) / 2.0;     (* -2.5 *)
         s := TIME_TO_DINT(T#1s500ms);    (* 1500 *)
         t := BOOL_TO_DINT(gsel) + DINT#16#7FFFFFFF;  (* wraps to -2147483648 *)
         u := DINT_TO_TIME(250);          (* 250 ms *)
         v := LREAL_TO_REAL(big) * 2.0;   (* 5 *)
         w := DINT_TO_INT(70000);         (* 70000 - 65536 = 4464 *)
         x := LN(1.0) + LOG(100.0) + EXP(0.0) + SIN(0.0) + COS(0.0) + TAN(0.0) + ASIN(0.0) + ACOS(1.0) + ATAN(0.0); (* 0+2+1+0+1+0+0+0+0 = 4 *)
         y := NOT BYTE#16#0F AND 16#3C;   (* F0 AND 3C = 30 *)
         z := MOVE(neg);",
    );
    assert_eq!(r.int("main.a"), 5);
    assert_eq!(r.real("main.b"), 4.0);
    assert_eq!(r.real("main.c"), 8.0);
    assert_eq!(r.int("main.d"), 10);
    assert_eq!(r.int("main.e"), 18);
    assert_eq!(r.int("main.f"), 32);
    assert_eq!(r.int("main.g"), 4);
    assert_eq!(r.int("main.h"), 0x0F00);
    assert_eq!(r.int("main.i"), 0x03);
    assert_eq!(r.int("main.j"), 0xC0);
    assert_eq!(r.int("main.k"), 100);
    assert_eq!(r.int("main.l"), 20);
    assert_eq!(r.int("main.m"), 300);
    assert_eq!(r.int("main.n"), -2);
    assert_eq!(r.int("main.o"), 1);
    assert_eq!(r.int("main.p"), 0);
    assert_eq!(r.real("main.q"), -2.5);
    assert_eq!(r.int("main.s"), 1500);
    assert_eq!(r.int("main.t"), -2147483648);
    assert_eq!(r.int("main.u"), 250_000_000);
    assert_eq!(r.real("main.v"), 5.0);
    assert_eq!(r.int("main.w"), 4464);
    assert_eq!(r.real("main.x"), 4.0);
    assert_eq!(r.int("main.y"), 0x30);
    assert_eq!(r.int("main.z"), -5);
}

#[test]
fn standard_functions_on_variables_at_run_time() {
    let r = once(
        "x : REAL := 9.0; n : INT := 3; w : WORD := 16#8001; c : INT := 1; s : BOOL; r1 : REAL; r2 : INT; r3 : WORD; r4 : INT; r5 : INT; r6 : DINT; r7 : TIME; t : TIME := T#2s;",
        "r1 := SQRT(x) + EXPT(x, 0.5);          (* 6 *)
         r2 := MAX(n, 7) - MIN(n, -1) + LIMIT(0, n * 100, 250); (* 7 + 1 + 250 = 258 *)
         r3 := ROL(w, c) OR SHR(w, 15);         (* 16#0003 OR 1 = 3 *)
         r4 := SEL(s, n, n * 2);                (* FALSE: 3 *)
         r5 := MUX(n - 2, 10, 20, 30);          (* 20 *)
         r6 := TIME_TO_DINT(t * 3 / 2);         (* 3000 *)
         r7 := t - T#500ms;",
    );
    assert_eq!(r.real("main.r1"), 6.0);
    assert_eq!(r.int("main.r2"), 258);
    assert_eq!(r.int("main.r3"), 3);
    assert_eq!(r.int("main.r4"), 3);
    assert_eq!(r.int("main.r5"), 20);
    assert_eq!(r.int("main.r6"), 3000);
    assert_eq!(r.int("main.r7"), 1_500_000_000);
}

#[test]
fn string_insert_delete_replace() {
    let r = once(
        "s : STRING := 'abcdef'; a : STRING; b : STRING; c : STRING;",
        "a := INSERT(s, 'XY', 2); b := DELETE(s, 2, 3); c := REPLACE(s, 'Z', 3, 2);",
    );
    assert_eq!(r.string("main.a"), "abXYcdef");
    assert_eq!(r.string("main.b"), "abef");
    assert_eq!(r.string("main.c"), "aZef");
}

#[test]
fn every_error_of_every_file_at_once() {
    let e = errors(
        "PROGRAM main
VAR a : INT; r : REAL; END_VAR
  a := r;
  b := 1;
  a := 70000;
END_PROGRAM",
    );
    assert_eq!(e.lines().count(), 3, "{e}");
}

/// A generated 10,000-line project compiles (its time measured in release for the report).
#[test]
fn ten_thousand_lines() {
    let mut src = String::new();
    for f in 0..200 {
        src.push_str(&format!("FUNCTION F{f} : DINT\nVAR_INPUT x : DINT; END_VAR\nVAR i : DINT; acc : DINT; END_VAR\n"));
        for k in 0..20 {
            src.push_str(&format!("  acc := acc + x * {k} - i;\n"));
        }
        src.push_str("  FOR i := 1 TO 10 DO\n    IF i MOD 2 = 0 THEN acc := acc + i; ELSE acc := acc - 1; END_IF;\n  END_FOR;\n");
        src.push_str(&format!("  F{f} := acc;\nEND_FUNCTION\n"));
    }
    src.push_str("PROGRAM main\nVAR a : ARRAY [0..199] OF DINT; END_VAR\n");
    for f in 0..200 {
        src.push_str(&format!("  a[{f}] := F{f}({f});\n"));
    }
    src.push_str("END_PROGRAM\n");
    while src.lines().count() < 10_000 {
        src.push_str("(* padding *)\n");
    }
    let start = std::time::Instant::now();
    let c = build(&src);
    eprintln!("{} lines compiled in {:?}", src.lines().count(), start.elapsed());
    assert!(c.programs[0].code.len() > 10_000);
}

// ---------------------------------------------------------------------------------------------
// EN and ENO, edge inputs, and what plcd accepts of CODESYS's habits (docs/ST.md)

#[test]
fn en_and_eno_are_checked_like_parameters() {
    let fb = "FUNCTION_BLOCK Fb\nVAR_OUTPUT q : BOOL; END_VAR\nq := TRUE;\nEND_FUNCTION_BLOCK\n\
              FUNCTION F : INT\nVAR_INPUT x : INT; END_VAR\nF := x;\nEND_FUNCTION\n";
    let prog = |vars: &str, body: &str| {
        errors(&format!("{fb}PROGRAM main\nVAR\n{vars}\nEND_VAR\n{body}\nEND_PROGRAM\n"))
    };
    let e = prog("a : INT;", "a := F(EN := 5, x := 1);");
    assert!(e.contains("integer constant `5` cannot be assigned to `BOOL`"), "{e}");
    let e = prog("a : INT;", "a := F(EN := TRUE, EN := FALSE, x := 1);");
    assert!(e.contains("`EN` is given twice"), "{e}");
    let e = prog("a : INT;", "a := F(x := 1, ENO => a);");
    assert!(e.contains("type mismatch: `BOOL` cannot be assigned to `INT`"), "{e}");
    let e = prog("a : INT;", "a := LIMIT(EN := TRUE, 0, a, 10);");
    assert!(e.contains("mixes positional and named arguments"), "{e}");
    let e = prog("a : INT;", "a := ADD(EN := TRUE, IN1 := a, IN2 := 1, ENO => a);");
    assert!(e.contains("type mismatch: `BOOL` cannot be assigned to `INT`"), "{e}");
    let e = prog("f : Fb; b : BOOL;", "f(); f.ENO := b;");
    assert!(e.contains("`ENO` is a VAR_OUTPUT of `Fb`"), "{e}");
    // the implicit EN is a condition of the call, not a variable of the instance
    let e = prog("f : Fb; b : BOOL;", "f(EN := TRUE); b := f.EN;");
    assert!(e.contains("`Fb` has no input or output `EN`"), "{e}");
}

#[test]
fn en_false_evaluates_no_other_argument() {
    let r = Run::new(
        "VAR_GLOBAL calls : INT; END_VAR
FUNCTION Next : INT
    calls := calls + 1;
    Next := calls;
END_FUNCTION
FUNCTION Id : INT
VAR_INPUT x : INT; END_VAR
    Id := x;
END_FUNCTION
FUNCTION_BLOCK Keep
VAR_INPUT x : INT; END_VAR
VAR_OUTPUT y : INT; END_VAR
    y := x;
END_FUNCTION_BLOCK
PROGRAM main
VAR a : INT := 5; k : Keep; s : STRING := 'kept'; t : STRING; END_VAR
    a := Id(EN := FALSE, x := Next());
    k(EN := FALSE, x := Next());
    s := CONCAT(EN := FALSE, IN1 := 'a', IN2 := INT_TO_STRING(Next()));
    t := CONCAT(CONCAT(EN := FALSE, IN1 := 'a', IN2 := 'b'), 'c');
END_PROGRAM",
    );
    let mut r = r;
    r.scan();
    assert_eq!(r.int("calls"), 0);
    assert_eq!(r.int("main.a"), 5);
    assert_eq!(r.int("main.k.x"), 0, "an input is not assigned");
    assert_eq!(r.string("main.s"), "kept");
    assert_eq!(r.string("main.t"), "c", "a STRING's default is ''");
}

#[test]
fn eno_is_there_only_when_something_may_read_it() {
    let src = |call: &str| {
        format!(
            "FUNCTION_BLOCK Fb\nVAR_OUTPUT q : BOOL; END_VAR\nq := TRUE;\nEND_FUNCTION_BLOCK\n\
             PROGRAM main\nVAR f : Fb; t : TON; b : BOOL; END_VAR\n{call}\nt(IN := TRUE, PT := T#1s);\nEND_PROGRAM\n"
        )
    };
    let names = |c: &Compiled| -> Vec<String> {
        c.variables.symbols.iter().map(|s| s.name.clone()).collect()
    };
    // no EN/ENO anywhere: the instances are as before, no ENO, no code
    let plain = build(&src("f();"));
    assert!(!names(&plain).iter().any(|n| n.ends_with(".ENO")), "{:?}", names(&plain));
    // EN alone: the call is skipped or not, and still no ENO stored
    let en = build(&src("f(EN := b);"));
    assert!(!names(&en).iter().any(|n| n.ends_with(".ENO")));
    // an ENO read: every FB has one, the tools see it
    let read = build(&src("f(ENO => b);"));
    for n in ["main.f.ENO", "main.t.ENO"] {
        assert!(names(&read).iter().any(|s| s == n), "{n} in {:?}", names(&read));
    }
    // the code of the body: ENO is set TRUE on entry only where it may have become FALSE
    let steps = |src: &str| {
        let mut r = Run::new(src);
        r.scan();
        r.vm.steps()
    };
    assert_eq!(steps(&src("f(ENO => b);")), steps(&src("f(); b := f.q;")));
}

#[test]
fn edge_declarations_belong_to_bool_inputs_of_function_blocks() {
    let e = errors(
        "FUNCTION_BLOCK Fb
VAR_INPUT a : INT R_EDGE; b : BOOL F_EDGE; END_VAR
VAR c : BOOL R_EDGE; END_VAR
VAR_OUTPUT d : BOOL R_EDGE; END_VAR
    d := b;
END_FUNCTION_BLOCK
PROGRAM main
VAR f : Fb; END_VAR
    f();
END_PROGRAM",
    );
    assert_eq!(e.matches("belongs to a `BOOL` VAR_INPUT of a FUNCTION_BLOCK").count(), 3, "{e}");
    assert!(e.contains("main.st:2:19: error: `R_EDGE`"), "{e}");
}

#[test]
fn codesys_habits_keep_their_limits() {
    let e = errors(
        "PROGRAM main
VAR b : BYTE; t : TIME; r : REAL; x : BOOL; i : INT; a : ARRAY [0..1] OF INT; END_VAR
    b := b + t;
    r := b MOD r;
    r := b * 1.5;
    x := b + x;
    i := SIZEOF(5);
    t := TIME(1);
    i := TO_INT(a);
    i := TRUNC_INT(i);
END_PROGRAM",
    );
    for m in [
        "3:10: error: `+` cannot be applied to `BYTE` and `TIME`",
        "4:10: error: `MOD` cannot be applied to `BYTE` and `REAL`",
        "5:14: error: type mismatch: a real constant cannot be assigned to `BYTE`",
        "6:10: error: `+` cannot be applied to `BYTE` and `BOOL`",
        "7:17: error: `SIZEOF` needs a variable or a type, not `ANY_INT`",
        "8:10: error: `TIME` takes no arguments",
        "9:17: error: `TO_INT` needs an elementary value, not `ARRAY [0..1] OF INT`",
        "10:20: error: `TRUNC_INT` needs a `REAL` or `LREAL`, not `INT`",
    ] {
        assert!(e.contains(m), "{m} in\n{e}");
    }
    assert_eq!(e.lines().count(), 8, "{e}");
}

#[test]
fn a_project_function_replaces_the_preludes_of_the_same_name() {
    let r = once("i : INT;", "i := BCD_TO_INT(16#12);");
    assert_eq!(r.int("main.i"), 12);
    let mut r = Run::new(
        "FUNCTION BCD_TO_INT : INT
VAR_INPUT b : BYTE; END_VAR
    BCD_TO_INT := 1234;
END_FUNCTION
PROGRAM main
VAR i : INT; END_VAR
    i := BCD_TO_INT(16#12);
END_PROGRAM",
    );
    r.scan();
    assert_eq!(r.int("main.i"), 1234);
    // a function block of the prelude stays reserved
    let e = errors(
        "FUNCTION_BLOCK TON\nVAR_INPUT IN : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n\
         PROGRAM main\nVAR t : TON; END_VAR\nt();\nEND_PROGRAM",
    );
    assert!(e.contains("`TON` is already declared"), "{e}");
}

/// A reference holds the VM pointer of its target, tagged so that 0 is NULL, and tools show
/// it as the area and offset of that target.
#[test]
fn a_reference_is_its_targets_pointer() {
    let r = once(
        "x : INT; buf : ARRAY [0..3] OF BYTE; p : POINTER TO BYTE; q : REF_TO INT; n : REF_TO INT;",
        "q := REF(x); p := ADR(buf) + 2;",
    );
    let (x_at, _) = r.sym("main.x");
    let (b2_at, _) = r.sym("main.buf[2]");
    assert_eq!(r.raw("main.q").0, x_at.to_slot() + (1 << 32));
    assert_eq!(r.raw("main.p").0, b2_at.to_slot() + (1 << 32));
    assert_eq!(r.raw("main.n").0, 0);
    let (_, ty) = r.sym("main.p");
    assert_eq!(ty, ValueType::Reference { type_name: "POINTER TO BYTE".into() });
    let shown = plcd_core::value::format(&ty, r.raw("main.p").0);
    assert_eq!(shown, format!("vars+{}", b2_at.offset));
    assert!(r.errors().is_empty());
}

/// References that cannot be made: to a constant, a bit, an expression; integers never
/// convert to references; REF_TO needs the same type, POINTER TO takes any pointer.
#[test]
fn references_are_checked() {
    let e = errors(
        "PROGRAM main
VAR
    x : INT;
    k : INT := 1;
    f : REAL;
    r : REF_TO INT;
    p : POINTER TO REAL;
    w : DWORD;
END_VAR
VAR CONSTANT
    c : INT := 4;
END_VAR
    r := REF(c);
    r := REF(x.3);
    r := REF(f);
    p := ADR(x);
    r := w;
    w := r;
    r := r + 1;
    p := p * 2;
    k := r^ + p^;
END_PROGRAM",
    );
    let lines: Vec<&str> = e.lines().collect();
    assert!(lines[0].contains("13:14: error: `REF` needs a variable"), "{e}");
    assert!(lines[1].contains("14:14: error: `REF` needs a variable"), "{e}");
    assert!(lines[2].contains("`REF_TO REAL` cannot be assigned to `REF_TO INT`"), "{e}");
    assert!(lines[3].contains("`DWORD` cannot be assigned to `REF_TO INT`"), "{e}");
    assert!(lines[4].contains("`REF_TO INT` cannot be assigned to `DWORD`"), "{e}");
    assert!(lines[5].contains("`+` cannot be applied to `REF_TO INT` and `ANY_INT`"), "{e}");
    assert!(lines[6].contains("`*` cannot be applied to `POINTER TO REAL` and `ANY_INT`"), "{e}");
    // r^ + p^ is INT + REAL, a REAL (what p points to is a REAL)
    assert!(lines[7].contains("21:10: error: type mismatch: `REAL` cannot be assigned"), "{e}");
    assert_eq!(lines.len(), 8, "{e}");
}

/// The constant 0 is NULL for a POINTER TO only, and no other integer is a reference.
#[test]
fn only_the_constant_0_is_null_and_only_for_pointers() {
    let e = errors(
        "PROGRAM main
VAR
    r : REF_TO INT;
    p : POINTER TO INT;
    ok : BOOL;
END_VAR
    p := 0;
    ok := p <> 0;
    r := 0;
    p := 1;
    ok := r = 0;
END_PROGRAM",
    );
    let lines: Vec<&str> = e.lines().collect();
    assert!(
        lines[0].contains(
            "9:10: error: type mismatch: integer constant `0` cannot be assigned to `REF_TO INT`"
        ),
        "{e}"
    );
    assert!(lines[1].contains("10:10: error: type mismatch: integer constant `1` cannot be assigned to `POINTER TO INT`"), "{e}");
    assert!(
        lines[2].contains("11:11: error: `=` cannot be applied to `REF_TO INT` and `ANY_INT`"),
        "{e}"
    );
    assert_eq!(lines.len(), 3, "{e}");
}

/// An enumeration's constant as the label of a CASE on a narrower integer (TcUnit's
/// F_AnyTypeClassToString: `CASE UDINT_TO_INT(AnyTypeClass) OF IBaseLibrary.TypeClass.TYPE_BOOL:
/// …`) converts without a word when its own value fits: only `TYPE_INTERFACE` (16#F000, more than
/// an INT holds) warns, though it makes the enumeration as a whole wider than an INT.
#[test]
fn an_enumeration_label_warns_only_when_its_own_value_does_not_fit() {
    let src = "FUNCTION Named : STRING
VAR_INPUT tc : __SYSTEM.TYPE_CLASS; END_VAR
CASE UDINT_TO_INT(tc) OF
    IBaseLibrary.TypeClass.TYPE_BOOL : Named := 'BOOL';
    IBaseLibrary.TypeClass.TYPE_LTIMEOFDAY : Named := 'LTOD';
    IBaseLibrary.TypeClass.TYPE_INTERFACE : Named := 'INTERFACE';
END_CASE
END_FUNCTION
PROGRAM main
VAR s : STRING; END_VAR
s := Named(__SYSTEM.TYPE_CLASS.TYPE_BOOL);
END_PROGRAM
";
    let compiled = try_build_with(src, None, Dialect::default()).expect("compiles");
    let warnings: Vec<String> = compiled.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with("main.st:6:5: warning: `DINT` converted implicitly"),
        "{warnings:?}"
    );
}

/// `[st] variable_memory_bytes` (compile/memory_limit.rs): an array of 134,217,800 bytes, just
/// above the 128 MiB default, is refused by default with the setting named, compiles under a
/// limit of 256 MiB and runs, its last element written and read. The array is one symbol
/// entry whatever its size (`plcd_core::symbols`): the test costs a few times the array.
#[test]
fn an_array_above_the_default_limit_runs_under_a_raised_one() {
    let src = "VAR_GLOBAL big : ARRAY [1..134217800] OF BYTE; END_VAR
PROGRAM main
VAR n : INT; last : BYTE; END_VAR
big[134217800] := 42;
last := big[134217800];
n := n + 1;
END_PROGRAM
";
    let Err(refused) = try_build(src) else { panic!("above the default limit, yet compiled") };
    assert!(
        refused.contains("the array takes 134217800 bytes of variable memory")
            && refused.contains("`[st] variable_memory_bytes` allows (134217728)"),
        "{refused}"
    );
    let dialect = Dialect { variable_memory_bytes: 256 << 20, ..Dialect::default() };
    let c = try_build_with(src, None, dialect).unwrap_or_else(|e| panic!("{e}"));
    assert!(c.variables.initial.len() > 134_217_800);
    let mut vm = Vm::for_programs(&c.programs);
    vm.set_variables(&c.variables);
    vm.reset_for_run(&plcd_core::device::RetainSet::default(), false);
    let mut state = ExecState::with_frame(c.programs[0].frame_bytes);
    let clock = ManualClock::new(0);
    assert!(matches!(vm.run(&c.programs[0], &mut state, &clock, 1_000_000), Exit::End));
    let last = c.variables.symbols.find("main.last").expect("main.last");
    assert_eq!(vm.read_value(last.at, last.ty.elem()), 42);
    let far = c.variables.symbols.find("big[134217800]").expect("the last element by name");
    assert_eq!(vm.read_value(far.at, far.ty.elem()), 42);
}

/// `[st] variable_memory_bytes` bounds variable memory in all (compile/memory_limit.rs):
/// three arrays of 400,000 bytes, each under a limit of 1 MiB, are refused together at the
/// third (globals: a program's own variables are bounded as one instance), the total named;
/// two of them compile. Small sizes keep the test quick.
#[test]
fn arrays_each_under_the_limit_are_refused_when_their_sum_crosses_it() {
    let declare = |n: usize| {
        let arrays: String =
            (1..=n).map(|i| format!("a{i} : ARRAY [1..100000] OF DINT;\n")).collect();
        format!("VAR_GLOBAL\n{arrays}END_VAR\nPROGRAM main\na1[1] := 1;\nEND_PROGRAM\n")
    };
    let dialect = Dialect { variable_memory_bytes: 1 << 20, ..Dialect::default() };
    let Err(refused) = try_build_with(&declare(3), None, dialect.clone()) else {
        panic!("1,200,000 bytes under a limit of 1 MiB, yet compiled")
    };
    assert!(
        refused.contains("main.st:4:1: error: with this declaration, variable memory takes"),
        "{refused}"
    );
    assert!(refused.contains("`[st] variable_memory_bytes` allows (1048576)"), "{refused}");
    assert_eq!(refused.matches("variable memory takes").count(), 1, "{refused}");
    try_build_with(&declare(2), None, dialect).unwrap_or_else(|e| panic!("{e}"));
}

// ---------------------------------------------------------------------------------------------
// Recursion: refused where the calls prove it, bounded at run time where dispatch decides it.

/// An interface with one method, and a block `B` that implements it and calls it on another
/// instance; `extra` is more of `B` (its body may call `A`) and more POUs.
fn dispatched_cycle(extra_body: &str, extra: &str) -> String {
    format!(
        "INTERFACE I METHOD M END_METHOD END_INTERFACE
         FUNCTION_BLOCK B IMPLEMENTS I
         VAR_INPUT next : I; END_VAR
         METHOD M
             IF next <> 0 THEN next.M(); END_IF
         END_METHOD
         {extra_body}
         END_FUNCTION_BLOCK
         {extra}
         PROGRAM main VAR x, y : B; END_VAR x.next := y; x.M(); x(); END_PROGRAM"
    )
}

#[test]
fn a_cycle_through_an_interface_call_is_no_recursion_error() {
    assert_eq!(errors(&dispatched_cycle("", "")), "");
}

#[test]
fn a_cycle_of_direct_calls_is_refused_beside_a_cycle_through_dispatch() {
    // M calls N through the interface first (a cycle M → N → M through dispatch), then Z,
    // which calls N directly, which calls M directly: the cycle M → Z → N → M is refused
    // whatever order the check meets the calls in.
    let src = "INTERFACE I METHOD N END_METHOD END_INTERFACE
         FUNCTION_BLOCK B IMPLEMENTS I
         VAR_INPUT next : I; END_VAR
         METHOD M
             IF next <> 0 THEN next.N(); END_IF
             Z();
         END_METHOD
         METHOD Z
             N();
         END_METHOD
         METHOD N
             M();
         END_METHOD
         END_FUNCTION_BLOCK
         PROGRAM main VAR x : B; END_VAR x.M(); END_PROGRAM";
    let errors = errors(src);
    assert!(errors.contains("recursive call: `B.M` → `B.Z` → `B.N` → `B.M`"), "{errors}");
    assert_eq!(errors.matches("recursive call").count(), 1, "{errors}");
}
