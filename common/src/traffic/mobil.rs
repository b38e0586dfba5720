//! MOBIL lane-change decisions ("minimizing overall braking induced by lane changes") as pure
//! functions of the accelerations before and after a prospective change.
//!
//! Source: Kesting, Treiber & Helbing (2007), "General lane-changing model MOBIL for
//! car-following models", Transportation Research Record 1999, pp. 86–94: safety criterion
//! Eq. (1) ã_n ≥ −b_safe, symmetric incentive criterion Eq. (2)
//! ã_c − a_c + p·[(ã_n − a_n) + (ã_o − a_o)] > Δa_th. Default parameters from their Table 1:
//! p = 0.5 (range 0…0.5), Δa_th = 0.1 m/s², b_safe = 4 m/s².

use serde::{Deserialize, Serialize};

/// MOBIL parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MobilParams {
    /// Politeness factor p: weight of the followers' advantage.
    pub politeness: f64,
    /// Changing threshold Δa_th: the net advantage a change must bring.
    pub threshold_mps2: f64,
    /// Maximum safe deceleration b_safe imposed on the new follower (and oneself).
    pub safe_decel_mps2: f64,
}

impl Default for MobilParams {
    /// Kesting, Treiber & Helbing (2007), Table 1.
    fn default() -> Self {
        Self { politeness: 0.5, threshold_mps2: 0.1, safe_decel_mps2: 4.0 }
    }
}

/// IDM accelerations of the three vehicles MOBIL weighs, now and after the change
/// (c: the changing vehicle, n: the follower in the target lane, o: the follower in the
/// current lane). A missing follower contributes 0 to both.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MobilAccels {
    pub own_now_mps2: f64,
    pub own_after_mps2: f64,
    pub new_follower_now_mps2: f64,
    pub new_follower_after_mps2: f64,
    pub old_follower_now_mps2: f64,
    pub old_follower_after_mps2: f64,
}

/// Safety criterion, Eq. (1): neither the new follower nor the changing vehicle has to brake
/// harder than b_safe.
pub fn mobil_safe(params: &MobilParams, acc: &MobilAccels) -> bool {
    acc.new_follower_after_mps2 >= -params.safe_decel_mps2 && acc.own_after_mps2 >= -params.safe_decel_mps2
}

/// Net incentive of Eq. (2) minus the threshold: positive means the change is worth it.
pub fn mobil_incentive(params: &MobilParams, acc: &MobilAccels) -> f64 {
    let own = acc.own_after_mps2 - acc.own_now_mps2;
    let others = (acc.new_follower_after_mps2 - acc.new_follower_now_mps2)
        + (acc.old_follower_after_mps2 - acc.old_follower_now_mps2);
    own + params.politeness * others - params.threshold_mps2
}

/// True when the change is safe and its incentive exceeds the threshold.
pub fn mobil_should_change(params: &MobilParams, acc: &MobilAccels) -> bool {
    mobil_safe(params, acc) && mobil_incentive(params, acc) > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overtakes_when_it_pays_and_is_safe() {
        let p = MobilParams::default();
        // Stuck behind a slow leader (−1 m/s²), free target lane (+0.5), nobody behind.
        let acc = MobilAccels { own_now_mps2: -1.0, own_after_mps2: 0.5, ..Default::default() };
        assert!(mobil_should_change(&p, &acc));
        // The same gain but the new follower would have to brake at 5 m/s² > b_safe.
        let unsafe_acc = MobilAccels { new_follower_after_mps2: -5.0, ..acc };
        assert!(!mobil_safe(&p, &unsafe_acc) && !mobil_should_change(&p, &unsafe_acc));
    }

    #[test]
    fn politeness_weighs_the_followers() {
        // Own gain 0.4; new follower loses 1.0 → with p = 0.5: 0.4 − 0.5 − 0.1 < 0.
        let acc = MobilAccels {
            own_now_mps2: 0.0,
            own_after_mps2: 0.4,
            new_follower_now_mps2: 0.0,
            new_follower_after_mps2: -1.0,
            ..Default::default()
        };
        assert!((mobil_incentive(&MobilParams::default(), &acc) + 0.2).abs() < 1e-12);
        assert!(!mobil_should_change(&MobilParams::default(), &acc));
        let selfish = MobilParams { politeness: 0.0, ..Default::default() };
        assert!(mobil_should_change(&selfish, &acc));
    }
}
