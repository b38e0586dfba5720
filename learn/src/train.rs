//! The training driver behind `risktwin train`: builds the environments for a variant, runs
//! the learner for a number of environment steps, records training curves, periodically
//! measures success on benign scenarios, and evaluates the final policy on held-out scenarios
//! of all five kinds through `episode::run` (the metrics of `simulate`).
//!
//! Scenario sources: `base` and `risk-only` sample the five kinds uniformly; `full` replays half
//! its episodes from a risk-ranked list — candidates scored by the reference driver, highest
//! S_risk first, the library's stand-in here (`risktwin run` feeds the real library) — and
//! samples the other half fresh ([`DEFAULT_REPLAY_SHARE`]).

use crate::LearnError;
use crate::learner::Learner;
use crate::policy::{Algo, PolicyNet};
use crate::ppo::{PpoConfig, PpoTimings};
use crate::sac::SacConfig;
use crate::warm::warm_start;
use rayon::prelude::*;
use risktwin_common::env::{DEFAULT_REPLAY_SHARE, RiskShaping, ScenarioSource, Variant, VecEnv, benign_specs};
use risktwin_common::episode;
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, build, check_feasible, sample};
use serde::Serialize;
use std::time::Instant;

/// What to train.
#[derive(Debug, Clone)]
pub struct TrainConfig {
    pub algo: Algo,
    pub variant: Variant,
    /// Environment steps to train for.
    pub steps: u64,
    pub seed: u64,
    /// Environments stepped together.
    pub n_envs: usize,
    /// Training scenarios; `None` for the variant's default (see the module docs).
    pub scenarios: Option<ScenarioSource>,
    /// Held-out evaluation scenarios per kind.
    pub eval_per_kind: usize,
    /// Benign scenarios for the success-over-time measurement (0: skip it).
    pub benign_eval: usize,
    /// Environment steps between benign evaluations.
    pub benign_every: u64,
    /// PPO hyper-parameters (`recurrent` is set from `algo`).
    pub ppo: PpoConfig,
    /// SAC hyper-parameters.
    pub sac: SacConfig,
    /// Start from an imitation of the reference driver ([`crate::warm`], PPO only); its
    /// demonstration steps count against `steps`.
    pub warm_start: bool,
}

impl TrainConfig {
    /// Defaults for `algo`/`variant`: 64 envs, 10 held-out scenarios per kind, no benign eval.
    pub fn new(algo: Algo, variant: Variant, steps: u64, seed: u64) -> Self {
        Self {
            algo,
            variant,
            steps,
            seed,
            n_envs: 64,
            scenarios: None,
            eval_per_kind: 10,
            benign_eval: 0,
            benign_every: 100_000,
            ppo: PpoConfig::default(),
            sac: SacConfig::default(),
            warm_start: false,
        }
    }
}

/// One point of the training curves: the training episodes finished since the previous point,
/// averaged. The one definition for `risktwin train` and the cloud's trainer (whose points go
/// into `risktwin run`'s metrics.json as they are).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CurvePoint {
    pub env_steps: u64,
    pub episodes: u64,
    /// The variant's own training reward (base has no risk term).
    pub reward: f64,
    pub success_rate: f64,
    pub route_completion: f64,
    pub avg_speed_mps: f64,
    pub collision_rate: f64,
}

/// A curve point of one training run, with when it was taken and, where measured there, the
/// benign success (measurements: not part of any deterministic output).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checkpoint {
    pub point: CurvePoint,
    pub wall_s: f64,
    /// Success of the deterministic policy on the benign set, where measured at this point.
    pub benign_success: Option<f64>,
}

/// Metrics as in `simulate`, averaged over evaluation episodes, plus rates.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct FinalMetrics {
    pub episodes: u64,
    pub success_rate: f64,
    pub collision_rate: f64,
    pub offroad_rate: f64,
    pub route_completion: f64,
    pub avg_speed_mps: f64,
    pub steering_smoothness: f64,
    pub longitudinal_smoothness: f64,
    /// Mean over episodes where some pair closed in (`None` if none did).
    pub min_ttc_s: Option<f64>,
    /// Mean over episodes with a finite minimum distance.
    pub min_distance_m: Option<f64>,
    pub risk_score: f64,
    pub reward: f64,
    pub steps: f64,
}

