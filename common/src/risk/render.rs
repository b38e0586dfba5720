//! A pure heatmap renderer for [`RiskGrid`]s: viridis colours, road edges, dashed lane
//! centrelines and vehicle outlines, into an RGB buffer that the caller encodes (PNG).

use super::raster::RiskGrid;
use crate::geometry::{Obb, Vec2};
use crate::road::Road;

/// Largest image the renderer makes (pixels); `pixels_per_cell` is reduced to stay below it.
pub const MAX_PIXELS: usize = 1 << 26;

/// An 8-bit RGB image, rows top to bottom, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl RgbImage {
    /// The pixel at (x, y), y = 0 at the top.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * self.width + x);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    fn put(&mut self, x: f64, y: f64, rgb: [u8; 3]) {
        if x >= 0.0 && y >= 0.0 && x < self.width as f64 && y < self.height as f64 {
            let i = 3 * (y as usize * self.width + x as usize);
            self.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
}

/// Viridis (matplotlib's perceptually uniform map) at nine evenly spaced stops.
const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];
const EDGE_RGB: [u8; 3] = [255, 255, 255];
const CENTRELINE_RGB: [u8; 3] = [190, 190, 190];
const OBJECT_RGB: [u8; 3] = [255, 255, 255];
const EGO_RGB: [u8; 3] = [255, 40, 40];
/// Dash and gap length of lane centrelines (m), like a painted lane line.
const DASH_M: f64 = 3.0;

/// Viridis colour of `t` ∈ [0, 1] (clamped; NaN maps to 0), linear between stops.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    std::array::from_fn(|k| (a[k] as f64 + f * (b[k] as f64 - a[k] as f64)).round() as u8)
}

/// World → pixel mapping of one render.
struct View {
    origin: Vec2,
    px_per_m: f64,
    height: f64,
}

impl View {
    fn to_px(&self, p: Vec2) -> (f64, f64) {
        ((p.x - self.origin.x) * self.px_per_m, self.height - (p.y - self.origin.y) * self.px_per_m)
    }

    /// A line from a to b, sampled every half pixel.
    fn line(&self, img: &mut RgbImage, a: Vec2, b: Vec2, rgb: [u8; 3]) {
        let (ax, ay) = self.to_px(a);
        let (bx, by) = self.to_px(b);
        let n = ((bx - ax).hypot(by - ay) * 2.0).ceil().clamp(1.0, 1e6) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            img.put(ax + t * (bx - ax), ay + t * (by - ay), rgb);
        }
    }
}

/// Brightness kept for off-road cells, percent.
const OFF_ROAD_DIM_PERCENT: u16 = 35;

