//! The simulation inputs file (`plcd sim --inputs`, `[io] stimulus`; docs/SIMULATION.md): timed
//! device changes, one a line.
//!
//! ```text
//! # time, device, value
//! 6ms,   P0000, 1
//! 6.5ms, P0000, 0
//! 15ms,  M0000, 1
//! 40ms,  MODE,  STOP
//! 50ms,  SWITCH, STOP
//! ```
//!
//! Fields are trimmed, `#` starts a comment anywhere on a line, blank lines are skipped. Every
//! error of the file is reported at once, each at the line and column of the bad field.
//!
//! The pseudo-device `SWITCH` turns the simulated RUN/STOP key switch, which only a config with
//! a `[switch]` has: [`parse_for`] checks a file against the config, [`parse`] reads it alone.
//! Reading the file is the caller's (`plcd::files`).

use std::path::Path;

use crate::config::Config;
use crate::device::{Address, Writer, WORD_VALUES};
use crate::diag::{Diagnostic, Diagnostics};
use crate::duration::parse_duration;
use crate::engine::event::Mode;
use crate::io::SwitchPosition;

/// What a stimulus line changes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// A device of the PLC, written with `Memory::write` semantics.
    Device(Address),
    /// The pseudo-device `MODE`: a switch to RUN or STOP.
    Mode(Mode),
    /// The pseudo-device `SWITCH`: the RUN/STOP key switch of `[switch]` turned to RUN or
    /// STOP (the sim field's switch; the engine sees it at its next input refresh).
    Switch(SwitchPosition),
}

/// One timed change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stimulus {
    /// Virtual time since RUN started, in nanoseconds.
    pub t_ns: u64,
    pub target: Target,
    /// The new value: 0 or 1 for a bit device, `-32768..=65535` for a word device (hex
    /// constants are read as unsigned, `hFFFF` is 65535), 0 for `MODE` and `SWITCH`.
    pub value: i32,
    /// The line of the file, from 1.
    pub line: u32,
}

/// [`parse`], checked against `config`: a `SWITCH` line is an error (at its line) when the config
/// has no `[switch]`. `plcd sim --inputs` and the daemon's `io.stimulus` both read a project's
/// inputs file through this.
pub fn parse_for(text: &str, path: &Path, config: &Config) -> Result<Vec<Stimulus>, Diagnostics> {
    parse_with(text, path, config.switch.is_some())
}

/// Parses the text of an inputs file; `path` is only used in diagnostics. The result is sorted
/// by time; changes at the same time keep their file order.
pub fn parse(text: &str, path: &Path) -> Result<Vec<Stimulus>, Diagnostics> {
    parse_with(text, path, true)
}

