//! The ablation: every variant trained with every seed, each policy evaluated on the held-out
//! set, and the results gathered per variant and per kind with their spread over seeds; the
//! reference driver is evaluated on the same set for scale.

use super::curriculum::Refresh;
use super::drive::drive_all;
use super::held_out::HeldOut;
use super::plan::{TrainerError, TrainingPlan};
use super::session::{CurvePoint, train_variant};
use super::stats::{EvalMetrics, EvalSpread, Spread};
use crate::generate::parallel_map;
use risktwin_common::env::Variant;
use risktwin_common::episode;
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};
use risktwin_learn::PolicyNet;
use risktwin_store::library::ScenarioLibrary;
use serde::Serialize;
use std::collections::BTreeMap;

/// One policy on the held-out set: over all scenarios and per kind.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PolicyEvaluation {
    pub overall: EvalMetrics,
    pub by_kind: BTreeMap<ScenarioKind, EvalMetrics>,
}

impl PolicyEvaluation {
    /// Episodes of `specs` (one metrics per spec, in order), averaged over all and per kind.
    pub fn from_episodes(specs: &[ScenarioSpec], ms: &[EpisodeMetrics]) -> Self {
        let mut by_kind = BTreeMap::new();
        for kind in ScenarioKind::ALL {
            let of_kind: Vec<EpisodeMetrics> =
                specs.iter().zip(ms).filter(|(s, _)| s.kind == kind).map(|(_, m)| m.clone()).collect();
            by_kind.insert(kind, EvalMetrics::average(&of_kind));
        }
        Self { overall: EvalMetrics::average(ms), by_kind }
    }
}

/// Evaluates a learned policy on the held-out set.
pub fn evaluate_policy(policy: &PolicyNet, held_out: &HeldOut, threads: usize) -> PolicyEvaluation {
    let ms: Vec<EpisodeMetrics> = drive_all(policy, &held_out.specs, threads).into_iter().map(|r| r.metrics).collect();
    PolicyEvaluation::from_episodes(&held_out.specs, &ms)
}

/// The reference driver's (IDM/MOBIL) episodes of `specs`, one per spec in order, with the same
/// reward weights: the one definition of the reference result (the ablation's `reference` and
/// the floor's comparison are both made of it).
pub fn reference_episodes(specs: &[ScenarioSpec], threads: usize) -> Vec<EpisodeMetrics> {
    parallel_map(specs, threads, |s| episode::evaluate(s).metrics)
}

/// One training seed of a variant.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeedResult {
    pub seed: u64,
    pub env_steps: u64,
    pub held_out: PolicyEvaluation,
    pub curve: Vec<CurvePoint>,
    pub refreshes: Vec<Refresh>,
}

/// The training curves at one checkpoint, over the seeds that finished episodes by then.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CurveBand {
    pub env_steps: u64,
    pub seeds: usize,
    pub reward: Spread,
    pub success_rate: Spread,
    pub route_completion: Spread,
    pub avg_speed_mps: Spread,
    pub collision_rate: Spread,
}

/// A variant over its seeds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VariantResult {
    pub variant: String,
    pub overall: EvalSpread,
    pub by_kind: BTreeMap<ScenarioKind, EvalSpread>,
    pub curve: Vec<CurveBand>,
    pub seeds: Vec<SeedResult>,
}

/// Everything the ablation measured (deterministic for a seed; wall times kept apart).
#[derive(Debug, Clone, Serialize)]
pub struct AblationReport {
    pub algo: String,
    pub steps_per_run: u64,
    pub held_out_per_kind: usize,
    pub held_out_episodes: usize,
    /// The reference driver on the held-out set.
    pub reference: PolicyEvaluation,
    /// Its episodes, one per held-out scenario in order (the floor's comparison), not serialised.
    #[serde(skip)]
    pub reference_episodes: Vec<EpisodeMetrics>,
    pub variants: Vec<VariantResult>,
    /// Wall time of each training run, s, by (variant, seed): a measurement, not serialised.
    #[serde(skip)]
    pub train_wall_s: Vec<(Variant, u64, f64)>,
    /// Each variant's policy from its first seed (for re-scoring and saving), not serialised.
    #[serde(skip)]
    pub policies: Vec<(Variant, PolicyNet)>,
}

