//! The heatmap of a [`CommonRoadField`] over the real lanelet map: lanelet bounds solid,
//! centrelines dashed, obstacle footprints white, the ego red.

use super::super::LaneletNetwork;
use super::snapshot::CommonRoadField;
use crate::geometry::{Obb, Vec2};
use crate::risk::RgbImage;
use crate::risk::render::viridis;

const BOUND_RGB: [u8; 3] = [255, 255, 255];
const CENTRELINE_RGB: [u8; 3] = [150, 150, 150];
const OBJECT_RGB: [u8; 3] = [255, 255, 255];
const EGO_RGB: [u8; 3] = [255, 40, 40];
/// Brightness kept off the lanelets, percent (the boundary term dominates there).
const OFF_MAP_PERCENT: u16 = 35;
const DASH_M: f64 = 3.0;

/// Renders the field scaled to its maximum on the lanelets, `pixels_per_cell`² pixels per cell;
/// image row 0 is the grid's top (max y).
pub fn render_field(field: &CommonRoadField, network: &LaneletNetwork, pixels_per_cell: usize) -> RgbImage {
    let grid = &field.grid;
    let n = grid.cols * grid.rows;
    let mut ppc = pixels_per_cell.max(1);
    while ppc > 1 && n.saturating_mul(ppc * ppc) > crate::risk::render::MAX_PIXELS {
        ppc -= 1;
    }
    let on_map: Vec<bool> =
        (0..n).map(|k| network.containing(grid.cell_centre(k % grid.cols, k / grid.cols)).next().is_some()).collect();
    let any_on = on_map.iter().any(|&b| b);
    let max = grid
        .cells
        .iter()
        .zip(&on_map)
        .filter(|(v, on)| v.is_finite() && (**on || !any_on))
        .fold(0.0f32, |m, (v, _)| m.max(*v))
        .max(1e-9);
    let (width, height) = (grid.cols * ppc, grid.rows * ppc);
    let mut img = RgbImage { width, height, data: vec![0; 3 * width * height] };
    for y in 0..height {
        let row = grid.rows - 1 - y / ppc;
        for x in 0..width {
            let k = row * grid.cols + x / ppc;
            let v = grid.cells.get(k).copied().unwrap_or(0.0);
            let mut rgb = viridis(f64::from((v / max).min(1.0)));
            if !on_map.get(k).copied().unwrap_or(true) {
                rgb = rgb.map(|c| (u16::from(c) * OFF_MAP_PERCENT / 100) as u8);
            }
            let i = 3 * (y * width + x);
            img.data[i..i + 3].copy_from_slice(&rgb);
        }
    }
    let view = View { origin: grid.origin_m, px_per_m: ppc as f64 / grid.resolution_m, height: height as f64 };
    for l in &network.lanelets {
        for bound in [&l.left_bound, &l.right_bound] {
            for w in bound.windows(2) {
                view.line(&mut img, w[0], w[1], BOUND_RGB, None);
            }
        }
        let mut s0 = 0.0;
        for w in l.centreline.windows(2) {
            view.line(&mut img, w[0], w[1], CENTRELINE_RGB, Some(s0));
            s0 += (w[1] - w[0]).norm();
        }
    }
    for obb in &field.others {
        draw_obb(&mut img, &view, obb, OBJECT_RGB);
    }
    draw_obb(&mut img, &view, &field.ego, EGO_RGB);
    img
}

fn draw_obb(img: &mut RgbImage, view: &View, obb: &Obb, rgb: [u8; 3]) {
    let c = obb.corners();
    for k in 0..4 {
        view.line(img, c[k], c[(k + 1) % 4], rgb, None);
    }
}

/// World → pixel mapping.
struct View {
    origin: Vec2,
    px_per_m: f64,
    height: f64,
}

impl View {
    fn to_px(&self, p: Vec2) -> (f64, f64) {
        let q = (p - self.origin) * self.px_per_m;
        (q.x, self.height - q.y)
    }

    /// A line from `a` to `b`; dashed every [`DASH_M`] when `dash_from_m` gives the arc length
    /// at `a`. Points outside the image are skipped; lines far off screen cost their length only.
    fn line(&self, img: &mut RgbImage, a: Vec2, b: Vec2, rgb: [u8; 3], dash_from_m: Option<f64>) {
        let (pa, pb) = (self.to_px(a), self.to_px(b));
        let (w, h) = (img.width as f64, img.height as f64);
        if (pa.0 < 0.0 && pb.0 < 0.0)
            || (pa.1 < 0.0 && pb.1 < 0.0)
            || (pa.0 >= w && pb.0 >= w)
            || (pa.1 >= h && pb.1 >= h)
        {
            return;
        }
        let len_px = (pb.0 - pa.0).hypot(pb.1 - pa.1);
        let n = (2.0 * len_px).ceil().clamp(1.0, 1e6) as usize;
        let len_m = (b - a).norm();
        for k in 0..=n {
            let f = k as f64 / n as f64;
            if let Some(s0) = dash_from_m
                && !(((s0 + f * len_m) / DASH_M) as u64).is_multiple_of(2)
            {
                continue;
            }
            let (x, y) = (pa.0 + f * (pb.0 - pa.0), pa.1 + f * (pb.1 - pa.1));
            if x >= 0.0 && y >= 0.0 && x < w && y < h {
                let i = 3 * (y as usize * img.width + x as usize);
                img.data[i..i + 3].copy_from_slice(&rgb);
            }
        }
    }
}
