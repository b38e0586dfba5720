//! Training curves: reward, success, route completion and speed against environment steps, one
//! panel each; per variant the mean over seeds as a line and the seeds' min–max as a band.

use super::canvas::{Bitmap, FONT, FigureError, PALETTE, register_fonts};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use risktwin_cloud::trainer::Spread;
use risktwin_cloud::trainer::ablation::{AblationReport, CurveBand};

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 930;
/// Height of the legend strip under the title, shared by the four panels (pixels).
const LEGEND_PX: u32 = 30;

/// One panel: its title, the y axis's name with unit, the metric, and whether it is a share
/// (drawn on [0, 1]).
struct Panel {
    title: &'static str,
    y_desc: &'static str,
    metric: fn(&CurveBand) -> Spread,
    share: bool,
}

const PANELS: [Panel; 4] = [
    Panel { title: "Training reward", y_desc: "reward per episode", metric: |b| b.reward, share: false },
    Panel { title: "Success rate", y_desc: "share of episodes", metric: |b| b.success_rate, share: true },
    Panel { title: "Route completion", y_desc: "share of the route", metric: |b| b.route_completion, share: true },
    Panel { title: "Average speed", y_desc: "speed (m/s)", metric: |b| b.avg_speed_mps, share: false },
];

/// The four panels in a 2 × 2 grid under one title.
pub fn training_curves(ab: &AblationReport) -> Result<Bitmap, FigureError> {
    register_fonts();
    let mut image = Bitmap::new(WIDTH, HEIGHT);
    {
        let root = BitMapBackend::with_buffer(&mut image.rgb, (WIDTH, HEIGHT)).into_drawing_area();
        let root = root
            .titled(&format!("Training curves ({}; line: mean over seeds, band: min–max)", ab.algo), (FONT, 24))
            .map_err(FigureError::draw)?;
        let (legend, panels) = root.split_vertically(LEGEND_PX);
        draw_legend(&legend, ab)?;
        for (area, panel) in panels.split_evenly((2, 2)).iter().zip(&PANELS) {
            draw_panel(area, panel, ab)?;
        }
        root.present().map_err(FigureError::draw)?;
    }
    Ok(image)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
    ab: &AblationReport,
) -> Result<(), FigureError> {
    let bands = ab.variants.iter().flat_map(|v| v.curve.iter());
    let (mut x_max, mut y_lo, mut y_hi) = (1.0f64, f64::INFINITY, f64::NEG_INFINITY);
    for b in bands {
        let s = (panel.metric)(b);
        x_max = x_max.max(b.env_steps as f64);
        for v in [s.min, s.max, s.mean].into_iter().filter(|v| v.is_finite()) {
            y_lo = y_lo.min(v);
            y_hi = y_hi.max(v);
        }
    }
    if !y_lo.is_finite() || panel.share {
        (y_lo, y_hi) = (0.0, 1.0);
    }
    let pad = ((y_hi - y_lo) * 0.06).max(0.02 * y_hi.abs().max(y_lo.abs()).max(1.0));
    let mut chart = ChartBuilder::on(area)
        .caption(panel.title, (FONT, 20))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..x_max * 1.02, (y_lo - pad)..(y_hi + pad))
        .map_err(FigureError::draw)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("environment steps")
        .y_desc(panel.y_desc)
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .x_labels(6)
        .x_label_formatter(&|x| steps_label(*x))
        .draw()
        .map_err(FigureError::draw)?;
    for (i, v) in ab.variants.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let spreads: Vec<(f64, Spread)> = v.curve.iter().map(|b| (b.env_steps as f64, (panel.metric)(b))).collect();
        // The band: up along the maxima, back along the minima.
        let mut outline: Vec<(f64, f64)> = spreads.iter().map(|(x, s)| (*x, s.max)).collect();
        outline.extend(spreads.iter().rev().map(|(x, s)| (*x, s.min)));
        if spreads.len() > 1 {
            chart.draw_series(std::iter::once(Polygon::new(outline, colour.mix(0.18)))).map_err(FigureError::draw)?;
        }
        chart
            .draw_series(LineSeries::new(spreads.iter().map(|(x, s)| (*x, s.mean)), colour.stroke_width(2)))
            .map_err(FigureError::draw)?;
        chart
            .draw_series(spreads.iter().map(|(x, s)| Circle::new((*x, s.mean), 3, colour.filled())))
            .map_err(FigureError::draw)?;
    }
    Ok(())
}

/// One legend for all panels, centred in a strip under the title: a line per variant.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    ab: &AblationReport,
) -> Result<(), FigureError> {
    const ENTRY_PX: i32 = 150;
    let (w, h) = area.dim_in_pixel();
    let y = h as i32 / 2;
    let mut x = (w as i32 - ENTRY_PX * ab.variants.len() as i32) / 2;
    for (i, v) in ab.variants.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        area.draw(&PathElement::new(vec![(x, y), (x + 28, y)], colour.stroke_width(3))).map_err(FigureError::draw)?;
        let style = TextStyle::from((FONT, 16).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
        area.draw(&Text::new(v.variant.clone(), (x + 36, y), style)).map_err(FigureError::draw)?;
        x += ENTRY_PX;
    }
    Ok(())
}

/// `250k`, `1.5M`: step counts short enough not to collide on the axis.
fn steps_label(x: f64) -> String {
    match x.abs() {
        a if a >= 1e6 => format!("{}M", trim(x / 1e6)),
        a if a >= 1e3 => format!("{}k", trim(x / 1e3)),
        _ => trim(x),
    }
}

fn trim(x: f64) -> String {
    let s = format!("{x:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    use super::steps_label;

    #[test]
    fn step_labels_are_short() {
        assert_eq!(steps_label(0.0), "0");
        assert_eq!(steps_label(2048.0), "2.05k");
        assert_eq!(steps_label(589_824.0), "589.82k");
        assert_eq!(steps_label(1_500_000.0), "1.5M");
    }
}
