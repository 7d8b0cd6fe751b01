//! The Structured Text conformance suite (tests/st/README.md): every `tests/st/<area>/<case>.st`
//! runs as the scan program `main` of a project of its own, with the clock standing still
//! during each scan, and every line of its `.expect` — values derived by hand from the
//! standard and docs/ST.md — must hold. Every failed line of every case is reported at once.

mod harness;

use std::fs;
use std::path::{Path, PathBuf};

use plcd::device::Address;
use plcd::project::{Project, Watched};
use plcd::value::{self, Elem, ValueType};
use plcd::vm::{ExecState, Exit, ManualClock, Vm};

const MS: u64 = 1_000_000;
/// A case that does not end a scan within this many VM steps has an endless loop.
const STEPS_PER_SCAN: u64 = 10_000_000;

/// One `after N scans: name = value` line.
struct Expectation {
    line: usize,
    after: u64,
    name: String,
    value: String,
}

/// A parsed `.expect` file.
struct Expect {
    period_ns: u64,
    values: Vec<Expectation>,
    errors: Vec<u16>,
}

fn parse_expect(path: &Path) -> Result<Expect, String> {
    let text = fs::read_to_string(path).map_err(|e| e.to_string())?;
    let mut expect = Expect { period_ns: MS, values: Vec::new(), errors: Vec::new() };
    let mut period: Option<u64> = None;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let content = strip_comment(raw).trim();
        if content.is_empty() {
            continue;
        }
        let at = |message: String| format!("{}:{line}: {message}", path.display());
        if let Some(code) = content.strip_prefix("error:") {
            let code = code.trim().trim_end_matches(['H', 'h']);
            let code = u16::from_str_radix(code, 16).map_err(|e| at(format!("error code: {e}")))?;
            expect.errors.push(code);
            continue;
        }
        let rest = content.strip_prefix("after ").ok_or_else(|| at("expected `after`".into()))?;
        let (when, assertion) =
            rest.split_once(':').ok_or_else(|| at("expected `:` after the scans".into()))?;
        let mut words = when.split_whitespace();
        let after: u64 = words
            .next()
            .and_then(|n| n.parse().ok())
            .ok_or_else(|| at("expected a number of scans".into()))?;
        if words.next() != Some("scans") {
            return Err(at("expected `scans`".into()));
        }
        if let (Some("at"), Some(p)) = (words.next(), words.next()) {
            let ns = plcd::duration::parse_duration(p).map_err(|e| at(e.to_string()))?;
            if period.is_some_and(|old| old != ns) {
                return Err(at("all the `after` lines of a case use the same period".into()));
            }
            period = Some(ns);
        }
        let (name, value) =
            assertion.split_once('=').ok_or_else(|| at("expected `name = value`".into()))?;
        expect.values.push(Expectation {
            line,
            after,
            name: name.trim().to_string(),
            value: value.trim().to_string(),
        });
    }
    expect.period_ns = period.unwrap_or(MS);
    Ok(expect)
}

/// The line without its `#` comment (a `#` inside a quoted value stays).
fn strip_comment(line: &str) -> &str {
    let mut quoted = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '#' if !quoted => return &line[..i],
            _ => {}
        }
    }
    line
}

fn project_for(case: &Path, period_ns: u64) -> Result<Project, String> {
    // a case's own sections (`[iec] preset = "codesys"`), from `<case>.toml` beside it
    let sections = fs::read_to_string(case.with_extension("toml")).unwrap_or_default();
    let config = format!(
        "[plc]\nwatchdog_ms = 1000\nscan_period_ms = {}\n[[program]]\nname = \"main\"\nfile = \"{}\"\n{sections}",
        period_ns / MS,
        case.file_name().unwrap().to_str().unwrap()
    );
    let config = plcd::config::parse(&config, &case.with_extension("toml"))
        .map_err(|d| format!("config: {d}"))?;
    plcd::project::from_config(config, |path| fs::read_to_string(path)).map_err(|d| d.to_string())
}

/// What one name reads as, in the trace's words.
fn read(project: &Project, vm: &Vm, name: &str) -> Result<(String, Option<ValueType>), String> {
    if let Ok(address) = Address::parse(name) {
        return Ok((vm.mem.read(&address).to_string(), None));
    }
    // a variable, or an access path to one (`count`, `timer.Q`), as clients name them
    let found = project.watched(name).unwrap_or_default();
    let symbol = match found.as_slice() {
        [Watched::Variable(symbol)] => symbol,
        _ => return Err(format!("no variable `{name}`")),
    };
    let text = match symbol.ty {
        ValueType::String { .. } => {
            format!("{:?}", plcd::value::decode_str(&vm.read_string(symbol.at)))
        }
        ValueType::WString { .. } => {
            format!("{:?}", String::from_utf16_lossy(&vm.read_wstring(symbol.at)))
        }
        ref ty => {
            let slot = vm.read_value(symbol.at, ty.elem());
            let text = match ty {
                ValueType::Reference { .. } => {
                    plcd::lang::reference_text(&project.variables.symbols, slot)
                }
                _ => value::format(ty, slot),
            };
            match ty {
                ValueType::Time
                | ValueType::Calendar(_)
                | ValueType::Enum { .. }
                | ValueType::Char
                | ValueType::WChar
                | ValueType::Reference { .. } => {
                    format!("{text:?}")
                }
                _ => text,
            }
        }
    };
    Ok((text, Some(symbol.ty.clone())))
}

