//! Login throttling: failed logins counted per source, the delay they earn, and the runs of
//! failures a service logs once each. Times are what the caller passes (a monotonic clock's
//! reading, from any origin), so every rule is tested with explicit times.
//!
//! The rules (docs/USERS.md, "Throttling"):
//! - a source may fail [`ThrottlePolicy::free_failures`] times without waiting; the last of
//!   those failures, and each one after it, makes the source wait before its next attempt is
//!   even verified: [`ThrottlePolicy::first_delay`], doubled with each further failure, at
//!   most [`ThrottlePolicy::max_delay`];
//! - a success, or [`ThrottlePolicy::forget_after`] without a failure, ends the source's run
//!   of failures and forgets it;
//! - the table holds at most [`ThrottlePolicy::capacity`] sources; a new one beyond that
//!   evicts the source whose last failure is oldest, which ends its run.
//!
//! A service logs a run twice: at its first failure ([`Failure::first_of_run`]) and when it
//! ends ([`EndedRun`], with the count), never once per failure.

use std::collections::BTreeMap;
use std::net::{IpAddr, Ipv6Addr};
use std::time::Duration;

/// The numbers of the rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ThrottlePolicy {
    /// Failures a source may have without waiting for its next attempt; default 3.
    pub free_failures: u32,
    /// The wait the last of those failures earns; default 1 s.
    pub first_delay: Duration,
    /// The longest wait; default 60 s.
    pub max_delay: Duration,
    /// A source without a failure for this long is forgotten, its run ended; default 15 min.
    pub forget_after: Duration,
    /// Sources remembered at most; default 1024.
    pub capacity: usize,
}

impl Default for ThrottlePolicy {
    fn default() -> Self {
        ThrottlePolicy {
            free_failures: 3,
            first_delay: Duration::from_secs(1),
            max_delay: Duration::from_secs(60),
            forget_after: Duration::from_secs(15 * 60),
            capacity: 1024,
        }
    }
}

impl ThrottlePolicy {
    /// The wait a source has earned with `failures` failures in its run.
    pub fn delay_after(&self, failures: u32) -> Duration {
        let Some(doublings) = failures.checked_sub(self.free_failures) else {
            return Duration::ZERO;
        };
        let factor = 1u32.checked_shl(doublings).unwrap_or(u32::MAX);
        self.first_delay.saturating_mul(factor).min(self.max_delay)
    }
}

/// A source's run of failures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Run {
    failures: u32,
    last: Duration,
}

/// What a recorded failure means for its source.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failure<K> {
    /// The first failure of the source's run: the one a service logs.
    pub first_of_run: bool,
    /// Failures in the run so far, this one included.
    pub failures: u32,
    /// How long the source must now wait before its next attempt is verified (zero while it
    /// has free failures left).
    pub retry_after: Duration,
    /// A run this failure ended: the source's own earlier run, forgotten for its quiet time,
    /// or the run of the source evicted to make room.
    pub ended: Option<EndedRun<K>>,
}

/// A run of failures that ended, for the service's log: who, and how many failures.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EndedRun<K> {
    pub source: K,
    pub failures: u32,
}

/// The failures of at most [`ThrottlePolicy::capacity`] sources. `K` is the source: an
/// `IpAddr` (through [`source_of`]) or a string. An ordered map, not a hash map: the core has
/// no random source for a hash map's seed, and the sources are chosen by whoever connects.
#[derive(Debug, Clone)]
pub struct Throttle<K> {
    policy: ThrottlePolicy,
    runs: BTreeMap<K, Run>,
}

impl<K: Ord + Clone> Throttle<K> {
    pub fn new(policy: ThrottlePolicy) -> Self {
        Throttle { policy, runs: BTreeMap::new() }
    }

    pub fn policy(&self) -> &ThrottlePolicy {
        &self.policy
    }

    /// Sources remembered now (forgotten ones that [`Throttle::expire`] has not yet taken out
    /// included).
    pub fn len(&self) -> usize {
        self.runs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }

    /// Whether a run is still remembered at `now`.
    fn live(&self, run: &Run, now: Duration) -> bool {
        now.saturating_sub(run.last) < self.policy.forget_after
    }

