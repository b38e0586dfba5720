//! One driving environment: a scenario's world, stepped by a policy's action, with the reward
//! of paper eq. 7 computed exactly as `episode::run` computes it.

use super::observe::{ACT_DIM, OBS_DIM, Observer, action_to_controls};
use super::reward::TrainingReward;
use crate::geometry::Vec2;
use crate::metrics::{EpisodeMetrics, MetricsAccumulator, RewardInputs, RewardWeights, StepSample, step_reward};
use crate::risk::{EgoKinematics, EgoLaneFrame, FieldObject, RiskFieldParams, VehicleState};
use crate::scenario::{ScenarioKind, ScenarioSpec, build};
use crate::world::World;

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepOutcome {
    pub reward: f64,
    /// The episode ended in a state with no future: collision or leaving the road.
    pub terminated: bool,
    /// The episode was cut (horizon reached or route completed): the state still has a value,
    /// so learners bootstrap from the final observation.
    pub truncated: bool,
}

impl StepOutcome {
    /// The episode is over, either way.
    pub fn done(&self) -> bool {
        self.terminated || self.truncated
    }
}

/// A finished episode, as the environment measured it (no scenario risk score: that needs the
/// criticality accumulator of `episode::run`, which evaluation uses).
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeSummary {
    pub kind: ScenarioKind,
    pub metrics: EpisodeMetrics,
}

/// One environment; allocation-free per step once its scratch buffers are warm (a reset builds
/// a new world, which allocates).
#[derive(Debug, Clone)]
pub struct DrivingEnv {
    world: World,
    kind: ScenarioKind,
    reward: TrainingReward,
    /// `reward`'s weights as `step_reward` takes them.
    step_weights: RewardWeights,
    field: RiskFieldParams,
    observer: Observer,
    objects: Vec<FieldObject>,
    metrics: MetricsAccumulator,
    progress_prev_m: f64,
    /// R̄ of the current state, for the potential difference (0 when not needed).
    risk_prev: f64,
    collision: bool,
    offroad: bool,
}

impl DrivingEnv {
    /// An environment on `spec` (which must be feasible, as `build` requires), rewarded with
    /// `reward`; `obs` receives s_0.
    pub fn new(spec: &ScenarioSpec, reward: TrainingReward, obs: &mut [f32; OBS_DIM]) -> Self {
        let world = build(spec);
        let mut env = Self {
            progress_prev_m: world.progress_m(),
            risk_prev: 0.0,
            world,
            kind: spec.kind,
            reward,
            step_weights: reward.step_weights(),
            field: RiskFieldParams::default(),
            observer: Observer::default(),
            objects: Vec::with_capacity(32),
            metrics: MetricsAccumulator::default(),
            collision: false,
            offroad: false,
        };
        env.observe(obs);
        env.start_potential();
        env
    }

    /// Starts a new episode on `spec`; `obs` receives s_0.
    pub fn reset(&mut self, spec: &ScenarioSpec, obs: &mut [f32; OBS_DIM]) {
        self.world = build(spec);
        self.kind = spec.kind;
        self.observer.reset();
        self.metrics = MetricsAccumulator::default();
        self.progress_prev_m = self.world.progress_m();
        (self.collision, self.offroad) = (false, false);
        self.observe(obs);
        self.start_potential();
    }

    /// R̄ of s_0 for the potential (after `observe`, which refreshed the scene); a per-step
    /// risk term never reads it, so no field is evaluated for it then.
    fn start_potential(&mut self) {
        self.risk_prev = if self.reward.needs_risk_before() { self.footprint_risk(0.0) } else { 0.0 };
    }

    /// R̄: the risk field over the true scene at the ego footprint, as `episode::run` samples it.
    fn footprint_risk(&mut self, jerk_mps3: f64) -> f64 {
        let w = &self.world;
        self.objects.clear();
        self.objects.extend(w.scene().iter().map(|o| FieldObject { obb: o.obb, velocity: o.velocity }));
        let ego = EgoKinematics {
            pose: w.ego.pose(),
            velocity: w.ego.velocity(),
            lateral_accel_mps2: w.ego.lateral_accel_mps2(),
            jerk_mps3,
            footprint: w.ego.params.footprint(),
        };
        self.field.evaluate_footprint(&w.road, &self.objects, &ego)
    }

