//! `[sim]`: the virtual clock of `plcd sim`.

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, Ctx};
use super::Sink;
use crate::value::Calendar;

/// `[sim]`: the virtual clock of `plcd sim`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimConfig {
    /// `step_ns`: virtual ns one executed instruction costs; at least 1, default 1000.
    pub step_ns: u64,
    /// `start`: the calendar time at virtual time 0, what the real-time clock of ST programs
    /// reads then, in ns since 1970-01-01 00:00:00 UTC; written as a `DT` literal's text
    /// (`"2026-01-01-00:00:00"`, a fraction of a second allowed); default 1970-01-01-00:00:00.
    pub start_utc_ns: u64,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig { step_ns: 1000, start_utc_ns: 0 }
    }
}

/// `[sim]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSim {
    pub step_ns: Option<Spanned<i64>>,
    pub start: Option<Spanned<String>>,
}

pub(super) fn validate(sink: &mut Sink, raw: RawSim) -> Option<SimConfig> {
    let ctx = Ctx::Section("sim");
    let step_ns =
        int_or(sink, &ctx, "step_ns", raw.step_ns, 1..=i64::MAX, SimConfig::default().step_ns);
    let start_utc_ns = match raw.start {
        None => Some(SimConfig::default().start_utc_ns),
        Some(start) => match crate::value::calendar_from_text(Calendar::LDt, start.get_ref()) {
            Ok(ns) => Some(ns),
            Err(why) => {
                let message = format!(
                    "{} {:?} is not a date and time ({why}; e.g. \"2026-01-01-00:00:00\")",
                    ctx.key("start"),
                    start.get_ref()
                );
                sink.error(start.span().start, message);
                None
            }
        },
    };
    Some(SimConfig { step_ns: step_ns?, start_utc_ns: start_utc_ns? })
}