    /// Whether an attempt from `source` may be verified at `now`: `Err` with how long it must
    /// still wait. A service refuses a waiting attempt without verifying it (no hash is
    /// computed), and counts it as no failure.
    pub fn check(&self, source: &K, now: Duration) -> Result<(), Duration> {
        let Some(run) = self.runs.get(source).filter(|run| self.live(run, now)) else {
            return Ok(());
        };
        let until = run.last.saturating_add(self.policy.delay_after(run.failures));
        match until.checked_sub(now) {
            Some(wait) if !wait.is_zero() => Err(wait),
            _ => Ok(()),
        }
    }

    /// Records a failed login from `source` at `now`.
    pub fn failure(&mut self, source: K, now: Duration) -> Failure<K> {
        let mut ended = None;
        let earlier = self.runs.get(&source).copied();
        let failures = match earlier {
            Some(run) if self.live(&run, now) => run.failures.saturating_add(1),
            Some(run) => {
                ended = Some(EndedRun { source: source.clone(), failures: run.failures });
                1
            }
            None => {
                if self.runs.len() >= self.policy.capacity {
                    ended = self.evict_oldest();
                }
                1
            }
        };
        self.runs.insert(source, Run { failures, last: now });
        Failure {
            first_of_run: failures == 1,
            failures,
            retry_after: self.policy.delay_after(failures),
            ended,
        }
    }

    /// Records a successful login from `source`: its run, if it had one, ends (forgotten or
    /// not: the count is still worth a line in the log).
    pub fn success(&mut self, source: &K) -> Option<EndedRun<K>> {
        let run = self.runs.remove(source)?;
        Some(EndedRun { source: source.clone(), failures: run.failures })
    }

    /// Forgets the sources quiet for [`ThrottlePolicy::forget_after`] at `now`, and returns
    /// their ended runs. A service calls it now and then (each second, or at each attempt).
    pub fn expire(&mut self, now: Duration) -> Vec<EndedRun<K>> {
        let mut ended = Vec::new();
        let forget_after = self.policy.forget_after;
        self.runs.retain(|source, run| {
            let live = now.saturating_sub(run.last) < forget_after;
            if !live {
                ended.push(EndedRun { source: source.clone(), failures: run.failures });
            }
            live
        });
        ended
    }

    /// Makes room: the source whose last failure is oldest goes (the first in key order among
    /// equals). A linear search, done only when a new source finds the table full.
    fn evict_oldest(&mut self) -> Option<EndedRun<K>> {
        let (source, run) = self.runs.iter().min_by_key(|(_, run)| run.last)?;
        let (source, failures) = (source.clone(), run.failures);
        self.runs.remove(&source);
        Some(EndedRun { source, failures })
    }
}

