//! OSCAT BASIC, a public library of 545 POUs nobody here wrote (tests/oscat/README.md), loaded
//! whole from its TwinCAT files as an `[st] library` folder: it compiles with native code and
//! without, and a table of its functions gives the values its documentation states, scan for
//! scan the same on native code and on the interpreter.

mod harness;

use std::fs;
use std::path::{Path, PathBuf};

use harness::tempdir::TempDir;

fn oscat() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/oscat")
}

/// A project of `tests/oscat/functions.st` on the whole library, a scan every 10 ms.
fn project() -> TempDir {
    let dir = TempDir::new("oscat");
    let o = oscat();
    let config = format!(
        "[plc]\nscan_period_ms = 10\n\n[[program]]\nname = \"main\"\nfile = \"{}\"\n\n\
         [st]\nlibrary = [\"{}\", \"{}/\"]\n",
        o.join("functions.st").display(),
        o.join("tc2_system.st").display(),
        o.join("basic").display()
    );
    fs::write(dir.path().join("plcd.toml"), config).unwrap();
    dir
}

use harness::daemon::plcd_in as plcd;

#[test]
fn the_whole_library_compiles_with_native_code_and_without() {
    let dir = project();
    let config = dir.path().join("plcd.toml");
    let out = plcd(dir.path(), &["check", "--config", "plcd.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let files = fs::read_dir(oscat().join("basic/POUs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .map(|d| count_pous(&d))
        .sum::<usize>();
    assert!(files >= 540, "only {files} POUs under tests/oscat/basic/POUs");
    let interpreted = plcd::files::interpreted_project(&config).unwrap();
    let native = plcd::files::project(&config).unwrap();
    // the library costs nothing at run time: only what the program calls is in it
    assert_eq!(interpreted.programs.len(), 1);
    assert!(interpreted.programs[0].code.len() < 20_000, "{}", interpreted.programs[0].code.len());
    assert_eq!(native.programs[0].code.len(), interpreted.programs[0].code.len());
}

fn count_pous(dir: &Path) -> usize {
    fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            if p.is_dir() {
                count_pous(&p)
            } else {
                usize::from(p.extension().is_some_and(|e| e == "TcPOU"))
            }
        })
        .sum()
}

/// The last value of each variable the trace shows.
fn values(trace: &str) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    for line in trace.lines().filter(|l| l.contains("\"ev\":\"set\"")) {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let name = v["dev"].as_str().unwrap().to_string();
        let value = v["value"].to_string();
        match out.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 = value,
            None => out.push((name, value)),
        }
    }
    out
}

