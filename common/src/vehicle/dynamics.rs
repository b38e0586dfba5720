//! The ego [`Vehicle`]: one state, two models (kinematic or dynamic single-track), actuators
//! in front, stepped with fixed-step RK4.
//!
//! Each `step(controls, mu, dt)`:
//! 1. sanitises the controls (NaN → 0, clamped) and the friction (NaN → [`MU_MIN`]);
//! 2. turns them into a steering velocity (rate-limited servo) and an acceleration demand,
//!    both held constant over the step;
//! 3. integrates `[x, y, δ, v, ψ, ψ', β, a_act]` with RK4, where `a_act` is the actuator
//!    output following the demand through a first-order lag `a_act' = (a_dem − a_act)/τ`, and
//!    the wheels get `a = clamp(a_act, ±μ·g)` (friction circle; the ST model also limits the
//!    lateral tyre forces, see `single_track`);
//! 4. splits `dt` into equal sub-steps no longer than 10 ms and short enough for RK4 to stay
//!    stable on the ST lateral modes, whose eigenvalues grow like μ·g·C_S/v at low speed.
//!
//! The car never reverses: braking holds it at v = 0 (CommonRoad's `v_min` is not used).
//! State positions are the centre of gravity (CommonRoad's reference point); [`Vehicle::pose`]
//! is the footprint centre, offset by `params.centre_ahead_of_cog_m` along the heading.

use super::actuator::{Controls, accel_demand_mps2, steering_rate_radps};
use super::cr_state::{BETA, CrState, DELTA, PSI, V, YAW_RATE};
use super::kinematic::{kinematic_slip_rad, kinematic_yaw_rate_radps, ks_cog_rhs};
use super::params::{GRAVITY_MPS2, VehicleParams};
use super::single_track::{KINEMATIC_SWITCH_MPS, lateral_forces_n, rk4, st_rhs};
use crate::geometry::{Obb, Pose, Vec2, wrap_angle};

/// Lowest friction coefficient accepted; NaN or smaller values are raised to it (worst case).
pub const MU_MIN: f64 = 0.01;
/// Highest friction coefficient accepted (racing slicks reach about 1.7).
pub const MU_MAX: f64 = 2.0;
/// Longest step accepted, s; longer steps are clamped to it.
pub const MAX_STEP_S: f64 = 1.0;
/// Longest RK4 sub-step, s.
const MAX_SUBSTEP_S: f64 = 0.01;
/// RK4 is stable for h·|λ| ≤ 2.78 on the negative real axis; keep a margin.
const RK4_STABLE_H_LAMBDA: f64 = 2.0;
/// Cap on sub-steps per step (reached only for steps near `MAX_STEP_S` at crawling speed).
const MAX_SUBSTEPS: usize = 2048;

/// Which equations of motion the vehicle uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// CommonRoad KS model (centre-of-gravity reference): no tyre slip; friction caps |a| ≤ μ·g.
    Kinematic,
    /// CommonRoad ST model with friction-limited linear tyres and load transfer.
    SingleTrack,
}

/// The vehicle state; positions are the centre of gravity.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleState {
    /// Centre-of-gravity x in the world frame, m.
    pub x_m: f64,
    /// Centre-of-gravity y in the world frame, m.
    pub y_m: f64,
    /// Yaw angle ψ, rad (not wrapped, so that it stays continuous).
    pub heading_rad: f64,
    /// Speed of the centre of gravity, m/s (never negative).
    pub speed_mps: f64,
    /// Yaw rate ψ', rad/s.
    pub yaw_rate_radps: f64,
    /// Body slip angle β between heading and velocity, rad.
    pub slip_angle_rad: f64,
    /// Front-wheel steering angle δ, rad.
    pub steer_rad: f64,
    /// Longitudinal acceleration applied at the wheels in the last step, m/s².
    pub accel_mps2: f64,
}

/// An ego vehicle: parameters, model choice and state.
#[derive(Debug, Clone, PartialEq)]
pub struct Vehicle {
    pub params: VehicleParams,
    pub model: ModelKind,
    pub state: VehicleState,
    /// Actuator output a_act (lag state), m/s²; differs from `state.accel_mps2` at standstill.
    actuator_accel_mps2: f64,
    /// Lateral acceleration at the end of the last step, m/s².
    lateral_accel_mps2: f64,
}

