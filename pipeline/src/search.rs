//! The scenario search of a run, after the first generation: rounds of neighbourhood search
//! (mutation) around the library's failures under the reference driver, and the per-kind
//! summary of what the library holds at the end.

use crate::config::RunConfig;
use risktwin_cloud::generate::{evaluate_all, reference_outcome};
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, mutate};
use risktwin_store::library::{LibraryError, ScenarioLibrary, ScenarioRecord};
use serde::Serialize;
use std::collections::BTreeMap;

/// One mutation round's effect.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RoundReport {
    pub round: u32,
    pub parents: usize,
    pub children: usize,
    pub infeasible_children: usize,
    pub parent_mean_risk: f64,
    pub child_mean_risk: f64,
    pub child_collisions: usize,
}

/// Aggregate over the library per kind.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct KindSummary {
    pub scenarios: u64,
    pub collisions: u64,
    pub collision_rate: f64,
    pub mean_risk: f64,
    pub max_risk: f64,
}

/// One round of neighbourhood search around the library's failures.
pub fn mutation_round(
    library: &mut ScenarioLibrary,
    config: &RunConfig,
    round: u32,
    rng: &mut Rng,
) -> Result<RoundReport, LibraryError> {
    let parents = library.select_for_mutation(config.mutations_per_iteration, rng)?;
    let mut children: Vec<(String, ScenarioSpec)> = Vec::new();
    let mut infeasible_children = 0;
    let mut parent_risk = 0.0;
    for parent in &parents {
        parent_risk += parent.risk.score;
        let spec = library.get(&parent.id)?.map(|s| s.spec);
        let Some(spec) = spec else { continue };
        match mutate(&spec, config.training.mutation_radius, rng) {
            Ok(child) => children.push((parent.id.clone(), child)),
            Err(_) => infeasible_children += 1,
        }
    }
    let (parent_ids, specs): (Vec<String>, Vec<ScenarioSpec>) = children.into_iter().unzip();
    let evaluated = evaluate_all(specs, config.training.threads);
    let records: Vec<ScenarioRecord> = evaluated
        .iter()
        .zip(&parent_ids)
        .map(|(e, pid)| ScenarioRecord::mutated(e.spec.clone(), pid, reference_outcome(&e.result)))
        .collect();
    library.insert_batch(&records)?;
    let n = evaluated.len().max(1) as f64;
    Ok(RoundReport {
        round,
        parents: parents.len(),
        children: evaluated.len(),
        infeasible_children,
        parent_mean_risk: parent_risk / parents.len().max(1) as f64,
        child_mean_risk: evaluated.iter().map(|e| e.result.risk.score).sum::<f64>() / n,
        child_collisions: evaluated.iter().filter(|e| e.result.metrics.collision).count(),
    })
}

/// Per kind: how many scenarios the library holds, their collisions and risk.
pub fn summarise(library: &ScenarioLibrary) -> Result<BTreeMap<ScenarioKind, KindSummary>, LibraryError> {
    let mut out = BTreeMap::new();
    for kind in ScenarioKind::ALL {
        let all = library.rank(None, Some(kind))?;
        let n = all.len() as u64;
        let collisions = all.iter().filter(|r| r.outcome.collision).count() as u64;
        let mean_risk = all.iter().map(|r| r.risk.score).sum::<f64>() / (n.max(1) as f64);
        let max_risk = all.iter().map(|r| r.risk.score).fold(0.0, f64::max);
        let collision_rate = collisions as f64 / n.max(1) as f64;
        out.insert(kind, KindSummary { scenarios: n, collisions, collision_rate, mean_risk, max_risk });
    }
    Ok(out)
}

/// The training seeds of a run: a seed stream of their own.
pub fn training_seeds(seed: u64, n: u32) -> Vec<u64> {
    let mut rng = Rng::derive(seed, 0x5345_4544);
    (0..n).map(|_| rng.below(1_000_000)).collect()
}