/// Renders `grid` scaled to its on-road maximum (cells ≤ 0 are the map's bottom colour; off-road
/// cells dimmed), with road
/// edges (solid), lane centrelines (dashed), `footprints` outlined in white and `ego` in red.
/// Each cell becomes `pixels_per_cell`² pixels; image row 0 is the grid's top (max y).
pub fn render_heatmap(grid: &RiskGrid, road: &Road, footprints: &[Obb], ego: &Obb, pixels_per_cell: usize) -> RgbImage {
    let cells = grid.cols * grid.rows;
    let mut ppc = pixels_per_cell.max(1);
    while ppc > 1 && cells.saturating_mul(ppc * ppc) > MAX_PIXELS {
        ppc -= 1;
    }
    let (width, height) = (grid.cols * ppc, grid.rows * ppc);
    let mut img = RgbImage { width, height, data: vec![0; 3 * width * height] };
    // Off the road the boundary term alone reaches an obstacle's peak; those cells are drawn
    // dimmed and left out of the colour scale, so the risk on the road stays readable.
    let on_road: Vec<bool> =
        (0..cells).map(|k| road.edge_distance_m(grid.cell_centre(k % grid.cols, k / grid.cols)) >= 0.0).collect();
    let scale_max = |on_road_only: bool| {
        grid.cells
            .iter()
            .zip(&on_road)
            .filter(|(v, r)| v.is_finite() && (**r || !on_road_only))
            .fold(0.0f32, |m, (v, _)| m.max(*v))
    };
    let max = if on_road.iter().any(|&r| r) { scale_max(true) } else { scale_max(false) }.max(1e-9);
    for y in 0..height {
        let row = grid.rows - 1 - y / ppc;
        for x in 0..width {
            // `get`: the fields are public, a short `cells` renders as 0 instead of panicking.
            let k = row * grid.cols + x / ppc;
            let v = grid.cells.get(k).copied().unwrap_or(0.0);
            let mut rgb = viridis((v / max).min(1.0) as f64);
            if !on_road.get(k).copied().unwrap_or(true) {
                rgb = rgb.map(|c| (u16::from(c) * OFF_ROAD_DIM_PERCENT / 100) as u8);
            }
            let i = 3 * (y * width + x);
            img.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
    let view = View { origin: grid.origin_m, px_per_m: ppc as f64 / grid.resolution_m, height: height as f64 };
    draw_road(&mut img, &view, road);
    for obb in footprints {
        draw_obb(&mut img, &view, obb, OBJECT_RGB);
    }
    draw_obb(&mut img, &view, ego, EGO_RGB);
    img
}

fn draw_obb(img: &mut RgbImage, view: &View, obb: &Obb, rgb: [u8; 3]) {
    let c = obb.corners();
    for k in 0..4 {
        view.line(img, c[k], c[(k + 1) % 4], rgb);
    }
}

/// Carriageway edges (a lane side without a neighbour) solid, centrelines dashed.
fn draw_road(img: &mut RgbImage, view: &View, road: &Road) {
    let step_m = 0.5 / view.px_per_m;
    for lane in &road.lanes {
        let len = lane.length_m();
        let n = (len / step_m).ceil().clamp(1.0, 1e6) as usize;
        let half = 0.5 * lane.width_m;
        for k in 0..=n {
            let s = len * k as f64 / n as f64;
            if ((s / DASH_M) as u64).is_multiple_of(2) {
                let p = lane.pose_at(s, 0.0);
                let (x, y) = view.to_px(p.position());
                img.put(x, y, CENTRELINE_RGB);
            }
            for (side, has_neighbour) in [(half, lane.left.is_some()), (-half, lane.right.is_some())] {
                if !has_neighbour {
                    let (x, y) = view.to_px(lane.pose_at(s, side).position());
                    img.put(x, y, EDGE_RGB);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Footprint, Pose};

    #[test]
    fn colormap_endpoints_and_monotone_brightness() {
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[8]);
        assert_eq!(viridis(f64::NAN), VIRIDIS[0]);
        let lum = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        let mut prev = -1.0;
        for k in 0..=100 {
            let l = lum(viridis(k as f64 / 100.0));
            assert!(l >= prev - 0.5, "viridis brightens: {l} after {prev}");
            prev = l;
        }
    }

    #[test]
    fn top_row_is_max_y_and_overlays_are_drawn() {
        let road = Road::straight(2, 3.5, 100.0, 30.0);
        // y from −1.5 to 4.5 m: every cell is on the road (edges at −1.75 and 5.25 m).
        let mut grid = RiskGrid::new(Vec2::new(0.0, -1.5), 1.0, 40, 6).expect("valid grid");
        grid.cells[5 * 40 + 39] = 1.0; // top-right cell (max x, max y)
        let ego = Obb::new(Pose::new(20.0, 0.0, 0.0), Footprint::new(4.0, 2.0));
        let other = Obb::new(Pose::new(30.0, 3.5, 0.0), Footprint::new(4.0, 2.0));
        let img = render_heatmap(&grid, &road, &[other], &ego, 4);
        assert_eq!((img.width, img.height, img.data.len()), (160, 24, 160 * 24 * 3));
        assert_eq!(img.pixel(159, 0), VIRIDIS[8], "hot cell at the top right");
        assert_eq!(img.pixel(159, 23), VIRIDIS[0]);
        // Ego's rear edge at x = 18 m → px 72; its centre y = 0 → py = 24 − 1.5·4 = 18.
        assert_eq!(img.pixel(72, 18), EGO_RGB);
        assert_eq!(img.pixel(112, 4), OBJECT_RGB, "other's rear edge at x = 28 m, y = 3.5 m");
    }

    #[test]
    fn off_road_cells_are_dimmed_and_left_out_of_the_scale() {
        let road = Road::straight(1, 3.5, 100.0, 30.0);
        // One row at y ∈ [−1, 0) on the road, one at y ∈ [5, 6) off it (edge at 1.75 m).
        let mut grid = RiskGrid::new(Vec2::new(0.0, -1.0), 1.0, 10, 1).expect("valid grid");
        grid.cells[3] = 0.5;
        let on = render_heatmap(&grid, &road, &[], &Obb::new(Pose::new(-50.0, 0.0, 0.0), Footprint::new(1.0, 1.0)), 1);
        assert_eq!(on.pixel(3, 0), VIRIDIS[8], "the on-road maximum is the top of the scale");
        let mut off = RiskGrid::new(Vec2::new(0.0, 5.0), 1.0, 10, 1).expect("valid grid");
        off.cells[3] = 2.0;
        let img = render_heatmap(&off, &road, &[], &Obb::new(Pose::new(-50.0, 0.0, 0.0), Footprint::new(1.0, 1.0)), 1);
        let dim = VIRIDIS[8].map(|c| (u16::from(c) * OFF_ROAD_DIM_PERCENT / 100) as u8);
        assert_eq!(img.pixel(3, 0), dim);
    }
}
