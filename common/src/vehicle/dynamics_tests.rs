//! Physics tests of the stepped [`Vehicle`]: braking distance against the analytic value,
//! kinematic/dynamic agreement, low-friction cornering, actuator limits and bad input.

use super::*;

const DT_S: f64 = 0.01;

fn car(model: ModelKind, speed_mps: f64) -> Vehicle {
    Vehicle::new(VehicleParams::bmw_320i(), model, Pose::new(0.0, 0.0, 0.0), speed_mps)
}

/// Stopping distance under a brake step: the actuator output follows −B(1 − e^(−t/τ)) until it
/// reaches the friction limit μ·g at t₁ = −τ·ln(1 − μg/B), then holds it. Phase 1 (closed form
/// of the lagged deceleration): v₁ = v₀ − B(t₁ − τ·e₁), x₁ = v₀t₁ − B(t₁²/2 − τt₁ + τ²·e₁) with
/// e₁ = 1 − e^(−t₁/τ) = μg/B; phase 2 at constant μ·g: v₁²/(2μg). The lag allowance is the
/// excess over v₀²/(2μg).
fn analytic_stop_m(v0: f64, brake_mps2: f64, mu_g: f64, tau_s: f64) -> f64 {
    assert!(brake_mps2 > mu_g, "formula for a friction-limited brake");
    let e1 = mu_g / brake_mps2;
    let t1 = -tau_s * (1.0 - e1).ln();
    let x1 = v0 * t1 - brake_mps2 * (0.5 * t1 * t1 - tau_s * t1 + tau_s * tau_s * e1);
    let v1 = v0 - brake_mps2 * (t1 - tau_s * e1);
    x1 + v1 * v1 / (2.0 * mu_g)
}

fn measured_stop_m(model: ModelKind, mu: f64) -> f64 {
    let mut v = car(model, 20.0);
    let x0_m = v.state.x_m;
    let full_brake = Controls::new(0.0, 0.0, 1.0);
    for _ in 0..2000 {
        v.step(full_brake, mu, DT_S);
        if v.state.speed_mps == 0.0 {
            break;
        }
    }
    assert_eq!(v.state.speed_mps, 0.0, "{model:?} stopped at μ={mu}");
    v.state.x_m - x0_m
}

#[test]
fn braking_distance_matches_mu_g_plus_lag() {
    let p = VehicleParams::bmw_320i();
    for model in [ModelKind::Kinematic, ModelKind::SingleTrack] {
        for mu in [0.9, 0.3] {
            let mu_g = mu * GRAVITY_MPS2;
            let ideal = 20.0 * 20.0 / (2.0 * mu_g);
            let analytic = analytic_stop_m(20.0, p.brake_decel_max_mps2, mu_g, p.accel_lag_s);
            let measured = measured_stop_m(model, mu);
            eprintln!(
                "{model:?} μ={mu}: measured {measured:.3} m, v²/(2μg) {ideal:.3} m, + lag {:.3} m = {analytic:.3} m",
                analytic - ideal
            );
            let rel = (measured - analytic).abs() / analytic;
            eprintln!("  relative error {rel:.1e}");
            assert!(rel < 0.005, "{model:?} μ={mu}: {measured} vs {analytic}");
            assert!(measured > ideal, "the lag adds distance");
        }
    }
}

#[test]
fn stopped_car_stays_stopped() {
    let mut v = car(ModelKind::SingleTrack, 3.0);
    for _ in 0..300 {
        v.step(Controls::new(0.2, 0.0, 1.0), 0.9, DT_S);
    }
    let rest = v.state;
    assert_eq!(rest.speed_mps, 0.0);
    for _ in 0..200 {
        v.step(Controls::new(0.2, 0.0, 1.0), 0.9, DT_S);
    }
    assert_eq!((v.state.x_m, v.state.y_m, v.state.speed_mps), (rest.x_m, rest.y_m, 0.0));
    assert_eq!(v.state.accel_mps2, 0.0, "no braking force at standstill");
    // Releasing the brake and pressing the throttle drives forward again.
    for _ in 0..100 {
        v.step(Controls::new(0.0, 0.5, 0.0), 0.9, DT_S);
    }
    assert!(v.state.speed_mps > 1.0, "speed {}", v.state.speed_mps);
}

/// Position gap between the two models after 5 s at constant speed and steering command.
fn ks_st_gap_m(speed_mps: f64) -> f64 {
    let mut ks = car(ModelKind::Kinematic, speed_mps);
    let mut st = car(ModelKind::SingleTrack, speed_mps);
    let c = Controls::new(0.05, 0.0, 0.0);
    for _ in 0..500 {
        ks.step(c, 0.9, DT_S);
        st.step(c, 0.9, DT_S);
    }
    assert!(ks.state.y_m > 0.02 * speed_mps * speed_mps, "the car turned");
    assert!((ks.state.heading_rad - st.state.heading_rad).abs() < 0.01);
    (ks.pose().position() - st.pose().position()).norm()
}

