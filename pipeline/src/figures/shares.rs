//! Shares with their intervals: one group per scenario kind, one bar per driver, the 95 %
//! interval as a whisker (`risktwin evaluate`'s collision and success figures).

use super::canvas::{Bitmap, FONT, FigureError, PALETTE, bar_legend, register_fonts};
use plotters::prelude::*;
use risktwin_cloud::trainer::outcomes::Share;

const WIDTH: u32 = 1100;
const HEIGHT: u32 = 560;

/// Share of a group's width the bars take.
const GROUP_FILL: f64 = 0.8;

/// One driver's bars: a share per group.
pub struct ShareSeries<'a> {
    pub label: &'a str,
    pub shares: Vec<Share>,
}

/// `series` over `groups` (each series has one share per group), titled `title`, the y axis
/// named `measure` (e.g. "collision share").
pub fn shares(
    title: &str,
    measure: &str,
    groups: &[String],
    series: &[ShareSeries<'_>],
) -> Result<Bitmap, FigureError> {
    register_fonts();
    let bar_w = GROUP_FILL / series.len().max(1) as f64;
    let mut image = Bitmap::new(WIDTH, HEIGHT);
    {
        let root = BitMapBackend::with_buffer(&mut image.rgb, (WIDTH, HEIGHT)).into_drawing_area();
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT, 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(-0.5..(groups.len() as f64 - 0.5), 0.0..1.05)
            .map_err(FigureError::draw)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(groups.len())
            .x_label_formatter(&|x| {
                let k = x.round();
                match (k >= 0.0 && (x - k).abs() < 1e-6).then(|| groups.get(k as usize)).flatten() {
                    Some(g) => g.clone(),
                    None => String::new(),
                }
            })
            .x_desc("scenario kind")
            .y_desc(format!("{measure} (whisker: 95 % interval)"))
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(FigureError::draw)?;
        for (i, s) in series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let left = move |j: usize| j as f64 - GROUP_FILL / 2.0 + i as f64 * bar_w;
            chart
                .draw_series(s.shares.iter().enumerate().map(|(j, sh)| {
                    Rectangle::new([(left(j) + 0.01, 0.0), (left(j) + bar_w - 0.01, sh.share)], colour.filled())
                }))
                .map_err(FigureError::draw)?
                .label(s.label)
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 16, y + 6)], colour.filled()));
            chart
                .draw_series(s.shares.iter().enumerate().map(|(j, sh)| {
                    let x = left(j) + bar_w / 2.0;
                    ErrorBar::new_vertical(x, sh.low, sh.share, sh.high, BLACK.stroke_width(2), 8)
                }))
                .map_err(FigureError::draw)?;
        }
        bar_legend(&mut chart)?;
        root.present().map_err(FigureError::draw)?;
    }
    Ok(image)
}
