//! Intelligent Driver Model (IDM) car following as a pure function.
//!
//! Source: Treiber, Hennecke & Helbing (2000), "Congested traffic states in empirical
//! observations and microscopic simulations", Phys. Rev. E 62, 1805, Eqs. (2)–(3):
//! a_IDM = a·[1 − (v/v0)^δ − (s*/s)²], s* = s0 + v·T + v·Δv/(2·√(a·b)).
//! The default parameters are the paper's Table I (v0 = 120 km/h, T = 1.6 s, a = 0.73 m/s²,
//! b = 1.67 m/s², δ = 4, s0 = 2 m, s1 = 0).

use serde::{Deserialize, Serialize};

/// The smallest gap the model divides by, so touching or overlapping leaders give a large but
/// finite deceleration (the actuator and μ·g cap it anyway).
pub const MIN_GAP_M: f64 = 0.01;

/// IDM parameters of one driver–vehicle type.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IdmParams {
    /// Desired speed v0.
    pub desired_speed_mps: f64,
    /// Safe time headway T.
    pub time_headway_s: f64,
    /// Jam distance s0 (bumper to bumper at standstill).
    pub min_gap_m: f64,
    /// Maximum acceleration a.
    pub max_accel_mps2: f64,
    /// Comfortable deceleration b.
    pub comfort_decel_mps2: f64,
    /// Acceleration exponent δ.
    pub exponent: f64,
}

impl IdmParams {
    /// Treiber, Hennecke & Helbing (2000), Table I, with the desired speed given.
    pub fn treiber2000(desired_speed_mps: f64) -> Self {
        Self {
            desired_speed_mps,
            time_headway_s: 1.6,
            min_gap_m: 2.0,
            max_accel_mps2: 0.73,
            comfort_decel_mps2: 1.67,
            exponent: 4.0,
        }
    }

    /// Equilibrium gap behind a leader driving at constant `v`:
    /// s_e(v) = (s0 + v·T) / √(1 − (v/v0)^δ) (Treiber et al. 2000, Eq. (5) with s1 = 0).
    pub fn equilibrium_gap_m(&self, v: f64) -> f64 {
        let ratio = (v / self.desired_speed_mps).powf(self.exponent);
        (self.min_gap_m + v * self.time_headway_s) / (1.0 - ratio).sqrt()
    }
}

impl Default for IdmParams {
    /// Table I of Treiber et al. (2000): v0 = 120 km/h.
    fn default() -> Self {
        Self::treiber2000(120.0 / 3.6)
    }
}

/// Parameters rearranged for the hot loop (reciprocals precomputed, δ = 4 special-cased).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct IdmCoeffs {
    inv_v0: f64,
    t_s: f64,
    s0_m: f64,
    a_mps2: f64,
    inv_2sqrt_ab: f64,
    exponent: f64,
}

impl IdmCoeffs {
    pub(crate) fn new(p: &IdmParams) -> Self {
        // Guards keep a degenerate parameter set finite (v0 = 0 means "stay stopped").
        let ab = (p.max_accel_mps2 * p.comfort_decel_mps2).max(1e-9);
        Self {
            inv_v0: 1.0 / p.desired_speed_mps.max(1e-3),
            t_s: p.time_headway_s,
            s0_m: p.min_gap_m,
            a_mps2: p.max_accel_mps2,
            inv_2sqrt_ab: 0.5 / ab.sqrt(),
            exponent: p.exponent,
        }
    }

    /// The IDM acceleration; `gap_m = ∞` means no leader.
    #[inline]
    pub(crate) fn accel(&self, v: f64, gap_m: f64, closing_mps: f64) -> f64 {
        let x = v * self.inv_v0;
        let free = if self.exponent == 4.0 {
            let x2 = x * x;
            x2 * x2
        } else {
            x.max(0.0).powf(self.exponent)
        };
        if gap_m == f64::INFINITY {
            return self.a_mps2 * (1.0 - free);
        }
        let s_star = self.s0_m + (v * self.t_s + v * closing_mps * self.inv_2sqrt_ab).max(0.0);
        let r = s_star / gap_m.max(MIN_GAP_M);
        self.a_mps2 * (1.0 - free - r * r)
    }
}

/// IDM acceleration of a vehicle at speed `v` with `gap_m` (bumper to bumper) to its leader,
/// approaching it at `closing_speed` (own speed minus leader speed). `gap_m = f64::INFINITY`
/// means no leader: the free-road term only.
pub fn idm_accel(params: &IdmParams, v: f64, gap_m: f64, closing_speed: f64) -> f64 {
    IdmCoeffs::new(params).accel(v, gap_m, closing_speed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_road_and_standstill_values() {
        let p = IdmParams::default();
        // At rest on a free road the IDM accelerates at a.
        assert_eq!(idm_accel(&p, 0.0, f64::INFINITY, 0.0), 0.73);
        // At v0 it stops accelerating.
        assert!(idm_accel(&p, p.desired_speed_mps, f64::INFINITY, 0.0).abs() < 1e-12);
        // Standing at the jam distance behind a stopped leader: a·(1 − 1) = 0.
        assert!(idm_accel(&p, 0.0, 2.0, 0.0).abs() < 1e-12);
        // Closer than s0: pushed back (negative).
        assert!(idm_accel(&p, 0.0, 1.0, 0.0) < -2.0);
    }

    #[test]
    fn equilibrium_gap_gives_zero_accel() {
        let p = IdmParams::default();
        for v in [5.0, 15.0, 25.0] {
            let s = p.equilibrium_gap_m(v);
            assert!(idm_accel(&p, v, s, 0.0).abs() < 1e-12, "v {v}");
        }
    }

    #[test]
    fn closing_in_brakes_harder() {
        let p = IdmParams::default();
        let a0 = idm_accel(&p, 20.0, 40.0, 0.0);
        let a1 = idm_accel(&p, 20.0, 40.0, 5.0);
        assert!(a1 < a0 - 1.0, "{a1} vs {a0}");
    }
}
