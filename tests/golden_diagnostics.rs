//! Golden diagnostics: what `plcd check` and `plcd sim --inputs` print for a broken project,
//! byte for byte.
//!
//! - Every error at once: each `.il` under `tests/golden/lang` produces exactly the lines of its
//!   `.expected` file, and `plcd check` on `tests/golden/config`, `tests/golden/remote` (remote
//!   I/O), `tests/golden/project` and `tests/golden/users` (a users file, and a program, with
//!   errors) exactly their `expected.stderr`.
//! - One case per diagnostic: each directory `tests/golden/<area>/<diagnostic>/` is a minimal
//!   project that makes the real binary report that one diagnostic and nothing else, with its
//!   stderr in `expected.stderr`. The areas are where the message comes from: `lang` (the
//!   assembler), `config` (the config file), `project` (the rules across programs),
//!   `stimulus` (an inputs file) and `users` (the users file of `[users] file`). A case is `plcd check --config plcd.toml` run in its
//!   directory, or `plcd sim --config plcd.toml --for 1ms --inputs inputs.csv` when it has an
//!   `inputs.csv`; either must exit 1 with nothing on stdout.
//!
//! A case of `st` whose name starts with `warning-` shows one warning instead: `plcd check`
//! accepts its project (exit 0) and prints that warning, and nothing else, on stderr.
//!
//! `PLCD_BLESS=1 cargo test --test golden_diagnostics` writes what the binary prints to every
//! expected file that differs (and says which) instead of failing; `git diff` then shows what
//! changed. A case that reports other than one diagnostic fails either way.

mod harness;

use harness::golden::compare_or_bless;
use harness::parallel;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

/// The directories of one case per diagnostic, by where the messages come from.
const AREAS: [&str; 6] = ["lang", "config", "project", "stimulus", "st", "users"];

/// The cases whose diagnostic never comes alone, and how many diagnostics they report.
const NOT_ALONE: &[(&str, usize)] = &[
    // A subroutine before `END` leaves the main routine there: the `END` that follows is
    // outside it, and without one the program has no `END`.
    ("lang/sbrt-before-end", 2),
];

use harness::daemon::plcd_in as plcd;

fn stdout(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn language_goldens() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for entry in fs::read_dir("tests/golden/lang").unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "il") {
            continue;
        }
        let source = fs::read_to_string(&path).unwrap();
        let relative = Path::new("tests/golden/lang").join(path.file_name().unwrap());
        let actual = match plcd::lang::assemble(
            "golden",
            &relative,
            &source,
            &harness::vm::context(false),
        ) {
            Ok(_) => String::new(),
            Err(diags) => diags.to_string(),
        };
        failures.extend(compare_or_bless(&path.with_extension("expected"), &actual));
        checked += 1;
    }
    assert!(checked >= 4, "golden files missing");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// `plcd check` on `tests/golden/<name>/plcd.toml` fails with exactly `expected.stderr`.
fn check_golden(name: &str) {
    let config = format!("tests/golden/{name}/plcd.toml");
    let output = plcd(Path::new("."), &["check", "--config", &config]);
    assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
    let expected = format!("tests/golden/{name}/expected.stderr");
    if let Some(failure) = compare_or_bless(Path::new(&expected), &stderr(&output)) {
        panic!("{failure}");
    }
    assert_eq!(stdout(&output), "");
}

#[test]
fn check_reports_every_error_of_every_file() {
    check_golden("project");
}

#[test]
fn check_reports_every_config_error() {
    check_golden("config");
}

#[test]
fn check_reports_every_remote_io_error() {
    check_golden("remote");
}

#[test]
fn check_reports_every_users_file_error_with_the_programs_errors() {
    check_golden("users");
}

/// The case directories of one area, sorted.
fn cases(area: &str) -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = fs::read_dir(Path::new("tests/golden").join(area))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    dirs
}

/// The prefix of a case that shows a warning (the load succeeds).
const WARNING_CASE: &str = "warning-";

