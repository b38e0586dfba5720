//! The learners learn: PPO, recurrent PPO and SAC solve the 1-D toy task within a bounded
//! number of steps, deterministically; policies survive a save/load roundtrip.

mod toy;

use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_learn::lagrange::CostConstraint;
use risktwin_learn::ppo::{Ppo, PpoConfig};
use risktwin_learn::{Algo, PolicyNet};
use toy::Toy;

/// Mean return a learned policy must beat (doing nothing: ≈ −10; optimal ≈ −0.6).
const THRESHOLD: f32 = -2.5;

fn ppo_on_toy(recurrent: bool, seed: u64, rollouts: usize) -> (f32, Vec<f32>) {
    // The pre-tuning settings: small and fast for the toy task.
    let cfg = PpoConfig {
        n_steps: 20,
        epochs: 4,
        minibatches: 4,
        init_log_std: -0.5,
        recurrent,
        hidden: vec![32, 32],
        lr: 3e-3,
        ..PpoConfig::default()
    };
    let mut ppo = Ppo::new(cfg, 16, seed).expect("config");
    let mut env = Toy::new(16, seed);
    for _ in 0..rollouts {
        ppo.learn_rollout(&mut env).expect("rollout");
    }
    let mut probe = vec![0.0f32; 2 * OBS_DIM];
    probe[0] = 0.5;
    probe[OBS_DIM] = -0.5;
    let mut state = vec![0.0; 2 * ppo.policy().state_dim()];
    let mut act = vec![0.0; 2 * ACT_DIM];
    ppo.policy().act_deterministic(&probe, &mut state, &mut act).expect("act");
    (env.recent_return(64), act)
}

#[test]
fn ppo_learns_the_toy_task_deterministically() {
    let (ret, act) = ppo_on_toy(false, 1, 60);
    assert!(ret > THRESHOLD, "mean return {ret}");
    assert!(act[0] < -0.3 && act[ACT_DIM] > 0.3, "pushes towards 0: {act:?}");
    assert_eq!(ppo_on_toy(false, 1, 3), ppo_on_toy(false, 1, 3), "same seed, same result");
}

#[test]
fn recurrent_ppo_learns_the_toy_task() {
    let (ret, act) = ppo_on_toy(true, 2, 60);
    assert!(ret > THRESHOLD, "mean return {ret}");
    assert!(act[0] < -0.3 && act[ACT_DIM] > 0.3, "pushes towards 0: {act:?}");
}

#[test]
fn save_load_roundtrip_gives_identical_actions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rng = risktwin_common::rng::Rng::new(3);
    let obs: Vec<f32> = (0..4 * OBS_DIM).map(|_| rng.uniform(-1.0, 1.0) as f32).collect();
    for algo in Algo::ALL {
        let net = PolicyNet::new(algo, &[16, 8], &mut rng).expect("net");
        let path = dir.path().join(format!("{algo}.safetensors"));
        net.save(&path).expect("save");
        let loaded = PolicyNet::load(&path).expect("load");
        assert_eq!(loaded.algo(), algo);
        // The same policy gives the same bytes (the metadata map is a HashMap, in a new order
        // each time, until the header is sorted), and so does the host reader's writer.
        let bytes = std::fs::read(&path).expect("read");
        let host = || net.host().expect("host").to_safetensors().expect("bytes");
        let host_bytes = host();
        for _ in 0..8 {
            net.save(&path).expect("save");
            assert_eq!(std::fs::read(&path).expect("read"), bytes, "{algo}");
            assert_eq!(host(), host_bytes, "{algo}");
        }
        let (mut s1, mut s2) = (vec![0.0; 4 * net.state_dim()], vec![0.0; 4 * net.state_dim()]);
        let (mut a1, mut a2) = (vec![0.0; 4 * ACT_DIM], vec![0.0; 4 * ACT_DIM]);
        for _ in 0..3 {
            net.act_deterministic(&obs, &mut s1, &mut a1).expect("act");
            loaded.act_deterministic(&obs, &mut s2, &mut a2).expect("act");
            assert_eq!(a1, a2, "{algo}");
            assert_eq!(s1, s2, "{algo}");
        }
    }
    std::fs::write(dir.path().join("bad.safetensors"), b"not a policy").expect("write");
    assert!(PolicyNet::load(&dir.path().join("bad.safetensors")).is_err());
}

