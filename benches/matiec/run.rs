//! The matiec column of `benches/st_native.rs`: the ST workloads compiled as OpenPLC compiles a
//! project, by matiec's `iec2c` to C and then by gcc -O2, and run as OpenPLC's runtime runs a
//! program. The files beside this one do the work: `setup` builds iec2c, `build` compiles one
//! workload and links it with `harness.c`, the C main that runs and times the scans. This
//! module runs them, each under `timeout`, and reads what the harness prints.

use std::path::Path;
use std::process::Command;

/// What a workload's harness printed: after each checked scan, the variables it compares
/// (named as plcd names them, each in plcd's slot encoding), and the median time of a scan.
pub struct Run {
    pub scans: Vec<Vec<(String, u64)>>,
    pub ns_per_scan: f64,
}

/// Builds iec2c unless it is built (`benches/matiec/setup`); the error says why it cannot be.
pub fn setup() -> Result<(), String> {
    let out = run(3600, &script("setup"), &[])?;
    eprint!("{out}");
    Ok(())
}

/// Workload `name` compiled with matiec and gcc, run for `checks` scans that print their
/// variables, then timed.
pub fn run_workload(name: &str, checks: usize) -> Result<Run, String> {
    let built = run(1800, &script("build"), &[name])?;
    let harness = built.lines().last().ok_or("benches/matiec/build printed no path")?;
    parse(&run(600, harness, &[&checks.to_string()])?, checks)
}

fn script(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/matiec").join(name).display().to_string()
}

/// `program` with `args` under `timeout seconds`: its standard output when it succeeds, else
/// the end of its standard error.
fn run(seconds: u32, program: &str, args: &[&str]) -> Result<String, String> {
    let out = Command::new("timeout")
        .arg(seconds.to_string())
        .arg(program)
        .args(args)
        .output()
        .map_err(|e| format!("cannot run timeout {program}: {e}"))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let lines: Vec<&str> = stderr.lines().collect();
        let tail = lines[lines.len().saturating_sub(3)..].join(" / ");
        let command = [&[program], args].concat().join(" ");
        return Err(format!("{command}: {}: {tail}", out.status));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The harness's lines "scan K NAME=SLOT ..." and "ns_per_scan X".
fn parse(out: &str, checks: usize) -> Result<Run, String> {
    let bad = |line: &str| format!("harness: cannot read the line {line:?}");
    let mut scans = Vec::new();
    let mut ns_per_scan = None;
    for line in out.lines() {
        let mut words = line.split_whitespace();
        match (words.next(), words.next()) {
            (Some("scan"), Some(_)) => {
                let vars = words.map(|w| {
                    let (name, slot) = w.split_once('=')?;
                    Some((name.to_string(), u64::from_str_radix(slot, 16).ok()?))
                });
                scans.push(vars.collect::<Option<Vec<_>>>().ok_or_else(|| bad(line))?);
            }
            (Some("ns_per_scan"), Some(ns)) => {
                ns_per_scan = Some(ns.parse().map_err(|_| bad(line))?)
            }
            _ => return Err(bad(line)),
        }
    }
    if scans.len() != checks {
        return Err(format!("harness: {} scans printed, not {checks}", scans.len()));
    }
    let ns_per_scan = ns_per_scan.ok_or("harness: no ns_per_scan")?;
    Ok(Run { scans, ns_per_scan })
}
