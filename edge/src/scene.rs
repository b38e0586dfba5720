//! The simulated scene behind an edge: a scenario's world driven by the ego controller (the
//! reference driver, or a policy received from the cloud: [`EgoController`]), and the
//! conversions from what it yields to the wire messages of `common::telemetry`.
//!
//! Every edge world steps at the world's own step (`common::world::STEP_S`, 50 ms), as the
//! library, `risktwin simulate` and `risktwin run` do; the faster streams are interpolated
//! samples of it ([`crate::cadence`]).
//!
//! A scenario pushed by the cloud is executed as one episode with `common::episode`, so its
//! outcome is exactly the one `risktwin simulate` measures (stopping at the first collision),
//! recorded step by step into a [`Tape`] that the vehicle then plays out on its streams in real
//! time; the outcome is reported when the tape has been played.

use crate::cadence::Segment;
use crate::error::EdgeError;
use risktwin_common::driver::{Policy, ReferenceDriver};
use risktwin_common::episode::{EpisodeResult, run_observed, with_reference_driver};
use risktwin_common::geometry::{Footprint, Pose};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, check_feasible, sample};
use risktwin_common::sensor::PerceivedObject;
use risktwin_common::telemetry::PolicyRef;
use risktwin_common::telemetry::{DetectedObject, HazardWarning};
use risktwin_common::vehicle::{Controls, Vehicle, VehicleState};
use risktwin_common::world::World;
use risktwin_policy::HostDriver;
use risktwin_policy::model::DriverModel;
use risktwin_v2x::warning::{Heard, Warning};
use std::fmt;

/// Candidates tried before giving up on finding a feasible scenario.
const MAX_CANDIDATES: u64 = 1000;

/// The first feasible scenario of `kind` for `seed` (candidate index 0, 1, 2, …).
pub fn feasible_spec(seed: u64, kind: ScenarioKind) -> Result<ScenarioSpec, EdgeError> {
    (0..MAX_CANDIDATES)
        .map(|index| sample(seed, kind, index))
        .find(|spec| check_feasible(spec).is_ok())
        .ok_or(EdgeError::NoFeasibleScenario { kind: kind.name(), seed, tried: MAX_CANDIDATES })
}

/// A scenario world stepping at the world's step with the ego controller; when the scenario's
/// horizon is reached it starts over, so an edge can publish for as long as it runs. Hazards
/// the cloud warned of are fused into what the controller sees (`v2x::warning::Heard`:
/// the warned objects it does not perceive itself, kept 1 s after last heard).
pub struct Scene {
    spec: ScenarioSpec,
    pub world: World,
    controller: EgoController,
    policy: Option<ActivePolicy>,
    heard: Heard,
}

impl Scene {
    /// The world of `spec` at t = 0, driven by the reference driver.
    pub fn new(spec: ScenarioSpec) -> Self {
        Self::with_policy(spec, None)
    }

    /// The world of `spec` at t = 0, driven by `policy` when given.
    pub fn with_policy(spec: ScenarioSpec, policy: Option<ActivePolicy>) -> Self {
        let (world, controller) = EgoController::world(&spec, policy.as_ref());
        Scene { spec, world, controller, policy, heard: Heard::default() }
    }

    /// A cloud hazard warning heard now; its hazard is object `id` of what the ego perceives.
    pub fn hear(&mut self, warning: &HazardWarning, id: u32) {
        let now_s = self.world.time_s;
        self.heard.hear(now_s, Warning::from_hazard(warning, id, now_s));
    }

    /// The hazards heard of and not yet forgotten.
    pub fn heard(&self) -> &Heard {
        &self.heard
    }

    /// Drives with `policy` from the next step on (the world goes on where it is).
    pub fn set_policy(&mut self, policy: ActivePolicy) {
        self.controller = EgoController::learned(&self.world, &policy);
        self.policy = Some(policy);
    }

    /// Which policy drives (`None`: the reference driver).
    pub fn driven_by(&self) -> Option<&PolicyRef> {
        self.controller.driven_by()
    }

    /// One step (and a restart first when the horizon was reached, forgetting what was heard:
    /// its time starts over): the ego over it. As `World::step`, with the heard hazards fused
    /// into the controller's view (nothing heard: the same step).
    pub fn step(&mut self) -> Segment {
        if self.world.time_s >= self.world.horizon_s {
            *self = Scene::with_policy(self.spec.clone(), self.policy.take());
        }
        let from = self.world.ego.state;
        self.heard.forget_old(self.world.time_s);
        self.world.perceive();
        let controls = self.heard.act(&self.world.view(), self.controller.policy());
        let controls = self.world.advance(controls).controls;
        Segment { ego: self.world.ego.clone(), from, controls }
    }
}

