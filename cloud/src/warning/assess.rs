//! One pair's criticality at one instant, for the warning path. Three tests, cheapest first:
//! - contact: the footprints overlap now (`Obb::overlaps`);
//! - lane TTC: one vehicle ahead of the other in the other's lane, closing in (common's
//!   `EgoLaneFrame::measure`: Jansson's constant-acceleration TTC, as the risk report computes
//!   it), in either vehicle's lane frame;
//! - predicted contact: the footprints moved on at constant velocity overlap within the
//!   threshold, checked every [`WarningConfig::step_s`] (crossing paths, sites without a road).
//!
//! The pair is critical when the smallest TTC of these lies below the threshold.

use super::WarningConfig;
use crate::ingest::ObservedKinematics;
use risktwin_common::geometry::{Obb, Vec2};
use risktwin_common::risk::{EgoLaneFrame, VehicleState};
use risktwin_common::road::Road;
use risktwin_common::telemetry::HazardKind;

/// A critical pair: how it was found, its TTC and the footprints' distance now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairRisk {
    pub kind: HazardKind,
    pub ttc_s: f64,
    pub distance_m: f64,
}

/// The criticality measures' view of observed kinematics (acceleration along the heading, as
/// the risk role takes it).
pub fn vehicle_state(k: &ObservedKinematics) -> VehicleState {
    let obb = Obb::new(k.pose, k.footprint);
    VehicleState { obb, velocity: k.velocity, accel: obb.axis * k.accel_mps2 }
}

/// Whether `a` and `b` can touch within `horizon_s` at all: their gap (centres less both
/// bounding radii) against what the relative speed and both accelerations can close in that
/// time. A cheap bound that lets the broad phase skip far pairs without missing a near one.
pub fn within_reach(a: &ObservedKinematics, b: &ObservedKinematics, horizon_s: f64) -> bool {
    let gap_m = (b.pose.position() - a.pose.position()).norm()
        - a.footprint.bounding_radius_m()
        - b.footprint.bounding_radius_m();
    let closable_m = (b.velocity - a.velocity).norm() * horizon_s
        + 0.5 * (a.accel_mps2.abs() + b.accel_mps2.abs()) * horizon_s * horizon_s;
    // NaN never gets here (the ingest refuses non-finite states); it would be kept in.
    gap_m.partial_cmp(&closable_m) != Some(std::cmp::Ordering::Greater)
}

/// The criticality of the pair (`a`, `b`), both at the same instant, or `None` when it is not
/// critical. `lane`: the site's road and `a`'s lane frame on it (none: no lane TTC).
pub fn assess_pair(
    lane: Option<(&Road, &EgoLaneFrame)>,
    a: &VehicleState,
    b: &VehicleState,
    config: &WarningConfig,
) -> Option<PairRisk> {
    if a.obb.overlaps(&b.obb) {
        return Some(PairRisk { kind: HazardKind::Contact, ttc_s: 0.0, distance_m: 0.0 });
    }
    let mut best: Option<(HazardKind, f64)> = None;
    if let Some((road, frame_a)) = lane {
        let b_ahead = frame_a.measure(road, b).ttc_s;
        let a_ahead = EgoLaneFrame::new(road, b).measure(road, a).ttc_s;
        let ttc_s = b_ahead.min(a_ahead);
        if ttc_s < config.critical_ttc_s {
            best = Some((HazardKind::LaneTtc, ttc_s));
        }
    }
    let horizon_s = best.map_or(config.critical_ttc_s, |(_, t)| t);
    if let Some(t) = first_contact_s(a, b, horizon_s, config.step_s).filter(|&t| t < horizon_s) {
        best = Some((HazardKind::PredictedContact, t));
    }
    let (kind, ttc_s) = best?;
    Some(PairRisk { kind, ttc_s, distance_m: a.obb.distance_to(&b.obb) })
}

