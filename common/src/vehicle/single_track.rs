//! Dynamic single-track (bicycle) model: CommonRoad's ST model with friction-limited tyres.
//!
//! Equations from Althoff & Würsching, "CommonRoad: Vehicle Models" (2020a) §7, as implemented
//! in `vehiclemodels/vehicle_dynamics_st.py` (commonroad-vehicle-models 3.0.2). State (CommonRoad
//! order) `[x, y, δ, v, ψ, ψ', β]`, reference point the centre of gravity; inputs the steering
//! velocity and the longitudinal acceleration.
//!
//! CommonRoad writes the model in closed form; we write the same equations in force form
//! (identical algebra), because that is where the friction limit goes:
//! - normal loads with longitudinal load transfer: `F_zf = m(g·l_r − a·h)/l`,
//!   `F_zr = m(g·l_f + a·h)/l` (h the sprung-mass CoG height, as the reference code uses);
//! - linear tyres scaled by the road friction: `F_yi = μ·C_Si·F_zi·α_i` with slip angles
//!   `α_f = δ − β − l_f·ψ'/v`, `α_r = −β + l_r·ψ'/v`;
//! - `ψ'' = (l_f·F_yf − l_r·F_yr)/I_z`, `β' = (F_yf + F_yr)/(m·v) − ψ'`.
//!
//! Friction circle (ours, not in CommonRoad, whose tyres never saturate): the longitudinal
//! force m·a is shared between the axles in proportion to their normal loads (ideal brake
//! distribution), so each axle uses the fraction |a|/g of its load longitudinally and keeps
//! `F_zi·√(μ² − (a/g)²)` for cornering: each `F_yi` is clamped to that. Longitudinal demand has
//! priority (the caller caps |a| ≤ μ·g), and the combined force of each axle stays inside its
//! circle of radius μ·F_zi. Within the linear range the model is exactly CommonRoad's.
//!
//! Below |v| = 0.1 m/s the slip angles are singular; as CommonRoad does, we switch to the
//! kinematic model (reference point the centre of gravity) with its yaw-rate and slip dynamics.

use super::actuator::{commonroad_accel_constraint, commonroad_steering_constraint};
use super::cr_state::{BETA, CrState, DELTA, PSI, V, YAW_RATE};
use super::kinematic::ks_cog_rhs;
use super::params::{GRAVITY_MPS2, VehicleParams};

/// Speed below which the model switches to kinematic equations, m/s (CommonRoad's value).
pub const KINEMATIC_SWITCH_MPS: f64 = 0.1;

/// Normal loads on the front and rear axle, N, with load transfer at longitudinal accel `a`.
pub fn axle_loads_n(p: &VehicleParams, accel_mps2: f64) -> (f64, f64) {
    let l = p.wheelbase_m();
    let front = p.mass_kg * (GRAVITY_MPS2 * p.lr_m - accel_mps2 * p.h_s_m) / l;
    let rear = p.mass_kg * (GRAVITY_MPS2 * p.lf_m + accel_mps2 * p.h_s_m) / l;
    (front, rear)
}

/// Lateral tyre forces of the front and rear axle, N, friction-limited (see module docs).
/// Needs |v| ≥ [`KINEMATIC_SWITCH_MPS`].
pub fn lateral_forces_n(p: &VehicleParams, mu: f64, x: &CrState, accel_mps2: f64) -> (f64, f64) {
    let (fz_f, fz_r) = axle_loads_n(p, accel_mps2);
    let v = x[V];
    let alpha_f = x[DELTA] - x[BETA] - p.lf_m * x[YAW_RATE] / v;
    let alpha_r = -x[BETA] + p.lr_m * x[YAW_RATE] / v;
    let a_g = accel_mps2 / GRAVITY_MPS2;
    let lateral_share = (mu * mu - a_g * a_g).max(0.0).sqrt();
    let fy_f = mu * p.c_sf_per_rad * fz_f * alpha_f;
    let fy_r = mu * p.c_sr_per_rad * fz_r * alpha_r;
    let lim_f = lateral_share * fz_f.max(0.0);
    let lim_r = lateral_share * fz_r.max(0.0);
    (fy_f.clamp(-lim_f, lim_f), fy_r.clamp(-lim_r, lim_r))
}

