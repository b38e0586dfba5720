//! Evaluation metrics (paper table 1 plus the risk score) averaged over episodes, and their
//! mean and spread over training seeds.

use risktwin_common::metrics::{Ending, EpisodeMetrics};
use serde::Serialize;

/// The metrics of one policy on a set of episodes (means, and rates for the booleans).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct EvalMetrics {
    pub episodes: u64,
    /// Mean episode return under the full reward weights (the same for every variant).
    pub reward: f64,
    pub success_rate: f64,
    pub route_completion: f64,
    pub collision_rate: f64,
    pub avg_speed_mps: f64,
    /// RMS steering-angle rate, rad/s (lower is smoother).
    pub steering_smoothness: f64,
    /// RMS longitudinal jerk, m/s³ (lower is smoother).
    pub longitudinal_smoothness: f64,
    /// Mean scenario S_risk of the episodes (lower is safer).
    pub risk_score: f64,
    /// Episodes that left the road.
    pub offroad_rate: f64,
    /// Episodes that ended at the horizon, unharmed but short of the route's end (too slow).
    pub timeout_rate: f64,
}

/// Names of the metrics in [`EvalMetrics::values`] order.
pub const METRIC_NAMES: [&str; 8] = [
    "reward",
    "success_rate",
    "route_completion",
    "collision_rate",
    "avg_speed_mps",
    "steering_smoothness",
    "longitudinal_smoothness",
    "risk_score",
];

/// Whether a larger value is better, in [`METRIC_NAMES`] order.
pub const HIGHER_IS_BETTER: [bool; 8] = [true, true, true, false, true, false, false, false];

impl EvalMetrics {
    /// Averages episodes (all zero for none).
    pub fn average(ms: &[EpisodeMetrics]) -> Self {
        let n = ms.len().max(1) as f64;
        let mean = |f: &dyn Fn(&EpisodeMetrics) -> f64| ms.iter().map(f).sum::<f64>() / n;
        Self {
            episodes: ms.len() as u64,
            reward: mean(&|m| m.reward),
            success_rate: mean(&|m| f64::from(u8::from(m.success))),
            route_completion: mean(&|m| m.route_completion),
            collision_rate: mean(&|m| f64::from(u8::from(m.collision))),
            avg_speed_mps: mean(&|m| m.avg_speed_mps),
            steering_smoothness: mean(&|m| m.steering_smoothness),
            longitudinal_smoothness: mean(&|m| m.longitudinal_smoothness),
            risk_score: mean(&|m| m.risk_score),
            offroad_rate: mean(&|m| f64::from(u8::from(m.offroad))),
            timeout_rate: mean(&|m| f64::from(u8::from(m.ending() == Ending::OutOfTime))),
        }
    }

    /// The metrics in [`METRIC_NAMES`] order.
    pub fn values(&self) -> [f64; 8] {
        [
            self.reward,
            self.success_rate,
            self.route_completion,
            self.collision_rate,
            self.avg_speed_mps,
            self.steering_smoothness,
            self.longitudinal_smoothness,
            self.risk_score,
        ]
    }
}

/// Mean and spread of one metric over seeds (`std` is the sample standard deviation, 0 for one
/// seed).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Spread {
    pub mean: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

impl Spread {
    /// The spread of `values` (all zero when empty).
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var =
            if values.len() > 1 { values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0) } else { 0.0 };
        Self {
            mean,
            std: var.sqrt(),
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// [`EvalMetrics`] over seeds, metric by metric.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct EvalSpread {
    /// Episodes per seed.
    pub episodes: u64,
    pub reward: Spread,
    pub success_rate: Spread,
    pub route_completion: Spread,
    pub collision_rate: Spread,
    pub avg_speed_mps: Spread,
    pub steering_smoothness: Spread,
    pub longitudinal_smoothness: Spread,
    pub risk_score: Spread,
    pub offroad_rate: Spread,
    pub timeout_rate: Spread,
}

impl EvalSpread {
    /// The spread of each metric over the seeds' evaluations.
    pub fn over(per_seed: &[EvalMetrics]) -> Self {
        let s = |f: fn(&EvalMetrics) -> f64| Spread::of(&per_seed.iter().map(f).collect::<Vec<_>>());
        Self {
            episodes: per_seed.first().map_or(0, |m| m.episodes),
            reward: s(|m| m.reward),
            success_rate: s(|m| m.success_rate),
            route_completion: s(|m| m.route_completion),
            collision_rate: s(|m| m.collision_rate),
            avg_speed_mps: s(|m| m.avg_speed_mps),
            steering_smoothness: s(|m| m.steering_smoothness),
            longitudinal_smoothness: s(|m| m.longitudinal_smoothness),
            risk_score: s(|m| m.risk_score),
            offroad_rate: s(|m| m.offroad_rate),
            timeout_rate: s(|m| m.timeout_rate),
        }
    }

    /// The spreads in [`METRIC_NAMES`] order.
    pub fn values(&self) -> [Spread; 8] {
        [
            self.reward,
            self.success_rate,
            self.route_completion,
            self.collision_rate,
            self.avg_speed_mps,
            self.steering_smoothness,
            self.longitudinal_smoothness,
            self.risk_score,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_uses_the_sample_std() {
        let s = Spread::of(&[1.0, 2.0, 3.0]);
        assert_eq!((s.mean, s.min, s.max), (2.0, 1.0, 3.0));
        assert!((s.std - 1.0).abs() < 1e-12);
        assert_eq!(Spread::of(&[4.0]).std, 0.0);
        assert_eq!(Spread::of(&[]), Spread::default());
    }

    #[test]
    fn rates_count_episodes() {
        let m = |collision, success| EpisodeMetrics {
            collision,
            offroad: false,
            success,
            route_completion: if success { 1.0 } else { 0.5 },
            avg_speed_mps: 10.0,
            steering_smoothness: 0.0,
            longitudinal_smoothness: 0.0,
            min_ttc_s: None,
            min_distance_m: 5.0,
            risk_score: 0.2,
            reward: 1.0,
            steps: 10,
        };
        let e = EvalMetrics::average(&[m(true, false), m(false, true), m(false, true), m(false, false)]);
        assert_eq!((e.episodes, e.collision_rate, e.success_rate), (4, 0.25, 0.5));
        assert_eq!((e.offroad_rate, e.timeout_rate), (0.0, 0.25));
        assert!((e.route_completion - 0.75).abs() < 1e-12);
    }
}
