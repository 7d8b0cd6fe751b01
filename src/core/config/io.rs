//! `[io]`, `[[io.input]]` and `[[io.output]]`: the backend, the chip, and the P bits wired to
//! its lines. How the lines make up the gpiocdev backend's line requests is [`super::wiring`].
//!
//! A `line` (here and in `[switch]`) is an offset on the chip or the kernel's name of a line
//! ([`LineRef`]). What the config alone can say about a name is checked here: it is not empty,
//! not longer than the kernel reports, not a number in quotes, and no two entries name the same
//! line. Whether the chip has it, and whether a name and an offset are one line, only the chip
//! can say: names are resolved when `plcd run` opens it ([`super::wiring`]).

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::de::{self, IgnoredAny, Visitor};
use serde::{Deserialize, Deserializer};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use super::common::{entries, int, peek_str, resolve, section, Ctx, Located};
use super::wiring::Place;
use super::{RawDoc, Sink};
use crate::device::{Address, Area};

/// `[io]`: where the P image's inputs come from and its outputs go.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct IoConfig {
    /// `backend`: `"sim"` (default, in-process) or `"gpiocdev"` (Linux GPIO character device).
    pub backend: Backend,
    /// `chip`: the GPIO chip, a path (`/dev/gpiochip0`, starting with `/`), a name under
    /// `/dev` or a label (at most [`LINE_NAME_MAX`] bytes); required for gpiocdev, ignored by
    /// sim. Default none.
    pub chip: Option<String>,
    /// `[[io.input]]`, in file order. Devices and lines are unique across inputs and outputs.
    pub inputs: Vec<IoLine>,
    /// `[[io.output]]`, in file order (`bias` and `debounce_us` are not allowed).
    pub outputs: Vec<IoLine>,
    /// `stimulus`: a CSV of input changes (docs/SIMULATION.md) for the sim backend, resolved relative
    /// to the config file; default none. An error with gpiocdev, whose inputs are the lines.
    pub stimulus: Option<PathBuf>,
    /// `stimulus_loop`: replay the stimulus from the start when it ends; default false.
    pub stimulus_loop: bool,
}

/// `io.backend`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    #[default]
    Sim,
    Gpiocdev,
}

impl Backend {
    /// The value as `[io] backend` writes it (and the log and `plcctl status` show it).
    pub fn as_str(self) -> &'static str {
        match self {
            Backend::Sim => "sim",
            Backend::Gpiocdev => "gpiocdev",
        }
    }
}

/// One `[[io.input]]` or `[[io.output]]`: a P bit wired to a GPIO line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IoLine {
    /// `device`: a P bit (P0000..=P127F); required.
    pub device: Address,
    /// `line`: the line on the chip, an offset or a name; required.
    pub line: LineRef,
    /// `active_low`: the device is ON when the line is low; default false.
    pub active_low: bool,
    /// `bias`: inputs only, `"disabled"` (default), `"pull-up"` or `"pull-down"`.
    pub bias: Bias,
    /// `debounce_us`: inputs only, 0..=4294967295 µs; default 0 (none).
    pub debounce_us: u32,
}

/// `line` of `[[io.input]]`, `[[io.output]]` and `[switch]`: which line of the `[io]` chip.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum LineRef {
    /// An integer: the line's offset on the chip, 0..=4294967295.
    Offset(u32),
    /// A string: the line's name as the kernel reports it (`"GPIO17"`), 1..=[`LINE_NAME_MAX`]
    /// bytes and not only digits. `plcd run` looks it up on the chip when it opens it.
    Name(String),
}

/// The longest line name (and chip label) the kernel reports: its GPIO uAPI carries them in 32
/// bytes (`GPIO_MAX_NAME_SIZE`), the terminating NUL included, and cuts longer ones there. A
/// longer name or label in the config could never match.
pub const LINE_NAME_MAX: usize = 31;

impl LineRef {
    /// The offset, if the line is given by one.
    pub fn offset(&self) -> Option<u32> {
        match self {
            LineRef::Offset(offset) => Some(*offset),
            LineRef::Name(_) => None,
        }
    }

    /// The name, if the line is given by one.
    pub fn name(&self) -> Option<&str> {
        match self {
            LineRef::Offset(_) => None,
            LineRef::Name(name) => Some(name),
        }
    }
}