/// Time derivative of the ST state for inputs already inside their constraints (steering
/// velocity, rad/s; longitudinal acceleration, m/s²) on a road of friction `mu`.
pub fn st_rhs(p: &VehicleParams, mu: f64, x: &CrState, steer_rate_radps: f64, accel_mps2: f64) -> CrState {
    let v = x[V];
    if v.abs() < KINEMATIC_SWITCH_MPS {
        return low_speed_rhs(p, x, steer_rate_radps, accel_mps2);
    }
    let (fy_f, fy_r) = lateral_forces_n(p, mu, x, accel_mps2);
    let course = x[PSI] + x[BETA];
    [
        v * course.cos(),
        v * course.sin(),
        steer_rate_radps,
        accel_mps2,
        x[YAW_RATE],
        (p.lf_m * fy_f - p.lr_m * fy_r) / p.iz_kgm2,
        (fy_f + fy_r) / (p.mass_kg * v) - x[YAW_RATE],
    ]
}

/// CommonRoad's low-speed branch: kinematic motion of the centre of gravity, plus the time
/// derivatives of the kinematic slip angle and yaw rate so that ψ' and β stay continuous.
fn low_speed_rhs(p: &VehicleParams, x: &CrState, steer_rate_radps: f64, accel_mps2: f64) -> CrState {
    let mut f = ks_cog_rhs(p, x, steer_rate_radps, accel_mps2);
    let l = p.wheelbase_m();
    let (delta, v, beta) = (x[DELTA], x[V], x[BETA]);
    let (tan_d, cos_d) = (delta.tan(), delta.cos());
    // d/dt atan(tan δ · l_r/l). CommonRoad 3.0.2 writes (tan²δ·l_r/l)² in the denominator, a typo
    // for (tan δ·l_r/l)²; we use the exact derivative (identical at δ = 0).
    let ratio = tan_d * p.lr_m / l;
    let d_beta = p.lr_m * steer_rate_radps / (l * cos_d * cos_d * (1.0 + ratio * ratio));
    let dd_psi = (accel_mps2 * beta.cos() * tan_d - v * beta.sin() * d_beta * tan_d
        + v * beta.cos() * steer_rate_radps / (cos_d * cos_d))
        / l;
    f[YAW_RATE] = dd_psi;
    f[BETA] = d_beta;
    f
}

/// Right-hand side of CommonRoad's `vehicle_dynamics_st(x, u, p)` with its input constraints
/// applied: `u = [steering velocity, longitudinal acceleration]`, friction `mu`.
pub fn commonroad_st_rhs(p: &VehicleParams, mu: f64, x: &CrState, u: [f64; 2]) -> CrState {
    let steer_rate = commonroad_steering_constraint(p, x[DELTA], u[0]);
    let accel = commonroad_accel_constraint(p, x[V], u[1]);
    st_rhs(p, mu, x, steer_rate, accel)
}

/// One classic fourth-order Runge–Kutta step of [`commonroad_st_rhs`] with inputs held
/// constant: the scheme of the reference trajectory in `tests/peers/vehicle_st_reference.py`.
pub fn commonroad_st_rk4_step(p: &VehicleParams, mu: f64, x: &CrState, u: [f64; 2], dt_s: f64) -> CrState {
    rk4(x, dt_s, |s| commonroad_st_rhs(p, mu, s, u))
}

