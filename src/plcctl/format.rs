//! Human output: durations in readable units, aligned columns, labelled fields, time stamps.

use std::time::SystemTime;

use plcd_ipc::{DeviceValue, NamedValue, Value};

/// A duration for a human, rounded to a resolution that suits its size: `850 ns`, `6.5 µs`,
/// `1.20 ms`, `2.50 s`. (The exact form, which reads back, is
/// [`plcd_core::duration::format_ns`].)
pub fn human_ns(ns: u64) -> String {
    let ns = u128::from(ns);
    if ns < 1_000 {
        return format!("{ns} ns");
    }
    let tenths_us = (ns + 50) / 100;
    if tenths_us < 10_000 {
        return format!("{}.{} µs", tenths_us / 10, tenths_us % 10);
    }
    let hundredths_ms = (ns + 5_000) / 10_000;
    if hundredths_ms < 100_000 {
        return format!("{}.{:02} ms", hundredths_ms / 100, hundredths_ms % 100);
    }
    let hundredths_s = (ns + 5_000_000) / 10_000_000;
    format!("{}.{:02} s", hundredths_s / 100, hundredths_s % 100)
}

/// An uptime: `42s`, `5m 06s`, `1h 02m 03s`, `3d 04h 05m 06s`.
pub fn human_uptime(ms: u64) -> String {
    let s = ms / 1000;
    let (d, h, m, s) = (s / 86_400, s / 3600 % 24, s / 60 % 60, s % 60);
    if d > 0 {
        format!("{d}d {h:02}h {m:02}m {s:02}s")
    } else if h > 0 {
        format!("{h}h {m:02}m {s:02}s")
    } else if m > 0 {
        format!("{m}m {s:02}s")
    } else {
        format!("{s}s")
    }
}

/// `P0000=1, D00010=-5`.
pub fn device_list(values: &[DeviceValue]) -> String {
    let items: Vec<String> = values.iter().map(|v| format!("{}={}", v.dev, v.value)).collect();
    items.join(", ")
}

/// `time` as `YYYY-MM-DDTHH:MM:SS.mmmZ` (UTC, rounded down to the millisecond), the daemon's
/// log format.
pub fn timestamp(time: SystemTime) -> String {
    let mut out = String::with_capacity(24);
    plcd_core::timestamp::write_timestamp(&mut out, time);
    out
}

/// How a column is aligned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    Left,
    Right,
}

/// Columns separated by two spaces, each as wide as its widest cell.
#[derive(Debug, Clone, Default)]
pub struct Table {
    align: Vec<Align>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table whose first row is `headers`.
    pub fn new(headers: &[(&str, Align)]) -> Table {
        Table {
            align: headers.iter().map(|(_, a)| *a).collect(),
            rows: vec![headers.iter().map(|(h, _)| h.to_string()).collect()],
        }
    }

    /// A table without headers.
    pub fn bare(align: &[Align]) -> Table {
        Table { align: align.to_vec(), rows: Vec::new() }
    }

    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }

    /// The lines, without trailing spaces, each ending with `\n`.
    pub fn render(&self) -> String {
        let columns = self.align.len();
        let mut widths = vec![0; columns];
        for row in &self.rows {
            for (w, cell) in widths.iter_mut().zip(row) {
                *w = (*w).max(cell.chars().count());
            }
        }
        let mut text = String::new();
        for row in &self.rows {
            let mut line = String::new();
            for (i, cell) in row.iter().enumerate().take(columns) {
                if i > 0 {
                    line.push_str("  ");
                }
                let pad = widths[i] - cell.chars().count();
                match self.align[i] {
                    Align::Left => {
                        line.push_str(cell);
                        line.extend(std::iter::repeat_n(' ', pad));
                    }
                    Align::Right => {
                        line.extend(std::iter::repeat_n(' ', pad));
                        line.push_str(cell);
                    }
                }
            }
            text.push_str(line.trim_end());
            text.push('\n');
        }
        text
    }
}

/// Labelled fields, the values aligned after the longest label; a value of several lines
/// continues under its first.
pub fn fields(fields: &[(&str, Vec<String>)]) -> String {
    let width = fields.iter().map(|(label, _)| label.chars().count()).max().unwrap_or(0);
    let mut text = String::new();
    for (label, lines) in fields {
        for (i, line) in lines.iter().enumerate() {
            let head = if i == 0 { *label } else { "" };
            let row = format!("{head:width$}  {line}");
            text.push_str(row.trim_end());
            text.push('\n');
        }
    }
    text
}

