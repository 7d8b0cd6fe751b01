//! Subroutines, jumps, loops, system requests, step counting, and resumption between any two
//! instructions.
mod harness;
use harness::vm::{assemble, context, Rig};
use plcd::lang::ops::SystemRequest;
use plcd::vm::{ExecState, Exit, ManualClock, Vm};

#[test]
fn call_runs_the_subroutine_and_returns_into_the_rung() {
    let mut rig = Rig::new(
        "LOAD P0000\nCALL 1\nOUT M0000\nLOAD P0001\nCALL 2\nEND\n\
         SBRT 1\nINC D00000\nCALL 2\nRET\n\
         SBRT 2\nLOAD NOT M0001\nOUT M0002\nINC D00001\nRET",
    );
    rig.scan();
    assert_eq!((rig.get("D00000"), rig.get("D00001"), rig.get("M0000")), (0, 0, 0));
    rig.set("P0000", 1).scan();
    assert_eq!((rig.get("D00000"), rig.get("D00001"), rig.get("M0000")), (1, 1, 1));
    assert_eq!(rig.get("M0002"), 1, "the subroutine's rungs start ON");
    rig.set("P0001", 1).scan();
    assert_eq!((rig.get("D00000"), rig.get("D00001")), (2, 3));
}

#[test]
fn call_preserves_the_callers_stacks() {
    let mut rig = Rig::new(
        "LOAD P0000\nMPUSH\nAND P0001\nCALL 1\nOUT M0001\nMPOP\nAND NOT P0001\nOUT M0000\nEND\n\
         SBRT 1\nLOAD M0100\nMPUSH\nOUT M0101\nMPOP\nLOAD M0100\nLOAD M0100\nOR LOAD\nOUT M0102\nRET",
    );
    rig.set("P0000", 1).scan();
    assert_eq!((rig.get("M0000"), rig.get("M0001")), (1, 0));
    rig.set("P0001", 1).scan();
    assert_eq!(rig.get("M0102"), 0, "the subroutine's last rung is OFF");
    assert_eq!((rig.get("M0000"), rig.get("M0001")), (0, 1), "the caller's rung is restored");
}

#[test]
fn runaway_recursion_stops_at_the_call_depth_limit() {
    let mut rig = Rig::new("CALL 1\nOUT M0000\nEND\nSBRT 1\nINC D00000\nCALL 1\nRET");
    rig.scan();
    assert_eq!(rig.exits, vec![Exit::OperationError { code: 0x4210, pc: 5 }]);
    assert_eq!(rig.get("D00000"), 16);
    assert_eq!(rig.get("_ERR_CODE") as u16, 0x4210);
    assert_eq!(rig.get("M0000"), 1, "execution unwinds and goes on");
}

#[test]
fn jumps_skip_and_loop() {
    let mut rig = Rig::new(
        "LOAD P0000\nJMP 1\nLOAD _ON\nOUT M0000\nLABEL 1\nOUT M0001\n\
         LABEL 2\nINC D00000\nLOAD< D00000 5\nJMP 2\nEND",
    );
    rig.scan();
    assert_eq!((rig.get("M0000"), rig.get("M0001"), rig.get("D00000")), (1, 1, 5));
    rig.set("P0000", 1).set("D00000", 0).scan();
    assert_eq!((rig.get("M0000"), rig.get("M0001")), (1, 1), "M0000 keeps its value when skipped");
    rig.set("M0000", 0).scan();
    assert_eq!(rig.get("M0000"), 0);
}

#[test]
fn for_next_break() {
    let mut rig = Rig::new(
        "FOR 4\nFOR D00010\nINC D00000\nNEXT\nINC D00001\nNEXT\n\
         FOR 100\nINC D00002\nLOAD>= D00002 7\nBREAK\nNEXT\n\
         FOR 0\nINC D00003\nNEXT\n\
         LOAD P0000\nFOR 3\nINC D00004\nNEXT\nEND",
    );
    rig.set("D00010", 3).scan();
    assert_eq!(rig.get("D00000"), 12);
    assert_eq!(rig.get("D00001"), 4);
    assert_eq!(rig.get("D00002"), 7);
    assert_eq!(rig.get("D00003"), 0);
    assert_eq!(rig.get("D00004"), 0, "a FOR whose rung is OFF skips its loop");
    rig.set("P0000", 1).scan();
    assert_eq!(rig.get("D00004"), 3);
}

#[test]
fn calls_inside_loops() {
    let mut rig = Rig::new("FOR 5\nCALL 7\nNEXT\nEND\nSBRT 7\nFOR 2\nINC D00000\nNEXT\nRET");
    rig.scan();
    assert_eq!(rig.get("D00000"), 10);
}