impl AblationReport {
    /// The result of a variant, if it was trained.
    pub fn variant(&self, v: Variant) -> Option<&VariantResult> {
        self.variants.iter().find(|r| r.variant == v.name())
    }
}

fn bands(curves: &[&[CurvePoint]]) -> Vec<CurveBand> {
    let mut at: BTreeMap<u64, Vec<&CurvePoint>> = BTreeMap::new();
    for c in curves {
        for p in c.iter() {
            at.entry(p.env_steps).or_default().push(p);
        }
    }
    at.into_iter()
        .map(|(env_steps, ps)| {
            let s = |f: fn(&CurvePoint) -> f64| Spread::of(&ps.iter().map(|p| f(p)).collect::<Vec<_>>());
            CurveBand {
                env_steps,
                seeds: ps.len(),
                reward: s(|p| p.reward),
                success_rate: s(|p| p.success_rate),
                route_completion: s(|p| p.route_completion),
                avg_speed_mps: s(|p| p.avg_speed_mps),
                collision_rate: s(|p| p.collision_rate),
            }
        })
        .collect()
}

/// Trains each variant with each seed (in that order, so the library evolves the same way for
/// a seed) and evaluates on `held_out`; `progress(run_label, done, total)` follows training.
pub fn run_ablation(
    plan: &TrainingPlan,
    variants: &[Variant],
    seeds: &[u64],
    library: &mut ScenarioLibrary,
    held_out: &HeldOut,
    progress: &mut dyn FnMut(&str, u64, u64),
) -> Result<AblationReport, TrainerError> {
    plan.validate()?;
    if seeds.is_empty() || variants.is_empty() {
        return Err(TrainerError::BadPlan("at least one variant and one seed are needed".into()));
    }
    let runs = variants.len() * seeds.len();
    let mut results = Vec::new();
    let mut walls = Vec::new();
    let mut policies = Vec::new();
    for (vi, &variant) in variants.iter().enumerate() {
        let mut per_seed = Vec::new();
        for (si, &seed) in seeds.iter().enumerate() {
            let label = format!("[{}/{runs}] {} {variant} seed {seed}", vi * seeds.len() + si + 1, plan.algo.name());
            let trained = train_variant(plan, variant, seed, library, held_out, &mut |d, t| progress(&label, d, t))?;
            walls.push((variant, seed, trained.wall_s));
            if si == 0 {
                policies.push((variant, trained.policy.clone()));
            }
            per_seed.push(SeedResult {
                seed,
                env_steps: trained.env_steps,
                held_out: evaluate_policy(&trained.policy, held_out, plan.threads),
                curve: trained.curve,
                refreshes: trained.refreshes,
            });
        }
        let overall = EvalSpread::over(&per_seed.iter().map(|s| s.held_out.overall).collect::<Vec<_>>());
        let by_kind = ScenarioKind::ALL
            .iter()
            .map(|k| {
                let ms: Vec<EvalMetrics> = per_seed.iter().filter_map(|s| s.held_out.by_kind.get(k).copied()).collect();
                (*k, EvalSpread::over(&ms))
            })
            .collect();
        let curve = bands(&per_seed.iter().map(|s| s.curve.as_slice()).collect::<Vec<_>>());
        results.push(VariantResult { variant: variant.name().to_string(), overall, by_kind, curve, seeds: per_seed });
    }
    let reference = reference_episodes(&held_out.specs, plan.threads);
    Ok(AblationReport {
        algo: plan.algo.name().to_string(),
        steps_per_run: plan.steps,
        held_out_per_kind: held_out.specs.len() / ScenarioKind::ALL.len(),
        held_out_episodes: held_out.specs.len(),
        reference: PolicyEvaluation::from_episodes(&held_out.specs, &reference),
        reference_episodes: reference,
        variants: results,
        train_wall_s: walls,
        policies,
    })
}