/// `switch`: the config has a `[switch]` (or there is no config to check against).
fn parse_with(text: &str, path: &Path, switch: bool) -> Result<Vec<Stimulus>, Diagnostics> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut stimuli = Vec::new();
    let mut diags = Diagnostics::default();
    for (index, raw_line) in text.lines().enumerate() {
        let line_no = u32::try_from(index + 1).unwrap_or(u32::MAX);
        let content = match raw_line.find('#') {
            Some(hash) => &raw_line[..hash],
            None => raw_line,
        };
        if content.trim().is_empty() {
            continue;
        }
        let mut error = |col: u32, message: String| {
            diags.push(Diagnostic::new(path, line_no, col, message));
        };
        let column = |offset: usize| raw_line[..offset].chars().count() as u32 + 1;

        // Each field as (trimmed text, column of its first character).
        let mut fields: Vec<(&str, u32)> = Vec::with_capacity(3);
        let mut start = 0;
        for piece in content.split(',') {
            let lead = piece.len() - piece.trim_start().len();
            fields.push((piece.trim(), column(start + lead)));
            start += piece.len() + 1;
        }
        if fields.len() != 3 {
            let (col, message) = if fields.len() > 3 {
                (
                    fields[3].1,
                    format!(
                        "expected 3 fields `time, device, value`, found {}; extra field",
                        fields.len()
                    ),
                )
            } else {
                let end = content.trim_end().len();
                (
                    column(end),
                    format!("expected 3 fields `time, device, value`, found {}", fields.len()),
                )
            };
            error(col, message);
            continue;
        }
        let (time_text, time_col) = fields[0];
        let (device_text, device_col) = fields[1];
        let (value_text, value_col) = fields[2];

        let t_ns = match parse_duration(time_text) {
            Ok(t) => Some(t),
            Err(e) => {
                error(time_col, format!("bad time: {e}"));
                None
            }
        };

        let target = if device_text.eq_ignore_ascii_case("MODE") {
            Some(Kind::Mode)
        } else if device_text.eq_ignore_ascii_case("SWITCH") {
            if !switch {
                error(
                    device_col,
                    "SWITCH: the config has no [switch], so there is no RUN/STOP key switch to \
                     turn"
                        .to_string(),
                );
            }
            Some(Kind::Switch)
        } else if device_text.is_empty() {
            error(device_col, "missing device".to_string());
            None
        } else {
            match Address::parse(device_text) {
                Ok(address) if !address.writable_by(Writer::Stimulus) => {
                    error(
                        device_col,
                        format!("`{device_text}` is a system flag, a stimulus cannot drive it"),
                    );
                    None
                }
                Ok(address) if address.as_word().is_ok() => Some(Kind::Word(address)),
                Ok(address) => Some(Kind::Bit(address)),
                Err(e) => {
                    error(device_col, e.to_string());
                    None
                }
            }
        };

        let value = match target {
            Some(Kind::Mode) => match value_text.to_ascii_uppercase().as_str() {
                "RUN" => Some((Target::Mode(Mode::Run), 0)),
                "STOP" => Some((Target::Mode(Mode::Stop), 0)),
                _ => {
                    error(value_col, format!("`{value_text}`: MODE takes RUN or STOP"));
                    None
                }
            },
            Some(Kind::Switch) => match value_text.to_ascii_uppercase().as_str() {
                "RUN" => Some((Target::Switch(SwitchPosition::Run), 0)),
                "STOP" => Some((Target::Switch(SwitchPosition::Stop), 0)),
                _ => {
                    error(value_col, format!("`{value_text}`: SWITCH takes RUN or STOP"));
                    None
                }
            },
            Some(Kind::Bit(address)) => match parse_value(value_text) {
                Ok(v @ (0 | 1)) => Some((Target::Device(address), v)),
                Ok(_) => {
                    error(
                        value_col,
                        format!("`{value_text}`: {address} is a bit device, its value is 0 or 1"),
                    );
                    None
                }
                Err(e) => {
                    error(value_col, e);
                    None
                }
            },
            Some(Kind::Word(address)) => match parse_value(value_text) {
                Ok(v) => Some((Target::Device(address), v)),
                Err(e) => {
                    error(value_col, e);
                    None
                }
            },
            // The device is bad: still report a value that is bad whatever the device.
            None => {
                if !value_text.eq_ignore_ascii_case("RUN")
                    && !value_text.eq_ignore_ascii_case("STOP")
                {
                    if let Err(e) = parse_value(value_text) {
                        error(value_col, e);
                    }
                }
                None
            }
        };

        if let (Some(t_ns), Some((target, value))) = (t_ns, value) {
            stimuli.push(Stimulus { t_ns, target, value, line: line_no });
        }
    }
    if !diags.is_empty() {
        return Err(diags);
    }
    stimuli.sort_by_key(|s| s.t_ns);
    Ok(stimuli)
}

/// A device target, before its value is checked.
#[derive(Clone, Copy)]
enum Kind {
    Mode,
    Switch,
    Bit(Address),
    Word(Address),
}

