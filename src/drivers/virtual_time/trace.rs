//! The `--trace` file of `plcd sim` (docs/SIMULATION.md): one JSON object a line, in time order.
//!
//! The format is byte-exact, keys in a fixed order and no spaces, so that traces can be
//! compared with golden files:
//!
//! ```text
//! {"t_ns":6000000,"ev":"task_start","task":"io_p0"}
//! ```

use std::fmt::Write as _;
use std::io::{self, Write};

use crate::engine::event::{message_kind, task_name, Event, EventSink, TaskId};
use crate::symbols::Symbols;
use crate::value::ValueType;

/// Writes events as JSON Lines.
///
/// Names come from the tables given to [`TraceWriter::new`]; an id outside its table is written
/// as `#` and the number (`"task":"#9"`), which only a bug in the caller produces.
///
/// Each event is written with one `write_all`; give it a `BufWriter` for files. After the first
/// I/O error nothing more is written, and [`TraceWriter::finish`] returns that error.
pub struct TraceWriter<W: Write> {
    out: W,
    task_names: Vec<String>,
    watch_names: Vec<String>,
    /// The type of each watched variable (`None` for a device), to write its values.
    watch_types: Vec<Option<ValueType>>,
    /// The project's variables, to name what a watched reference points to.
    symbols: Symbols,
    program_lines: Vec<(String, Vec<u32>)>,
    line: String,
    error: Option<io::Error>,
}

impl<W: Write> TraceWriter<W> {
    /// `task_names` is indexed by [`TaskId`] (`scan`, `init`, then the configured tasks),
    /// `watch_names` by the `watch` of [`Event::Set`] (`"P0040"`), and `program_lines` by the
    /// `program` of an operation error: the program's name and the source line of each
    /// instruction (index = pc).
    pub fn new(
        out: W,
        task_names: Vec<String>,
        watch_names: Vec<String>,
        program_lines: Vec<(String, Vec<u32>)>,
    ) -> Self {
        TraceWriter {
            out,
            task_names,
            watch_names,
            watch_types: Vec::new(),
            symbols: Symbols::default(),
            program_lines,
            line: String::with_capacity(128),
            error: None,
        }
    }

    /// The types of the watched variables, by the `watch` of [`Event::SetVariable`]: how their
    /// values are written (a number, a `"T#1s500ms"` TIME, an enumeration value's name).
    pub fn with_types(mut self, watch_types: Vec<Option<ValueType>>) -> Self {
        self.watch_types = watch_types;
        self
    }

    /// The project's variables: a watched reference is written as the one it points to
    /// (`"main.buf[2]"`).
    pub fn with_symbols(mut self, symbols: Symbols) -> Self {
        self.symbols = symbols;
        self
    }

    /// The first write error, if one happened (the writer has stopped writing since).
    pub fn io_error(&self) -> Option<&io::Error> {
        self.error.as_ref()
    }

    /// Flushes and returns the output, or the first write error.
    pub fn finish(mut self) -> io::Result<W> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        self.out.flush()?;
        Ok(self.out)
    }

    /// Formats one event, without its newline, into `self.line`.
    fn format(&mut self, t_ns: u64, event: Event) {
        let line = &mut self.line;
        line.clear();
        // Writing into a String cannot fail.
        let _ = write!(line, "{{\"t_ns\":{t_ns},\"ev\":\"{}\"", event_name(&event));
        let names = &self.task_names;
        match event {
            Event::Mode(mode) => {
                let _ = write!(line, ",\"mode\":\"{}\"", mode.as_str());
            }
            Event::ScanStart { n } | Event::ScanEnd { n } => {
                let _ = write!(line, ",\"n\":{n}");
            }
            Event::TaskRequest { task }
            | Event::TaskStart { task }
            | Event::TaskEnd { task }
            | Event::TaskResume { task } => {
                push_str_field(line, "task", &task_name(names, task));
            }
            Event::TaskIgnored { task, why } => {
                push_str_field(line, "task", &task_name(names, task));
                push_str_field(line, "why", why.as_str());
            }
            Event::TaskPreempt { task, by } => {
                push_str_field(line, "task", &task_name(names, task));
                push_str_field(line, "by", &task_name(names, by));
            }
            Event::Set { watch, value } => {
                let dev = watch_name(&self.watch_names, watch);
                push_str_field(line, "dev", &dev);
                let _ = write!(line, ",\"value\":{value}");
            }
            Event::SetVariable { watch, slot } => {
                let dev = watch_name(&self.watch_names, watch);
                push_str_field(line, "dev", &dev);
                line.push_str(",\"value\":");
                match self.watch_types.get(usize::from(watch)) {
                    Some(Some(ty)) => push_json_value(line, ty, slot, &self.symbols),
                    _ => {
                        let _ = write!(line, "{slot}");
                    }
                }
            }
            Event::Error(kind) => {
                let (code, detail) = kind.describe(names, &self.program_lines);
                push_str_field(line, "code", &code);
                push_str_field(line, "detail", &detail);
            }
            Event::Switch(position) => {
                push_str_field(line, "position", position.as_str());
            }
        }
        line.push_str("}\n");
    }
}

