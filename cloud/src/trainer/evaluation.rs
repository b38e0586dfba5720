//! One driver's evaluation over a scenario set beside the reference driver: the document
//! `risktwin evaluate` prints and the Python package returns (docs/cli.md, `evaluate`), built
//! in one place so the two cannot drift. Shares and means carry their 95 % intervals
//! ([`super::outcomes`]).

use super::drive::Driver;
use super::evaluate_floor;
use super::outcomes::{CONFIDENCE, OutcomeSummary, Share};
use risktwin_common::driver::REFERENCE_LABEL;
use risktwin_common::episode::EpisodeResult;
use risktwin_common::metrics::{Ending, EpisodeMetrics};
use risktwin_common::planner::Verdict;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};
use risktwin_store::library::{COMMONROAD_KIND, LibraryError, Outcome, ScenarioLibrary, ScenarioRecord, content_id};
use serde::Serialize;
use std::collections::BTreeMap;

/// The most held-out scenarios of one kind an evaluation drives.
pub const MAX_PER_KIND: u64 = 10_000;
/// The held-out set evaluated when none is named: run seed 1, 12 scenarios per kind.
pub const DEFAULT_SEED: u64 = 1;
pub const DEFAULT_PER_KIND: u64 = 12;

/// Which scenarios were driven.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "source", rename_all = "kebab-case")]
pub enum ScenarioSet {
    HeldOut {
        seed: u64,
        per_kind: u64,
    },
    Library {
        db: String,
    },
    #[serde(rename = "commonroad")]
    CommonRoad {
        files: Vec<String>,
    },
}

/// The achievable floor of a set: scenarios in which the privileged planner found a drive that
/// completes the route unharmed, and the collision share no driver can go below (1 − that).
#[derive(Debug, Clone, Serialize)]
pub struct FloorSummary {
    pub avoidable: Share,
}

/// One kind (or all): the driver, the reference driver and the floor.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    pub driver: OutcomeSummary,
    pub reference: OutcomeSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floor: Option<FloorSummary>,
}

/// One scenario's episode.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeRow {
    pub id: String,
    /// A scenario kind, or `commonroad` for a recording.
    pub kind: String,
    /// The generated scenario's seed (`null` for a recording).
    pub seed: Option<u64>,
    pub ended: Ending,
    pub reference_ended: Ending,
    pub metrics: EpisodeMetrics,
}

/// A scenario driven by the driver and by the reference driver.
pub struct Driven {
    pub id: String,
    pub kind: String,
    pub seed: Option<u64>,
    pub driver: EpisodeResult,
    pub reference: EpisodeResult,
}

impl Driven {
    /// Generated scenarios with the driver's and the reference driver's episodes, in order.
    pub fn generated(specs: &[ScenarioSpec], runs: Vec<EpisodeResult>, reference: Vec<EpisodeResult>) -> Vec<Self> {
        specs
            .iter()
            .zip(runs.into_iter().zip(reference))
            .map(|(s, (driver, reference))| Driven {
                id: content_id(s),
                kind: s.kind.name().to_owned(),
                seed: Some(s.seed),
                driver,
                reference,
            })
            .collect()
    }
}

/// The evaluation document (docs/cli.md, `evaluate`).
#[derive(Debug, Clone, Serialize)]
pub struct EvaluationDoc {
    pub driver: String,
    pub reference: &'static str,
    pub set: ScenarioSet,
    pub confidence: f64,
    pub overall: Comparison,
    pub by_kind: BTreeMap<String, Comparison>,
    /// Decisions the model failed to give (driven as the zero action); 0 for a sound model.
    pub model_faults: u64,
    pub episodes: Vec<EpisodeRow>,
}

impl EvaluationDoc {
    /// The document of `driven` by the driver `label`; `avoidable` (one per scenario, with
    /// the floor searched) adds each kind's floor.
    pub fn new(label: String, set: ScenarioSet, driven: &[Driven], avoidable: Option<&[bool]>, faults: u64) -> Self {
        let compare = |kind: Option<&str>| {
            let of = |d: &&Driven| kind.is_none_or(|want| d.kind == want);
            let pick =
                |f: fn(&Driven) -> &EpisodeResult| OutcomeSummary::of(driven.iter().filter(of).map(|d| &f(d).metrics));
            let floor = avoidable.map(|a| {
                let (mine, n) = driven
                    .iter()
                    .zip(a)
                    .filter(|(d, _)| of(d))
                    .fold((0, 0), |(k, n), (_, &v)| (k + u64::from(v), n + 1));
                FloorSummary { avoidable: Share::wilson(mine, n) }
            });
            Comparison { driver: pick(|d| &d.driver), reference: pick(|d| &d.reference), floor }
        };
        let mut kinds: Vec<&str> = ScenarioKind::ALL.iter().map(|k| k.name()).chain([COMMONROAD_KIND]).collect();
        kinds.retain(|k| driven.iter().any(|d| d.kind == *k));
        EvaluationDoc {
            driver: label,
            reference: REFERENCE_LABEL,
            set,
            confidence: CONFIDENCE,
            overall: compare(None),
            by_kind: kinds.iter().map(|&k| (k.to_owned(), compare(Some(k)))).collect(),
            model_faults: faults,
            episodes: driven
                .iter()
                .map(|d| EpisodeRow {
                    id: d.id.clone(),
                    kind: d.kind.clone(),
                    seed: d.seed,
                    ended: d.driver.metrics.ending(),
                    reference_ended: d.reference.metrics.ending(),
                    metrics: d.driver.metrics.clone(),
                })
                .collect(),
        }
    }
}

/// The reference driver's episodes of `specs` on `threads` workers.
pub fn reference_runs(specs: &[ScenarioSpec], threads: usize) -> Vec<EpisodeResult> {
    Driver::Reference.episodes(specs, threads)
}

/// Whether the privileged planner finds each scenario avoidable (its floor), given the
/// reference driver's episodes of them.
pub fn avoidable(specs: &[ScenarioSpec], reference: &[EpisodeResult], threads: usize) -> Vec<bool> {
    let metrics: Vec<EpisodeMetrics> = reference.iter().map(|r| r.metrics.clone()).collect();
    evaluate_floor(specs, &metrics, threads).cases.iter().map(|c| c.verdict == Verdict::Avoidable).collect()
}

/// Every generated scenario of the library, in id order.
pub fn library_specs(library: &ScenarioLibrary) -> Result<Vec<ScenarioSpec>, LibraryError> {
    let mut ids: Vec<String> = library.rank(None, None)?.into_iter().map(|r| r.id).collect();
    ids.sort();
    ids.iter()
        .map(|id| library.get(id)?.map(|s| s.spec).ok_or_else(|| LibraryError::UnknownScenario(id.clone())))
        .collect()
}

/// Every episode's outcome in the library under `label` (a collision marks a regression case).
pub fn store_outcomes(
    library: &mut ScenarioLibrary,
    specs: &[ScenarioSpec],
    runs: &[EpisodeResult],
    label: &str,
) -> Result<(), LibraryError> {
    let records: Vec<ScenarioRecord> = specs
        .iter()
        .zip(runs)
        .map(|(s, r)| {
            let outcome = Outcome { policy: label.to_owned(), metrics: r.metrics.clone(), risk: r.risk };
            ScenarioRecord::sampled(s.clone(), outcome)
        })
        .collect();
    library.insert_batch(&records)?;
    Ok(())
}
