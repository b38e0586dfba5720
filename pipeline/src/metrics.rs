//! `metrics.json`, the deterministic record of a run.

use crate::closed_loop::ClosedLoop;
use crate::config::RunConfig;
use crate::rescore::Rescore;
use crate::search::{KindSummary, RoundReport};
use crate::verdict::Verdict;
use risktwin_cloud::generate::GenerateReport;
use risktwin_cloud::trainer::{AblationReport, FloorEvaluation};
use risktwin_common::scenario::ScenarioKind;
use risktwin_store::library::RankedScenario;
use serde::Serialize;
use std::collections::BTreeMap;

/// `metrics.json`: everything measured, nothing from the wall clock (same seed → same bytes).
#[derive(Debug, Clone, Serialize)]
pub struct RunMetrics {
    pub seed: u64,
    pub config: RunConfig,
    pub generation: GenerateReport,
    pub rounds: Vec<RoundReport>,
    pub by_kind: BTreeMap<ScenarioKind, KindSummary>,
    pub top: Vec<RankedScenario>,
    pub heatmaps: Vec<String>,
    /// The training seeds (derived from `seed`).
    pub training_seeds: Vec<u64>,
    pub ablation: AblationReport,
    /// The privileged planner on the held-out set: the achievable floor per kind.
    pub floor: FloorEvaluation,
    /// The target checked against the ablation (absent when base or full was not trained).
    pub verdict: Option<Verdict>,
    /// The top scenarios driven again by each variant's policy.
    pub rescore: Vec<Rescore>,
    /// What `recording.mcap` holds (absent when nothing was recorded).
    pub recording: Option<String>,
    /// The push phase: what an edge vehicle reported over Zenoh, against the same episodes run
    /// here (absent when `push_scenarios` is 0).
    pub closed_loop: Option<ClosedLoop>,
    /// Files of the report folder.
    pub files: Vec<String>,
}
