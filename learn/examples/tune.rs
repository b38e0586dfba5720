//! Trains PPO (or SAC) with hyper-parameters from the environment and prints the curve and the
//! held-out metrics: the tool behind the defaults. Variables (all optional): ALGO, VARIANT,
//! STEPS, SEED, ENVS, NSTEPS, EPOCHS, MB, LR, GAMMA, LOGSTD, ENT, BENIGN, BENIGN_EVERY.
//!
//! `STEPS=200000 cargo run --release -p risktwin-learn --example tune`

use risktwin_common::env::Variant;
use risktwin_learn::Algo;
use risktwin_learn::train::{TrainConfig, train};
use std::str::FromStr;

fn var<T: FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn main() {
    let algo: Algo = var("ALGO", "ppo".to_string()).parse().expect("ALGO");
    let variant: Variant = var("VARIANT", "base".to_string()).parse().expect("VARIANT");
    let mut cfg = TrainConfig::new(algo, variant, var("STEPS", 200_000), var("SEED", 1));
    cfg.n_envs = var("ENVS", cfg.n_envs);
    cfg.benign_eval = var("BENIGN", 20);
    cfg.benign_every = var("BENIGN_EVERY", 50_000);
    let p = &mut cfg.ppo;
    p.n_steps = var("NSTEPS", p.n_steps);
    p.epochs = var("EPOCHS", p.epochs);
    p.minibatches = var("MB", p.minibatches);
    p.lr = var("LR", p.lr);
    p.gamma = var("GAMMA", p.gamma);
    p.init_log_std = var("LOGSTD", p.init_log_std);
    p.ent_coef = var("ENT", p.ent_coef);
    let r = train(&cfg, &mut |_, _| {}).expect("train");
    for checkpoint in &r.curve {
        let c = &checkpoint.point;
        println!(
            "{:>7} {:6.1}s ep {:4} rew {:7.2} succ {:.2} compl {:.2} v {:5.1} coll {:.2} benign {:?}",
            c.env_steps,
            checkpoint.wall_s,
            c.episodes,
            c.reward,
            c.success_rate,
            c.route_completion,
            c.avg_speed_mps,
            c.collision_rate,
            checkpoint.benign_success
        );
    }
    let f = &r.final_metrics;
    println!(
        "FINAL held-out: success {:.2} collision {:.2} offroad {:.2} completion {:.2} speed {:.1} reward {:.1}; \
         {:.0} steps/s, benign90 {:?}, timings {:?}",
        f.success_rate,
        f.collision_rate,
        f.offroad_rate,
        f.route_completion,
        f.avg_speed_mps,
        f.reward,
        r.env_steps_per_s,
        r.benign_90_wall_s,
        r.timings
    );
}
