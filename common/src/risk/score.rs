//! The scalar scenario risk score S_risk = β1·S_TTC + β2·S_dist + β3·S_lane + β4·S_jerk +
//! β5·S_col (paper §3.4, docs/method.md §5) and the accumulator that reduces an episode to it.

use super::criticality::{EgoLaneFrame, PairMeasures, VehicleState};
use crate::road::Road;
use serde::{Deserialize, Serialize};

/// S_risk and its terms, each in [0, 1]; `score` is their weighted sum.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RiskTerms {
    pub score: f64,
    pub ttc: f64,
    pub dist: f64,
    pub lane: f64,
    pub jerk: f64,
    pub collision: f64,
}

/// The β weights, summing to 1 so S_risk ∈ [0, 1]. Defaults (paper §3.4: TTC and distance
/// dominate in dense interaction, lane and comfort matter far from conflict): TTC 0.30 and
/// distance 0.25 carry most of the score; collision 0.25 guarantees that any collision
/// outranks every collision-free episode with the same TTC and distance terms; lane 0.10 and
/// jerk 0.10 separate episodes that never came near a conflict.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RiskWeights {
    pub ttc: f64,
    pub dist: f64,
    pub lane: f64,
    pub jerk: f64,
    pub collision: f64,
}

/// Why score weights or references were rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScoreError {
    #[error("invalid risk-score parameter {name} = {value} (expected {expected})")]
    InvalidParam { name: &'static str, value: f64, expected: &'static str },
}

impl RiskWeights {
    /// Each β finite and ≥ 0, and their sum 1 (± 1e-6) so S_risk stays in [0, 1].
    pub fn validate(&self) -> Result<(), ScoreError> {
        let all = [
            ("ttc", self.ttc),
            ("dist", self.dist),
            ("lane", self.lane),
            ("jerk", self.jerk),
            ("collision", self.collision),
        ];
        for (name, value) in all {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ScoreError::InvalidParam { name, value, expected: "finite and >= 0" });
            }
        }
        let sum: f64 = all.iter().map(|(_, v)| v).sum();
        if (sum - 1.0).abs() > 1e-6 {
            return Err(ScoreError::InvalidParam { name: "sum of weights", value: sum, expected: "1" });
        }
        Ok(())
    }
}

impl ScoreReferences {
    /// Every reference finite and > 0, and the jerk maximum above the comfort level.
    pub fn validate(&self) -> Result<(), ScoreError> {
        let all = [
            ("ttc_crit_s", self.ttc_crit_s),
            ("dist_ref_m", self.dist_ref_m),
            ("jerk_comfort_mps3", self.jerk_comfort_mps3),
            ("jerk_max_mps3", self.jerk_max_mps3),
        ];
        for (name, value) in all {
            if !(value.is_finite() && value > 0.0) {
                return Err(ScoreError::InvalidParam { name, value, expected: "finite and > 0" });
            }
        }
        if self.jerk_max_mps3 <= self.jerk_comfort_mps3 {
            let value = self.jerk_max_mps3;
            return Err(ScoreError::InvalidParam { name: "jerk_max_mps3", value, expected: "> jerk_comfort_mps3" });
        }
        Ok(())
    }
}

impl Default for RiskWeights {
    fn default() -> Self {
        Self { ttc: 0.30, dist: 0.25, lane: 0.10, jerk: 0.10, collision: 0.25 }
    }
}

/// The references that normalise each term to [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ScoreReferences {
    /// TTC_crit. 4 s: the usual upper bound of "critical" TTC in the conflict literature
    /// (thresholds of 1.5–4 s); S_TTC = clamp(1 − min TTC/TTC_crit).
    pub ttc_crit_s: f64,
    /// d_ref. 2 m: two cars side by side in adjacent 3.5 m lanes keep ≈ 1.6–1.7 m, so regular
    /// passing scores ≈ 0.15 and only closer approaches score high; S_dist = clamp(1 − d/d_ref).
    pub dist_ref_m: f64,
    /// 2 m/s³: comfortable jerk (the field's comfort reference); below it S_jerk = 0.
    pub jerk_comfort_mps3: f64,
    /// 10 m/s³: emergency-manoeuvre jerk; at or above it S_jerk = 1, linear in between.
    pub jerk_max_mps3: f64,
}

