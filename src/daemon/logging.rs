//! The daemon's `log` backend: one line per record on stderr, in the form its reader expects.
//!
//! Under systemd stderr is normally a stream into journald, which timestamps every line itself
//! and, with `SyslogLevelPrefix=yes` (the default), takes a leading `<N>` as the line's syslog
//! priority. So there each line is `<N>message`: no timestamp, and the priority lets
//! `journalctl -p warning` and the red/bold highlighting work. journald makes every line its own
//! entry, so each continuation line of a multi-line message carries the prefix too, or it would
//! be logged at the default priority.
//!
//! Anywhere else (a terminal, a file, a pipe) nothing adds a time, so each record starts with a
//! UTC timestamp with milliseconds, computed here to avoid a date crate for fifteen lines.
//!
//! The module target is shown only at debug and trace, or for other crates' records: at the
//! levels an operator reads, plcd's own messages should be short and self-explanatory.
//!
//! Each record is formatted completely and then written with one `write_all` on locked stderr,
//! so lines from different threads never interleave. Write errors are ignored: a closed or
//! broken stderr must not take the PLC down.

use std::io::{self, Write};
use std::time::SystemTime;

use log::{Level, LevelFilter, Log, Metadata, Record, SetLoggerError};

/// How lines are formatted, chosen once at startup from where stderr goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// `<N>message`: stderr is connected to journald.
    Journal,
    /// `2026-11-21T10:46:48.123Z INFO  message`: anything else.
    Plain,
}

impl Style {
    /// The style for this process's stderr.
    pub fn detect() -> Style {
        let journal_stream = std::env::var("JOURNAL_STREAM").ok();
        let stderr = nix::sys::stat::fstat(io::stderr()).ok().map(|st| (st.st_dev, st.st_ino));
        Style::detect_from(journal_stream.as_deref(), stderr)
    }

    /// The style given `JOURNAL_STREAM` (`device:inode` of the journal stream systemd connected)
    /// and the device and inode of stderr. `INVOCATION_ID` or `JOURNAL_STREAM` alone are not
    /// enough, as systemd.exec(5) advises: both are inherited by processes whose stderr went
    /// elsewhere (`StandardError=file:…`, a shell in a terminal emulator run as a user service),
    /// where `<N>` prefixes would be noise and timestamps are needed.
    pub fn detect_from(
        journal_stream: Option<&str>,
        stderr: Option<(libc::dev_t, libc::ino_t)>,
    ) -> Style {
        let parsed = journal_stream.and_then(|s| {
            let (dev, ino) = s.split_once(':')?;
            Some((dev.parse::<libc::dev_t>().ok()?, ino.parse::<libc::ino_t>().ok()?))
        });
        match (parsed, stderr) {
            (Some(journal), Some(stderr)) if journal == stderr => Style::Journal,
            _ => Style::Plain,
        }
    }
}

/// Installs the stderr logger with the style detected from the environment, showing records up
/// to `level`. Fails if a logger is already installed.
pub fn init(level: LevelFilter) -> Result<(), SetLoggerError> {
    // Leaked because the logger lives as long as the process; `set_boxed_logger` would need
    // log's `std` feature for the same effect.
    let logger: &'static StderrLogger =
        Box::leak(Box::new(StderrLogger { style: Style::detect(), level }));
    log::set_logger(logger)?;
    log::set_max_level(level);
    Ok(())
}

struct StderrLogger {
    style: Style,
    level: LevelFilter,
}

impl Log for StderrLogger {
    fn enabled(&self, metadata: &Metadata) -> bool {
        // Cranelift (the code generator of `plcd-native`) logs each function it compiles, IR
        // and all, at info: only its warnings and errors are the operator's business.
        if metadata.target().starts_with("cranelift") {
            return metadata.level() <= Level::Warn && metadata.level() <= self.level;
        }
        effective_level(metadata) <= self.level
    }

    fn log(&self, record: &Record) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let formatted;
        let message = match record.args().as_str() {
            Some(message) => message,
            None => {
                formatted = record.args().to_string();
                &formatted
            }
        };
        let line =
            format_record(self.style, record.level(), record.target(), message, SystemTime::now());
        let _ = io::stderr().lock().write_all(line.as_bytes());
    }

    fn flush(&self) {
        let _ = io::stderr().lock().flush();
    }
}

/// The level a record is shown at. The OPC UA stack (`async-opcua`, through `tracing`) logs
/// every connection, handshake and session at info: those show at debug; its warnings and
/// errors (a certificate rejected, a session refused) as they are.
fn effective_level(metadata: &Metadata) -> Level {
    let target = metadata.target();
    let stack = target.starts_with("opcua") || target.starts_with("tracing::span");
    match metadata.level() {
        Level::Info if stack => Level::Debug,
        level => level,
    }
}

