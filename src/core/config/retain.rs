//! `[retain]`: which devices survive a restart, and how often they are written to disk
//! (docs/RETAIN.md). The K area is always retained and is not named here.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::common::{int_or, resolve, widen, Ctx};
use super::Sink;
pub use crate::device::retained::{RetainArea, RetainRange};

/// `[retain]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RetainConfig {
    /// `ranges`: D, T and C ranges retained besides K, in the order written; no two overlap.
    pub ranges: Vec<RetainRange>,
    /// `interval_ms`: how often changed values are written; default 1000.
    pub interval_ms: u32,
    /// `dir`: where the two generation files live, resolved against the config file's
    /// directory. `None`: `$STATE_DIRECTORY` (set by systemd's `StateDirectory=`), and without
    /// it nothing is persisted (retained values then survive STOP/RUN only).
    pub dir: Option<PathBuf>,
    /// `restart`: what a start of the daemon does with the files (XGB restart modes).
    pub restart: Restart,
}

impl RetainConfig {
    pub const INTERVAL_MS: RangeInclusive<u32> = 10..=3_600_000;
    pub const DEFAULT_INTERVAL_MS: u32 = 1000;
}

impl Default for RetainConfig {
    fn default() -> Self {
        RetainConfig {
            ranges: Vec::new(),
            interval_ms: Self::DEFAULT_INTERVAL_MS,
            dir: None,
            restart: Restart::Warm,
        }
    }
}

/// `retain.restart`: the restart mode at the daemon's start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Restart {
    /// `"warm"` (default): the retained devices are restored from the newest valid file.
    #[default]
    Warm,
    /// `"cold"`: every device starts cleared, K included; the files are not read for values.
    Cold,
}

/// `[retain]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRetain {
    pub ranges: Option<Vec<Spanned<String>>>,
    pub interval_ms: Option<Spanned<i64>>,
    pub dir: Option<Spanned<String>>,
    #[serde(default)]
    pub restart: Restart,
}

/// Pass 2 of `[retain]`; `config` is the config file, for `dir`.
pub(super) fn validate(sink: &mut Sink, raw: RawRetain, config: &Path) -> Option<RetainConfig> {
    let ctx = Ctx::Section("retain");
    let mut ok = true;
    let mut ranges: Vec<RetainRange> = Vec::new();
    for text in raw.ranges.unwrap_or_default() {
        let at = text.span().start;
        match RetainRange::parse(text.get_ref()) {
            Err(message) => {
                sink.error(at, format!("{}: {message}", ctx.key("ranges")));
                ok = false;
            }
            Ok(range) => {
                if let Some(earlier) = ranges.iter().find(|r| r.overlaps(&range)) {
                    let message = format!("{}: {range} overlaps {earlier}", ctx.key("ranges"));
                    sink.error(at, message);
                    ok = false;
                } else {
                    ranges.push(range);
                }
            }
        }
    }
    let interval_ms = int_or(
        sink,
        &ctx,
        "interval_ms",
        raw.interval_ms,
        widen(RetainConfig::INTERVAL_MS),
        RetainConfig::DEFAULT_INTERVAL_MS,
    );
    let dir = match raw.dir {
        None => Some(None),
        Some(dir) if dir.get_ref().trim().is_empty() => {
            sink.error(dir.span().start, format!("{} must not be empty", ctx.key("dir")));
            None
        }
        Some(dir) => Some(Some(resolve(config, dir.get_ref()))),
    };
    let retain =
        RetainConfig { ranges, interval_ms: interval_ms?, dir: dir?, restart: raw.restart };
    ok.then_some(retain)
}
