//! The risk field on a grid: [`RiskGrid`] (the cells, as `foxglove.Grid` wants them), the static
//! road raster [`RoadRaster`] and the fast fill [`GridEvaluator`].
//!
//! Speed comes from three things. (1) The lane and boundary terms depend only on the road, so
//! they are computed once on a world-aligned raster at the field's resolution; a grid whose
//! origin lies on the raster lattice copies row slices of it (`RoadRaster::snap_origin` gives
//! such an origin). Cells outside the raster, or a grid off the lattice, fall back to exact
//! evaluation (correct, slow). (2) Each object only touches the cells within the cut-off radius
//! σ_d·sqrt(2 ln(1/ε)) of its footprint. (3) The Gaussian comes from a table over d²
//! ([`GaussTable`]), and d² to the box is updated incrementally along a row.

use super::field::{EgoKinematics, FieldError, FieldObject, RiskFieldParams, footprint_max, trajectory_mean};
use super::kernel::GaussTable;
use crate::geometry::Pose;
use crate::geometry::Vec2;
use crate::road::Road;

/// Largest raster or grid the field builds (cells), so a wild resolution cannot exhaust memory.
pub const MAX_CELLS: usize = 16 << 20;

fn check_shape(resolution_m: f64, cols: usize, rows: usize) -> Result<usize, FieldError> {
    if !(resolution_m.is_finite() && resolution_m > 0.0) || cols == 0 || rows == 0 {
        return Err(FieldError::InvalidGrid { resolution_m, cols, rows });
    }
    let cells = cols.saturating_mul(rows);
    if cells > MAX_CELLS {
        return Err(FieldError::TooLarge { cells, max: MAX_CELLS });
    }
    Ok(cells)
}

/// Field values on a world-aligned grid. Cell (c, r) covers [origin + (c, r)·res, + res) and
/// holds the value at its centre; `cells[r·cols + c]`, row 0 at the lowest y.
#[derive(Debug, Clone, PartialEq)]
pub struct RiskGrid {
    pub origin_m: Vec2,
    pub resolution_m: f64,
    pub cols: usize,
    pub rows: usize,
    pub cells: Vec<f32>,
}

impl RiskGrid {
    /// A zeroed grid; the allocation is the only one its fills ever make.
    pub fn new(origin_m: Vec2, resolution_m: f64, cols: usize, rows: usize) -> Result<Self, FieldError> {
        let n = check_shape(resolution_m, cols, rows)?;
        Ok(Self { origin_m, resolution_m, cols, rows, cells: vec![0.0; n] })
    }

    /// World position of the centre of cell (c, r).
    pub fn cell_centre(&self, col: usize, row: usize) -> Vec2 {
        self.origin_m + Vec2::new((col as f64 + 0.5) * self.resolution_m, (row as f64 + 0.5) * self.resolution_m)
    }

    /// The cell containing `p`, if any.
    pub fn cell_of(&self, p: Vec2) -> Option<(usize, usize)> {
        let c = ((p.x - self.origin_m.x) / self.resolution_m).floor();
        let r = ((p.y - self.origin_m.y) / self.resolution_m).floor();
        let inside = c >= 0.0 && r >= 0.0 && c < self.cols as f64 && r < self.rows as f64;
        inside.then_some((c as usize, r as usize))
    }

    /// The value of the cell containing `p`, if any.
    pub fn value_at(&self, p: Vec2) -> Option<f32> {
        self.cell_of(p).map(|(c, r)| self.cells[r * self.cols + c])
    }

    /// (col, row) of the largest value (first one on ties).
    pub fn argmax(&self) -> (usize, usize) {
        let mut best = (0, f32::NEG_INFINITY);
        for (i, v) in self.cells.iter().enumerate() {
            if *v > best.1 {
                best = (i, *v);
            }
        }
        (best.0 % self.cols, best.0 / self.cols)
    }

    /// Maximum, mean and the world position of the maximum.
    pub fn stats(&self) -> (f64, f64, Vec2) {
        let max = self.cells.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let mean = self.cells.iter().map(|&c| f64::from(c)).sum::<f64>() / self.cells.len().max(1) as f64;
        let (col, row) = self.argmax();
        (f64::from(max), mean, self.cell_centre(col, row))
    }
}