impl<W: Write> TraceWriter<W> {
    fn write_line(&mut self) {
        if let Err(e) = self.out.write_all(self.line.as_bytes()) {
            self.error = Some(e);
        }
    }
}

impl<W: Write> EventSink for TraceWriter<W> {
    fn event(&mut self, t_ns: u64, event: Event) {
        if self.error.is_some() {
            return;
        }
        self.format(t_ns, event);
        self.write_line();
    }

    fn text(&mut self, t_ns: u64, watch: u16, text: &[u8]) {
        if self.error.is_some() {
            return;
        }
        let dev = watch_name(&self.watch_names, watch);
        let line = &mut self.line;
        line.clear();
        let _ = write!(line, "{{\"t_ns\":{t_ns},\"ev\":\"set\"");
        push_str_field(line, "dev", &dev);
        push_str_field(line, "value", &crate::value::decode_str(text));
        line.push_str("}\n");
        self.write_line();
    }

    fn wide_text(&mut self, t_ns: u64, watch: u16, units: &[u8]) {
        if self.error.is_some() {
            return;
        }
        let dev = watch_name(&self.watch_names, watch);
        let units = units.chunks_exact(2).map(|u| u16::from_le_bytes([u[0], u[1]]));
        let text: String = char::decode_utf16(units).map(|c| c.unwrap_or('\u{FFFD}')).collect();
        let line = &mut self.line;
        line.clear();
        let _ = write!(line, "{{\"t_ns\":{t_ns},\"ev\":\"set\"");
        push_str_field(line, "dev", &dev);
        push_str_field(line, "value", &text);
        line.push_str("}\n");
        self.write_line();
    }

    fn message(&mut self, t_ns: u64, task: TaskId, mask: u32, text: &[u8]) {
        if self.error.is_some() {
            return;
        }
        let line = &mut self.line;
        line.clear();
        let _ = write!(line, "{{\"t_ns\":{t_ns},\"ev\":\"message\"");
        push_str_field(line, "task", &task_name(&self.task_names, task));
        push_str_field(line, "kind", message_kind(mask));
        push_str_field(line, "text", &crate::value::decode_str(text));
        line.push_str("}\n");
        self.write_line();
    }

    fn messages_dropped(&mut self, t_ns: u64, task: TaskId, count: u32) {
        if self.error.is_some() {
            return;
        }
        let line = &mut self.line;
        line.clear();
        let _ = write!(line, "{{\"t_ns\":{t_ns},\"ev\":\"messages_dropped\"");
        push_str_field(line, "task", &task_name(&self.task_names, task));
        let _ = writeln!(line, ",\"count\":{count}}}");
        self.write_line();
    }
}

/// A watch's name, or `#` and its number for one outside the table (only a bug gives that).
fn watch_name(names: &[String], watch: u16) -> String {
    match names.get(usize::from(watch)) {
        Some(name) => name.clone(),
        None => format!("#{watch}"),
    }
}

