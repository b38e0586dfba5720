//! Risk-field heatmaps: the grid in viridis colours (cells off the map dimmed and left out of
//! the scale, see [`HeatmapLayers`]), road edges solid, lane centrelines dashed, other road users
//! outlined in white and the ego in red, on axes in metres, with a colour bar of risk values.

use super::canvas::{Bitmap, FONT, FigureError, register_fonts};
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use risktwin_common::episode::FieldSnapshot;
use risktwin_common::geometry::{Obb, Vec2};
use risktwin_common::risk::{HeatmapLayers, RiskGrid, road_layers};
use risktwin_commonroad::LaneletNetwork;
use risktwin_commonroad::twin::{CommonRoadField, lanelet_layers};

/// Pixels per grid cell, reduced for large grids so an image stays below [`MAX_PIXELS`], and
/// raised for small ones so the map keeps [`MIN_MAP_PX`] (room for the legend and the labels).
const PIXELS_PER_CELL: u32 = 4;
/// Longest side of the map at least, pixels.
const MIN_MAP_PX: u32 = 480;
/// Largest plot area (pixels).
const MAX_PIXELS: u64 = 1 << 26;
/// Brightness kept for off-map cells, percent.
const OFF_MAP_PERCENT: u16 = 35;
/// Room around the plot area: title, axes and colour bar (pixels).
const LEFT_PX: u32 = 100;
const RIGHT_PX: u32 = 150;
const TOP_PX: u32 = 50;
const BOTTOM_PX: u32 = 60;
const MAP_MARGIN_PX: u32 = 16;
const Y_LABELS_PX: u32 = LEFT_PX - MAP_MARGIN_PX;

const EDGE: RGBColor = RGBColor(255, 255, 255);
const CENTRELINE: RGBColor = RGBColor(190, 190, 190);
const OTHER: RGBColor = RGBColor(255, 255, 255);
/// The ego's outline.
pub const EGO: RGBColor = RGBColor(255, 40, 40);

/// Everything one heatmap shows.
#[derive(Debug, Clone)]
pub struct HeatmapScene<'a> {
    pub title: String,
    pub grid: &'a RiskGrid,
    pub layers: HeatmapLayers,
    pub others: &'a [Obb],
    pub ego: &'a Obb,
}

impl<'a> HeatmapScene<'a> {
    /// A snapshot of a generated scenario, over the twin's road.
    pub fn of_snapshot(snap: &'a FieldSnapshot, title: String) -> Self {
        let layers = road_layers(&snap.grid, &snap.road);
        HeatmapScene { title, grid: &snap.grid, layers, others: &snap.others, ego: &snap.ego }
    }

    /// A recorded CommonRoad scenario's field, over its lanelet map.
    pub fn of_commonroad(field: &'a CommonRoadField, network: &LaneletNetwork, title: String) -> Self {
        let layers = lanelet_layers(field, network);
        HeatmapScene { title, grid: &field.grid, layers, others: &field.others, ego: &field.ego }
    }
}

/// The colour of `value` on a scale with top `max`, dimmed off the map.
fn cell_colour(value: f32, max: f32, on_map: bool) -> RGBColor {
    let t = if value.is_finite() { (value / max).clamp(0.0, 1.0) } else { 0.0 };
    let c = ViridisRGB::get_color(t);
    if on_map {
        c
    } else {
        let dim = |v: u8| (u16::from(v) * OFF_MAP_PERCENT / 100) as u8;
        RGBColor(dim(c.0), dim(c.1), dim(c.2))
    }
}

