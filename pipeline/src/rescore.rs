//! Re-scoring after training: each variant's policy (first seed) drives the library's top
//! scenarios; its outcomes are stored in the library under `<algo>-<variant>-final`, next to the
//! reference driver's, so the ranking can be read per policy.

use risktwin_cloud::trainer::drive::drive_all;
use risktwin_common::env::Variant;
use risktwin_learn::PolicyNet;
use risktwin_store::library::{LibraryError, Origin, Outcome, RankedScenario, ScenarioLibrary, ScenarioRecord};
use serde::Serialize;

/// One policy on the top scenarios.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rescore {
    pub policy: String,
    pub scenarios: usize,
    pub collisions: usize,
    pub mean_risk: f64,
    /// S_risk per top scenario, in ranking order.
    pub risk: Vec<f64>,
}

/// Drives `top` with every policy and stores the outcomes.
pub fn rescore(
    library: &mut ScenarioLibrary,
    top: &[RankedScenario],
    policies: &[(Variant, PolicyNet)],
    algo: &str,
    threads: usize,
) -> Result<Vec<Rescore>, LibraryError> {
    let mut specs = Vec::with_capacity(top.len());
    for r in top {
        if let Some(s) = library.get(&r.id)? {
            specs.push(s.spec);
        }
    }
    let mut out = vec![Rescore {
        policy: "idm".to_string(),
        scenarios: top.len(),
        collisions: top.iter().filter(|r| r.outcome.collision).count(),
        mean_risk: top.iter().map(|r| r.risk.score).sum::<f64>() / top.len().max(1) as f64,
        risk: top.iter().map(|r| r.risk.score).collect(),
    }];
    for (variant, policy) in policies {
        let label = format!("{algo}-{variant}-final");
        let results = drive_all(policy, &specs, threads);
        let records: Vec<ScenarioRecord> = specs
            .iter()
            .zip(&results)
            .map(|(s, r)| ScenarioRecord {
                spec: s.clone(),
                origin: Origin::Imported,
                parent_id: None,
                outcome: Some(Outcome { policy: label.clone(), metrics: r.metrics.clone(), risk: r.risk }),
            })
            .collect();
        library.insert_batch(&records)?;
        out.push(Rescore {
            policy: label,
            scenarios: results.len(),
            collisions: results.iter().filter(|r| r.metrics.collision).count(),
            mean_risk: results.iter().map(|r| r.risk.score).sum::<f64>() / results.len().max(1) as f64,
            risk: results.iter().map(|r| r.risk.score).collect(),
        });
    }
    Ok(out)
}
