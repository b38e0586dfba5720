//! Criticality of a CommonRoad scenario: HW, THW, TTC and a_long,req of the ego against every
//! other dynamic obstacle at every time step where both have a state, plus PET and the minimum
//! distance per pair. Definitions, sources and our departures from CommonRoad-CriMe 0.4.5 are in
//! `docs/criticality.md`; in short:
//!
//! - **Frame.** One reference path per scenario, around the ego's initial lanelet ([`path`],
//!   CriMe §2). s is the arc length on it.
//! - **Which others count** (CriMe §3): those whose footprint meets a lanelet that is, or is a
//!   predecessor/successor of, a lanelet the ego's footprint meets. Others give HW = THW =
//!   TTC = inf and a_long,req = 0.
//! - **HW** (m): bumper to bumper along the path, s_o − ℓ_o/2 − (s_e + ℓ_e/2); inf when negative
//!   or when either centre is outside the path's domain (CriMe §6.1 without its diagonal-offset
//!   quirk).
//! - **THW** (s): the time until the ego's front, following its *recorded* future positions,
//!   first passes the point where the other's rear is now (CriMe §6.2, exactly).
//! - **TTC** (s): Jansson 2005 eq. 5.24/5.26, first τ ≥ 0 with HW + Δv·τ + ½Δa·τ² = 0, with
//!   speeds and accelerations signed along the path tangent (a braking leader brakes), via
//!   [`risktwin_common::risk::ttc_constant_accel_s`].
//! - **a_long,req** (m/s²): a_other − Δv²/(2·HW) while closing, else min(a_other, 0); ≤ 0
//!   ([`risktwin_common::risk::pair_measures`], CriMe §6.4 mode 1 with the closing check CriMe lacks).
//! - **PET** (s): Allen et al. 1978, discretised: the smallest |i − j|·dt over ego step i and
//!   other step j whose footprints overlap (the gap between one leaving and the other entering a
//!   common point; 0 for a collision, inf when the swept paths never meet).
//! - Accelerations are d/dt of the recorded speed (numpy.gradient, CriMe §1), not the XML field.

mod measures;
pub mod path;
pub mod tracks;

use crate::model::Scenario;
pub use measures::{CellMeasures, PairSummary, ScenarioCriticality};
pub use path::{PathPoint, ReferencePath};
pub use tracks::{Body, Track};

/// Why the measures of a scenario cannot be computed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CriticalityError {
    #[error("ego id {ego_id} is not a dynamic obstacle of the scenario (dynamic obstacles: {available})")]
    UnknownEgo { ego_id: u64, available: String },
    #[error("the scenario has no dynamic obstacle to take as the ego")]
    NoEgo,
    #[error("no reference path for ego {ego_id}: {reason}")]
    NoPath { ego_id: u64, reason: String },
}

