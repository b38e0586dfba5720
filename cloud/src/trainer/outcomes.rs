//! A driver's outcomes on a set of scenarios with 95 % intervals (`risktwin evaluate`).
//!
//! The set's episodes are taken as independent draws from the scenario distribution the set
//! was sampled from (the held-out sampler of a seed, per kind; or the library's scenarios as
//! they are). A share (collision, success, off-road, out of time) is a binomial proportion, its
//! interval the Wilson score interval, which stays inside [0, 1] and is not empty at 0 of n
//! (Wilson 1927; Brown, Cai & DasGupta 2001 recommend it over the normal interval). A mean
//! (route completion, speed, smoothness, risk, reward) gets the Student-t interval
//! mean ± t(0.975, n − 1)·s/√n; with one episode the interval is the point.

use risktwin_common::metrics::{Ending, EpisodeMetrics};
use serde::Serialize;

/// Coverage of every interval.
pub const CONFIDENCE: f64 = 0.95;
/// The standard normal's 0.975 quantile.
const Z_975: f64 = 1.959_963_984_540_054;
/// Student t's 0.975 quantile for 1…30 degrees of freedom (standard tables); beyond, the
/// Cornish-Fisher expansion in 1/ν ([`t_975`]).
const T_975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131, 2.120,
    2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
];

/// A share of episodes with its Wilson 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Share {
    pub count: u64,
    pub episodes: u64,
    pub share: f64,
    pub low: f64,
    pub high: f64,
}

impl Share {
    /// `count` of `episodes` (all zero for no episodes: nothing was measured).
    pub fn wilson(count: u64, episodes: u64) -> Self {
        if episodes == 0 {
            return Self { count, episodes, share: 0.0, low: 0.0, high: 0.0 };
        }
        let (k, n) = (count as f64, episodes as f64);
        let p = k / n;
        let z2 = Z_975 * Z_975;
        let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
        let half = Z_975 / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
        // At 0 of n the low end is 0 and at n of n the high end 1 exactly; the formula gives
        // them up to a rounding error, which could leave the share outside its own interval.
        let low = if count == 0 { 0.0 } else { (centre - half).clamp(0.0, p) };
        let high = if count >= episodes { 1.0 } else { (centre + half).clamp(p, 1.0) };
        Self { count, episodes, share: p, low, high }
    }
}

/// A mean over episodes with its Student-t 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mean {
    pub mean: f64,
    pub low: f64,
    pub high: f64,
}

impl Mean {
    /// The mean of `values` (all zero when empty).
    pub fn of(values: &[f64]) -> Self {
        let n = values.len();
        if n == 0 {
            return Self { mean: 0.0, low: 0.0, high: 0.0 };
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        if n == 1 {
            return Self { mean, low: mean, high: mean };
        }
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let t = t_975(n - 1);
        let half = t * (var / n as f64).sqrt();
        Self { mean, low: mean - half, high: mean + half }
    }
}

/// Student t's 0.975 quantile for `dof` ≥ 1 degrees of freedom: the table to 30, then
/// z + (z³ + z)/(4ν) + (5z⁵ + 16z³ + 3z)/(96ν²) (Abramowitz & Stegun 26.7.5; at ν = 30 it gives
/// 2.0422 against the table's 2.042, and at ν = 60 2.0003 against 2.000).
fn t_975(dof: usize) -> f64 {
    if let Some(&t) = T_975.get(dof.wrapping_sub(1)) {
        return t;
    }
    let (z, nu) = (Z_975, dof as f64);
    z + (z.powi(3) + z) / (4.0 * nu) + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * nu * nu)
}

/// One driver on a set of episodes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutcomeSummary {
    pub episodes: u64,
    pub collision: Share,
    pub success: Share,
    pub offroad: Share,
    /// Ended at the horizon, unharmed but short of the route's end.
    pub out_of_time: Share,
    pub route_completion: Mean,
    pub avg_speed_mps: Mean,
    /// RMS steering-angle rate, rad/s.
    pub steering_smoothness: Mean,
    /// RMS longitudinal jerk, m/s³.
    pub longitudinal_smoothness: Mean,
    pub risk_score: Mean,
    pub reward: Mean,
}