/// Draws the heatmap: about [`PIXELS_PER_CELL`] pixels per cell, y up, metres on both axes.
pub fn heatmap(scene: &HeatmapScene) -> Result<Bitmap, FigureError> {
    register_fonts();
    let grid = scene.grid;
    let long_side = grid.cols.max(grid.rows).max(1) as u32;
    let mut ppc = PIXELS_PER_CELL.max(MIN_MAP_PX.div_ceil(long_side));
    while ppc > 1 && (grid.cols as u64 * grid.rows as u64) * u64::from(ppc * ppc) > MAX_PIXELS {
        ppc -= 1;
    }
    let (plot_w, plot_h) = (grid.cols as u32 * ppc, grid.rows as u32 * ppc);
    let (width, height) = (plot_w + LEFT_PX + RIGHT_PX, plot_h + TOP_PX + BOTTOM_PX);
    let (x0, y0) = (grid.origin_m.x, grid.origin_m.y);
    let (x1, y1) = (x0 + grid.cols as f64 * grid.resolution_m, y0 + grid.rows as f64 * grid.resolution_m);
    let mut image = Bitmap::new(width, height);
    {
        let root = BitMapBackend::with_buffer(&mut image.rgb, (width, height)).into_drawing_area();
        // The map's area: its y labels, the plot (plot_w wide) and a margin.
        let (main, bar) = root.split_horizontally(MAP_MARGIN_PX + Y_LABELS_PX + plot_w + MAP_MARGIN_PX);
        let mut chart = ChartBuilder::on(&main)
            .caption(&scene.title, (FONT, 18))
            .margin_top(8)
            .margin_left(MAP_MARGIN_PX)
            .margin_right(MAP_MARGIN_PX)
            .x_label_area_size(BOTTOM_PX - 12)
            .y_label_area_size(Y_LABELS_PX)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(FigureError::draw)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .draw()
            .map_err(FigureError::draw)?;
        // The cells, sampled at each pixel of the plot area (whatever size plotters gave it).
        let (w, h) = chart.plotting_area().dim_in_pixel();
        let mut cells = vec![0u8; 3 * w as usize * h as usize];
        for py in 0..h as usize {
            let row = grid.rows - 1 - (py * grid.rows / h.max(1) as usize).min(grid.rows - 1);
            for px in 0..w as usize {
                let col = (px * grid.cols / w.max(1) as usize).min(grid.cols - 1);
                let k = row * grid.cols + col;
                let value = grid.cells.get(k).copied().unwrap_or(0.0);
                let c = cell_colour(value, scene.layers.scale_max, scene.layers.is_on_map(k));
                cells[3 * (py * w as usize + px)..][..3].copy_from_slice(&[c.0, c.1, c.2]);
            }
        }
        let bitmap = BitMapElement::with_owned_buffer((x0, y1), (w, h), cells)
            .ok_or_else(|| FigureError::Draw("the cell bitmap does not fit its size".into()))?;
        chart.draw_series(std::iter::once(bitmap)).map_err(FigureError::draw)?;

        // Lines are clipped to the map: plotters would draw their outside parts over the axes.
        let view = (Vec2::new(x0, y0), Vec2::new(x1, y1));
        let mut labelled = false;
        for run in scene.layers.centrelines.iter().flat_map(|line| clip(line, view)) {
            let series = chart
                .draw_series(DashedLineSeries::new(run, 6, 6, CENTRELINE.stroke_width(1)))
                .map_err(FigureError::draw)?;
            if !std::mem::replace(&mut labelled, true) {
                series.label("lane centreline").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 8, y)], CENTRELINE));
            }
        }
        labelled = false;
        for run in scene.layers.edges.iter().flat_map(|line| clip(line, view)) {
            let series = chart.draw_series(LineSeries::new(run, EDGE.stroke_width(1))).map_err(FigureError::draw)?;
            if !std::mem::replace(&mut labelled, true) {
                series.label("road edge").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], EDGE));
            }
        }
        let outline = |obb: &Obb| {
            let c = obb.corners();
            clip(&[c[0], c[1], c[2], c[3], c[0]], view)
        };
        let others: Vec<_> = scene.others.iter().flat_map(outline).collect();
        if !others.is_empty() {
            chart
                .draw_series(others.into_iter().map(|run| PathElement::new(run, OTHER.stroke_width(2))))
                .map_err(FigureError::draw)?
                .label("other road users")
                .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], OTHER.stroke_width(2)));
        }
        chart
            .draw_series(outline(scene.ego).into_iter().map(|run| PathElement::new(run, EGO.stroke_width(2))))
            .map_err(FigureError::draw)?
            .label("ego")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], EGO.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font((FONT, 12).into_font().color(&WHITE))
            .background_style(BLACK.mix(0.55))
            .border_style(WHITE.mix(0.6))
            .draw()
            .map_err(FigureError::draw)?;
        colour_bar(&bar, scene.layers.scale_max)?;
        root.present().map_err(FigureError::draw)?;
    }
    Ok(image)
}

/// The parts of the polyline `line` inside the box `(lo, hi)`, as runs of points (each segment
/// clipped by Liang–Barsky).
fn clip(line: &[Vec2], (lo, hi): (Vec2, Vec2)) -> Vec<Vec<(f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut open = false;
    for w in line.windows(2) {
        let (a, d) = (w[0], w[1] - w[0]);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let inside =
            [(-d.x, a.x - lo.x), (d.x, hi.x - a.x), (-d.y, a.y - lo.y), (d.y, hi.y - a.y)].iter().all(|&(p, q)| {
                if p == 0.0 {
                    return q >= 0.0;
                }
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r)
                } else {
                    t1 = t1.min(r)
                }
                t0 <= t1
            });
        if !inside {
            open = false;
            continue;
        }
        let (p0, p1) = (a + d * t0, a + d * t1);
        if !open || t0 > 0.0 {
            runs.push(vec![(p0.x, p0.y)]);
        }
        if let Some(run) = runs.last_mut() {
            run.push((p1.x, p1.y));
        }
        open = t1 >= 1.0;
    }
    runs
}

