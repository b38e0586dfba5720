//! What a training run is asked to do ([`TrainingPlan`]) and why the trainer fails ([`TrainerError`]):
//! their own file so that the trainer's modules import them without importing `trainer/mod.rs`.

use risktwin_common::env::RiskShaping;
use risktwin_learn::lagrange::CostConstraint;
use risktwin_learn::{Algo, LearnError};
use risktwin_store::library::LibraryError;
use serde::{Deserialize, Serialize};

/// Why training or evaluation failed.
#[derive(Debug, thiserror::Error)]
pub enum TrainerError {
    #[error(transparent)]
    Learn(#[from] LearnError),
    #[error(transparent)]
    Library(#[from] LibraryError),
    #[error(transparent)]
    Source(#[from] risktwin_common::env::SourceError),
    #[error("held-out scenario {0} reached a training or library set")]
    HeldOutLeak(String),
    #[error("the scenario library has no scenarios to train the full variant on")]
    EmptyLibrary,
    #[error("bad training plan: {0}")]
    BadPlan(String),
    #[error("{0}")]
    Io(String),
    #[error("the training run ended without a result (it panicked)")]
    Lost,
}

/// How `full`'s replay list is chosen after each training phase (docs/method.md §7,
/// "Variants").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReplayRule {
    /// The policy's riskiest scenarios and its failures, with children of the failures.
    #[default]
    RiskRanked,
    /// The frontier: scenarios the policy completes in some but not all of a few drives with
    /// its exploration noise, most uncertain first, with children of them (the learning
    /// potential of prioritised level replay, Jiang et al. 2021, as a success-rate estimate).
    /// Needs a policy with a state-independent σ (PPO).
    Frontier,
}

/// How every training run of an ablation is done.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingPlan {
    pub algo: Algo,
    /// Environment steps per run (variant × seed).
    pub steps: u64,
    /// Environments stepped together.
    pub n_envs: usize,
    /// Training phases; `full` refreshes its scenarios between phases.
    pub phases: u32,
    /// Checkpoints of the training curves.
    pub curve_points: u32,
    /// Risk-ranked replay: the riskiest library scenarios in `full`'s set.
    pub replay_top: usize,
    /// Ordinary library scenarios drawn uniformly into `full`'s set.
    pub background: usize,
    /// Probability that a `full` training episode replays a library scenario rather than a
    /// fresh sample of the five kinds.
    pub replay_share: f64,
    /// Mutated children around failures per refresh.
    pub mutations: usize,
    /// Mutation step as a share of each parameter's range.
    pub mutation_radius: f64,
    /// How the risk term enters `risk-only`'s and `full`'s training reward.
    pub risk_shaping: RiskShaping,
    /// Start PPO from an imitation of the reference driver's clean drives
    /// (`risktwin_learn::warm`); their environment steps count against `steps`.
    pub warm_start: bool,
    /// PPO-Lagrangian (`risktwin_learn::lagrange`): the share of training episodes that may
    /// end in a collision or off the road; `None` trains unconstrained.
    pub cost_limit: Option<f64>,
    /// How `full`'s replay list is refreshed.
    pub replay_rule: ReplayRule,
    /// Worker threads for evaluation episodes.
    pub threads: usize,
}

impl TrainingPlan {
    /// Checks the plan can run.
    pub fn validate(&self) -> Result<(), TrainerError> {
        if self.steps == 0 || self.n_envs == 0 || self.phases == 0 {
            return Err(TrainerError::BadPlan(format!(
                "steps ({}), n_envs ({}) and phases ({}) must be positive",
                self.steps, self.n_envs, self.phases
            )));
        }
        if !(self.mutation_radius > 0.0 && self.mutation_radius <= 1.0) {
            return Err(TrainerError::BadPlan(format!(
                "mutation_radius {} is out of range (0, 1]",
                self.mutation_radius
            )));
        }
        if !(0.0..=1.0).contains(&self.replay_share) {
            return Err(TrainerError::BadPlan(format!("replay_share {} is out of range [0, 1]", self.replay_share)));
        }
        self.risk_shaping.validate().map_err(TrainerError::BadPlan)?;
        if self.warm_start && self.algo != Algo::Ppo {
            return Err(TrainerError::BadPlan(format!("a warm start needs PPO, not {}", self.algo.name())));
        }
        if let Some(limit) = self.cost_limit {
            if self.algo != Algo::Ppo {
                return Err(TrainerError::BadPlan(format!("a cost limit needs PPO, not {}", self.algo.name())));
            }
            CostConstraint::new(limit).validate().map_err(TrainerError::BadPlan)?;
        }
        if self.replay_rule == ReplayRule::Frontier && self.algo == Algo::Sac {
            return Err(TrainerError::BadPlan(
                "the frontier replay rule needs PPO (SAC's σ depends on the state)".into(),
            ));
        }
        if self.replay_top + self.background == 0 {
            return Err(TrainerError::BadPlan("replay_top + background must be positive".into()));
        }
        Ok(())
    }
}
