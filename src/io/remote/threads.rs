//! The poller threads: one per TCP device, one per RTU port for every device on it. A thread
//! asks its pollers for the next job, carries it out on its link, reports back, logs what the
//! pollers noticed, and sleeps until the next job is due or the scan thread wakes it (outputs
//! changed). Not real time: it blocks on the network or the line, which the scan never does.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::link::Link;
use super::poller::{Job, Notice, Poller};
use crate::config::OnLoss;

/// The longest sleep between two looks at the stop flag.
const STOP_CHECK: Duration = Duration::from_millis(200);

/// The pollers that share a link, and the link.
pub struct Group {
    pub pollers: Vec<Poller>,
    pub link: Link,
}

/// The thread's loop, until `stop`. `epoch` is the pollers' clock's zero.
pub fn run(mut group: Group, stop: Arc<AtomicBool>, epoch: Instant) {
    let clock = || epoch.elapsed().as_nanos() as u64;
    let count = group.pollers.len();
    // Devices on one line take turns when several are due.
    let mut next_first = 0;
    loop {
        if stop.load(Ordering::Acquire) {
            finish_writes(&mut group, clock());
            return;
        }
        let now = clock();
        let mut wake = u64::MAX;
        let mut chosen = None;
        for k in 0..count {
            let i = (next_first + k) % count;
            match group.pollers[i].next_job(now) {
                Ok(job) => {
                    chosen = Some((i, job));
                    break;
                }
                Err(at) => wake = wake.min(at),
            }
        }
        let Some((i, job)) = chosen else {
            let sleep = Duration::from_nanos(wake.saturating_sub(now)).min(STOP_CHECK);
            std::thread::park_timeout(sleep);
            continue;
        };
        next_first = (i + 1) % count;
        carry_out(&mut group.pollers[i], &mut group.link, job, clock);
    }
}

/// One job of `poller` on `link`, reported back as ended at `ended()`, and what it noticed
/// logged.
fn carry_out(poller: &mut Poller, link: &mut Link, job: Job, ended: impl FnOnce() -> u64) {
    let unit = poller.unit;
    let timeout = Duration::from_millis(u64::from(poller.timeout_ms));
    let (ask, values) = poller.prepare(job);
    let result = link.exchange(unit, &ask, values, timeout);
    let late = link.take_late();
    poller.finish(job, ended(), link.round_trip_ns(), result, late);
    for notice in poller.take_notices() {
        log_notice(poller, &notice);
    }
}

/// At stop: each write that is due now (the safe state's zeros) is carried out once, so that
/// the devices' outputs do not stay as they were.
fn finish_writes(group: &mut Group, now: u64) {
    for poller in &mut group.pollers {
        let mut tries = poller.write_tables();
        while tries > 0 {
            tries -= 1;
            let Ok(job @ Job::Write(_)) = poller.next_job(now) else {
                break;
            };
            carry_out(poller, &mut group.link, job, || now);
        }
    }
}

fn log_notice(poller: &Poller, notice: &Notice) {
    let who = format!("remote {} ({})", poller.name, poller.describe);
    match notice {
        Notice::Fault { ask, fault } => log::warn!("{who}: {ask} failed: {fault}"),
        Notice::Lost { failures, on_loss } => log::error!(
            "{who}: lost after {failures} failed request{}; its inputs are {} (on_loss = \"{}\") \
             and its status is OFF until it answers again",
            if *failures == 1 { "" } else { "s" },
            match on_loss {
                OnLoss::Clear => "cleared",
                OnLoss::Hold => "held",
            },
            match on_loss {
                OnLoss::Clear => "clear",
                OnLoss::Hold => "hold",
            },
        ),
        Notice::Back { failures, lost_ms: Some(ms) } => log::info!(
            "{who}: answering again after {failures} failed requests ({}.{:03} s lost)",
            ms / 1000,
            ms % 1000
        ),
        Notice::Back { failures, lost_ms: None } => {
            log::info!("{who}: answering again after {failures} failed requests")
        }
        Notice::Late => log::warn!(
            "{who}: an answer came after its request had timed out and was dropped (more are \
             counted in plcctl status, not logged)"
        ),
    }
}
