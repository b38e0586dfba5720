//! The report's charts: training curves (one line per variant, the seeds' min–max as a band)
//! and the ablation spectrum (all metrics, normalised per metric so that higher is better).

use crate::plot::PALETTE;
use crate::plot::bars::{self, BarSeries};
use crate::plot::lines::{self, Panel, Series};
use risktwin_cloud::trainer::ablation::CurveBand;
use risktwin_cloud::trainer::stats::HIGHER_IS_BETTER;
use risktwin_cloud::trainer::{AblationReport, Spread};
use risktwin_common::risk::RgbImage;

/// Group labels under the axis, in `METRIC_NAMES` order (short, so neighbours do not overlap).
const SHORT_NAMES: [&str; 8] =
    ["reward", "success", "completion", "collision", "speed", "steer rate", "jerk", "S_risk"];

/// Height of the worst variant's bar, so every bar stays visible.
const FLOOR: f64 = 0.15;

/// Reward, success, route completion and speed against environment steps, 2 × 2 panels.
pub fn training_curves(ab: &AblationReport) -> RgbImage {
    let metric = |title: &str, f: fn(&CurveBand) -> Spread| Panel {
        title: title.to_string(),
        x_label: "environment steps".to_string(),
        series: ab
            .variants
            .iter()
            .enumerate()
            .map(|(i, v)| Series {
                name: v.variant.clone(),
                color: PALETTE[i % PALETTE.len()],
                points: v.curve.iter().map(|b| (b.env_steps as f64, f(b).mean)).collect(),
                band: v.curve.iter().map(|b| (b.env_steps as f64, f(b).min, f(b).max)).collect(),
            })
            .collect(),
    };
    let panels = [
        metric("training reward", |b| b.reward),
        metric("success rate", |b| b.success_rate),
        metric("route completion", |b| b.route_completion),
        metric("average speed m/s", |b| b.avg_speed_mps),
    ];
    lines::render(&panels, 2, 640, 420)
}

/// Per metric, maps each variant's mean to [FLOOR, 1] with the best at 1 (min–max over the
/// variants, flipped where lower is better); a metric on which all agree gives 1 for all.
pub fn normalise(means: &[f64], higher_is_better: bool) -> (Vec<f64>, f64) {
    let lo = means.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = means.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = hi - lo;
    // NaN spans (no finite means) fall here too.
    if span.is_nan() || span <= 1e-12 {
        return (vec![1.0; means.len()], 0.0);
    }
    let scale = (1.0 - FLOOR) / span;
    let heights = means.iter().map(|&m| FLOOR + scale * if higher_is_better { m - lo } else { hi - m }).collect();
    (heights, scale)
}

/// The ablation spectrum: one group per metric, one bar per variant, raw means as labels.
pub fn ablation(ab: &AblationReport) -> RgbImage {
    let spreads: Vec<[Spread; 8]> = ab.variants.iter().map(|v| v.overall.values()).collect();
    let mut series: Vec<BarSeries> = ab
        .variants
        .iter()
        .enumerate()
        .map(|(i, v)| BarSeries {
            name: v.variant.clone(),
            color: PALETTE[i % PALETTE.len()],
            heights: Vec::new(),
            spreads: Vec::new(),
            labels: Vec::new(),
        })
        .collect();
    for (j, &higher) in HIGHER_IS_BETTER.iter().enumerate() {
        let means: Vec<f64> = spreads.iter().map(|s| s[j].mean).collect();
        let (heights, _) = normalise(&means, higher);
        for (i, s) in series.iter_mut().enumerate() {
            s.heights.push(heights[i]);
            // Seed spreads are often wider than the gaps between variants; whiskers that size
            // would cover the chart, so the spread lives in the report's table instead.
            s.spreads.push(0.0);
            s.labels.push(format!("{:.2}", spreads[i][j].mean));
        }
    }
    let groups: Vec<String> = SHORT_NAMES.iter().map(|n| n.to_string()).collect();
    bars::render("ablation on the held-out set (per metric: best = full height)", &groups, &series, 1400, 560)
}

#[cfg(test)]
mod tests {
    use super::normalise;

    #[test]
    fn best_is_one_worst_is_the_floor_either_direction() {
        let (h, scale) = normalise(&[0.2, 0.6, 0.4], true);
        assert_eq!(h[1], 1.0);
        assert!((h[0] - super::FLOOR).abs() < 1e-12);
        assert!((scale - 0.85 / 0.4).abs() < 1e-12);
        let (h, _) = normalise(&[0.2, 0.6, 0.4], false);
        assert_eq!(h[0], 1.0);
        assert!((h[1] - super::FLOOR).abs() < 1e-12);
        assert_eq!(normalise(&[3.0, 3.0], true).0, vec![1.0, 1.0]);
    }
}
