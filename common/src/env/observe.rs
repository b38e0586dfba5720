//! The observation s_t (docs/method.md §7) and the action mapping, computed only from what a
//! policy may know: a [`DriverView`] (the ego's own state and what its sensor perceives) and
//! the desired speed. The same code feeds training ([`super::DrivingEnv`]) and evaluation
//! through `episode::run` ([`super::ObsPolicy`]), so a policy sees identical inputs in both.
//!
//! Features, all `f32` and scaled to roughly [−1, 1] (scales are the `*_SCALE` constants):
//!
//! | index | feature | definition | scale |
//! |---|---|---|---|
//! | 0 | v | ego speed | / 20 m/s |
//! | 1 | a | ego longitudinal acceleration | / 5 m/s² |
//! | 2 | ψ | yaw rate ψ̇ (heading change over the last step; the world-frame ψ itself carries no information on roads of arbitrary orientation, its lane-relative part is e_ψ) | / 0.5 rad/s |
//! | 3 | e_y | lateral offset from the lane centre (+ left) | / (lane width / 2) |
//! | 4 | e_ψ | heading error to the lane tangent, wrapped | / 0.5 rad |
//! | 5 | d_f | gap to the nearest perceived object ahead in the ego lane, 1 when none | / 100 m, ≤ 1 |
//! | 6 | Δv_f | closing speed to that object (ego minus its along-lane speed), 0 when none | / 10 m/s |
//! | 7 | ρ_lane | α_l·R_l + α_b·R_b, maximum over the footprint | as is |
//! | 8 | ρ_obs | α_o·R_o over perceived objects, maximum over the footprint | as is |
//! | 9 | ρ_TTC | min(1, 2 s / TTC) to the front object at constant speeds, 0 when not closing | as is |
//! | 10 | v_ref | desired speed (extension: the reward's target) | / 20 m/s |
//! | 11 | κ | lane curvature at the ego (extension: bends) | × 25 m |
//! | 12 | κ_ahead | the sharpest lane curvature within the braking preview 10 m + 3 s·v ahead, signed (extension: what the reference driver slows for) | × 25 m |
//! | 13 | μ | road friction under the ego (extension: the twin's friction estimate) | as is |
//! | 14, 19 | lane_L, lane_R | 1 when a lane exists to the left / right, else 0 (extension: room to pass) | as is |
//! | 15, 20 | d_f | gap to the nearest perceived object ahead in that lane, 1 when none or no lane | / 100 m, ≤ 1 |
//! | 16, 21 | Δv_f | closing speed to it, 0 when none | / 10 m/s |
//! | 17, 22 | d_r | gap to the nearest perceived object behind in that lane, 1 when none or no lane | / 100 m, ≤ 1 |
//! | 18, 23 | Δv_r | its closing speed (its along-lane speed minus the ego's), 0 when none | / 10 m/s |
//!
//! "Perceived" objects are those the sensor sees and those a V2X warning reports
//! ([`DriverView::warned`]): the features do not tell the two apart, so the layout, and the
//! policy file's format, stayed the same when warnings came (docs/v2x.md).
//!
//! The side-lane features let a policy pass a stopped or slow car (the reference driver does
//! so with MOBIL); without them a lane change is blind.
//!
//! Actions are three numbers in [−1, 1]: steering δ = a₀·[`STEER_SCALE_RAD`] (a servo command,
//! rate-limited by the actuator), throttle = max(a₁, 0), brake = max(a₂, 0). A zero action is
//! "straight, coast"; both pedals at once give their sum, as on the vehicle.

use crate::driver::{DriverView, braking_preview_m};
use crate::geometry::{Vec2, wrap_angle};
use crate::risk::{EgoKinematics, FieldObject, RiskFieldParams, field::footprint_samples};
use crate::vehicle::Controls;