impl Default for ScoreReferences {
    fn default() -> Self {
        Self { ttc_crit_s: 4.0, dist_ref_m: 2.0, jerk_comfort_mps3: 2.0, jerk_max_mps3: 10.0 }
    }
}

/// The raw extremes of an episode that the score is computed from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RiskSummary {
    /// Smallest finite TTC of any in-lane pair; `None` when no pair ever closed in.
    pub min_ttc_s: Option<f64>,
    /// Smallest footprint distance to any object (m); +inf when there were none.
    pub min_distance_m: f64,
    /// Largest |e_y|/(w/2) of the ego.
    pub max_lane_ratio: f64,
    /// Largest |jerk| of the ego (m/s³).
    pub peak_jerk_mps3: f64,
    pub collision: bool,
    /// The ego left the road (a run-off-road crash).
    pub offroad: bool,
}

fn unit(x: f64) -> f64 {
    if x.is_nan() { 1.0 } else { x.clamp(0.0, 1.0) }
}

impl RiskSummary {
    /// The normalised terms and S_risk. S_lane = min(ratio, 1)², the peak of the lane term
    /// R_l of the field (paper eq. for R_l) — a lane change crosses a lane line and so reaches
    /// 1 as well, which is why S_lane weighs little; NaN inputs count as the worst case.
    pub fn terms(&self, weights: &RiskWeights, refs: &ScoreReferences) -> RiskTerms {
        let ttc = self.min_ttc_s.map_or(0.0, |t| unit(1.0 - t / refs.ttc_crit_s));
        let dist = unit(1.0 - self.min_distance_m / refs.dist_ref_m);
        let lane = unit(self.max_lane_ratio).powi(2);
        let span = (refs.jerk_max_mps3 - refs.jerk_comfort_mps3).max(f64::EPSILON);
        let jerk = unit((self.peak_jerk_mps3 - refs.jerk_comfort_mps3) / span);
        // Leaving the road counts as a collision: run-off-road crashes are collisions with the
        // roadside in crash statistics, and a scenario that ends in a ditch is as critical as
        // one that ends in a rear-end crash.
        let collision = if self.collision || self.offroad { 1.0 } else { 0.0 };
        let score = weights.ttc * ttc
            + weights.dist * dist
            + weights.lane * lane
            + weights.jerk * jerk
            + weights.collision * collision;
        RiskTerms { score, ttc, dist, lane, jerk, collision }
    }
}

/// One step of an episode as the accumulator sees it.
#[derive(Debug, Clone, Copy)]
pub struct RiskStep<'a> {
    pub ego: VehicleState,
    /// Lateral offset from the centre of the lane the ego should be in (m).
    pub lane_offset_m: f64,
    pub lane_width_m: f64,
    pub jerk_mps3: f64,
    /// The other objects, in a stable order (index i is the same object every step).
    pub others: &'a [VehicleState],
    pub collision: bool,
    pub offroad: bool,
}

/// The worst values one (ego, other) pair reached in an episode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairExtremes {
    pub min_hw_m: f64,
    pub min_thw_s: f64,
    pub min_ttc_s: f64,
    /// Most negative required acceleration (m/s²).
    pub min_a_long_req_mps2: f64,
    pub min_distance_m: f64,
}

impl PairExtremes {
    const NONE: PairExtremes = PairExtremes {
        min_hw_m: f64::INFINITY,
        min_thw_s: f64::INFINITY,
        min_ttc_s: f64::INFINITY,
        min_a_long_req_mps2: 0.0,
        min_distance_m: f64::INFINITY,
    };

    fn update(&mut self, m: &PairMeasures, distance_m: f64) {
        // `f64::min` ignores NaN, so a NaN measure (contact) never hides a finite extreme.
        self.min_hw_m = self.min_hw_m.min(m.hw_m);
        self.min_thw_s = self.min_thw_s.min(m.thw_s);
        self.min_ttc_s = self.min_ttc_s.min(m.ttc_s);
        self.min_a_long_req_mps2 = self.min_a_long_req_mps2.min(m.a_long_req_mps2);
        self.min_distance_m = self.min_distance_m.min(distance_m);
    }
}

