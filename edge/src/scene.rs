//! The simulated scene behind an edge: a scenario's world driven by the ego controller (the
//! reference driver for now), and the conversions from what it yields to the wire messages of
//! `common::telemetry`.
//!
//! A scenario pushed by the cloud is executed as one episode with `common::episode` (so its
//! outcome is measured as `risktwin simulate` measures it, stopping at the first collision —
//! but at the edge's 20 ms step, which the vehicle's 50 Hz streams need, where the library's
//! outcomes use the world's own step; discretisation makes the two differ slightly), recorded
//! step by step into a [`Tape`] that the vehicle then plays out on its
//! streams in real time; the outcome is reported when the tape has been played.

use crate::EdgeError;
use risktwin_common::driver::{Policy, ReferenceDriver};
use risktwin_common::episode::{EpisodeResult, run_observed, with_reference_driver};
use risktwin_common::geometry::{Footprint, Pose};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, check_feasible, sample};
use risktwin_common::sensor::PerceivedObject;
use risktwin_common::telemetry::{DetectedObject, VehicleStateSample};
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

/// What drives the ego. The seam for learned policies: a `Learned` variant backed by the
/// `learn` crate's networks (built from a received `PolicyUpdate`) will implement
/// [`Policy`] next to the reference driver; until then every episode uses the reference driver.
#[derive(Debug, Clone)]
pub enum EgoController {
    /// The IDM/MOBIL reference driver of the scenario.
    Reference(ReferenceDriver),
}

impl EgoController {
    /// The policy to drive with.
    pub fn policy(&mut self) -> &mut dyn Policy {
        match self {
            EgoController::Reference(driver) => driver,
        }
    }
}

/// One recorded step of an episode: what the vehicle publishes for it.
#[derive(Debug, Clone)]
pub struct TapeStep {
    /// The ego's state (header filled in when published).
    pub state: VehicleStateSample,
    pub controls: Controls,
    pub perceived: Vec<DetectedObject>,
}

/// An episode executed ahead of time, played out step by step.
#[derive(Debug, Clone)]
pub struct Tape {
    pub steps: Vec<TapeStep>,
    pub result: EpisodeResult,
    next: usize,
}

impl Tape {
    /// Runs `spec` (which must be feasible) to its end with the ego controller of the
    /// scenario, recording every step.
    pub fn record(spec: &ScenarioSpec) -> Tape {
        let (mut world, driver) = with_reference_driver(spec);
        world.dt_s = STEP_S;
        let mut controller = EgoController::Reference(driver);
        let mut steps = Vec::new();
        let mut states = Vec::new();
        let result = run_observed(&mut world, controller.policy(), &RewardWeights::default(), &mut |w, report| {
            w.state_samples(0, &mut states);
            if let Some(state) = states.first() {
                steps.push(TapeStep {
                    state: state.clone(),
                    controls: report.controls,
                    perceived: w.perceived().iter().map(detected).collect(),
                });
            }
        });
        Tape { steps, result, next: 0 }
    }

    /// The next step to play, `None` once all were played.
    pub fn next_step(&mut self) -> Option<&TapeStep> {
        let step = self.steps.get(self.next)?;
        self.next += 1;
        Some(step)
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

    #[test]
    fn a_tape_holds_every_step_of_the_episode_and_its_outcome() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("a feasible cut-in");
        let mut tape = Tape::record(&spec);
        // `simulate` measured at the edge's step (the library's outcomes use the world's own).
        let (mut world, mut driver) = with_reference_driver(&spec);
        world.dt_s = STEP_S;
        let expected = risktwin_common::episode::run(&mut world, &mut driver, &RewardWeights::default());
        assert_eq!(tape.result, expected, "the outcome `common::episode` measures");
        assert_eq!(tape.steps.len() as u64, expected.metrics.steps);
        let x0 = tape.steps[0].state.pose.x_m;
        let n = tape.steps.len();
        let last_x = tape.steps[n - 1].state.pose.x_m;
        assert!(last_x > x0, "the ego moved along the episode");
        for _ in 0..n {
            assert!(tape.next_step().is_some());
        }
        assert!(tape.next_step().is_none());
    }
}
