//! The knobs of `risktwin run`: defaults sized for ≤ 10 minutes on 2 cores, `--quick` for a
//! smoke test under a minute, any of them overridable from a `--config` JSON file.
//!
//! The training knobs are the cloud trainer's own [`TrainingPlan`], embedded; the run adds the
//! generation, mutation, ranking and push knobs around it. The `--config` file stays one flat
//! object with the names of docs/cli.md (`train_steps`, `failure_mutations`, ...): it is read and
//! written through a private serde proxy, [`ConfigFile`], because serde's `flatten` cannot be
//! combined with `deny_unknown_fields` (an unknown key must stay an error) and two file names
//! differ from the plan's field names. `algo` and `threads` are not in the file: the caller sets
//! them (`--algo`, the machine's cores).

use risktwin_cloud::trainer::{ReplayRule, TrainingPlan};
use risktwin_common::env::{DEFAULT_REPLAY_SHARE, RiskShaping};
use risktwin_learn::Algo;
use risktwin_learn::lagrange::CostConstraint;
use serde::{Deserialize, Serialize};

/// The knobs of a run; a `--config` JSON file may set any of those it serialises.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(from = "ConfigFile", into = "ConfigFile")]
pub struct RunConfig {
    /// Candidates sampled per kind in the first generation.
    pub count_per_kind: u64,
    /// Mutation rounds after the first generation.
    pub iterations: u32,
    /// Parents picked for mutation per round (failures first, then highest risk); the step of
    /// each mutation is the plan's `mutation_radius`, shared with the trainer's refreshes.
    pub mutations_per_iteration: usize,
    /// Scenarios listed in the report's ranking (and re-scored by the trained policies).
    pub top_k: usize,
    /// Risk-field heatmaps drawn for the top scenarios.
    pub heatmaps: usize,
    /// Training seeds per variant.
    pub seeds: u32,
    /// Held-out evaluation scenarios per kind.
    pub eval_per_kind: usize,
    /// Top scenarios (at most `top_k`) pushed over Zenoh to an in-process edge vehicle, before
    /// and after the `full` policy; 0 skips the closed-loop phase.
    pub push_scenarios: usize,
    /// How every training run of the ablation is done (also the worker threads of the run).
    pub training: TrainingPlan,
}

/// Why a config is refused; the message names the offending value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct ConfigError(String);

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            count_per_kind: 200,
            iterations: 4,
            mutations_per_iteration: 40,
            top_k: 10,
            heatmaps: 3,
            seeds: 3,
            eval_per_kind: 12,
            push_scenarios: 3,
            training: TrainingPlan {
                algo: Algo::Ppo,
                steps: 589_824,
                n_envs: 32,
                phases: 4,
                curve_points: 16,
                replay_top: 60,
                background: 60,
                replay_share: DEFAULT_REPLAY_SHARE,
                mutations: 40,
                mutation_radius: 0.1,
                risk_shaping: RiskShaping::default(),
                warm_start: false,
                cost_limit: None,
                replay_rule: ReplayRule::default(),
                threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            },
        }
    }
}

impl RunConfig {
    /// The `--quick` smoke-test size.
    pub fn quick() -> Self {
        let default = Self::default();
        Self {
            count_per_kind: 12,
            iterations: 1,
            mutations_per_iteration: 8,
            top_k: 5,
            heatmaps: 2,
            eval_per_kind: 2,
            push_scenarios: 1,
            training: TrainingPlan {
                steps: 2048,
                n_envs: 16,
                phases: 2,
                curve_points: 2,
                replay_top: 12,
                background: 8,
                mutations: 8,
                ..default.training
            },
            ..default
        }
    }

