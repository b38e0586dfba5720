//! The edge's own clock: true time seen through a constant offset, a rate drift and a random
//! capture jitter, so that the cloud has real clock differences to estimate and align.

use risktwin_common::rng::Rng;
use std::time::Duration;

/// How an edge's clock differs from true time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockModel {
    /// Constant offset added to every stamp, ns.
    pub offset_ns: i64,
    /// Rate error in parts per million (positive: the edge clock runs fast).
    pub drift_ppm: f64,
    /// Capture stamps are moved by a uniform random amount in ±`jitter_ns`.
    pub jitter_ns: i64,
    /// Seed of the jitter.
    pub seed: u64,
}

impl Default for ClockModel {
    fn default() -> Self {
        ClockModel { offset_ns: 0, drift_ppm: 0.0, jitter_ns: 0, seed: 0 }
    }
}

/// A running edge clock: true time comes in as the elapsed time since `epoch_ns` (the caller
/// owns the real clock, which keeps this deterministic under test).
#[derive(Debug, Clone)]
pub struct EdgeClock {
    model: ClockModel,
    epoch_ns: i64,
    rng: Rng,
}

impl EdgeClock {
    /// A clock whose true time at elapsed zero is `epoch_ns` (ns since the Unix epoch).
    pub fn new(model: ClockModel, epoch_ns: i64) -> Self {
        EdgeClock { model, epoch_ns, rng: Rng::new(model.seed) }
    }

    /// The edge's reading at `elapsed` true time, without jitter (publish stamps).
    pub fn now_ns(&self, elapsed: Duration) -> i64 {
        let elapsed_ns = elapsed.as_nanos() as f64;
        let drifted_ns = elapsed_ns * (1.0 + self.model.drift_ppm * 1e-6);
        self.epoch_ns.saturating_add(drifted_ns as i64).saturating_add(self.model.offset_ns)
    }

    /// The edge's capture stamp at `elapsed` true time: [`EdgeClock::now_ns`] plus jitter.
    pub fn capture_ns(&mut self, elapsed: Duration) -> i64 {
        let jitter_ns = if self.model.jitter_ns > 0 {
            let j = self.model.jitter_ns as f64;
            self.rng.uniform(-j, j) as i64
        } else {
            0
        };
        self.now_ns(elapsed).saturating_add(jitter_ns)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_and_drift_shift_the_reading() {
        let model = ClockModel { offset_ns: 2_000, drift_ppm: 100.0, jitter_ns: 0, seed: 1 };
        let clock = EdgeClock::new(model, 1_000_000);
        assert_eq!(clock.now_ns(Duration::ZERO), 1_002_000);
        // 100 ppm over 1 s is 100 µs fast.
        assert_eq!(clock.now_ns(Duration::from_secs(1)), 1_000_000 + 1_000_000_000 + 100_000 + 2_000);
    }

    #[test]
    fn jitter_stays_in_bounds_and_is_seeded() {
        let model = ClockModel { jitter_ns: 500, seed: 7, ..ClockModel::default() };
        let (mut a, mut b) = (EdgeClock::new(model, 0), EdgeClock::new(model, 0));
        let mut moved = false;
        for i in 0..1000 {
            let t = Duration::from_millis(i);
            let (sa, sb) = (a.capture_ns(t), b.capture_ns(t));
            assert_eq!(sa, sb, "same seed, same jitter");
            let base = a.now_ns(t);
            assert!((sa - base).abs() <= 500, "jitter {} out of ±500", sa - base);
            moved |= sa != base;
        }
        assert!(moved, "jitter never moved a stamp");
    }
}
