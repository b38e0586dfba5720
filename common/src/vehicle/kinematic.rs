//! Kinematic single-track model with the centre of gravity as reference point.
//!
//! This is CommonRoad's `vehicle_dynamics_ks_cog` (commonroad-vehicle-models 3.0.2,
//! `vehiclemodels/utils/vehicle_dynamics_ks_cog.py`): the KS model of the CommonRoad vehicle
//! models document §5 moved from the rear axle to the centre of gravity, so that it shares its
//! reference point with the dynamic single-track model (which uses it below 0.1 m/s). The wheels
//! do not slip; the body slip angle β is fixed by the steering angle.

use super::cr_state::{CrState, DELTA, PSI, V};
use super::params::VehicleParams;

/// Body slip angle of the kinematic model, rad: β = atan(tan δ · l_r / l).
pub fn kinematic_slip_rad(p: &VehicleParams, steer_rad: f64) -> f64 {
    (steer_rad.tan() * p.lr_m / p.wheelbase_m()).atan()
}

/// Yaw rate of the kinematic model, rad/s: ψ' = v·cos β·tan δ / l.
pub fn kinematic_yaw_rate_radps(p: &VehicleParams, speed_mps: f64, steer_rad: f64) -> f64 {
    speed_mps * kinematic_slip_rad(p, steer_rad).cos() * steer_rad.tan() / p.wheelbase_m()
}

/// Time derivative of the CommonRoad state `[x, y, δ, v, ψ, ψ', β]` under the kinematic model,
/// for inputs already inside their constraints. The yaw-rate and slip entries are 0: in this
/// model they are functions of (v, δ), set after each step.
pub fn ks_cog_rhs(p: &VehicleParams, x: &CrState, steer_rate_radps: f64, accel_mps2: f64) -> CrState {
    let beta = kinematic_slip_rad(p, x[DELTA]);
    let v = x[V];
    [
        v * (beta + x[PSI]).cos(),
        v * (beta + x[PSI]).sin(),
        steer_rate_radps,
        accel_mps2,
        kinematic_yaw_rate_radps(p, v, x[DELTA]),
        0.0,
        0.0,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinematic_turn_radius_matches_geometry() {
        // Steady turn: the centre of gravity moves on a circle of radius l_r / sin β
        // (the instantaneous centre lies on the rear-axle line).
        let p = VehicleParams::bmw_320i();
        let delta = 0.1;
        let v = 5.0;
        let beta = kinematic_slip_rad(&p, delta);
        let radius = v / kinematic_yaw_rate_radps(&p, v, delta);
        assert!((radius - p.lr_m / beta.sin()).abs() < 1e-9, "radius {radius}");
        // Rear-axle radius l / tan δ (CommonRoad KS, rear-axle reference).
        assert!((radius * beta.cos() - p.wheelbase_m() / delta.tan()).abs() < 1e-9);
    }
}