/// As messages write it: `17`, or the name in quotes, `"GPIO17"`.
impl fmt::Display for LineRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LineRef::Offset(offset) => write!(f, "{offset}"),
            LineRef::Name(name) => write!(f, "{name:?}"),
        }
    }
}

/// `line` as written: an integer or a string, checked by [`line_ref`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum RawLine {
    Offset(i64),
    Name(String),
}

impl RawLine {
    /// Whether this is `line`, as the uniqueness checks compare lines: offsets by value, names
    /// as written (the kernel's names are case-sensitive).
    pub fn is(&self, line: &LineRef) -> bool {
        match (self, line) {
            (RawLine::Offset(a), LineRef::Offset(b)) => *a == i64::from(*b),
            (RawLine::Name(a), LineRef::Name(b)) => a == b,
            _ => false,
        }
    }
}

impl<'de> Deserialize<'de> for RawLine {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct LineVisitor;

        impl Visitor<'_> for LineVisitor {
            type Value = RawLine;

            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a line offset (an integer) or a line name (a string)")
            }

            fn visit_i64<E: de::Error>(self, v: i64) -> Result<RawLine, E> {
                Ok(RawLine::Offset(v))
            }

            fn visit_u64<E: de::Error>(self, v: u64) -> Result<RawLine, E> {
                // Past i64 it is out of range all the same; say so with the number.
                i64::try_from(v)
                    .map(RawLine::Offset)
                    .map_err(|_| E::invalid_value(de::Unexpected::Unsigned(v), &self))
            }

            fn visit_str<E: de::Error>(self, v: &str) -> Result<RawLine, E> {
                Ok(RawLine::Name(v.to_string()))
            }
        }

        deserializer.deserialize_any(LineVisitor)
    }
}

/// A `line` as written, checked: an offset in range, or a name the kernel could report.
pub(super) fn line_ref(sink: &mut Sink, ctx: &Ctx, line: &Spanned<RawLine>) -> Option<LineRef> {
    let at = line.span().start;
    let key = ctx.key("line");
    let message = match line.get_ref() {
        RawLine::Offset(offset) => {
            let offset = Spanned::new(line.span(), *offset);
            return int(sink, ctx, "line", &offset, 0..=i64::from(u32::MAX)).map(LineRef::Offset);
        }
        RawLine::Name(name) if name.is_empty() => {
            format!("{key} must not be empty: a line name (\"GPIO17\") or an offset (17)")
        }
        RawLine::Name(name) if name.len() > LINE_NAME_MAX => format!(
            "{key} {name:?} is {} bytes long, but the kernel reports line names of at most \
             {LINE_NAME_MAX} bytes: no line is named so",
            name.len()
        ),
        RawLine::Name(name) if name.bytes().all(|b| b.is_ascii_digit()) => format!(
            "{key} {name:?} is a number in quotes: an offset is written without them \
             (line = {name})"
        ),
        RawLine::Name(name) => return Some(LineRef::Name(name.clone())),
    };
    sink.error(at, message);
    None
}

/// `bias` of an input line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Bias {
    #[default]
    Disabled,
    PullUp,
    PullDown,
}

/// `[io]` without `input` and `output`, which are read entry by entry; they are declared here
/// only so that an unknown key's message lists them among the expected ones.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawIo {
    #[serde(default)]
    pub backend: Backend,
    pub chip: Option<Spanned<String>>,
    pub stimulus: Option<Spanned<String>>,
    #[serde(default)]
    pub stimulus_loop: bool,
    #[serde(rename = "input")]
    _input: Option<IgnoredAny>,
    #[serde(rename = "output")]
    _output: Option<IgnoredAny>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInput {
    pub device: Spanned<String>,
    pub line: Spanned<RawLine>,
    #[serde(default)]
    pub active_low: bool,
    #[serde(default)]
    pub bias: Bias,
    pub debounce_us: Option<Spanned<i64>>,
}

/// An output line. `bias` and `debounce_us` are accepted here only to be rejected by
/// `validate` with a clearer message than serde's "unknown field".
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOutput {
    pub device: Spanned<String>,
    pub line: Spanned<RawLine>,
    #[serde(default)]
    pub active_low: bool,
    pub bias: Option<Spanned<IgnoredAny>>,
    pub debounce_us: Option<Spanned<IgnoredAny>>,
}

