//! Warm start: the reference driver's clean drives (with DART noise, [`demonstrate`]) imitated
//! by the PPO policy before reinforcement learning begins (docs/method.md §7, "Warm start"),
//! for the cloud's trainer (`risktwin run`'s `warm_start`) and `examples/imitate.rs`.

use crate::LearnError;
use crate::learner::Learner;
use risktwin_common::env::{DemoPlan, ScenarioSource, TrainingReward, demonstrate};
use risktwin_common::rng::Rng;

/// Demonstration steps per environment: with `risktwin run`'s 32 environments 131,072 steps
/// (22 % of its 589,824), about 20 episodes per stream. Measured by `examples/imitate.rs`
/// (seed 1, held-out collision / success of the imitation alone, the reference driver's
/// 0.13 / 0.55): 1,024 steps and 20 epochs 0.27 / 0.33, 4,096 and 60 epochs 0.27 / 0.45,
/// and with the pedals as one signed demand (`env::controls_to_action`) 0.13 / 0.45.
pub const DEMO_STEPS_PER_ENV: usize = 4096;
/// Noise on the driver's executed action (DART): enough to leave the centre of the lane and
/// show the way back, small against the steering scale.
pub const DEMO_NOISE_STD: f64 = 0.1;
/// Passes over the demonstrations.
pub const IMITATION_EPOCHS: usize = 60;

/// What a warm start did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarmStart {
    /// Environment steps driven by the reference driver (kept or not).
    pub env_steps: u64,
    pub episodes: usize,
    /// Episodes kept (no collision, never off the road).
    pub kept: usize,
    /// Mean squared error of the imitation's last epoch.
    pub mse: f32,
}

/// Collects demonstrations on `source` (with `n_envs` streams) and fits `learner`'s policy to them;
/// the demonstrations' random stream is derived from the training run's `seed`.
pub fn warm_start(
    learner: &mut Learner,
    source: &ScenarioSource,
    reward: TrainingReward,
    n_envs: usize,
    seed: u64,
) -> Result<WarmStart, LearnError> {
    let seed = Rng::derive(seed, 0xDE30).next_u64();
    let plan = DemoPlan { n_envs, steps_per_env: DEMO_STEPS_PER_ENV, noise_std: DEMO_NOISE_STD, seed };
    let demos = demonstrate(source, reward, &plan)?;
    let Learner::Ppo(ppo) = learner else {
        return Err(LearnError::BadConfig("a warm start needs a PPO learner".into()));
    };
    let mse = ppo.imitate(&demos.obs, &demos.actions, IMITATION_EPOCHS, DEMO_NOISE_STD as f32)?;
    Ok(WarmStart { env_steps: (n_envs * DEMO_STEPS_PER_ENV) as u64, episodes: demos.episodes, kept: demos.kept, mse })
}
