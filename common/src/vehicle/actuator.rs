//! Actuators: turn a driver's (or a learned policy's) commands into the CommonRoad model inputs,
//! steering velocity and longitudinal acceleration demand.
//!
//! Steering is an angle servo: the commanded angle is clamped to the steering range and tracked
//! at most at the maximum steering rate. Throttle and brake map to an acceleration demand; the
//! demand reaches the wheels through a first-order lag (integrated with the vehicle state, see
//! `dynamics`). Commands are sanitised first because they may come from a learned policy: NaN
//! becomes 0 and values are clamped to their ranges.

use super::params::VehicleParams;

/// One control command: front-wheel steering angle, throttle and brake pedal positions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Controls {
    /// Commanded front-wheel steering angle, rad (positive turns left).
    pub steer_rad: f64,
    /// Throttle pedal in [0, 1].
    pub throttle: f64,
    /// Brake pedal in [0, 1].
    pub brake: f64,
}

/// NaN → 0, ±inf and everything else clamped to `[lo, hi]`.
fn clean(v: f64, lo: f64, hi: f64) -> f64 {
    if v.is_nan() { 0.0 } else { v.clamp(lo, hi) }
}

impl Controls {
    /// A command with the given steering angle, throttle and brake.
    pub fn new(steer_rad: f64, throttle: f64, brake: f64) -> Self {
        Self { steer_rad, throttle, brake }
    }

    /// The command with NaN replaced by 0 and every field clamped to its range.
    pub fn sanitized(&self, p: &VehicleParams) -> Self {
        Self {
            steer_rad: clean(self.steer_rad, p.steer_min_rad, p.steer_max_rad),
            throttle: clean(self.throttle, 0.0, 1.0),
            brake: clean(self.brake, 0.0, 1.0),
        }
    }
}

/// Steering velocity that moves the wheels from `steer_rad` toward the (sanitised) command
/// within `dt_s`, limited to the maximum steering rate. Held constant over the step, it lands
/// exactly on the command when the rate allows.
pub fn steering_rate_radps(p: &VehicleParams, steer_rad: f64, command_rad: f64, dt_s: f64) -> f64 {
    let rate = (command_rad - steer_rad) / dt_s;
    clean(rate, -p.steer_rate_max_radps, p.steer_rate_max_radps)
}

/// Longitudinal acceleration demand, m/s², for sanitised pedals at speed `speed_mps`.
///
/// Throttle scales the drive limit of CommonRoad's acceleration constraint (`a_max`, and
/// `a_max·v_switch/v` above `v_switch`: constant power); brake scales `brake_decel_max_mps2`.
/// Pressing both gives their sum.
pub fn accel_demand_mps2(p: &VehicleParams, c: &Controls, speed_mps: f64) -> f64 {
    c.throttle * drive_limit_mps2(p, speed_mps) - c.brake * p.brake_decel_max_mps2
}

/// Positive acceleration limit of CommonRoad's `acceleration_constraints`, m/s².
pub fn drive_limit_mps2(p: &VehicleParams, speed_mps: f64) -> f64 {
    if speed_mps > p.v_switch_mps { p.a_max_mps2 * p.v_switch_mps / speed_mps } else { p.a_max_mps2 }
}

/// CommonRoad `acceleration_constraints(velocity, acceleration, p.longitudinal)`, verbatim.
pub fn commonroad_accel_constraint(p: &VehicleParams, speed_mps: f64, accel_mps2: f64) -> f64 {
    let pos_limit = drive_limit_mps2(p, speed_mps);
    if (speed_mps <= p.v_min_mps && accel_mps2 <= 0.0) || (speed_mps >= p.v_max_mps && accel_mps2 >= 0.0) {
        0.0
    } else if accel_mps2 <= -p.a_max_mps2 {
        -p.a_max_mps2
    } else if accel_mps2 >= pos_limit {
        pos_limit
    } else {
        accel_mps2
    }
}

/// CommonRoad `steering_constraints(steering_angle, steering_velocity, p.steering)`, verbatim.
pub fn commonroad_steering_constraint(p: &VehicleParams, steer_rad: f64, steer_rate_radps: f64) -> f64 {
    if (steer_rad <= p.steer_min_rad && steer_rate_radps <= 0.0)
        || (steer_rad >= p.steer_max_rad && steer_rate_radps >= 0.0)
    {
        0.0
    } else if steer_rate_radps <= -p.steer_rate_max_radps {
        -p.steer_rate_max_radps
    } else if steer_rate_radps >= p.steer_rate_max_radps {
        p.steer_rate_max_radps
    } else {
        steer_rate_radps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sanitize_replaces_nan_and_clamps() {
        let p = VehicleParams::bmw_320i();
        let c = Controls::new(f64::NAN, f64::INFINITY, -3.0).sanitized(&p);
        assert_eq!(c, Controls::new(0.0, 1.0, 0.0));
        let c = Controls::new(5.0, f64::NAN, f64::NEG_INFINITY).sanitized(&p);
        assert_eq!(c, Controls::new(1.066, 0.0, 0.0));
    }

    #[test]
    fn steering_rate_is_limited() {
        let p = VehicleParams::bmw_320i();
        // 0.3 rad in 0.1 s would be 3 rad/s: limited to 0.4 rad/s.
        assert_eq!(steering_rate_radps(&p, 0.0, 0.3, 0.1), 0.4);
        assert_eq!(steering_rate_radps(&p, 0.0, -0.3, 0.1), -0.4);
        // A small correction is reached exactly within the step.
        assert!((steering_rate_radps(&p, 0.1, 0.102, 0.1) - 0.02).abs() < 1e-12);
    }

    #[test]
    fn drive_demand_follows_commonroad_power_limit() {
        let p = VehicleParams::bmw_320i();
        let full = Controls::new(0.0, 1.0, 0.0);
        assert_eq!(accel_demand_mps2(&p, &full, 5.0), 11.5);
        // Above v_switch = 7.319 m/s: a ≤ a_max·v_switch/v = 11.5·7.319/20 = 4.208 m/s².
        assert!((accel_demand_mps2(&p, &full, 20.0) - 4.208425).abs() < 1e-6);
        assert_eq!(accel_demand_mps2(&p, &Controls::new(0.0, 0.0, 1.0), 20.0), -11.0);
        assert_eq!(commonroad_accel_constraint(&p, 20.0, 9.0), accel_demand_mps2(&p, &full, 20.0));
        assert_eq!(commonroad_accel_constraint(&p, 60.0, 1.0), 0.0);
        assert_eq!(commonroad_steering_constraint(&p, 1.066, 0.1), 0.0);
        assert_eq!(commonroad_steering_constraint(&p, 0.0, -1.0), -0.4);
    }
}