/// The throttling source of a client address: an IPv4 address as it is (an IPv4 address
/// mapped into IPv6 as the IPv4 one); an IPv6 address by its /64 prefix, because one host
/// usually has a whole /64 to pick addresses from.
pub fn source_of(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V4(_) => ip,
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => IpAddr::V4(v4),
            None => {
                let prefix = u128::from(v6) & !((1u128 << 64) - 1);
                IpAddr::V6(Ipv6Addr::from(prefix))
            }
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(secs: u64) -> Duration {
        Duration::from_secs(secs)
    }

    fn policy() -> ThrottlePolicy {
        ThrottlePolicy::default()
    }

    #[test]
    fn the_delay_doubles_after_the_free_failures_and_is_capped() {
        let p = policy();
        let delays: Vec<u64> = (0..=12).map(|n| p.delay_after(n).as_secs()).collect();
        assert_eq!(delays, [0, 0, 0, 1, 2, 4, 8, 16, 32, 60, 60, 60, 60]);
        assert_eq!(p.delay_after(u32::MAX), s(60), "no overflow");
    }

    #[test]
    fn a_source_waits_after_its_free_failures_and_others_do_not() {
        let mut t = Throttle::new(policy());
        let a = "10.0.0.1".to_string();
        for (n, at) in [(1, 0), (2, 1), (3, 2)] {
            assert_eq!(t.check(&a, s(at)), Ok(()));
            let f = t.failure(a.clone(), s(at));
            assert_eq!((f.failures, f.first_of_run), (n, n == 1));
        }
        // The third failure, at 2 s, earned 1 s.
        assert_eq!(t.check(&a, s(2)), Err(s(1)));
        assert_eq!(t.check(&a, s(2) + Duration::from_millis(400)), Err(Duration::from_millis(600)));
        assert_eq!(t.check(&"10.0.0.2".to_string(), s(2)), Ok(()));
        assert_eq!(t.check(&a, s(3)), Ok(()));
        let f = t.failure(a.clone(), s(3));
        assert_eq!((f.failures, f.first_of_run, f.retry_after), (4, false, s(2)));
        assert_eq!(t.check(&a, s(4)), Err(s(1)));
        assert_eq!(t.check(&a, s(5)), Ok(()));
    }

    #[test]
    fn a_success_ends_the_run_with_its_count() {
        let mut t = Throttle::new(policy());
        t.failure("a", s(0));
        t.failure("a", s(1));
        assert_eq!(t.success(&"a"), Some(EndedRun { source: "a", failures: 2 }));
        assert_eq!(t.success(&"a"), None, "no run, nothing to log");
        assert!(t.failure("a", s(2)).first_of_run, "a new run");
    }

    #[test]
    fn a_quiet_source_is_forgotten_and_its_run_ended() {
        let mut t = Throttle::new(policy());
        for at in 0..5 {
            t.failure("a", s(at));
        }
        t.failure("b", s(100));
        let quiet = s(4) + s(15 * 60);
        assert!(t.check(&"a", quiet - s(1)).is_ok(), "its 4 s wait passed long ago");
        assert_eq!(t.expire(quiet - Duration::from_nanos(1)), []);
        assert_eq!(t.expire(quiet), [EndedRun { source: "a", failures: 5 }]);
        assert_eq!(t.len(), 1);
        // A failure after the quiet time without an expire in between: a new run, which
        // reports the old one ended.
        let mut t2 = Throttle::new(policy());
        t2.failure("a", s(0));
        t2.failure("a", s(1));
        let f = t2.failure("a", s(1) + s(15 * 60));
        assert!(f.first_of_run);
        assert_eq!(f.ended, Some(EndedRun { source: "a", failures: 2 }));
        // A waiting source is not waiting any more once forgotten.
        let mut t3 = Throttle::new(ThrottlePolicy { forget_after: s(10), ..policy() });
        for at in 0..12 {
            t3.failure("a", s(at));
        }
        assert_eq!(t3.check(&"a", s(20)), Err(s(51)));
        assert_eq!(t3.check(&"a", s(21)), Ok(()));
    }

    #[test]
    fn a_full_table_evicts_the_oldest_failure() {
        let mut t = Throttle::new(ThrottlePolicy { capacity: 3, ..policy() });
        t.failure(1, s(5));
        t.failure(2, s(1));
        t.failure(3, s(3));
        t.failure(2, s(2));
        // 1 at 5 s, 2 at 2 s (twice), 3 at 3 s: 2 is oldest.
        let f = t.failure(4, s(6));
        assert_eq!(f.ended, Some(EndedRun { source: 2, failures: 2 }));
        assert_eq!(t.len(), 3);
        // A known source never evicts.
        assert_eq!(t.failure(1, s(7)).ended, None);
        assert_eq!(t.len(), 3);
    }

    #[test]
    fn the_table_stays_bounded_under_many_sources() {
        let mut t = Throttle::new(policy());
        for n in 0u32..5000 {
            t.failure(n, Duration::from_millis(u64::from(n)));
        }
        assert_eq!(t.len(), 1024);
        assert_eq!(t.check(&4999, Duration::from_millis(4999)), Ok(()), "one failure is free");
    }

    #[test]
    fn sources_are_addresses_and_ipv6_hosts_by_their_prefix() {
        let ip = |text: &str| text.parse::<IpAddr>().unwrap();
        assert_eq!(source_of(ip("192.0.2.7")), ip("192.0.2.7"));
        assert_eq!(source_of(ip("::ffff:192.0.2.7")), ip("192.0.2.7"));
        assert_eq!(source_of(ip("2001:db8:1:2:aaaa:bbbb:cccc:dddd")), ip("2001:db8:1:2::"));
        assert_eq!(source_of(ip("2001:db8:1:2::1")), source_of(ip("2001:db8:1:2::2")));
        assert_ne!(source_of(ip("2001:db8:1:2::1")), source_of(ip("2001:db8:1:3::1")));
    }
}
