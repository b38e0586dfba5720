//! Scripted manoeuvres of traffic vehicles and the lateral profile every lane change follows.
//!
//! A lane change moves the lateral offset from its value at the start to the target lane's
//! centre with the quintic minimum-jerk profile q(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (Flash & Hogan 1985;
//! the standard lane-change polynomial of Werling et al. 2010): zero lateral speed and
//! acceleration at both ends, half the offset at τ = ½.

use super::LaneId;
use serde::{Deserialize, Serialize};

/// Duration of a MOBIL-triggered lane change. Observed lane changes last ≈ 3–6 s (Toledo &
/// Zohar 2007, mean ≈ 4.6 s); 4 s is a brisk but ordinary one.
pub const MOBIL_LANE_CHANGE_S: f64 = 4.0;

/// What a traffic vehicle does besides following its lane with IDM (and MOBIL when enabled).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub enum Manoeuvre {
    /// Plain IDM, plus MOBIL lane changes if the vehicle has them enabled.
    #[default]
    None,
    /// Never moves; still an obstacle and a collision partner.
    Parked,
    /// From `start_time_s`, moves into `target_lane` over `duration_s` regardless of MOBIL.
    CutIn { start_time_s: f64, duration_s: f64, target_lane: LaneId },
    /// From `start_time_s`, brakes at `decel_mps2` (capped at μ·g) to a standstill.
    Brake { start_time_s: f64, decel_mps2: f64 },
    /// When the gap to the leader falls below `trigger_gap_m`, moves into `target_lane` over
    /// `duration_s` (a lead truck revealing a stopped car).
    Swerve { trigger_gap_m: f64, duration_s: f64, target_lane: LaneId },
}

/// State of a lane change in progress: the lateral offset (relative to the target lane, which
/// is already the vehicle's lane) goes from `d0_m` to 0 between `t0_s` and `t0_s + duration_s`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct LaneChange {
    pub active: bool,
    pub t0_s: f64,
    pub duration_s: f64,
    pub d0_m: f64,
}

impl LaneChange {
    /// Lateral offset and its rate at `time_s`; `None` once the change is over.
    pub(crate) fn lateral_at(&self, time_s: f64) -> Option<(f64, f64)> {
        let dur = self.duration_s.max(1e-3);
        let tau = ((time_s - self.t0_s) / dur).max(0.0);
        if tau >= 1.0 {
            return None;
        }
        let (q, dq) = quintic(tau);
        Some((self.d0_m * (1.0 - q), -self.d0_m * dq / dur))
    }
}

/// Minimum-jerk blend q(τ) and dq/dτ on τ ∈ [0, 1].
pub(crate) fn quintic(tau: f64) -> (f64, f64) {
    let t = tau.clamp(0.0, 1.0);
    let t2 = t * t;
    let q = t2 * t * (10.0 - 15.0 * t + 6.0 * t2);
    let dq = 30.0 * t2 * (1.0 - 2.0 * t + t2);
    (q, dq)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quintic_endpoints_and_midpoint() {
        assert_eq!(quintic(0.0), (0.0, 0.0));
        assert_eq!(quintic(1.0), (1.0, 0.0));
        let (q, dq) = quintic(0.5);
        assert!((q - 0.5).abs() < 1e-12);
        // Peak lateral rate of the quintic: 15/8 of the mean rate.
        assert!((dq - 1.875).abs() < 1e-12);
    }

    #[test]
    fn lane_change_profile_in_time() {
        let lc = LaneChange { active: true, t0_s: 2.0, duration_s: 4.0, d0_m: 3.5 };
        assert_eq!(lc.lateral_at(2.0), Some((3.5, 0.0)));
        let (d, rate) = lc.lateral_at(4.0).expect("mid-change");
        assert!((d - 1.75).abs() < 1e-12);
        assert!((rate + 3.5 * 1.875 / 4.0).abs() < 1e-12);
        assert_eq!(lc.lateral_at(6.0), None);
    }
}