/// Version of the observation and action contract (docs/driver-interface.md): what feature
/// each index holds, its scale, and the action mapping; bumped when any of them changes.
pub const OBSERVATION_VERSION: u32 = 1;
/// Length of the observation vector.
pub const OBS_DIM: usize = 24;
/// Length of the action vector: steering, throttle, brake.
pub const ACT_DIM: usize = 3;
/// Steering angle at a₀ = ±1, rad: twice what the tightest bend (κ = 0.04 1/m) needs, and
/// small enough that exploration noise at highway speed does not throw the car off the road.
pub const STEER_SCALE_RAD: f64 = 0.25;
/// Speed scale of features 0 and 10, m/s.
pub const SPEED_SCALE_MPS: f64 = 20.0;
/// Acceleration scale, m/s².
pub const ACCEL_SCALE_MPS2: f64 = 5.0;
/// Yaw-rate scale, rad/s.
pub const YAW_RATE_SCALE_RADPS: f64 = 0.5;
/// Heading-error scale, rad.
pub const HEADING_SCALE_RAD: f64 = 0.5;
/// Front gap beyond which the front object does not matter, m.
pub const FRONT_RANGE_M: f64 = 100.0;
/// Closing-speed scale, m/s.
pub const CLOSING_SCALE_MPS: f64 = 10.0;
/// TTC at which ρ_TTC saturates at 1, s.
pub const TTC_REF_S: f64 = 2.0;
/// Curvature scale, m (κ × 25 m: 0.04 1/m → 1).
pub const CURVATURE_SCALE_M: f64 = 25.0;

/// Maps a policy action in [−1, 1]³ to actuator commands (NaN and range handled downstream by
/// `Controls::sanitized`).
pub fn action_to_controls(action: &[f32; ACT_DIM]) -> Controls {
    let a = action.map(|x| if x.is_finite() { f64::from(x).clamp(-1.0, 1.0) } else { 0.0 });
    Controls::new(a[0] * STEER_SCALE_RAD, a[1].max(0.0), a[2].max(0.0))
}

/// Builds observations; keeps the previous heading for the yaw-rate feature and a scratch
/// buffer for the perceived objects, so a step allocates nothing once warm.
#[derive(Debug, Clone)]
pub struct Observer {
    field: RiskFieldParams,
    prev_heading_rad: Option<f64>,
    objects: Vec<FieldObject>,
}

impl Default for Observer {
    fn default() -> Self {
        Self { field: RiskFieldParams::default(), prev_heading_rad: None, objects: Vec::with_capacity(32) }
    }
}

/// The nearest perceived objects ahead and behind in one lane: (gap, closing speed) each.
#[derive(Debug, Clone, Copy, Default)]
struct LaneGaps {
    front: Option<(f64, f64)>,
    rear: Option<(f64, f64)>,
}

impl LaneGaps {
    /// Scans the view's objects (perceived and warned of) in `lane` around the ego at arc length
    /// `s_ego_m`. An object overlapping the ego lengthwise counts as ahead (or behind) at gap 0.
    fn scan(view: &DriverView, lane: usize, s_ego_m: f64) -> Self {
        let l = view.road.lane(lane);
        let half_w = 0.5 * l.width_m;
        let ego_half_len = 0.5 * view.ego_footprint.length_m;
        let mut out = LaneGaps::default();
        for o in view.perceived.iter().chain(view.warned) {
            let f = l.project(o.obb.centre);
            if f.e_y_m.abs() - o.obb.half_width_m.min(o.obb.half_length_m) > half_w {
                continue;
            }
            let half_len = o.obb.half_length_m.max(o.obb.half_width_m);
            let along_mps = o.velocity.dot(&Vec2::new(f.lane_heading_rad.cos(), f.lane_heading_rad.sin()));
            if f.s_m >= s_ego_m {
                let gap_m = (f.s_m - half_len - s_ego_m - ego_half_len).max(0.0);
                if out.front.is_none_or(|b| gap_m < b.0) {
                    out.front = Some((gap_m, view.ego_speed_mps - along_mps));
                }
            } else {
                let gap_m = (s_ego_m - ego_half_len - f.s_m - half_len).max(0.0);
                if out.rear.is_none_or(|b| gap_m < b.0) {
                    out.rear = Some((gap_m, along_mps - view.ego_speed_mps));
                }
            }
        }
        out
    }
}

