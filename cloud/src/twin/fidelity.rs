//! Twin fidelity against a scene's ground truth: at every tick, each twin vehicle's position
//! against where its scene's authority says that vehicle truly was at the tick's time
//! (`risktwin/v1/<site>/scene/gt/<source>`, stamped on the same wall clock as the streams),
//! interpolated between the two surrounding truth samples. The error is what a user of the twin
//! sees: transport, alignment lateness and interpolation together.

use super::SiteTwin;
use risktwin_common::geometry::Vec2;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap, VecDeque};

/// Truth samples kept per vehicle: 10 s at 20 Hz, far more than any tick lags.
const KEPT_SAMPLES: usize = 200;
/// Histogram bin of the position error, m, and its range (errors beyond land in the last bin).
const BIN_M: f64 = 0.005;
const BINS: usize = 2000;

/// Position error of one vehicle over the ticks it was compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PositionError {
    pub ticks: u64,
    pub mean_m: f64,
    /// 95th percentile, to the histogram's 5 mm bin (upper edge).
    pub p95_m: f64,
    pub max_m: f64,
}

#[derive(Debug, Clone)]
struct Accumulator {
    ticks: u64,
    sum_m: f64,
    max_m: f64,
    histogram: Vec<u32>,
}

impl Accumulator {
    fn add(&mut self, error_m: f64) {
        self.ticks += 1;
        self.sum_m += error_m;
        self.max_m = self.max_m.max(error_m);
        self.histogram[((error_m / BIN_M) as usize).min(BINS - 1)] += 1;
    }

    fn finish(&self) -> PositionError {
        let rank = (0.95 * self.ticks as f64).ceil() as u64;
        let mut seen = 0u64;
        let bin = self.histogram.iter().position(|&n| {
            seen += u64::from(n);
            seen >= rank
        });
        let p95_m = bin.map_or(self.max_m, |b| ((b + 1) as f64 * BIN_M).min(self.max_m));
        PositionError { ticks: self.ticks, mean_m: self.sum_m / self.ticks.max(1) as f64, p95_m, max_m: self.max_m }
    }
}

/// The ground truth received so far and the errors measured against it.
#[derive(Debug, Default)]
pub struct Fidelity {
    /// Per `site/source`: (capture time ns, position), oldest first.
    truth: HashMap<String, VecDeque<(i64, Vec2)>>,
    errors: BTreeMap<String, Accumulator>,
}

impl Fidelity {
    /// A true position of `source` at `site` at `time_ns`.
    pub fn observe_truth(&mut self, site: &str, source: &str, time_ns: i64, position: Vec2) {
        let samples = self.truth.entry(format!("{site}/{source}")).or_default();
        // Out-of-order truth cannot be interpolated against; the publisher sends in order.
        if samples.back().is_some_and(|&(t, _)| t >= time_ns) {
            return;
        }
        if samples.len() == KEPT_SAMPLES {
            samples.pop_front();
        }
        samples.push_back((time_ns, position));
    }

    /// Compares every vehicle of `twin` (site `site`) at `tick_ns` with its truth, where the
    /// truth brackets the tick.
    pub fn compare(&mut self, site: &str, tick_ns: i64, twin: &SiteTwin) {
        for v in &twin.vehicles {
            let key = format!("{site}/{}", v.source);
            let Some(truth) = self.truth.get(&key).and_then(|s| position_at(s, tick_ns)) else { continue };
            let error_m = (v.kinematics.pose.position() - truth).norm();
            let histogram = vec![0; BINS];
            let acc = self.errors.entry(key).or_insert(Accumulator { ticks: 0, sum_m: 0.0, max_m: 0.0, histogram });
            acc.add(error_m);
        }
    }

    /// The errors per `site/source`.
    pub fn summary(&self) -> BTreeMap<String, PositionError> {
        self.errors.iter().map(|(k, a)| (k.clone(), a.finish())).collect()
    }
}

/// The position at `t_ns`, linear between the samples around it; `None` outside them.
fn position_at(samples: &VecDeque<(i64, Vec2)>, t_ns: i64) -> Option<Vec2> {
    let after = samples.iter().position(|&(t, _)| t >= t_ns)?;
    let (t1, p1) = samples[after];
    if t1 == t_ns {
        return Some(p1);
    }
    let (t0, p0) = samples.get(after.checked_sub(1)?).copied()?;
    let w = (t_ns - t0) as f64 / (t1 - t0) as f64;
    Some(p0 + (p1 - p0) * w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_is_interpolated_at_the_tick_and_errors_summarised() {
        let mut samples = VecDeque::new();
        samples.push_back((0, Vec2::new(0.0, 0.0)));
        samples.push_back((100, Vec2::new(10.0, 0.0)));
        assert_eq!(position_at(&samples, 25), Some(Vec2::new(2.5, 0.0)));
        assert_eq!(position_at(&samples, 100), Some(Vec2::new(10.0, 0.0)));
        assert_eq!(position_at(&samples, 101), None, "no extrapolation");
        assert_eq!(position_at(&samples, -1), None);
        let mut acc = Accumulator { ticks: 0, sum_m: 0.0, max_m: 0.0, histogram: vec![0; BINS] };
        for k in 0..100 {
            acc.add(0.001 * f64::from(k));
        }
        let e = acc.finish();
        assert_eq!(e.ticks, 100);
        assert!((e.mean_m - 0.0495).abs() < 1e-9 && (e.max_m - 0.099).abs() < 1e-12);
        assert!((e.p95_m - 0.095).abs() < 1e-9, "{}", e.p95_m);
    }
}
