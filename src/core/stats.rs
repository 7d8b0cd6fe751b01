//! Latency and execution-time figures, kept without allocation: a fixed log-scale histogram.
//!
//! The real-time threads record into these on every task start and end, so recording must be
//! a few arithmetic operations on memory that exists from the start. Values are nanoseconds;
//! buckets are exact below 32 ns and then 32 per power of two (at most 1/32 ≈ 3 % wide), up to
//! 2^40 ns (about 18 minutes), past which values share the last bucket. A percentile reports
//! the upper edge of its bucket (never optimistic), capped by the exact maximum.

/// Sub-buckets per power of two (5 bits of mantissa).
const SUB_BITS: u32 = 5;
const SUB: usize = 1 << SUB_BITS;
/// Values from 2^MAX_EXP on share the last bucket.
const MAX_EXP: u32 = 40;
const BUCKETS: usize = SUB + (MAX_EXP - SUB_BITS) as usize * SUB;

/// A log-scale histogram of nanosecond values with exact count, min, max and mean.
#[derive(Clone, PartialEq, Eq)]
pub struct Histogram {
    counts: [u64; BUCKETS],
    count: u64,
    sum: u128,
    min: u64,
    max: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram { counts: [0; BUCKETS], count: 0, sum: 0, min: u64::MAX, max: 0 }
    }
}

impl std::fmt::Debug for Histogram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Histogram").field("summary", &self.summary()).finish()
    }
}

/// The figures of a histogram, in ns; all 0 when nothing was recorded.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Summary {
    pub count: u64,
    pub min: u64,
    pub avg: u64,
    pub p50: u64,
    pub p99: u64,
    pub p999: u64,
    pub max: u64,
}

fn bucket_of(value: u64) -> usize {
    if value < SUB as u64 {
        return value as usize;
    }
    let exp = 63 - value.leading_zeros();
    if exp >= MAX_EXP {
        return BUCKETS - 1;
    }
    let mantissa = (value >> (exp - SUB_BITS)) as usize & (SUB - 1);
    SUB + (exp - SUB_BITS) as usize * SUB + mantissa
}

/// The largest value that falls in `bucket`.
fn bucket_top(bucket: usize) -> u64 {
    if bucket < SUB {
        return bucket as u64;
    }
    let exp = (bucket - SUB) / SUB + SUB_BITS as usize;
    let mantissa = ((bucket - SUB) % SUB) as u64;
    let width = 1u64 << (exp - SUB_BITS as usize);
    ((SUB as u64 + mantissa) << (exp - SUB_BITS as usize)) + width - 1
}

impl Histogram {
    pub fn new() -> Histogram {
        Histogram::default()
    }

    /// Makes this histogram equal to `src`, touching only the buckets either has in use (from
    /// the bucket of its minimum to that of its maximum), so that a snapshot of a few
    /// histograms costs a few hundred bytes of copying rather than kilobytes.
    pub fn copy_from(&mut self, src: &Histogram) {
        if self.count > 0 {
            self.counts[bucket_of(self.min)..=bucket_of(self.max)].fill(0);
        }
        if src.count > 0 {
            let used = bucket_of(src.min)..=bucket_of(src.max);
            self.counts[used.clone()].copy_from_slice(&src.counts[used]);
        }
        self.count = src.count;
        self.sum = src.sum;
        self.min = src.min;
        self.max = src.max;
    }

    #[inline]
    pub fn record(&mut self, ns: u64) {
        self.counts[bucket_of(ns)] += 1;
        self.count += 1;
        self.sum += u128::from(ns);
        self.min = self.min.min(ns);
        self.max = self.max.max(ns);
    }

    pub fn count(&self) -> u64 {
        self.count
    }

    /// The buckets in use, in order: (largest value of the bucket, count).
    pub fn buckets(&self) -> impl Iterator<Item = (u64, u64)> + '_ {
        self.counts
            .iter()
            .enumerate()
            .filter(|&(_, &n)| n > 0)
            .map(|(bucket, &n)| (bucket_top(bucket), n))
    }

    /// The value below or at which a share `q` (0.0..=1.0) of the recorded values lie, rounded
    /// up to its bucket's upper edge and capped by the maximum; 0 when empty.
    pub fn quantile(&self, q: f64) -> u64 {
        if self.count == 0 {
            return 0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.count as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (bucket, &n) in self.counts.iter().enumerate() {
            seen += n;
            if seen >= rank {
                return bucket_top(bucket).clamp(self.min, self.max);
            }
        }
        self.max
    }

    pub fn summary(&self) -> Summary {
        if self.count == 0 {
            return Summary::default();
        }
        Summary {
            count: self.count,
            min: self.min,
            avg: (self.sum / u128::from(self.count)) as u64,
            p50: self.quantile(0.50),
            p99: self.quantile(0.99),
            p999: self.quantile(0.999),
            max: self.max,
        }
    }
}

