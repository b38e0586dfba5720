//! The risk field around the recorded ego at one moment of a CommonRoad scenario.

use super::super::Scenario;
use super::TwinError;
use super::scene::TwinScene;
use risktwin_common::geometry::{Obb, Vec2};
use risktwin_common::risk::{EgoKinematics, FieldObject, GridEvaluator, RiskFieldParams, RiskGrid, RoadRaster};
use risktwin_common::road::{Lane, Road};

/// Lanes are kept this far beyond the grid (m): past it the boundary term is capped anyway.
const CROP_MARGIN_M: f64 = 30.0;

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
    /// Maximum, mean and the world position of the maximum (see [`RiskGrid::stats`]).
    pub fn stats(&self) -> (f64, f64, Vec2) {
        self.grid.stats()
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
    let mut grid = RiskGrid::new(centre - Vec2::repeat(half_extent_m), resolution_m, cells, cells)?;
    // The static terms once, on the grid's own lattice: a raster over the whole (cropped) road
    // would cost several grids.
    let raster = RoadRaster::covering(&road, &params, &grid)?;
    GridEvaluator::new(params).fill(&mut grid, &raster, &road, &field_objects, &ego);
    Ok(CommonRoadField { time_s, grid, ego: ego.obb(), others: objects.iter().map(|o| o.obb).collect() })
}

/// The lanes' parts near the box `[lo, hi]`: each lane from one segment before the first
/// segment whose bounding box meets the box to one segment after the last, neighbours remapped;
/// `None` when no lane reaches the box. Lanes elsewhere on the map only cost time: the box
/// reaches [`CROP_MARGIN_M`] beyond the grid, past which the boundary term is capped and no cell
/// of the grid is nearer to them than to the kept lanes.
fn crop_road(road: &Road, lo: Vec2, hi: Vec2) -> Option<Road> {
    let meets =
        |a: Vec2, b: Vec2| a.x.min(b.x) <= hi.x && a.x.max(b.x) >= lo.x && a.y.min(b.y) <= hi.y && a.y.max(b.y) >= lo.y;
    let mut new_index = vec![None; road.lanes.len()];
    let mut lanes = Vec::new();
    for (i, lane) in road.lanes.iter().enumerate() {
        let c = &lane.centre;
        let Some(first) = c.windows(2).position(|w| meets(w[0], w[1])) else { continue };
        let last = c.windows(2).rposition(|w| meets(w[0], w[1])).unwrap_or(first);
        let (a, b) = (first.saturating_sub(1), (last + 2).min(c.len() - 1));
        new_index[i] = Some(lanes.len());
        let mut l = Lane::new(c[a..=b].to_vec(), lane.width_m, lane.speed_limit_mps);
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
