//! The driving risk field R(p, t) = α_o·R_o + α_l·R_l + α_b·R_b + α_c·R_c (paper §3.4,
//! docs/method.md §4), evaluated exactly at a point, over the ego footprint and along a trajectory.
//!
//! These are the reference evaluations: plain `f64`, no cut-off, no tables. The fast grid fill
//! in [`super::raster`] approximates them within [`RiskFieldParams::grid_error_bound`].

use crate::geometry::{Footprint, Obb, Pose, Vec2};
use crate::road::Road;
use serde::{Deserialize, Serialize};

/// Why field parameters, a grid or a raster were rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FieldError {
    #[error("invalid grid: resolution {resolution_m} m, {cols}×{rows} cells (need resolution > 0 and cells > 0)")]
    InvalidGrid { resolution_m: f64, cols: usize, rows: usize },
    #[error("grid of {cells} cells exceeds the limit of {max}")]
    TooLarge { cells: usize, max: usize },
    #[error("invalid risk-field parameter {name} = {value} (expected {expected})")]
    InvalidParam { name: &'static str, value: f64, expected: &'static str },
}

/// Weights and shape parameters of the risk field; every default carries its reason.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RiskFieldParams {
    /// α_o. 1: obstacles are the reference scale (a touching, non-closing object gives 1).
    pub alpha_obstacle: f64,
    /// α_l. 0.3: reaching the lane edge is a normal part of a lane change, so it weighs less
    /// than touching an obstacle or leaving the road.
    pub alpha_lane: f64,
    /// α_b. 0.5: the road edge itself (R_b = 1) is half as risky as touching an obstacle; off
    /// the road R_b keeps growing, so leaving the road soon outweighs everything else.
    pub alpha_boundary: f64,
    /// α_c. 0.2: discomfort is risk of a lower order (paper §3.4: comfort matters far from
    /// conflict); at the comfort references it adds 0.2·2 = 0.4 uniformly.
    pub alpha_comfort: f64,
    /// σ_d. 2 m: at 2 m from a footprint the risk has fallen to e^{−1/2} ≈ 0.61 and at 5 m to
    /// 0.04, i.e. the field spans roughly one lane width around each vehicle.
    pub sigma_d_m: f64,
    /// λ_v. 0.1 s/m: a closing speed of 10 m/s doubles an object's risk.
    pub lambda_v_s_per_m: f64,
    /// σ_b. 0.5 m: the boundary term is 1 at the edge, e^{−3.5} ≈ 0.03 at the centre of an
    /// outer 3.5 m lane, and grows by 1 per 0.5 m beyond the edge.
    pub boundary_scale_m: f64,
    /// Cap on R_b off the road (2, reached 0.5 m beyond the edge): off the road the static
    /// terms then sum to α_l + 2α_b = 1.3, above a touching static obstacle (α_o = 1), without
    /// swallowing a heatmap's colour scale in far off-road cells.
    pub boundary_cap: f64,
    /// j_ref. 2 m/s³: the ride-comfort jerk threshold commonly used in the comfort literature
    /// (ISO 15622 caps ACC jerk at 2.5 m/s³).
    pub jerk_ref_mps3: f64,
    /// a_y,ref. 3 m/s²: upper end of comfortable lateral acceleration (ISO 11270 limits lane
    /// keeping assistance to 3 m/s²).
    pub lateral_accel_ref_mps2: f64,
    /// Cap on R_c (4: twice both references), so a jerk spike of a crash does not dominate.
    pub comfort_cap: f64,
    /// ε. 1e-3: Gaussian obstacle factors below ε are dropped by the grid fill, which bounds
    /// each object's influence to σ_d·sqrt(2 ln(1/ε)) ≈ 3.7σ_d beyond its footprint.
    pub cutoff_eps: f64,
}

impl Default for RiskFieldParams {
    fn default() -> Self {
        Self {
            alpha_obstacle: 1.0,
            alpha_lane: 0.3,
            alpha_boundary: 0.5,
            alpha_comfort: 0.2,
            sigma_d_m: 2.0,
            lambda_v_s_per_m: 0.1,
            boundary_scale_m: 0.5,
            boundary_cap: 2.0,
            jerk_ref_mps3: 2.0,
            lateral_accel_ref_mps2: 3.0,
            comfort_cap: 4.0,
            cutoff_eps: 1e-3,
        }
    }
}

