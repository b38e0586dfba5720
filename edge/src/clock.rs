//! The edge's own clock: true time seen through a constant offset, a rate drift and a random
//! capture jitter, so that the cloud has real clock differences to estimate and align.

use risktwin_common::rng::Rng;
use std::path::{Path, PathBuf};
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

    /// Steps the clock by `by_ns` (a host's clock set by hand or by a time server).
    pub fn step(&mut self, by_ns: i64) {
        self.model.offset_ns = self.model.offset_ns.saturating_add(by_ns);
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

/// How often an edge looks for new clock steps.
pub const CLOCK_STEPS_EVERY: Duration = Duration::from_millis(100);

/// The clock steps of a file that grows by lines (one signed number of ms each): a deployment
/// appends one per `clock_step` event of the host, and every edge process of the host follows
/// them all, one started after a step too. A line that is not a number within ± a day is logged
/// and skipped; a file that cannot be read yet has no steps.
#[derive(Debug)]
pub struct ClockSteps {
    path: PathBuf,
    /// Bytes of whole lines read so far.
    read: usize,
}

/// The largest step taken, ms (a day).
const MAX_STEP_MS: f64 = 86_400_000.0;

impl ClockSteps {
    pub fn new(path: &Path) -> Self {
        ClockSteps { path: path.to_owned(), read: 0 }
    }

    /// The sum of the steps appended since the last call, ns.
    pub fn read_new(&mut self) -> i64 {
        let Ok(text) = std::fs::read_to_string(&self.path) else { return 0 };
        let Some(fresh) = text.get(self.read..) else { return 0 };
        // Only whole lines: the writer may be half-way through one.
        let Some(end) = fresh.rfind('\n') else { return 0 };
        self.read += end + 1;
        let mut by_ns = 0i64;
        for line in fresh[..end].lines().map(str::trim).filter(|l| !l.is_empty()) {
            match line.parse::<f64>() {
                Ok(ms) if ms.is_finite() && ms.abs() <= MAX_STEP_MS => {
                    by_ns = by_ns.saturating_add((ms * 1e6).round() as i64);
                }
                _ => tracing::warn!("{}: {line:?} is not a clock step in ms (± a day), skipped", self.path.display()),
            }
        }
        by_ns
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

    #[test]
    fn steps_are_read_as_whole_lines_as_they_are_appended() {
        let dir = tempfile::tempdir().expect("a temp dir");
        let path = dir.path().join("clock-steps");
        let mut steps = ClockSteps::new(&path);
        assert_eq!(steps.read_new(), 0, "no file yet: no step");
        std::fs::write(&path, "500\n-20.5\n").expect("writes");
        assert_eq!(steps.read_new(), 479_500_000);
        assert_eq!(steps.read_new(), 0, "each step once");
        std::fs::write(&path, "500\n-20.5\nnonsense\n1e12\n7").expect("writes");
        assert_eq!(steps.read_new(), 0, "bad lines skipped, a half line waits");
        std::fs::write(&path, "500\n-20.5\nnonsense\n1e12\n7\n").expect("writes");
        assert_eq!(steps.read_new(), 7_000_000);
        let mut clock = EdgeClock::new(ClockModel::default(), 0);
        clock.step(2_000_000);
        assert_eq!(clock.now_ns(Duration::from_secs(1)), 1_002_000_000);
    }
}