impl OutcomeSummary {
    /// The summary of `episodes`.
    pub fn of<'a>(episodes: impl IntoIterator<Item = &'a EpisodeMetrics>) -> Self {
        let ms: Vec<&EpisodeMetrics> = episodes.into_iter().collect();
        let n = ms.len() as u64;
        let share = |end: Ending| Share::wilson(ms.iter().filter(|m| m.ending() == end).count() as u64, n);
        let mean = |f: fn(&EpisodeMetrics) -> f64| Mean::of(&ms.iter().map(|m| f(m)).collect::<Vec<_>>());
        Self {
            episodes: n,
            collision: share(Ending::Collision),
            success: share(Ending::Success),
            offroad: share(Ending::Offroad),
            out_of_time: share(Ending::OutOfTime),
            route_completion: mean(|m| m.route_completion),
            avg_speed_mps: mean(|m| m.avg_speed_mps),
            steering_smoothness: mean(|m| m.steering_smoothness),
            longitudinal_smoothness: mean(|m| m.longitudinal_smoothness),
            risk_score: mean(|m| m.risk_score),
            reward: mean(|m| m.reward),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_matches_published_values() {
        // Brown, Cai & DasGupta (2001) and any Wilson calculator: 0 of 10 → [0, 0.2775];
        // 5 of 10 → [0.2366, 0.7634]; 1 of 20 → [0.0089, 0.2361].
        let close = |s: Share, lo: f64, hi: f64| (s.low - lo).abs() < 5e-4 && (s.high - hi).abs() < 5e-4;
        assert!(close(Share::wilson(0, 10), 0.0, 0.2775), "{:?}", Share::wilson(0, 10));
        assert!(close(Share::wilson(5, 10), 0.2366, 0.7634), "{:?}", Share::wilson(5, 10));
        assert!(close(Share::wilson(1, 20), 0.0089, 0.2361), "{:?}", Share::wilson(1, 20));
        assert!(close(Share::wilson(10, 10), 0.7225, 1.0), "{:?}", Share::wilson(10, 10));
        assert_eq!(Share::wilson(0, 0).high, 0.0);
        // The share always lies in its interval, 0 of n from 0 and n of n to 1 exactly.
        for n in 1..=300 {
            for k in [0, 1, n / 2, n - 1, n] {
                let s = Share::wilson(k, n);
                assert!(s.low <= s.share && s.share <= s.high, "{k} of {n}: {s:?}");
            }
            assert_eq!((Share::wilson(0, n).low, Share::wilson(n, n).high), (0.0, 1.0), "n = {n}");
        }
    }

    #[test]
    fn the_mean_interval_uses_student_t() {
        // 1, 2, 3: mean 2, s = 1, t(0.975, 2) = 4.303 → 2 ± 4.303/√3.
        let m = Mean::of(&[1.0, 2.0, 3.0]);
        assert_eq!(m.mean, 2.0);
        assert!((m.high - (2.0 + 4.303 / 3f64.sqrt())).abs() < 1e-12, "{m:?}");
        assert_eq!(Mean::of(&[4.0]), Mean { mean: 4.0, low: 4.0, high: 4.0 });
        // Past the table, the expansion: t(0.975, 60) = 2.000, t(0.975, 120) = 1.980 (tables).
        assert!((t_975(30) - 2.042).abs() < 1e-3 && (t_975(31) - 2.040).abs() < 1e-3, "{}", t_975(31));
        assert!((t_975(60) - 2.000).abs() < 1e-3 && (t_975(120) - 1.980).abs() < 1e-3);
        let many: Vec<f64> = (0..100).map(f64::from).collect();
        let m = Mean::of(&many);
        let s = (many.iter().map(|v| (v - 49.5f64).powi(2)).sum::<f64>() / 99.0).sqrt();
        assert!((m.high - m.mean - t_975(99) * s / 10.0).abs() < 1e-9);
    }
}
