//! Line charts in panels: each panel has its own axes and series, a series a line (solid or
//! dashed), optionally a min–max band, and a legend entry. The V2X sweep's figures are drawn
//! with it.

use super::canvas::{Bitmap, FONT, FigureError, PALETTE, register_fonts};
use plotters::prelude::*;

/// One line.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// (x, low, high) of a band drawn under the line.
    pub band: Vec<(f64, f64, f64)>,
    pub dashed: bool,
    /// Index into the palette.
    pub colour: usize,
}

/// One panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    pub title: String,
    pub x_desc: String,
    pub y_desc: String,
    /// Draw y on [0, 1].
    pub share: bool,
    pub series: Vec<Series>,
}

/// `panels` in a grid of `columns`, under `title`.
pub fn line_panels(title: &str, panels: &[Panel], columns: usize, panel_px: (u32, u32)) -> Result<Bitmap, FigureError> {
    register_fonts();
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let (width, height) = (panel_px.0 * columns as u32, panel_px.1 * rows as u32 + 40);
    let mut image = Bitmap::new(width, height);
    {
        let root = BitMapBackend::with_buffer(&mut image.rgb, (width, height)).into_drawing_area();
        let root = root.titled(title, (FONT, 22)).map_err(FigureError::draw)?;
        for (area, panel) in root.split_evenly((rows, columns)).iter().zip(panels) {
            draw_panel(area, panel)?;
        }
        root.present().map_err(FigureError::draw)?;
    }
    Ok(image)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
) -> Result<(), FigureError> {
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for s in &panel.series {
        let ys = s.points.iter().map(|p| (p.0, p.1)).chain(s.band.iter().flat_map(|b| [(b.0, b.1), (b.0, b.2)]));
        for (x, y) in ys.filter(|(x, y)| x.is_finite() && y.is_finite()) {
            (x_lo, x_hi, y_lo, y_hi) = (x_lo.min(x), x_hi.max(x), y_lo.min(y), y_hi.max(y));
        }
    }
    if !x_lo.is_finite() {
        (x_lo, x_hi) = (0.0, 1.0);
    }
    if !y_lo.is_finite() || panel.share {
        (y_lo, y_hi) = (0.0, 1.0);
    }
    let x_pad = ((x_hi - x_lo) * 0.03).max(1e-9);
    let y_pad = ((y_hi - y_lo) * 0.06).max(1e-3);
    let (y_lo, y_hi) = if panel.share { (-0.02, 1.02) } else { (y_lo.min(0.0) - y_pad, y_hi + y_pad) };
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, (FONT, 17))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d((x_lo - x_pad)..(x_hi + x_pad), y_lo..y_hi)
        .map_err(FigureError::draw)?;
    chart
        .configure_mesh()
        .light_line_style(WHITE)
        .x_desc(panel.x_desc.as_str())
        .y_desc(panel.y_desc.as_str())
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .draw()
        .map_err(FigureError::draw)?;
    for s in &panel.series {
        let colour = PALETTE[s.colour % PALETTE.len()];
        if s.band.len() > 1 {
            let upper = s.band.iter().map(|b| (b.0, b.2));
            let lower = s.band.iter().rev().map(|b| (b.0, b.1));
            chart
                .draw_series(std::iter::once(Polygon::new(upper.chain(lower).collect::<Vec<_>>(), colour.mix(0.15))))
                .map_err(FigureError::draw)?;
        }
        let style = colour.stroke_width(2);
        let drawn = if s.dashed {
            chart.draw_series(DashedLineSeries::new(s.points.iter().copied(), 8, 5, style))
        } else {
            chart.draw_series(LineSeries::new(s.points.iter().copied(), style))
        }
        .map_err(FigureError::draw)?;
        drawn
            .label(s.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
        chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, colour.filled()))).map_err(FigureError::draw)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font((FONT, 12))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(FigureError::draw)?;
    Ok(())
}
