//! A latency histogram that threads fill without locks or allocation (a deployment's link
//! relays, V2X awareness): log-linear buckets (64 per power of two, so a quantile is within
//! 1.6 % of the truth) of microseconds.

use std::sync::atomic::{AtomicU64, Ordering};

/// Sub-buckets per power of two.
const SUB: u32 = 64;
/// Rows of buckets: values up to 2^46 µs (two years) land in their own bucket; larger ones in
/// the last row.
const POWERS: u32 = 40;

/// Counts of values in µs.
pub struct Histogram {
    buckets: Box<[AtomicU64]>,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram { buckets: (0..(SUB * (POWERS + 1))).map(|_| AtomicU64::new(0)).collect() }
    }
}

impl std::fmt::Debug for Histogram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Histogram({} values)", self.count())
    }
}

/// The bucket of `us`: values below `SUB` are exact, above they share a bucket with the values
/// within 1/`SUB` of them.
fn bucket_of(us: u64) -> usize {
    if us < u64::from(SUB) {
        return us as usize;
    }
    let power = 63 - us.leading_zeros(); // ≥ log2(SUB)
    let shift = power - SUB.trailing_zeros();
    let sub = (us >> shift) as u32 - SUB; // 0..SUB
    let row = (shift + 1).min(POWERS);
    (row * SUB + sub) as usize
}

/// The middle of bucket `k`, µs.
fn value_of(k: usize) -> f64 {
    let (row, sub) = (k as u32 / SUB, k as u32 % SUB);
    if row == 0 {
        return f64::from(sub);
    }
    (f64::from(SUB + sub) + 0.5) * 2f64.powi(row as i32 - 1)
}

impl Histogram {
    pub fn record(&self, us: u64) {
        self.buckets[bucket_of(us)].fetch_add(1, Ordering::Relaxed);
    }

    /// Adds `other`'s counts to these.
    pub fn merge(&self, other: &Histogram) {
        for (mine, theirs) in self.buckets.iter().zip(other.buckets.iter()) {
            mine.fetch_add(theirs.load(Ordering::Relaxed), Ordering::Relaxed);
        }
    }

    pub fn count(&self) -> u64 {
        self.buckets.iter().map(|b| b.load(Ordering::Relaxed)).sum()
    }

    /// The `q` quantile (0–1), µs; `None` when empty.
    pub fn quantile(&self, q: f64) -> Option<f64> {
        let counts: Vec<u64> = self.buckets.iter().map(|b| b.load(Ordering::Relaxed)).collect();
        let total: u64 = counts.iter().sum();
        if total == 0 {
            return None;
        }
        let rank = ((q.clamp(0.0, 1.0) * total as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (k, c) in counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return Some(value_of(k));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_within_the_bucket_width() {
        let h = Histogram::default();
        for us in 1..=100_000u64 {
            h.record(us);
        }
        for (q, truth) in [(0.5, 50_000.0), (0.99, 99_000.0), (0.0001, 10.0)] {
            let got = h.quantile(q).expect("values");
            assert!((got - truth).abs() <= truth / 60.0 + 1.0, "q {q}: {got} against {truth}");
        }
        assert_eq!(h.count(), 100_000);
        assert_eq!(Histogram::default().quantile(0.5), None);
        h.record(u64::MAX);
        assert!(h.quantile(1.0).expect("values") > 1e12, "the largest values land in the last row");
    }
}