/// A value for a human: a number or text as the daemon sent it, a `STRING` as an IEC literal
/// (`'it$'s'`), so that what `set` reads back is what it shows.
pub fn value_text(v: &NamedValue) -> String {
    match (&v.value, v.ty.as_deref()) {
        (Value::Text(text), Some(ty)) if ty.starts_with("STRING") => {
            plcd_core::value::format_string(text.as_bytes())
        }
        (Value::Text(text), Some(ty)) if ty.starts_with("WSTRING") => {
            let units: Vec<u16> = text.encode_utf16().collect();
            plcd_core::value::format_wstring(&units)
        }
        (value, _) => value.to_string(),
    }
}

/// One `NAME  VALUE  TYPE` line per device or variable, aligned (a device has no type).
pub fn value_table(values: &[NamedValue]) -> String {
    let mut table = Table::bare(&[Align::Left, Align::Right, Align::Left]);
    for v in values {
        table.row(vec![v.dev.clone(), value_text(v), v.ty.clone().unwrap_or_default()]);
    }
    table.render()
}

/// One `DEVICE  VALUE` line per device, aligned.
pub fn device_table(values: &[DeviceValue]) -> String {
    let mut table = Table::bare(&[Align::Left, Align::Right]);
    for v in values {
        table.row(vec![v.dev.clone(), v.value.to_string()]);
    }
    table.render()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, UNIX_EPOCH};

    #[test]
    fn durations() {
        assert_eq!(human_ns(0), "0 ns");
        assert_eq!(human_ns(999), "999 ns");
        assert_eq!(human_ns(1_000), "1.0 µs");
        assert_eq!(human_ns(6_500), "6.5 µs");
        assert_eq!(human_ns(6_549), "6.5 µs");
        assert_eq!(human_ns(6_550), "6.6 µs");
        assert_eq!(human_ns(999_949), "999.9 µs");
        assert_eq!(human_ns(999_950), "1.00 ms");
        assert_eq!(human_ns(1_200_000), "1.20 ms");
        assert_eq!(human_ns(48_123_456), "48.12 ms");
        assert_eq!(human_ns(999_995_000), "1.00 s");
        assert_eq!(human_ns(2_500_000_000), "2.50 s");
        assert_eq!(human_ns(u64::MAX), "18446744073.71 s");
    }

    #[test]
    fn uptimes() {
        assert_eq!(human_uptime(999), "0s");
        assert_eq!(human_uptime(42_000), "42s");
        assert_eq!(human_uptime(306_000), "5m 06s");
        assert_eq!(human_uptime(3_723_000), "1h 02m 03s");
        assert_eq!(human_uptime(273_906_000), "3d 04h 05m 06s");
    }

    #[test]
    fn timestamps() {
        let at = UNIX_EPOCH + Duration::from_millis(1_795_258_008_123) + Duration::from_micros(999);
        assert_eq!(timestamp(at), "2026-11-21T10:46:48.123Z");
        assert_eq!(timestamp(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
    }

    #[test]
    fn typed_values() {
        let typed = |dev: &str, value: Value, ty: &str| NamedValue {
            dev: dev.into(),
            value,
            ty: Some(ty.into()),
        };
        assert_eq!(
            value_table(&[
                NamedValue::device("D00010", -5),
                typed("main.t1.ET", "T#1s500ms".into(), "TIME"),
                typed("main.s", "it's".into(), "STRING[80]"),
                typed("main.mode", "Running".into(), "Mode"),
            ]),
            "D00010             -5\n\
             main.t1.ET  T#1s500ms  TIME\n\
             main.s        'it$'s'  STRING[80]\n\
             main.mode     Running  Mode\n"
        );
    }

    #[test]
    fn tables_align() {
        let mut t = Table::new(&[("NAME", Align::Left), ("RUNS", Align::Right)]);
        t.row(vec!["fast".into(), "12345".into()]);
        t.row(vec!["a".into(), "7".into()]);
        assert_eq!(t.render(), "NAME   RUNS\nfast  12345\na         7\n");
        assert_eq!(
            fields(&[("mode", vec!["RUN".into()]), ("debug", vec!["a".into(), "b".into()])]),
            "mode   RUN\ndebug  a\n       b\n"
        );
    }
}
