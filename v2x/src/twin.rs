//! How stale a twin is that knows the vehicles only from their CAMs: every vehicle's CAMs
//! ([`super::cam`]) cross the channel to one receiver — the RSU, which hands them to the cloud
//! twin — and the twin moves each vehicle on from its newest CAM at constant velocity. Against
//! the ground truth, each step: the position error of every vehicle it knows, the error of the
//! risk the ego sees (the field at its footprint, from the twin's vehicles against the true
//! ones), and when the twin first sees a critical event (a time to collision below
//! [`CRITICAL_TTC_S`] between the ego and a vehicle in its lane) against when it happened.
//! Pedestrians send no CAMs and are left out of both sides.

use super::cam::{CamState, CamTrigger};
use super::link::V2xChannel;
use super::loss::BurstState;
use risktwin_common::geometry::{Obb, Pose, Vec2};
use risktwin_common::histogram::Histogram;
use risktwin_common::risk::{EgoKinematics, EgoLaneFrame, FieldObject, RiskFieldParams, VehicleState};
use risktwin_common::rng::Rng;
use risktwin_common::world::World;
use serde::Serialize;

/// A time to collision below this is a critical event, s (the lower end of the 1.5–3 s range
/// used for warnings; Vogel 2003, "A comparison of headway and time to collision").
pub const CRITICAL_TTC_S: f64 = 2.0;

/// What the twin's staleness cost over an episode.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TwinSummary {
    /// Vehicle-steps at which the twin knew the vehicle, and its mean and 95th-percentile
    /// position error there, m.
    pub position_samples: u64,
    pub position_error_mean_m: Option<f64>,
    pub position_error_p95_m: Option<f64>,
    /// Mean absolute error of the risk at the ego's footprint, over the steps at which the twin
    /// knew the ego.
    pub risk_error_mean: Option<f64>,
    /// When a critical event happened, and when the twin first saw one, s.
    pub critical_true_s: Option<f64>,
    pub critical_seen_s: Option<f64>,
}

impl TwinSummary {
    /// How much later than the truth the twin saw the episode's first critical event, s;
    /// `None` when there was none or the twin never saw it.
    pub fn critical_lag_s(&self) -> Option<f64> {
        Some(self.critical_seen_s? - self.critical_true_s?)
    }
}

/// The twin's view of `n` vehicles (the ego first) through a receiver at `receiver`.
pub struct TwinLag {
    channel: V2xChannel,
    receiver: Vec2,
    triggers: Vec<CamTrigger>,
    bursts: Vec<BurstState>,
    /// CAMs on their way: (arrives, vehicle, state).
    in_flight: Vec<(f64, usize, CamState)>,
    newest: Vec<Option<CamState>>,
    rng: Rng,
    field: RiskFieldParams,
    /// Position errors, µm (the histogram's unit is 1e-6 of the quantity).
    position_um: Histogram,
    position_sum_m: f64,
    risk_sum: f64,
    risk_samples: u64,
    critical_true_s: Option<f64>,
    critical_seen_s: Option<f64>,
    true_objects: Vec<FieldObject>,
    twin_objects: Vec<FieldObject>,
    true_states: Vec<VehicleState>,
    twin_states: Vec<VehicleState>,
}

/// Where a CAM's vehicle is `now_s`, moved on at its speed along its heading.
fn moved_on(cam: &CamState, now_s: f64) -> (Pose, Vec2) {
    let velocity = Vec2::new(cam.heading_rad.cos(), cam.heading_rad.sin()) * cam.speed_mps;
    let at = Vec2::new(cam.x_m, cam.y_m) + velocity * (now_s - cam.time_s);
    (Pose::new(at.x, at.y, cam.heading_rad), velocity)
}

impl TwinLag {
    pub fn new(channel: V2xChannel, receiver: Vec2, vehicles: usize, seed: u64) -> TwinLag {
        TwinLag {
            channel,
            receiver,
            triggers: vec![CamTrigger::default(); vehicles],
            bursts: vec![BurstState::default(); vehicles],
            in_flight: Vec::new(),
            newest: vec![None; vehicles],
            rng: Rng::new(seed),
            field: RiskFieldParams::default(),
            position_um: Histogram::default(),
            position_sum_m: 0.0,
            risk_sum: 0.0,
            risk_samples: 0,
            critical_true_s: None,
            critical_seen_s: None,
            true_objects: Vec::new(),
            twin_objects: Vec::new(),
            true_states: Vec::new(),
            twin_states: Vec::new(),
        }
    }

