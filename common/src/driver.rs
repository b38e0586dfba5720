//! Policies that drive the ego, and the reference driver: IDM car following and MOBIL-style
//! lane changes acting only on what the ego's sensor perceives, with pure-pursuit steering.
//!
//! The reference driver is the yardstick every scenario is scored with. It is a competent but
//! ordinary driver: it assumes dry-road comfort limits (it does not know μ), it reacts to what
//! it sees (occluded or dropped objects do not exist for it), and it predicts crossing objects
//! only by constant velocity.

use crate::geometry::{Footprint, Pose, Vec2, wrap_angle};
use crate::road::{LaneId, Road};
use crate::sensor::PerceivedObject;
use crate::traffic::{IdmParams, MobilParams, idm_accel};
use crate::vehicle::actuator::drive_limit_mps2;
use crate::vehicle::{Controls, VehicleParams};

/// The reference driver's name: its `--driver` SPEC and the label its outcomes are stored under.
pub const REFERENCE_LABEL: &str = "idm";
/// A recording's ego played back as it drove: its SPEC and outcome label.
pub const REPLAY_LABEL: &str = "replay";

/// What a policy sees each step.
#[derive(Debug, Clone, Copy)]
pub struct DriverView<'a> {
    pub road: &'a Road,
    pub time_s: f64,
    pub ego_pose: Pose,
    pub ego_speed_mps: f64,
    pub ego_accel_mps2: f64,
    pub ego_footprint: Footprint,
    pub perceived: &'a [PerceivedObject],
    /// Hazards the ego knows of only from warnings heard over V2X, moved on to now (empty
    /// without V2X; `v2x::warning`).
    pub warned: &'a [PerceivedObject],
}

/// Anything that drives the ego: the reference driver now, learned policies later.
pub trait Policy {
    fn act(&mut self, view: &DriverView) -> Controls;
}

/// How far ahead a driver at `speed_mps` looks for bends: 10 m + 3 s of travel.
pub fn braking_preview_m(speed_mps: f64) -> f64 {
    10.0 + 3.0 * speed_mps.max(0.0)
}

/// The nearest perceived object in a lane ahead of (or behind) the ego.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Neighbour {
    /// Bumper-to-bumper gap along the lane, m (≥ 0).
    gap_m: f64,
    /// Speed along the lane, m/s.
    speed_mps: f64,
}

/// The nearest objects ahead and behind in one lane, and whether one is alongside.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct LaneNeighbours {
    leader: Option<Neighbour>,
    follower: Option<Neighbour>,
    alongside: bool,
}

/// IDM + lane changes + pure pursuit, on perceived objects only.
#[derive(Debug, Clone)]
pub struct ReferenceDriver {
    pub idm: IdmParams,
    pub vehicle: VehicleParams,
    /// Lateral acceleration the driver accepts in bends (dry-road comfort, not μ-aware), m/s².
    pub comfort_lat_accel_mps2: f64,
    /// Horizon over which a crossing object's constant-velocity path is checked against the lane.
    pub crossing_horizon_s: f64,
    /// Lateral speed below which an object is taken to hold its lane (≈ 3σ of velocity noise).
    pub min_crossing_speed_mps: f64,
    /// Lane-change threshold and safe deceleration (MOBIL's Δa_th and b_safe).
    pub mobil: MobilParams,
    target_lane: Option<LaneId>,
    /// The lane being left while the ego's footprint still overlaps it.
    leaving_lane: Option<LaneId>,
    /// How long an object stays known after it was last perceived, s.
    pub track_memory_s: f64,
    /// Brake/throttle reaction time: a longitudinal decision takes effect this much later
    /// (expected-event brake reaction ≈ 0.75 s, Green 2000, "How long does it take to stop?").
    pub reaction_time_s: f64,
    /// Longitudinal decisions not yet in effect: (time decided, acceleration).
    pending_accel: std::collections::VecDeque<(f64, f64)>,
    /// Objects perceived recently: (last time seen, what was seen).
    tracks: Vec<(f64, PerceivedObject)>,
    /// The tracks predicted to now: what the driver believes is around it.
    known: Vec<PerceivedObject>,
    last_change_s: f64,
}

impl ReferenceDriver {
    /// A driver who wants to go at `desired_speed_mps`.
    pub fn new(desired_speed_mps: f64, vehicle: VehicleParams) -> Self {
        Self {
            idm: IdmParams { desired_speed_mps, ..IdmParams::default() },
            vehicle,
            comfort_lat_accel_mps2: 3.0,
            crossing_horizon_s: 1.5,
            min_crossing_speed_mps: 0.8,
            mobil: MobilParams { threshold_mps2: 0.3, ..MobilParams::default() },
            target_lane: None,
            leaving_lane: None,
            track_memory_s: 1.0,
            reaction_time_s: 0.75,
            pending_accel: std::collections::VecDeque::new(),
            tracks: Vec::new(),
            known: Vec::new(),
            last_change_s: f64::NEG_INFINITY,
        }
    }

