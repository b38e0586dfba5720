//! One episode of a scenario: build the world, drive it with a policy, measure and score it.

use crate::driver::{Policy, ReferenceDriver};
use crate::geometry::{Obb, Vec2};
use crate::metrics::{EpisodeMetrics, MetricsAccumulator, RewardInputs, RewardWeights, StepSample, step_reward};
use crate::risk::{
    EgoKinematics, FieldError, FieldObject, GridEvaluator, RiskAccumulator, RiskFieldParams, RiskGrid, RiskStep,
    RiskTerms, RiskWeights, RoadRaster, ScoreReferences, VehicleState,
};
use crate::road::Road;
use crate::scenario::{ScenarioSpec, build};
use crate::world::{StepReport, World};

/// What an episode produced.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeResult {
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
}

/// Field inputs for the ego and everything around it (the world's current scene) into `objects`.
fn field_inputs(world: &World, jerk_mps3: f64, objects: &mut Vec<FieldObject>) -> EgoKinematics {
    objects.clear();
    objects.extend(world.scene().iter().map(|o| FieldObject { obb: o.obb, velocity: o.velocity }));
    EgoKinematics {
        pose: world.ego.pose(),
        velocity: world.ego.velocity(),
        lateral_accel_mps2: world.ego.lateral_accel_mps2(),
        jerk_mps3,
        footprint: world.ego.params.footprint(),
    }
}

/// Kinematic states of everything but the ego for the criticality measures: traffic in index
/// order, then the pedestrians on the road (accelerations along the heading).
fn critical_states(world: &World, out: &mut Vec<VehicleState>) {
    out.clear();
    let t = &world.traffic;
    for i in 0..t.len() {
        let obb = t.obb(i);
        out.push(VehicleState { obb, velocity: t.velocity(i), accel: obb.axis * t.accel_mps2(i) });
    }
    for p in &world.pedestrians {
        if let Some(pos) = p.position_at(world.time_s) {
            let velocity = p.velocity_at(world.time_s);
            out.push(VehicleState { obb: World::pedestrian_obb(pos, velocity), velocity, accel: Vec2::zeros() });
        }
    }
}

/// Runs `world` to its end with `policy`, stopping at the first collision or road departure.
pub fn run(world: &mut World, policy: &mut dyn Policy, weights: &RewardWeights) -> EpisodeResult {
    run_observed(world, policy, weights, &mut |_, _| {})
}

/// [`run`], calling `observe` after every step (for traces and recordings).
pub fn run_observed(
    world: &mut World,
    policy: &mut dyn Policy,
    weights: &RewardWeights,
    observe: &mut dyn FnMut(&World, &StepReport),
) -> EpisodeResult {
    run_stepped(world, weights, observe, &mut |w| Ok::<_, std::convert::Infallible>(w.step(policy)))
        .unwrap_or_else(|e| match e {})
}

/// [`run_observed`] with the step left to `step`: a scene whose drivers live in other processes
/// perceives and acts there, and advances the world here with their controls. The first error
/// of `step` ends the episode.
pub fn run_stepped<E>(
    world: &mut World,
    weights: &RewardWeights,
    observe: &mut dyn FnMut(&World, &StepReport),
    step: &mut dyn FnMut(&mut World) -> Result<StepReport, E>,
) -> Result<EpisodeResult, E> {
    let mut scorer = EpisodeScorer::new(*weights, world.progress_m());
    let mut objects = Vec::new();
    let mut others = Vec::new();
    let (mut collision, mut offroad) = (false, false);
    while !world.finished() && !collision && !offroad {
        let report = step(world)?;
        collision = report.contacts.collision;
        offroad = report.contacts.offroad;
        observe(world, &report);
        let jerk_mps3 = scorer.jerk_of(world.ego.state.accel_mps2, world.dt_s);
        // `step` left the post-step scene in the world: no second rebuild.
        let ego = field_inputs(world, jerk_mps3, &mut objects);
        critical_states(world, &mut others);
        scorer.push(
            &world.road,
            &ScoredStep {
                dt_s: world.dt_s,
                ego,
                speed_mps: world.ego.state.speed_mps,
                steer_rad: world.ego.state.steer_rad,
                accel_mps2: world.ego.state.accel_mps2,
                progress_m: world.progress_m(),
                desired_speed_mps: world.desired_speed_mps,
                objects: &objects,
                others: &others,
                collision,
                offroad,
            },
        );
    }
    Ok(scorer.finish(world.progress_m() / world.route.length_m))
}

