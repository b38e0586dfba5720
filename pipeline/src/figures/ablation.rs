//! The ablation spectrum: one group per metric, one bar per variant, normalised per metric so
//! that the best variant reaches full height (flipped where lower is better), the raw means
//! written on the bars.

use super::canvas::{Bitmap, FONT, FigureError, PALETTE, bar_legend, register_fonts};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use risktwin_cloud::trainer::stats::HIGHER_IS_BETTER;
use risktwin_cloud::trainer::{AblationReport, Spread};

const WIDTH: u32 = 1400;
const HEIGHT: u32 = 620;

/// Group labels under the axis, in `METRIC_NAMES` order (short, so neighbours do not overlap).
const SHORT_NAMES: [&str; 8] =
    ["reward", "success", "completion", "collision ↓", "speed m/s", "steer rate ↓", "jerk ↓", "S_risk ↓"];

/// Height of the worst variant's bar, so every bar stays visible.
const FLOOR: f64 = 0.15;

/// Share of a group's width the bars take.
const GROUP_FILL: f64 = 0.8;

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

/// The spectrum as one chart; seed spreads are in the report's table, not drawn as whiskers
/// (they are often wider than the gaps between variants and would cover the chart).
pub fn ablation(ab: &AblationReport) -> Result<Bitmap, FigureError> {
    register_fonts();
    let spreads: Vec<[Spread; 8]> = ab.variants.iter().map(|v| v.overall.values()).collect();
    let n = ab.variants.len().max(1);
    let bar_w = GROUP_FILL / n as f64;
    // (variant, metric) → (height, raw mean).
    let mut bars: Vec<Vec<(f64, f64)>> = vec![Vec::new(); ab.variants.len()];
    for (j, &higher) in HIGHER_IS_BETTER.iter().enumerate() {
        let means: Vec<f64> = spreads.iter().map(|s| s[j].mean).collect();
        let (heights, _) = normalise(&means, higher);
        for (i, b) in bars.iter_mut().enumerate() {
            b.push((heights[i], means[i]));
        }
    }
    let mut image = Bitmap::new(WIDTH, HEIGHT);
    {
        let root = BitMapBackend::with_buffer(&mut image.rgb, (WIDTH, HEIGHT)).into_drawing_area();
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "Ablation on the held-out set ({} episodes): per metric, best variant = full height",
                    ab.held_out_episodes
                ),
                (FONT, 22),
            )
            .margin(16)
            .x_label_area_size(56)
            .y_label_area_size(80)
            .build_cartesian_2d(-0.5..(SHORT_NAMES.len() as f64 - 0.5), 0.0..1.18)
            .map_err(FigureError::draw)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .light_line_style(WHITE)
            .x_labels(SHORT_NAMES.len())
            .x_label_formatter(&|x| {
                let k = x.round();
                if (x - k).abs() < 1e-6 && k >= 0.0 {
                    SHORT_NAMES.get(k as usize).copied().unwrap_or("").to_string()
                } else {
                    String::new()
                }
            })
            .x_desc("metric on the held-out set (↓: lower is better, bar flipped)")
            .y_desc("normalised score (1 = best variant)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(FigureError::draw)?;
        for (i, (v, b)) in ab.variants.iter().zip(&bars).enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let left = |j: usize| j as f64 - GROUP_FILL / 2.0 + i as f64 * bar_w;
            chart
                .draw_series(b.iter().enumerate().map(|(j, (h, _))| {
                    Rectangle::new([(left(j) + 0.01, 0.0), (left(j) + bar_w - 0.01, *h)], colour.filled())
                }))
                .map_err(FigureError::draw)?
                .label(v.variant.as_str())
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 16, y + 6)], colour.filled()));
            let label_style = TextStyle::from((FONT, 12).into_font()).pos(Pos::new(HPos::Center, VPos::Bottom));
            chart
                .draw_series(b.iter().enumerate().map(|(j, (h, mean))| {
                    Text::new(format!("{mean:.2}"), (left(j) + bar_w / 2.0, h + 0.01), label_style.clone())
                }))
                .map_err(FigureError::draw)?;
        }
        bar_legend(&mut chart)?;
        root.present().map_err(FigureError::draw)?;
    }
    Ok(image)
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
