//! The simulated scene behind an edge: a scenario's world driven by the reference driver, and
//! the conversions from what it yields to the wire messages of `common::telemetry`.

use crate::EdgeError;
use risktwin_common::driver::ReferenceDriver;
use risktwin_common::episode::with_reference_driver;
use risktwin_common::geometry::{Footprint, Pose};
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, check_feasible, sample};
use risktwin_common::sensor::PerceivedObject;
use risktwin_common::telemetry::DetectedObject;
use risktwin_common::vehicle::Controls;
use risktwin_common::world::World;

/// Simulation step of every edge world, s (50 Hz).
pub const STEP_S: f64 = 0.02;

/// Candidates tried before giving up on finding a feasible scenario.
const MAX_CANDIDATES: u64 = 1000;

/// The first feasible scenario of `kind` for `seed` (candidate index 0, 1, 2, …).
pub fn feasible_spec(seed: u64, kind: ScenarioKind) -> Result<ScenarioSpec, EdgeError> {
    (0..MAX_CANDIDATES)
        .map(|index| sample(seed, kind, index))
        .find(|spec| check_feasible(spec).is_ok())
        .ok_or(EdgeError::NoFeasibleScenario { kind: kind.name(), seed, tried: MAX_CANDIDATES })
}

/// A scenario world stepping at [`STEP_S`] with the reference driver; when the scenario's
/// horizon is reached it starts over, so an edge can publish for as long as it runs.
pub struct Scene {
    spec: ScenarioSpec,
    pub world: World,
    driver: ReferenceDriver,
}

impl Scene {
    /// The world of `spec` at t = 0.
    pub fn new(spec: ScenarioSpec) -> Self {
        let (mut world, driver) = with_reference_driver(&spec);
        world.dt_s = STEP_S;
        Scene { spec, world, driver }
    }

    /// One step (and a restart first when the horizon was reached); the driver's controls.
    pub fn step(&mut self) -> Controls {
        if self.world.time_s >= self.world.horizon_s {
            *self = Scene::new(self.spec.clone());
        }
        self.world.step(&mut self.driver).controls
    }
}

/// A perceived object as it goes on the wire: the pose and size of its footprint.
pub fn detected(object: &PerceivedObject) -> DetectedObject {
    let obb = &object.obb;
    DetectedObject {
        id: object.id,
        kind: object.kind,
        pose: Pose::new(obb.centre.x, obb.centre.y, obb.axis.y.atan2(obb.axis.x)),
        footprint: Footprint::new(2.0 * obb.half_length_m, 2.0 * obb.half_width_m),
        velocity: object.velocity,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_feasible_cut_in_steps_and_restarts_at_its_horizon() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("a feasible cut-in");
        assert!(check_feasible(&spec).is_ok());
        let mut scene = Scene::new(spec);
        let x0 = scene.world.ego.pose().x_m;
        for _ in 0..50 {
            scene.step();
        }
        assert!((scene.world.time_s - 1.0).abs() < 1e-9, "50 steps of 20 ms: {}", scene.world.time_s);
        assert!(scene.world.ego.pose().x_m != x0, "the ego moved");
        scene.world.time_s = scene.world.horizon_s;
        scene.step();
        assert!((scene.world.time_s - STEP_S).abs() < 1e-9, "restarted: {}", scene.world.time_s);
    }
}