pub(super) fn read(sink: &mut Sink, io: Option<Spanned<DeValue<'_>>>, doc: &mut RawDoc) {
    let Some(io) = io else {
        let (span, ctx) = (0..0, Ctx::Section("io"));
        doc.io = Some(Located { span, ctx, value: RawIo::default() });
        return;
    };
    let span = io.span();
    let DeValue::Table(mut table) = io.into_inner() else {
        sink.error(span.start, "`io` must be a table, written [io]");
        doc.failed.input = true;
        return;
    };
    let input = table.remove("input");
    let output = table.remove("output");
    let io = Spanned::new(span.clone(), DeValue::Table(table));
    doc.io = section(sink, Some(io), "io", &mut doc.failed.keys).map(|value| Located {
        span,
        ctx: Ctx::Section("io"),
        value,
    });
    let device = |table: &DeTable| peek_str(table, "device");
    doc.inputs = entries(sink, input, "io.input", device)
        .into_iter()
        .filter_map(|entry| entry.map_err(|_| doc.failed.input = true).ok())
        .collect();
    doc.outputs =
        entries(sink, output, "io.output", device).into_iter().filter_map(Result::ok).collect();
}

pub(super) fn validate(
    sink: &mut Sink,
    raw: Option<Located<RawIo>>,
    inputs: Vec<Located<RawInput>>,
    outputs: Vec<Located<RawOutput>>,
    failed: &[String],
    config: &Path,
) -> Option<(IoConfig, Vec<Place>, Vec<Place>)> {
    let mut ok = raw.is_some();
    let mut config_io = IoConfig::default();
    if let Some(Located { span, ctx, value: raw }) = raw {
        config_io.backend = raw.backend;
        config_io.stimulus_loop = raw.stimulus_loop;
        match raw.chip {
            Some(chip) if chip.get_ref().trim().is_empty() => {
                sink.error(chip.span().start, format!("{} must not be empty", ctx.key("chip")));
                ok = false;
            }
            // The kernel reports labels cut to the size it reports line names in: a longer
            // one would never match (found out on gpio-sim, whose labels are the user's).
            Some(chip)
                if !chip.get_ref().starts_with('/') && chip.get_ref().len() > LINE_NAME_MAX =>
            {
                let message = format!(
                    "{} {:?} is {} bytes long, but the kernel reports chip labels of at most \
                     {LINE_NAME_MAX} bytes: no chip is labelled so (a path starts with `/`)",
                    ctx.key("chip"),
                    chip.get_ref(),
                    chip.get_ref().len()
                );
                sink.error(chip.span().start, message);
                ok = false;
            }
            Some(chip) => config_io.chip = Some(chip.into_inner()),
            // A malformed chip is reported already, not missing.
            None if raw.backend == Backend::Gpiocdev && !failed.iter().any(|k| k == "io.chip") => {
                let message = format!("{} is required for the gpiocdev backend", ctx.key("chip"));
                sink.error(span.start, message);
                ok = false;
            }
            None => {}
        }
        match raw.stimulus {
            // Inputs come from the chip's lines: a stimulus would be silently unused.
            Some(file) if raw.backend == Backend::Gpiocdev => {
                let message = format!(
                    "{} is for the sim backend: the gpiocdev backend reads its inputs from the \
                     chip's lines",
                    ctx.key("stimulus")
                );
                sink.error(file.span().start, message);
                ok = false;
            }
            Some(file) if file.get_ref().trim().is_empty() => {
                sink.error(file.span().start, format!("{} must not be empty", ctx.key("stimulus")));
                ok = false;
            }
            Some(file) => config_io.stimulus = Some(resolve(config, file.get_ref())),
            None => {}
        }
    }

    // Inputs and outputs share the P image and the chip, so devices and lines are unique
    // across both; the later one in the file is the one reported. Lines are compared as
    // written: two offsets, or two names; whether a name is an offset's line only the chip says.
    let mut wired: Vec<Wired> = Vec::new();
    for input in inputs {
        let Located { span, ctx, value: raw } = input;
        let debounce_us = match &raw.debounce_us {
            Some(value) => int(sink, &ctx, "debounce_us", value, 0..=i64::from(u32::MAX)),
            None => Some(0),
        };
        let line = io_line(sink, &ctx, &raw.device, &raw.line, raw.active_low);
        match (line, debounce_us) {
            (Some(line), Some(debounce_us)) => wired.push(Wired {
                at: span.start,
                line: IoLine { bias: raw.bias, debounce_us, ..line },
                input: true,
                device_at: raw.device.span().start,
                line_at: raw.line.span().start,
                ctx,
            }),
            _ => ok = false,
        }
    }
    for output in outputs {
        let Located { span, ctx, value: raw } = output;
        for (key, value) in [("bias", &raw.bias), ("debounce_us", &raw.debounce_us)] {
            if let Some(value) = value {
                let message = format!("{}: {key} is only for inputs", ctx.subject());
                sink.error(value.span().start, message);
                ok = false;
            }
        }
        match io_line(sink, &ctx, &raw.device, &raw.line, raw.active_low) {
            Some(line) => wired.push(Wired {
                at: span.start,
                line,
                input: false,
                device_at: raw.device.span().start,
                line_at: raw.line.span().start,
                ctx,
            }),
            None => ok = false,
        }
    }

    wired.sort_by_key(|w| w.at);
    let mut devices: HashMap<Address, &Wired> = HashMap::new();
    let mut lines: HashMap<&LineRef, &Wired> = HashMap::new();
    for w in &wired {
        if let Some(first) = devices.insert(w.line.device, w) {
            let message = format!(
                "{}: device {} is already used by {}",
                w.ctx.subject(),
                w.line.device,
                first.ctx.subject()
            );
            sink.error(w.device_at, message);
            devices.insert(w.line.device, first);
            ok = false;
        }
        if let Some(first) = lines.insert(&w.line.line, w) {
            let message = format!(
                "{}: line {} is already used by {}",
                w.ctx.subject(),
                w.line.line,
                first.ctx.subject()
            );
            sink.error(w.line_at, message);
            lines.insert(&w.line.line, first);
            ok = false;
        }
    }
    let (mut inputs, mut outputs) = (Vec::new(), Vec::new());
    for w in wired {
        let place = Place { at: w.at, subject: w.ctx.subject() };
        if w.input {
            config_io.inputs.push(w.line);
            inputs.push(place);
        } else {
            config_io.outputs.push(w.line);
            outputs.push(place);
        }
    }
    ok.then_some((config_io, inputs, outputs))
}

