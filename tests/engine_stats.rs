//! The engine's figures in virtual time: start latency (deadline or edge → first instruction),
//! execution time without preemption, overruns, ignored requests and scan time. Every
//! instruction costs 1 µs, so each figure is known exactly from the programs.

mod harness;

use plcd::device::Address;
use plcd::engine::event::Recorder;
use plcd::engine::Engine;
use plcd::stimulus::{Stimulus, Target};

const US: u64 = 1000;

/// Runs `tasks` (TOML) with programs by file name for `ms` of virtual time.
fn run(tasks: &str, programs: &[(&str, &str)], stimuli: &[Stimulus], ms: u64) -> Engine {
    let text = format!("[sim]\nstep_ns = 1000\n{tasks}");
    let project = harness::engine::project(&text, programs);
    harness::engine::sim(&project, stimuli, &[], ms * 1_000_000).0
}

/// A scan program of `n` instructions.
fn scan_of(n: usize) -> String {
    "MOV 1 D00099\n".repeat(n - 1) + "END\n"
}

fn edge(t_ns: u64, value: i32) -> Stimulus {
    Stimulus { t_ns, target: Target::Device(Address::parse("P0000").unwrap()), value, line: 1 }
}

#[test]
fn start_latency_is_the_di_section_that_holds_the_request() {
    // The scan holds task starts from its first instruction (DI) to EI, its 101st; an edge at
    // 10 µs waits for EI, which ends at 101 µs: 91 µs of start latency. The task, INC INC END,
    // executes 3 µs.
    let scan =
        format!("DI\n{}EI\n{}END\n", "MOV 1 D00099\n".repeat(99), "MOV 1 D00099\n".repeat(98));
    let tasks =
        "[[program]]\nfile = \"scan.il\"\n[[program]]\nfile = \"edge.il\"\ntask = \"edge\"\n\
                 [[task]]\nname = \"edge\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
                 contact = \"P0000\"\nedge = \"rising\"\n";
    let program = "INC D00000\nINC D00001\nEND\n";
    let stimuli = [edge(10_000, 1), edge(20_000, 0)];
    let engine = run(tasks, &[("scan.il", &scan), ("edge.il", program)], &stimuli, 1);
    let stats = engine.task_stats("edge").unwrap();
    assert_eq!(stats.runs, 1);
    let latency = stats.start_latency.summary();
    assert_eq!((latency.min, latency.max), (91 * US, 91 * US), "{latency:?}");
    // The engine knew of the edge at once: all 91 µs are the DI section's, none the driver's.
    let noticed = stats.notice_latency.summary();
    assert_eq!((noticed.count, noticed.max), (1, 0), "{noticed:?}");
    let exec = stats.exec_time.summary();
    assert_eq!((exec.min, exec.max), (3 * US, 3 * US), "INC, INC, END");
    assert_eq!((stats.overruns, stats.ignored), (0, 0));
}

#[test]
fn cycle_latency_counts_from_the_deadline() {
    // A 1 ms cycle task below an io task that takes 300 µs, started by an edge 100 µs before
    // each deadline: each deadline waits 200 µs for the io task.
    let tasks = "[[program]]\nfile = \"scan.il\"\n[[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
                 [[program]]\nfile = \"edge.il\"\ntask = \"edge\"\n\
                 [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n\
                 [[task]]\nname = \"edge\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
                 contact = \"P0000\"\nedge = \"both\"\n";
    let stimuli: Vec<Stimulus> =
        (1..=4).map(|k| edge(k * 1_000_000 - 100_000, (k % 2) as i32)).collect();
    let io_task = scan_of(300);
    let programs = [("scan.il", "END\n"), ("tick.il", "END\n"), ("edge.il", io_task.as_str())];
    let engine = run(tasks, &programs, &stimuli, 5);
    let tick = engine.task_stats("tick").unwrap().start_latency.summary();
    assert_eq!((tick.count, tick.min, tick.max), (4, 200 * US, 200 * US), "{tick:?}");
    let noticed = engine.task_stats("tick").unwrap().notice_latency.summary();
    // Five deadlines in 5 ms, the last at the end of the run (noticed, not yet started); virtual
    // time notices each on time.
    assert_eq!((noticed.count, noticed.max), (5, 0), "{noticed:?}");
    let edge = engine.task_stats("edge").unwrap().start_latency.summary();
    assert_eq!((edge.count, edge.max), (4, 0), "{edge:?}");
}