/// A surrounding object as the field sees it: footprint and world-frame velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldObject {
    pub obb: Obb,
    pub velocity: Vec2,
}

/// The ego state the field needs: pose, velocity and the comfort quantities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoKinematics {
    pub pose: Pose,
    pub velocity: Vec2,
    pub lateral_accel_mps2: f64,
    pub jerk_mps3: f64,
    pub footprint: Footprint,
}

impl EgoKinematics {
    /// The ego's oriented box.
    pub fn obb(&self) -> Obb {
        Obb::new(self.pose, self.footprint)
    }
}

/// Closing speed Δv_i of `object` towards the ego (m/s, ≥ 0): the component of the relative
/// velocity along the ego→object direction û, negated, so Δv = max(0, −(v_i − v_ego)·û).
/// Only approaching objects raise risk (docs/method.md §4); a receding one counts like a static
/// one. When the centres coincide (a collision) the full relative speed counts.
pub fn closing_speed_mps(object: &FieldObject, ego: &EgoKinematics) -> f64 {
    let rel_v = object.velocity - ego.velocity;
    let offset = object.obb.centre - ego.pose.position();
    let dist = offset.norm();
    if dist < 1e-9 {
        return rel_v.norm();
    }
    (-rel_v.dot(&offset) / dist).max(0.0)
}