impl Summary {
    /// `min/avg/p50/p99/p99.9/max` in µs with one decimal, for logs and the exit report.
    pub fn micros(&self) -> String {
        let us = |ns: u64| ns as f64 / 1000.0;
        format!(
            "min {:.1} avg {:.1} p50 {:.1} p99 {:.1} p99.9 {:.1} max {:.1} µs",
            us(self.min),
            us(self.avg),
            us(self.p50),
            us(self.p99),
            us(self.p999),
            us(self.max)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_list_the_counts_in_use_by_their_upper_edge() {
        let mut h = Histogram::new();
        for v in [3, 3, 40_000, 1_000_000] {
            h.record(v);
        }
        let buckets: Vec<(u64, u64)> = h.buckets().collect();
        assert_eq!(buckets.len(), 3);
        assert_eq!(buckets[0], (3, 2));
        assert!(buckets[1].0 >= 40_000 && buckets[1].0 < 40_000 * 103 / 100, "{buckets:?}");
        assert_eq!(buckets.iter().map(|b| b.1).sum::<u64>(), h.count());
    }

    #[test]
    fn copy_from_equals_a_clone_whatever_was_there_before() {
        let mut a = Histogram::new();
        for v in [5, 90, 1_000, 70_000, 3_000_000] {
            a.record(v);
        }
        let mut b = Histogram::new();
        for v in [10_000_000_000, 2, 400] {
            b.record(v);
        }
        b.copy_from(&a);
        assert_eq!(b, a);
        b.copy_from(&Histogram::new());
        assert_eq!(b, Histogram::new());
    }

    #[test]
    fn buckets_cover_values_in_order() {
        let mut last = 0;
        for value in (0..100_000u64).chain([1 << 20, (1 << 40) - 1]) {
            let b = bucket_of(value);
            assert!(b >= last, "bucket order at {value}");
            assert!(bucket_top(b) >= value, "{value} above the top of its bucket {b}");
            if b > 0 {
                assert!(bucket_top(b - 1) < value, "{value} belongs to an earlier bucket");
            }
            last = b;
        }
        assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
    }

    #[test]
    fn bucket_width_is_at_most_a_32nd() {
        for b in SUB..BUCKETS - 1 {
            let low = bucket_top(b - 1) + 1;
            let width = bucket_top(b) - low + 1;
            assert!(width * 32 <= low, "bucket {b}: {low} + {width}");
        }
    }

    #[test]
    fn quantiles_of_a_known_distribution() {
        let mut h = Histogram::new();
        for v in 1..=1000u64 {
            h.record(v * 1000);
        }
        let s = h.summary();
        assert_eq!((s.count, s.min, s.max, s.avg), (1000, 1000, 1_000_000, 500_500));
        // Upper bucket edges: within 1/32 above the exact quantile, never below it.
        for (got, exact) in [(s.p50, 500_000), (s.p99, 990_000), (s.p999, 999_000)] {
            assert!(got >= exact && got <= exact + exact / 32, "{got} vs {exact}");
        }
    }

    #[test]
    fn a_single_value_is_every_quantile() {
        let mut h = Histogram::new();
        h.record(12_345);
        let s = h.summary();
        assert_eq!([s.min, s.p50, s.p99, s.p999, s.max], [12_345; 5]);
    }

    #[test]
    fn empty_is_all_zero() {
        assert_eq!(Histogram::new().summary(), Summary::default());
        assert_eq!(Histogram::new().quantile(0.5), 0);
    }

    #[test]
    fn rare_outliers_show_in_the_tail_only() {
        let mut h = Histogram::new();
        for _ in 0..9980 {
            h.record(10_000);
        }
        for _ in 0..20 {
            h.record(5_000_000);
        }
        let s = h.summary();
        assert!((10_000..=10_000 + 10_000 / 32).contains(&s.p50));
        assert_eq!(s.p99, s.p50);
        assert!(s.p999 > 4_000_000);
        assert_eq!(s.max, 5_000_000);
    }
}