#[test]
fn io_latency_counts_from_the_edge_and_preemption_bounds_it() {
    let tasks =
        "[[program]]\nfile = \"scan.il\"\n[[program]]\nfile = \"edge.il\"\ntask = \"edge\"\n\
                 [[task]]\nname = \"edge\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
                 contact = \"P0000\"\nedge = \"both\"\n";
    let scan = scan_of(1000);
    let stimuli: Vec<Stimulus> = (1..=8)
        .map(|i| Stimulus {
            t_ns: i * 1_234_567,
            target: Target::Device(Address::parse("P0000").unwrap()),
            value: (i % 2) as i32,
            line: i as u32,
        })
        .collect();
    let engine = run(tasks, &[("scan.il", &scan), ("edge.il", "END\n")], &stimuli, 12);
    let stats = engine.task_stats("edge").unwrap();
    assert_eq!(stats.runs, 8);
    // An edge preempts the 1000-step scan at the next instruction boundary: under 1 µs.
    assert!(stats.start_latency.summary().max < US, "{:?}", stats.start_latency.summary());
}

#[test]
fn overruns_and_ignored_requests_are_counted() {
    // A 1 ms cycle task that takes 1.5 ms: every other deadline finds it still running.
    let tasks = "[[program]]\nfile = \"scan.il\"\n[[program]]\nfile = \"slow.il\"\ntask = \"slow\"\n\
                 [[task]]\nname = \"slow\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n";
    let slow = scan_of(1500);
    let engine = run(tasks, &[("scan.il", "END\n"), ("slow.il", &slow)], &[], 10);
    let stats = engine.task_stats("slow").unwrap();
    // Deadlines at 1..=10 ms: the odd ones start it, and it still runs at each even one.
    assert_eq!((stats.runs, stats.overruns, stats.ignored), (5, 5, 5), "{stats:?}");
    let exec = stats.exec_time.summary();
    assert_eq!((exec.count, exec.max), (4, 1500 * US), "the fifth run goes on past the end");
}

#[test]
fn scan_time_histogram_matches_the_program() {
    let tasks = "[[program]]\nfile = \"scan.il\"\n";
    let engine = run(tasks, &[("scan.il", &scan_of(250))], &[], 5);
    let scan = engine.scan_stats();
    // 20 scans end by 5 ms; the 21st starts at 5 ms as the run ends.
    assert_eq!(scan.count, 21);
    let summary = scan.time.summary();
    assert_eq!(summary.count, 20);
    assert_eq!((summary.min, summary.max), (250 * US, 250 * US));
    assert_eq!((scan.min_ns, scan.max_ns, scan.last_ns), (250 * US, 250 * US, 250 * US));
}

#[test]
fn a_late_poll_counts_from_the_deadline_not_from_the_poll() {
    // A driver that notices a deadline late (the real-time driver's thread woke late): the
    // latency is measured from the deadline.
    let text =
        "[[program]]\nfile = \"scan.il\"\n[[program]]\nfile = \"tick.il\"\ntask = \"tick\"\n\
                [[task]]\nname = \"tick\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\n\
                interval_ms = 1\n[plc]\nscan_period_ms = 100\n";
    let project = harness::engine::project(text, &[("scan.il", "END\n"), ("tick.il", "END\n")]);
    let mut engine = Engine::new::<plcd::device::Address>(&project, &[]);
    let mut io = plcd::io::simulated::SimulatedIo::default();
    let mut sink = Recorder::default();
    let clock = plcd::vm::ManualClock::new(0);
    engine.set_mode(plcd::engine::event::Mode::Run, 0, &mut io, &mut sink);
    engine.run(&clock, &mut io, &mut sink, 100);
    clock.set(1_050_000);
    engine.poll_time(1_050_000, &mut io, &mut sink);
    engine.run(&clock, &mut io, &mut sink, 100);
    let latency = engine.task_stats("tick").unwrap().start_latency.summary();
    assert_eq!((latency.count, latency.max), (1, 50_000), "{latency:?}");
    assert_eq!(engine.cycle_deadlines().collect::<Vec<_>>(), [(0, 2_000_000, 1_000_000)]);
}

#[test]
fn a_task_no_program_runs_in_runs_empty() {
    // A cycle task of 1 ms that no [[program]] names (a CONFIGURATION could name it): it runs
    // nothing, ends where it starts, executes 0 µs, and delays nothing (it once panicked the
    // engine, which looked for its first program). The scan (MOV, END: 2 µs) runs every 1 ms.
    let tasks = "[plc]\nscan_period_ms = 1\n[[program]]\nfile = \"scan.il\"\n\
                 [[task]]\nname = \"idle\"\nkind = \"cycle\"\nnumber = 0\npriority = 2\n\
                 interval_ms = 1\n";
    let engine = run(tasks, &[("scan.il", &scan_of(2))], &[], 10);
    let stats = engine.task_stats("idle").unwrap();
    assert_eq!(stats.runs, 9, "a run each 1 ms deadline of the 10 ms run but its start");
    let exec = stats.exec_time.summary();
    assert_eq!((exec.min, exec.max), (0, 0));
    assert_eq!((stats.overruns, stats.ignored), (0, 0));
}
