//! The twin's fidelity over time: per connected vehicle (one colour each), the S_risk score and
//! the risk field at its footprint as the twin saw them (solid) and as the truth had them
//! (dashed), and the twin's position error.

use super::canvas::{Bitmap, FONT, FigureError, PALETTE, register_fonts};
use plotters::prelude::*;
use risktwin_cloud::twin::fidelity::SeriesPoint;
use std::collections::BTreeMap;

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 1050;

/// One panel: title, y axis with unit, and the (twin, truth) values of a point (truth NaN: none).
struct Panel {
    title: &'static str,
    y_desc: &'static str,
    values: fn(&SeriesPoint) -> (f64, f64),
}

const PANELS: [Panel; 3] = [
    Panel { title: "S_risk (solid: twin, dashed: truth)", y_desc: "S_risk", values: |p| p.s_risk },
    Panel { title: "Risk field at the vehicle (solid: twin, dashed: truth)", y_desc: "R", values: |p| p.risk_at_ego },
    Panel { title: "Twin position error", y_desc: "error (m)", values: |p| (p.position_error_m, f64::NAN) },
];

/// The three panels, one above the other, time in seconds from the first point of any vehicle.
/// At most as many vehicles as the palette has colours are drawn (the first by name).
pub fn fidelity(series: &BTreeMap<String, Vec<SeriesPoint>>) -> Result<Bitmap, FigureError> {
    register_fonts();
    let mut image = Bitmap::new(WIDTH, HEIGHT);
    let t0_ns = series.values().filter_map(|s| s.first()).map(|p| p.tick_ns).min().unwrap_or(0);
    let drawn: Vec<(&String, &Vec<SeriesPoint>)> = series.iter().take(PALETTE.len()).collect();
    {
        let root = BitMapBackend::with_buffer(&mut image.rgb, (WIDTH, HEIGHT)).into_drawing_area();
        let names = drawn.iter().map(|(k, _)| k.as_str()).collect::<Vec<_>>().join(", ");
        let root =
            root.titled(&format!("Twin against ground truth ({names})"), (FONT, 22)).map_err(FigureError::draw)?;
        for (area, panel) in root.split_evenly((3, 1)).iter().zip(&PANELS) {
            draw_panel(area, panel, &drawn, t0_ns)?;
        }
        root.present().map_err(FigureError::draw)?;
    }
    Ok(image)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
    drawn: &[(&String, &Vec<SeriesPoint>)],
    t0_ns: i64,
) -> Result<(), FigureError> {
    let t_s = |p: &SeriesPoint| (p.tick_ns - t0_ns) as f64 * 1e-9;
    let (mut t_max, mut y_max) = (1.0f64, 0.0f64);
    for (_, points) in drawn {
        for p in points.iter() {
            let (a, b) = (panel.values)(p);
            t_max = t_max.max(t_s(p));
            y_max = [a, b].into_iter().filter(|v| v.is_finite()).fold(y_max, f64::max);
        }
    }
    let y_hi = if y_max > 0.0 { y_max * 1.08 } else { 1.0 };
    let mut chart = ChartBuilder::on(area)
        .caption(panel.title, (FONT, 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..t_max * 1.01, 0.0..y_hi)
        .map_err(FigureError::draw)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc("time (s)")
        .y_desc(panel.y_desc)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .draw()
        .map_err(FigureError::draw)?;
    for (i, (name, points)) in drawn.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let twin = points.iter().map(|p| (t_s(p), (panel.values)(p).0)).filter(|(_, v)| v.is_finite());
        chart
            .draw_series(LineSeries::new(twin, colour.stroke_width(2)))
            .map_err(FigureError::draw)?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        let truth: Vec<(f64, f64)> =
            points.iter().map(|p| (t_s(p), (panel.values)(p).1)).filter(|(_, v)| v.is_finite()).collect();
        if !truth.is_empty() {
            chart
                .draw_series(DashedLineSeries::new(truth, 6, 4, colour.mix(0.8).stroke_width(1)))
                .map_err(FigureError::draw)?;
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font((FONT, 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(FigureError::draw)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_figure_draws_twin_and_truth_lines() {
        let point = |k: i64, twin: f64, truth: f64| SeriesPoint {
            tick_ns: k * 100_000_000,
            position_error_m: 0.2,
            s_risk: (twin, truth),
            risk_at_ego: (twin, truth),
        };
        let mut series = BTreeMap::new();
        series.insert("site0/v0".to_owned(), (0..50).map(|k| point(k, 0.3, 0.35)).collect());
        let image = fidelity(&series).expect("draws");
        assert_eq!((image.width, image.height), (WIDTH, HEIGHT));
        let coloured = image.rgb.chunks(3).filter(|p| p == &[31, 119, 180]).count();
        assert!(coloured > 500, "the first vehicle's colour is drawn ({coloured} pixels)");
    }
}
