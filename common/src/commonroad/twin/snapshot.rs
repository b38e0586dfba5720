//! The risk field around the recorded ego at one moment of a CommonRoad scenario.

use super::super::Scenario;
use super::TwinError;
use super::scene::TwinScene;
use crate::geometry::{Obb, Vec2};
use crate::risk::{EgoKinematics, FieldObject, GridEvaluator, RiskFieldParams, RiskGrid, RoadRaster};
use crate::road::{Lane, Road};

/// Lanes are kept this far beyond the grid (m): past it the boundary term is capped anyway.
const CROP_MARGIN_M: f64 = 30.0;
/// Centreline segments are split to at most this length before cropping, so the cropped road's
/// bounds (and its raster) stay near the grid.
const MAX_SEGMENT_M: f64 = 2.0;

/// The field at one moment, with what is needed to draw it.
#[derive(Debug, Clone)]
pub struct CommonRoadField {
    /// Scenario time, s (time step × dt).
    pub time_s: f64,
    pub grid: RiskGrid,
    /// The ego's footprint (recorded, at `time_s`).
    pub ego: Obb,
    /// Footprints of every other obstacle present.
    pub others: Vec<Obb>,
}

impl CommonRoadField {
    /// Maximum, mean and the world position of the maximum.
    pub fn stats(&self) -> (f64, f64, Vec2) {
        let cells = &self.grid.cells;
        let max = cells.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        let mean = cells.iter().map(|&c| f64::from(c)).sum::<f64>() / cells.len().max(1) as f64;
        let (col, row) = self.grid.argmax();
        (f64::from(max), mean, self.grid.cell_centre(col, row))
    }
}

/// The field on a `cells`×`cells` grid of `resolution_m` centred on the recorded ego at scenario
/// time `time_s`, over the scenario's lanelet map (converted by [`super::road_from_lanelets`]),
/// with every obstacle present at that time (interpolated between steps).
pub fn field_at(
    scenario: &Scenario,
    ego_id: Option<u64>,
    time_s: f64,
    resolution_m: f64,
    cells: usize,
) -> Result<CommonRoadField, TwinError> {
    let scene = TwinScene::new(scenario, ego_id)?;
    let (start_s, end_s) = (scene.ego.start_s(), scene.ego.end_s());
    let ego_state = scene.ego.at(time_s).ok_or(TwinError::TimeOutOfRange { time_s, start_s, end_s })?;
    let ego = EgoKinematics {
        pose: ego_state.pose,
        velocity: ego_state.velocity(),
        lateral_accel_mps2: 0.0,
        jerk_mps3: 0.0,
        footprint: scene.ego.footprint,
    };
    let mut objects = Vec::new();
    scene.objects_at(time_s, &mut objects);
    let field_objects: Vec<FieldObject> =
        objects.iter().map(|o| FieldObject { obb: o.obb, velocity: o.velocity }).collect();

    let params = RiskFieldParams::default();
    let half_extent_m = 0.5 * resolution_m * cells as f64;
    let centre = ego_state.pose.position();
    let lo = centre - Vec2::repeat(half_extent_m + CROP_MARGIN_M);
    let hi = centre + Vec2::repeat(half_extent_m + CROP_MARGIN_M);
    let road = crop_road(&scene.road, lo, hi).unwrap_or(scene.road);
    let raster = RoadRaster::new(&road, &params, resolution_m, half_extent_m + 10.0)?;
    let origin = raster.snap_origin(centre - Vec2::repeat(half_extent_m));
    let mut grid = RiskGrid::new(origin, resolution_m, cells, cells)?;
    GridEvaluator::new(params).fill(&mut grid, &raster, &road, &field_objects, &ego);
    Ok(CommonRoadField { time_s, grid, ego: ego.obb(), others: objects.iter().map(|o| o.obb).collect() })
}

/// The lanes' parts within the box `[lo, hi]` (segments split to ≤ [`MAX_SEGMENT_M`] first),
/// neighbours remapped; `None` when no lane reaches the box.
fn crop_road(road: &Road, lo: Vec2, hi: Vec2) -> Option<Road> {
    let inside = |p: &Vec2| p.x >= lo.x && p.y >= lo.y && p.x <= hi.x && p.y <= hi.y;
    let mut new_index = vec![None; road.lanes.len()];
    let mut lanes = Vec::new();
    for (i, lane) in road.lanes.iter().enumerate() {
        let mut dense = Vec::with_capacity(lane.centre.len());
        for w in lane.centre.windows(2) {
            let n = ((w[1] - w[0]).norm() / MAX_SEGMENT_M).ceil().max(1.0) as usize;
            dense.extend((0..n).map(|k| w[0] + (w[1] - w[0]) * (k as f64 / n as f64)));
        }
        dense.extend(lane.centre.last().copied());
        let Some(first) = dense.iter().position(inside) else { continue };
        let last = dense.iter().rposition(inside).unwrap_or(first);
        let (a, b) = (first.saturating_sub(1), (last + 1).min(dense.len() - 1));
        if b <= a {
            continue;
        }
        new_index[i] = Some(lanes.len());
        let mut l = Lane::new(dense[a..=b].to_vec(), lane.width_m, lane.speed_limit_mps);
        (l.left, l.right) = (lane.left, lane.right);
        lanes.push(l);
    }
    if lanes.is_empty() {
        return None;
    }
    for l in &mut lanes {
        l.left = l.left.and_then(|k| new_index[k]);
        l.right = l.right.and_then(|k| new_index[k]);
    }
    Some(Road { lanes, reference_lane: 0, friction_patches: Vec::new(), ..road.clone() })
}
