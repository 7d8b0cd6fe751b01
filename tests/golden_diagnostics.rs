//! Golden diagnostics: every `.il` under tests/golden/lang must produce exactly the lines of
//! its `.expected` file, and `plcd check` on tests/golden/project exactly `expected.stderr`.
//! The expected files are written by hand from the rules in docs/LANGUAGE.md.
mod harness;

use std::fs;
use std::path::Path;
use std::process::Command;

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
        let expected = fs::read_to_string(path.with_extension("expected")).unwrap();
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
        if actual != expected {
            failures
                .push(format!("{}:\n--- expected\n{expected}--- actual\n{actual}", path.display()));
        }
        checked += 1;
    }
    assert!(checked >= 4, "golden files missing");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// `plcd check` on `tests/golden/<name>/plcd.toml` fails with exactly `expected.stderr`.
fn check_golden(name: &str) {
    let config = format!("tests/golden/{name}/plcd.toml");
    let output = Command::new(env!("CARGO_BIN_EXE_plcd"))
        .args(["check", "--config", &config])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let expected = fs::read_to_string(format!("tests/golden/{name}/expected.stderr")).unwrap();
    assert_eq!(String::from_utf8_lossy(&output.stderr), expected);
    assert!(output.stdout.is_empty());
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
fn check_names_a_missing_config() {
    let output = Command::new(env!("CARGO_BIN_EXE_plcd"))
        .args(["check", "--config", "tests/golden/no-such.toml"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.starts_with("tests/golden/no-such.toml:0:0: error: "), "{stderr}");
    assert!(stderr.contains("No such file"), "{stderr}");
}

#[test]
fn usage_errors_exit_2() {
    let output = Command::new(env!("CARGO_BIN_EXE_plcd")).args(["check"]).output().unwrap();
    assert_eq!(output.status.code(), Some(2));
}

#[test]
fn check_accepts_the_example_project() {
    let output = Command::new(env!("CARGO_BIN_EXE_plcd"))
        .args(["check", "--config", "etc/plcd.toml"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(0), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(String::from_utf8_lossy(&output.stdout).contains("ok: 5 program(s)"));
}
