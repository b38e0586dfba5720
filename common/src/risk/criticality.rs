//! Pairwise criticality measures along the ego's lane: headway distance HW, time headway THW,
//! time-to-collision TTC (Jansson's constant-acceleration model) and the required longitudinal
//! acceleration a_long,req (DRAC), after CommonRoad-CriMe 0.4.5 (docs/criticality.md).
//!
//! RiskTwin computes the physically correct definitions (docs/criticality.md): HW is
//! bumper to bumper along the ego's lane, speeds and accelerations are signed along the lane
//! direction, a braking leader brakes. Departures from CommonRoad-CriMe 0.4.5: THW = HW/v_ego
//! instead of walking the ego's recorded future; TTC's constant-velocity branch is taken only
//! for |Δa| < 1e-9 m/s² (CriMe: 0.1); a_long,req only adds the v_rel² term when the gap closes.
//! The inf/0/NaN conventions follow CriMe's (docs/criticality.md).

use super::field::footprint_samples;
use crate::geometry::{Obb, Vec2};
use crate::road::{LaneId, Road};

/// One vehicle projected on a lane: arc length of its centre, along-lane speed and
/// acceleration (signed, + in the lane direction) and its extent along the lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneState {
    pub s_m: f64,
    pub speed_mps: f64,
    pub accel_mps2: f64,
    pub length_m: f64,
}

/// HW, THW, TTC and a_long,req of one (ego, other) pair at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairMeasures {
    /// Bumper-to-bumper gap along the lane (m); +inf when the other is not ahead in the lane.
    pub hw_m: f64,
    /// HW / v_ego (s); +inf when not ahead or the ego does not move forward.
    pub thw_s: f64,
    /// Time until the gap closes under constant accelerations (s); +inf when it never does.
    pub ttc_s: f64,
    /// Ego acceleration needed to avoid the collision (m/s², ≤ 0); 0 when not in the lane.
    pub a_long_req_mps2: f64,
}

impl PairMeasures {
    /// The values of a pair that is not in the ego's lane (CriMe's "not in same
    /// lanelet" values, docs/criticality.md).
    pub const NOT_IN_LANE: PairMeasures =
        PairMeasures { hw_m: f64::INFINITY, thw_s: f64::INFINITY, ttc_s: f64::INFINITY, a_long_req_mps2: 0.0 };
}

/// First τ ≥ 0 with gap(τ) = d + Δv·τ + ½·Δa·τ² = 0 (Jansson 2005, eq. 5.24/5.26), +inf when
/// the gap never closes. `gap_m` ≥ 0.
pub fn ttc_constant_accel_s(gap_m: f64, dv_mps: f64, da_mps2: f64) -> f64 {
    ttc_jansson_s(gap_m, dv_mps, da_mps2, 1e-9)
}

/// [`ttc_constant_accel_s`] with a constant-velocity band: while closing (Δv < 0) and
/// |Δa| ≤ `cv_band_mps2`, TTC = d/−Δv. CommonRoad-CriMe uses a 0.1 m/s² band (`ttc.py`,
/// its first branch), which keeps acceleration noise of differentiated recorded
/// speeds from swinging TTC; the simulator's exact accelerations use 1e-9.
pub fn ttc_jansson_s(gap_m: f64, dv_mps: f64, da_mps2: f64, cv_band_mps2: f64) -> f64 {
    if !(gap_m.is_finite() && dv_mps.is_finite() && da_mps2.is_finite()) {
        return if gap_m == f64::INFINITY { f64::INFINITY } else { f64::NAN };
    }
    if gap_m <= 0.0 {
        return if dv_mps < 0.0 || (dv_mps == 0.0 && da_mps2 < 0.0) { 0.0 } else { f64::INFINITY };
    }
    if da_mps2.abs() < 1e-9 || (dv_mps < 0.0 && da_mps2.abs() <= cv_band_mps2) {
        return if dv_mps < 0.0 { gap_m / -dv_mps } else { f64::INFINITY };
    }
    let disc = dv_mps * dv_mps - 2.0 * gap_m * da_mps2;
    if disc < 0.0 || (dv_mps >= 0.0 && da_mps2 > 0.0) {
        return f64::INFINITY;
    }
    let root = disc.sqrt();
    // The first positive root is (−Δv − √disc)/Δa; for Δv ≤ 0 its rationalised form
    // 2d/(−Δv + √disc) avoids cancellation when Δa is small.
    if dv_mps <= 0.0 { 2.0 * gap_m / (-dv_mps + root) } else { (-dv_mps - root) / da_mps2 }
}

