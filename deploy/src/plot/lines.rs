//! Line charts in panels (training curves): one panel per metric, one coloured line per series,
//! an optional shaded band (e.g. the spread over seeds), nice ticks and a legend.

use super::axes::{Scale, label, range, ticks};
use super::canvas::{BLACK, Canvas, GREY, LIGHT_GREY, Rgb, text_height, text_width};
use risktwin_common::risk::RgbImage;

/// One line: points (x, y) in x order, and optionally a band (x, low, high) around it.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub color: Rgb,
    pub points: Vec<(f64, f64)>,
    pub band: Vec<(f64, f64, f64)>,
}

/// One chart: a title, an x-axis label and its series.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub series: Vec<Series>,
}

const SCALE: usize = 2;
const MARGIN_LEFT: f64 = 90.0;
const MARGIN_RIGHT: f64 = 20.0;
const MARGIN_TOP: f64 = 40.0;
const MARGIN_BOTTOM: f64 = 60.0;

/// Renders the panels in a grid of `columns`, each `panel_w` × `panel_h` pixels.
pub fn render(panels: &[Panel], columns: usize, panel_w: usize, panel_h: usize) -> RgbImage {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let mut canvas = Canvas::new(columns * panel_w, rows * panel_h);
    for (i, panel) in panels.iter().enumerate() {
        let (x0, y0) = (((i % columns) * panel_w) as f64, ((i / columns) * panel_h) as f64);
        draw_panel(&mut canvas, panel, x0, y0, panel_w as f64, panel_h as f64);
    }
    canvas.into_image()
}

fn draw_panel(c: &mut Canvas, panel: &Panel, x0: f64, y0: f64, w: f64, h: f64) {
    let (left, right) = (x0 + MARGIN_LEFT, x0 + w - MARGIN_RIGHT);
    let (top, bottom) = (y0 + MARGIN_TOP, y0 + h - MARGIN_BOTTOM);
    c.text(x0 + (w - text_width(&panel.title, SCALE)) / 2.0, y0 + 12.0, &panel.title, SCALE, BLACK);
    let xs = panel.series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let ys =
        panel.series.iter().flat_map(|s| s.points.iter().map(|p| p.1).chain(s.band.iter().flat_map(|b| [b.1, b.2])));
    let (Some(x_range), Some(y_range)) = (range(xs), range(ys)) else {
        c.text(left + 10.0, (top + bottom) / 2.0, "no data", SCALE, GREY);
        return;
    };
    let x = Scale { data: x_range, pixels: (left, right) };
    let y = Scale { data: y_range, pixels: (bottom, top) };
    let x_ticks = ticks(x_range.0, x_range.1, 5);
    let y_ticks = ticks(y_range.0, y_range.1, 5);
    let step = |t: &[f64]| if t.len() > 1 { t[1] - t[0] } else { 1.0 };
    for &v in &y_ticks {
        let py = y.map(v);
        c.line((left, py), (right, py), 1, LIGHT_GREY);
        let l = label(v, step(&y_ticks));
        c.text(left - 8.0 - text_width(&l, SCALE), py - text_height(SCALE) / 2.0, &l, SCALE, BLACK);
    }
    for &v in &x_ticks {
        let px = x.map(v);
        c.line((px, bottom), (px, bottom + 5.0), 1, BLACK);
        let l = label(v, step(&x_ticks));
        c.text(px - text_width(&l, SCALE) / 2.0, bottom + 10.0, &l, SCALE, BLACK);
    }
    let xl = &panel.x_label;
    c.text((left + right - text_width(xl, SCALE)) / 2.0, bottom + 32.0, xl, SCALE, GREY);
    for s in &panel.series {
        let pale = s.color.map(|v| (v as f64 * 0.3 + 255.0 * 0.7) as u8);
        for pair in s.band.windows(2) {
            // A band drawn as vertical strips between consecutive samples.
            let (a, b) = (pair[0], pair[1]);
            let (xa, xb) = (x.map(a.0), x.map(b.0));
            let n = (xb - xa).abs().ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                let px = xa + t * (xb - xa);
                let lo = a.1 + t * (b.1 - a.1);
                let hi = a.2 + t * (b.2 - a.2);
                c.line((px, y.map(lo)), (px, y.map(hi)), 1, pale);
            }
        }
    }
    for s in &panel.series {
        for pair in s.points.windows(2) {
            c.line((x.map(pair[0].0), y.map(pair[0].1)), (x.map(pair[1].0), y.map(pair[1].1)), 3, s.color);
        }
        if let [only] = s.points.as_slice() {
            c.fill_rect(x.map(only.0) - 3.0, y.map(only.1) - 3.0, x.map(only.0) + 3.0, y.map(only.1) + 3.0, s.color);
        }
    }
    c.outline(left, top, right, bottom, BLACK);
    // Legend, top left inside the plot.
    for (i, s) in panel.series.iter().enumerate() {
        let ly = top + 8.0 + i as f64 * (text_height(SCALE) + 6.0);
        c.fill_rect(left + 8.0, ly + 4.0, left + 28.0, ly + 10.0, s.color);
        c.text(left + 34.0, ly, &s.name, SCALE, BLACK);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(color: Rgb, points: Vec<(f64, f64)>) -> Series {
        Series { name: "s".into(), color, points, band: vec![] }
    }

    #[test]
    fn lines_land_where_the_data_says() {
        const RED: Rgb = [220, 0, 0];
        let panel =
            Panel { title: "t".into(), x_label: "x".into(), series: vec![series(RED, vec![(0.0, 0.0), (10.0, 10.0)])] };
        let img = render(&[panel], 1, 400, 300);
        assert_eq!((img.width, img.height), (400, 300));
        // The diagonal runs from the bottom-left to the top-right corner of the plot area.
        assert_eq!(img.pixel(MARGIN_LEFT as usize + 2, (300.0 - MARGIN_BOTTOM) as usize - 2), RED);
        let (cx, cy) = ((MARGIN_LEFT + 400.0 - MARGIN_RIGHT) / 2.0, (MARGIN_TOP + 300.0 - MARGIN_BOTTOM) / 2.0);
        assert_eq!(img.pixel(cx as usize, cy as usize), RED, "midpoint of the line");
        assert_ne!(img.pixel(cx as usize, MARGIN_TOP as usize + 60), RED, "nothing far above the line");
    }

    #[test]
    fn panels_tile_and_empty_panels_do_not_panic() {
        let empty = Panel { title: "empty".into(), x_label: String::new(), series: vec![] };
        let nan = Panel {
            title: "nan".into(),
            x_label: String::new(),
            series: vec![series(BLACK, vec![(f64::NAN, 1.0), (1.0, f64::INFINITY)])],
        };
        let img = render(&[empty, nan.clone(), nan], 2, 200, 100);
        assert_eq!((img.width, img.height), (400, 200));
    }
}