/// Whether `actual` is `expected`: reals after rounding the expectation to the type.
fn agrees(actual: &str, expected: &str, ty: Option<&ValueType>) -> bool {
    match ty {
        Some(ValueType::Real(elem)) => {
            let (Ok(a), Ok(e)) = (actual.parse::<f64>(), expected.parse::<f64>()) else {
                return actual == expected;
            };
            if *elem == Elem::F32 {
                (a as f32).to_bits() == (e as f32).to_bits()
            } else {
                a.to_bits() == e.to_bits()
            }
        }
        _ => actual == expected,
    }
}

/// Runs one case; every failed expectation, as `file:line: message`.
fn run_case(case: &Path) -> Vec<String> {
    let expect_path = case.with_extension("expect");
    let expect = match parse_expect(&expect_path) {
        Ok(e) => e,
        Err(e) => return vec![e],
    };
    let project = match project_for(case, expect.period_ns) {
        Ok(p) => p,
        Err(e) => return vec![format!("{}: does not compile:\n{e}", case.display())],
    };
    let program = &project.programs[0];
    let mut vm = Vm::for_programs(&project.programs);
    vm.set_variables(&project.variables);
    vm.reset_for_run(&plcd::device::RetainSet::new(&[]), false);
    let mut state = ExecState::with_frame(project.frame_bytes());
    let clock = ManualClock::new(0);
    let mut failures = Vec::new();
    let mut errors = Vec::new();
    let last = expect.values.iter().map(|e| e.after).max().unwrap_or(1);
    for scan in 1..=last {
        clock.set((scan - 1) * expect.period_ns);
        vm.begin_scan(scan == 1, (scan - 1) * expect.period_ns);
        state.restart();
        let budget_end = vm.steps() + STEPS_PER_SCAN;
        loop {
            let left = budget_end.saturating_sub(vm.steps());
            match vm.run(program, &mut state, &clock, left) {
                Exit::End => break,
                Exit::OperationError { code, .. } => errors.push(code),
                Exit::System(_) => {}
                Exit::Budget => {
                    failures.push(format!("{}: scan {scan} did not end", case.display()));
                    return failures;
                }
            }
        }
        vm.end_scan();
        for e in expect.values.iter().filter(|e| e.after == scan) {
            match read(&project, &vm, &e.name) {
                Ok((actual, ty)) if agrees(&actual, &e.value, ty.as_ref()) => {}
                Ok((actual, _)) => failures.push(format!(
                    "{}:{}: after {scan} scans: {} = {actual}, expected {}",
                    expect_path.display(),
                    e.line,
                    e.name,
                    e.value
                )),
                Err(message) => {
                    failures.push(format!("{}:{}: {message}", expect_path.display(), e.line))
                }
            }
        }
    }
    for code in &expect.errors {
        if !errors.contains(code) {
            failures.push(format!("{}: error {code:04X}H was not reported", expect_path.display()));
        }
    }
    if expect.errors.is_empty() {
        if let Some(code) = errors.first() {
            failures.push(format!("{}: unexpected error {code:04X}H", expect_path.display()));
        }
    }
    failures
}

fn cases() -> Vec<PathBuf> {
    let mut cases = Vec::new();
    for area in fs::read_dir("tests/st").unwrap() {
        let area = area.unwrap().path();
        if !area.is_dir() {
            continue;
        }
        for entry in fs::read_dir(&area).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "st") {
                cases.push(path);
            }
        }
    }
    cases.sort();
    cases
}

#[test]
fn every_conformance_case_holds() {
    let cases = cases();
    assert!(cases.len() >= 60, "only {} conformance cases", cases.len());
    let mut failures = Vec::new();
    let mut failed_cases = 0;
    for case in &cases {
        let f = run_case(case);
        if !f.is_empty() {
            failed_cases += 1;
        }
        failures.extend(f);
    }
    assert!(
        failures.is_empty(),
        "{failed_cases} of {} cases fail:\n{}",
        cases.len(),
        failures.join("\n")
    );
}
