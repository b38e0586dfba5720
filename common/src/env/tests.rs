//! Environment tests: shapes, determinism (also across thread counts), reward signs,
//! termination, and agreement with `episode::run`.

use super::*;
use crate::episode;
use crate::scenario::{ScenarioKind, ScenarioSpec, build, check_feasible, sample};
use crate::vehicle::Controls;
use std::collections::BTreeMap;

pub(super) fn spec(kind: ScenarioKind, params: &[(&str, f64)]) -> ScenarioSpec {
    let params: BTreeMap<String, f64> = params.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    let s = ScenarioSpec::new(kind, 7, params).expect("valid test spec");
    check_feasible(&s).expect("feasible test spec");
    s
}

/// A lead car braking hard right in front: full throttle must crash into it.
fn crash_spec() -> ScenarioSpec {
    spec(
        ScenarioKind::EmergencyBraking,
        &[
            ("ego_speed_mps", 20.0),
            ("initial_headway_m", 10.0),
            ("braking_decel_mps2", 8.0),
            ("brake_time_s", 0.5),
            ("friction_mu", 1.0),
        ],
    )
}

/// A simple lane-keeping controller on the observation: steer against e_y and e_ψ, hold speed.
fn keep_lane(o: &[f32; OBS_DIM]) -> [f32; ACT_DIM] {
    let steer = -0.8 * o[3] - 1.5 * o[4];
    let speed_err = o[10] - o[0];
    [steer.clamp(-1.0, 1.0), (4.0 * speed_err).clamp(0.0, 1.0), (-4.0 * speed_err).clamp(0.0, 1.0)]
}

#[test]
fn observations_are_finite_and_scaled() {
    let s = sample(1, ScenarioKind::CutIn, 0);
    let mut obs = [0.0; OBS_DIM];
    let env = DrivingEnv::new(&s, TrainingReward::eq7(Variant::Full.weights()), &mut obs);
    assert!(obs.iter().all(|x| x.is_finite() && x.abs() <= 10.0), "{obs:?}");
    let w = env.world();
    assert!((obs[0] as f64 - w.ego.state.speed_mps / observe::SPEED_SCALE_MPS).abs() < 1e-6);
    assert!((obs[10] as f64 - w.desired_speed_mps / observe::SPEED_SCALE_MPS).abs() < 1e-6);
    assert!(obs[3].abs() < 0.05 && obs[4].abs() < 0.05, "starts centred and aligned: {obs:?}");
}

/// A slippery bend with a lead ahead in the ego lane and an empty lane beside it: the
/// preview, friction and side-lane features say so.
#[test]
fn observations_show_the_bend_ahead_the_friction_and_the_free_lane_beside() {
    let s = spec(
        ScenarioKind::LowFriction,
        &[
            ("curvature_1pm", 0.02),
            ("entry_speed_mps", 18.0),
            ("friction_mu", 0.3),
            ("lead_decel_mps2", 0.0),
            ("lead_gap_m", 30.0),
        ],
    );
    let mut obs = [0.0; OBS_DIM];
    let mut env = DrivingEnv::new(&s, TrainingReward::eq7(Variant::Base.weights()), &mut obs);
    // The ego starts 50 m before the bend, within its 10 m + 3 s × 18 m/s preview.
    assert!(obs[11].abs() < 1e-6, "straight lead-in under the ego: {obs:?}");
    assert!((obs[12].abs() - 0.02 * 25.0).abs() < 1e-3, "the bend ahead: {obs:?}");
    let dry = env.world().road.friction_at(env.world().ego.pose().position());
    assert!(dry > 0.5 && (obs[13] as f64 - dry).abs() < 1e-6, "dry lead-in: {obs:?}");
    assert!((0.25..0.35).contains(&obs[5]), "the lead 30 m ahead, bumper to bumper: {}", obs[5]);
    let (left, right) = (&obs[14..19], &obs[19..24]);
    assert_eq!(left[0] + right[0], 1.0, "two lanes: exactly one beside the ego: {obs:?}");
    let (beside, other) = if left[0] == 1.0 { (left, right) } else { (right, left) };
    assert_eq!(beside, [1.0, 1.0, 0.0, 1.0, 0.0], "the lane beside is empty");
    assert_eq!(other, [0.0, 1.0, 0.0, 1.0, 0.0], "no lane on the other side");
    // Past the start of the patch (60 m) the observation carries its μ.
    while env.world().time_s < 3.0 {
        env.step(&keep_lane(&obs), &mut obs);
    }
    assert!((obs[13] - 0.3).abs() < 1e-6, "on the patch: {obs:?}");
}