/// Classic RK4 on a fixed-size state; no allocation.
pub(crate) fn rk4<const N: usize>(x: &[f64; N], h: f64, f: impl Fn(&[f64; N]) -> [f64; N]) -> [f64; N] {
    let axpy = |a: &[f64; N], k: &[f64; N], s: f64| -> [f64; N] { std::array::from_fn(|i| a[i] + s * k[i]) };
    let k1 = f(x);
    let k2 = f(&axpy(x, &k1, 0.5 * h));
    let k3 = f(&axpy(x, &k2, 0.5 * h));
    let k4 = f(&axpy(x, &k3, h));
    std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CommonRoad ST reference: `vehicle_dynamics_st` + `parameters_vehicle2` of
    /// commonroad-vehicle-models 3.0.2, fixed-step RK4, dt = 0.01 s, from x0 = [0,0,0,15,0,0,0],
    /// u = [0.05, 1.0] for t < 1 s then [−0.05, −2.0]. Produced by
    /// `/tmp/venv-cr/bin/python tests/peers/vehicle_st_reference.py` (see its docstring).
    const REFERENCE: [(f64, CrState); 6] = [
        (
            0.50,
            [
                7.624249008504435,
                0.08012045143110892,
                0.02500000000000002,
                15.49999999999999,
                0.0271607236647822,
                0.12385841668672155,
                0.004310629034104601,
            ],
        ),
        (
            1.00,
            [
                15.472840321046451,
                0.6811830754232739,
                0.05000000000000004,
                15.999999999999979,
                0.1264904235886954,
                0.2748668199014561,
                0.006731698909415488,
            ],
        ),
        (
            1.50,
            [
                23.06549711459463,
                2.208826599898195,
                0.025000000000000015,
                15.0,
                0.25698838116482436,
                0.18558412577577638,
                0.000592152544146452,
            ],
        ),
        (
            2.00,
            [
                30.014325678036776,
                4.274068655462993,
                -3.469446951953614e-18,
                14.000000000000021,
                0.3077450515878667,
                0.021379178606980704,
                -0.0011555907612711828,
            ],
        ),
        (
            2.50,
            [
                36.46691550602279,
                6.254678702728905,
                -0.025000000000000022,
                13.000000000000043,
                0.2825050049836408,
                -0.11825379786969101,
                -0.0059608882581979284,
            ],
        ),
        (
            3.00,
            [
                42.544310080554716,
                7.702851830758757,
                -0.050000000000000044,
                12.000000000000064,
                0.1934820526967847,
                -0.23393770428869592,
                -0.013531531373542656,
            ],
        ),
    ];

    #[test]
    fn agrees_with_commonroad_st() {
        let p = VehicleParams::bmw_320i();
        // The reference runs on the package's nominal friction μ = p_dy1.
        let mu = p.mu_nominal;
        let mut x: CrState = [0.0, 0.0, 0.0, 15.0, 0.0, 0.0, 0.0];
        let mut checked = 0;
        for k in 0..300 {
            let u = if k < 100 { [0.05, 1.0] } else { [-0.05, -2.0] };
            x = commonroad_st_rk4_step(&p, mu, &x, u, 0.01);
            let t = (k + 1) as f64 * 0.01;
            for (t_ref, x_ref) in REFERENCE.iter().filter(|(t_ref, _)| (t_ref - t).abs() < 1e-9) {
                for i in 0..7 {
                    assert!(
                        (x[i] - x_ref[i]).abs() < 1e-9,
                        "t={t_ref} state[{i}]: ours {} reference {}",
                        x[i],
                        x_ref[i]
                    );
                }
                checked += 1;
            }
        }
        assert_eq!(checked, REFERENCE.len());
    }

    #[test]
    fn load_transfer_and_friction_circle() {
        let p = VehicleParams::bmw_320i();
        let weight_n = p.mass_kg * GRAVITY_MPS2;
        let (f, r) = axle_loads_n(&p, -5.0);
        assert!((f + r - weight_n).abs() < 1e-6, "loads sum to the weight");
        assert!(f > weight_n * p.lr_m / p.wheelbase_m(), "braking loads the front axle");
        // A large slip angle saturates both axles at F_z·√(μ² − (a/g)²).
        let mu = 0.5;
        let a = -3.0;
        let x: CrState = [0.0, 0.0, 0.3, 10.0, 0.0, 0.0, -0.3];
        let (fy_f, fy_r) = lateral_forces_n(&p, mu, &x, a);
        let share = (mu * mu - (a / GRAVITY_MPS2).powi(2)).sqrt();
        let (fz_f, fz_r) = axle_loads_n(&p, a);
        assert!((fy_f - share * fz_f).abs() < 1e-9 && (fy_r - share * fz_r).abs() < 1e-9);
        // Combined force per axle on its friction circle: (a/g·F_z)² + F_y² = (μ·F_z)².
        assert!(((a / GRAVITY_MPS2 * fz_f).hypot(fy_f) - mu * fz_f).abs() < 1e-6);
    }
}
