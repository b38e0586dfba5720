//! A re-simulation one step at a time: the recorded traffic plays back, the ego moves with the
//! controls it is handed (or replays its recording), and every step is measured. The driver is
//! not in here: [`super::resimulate`] drives in the same process, a scene's authority
//! (edge::fleet) with the controls of the ego's own process, and both measure with this code.

use super::super::LaneletNetwork;
use super::scene::TwinScene;
use super::{PlaybackState, TwinError};
use risktwin_common::geometry::{Obb, Pose};
use risktwin_common::metrics::{
    EpisodeMetrics, MetricsAccumulator, RewardInputs, RewardWeights, StepSample, step_reward,
};
use risktwin_common::risk::{
    EgoKinematics, FieldObject, RiskAccumulator, RiskFieldParams, RiskStep, RiskTerms, RiskWeights, ScoreReferences,
    VehicleState,
};
use risktwin_common::road::{Lane, Road};
use risktwin_common::sensor::SceneObject;
use risktwin_common::vehicle::{Controls, Vehicle};
use risktwin_common::world::Contacts;

/// Who drives the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EgoMode {
    /// The recorded ego trajectory, played back (open loop).
    Replay,
    /// The twin's reference driver (IDM + lane changes on what its sensor perceives) on the
    /// twin's single-track vehicle, from the recorded initial state (closed loop).
    ReferenceDriver,
}

/// The ego after one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResimSample {
    pub time_s: f64,
    pub ego: Obb,
    pub speed_mps: f64,
    /// Smallest footprint distance to any other object now, m (∞ when alone).
    pub min_distance_m: f64,
    pub collision: bool,
    pub offroad: bool,
}

/// What a re-simulation produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Resimulation {
    /// As `risktwin simulate` reports them (route = the recorded ego path).
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
    /// The ego's initial sample, then one per step.
    pub trace: Vec<ResimSample>,
    pub start_s: f64,
    pub end_s: f64,
}

/// A recorded scenario being re-run: the scene, the ego's vehicle and the measures so far.
pub struct ResimStepper<'a> {
    lanelets: &'a LaneletNetwork,
    scene: TwinScene,
    mode: EgoMode,
    step_s: f64,
    start_s: f64,
    end_s: f64,
    /// Steps to the end of the ego's recording, and steps taken.
    n_steps: usize,
    taken: usize,
    vehicle: Vehicle,
    first: PlaybackState,
    route: Lane,
    desired_speed_mps: f64,
    field: RiskFieldParams,
    weights: RewardWeights,
    metrics: MetricsAccumulator,
    risk: RiskAccumulator,
    /// Everything but the ego now (at the start of the next step).
    objects: Vec<SceneObject>,
    field_objects: Vec<FieldObject>,
    others: Vec<VehicleState>,
    trace: Vec<ResimSample>,
    collision: bool,
    offroad: bool,
    progress_prev_m: f64,
}

/// The ego's state as the measures need it, whoever drives.
struct EgoNow {
    pose: Pose,
    speed_mps: f64,
    accel_mps2: f64,
    steer_rad: f64,
    lat_mps2: f64,
}

/// A positive finite step, or the error naming it.
pub(super) fn check_step(step_s: f64) -> Result<(), TwinError> {
    if step_s > 0.0 && step_s.is_finite() { Ok(()) } else { Err(TwinError::BadStep { step_s }) }
}