/// Integration state: CommonRoad's seven plus the actuator output.
type SimState = [f64; 8];
const A_ACT: usize = 7;

fn finite_or(v: f64, fallback: f64) -> f64 {
    if v.is_finite() { v } else { fallback }
}

impl Vehicle {
    /// A vehicle whose footprint centre is at `pose`, driving straight at `speed_mps`
    /// (clamped to [0, v_max]; NaN → 0). Non-finite pose fields become 0.
    pub fn new(params: VehicleParams, model: ModelKind, pose: Pose, speed_mps: f64) -> Vehicle {
        let heading_rad = finite_or(pose.heading_rad, 0.0);
        let offset = params.centre_ahead_of_cog_m;
        let state = VehicleState {
            x_m: finite_or(pose.x_m, 0.0) - offset * heading_rad.cos(),
            y_m: finite_or(pose.y_m, 0.0) - offset * heading_rad.sin(),
            heading_rad,
            speed_mps: finite_or(speed_mps, 0.0).clamp(0.0, params.v_max_mps),
            ..VehicleState::default()
        };
        Vehicle { params, model, state, actuator_accel_mps2: 0.0, lateral_accel_mps2: 0.0 }
    }

    /// Footprint-centre pose, heading wrapped into (−π, π].
    pub fn pose(&self) -> Pose {
        let s = &self.state;
        let off = self.params.centre_ahead_of_cog_m;
        Pose::new(s.x_m + off * s.heading_rad.cos(), s.y_m + off * s.heading_rad.sin(), wrap_angle(s.heading_rad))
    }

    /// The body's oriented box.
    pub fn obb(&self) -> Obb {
        Obb::new(self.pose(), self.params.footprint())
    }

    /// World-frame velocity of the footprint centre, m/s: the centre-of-gravity velocity along
    /// the course ψ + β, plus the rigid-body term ψ' × r for the centre's offset r.
    pub fn velocity(&self) -> Vec2 {
        let s = &self.state;
        let course = s.heading_rad + s.slip_angle_rad;
        let v_cog = Vec2::new(course.cos(), course.sin()) * s.speed_mps;
        let r = self.params.centre_ahead_of_cog_m;
        v_cog + Vec2::new(-s.heading_rad.sin(), s.heading_rad.cos()) * (s.yaw_rate_radps * r)
    }

    /// Lateral acceleration at the end of the last step, m/s² (positive left): (F_yf + F_yr)/m
    /// for the single-track model, v·ψ' for the kinematic one and below 0.1 m/s.
    pub fn lateral_accel_mps2(&self) -> f64 {
        self.lateral_accel_mps2
    }

    /// Advances the vehicle by `dt_s` under `controls` on a road of friction `mu`.
    /// `dt_s` NaN or ≤ 0 leaves the vehicle unchanged; above [`MAX_STEP_S`] it is clamped.
    pub fn step(&mut self, controls: Controls, mu: f64, dt_s: f64) {
        if dt_s.is_nan() || dt_s <= 0.0 {
            return;
        }
        let dt_s = dt_s.min(MAX_STEP_S);
        let p = self.params;
        let mu = if mu.is_nan() { MU_MIN } else { mu.clamp(MU_MIN, MU_MAX) };
        let c = controls.sanitized(&p);
        let s = self.state;
        let steer_rate = steering_rate_radps(&p, s.steer_rad, c.steer_rad, dt_s);
        let demand = accel_demand_mps2(&p, &c, s.speed_mps);
        let n = self.substeps(mu, dt_s);
        let h = dt_s / n as f64;
        let mut x: SimState = [
            s.x_m,
            s.y_m,
            s.steer_rad,
            s.speed_mps,
            s.heading_rad,
            s.yaw_rate_radps,
            s.slip_angle_rad,
            self.actuator_accel_mps2,
        ];
        let model = self.model;
        for _ in 0..n {
            x = rk4(&x, h, |y| sim_rhs(&p, model, mu, y, steer_rate, demand));
            self.settle(&mut x, mu);
        }
        self.store(&x, mu);
    }