/// Each variable of functions.st, the value OSCAT's documentation gives (as the trace writes
/// it; a value equal to the variable's initial value is never traced, so none is one), and why.
const TABLE: &[(&str, &str, &str)] = &[
    ("leap_2024", "1", "LEAP_YEAR: 2024 is a leap year"),
    ("gcd_12_18", "6", "GCD: the greatest common divisor of 12 and 18"),
    ("fact_5", "120", "FACT: 5! = 120"),
    ("bits_f0f0", "8", "BIT_COUNT: 16#F0F0 has eight bits set"),
    ("swapped", "13330", "SWAP_BYTE swaps the high and low byte: 16#3412"),
    ("reversed", "128", "REVERSE moves bit 0 to bit 7: 2#1000_0000"),
    ("even_4", "1", "EVEN(4)"),
    ("upper", "\"TANK 1\"", "UPPERCASE"),
    ("lower", "\"pump\"", "LOWERCASE"),
    ("capital", "\"Hello World\"", "CAPITALIZE: each first letter after a blank"),
    ("trimmed", "\"ab\"", "TRIM deletes all blanks within a string"),
    ("replaced", "\"a+b+c\"", "REPLACE_ALL replaces every occurrence"),
    ("hour_", "12", "HOUR of 12:30:15"),
    ("minute_", "30", "MINUTE of 12:30:15"),
    ("day_of_year_", "61", "DAY_OF_YEAR: 31 (January) + 29 (February 2024) + 1"),
    ("month_", "3", "MONTH_OF_DATE of 2024-03-01"),
    ("day_of_month_", "1", "DAY_OF_MONTH of 2024-03-01"),
    ("days_in_feb", "29", "DAYS_IN_MONTH: February of the leap year 2024"),
    ("hex_byte", "\"3C\"", "BYTE_TO_STRH: two hex digits, the high one on the left"),
    ("hex_dword", "\"DEADBEEF\"", "DWORD_TO_STRH: eight hex digits"),
    ("byte_1", "51", "BYTE_OF_DWORD: byte 1 from the right (N = 0 the lowest): 16#33"),
    ("negative", "1", "SIGN_I: TRUE for a negative input"),
    ("fahrenheit", "212.0", "C_TO_F: 100 °C is 212 °F"),
    ("biggest", "5.0", "MAX3 of 1, 5, 3"),
    ("smallest", "2.0", "MIN3 of 4, 2, 9"),
    ("inside", "1", "WINDOW: 5 lies between 0 and 10"),
    ("letter", "\"A\"", "CHR_TO_STRING: the character of code 65"),
    ("alpha_a", "1", "ISC_ALPHA: `a` (97) is a letter"),
    ("sign_", "-1", "SGN: -1 below zero"),
    ("plc_ms", "20", "T_PLC_MS: the PLC's clock in ms at the last scan, t = 20 ms"),
];

/// Reals compared to the precision of a REAL.
const REALS: &[(&str, f64, &str)] =
    &[("pi", std::f64::consts::PI, "RAD(180°) is π, to a REAL's precision")];

/// Variables whose documented value is their initial value (FALSE, 0): never traced.
const UNCHANGED: &[(&str, &str)] = &[
    ("leap_2023", "LEAP_YEAR: 2023 is not a leap year"),
    ("even_7", "EVEN(7) is FALSE"),
    ("celsius", "F_TO_C: 32 °F is 0 °C"),
    ("alpha_1", "ISC_ALPHA: `1` is no letter"),
];

fn run(interpreter: bool) -> Vec<(String, String)> {
    let dir = project();
    let mut names: Vec<String> = TABLE.iter().map(|(n, _, _)| format!("main.{n}")).collect();
    names.extend(REALS.iter().map(|(n, _, _)| format!("main.{n}")));
    names.extend(UNCHANGED.iter().map(|(n, _)| format!("main.{n}")));
    let watch = names.join(",");
    // a step costs 1 ns: the clock moves less than a millisecond during a scan
    let mut args =
        vec!["sim", "--config", "plcd.toml", "--for", "25ms", "--step-ns", "1", "--watch", &watch];
    args.extend(["--trace", "-"]);
    if interpreter {
        args.push("--interpreter");
    }
    let out = plcd(dir.path(), &args);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    values(&String::from_utf8_lossy(&out.stdout))
}

#[test]
fn the_library_functions_give_their_documented_values() {
    let native = run(false);
    let get = |name: &str| {
        let full = format!("main.{name}");
        native.iter().find(|(n, _)| *n == full).map(|(_, v)| v.clone())
    };
    let mut failures = Vec::new();
    for (name, want, why) in TABLE {
        if get(name).as_deref() != Some(want) {
            failures.push(format!("{name} = {:?}, expected {want}: {why}", get(name)));
        }
    }
    for (name, want, why) in REALS {
        let got: Option<f64> = get(name).and_then(|v| v.parse().ok());
        if !got.is_some_and(|g| ((g - want) / want).abs() < 1e-6) {
            failures.push(format!("{name} = {got:?}, expected {want}: {why}"));
        }
    }
    for (name, why) in UNCHANGED {
        if let Some(v) = get(name) {
            failures.push(format!("{name} changed to {v}, expected its initial value: {why}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert_eq!(run(true), native, "the interpreter and native code differ");
}