/// Reduces an episode to [`RiskTerms`] and [`RiskSummary`], one [`RiskStep`] at a time. It
/// allocates only when more objects appear than ever before (the per-pair table grows).
#[derive(Debug, Clone)]
pub struct RiskAccumulator {
    weights: RiskWeights,
    refs: ScoreReferences,
    summary: RiskSummary,
    pairs: Vec<PairExtremes>,
}

impl RiskAccumulator {
    /// An empty accumulator.
    pub fn new(weights: RiskWeights, refs: ScoreReferences) -> Self {
        let summary = RiskSummary {
            min_ttc_s: None,
            min_distance_m: f64::INFINITY,
            max_lane_ratio: 0.0,
            peak_jerk_mps3: 0.0,
            collision: false,
            offroad: false,
        };
        Self { weights, refs, summary, pairs: Vec::new() }
    }

    /// Feeds one step.
    pub fn push(&mut self, road: &Road, step: &RiskStep<'_>) {
        let s = &mut self.summary;
        let half_w = 0.5 * step.lane_width_m;
        let ratio = if half_w > 0.0 { step.lane_offset_m.abs() / half_w } else { f64::INFINITY };
        s.max_lane_ratio = max_nan_worst(s.max_lane_ratio, ratio);
        s.peak_jerk_mps3 = max_nan_worst(s.peak_jerk_mps3, step.jerk_mps3.abs());
        s.collision |= step.collision;
        s.offroad |= step.offroad;
        if self.pairs.len() < step.others.len() {
            self.pairs.resize(step.others.len(), PairExtremes::NONE);
        }
        if step.others.is_empty() {
            return;
        }
        let frame = EgoLaneFrame::new(road, &step.ego);
        for (other, extremes) in step.others.iter().zip(&mut self.pairs) {
            let m = frame.measure(road, other);
            let d = step.ego.obb.distance_to(&other.obb);
            extremes.update(&m, d);
            s.min_distance_m = s.min_distance_m.min(d);
            if m.ttc_s.is_finite() {
                s.min_ttc_s = Some(s.min_ttc_s.map_or(m.ttc_s, |t| t.min(m.ttc_s)));
            }
        }
    }

    /// The per-pair extremes so far, indexed like `RiskStep::others`.
    pub fn pairs(&self) -> &[PairExtremes] {
        &self.pairs
    }

    /// The terms and the summary of the steps fed so far.
    pub fn finish(&self) -> (RiskTerms, RiskSummary) {
        (self.summary.terms(&self.weights, &self.refs), self.summary)
    }
}

