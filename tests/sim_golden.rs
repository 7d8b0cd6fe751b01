//! Golden traces: each directory under tests/sim holds a project (`plcd.toml` and programs),
//! the arguments of its run (`args`, relative to the directory), usually an inputs CSV, and
//! `expected.trace`, written by hand from the manuals (docs/EXECUTION.md says how). `plcd sim`
//! must produce that trace byte for byte.

mod harness;

use std::fs;
use std::path::Path;
use std::process::Command;

use harness::tempdir::TempDir;

/// `plcd sim` in `dir` with the scenario's `args`, or with `args` given here instead.
fn sim(dir: &Path, args: Option<&[&str]>) -> (Option<i32>, Vec<u8>, String) {
    let from_file = fs::read_to_string(dir.join("args")).unwrap();
    let args: Vec<&str> =
        args.map_or_else(|| from_file.split_whitespace().collect(), <[_]>::to_vec);
    let output = harness::runner::command(env!("CARGO_BIN_EXE_plcd"))
        .current_dir(dir)
        .args(["sim", "--config", "plcd.toml", "--trace", "-"])
        .args(args)
        .output()
        .unwrap();
    (output.status.code(), output.stdout, String::from_utf8_lossy(&output.stderr).into_owned())
}

#[test]
fn golden_traces() {
    let mut failures = Vec::new();
    let mut count = 0;
    let mut dirs: Vec<_> = fs::read_dir("tests/sim").unwrap().map(|e| e.unwrap().path()).collect();
    dirs.sort();
    for dir in dirs.iter().filter(|d| d.join("expected.trace").exists()) {
        count += 1;
        let expected = fs::read_to_string(dir.join("expected.trace")).unwrap();
        let (code, stdout, stderr) = sim(dir, None);
        let actual = String::from_utf8_lossy(&stdout);
        if code != Some(0) || actual != expected {
            failures.push(format!(
                "{} (exit {code:?}, stderr: {stderr})\n--- expected\n{expected}--- actual\n{actual}",
                dir.display()
            ));
        }
    }
    assert!(count >= 1, "no golden traces found");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn identical_inputs_give_identical_bytes() {
    let dir = Path::new("tests/sim/xgb_example");
    let args: &[&str] = &["--for", "1s", "--inputs", "inputs.csv"];
    let first = sim(dir, Some(args));
    let second = sim(dir, Some(args));
    assert_eq!(first.0, Some(0));
    assert!(first.1.len() > 1000);
    assert!(first.1 == second.1, "two runs differ");
}

fn plcd(args: &[&str]) -> std::process::Output {
    harness::runner::command(env!("CARGO_BIN_EXE_plcd")).args(args).output().unwrap()
}

/// The README's example: `plcd sim` of `etc/plcd.toml` for 8 s with `etc/stimulus.csv`, and
/// `output` (`--timeline`, `--trace -`); its standard output, once it exited 0.
fn example(output: &str) -> String {
    let args = ["sim", "--config", "etc/plcd.toml", "--for", "8s", "--inputs", "etc/stimulus.csv"];
    let out = plcd(&[&args[..], &output.split_whitespace().collect::<Vec<_>>()].concat());
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn the_readme_run_command_draws_the_example_project() {
    let chart = example("--timeline");
    for task in ["scan", "init", "blink_250ms", "tank_10ms", "count_p0000", "batch_full"] {
        let row = chart.lines().find(|l| l.starts_with(task)).unwrap_or_else(|| panic!("{chart}"));
        assert!(row.contains('#'), "{task} never ran:\n{chart}");
    }
}

#[test]
fn every_output_of_the_example_project_moves() {
    // What the README promises of it: the blink lamp, the conveyor motor, the DUTY heartbeat
    // and the batch lamp each change within the 8 s of the stimulus; and the tank's level loop
    // (level.st on tank_model.st): the low alarm on the empty tank, the pump once the set point
    // goes to 85 %, the high alarm once it goes to 95 %, each alarm clearing again.
    let trace = example("--trace -");
    let set = |output: &str, value: u8| {
        let event = format!("\"ev\":\"set\",\"dev\":\"{output}\",\"value\":{value}");
        trace.find(&event).unwrap_or_else(|| panic!("{output} never goes to {value}"))
    };
    for output in ["P0040", "P0041", "P0042", "P0043", "P0044", "P0045", "P0046"] {
        set(output, 1);
    }
    assert!(set("P0045", 0) > set("P0045", 1), "the low alarm clears as the tank fills");
    assert!(set("P0044", 0) > set("P0044", 1), "the high alarm closes the valve and clears");
}

#[test]
fn the_level_loop_holds_its_set_point() {
    // The PI loop of level.st on the tank model: with the set point at 50 % (the stimulus
    // sets it at 100 ms), the level settles within 2 % of it, and the pump stays off (it
    // starts at 70 %).
    let args =
        ["sim", "--config", "etc/plcd.toml", "--for", "2.4s", "--inputs", "etc/stimulus.csv"];
    let out = plcd(&[&args[..], &["--trace", "-", "--watch", "level.level_pct,P0046"]].concat());
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = String::from_utf8_lossy(&out.stdout);
    let mut last = None;
    for line in trace.lines() {
        let event: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_ne!(event["dev"], "P0046", "the pump started: {line}");
        if event["dev"] == "level.level_pct" {
            last = event["value"].as_f64();
        }
    }
    let level = last.expect("the level moves");
    assert!((48.0..=52.0).contains(&level), "level {level} % after 2.4 s");
}

#[test]
fn bad_inputs_exit_1_and_bad_usage_exit_2() {
    let dir = TempDir::new("sim-bad-inputs");
    let csv = dir.write("bad.csv", "1ms, P0000, 1\nsoon, P0000, 0\n");
    let out = plcd(&[
        "sim",
        "--config",
        "etc/plcd.toml",
        "--for",
        "1s",
        "--inputs",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("bad.csv:2:1: error"), "{stderr}");
    let out = plcd(&["sim", "--config", "etc/plcd.toml", "--for", "10 parsecs"]);
    assert_eq!(out.status.code(), Some(2));
    let out = plcd(&["sim", "--config", "tests/golden/project/plcd.toml", "--for", "1s"]);
    assert_eq!(out.status.code(), Some(1));
}
