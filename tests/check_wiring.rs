//! `plcd check` refuses a gpiocdev wiring the kernel would refuse at `plcd run`: more lines
//! than one line request holds, or more distinct line settings than a request carries. The
//! check needs no GPIO chip (the config's chip need not exist), lines by name included, and
//! reports every such error with the config's others, located. It accepts the Raspberry Pi
//! examples of `etc/`, wired by line names.

mod harness;

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
    let output = harness::runner::command(env!("CARGO_BIN_EXE_plcd"))
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

#[test]
fn too_many_lines_by_name_without_the_chip() {
    // Names are resolved only on the chip; how many lines there are, the config says.
    let inputs: String = (0..65)
        .map(|n| {
            format!(
                "[[io.input]]\ndevice = \"P{:03}{:X}\"\nline = \"IN{n}\"\n",
                10 + n / 16,
                n % 16
            )
        })
        .collect();
    let dir = project("names", &format!("{HEAD}{inputs}"));
    let (code, stderr) = check(&dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains(
            ":198:1: error: io.input \"P0140\": 65 input lines configured, but one GPIO \
                         line request holds at most 64\n"
        ),
        "{stderr}"
    );
}

/// `plcd check` accepts `etc/pi4.toml` and `etc/pi5.toml` as they are (the header's chips by
/// label, the lines by name: nothing that needs the board), and they differ in the chip only.
#[test]
fn the_raspberry_pi_examples_check() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for board in ["pi4", "pi5"] {
        let output = harness::runner::command(env!("CARGO_BIN_EXE_plcd"))
            .args(["check", "--config"])
            .arg(root.join(format!("etc/{board}.toml")))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(0), "etc/{board}.toml: {stderr}");
        let config = plcd::config::parse(
            &std::fs::read_to_string(root.join(format!("etc/{board}.toml"))).unwrap(),
            &root.join(format!("etc/{board}.toml")),
        )
        .unwrap();
        assert_eq!(config.io.backend, plcd::config::Backend::Gpiocdev);
        assert!(config.uses_line_names(), "etc/{board}.toml wires by names");
        let label = if board == "pi4" { "pinctrl-bcm2711" } else { "pinctrl-rp1" };
        assert_eq!(config.io.chip.as_deref(), Some(label));
    }
    let text =
        |board: &str| std::fs::read_to_string(root.join(format!("etc/{board}.toml"))).unwrap();
    let (pi4, pi5) = (text("pi4"), text("pi5"));
    let differ: Vec<(&str, &str)> = pi4.lines().zip(pi5.lines()).filter(|(a, b)| a != b).collect();
    assert_eq!(differ.len(), 2, "the header comment and the chip: {differ:#?}");
    assert_eq!(pi4.lines().count(), pi5.lines().count());
}