    /// Time to collision with the nearest object ahead in the ego's lane over the true scene,
    /// at constant speeds (∞ when none is closing).
    fn lane_ttc_s(&self) -> f64 {
        let w = &self.world;
        let state = |obb, velocity| VehicleState { obb, velocity, accel: Vec2::zeros() };
        let frame = EgoLaneFrame::new(&w.road, &state(w.ego.obb(), w.ego.velocity()));
        let ttc = w.scene().iter().map(|o| frame.measure(&w.road, &state(o.obb, o.velocity)).ttc_s);
        ttc.filter(|t| !t.is_nan()).fold(f64::INFINITY, f64::min)
    }

    /// The world being driven.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The kind of the current scenario.
    pub fn kind(&self) -> ScenarioKind {
        self.kind
    }

    fn observe(&mut self, obs: &mut [f32; OBS_DIM]) {
        self.world.perceive();
        let (v_ref, dt) = (self.world.desired_speed_mps, self.world.dt_s);
        self.observer.observe(&self.world.view(), v_ref, dt, obs);
    }

    /// Applies `action`, advances one step and writes the next observation into `obs` (also
    /// when the episode ended; the caller then resets). Returns the reward and whether the
    /// episode ended.
    pub fn step(&mut self, action: &[f32; ACT_DIM], obs: &mut [f32; OBS_DIM]) -> StepOutcome {
        let report = self.world.advance(action_to_controls(action));
        let (collision, offroad) = (report.contacts.collision, report.contacts.offroad);
        // The reward exactly as `episode::run` forms it: footprint risk over the true scene.
        let (accel_mps2, dt_s) = (self.world.ego.state.accel_mps2, self.world.dt_s);
        let jerk = self.metrics.jerk_of(accel_mps2, dt_s);
        // Base variant: risk weight 0, the field need not be evaluated.
        let risk = if self.reward.needs_risk() { self.footprint_risk(jerk) } else { 0.0 };
        let w = &self.world;
        let lane_pos = w.road.locate_heading(w.ego.pose().position(), w.ego.pose().heading_rad);
        let progress = w.progress_m();
        let mut reward = step_reward(
            &self.step_weights,
            &RewardInputs {
                progress_m: progress - self.progress_prev_m,
                desired_speed_mps: w.desired_speed_mps,
                speed_mps: w.ego.state.speed_mps,
                dt_s,
                risk,
                lane_offset_m: lane_pos.frenet.e_y_m,
                jerk_mps3: jerk,
                collision,
                offroad,
            },
        );
        reward += self.reward.potential_term(self.risk_prev, risk);
        if self.reward.ttc != 0.0 {
            reward += self.reward.ttc_term(self.lane_ttc_s(), dt_s);
        }
        self.risk_prev = risk;
        self.progress_prev_m = progress;
        (self.collision, self.offroad) = (collision, offroad);
        self.metrics.observe(StepSample {
            dt_s: w.dt_s,
            speed_mps: w.ego.state.speed_mps,
            steer_rad: w.ego.state.steer_rad,
            accel_mps2: w.ego.state.accel_mps2,
            reward,
        });
        let terminated = collision || offroad;
        let truncated = !terminated && w.finished();
        // Observed even at the end: a truncated episode's learner bootstraps from it.
        self.observe(obs);
        StepOutcome { reward, terminated, truncated }
    }

    /// The metrics of the episode so far (call when it is over).
    pub fn summary(&self) -> EpisodeSummary {
        let w = &self.world;
        let completion = w.progress_m() / w.route.length_m;
        EpisodeSummary { kind: self.kind, metrics: self.metrics.finish(completion, self.collision, self.offroad) }
    }
}