    /// Objects whose footprint is in `lane`'s strip — now or, moving at constant velocity,
    /// within the crossing horizon (so a pedestrian stepping out counts before it arrives).
    fn neighbours(
        &self,
        road: &Road,
        lane: LaneId,
        s_ego: f64,
        ego_half_len: f64,
        objects: &[PerceivedObject],
    ) -> LaneNeighbours {
        let l = road.lane(lane);
        let half_w = 0.5 * l.width_m;
        let mut out = LaneNeighbours::default();
        for o in objects {
            let f = l.project(o.obb.centre);
            let dir = Vec2::new(f.lane_heading_rad.cos(), f.lane_heading_rad.sin());
            let along = o.obb.axis.dot(&dir).abs();
            let across = (1.0 - along * along).max(0.0).sqrt();
            let half_len = o.obb.half_length_m * along + o.obb.half_width_m * across;
            let half_wid = o.obb.half_length_m * across + o.obb.half_width_m * along;
            // Predict crossing only for a lateral speed well above the sensor's velocity noise,
            // so a neighbour holding its lane does not cause phantom braking.
            let v_lat = o.velocity.dot(&Vec2::new(-dir.y, dir.x));
            let v_lat = if v_lat.abs() > self.min_crossing_speed_mps { v_lat } else { 0.0 };
            let (e0, e1) = (f.e_y_m, f.e_y_m + v_lat * self.crossing_horizon_s);
            if e0.max(e1) + half_wid < -half_w || e0.min(e1) - half_wid > half_w {
                continue;
            }
            let n = |gap_m: f64| Some(Neighbour { gap_m: gap_m.max(0.0), speed_mps: o.velocity.dot(&dir) });
            let ahead_gap = f.s_m - half_len - s_ego - ego_half_len;
            let behind_gap = s_ego - ego_half_len - f.s_m - half_len;
            if ahead_gap < 0.0 && behind_gap < 0.0 {
                out.alongside = true;
            } else if f.s_m >= s_ego {
                if out.leader.is_none_or(|b| ahead_gap < b.gap_m) {
                    out.leader = n(ahead_gap);
                }
            } else if out.follower.is_none_or(|b| behind_gap < b.gap_m) {
                out.follower = n(behind_gap);
            }
        }
        out
    }

    fn accel_behind(&self, v: f64, v0: f64, leader: Option<Neighbour>) -> f64 {
        let p = IdmParams { desired_speed_mps: v0, ..self.idm };
        match leader {
            Some(l) => idm_accel(&p, v, l.gap_m, v - l.speed_mps),
            None => idm_accel(&p, v, f64::INFINITY, 0.0),
        }
    }

    /// Desired speed lowered for the sharpest bend within the braking preview.
    fn bend_speed(&self, road: &Road, lane: LaneId, s: f64, v: f64) -> f64 {
        let kappa = road.lane(lane).sharpest_curvature_ahead(s, braking_preview_m(v)).abs();
        if kappa > 1e-6 {
            self.idm.desired_speed_mps.min((self.comfort_lat_accel_mps2 / kappa).sqrt())
        } else {
            self.idm.desired_speed_mps
        }
    }

    /// MOBIL (Kesting, Treiber & Helbing 2007) on perceived objects: change when the own
    /// advantage exceeds the threshold and neither the ego (during the move) nor the new
    /// follower would have to brake harder than b_safe. Politeness is 0 here: the followers' gains are unknown to a
    /// driver that only sees positions and speeds. At most one change per four seconds.
    fn maybe_change_lane(
        &mut self,
        view: &DriverView,
        known: &[PerceivedObject],
        lane: LaneId,
        v: f64,
        v0: f64,
        a_here: f64,
    ) -> LaneId {
        if view.time_s - self.last_change_s < 4.0 {
            return lane;
        }
        let half_len = 0.5 * view.ego_footprint.length_m;
        let b_safe = self.mobil.safe_decel_mps2;
        let l = view.road.lane(lane);
        let mut best = (a_here + self.mobil.threshold_mps2, lane);
        for cand in [l.left, l.right].into_iter().flatten() {
            let s_c = view.road.lane(cand).project(view.ego_pose.position()).s_m;
            let n = self.neighbours(view.road, cand, s_c, half_len, known);
            if n.alongside {
                continue;
            }
            let a_new = self.accel_behind(v, v0, n.leader);
            let follower_safe = n.follower.is_none_or(|f| {
                let idm = IdmParams { desired_speed_mps: f.speed_mps.max(v), ..self.idm };
                idm_accel(&idm, f.speed_mps, f.gap_m, f.speed_mps - v) >= -b_safe
            });
            // While changing, the old lane's leader still binds (see `decide`), so the ego's own
            // deceleration during the move is the worse of the two lanes'.
            if a_new.min(a_here) >= -b_safe && follower_safe && a_new > best.0 {
                best = (a_new, cand);
            }
        }
        if best.1 != lane {
            self.last_change_s = view.time_s;
        }
        best.1
    }
}