/// α_l·R_l + α_b·R_b of one road on a world-aligned lattice, computed once per road.
#[derive(Debug, Clone)]
pub struct RoadRaster {
    grid: RiskGrid,
    /// The parameters the values were computed with; a fill with others falls back to exact.
    params: RiskFieldParams,
}

impl RoadRaster {
    /// Rasterises the road's bounds plus `margin_m` on each side at `resolution_m`.
    pub fn new(road: &Road, params: &RiskFieldParams, resolution_m: f64, margin_m: f64) -> Result<Self, FieldError> {
        let (lo, hi) = road.bounds();
        let margin = if margin_m.is_finite() { margin_m.max(0.0) } else { 0.0 };
        let size = hi - lo + Vec2::new(2.0 * margin, 2.0 * margin);
        let cols = (size.x / resolution_m).ceil();
        let rows = (size.y / resolution_m).ceil();
        if !(cols.is_finite() && rows.is_finite()) || cols > MAX_CELLS as f64 || rows > MAX_CELLS as f64 {
            return Err(FieldError::InvalidGrid { resolution_m, cols: 0, rows: 0 });
        }
        let mut grid = RiskGrid::new(lo - Vec2::new(margin, margin), resolution_m, cols as usize, rows as usize)?;
        for r in 0..grid.rows {
            for c in 0..grid.cols {
                let v = params.static_terms(road, grid.cell_centre(c, r));
                grid.cells[r * grid.cols + c] = v as f32;
            }
        }
        Ok(Self { grid, params: *params })
    }

    /// Rasterises the road on exactly the lattice of `grid` (its origin, resolution and size):
    /// a grid filled once on a large map, where a raster over the whole road would cost far more
    /// than the grid itself.
    pub fn covering(road: &Road, params: &RiskFieldParams, grid: &RiskGrid) -> Result<Self, FieldError> {
        let mut grid = RiskGrid::new(grid.origin_m, grid.resolution_m, grid.cols, grid.rows)?;
        for r in 0..grid.rows {
            for c in 0..grid.cols {
                let v = params.static_terms(road, grid.cell_centre(c, r));
                grid.cells[r * grid.cols + c] = v as f32;
            }
        }
        Ok(Self { grid, params: *params })
    }

    /// The raster itself (e.g. to render the road's static risk).
    pub fn grid(&self) -> &RiskGrid {
        &self.grid
    }

    /// The parameters the raster was built with.
    pub fn params(&self) -> &RiskFieldParams {
        &self.params
    }

    /// α_l·R_l + α_b·R_b at `p`, bilinear between cell centres; `None` outside the raster.
    /// Exact at cell centres; between them it smooths the lane term's jump from 1 to 0 at a
    /// lane line over one cell, so within one cell of a lane line it can be off by up to α_l.
    pub fn static_at(&self, p: Vec2) -> Option<f64> {
        let g = &self.grid;
        let u = (p - g.origin_m) / g.resolution_m - Vec2::new(0.5, 0.5);
        let inside = u.x >= 0.0 && u.y >= 0.0 && u.x <= (g.cols - 1) as f64 && u.y <= (g.rows - 1) as f64;
        if !inside {
            return None;
        }
        let (c, r) = ((u.x as usize).min(g.cols.saturating_sub(2)), (u.y as usize).min(g.rows.saturating_sub(2)));
        let (fx, fy) = (u.x - c as f64, u.y - r as f64);
        let at = |cc: usize, rr: usize| g.cells[(rr.min(g.rows - 1)) * g.cols + cc.min(g.cols - 1)] as f64;
        let bottom = at(c, r) * (1.0 - fx) + at(c + 1, r) * fx;
        let top = at(c, r + 1) * (1.0 - fx) + at(c + 1, r + 1) * fx;
        Some(bottom * (1.0 - fy) + top * fy)
    }

    /// R(p, t) with the static terms from the raster (exact outside it) and the obstacle and
    /// comfort terms exact: the fast point evaluation for per-step rewards.
    pub fn evaluate_point(&self, road: &Road, objects: &[FieldObject], ego: &EgoKinematics, p: Vec2) -> f64 {
        let prm = &self.params;
        let statics = self.static_at(p).unwrap_or_else(|| prm.static_terms(road, p));
        prm.alpha_obstacle * prm.obstacle_term(objects, ego, p) + statics + prm.alpha_comfort * prm.comfort_term(ego)
    }