    /// One step of `world`, whose vehicles' CAM states (the ego, then its traffic in index order;
    /// `None` off the road) are `states`.
    pub fn step(&mut self, world: &World, states: &[Option<CamState>]) {
        let now_s = world.time_s;
        for (i, state) in states.iter().enumerate() {
            let Some(state) = state else { continue };
            if self.triggers[i].check(*state).is_none() {
                continue;
            }
            let latency_ms = self.channel.latency_ms(&mut self.rng);
            let distance_m = (Vec2::new(state.x_m, state.y_m) - self.receiver).norm();
            if self.channel.receives(distance_m, &mut self.bursts[i], &mut self.rng) {
                self.in_flight.push((now_s + latency_ms / 1e3, i, *state));
            }
        }
        let newest = &mut self.newest;
        self.in_flight.retain(|&(arrives_s, i, cam)| {
            let arrived = arrives_s <= now_s + 1e-9;
            if arrived && newest[i].is_none_or(|n| n.time_s < cam.time_s) {
                newest[i] = Some(cam);
            }
            !arrived
        });
        self.measure(world, states);
    }

    fn measure(&mut self, world: &World, states: &[Option<CamState>]) {
        let now_s = world.time_s;
        let ego_obb = world.ego.obb();
        let footprint = world.ego.params.footprint();
        let truth_ego = VehicleState { obb: ego_obb, velocity: world.ego.velocity(), accel: Vec2::zeros() };
        let twin_ego = self.newest[0].map(|cam| {
            let (pose, velocity) = moved_on(&cam, now_s);
            VehicleState { obb: Obb::new(pose, footprint), velocity, accel: Vec2::zeros() }
        });
        self.true_objects.clear();
        self.twin_objects.clear();
        self.true_states.clear();
        self.twin_states.clear();
        for (i, state) in states.iter().enumerate() {
            let (Some(_), Some(cam)) = (state, self.newest[i]) else { continue };
            let truth = if i == 0 { ego_obb } else { world.traffic.obb(i - 1) };
            let (pose, velocity) = moved_on(&cam, now_s);
            let error_m = (pose.position() - truth.centre).norm();
            self.position_um.record((error_m * 1e6).round() as u64);
            self.position_sum_m += error_m;
            if i > 0 {
                let obb = Obb {
                    centre: pose.position(),
                    axis: Vec2::new(pose.heading_rad.cos(), pose.heading_rad.sin()),
                    ..truth
                };
                self.twin_objects.push(FieldObject { obb, velocity });
                self.twin_states.push(VehicleState { obb, velocity, accel: Vec2::zeros() });
            }
        }
        for (i, state) in states.iter().enumerate().skip(1) {
            if state.is_some() {
                let (obb, velocity) = (world.traffic.obb(i - 1), world.traffic.velocity(i - 1));
                self.true_objects.push(FieldObject { obb, velocity });
                self.true_states.push(VehicleState { obb, velocity, accel: Vec2::zeros() });
            }
        }
        let road = &world.road;
        if self.critical_true_s.is_none() && critical(road, &truth_ego, &self.true_states) {
            self.critical_true_s = Some(now_s);
        }
        let Some(twin_ego) = twin_ego else { return };
        // Only a detection at or after the event is its sighting: a stale twin that still moves
        // a braking ego at its old speed may see a critical pair before there is one.
        if self.critical_seen_s.is_none()
            && self.critical_true_s.is_some()
            && critical(road, &twin_ego, &self.twin_states)
        {
            self.critical_seen_s = Some(now_s);
        }
        let kinematics = |s: &VehicleState| EgoKinematics {
            pose: Pose::new(s.obb.centre.x, s.obb.centre.y, s.obb.axis.y.atan2(s.obb.axis.x)),
            velocity: s.velocity,
            lateral_accel_mps2: 0.0,
            jerk_mps3: 0.0,
            footprint,
        };
        let risk_true = self.field.evaluate_footprint(road, &self.true_objects, &kinematics(&truth_ego));
        let risk_twin = self.field.evaluate_footprint(road, &self.twin_objects, &kinematics(&twin_ego));
        self.risk_sum += (risk_twin - risk_true).abs();
        self.risk_samples += 1;
    }

    pub fn summary(&self) -> TwinSummary {
        let n = self.position_um.count();
        TwinSummary {
            position_samples: n,
            position_error_mean_m: (n > 0).then(|| self.position_sum_m / n as f64),
            position_error_p95_m: self.position_um.quantile(0.95).map(|um| um / 1e6),
            risk_error_mean: (self.risk_samples > 0).then(|| self.risk_sum / self.risk_samples as f64),
            critical_true_s: self.critical_true_s,
            critical_seen_s: self.critical_seen_s,
        }
    }
}

/// Whether the ego is on a collision course with a vehicle in its lane within [`CRITICAL_TTC_S`].
fn critical(road: &risktwin_common::road::Road, ego: &VehicleState, others: &[VehicleState]) -> bool {
    let frame = EgoLaneFrame::new(road, ego);
    others.iter().any(|o| frame.measure(road, o).ttc_s < CRITICAL_TTC_S)
}
