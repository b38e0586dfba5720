//! The pairwise loop: every (time step, other) cell from the precomputed tracks, then PET and
//! the minimum distance per other. Allocation-free per cell: everything it reads is in the
//! [`Track`] arrays, and the output vector is sized once.

use super::path::ReferencePath;
use super::tracks::Track;
use crate::model::{DynamicObstacle, Scenario};
use risktwin_common::risk::{LaneState, pair_measures, ttc_jansson_s};

/// CriMe's constant-velocity band for TTC, m/s² (see [`ttc_jansson_s`]).
const TTC_CV_BAND_MPS2: f64 = 0.1;
use serde::Serialize;

/// The measures of one (time step, other) cell. Non-finite values are meaningful (inf: no
/// conflict; NaN: undefined), as in criticality.md §7.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CellMeasures {
    pub time_step: i64,
    pub other_id: u64,
    /// Headway distance, m.
    pub hw_m: f64,
    /// Time headway, s.
    pub thw_s: f64,
    /// Time to collision, s.
    pub ttc_s: f64,
    /// Required longitudinal acceleration, m/s² (≤ 0).
    pub a_long_req_mps2: f64,
    /// Distance between the two outlines, m (0 when they overlap).
    pub distance_m: f64,
}

/// Scenario-level values of one (ego, other) pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PairSummary {
    pub other_id: u64,
    /// Post-encroachment time, s (inf when the swept footprints never meet).
    pub pet_s: f64,
    /// Smallest outline distance over the shared time steps, m (inf when none is shared).
    pub min_distance_m: f64,
    /// The time step of that minimum.
    pub min_distance_time_step: Option<i64>,
}

/// All measures of one ego in one scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScenarioCriticality {
    pub ego_id: u64,
    pub dt_s: f64,
    /// The lanelet the reference path is built around.
    pub ego_lanelet_id: u64,
    /// Direction of the reference path at the ego's initial position, rad (NaN when the ego
    /// starts outside the path's domain).
    pub ego_lane_heading_rad: f64,
    /// Cells ordered by time step, then other id.
    pub cells: Vec<CellMeasures>,
    /// One per other dynamic obstacle, by id.
    pub pairs: Vec<PairSummary>,
}

pub(super) fn compute(
    scenario: &Scenario,
    ego_obstacle: &DynamicObstacle,
    ego_lanelet_id: u64,
    path: &ReferencePath,
) -> ScenarioCriticality {
    let dt = scenario.dt_s;
    let ego = Track::new(ego_obstacle, path, &scenario.lanelets, dt);
    let mut others: Vec<Track> = scenario
        .dynamic_obstacles
        .iter()
        .filter(|o| o.id != ego.id)
        .map(|o| Track::new(o, path, &scenario.lanelets, dt))
        .collect();
    others.sort_by_key(|t| t.id);
    let capacity = others.iter().map(|o| overlap(&ego, o).map_or(0, |(a, b)| (b - a + 1) as usize)).sum();
    let mut cells = Vec::with_capacity(capacity);
    for i in 0..ego.len() {
        let t = ego.first_step + i as i64;
        for o in &others {
            if let Some(j) = o.index(t) {
                cells.push(cell(&ego, i, o, j, dt));
            }
        }
    }
    let pairs = others.iter().map(|o| pair_summary(&ego, o, dt)).collect();
    let ego_lane_heading_rad = path.project(ego_obstacle.initial_state.position).map_or(f64::NAN, |p| p.heading_rad);
    ScenarioCriticality { ego_id: ego.id, dt_s: dt, ego_lanelet_id, ego_lane_heading_rad, cells, pairs }
}

/// First and last time step both tracks have.
fn overlap(a: &Track, b: &Track) -> Option<(i64, i64)> {
    let start = a.first_step.max(b.first_step);
    let end = (a.first_step + a.len() as i64).min(b.first_step + b.len() as i64) - 1;
    (start <= end).then_some((start, end))
}

