//! The ways a real-time thread can sleep until an absolute CLOCK_MONOTONIC deadline, side by
//! side: how late each wakes up. This separates the kernel's wake-up path from plcd's own work
//! in the cycle-task latency that `benches/latency-vs-cyclictest` compares with cyclictest.
//!
//! - `clock_nanosleep`: what cyclictest does (`TIMER_ABSTIME`).
//! - `timerfd read`: a blocking timerfd armed at the deadline, then `read`.
//! - `timerfd ppoll 1`: a non-blocking timerfd, `ppoll` on it alone.
//! - `timerfd+eventfd ppoll`: the scan thread's sleep (timerfd and the wake eventfd in one
//!   `ppoll`).
//! - `clock_nanosleep` again, last in each round: an A/A control. How far it lands from the
//!   first is how far apart two identical sleeps measure on this machine in one run.
//!
//! Each method sleeps `--cycles` deadlines of `--interval-us` in each of `--rounds` rounds, the
//! methods taking turns round after round so that all see the same window of time; idle, then
//! under `stress-ng --cpu 2` if it is installed. As root: SCHED_FIFO 80, memory locked, PM QoS
//! 0 µs, as cyclictest runs by default.
//!
//!     cargo bench --bench sleep_paths [-- --cycles N --rounds R --interval-us US]

use std::os::fd::AsFd;
use std::process::{Child, Command, Stdio};

use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{
    ClockId as TimerClock, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags,
};
use nix::time::{clock_nanosleep, ClockId, ClockNanosleepFlags};
use plcd::bench::{write_fragment, Fragment};
use plcd::drivers::real_time::sys::{self, Timer, Wake};
use plcd::stats::Histogram;

#[derive(Clone, Copy, PartialEq, Eq)]
enum Method {
    Nanosleep,
    /// The same again: the spread between two identical methods is the measurement's noise.
    NanosleepAgain,
    TimerfdRead,
    TimerfdPoll,
    TimerfdEventfdPoll,
}

const METHODS: [Method; 5] = [
    Method::Nanosleep,
    Method::TimerfdRead,
    Method::TimerfdPoll,
    Method::TimerfdEventfdPoll,
    Method::NanosleepAgain,
];

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Nanosleep => "clock_nanosleep (cyclictest)",
            Method::NanosleepAgain => "clock_nanosleep again (A/A control)",
            Method::TimerfdRead => "timerfd, blocking read",
            Method::TimerfdPoll => "timerfd, ppoll on it alone",
            Method::TimerfdEventfdPoll => "timerfd + eventfd, ppoll (the scan thread)",
        }
    }
}

fn timespec(ns: u64) -> TimeSpec {
    TimeSpec::new((ns / 1_000_000_000) as i64, (ns % 1_000_000_000) as i64)
}

/// Sleeps `cycles` deadlines `interval_ns` apart with `method`, recording how late each woke.
fn run(method: Method, cycles: u64, interval_ns: u64, into: &mut Histogram) {
    let blocking =
        TimerFd::new(TimerClock::CLOCK_MONOTONIC, TimerFlags::TFD_CLOEXEC).expect("timerfd_create");
    let timer = Timer::new().expect("timerfd_create");
    let wake = Wake::new().expect("eventfd");
    let mut deadline = sys::now_ns() + interval_ns;
    for _ in 0..cycles {
        match method {
            Method::Nanosleep | Method::NanosleepAgain => {
                let _ = clock_nanosleep(
                    ClockId::CLOCK_MONOTONIC,
                    ClockNanosleepFlags::TIMER_ABSTIME,
                    &timespec(deadline),
                );
            }
            Method::TimerfdRead => {
                blocking
                    .set(
                        Expiration::OneShot(timespec(deadline)),
                        TimerSetTimeFlags::TFD_TIMER_ABSTIME,
                    )
                    .expect("timerfd_settime");
                let _ = blocking.wait();
            }
            Method::TimerfdPoll => {
                timer.arm(deadline, 0).expect("timerfd_settime");
                let _ = sys::wait_any(&[timer.as_fd()], None);
            }
            Method::TimerfdEventfdPoll => {
                timer.arm(deadline, 0).expect("timerfd_settime");
                let _ = sys::wait_any(&[timer.as_fd(), wake.as_fd()], None);
            }
        }
        let late = sys::now_ns().saturating_sub(deadline);
        into.record(late);
        deadline += interval_ns;
    }
}

fn arg(name: &str, default: u64) -> u64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn stress() -> Option<Child> {
    Command::new("stress-ng")
        .args(["--cpu", "2", "--timeout", "0", "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .ok()
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1000.0)
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes benches with --list
    }
    let cycles = arg("--cycles", 5000);
    let rounds = arg("--rounds", 4);
    let interval_ns = arg("--interval-us", 1000) * 1000;
    let locked = sys::lock_memory().is_ok();
    let fifo = sys::set_fifo(80).is_ok();
    let _qos = sys::request_cpu_latency(0).ok();
    if !fifo {
        eprintln!("sleep_paths: not SCHED_FIFO (run as root); the figures are not real-time ones");
    }
    let command = format!(
        "cargo bench --bench sleep_paths -- --cycles {cycles} --rounds {rounds} --interval-us {}",
        interval_ns / 1000
    );
    let mut fragment = Fragment::new(&command);
    fragment.line(format!(
        "{} cycles of {} µs per method and condition, in {rounds} alternating rounds; \
         SCHED_FIFO 80: {fifo}, memory locked: {locked}, PM QoS 0 µs: {}. Wake-up lateness \
         after the deadline, µs.\n",
        cycles * rounds,
        interval_ns / 1000,
        _qos.is_some()
    ));
    for condition in ["idle", "stress-ng --cpu 2"] {
        let mut load = None;
        if condition != "idle" {
            load = stress();
            if load.is_none() {
                eprintln!("sleep_paths: stress-ng is missing; no loaded figures");
                break;
            }
            std::thread::sleep(std::time::Duration::from_secs(1));
        }
        let mut histograms: Vec<Histogram> = METHODS.iter().map(|_| Histogram::new()).collect();
        for round in 0..rounds {
            for (method, histogram) in METHODS.iter().zip(&mut histograms) {
                eprintln!("== {condition}, round {}/{rounds}: {}", round + 1, method.name());
                run(*method, cycles, interval_ns, histogram);
            }
        }
        if let Some(mut child) = load {
            let _ = child.kill();
            let _ = child.wait();
        }
        let base = histograms[0].quantile(0.99) as i64;
        let rows: Vec<Vec<String>> = METHODS
            .iter()
            .zip(&histograms)
            .map(|(method, h)| {
                vec![
                    condition.to_string(),
                    method.name().to_string(),
                    us(h.quantile(0.5)),
                    us(h.quantile(0.99)),
                    us(h.quantile(0.999)),
                    us(h.summary().max),
                    format!("{:+.1}", (h.quantile(0.99) as i64 - base) as f64 / 1000.0),
                ]
            })
            .collect();
        fragment.table(
            &["condition", "sleep", "p50", "p99", "p99.9", "max", "p99 − nanosleep's"],
            &rows,
        );
    }
    print!("{}", fragment.as_str());
    write_fragment("sleep", &fragment).expect("the fragment is written");
}