/// (gap, closing) as features: gap / range capped at 1 and 1 when none; closing / scale, 0 when none.
fn gap_features(g: Option<(f64, f64)>) -> (f64, f64) {
    g.map_or((1.0, 0.0), |(gap, closing)| ((gap / FRONT_RANGE_M).min(1.0), closing / CLOSING_SCALE_MPS))
}

/// Features 14–18 (or 19–23) for the lane beside the ego, if any (no lane: no room either way).
fn side_lane_features(view: &DriverView, side: Option<usize>) -> [f64; 5] {
    let Some(lane) = side else { return [0.0, 1.0, 0.0, 1.0, 0.0] };
    let s_m = view.road.lane(lane).project(view.ego_pose.position()).s_m;
    let gaps = LaneGaps::scan(view, lane, s_m);
    let (d_f, dv_f) = gap_features(gaps.front);
    let (d_r, dv_r) = gap_features(gaps.rear);
    [1.0, d_f, dv_f, d_r, dv_r]
}

impl Observer {
    /// Forgets the previous heading (call at episode start).
    pub fn reset(&mut self) {
        self.prev_heading_rad = None;
    }

    /// Writes s_t for `view` into `out` (see the module table).
    pub fn observe(&mut self, view: &DriverView, desired_speed_mps: f64, dt_s: f64, out: &mut [f32; OBS_DIM]) {
        let pose = view.ego_pose;
        let yaw_rate = self.prev_heading_rad.map_or(0.0, |h| wrap_angle(pose.heading_rad - h) / dt_s);
        self.prev_heading_rad = Some(pose.heading_rad);
        let at = view.road.locate_heading(pose.position(), pose.heading_rad);
        let lane = view.road.lane(at.lane);
        let e_psi = wrap_angle(pose.heading_rad - at.frenet.lane_heading_rad);
        let front = LaneGaps::scan(view, at.lane, at.frenet.s_m).front;
        let (d_f, dv_f) = gap_features(front);
        let rho_ttc = front.map_or(0.0, |(gap, closing)| {
            let ttc = if closing > 1e-6 { gap / closing } else { f64::INFINITY };
            (TTC_REF_S / ttc).min(1.0)
        });
        self.objects.clear();
        let objects = view.perceived.iter().chain(view.warned);
        self.objects.extend(objects.map(|o| FieldObject { obb: o.obb, velocity: o.velocity }));
        let ego = EgoKinematics {
            pose,
            velocity: Vec2::new(pose.heading_rad.cos(), pose.heading_rad.sin()) * view.ego_speed_mps,
            lateral_accel_mps2: 0.0,
            jerk_mps3: 0.0,
            footprint: view.ego_footprint,
        };
        let (mut rho_lane, mut rho_obs) = (0.0f64, 0.0f64);
        for p in footprint_samples(&ego.obb()) {
            rho_lane = rho_lane.max(self.field.static_terms(view.road, p));
            rho_obs = rho_obs.max(self.field.alpha_obstacle * self.field.obstacle_term(&self.objects, &ego, p));
        }
        let features = [
            view.ego_speed_mps / SPEED_SCALE_MPS,
            view.ego_accel_mps2 / ACCEL_SCALE_MPS2,
            yaw_rate / YAW_RATE_SCALE_RADPS,
            at.frenet.e_y_m / (0.5 * lane.width_m).max(0.1),
            e_psi / HEADING_SCALE_RAD,
            d_f,
            dv_f,
            rho_lane,
            rho_obs,
            rho_ttc,
            desired_speed_mps / SPEED_SCALE_MPS,
            lane.curvature_at(at.frenet.s_m) * CURVATURE_SCALE_M,
            lane.sharpest_curvature_ahead(at.frenet.s_m, braking_preview_m(view.ego_speed_mps)) * CURVATURE_SCALE_M,
            view.road.friction_at(pose.position()),
        ];
        let left = side_lane_features(view, lane.left);
        let right = side_lane_features(view, lane.right);
        for (o, f) in out.iter_mut().zip(features.into_iter().chain(left).chain(right)) {
            // Clamped so a far off-road state cannot feed huge numbers to the network.
            *o = f.clamp(-10.0, 10.0) as f32;
        }
    }
}