    /// [`RiskFieldParams::evaluate_footprint`] with raster statics.
    pub fn evaluate_footprint(&self, road: &Road, objects: &[FieldObject], ego: &EgoKinematics) -> f64 {
        footprint_max(ego, |p| self.evaluate_point(road, objects, ego, p))
    }

    /// [`RiskFieldParams::evaluate_trajectory`] (R̄_t) with raster statics.
    pub fn evaluate_trajectory(
        &self,
        road: &Road,
        objects: &[FieldObject],
        ego: &EgoKinematics,
        poses: &[Pose],
    ) -> f64 {
        trajectory_mean(ego, poses, |e| self.evaluate_footprint(road, objects, e))
    }

    /// The lattice point nearest to `p`: a grid with this origin and the raster's resolution
    /// copies the static terms instead of evaluating them.
    pub fn snap_origin(&self, p: Vec2) -> Vec2 {
        let res = self.grid.resolution_m;
        let o = self.grid.origin_m;
        o + Vec2::new(((p.x - o.x) / res).round() * res, ((p.y - o.y) / res).round() * res)
    }

    /// The lattice offset (columns, rows) of `grid` in the raster, when it lies on the lattice.
    pub(super) fn lattice_offset(&self, grid: &RiskGrid, params: &RiskFieldParams) -> Option<(i64, i64)> {
        let same_static = params.alpha_lane == self.params.alpha_lane
            && params.alpha_boundary == self.params.alpha_boundary
            && params.boundary_scale_m == self.params.boundary_scale_m
            && params.boundary_cap == self.params.boundary_cap;
        let res = self.grid.resolution_m;
        if !same_static || (grid.resolution_m - res).abs() > 1e-9 * res {
            return None;
        }
        let off = (grid.origin_m - self.grid.origin_m) / res;
        let (ox, oy) = (off.x.round(), off.y.round());
        let on_lattice = (off.x - ox).abs() < 1e-6 && (off.y - oy).abs() < 1e-6;
        (on_lattice && ox.abs() < 1e15 && oy.abs() < 1e15).then_some((ox as i64, oy as i64))
    }
}

/// Fills [`RiskGrid`]s fast: owns the Gaussian table and the obstacle scratch layer, so
/// repeated fills of one grid size allocate nothing.
#[derive(Debug, Clone)]
pub struct GridEvaluator {
    params: RiskFieldParams,
    table: GaussTable,
    obstacle: Vec<f32>,
}

impl GridEvaluator {
    /// An evaluator for `params`.
    pub fn new(params: RiskFieldParams) -> Self {
        Self { table: GaussTable::new(params.sigma_d_m, params.cutoff_eps), params, obstacle: Vec::new() }
    }

    /// The parameters it evaluates.
    pub fn params(&self) -> &RiskFieldParams {
        &self.params
    }

    /// Bound on |fast − exact| for every cell of a fill with these objects (see the module doc
    /// of `kernel`): α_o·max gain·max(ε, h/2) from the cut-off and the table, plus `f32`
    /// rounding of values up to `max_value`.
    pub fn error_bound(&self, objects: &[FieldObject], ego: &EgoKinematics, max_value: f64) -> f64 {
        let gain = objects.iter().map(|o| self.params.object_gain(o, ego)).fold(1.0, f64::max);
        self.params.alpha_obstacle * gain * self.table.max_error() + 4.0 * f32::EPSILON as f64 * max_value.abs()
    }

    /// Evaluates the whole field into `grid` in place.
    pub fn fill(
        &mut self,
        grid: &mut RiskGrid,
        raster: &RoadRaster,
        road: &Road,
        objects: &[FieldObject],
        ego: &EgoKinematics,
    ) {
        let n = grid.cols * grid.rows;
        // The fields are public: restore the cells = cols·rows invariant rather than panic.
        grid.cells.resize(n, 0.0);
        self.obstacle.clear();
        self.obstacle.resize(n, 0.0);
        for o in objects {
            let gain = (self.params.alpha_obstacle * self.params.object_gain(o, ego)) as f32;
            splat_max(&mut self.obstacle, grid, o, gain, &self.table, self.params.cutoff_radius_m());
        }
        let base = (self.params.alpha_comfort * self.params.comfort_term(ego)) as f32;
        self.fill_static(grid, raster, road);
        for (cell, obs) in grid.cells.iter_mut().zip(&self.obstacle) {
            *cell += base + *obs;
        }
    }

