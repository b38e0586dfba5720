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
use crate::traffic::{IdmParams, idm_accel};
use crate::vehicle::actuator::drive_limit_mps2;
use crate::vehicle::{Controls, VehicleParams};

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
}

/// Anything that drives the ego: the reference driver now, learned policies later.
pub trait Policy {
    fn act(&mut self, view: &DriverView) -> Controls;
}

/// The nearest perceived object in a lane ahead of the ego.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Leader {
    gap_m: f64,
    speed_mps: f64,
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
    /// Advantage in IDM acceleration a lane change must bring (MOBIL's Δa_th), m/s².
    pub lane_change_threshold_mps2: f64,
    target_lane: Option<LaneId>,
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
            lane_change_threshold_mps2: 0.3,
            target_lane: None,
            last_change_s: f64::NEG_INFINITY,
        }
    }

    /// The nearest object whose footprint is in `lane`'s strip (now or, moving by constant
    /// velocity, within the crossing horizon) and ahead of `s_ego`.
    fn leader(&self, road: &Road, lane: LaneId, s_ego: f64, ego_half_len: f64, objects: &[PerceivedObject]) -> Option<Leader> {
        let l = road.lane(lane);
        let half_w = 0.5 * l.width_m;
        let mut best: Option<Leader> = None;
        for o in objects {
            let f = l.project(o.obb.centre);
            let dir = Vec2::new(f.lane_heading_rad.cos(), f.lane_heading_rad.sin());
            let along = o.obb.axis.dot(&dir).abs();
            let across = (1.0 - along * along).max(0.0).sqrt();
            let half_len = o.obb.half_length_m * along + o.obb.half_width_m * across;
            let half_wid = o.obb.half_length_m * across + o.obb.half_width_m * along;
            let gap = f.s_m - half_len - s_ego - ego_half_len;
            if gap < -ego_half_len || f.s_m < s_ego {
                continue;
            }
            let v_lat = o.velocity.dot(&Vec2::new(-dir.y, dir.x));
            let (e0, e1) = (f.e_y_m, f.e_y_m + v_lat * self.crossing_horizon_s);
            let (lo, hi) = (e0.min(e1) - half_wid, e0.max(e1) + half_wid);
            if hi < -half_w || lo > half_w {
                continue;
            }
            if best.is_none_or(|b| gap < b.gap_m) {
                best = Some(Leader { gap_m: gap.max(0.0), speed_mps: o.velocity.dot(&dir) });
            }
        }
        best
    }

    fn accel_behind(&self, v: f64, v0: f64, leader: Option<Leader>) -> f64 {
        let p = IdmParams { desired_speed_mps: v0, ..self.idm };
        match leader {
            Some(l) => idm_accel(&p, v, l.gap_m, v - l.speed_mps),
            None => idm_accel(&p, v, f64::INFINITY, 0.0),
        }
    }

    /// Desired speed lowered for the sharpest bend within the braking preview.
    fn bend_speed(&self, road: &Road, lane: LaneId, s: f64, v: f64) -> f64 {
        let l = road.lane(lane);
        let preview_m = 10.0 + 3.0 * v;
        let mut kappa: f64 = 0.0;
        let mut d = 0.0;
        while d <= preview_m {
            kappa = kappa.max(l.curvature_at(s + d).abs());
            d += 5.0;
        }
        if kappa > 1e-6 { self.idm.desired_speed_mps.min((self.comfort_lat_accel_mps2 / kappa).sqrt()) } else { self.idm.desired_speed_mps }
    }

    fn maybe_change_lane(&mut self, view: &DriverView, lane: LaneId, v: f64, v0: f64, a_here: f64) -> LaneId {
        if view.time_s - self.last_change_s < 4.0 {
            return lane;
        }
        let half_len = 0.5 * view.ego_footprint.length_m;
        let l = view.road.lane(lane);
        let mut best = (a_here + self.lane_change_threshold_mps2, lane);
        for cand in [l.left, l.right].into_iter().flatten() {
            let cl = view.road.lane(cand);
            let s_c = cl.project(view.ego_pose.position()).s_m;
            // Safety: nothing perceived alongside or just behind in the target lane.
            let blocked = view.perceived.iter().any(|o| {
                let f = cl.project(o.obb.centre);
                f.e_y_m.abs() < 0.5 * cl.width_m + o.obb.half_width_m && (f.s_m - s_c).abs() < half_len + o.obb.half_length_m + 3.0
            });
            if blocked {
                continue;
            }
            let a_new = self.accel_behind(v, v0, self.leader(view.road, cand, s_c, half_len, view.perceived));
            if a_new > best.0 {
                best = (a_new, cand);
            }
        }
        if best.1 != lane {
            self.last_change_s = view.time_s;
        }
        best.1
    }
}

impl Policy for ReferenceDriver {
    fn act(&mut self, view: &DriverView) -> Controls {
        let road = view.road;
        let pos = view.ego_pose.position();
        let lane = self.target_lane.unwrap_or_else(|| road.locate_heading(pos, view.ego_pose.heading_rad).lane);
        let s = road.lane(lane).project(pos).s_m;
        let v = view.ego_speed_mps.max(0.0);
        let half_len = 0.5 * view.ego_footprint.length_m;
        let v0 = self.bend_speed(road, lane, s, v);
        let a_here = self.accel_behind(v, v0, self.leader(road, lane, s, half_len, view.perceived));
        let lane = self.maybe_change_lane(view, lane, v, v0, a_here);
        self.target_lane = Some(lane);
        // While changing lanes, the old lane's leader still bounds the speed.
        let accel = a_here;

        // Pure pursuit on the target lane centreline (Coulter 1992), look-ahead growing with speed.
        let l = road.lane(lane);
        let s_t = l.project(pos).s_m;
        let look_m = (1.0 * v).max(6.0);
        let target = l.pose_at(s_t + look_m, 0.0).position();
        let to = target - pos;
        let alpha = wrap_angle(to.y.atan2(to.x) - view.ego_pose.heading_rad);
        let steer_rad = (2.0 * self.vehicle.wheelbase_m() * alpha.sin() / to.norm().max(1e-3)).atan();

        let (throttle, brake) = if accel >= 0.0 {
            ((accel / drive_limit_mps2(&self.vehicle, v)).min(1.0), 0.0)
        } else {
            (0.0, (-accel / self.vehicle.brake_decel_max_mps2).min(1.0))
        };
        Controls { steer_rad, throttle, brake }
    }
}