/// What an edge does with a saved policy (common's reader, no candle) acts as the candle net,
/// the recurrent one with its state carried from step to step.
#[test]
fn a_saved_policy_acts_the_same_on_the_host_reader() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rng = risktwin_common::rng::Rng::new(4);
    let obs: Vec<f32> = (0..12 * OBS_DIM).map(|_| rng.uniform(-1.0, 1.0) as f32).collect();
    for algo in Algo::ALL {
        let net = PolicyNet::new(algo, &[16, 8], &mut rng).expect("net");
        let path = dir.path().join(format!("{algo}.safetensors"));
        net.save(&path).expect("save");
        let bytes = std::fs::read(&path).expect("read");
        let host = risktwin_policy::HostPolicy::from_safetensors(&bytes).expect("a host policy");
        assert_eq!(host.kind().algo(), algo.name());
        let (mut state, mut memory) = (vec![0.0; net.state_dim()], host.memory());
        for row in obs.chunks(OBS_DIM) {
            let mut want = [0.0; ACT_DIM];
            net.act_deterministic(row, &mut state, &mut want).expect("act");
            let got = host.act_deterministic(row.try_into().expect("a row"), &mut memory);
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() < 1e-5, "{algo}: {got:?} vs {want:?}");
            }
        }
    }
}

/// PPO-Lagrangian holds its constraint where plain PPO breaks it: on the cliff task, whose
/// reward pays for failing, the unconstrained learner fails in most episodes, the constrained
/// one (limit 0.1) in far fewer, with λ risen above 0; the same seed gives the same λ.
#[test]
fn a_cost_limit_makes_ppo_fail_less_where_failing_pays() {
    let run = |constraint: Option<CostConstraint>| {
        let cfg = PpoConfig {
            n_steps: 20,
            epochs: 4,
            minibatches: 4,
            init_log_std: -0.5,
            hidden: vec![32, 32],
            lr: 3e-3,
            constraint,
            ..PpoConfig::default()
        };
        let mut ppo = Ppo::new(cfg, 16, 7).expect("config");
        let mut env = Toy::cliff(16, 7);
        for _ in 0..80 {
            ppo.learn_rollout(&mut env).expect("rollout");
        }
        (env.recent_failures(200), env.recent_return(200), ppo.lagrange_multiplier())
    };
    let limit = CostConstraint { limit: 0.1, lambda_lr: 0.5 };
    let (free_fail, free_ret, free_lambda) = run(None);
    let (held_fail, held_ret, lambda) = run(Some(limit));
    assert_eq!(free_lambda, None);
    assert!(free_fail > 0.6, "unconstrained PPO fails where failing pays: {free_fail}");
    assert!(held_fail < 0.5 * free_fail, "constrained {held_fail} against unconstrained {free_fail}");
    assert!(held_ret < free_ret, "holding the limit costs return: {held_ret} vs {free_ret}");
    assert!(lambda.is_some_and(|l| l > 0.0), "λ {lambda:?}");
    assert_eq!(run(Some(limit)).2, lambda, "same seed, same λ");
}

#[test]
fn a_cost_limit_needs_the_feed_forward_policy() {
    let cfg = PpoConfig { recurrent: true, constraint: Some(CostConstraint::new(0.1)), ..PpoConfig::default() };
    assert!(Ppo::new(cfg, 16, 1).is_err());
}

/// The toy's good controller, a₀ = −10x clipped, demonstrated on 4096 states.
fn toy_demonstrations() -> (Vec<f32>, Vec<f32>) {
    let mut rng = risktwin_common::rng::Rng::new(5);
    let (mut obs, mut act) = (Vec::new(), Vec::new());
    for _ in 0..4096 {
        let x = rng.uniform(-1.0, 1.0) as f32;
        let mut o = [0.0f32; OBS_DIM];
        o[0] = x;
        obs.extend_from_slice(&o);
        act.extend_from_slice(&[(-10.0 * x).clamp(-1.0, 1.0), -0.5, -0.5]);
    }
    (obs, act)
}

/// A PPO learner on the toy task warm-started from its good controller, with the imitation
/// term's weight `imitation_coef`, and a probe of its deterministic actions on two states.
fn warm_toy(imitation_coef: f64) -> (Ppo, impl Fn(&Ppo) -> Vec<f32>, Vec<f32>) {
    let cfg = PpoConfig {
        n_steps: 20,
        epochs: 4,
        minibatches: 4,
        hidden: vec![32, 32],
        lr: 3e-3,
        critic_warmup: 2,
        imitation_coef,
        ..PpoConfig::default()
    };
    let mut ppo = Ppo::new(cfg, 16, 4).expect("config");
    let (obs, act) = toy_demonstrations();
    let mse = ppo.imitate(&obs, &act, 60, 0.1).expect("imitates");
    assert!(mse < 0.01, "imitation error {mse}");
    let bad = ppo.imitate(&obs[..OBS_DIM], &act, 1, 0.1);
    assert!(bad.is_err(), "observations and actions must pair up");
    let probe_obs = obs[..2 * OBS_DIM].to_vec();
    let probe = move |ppo: &Ppo| {
        let mut out = vec![0.0f32; 2 * ACT_DIM];
        ppo.policy().act_deterministic(&probe_obs, &mut [], &mut out).expect("act");
        out
    };
    (ppo, probe, act[..2 * ACT_DIM].to_vec())
}

