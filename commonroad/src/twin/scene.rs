//! The scenario as the twin sees it: converted road, the ego's recording, everything else as
//! playback, and the scene (footprints, velocities) at any moment.

use super::super::{Scenario, Shape};
use super::playback::{Playback, footprint_of};
use super::{TwinError, ego_of, road_from_lanelets};
use risktwin_common::geometry::{Obb, Pose, Vec2};
use risktwin_common::risk::VehicleState;
use risktwin_common::road::Road;
use risktwin_common::sensor::{ObjectKind, SceneObject};

/// A scenario prepared for the twin.
#[derive(Debug, Clone)]
pub struct TwinScene {
    pub road: Road,
    /// Lanelet id of each road lane.
    pub lane_lanelets: Vec<u64>,
    pub ego: Playback,
    /// Every dynamic obstacle but the ego, in file order.
    pub others: Vec<Playback>,
    /// Static obstacles: footprint (velocity zero).
    pub statics: Vec<Obb>,
    /// Indices into `others` taken out of the scene ([`TwinScene::withdraw`]), ascending.
    withdrawn: Vec<usize>,
}

impl TwinScene {
    /// Converts `scenario` with `ego_id` (default: the scenario's) as the ego.
    pub fn new(scenario: &Scenario, ego_id: Option<u64>) -> Result<Self, TwinError> {
        let ego_obstacle = ego_of(scenario, ego_id)?;
        let (road, lane_lanelets) = road_from_lanelets(&scenario.lanelets)?;
        let others = scenario
            .dynamic_obstacles
            .iter()
            .filter(|o| o.id != ego_obstacle.id)
            .map(|o| Playback::new(o, scenario.dt_s))
            .collect();
        let statics = scenario
            .static_obstacles
            .iter()
            .map(|o| {
                let s = &o.initial_state;
                let (centre, footprint) = match &o.shape {
                    // Static polygons are usually written in the world frame: their box.
                    Shape::Polygon { vertices } if !vertices.is_empty() => {
                        let (mut lo, mut hi) = (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY));
                        for v in vertices {
                            let w = s.position + v;
                            lo = lo.inf(&w);
                            hi = hi.sup(&w);
                        }
                        (0.5 * (lo + hi), risktwin_common::geometry::Footprint::new(hi.x - lo.x, hi.y - lo.y))
                    }
                    shape => (s.position, footprint_of(shape)),
                };
                let heading = if matches!(o.shape, Shape::Polygon { .. }) { 0.0 } else { s.orientation_rad };
                Obb::new(Pose::new(centre.x, centre.y, heading), footprint)
            })
            .collect();
        let ego = Playback::new(ego_obstacle, scenario.dt_s);
        Ok(Self { road, lane_lanelets, ego, others, statics, withdrawn: Vec::new() })
    }

    /// Takes `others[index]` out of the scene (a counterfactual: the recording without it); the
    /// others keep their ids.
    pub fn withdraw(&mut self, index: usize) {
        if let Err(at) = self.withdrawn.binary_search(&index) {
            self.withdrawn.insert(at, index);
        }
    }

    /// The other dynamic obstacles still in the scene, with their index in `others`.
    fn present(&self) -> impl Iterator<Item = (usize, &Playback)> {
        self.others.iter().enumerate().filter(|(i, _)| self.withdrawn.binary_search(i).is_err())
    }

    /// Indices into `others` of the recorded vehicles (not pedestrians, cyclists or parked
    /// vehicles), in file order.
    pub fn vehicles(&self) -> Vec<usize> {
        self.others.iter().enumerate().filter(|(_, p)| p.kind == ObjectKind::Vehicle).map(|(i, _)| i).collect()
    }

    /// Acceleration along the heading of object `id` of [`TwinScene::objects_at`] at `time_s`,
    /// m/s² (0 for static obstacles and outside the recording).
    pub fn accel_mps2_at(&self, id: u32, time_s: f64) -> f64 {
        let playback = self.others.get(id as usize);
        playback.and_then(|p| p.at(time_s)).map_or(0.0, |s| s.accel_mps2)
    }

    /// Everything but the ego at `time_s`: dynamic obstacles present then (id = index in
    /// `others`), then the static ones (ids after them), into `out`.
    pub fn objects_at(&self, time_s: f64, out: &mut Vec<SceneObject>) {
        out.clear();
        for (i, p) in self.present() {
            if let Some(s) = p.at(time_s) {
                out.push(SceneObject { id: i as u32, obb: p.obb(&s), velocity: s.velocity(), kind: p.kind });
            }
        }
        let base = self.others.len() as u32;
        for (k, obb) in self.statics.iter().enumerate() {
            out.push(SceneObject { id: base + k as u32, obb: *obb, velocity: Vec2::zeros(), kind: ObjectKind::Parked });
        }
    }

    /// The criticality states of the objects in `objects` (accelerations along the heading).
    pub fn critical_states_at(&self, time_s: f64, out: &mut Vec<VehicleState>) {
        out.clear();
        for (_, p) in self.present() {
            if let Some(s) = p.at(time_s) {
                let obb = p.obb(&s);
                out.push(VehicleState { obb, velocity: s.velocity(), accel: obb.axis * s.accel_mps2 });
            }
        }
        for obb in &self.statics {
            out.push(VehicleState { obb: *obb, velocity: Vec2::zeros(), accel: Vec2::zeros() });
        }
    }
}
