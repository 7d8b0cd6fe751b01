//! `[sim]`: the virtual clock of `plcd sim`.

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, Ctx};
use super::Sink;

/// `[sim]`: the virtual clock of `plcd sim`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimConfig {
    /// `step_ns`: virtual ns one executed instruction costs; at least 1, default 1000.
    pub step_ns: u64,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig { step_ns: 1000 }
    }
}

/// `[sim]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSim {
    pub step_ns: Option<Spanned<i64>>,
}

pub(super) fn validate(sink: &mut Sink, raw: RawSim) -> Option<SimConfig> {
    let ctx = Ctx::Section("sim");
    let step_ns =
        int_or(sink, &ctx, "step_ns", raw.step_ns, 1..=i64::MAX, SimConfig::default().step_ns);
    Some(SimConfig { step_ns: step_ns? })
}