/// Runs a warning case: `plcd check` accepts the project and prints exactly one warning on
/// stderr; what is wrong with it, if anything.
fn run_warning_case(dir: &Path) -> Option<String> {
    let output = plcd(dir, &["check", "--config", "plcd.toml"]);
    let err = stderr(&output);
    let warnings = err.lines().filter(|l| l.contains(": warning: ")).count();
    if output.status.code() != Some(0) || warnings != 1 || err.lines().count() != 1 {
        return Some(format!(
            "{}: exit {:?} with {warnings} warning(s), expected 0 with one warning alone\n--- stderr\n{err}",
            dir.display(),
            output.status.code()
        ));
    }
    compare_or_bless(&dir.join("expected.stderr"), &err)
}

/// Runs one case; what is wrong with it, if anything.
fn run_case(dir: &Path) -> Option<String> {
    if dir.file_name().is_some_and(|n| n.to_string_lossy().starts_with(WARNING_CASE)) {
        return run_warning_case(dir);
    }
    // A symlink counts, dangling or not: the case of an inputs file that cannot be read.
    let sim = fs::symlink_metadata(dir.join("inputs.csv")).is_ok();
    let output = if sim {
        plcd(dir, &["sim", "--config", "plcd.toml", "--for", "1ms", "--inputs", "inputs.csv"])
    } else {
        plcd(dir, &["check", "--config", "plcd.toml"])
    };
    let (out, err) = (stdout(&output), stderr(&output));
    if output.status.code() != Some(1) || !out.is_empty() {
        return Some(format!(
            "{}: exit {:?}, expected 1 with nothing on stdout\n--- stdout\n{out}--- stderr\n{err}",
            dir.display(),
            output.status.code()
        ));
    }
    // One diagnostic (or the few of a case in NOT_ALONE), and for `check` their count.
    let case = dir.strip_prefix("tests/golden").unwrap().to_string_lossy().into_owned();
    let wanted = NOT_ALONE.iter().find(|(c, _)| *c == case).map_or(1, |(_, n)| *n);
    let reported = err.lines().filter(|l| l.contains(": error: ")).count();
    let counted = sim || err.ends_with(&format!("plcd.toml: {wanted} error(s)\n"));
    if reported != wanted || !counted {
        return Some(format!("{}: {reported} diagnostics, not {wanted}:\n{err}", dir.display()));
    }
    compare_or_bless(&dir.join("expected.stderr"), &err)
}

#[test]
fn one_golden_file_per_diagnostic() {
    let mut failures = Vec::new();
    let mut counted = Vec::new();
    for area in AREAS {
        let cases = cases(area);
        counted.push(format!("{area}: {}", cases.len()));
        assert!(!cases.is_empty(), "no cases under tests/golden/{area}");
        // Hundreds of `plcd` runs: on every core (under qemu-user, a minute and more alone).
        failures.extend(parallel::map(&cases, |dir| run_case(dir)).into_iter().flatten());
    }
    assert!(failures.is_empty(), "{}\n\n{}", failures.join("\n"), counted.join(", "));
}

#[test]
fn check_names_a_missing_config() {
    let output = plcd(Path::new("."), &["check", "--config", "tests/golden/no-such.toml"]);
    assert_eq!(output.status.code(), Some(1));
    let stderr = stderr(&output);
    assert!(stderr.starts_with("tests/golden/no-such.toml:0:0: error: "), "{stderr}");
    assert!(stderr.contains("No such file"), "{stderr}");
}

#[test]
fn usage_errors_exit_2() {
    let output = plcd(Path::new("."), &["check"]);
    assert_eq!(output.status.code(), Some(2));
}

#[test]
fn check_accepts_the_example_project() {
    let output = plcd(Path::new("."), &["check", "--config", "etc/plcd.toml"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!(stdout(&output).contains("ok: 7 program(s)"), "{}", stdout(&output));
}

#[test]
fn check_counts_the_remote_devices_of_a_valid_project() {
    let dir = Path::new("tests/sim/remote_devices");
    let output = plcd(dir, &["check", "--config", "plcd.toml"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(
        stdout(&output),
        "plcd.toml: ok: 1 program(s), 6 instruction(s), 0 task(s), 1 remote device(s)\n"
    );
}
