//! One training run: a learner (PPO or SAC from `risktwin-learn`) on a vectorised driving
//! environment for a variant and a seed, in phases; between phases the `full` variant's
//! scenarios are refreshed from the library ([`super::curriculum`]). Training curves are the
//! finished training episodes averaged between evenly spaced checkpoints.

use super::curriculum::{Curriculum, Refresh};
use super::held_out::HeldOut;
use super::plan::{TrainerError, TrainingPlan};
use risktwin_common::env::{ScenarioSource, Variant, VecEnv};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::rng::Rng;
use risktwin_learn::PolicyNet;
use risktwin_learn::lagrange::CostConstraint;
use risktwin_learn::learner::Learner;
use risktwin_learn::ppo::PpoConfig;
use risktwin_learn::sac::SacConfig;
pub use risktwin_learn::train::CurvePoint;
use risktwin_learn::warm::warm_start;
use risktwin_store::library::ScenarioLibrary;
use std::time::Instant;

/// What one training run produced.
#[derive(Debug, Clone)]
pub struct TrainedPolicy {
    pub variant: Variant,
    /// The training seed.
    pub seed: u64,
    pub env_steps: u64,
    /// Checkpoints with at least one finished episode.
    pub curve: Vec<CurvePoint>,
    /// The `full` variant's library refreshes (empty for the others).
    pub refreshes: Vec<Refresh>,
    pub policy: PolicyNet,
    /// Wall time of training (measurement; not part of deterministic output).
    pub wall_s: f64,
}

fn curve_point(env_steps: u64, acc: &[EpisodeMetrics]) -> CurvePoint {
    let n = acc.len().max(1) as f64;
    let mean = |f: fn(&EpisodeMetrics) -> f64| acc.iter().map(f).sum::<f64>() / n;
    CurvePoint {
        env_steps,
        episodes: acc.len() as u64,
        reward: mean(|m| m.reward),
        success_rate: mean(|m| f64::from(u8::from(m.success))),
        route_completion: mean(|m| m.route_completion),
        avg_speed_mps: mean(|m| m.avg_speed_mps),
        collision_rate: mean(|m| f64::from(u8::from(m.collision))),
    }
}

/// Trains `variant` with training seed `seed`; `library` feeds the `full` variant (and receives
/// its policies' outcomes); `progress(done, total)` follows the environment steps.
pub fn train_variant(
    plan: &TrainingPlan,
    variant: Variant,
    seed: u64,
    library: &mut ScenarioLibrary,
    held_out: &HeldOut,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<TrainedPolicy, TrainerError> {
    plan.validate()?;
    let start = Instant::now();
    let threads = plan.threads.max(1);
    let mut curriculum = Curriculum::new(seed);
    let source = match variant {
        Variant::Full => ScenarioSource::Replay {
            seed: Rng::derive(seed, 0).next_u64(),
            specs: curriculum.initial(library, plan, held_out)?,
            share: plan.replay_share,
        },
        Variant::Base | Variant::RiskOnly | Variant::Ttc => {
            ScenarioSource::all_kinds(Rng::derive(seed, 0x5A4D_504C).next_u64())
        }
    };
    let reward = variant.training_reward(plan.risk_shaping);
    let ppo = PpoConfig { constraint: plan.cost_limit.map(CostConstraint::new), ..PpoConfig::default() };
    let mut learner = Learner::new(plan.algo, &ppo, &SacConfig::default(), plan.n_envs, seed)?;
    let demo_steps = if plan.warm_start {
        let warm = warm_start(&mut learner, &source, reward, plan.n_envs, seed)?;
        tracing::info!(
            "{variant} seed {seed}: warm start from {} of {} demonstrated episodes, imitation error {:.4}",
            warm.kept,
            warm.episodes,
            warm.mse
        );
        warm.env_steps
    } else {
        0
    };
    let mut env = VecEnv::new(plan.n_envs, source, reward)?;
    let checkpoint = plan.steps.div_ceil(plan.curve_points.max(1) as u64).max(1);
    let phase_steps = plan.steps.div_ceil(u64::from(plan.phases.max(1)));
    let (mut done, mut next_checkpoint) = (demo_steps, checkpoint);
    let mut acc: Vec<EpisodeMetrics> = Vec::new();
    let mut curve = Vec::new();
    let mut refreshes = Vec::new();
    for phase in 0..plan.phases.max(1) {
        let phase_end = (u64::from(phase) + 1).saturating_mul(phase_steps).min(plan.steps);
        while done < phase_end {
            done += learner.step(&mut env)?;
            env.drain_finished(|_, s| acc.push(s.metrics));
            if done >= next_checkpoint || done >= plan.steps {
                while next_checkpoint <= done {
                    next_checkpoint += checkpoint;
                }
                // An empty window (no episode finished yet) carries over to the next one.
                if !acc.is_empty() {
                    curve.push(curve_point(done, &acc));
                    acc.clear();
                }
                if let Some(lambda) = learner.lagrange_multiplier() {
                    tracing::info!("{variant} seed {seed}: {done} steps, Lagrange multiplier {lambda:.3}");
                }
            }
            progress(done.min(plan.steps), plan.steps);
        }
        if variant == Variant::Full && phase + 1 < plan.phases {
            let label = format!("{}-full-seed{seed}-phase{phase}", plan.algo.name());
            let (specs, refresh) =
                curriculum.refresh(library, learner.policy(), &label, phase, plan, held_out, threads)?;
            let seed = Rng::derive(seed, u64::from(phase) + 1).next_u64();
            env.set_source(ScenarioSource::Replay { seed, specs, share: plan.replay_share })?;
            refreshes.push(refresh);
        }
    }
    Ok(TrainedPolicy {
        variant,
        seed,
        env_steps: done,
        curve,
        refreshes,
        policy: learner.policy().clone(),
        wall_s: start.elapsed().as_secs_f64(),
    })
}
