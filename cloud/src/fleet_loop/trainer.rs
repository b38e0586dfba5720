//! The `trainer` role's work: once enough new fleet failures are in the library (or, on a
//! schedule, one new failure once the period has passed), a policy is
//! trained on the library (the `full` variant: the library's riskiest scenarios replayed among
//! fresh samples, with the risk-shaped reward) and put through the regression gate against the
//! version deployed now (the reference driver before the first). The decision is stored with the
//! version in `policies`; only a version the gate lets through is pushed to the fleet.
//!
//! A run takes seconds, so it runs on a thread of its own, on a snapshot of the library taken
//! when it was decided on, while the loop goes on.

use crate::trainer::gate::{Decision, Driver, GateReport, gate};
use crate::trainer::{HeldOut, ReplayRule, TrainerError, TrainingPlan, train_variant};
use risktwin_common::env::{RiskShaping, Variant};
use risktwin_learn::{Algo, PolicyNet};
use risktwin_policy::model::DriverModel;
use risktwin_store::library::{PolicyVersion, ScenarioLibrary};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

/// The policy id of the versions the trainer produces.
pub const POLICY_ID: &str = "risktwin-full";

/// How the trainer trains and gates.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainerConfig {
    /// New fleet failures (collision or leaving the road, as the edges reported) since the last
    /// version that start the next training.
    pub retrain_failures: u64,
    /// The schedule: a run is also due this long after the last one began (or the role
    /// started) once at least one new fleet failure is in.
    pub every: Option<Duration>,
    /// Environment steps per training run.
    pub steps: u64,
    /// Held-out scenarios per kind the gate drives.
    pub held_out_per_kind: usize,
    /// Seed of the held-out set and of the training runs (version `v` trains with `seed + v`).
    pub seed: u64,
}

impl Default for TrainerConfig {
    fn default() -> Self {
        TrainerConfig { retrain_failures: 5, every: None, steps: 200_000, held_out_per_kind: 6, seed: 1 }
    }
}

impl TrainerConfig {
    /// The training plan of one run: PPO, one phase (the library is read once, at the start), the
    /// riskiest 60 and 30 other library scenarios replayed in half the episodes.
    pub fn plan(&self) -> TrainingPlan {
        TrainingPlan {
            algo: Algo::Ppo,
            steps: self.steps,
            n_envs: 32,
            phases: 1,
            curve_points: 1,
            replay_top: 60,
            background: 30,
            replay_share: 0.5,
            mutations: 0,
            mutation_radius: 0.1,
            risk_shaping: RiskShaping::default(),
            warm_start: false,
            cost_limit: None,
            replay_rule: ReplayRule::default(),
            threads: 1,
        }
    }
}

/// One training run to do, on a snapshot of the library taken when it was decided on (so that
/// what it trains on and is gated on does not depend on what the fleet reports meanwhile).
#[derive(Debug)]
pub struct TrainJob {
    /// Holds the snapshot `library.db` (removed with it).
    dir: tempfile::TempDir,
    pub version: u32,
    /// The version deployed now; `None`: the reference driver.
    pub deployed: Option<PolicyVersion>,
    pub failures: u64,
    pub config: TrainerConfig,
}

impl TrainJob {
    /// Trains version `version` and gates it (blocking: seconds). The version is not stored:
    /// the loop stores it with its decision.
    pub fn run(self) -> Result<(PolicyVersion, GateReport), TrainerError> {
        let mut library = ScenarioLibrary::open(self.dir.path().join("library.db"))?;
        let held_out = HeldOut::new(self.config.seed, self.config.held_out_per_kind);
        let seed = self.config.seed.wrapping_add(u64::from(self.version));
        let plan = self.config.plan();
        let trained = train_variant(&plan, Variant::Full, seed, &mut library, &held_out, &mut |_, _| {})?;
        let weights = policy_bytes(&trained.policy, &self.dir.path().join("candidate.safetensors"))?;
        let deployed = match &self.deployed {
            Some(v) => Some(policy_from(&v.weights, &self.dir.path().join("deployed.safetensors"))?),
            None => None,
        };
        let host = |p: &PolicyNet| p.host().map(|h| DriverModel::Native(Arc::new(h)));
        let candidate = host(&trained.policy)?;
        let deployed = deployed.as_ref().map(host).transpose()?;
        let driver = deployed.as_ref().map_or(Driver::Reference, Driver::Model);
        let gate_start = std::time::Instant::now();
        let report = gate(&library, Driver::Model(&candidate), driver, &held_out, plan.threads)?;
        tracing::info!(
            "trainer: version {} trained in {:.1} s ({} steps), gated in {:.1} s",
            self.version,
            trained.wall_s,
            trained.env_steps,
            gate_start.elapsed().as_secs_f64()
        );
        let version = PolicyVersion {
            version: self.version,
            policy_id: POLICY_ID.to_owned(),
            algo: plan.algo.name().to_owned(),
            weights,
            pushed: report.decision == Decision::Push,
            reasons: report.reasons.clone(),
            failures: self.failures,
        };
        Ok((version, report))
    }
}

fn io_error(what: &str, e: &std::io::Error) -> TrainerError {
    TrainerError::Io(format!("{what}: {e}"))
}

/// The policy's safetensors file, as bytes (written through `path`).
fn policy_bytes(policy: &PolicyNet, path: &Path) -> Result<Vec<u8>, TrainerError> {
    policy.save(path)?;
    std::fs::read(path).map_err(|e| io_error("reading the trained policy back", &e))
}

/// The policy of a stored safetensors file (written out to `path` to load it).
fn policy_from(weights: &[u8], path: &Path) -> Result<PolicyNet, TrainerError> {
    std::fs::write(path, weights).map_err(|e| io_error("writing the deployed policy out", &e))?;
    Ok(PolicyNet::load(path)?)
}

/// The next job, if `library` has enough new failures since the last version: `retrain_failures`,
/// or one once the schedule's period has passed since the last run began (`since_last`).
pub fn due(
    library: &ScenarioLibrary,
    config: &TrainerConfig,
    since_last: Duration,
) -> Result<Option<TrainJob>, TrainerError> {
    let latest = library.latest_policy()?;
    let failures = library.fleet_counts()?.failures;
    let since = latest.map_or(0, |(_, failures)| failures);
    let scheduled = config.every.is_some_and(|every| since_last >= every);
    let needed = if scheduled { 1 } else { config.retrain_failures.max(1) };
    if failures < since + needed {
        return Ok(None);
    }
    let dir = tempfile::tempdir().map_err(|e| io_error("a temporary directory", &e))?;
    library.snapshot(&dir.path().join("library.db"))?;
    let version = latest.map_or(1, |(v, _)| v + 1);
    let deployed = library.deployed_policy()?;
    Ok(Some(TrainJob { dir, version, deployed, failures, config: config.clone() }))
}