/// The colour scale from 0 to `max` with its values, right of the map.
fn colour_bar<DB: DrawingBackend>(area: &DrawingArea<DB, plotters::coord::Shift>, max: f32) -> Result<(), FigureError> {
    const STEPS: usize = 128;
    let top = f64::from(max);
    let mut chart = ChartBuilder::on(area)
        .margin_top(TOP_PX as i32)
        .margin_bottom(BOTTOM_PX as i32 - 12)
        .margin_right(8)
        .set_label_area_size(LabelAreaPosition::Right, 90)
        .build_cartesian_2d(0.0..1.0, 0.0..top)
        .map_err(FigureError::draw)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(6)
        .y_label_formatter(&|v| format!("{v:.2}"))
        .y_desc("risk R (top: on-road max)")
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 13))
        .draw()
        .map_err(FigureError::draw)?;
    chart
        .draw_series((0..STEPS).map(|k| {
            let (lo, hi) = (top * k as f64 / STEPS as f64, top * (k + 1) as f64 / STEPS as f64);
            let c = ViridisRGB::get_color((k as f32 + 0.5) / STEPS as f32);
            Rectangle::new([(0.0, lo), (1.0, hi)], c.filled())
        }))
        .map_err(FigureError::draw)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::geometry::{Footprint, Pose};
    use risktwin_common::road::Road;

    #[test]
    fn the_hot_cell_is_top_right_and_the_ego_is_drawn_red() {
        let road = Road::straight(2, 3.5, 100.0, 30.0);
        // y from −1.5 to 4.5 m: every cell is on the road (edges at −1.75 and 5.25 m).
        let mut grid = RiskGrid::new(Vec2::new(0.0, -1.5), 1.0, 40, 6).expect("valid grid");
        grid.cells[5 * 40 + 39] = 1.0; // top-right cell (max x, max y)
        let ego = Obb::new(Pose::new(20.0, 0.0, 0.0), Footprint::new(4.0, 2.0));
        let others = [Obb::new(Pose::new(30.0, 3.5, 0.0), Footprint::new(4.0, 2.0))];
        let scene = HeatmapScene {
            title: "test".into(),
            layers: road_layers(&grid, &road),
            grid: &grid,
            others: &others,
            ego: &ego,
        };
        let img = heatmap(&scene).expect("draws");
        // The long side gets MIN_MAP_PX: 12 px per cell.
        assert_eq!((img.width, img.height), (480 + LEFT_PX + RIGHT_PX, 72 + TOP_PX + BOTTOM_PX));
        let top = ViridisRGB::get_color(1.0);
        let hot: Vec<(u32, u32)> = (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .filter(|&(x, y)| img.pixel(x, y) == [top.0, top.1, top.2])
            .collect();
        assert!(!hot.is_empty(), "the hot cell has the top colour");
        // In the map (not the colour bar): right end of the plot, its top rows.
        let map_hot: Vec<_> = hot.iter().filter(|(x, _)| *x < img.width - RIGHT_PX).collect();
        assert!(!map_hot.is_empty());
        for &&(x, y) in &map_hot {
            // Cell 39 of 40 at 12 px per cell, in the top rows.
            assert!(x >= LEFT_PX + 39 * 12 - 2 && y < TOP_PX + 36, "hot pixel at ({x}, {y})");
        }
        assert!(img.rgb.chunks(3).any(|p| p == [EGO.0, EGO.1, EGO.2]), "the ego is outlined in red");
    }

    #[test]
    fn lines_are_clipped_to_the_map() {
        let view = (Vec2::new(0.0, 0.0), Vec2::new(10.0, 10.0));
        let line = [Vec2::new(-5.0, 5.0), Vec2::new(5.0, 5.0), Vec2::new(15.0, 5.0), Vec2::new(20.0, 20.0)];
        assert_eq!(clip(&line, view), vec![vec![(0.0, 5.0), (5.0, 5.0), (10.0, 5.0)]]);
        let out_and_back = [Vec2::new(5.0, 5.0), Vec2::new(5.0, 20.0), Vec2::new(6.0, 5.0)];
        assert_eq!(clip(&out_and_back, view).len(), 2);
        assert!(clip(&[Vec2::new(20.0, 20.0), Vec2::new(30.0, 20.0)], view).is_empty());
    }

    #[test]
    fn off_map_cells_are_dimmed() {
        assert_eq!(cell_colour(2.0, 1.0, true), ViridisRGB::get_color(1.0));
        let c = ViridisRGB::get_color(1.0);
        let dim = cell_colour(2.0, 1.0, false);
        assert_eq!((dim.0, dim.1), ((u16::from(c.0) * 35 / 100) as u8, (u16::from(c.1) * 35 / 100) as u8));
        assert_eq!(cell_colour(f32::NAN, 1.0, true), ViridisRGB::get_color(0.0));
    }
}