#[test]
fn kinematic_and_single_track_agree_at_low_speed() {
    let gap_5 = ks_st_gap_m(5.0);
    let gap_2_5 = ks_st_gap_m(2.5);
    eprintln!("δ=0.05 rad, 5 s: KS–ST position gap {gap_5:.4} m at 5 m/s (25 m path), {gap_2_5:.4} m at 2.5 m/s");
    assert!(gap_5 < 0.2, "gap {gap_5}");
    // The ST slip angle departs from the kinematic one by ≈ v²/(μ·C_S·g·R) (tyre compliance):
    // halving the speed must shrink the gap (to about a quarter, over half the distance).
    assert!(gap_2_5 < 0.25 * gap_5, "gap {gap_2_5} vs {gap_5}");
}

/// Radius of the circle through three points.
fn circumradius_m(a: Vec2, b: Vec2, c: Vec2) -> f64 {
    let (ab, bc, ca) = ((b - a).norm(), (c - b).norm(), (a - c).norm());
    let cross = (b - a).perp(&(c - a)).abs();
    ab * bc * ca / (2.0 * cross)
}

/// Drives a steady circle at 12 m/s with δ = 0.11 rad; returns the path radius over the last
/// 3 s and the largest acceleration magnitude, from the second difference of the CoG positions
/// (coasting at constant speed, so it is all lateral).
fn circle_run(mu: f64) -> (f64, f64) {
    let mut v = car(ModelKind::SingleTrack, 12.0);
    let c = Controls::new(0.11, 0.0, 0.0);
    let mut pts = [Vec2::zeros(); 3];
    let mut prev = [Vec2::zeros(); 2];
    let mut max_lat = 0.0_f64;
    for k in 1..=800 {
        v.step(c, mu, DT_S);
        let p = Vec2::new(v.state.x_m, v.state.y_m);
        if k >= 3 {
            max_lat = max_lat.max(((p - 2.0 * prev[1] + prev[0]) / (DT_S * DT_S)).norm());
        }
        prev = [prev[1], p];
        match k {
            500 => pts[0] = p,
            650 => pts[1] = p,
            800 => pts[2] = p,
            _ => {}
        }
        // The force-based lateral acceleration stays inside the friction circle at every step.
        assert!(v.lateral_accel_mps2().abs() <= mu * GRAVITY_MPS2 + 1e-9);
    }
    (circumradius_m(pts[0], pts[1], pts[2]), max_lat)
}

#[test]
fn low_friction_cannot_hold_the_tight_circle() {
    let (r_dry, lat_dry) = circle_run(0.9);
    let (r_low, lat_low) = circle_run(0.3);
    let p = VehicleParams::bmw_320i();
    let r_kin = p.wheelbase_m() / (kinematic_slip_rad(&p, 0.11).cos() * 0.11_f64.tan());
    eprintln!(
        "12 m/s, δ=0.11: radius μ=0.9 {r_dry:.2} m (kinematic {r_kin:.2} m), μ=0.3 {r_low:.2} m; \
         max |a| μ=0.9 {lat_dry:.3}, μ=0.3 {lat_low:.3} m/s² (0.3g = {:.3})",
        0.3 * GRAVITY_MPS2
    );
    // Dry: the linear tyres hold the circle, near the kinematic radius (CommonRoad's equal
    // normalised stiffnesses make the car neutral-steering).
    assert!((r_dry - r_kin).abs() < 0.05 * r_kin, "dry radius {r_dry} vs {r_kin}");
    // Low μ: the tyres saturate, the path widens to at least v²/(μg).
    assert!(r_low > 1.5 * r_dry, "low-μ radius {r_low}");
    assert!(r_low > 0.97 * 144.0 / (0.3 * GRAVITY_MPS2), "low-μ radius {r_low}");
    assert!(lat_low < 1.03 * 0.3 * GRAVITY_MPS2, "lateral accel {lat_low}");
    assert!(lat_dry > 0.5 * GRAVITY_MPS2, "dry lateral accel {lat_dry}");
}

#[test]
fn steering_rate_and_range_are_limited() {
    let p = VehicleParams::bmw_320i();
    for model in [ModelKind::Kinematic, ModelKind::SingleTrack] {
        let mut v = car(model, 10.0);
        let mut prev = v.state.steer_rad;
        for _ in 0..100 {
            v.step(Controls::new(2.0, 0.0, 0.0), 0.9, DT_S);
            assert!(v.state.steer_rad - prev <= p.steer_rate_max_radps * DT_S + 1e-12);
            prev = v.state.steer_rad;
        }
        // One second at 0.4 rad/s.
        assert!((v.state.steer_rad - 0.4).abs() < 1e-9, "{}", v.state.steer_rad);
        for _ in 0..300 {
            v.step(Controls::new(2.0, 0.0, 0.0), 0.9, DT_S);
        }
        assert!((v.state.steer_rad - p.steer_max_rad).abs() < 1e-9, "held at the steering limit");
    }
}

