//! `[rt]`: the real-time threads of `plcd run`: policy, priorities, CPUs, memory locking.

use std::ops::RangeInclusive;

use serde::Deserialize;
use toml::Spanned;

use super::common::{int, widen, Ctx};
use super::Sink;

/// `[rt]`: the real-time threads of `plcd run` (checked by every command, used only by
/// `plcd run`; `plcd sim` and `plcd check` start no real-time threads).
///
/// The three priorities must rise strictly: `scan_priority < event_priority <
/// watchdog_priority`, so the watchdog can always preempt a runaway scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtConfig {
    /// `policy`: `"fifo"` (default: SCHED_FIFO) or `"other"` (SCHED_OTHER, no real time).
    pub policy: RtPolicy,
    /// `scan_priority`: SCHED_FIFO priority of the scan thread, 1..=99 and below
    /// `event_priority`; default 80.
    pub scan_priority: u8,
    /// `event_priority`: of the event thread (timers, GPIO edges), 1..=99 and above
    /// `scan_priority`; default 85.
    pub event_priority: u8,
    /// `watchdog_priority`: of the watchdog thread, 1..=99 and above `event_priority`;
    /// default 90.
    pub watchdog_priority: u8,
    /// `scan_cpus`: CPU numbers the scan thread may run on (0..=1023, no duplicates);
    /// default empty = any CPU.
    pub scan_cpus: Vec<u16>,
    /// `event_cpus`: the same for the event thread.
    pub event_cpus: Vec<u16>,
    /// `watchdog_cpus`: the same for the watchdog thread.
    pub watchdog_cpus: Vec<u16>,
    /// `lock_memory`: mlockall(MCL_CURRENT|MCL_FUTURE) at start; default true.
    pub lock_memory: bool,
    /// `cpu_dma_latency_us`: a CPU wake-up latency to request from the kernel's PM QoS
    /// (`/dev/cpu_dma_latency`, held while the driver runs, with policy fifo) so that idle CPUs
    /// stay in shallow states, as cyclictest does by default; 0..=2000000000; default -1
    /// (`None`): no request, the idle states are the system's.
    pub cpu_dma_latency_us: Option<u32>,
    /// `require`: refuse to start when real-time scheduling or memory locking is not
    /// permitted; default false (warn once and run without).
    pub require: bool,
}

impl RtConfig {
    /// The SCHED_FIFO priorities of Linux.
    pub const PRIORITY: RangeInclusive<u8> = 1..=99;
    /// The CPU numbers a CPU list may hold (a `cpu_set_t` has 1024).
    pub const CPU: RangeInclusive<u16> = 0..=1023;
    /// `cpu_dma_latency_us`: -1 (no request) or the kernel's PM QoS range in µs.
    pub const CPU_DMA_LATENCY: RangeInclusive<i64> = -1..=2_000_000_000;
}

impl Default for RtConfig {
    fn default() -> Self {
        RtConfig {
            policy: RtPolicy::Fifo,
            scan_priority: 80,
            event_priority: 85,
            watchdog_priority: 90,
            scan_cpus: Vec::new(),
            event_cpus: Vec::new(),
            watchdog_cpus: Vec::new(),
            lock_memory: true,
            cpu_dma_latency_us: None,
            require: false,
        }
    }
}

/// `rt.policy`: the scheduling policy of the real-time threads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RtPolicy {
    /// `"fifo"`: SCHED_FIFO with the configured priorities (default).
    #[default]
    Fifo,
    /// `"other"`: SCHED_OTHER, the normal time-sharing policy; the priorities are not used.
    Other,
}

/// `[rt]` as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRt {
    #[serde(default)]
    pub policy: RtPolicy,
    pub scan_priority: Option<Spanned<i64>>,
    pub event_priority: Option<Spanned<i64>>,
    pub watchdog_priority: Option<Spanned<i64>>,
    pub scan_cpus: Option<Vec<Spanned<i64>>>,
    pub event_cpus: Option<Vec<Spanned<i64>>>,
    pub watchdog_cpus: Option<Vec<Spanned<i64>>>,
    pub lock_memory: Option<bool>,
    pub cpu_dma_latency_us: Option<Spanned<i64>>,
    #[serde(default)]
    pub require: bool,
}

/// One `[rt]` priority after its range check.
struct RtPriority {
    name: &'static str,
    /// The byte offset of the value, if the key was given.
    at: Option<usize>,
    /// `None` if out of range or malformed (already reported).
    value: Option<u8>,
}