/// The ego's initial lanelet (CriMe §2, L0): among the lanelets containing its centre, the one
/// whose direction at the nearest centreline segment is closest to the ego's heading (CriMe
/// takes the first in Python set order); when none contains it, the lanelet with the nearest
/// centreline.
pub fn ego_initial_lanelet(scenario: &Scenario, ego_id: u64) -> Option<u64> {
    let ego = scenario.dynamic_obstacle(ego_id)?;
    let p = ego.initial_state.position;
    let heading = ego.initial_state.orientation_rad;
    let score = |l: &risktwin_common::road::lanelet::Lanelet| {
        let path = ReferencePath::from_points(l.centreline.clone())?;
        let (d, dir) = path.nearest(p);
        Some((d, risktwin_common::geometry::wrap_angle(dir - heading).abs()))
    };
    let containing: Vec<u64> = scenario.lanelets.containing(p).map(|i| scenario.lanelets.lanelets[i].id).collect();
    let pick = |ids: &mut dyn Iterator<Item = u64>, by_heading: bool| {
        ids.filter_map(|id| {
            scenario.lanelets.get(id).and_then(score).map(|(d, a)| (id, if by_heading { a } else { d }))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(id, _)| id)
    };
    if containing.is_empty() {
        pick(&mut scenario.lanelets.lanelets.iter().map(|l| l.id), false)
    } else {
        pick(&mut containing.into_iter(), true)
    }
}

/// The measures of `ego_id` (default: [`Scenario::default_ego_id`]) against every other dynamic
/// obstacle of `scenario`.
pub fn scenario_criticality(scenario: &Scenario, ego_id: Option<u64>) -> Result<ScenarioCriticality, CriticalityError> {
    let ego_id = match ego_id {
        Some(id) => id,
        None => scenario.default_ego_id().ok_or(CriticalityError::NoEgo)?,
    };
    let Some(ego) = scenario.dynamic_obstacle(ego_id) else {
        let ids: Vec<String> = scenario.dynamic_obstacles.iter().map(|o| o.id.to_string()).collect();
        let available = if ids.is_empty() { "none".to_string() } else { ids.join(", ") };
        return Err(CriticalityError::UnknownEgo { ego_id, available });
    };
    let no_path = |reason: &str| CriticalityError::NoPath { ego_id, reason: reason.to_string() };
    let lanelet = ego_initial_lanelet(scenario, ego_id).ok_or_else(|| no_path("the scenario has no lanelet"))?;
    let path = ReferencePath::around_lanelet(&scenario.lanelets, lanelet)
        .ok_or_else(|| no_path(&format!("lanelet {lanelet} has a degenerate centreline")))?;
    Ok(measures::compute(scenario, ego, lanelet, &path))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse_scenario;

    /// A 200 m lanelet along +x; ego (id 1) at x = 10 m, 20 m/s; other (id 2) at x = 40 m,
    /// 10 m/s; both 4 m long, 21 steps of 0.1 s (the fixture the cloud's collector tests share).
    fn two_cars() -> Scenario {
        parse_scenario(include_str!("../../../tests/fixtures/two_cars.xml")).unwrap()
    }

    #[test]
    fn measures_of_a_closing_pair() {
        let m = scenario_criticality(&two_cars(), Some(1)).unwrap();
        assert_eq!((m.ego_lanelet_id, m.cells.len()), (1, 21));
        let c = m.cells[0];
        // Bumper gap 40 − 2 − (10 + 2) = 26 m, closing at 10 m/s.
        assert!((c.hw_m - 26.0).abs() < 1e-9 && (c.ttc_s - 2.6).abs() < 1e-9, "{c:?}");
        // The ego's front (12 + 2k m) first passes the other's rear at 38 m after k = 14 steps.
        assert!((c.thw_s - 1.4).abs() < 1e-9, "{c:?}");
        assert!((c.a_long_req_mps2 + 100.0 / 52.0).abs() < 1e-9 && (c.distance_m - 26.0).abs() < 1e-9);
        // After 2.0 s the gap is 6 m; the ego's recorded future ends before it passes: THW inf.
        let last = m.cells[20];
        assert!((last.hw_m - 6.0).abs() < 1e-9 && last.thw_s == f64::INFINITY);
        // Never overlapping at the same time, but the swept outlines meet: the ego's front at
        // step 20 (52 m) reaches where the other's rear was at step 13 (51 m) or, touching, 14
        // (52 m): PET 0.7 s (0.6 s if the touch survives rounding). Minimum distance 6 m at the end.
        let p = m.pairs[0];
        assert!((p.pet_s - 0.7).abs() < 1e-9 || (p.pet_s - 0.6).abs() < 1e-9, "{p:?}");
        assert_eq!(p.min_distance_time_step, Some(20));
        // Seen from the other, the ego is behind: no headway.
        let back = scenario_criticality(&two_cars(), Some(2)).unwrap();
        assert_eq!(back.cells[0].hw_m, f64::INFINITY);
        assert!(scenario_criticality(&two_cars(), Some(9)).unwrap_err().to_string().contains("ego id 9"));
    }
}