/// max that lets NaN win: a NaN jerk or offset is bad data, scored as the worst case.
fn max_nan_worst(acc: f64, x: f64) -> f64 {
    if x.is_nan() { f64::INFINITY } else { acc.max(x) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Footprint, Obb, Pose, Vec2};

    fn car(x: f64, y: f64, vx: f64, ax: f64) -> VehicleState {
        VehicleState {
            obb: Obb::new(Pose::new(x, y, 0.0), Footprint::new(4.0, 1.8)),
            velocity: Vec2::new(vx, 0.0),
            accel: Vec2::new(ax, 0.0),
        }
    }

    /// An ego at 20 m/s following a lead that starts 40 m ahead at `lead_mps` and brakes to a
    /// stop at `lead_brake_mps2`, while the ego brakes at `ego_brake_mps2` once the gap is below
    /// 25 m; 0.1 s steps for 10 s. Returns the score.
    fn episode(lead_mps: f64, lead_brake_mps2: f64, ego_brake_mps2: f64) -> (RiskTerms, RiskSummary) {
        let road = Road::straight(2, 3.5, 500.0, 30.0);
        let mut acc = RiskAccumulator::new(RiskWeights::default(), ScoreReferences::default());
        let (mut xe, mut ve, mut xl, mut vl) = (50.0, 20.0, 90.0, lead_mps);
        let dt = 0.1;
        let mut ae_prev = 0.0;
        for _ in 0..100 {
            let gap = xl - xe - 4.0;
            let ae = if gap < 25.0 && ve > 0.0 { -ego_brake_mps2 } else { 0.0 };
            let al = if vl > 0.0 { -lead_brake_mps2 } else { 0.0 };
            let ego = car(xe, 0.0, ve, ae);
            let others = [car(xl, 0.0, vl, al)];
            let collision = ego.obb.overlaps(&others[0].obb);
            let step = RiskStep {
                ego,
                lane_offset_m: 0.2,
                lane_width_m: 3.5,
                jerk_mps3: (ae - ae_prev) / dt,
                others: &others,
                collision,
                offroad: false,
            };
            acc.push(&road, &step);
            ae_prev = ae;
            if !collision {
                ve = (ve + ae * dt).max(0.0);
                vl = (vl + al * dt).max(0.0);
                xe += ve * dt;
                xl += vl * dt;
            }
        }
        acc.finish()
    }

    #[test]
    fn terms_are_normalised() {
        let s = RiskSummary {
            min_ttc_s: Some(1.0),
            min_distance_m: 0.5,
            max_lane_ratio: 2.0,
            peak_jerk_mps3: 6.0,
            collision: false,
            offroad: false,
        };
        let t = s.terms(&RiskWeights::default(), &ScoreReferences::default());
        assert!((t.ttc - 0.75).abs() < 1e-12 && (t.dist - 0.75).abs() < 1e-12);
        assert_eq!(t.lane, 1.0);
        assert!((t.jerk - 0.5).abs() < 1e-12);
        let w = RiskWeights::default();
        assert_eq!(w.validate(), Ok(()));
        assert_eq!(ScoreReferences::default().validate(), Ok(()));
        let heavy = RiskWeights { ttc: 0.5, ..w };
        assert!(matches!(heavy.validate(), Err(ScoreError::InvalidParam { name: "sum of weights", .. })));
        let worst = RiskSummary {
            min_ttc_s: Some(0.0),
            min_distance_m: 0.0,
            max_lane_ratio: f64::NAN,
            peak_jerk_mps3: 1e9,
            collision: true,
            offroad: false,
        };
        assert!((worst.terms(&w, &ScoreReferences::default()).score - 1.0).abs() < 1e-12);
        // Leaving the road is a run-off-road crash: S_col = 1 as for a collision.
        let ditch = RiskSummary { collision: false, offroad: true, ..s };
        assert_eq!(ditch.terms(&w, &ScoreReferences::default()).collision, 1.0);
    }

    #[test]
    fn collision_above_near_miss_above_benign() {
        let (benign, bs) = episode(20.0, 0.0, 0.0);
        let (near, ns) = episode(20.0, 6.0, 8.0);
        let (crash, cs) = episode(20.0, 8.0, 1.0);
        for t in [benign, near, crash] {
            for v in [t.score, t.ttc, t.dist, t.lane, t.jerk, t.collision] {
                assert!((0.0..=1.0).contains(&v), "{t:?}");
            }
        }
        assert!(!bs.collision && !ns.collision && cs.collision, "{bs:?} {ns:?} {cs:?}");
        assert_eq!(bs.min_ttc_s, None, "constant gap never closes");
        assert!(ns.min_distance_m > 0.0 && ns.min_distance_m < 10.0, "{ns:?}");
        assert!(crash.score > near.score && near.score > benign.score, "{crash:?} {near:?} {benign:?}");
        assert_eq!(crash.collision, 1.0);
    }

    #[test]
    fn pairs_track_each_object() {
        let road = Road::straight(2, 3.5, 500.0, 30.0);
        let mut acc = RiskAccumulator::new(RiskWeights::default(), ScoreReferences::default());
        let others = [car(80.0, 0.0, 10.0, 0.0), car(52.0, 3.5, 30.0, 0.0)];
        let step = RiskStep {
            ego: car(50.0, 0.0, 20.0, 0.0),
            lane_offset_m: 0.0,
            lane_width_m: 3.5,
            jerk_mps3: 0.0,
            others: &others,
            collision: false,
            offroad: false,
        };
        acc.push(&road, &step);
        let p = acc.pairs();
        assert!((p[0].min_ttc_s - 2.6).abs() < 1e-9 && (p[0].min_hw_m - 26.0).abs() < 1e-9);
        assert_eq!(p[1].min_ttc_s, f64::INFINITY, "next lane");
        assert!((p[1].min_distance_m - 1.7).abs() < 1e-9);
        assert_eq!(acc.finish().1.min_ttc_s, Some(p[0].min_ttc_s));
    }
}
