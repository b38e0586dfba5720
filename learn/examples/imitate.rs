//! Behaviour cloning of the reference driver alone (no reinforcement learning): how well the
//! warm start's imitation drives the held-out scenarios. Variables (optional): SEED, ENVS,
//! DEMO_STEPS (per environment), NOISE, EPOCHS, LR.
//!
//! `cargo run --release -p risktwin-learn --example imitate`

use risktwin_common::env::{DemoPlan, ScenarioSource, Variant, demonstrate};
use risktwin_learn::Algo;
use risktwin_learn::learner::Learner;
use risktwin_learn::ppo::PpoConfig;
use risktwin_learn::sac::SacConfig;
use risktwin_learn::train::{FinalMetrics, evaluate_policy, held_out_specs};
use std::str::FromStr;
use std::time::Instant;

fn var<T: FromStr>(name: &str, default: T) -> T {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn main() {
    let seed = var("SEED", 1u64);
    let n_envs = var("ENVS", 32usize);
    let plan = DemoPlan { n_envs, steps_per_env: var("DEMO_STEPS", 1024), noise_std: var("NOISE", 0.1), seed };
    let t = Instant::now();
    let source = ScenarioSource::all_kinds(seed);
    let demos = demonstrate(&source, Variant::Base.training_reward(Default::default()), &plan).expect("demos");
    println!(
        "{} pairs from {} of {} episodes in {:.1} s",
        demos.len(),
        demos.kept,
        demos.episodes,
        t.elapsed().as_secs_f64()
    );
    let ppo = PpoConfig { lr: var("LR", 1e-3), ..PpoConfig::default() };
    let mut learner = Learner::new(Algo::Ppo, &ppo, &SacConfig::default(), n_envs, seed).expect("learner");
    let Learner::Ppo(p) = &mut learner else { unreachable!() };
    let epochs = var("EPOCHS", 20usize);
    for chunk in [epochs / 4, epochs / 4, epochs / 2] {
        let t = Instant::now();
        let mse = p.imitate(&demos.obs, &demos.actions, chunk.max(1), plan.noise_std as f32).expect("imitate");
        println!("after {chunk} more epochs: mse {mse:.4} ({:.1} s)", t.elapsed().as_secs_f64());
    }
    let specs = held_out_specs(seed, 12);
    let imitated = evaluate_policy(learner.policy(), &specs);
    let reference: Vec<_> = specs.iter().map(|s| risktwin_common::episode::evaluate(s).metrics).collect();
    for (name, m) in [("imitation", imitated), ("reference", reference)] {
        let f = FinalMetrics::average(&m);
        println!(
            "held-out {name}: coll {:.2} succ {:.2} compl {:.2} speed {:.1} off {:.2}",
            f.collision_rate, f.success_rate, f.route_completion, f.avg_speed_mps, f.offroad_rate
        );
        for kind in risktwin_common::scenario::ScenarioKind::ALL {
            let k: Vec<_> = specs.iter().zip(&m).filter(|(s, _)| s.kind == kind).map(|(_, m)| m.clone()).collect();
            let f = FinalMetrics::average(&k);
            println!(
                "  {kind:20} coll {:.2} succ {:.2} off {:.2} speed {:.1}",
                f.collision_rate, f.success_rate, f.offroad_rate, f.avg_speed_mps
            );
        }
    }
}
