//! `set` events of watched devices of every kind — P and M bits, signed D words, timer values
//! and contacts, counter values, SM bits, flag words — at every output refresh (END) and when an
//! interrupt task ends, with the value `Memory::read` gives: the engine resolves each watched
//! address once and compares the resolved device (benches/scaling.rs: the comparison runs for
//! every output bit at every END and task end).

mod harness;

use plcd::device::Address;
use plcd::engine::event::Event;

const CONFIG: &str = r#"
[sim]
step_ns = 1000
[[program]]
file = "scan.il"
[[program]]
file = "tick.il"
task = "tick"
[[task]]
name = "tick"
kind = "cycle"
number = 0
priority = 3
interval_ms = 1
"#;

/// 10 steps, so 10 µs a scan: D00011 counts down from -1, M0005 toggles, T1500 (1 ms base)
/// counts, and C0000 counts the timer's contact.
const SCAN: &str = "LOAD SM400\nSUB D00011 1 D00011\nLOAD NOT M0005\nOUT M0005\n\
                    LOAD NOT T1500\nTON T1500 3\nLOAD T1500\nCTU C0000 100\nOUT P0040\nEND\n";
/// 2 steps every 1 ms: D00020 counts the task's runs.
const TICK: &str = "INC D00020\nEND\n";

const WATCH: [&str; 8] = ["P0040", "M0005", "D00011", "T1500", "T1500", "C0000", "SM400", "D00020"];

#[test]
fn watched_devices_report_their_values_at_end_and_task_end() {
    let project = harness::engine::project(CONFIG, &[("scan.il", SCAN), ("tick.il", TICK)]);
    // T1500 twice: as a word (its current value); "T1500" is never a bit address.
    let watch: Vec<Address> = WATCH.iter().map(|a| Address::parse(a).unwrap()).collect();
    let (engine, recorder) = harness::engine::sim(&project, &[], &watch, 5_000_000);

    let sets = |index: u16| -> Vec<(u64, i32)> {
        recorder
            .0
            .iter()
            .filter_map(|&(t, e)| match e {
                Event::Set { watch, value } if watch == index => Some((t, value)),
                _ => None,
            })
            .collect()
    };
    let ends: Vec<u64> = recorder
        .0
        .iter()
        .filter_map(|&(t, e)| matches!(e, Event::ScanEnd { .. }).then_some(t))
        .collect();

    let task_ends: Vec<u64> = recorder
        .0
        .iter()
        .filter_map(|&(t, e)| matches!(e, Event::TaskEnd { .. }).then_some(t))
        .collect();
    // A signed word: -1, -2, … once a scan, seen at its END (or at the end of the cycle task
    // that preempted the scan after the SUB).
    let d11 = sets(2);
    assert!(d11.len() >= 400, "{}", d11.len());
    for (k, &(t, value)) in d11.iter().enumerate() {
        assert_eq!(value, -(k as i32) - 1);
        assert!(ends.contains(&t) || task_ends.contains(&t), "D00011 at {t}");
    }
    assert_eq!(d11.len(), ends.len());
    // A bit toggled every scan.
    let m5 = sets(1);
    assert_eq!(m5.len(), d11.len());
    assert!(m5.iter().enumerate().all(|(k, &(_, v))| v == i32::from(k % 2 == 0)));
    // Timer values as words: they count up to 3 in 1 ms steps and restart at 0 (TON on its
    // own contact's negation), each count reported once; the watch listed twice reports twice.
    let t1500 = sets(3);
    assert_eq!(t1500, sets(4));
    assert!(t1500.iter().all(|&(_, v)| (0..=3).contains(&v)), "{t1500:?}");
    assert!(t1500.windows(2).all(|w| w[0].1 != w[1].1), "{t1500:?}");
    // The counter counts the timer's completions, P0040 follows the timer's contact.
    let c0 = sets(5);
    assert!(c0.iter().enumerate().all(|(k, &(_, v))| v == k as i32 + 1), "{c0:?}");
    assert!(!sets(0).is_empty());
    // SM400 is ON from the first scan on: one change.
    assert_eq!(sets(6).len(), 1);
    assert_eq!(sets(6)[0].1, 1);
    // D00020 changes when the cycle task ends (mid-scan), once a millisecond.
    let d20 = sets(7);
    assert_eq!(d20.iter().map(|&(t, _)| t).collect::<Vec<_>>(), task_ends);
    assert!(d20.iter().enumerate().all(|(k, &(_, v))| v == k as i32 + 1));
    assert_eq!(d20.len(), 4, "cycle runs at 1, 2, 3 and 4 ms");

    // The last reports are what memory holds: nothing wrote SM400 or D00020 since.
    let mem = &engine.vm().mem;
    assert_eq!(sets(6).last().unwrap().1, mem.read(&watch[6]));
    assert_eq!(d20.last().unwrap().1, mem.read(&watch[7]));
}
