//! `get NAME…`, `set NAME=VALUE…`, `watch NAME…`: values of devices and Structured Text
//! variables. A name is a device (`D00010`, `P0040`) or a variable (`main.speed`,
//! `main.m[1,2]`, `main.pid`, a global); the daemon resolves it against the running project.

use std::time::{Duration, Instant, SystemTime};

use plcd_core::device::{Address, WORD_VALUES};
use plcd_core::project::split_names;
use plcd_ipc::{NamedValue, Reply, Request, Value};

use super::client::Answer;
use super::{format, json_line, parse_positive_duration, Session, EXIT_OK};

/// `get`'s arguments.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct GetArgs {
    /// Devices (`P0040`, `D00010`, `D00010.3`, `T0005`, `SM420`, `_T1S`, …) and Structured
    /// Text variables (`main.speed`, `main.buf[3]`, `main.m[1,2]`, a global; a structure,
    /// array or instance such as `main.pid` for each of its variables); commas also separate.
    #[arg(required = true, value_name = "NAME", value_parser = parse_name)]
    pub names: Vec<String>,
}

impl GetArgs {
    pub fn request(&self) -> Request {
        Request::Get { devices: names(&self.names) }
    }
}

/// `set`'s arguments.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct SetArgs {
    /// Devices and variables with their values, as `NAME=VALUE` or `NAME VALUE`, written
    /// together at one END: `D00010=-5 M0001=1 D00011=h7FFF`, `main.speed 5`, `main.t T#2s`,
    /// `main.mode Running`, `main.s 'hello'` (a value that starts with `-` and is no number
    /// goes after `=`: `main.r=-inf`).
    #[arg(required = true, value_name = "NAME=VALUE", allow_negative_numbers = true)]
    pub writes: Vec<String>,
}

impl SetArgs {
    pub fn request(&self) -> Result<Request, String> {
        parse_writes(&self.writes).map(|writes| Request::Set { writes })
    }
}

/// `watch`'s arguments.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct WatchArgs {
    /// Time between two samples.
    #[arg(long, value_name = "DURATION", default_value = "500ms",
        value_parser = parse_positive_duration)]
    pub interval: Duration,
    /// Stop after N samples (default: run until interrupted).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub count: Option<u64>,
    /// The devices and variables to read, as for `get`.
    #[arg(required = true, value_name = "NAME", value_parser = parse_name)]
    pub names: Vec<String>,
}

/// A device or variable name, sent as written (the daemon resolves it; names are
/// case-insensitive).
pub fn parse_name(text: &str) -> Result<String, String> {
    if text.trim().is_empty() {
        return Err("a name is empty".to_string());
    }
    Ok(text.trim().to_string())
}

/// The names of the command line, a comma list split outside `[…]` (`main.m[1,2],P0040`).
pub fn names(args: &[String]) -> Vec<String> {
    args.iter().flat_map(|a| split_names(a)).map(str::to_string).collect()
}

/// `NAME=VALUE` (split at the first `=`) or `NAME VALUE`, left to right: a word without `=`
/// is a name and the next word its value, whatever it holds.
pub fn parse_writes(words: &[String]) -> Result<Vec<NamedValue>, String> {
    let mut writes = Vec::new();
    let mut words = words.iter();
    while let Some(word) = words.next() {
        let (name, value) = match word.split_once('=') {
            Some((name, value)) => (name, value.to_string()),
            None => match words.next() {
                Some(value) => (word.as_str(), value.clone()),
                None => {
                    return Err(format!("`{word}` has no value: write NAME=VALUE or NAME VALUE"))
                }
            },
        };
        writes.push(parse_write_of(name, &value)?);
    }
    Ok(writes)
}

/// One write: a device's value is parsed here (decimal or hex, 16 bits), a variable's is sent
/// as written, for the daemon to read against the variable's type.
fn parse_write_of(name: &str, value: &str) -> Result<NamedValue, String> {
    let name = parse_name(name)?;
    if Address::parse(&name).is_ok() {
        return Ok(NamedValue::device(name, parse_value(value)?));
    }
    Ok(NamedValue::write(name, Value::Text(value.to_string())))
}

/// `DEV=VALUE` or `NAME=VALUE`: one write.
pub fn parse_write(text: &str) -> Result<NamedValue, String> {
    let Some((name, value)) = text.split_once('=') else {
        return Err(format!("`{text}` is not NAME=VALUE"));
    };
    parse_write_of(name.trim(), value)
}

/// A value as the instruction list writes constants: decimal `-32768` to `65535`, or hex
/// `h0` to `hFFFF` (also `0x0` to `0xFFFF`). Values above 32767 are sent as the signed
/// 16-bit value of the same bit pattern (`65535` and `hFFFF` as -1).
pub fn parse_value(text: &str) -> Result<i32, String> {
    let t = text.trim();
    let hex = t
        .strip_prefix(['h', 'H'])
        .or_else(|| t.strip_prefix("0x"))
        .or_else(|| t.strip_prefix("0X"));
    let bad = || format!("`{t}` is not a value (decimal -32768 to 65535, or hex h0 to hFFFF)");
    let value: i64 = match hex {
        Some(digits) => {
            if digits.is_empty() || !digits.chars().all(|c| c.is_ascii_hexdigit()) {
                return Err(bad());
            }
            i64::from_str_radix(digits, 16).map_err(|_| bad())?
        }
        None => t.parse().map_err(|_| bad())?,
    };
    if !(i64::from(*WORD_VALUES.start())..=i64::from(*WORD_VALUES.end())).contains(&value) {
        return Err(bad());
    }
    Ok(if value > 32767 { (value - 65536) as i32 } else { value as i32 })
}