impl<'a> ResimStepper<'a> {
    /// `scene` (of a scenario with `lanelets`) at the ego's first recorded state, to be stepped
    /// at `step_s` to its last.
    pub fn new(lanelets: &'a LaneletNetwork, scene: TwinScene, mode: EgoMode, step_s: f64) -> Result<Self, TwinError> {
        check_step(step_s)?;
        let (start_s, end_s) = (scene.ego.start_s(), scene.ego.end_s());
        let first = scene.ego.recorded()[0];
        let route = scene.ego_route();
        let mut run = ResimStepper {
            lanelets,
            mode,
            step_s,
            start_s,
            end_s,
            n_steps: ((end_s - start_s) / step_s + 1e-9).floor() as usize,
            taken: 0,
            vehicle: scene.ego_vehicle(),
            first,
            desired_speed_mps: scene.ego_desired_speed_mps(),
            field: RiskFieldParams::default(),
            weights: RewardWeights::default(),
            metrics: MetricsAccumulator::default(),
            risk: RiskAccumulator::new(RiskWeights::default(), ScoreReferences::default()),
            objects: Vec::new(),
            field_objects: Vec::new(),
            others: Vec::new(),
            trace: Vec::new(),
            collision: false,
            offroad: false,
            progress_prev_m: 0.0,
            route,
            scene,
        };
        run.scene.objects_at(start_s, &mut run.objects);
        let e0 = run.ego_now(start_s);
        let obb = Obb::new(e0.pose, run.scene.ego.footprint);
        let contacts = Contacts::detect(&obb, &run.objects, &run.scene.road);
        run.trace.push(ResimSample {
            time_s: start_s,
            ego: obb,
            speed_mps: e0.speed_mps,
            min_distance_m: contacts.min_distance_m,
            collision: contacts.collision,
            offroad: run.off_the_map(e0.pose),
        });
        run.progress_prev_m = run.route.project(e0.pose.position()).s_m;
        Ok(run)
    }

    /// True once the ego's recording is over, or the driven ego collided (as a twin episode
    /// stops); a replay runs to the end, so its min distance covers the whole recording.
    pub fn finished(&self) -> bool {
        self.taken >= self.n_steps || (self.mode == EgoMode::ReferenceDriver && self.collision)
    }

    /// The scenario's time now, s.
    fn now_s(&self) -> f64 {
        self.start_s + self.taken as f64 * self.step_s
    }

    /// Time since the ego's first recorded state, s: the driver's clock.
    pub fn time_s(&self) -> f64 {
        self.now_s() - self.start_s
    }

    /// Everything but the ego now: dynamic obstacles (id = index in `scene.others`), then the
    /// static ones.
    pub fn objects(&self) -> &[SceneObject] {
        &self.objects
    }

    /// Acceleration of object `id` of [`ResimStepper::objects`] along its heading, m/s².
    pub fn accel_mps2(&self, id: u32) -> f64 {
        self.scene.accel_mps2_at(id, self.now_s())
    }

    /// The driven ego's vehicle (in [`EgoMode::Replay`], its initial state throughout).
    pub fn vehicle(&self) -> &Vehicle {
        &self.vehicle
    }

    pub fn scene(&self) -> &TwinScene {
        &self.scene
    }

    pub fn road(&self) -> &Road {
        &self.scene.road
    }