#[test]
fn a_warm_start_imitates_and_then_only_the_critic_learns_for_its_warmup() {
    let (mut ppo, probe, labels) = warm_toy(0.0);
    let imitated = probe(&ppo);
    let sigma = ppo.policy().log_std().expect("log σ").expect("Gaussian").map(f32::exp);
    assert!(sigma.iter().all(|s| (s - 0.1).abs() < 1e-6), "exploration at the demonstrations' noise: {sigma:?}");
    for (a, b) in imitated.iter().zip(&labels) {
        assert!((a - b).abs() < 0.15, "imitated {imitated:?} against {labels:?}");
    }
    // Without any reinforcement learning the imitation already solves the task.
    let mut env = Toy::new(16, 4);
    ppo.learn_rollout(&mut env).expect("rollout");
    assert_eq!(probe(&ppo), imitated, "the first warm-up rollout leaves the policy alone");
    ppo.learn_rollout(&mut env).expect("rollout");
    assert_eq!(probe(&ppo), imitated, "so does the second");
    assert!(env.recent_return(16) > THRESHOLD, "the imitation drives x to 0: {}", env.recent_return(16));
    ppo.learn_rollout(&mut env).expect("rollout");
    assert_ne!(probe(&ppo), imitated, "after the warm-up the policy learns");
}

#[test]
fn the_imitation_term_keeps_fitting_the_demonstrations() {
    // With the term on, the warm-up rollouts go on fitting the demonstrations (the policy
    // moves, but stays on them), and the updates after it stay near them too.
    let (mut ppo, probe, labels) = warm_toy(10.0);
    let imitated = probe(&ppo);
    let mut env = Toy::new(16, 4);
    ppo.learn_rollout(&mut env).expect("rollout");
    assert_ne!(probe(&ppo), imitated, "the imitation term trains the policy during the warm-up");
    for _ in 0..4 {
        ppo.learn_rollout(&mut env).expect("rollout");
    }
    let now = probe(&ppo);
    for (a, b) in now.iter().zip(&labels) {
        assert!((a - b).abs() < 0.15, "held near the demonstrations: {now:?} against {labels:?}");
    }
}

#[test]
fn a_warm_start_needs_the_feed_forward_policy() {
    let cfg = PpoConfig { recurrent: true, hidden: vec![8, 8], ..PpoConfig::default() };
    let mut ppo = Ppo::new(cfg, 8, 1).expect("config");
    let (obs, act) = toy_demonstrations();
    assert!(ppo.imitate(&obs, &act, 1, 0.1).is_err());
}

#[test]
fn train_with_a_warm_start_counts_the_demonstrations_and_needs_ppo() {
    use risktwin_common::env::Variant;
    use risktwin_learn::train::{TrainConfig, train};
    use risktwin_learn::warm::DEMO_STEPS_PER_ENV;
    let n_envs = 2;
    let demo_steps = (n_envs * DEMO_STEPS_PER_ENV) as u64;
    let cfg = TrainConfig {
        n_envs,
        eval_per_kind: 1,
        warm_start: true,
        ..TrainConfig::new(Algo::Ppo, Variant::Base, demo_steps + 1, 5)
    };
    let warm = train(&cfg, &mut |_, _| {}).expect("trains");
    assert!(warm.steps > demo_steps, "the demonstrations and one rollout: {}", warm.steps);
    assert!(warm.curve.iter().all(|c| c.point.env_steps > demo_steps));
    let cold = train(&TrainConfig { warm_start: false, ..cfg.clone() }, &mut |_, _| {}).expect("trains");
    assert!(cold.curve.first().is_some_and(|c| c.point.env_steps < demo_steps), "without it, learning from the start");
    let sac = TrainConfig { warm_start: true, ..TrainConfig::new(Algo::Sac, Variant::Base, 1, 5) };
    assert!(train(&sac, &mut |_, _| {}).is_err(), "a warm start needs PPO");
}

#[test]
fn evaluation_scores_every_policy_with_the_evaluation_weights() {
    use risktwin_common::env::Variant;
    use risktwin_common::metrics::RewardWeights;
    use risktwin_common::scenario::build;
    use risktwin_learn::train::{evaluate_policy, held_out_specs};
    let mut rng = risktwin_common::rng::Rng::new(5);
    let policy = PolicyNet::new(Algo::Ppo, &[16, 8], &mut rng).expect("net");
    let specs = held_out_specs(1, 1);
    let evaluated = evaluate_policy(&policy, &specs);
    let mut risk_counted = false;
    for (spec, m) in specs.iter().zip(&evaluated) {
        let drive =
            |w: &RewardWeights| risktwin_learn::drive::drive(&policy, &mut build(spec), w, &mut |_, _| {}).metrics;
        assert_eq!(*m, drive(&RewardWeights::default()), "what `simulate --driver` prints for this file");
        risk_counted |= m.reward != drive(&Variant::Base.weights()).reward;
    }
    assert!(risk_counted, "base's weights (no risk term) would have scored some episode otherwise");
}
