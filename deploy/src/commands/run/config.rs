//! The knobs of `risktwin run`: defaults sized for ≤ 10 minutes on 2 cores, `--quick` for a
//! smoke test under a minute, any of them overridable from a `--config` JSON file.

use risktwin_common::env::DEFAULT_REPLAY_SHARE;
use serde::{Deserialize, Serialize};

/// The knobs of a run; a `--config` JSON file may set any of them.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Candidates sampled per kind in the first generation.
    pub count_per_kind: u64,
    /// Mutation rounds after the first generation.
    pub iterations: u32,
    /// Parents picked for mutation per round (failures first, then highest risk).
    pub mutations_per_iteration: usize,
    /// Mutation step as a share of each parameter's range.
    pub mutation_radius: f64,
    /// Scenarios listed in the report's ranking (and re-scored by the trained policies).
    pub top_k: usize,
    /// Risk-field heatmaps drawn for the top scenarios.
    pub heatmaps: usize,
    /// Environment steps per training run (one variant, one seed).
    pub train_steps: u64,
    /// Training seeds per variant.
    pub seeds: u32,
    /// Environments stepped together in training.
    pub n_envs: usize,
    /// Training phases; `full` refreshes its library scenarios between them.
    pub phases: u32,
    /// Checkpoints on the training curves.
    pub curve_points: u32,
    /// Risk-ranked replay: the riskiest library scenarios in `full`'s training set.
    pub replay_top: usize,
    /// Ordinary library scenarios drawn uniformly into `full`'s training set.
    pub background: usize,
    /// Probability that a `full` training episode replays a library scenario rather than a
    /// fresh sample of the five kinds (prioritised level replay).
    pub replay_share: f64,
    /// Mutated children around the policy's failures per refresh.
    pub failure_mutations: usize,
    /// Held-out evaluation scenarios per kind.
    pub eval_per_kind: usize,
    /// Top scenarios (at most `top_k`) pushed over Zenoh to an in-process edge vehicle, before
    /// and after the `full` policy; 0 skips the closed-loop phase.
    pub push_scenarios: usize,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            count_per_kind: 200,
            iterations: 4,
            mutations_per_iteration: 40,
            mutation_radius: 0.1,
            top_k: 10,
            heatmaps: 3,
            train_steps: 589_824,
            seeds: 3,
            n_envs: 32,
            phases: 4,
            curve_points: 16,
            replay_top: 60,
            background: 60,
            replay_share: DEFAULT_REPLAY_SHARE,
            failure_mutations: 40,
            eval_per_kind: 12,
            push_scenarios: 3,
        }
    }
}

impl RunConfig {
    /// The `--quick` smoke-test size.
    pub fn quick() -> Self {
        Self {
            count_per_kind: 12,
            iterations: 1,
            mutations_per_iteration: 8,
            top_k: 5,
            heatmaps: 2,
            train_steps: 2048,
            n_envs: 16,
            phases: 2,
            curve_points: 2,
            replay_top: 12,
            background: 8,
            failure_mutations: 8,
            eval_per_kind: 2,
            push_scenarios: 1,
            ..Self::default()
        }
    }

    /// Checks every knob's range; the message names the offending value.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=100_000).contains(&self.count_per_kind) {
            return Err(format!("count_per_kind {} is out of range [1, 100000]", self.count_per_kind));
        }
        if self.iterations > 1000 || self.mutations_per_iteration > 100_000 {
            return Err("iterations (≤ 1000) or mutations_per_iteration (≤ 100000) too large".into());
        }
        if !(self.mutation_radius > 0.0 && self.mutation_radius <= 1.0) {
            return Err(format!("mutation_radius {} is out of range (0, 1]", self.mutation_radius));
        }
        if self.top_k > 1000 || self.heatmaps > 20 {
            return Err("top_k (≤ 1000) or heatmaps (≤ 20) too large".into());
        }
        if !(1..=1_000_000_000).contains(&self.train_steps) {
            return Err(format!("train_steps {} is out of range [1, 1000000000]", self.train_steps));
        }
        if !(1..=32).contains(&self.seeds) {
            return Err(format!("seeds {} is out of range [1, 32]", self.seeds));
        }
        if !(1..=4096).contains(&self.n_envs) {
            return Err(format!("n_envs {} is out of range [1, 4096]", self.n_envs));
        }
        if !(1..=100).contains(&self.phases) || !(1..=1000).contains(&self.curve_points) {
            return Err(format!(
                "phases {} (1..=100) or curve_points {} (1..=1000) is out of range",
                self.phases, self.curve_points
            ));
        }
        if self.replay_top + self.background == 0 || self.replay_top > 100_000 || self.background > 100_000 {
            return Err(format!(
                "replay_top {} + background {} must be in [1, 200000]",
                self.replay_top, self.background
            ));
        }
        if !(0.0..=1.0).contains(&self.replay_share) {
            return Err(format!("replay_share {} is out of range [0, 1]", self.replay_share));
        }
        if self.failure_mutations > 100_000 {
            return Err(format!("failure_mutations {} is too large (≤ 100000)", self.failure_mutations));
        }
        if self.push_scenarios > 100 {
            return Err(format!("push_scenarios {} is too large (≤ 100)", self.push_scenarios));
        }
        if !(1..=10_000).contains(&self.eval_per_kind) {
            return Err(format!("eval_per_kind {} is out of range [1, 10000]", self.eval_per_kind));
        }
        Ok(())
    }
}
