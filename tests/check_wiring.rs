//! `plcd check` refuses a gpiocdev wiring the kernel would refuse at `plcd run`: more lines
//! than one line request holds, or more distinct line settings than a request carries. The
//! check needs no GPIO chip (the config's chip need not exist), and reports every such error
//! with the config's others, located.

mod harness;

use std::process::Command;

use harness::tempdir::TempDir;

/// A fresh project directory with `plcd.toml` = `config` and an empty scan program.
fn project(name: &str, config: &str) -> TempDir {
    let dir = TempDir::new(&format!("check-wiring-{name}"));
    dir.write("main.il", "END\n");
    dir.write("plcd.toml", config);
    dir
}

/// `plcd check` on the project: its exit code and stderr.
fn check(dir: &TempDir) -> (Option<i32>, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_plcd"))
        .args(["check", "--config"])
        .arg(dir.join("plcd.toml"))
        .output()
        .unwrap();
    (output.status.code(), String::from_utf8_lossy(&output.stderr).into_owned())
}

const HEAD: &str = "[[program]]\nfile = \"main.il\"\n\
                    [io]\nbackend = \"gpiocdev\"\nchip = \"/dev/plcd-no-such-chip\"\n";

fn input(n: u32, extra: &str) -> String {
    format!("[[io.input]]\ndevice = \"P{:03}{:X}\"\nline = {n}\n{extra}", 10 + n / 16, n % 16)
}

#[test]
fn too_many_lines_for_one_request() {
    let inputs: String = (0..65).map(|n| input(n, "")).collect();
    let dir = project("lines", &format!("{HEAD}{inputs}"));
    let (code, stderr) = check(&dir);
    let path = dir.join("plcd.toml");
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(
        stderr,
        format!(
            "{}:198:1: error: io.input \"P0140\": 65 input lines configured, but one GPIO line \
             request holds at most 64\n{}: 1 error(s)\n",
            path.display(),
            path.display()
        )
    );
    // 64 are fine, without the chip.
    let inputs: String = (0..64).map(|n| input(n, "")).collect();
    let dir = project("lines-ok", &format!("{HEAD}{inputs}"));
    let (code, stderr) = check(&dir);
    assert_eq!(code, Some(0), "{stderr}");
}

#[test]
fn too_many_line_settings_with_the_other_errors() {
    // Eleven debounce periods: eleven attributes besides the default flags.
    let inputs: String =
        (0..11).map(|n| input(n, &format!("debounce_us = {}\n", 100 * (n + 1)))).collect();
    let dir = project("settings", &format!("[plc]\nwatchdog_ms = 5\n{HEAD}{inputs}"));
    let (code, stderr) = check(&dir);
    let path = dir.join("plcd.toml");
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(
        stderr,
        format!(
            "{path}:2:15: error: plc.watchdog_ms 5 out of range 10..=1000\n\
             {path}:48:1: error: io.input \"P010A\": the input lines need 11 distinct line \
             settings (combinations of active_low, bias and edge, and debounce periods) besides \
             the most common one; the kernel takes at most 10 per request\n\
             {path}: 2 error(s)\n",
            path = path.display()
        )
    );
}