impl FinalMetrics {
    /// Averages episode metrics.
    pub fn average(ms: &[EpisodeMetrics]) -> Self {
        let n = ms.len().max(1) as f64;
        let mean = |f: &dyn Fn(&EpisodeMetrics) -> f64| ms.iter().map(f).sum::<f64>() / n;
        let rate = |f: &dyn Fn(&EpisodeMetrics) -> bool| ms.iter().filter(|m| f(m)).count() as f64 / n;
        let opt_mean = |v: Vec<f64>| if v.is_empty() { None } else { Some(v.iter().sum::<f64>() / v.len() as f64) };
        Self {
            episodes: ms.len() as u64,
            success_rate: rate(&|m| m.success),
            collision_rate: rate(&|m| m.collision),
            offroad_rate: rate(&|m| m.offroad),
            route_completion: mean(&|m| m.route_completion),
            avg_speed_mps: mean(&|m| m.avg_speed_mps),
            steering_smoothness: mean(&|m| m.steering_smoothness),
            longitudinal_smoothness: mean(&|m| m.longitudinal_smoothness),
            min_ttc_s: opt_mean(ms.iter().filter_map(|m| m.min_ttc_s).collect()),
            min_distance_m: opt_mean(ms.iter().map(|m| m.min_distance_m).filter(|d| d.is_finite()).collect()),
            risk_score: mean(&|m| m.risk_score),
            reward: mean(&|m| m.reward),
            steps: mean(&|m| m.steps as f64),
        }
    }
}

/// What a training run produced.
#[derive(Debug, Clone)]
pub struct TrainReport {
    pub algo: Algo,
    pub variant: Variant,
    pub steps: u64,
    pub wall_s: f64,
    pub env_steps_per_s: f64,
    pub final_metrics: FinalMetrics,
    pub curve: Vec<Checkpoint>,
    /// Wall time at which the benign success first reached 90 %, s.
    pub benign_90_wall_s: Option<f64>,
    pub policy: PolicyNet,
    /// Where PPO's time went (zeros for SAC).
    pub timings: PpoTimings,
}

/// Held-out evaluation scenarios: `per_kind` feasible samples of each kind from a seed stream
/// disjoint from training's.
pub fn held_out_specs(seed: u64, per_kind: usize) -> Vec<ScenarioSpec> {
    let run_seed = Rng::derive(seed, 0xE7A1_0000).next_u64();
    ScenarioKind::ALL
        .iter()
        .flat_map(|&kind| {
            (0..).map(move |i| sample(run_seed, kind, i)).filter(|s| check_feasible(s).is_ok()).take(per_kind)
        })
        .collect()
}

/// The `full` variant's training list: `per_kind` candidates of each kind scored by the
/// reference driver, the riskier half kept.
pub fn risk_ranked_specs(seed: u64, per_kind: usize) -> Vec<ScenarioSpec> {
    let run_seed = Rng::derive(seed, 0x5C0_0000).next_u64();
    let candidates: Vec<ScenarioSpec> = ScenarioKind::ALL
        .iter()
        .flat_map(|&kind| {
            (0..).map(move |i| sample(run_seed, kind, i)).filter(|s| check_feasible(s).is_ok()).take(per_kind)
        })
        .collect();
    let mut scored: Vec<(f64, ScenarioSpec)> =
        candidates.into_par_iter().map(|s| (episode::evaluate(&s).metrics.risk_score, s)).collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    scored.truncate(scored.len().div_ceil(2));
    scored.into_iter().map(|(_, s)| s).collect()
}

/// The scenarios a run of `variant` and `seed` trains on: every kind sampled fresh, and for
/// `full` the risk-ranked list replayed beside them.
pub fn training_source(variant: Variant, seed: u64) -> ScenarioSource {
    match variant {
        Variant::Full => {
            ScenarioSource::Replay { seed, specs: risk_ranked_specs(seed, 40), share: DEFAULT_REPLAY_SHARE }
        }
        _ => ScenarioSource::all_kinds(seed),
    }
}

/// Drives each spec with the policy's deterministic action ([`crate::drive::drive`]), scored
/// as every evaluation scores (`full`'s weights, whatever the policy trained with): the metrics
/// `risktwin simulate --driver` prints for the same file.
pub fn evaluate_policy(policy: &PolicyNet, specs: &[ScenarioSpec]) -> Vec<EpisodeMetrics> {
    let weights = Variant::Full.weights();
    specs
        .par_iter()
        .map(|spec| crate::drive::drive(policy, &mut build(spec), &weights, &mut |_, _| {}).metrics)
        .collect()
}

