//! Grouped bar charts (the ablation spectrum): one group per metric, one bar per variant,
//! heights in [0, 1] (the caller normalises each metric), whiskers for the spread over seeds and
//! the raw value printed above each bar.

use super::canvas::{BLACK, Canvas, GREY, LIGHT_GREY, Rgb, text_height, text_width};
use risktwin_common::risk::RgbImage;

/// One variant's bars: per group a height in [0, 1], its spread (± half-width in the same
/// units) and the label printed above it.
#[derive(Debug, Clone, PartialEq)]
pub struct BarSeries {
    pub name: String,
    pub color: Rgb,
    pub heights: Vec<f64>,
    pub spreads: Vec<f64>,
    pub labels: Vec<String>,
}

const SCALE: usize = 2;
/// Value labels are small so that eight groups of three bars stay legible.
const LABEL_SCALE: usize = 1;

/// Renders `groups` (names under the axis) × `series` into a `width` × `height` image.
pub fn render(title: &str, groups: &[String], series: &[BarSeries], width: usize, height: usize) -> RgbImage {
    let mut c = Canvas::new(width, height);
    let (w, h) = (width as f64, height as f64);
    let (left, right, top, bottom) = (40.0, w - 20.0, 90.0, h - 50.0);
    c.text((w - text_width(title, SCALE)) / 2.0, 12.0, title, SCALE, BLACK);
    // Legend in one row under the title.
    let mut lx = left;
    for s in series {
        c.fill_rect(lx, 46.0, lx + 20.0, 58.0, s.color);
        c.text(lx + 26.0, 45.0, &s.name, SCALE, BLACK);
        lx += 26.0 + text_width(&s.name, SCALE) + 30.0;
    }
    for k in 0..=4 {
        let py = bottom - (bottom - top) * k as f64 / 4.0;
        c.line((left, py), (right, py), 1, LIGHT_GREY);
    }
    let group_w = (right - left) / groups.len().max(1) as f64;
    let bar_w = group_w * 0.8 / series.len().max(1) as f64;
    for (g, name) in groups.iter().enumerate() {
        let gx = left + g as f64 * group_w + group_w * 0.1;
        for (i, s) in series.iter().enumerate() {
            let v = s.heights.get(g).copied().filter(|v| v.is_finite()).unwrap_or(0.0).clamp(0.0, 1.0);
            let bx = gx + i as f64 * bar_w;
            let py = bottom - v * (bottom - top);
            c.fill_rect(bx + 1.0, py, bx + bar_w - 1.0, bottom, s.color);
            let mut label_y = py;
            if let Some(&sd) = s.spreads.get(g).filter(|sd| sd.is_finite() && **sd > 0.0) {
                let mid = bx + bar_w / 2.0;
                let hi = bottom - (v + sd).min(1.05) * (bottom - top);
                let lo = bottom - (v - sd).max(0.0) * (bottom - top);
                c.line((mid, hi), (mid, lo), 1, BLACK);
                c.line((mid - 3.0, hi), (mid + 3.0, hi), 1, BLACK);
                c.line((mid - 3.0, lo), (mid + 3.0, lo), 1, BLACK);
                label_y = hi;
            }
            if let Some(l) = s.labels.get(g) {
                let tx = bx + (bar_w - text_width(l, LABEL_SCALE)) / 2.0;
                c.text(tx, label_y - text_height(LABEL_SCALE) - 3.0, l, LABEL_SCALE, GREY);
            }
        }
        c.text(
            left + g as f64 * group_w + (group_w - text_width(name, SCALE)) / 2.0,
            bottom + 12.0,
            name,
            SCALE,
            BLACK,
        );
    }
    c.line((left, bottom), (right, bottom), 2, BLACK);
    c.into_image()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bar_heights_follow_values() {
        const BLUE: Rgb = [0, 0, 200];
        let s = BarSeries {
            name: "a".into(),
            color: BLUE,
            heights: vec![1.0, 0.25],
            spreads: vec![0.0, f64::NAN],
            labels: vec![],
        };
        let img = render("t", &["m1".into(), "m2".into()], &[s], 400, 300);
        let column = |x: usize| (0..300).filter(|&y| img.pixel(x, y) == BLUE).count();
        let (full, quarter) = (column(40 + 85), column(40 + 170 + 85));
        assert!(full > 3 * quarter && quarter > 0, "full {full}, quarter {quarter}");
    }
}