/// A valid `[[io.input]]` or `[[io.output]]`, with what the uniqueness checks report.
struct Wired {
    /// Where its header is, for file order.
    at: usize,
    line: IoLine,
    input: bool,
    device_at: usize,
    line_at: usize,
    ctx: Ctx,
}

/// The keys inputs and outputs share: a P bit and a line.
fn io_line(
    sink: &mut Sink,
    ctx: &Ctx,
    device: &Spanned<String>,
    line: &Spanned<RawLine>,
    active_low: bool,
) -> Option<IoLine> {
    let address = match Address::parse(device.get_ref()) {
        Ok(address) if address.area == Area::P && address.bit.is_some() => Some(address),
        Ok(_) => {
            let message = format!(
                "{} {:?} is not a P bit (P0000..=P127F)",
                ctx.key("device"),
                device.get_ref()
            );
            sink.error(device.span().start, message);
            None
        }
        Err(e) => {
            sink.error(device.span().start, format!("{}: {e}", ctx.key("device")));
            None
        }
    };
    let line = line_ref(sink, ctx, line);
    Some(IoLine {
        device: address?,
        line: line?,
        active_low,
        bias: Default::default(),
        debounce_us: 0,
    })
}

/// A line of `[[io.input]]` or `[[io.output]]` as written: the line, where it is, and what the
/// entry is called.
pub(super) struct WiredLine {
    pub line: RawLine,
    pub at: usize,
    pub subject: String,
}

/// The lines of the `[[io.input]]` and `[[io.output]]` entries that deserialized.
pub(super) fn wired_lines(
    inputs: &[Located<RawInput>],
    outputs: &[Located<RawOutput>],
) -> Vec<WiredLine> {
    let inputs = inputs.iter().map(|e| (&e.ctx, &e.value.line));
    let outputs = outputs.iter().map(|e| (&e.ctx, &e.value.line));
    inputs
        .chain(outputs)
        .map(|(ctx, line)| WiredLine {
            line: line.get_ref().clone(),
            at: line.span().start,
            subject: ctx.subject(),
        })
        .collect()
}