/// One `NAME  VALUE  TYPE` line per device or variable (devices have no type).
pub fn render_values(values: &[NamedValue]) -> String {
    format::value_table(values)
}

/// `2 writes applied at the END of scan 1234`.
pub fn render_written(scan: u64, count: usize) -> String {
    let writes = if count == 1 { "1 write".to_string() } else { format!("{count} writes") };
    format!("{writes} applied at the END of scan {scan}\n")
}

/// A `get` every interval on one connection (a new one when the daemon closed it, idle, in
/// between), one line per sample, until `--count` samples or an error.
pub fn watch(session: &mut Session, args: &WatchArgs) -> u8 {
    let request = Request::Get { devices: names(&args.names) };
    let mut client = match session.connect() {
        Ok(client) => client,
        Err(e) => return session.fail(&e),
    };
    let start = Instant::now();
    let mut samples = 0u64;
    loop {
        let answer = match client.exchange(&request) {
            // The daemon closes connections idle for `[control] idle_timeout_s`; a get can be
            // asked again.
            Err(e) if e.is_closed() => match session.connect() {
                Ok(fresh) => {
                    client = fresh;
                    client.exchange(&request)
                }
                Err(e) => Err(e),
            },
            other => other,
        };
        let answer = match answer {
            Ok(answer) => answer,
            Err(e) => return session.fail(&e),
        };
        let line = sample_line(session.json, SystemTime::now(), &request, &answer);
        // A closed stdout (`plcctl watch … | head`) ends the watch.
        if session.out.write_all(line.as_bytes()).and_then(|()| session.out.flush()).is_err() {
            return EXIT_OK;
        }
        samples += 1;
        if args.count.is_some_and(|count| samples >= count) {
            return EXIT_OK;
        }
        std::thread::sleep(until_next_tick(start.elapsed(), args.interval));
    }
}

/// One sample: `2026-11-21T10:46:48.123Z  scan 1234  D00010=7       P0040=1`, or with
/// `--json` the `values` object with a `"time"` field added.
pub fn sample_line(json: bool, now: SystemTime, request: &Request, answer: &Answer) -> String {
    let time = format::timestamp(now);
    if json {
        let mut raw = answer.raw.clone();
        if let Some(object) = raw.as_object_mut() {
            object.insert("time".to_string(), serde_json::Value::String(time));
        }
        return json_line(&raw);
    }
    match &answer.reply {
        Reply::Values { scan, values } => {
            let mut line = format!("{time}  scan {scan}");
            for v in values {
                // Wide enough for any 16-bit value, so that columns stay put.
                line.push_str(&format!("  {:<13}", format!("{}={}", v.dev, format::value_text(v))));
            }
            let mut line = line.trim_end().to_string();
            line.push('\n');
            line
        }
        other => super::render(request, other),
    }
}

/// The wait until the next multiple of `interval` since the start: samples keep their rhythm,
/// and a slow answer skips ticks instead of bunching them.
fn until_next_tick(elapsed: Duration, interval: Duration) -> Duration {
    let interval_ns = interval.as_nanos().max(1);
    let elapsed_ns = elapsed.as_nanos();
    let next = (elapsed_ns / interval_ns + 1) * interval_ns;
    Duration::from_nanos((next - elapsed_ns) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values() {
        assert_eq!(parse_value("0"), Ok(0));
        assert_eq!(parse_value("-32768"), Ok(-32768));
        assert_eq!(parse_value("65535"), Ok(-1));
        assert_eq!(parse_value("32768"), Ok(-32768));
        assert_eq!(parse_value("hFFFF"), Ok(-1));
        assert_eq!(parse_value("H7fff"), Ok(32767));
        assert_eq!(parse_value("0x10"), Ok(16));
        for bad in ["", "x", "65536", "-32769", "h", "h-1", "0x+1", "1.5", "h10000"] {
            assert!(parse_value(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn writes() {
        assert_eq!(parse_write("D00010=-5"), Ok(NamedValue::device("D00010", -5)));
        assert!(parse_write("D00010").unwrap_err().contains("NAME=VALUE"));
        assert!(parse_write("D00010=x").unwrap_err().contains("not a value"));
        assert_eq!(parse_write("main.x=1"), Ok(NamedValue::write("main.x", "1".into())));
        assert!(parse_name(" ").is_err());
    }

    #[test]
    fn names_and_values_in_both_forms() {
        let words = |w: &[&str]| w.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let text = |name: &str, value: &str| NamedValue::write(name, Value::from(value));
        assert_eq!(
            parse_writes(&words(&[
                "main.speed",
                "5",
                "D10=h7FFF",
                "main.s",
                "a=b",
                "main.m[1,2]=-3",
                "main.t",
                "T#2s",
                "M0001",
                "1",
                "main.e=x=y"
            ])),
            Ok(vec![
                text("main.speed", "5"),
                NamedValue::device("D10", 32767),
                text("main.s", "a=b"),
                text("main.m[1,2]", "-3"),
                text("main.t", "T#2s"),
                NamedValue::device("M0001", 1),
                text("main.e", "x=y"),
            ])
        );
        assert!(parse_writes(&words(&["main.speed"])).unwrap_err().contains("no value"));
        assert!(parse_writes(&words(&["D10", "x"])).unwrap_err().contains("not a value"));
        assert_eq!(
            names(&words(&["main.m[1,2],P0040", "main.pid"])),
            ["main.m[1,2]", "P0040", "main.pid"]
        );
    }

    #[test]
    fn ticks() {
        let ms = Duration::from_millis;
        assert_eq!(until_next_tick(ms(0), ms(500)), ms(500));
        assert_eq!(until_next_tick(ms(120), ms(500)), ms(380));
        assert_eq!(until_next_tick(ms(1_600), ms(500)), ms(400));
    }
}