    /// A config file's text: any knob not named keeps its [`RunConfig::default`] value.
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(text)
    }

    /// Checks every knob's range; the message names the offending value.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |message: String| Err(ConfigError(message));
        let t = &self.training;
        if !(1..=100_000).contains(&self.count_per_kind) {
            return bad(format!("count_per_kind {} is out of range [1, 100000]", self.count_per_kind));
        }
        if self.iterations > 1000 || self.mutations_per_iteration > 100_000 {
            return bad("iterations (≤ 1000) or mutations_per_iteration (≤ 100000) too large".into());
        }
        if !(t.mutation_radius > 0.0 && t.mutation_radius <= 1.0) {
            return bad(format!("mutation_radius {} is out of range (0, 1]", t.mutation_radius));
        }
        if self.top_k > 1000 || self.heatmaps > 20 {
            return bad("top_k (≤ 1000) or heatmaps (≤ 20) too large".into());
        }
        if !(1..=1_000_000_000).contains(&t.steps) {
            return bad(format!("train_steps {} is out of range [1, 1000000000]", t.steps));
        }
        if !(1..=32).contains(&self.seeds) {
            return bad(format!("seeds {} is out of range [1, 32]", self.seeds));
        }
        if !(1..=4096).contains(&t.n_envs) {
            return bad(format!("n_envs {} is out of range [1, 4096]", t.n_envs));
        }
        if !(1..=100).contains(&t.phases) || !(1..=1000).contains(&t.curve_points) {
            return bad(format!(
                "phases {} (1..=100) or curve_points {} (1..=1000) is out of range",
                t.phases, t.curve_points
            ));
        }
        if t.replay_top + t.background == 0 || t.replay_top > 100_000 || t.background > 100_000 {
            return bad(format!("replay_top {} + background {} must be in [1, 200000]", t.replay_top, t.background));
        }
        if !(0.0..=1.0).contains(&t.replay_share) {
            return bad(format!("replay_share {} is out of range [0, 1]", t.replay_share));
        }
        if let Err(message) = t.risk_shaping.validate() {
            return bad(message);
        }
        if let Some(Err(message)) = t.cost_limit.map(|limit| CostConstraint::new(limit).validate()) {
            return bad(message);
        }
        if t.mutations > 100_000 {
            return bad(format!("failure_mutations {} is too large (≤ 100000)", t.mutations));
        }
        if self.push_scenarios > 100 {
            return bad(format!("push_scenarios {} is too large (≤ 100)", self.push_scenarios));
        }
        if !(1..=10_000).contains(&self.eval_per_kind) {
            return bad(format!("eval_per_kind {} is out of range [1, 10000]", self.eval_per_kind));
        }
        Ok(())
    }
}

/// The `--config` file and the `config` object of metrics.json: flat, in this order, with the
/// names of docs/cli.md.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct ConfigFile {
    count_per_kind: u64,
    iterations: u32,
    mutations_per_iteration: usize,
    mutation_radius: f64,
    top_k: usize,
    heatmaps: usize,
    train_steps: u64,
    seeds: u32,
    n_envs: usize,
    phases: u32,
    curve_points: u32,
    replay_top: usize,
    background: usize,
    replay_share: f64,
    risk_shaping: RiskShaping,
    warm_start: bool,
    cost_limit: Option<f64>,
    replay_rule: ReplayRule,
    failure_mutations: usize,
    eval_per_kind: usize,
    push_scenarios: usize,
}

impl Default for ConfigFile {
    fn default() -> Self {
        RunConfig::default().into()
    }
}

impl From<RunConfig> for ConfigFile {
    fn from(c: RunConfig) -> Self {
        let t = c.training;
        ConfigFile {
            count_per_kind: c.count_per_kind,
            iterations: c.iterations,
            mutations_per_iteration: c.mutations_per_iteration,
            mutation_radius: t.mutation_radius,
            top_k: c.top_k,
            heatmaps: c.heatmaps,
            train_steps: t.steps,
            seeds: c.seeds,
            n_envs: t.n_envs,
            phases: t.phases,
            curve_points: t.curve_points,
            replay_top: t.replay_top,
            background: t.background,
            replay_share: t.replay_share,
            risk_shaping: t.risk_shaping,
            warm_start: t.warm_start,
            cost_limit: t.cost_limit,
            replay_rule: t.replay_rule,
            failure_mutations: t.mutations,
            eval_per_kind: c.eval_per_kind,
            push_scenarios: c.push_scenarios,
        }
    }
}