/// One step of an episode as it is scored: the ego and everything around it after the step.
/// `run_stepped` fills it from the world; an observer of the episode (the cloud twin, from what
/// a vehicle reported) fills it from what it saw.
#[derive(Debug, Clone, Copy)]
pub struct ScoredStep<'a> {
    pub dt_s: f64,
    /// The ego for the risk field; its jerk from [`EpisodeScorer::jerk_of`].
    pub ego: EgoKinematics,
    pub speed_mps: f64,
    pub steer_rad: f64,
    pub accel_mps2: f64,
    /// Distance along the route from its start, m.
    pub progress_m: f64,
    pub desired_speed_mps: f64,
    /// Everything around the ego, for the risk field at its footprint.
    pub objects: &'a [FieldObject],
    /// Everything around the ego with accelerations, for the criticality measures.
    pub others: &'a [VehicleState],
    pub collision: bool,
    pub offroad: bool,
}

/// Reduces an episode to its [`EpisodeResult`] one [`ScoredStep`] at a time: the reward, the
/// metrics and the risk terms, allocation-free per step. One definition for every episode,
/// whoever observed it.
#[derive(Debug, Clone)]
pub struct EpisodeScorer {
    weights: RewardWeights,
    field: RiskFieldParams,
    metrics: MetricsAccumulator,
    risk: RiskAccumulator,
    progress_prev_m: f64,
    collision: bool,
    offroad: bool,
}

impl EpisodeScorer {
    /// An episode that starts `start_progress_m` along its route, scored with `weights`.
    pub fn new(weights: RewardWeights, start_progress_m: f64) -> Self {
        EpisodeScorer {
            weights,
            field: RiskFieldParams::default(),
            metrics: MetricsAccumulator::default(),
            risk: RiskAccumulator::new(RiskWeights::default(), ScoreReferences::default()),
            progress_prev_m: start_progress_m,
            collision: false,
            offroad: false,
        }
    }

    /// The jerk of a step with this acceleration, from the previous step's (0 on the first).
    pub fn jerk_of(&self, accel_mps2: f64, dt_s: f64) -> f64 {
        self.metrics.jerk_of(accel_mps2, dt_s)
    }

    /// Feeds one step on `road`.
    pub fn push(&mut self, road: &Road, step: &ScoredStep<'_>) {
        let ego = &step.ego;
        let ego_risk = self.field.evaluate_footprint(road, step.objects, ego);
        let lane_pos = road.locate_heading(ego.pose.position(), ego.pose.heading_rad);
        let reward = step_reward(
            &self.weights,
            &RewardInputs {
                progress_m: step.progress_m - self.progress_prev_m,
                desired_speed_mps: step.desired_speed_mps,
                speed_mps: step.speed_mps,
                dt_s: step.dt_s,
                risk: ego_risk,
                lane_offset_m: lane_pos.frenet.e_y_m,
                jerk_mps3: ego.jerk_mps3,
                collision: step.collision,
                offroad: step.offroad,
            },
        );
        self.progress_prev_m = step.progress_m;
        self.metrics.observe(StepSample {
            dt_s: step.dt_s,
            speed_mps: step.speed_mps,
            steer_rad: step.steer_rad,
            accel_mps2: step.accel_mps2,
            reward,
        });
        let ego_state =
            VehicleState { obb: ego.obb(), velocity: ego.velocity, accel: ego.obb().axis * step.accel_mps2 };
        self.risk.push(
            road,
            &RiskStep {
                ego: ego_state,
                lane_offset_m: lane_pos.frenet.e_y_m,
                lane_width_m: road.lane(lane_pos.lane).width_m,
                jerk_mps3: ego.jerk_mps3,
                others: step.others,
                collision: step.collision,
                offroad: step.offroad,
            },
        );
        self.collision |= step.collision;
        self.offroad |= step.offroad;
    }