/// The first multiple of `step_s` in (0, `horizon_s`) at which the footprints, moved on at
/// their velocities, overlap.
fn first_contact_s(a: &VehicleState, b: &VehicleState, horizon_s: f64, step_s: f64) -> Option<f64> {
    let moved = |obb: &Obb, v: Vec2, t: f64| Obb { centre: obb.centre + v * t, ..*obb };
    let steps = (horizon_s / step_s).ceil() as u32;
    (1..steps)
        .map(|k| f64::from(k) * step_s)
        .find(|&t| moved(&a.obb, a.velocity, t).overlaps(&moved(&b.obb, b.velocity, t)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::geometry::{Footprint, Pose};

    fn car(x: f64, y: f64, heading: f64, vx: f64, vy: f64) -> ObservedKinematics {
        ObservedKinematics {
            pose: Pose::new(x, y, heading),
            velocity: Vec2::new(vx, vy),
            speed_mps: vx.hypot(vy),
            accel_mps2: 0.0,
            footprint: Footprint::new(4.0, 2.0),
            seqs: (0, 0),
        }
    }

    fn assess(road: Option<&Road>, a: &ObservedKinematics, b: &ObservedKinematics) -> Option<PairRisk> {
        let (a, b) = (vehicle_state(a), vehicle_state(b));
        let frame = road.map(|r| (r, EgoLaneFrame::new(r, &a)));
        assess_pair(frame.as_ref().map(|(r, f)| (*r, f)), &a, &b, &WarningConfig::default())
    }

    #[test]
    fn a_follower_closing_in_its_lane_gets_the_lane_ttc() {
        let road = Road::straight(2, 3.5, 500.0, 30.0);
        let lane_y = road.lane(0).project(Vec2::new(100.0, 0.0));
        let y = -lane_y.e_y_m;
        // Centres 20 m apart, 4 m cars: gap 16 m, closing at 10 m/s → TTC 1.6 s, both ways round.
        let (follower, leader) = (car(100.0, y, 0.0, 25.0, 0.0), car(120.0, y, 0.0, 15.0, 0.0));
        for (a, b) in [(&follower, &leader), (&leader, &follower)] {
            let risk = assess(Some(&road), a, b).expect("critical");
            assert_eq!(risk.kind, HazardKind::LaneTtc);
            assert!((risk.ttc_s - 1.6).abs() < 1e-9, "{risk:?}");
            assert!((risk.distance_m - 16.0).abs() < 1e-9, "{risk:?}");
        }
        // Without a road the same pair is found by moving the footprints on: contact after
        // 1.6 s, seen at the first 50 ms step there or past it.
        let risk = assess(None, &follower, &leader).expect("critical");
        assert_eq!(risk.kind, HazardKind::PredictedContact);
        assert!(risk.ttc_s > 1.6 - 1e-9 && risk.ttc_s < 1.65 + 1e-9, "{risk:?}");
    }

    #[test]
    fn crossing_paths_are_found_by_prediction_and_safe_pairs_are_not_critical() {
        // One drives east, one north, both reach (20, 0) after 1 s.
        let east = car(0.0, 0.0, 0.0, 20.0, 0.0);
        let north = car(20.0, -20.0, std::f64::consts::FRAC_PI_2, 0.0, 20.0);
        let risk = assess(None, &east, &north).expect("critical");
        assert_eq!(risk.kind, HazardKind::PredictedContact);
        assert!(risk.ttc_s > 0.8 && risk.ttc_s <= 1.0, "{risk:?}");
        // Side by side in two lanes, the same speed: never closer.
        assert_eq!(assess(None, &car(0.0, 0.0, 0.0, 20.0, 0.0), &car(0.0, 3.5, 0.0, 20.0, 0.0)), None);
        // Closing, but 2.5 s away: beyond the 2 s threshold.
        assert_eq!(assess(None, &car(0.0, 0.0, 0.0, 20.0, 0.0), &car(29.0, 0.0, 0.0, 10.0, 0.0)), None);
        // Overlapping now: contact.
        let touching = assess(None, &car(0.0, 0.0, 0.0, 0.0, 0.0), &car(3.9, 0.0, 0.0, 0.0, 0.0));
        assert_eq!(touching, Some(PairRisk { kind: HazardKind::Contact, ttc_s: 0.0, distance_m: 0.0 }));
    }

    #[test]
    fn reach_keeps_every_pair_that_can_meet_and_skips_far_ones() {
        let a = car(0.0, 0.0, 0.0, 20.0, 0.0);
        // 2 s at 20 m/s closes 40 m; radii 2.24 m each.
        assert!(within_reach(&a, &car(44.0, 0.0, 0.0, 0.0, 0.0), 2.0));
        assert!(!within_reach(&a, &car(45.0, 0.0, 0.0, 0.0, 0.0), 2.0));
        // Both at 20 m/s, 20 m apart: only a braking lead (8 m/s² closes 16 m in 2 s) is in reach.
        let braking = ObservedKinematics { accel_mps2: -8.0, ..car(20.0, 0.0, 0.0, 20.0, 0.0) };
        assert!(within_reach(&a, &braking, 2.0));
        assert!(!within_reach(&a, &car(20.0, 0.0, 0.0, 20.0, 0.0), 2.0));
    }
}
