//! `[plc]`: the scan watchdog, the outputs after a stopping error, the scan period and what
//! a congestion does.

use std::ops::RangeInclusive;

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, widen, Ctx};
use super::Sink;

/// `[plc]`: the scan and what happens when it fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlcConfig {
    /// `watchdog_ms`: the scan watchdog in ms, 10..=1000 (the XGB setting range); default 200.
    pub watchdog_ms: u32,
    /// `on_fault`: the outputs on a stopping error, `"clear"` (default) or `"hold"`.
    pub on_fault: OnFault,
    /// `scan_period_ms`: 0 (default) runs the scan free; N starts a new scan every N ms.
    /// Range 0..=1000: a period longer than the longest watchdog would leave outputs
    /// unrefreshed longer than any scan may take, which is never what a PLC wants.
    pub scan_period_ms: u32,
    /// `continue_on_congestion`: keep running when a task exceeds its `max_exec_ms`
    /// (the Hitachi "continued operation" setting); default false (stop with an error).
    pub continue_on_congestion: bool,
}

impl PlcConfig {
    pub const WATCHDOG_MS: RangeInclusive<u32> = 10..=1000;
    pub const SCAN_PERIOD_MS: RangeInclusive<u32> = 0..=1000;
}

impl Default for PlcConfig {
    fn default() -> Self {
        PlcConfig {
            watchdog_ms: 200,
            on_fault: OnFault::Clear,
            scan_period_ms: 0,
            continue_on_congestion: false,
        }
    }
}

/// `plc.on_fault`: the outputs after a stopping error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OnFault {
    /// `"clear"`: every output OFF (default).
    #[default]
    Clear,
    /// `"hold"`: outputs keep their last state.
    Hold,
}

/// `[plc]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlc {
    pub watchdog_ms: Option<Spanned<i64>>,
    #[serde(default)]
    pub on_fault: OnFault,
    pub scan_period_ms: Option<Spanned<i64>>,
    #[serde(default)]
    pub continue_on_congestion: bool,
}

pub(super) fn validate(sink: &mut Sink, raw: RawPlc) -> Option<PlcConfig> {
    let ctx = Ctx::Section("plc");
    let default = PlcConfig::default();
    let watchdog_ms = int_or(
        sink,
        &ctx,
        "watchdog_ms",
        raw.watchdog_ms,
        widen(PlcConfig::WATCHDOG_MS),
        default.watchdog_ms,
    );
    let scan_period_ms = int_or(
        sink,
        &ctx,
        "scan_period_ms",
        raw.scan_period_ms,
        widen(PlcConfig::SCAN_PERIOD_MS),
        default.scan_period_ms,
    );
    Some(PlcConfig {
        watchdog_ms: watchdog_ms?,
        on_fault: raw.on_fault,
        scan_period_ms: scan_period_ms?,
        continue_on_congestion: raw.continue_on_congestion,
    })
}