/// Appends a variable's value as JSON: a number for integers, bit strings and reals (a real
/// that is not finite as the string `"NaN"`, `"inf"` or `"-inf"`), 0/1 for BOOL, a string for
/// TIME, DATE, TOD, DT and their long forms (IEC literals) and for an enumeration (its value's
/// name, or a number for a value that has none); for a reference, what it points to: one of
/// `symbols` or a device ([`crate::lang::reference_text`]).
pub fn push_json_value(line: &mut String, ty: &ValueType, slot: u64, symbols: &Symbols) {
    let text = match ty {
        ValueType::Reference { .. } => crate::lang::reference_text(symbols, slot),
        _ => crate::value::format(ty, slot),
    };
    let numeric = match ty {
        ValueType::Real(_) => text.parse::<f64>().is_ok_and(f64::is_finite),
        ValueType::Enum { .. } => text.parse::<i64>().is_ok(),
        ValueType::Time
        | ValueType::Calendar(_)
        | ValueType::String { .. }
        | ValueType::Char
        | ValueType::WChar
        | ValueType::Reference { .. } => false,
        _ => true,
    };
    if numeric {
        line.push_str(&text);
    } else {
        push_json_string(line, &text);
    }
}

/// The `ev` value of an event.
fn event_name(event: &Event) -> &'static str {
    match event {
        Event::Mode(_) => "mode",
        Event::ScanStart { .. } => "scan_start",
        Event::ScanEnd { .. } => "scan_end",
        Event::TaskRequest { .. } => "task_request",
        Event::TaskIgnored { .. } => "task_ignored",
        Event::TaskStart { .. } => "task_start",
        Event::TaskEnd { .. } => "task_end",
        Event::TaskPreempt { .. } => "task_preempt",
        Event::TaskResume { .. } => "task_resume",
        Event::Set { .. } | Event::SetVariable { .. } => "set",
        Event::Error(_) => "error",
        Event::Switch(_) => "switch",
    }
}

/// Appends `,"key":"value"` with `value` escaped.
fn push_str_field(line: &mut String, key: &str, value: &str) {
    line.push_str(",\"");
    line.push_str(key);
    line.push_str("\":");
    push_json_string(line, value);
}

