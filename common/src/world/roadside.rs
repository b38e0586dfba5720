//! What a roadside unit sees: a fixed sensor over the same scene the ego moves in, which (unlike
//! the ego's) also sees the ego.

use super::World;
use crate::geometry::Pose;
use crate::rng::Rng;
use crate::sensor::{ObjectKind, PerceivedObject, SceneObject, Sensor};

/// Id under which an RSU reports the ego (traffic and pedestrians keep their scene ids).
pub const EGO_OBJECT_ID: u32 = u32::MAX;

impl World {
    /// Objects a roadside sensor at `pose` perceives now, into `out`; `scratch` is reused.
    pub fn roadside_view(
        &mut self,
        sensor: &mut Sensor,
        pose: Pose,
        rng: &mut Rng,
        scratch: &mut Vec<SceneObject>,
        out: &mut Vec<PerceivedObject>,
    ) {
        scratch.clear();
        scratch.extend_from_slice(self.scene_objects());
        scratch.push(SceneObject {
            id: EGO_OBJECT_ID,
            obb: self.ego.obb(),
            velocity: self.ego.velocity(),
            kind: ObjectKind::Vehicle,
        });
        sensor.perceive(pose, scratch, rng, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{ScenarioKind, build, sample};
    use crate::sensor::SensorParams;

    #[test]
    fn a_roadside_unit_sees_the_ego_and_the_traffic() {
        let mut world = build(&sample(1, ScenarioKind::EmergencyBraking, 0));
        let ego = world.ego.pose();
        // A mast 10 m beside the road, level with the ego, looking all around.
        let mast = Pose::new(ego.x_m, ego.y_m - 12.0, std::f64::consts::FRAC_PI_2);
        let params = SensorParams {
            fov_rad: std::f64::consts::TAU,
            dropout_rate: 0.0,
            occlusion: false,
            ..SensorParams::default()
        };
        let mut sensor = Sensor::new(params).expect("valid sensor");
        let (mut scratch, mut seen) = (Vec::new(), Vec::new());
        world.roadside_view(&mut sensor, mast, &mut Rng::new(1), &mut scratch, &mut seen);
        assert!(seen.iter().any(|o| o.id == EGO_OBJECT_ID), "the ego is visible to the RSU");
        assert_eq!(seen.len(), world.traffic.len() + 1, "everything within 150 m: {seen:?}");
    }
}
