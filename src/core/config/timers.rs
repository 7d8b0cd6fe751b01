//! `[timers]`: the time base of each timer number.

use std::ops::RangeInclusive;

use serde::Deserialize;
use toml::Spanned;

use super::common::Ctx;
use super::Sink;
use crate::device::{Address, Area};

/// `[timers]`: the time base of each timer number.
///
/// Each key is `"Txxxx-Tyyyy"` (inclusive, within T0000..=T2047, first <= last) or `""` for no
/// timers of that base. A key not given keeps its default; the ranges must not overlap. Timer
/// numbers no range covers have no base ([`TimerConfig::base_ms`] is `None`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TimerConfig {
    /// `ms100`: the 100 ms timers; default T0000..=T0999.
    pub ms100: Option<RangeInclusive<u32>>,
    /// `ms10`: the 10 ms timers; default T1000..=T1499.
    pub ms10: Option<RangeInclusive<u32>>,
    /// `ms1`: the 1 ms timers; default T1500..=T2047.
    pub ms1: Option<RangeInclusive<u32>>,
}

impl TimerConfig {
    /// The highest timer number (T2047).
    pub const LAST_TIMER: u32 = 2047;

    /// The base of timer `timer` in ms (100, 10 or 1), or `None` if no range covers it.
    pub fn base_ms(&self, timer: u32) -> Option<u32> {
        [(&self.ms100, 100), (&self.ms10, 10), (&self.ms1, 1)]
            .into_iter()
            .find(|(range, _)| range.as_ref().is_some_and(|r| r.contains(&timer)))
            .map(|(_, base)| base)
    }
}

impl Default for TimerConfig {
    fn default() -> Self {
        TimerConfig { ms100: Some(0..=999), ms10: Some(1000..=1499), ms1: Some(1500..=2047) }
    }
}

/// `[timers]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTimers {
    pub ms100: Option<Spanned<String>>,
    pub ms10: Option<Spanned<String>>,
    pub ms1: Option<Spanned<String>>,
}

/// One `[timers]` key after parsing: what it says and where, if it was written.
struct TimerKey {
    name: &'static str,
    /// The byte offset of the value, if the key was given.
    at: Option<usize>,
    /// As written, or the default's text.
    text: String,
    /// `None` if the value did not parse (already reported).
    range: Option<Option<RangeInclusive<u32>>>,
}

/// `failed`: malformed keys, already reported; their ranges are unknown, not the defaults.
pub(super) fn validate(sink: &mut Sink, raw: RawTimers, failed: &[String]) -> Option<TimerConfig> {
    let ctx = Ctx::Section("timers");
    let default = TimerConfig::default();
    let keys = [
        ("ms100", raw.ms100, default.ms100),
        ("ms10", raw.ms10, default.ms10),
        ("ms1", raw.ms1, default.ms1),
    ];
    let keys: [TimerKey; 3] = keys.map(|(name, given, default)| match given {
        Some(given) => {
            let at = given.span().start;
            let text = given.into_inner();
            let range = timer_range(&text)
                .map_err(|e| sink.error(at, format!("{}: {e}", ctx.key(name))))
                .ok();
            TimerKey { name, at: Some(at), text, range }
        }
        None => {
            let text = default.as_ref().map_or_else(String::new, range_text);
            let malformed = failed.iter().any(|k| *k == ctx.key(name));
            TimerKey { name, at: None, text, range: (!malformed).then_some(default) }
        }
    });

    for (i, a) in keys.iter().enumerate() {
        for b in &keys[i + 1..] {
            let (Some(Some(ra)), Some(Some(rb))) = (&a.range, &b.range) else {
                continue;
            };
            if ra.start() > rb.end() || rb.start() > ra.end() {
                continue;
            }
            // Report at the later of the keys that were written (defaults never overlap).
            let (here, there) = if a.at > b.at { (a, b) } else { (b, a) };
            let Some(at) = here.at else { continue };
            let there_text = match there.at {
                Some(_) => format!("{:?}", there.text),
                None => format!("{:?} (its default)", there.text),
            };
            let message = format!(
                "{} {:?} overlaps {} {there_text}",
                ctx.key(here.name),
                here.text,
                ctx.key(there.name),
            );
            sink.error(at, message);
        }
    }

    let [ms100, ms10, ms1] = keys.map(|k| k.range);
    Some(TimerConfig { ms100: ms100?, ms10: ms10?, ms1: ms1? })
}

/// `"Txxxx-Tyyyy"` as an inclusive range of timer numbers, `""` as none.
fn timer_range(text: &str) -> Result<Option<RangeInclusive<u32>>, String> {
    if text.trim().is_empty() {
        return Ok(None);
    }
    let Some((first, last)) = text.split_once('-') else {
        return Err(format!("{text:?} is not a range \"Txxxx-Tyyyy\" (or \"\" for none)"));
    };
    let timer = |part: &str| {
        let part = part.trim();
        match Address::parse(part) {
            Ok(address) if address.area == Area::T => Ok(address.number),
            Ok(_) => {
                Err(format!("`{part}` is not a timer (T0000-T{:04})", TimerConfig::LAST_TIMER))
            }
            Err(e) => Err(e.to_string()),
        }
    };
    let (first, last) = (timer(first)?, timer(last)?);
    if first > last {
        return Err(format!("{text:?} is backwards: T{first:04} comes after T{last:04}"));
    }
    Ok(Some(first..=last))
}

fn range_text(range: &RangeInclusive<u32>) -> String {
    format!("T{:04}-T{:04}", range.start(), range.end())
}