    /// Sub-steps for one step: h ≤ 10 ms and h·λ ≤ 2 for the ST lateral modes, whose fastest
    /// eigenvalue is bounded by μ·g·(C_Sf + C_Sr)/v (from the β' and ψ'' rows of the ST model).
    fn substeps(&self, mu: f64, dt_s: f64) -> usize {
        let mut n = (dt_s / MAX_SUBSTEP_S).ceil();
        if self.model == ModelKind::SingleTrack {
            let p = &self.params;
            // Lowest speed this step can reach, but never below the kinematic switch.
            let v_low = (self.state.speed_mps - p.a_max_mps2 * dt_s).max(KINEMATIC_SWITCH_MPS);
            let lambda = mu * GRAVITY_MPS2 * (p.c_sf_per_rad + p.c_sr_per_rad) / v_low;
            n = n.max((dt_s * lambda / RK4_STABLE_H_LAMBDA).ceil());
        }
        (n as usize).clamp(1, MAX_SUBSTEPS)
    }

    /// Keeps the state physical after a sub-step: no reverse, actuator output inside ±μ·g
    /// (anti-windup: ABS and traction control hold the wheels at the friction limit).
    fn settle(&self, x: &mut SimState, mu: f64) {
        let mu_g = mu * GRAVITY_MPS2;
        x[A_ACT] = x[A_ACT].clamp(-mu_g, mu_g);
        if x[V] <= 0.0 {
            x[V] = 0.0;
            x[YAW_RATE] = 0.0;
        }
        if self.model == ModelKind::Kinematic {
            x[YAW_RATE] = kinematic_yaw_rate_radps(&self.params, x[V], x[DELTA]);
            x[BETA] = kinematic_slip_rad(&self.params, x[DELTA]);
        }
    }

    fn store(&mut self, x: &SimState, mu: f64) {
        let p = &self.params;
        let accel = applied_accel_mps2(p, mu, x);
        self.state = VehicleState {
            x_m: x[0],
            y_m: x[1],
            heading_rad: x[PSI],
            speed_mps: x[V],
            yaw_rate_radps: x[YAW_RATE],
            slip_angle_rad: x[BETA],
            steer_rad: x[DELTA],
            accel_mps2: accel,
        };
        self.actuator_accel_mps2 = x[A_ACT];
        self.lateral_accel_mps2 = if self.model == ModelKind::SingleTrack && x[V] >= KINEMATIC_SWITCH_MPS {
            let cr: CrState = std::array::from_fn(|i| x[i]);
            let (fy_f, fy_r) = lateral_forces_n(p, mu, &cr, accel);
            (fy_f + fy_r) / p.mass_kg
        } else {
            x[V] * x[YAW_RATE]
        };
    }
}

/// Acceleration the wheels deliver: actuator output within ±μ·g, zero when it would push the
/// car into reverse or past v_max.
fn applied_accel_mps2(p: &VehicleParams, mu: f64, x: &SimState) -> f64 {
    let mu_g = mu * GRAVITY_MPS2;
    let a = x[A_ACT].clamp(-mu_g, mu_g);
    if (x[V] <= 0.0 && a < 0.0) || (x[V] >= p.v_max_mps && a > 0.0) { 0.0 } else { a }
}

fn sim_rhs(p: &VehicleParams, model: ModelKind, mu: f64, x: &SimState, steer_rate: f64, demand: f64) -> SimState {
    let a = applied_accel_mps2(p, mu, x);
    let cr: CrState = std::array::from_fn(|i| x[i]);
    let f = match model {
        ModelKind::Kinematic => ks_cog_rhs(p, &cr, steer_rate, a),
        ModelKind::SingleTrack => st_rhs(p, mu, &cr, steer_rate, a),
    };
    let mut out = [0.0; 8];
    out[..7].copy_from_slice(&f);
    out[A_ACT] = (demand - x[A_ACT]) / p.accel_lag_s;
    out
}

#[cfg(test)]
#[path = "dynamics_tests.rs"]
mod tests;