/// A learned driver, checked and ready to drive: a policy received from the cloud, or the
/// model file an edge vehicle starts with (`edge vehicle --driver`).
#[derive(Debug, Clone)]
pub struct ActivePolicy {
    /// Which policy and version (a model file: its label, version 0).
    pub id: PolicyRef,
    /// Its model, shared by every world it drives.
    pub model: DriverModel,
}

/// What drives the ego: the scenario's reference driver, or a received policy acting on the
/// training environment's observation through its action mapping (`policy::HostDriver`).
pub enum EgoController {
    /// The IDM/MOBIL reference driver of the scenario.
    Reference(Box<ReferenceDriver>),
    /// A learned policy.
    Learned { id: PolicyRef, driver: Box<HostDriver> },
}

impl fmt::Debug for EgoController {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EgoController::Reference(driver) => f.debug_tuple("Reference").field(driver).finish(),
            EgoController::Learned { id, .. } => f.debug_struct("Learned").field("id", id).finish_non_exhaustive(),
        }
    }
}

impl EgoController {
    /// The world of `spec` and its controller: `policy` when given, else the scenario's
    /// reference driver.
    pub fn world(spec: &ScenarioSpec, policy: Option<&ActivePolicy>) -> (World, EgoController) {
        let (world, reference) = with_reference_driver(spec);
        let controller = match policy {
            Some(p) => EgoController::learned(&world, p),
            None => EgoController::Reference(Box::new(reference)),
        };
        (world, controller)
    }

    /// `policy` driving in `world` (its desired speed and step are part of the observation).
    pub fn learned(world: &World, policy: &ActivePolicy) -> EgoController {
        let driver = policy.model.driver(world.desired_speed_mps, world.dt_s);
        EgoController::Learned { id: policy.id.clone(), driver: Box::new(driver) }
    }

    /// The policy to drive with.
    pub fn policy(&mut self) -> &mut dyn Policy {
        match self {
            EgoController::Reference(driver) => driver.as_mut(),
            EgoController::Learned { driver, .. } => driver.as_mut(),
        }
    }

    /// Which received policy drives (`None`: the reference driver).
    pub fn driven_by(&self) -> Option<&PolicyRef> {
        match self {
            EgoController::Reference(_) => None,
            EgoController::Learned { id, .. } => Some(id),
        }
    }
}

/// One recorded step of an episode: what the vehicle publishes for it.
#[derive(Debug, Clone)]
pub struct TapeStep {
    /// The ego's state at the end of the step.
    pub state: VehicleState,
    /// The controls held over the step.
    pub controls: Controls,
    /// What the ego perceived at the start of the step.
    pub perceived: Vec<DetectedObject>,
}

/// An episode executed ahead of time, played out step by step.
#[derive(Debug, Clone)]
pub struct Tape {
    /// The ego at t = 0.
    pub start: Vehicle,
    pub steps: Vec<TapeStep>,
    pub result: EpisodeResult,
    /// The received policy that drove (`None`: the reference driver).
    pub driven_by: Option<PolicyRef>,
    next: usize,
}

impl Tape {
    /// Runs `spec` (which must be feasible) to its end driven by `policy` (the scenario's
    /// reference driver when `None`), recording every step.
    pub fn record(spec: &ScenarioSpec, policy: Option<&ActivePolicy>) -> Tape {
        let (mut world, mut controller) = EgoController::world(spec, policy);
        let start = world.ego.clone();
        let mut steps = Vec::new();
        let result = run_observed(&mut world, controller.policy(), &RewardWeights::default(), &mut |w, report| {
            steps.push(TapeStep {
                state: w.ego.state,
                controls: report.controls,
                perceived: w.perceived().iter().map(detected).collect(),
            });
        });
        Tape { start, steps, result, driven_by: controller.driven_by().cloned(), next: 0 }
    }