/// `failed`: malformed keys, already reported; their values are unknown, not the defaults.
pub(super) fn validate(sink: &mut Sink, raw: RawRt, failed: &[String]) -> Option<RtConfig> {
    let ctx = Ctx::Section("rt");
    let default = RtConfig::default();
    let mut ok = true;
    let priorities = [
        ("scan_priority", raw.scan_priority, default.scan_priority),
        ("event_priority", raw.event_priority, default.event_priority),
        ("watchdog_priority", raw.watchdog_priority, default.watchdog_priority),
    ];
    let priorities = priorities.map(|(name, given, default)| match given {
        Some(given) => {
            let value = int(sink, &ctx, name, &given, widen(RtConfig::PRIORITY));
            RtPriority { name, at: Some(given.span().start), value }
        }
        None => {
            let malformed = failed.iter().any(|k| *k == ctx.key(name));
            RtPriority { name, at: None, value: (!malformed).then_some(default) }
        }
    });

    // scan < event < watchdog, between neighbours whose values are known (with the event
    // priority unknown, scan < watchdog still holds).
    let known: Vec<(&RtPriority, u8)> =
        priorities.iter().filter_map(|p| p.value.map(|v| (p, v))).collect();
    for pair in known.windows(2) {
        let [(low, low_value), (high, high_value)] = [pair[0], pair[1]];
        if high_value > low_value {
            continue;
        }
        ok = false;
        let given = |p: &RtPriority, value: u8| match p.at {
            Some(_) => format!("{} {value}", ctx.key(p.name)),
            None => format!("{} {value} (its default)", ctx.key(p.name)),
        };
        // Report at the later of the keys that were written (the defaults are in order).
        let (at, message) = if high.at > low.at {
            let message = format!("must be above {}", given(low, low_value));
            (high.at, format!("{} {message}", given(high, high_value)))
        } else {
            let message = format!("must be below {}", given(high, high_value));
            (low.at, format!("{} {message}", given(low, low_value)))
        };
        if let Some(at) = at {
            sink.error(at, message);
        }
    }

    let scan_cpus = cpus(sink, &ctx, "scan_cpus", raw.scan_cpus);
    let event_cpus = cpus(sink, &ctx, "event_cpus", raw.event_cpus);
    let watchdog_cpus = cpus(sink, &ctx, "watchdog_cpus", raw.watchdog_cpus);
    let cpu_dma_latency_us = match &raw.cpu_dma_latency_us {
        None => Some(default.cpu_dma_latency_us),
        Some(value) => {
            int::<i64>(sink, &ctx, "cpu_dma_latency_us", value, RtConfig::CPU_DMA_LATENCY)
                .map(|us| u32::try_from(us).ok())
        }
    };
    let [scan, event, watchdog] = priorities.map(|p| p.value);
    let rt = RtConfig {
        policy: raw.policy,
        scan_priority: scan?,
        event_priority: event?,
        watchdog_priority: watchdog?,
        scan_cpus: scan_cpus?,
        event_cpus: event_cpus?,
        watchdog_cpus: watchdog_cpus?,
        lock_memory: raw.lock_memory.unwrap_or(default.lock_memory),
        cpu_dma_latency_us: cpu_dma_latency_us?,
        require: raw.require,
    };
    ok.then_some(rt)
}

/// A CPU list of `[rt]`: each CPU in range and listed once, in the order written.
fn cpus(sink: &mut Sink, ctx: &Ctx, key: &str, raw: Option<Vec<Spanned<i64>>>) -> Option<Vec<u16>> {
    let mut ok = true;
    let mut cpus: Vec<u16> = Vec::new();
    for cpu in raw.unwrap_or_default() {
        let (value, at) = (*cpu.get_ref(), cpu.span().start);
        let Some(number) = u16::try_from(value).ok().filter(|n| RtConfig::CPU.contains(n)) else {
            let (first, last) = (RtConfig::CPU.start(), RtConfig::CPU.end());
            sink.error(at, format!("{}: CPU {value} out of range {first}..={last}", ctx.key(key)));
            ok = false;
            continue;
        };
        if cpus.contains(&number) {
            sink.error(at, format!("{}: CPU {number} is listed twice", ctx.key(key)));
            ok = false;
            continue;
        }
        cpus.push(number);
    }
    ok.then_some(cpus)
}