/// The measures of ego step `i` against other step `j` (same time step).
fn cell(ego: &Track, i: usize, o: &Track, j: usize, dt: f64) -> CellMeasures {
    let time_step = ego.first_step + i as i64;
    let distance_m = ego.body[i].distance_to(&o.body[j]);
    let mut c = CellMeasures {
        time_step,
        other_id: o.id,
        hw_m: f64::INFINITY,
        thw_s: f64::INFINITY,
        ttc_s: f64::INFINITY,
        a_long_req_mps2: 0.0,
        distance_m,
    };
    if !ego.shares_lanelet(i, o, j) {
        return c;
    }
    let (s_e, s_o) = (ego.s_m[i], o.s_m[j]);
    let ego_ls = LaneState {
        s_m: s_e,
        speed_mps: ego.speed_along_mps[i],
        accel_mps2: ego.accel_along_mps2[i],
        length_m: 2.0 * ego.half_length_m,
    };
    let other_ls = LaneState {
        s_m: s_o,
        speed_mps: o.speed_along_mps[j],
        accel_mps2: o.accel_along_mps2[j],
        length_m: 2.0 * o.half_length_m,
    };
    if s_e.is_nan() || s_o.is_nan() {
        // Outside the path's domain: HW, TTC inf (criticality.md §7), a_long,req its x = inf limit.
        c.a_long_req_mps2 = other_ls.accel_mps2.min(0.0);
    } else {
        let m = pair_measures(&ego_ls, &other_ls);
        c.hw_m = m.hw_m;
        c.ttc_s = if m.hw_m.is_finite() {
            let (dv, da) = (other_ls.speed_mps - ego_ls.speed_mps, other_ls.accel_mps2 - ego_ls.accel_mps2);
            ttc_jansson_s(m.hw_m, dv, da, TTC_CV_BAND_MPS2)
        } else {
            m.ttc_s
        };
        c.a_long_req_mps2 = m.a_long_req_mps2;
    }
    if !ego.in_lanelet[i] {
        // CriMe needs the ego's lanelet for the lane direction; without one these are undefined.
        if c.hw_m.is_finite() {
            c.ttc_s = f64::NAN;
        }
        c.a_long_req_mps2 = f64::NAN;
    }
    c.thw_s = thw_s(ego, i, s_o - o.half_length_m, dt);
    c
}

/// THW (CriMe §6.2): steps until the ego's front first passes `rear_s_m`, walking its recorded
/// future; inf when it is already past or never passes, NaN when the ego leaves the path's
/// domain first.
fn thw_s(ego: &Track, i: usize, rear_s_m: f64, dt: f64) -> f64 {
    if rear_s_m.is_nan() {
        return f64::INFINITY;
    }
    let front = |k: usize| ego.s_m[k] + ego.half_length_m;
    if ego.s_m[i].is_nan() {
        return f64::NAN;
    }
    if front(i) > rear_s_m {
        return f64::INFINITY;
    }
    for k in i + 1..ego.len() {
        let f = front(k);
        if f.is_nan() {
            return f64::NAN;
        }
        if f > rear_s_m {
            return (k - i) as f64 * dt;
        }
    }
    f64::INFINITY
}

/// PET and minimum distance of one pair.
fn pair_summary(ego: &Track, o: &Track, dt: f64) -> PairSummary {
    let mut min_distance_m = f64::INFINITY;
    let mut min_distance_time_step = None;
    if let Some((a, b)) = overlap(ego, o) {
        for t in a..=b {
            let (Some(i), Some(j)) = (ego.index(t), o.index(t)) else { continue };
            let d = ego.body[i].distance_to(&o.body[j]);
            if d < min_distance_m {
                min_distance_m = d;
                min_distance_time_step = Some(t);
            }
        }
    }
    PairSummary {
        other_id: o.id,
        pet_s: pet_steps(ego, o).map_or(f64::INFINITY, |k| k as f64 * dt),
        min_distance_m,
        min_distance_time_step,
    }
}

/// The smallest |t_ego − t_other| (in steps) over states whose outlines overlap.
fn pet_steps(ego: &Track, o: &Track) -> Option<u64> {
    let mut best: Option<u64> = None;
    // Broad phase from arrays: bound_radius_m is a hypot, too dear for the O(T²) loop.
    let (o_centre, o_radius): (Vec<_>, Vec<_>) = o.body.iter().map(|b| (b.centre(), b.bound_radius_m())).unzip();
    for i in 0..ego.len() {
        let (ce, re) = (ego.body[i].centre(), ego.body[i].bound_radius_m());
        let ti = ego.first_step + i as i64;
        for j in 0..o.len() {
            let lag = (o.first_step + j as i64 - ti).unsigned_abs();
            if best.is_some_and(|b| lag >= b) {
                continue;
            }
            let r = re + o_radius[j];
            if (o_centre[j] - ce).norm_squared() > r * r {
                continue;
            }
            if ego.body[i].distance_to(&o.body[j]) == 0.0 {
                best = Some(lag);
            }
        }
    }
    best
}
