//! `plcd bench latency|edge`: the real-time driver measured by itself. These tests check what
//! the commands report and that they clean up, never how fast anything is (figures belong to
//! BENCHMARKS.md).

mod harness;

use std::process::Output;

use harness::tempdir::TempDir;

/// `plcd ARGS` with `tmp` as its temp directory, where a bench writes its generated project.
fn plcd(tmp: &TempDir, args: &[&str]) -> Output {
    harness::runner::command(env!("CARGO_BIN_EXE_plcd"))
        .args(args)
        .env("TMPDIR", tmp.path())
        .output()
        .expect("plcd runs")
}

/// The checks every report passes: quantiles in order, the histogram adds up.
fn check_distribution(d: &serde_json::Value, what: &str) -> u64 {
    let n = |k: &str| d[k].as_u64().unwrap_or_else(|| panic!("{what}.{k} in {d}"));
    let samples = n("samples");
    assert!(samples > 0, "{what}: no samples");
    assert!(n("min_ns") <= n("p50_ns"), "{what}");
    assert!(n("p50_ns") <= n("p99_ns") && n("p99_ns") <= n("p999_ns"), "{what}");
    assert!(n("p999_ns") <= n("max_ns"), "{what}");
    let counted: u64 =
        d["histogram"].as_array().unwrap().iter().map(|b| b[1].as_u64().unwrap()).sum();
    assert_eq!(counted, samples, "{what}: the histogram holds every sample");
    samples
}

#[test]
fn latency_reports_one_start_per_deadline_and_cleans_up() {
    let tmp = TempDir::new("bench-latency");
    let out = plcd(&tmp, &["bench", "latency", "--interval", "2ms", "--cycles", "25", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(report["bench"], "cycle");
    assert_eq!(report["interval_ns"], 2_000_000);
    let samples = check_distribution(&report["start_latency"], "start_latency");
    // It runs until 25 deadlines have passed (a deadline that finds the task running is an
    // overrun); how far past the 25th it stops depends on the machine's load.
    let overruns = report["overruns"].as_u64().unwrap();
    assert!(samples + overruns >= 25, "{samples} + {overruns} for 25 deadlines");
    // Every start was noticed first; one deadline may be noticed and not started when it stops.
    let noticed = check_distribution(&report["notice_latency"], "notice_latency");
    assert!((samples..=samples + 1).contains(&noticed), "{noticed} noticed, {samples} started");
    check_distribution(&report["scan_time"], "scan_time");
    assert!(["fifo", "other"].contains(&report["scheduling"]["policy"].as_str().unwrap()));
    assert_eq!(tmp.entries(), Vec::<String>::new(), "the generated project is removed");
}

#[test]
fn edge_reports_the_io_task_and_the_scan_length() {
    let tmp = TempDir::new("bench-edge");
    let args = ["bench", "edge", "--steps", "400", "--edges", "20", "--interval", "1ms", "--json"];
    let out = plcd(&tmp, &args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(report["bench"], "edge");
    assert_eq!(report["scan_steps"], 400, "133 rungs of three and END");
    let samples = check_distribution(&report["start_latency"], "start_latency");
    assert!(samples >= 20, "{samples} edges for 20");
    let noticed = check_distribution(&report["notice_latency"], "notice_latency");
    assert!((samples..=samples + 1).contains(&noticed), "{noticed} noticed, {samples} started");
    assert_eq!(tmp.entries(), Vec::<String>::new(), "the generated project is removed");
}

#[test]
fn text_output_and_usage_errors() {
    let tmp = TempDir::new("bench-usage");
    let out = plcd(&tmp, &["bench", "latency", "--cycles", "3"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with("cycle task start latency (deadline → first instruction)\n"),
        "{text}"
    );
    for (args, says) in [
        (&["bench", "latency", "--interval", "1500us"][..], "whole milliseconds"),
        (&["bench", "latency", "--cycles", "0"][..], "above 0"),
        (&["bench", "latency", "--priority", "99"][..], "priority 99: expected 1..=97"),
        (&["bench", "edge", "--interval", "5us"][..], "at least 10 µs"),
    ] {
        let out = plcd(&tmp, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
