//! Every internal-device condition and every I/O edge kind, counted over a run. The scan
//! program drives M0000 and D00000 by its own scan count, so the samples at END are known:
//!
//! | END of scan | 1 | 2 | 3 | 4 | 5 |
//! |---|---|---|---|---|---|
//! | M0000 | 0 | 1 | 1 | 0 | 0 |
//! | D00000 | 0 | 5 | 5 | 6 | 6 |
//!
//! (The first END compares with the sample taken at RUN start: M0000 = 0.)

mod harness;

use plcd::device::Address;
use plcd::engine::event::Event;
use plcd::stimulus::{Stimulus, Target};

const SCAN: &str = "INC D00100\nLOAD= D00100 2\nOR= D00100 3\nOUT M0000\n\
                    LOAD>= D00100 2\nMOV 5 D00000\nLOAD>= D00100 4\nMOV 6 D00000\nEND\n";

/// Runs a project of `tasks` (TOML of `[[task]]` entries, each with a program `END`) and
/// returns, per task name, how often it started before scan 6 began.
fn starts(tasks: &[(&str, &str)], stimuli: &[Stimulus]) -> Vec<(String, usize)> {
    let mut text = String::from("[sim]\nstep_ns = 1000\n[[program]]\nfile = \"scan.il\"\n");
    for (number, (name, condition)) in tasks.iter().enumerate() {
        text += &format!(
            "[[program]]\nfile = \"{name}.il\"\ntask = \"{name}\"\n\
             [[task]]\nname = \"{name}\"\npriority = 4\n{condition}\n",
        );
        let kind_number = if condition.contains("\"io\"") { 8 } else { 16 };
        text += &format!("number = {}\n", kind_number + number);
    }
    let project = harness::engine::project_from(harness::engine::config(&text), |file| {
        if file == "scan.il" { SCAN } else { "END\n" }.to_string()
    });
    let (engine, recorder) = harness::engine::sim(&project, stimuli, &[], 1_000_000);
    let names = engine.task_names();
    let sixth = recorder.0.iter().position(|(_, e)| *e == Event::ScanStart { n: 6 }).unwrap();
    tasks
        .iter()
        .map(|(name, _)| {
            let id = names.iter().position(|n| n == name).unwrap() as u16;
            let count = recorder.0[..sixth]
                .iter()
                .filter(|(_, e)| *e == Event::TaskStart { task: id })
                .count();
            (name.to_string(), count)
        })
        .collect()
}

fn expect(actual: Vec<(String, usize)>, expected: &[(&str, usize)]) {
    let expected: Vec<(String, usize)> =
        expected.iter().map(|(n, c)| (n.to_string(), *c)).collect();
    assert_eq!(actual, expected);
}

#[test]
fn bit_conditions() {
    let bit = |c: &str| format!("kind = \"device\"\ndevice = \"M0000\"\ncondition = \"{c}\"");
    let tasks = [
        ("rising", bit("rising")),
        ("falling", bit("falling")),
        ("transition", bit("transition")),
        ("on", bit("on")),
        ("off", bit("off")),
    ];
    let tasks: Vec<(&str, &str)> = tasks.iter().map(|(n, c)| (*n, c.as_str())).collect();
    // rising: END 2; falling: END 4; transition: 2, 4; on: 2, 3; off: 1, 4, 5.
    expect(
        starts(&tasks, &[]),
        &[("rising", 1), ("falling", 1), ("transition", 2), ("on", 2), ("off", 3)],
    );
}

#[test]
fn word_conditions() {
    let word =
        |c: &str| format!("kind = \"device\"\ndevice = \"D00000\"\ncondition = \"{c}\"\nvalue = 5");
    let tasks = [("gt", word(">")), ("ge", word(">=")), ("lt", word("<")), ("le", word("<="))];
    let tasks: Vec<(&str, &str)> = tasks.iter().map(|(n, c)| (*n, c.as_str())).collect();
    // > 5: ENDs 4, 5; >= 5: 2..=5; < 5: 1; <= 5: 1, 2, 3.
    expect(starts(&tasks, &[]), &[("gt", 2), ("ge", 4), ("lt", 1), ("le", 3)]);
}

#[test]
fn io_edges() {
    let io = |contact: &str, edge: &str| {
        format!("kind = \"io\"\ncontact = \"{contact}\"\nedge = \"{edge}\"")
    };
    let tasks = [
        ("up", io("P0001", "rising")),
        ("down", io("P0001", "falling")),
        ("both", io("P0002", "both")),
    ];
    let tasks: Vec<(&str, &str)> = tasks.iter().map(|(n, c)| (*n, c.as_str())).collect();
    let change = |t_ns, device: &str, value| Stimulus {
        t_ns,
        target: Target::Device(Address::parse(device).unwrap()),
        value,
        line: 0,
    };
    let stimuli = [
        change(1_000, "P0001", 1),
        change(1_000, "P0002", 1),
        change(30_000, "P0001", 0),
        change(30_000, "P0002", 0),
    ];
    expect(starts(&tasks, &stimuli), &[("up", 1), ("down", 1), ("both", 2)]);
}