#[test]
fn full_throttle_into_a_braking_lead_collides_and_terminates() {
    let mut obs = [0.0; OBS_DIM];
    let mut env = DrivingEnv::new(&crash_spec(), TrainingReward::eq7(Variant::Full.weights()), &mut obs);
    let mut last = StepOutcome::default();
    for _ in 0..400 {
        last = env.step(&[0.0, 1.0, 0.0], &mut obs);
        if last.done() {
            break;
        }
    }
    assert!(last.terminated && !last.truncated, "{last:?}");
    assert!(last.reward < -100.0, "the crash penalty dominates: {}", last.reward);
    let s = env.summary();
    assert!(s.metrics.collision && !s.metrics.success);
}

#[test]
fn reward_signs_progress_positive_risk_negative() {
    let s = sample(2, ScenarioKind::PedestrianCrossing, 3);
    let (mut o1, mut o2) = ([0.0; OBS_DIM], [0.0; OBS_DIM]);
    let mut base = DrivingEnv::new(&s, TrainingReward::eq7(Variant::Base.weights()), &mut o1);
    let mut full = DrivingEnv::new(&s, TrainingReward::eq7(Variant::Full.weights()), &mut o2);
    let (rb, rf) = (base.step(&keep_lane(&o1), &mut o1).reward, full.step(&keep_lane(&o2), &mut o2).reward);
    assert!(rb > 0.0, "driving at the desired speed pays: {rb}");
    assert!(rf < rb, "the risk term only subtracts: {rf} vs {rb}");
    // Standing still and braking earns less than driving on.
    let mut still = DrivingEnv::new(&s, TrainingReward::eq7(Variant::Base.weights()), &mut o1);
    let mut r_still = 0.0;
    for _ in 0..40 {
        r_still = still.step(&[0.0, 0.0, 1.0], &mut o1).reward;
    }
    assert!(r_still < rb, "{r_still} vs {rb}");
}

#[test]
fn env_rollout_matches_episode_run() {
    for kind in ScenarioKind::ALL {
        let s = (0..20).map(|i| sample(4, kind, i)).find(|s| check_feasible(s).is_ok()).expect("feasible sample");
        let weights = Variant::Full.weights();
        let mut obs = [0.0; OBS_DIM];
        let mut env = DrivingEnv::new(&s, TrainingReward::eq7(weights), &mut obs);
        let mut reward = 0.0;
        loop {
            let out = env.step(&keep_lane(&obs), &mut obs);
            reward += out.reward;
            if out.done() {
                break;
            }
        }
        let summary = env.summary();
        let mut world = build(&s);
        let mut policy = ObsPolicy::new(keep_lane, world.desired_speed_mps, world.dt_s);
        let m = episode::run(&mut world, &mut policy, &weights).metrics;
        assert_eq!(m.steps, summary.metrics.steps, "{kind}");
        assert!((m.reward - reward).abs() < 1e-9, "{kind}: {} vs {reward}", m.reward);
        assert_eq!(
            (m.collision, m.offroad, m.success),
            (summary.metrics.collision, summary.metrics.offroad, summary.metrics.success)
        );
    }
}

fn run_vec(threads: usize) -> (Vec<f32>, Vec<f32>, usize) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        let mut env = VecEnv::new(16, ScenarioSource::all_kinds(11), TrainingReward::eq7(Variant::Full.weights()))
            .expect("source");
        assert_eq!(env.obs().len(), 16 * OBS_DIM);
        let mut actions = vec![0.0f32; 16 * ACT_DIM];
        let (mut rewards, mut episodes) = (Vec::new(), 0);
        for _ in 0..400 {
            for (a, o) in actions.chunks_mut(ACT_DIM).zip(env.obs().chunks(OBS_DIM)) {
                a.copy_from_slice(&keep_lane(o.try_into().expect("row")));
            }
            env.step(&actions).expect("step");
            assert_eq!(env.rewards().len(), 16);
            rewards.extend_from_slice(env.rewards());
            env.drain_finished(|_, _| episodes += 1);
        }
        (env.obs().to_vec(), rewards, episodes)
    })
}

#[test]
fn vec_env_is_deterministic_across_thread_counts_and_resets() {
    let (o1, r1, e1) = run_vec(1);
    let (o2, r2, e2) = run_vec(2);
    assert!(e1 > 0, "400 steps finish some episodes");
    assert_eq!(e1, e2);
    assert_eq!(o1, o2);
    assert_eq!(r1, r2);
}

#[test]
fn a_restart_starts_each_environments_next_episode_as_an_auto_reset_would() {
    let reward = TrainingReward::eq7(Variant::Full.weights());
    let source = ScenarioSource::all_kinds(3);
    let mut env = VecEnv::new(4, source.clone(), reward).expect("source");
    env.step(&[0.0; 4 * ACT_DIM]).expect("step");
    env.restart().expect("restart");
    // Episode 1 of each environment, from its s_0.
    for i in 0..4 {
        let mut obs = [0.0; OBS_DIM];
        DrivingEnv::new(&source.spec(i, 1).expect("spec"), reward, &mut obs);
        assert_eq!(&env.obs()[i * OBS_DIM..(i + 1) * OBS_DIM], &obs[..], "environment {i}");
    }
    assert!(env.rewards().iter().all(|&r| r == 0.0) && env.terminated().iter().all(|&t| t == 0));
    let mut abandoned = 0;
    env.drain_finished(|_, _| abandoned += 1);
    assert_eq!(abandoned, 0, "an abandoned episode is not reported");
}

