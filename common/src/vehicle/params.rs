//! Vehicle parameters: geometry, mass, tyre and actuator limits of a real passenger car.
//!
//! The default set is CommonRoad vehicle ID 2 (BMW 320i), from Althoff & Würsching,
//! "CommonRoad: Vehicle Models" (vehicleModels_commonRoad.pdf, version 2020a) as shipped in the
//! PyPI package `commonroad-vehicle-models` 3.0.2 (`vehiclemodels/parameters/parameters_vehicle2.yaml`
//! and `parameters_tire.yaml`, read through `vehiclemodels.parameters_vehicle2()`).

use crate::geometry::Footprint;

/// Standard gravity used by the CommonRoad models, m/s².
pub const GRAVITY_MPS2: f64 = 9.81;

/// Physical and actuator parameters of one car. All fields SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleParams {
    /// Body length, m (CommonRoad `l`).
    pub length_m: f64,
    /// Body width, m (CommonRoad `w`).
    pub width_m: f64,
    /// Distance from the centre of gravity to the front axle, m (CommonRoad `a`).
    pub lf_m: f64,
    /// Distance from the centre of gravity to the rear axle, m (CommonRoad `b`).
    pub lr_m: f64,
    /// Longitudinal offset of the footprint centre ahead of the centre of gravity, m
    /// (negative: behind). CommonRoad does not publish overhangs; we assume equal front and rear
    /// overhangs, so the footprint centre is the wheelbase midpoint, `(lf − lr)/2`.
    pub centre_ahead_of_cog_m: f64,
    /// Total mass, kg (CommonRoad `m`).
    pub mass_kg: f64,
    /// Yaw moment of inertia, kg·m² (CommonRoad `I_z`).
    pub iz_kgm2: f64,
    /// Centre-of-gravity height of the total mass, m (CommonRoad `h_cg`); informative.
    pub h_cg_m: f64,
    /// Sprung-mass centre-of-gravity height, m (CommonRoad `h_s`). The reference
    /// `vehicle_dynamics_st` (package 3.0.2) uses this height for the load transfer, so our
    /// single-track model does too, to agree with it exactly.
    pub h_s_m: f64,
    /// Normalised front cornering stiffness C_Sf, 1/rad (lateral force per normal load per rad,
    /// before scaling by μ). CommonRoad: `C_Sf = −p_ky1 / p_dy1`.
    pub c_sf_per_rad: f64,
    /// Normalised rear cornering stiffness C_Sr, 1/rad. CommonRoad: `C_Sr = −p_ky1 / p_dy1`.
    pub c_sr_per_rad: f64,
    /// Nominal (dry) tyre–road friction coefficient, CommonRoad `μ = p_dy1`.
    pub mu_nominal: f64,
    /// Minimum front-wheel steering angle, rad (CommonRoad `steering.min`).
    pub steer_min_rad: f64,
    /// Maximum front-wheel steering angle, rad (CommonRoad `steering.max`).
    pub steer_max_rad: f64,
    /// Maximum steering rate magnitude, rad/s (CommonRoad `steering.v_max` = −`steering.v_min`).
    pub steer_rate_max_radps: f64,
    /// Speed above which the drive acceleration is power-limited, m/s (CommonRoad `v_switch`).
    pub v_switch_mps: f64,
    /// Maximum longitudinal acceleration magnitude, m/s² (CommonRoad `a_max`).
    pub a_max_mps2: f64,
    /// Minimum speed, m/s (CommonRoad `v_min`; our actuators never reverse, see `actuator`).
    pub v_min_mps: f64,
    /// Maximum speed, m/s (CommonRoad `v_max`).
    pub v_max_mps: f64,
    /// Braking deceleration demanded at full brake (brake = 1.0), m/s². Ours, not CommonRoad's:
    /// 11 m/s² exceeds μ·g on any road (≤ 1.05·g), so full brake is friction-limited, and stays
    /// inside CommonRoad's `a_max` bound.
    pub brake_decel_max_mps2: f64,
    /// Time constant of the first-order lag between the longitudinal demand and the achieved
    /// acceleration, s. Ours: 0.15 s, a typical brake-pressure build-up time.
    pub accel_lag_s: f64,
}

impl VehicleParams {
    /// CommonRoad vehicle ID 2, BMW 320i (parameters_vehicle2, commonroad-vehicle-models 3.0.2).
    pub fn bmw_320i() -> Self {
        // Tyre parameters from parameters_tire.yaml (shared by all CommonRoad vehicles).
        let p_dy1 = 1.0489;
        let p_ky1 = -21.92;
        let lf_m = 1.1561957064;
        let lr_m = 1.4227170936;
        Self {
            length_m: 4.508,
            width_m: 1.61,
            lf_m,
            lr_m,
            centre_ahead_of_cog_m: 0.5 * (lf_m - lr_m),
            mass_kg: 1093.2952334674046,
            iz_kgm2: 1791.5995300122856,
            h_cg_m: 0.5748689544000001,
            h_s_m: 0.61373004,
            c_sf_per_rad: -p_ky1 / p_dy1,
            c_sr_per_rad: -p_ky1 / p_dy1,
            mu_nominal: p_dy1,
            steer_min_rad: -1.066,
            steer_max_rad: 1.066,
            steer_rate_max_radps: 0.4,
            v_switch_mps: 7.319,
            a_max_mps2: 11.5,
            v_min_mps: -13.9,
            v_max_mps: 50.8,
            brake_decel_max_mps2: 11.0,
            accel_lag_s: 0.15,
        }
    }

    /// The rectangular body footprint.
    pub fn footprint(&self) -> Footprint {
        Footprint::new(self.length_m, self.width_m)
    }

    /// Distance between the axles, m.
    pub fn wheelbase_m(&self) -> f64 {
        self.lf_m + self.lr_m
    }
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self::bmw_320i()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bmw_320i_matches_commonroad_vehicle_2() {
        let p = VehicleParams::bmw_320i();
        assert_eq!(p.footprint(), Footprint::new(4.508, 1.61));
        assert!((p.wheelbase_m() - 2.5789128).abs() < 1e-7);
        // −p_ky1/p_dy1 = 21.92/1.0489, the value the CommonRoad documentation lists as 20.89.
        assert!((p.c_sf_per_rad - 20.898083).abs() < 1e-6);
        assert_eq!(p.c_sf_per_rad, p.c_sr_per_rad);
        // The wheelbase lies inside the body, and the centre sits between the axles.
        assert!(p.wheelbase_m() < p.length_m);
        assert!(p.centre_ahead_of_cog_m.abs() < 0.5 * p.wheelbase_m());
    }
}