    /// The lanelets the road was converted from.
    pub fn lanelets(&self) -> &'a LaneletNetwork {
        self.lanelets
    }

    /// Offroad means the ego's centre is in no lanelet: recorded vehicles' corners overhang the
    /// lanelet bounds routinely, so the twin's corner test would flag the recording itself.
    fn off_the_map(&self, pose: Pose) -> bool {
        self.lanelets.containing(pose.position()).next().is_none()
    }

    fn ego_now(&self, t: f64) -> EgoNow {
        match self.mode {
            EgoMode::Replay => {
                let s = self.scene.ego.at(t).unwrap_or(self.first);
                EgoNow { pose: s.pose, speed_mps: s.speed_mps, accel_mps2: s.accel_mps2, steer_rad: 0.0, lat_mps2: 0.0 }
            }
            EgoMode::ReferenceDriver => EgoNow {
                pose: self.vehicle.pose(),
                speed_mps: self.vehicle.state.speed_mps,
                accel_mps2: self.vehicle.state.accel_mps2,
                steer_rad: self.vehicle.state.steer_rad,
                lat_mps2: self.vehicle.lateral_accel_mps2(),
            },
        }
    }

    /// One step: the driven ego applies `controls` (a replay ignores them), the recording moves
    /// on, and the step is measured.
    pub fn advance(&mut self, controls: Controls) {
        if self.mode == EgoMode::ReferenceDriver {
            let mu = self.scene.road.friction_at(self.vehicle.pose().position());
            self.vehicle.step(controls, mu, self.step_s);
        }
        self.taken += 1;
        let t = self.now_s();
        let footprint = self.scene.ego.footprint;
        let e = self.ego_now(t);
        let obb = Obb::new(e.pose, footprint);
        self.scene.objects_at(t, &mut self.objects);
        let contacts = Contacts::detect(&obb, &self.objects, &self.scene.road);
        let off = self.off_the_map(e.pose);
        self.collision |= contacts.collision;
        self.offroad |= off;
        self.trace.push(ResimSample {
            time_s: t,
            ego: obb,
            speed_mps: e.speed_mps,
            min_distance_m: contacts.min_distance_m,
            collision: contacts.collision,
            offroad: off,
        });
        let jerk = self.metrics.jerk_of(e.accel_mps2, self.step_s);
        self.field_objects.clear();
        self.field_objects.extend(self.objects.iter().map(|o| FieldObject { obb: o.obb, velocity: o.velocity }));
        let kin = EgoKinematics {
            pose: e.pose,
            velocity: e.pose.forward() * e.speed_mps,
            lateral_accel_mps2: e.lat_mps2,
            jerk_mps3: jerk,
            footprint,
        };
        let road = &self.scene.road;
        let ego_risk = self.field.evaluate_footprint(road, &self.field_objects, &kin);
        let lane_pos = road.locate_heading(e.pose.position(), e.pose.heading_rad);
        let progress_m = self.route.project(e.pose.position()).s_m;
        let reward = step_reward(
            &self.weights,
            &RewardInputs {
                progress_m: progress_m - self.progress_prev_m,
                desired_speed_mps: self.desired_speed_mps,
                speed_mps: e.speed_mps,
                dt_s: self.step_s,
                risk: ego_risk,
                lane_offset_m: lane_pos.frenet.e_y_m,
                jerk_mps3: jerk,
                collision: contacts.collision,
                offroad: off,
            },
        );
        self.progress_prev_m = progress_m;
        self.metrics.observe(StepSample {
            dt_s: self.step_s,
            speed_mps: e.speed_mps,
            steer_rad: e.steer_rad,
            accel_mps2: e.accel_mps2,
            reward,
        });
        self.scene.critical_states_at(t, &mut self.others);
        self.risk.push(
            road,
            &RiskStep {
                ego: VehicleState { obb, velocity: kin.velocity, accel: obb.axis * e.accel_mps2 },
                lane_offset_m: lane_pos.frenet.e_y_m,
                lane_width_m: road.lane(lane_pos.lane).width_m,
                jerk_mps3: jerk,
                others: &self.others,
                collision: contacts.collision,
                offroad: off,
            },
        );
    }

    /// The run's measures: metrics as `risktwin simulate` reports them (route = the recorded
    /// ego path), S_risk and the trace.
    pub fn finish(self) -> Resimulation {
        let e0 = self.trace[0].ego;
        let last = self.trace.last().map_or(e0.centre, |s| s.ego.centre);
        let length_m = self.route.length_m();
        let completion = if length_m > 0.0 { self.route.project(last).s_m / length_m } else { 1.0 };
        let mut m = self.metrics.finish(completion, self.collision, self.offroad);
        let (terms, summary) = self.risk.finish();
        m.min_ttc_s = summary.min_ttc_s;
        m.min_distance_m = summary.min_distance_m;
        m.risk_score = terms.score;
        Resimulation { metrics: m, risk: terms, trace: self.trace, start_s: self.start_s, end_s: self.end_s }
    }
}