    /// The next step to play (the ego over it, and what it perceived at its start), `None`
    /// once all were played.
    pub fn next_step(&mut self) -> Option<(Segment, &[DetectedObject])> {
        let step = self.steps.get(self.next)?;
        let from = self.next.checked_sub(1).map_or(self.start.state, |i| self.steps[i].state);
        self.next += 1;
        let mut ego = self.start.clone();
        ego.state = step.state;
        Some((Segment { ego, from, controls: step.controls }, &step.perceived))
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
        // The sensor model estimates no acceleration.
        accel_mps2: 0.0,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use risktwin_common::env::OBS_DIM;
    use risktwin_common::world::STEP_S;
    use risktwin_policy::{Dense, HostMlp, HostPolicy, PolicyKind};
    use std::sync::Arc;

    /// A `kind` policy file OBS_DIM → 4 → out: zero weights, so the action is the output bias.
    pub(crate) fn policy_net(kind: PolicyKind, out_bias: &[f32]) -> HostPolicy {
        let hidden = Dense::new("h", vec![0.0; OBS_DIM * 4], vec![0.0; 4], OBS_DIM, 4).expect("a layer");
        let out =
            Dense::new("o", vec![0.0; 4 * kind.out_dim()], out_bias.to_vec(), 4, kind.out_dim()).expect("a layer");
        HostPolicy::new(kind, HostMlp::from_layers(vec![hidden, out]).expect("a chain")).expect("a policy")
    }

    /// [`policy_net`] as a policy file.
    pub(crate) fn policy_file(kind: PolicyKind, out_bias: &[f32]) -> Vec<u8> {
        policy_net(kind, out_bias).to_safetensors().expect("serialised")
    }

    #[test]
    fn a_received_policy_drives_the_tape_and_the_scene() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("a feasible cut-in");
        let reference = Tape::record(&spec, None);
        // Full brake from the first step.
        let id = PolicyRef { policy_id: "brake".into(), version: 2 };
        let net = Arc::new(policy_net(PolicyKind::Gaussian, &[0.0, 0.0, 1.0]));
        let policy = ActivePolicy { id: id.clone(), model: DriverModel::Native(net) };
        let braking = Tape::record(&spec, Some(&policy));
        assert_eq!(braking.driven_by.as_ref(), Some(&id));
        let last = |t: &Tape| t.steps.last().map(|s| (s.state.x_m, s.state.speed_mps)).expect("steps");
        assert!(braking.steps.iter().all(|s| s.controls.brake == 1.0 && s.controls.throttle == 0.0));
        assert!(last(&braking).1 < 0.1, "stopped: {:?}", last(&braking));
        assert!(last(&reference).1 > 5.0, "the reference driver keeps going: {:?}", last(&reference));
        assert!(braking.result.metrics.avg_speed_mps < reference.result.metrics.avg_speed_mps);

        let mut scene = Scene::new(spec);
        scene.step();
        assert_eq!(scene.driven_by(), None);
        scene.set_policy(policy);
        assert_eq!(scene.step().controls.brake, 1.0);
        scene.world.time_s = scene.world.horizon_s;
        assert_eq!(scene.step().controls.brake, 1.0, "still the policy after the restart");
        assert_eq!(scene.driven_by(), Some(&id));
    }

    #[test]
    fn a_feasible_cut_in_steps_and_restarts_at_its_horizon() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("a feasible cut-in");
        assert!(check_feasible(&spec).is_ok());
        let mut scene = Scene::new(spec);
        let x0 = scene.world.ego.pose().x_m;
        let start = scene.world.ego.state;
        let mut end = start;
        for _ in 0..20 {
            let segment = scene.step();
            assert_eq!(segment.from, end, "each step starts where the last one ended");
            end = segment.ego.state;
        }
        assert!((scene.world.time_s - 1.0).abs() < 1e-9, "20 steps of 50 ms: {}", scene.world.time_s);
        assert!(scene.world.ego.pose().x_m != x0, "the ego moved");
        scene.world.time_s = scene.world.horizon_s;
        let restarted = scene.step();
        assert!((scene.world.time_s - STEP_S).abs() < 1e-9, "restarted: {}", scene.world.time_s);
        assert_eq!(restarted.from, start, "from the start again");
    }

    #[test]
    fn a_tape_holds_every_step_of_the_episode_and_its_outcome() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("a feasible cut-in");
        let mut tape = Tape::record(&spec, None);
        assert_eq!(tape.driven_by, None);
        // Exactly what `risktwin simulate` and the library measure: same step, same code.
        let expected = risktwin_common::episode::evaluate(&spec);
        assert_eq!(tape.result, expected, "the outcome `common::episode` measures");
        assert_eq!(tape.steps.len() as u64, expected.metrics.steps);
        let n = tape.steps.len();
        assert!(tape.steps[n - 1].state.x_m > tape.start.state.x_m, "the ego moved along the episode");
        let mut end = tape.start.state;
        for step in 0..n {
            let (segment, _) = tape.next_step().expect("a step");
            assert_eq!(segment.from, end, "step {step} starts where the last one ended");
            end = segment.ego.state;
        }
        assert_eq!(end, tape.steps[n - 1].state);
        assert!(tape.next_step().is_none());
    }
}