/// Trains as configured; `progress(done, total)` is called after each learner iteration.
pub fn train(cfg: &TrainConfig, progress: &mut dyn FnMut(u64, u64)) -> Result<TrainReport, LearnError> {
    if cfg.steps == 0 || cfg.n_envs == 0 {
        return Err(LearnError::BadConfig(format!("steps ({}) and envs ({}) must be positive", cfg.steps, cfg.n_envs)));
    }
    let source = cfg.scenarios.clone().unwrap_or_else(|| training_source(cfg.variant, cfg.seed));
    let benign = if cfg.benign_eval > 0 { benign_specs(cfg.seed ^ 0xBE91_6000, cfg.benign_eval) } else { Vec::new() };
    let start = Instant::now();
    let reward = cfg.variant.training_reward(RiskShaping::default());
    let mut learner = Learner::new(cfg.algo, &cfg.ppo, &cfg.sac, cfg.n_envs, cfg.seed)?;
    let mut done_steps =
        if cfg.warm_start { warm_start(&mut learner, &source, reward, cfg.n_envs, cfg.seed)?.env_steps } else { 0 };
    let mut env = VecEnv::new(cfg.n_envs, source, reward)?;
    let mut curve = Vec::new();
    let mut acc: Vec<EpisodeMetrics> = Vec::new();
    let mut next_benign = 0u64;
    let mut benign_90 = None;
    while done_steps < cfg.steps {
        let n = learner.step(&mut env)?;
        done_steps += n;
        env.drain_finished(|_, s| acc.push(s.metrics));
        let policy = learner.policy();
        let benign_success = if !benign.is_empty() && done_steps >= next_benign {
            next_benign = done_steps + cfg.benign_every;
            let m = evaluate_policy(policy, &benign);
            let rate = m.iter().filter(|m| m.success).count() as f64 / m.len() as f64;
            if rate >= 0.9 && benign_90.is_none() {
                benign_90 = Some(start.elapsed().as_secs_f64());
            }
            Some(rate)
        } else {
            None
        };
        if !acc.is_empty() || benign_success.is_some() {
            let f = FinalMetrics::average(&acc);
            curve.push(Checkpoint {
                point: CurvePoint {
                    env_steps: done_steps,
                    episodes: acc.len() as u64,
                    reward: f.reward,
                    success_rate: f.success_rate,
                    route_completion: f.route_completion,
                    avg_speed_mps: f.avg_speed_mps,
                    collision_rate: f.collision_rate,
                },
                wall_s: start.elapsed().as_secs_f64(),
                benign_success,
            });
            acc.clear();
        }
        progress(done_steps.min(cfg.steps), cfg.steps);
    }
    let wall_s = start.elapsed().as_secs_f64();
    let timings = learner.timings();
    let policy = learner.policy().clone();
    let final_metrics = FinalMetrics::average(&evaluate_policy(&policy, &held_out_specs(cfg.seed, cfg.eval_per_kind)));
    Ok(TrainReport {
        algo: cfg.algo,
        variant: cfg.variant,
        steps: done_steps,
        wall_s,
        env_steps_per_s: done_steps as f64 / wall_s.max(1e-9),
        final_metrics,
        curve,
        benign_90_wall_s: benign_90,
        policy,
        timings,
    })
}

/// The curves as CSV (header + one row per point; empty benign cells where not measured).
pub fn curves_csv(curve: &[Checkpoint]) -> String {
    let mut s = String::from(
        "env_steps,wall_s,episodes,reward,success_rate,route_completion,avg_speed_mps,collision_rate,benign_success\n",
    );
    for c in curve {
        let p = &c.point;
        s.push_str(&format!(
            "{},{:.3},{},{:.6},{:.6},{:.6},{:.6},{:.6},{}\n",
            p.env_steps,
            c.wall_s,
            p.episodes,
            p.reward,
            p.success_rate,
            p.route_completion,
            p.avg_speed_mps,
            p.collision_rate,
            c.benign_success.map(|b| format!("{b:.4}")).unwrap_or_default()
        ));
    }
    s
}