/// The text written for one record, ending in a newline; continuation lines of a multi-line
/// message each get their own prefix in [`Style::Journal`] and are written as they are in
/// [`Style::Plain`]. `now` is used only by [`Style::Plain`].
pub fn format_record(
    style: Style,
    level: Level,
    target: &str,
    message: &str,
    now: SystemTime,
) -> String {
    use std::fmt::Write as _;

    // A trailing newline would make journald log an empty entry.
    let message = message.trim_end_matches('\n');
    let show_target = level >= Level::Debug || !is_own_target(target);
    let mut out = String::with_capacity(message.len() + target.len() + 40);
    match style {
        Style::Journal => {
            let priority = syslog_priority(level);
            for (i, line) in message.split('\n').enumerate() {
                let _ = write!(out, "<{priority}>");
                if i == 0 && show_target {
                    let _ = write!(out, "{target}: ");
                }
                out.push_str(line);
                out.push('\n');
            }
        }
        Style::Plain => {
            plcd_core::timestamp::write_timestamp(&mut out, now);
            let _ = write!(out, " {:<5} ", level.as_str());
            if show_target {
                let _ = write!(out, "{target}: ");
            }
            out.push_str(message);
            out.push('\n');
        }
    }
    out
}

/// Targets of this crate and of the `plcd` binary (which shares its name).
fn is_own_target(target: &str) -> bool {
    const OWN: &str = env!("CARGO_CRATE_NAME");
    target.strip_prefix(OWN).is_some_and(|rest| rest.is_empty() || rest.starts_with("::"))
}

/// syslog(3) priorities: `log` has no notice level, so info is LOG_INFO and both debug and trace
/// are LOG_DEBUG.
fn syslog_priority(level: Level) -> u8 {
    match level {
        Level::Error => 3,
        Level::Warn => 4,
        Level::Info => 6,
        Level::Debug | Level::Trace => 7,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, UNIX_EPOCH};

    /// 2026-11-21T10:46:48.123Z
    fn at() -> SystemTime {
        UNIX_EPOCH + Duration::from_millis(1_795_258_008_123) + Duration::from_micros(999)
    }

    #[test]
    fn the_opc_ua_stacks_info_lines_show_at_debug() {
        let at = |target: &str, level: Level| {
            effective_level(&Metadata::builder().target(target).level(level).build())
        };
        assert_eq!(at("opcua_server::session::manager", Level::Info), Level::Debug);
        assert_eq!(at("tracing::span", Level::Info), Level::Debug);
        assert_eq!(at("opcua_crypto::certificate_store", Level::Error), Level::Error);
        assert_eq!(at("opcua_server::server", Level::Warn), Level::Warn);
        assert_eq!(at("plcd::services::opcua::server", Level::Info), Level::Info);
    }

    #[test]
    fn plain_lines() {
        let line =
            |level, target, message| format_record(Style::Plain, level, target, message, at());
        assert_eq!(
            line(Level::Info, "plcd", "started"),
            "2026-11-21T10:46:48.123Z INFO  started\n"
        );
        assert_eq!(line(Level::Error, "plcd::io", "lost"), "2026-11-21T10:46:48.123Z ERROR lost\n");
        assert_eq!(
            line(Level::Debug, "plcd::engine", "tick"),
            "2026-11-21T10:46:48.123Z DEBUG plcd::engine: tick\n"
        );
        assert_eq!(
            line(Level::Warn, "gpiocdev::chip", "busy"),
            "2026-11-21T10:46:48.123Z WARN  gpiocdev::chip: busy\n"
        );
        assert_eq!(line(Level::Info, "plcd", "a\nb\n"), "2026-11-21T10:46:48.123Z INFO  a\nb\n");
    }

    #[test]
    fn journal_lines() {
        let line =
            |level, target, message| format_record(Style::Journal, level, target, message, at());
        assert_eq!(line(Level::Error, "plcd", "e"), "<3>e\n");
        assert_eq!(line(Level::Warn, "plcd::io", "w"), "<4>w\n");
        assert_eq!(line(Level::Info, "plcd", "i"), "<6>i\n");
        assert_eq!(line(Level::Debug, "plcd::engine", "d"), "<7>plcd::engine: d\n");
        assert_eq!(line(Level::Trace, "plcd::vm", "t"), "<7>plcd::vm: t\n");
        assert_eq!(line(Level::Info, "plcdx", "i"), "<6>plcdx: i\n");
        assert_eq!(line(Level::Info, "plcd", ""), "<6>\n");
    }

    #[test]
    fn journal_continuation_lines_keep_the_priority() {
        assert_eq!(
            format_record(Style::Journal, Level::Warn, "plcd", "first\nsecond\n\nfourth\n", at()),
            "<4>first\n<4>second\n<4>\n<4>fourth\n"
        );
        assert_eq!(
            format_record(Style::Journal, Level::Debug, "plcd::io", "a\nb", at()),
            "<7>plcd::io: a\n<7>b\n"
        );
    }

    #[test]
    fn journal_only_when_stderr_is_the_journal_stream() {
        assert_eq!(Style::detect_from(None, Some((8, 1234))), Style::Plain);
        assert_eq!(Style::detect_from(Some("8:1234"), Some((8, 1234))), Style::Journal);
        assert_eq!(Style::detect_from(Some("8:1234"), Some((8, 999))), Style::Plain);
        assert_eq!(Style::detect_from(Some("8:1234"), None), Style::Plain);
        assert_eq!(Style::detect_from(Some("8"), Some((8, 1234))), Style::Plain);
        assert_eq!(Style::detect_from(Some(""), Some((8, 1234))), Style::Plain);
    }
}