/// A value: decimal `-32768..=65535` or hex `h0`..`hFFFF`.
fn parse_value(text: &str) -> Result<i32, String> {
    if text.is_empty() {
        return Err("missing value".to_string());
    }
    let bad = || format!("`{text}` is not a value (decimal {WORD_VALUES:?} or hex h0000..=hFFFF)");
    if let Some(hex) = text.strip_prefix(['h', 'H']) {
        if hex.is_empty() || hex.len() > 4 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad());
        }
        return i32::from_str_radix(hex, 16).map_err(|_| bad());
    }
    let digits = text.strip_prefix('-').unwrap_or(text);
    if digits.is_empty() || digits.len() > 6 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let value: i32 = text.parse().map_err(|_| bad())?;
    if !WORD_VALUES.contains(&value) {
        return Err(format!("`{text}` is out of range ({WORD_VALUES:?})"));
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(s: &str) -> Address {
        Address::parse(s).unwrap()
    }

    fn dev(t_ns: u64, device: &str, value: i32, line: u32) -> Stimulus {
        Stimulus { t_ns, target: Target::Device(addr(device)), value, line }
    }

    fn mode(t_ns: u64, mode: Mode, line: u32) -> Stimulus {
        Stimulus { t_ns, target: Target::Mode(mode), value: 0, line }
    }

    fn switch(t_ns: u64, position: SwitchPosition, line: u32) -> Stimulus {
        Stimulus { t_ns, target: Target::Switch(position), value: 0, line }
    }

    /// A config, with a `[switch]` or without.
    fn config(with_switch: bool) -> Config {
        let switch = if with_switch { "[switch]\n" } else { "" };
        let text = format!("{switch}[[program]]\nfile = \"main.il\"\n");
        crate::config::parse(&text, Path::new("plcd.toml")).unwrap()
    }

    fn ok(text: &str) -> Vec<Stimulus> {
        parse(text, Path::new("in.csv")).unwrap_or_else(|d| panic!("{d}"))
    }

    fn errors(text: &str) -> Vec<String> {
        match parse(text, Path::new("in.csv")) {
            Ok(s) => panic!("expected errors, got {s:?}"),
            Err(d) => d.iter().map(ToString::to_string).collect(),
        }
    }

    #[test]
    fn contract_example() {
        let text = "# time, device, value\n\
                    6ms,   P0000, 1\n\
                    6.5ms, P0000, 0\n\
                    15ms,  M0000, 1\n\
                    40ms,  MODE,  STOP\n";
        assert_eq!(
            ok(text),
            vec![
                dev(6_000_000, "P0000", 1, 2),
                dev(6_500_000, "P0000", 0, 3),
                dev(15_000_000, "M0000", 1, 4),
                mode(40_000_000, Mode::Stop, 5),
            ]
        );
    }

    #[test]
    fn comments_blank_lines_and_crlf() {
        let text = "\u{feff}\r\n  # only a comment\r\n\t\r\n1ms, D00010, -5 # mid-line comment\r\n\
                    2ms,mode,run#tight\r\n3ms , d10 , h00ff";
        assert_eq!(
            ok(text),
            vec![
                dev(1_000_000, "D00010", -5, 4),
                mode(2_000_000, Mode::Run, 5),
                dev(3_000_000, "D00010", 255, 6),
            ]
        );
        assert_eq!(ok(""), vec![]);
        assert_eq!(ok("# nothing\n\n"), vec![]);
    }

    #[test]
    fn sorted_by_time_and_stable() {
        let text = "5ms, M0001, 1\n1ms, M0002, 1\n5ms, M0003, 1\n1ms, M0004, 1\n0ns, M0005, 1\n";
        let order: Vec<(u64, u32)> = ok(text).iter().map(|s| (s.t_ns, s.line)).collect();
        assert_eq!(
            order,
            vec![(0, 5), (1_000_000, 2), (1_000_000, 4), (5_000_000, 1), (5_000_000, 3)]
        );
    }

    #[test]
    fn values_by_device_kind() {
        let text = "0ms, D00000, -32768\n0ms, D00001, 65535\n0ms, D00002, hFFFF\n\
                    0ms, T0005, 100\n0ms, C0001, 0\n0ms, P004, h0F\n0ms, D00003.F, 1\n\
                    0ms, SM400, 0\n0ms, P0040, h1\n";
        let values: Vec<i32> = ok(text).iter().map(|s| s.value).collect();
        assert_eq!(values, vec![-32768, 65535, 65535, 100, 0, 15, 1, 0, 1]);
    }

    #[test]
    fn error_file_reports_every_error_with_its_column() {
        let text = "\
# a file with one error or more on most lines
6ms,   P0000, 1
6.5,   P0000, 0
15ms,  X0000, 1
15ms,  M0000, 2
20ms,  D00010
20ms,  D00010, 70000, 4
40ms,  MODE,  PAUSE
-1ms,  Q1,    h12345
 1ms , P0040 , 1 , # trailing comma
";
        assert_eq!(
            errors(text),
            vec![
                "in.csv:3:1: error: bad time: `6.5` has no unit (use ns, us, ms or s)",
                "in.csv:4:8: error: `X0000` is not a device address",
                "in.csv:5:15: error: `2`: M0000 is a bit device, its value is 0 or 1",
                "in.csv:6:14: error: expected 3 fields `time, device, value`, found 2",
                "in.csv:7:23: error: expected 3 fields `time, device, value`, found 4; extra field",
                "in.csv:8:15: error: `PAUSE`: MODE takes RUN or STOP",
                "in.csv:9:1: error: bad time: `-1ms` is not a duration (a number followed by ns, \
                 us, ms or s)",
                "in.csv:9:8: error: `Q1` is not a device address",
                "in.csv:9:15: error: `h12345` is not a value (decimal -32768..=65535 or hex \
                 h0000..=hFFFF)",
                "in.csv:10:20: error: expected 3 fields `time, device, value`, found 4; extra \
                 field",
            ]
        );
    }

    #[test]
    fn value_errors() {
        let errs = errors("1ms, D00000, 65536\n1ms, D00000, -32769\n1ms, D00000,\n1ms,,1\n");
        assert_eq!(
            errs,
            vec![
                "in.csv:1:14: error: `65536` is out of range (-32768..=65535)",
                "in.csv:2:14: error: `-32769` is out of range (-32768..=65535)",
                "in.csv:3:13: error: missing value",
                "in.csv:4:5: error: missing device",
            ]
        );
        let errs = errors("1ms, P0000, h2\n1ms, MODE, ERROR\n1ms, _ON, 1\n1ms, P1280, 1\n");
        assert_eq!(
            errs,
            vec![
                "in.csv:1:13: error: `h2`: P0000 is a bit device, its value is 0 or 1",
                "in.csv:2:12: error: `ERROR`: MODE takes RUN or STOP",
                "in.csv:3:6: error: `_ON` is a system flag, a stimulus cannot drive it",
                "in.csv:4:6: error: `P1280` is out of range (P0000-P127F, P000-P127)",
            ]
        );
    }

    #[test]
    fn columns_count_characters() {
        // `µ` is two bytes but one column.
        let errs = errors("1µs, M0000, 9\n");
        assert_eq!(
            errs,
            vec!["in.csv:1:13: error: `9`: M0000 is a bit device, its value is 0 or 1"]
        );
    }

    #[test]
    fn switch_lines_turn_the_key_switch() {
        let text = "1ms, SWITCH, STOP\n2ms, switch, run\n3ms, Switch, Stop # mixed case\n";
        let expected = vec![
            switch(1_000_000, SwitchPosition::Stop, 1),
            switch(2_000_000, SwitchPosition::Run, 2),
            switch(3_000_000, SwitchPosition::Stop, 3),
        ];
        assert_eq!(ok(text), expected);
        let checked = parse_for(text, Path::new("in.csv"), &config(true)).unwrap();
        assert_eq!(checked, expected);
        assert_eq!(
            errors("1ms, SWITCH, 1\n2ms, SWITCH, DEBUG\n"),
            vec![
                "in.csv:1:14: error: `1`: SWITCH takes RUN or STOP",
                "in.csv:2:14: error: `DEBUG`: SWITCH takes RUN or STOP",
            ]
        );
    }

    #[test]
    fn a_switch_line_needs_a_switch_in_the_config() {
        let text = "1ms, P0000, 1\n# the key\n5ms,  SWITCH, STOP\n6ms, SWITCH, OFF\n";
        let diags = parse_for(text, Path::new("in.csv"), &config(false)).unwrap_err();
        let errs: Vec<String> = diags.iter().map(ToString::to_string).collect();
        assert_eq!(
            errs,
            vec![
                "in.csv:3:7: error: SWITCH: the config has no [switch], so there is no RUN/STOP \
                 key switch to turn",
                "in.csv:4:6: error: SWITCH: the config has no [switch], so there is no RUN/STOP \
                 key switch to turn",
                "in.csv:4:14: error: `OFF`: SWITCH takes RUN or STOP",
            ]
        );
        // Without SWITCH lines, any config will do.
        let plain = parse_for("1ms, P0000, 1\n", Path::new("in.csv"), &config(false)).unwrap();
        assert_eq!(plain, vec![dev(1_000_000, "P0000", 1, 1)]);
    }
}