#[test]
fn bad_input_never_poisons_the_state() {
    for model in [ModelKind::Kinematic, ModelKind::SingleTrack] {
        let mut v = Vehicle::new(VehicleParams::bmw_320i(), model, Pose::new(f64::NAN, 1.0, f64::INFINITY), f64::NAN);
        let bad = [
            Controls::new(f64::NAN, f64::NAN, f64::NAN),
            Controls::new(f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY),
            Controls::new(-1e300, 7.0, -2.0),
        ];
        for (k, c) in bad.iter().cycle().take(600).enumerate() {
            let mu = [f64::NAN, 0.0, -1.0, f64::INFINITY, 0.9][k % 5];
            let dt = [DT_S, f64::NAN, -0.1, 0.0, 1e9][k % 4];
            v.step(*c, mu, dt);
            let s = v.state;
            let all = [
                s.x_m,
                s.y_m,
                s.heading_rad,
                s.speed_mps,
                s.yaw_rate_radps,
                s.slip_angle_rad,
                s.steer_rad,
                s.accel_mps2,
            ];
            assert!(all.iter().all(|x| x.is_finite()), "{model:?} step {k}: {s:?}");
            assert!(v.lateral_accel_mps2().is_finite() && s.speed_mps >= 0.0);
        }
    }
}

#[test]
fn pose_is_the_footprint_centre() {
    let p = VehicleParams::bmw_320i();
    let v = Vehicle::new(p, ModelKind::SingleTrack, Pose::new(10.0, 5.0, std::f64::consts::FRAC_PI_2), 8.0);
    let pose = v.pose();
    assert!((pose.x_m - 10.0).abs() < 1e-12 && (pose.y_m - 5.0).abs() < 1e-12);
    // The CoG sits (l_r − l_f)/2 = 0.133 m ahead of the centre, here along +y.
    assert!((v.state.y_m - 5.0 - 0.5 * (p.lr_m - p.lf_m)).abs() < 1e-12);
    let obb = v.obb();
    assert!((obb.half_length_m - 2.254).abs() < 1e-12 && obb.axis.y > 0.999);
    assert!((v.velocity() - Vec2::new(0.0, 8.0)).norm() < 1e-12);
}

#[test]
fn crawling_single_track_is_stable_at_any_step() {
    // At 0.5 m/s the ST lateral modes have eigenvalues near −700 1/s: plain RK4 at 10 ms would
    // blow up; the sub-stepping must keep it stable and close to the kinematic motion.
    let p = VehicleParams::bmw_320i();
    for dt in [0.01, 0.1] {
        let mut st = car(ModelKind::SingleTrack, 0.5);
        let mut ks = car(ModelKind::Kinematic, 0.5);
        let steps = (5.0 / dt) as usize;
        for _ in 0..steps {
            st.step(Controls::new(0.1, 0.0, 0.0), 0.9, dt);
            ks.step(Controls::new(0.1, 0.0, 0.0), 0.9, dt);
        }
        // δ small enough that the ST small-angle form (v·δ/l) and the kinematic
        // v·cos β·tan δ/l agree to 0.1 %.
        let kin_yaw = kinematic_yaw_rate_radps(&p, 0.5, 0.1);
        assert!((st.state.yaw_rate_radps - kin_yaw).abs() < 0.01 * kin_yaw, "dt {dt}: {:?}", st.state);
        assert!((st.pose().position() - ks.pose().position()).norm() < 0.01, "dt {dt}");
    }
}

#[test]
fn full_throttle_is_power_limited_above_v_switch() {
    let p = VehicleParams::bmw_320i();
    let mut v = car(ModelKind::SingleTrack, 20.0);
    for _ in 0..100 {
        v.step(Controls::new(0.0, 1.0, 0.0), 0.9, DT_S);
    }
    // After 1 s (≫ τ) the acceleration tracks the power limit a_max·v_switch/v, trailing it by
    // the lag: a first-order lag follows a ramp τ·|d(limit)/dt| = τ·limit·a/v behind.
    let (a, speed) = (v.state.accel_mps2, v.state.speed_mps);
    let limit = p.a_max_mps2 * p.v_switch_mps / speed;
    let trail = p.accel_lag_s * limit * a / speed;
    assert!(a > limit && a - limit < 1.2 * trail, "{a} vs {limit} (+{trail})");
    // From rest, full throttle is capped by traction: μ·g, not a_max.
    let mut v = car(ModelKind::Kinematic, 0.0);
    for _ in 0..50 {
        v.step(Controls::new(0.0, 1.0, 0.0), 0.3, DT_S);
    }
    assert!((v.state.accel_mps2 - 0.3 * GRAVITY_MPS2).abs() < 1e-9, "{}", v.state.accel_mps2);
}
