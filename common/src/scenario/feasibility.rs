//! The feasibility filter: rejects parameter combinations that cannot happen physically, and
//! says why. Risky is not infeasible: a cutter that cuts in too close stays in, a lead car
//! braking harder than the tyres allow does not.

use super::{ScenarioKind, ScenarioSpec, cast};
use crate::vehicle::GRAVITY_MPS2;

/// Why a candidate was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Infeasible {
    #[error("braking at {decel_mps2:.2} m/s² exceeds the tyre limit μ·g = {limit_mps2:.2} m/s²")]
    BrakingBeyondFriction { decel_mps2: f64, limit_mps2: f64 },
    #[error("the lateral move needs {lat_accel_mps2:.2} m/s², beyond μ·g = {limit_mps2:.2} m/s²")]
    LateralBeyondFriction { lat_accel_mps2: f64, limit_mps2: f64 },
    #[error("a vehicle would start with a negative speed ({speed_mps:.2} m/s)")]
    NegativeSpeed { speed_mps: f64 },
    #[error("vehicles overlap at t = 0 ({what})")]
    OverlapAtStart { what: &'static str },
}

impl Infeasible {
    /// A short, stable code for counting rejections by reason.
    pub fn code(&self) -> &'static str {
        match self {
            Infeasible::BrakingBeyondFriction { .. } => "braking-beyond-friction",
            Infeasible::LateralBeyondFriction { .. } => "lateral-beyond-friction",
            Infeasible::NegativeSpeed { .. } => "negative-speed",
            Infeasible::OverlapAtStart { .. } => "overlap-at-start",
        }
    }
}

fn braking_within(decel_mps2: f64, mu: f64) -> Result<(), Infeasible> {
    let limit_mps2 = mu * GRAVITY_MPS2;
    if decel_mps2 > limit_mps2 {
        return Err(Infeasible::BrakingBeyondFriction { decel_mps2, limit_mps2 });
    }
    Ok(())
}

/// Accepts the spec or names the physical law it breaks.
pub fn check(spec: &ScenarioSpec) -> Result<(), Infeasible> {
    let p = |n: &str| spec.get(n);
    match spec.kind {
        ScenarioKind::CutIn => {
            let speed_mps = p("ego_speed_mps") + p("relative_speed_mps");
            if speed_mps < 0.0 {
                return Err(Infeasible::NegativeSpeed { speed_mps });
            }
            // The cutter's lateral profile is a half cosine; its peak lateral acceleration is
            // (π²/2)·Δy/T². A move sharper than the tyres can carry cannot be driven.
            let (dy, t) = (p("lateral_gap_m"), p("cut_in_duration_s"));
            let lat_accel_mps2 = std::f64::consts::PI.powi(2) / 2.0 * dy / (t * t);
            let limit_mps2 = cast::DRY_MU * GRAVITY_MPS2;
            if lat_accel_mps2 > limit_mps2 {
                return Err(Infeasible::LateralBeyondFriction { lat_accel_mps2, limit_mps2 });
            }
            Ok(())
        }
        ScenarioKind::EmergencyBraking => braking_within(p("braking_decel_mps2"), p("friction_mu")),
        // Within its ranges every pedestrian combination is physically possible: the parked
        // row (≤ 3 × 5.5 m, ending 1 m before the crosswalk) stays ahead of the ego's rear bumper
        // (≥ 15 m + ego length back), and walking speeds stop at a sprint (3 m/s).
        ScenarioKind::PedestrianCrossing => Ok(()),
        ScenarioKind::SensorOcclusion => {
            let truck_rear_m = p("occluder_gap_m") + cast::EGO.length_m / 2.0;
            let truck_front_m = truck_rear_m + cast::TRUCK.length_m;
            if p("hidden_obstacle_distance_m") - cast::CAR.length_m / 2.0 <= truck_front_m + 2.0 {
                return Err(Infeasible::OverlapAtStart { what: "hidden vehicle overlaps the truck" });
            }
            Ok(())
        }
        ScenarioKind::LowFriction => braking_within(p("lead_decel_mps2"), p("friction_mu")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    fn spec(kind: ScenarioKind, overrides: &[(&str, f64)]) -> ScenarioSpec {
        let mut params: BTreeMap<String, f64> =
            kind.params().iter().map(|d| (d.name.to_string(), 0.5 * (d.min + d.max))).collect();
        for (k, v) in overrides {
            params.insert(k.to_string(), *v);
        }
        ScenarioSpec::new(kind, 1, params).expect("test spec in range")
    }

    #[test]
    fn braking_beyond_mu_g_is_rejected() {
        let k = ScenarioKind::EmergencyBraking;
        let err = check(&spec(k, &[("friction_mu", 0.3), ("braking_decel_mps2", 6.0)])).unwrap_err();
        assert_eq!(err.code(), "braking-beyond-friction");
        assert!(check(&spec(k, &[("friction_mu", 0.9), ("braking_decel_mps2", 8.0)])).is_ok());
        let lf = ScenarioKind::LowFriction;
        assert!(check(&spec(lf, &[("friction_mu", 0.2), ("lead_decel_mps2", 3.0)])).is_err());
    }

    #[test]
    fn overlap_and_impossible_motion_are_rejected() {
        let occ = ScenarioKind::SensorOcclusion;
        let err = check(&spec(occ, &[("occluder_gap_m", 30.0), ("hidden_obstacle_distance_m", 40.0)])).unwrap_err();
        assert_eq!(err.code(), "overlap-at-start");
        assert!(check(&spec(occ, &[("occluder_gap_m", 10.0), ("hidden_obstacle_distance_m", 80.0)])).is_ok());
        let cut = ScenarioKind::CutIn;
        let err = check(&spec(cut, &[("ego_speed_mps", 10.0), ("relative_speed_mps", -11.0)])).unwrap_err();
        assert_eq!(err.code(), "negative-speed");
        let err = check(&spec(cut, &[("lateral_gap_m", 4.5), ("cut_in_duration_s", 1.0)])).unwrap_err();
        assert_eq!(err.code(), "lateral-beyond-friction");
    }
}