#[test]
fn system_instructions_surface_when_their_rung_is_on() {
    let mut rig =
        Rig::new("DI\nDI 3\nLOAD P0000\nEI 3\nEI\nWDT\nSTOP\nIORF\nLOAD M0000\nSTOP\nEND");
    rig.scan();
    assert_eq!(
        rig.exits,
        vec![
            Exit::System(SystemRequest::DisableTasks(None)),
            Exit::System(SystemRequest::DisableTasks(Some(3))),
        ]
    );
    rig.set("P0000", 1).scan();
    assert_eq!(rig.exits.len(), 7);
    assert_eq!(
        rig.exits[2..6],
        [
            Exit::System(SystemRequest::EnableTasks(Some(3))),
            Exit::System(SystemRequest::EnableTasks(None)),
            Exit::System(SystemRequest::ResetWatchdog),
            Exit::System(SystemRequest::Stop),
        ]
    );
    assert_eq!(rig.exits[6], Exit::System(SystemRequest::RefreshIo));
}

#[test]
fn init_done_surfaces_in_init_programs() {
    let program = plcd::lang::assemble(
        "init",
        std::path::Path::new("init.il"),
        "MOV 1 D00000\nINIT_DONE\nEND",
        &context(true),
    )
    .unwrap();
    let mut vm = Vm::for_programs([&program]);
    let mut state = ExecState::new();
    let clock = ManualClock::new(0);
    assert_eq!(vm.run(&program, &mut state, &clock, 100), Exit::System(SystemRequest::InitDone));
    assert_eq!(vm.run(&program, &mut state, &clock, 100), Exit::End);
    assert!(state.is_finished());
}

#[test]
fn steps_are_counted_per_executed_instruction() {
    let program = assemble("FOR 3\nNOP\nNEXT\nLOAD P0000\nJMP 1\nNOP\nLABEL 1\nEND");
    let mut vm = Vm::for_programs([&program]);
    let mut state = ExecState::new();
    assert_eq!(vm.run(&program, &mut state, &ManualClock::new(0), u64::MAX), Exit::End);
    // FOR, 3 x (NOP, NEXT), LOAD, JMP (not taken), NOP, LABEL, END
    assert_eq!(vm.steps(), 1 + 6 + 1 + 1 + 1 + 1 + 1);
}

#[test]
fn the_budget_stops_between_instructions() {
    let program = assemble("INC D00000\nINC D00000\nINC D00000\nEND");
    let mut vm = Vm::for_programs([&program]);
    let mut state = ExecState::new();
    let clock = ManualClock::new(0);
    assert_eq!(vm.run(&program, &mut state, &clock, 2), Exit::Budget);
    assert_eq!((state.pc(), vm.steps()), (2, 2));
    assert_eq!(vm.mem.read(&plcd::device::Address::parse("D00000").unwrap()), 2);
    assert_eq!(vm.run(&program, &mut state, &clock, 0), Exit::Budget);
    assert_eq!(vm.run(&program, &mut state, &clock, 5), Exit::End);
    assert_eq!(vm.steps(), 4);
}

/// A program touching every kind of control state; run whole, and run one to four
/// instructions at a time with another program interleaved (as a preempting task would),
/// it must leave memory exactly the same.
#[test]
fn resuming_at_any_instruction_boundary_changes_nothing() {
    let source = "LOAD P0000\nMPUSH\nAND P0001\nLOAD M0000\nOR LOAD\nOUT M0001\nMPOP\nOUTP M0002\n\
                  FOR 3\nCALL 1\nLOAD>= D00000 4\nBREAK\nNEXT\n\
                  LOAD P0001\nTON T1500 2\nCTU C0000 2\nLOADP P0001\nFF M0003\nEND\n\
                  SBRT 1\nFOR 2\nINC D00000\nNEXT\nLOAD D00000.1\nMPUSH\nOUT M0004\nMPOP\nRET";
    let other = assemble("INC D00100\nLOAD M0200\nOUT M0201\nEND");
    let program = assemble(source);
    let run = |chunk: u64| -> Vec<u16> {
        let mut vm = Vm::for_programs([&program]);
        let mut vm_other_state = ExecState::new();
        let clock = ManualClock::new(0);
        let mut state = ExecState::new();
        for scan in 0..6u64 {
            clock.set(scan * 1_000_000);
            vm.mem.write(&plcd::device::Address::parse("P0000").unwrap(), (scan % 2) as i32);
            vm.mem.write(&plcd::device::Address::parse("P0001").unwrap(), (scan / 2 % 2) as i32);
            vm.begin_scan(scan == 0, clock.get());
            state.restart();
            loop {
                match vm.run(&program, &mut state, &clock, chunk) {
                    Exit::End => break,
                    Exit::Budget => {
                        // The interleaved program shares no devices with the first.
                        vm_other_state.restart();
                        while vm.run(&other, &mut vm_other_state, &clock, u64::MAX) != Exit::End {}
                    }
                    other => panic!("unexpected {other:?}"),
                }
            }
            vm.end_scan();
        }
        let d100 = plcd::device::Address::parse("D00100").unwrap().as_word().unwrap().0 as usize;
        let mut words = vm.mem.words().to_vec();
        words[d100] = 0;
        words
    };
    let whole = run(u64::MAX);
    for chunk in 1..=4 {
        assert!(run(chunk) == whole, "chunk {chunk} differs");
    }
}
