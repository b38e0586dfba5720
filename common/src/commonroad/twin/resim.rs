//! Closed-loop re-simulation of a recorded scenario: the recorded traffic plays back, the ego
//! is replayed or driven by the reference driver from its recorded initial state, and the run
//! is measured like any twin episode (metrics, S_risk).

use super::super::Scenario;
use super::scene::TwinScene;
use super::{PlaybackState, TwinError};
use crate::driver::{DriverView, Policy, ReferenceDriver};
use crate::geometry::{Obb, Pose};
use crate::metrics::{EpisodeMetrics, MetricsAccumulator, RewardInputs, RewardWeights, StepSample, step_reward};
use crate::risk::{
    EgoKinematics, FieldObject, RiskAccumulator, RiskFieldParams, RiskStep, RiskTerms, RiskWeights, ScoreReferences,
    VehicleState,
};
use crate::rng::Rng;
use crate::road::Lane;
use crate::sensor::{PerceivedObject, SceneObject, Sensor, SensorParams};
use crate::vehicle::{ModelKind, Vehicle, VehicleParams};
use crate::world::Contacts;

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

/// Re-runs `scenario` at `step_s` from the ego's first to its last recorded state. The run stops
/// at the first collision when the reference driver drives (as a twin episode does); a replay
/// runs to the end, so its min distance covers the whole recording. Offroad means the ego's
/// centre is in no lanelet: recorded vehicles' corners overhang the lanelet bounds routinely,
/// so the twin's corner test would flag the recording itself.
pub fn resimulate(
    scenario: &Scenario,
    ego_id: Option<u64>,
    mode: EgoMode,
    step_s: f64,
) -> Result<Resimulation, TwinError> {
    if !(step_s > 0.0 && step_s.is_finite()) {
        return Err(TwinError::BadStep { step_s });
    }
    let scene = TwinScene::new(scenario, ego_id)?;
    let (start_s, end_s) = (scene.ego.start_s(), scene.ego.end_s());
    let first = scene.ego.recorded()[0];
    let route = ego_route(&scene);
    let desired_speed_mps = scene.ego.recorded().iter().map(|s| s.speed_mps).fold(1.0, f64::max);
    let mut params = VehicleParams::bmw_320i();
    params.length_m = scene.ego.footprint.length_m;
    params.width_m = scene.ego.footprint.width_m;
    let mut vehicle = Vehicle::new(params, ModelKind::SingleTrack, first.pose, first.speed_mps);
    let mut driver = ReferenceDriver::new(desired_speed_mps, params);
    let mut sensor =
        Sensor::new(SensorParams::default()).expect("the default sensor parameters are valid (sensor module tests)");
    let mut rng = Rng::derive(0, 0x5E45);

    let field = RiskFieldParams::default();
    let weights = RewardWeights::default();
    let mut metrics = MetricsAccumulator::default();
    let mut risk = RiskAccumulator::new(RiskWeights::default(), ScoreReferences::default());
    let (mut objects, mut perceived, mut field_objects, mut others) =
        (Vec::<SceneObject>::new(), Vec::<PerceivedObject>::new(), Vec::new(), Vec::new());

    let ego_now = |vehicle: &Vehicle, t: f64| -> EgoNow {
        match mode {
            EgoMode::Replay => {
                let s: PlaybackState = scene.ego.at(t).unwrap_or(first);
                EgoNow { pose: s.pose, speed_mps: s.speed_mps, accel_mps2: s.accel_mps2, steer_rad: 0.0, lat_mps2: 0.0 }
            }
            EgoMode::ReferenceDriver => EgoNow {
                pose: vehicle.pose(),
                speed_mps: vehicle.state.speed_mps,
                accel_mps2: vehicle.state.accel_mps2,
                steer_rad: vehicle.state.steer_rad,
                lat_mps2: vehicle.lateral_accel_mps2(),
            },
        }
    };
    let footprint = scene.ego.footprint;
    scene.objects_at(start_s, &mut objects);
    let e0 = ego_now(&vehicle, start_s);
    let c0 = Contacts::detect(&Obb::new(e0.pose, footprint), &objects, &scene.road);
    let mut trace = vec![ResimSample {
        time_s: start_s,
        ego: Obb::new(e0.pose, footprint),
        speed_mps: e0.speed_mps,
        min_distance_m: c0.min_distance_m,
        collision: c0.collision,
        offroad: scenario.lanelets.containing(e0.pose.position()).next().is_none(),
    }];
    let n_steps = ((end_s - start_s) / step_s + 1e-9).floor() as usize;
    let (mut collision, mut offroad) = (false, false);
    let mut progress_prev = route.project(e0.pose.position()).s_m;
    for k in 1..=n_steps {
        let t_prev = start_s + (k - 1) as f64 * step_s;
        let t = start_s + k as f64 * step_s;
        if mode == EgoMode::ReferenceDriver {
            scene.objects_at(t_prev, &mut objects);
            let pose = vehicle.pose();
            sensor.perceive(pose, &objects, &mut rng, &mut perceived);
            let view = DriverView {
                road: &scene.road,
                time_s: t_prev - start_s,
                ego_pose: pose,
                ego_speed_mps: vehicle.state.speed_mps,
                ego_accel_mps2: vehicle.state.accel_mps2,
                ego_footprint: footprint,
                perceived: &perceived,
            };
            let controls = driver.act(&view);
            let mu = scene.road.friction_at(pose.position());
            vehicle.step(controls, mu, step_s);
        }
        let e = ego_now(&vehicle, t);
        let obb = Obb::new(e.pose, footprint);
        scene.objects_at(t, &mut objects);
        let contacts = Contacts::detect(&obb, &objects, &scene.road);
        let off = scenario.lanelets.containing(e.pose.position()).next().is_none();
        collision |= contacts.collision;
        offroad |= off;
        trace.push(ResimSample {
            time_s: t,
            ego: obb,
            speed_mps: e.speed_mps,
            min_distance_m: contacts.min_distance_m,
            collision: contacts.collision,
            offroad: off,
        });
        let jerk = metrics.jerk_of(e.accel_mps2, step_s);
        field_objects.clear();
        field_objects.extend(objects.iter().map(|o| FieldObject { obb: o.obb, velocity: o.velocity }));
        let kin = EgoKinematics {
            pose: e.pose,
            velocity: e.pose.forward() * e.speed_mps,
            lateral_accel_mps2: e.lat_mps2,
            jerk_mps3: jerk,
            footprint,
        };
        let ego_risk = field.evaluate_footprint(&scene.road, &field_objects, &kin);
        let lane_pos = scene.road.locate_heading(e.pose.position(), e.pose.heading_rad);
        let progress = route.project(e.pose.position()).s_m;
        let reward = step_reward(
            &weights,
            &RewardInputs {
                progress_m: progress - progress_prev,
                desired_speed_mps,
                speed_mps: e.speed_mps,
                dt_s: step_s,
                risk: ego_risk,
                lane_offset_m: lane_pos.frenet.e_y_m,
                jerk_mps3: jerk,
                collision: contacts.collision,
                offroad: off,
            },
        );
        progress_prev = progress;
        metrics.observe(StepSample {
            dt_s: step_s,
            speed_mps: e.speed_mps,
            steer_rad: e.steer_rad,
            accel_mps2: e.accel_mps2,
            reward,
        });
        scene.critical_states_at(t, &mut others);
        risk.push(
            &scene.road,
            &RiskStep {
                ego: VehicleState { obb, velocity: kin.velocity, accel: obb.axis * e.accel_mps2 },
                lane_offset_m: lane_pos.frenet.e_y_m,
                lane_width_m: scene.road.lane(lane_pos.lane).width_m,
                jerk_mps3: jerk,
                others: &others,
                collision: contacts.collision,
                offroad: off,
            },
        );
        if mode == EgoMode::ReferenceDriver && collision {
            break;
        }
    }
    let last = trace.last().map_or(e0.pose, |s| Pose::new(s.ego.centre.x, s.ego.centre.y, 0.0));
    let completion = if route.length_m() > 0.0 { route.project(last.position()).s_m / route.length_m() } else { 1.0 };
    let mut m = metrics.finish(completion, collision, offroad);
    let (terms, summary) = risk.finish();
    m.min_ttc_s = summary.min_ttc_s;
    m.min_distance_m = summary.min_distance_m;
    m.risk_score = terms.score;
    Ok(Resimulation { metrics: m, risk: terms, trace, start_s, end_s })
}

/// The ego's state as the measures need it, whoever drives.
struct EgoNow {
    pose: Pose,
    speed_mps: f64,
    accel_mps2: f64,
    steer_rad: f64,
    lat_mps2: f64,
}

/// The recorded ego path as a lane (the route whose completion is measured); a standing ego
/// gets a 1 m stub along its heading.
fn ego_route(scene: &TwinScene) -> Lane {
    let mut pts: Vec<crate::geometry::Vec2> = Vec::new();
    for s in scene.ego.recorded() {
        let p = s.pose.position();
        if pts.last().is_none_or(|q| (p - q).norm() > 0.05) {
            pts.push(p);
        }
    }
    if pts.len() < 2 {
        let s = scene.ego.recorded()[0].pose;
        pts = vec![s.position(), s.position() + s.forward()];
    }
    Lane::new(pts, 3.5, 36.0)
}