impl RiskFieldParams {
    /// Checks every parameter (they can come from a config file): weights and λ_v finite and
    /// ≥ 0, scales and references finite and > 0, caps ≥ 1, ε in (0, 1).
    pub fn validate(&self) -> Result<(), FieldError> {
        let nonneg = [
            ("alpha_obstacle", self.alpha_obstacle),
            ("alpha_lane", self.alpha_lane),
            ("alpha_boundary", self.alpha_boundary),
            ("alpha_comfort", self.alpha_comfort),
            ("lambda_v_s_per_m", self.lambda_v_s_per_m),
        ];
        let positive = [
            ("sigma_d_m", self.sigma_d_m),
            ("boundary_scale_m", self.boundary_scale_m),
            ("jerk_ref_mps3", self.jerk_ref_mps3),
            ("lateral_accel_ref_mps2", self.lateral_accel_ref_mps2),
        ];
        let caps = [("boundary_cap", self.boundary_cap), ("comfort_cap", self.comfort_cap)];
        let bad = |name, value, expected| Err(FieldError::InvalidParam { name, value, expected });
        for (name, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, v, "finite and >= 0");
            }
        }
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, v, "finite and > 0");
            }
        }
        for (name, v) in caps {
            if !(v.is_finite() && v >= 1.0) {
                return bad(name, v, "finite and >= 1");
            }
        }
        if !(self.cutoff_eps > 0.0 && self.cutoff_eps < 1.0) {
            return bad("cutoff_eps", self.cutoff_eps, "in (0, 1)");
        }
        Ok(())
    }

    /// The velocity gain (1 + λ_v·Δv_i) of one object.
    pub fn object_gain(&self, object: &FieldObject, ego: &EgoKinematics) -> f64 {
        1.0 + self.lambda_v_s_per_m * closing_speed_mps(object, ego)
    }

    /// R_o at `p`: the **maximum** over objects of exp(−d_i²/(2σ_d²))·(1 + λ_v·Δv_i), with d_i
    /// the distance from `p` to object i's footprint. Max, not sum: the value stays the risk of
    /// the worst single object, so a row of parked cars or a platoon does not build a wall worse
    /// than one closing vehicle, and the grid's cut-off error does not grow with the number of
    /// objects (|max a_i − max b_i| ≤ max |a_i − b_i|).
    pub fn obstacle_term(&self, objects: &[FieldObject], ego: &EgoKinematics, p: Vec2) -> f64 {
        let inv_two_sigma_sq = 1.0 / (2.0 * self.sigma_d_m * self.sigma_d_m);
        objects
            .iter()
            .map(|o| (-o.obb.distance_sq_to_point(p) * inv_two_sigma_sq).exp() * self.object_gain(o, ego))
            .fold(0.0, f64::max)
    }

    /// R_l at `p`: (|e_y|/(w_l/2))² in the lane containing `p` (`Road::locate`), clamped to 1:
    /// within a lane strip it never exceeds 1, and beyond the road the boundary term takes over.
    pub fn lane_term(&self, road: &Road, p: Vec2) -> f64 {
        let at = road.locate(p);
        let half_w = 0.5 * road.lane(at.lane).width_m;
        if half_w <= 0.0 {
            return 1.0;
        }
        (at.frenet.e_y_m.abs() / half_w).powi(2).min(1.0)
    }

    /// R_b for a signed edge distance `d` (+ on the road): exp(−d/σ_b) on the road, 1 at the
    /// edge, 1 + (−d)/σ_b beyond it (C¹ at the edge), capped at `boundary_cap`.
    pub fn boundary_from_edge_distance(&self, edge_distance_m: f64) -> f64 {
        let d = edge_distance_m / self.boundary_scale_m;
        let r = if d >= 0.0 { (-d).exp() } else { 1.0 - d };
        r.min(self.boundary_cap)
    }

    /// R_b at `p` from `Road::edge_distance_m`.
    pub fn boundary_term(&self, road: &Road, p: Vec2) -> f64 {
        self.boundary_from_edge_distance(road.edge_distance_m(p))
    }

    /// R_c, uniform in p: (|j|/j_ref)² + (|a_y|/a_y,ref)², capped at `comfort_cap`.
    pub fn comfort_term(&self, ego: &EgoKinematics) -> f64 {
        let j = ego.jerk_mps3 / self.jerk_ref_mps3;
        let a = ego.lateral_accel_mps2 / self.lateral_accel_ref_mps2;
        let r = j * j + a * a;
        if r.is_finite() { r.min(self.comfort_cap) } else { self.comfort_cap }
    }

    /// α_l·R_l + α_b·R_b: the static (road-only) part of the field at `p`.
    pub fn static_terms(&self, road: &Road, p: Vec2) -> f64 {
        self.alpha_lane * self.lane_term(road, p) + self.alpha_boundary * self.boundary_term(road, p)
    }

    /// The full field R(p, t), exactly (no cut-off, no table).
    pub fn evaluate_point(&self, road: &Road, objects: &[FieldObject], ego: &EgoKinematics, p: Vec2) -> f64 {
        self.alpha_obstacle * self.obstacle_term(objects, ego, p)
            + self.static_terms(road, p)
            + self.alpha_comfort * self.comfort_term(ego)
    }

    /// R over the ego footprint: the maximum over nine sample points (centre, four corners,
    /// four edge midpoints). Max because risk reaching any part of the car counts; the corners
    /// and midpoints catch a Gaussian or an edge that touches only one side of the car.
    pub fn evaluate_footprint(&self, road: &Road, objects: &[FieldObject], ego: &EgoKinematics) -> f64 {
        footprint_max(ego, |p| self.evaluate_point(road, objects, ego, p))
    }

    /// R̄_t: the mean footprint risk over the poses of a candidate trajectory, with the
    /// objects frozen at their current state (the reward's look-ahead term). 0 for no poses.
    pub fn evaluate_trajectory(
        &self,
        road: &Road,
        objects: &[FieldObject],
        ego: &EgoKinematics,
        poses: &[Pose],
    ) -> f64 {
        trajectory_mean(ego, poses, |e| self.evaluate_footprint(road, objects, e))
    }

    /// Radius beyond a footprint where the Gaussian factor falls to ε: σ_d·sqrt(2 ln(1/ε)).
    pub fn cutoff_radius_m(&self) -> f64 {
        self.sigma_d_m * (2.0 * (1.0 / self.cutoff_eps).ln()).sqrt()
    }
}

/// The maximum of `eval` over the ego's footprint samples.
pub(crate) fn footprint_max(ego: &EgoKinematics, eval: impl Fn(Vec2) -> f64) -> f64 {
    footprint_samples(&ego.obb()).iter().map(|p| eval(*p)).fold(f64::NEG_INFINITY, f64::max)
}

