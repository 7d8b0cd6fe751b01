//! Golden syntax diagnostics of Structured Text: what `plcd_core::st::parse_file` reports for a
//! broken file, byte for byte.
//!
//! - One case per message: each directory `tests/golden/st-syntax/<case>/` holds a `main.st`
//!   that makes the parser report that one diagnostic and nothing else, in `expected.stderr`
//!   (`main.st:line:col: error: message`). The case `many-errors` reports several at once.
//! - Every message template of the parser (`st::syntax::message_templates`) has a case, and
//!   every case's message is one of the templates.
//! - A realistic program (`tests/golden/st-syntax/realistic.st`) parses without an error.
//!
//! `PLCD_BLESS=1 cargo test --test st_syntax` writes what the parser reports to every expected
//! file that differs (and says which) instead of failing; `git diff` then shows what changed.
//! A case that reports other than one diagnostic fails either way.

mod harness;

use harness::golden::{compare_or_bless, matches_template};
use std::fs;
use std::path::{Path, PathBuf};

use plcd_core::st::{ast, parse_file, syntax};

const ROOT: &str = "tests/golden/st-syntax";

/// The cases that report several diagnostics, and how many.
const SEVERAL: &[(&str, usize)] = &[("many-errors", 8)];

/// The case directories, sorted.
fn cases() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> =
        fs::read_dir(ROOT).unwrap().map(|e| e.unwrap().path()).filter(|p| p.is_dir()).collect();
    dirs.sort();
    dirs
}

/// What the parser reports for a case's `main.st`, read as `main.st`.
fn report(dir: &Path) -> String {
    let text = fs::read_to_string(dir.join("main.st")).unwrap();
    let (_, diags) = parse_file(Path::new("main.st"), &text);
    diags.to_string()
}

/// The message of a diagnostic line `main.st:L:C: error: message`.
fn message(line: &str) -> &str {
    line.split_once(": error: ").map_or(line, |(_, m)| m)
}

#[test]
fn every_case_reports_exactly_its_diagnostics() {
    let cases = cases();
    assert!(cases.len() > 40, "cases missing under {ROOT}");
    let mut failures = Vec::new();
    for dir in &cases {
        let actual = report(dir);
        let name = dir.file_name().unwrap().to_string_lossy().into_owned();
        let wanted = SEVERAL.iter().find(|(c, _)| *c == name).map_or(1, |(_, n)| *n);
        let reported = actual.lines().count();
        if reported != wanted {
            failures.push(format!("{name}: {reported} diagnostics, not {wanted}:\n{actual}"));
            continue;
        }
        failures.extend(compare_or_bless(&dir.join("expected.stderr"), &actual));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_message_template_has_a_case() {
    let templates = syntax::message_templates();
    let mut covered = vec![false; templates.len()];
    let mut unknown = Vec::new();
    for dir in cases() {
        let expected = fs::read_to_string(dir.join("expected.stderr")).unwrap_or_default();
        for line in expected.lines() {
            assert!(line.starts_with("main.st:"), "{}: {line}", dir.display());
            let msg = message(line);
            let mut known = false;
            for (t, template) in templates.iter().enumerate() {
                if matches_template(template, msg) {
                    covered[t] = true;
                    known = true;
                }
            }
            if !known {
                unknown.push(format!("{}: {msg}", dir.display()));
            }
        }
    }
    let missing: Vec<&String> =
        templates.iter().zip(&covered).filter(|(_, c)| !**c).map(|(t, _)| t).collect();
    assert!(missing.is_empty(), "templates without a golden case:\n{missing:#?}");
    assert!(unknown.is_empty(), "messages of no template:\n{unknown:#?}");
}

#[test]
fn template_matching_is_exact_enough() {
    assert!(matches_template("expected {}, found {}", "expected `;`, found `x`"));
    assert!(matches_template("`{}` is not a number", "`16#FG` is not a number"));
    assert!(!matches_template(
        "`{}` is not a number",
        "`T#5x` is not a duration: unknown unit `x`"
    ));
    assert!(matches_template("unterminated string", "unterminated string"));
    assert!(!matches_template("unterminated string", "unterminated strings"));
}

#[test]
fn a_realistic_program_parses_without_errors() {
    let path = Path::new(ROOT).join("realistic.st");
    let text = fs::read_to_string(&path).unwrap();
    assert!(text.lines().count() >= 300);
    let (file, diags) = parse_file(&path, &text);
    assert!(diags.is_empty(), "{diags}");
    let pous: Vec<(&str, ast::PouKind)> = file
        .items
        .iter()
        .filter_map(|item| match item {
            ast::Item::Pou(pou) => Some((pou.name.name.as_str(), pou.kind)),
            _ => None,
        })
        .collect();
    assert_eq!(
        pous,
        [
            ("PID", ast::PouKind::FunctionBlock),
            ("Clamp", ast::PouKind::Function),
            ("ScaleRaw", ast::PouKind::Function),
            ("Logger", ast::PouKind::FunctionBlock),
            ("Debounce", ast::PouKind::FunctionBlock),
            ("main", ast::PouKind::Program),
        ]
    );
    let types = file.items.iter().filter(|i| matches!(i, ast::Item::Type(_))).count();
    let globals = file.items.iter().filter(|i| matches!(i, ast::Item::Globals(_))).count();
    assert_eq!((types, globals), (8, 2));
    // The state machine: a CASE over the enumeration, five arms and an ELSE.
    let Some(ast::Item::Pou(main)) = file.items.last() else { panic!() };
    let ast::StmtKind::For { body, .. } = &main.body[4].kind else { panic!("{:?}", main.body[4]) };
    let case = body.iter().find_map(|s| match &s.kind {
        ast::StmtKind::Case { arms, otherwise, .. } => Some((arms.len(), otherwise.is_some())),
        _ => None,
    });
    assert_eq!(case, Some((5, true)));
}