impl ReferenceDriver {
    /// Tracking in its simplest honest form: an object missed for a frame (dropout, a brief
    /// occlusion) is still there, moved on at its last velocity, until `track_memory_s` passes.
    fn update_tracks(&mut self, view: &DriverView) {
        let now = view.time_s;
        for o in view.perceived {
            match self.tracks.iter_mut().find(|(_, t)| t.id == o.id) {
                Some(entry) => *entry = (now, *o),
                None => self.tracks.push((now, *o)),
            }
        }
        let memory = self.track_memory_s;
        self.tracks.retain(|(seen, _)| now - seen <= memory);
        self.known.clear();
        self.known.extend(self.tracks.iter().map(|(seen, o)| {
            let mut o = *o;
            o.obb.centre += o.velocity * (now - seen);
            o
        }));
    }
}

impl ReferenceDriver {
    /// The longitudinal decision that is in effect now: the latest one at least the reaction
    /// time old (0, i.e. holding speed, before the first one matures).
    fn react(&mut self, now_s: f64, decided_mps2: f64) -> f64 {
        self.pending_accel.push_back((now_s, decided_mps2));
        let due = now_s - self.reaction_time_s + 1e-9;
        while self.pending_accel.len() > 1 && self.pending_accel[1].0 <= due {
            self.pending_accel.pop_front();
        }
        match self.pending_accel.front() {
            Some(&(t, a)) if t <= due => a,
            _ => 0.0,
        }
    }
}

impl Policy for ReferenceDriver {
    fn act(&mut self, view: &DriverView) -> Controls {
        self.update_tracks(view);
        let known = std::mem::take(&mut self.known);
        let controls = self.decide(view, &known);
        self.known = known;
        controls
    }
}

impl ReferenceDriver {
    fn decide(&mut self, view: &DriverView, known: &[PerceivedObject]) -> Controls {
        let road = view.road;
        let pos = view.ego_pose.position();
        let lane = self.target_lane.unwrap_or_else(|| road.locate_heading(pos, view.ego_pose.heading_rad).lane);
        let s = road.lane(lane).project(pos).s_m;
        let v = view.ego_speed_mps.max(0.0);
        let half_len = 0.5 * view.ego_footprint.length_m;
        let v0 = self.bend_speed(road, lane, s, v);
        let a_here = self.accel_behind(v, v0, self.neighbours(road, lane, s, half_len, known).leader);
        let new_lane = self.maybe_change_lane(view, known, lane, v, v0, a_here);
        if new_lane != lane {
            self.leaving_lane = Some(lane);
        }
        let lane = new_lane;
        self.target_lane = Some(lane);
        // Until the footprint has left the old lane, its leader still bounds the speed.
        let mut accel = a_here;
        if let Some(old) = self.leaving_lane {
            let ol = road.lane(old);
            let f = ol.project(pos);
            if f.e_y_m.abs() < 0.5 * (ol.width_m + view.ego_footprint.width_m) {
                let s_old = f.s_m;
                accel = accel.min(self.accel_behind(v, v0, self.neighbours(road, old, s_old, half_len, known).leader));
            } else {
                self.leaving_lane = None;
            }
        }
        // A hazard heard of over V2X binds on its own, even behind a nearer leader the driver
        // sees: the warning says it is there (the truck ahead may swerve around it).
        let hazard = if view.warned.is_empty() {
            None
        } else {
            let s_lane = road.lane(lane).project(pos).s_m;
            self.neighbours(road, lane, s_lane, half_len, view.warned).leader
        };
        if let Some(hazard) = hazard {
            accel = accel.min(self.accel_behind(v, v0, Some(hazard)));
        }
        let accel = self.react(view.time_s, accel);

        let steer_rad = pure_pursuit_steer_rad(road, lane, view.ego_pose, v, self.vehicle.wheelbase_m());
        controls_for_accel(&self.vehicle, v, steer_rad, accel)
    }
}

/// Pure pursuit on `lane`'s centreline (Coulter 1992), look-ahead growing with speed: the
/// front-wheel angle that steers a vehicle at `pose` onto it, rad.
pub fn pure_pursuit_steer_rad(road: &Road, lane: LaneId, pose: Pose, speed_mps: f64, wheelbase_m: f64) -> f64 {
    let l = road.lane(lane);
    let pos = pose.position();
    let s_t = l.project(pos).s_m;
    let look_m = (1.0 * speed_mps).max(6.0);
    let target = l.pose_at(s_t + look_m, 0.0).position();
    let to = target - pos;
    let alpha = wrap_angle(to.y.atan2(to.x) - pose.heading_rad);
    (2.0 * wheelbase_m * alpha.sin() / to.norm().max(1e-3)).atan()
}

/// The pedals that ask for `accel_mps2` at `speed_mps` (throttle against the drive limit, brake
/// against the maximum deceleration, each clamped to 1), with `steer_rad`.
pub fn controls_for_accel(vehicle: &VehicleParams, speed_mps: f64, steer_rad: f64, accel_mps2: f64) -> Controls {
    let (throttle, brake) = if accel_mps2 >= 0.0 {
        ((accel_mps2 / drive_limit_mps2(vehicle, speed_mps)).min(1.0), 0.0)
    } else {
        (0.0, (-accel_mps2 / vehicle.brake_decel_max_mps2).min(1.0))
    };
    Controls { steer_rad, throttle, brake }
}