/// The measures of `other` ahead of `ego` on the same lane (both already projected on it).
/// An other whose bumper gap is negative is not a headway pair (CriMe's HW: h < 0 gives inf);
/// then a_long,req is min(a_other, 0), the x = inf limit of CriMe's `a_long_req.py`.
pub fn pair_measures(ego: &LaneState, other: &LaneState) -> PairMeasures {
    let hw = other.s_m - 0.5 * other.length_m - (ego.s_m + 0.5 * ego.length_m);
    if hw.is_nan() {
        return PairMeasures { hw_m: f64::NAN, thw_s: f64::NAN, ttc_s: f64::NAN, a_long_req_mps2: f64::NAN };
    }
    if hw < 0.0 {
        return PairMeasures { a_long_req_mps2: other.accel_mps2.min(0.0), ..PairMeasures::NOT_IN_LANE };
    }
    let thw = if ego.speed_mps > 0.0 { hw / ego.speed_mps } else { f64::INFINITY };
    let dv = other.speed_mps - ego.speed_mps;
    let ttc = ttc_constant_accel_s(hw, dv, other.accel_mps2 - ego.accel_mps2);
    // a_req = a_lead − v_rel²/(2·HW) when closing (CriMe's `a_long_req.py`, acceleration mode 1); an opening gap only
    // requires matching the leader's deceleration.
    let a_req = if dv < 0.0 {
        if hw > 0.0 { (other.accel_mps2 - dv * dv / (2.0 * hw)).min(0.0) } else { f64::NAN }
    } else {
        other.accel_mps2.min(0.0)
    };
    PairMeasures { hw_m: hw, thw_s: thw, ttc_s: ttc, a_long_req_mps2: a_req }
}

/// A vehicle's world state for the criticality measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleState {
    pub obb: Obb,
    pub velocity: Vec2,
    pub accel: Vec2,
}

/// The ego's lane frame at one instant: its lane (`Road::locate_heading`) and its state on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoLaneFrame {
    pub lane: LaneId,
    pub ego: LaneState,
    /// The ego's lateral offset from the lane centre (m, + left).
    pub e_y_m: f64,
}

/// Extent of `obb` along the unit direction `t`.
fn extent_along(obb: &Obb, t: Vec2) -> f64 {
    let normal = Vec2::new(-obb.axis.y, obb.axis.x);
    2.0 * (obb.half_length_m * obb.axis.dot(&t).abs() + obb.half_width_m * normal.dot(&t).abs())
}

impl EgoLaneFrame {
    /// Locates the ego on the road and projects its state on its lane.
    pub fn new(road: &Road, ego: &VehicleState) -> Self {
        let heading = ego.obb.axis.y.atan2(ego.obb.axis.x);
        let at = road.locate_heading(ego.obb.centre, heading);
        Self { lane: at.lane, ego: project(road, at.lane, ego).0, e_y_m: at.frenet.e_y_m }
    }

    /// The pair measures of `other`, or [`PairMeasures::NOT_IN_LANE`] when its footprint does
    /// not overlap the ego's lane strip laterally. The test projects the footprint's nine sample
    /// points on the lane and asks whether their e_y range meets [−w/2, w/2]; like CriMe's
    /// "same lanelet" test a car straddling the lane line counts, one fully in the next
    /// lane does not, and there is no heading condition (a crossing pedestrian counts).
    pub fn measure(&self, road: &Road, other: &VehicleState) -> PairMeasures {
        let (state, lo, hi) = project(road, self.lane, other);
        let half_w = 0.5 * road.lane(self.lane).width_m;
        if hi < -half_w || lo > half_w {
            return PairMeasures::NOT_IN_LANE;
        }
        pair_measures(&self.ego, &state)
    }
}

