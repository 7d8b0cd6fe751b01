//! Any text either assembles or yields diagnostics, never a panic; and any program that
//! assembles runs (within a step budget) without a panic.
mod harness;

use proptest::prelude::*;

use plcd::vm::{ExecState, Exit, ManualClock, Vm};

use harness::vm::try_assemble as assemble;

const MNEMONICS: &[&str] = &[
    "LOAD",
    "LOAD NOT",
    "LOADP",
    "LOADN",
    "AND",
    "AND NOT",
    "ANDP",
    "ANDN",
    "OR",
    "OR NOT",
    "ORP",
    "ORN",
    "AND LOAD",
    "OR LOAD",
    "MPUSH",
    "MLOAD",
    "MPOP",
    "NOT",
    "LOAD=",
    "AND<>",
    "OR>",
    "LOAD>=",
    "AND<",
    "OR<=",
    "OUT",
    "OUT NOT",
    "OUTP",
    "OUTN",
    "SET",
    "RST",
    "FF",
    "TON",
    "TOFF",
    "TMR",
    "TMON",
    "TRTG",
    "CTU",
    "CTD",
    "CTR",
    "CTUD",
    "MOV",
    "MOVP",
    "ADD",
    "SUBP",
    "MUL",
    "DIV",
    "INC",
    "DECP",
    "CALL",
    "SBRT",
    "RET",
    "JMP",
    "LABEL",
    "FOR",
    "NEXT",
    "BREAK",
    "DI",
    "EI",
    "WDT",
    "INIT_DONE",
    "STOP",
    "END",
    "NOP",
    "IORF",
    "DUTY",
    "BOGUS",
];
const OPERANDS: &[&str] = &[
    "P0000",
    "P0041",
    "M0000",
    "M0001",
    "K0005",
    "D00000",
    "D00001",
    "D00002.3",
    "T0000",
    "T1500",
    "C0000",
    "C0001",
    "SM420",
    "SM8331",
    "SM400",
    "SD8330",
    "_ON",
    "_T1S",
    "_SCAN_CUR",
    "0",
    "1",
    "2",
    "3",
    "-1",
    "32767",
    "h00FF",
    "70000",
    "X",
    "",
    "P128",
    "D99999",
];

fn line() -> impl Strategy<Value = String> {
    (prop::sample::select(MNEMONICS), prop::collection::vec(prop::sample::select(OPERANDS), 0..5))
        .prop_map(|(m, ops)| format!("{m} {}", ops.join(" ")))
}

fn program() -> impl Strategy<Value = String> {
    prop::collection::vec(line(), 0..40).prop_map(|lines| lines.join("\n"))
}

fn run_bounded(program: &plcd::lang::Program) {
    let mut vm = Vm::for_programs([program]);
    let mut state = ExecState::new();
    let clock = ManualClock::new(0);
    for scan in 0..3u64 {
        clock.set(scan * 7_000_000);
        vm.begin_scan(scan == 0, clock.get());
        state.restart();
        let mut budget = 20_000u64;
        while budget > 0 {
            let before = vm.steps();
            match vm.run(program, &mut state, &clock, budget.min(97)) {
                Exit::End => break,
                _ => budget -= (vm.steps() - before).max(1),
            }
        }
        vm.end_scan();
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,300}") {
        if let Err(diags) = assemble(&text) {
            prop_assert!(!diags.is_empty());
        }
    }

    #[test]
    fn instruction_soup_assembles_or_explains(text in program()) {
        match assemble(&text) {
            Ok(program) => run_bounded(&program),
            Err(diags) => {
                prop_assert!(!diags.is_empty());
                for d in diags.iter() {
                    prop_assert!(d.line >= 1 && d.col >= 1, "{d}");
                    prop_assert!(!d.message.is_empty());
                }
            }
        }
    }

    #[test]
    fn well_formed_soup_runs(body in prop::collection::vec(line(), 0..30)) {
        // Wrapping soup in a frame that often assembles: the lines that fail are dropped.
        let mut kept: Vec<String> = Vec::new();
        for l in body {
            let mut candidate = kept.clone();
            candidate.push(l.clone());
            candidate.push("END".into());
            if assemble(&candidate.join("\n")).is_ok() {
                kept.push(l);
            }
        }
        kept.push("END".into());
        let program = assemble(&kept.join("\n")).expect("kept lines assemble");
        run_bounded(&program);
    }
}