#[test]
fn variants_parse_and_base_has_no_risk_weight() {
    assert_eq!("risk-only".parse::<Variant>(), Ok(Variant::RiskOnly));
    assert!("bogus".parse::<Variant>().is_err());
    assert_eq!(Variant::Base.weights().risk, 0.0);
    assert!(Variant::Full.weights().risk > 0.0);
}

/// Throughput of the environment alone: `cargo test --release -p risktwin-common env_throughput -- --ignored --nocapture`.
#[test]
#[ignore]
fn env_throughput() {
    let n = 64;
    let mut env =
        VecEnv::new(n, ScenarioSource::all_kinds(1), TrainingReward::eq7(Variant::Full.weights())).expect("source");
    let mut actions = vec![0.0f32; n * ACT_DIM];
    let mut rng = crate::rng::Rng::new(5);
    let steps = 400;
    let t0 = std::time::Instant::now();
    for _ in 0..steps {
        for (a, o) in actions.chunks_mut(ACT_DIM).zip(env.obs().chunks(OBS_DIM)) {
            let mut k = keep_lane(o.try_into().expect("row"));
            k[0] += 0.3 * rng.normal() as f32;
            a.copy_from_slice(&k);
        }
        env.step(&actions).expect("step");
    }
    let dt = t0.elapsed().as_secs_f64();
    println!(
        "{} env steps in {dt:.3} s: {:.0} steps/s ({} threads)",
        n * steps,
        (n * steps) as f64 / dt,
        rayon::current_num_threads()
    );
}

#[test]
fn a_demonstrated_action_commands_what_the_driver_commanded() {
    for c in [Controls::new(0.1, 0.4, 0.0), Controls::new(-0.05, 0.0, 0.7), Controls::new(0.0, 0.0, 0.0)] {
        let a = controls_to_action(&c);
        let back = action_to_controls(&a);
        assert!((back.steer_rad - c.steer_rad).abs() < 1e-6 && (back.throttle - c.throttle).abs() < 1e-6, "{c:?}");
        assert!((back.brake - c.brake).abs() < 1e-6, "{c:?}");
        // The idle pedal sits as far below 0 as the other is pressed.
        assert_eq!(a[1], -a[2], "{c:?} → {a:?}");
    }
    // Beyond the steering scale the action saturates.
    assert_eq!(controls_to_action(&Controls::new(1.0, 0.0, 0.0))[0], 1.0);
}

fn demonstrate_on(specs: Vec<ScenarioSpec>, noise_std: f64, threads: usize) -> Demonstrations {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    let plan = DemoPlan { n_envs: 3, steps_per_env: 900, noise_std, seed: 9 };
    let source = ScenarioSource::List { seed: 2, specs };
    pool.install(|| demonstrate(&source, TrainingReward::eq7(Variant::Base.weights()), &plan)).expect("drives")
}

#[test]
fn demonstrations_keep_only_the_drivers_clean_episodes() {
    // A low-friction scenario the reference driver crashes in or leaves the road, and a
    // pedestrian crossing it completes (both found by episode::evaluate).
    let fails = |s: &ScenarioSpec| {
        let m = episode::evaluate(s).metrics;
        m.collision || m.offroad
    };
    let crash = (0..200)
        .map(|i| sample(3, ScenarioKind::LowFriction, i))
        .find(|s| check_feasible(s).is_ok() && fails(s))
        .expect("the reference driver fails some low-friction scenario");
    let clean = (0..200)
        .map(|i| sample(3, ScenarioKind::PedestrianCrossing, i))
        .find(|s| check_feasible(s).is_ok() && episode::evaluate(s).metrics.success)
        .expect("the reference driver completes some pedestrian crossing");
    let crashes = demonstrate_on(vec![crash.clone()], 0.0, 1);
    assert!(crashes.episodes > 0);
    assert_eq!((crashes.kept, crashes.len()), (0, 0), "a crash is not a demonstration");
    let drives = demonstrate_on(vec![clean.clone()], 0.0, 1);
    assert_eq!(drives.kept, drives.episodes, "every noise-free drive of it is clean");
    assert_eq!(drives.obs.len(), drives.len() * OBS_DIM);
    assert!(!drives.is_empty());
    // Noisy drives are the same whatever the thread count; the failing scenario stays out.
    let noisy = demonstrate_on(vec![clean.clone(), crash.clone()], 0.1, 1);
    assert_eq!(noisy, demonstrate_on(vec![clean, crash], 0.1, 2));
    assert!(noisy.kept < noisy.episodes && noisy.kept > 0, "{} of {}", noisy.kept, noisy.episodes);
}