/// Appends `value` as a JSON string literal.
fn push_json_string(line: &mut String, value: &str) {
    line.push('"');
    for c in value.chars() {
        match c {
            '"' => line.push_str("\\\""),
            '\\' => line.push_str("\\\\"),
            '\n' => line.push_str("\\n"),
            '\r' => line.push_str("\\r"),
            '\t' => line.push_str("\\t"),
            '\u{8}' => line.push_str("\\b"),
            '\u{c}' => line.push_str("\\f"),
            c if u32::from(c) < 0x20 || c == '\u{7f}' => {
                let _ = write!(line, "\\u{:04x}", u32::from(c));
            }
            c => line.push(c),
        }
    }
    line.push('"');
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::event::{ErrorKind, Ignored, Mode};

    fn writer() -> TraceWriter<Vec<u8>> {
        TraceWriter::new(
            Vec::new(),
            ["scan", "init", "fast", "io_p0"].map(String::from).to_vec(),
            ["P0040", "D00010"].map(String::from).to_vec(),
            vec![("main".to_string(), vec![3, 4, 17]), ("aux".to_string(), vec![])],
        )
    }

    #[test]
    fn a_reference_is_written_as_what_it_points_to() {
        let ty = ValueType::Reference { type_name: "POINTER TO INT".into() };
        let symbols: Symbols = vec![crate::value::Symbol {
            name: "main.s".into(),
            ty: ValueType::String { cap: 10 },
            at: crate::value::Pointer { space: crate::value::Space::Var, offset: 100 },
            retain: false,
            constant: false,
        }]
        .into();
        let json = |slot: u64| {
            let mut line = String::new();
            push_json_value(&mut line, &ty, slot, &symbols);
            line
        };
        let reference = |space, offset| {
            crate::value::Pointer { space, offset }.to_slot() + crate::value::REF_TAG
        };
        let d100 = crate::device::Address::parse("D00100").unwrap().as_word().unwrap();
        assert_eq!(json(0), r#""NULL""#);
        assert_eq!(json(reference(crate::value::Space::Word, u32::from(d100.0))), r#""D00100""#);
        assert_eq!(json(reference(crate::value::Space::Var, 24)), r#""vars+24""#);
        assert_eq!(json(reference(crate::value::Space::Var, 100)), r#""main.s""#);
        assert_eq!(json(reference(crate::value::Space::Var, 103)), r#""main.s+3""#);
        assert_eq!(json(reference(crate::value::Space::Var, 111)), r#""vars+111""#);
    }

    fn line(t_ns: u64, event: Event) -> String {
        let mut w = writer();
        w.event(t_ns, event);
        String::from_utf8(w.finish().unwrap()).unwrap()
    }

    #[test]
    fn one_line_per_event_kind() {
        let cases: Vec<(u64, Event, &str)> = vec![
            (0, Event::Mode(Mode::Run), r#"{"t_ns":0,"ev":"mode","mode":"RUN"}"#),
            (1, Event::Mode(Mode::Stop), r#"{"t_ns":1,"ev":"mode","mode":"STOP"}"#),
            (2, Event::Mode(Mode::Error), r#"{"t_ns":2,"ev":"mode","mode":"ERROR"}"#),
            (0, Event::ScanStart { n: 3 }, r#"{"t_ns":0,"ev":"scan_start","n":3}"#),
            (
                25_000_000,
                Event::ScanEnd { n: 18446744073709551615 },
                r#"{"t_ns":25000000,"ev":"scan_end","n":18446744073709551615}"#,
            ),
            (
                6_000_000,
                Event::TaskRequest { task: 3 },
                r#"{"t_ns":6000000,"ev":"task_request","task":"io_p0"}"#,
            ),
            (
                6_000_000,
                Event::TaskStart { task: 3 },
                r#"{"t_ns":6000000,"ev":"task_start","task":"io_p0"}"#,
            ),
            (
                8_000_000,
                Event::TaskEnd { task: 3 },
                r#"{"t_ns":8000000,"ev":"task_end","task":"io_p0"}"#,
            ),
            (
                8_000_000,
                Event::TaskResume { task: 0 },
                r#"{"t_ns":8000000,"ev":"task_resume","task":"scan"}"#,
            ),
            (
                7_000_000,
                Event::TaskIgnored { task: 3, why: Ignored::Running },
                r#"{"t_ns":7000000,"ev":"task_ignored","task":"io_p0","why":"running"}"#,
            ),
            (
                7,
                Event::TaskIgnored { task: 1, why: Ignored::Disabled },
                r#"{"t_ns":7,"ev":"task_ignored","task":"init","why":"disabled"}"#,
            ),
            (
                6_000_000,
                Event::TaskPreempt { task: 0, by: 3 },
                r#"{"t_ns":6000000,"ev":"task_preempt","task":"scan","by":"io_p0"}"#,
            ),
            (
                12,
                Event::Set { watch: 0, value: 1 },
                r#"{"t_ns":12,"ev":"set","dev":"P0040","value":1}"#,
            ),
            (
                13,
                Event::Set { watch: 1, value: -32768 },
                r#"{"t_ns":13,"ev":"set","dev":"D00010","value":-32768}"#,
            ),
            (
                200_000_000,
                Event::Error(ErrorKind::Watchdog { scan: 12, limit_ms: 200 }),
                r#"{"t_ns":200000000,"ev":"error","code":"WDT","detail":"scan 12 exceeded watchdog_ms 200"}"#,
            ),
            (
                5_000_001,
                Event::Error(ErrorKind::Congestion { task: 2, limit_ms: 5 }),
                r#"{"t_ns":5000001,"ev":"error","code":"CONGESTION","detail":"task fast exceeded max_exec_ms 5"}"#,
            ),
            (
                42,
                Event::Error(ErrorKind::Operation { code: 0x3405, task: 0, program: 0, pc: 2 }),
                r#"{"t_ns":42,"ev":"error","code":"3405H","detail":"task scan, program main, line 17"}"#,
            ),
            (
                43,
                Event::Error(ErrorKind::Operation { code: 0x2820, task: 2, program: 1, pc: 5 }),
                r#"{"t_ns":43,"ev":"error","code":"2820H","detail":"task fast, program aux, step 5"}"#,
            ),
            (
                44,
                Event::Error(ErrorKind::Operation { code: 0xab, task: 2, program: 9, pc: 0 }),
                r##"{"t_ns":44,"ev":"error","code":"00ABH","detail":"task fast, program #9, step 0"}"##,
            ),
            (
                45,
                Event::TaskPreempt { task: 2, by: 40 },
                r##"{"t_ns":45,"ev":"task_preempt","task":"fast","by":"#40"}"##,
            ),
            (
                46,
                Event::Set { watch: 7, value: 0 },
                r##"{"t_ns":46,"ev":"set","dev":"#7","value":0}"##,
            ),
        ];
        for (t_ns, event, expected) in cases {
            assert_eq!(line(t_ns, event), format!("{expected}\n"), "{event:?}");
        }
    }

    #[test]
    fn dates_and_times_of_day_are_literals_in_strings() {
        use crate::value::Calendar;
        let mut line = String::new();
        // 2024-03-01 12:30:15 is 1709296215 s after 1970-01-01.
        push_json_value(
            &mut line,
            &ValueType::Calendar(Calendar::Dt),
            1_709_296_215,
            &Symbols::default(),
        );
        line.push(' ');
        push_json_value(
            &mut line,
            &ValueType::Calendar(Calendar::LTod),
            1_500_000_000,
            &Symbols::default(),
        );
        assert_eq!(line, r#""DT#2024-03-01-12:30:15" "LTOD#00:00:01.5""#);
    }

    #[test]
    fn lines_follow_each_other() {
        let mut w = writer();
        w.event(0, Event::Mode(Mode::Run));
        w.event(0, Event::ScanStart { n: 1 });
        w.event(1_000, Event::Set { watch: 0, value: 1 });
        let bytes = w.finish().unwrap();
        assert_eq!(
            String::from_utf8(bytes).unwrap(),
            "{\"t_ns\":0,\"ev\":\"mode\",\"mode\":\"RUN\"}\n\
             {\"t_ns\":0,\"ev\":\"scan_start\",\"n\":1}\n\
             {\"t_ns\":1000,\"ev\":\"set\",\"dev\":\"P0040\",\"value\":1}\n"
        );
    }

    #[test]
    fn strings_and_characters_are_their_text() {
        let mut w = writer();
        // "Grüße" in Windows-1252
        w.text(1, 1, b"Gr\xfc\xdfe");
        // "Ω€" in UTF-16, little-endian
        w.wide_text(2, 1, &[0xA9, 0x03, 0xAC, 0x20]);
        let text = String::from_utf8(w.finish().unwrap()).unwrap();
        assert_eq!(
            text,
            "{\"t_ns\":1,\"ev\":\"set\",\"dev\":\"D00010\",\"value\":\"Grüße\"}\n\
             {\"t_ns\":2,\"ev\":\"set\",\"dev\":\"D00010\",\"value\":\"Ω€\"}\n"
        );
        let mut line = String::new();
        push_json_value(&mut line, &ValueType::Char, 0x80, &Symbols::default());
        line.push(' ');
        push_json_value(&mut line, &ValueType::WChar, 0x3A9, &Symbols::default());
        assert_eq!(line, r#""'$80'" "\"Ω\"""#);
    }

    #[test]
    fn names_are_escaped() {
        let mut w = TraceWriter::new(
            Vec::new(),
            vec!["a\"b\\c\n\t\u{1}\u{7f}é".to_string()],
            vec![],
            vec![],
        );
        w.event(5, Event::TaskStart { task: 0 });
        let text = String::from_utf8(w.finish().unwrap()).unwrap();
        assert_eq!(
            text,
            "{\"t_ns\":5,\"ev\":\"task_start\",\"task\":\"a\\\"b\\\\c\\n\\t\\u0001\\u007fé\"}\n"
        );
    }

    /// Accepts `budget` bytes, then fails every write.
    #[derive(Debug)]
    struct Failing {
        written: Vec<u8>,
        budget: usize,
        calls_after_failure: usize,
    }

    impl Write for Failing {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.written.len() + buf.len() > self.budget {
                self.calls_after_failure += 1;
                return Err(io::Error::new(io::ErrorKind::BrokenPipe, "closed"));
            }
            self.written.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn the_first_error_stops_writing_and_is_returned() {
        let out = Failing { written: Vec::new(), budget: 40, calls_after_failure: 0 };
        let mut w = TraceWriter::new(out, vec!["scan".into()], vec![], vec![]);
        w.event(0, Event::ScanStart { n: 1 });
        assert!(w.io_error().is_none());
        w.event(1, Event::ScanEnd { n: 1 });
        assert_eq!(w.io_error().map(io::Error::kind), Some(io::ErrorKind::BrokenPipe));
        w.event(2, Event::ScanStart { n: 2 });
        w.event(3, Event::ScanEnd { n: 2 });
        assert_eq!(w.out.calls_after_failure, 1);
        assert_eq!(w.out.written, b"{\"t_ns\":0,\"ev\":\"scan_start\",\"n\":1}\n");
        let err = w.finish().unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::BrokenPipe);
    }
}