    /// The episode so far, with `route_completion` (a share of the route, clamped to [0, 1]).
    pub fn finish(&self, route_completion: f64) -> EpisodeResult {
        let mut m = self.metrics.finish(route_completion, self.collision, self.offroad);
        let (terms, summary) = self.risk.finish();
        m.min_ttc_s = summary.min_ttc_s;
        m.min_distance_m = summary.min_distance_m;
        m.risk_score = terms.score;
        EpisodeResult { metrics: m, risk: terms }
    }
}

/// The scenario driven by the reference driver, with the default reward weights.
pub fn evaluate(spec: &ScenarioSpec) -> EpisodeResult {
    evaluate_observed(spec, &mut |_, _| {})
}

/// [`evaluate`], calling `observe` after every step.
pub fn evaluate_observed(spec: &ScenarioSpec, observe: &mut dyn FnMut(&World, &StepReport)) -> EpisodeResult {
    let (mut world, mut driver) = with_reference_driver(spec);
    run_observed(&mut world, &mut driver, &RewardWeights::default(), observe)
}

/// The scenario's world at t = 0 and the reference driver for its ego.
pub fn with_reference_driver(spec: &ScenarioSpec) -> (World, ReferenceDriver) {
    let world = build(spec);
    let mut driver = ReferenceDriver::new(world.desired_speed_mps, world.ego.params);
    if let Some(t) = world.driver_time_headway_s {
        driver.idm.time_headway_s = t;
    }
    (world, driver)
}

/// The risk field around the ego at one moment of a scenario, with what is needed to draw it.
#[derive(Debug, Clone)]
pub struct FieldSnapshot {
    pub time_s: f64,
    pub grid: RiskGrid,
    pub road: Road,
    pub ego: Obb,
    pub others: Vec<Obb>,
}

impl FieldSnapshot {
    /// Maximum, mean and the world position of the maximum (see [`RiskGrid::stats`]).
    pub fn stats(&self) -> (f64, f64, Vec2) {
        self.grid.stats()
    }
}

/// Drives the scenario with the reference driver until `time_s` (or its end) and evaluates the
/// field on a `cells`×`cells` grid centred on the ego.
pub fn field_snapshot(
    spec: &ScenarioSpec,
    time_s: f64,
    resolution_m: f64,
    cells: usize,
) -> Result<FieldSnapshot, FieldError> {
    let (mut world, mut driver) = with_reference_driver(spec);
    while world.time_s + 1e-9 < time_s && !world.finished() {
        let report = world.step(&mut driver);
        if report.contacts.collision || report.contacts.offroad {
            break;
        }
    }
    let params = RiskFieldParams::default();
    let half_extent_m = 0.5 * resolution_m * cells as f64;
    let raster = RoadRaster::new(&world.road, &params, resolution_m, half_extent_m + 10.0)?;
    let mut objects = Vec::new();
    world.scene_objects(); // the snapshot may come before any step
    let ego = field_inputs(&world, 0.0, &mut objects);
    let origin = raster.snap_origin(ego.pose.position() - Vec2::new(half_extent_m, half_extent_m));
    let mut grid = RiskGrid::new(origin, resolution_m, cells, cells)?;
    GridEvaluator::new(params).fill(&mut grid, &raster, &world.road, &objects, &ego);
    Ok(FieldSnapshot {
        time_s: world.time_s,
        grid,
        road: world.road.clone(),
        ego: ego.obb(),
        others: objects.iter().map(|o| o.obb).collect(),
    })
}