/// Projects a vehicle on lane `lane`: its lane state and the e_y range of its footprint.
fn project(road: &Road, lane: LaneId, v: &VehicleState) -> (LaneState, f64, f64) {
    let l = road.lane(lane);
    let f = l.project(v.obb.centre);
    let t = Vec2::new(f.lane_heading_rad.cos(), f.lane_heading_rad.sin());
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in footprint_samples(&v.obb) {
        let e = l.project(p).e_y_m;
        lo = lo.min(e);
        hi = hi.max(e);
    }
    let state = LaneState {
        s_m: f.s_m,
        speed_mps: v.velocity.dot(&t),
        accel_mps2: v.accel.dot(&t),
        length_m: extent_along(&v.obb, t),
    };
    (state, lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Footprint, Pose};

    fn st(s: f64, v: f64, a: f64) -> LaneState {
        LaneState { s_m: s, speed_mps: v, accel_mps2: a, length_m: 4.0 }
    }

    #[test]
    fn constant_speed_closing() {
        // Centres 30 m apart, 4 m cars: HW 26 m; ego 20 m/s, lead 10 m/s → TTC 2.6 s.
        let m = pair_measures(&st(0.0, 20.0, 0.0), &st(30.0, 10.0, 0.0));
        assert!((m.hw_m - 26.0).abs() < 1e-12);
        assert!((m.thw_s - 1.3).abs() < 1e-12);
        assert!((m.ttc_s - 2.6).abs() < 1e-12);
        // a_req = 0 − 10²/(2·26) = −1.923 m/s².
        assert!((m.a_long_req_mps2 + 100.0 / 52.0).abs() < 1e-12);
    }

    #[test]
    fn braking_lead() {
        // Same speed, lead brakes at 5 m/s²: 26 − 2.5τ² = 0 → τ = sqrt(10.4) s.
        let m = pair_measures(&st(0.0, 20.0, 0.0), &st(30.0, 20.0, -5.0));
        assert!((m.ttc_s - 10.4f64.sqrt()).abs() < 1e-12, "{}", m.ttc_s);
        assert_eq!(m.a_long_req_mps2, -5.0, "opening/equal speeds: match the leader");
        // Closing at 5 m/s and lead braking 4 m/s²: 26 − 5τ − 2τ² = 0 → τ = (−5 + sqrt(233))/4.
        let m = pair_measures(&st(0.0, 20.0, 0.0), &st(30.0, 15.0, -4.0));
        assert!((m.ttc_s - (233f64.sqrt() - 5.0) / 4.0).abs() < 1e-12, "{}", m.ttc_s);
        assert!((m.a_long_req_mps2 - (-4.0 - 25.0 / 52.0)).abs() < 1e-12);
    }

    #[test]
    fn never_closing_is_infinite() {
        let opening = pair_measures(&st(0.0, 20.0, 0.0), &st(30.0, 25.0, 0.0));
        assert_eq!(opening.ttc_s, f64::INFINITY);
        assert_eq!(opening.a_long_req_mps2, 0.0);
        // Closing at 5 m/s but the ego brakes at 2 m/s²: Δv² − 2dΔa = 25 − 104 < 0, no contact.
        let braking_ego = pair_measures(&st(0.0, 20.0, -2.0), &st(30.0, 15.0, 0.0));
        assert_eq!(braking_ego.ttc_s, f64::INFINITY);
        // Behind: not a headway pair.
        let behind = pair_measures(&st(30.0, 20.0, 0.0), &st(0.0, 30.0, -1.0));
        assert_eq!(behind.hw_m, f64::INFINITY);
        assert_eq!(behind.a_long_req_mps2, -1.0);
        assert_eq!(ttc_constant_accel_s(0.0, -1.0, 0.0), 0.0);
    }

    #[test]
    fn constant_velocity_band() {
        // Closing at 2 m/s over 50 m with Δa = 0.05 m/s²: the gap never closes (disc < 0) …
        assert_eq!(ttc_constant_accel_s(50.0, -2.0, 0.05), f64::INFINITY);
        // … but inside CriMe's 0.1 m/s² band it is 50/2 s.
        assert_eq!(ttc_jansson_s(50.0, -2.0, 0.05, 0.1), 25.0);
        // Outside the band, or opening, the band changes nothing.
        assert_eq!(ttc_jansson_s(50.0, -2.0, 0.5, 0.1), ttc_constant_accel_s(50.0, -2.0, 0.5));
        assert_eq!(ttc_jansson_s(50.0, 2.0, -0.05, 0.1), ttc_constant_accel_s(50.0, 2.0, -0.05));
    }

    #[test]
    fn lane_frame_counts_only_cars_in_the_lane() {
        let road = Road::straight(2, 3.5, 300.0, 30.0);
        let car = |x: f64, y: f64, vx: f64| VehicleState {
            obb: Obb::new(Pose::new(x, y, 0.0), Footprint::new(4.0, 1.8)),
            velocity: Vec2::new(vx, 0.0),
            accel: Vec2::zeros(),
        };
        let ego = car(100.0, 0.0, 20.0);
        let frame = EgoLaneFrame::new(&road, &ego);
        assert_eq!(frame.lane, 0);
        let ahead = frame.measure(&road, &car(130.0, 0.3, 10.0));
        assert!((ahead.ttc_s - 2.6).abs() < 1e-9, "{}", ahead.ttc_s);
        assert_eq!(frame.measure(&road, &car(130.0, 3.5, 10.0)), PairMeasures::NOT_IN_LANE);
        // Straddling the lane line (its right side at 1.75 − 0.05 m): counts.
        let straddling = frame.measure(&road, &car(130.0, 2.6, 10.0));
        assert!(straddling.ttc_s.is_finite());
        // A westbound car ahead in our lane: closing at 30 m/s.
        let head_on = VehicleState { velocity: Vec2::new(-10.0, 0.0), ..car(130.0, 0.0, 0.0) };
        assert!((frame.measure(&road, &head_on).ttc_s - 26.0 / 30.0).abs() < 1e-9);
    }
}
