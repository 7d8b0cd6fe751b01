//! `get DEV…`, `set DEV=VALUE…`, `watch DEV…`: device values.

use std::time::{Duration, Instant, SystemTime};

use plcd_core::device::{Address, WORD_VALUES};
use plcd_ipc::{DeviceValue, Reply, Request};

use super::client::Answer;
use super::{format, json_line, parse_positive_duration, Session, EXIT_OK};

/// `get`'s arguments.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct GetArgs {
    /// Devices: `P0040`, `M0001`, `D00010`, `D00010.3`, `T0005`, `SM420`, `_T1S`, …
    #[arg(required = true, value_name = "DEV", value_parser = parse_device)]
    pub devices: Vec<String>,
}

/// `set`'s arguments.
#[derive(Debug, Clone, PartialEq, Eq, clap::Args)]
pub struct SetArgs {
    /// Devices and values, e.g. `D00010=-5 M0001=1 D00011=h7FFF`, written together at one
    /// END.
    #[arg(required = true, value_name = "DEV=VALUE", value_parser = parse_write)]
    pub writes: Vec<DeviceValue>,
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
    /// The devices to read.
    #[arg(required = true, value_name = "DEV", value_parser = parse_device)]
    pub devices: Vec<String>,
}

/// A device name, checked with [`Address::parse`] for an early error; sent as written (the
/// daemon resolves it).
pub fn parse_device(text: &str) -> Result<String, String> {
    Address::parse(text).map_err(|e| e.to_string())?;
    Ok(text.to_string())
}

/// `DEV=VALUE`.
pub fn parse_write(text: &str) -> Result<DeviceValue, String> {
    let Some((dev, value)) = text.split_once('=') else {
        return Err(format!("`{text}` is not DEV=VALUE"));
    };
    let dev = parse_device(dev.trim())?;
    let value = parse_value(value)?;
    Ok(DeviceValue { dev, value })
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

/// One `DEVICE  VALUE` line per device.
pub fn render_values(values: &[DeviceValue]) -> String {
    format::device_table(values)
}

/// `2 writes applied at the END of scan 1234`.
pub fn render_written(scan: u64, count: usize) -> String {
    let writes = if count == 1 { "1 write".to_string() } else { format!("{count} writes") };
    format!("{writes} applied at the END of scan {scan}\n")
}

/// A `get` every interval on one connection (a new one when the daemon closed it, idle, in
/// between), one line per sample, until `--count` samples or an error.
pub fn watch(session: &mut Session, args: &WatchArgs) -> u8 {
    let request = Request::Get { devices: args.devices.clone() };
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
                line.push_str(&format!("  {:<13}", format!("{}={}", v.dev, v.value)));
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
        assert_eq!(parse_write("D00010=-5"), Ok(DeviceValue { dev: "D00010".into(), value: -5 }));
        assert!(parse_write("D00010").unwrap_err().contains("DEV=VALUE"));
        assert!(parse_write("Q1=1").unwrap_err().contains("not a device"));
        assert!(parse_device("P0040").is_ok());
        assert!(parse_device("D99999").is_err());
    }

    #[test]
    fn ticks() {
        let ms = Duration::from_millis;
        assert_eq!(until_next_tick(ms(0), ms(500)), ms(500));
        assert_eq!(until_next_tick(ms(120), ms(500)), ms(380));
        assert_eq!(until_next_tick(ms(1_600), ms(500)), ms(400));
    }
}