impl From<ConfigFile> for RunConfig {
    fn from(f: ConfigFile) -> Self {
        let default = RunConfig::default();
        RunConfig {
            count_per_kind: f.count_per_kind,
            iterations: f.iterations,
            mutations_per_iteration: f.mutations_per_iteration,
            top_k: f.top_k,
            heatmaps: f.heatmaps,
            seeds: f.seeds,
            eval_per_kind: f.eval_per_kind,
            push_scenarios: f.push_scenarios,
            training: TrainingPlan {
                steps: f.train_steps,
                n_envs: f.n_envs,
                phases: f.phases,
                curve_points: f.curve_points,
                replay_top: f.replay_top,
                background: f.background,
                replay_share: f.replay_share,
                risk_shaping: f.risk_shaping,
                warm_start: f.warm_start,
                cost_limit: f.cost_limit,
                replay_rule: f.replay_rule,
                mutations: f.failure_mutations,
                mutation_radius: f.mutation_radius,
                ..default.training
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::RunConfig;

    #[test]
    fn a_file_round_trips_flat_with_the_documented_names() {
        let mut config = RunConfig::quick();
        config.training.mutation_radius = 0.25;
        let text = serde_json::to_string(&config).expect("serialises");
        assert!(
            text.starts_with(
                r#"{"count_per_kind":12,"iterations":1,"mutations_per_iteration":8,"mutation_radius":0.25,"#
            )
        );
        assert!(text.contains(r#""train_steps":2048,"seeds":3,"#) && text.contains(r#""failure_mutations":8,"#));
        assert_eq!(RunConfig::from_json(&text).expect("parses"), config);
    }

    #[test]
    fn unnamed_knobs_keep_their_defaults_and_unknown_ones_are_refused() {
        let config = RunConfig::from_json(r#"{"train_steps": 99}"#).expect("parses");
        assert_eq!(config.training.steps, 99);
        assert_eq!(config.count_per_kind, RunConfig::default().count_per_kind);
        let e = RunConfig::from_json(r#"{"colour": "red"}"#).expect_err("unknown key");
        assert!(e.to_string().contains("unknown field `colour`"), "{e}");
        assert!(RunConfig::from_json(r#"{"threads": 4}"#).is_err(), "threads is not a file knob");
    }

    #[test]
    fn validation_names_the_knob_by_its_file_name() {
        let mut config = RunConfig::default();
        config.training.steps = 0;
        assert_eq!(
            config.validate().expect_err("0 steps").to_string(),
            "train_steps 0 is out of range [1, 1000000000]"
        );
        assert!(RunConfig::quick().validate().is_ok());
    }

    #[test]
    fn the_risk_shaping_is_named_per_step_or_a_potential_with_its_scale() {
        use risktwin_common::env::RiskShaping;
        assert_eq!(RunConfig::default().training.risk_shaping, RiskShaping::PerStep);
        assert!(serde_json::to_string(&RunConfig::default()).unwrap().contains(r#""risk_shaping":"per-step""#));
        let config = RunConfig::from_json(r#"{"risk_shaping": {"potential": {"scale": 2.5}}}"#).expect("parses");
        assert_eq!(config.training.risk_shaping, RiskShaping::Potential { scale: 2.5 });
        assert!(config.validate().is_ok());
        let zero = RunConfig::from_json(r#"{"risk_shaping": {"potential": {"scale": 0}}}"#).expect("parses");
        assert_eq!(
            zero.validate().expect_err("scale 0").to_string(),
            "risk potential scale 0 is out of range (0, 100]"
        );
        assert!(RunConfig::from_json(r#"{"risk_shaping": "sometimes"}"#).is_err());
    }
}
