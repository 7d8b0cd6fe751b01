//! `BOOL`s of variable memory kept at 0 or 1 (`Program::var_bools_canonical`), which native
//! code then reads as the bytes they are: the compiler grants it only to a project that never
//! writes another type over a `BOOL` (no UNION holding one, no reference followed), and the
//! engine rewrites the `BOOL`s after copying bytes in from another project's memory (a
//! replacement engine's retained variables, an online change) or from a retain file, so that
//! a byte of 2 that another program left reads TRUE on native code as on the interpreter.

mod harness;

use plcd::engine::event::Mode;
use plcd::project::Project;
use plcd::vm::retained::SavedVariable;

use harness::engine::{project, with_native, Plc, MS};

const CONFIG: &str = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n";

/// Writes 2 into its retained BOOL through a byte pointer (it reads TRUE).
const WRITES_TWO: &str = "
PROGRAM Main
VAR RETAIN flag : BOOL; END_VAR
VAR p : POINTER TO BYTE; END_VAR
    p := ADR(flag);
    p^ := 2;
END_PROGRAM
";

/// Reads its retained BOOL, as a value and negated.
const READS: &str = "
PROGRAM Main
VAR RETAIN flag : BOOL; END_VAR
VAR seen, inverted : BOOL; END_VAR
    seen := flag;
    inverted := NOT flag;
END_PROGRAM
";

fn st(main: &str, native: bool) -> Project {
    with_native(project(CONFIG, &[("main.st", main)]), native)
}

/// The byte at the variable `name` of `plc`'s project `p`.
fn byte(plc: &Plc, p: &Project, name: &str) -> u8 {
    let at = p.variable(name).unwrap_or_else(|| panic!("no variable {name}")).at;
    plc.engine.vm().vars()[at.offset as usize]
}

/// A scan of `plc` in RUN, then STOP.
fn one_run(plc: &mut Plc) {
    plc.set_mode(Mode::Run);
    plc.run_for(MS);
    plc.set_mode(Mode::Stop);
}

/// The old engine, stopped after its program wrote 2 into `flag`.
fn old_with_two() -> (Plc, Project) {
    let old_p = st(WRITES_TWO, false);
    let mut old = Plc::new(&old_p);
    one_run(&mut old);
    assert_eq!(byte(&old, &old_p, "main.flag"), 2, "the pointer wrote 2");
    (old, old_p)
}

/// `new` runs `READS` on the flag it was given: TRUE, whatever byte it came as.
fn assert_reads_true(new: &mut Plc, new_p: &Project) {
    assert_eq!(byte(new, new_p, "main.flag"), 1, "rewritten to 1");
    one_run(new);
    assert_eq!(byte(new, new_p, "main.seen"), 1);
    assert_eq!(byte(new, new_p, "main.inverted"), 0, "NOT of TRUE");
}

#[test]
fn the_compiler_grants_it_only_where_no_code_writes_another_type_over_a_bool() {
    let canonical = |source: &str| st(source, false).programs[0].var_bools_canonical;
    assert!(canonical(READS));
    assert!(!canonical(WRITES_TWO), "a reference followed");
    let union = "
TYPE U : UNION b : BOOL; n : USINT; END_UNION END_TYPE
PROGRAM Main
VAR u : U; x : BOOL; END_VAR
    u.n := 2;
    x := NOT u.b;
END_PROGRAM
";
    assert!(!canonical(union), "a UNION holding a BOOL");
    assert!(canonical(&union.replace("b : BOOL", "b : SINT").replace("NOT u.b", "u.b = 2")));
    // And native code reads the union's BOOL as the interpreter does: 2 is TRUE.
    for native in [false, true] {
        let p = st(union, native);
        let mut plc = Plc::new(&p);
        one_run(&mut plc);
        assert_eq!(byte(&plc, &p, "main.x"), 0, "native {native}: NOT of TRUE");
    }
}

#[test]
fn a_replacement_engine_rewrites_the_bools_it_inherits() {
    let (old, _) = old_with_two();
    for native in [false, true] {
        let new_p = st(READS, native);
        let mut new = Plc::new(&new_p);
        new.engine.inherit_retained(&old.engine);
        assert_reads_true(&mut new, &new_p);
    }
}

#[test]
fn an_online_change_rewrites_the_bools_it_keeps() {
    for native in [false, true] {
        let (mut old, old_p) = old_with_two();
        let new_p = st(READS, native);
        let mut change = plcd::engine::online::prepare(&old_p, &new_p, &[]).unwrap();
        change.engine.take_over(&mut old.engine, &change.edges).unwrap();
        std::mem::swap(&mut old.engine, &mut change.engine);
        assert_reads_true(&mut old, &new_p);
    }
}

#[test]
fn a_restore_from_a_retain_file_rewrites_the_bools() {
    for native in [false, true] {
        let new_p = st(READS, native);
        let mut new = Plc::new(&new_p);
        let saved = [SavedVariable { name: "main.flag".into(), ty: "BOOL".into(), bytes: vec![2] }];
        let plan = new.engine.restore_retained_variables(&saved);
        assert_eq!(plan.restore.len(), 1, "restored");
        assert_reads_true(&mut new, &new_p);
    }
}
