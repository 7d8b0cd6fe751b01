//! `[switch]`: the RUN/STOP key switch, simulated (sim backend) or on an input line
//! (gpiocdev).

use std::ops::RangeInclusive;

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, widen, Ctx, Located};
use super::io::{line_ref, Backend, Bias, LineRef, RawLine, WiredLine};
use super::Sink;
use crate::io::SwitchPosition;

/// `[switch]`: a RUN/STOP key switch (XGB §5.2.3). With the switch at RUN the PLC runs and
/// remote RUN/STOP/DEBUG are refused; at STOP the PLC is stopped and remote mode changes are
/// accepted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SwitchConfig {
    /// `line`: the input line of the `[io]` chip (an offset, 0..=4294967295, or a name) that is
    /// active when the switch is at RUN. Required with the gpiocdev backend, not allowed with
    /// the sim backend; not the line of any `[[io.input]]` or `[[io.output]]`. The line is no
    /// P bit.
    pub line: Option<LineRef>,
    /// `active_low`: the line is active when low; default false. Unused by the sim backend.
    pub active_low: bool,
    /// `bias`: `"pull-up"`, `"pull-down"` or `"disabled"` (default). Unused by the sim backend.
    pub bias: Bias,
    /// `debounce_us`: the kernel's debounce period for the contact, 0..=1000000 µs (0: none);
    /// default 10000. Unused by the sim backend.
    pub debounce_us: u32,
    /// `position`: sim backend only (an error with gpiocdev): where the simulated switch
    /// starts, `"run"` (default) or `"stop"`; stimulus lines `SWITCH, RUN|STOP` move it.
    pub position: crate::io::SwitchPosition,
}

impl SwitchConfig {
    pub const DEBOUNCE_US: RangeInclusive<u32> = 0..=1_000_000;
}

impl Default for SwitchConfig {
    fn default() -> Self {
        SwitchConfig {
            line: None,
            active_low: false,
            bias: Bias::Disabled,
            debounce_us: 10_000,
            position: crate::io::SwitchPosition::Run,
        }
    }
}

/// `[switch]` with the keys of both backends; `validate` checks which belong.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSwitch {
    pub line: Option<Spanned<RawLine>>,
    #[serde(default)]
    pub active_low: bool,
    #[serde(default)]
    pub bias: Bias,
    pub debounce_us: Option<Spanned<i64>>,
    pub position: Option<Spanned<SwitchPosition>>,
}

/// `[switch]`: `Some(None)` when there is none, `None` on errors. `backend` is `None` when
/// it is unknown (malformed, already reported): the keys that depend on it are not checked.
pub(super) fn validate(
    sink: &mut Sink,
    raw: Option<Located<RawSwitch>>,
    backend: Option<Backend>,
    wired: &[WiredLine],
    failed: &[String],
) -> Option<Option<SwitchConfig>> {
    let Some(Located { span, ctx, value: raw }) = raw else {
        return Some(None);
    };
    let default = SwitchConfig::default();
    let mut ok = true;
    let debounce_us = int_or(
        sink,
        &ctx,
        "debounce_us",
        raw.debounce_us,
        widen(SwitchConfig::DEBOUNCE_US),
        default.debounce_us,
    );
    let line = match &raw.line {
        Some(line) if backend == Some(Backend::Sim) => {
            let message = format!(
                "{} is for the gpiocdev backend: the sim backend simulates the switch \
                 (`position`, and `SWITCH` lines of a stimulus)",
                ctx.key("line")
            );
            sink.error(line.span().start, message);
            ok = false;
            None
        }
        Some(raw) => match line_ref(sink, &ctx, raw) {
            Some(line) => {
                ok &= switch_line_is_free(sink, &ctx, &line, raw.span().start, wired);
                Some(line)
            }
            None => {
                ok = false;
                None
            }
        },
        // A malformed line is reported already, not missing.
        None if backend == Some(Backend::Gpiocdev)
            && !failed.iter().any(|k| *k == ctx.key("line")) =>
        {
            let message = format!(
                "{} is required for the gpiocdev backend: the input line that is active at RUN",
                ctx.key("line")
            );
            sink.error(span.start, message);
            ok = false;
            None
        }
        None => None,
    };
    let position = match raw.position {
        Some(position) if backend == Some(Backend::Gpiocdev) => {
            let message = format!(
                "{} is for the sim backend: the gpiocdev backend reads the switch from its line",
                ctx.key("position")
            );
            sink.error(position.span().start, message);
            ok = false;
            default.position
        }
        Some(position) => position.into_inner(),
        None => default.position,
    };
    let switch = SwitchConfig {
        line,
        active_low: raw.active_low,
        bias: raw.bias,
        debounce_us: debounce_us?,
        position,
    };
    ok.then_some(Some(switch))
}

/// The switch's line is no `[[io.input]]` or `[[io.output]]` line (compared as written, as
/// among those entries). As among them, the later one in the file is reported, naming the
/// other.
fn switch_line_is_free(
    sink: &mut Sink,
    ctx: &Ctx,
    line: &LineRef,
    at: usize,
    wired: &[WiredLine],
) -> bool {
    let mut free = true;
    for w in wired.iter().filter(|w| w.line.is(line)) {
        let (at, message) = if w.at > at {
            (w.at, format!("{}: line {line} is already used by {}", w.subject, ctx.subject()))
        } else {
            (at, format!("{} {line} is already used by {}", ctx.key("line"), w.subject))
        };
        sink.error(at, message);
        free = false;
    }
    free
}