    /// Writes α_l·R_l + α_b·R_b into every cell: copied from the raster where the grid lies on
    /// its lattice and inside it, evaluated exactly elsewhere.
    fn fill_static(&self, grid: &mut RiskGrid, raster: &RoadRaster, road: &Road) {
        let offset = raster.lattice_offset(grid, &self.params);
        let (rc, rr) = (raster.grid.cols as i64, raster.grid.rows as i64);
        for r in 0..grid.rows {
            let row = &mut grid.cells[r * grid.cols..(r + 1) * grid.cols];
            let mut covered = 0..0;
            if let Some((ox, oy)) = offset {
                let src_r = oy + r as i64;
                if (0..rr).contains(&src_r) {
                    // Grid columns c with 0 <= ox + c < rc.
                    let c0 = (-ox).clamp(0, grid.cols as i64) as usize;
                    let c1 = (rc - ox).clamp(0, grid.cols as i64) as usize;
                    if c0 < c1 {
                        let start = (src_r * rc + ox + c0 as i64) as usize;
                        row[c0..c1].copy_from_slice(&raster.grid.cells[start..start + (c1 - c0)]);
                        covered = c0..c1;
                    }
                }
            }
            for (c, v) in row.iter_mut().enumerate() {
                if !covered.contains(&c) {
                    let p = grid.origin_m
                        + Vec2::new((c as f64 + 0.5) * grid.resolution_m, (r as f64 + 0.5) * grid.resolution_m);
                    *v = self.params.static_terms(road, p) as f32;
                }
            }
        }
    }
}

/// Max-accumulates `gain`·exp(−d²/(2σ²)) of one object into the cells within `cutoff_m` of
/// its footprint. d² to the box is kept in box coordinates (lx, ly), which step by constants
/// along a row, so the inner loop is multiply-adds, two `abs`/`max` and a table lookup.
fn splat_max(layer: &mut [f32], grid: &RiskGrid, o: &FieldObject, gain: f32, table: &GaussTable, cutoff_m: f64) {
    let obb = &o.obb;
    let (axis, normal) = (obb.axis, Vec2::new(-obb.axis.y, obb.axis.x));
    let reach = obb.half_length_m * axis.abs() + obb.half_width_m * normal.abs() + Vec2::new(cutoff_m, cutoff_m);
    let lo = (obb.centre - reach - grid.origin_m) / grid.resolution_m;
    let hi = (obb.centre + reach - grid.origin_m) / grid.resolution_m;
    if !(lo.x.is_finite() && lo.y.is_finite() && hi.x.is_finite() && hi.y.is_finite()) {
        return;
    }
    let c0 = lo.x.floor().max(0.0) as usize;
    let r0 = lo.y.floor().max(0.0) as usize;
    let c1 = (hi.x.ceil().max(0.0) as usize).min(grid.cols);
    let r1 = (hi.y.ceil().max(0.0) as usize).min(grid.rows);
    if c0 >= c1 || r0 >= r1 {
        return;
    }
    let res = grid.resolution_m;
    let (step_lx, step_ly) = (res * axis.x, res * normal.x);
    for r in r0..r1 {
        let d = grid.cell_centre(c0, r) - obb.centre;
        let (mut lx, mut ly) = (d.dot(&axis), d.dot(&normal));
        let row = &mut layer[r * grid.cols + c0..r * grid.cols + c1];
        for cell in row {
            let ex = (lx.abs() - obb.half_length_m).max(0.0);
            let ey = (ly.abs() - obb.half_width_m).max(0.0);
            let v = gain * table.lookup(ex * ex + ey * ey);
            *cell = cell.max(v);
            lx += step_lx;
            ly += step_ly;
        }
    }
}