/// The mean of `eval` over the ego moved to each pose; 0 for no poses.
pub(crate) fn trajectory_mean(ego: &EgoKinematics, poses: &[Pose], eval: impl Fn(&EgoKinematics) -> f64) -> f64 {
    if poses.is_empty() {
        return 0.0;
    }
    let sum: f64 = poses.iter().map(|pose| eval(&EgoKinematics { pose: *pose, ..*ego })).sum();
    sum / poses.len() as f64
}

/// The nine footprint sample points: centre, corners, edge midpoints.
pub fn footprint_samples(obb: &Obb) -> [Vec2; 9] {
    let c = obb.corners();
    [
        obb.centre,
        c[0],
        c[1],
        c[2],
        c[3],
        0.5 * (c[0] + c[1]),
        0.5 * (c[1] + c[2]),
        0.5 * (c[2] + c[3]),
        0.5 * (c[3] + c[0]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ego_at(x: f64, vx: f64) -> EgoKinematics {
        EgoKinematics {
            pose: Pose::new(x, 0.0, 0.0),
            velocity: Vec2::new(vx, 0.0),
            lateral_accel_mps2: 0.0,
            jerk_mps3: 0.0,
            footprint: Footprint::new(4.5, 1.8),
        }
    }

    fn car(x: f64, y: f64, vx: f64) -> FieldObject {
        FieldObject { obb: Obb::new(Pose::new(x, y, 0.0), Footprint::new(4.5, 1.8)), velocity: Vec2::new(vx, 0.0) }
    }

    #[test]
    fn validation_names_the_bad_parameter() {
        assert_eq!(RiskFieldParams::default().validate(), Ok(()));
        let p = RiskFieldParams { sigma_d_m: 0.0, ..Default::default() };
        assert!(matches!(p.validate(), Err(FieldError::InvalidParam { name: "sigma_d_m", .. })));
        let p = RiskFieldParams { cutoff_eps: 1.0, ..Default::default() };
        assert!(matches!(p.validate(), Err(FieldError::InvalidParam { name: "cutoff_eps", .. })));
        let p = RiskFieldParams { alpha_lane: f64::NAN, ..Default::default() };
        assert!(matches!(p.validate(), Err(FieldError::InvalidParam { name: "alpha_lane", .. })));
    }

    #[test]
    fn closing_speed_counts_only_approach() {
        let ego = ego_at(0.0, 20.0);
        assert!((closing_speed_mps(&car(30.0, 0.0, 10.0), &ego) - 10.0).abs() < 1e-12);
        assert_eq!(closing_speed_mps(&car(30.0, 0.0, 25.0), &ego), 0.0);
        // Behind the ego and faster: closing.
        assert!((closing_speed_mps(&car(-30.0, 0.0, 26.0), &ego) - 6.0).abs() < 1e-12);
    }

    #[test]
    fn obstacle_term_grows_with_closing_speed() {
        let p = RiskFieldParams::default();
        let ego = ego_at(0.0, 20.0);
        let at = Vec2::new(25.0, 0.0); // 2.75 m behind the object's rear bumper
        let approaching = p.obstacle_term(&[car(30.0, 0.0, 10.0)], &ego, at);
        let static_obj = p.obstacle_term(&[car(30.0, 0.0, 20.0)], &ego, at);
        let receding = p.obstacle_term(&[car(30.0, 0.0, 30.0)], &ego, at);
        let none = p.obstacle_term(&[], &ego, at);
        let g = (-2.75f64 * 2.75 / 8.0).exp();
        assert!((static_obj - g).abs() < 1e-12);
        assert!((approaching - g * 2.0).abs() < 1e-12, "Δv 10 m/s doubles: {approaching}");
        assert!(approaching > receding && receding > none, "{approaching} {receding} {none}");
        assert_eq!(receding, static_obj, "receding counts like static");
    }

    #[test]
    fn obstacle_term_is_the_max_not_the_sum() {
        let p = RiskFieldParams::default();
        let ego = ego_at(0.0, 0.0);
        let a = car(30.0, 0.0, 0.0);
        let b = car(30.0, 5.0, 0.0);
        let at = Vec2::new(30.0, 2.5);
        let both = p.obstacle_term(&[a, b], &ego, at);
        let one = p.obstacle_term(&[a], &ego, at);
        assert!((both - one).abs() < 1e-12, "symmetric point: max equals each single value");
        assert_eq!(p.obstacle_term(&[a, a], &ego, at), one, "duplicates do not add up");
        // Inside a footprint the Gaussian factor is 1.
        assert_eq!(p.obstacle_term(&[a], &ego, Vec2::new(30.0, 0.0)), 1.0);
    }

    #[test]
    fn lane_term_zero_at_centre_one_at_edge() {
        let road = Road::straight(2, 3.5, 200.0, 30.0);
        let p = RiskFieldParams::default();
        assert!(p.lane_term(&road, Vec2::new(50.0, 0.0)).abs() < 1e-12);
        assert!((p.lane_term(&road, Vec2::new(50.0, -1.75)) - 1.0).abs() < 1e-12);
        assert!((p.lane_term(&road, Vec2::new(50.0, 0.875)) - 0.25).abs() < 1e-12);
        assert!(p.lane_term(&road, Vec2::new(50.0, 3.5)).abs() < 1e-12, "centre of lane 1");
        assert_eq!(p.lane_term(&road, Vec2::new(50.0, -9.0)), 1.0, "clamped off the road");
    }

    #[test]
    fn boundary_term_is_large_off_the_road() {
        let road = Road::straight(2, 3.5, 200.0, 30.0);
        let p = RiskFieldParams::default();
        let on_road_max =
            (0..=70).map(|k| p.boundary_term(&road, Vec2::new(50.0, -1.75 + 0.1 * k as f64))).fold(0.0, f64::max);
        assert!((on_road_max - 1.0).abs() < 1e-9, "1 at the edge: {on_road_max}");
        let off = p.boundary_term(&road, Vec2::new(50.0, -2.0));
        assert!((off - 1.5).abs() < 1e-9, "0.25 m off: 1 + 0.25/0.5 = {off}");
        assert!(off > on_road_max);
        assert_eq!(p.boundary_term(&road, Vec2::new(50.0, -30.0)), p.boundary_cap);
        // Centre of lane 0: 1.75 m from the right edge.
        assert!((p.boundary_term(&road, Vec2::new(50.0, 0.0)) - (-3.5f64).exp()).abs() < 1e-9);
    }

    #[test]
    fn comfort_term_uses_both_references() {
        let p = RiskFieldParams::default();
        let mut ego = ego_at(0.0, 10.0);
        assert_eq!(p.comfort_term(&ego), 0.0);
        ego.jerk_mps3 = -2.0;
        ego.lateral_accel_mps2 = 3.0;
        assert!((p.comfort_term(&ego) - 2.0).abs() < 1e-12);
        ego.jerk_mps3 = 100.0;
        assert_eq!(p.comfort_term(&ego), p.comfort_cap);
        ego.jerk_mps3 = f64::NAN;
        assert_eq!(p.comfort_term(&ego), p.comfort_cap);
    }

    #[test]
    fn footprint_and_trajectory_see_a_nearby_car() {
        let road = Road::straight(2, 3.5, 200.0, 30.0);
        let p = RiskFieldParams::default();
        let ego = ego_at(50.0, 10.0);
        let objs = [car(57.0, 0.0, 10.0)]; // 2.5 m bumper to bumper
        let fp = p.evaluate_footprint(&road, &objs, &ego);
        let expected_obstacle = (-2.5f64 * 2.5 / 8.0).exp(); // front corners/midpoint, same e_y
        assert!(fp >= expected_obstacle && fp < expected_obstacle + 1.0, "{fp}");
        let far = [EgoKinematics { pose: Pose::new(20.0, 0.0, 0.0), ..ego }.pose];
        let near = [ego.pose];
        let r_far = p.evaluate_trajectory(&road, &objs, &ego, &far);
        let r_near = p.evaluate_trajectory(&road, &objs, &ego, &near);
        assert!(r_near > r_far + 0.4, "{r_near} vs {r_far}");
        let mean = p.evaluate_trajectory(&road, &objs, &ego, &[far[0], near[0]]);
        assert!((mean - 0.5 * (r_far + r_near)).abs() < 1e-12);
        assert_eq!(p.evaluate_trajectory(&road, &objs, &ego, &[]), 0.0);
    }
}
