//! The `full` variant's training scenarios, fed from the scenario library and refreshed as the
//! policy improves (docs/method.md §7, "risk-aware scenario library feeding training").
//!
//! The first phase trains on the library's risk-ranked replay (the reference driver's riskiest
//! scenarios among those it survives, see [`solvable_replay`]) mixed with an equal share of ordinary library scenarios drawn uniformly, so the
//! policy still sees the distribution it is evaluated on. After each phase the current policy
//! drives the replay set and the previous children; its outcomes are stored in the library under
//! the phase's policy label, its failures (collision or leaving the road; the riskiest episodes
//! when it has none) are mutated — neighbourhood search — and the children are stored with their
//! lineage, driven by the policy and by the reference driver. The next phase trains on the
//! policy's own risk ranking, the failures, their children and the background share (children
//! the reference driver crashes in are stored but not trained on).
//! With the frontier rule ([`ReplayRule::Frontier`]) the candidates include a background draw,
//! and the next phase instead trains on the candidates the policy completes in some but not all of [`FRONTIER_DRIVES`] drives with its
//! exploration noise, most uncertain first, and the children are mutated around those.
//! Held-out scenarios never enter: every list is checked against [`HeldOut`].

use super::drive::{drive_all, success_shares};
use super::held_out::HeldOut;
use super::plan::{ReplayRule, TrainerError, TrainingPlan};
use crate::generate::{evaluate_all, reference_outcome};
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioSpec, mutate};
use risktwin_learn::PolicyNet;
use risktwin_store::library::{Origin, Outcome, ScenarioLibrary, ScenarioRecord, content_id};
use serde::Serialize;
use std::collections::BTreeSet;

/// What one refresh of the training set did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refresh {
    /// The phase whose policy was evaluated (0-based); its set feeds phase + 1.
    pub phase: u32,
    /// Label under which the policy's outcomes are stored in the library.
    pub policy: String,
    /// Library scenarios the policy drove.
    pub evaluated: usize,
    /// Of those, collisions or road departures.
    pub failures: usize,
    /// Mutated children stored around the failures.
    pub children: usize,
    /// Of the children, failures of the policy.
    pub child_failures: usize,
    /// Scenarios in the next phase's training list.
    pub training_set: usize,
    /// Mean S_risk of the policy on the evaluated scenarios.
    pub policy_mean_risk: f64,
    /// With the frontier rule: the scenarios on the frontier (trained on, up to `replay_top`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frontier: Option<usize>,
}

/// Drives per candidate with the exploration noise for the frontier rule: success shares of
/// 1/4 to 3/4 count as the frontier (a cheap estimate; 4 drives of ≈ 190 candidates, at most
/// 300 steps each, cost at most 230k environment steps per refresh, driven on all threads).
pub const FRONTIER_DRIVES: usize = 4;

/// The growing training list of one `full` run.
#[derive(Debug)]
pub struct Curriculum {
    rng: Rng,
    /// Children of the last refresh, re-driven at the next one.
    children: Vec<ScenarioSpec>,
}

fn dedup(specs: impl IntoIterator<Item = ScenarioSpec>, held_out: &HeldOut) -> Vec<ScenarioSpec> {
    let mut seen = BTreeSet::new();
    specs.into_iter().filter(|s| !held_out.contains(s) && seen.insert(content_id(s))).collect()
}

/// The risk-ranked replay: the reference driver's `plan.replay_top` riskiest scenarios among
/// those it survives. A scenario it crashes in has no known way through, so replaying it teaches
/// a policy only how to fail cheaply (leaving the road instead of colliding, or crawling);
/// prioritised level replay likewise replays the levels with learning potential, not the hardest.
fn solvable_replay(library: &ScenarioLibrary, plan: &TrainingPlan) -> Result<Vec<ScenarioSpec>, TrainerError> {
    let mut specs = Vec::with_capacity(plan.replay_top);
    for r in library.rank(None, None)? {
        if specs.len() == plan.replay_top {
            break;
        }
        if !r.outcome.collision
            && let Some(s) = library.get(&r.id)?
        {
            specs.push(s.spec);
        }
    }
    Ok(specs)
}

impl Curriculum {
    /// A curriculum for the training seed `seed`.
    pub fn new(seed: u64) -> Self {
        Self { rng: Rng::derive(seed, 0x4355_5252), children: Vec::new() }
    }

    /// `plan.background` library scenarios drawn uniformly (without replacement).
    fn background(
        &mut self,
        library: &ScenarioLibrary,
        plan: &TrainingPlan,
    ) -> Result<Vec<ScenarioSpec>, TrainerError> {
        let mut all = library.rank(None, None)?;
        let mut out = Vec::with_capacity(plan.background);
        while out.len() < plan.background && !all.is_empty() {
            let r = all.swap_remove(self.rng.below(all.len() as u64) as usize);
            if let Some(s) = library.get(&r.id)? {
                out.push(s.spec);
            }
        }
        Ok(out)
    }

    /// The first phase's list: the reference driver's `plan.replay_top` riskiest scenarios and
    /// the background share.
    pub fn initial(
        &mut self,
        library: &ScenarioLibrary,
        plan: &TrainingPlan,
        held_out: &HeldOut,
    ) -> Result<Vec<ScenarioSpec>, TrainerError> {
        let mut specs = solvable_replay(library, plan)?;
        specs.extend(self.background(library, plan)?);
        let specs = dedup(specs, held_out);
        if specs.is_empty() {
            return Err(TrainerError::EmptyLibrary);
        }
        held_out.check_disjoint(&specs)?;
        Ok(specs)
    }

    /// Evaluates `policy` (stored as `label`) on the replay set, mutates around its failures,
    /// and returns the next phase's list with what was done.
    #[allow(clippy::too_many_arguments)]
    pub fn refresh(
        &mut self,
        library: &mut ScenarioLibrary,
        policy: &PolicyNet,
        label: &str,
        phase: u32,
        plan: &TrainingPlan,
        held_out: &HeldOut,
        threads: usize,
    ) -> Result<(Vec<ScenarioSpec>, Refresh), TrainerError> {
        let mut candidates = solvable_replay(library, plan)?;
        candidates.extend(std::mem::take(&mut self.children));
        if plan.replay_rule == ReplayRule::Frontier {
            // The riskiest scenarios are mostly beyond the policy (it failed 57-68 of 60-77 in
            // every noisy drive on seed 1): the frontier is sought among ordinary ones too.
            candidates.extend(self.background(library, plan)?);
        }
        let candidates = dedup(candidates, held_out);
        held_out.check_disjoint(&candidates)?;
        let results = drive_all(policy, &candidates, threads);
        let outcome = |r: &risktwin_common::episode::EpisodeResult| Outcome {
            policy: label.to_string(),
            metrics: r.metrics.clone(),
            risk: r.risk,
        };
        // Already stored scenarios keep their row and lineage; only the outcome is added.
        let records: Vec<ScenarioRecord> = candidates
            .iter()
            .zip(&results)
            .map(|(s, r)| ScenarioRecord {
                spec: s.clone(),
                origin: Origin::Imported,
                parent_id: None,
                outcome: Some(outcome(r)),
            })
            .collect();
        library.insert_batch(&records)?;

        let failed = |r: &risktwin_common::episode::EpisodeResult| r.metrics.collision || r.metrics.offroad;
        let mut order: Vec<usize> = (0..candidates.len()).collect();
        // Failures first, then the policy's riskiest episodes; ties by content id.
        order.sort_by(|&a, &b| {
            failed(&results[b])
                .cmp(&failed(&results[a]))
                .then(results[b].risk.score.total_cmp(&results[a].risk.score))
                .then_with(|| content_id(&candidates[a]).cmp(&content_id(&candidates[b])))
        });
        let failures: Vec<usize> = order.iter().copied().filter(|&i| failed(&results[i])).collect();
        let frontier = match plan.replay_rule {
            ReplayRule::RiskRanked => None,
            ReplayRule::Frontier => Some(self.frontier(policy, &candidates, &results, plan, threads)?),
        };
        let parents: Vec<usize> = if let Some(f) = frontier.as_ref().filter(|f| !f.is_empty()) {
            f.clone()
        } else if failures.is_empty() {
            order.iter().copied().take(plan.mutations.div_ceil(4)).collect()
        } else {
            failures.clone()
        };

        let mut children: Vec<(String, ScenarioSpec)> = Vec::new();
        for k in 0..plan.mutations {
            let Some(&p) = parents.get(k % parents.len().max(1)) else { break };
            // An infeasible neighbourhood (mutate gives up) just yields no child.
            if let Ok(child) = mutate(&candidates[p], plan.mutation_radius, &mut self.rng)
                && !held_out.contains(&child)
            {
                children.push((content_id(&candidates[p]), child));
            }
        }
        let child_specs: Vec<ScenarioSpec> = children.iter().map(|(_, c)| c.clone()).collect();
        let child_results = drive_all(policy, &child_specs, threads);
        let reference = evaluate_all(child_specs.clone(), threads);
        let mut child_records: Vec<ScenarioRecord> = children
            .iter()
            .zip(&child_results)
            .map(|((pid, c), r)| ScenarioRecord::mutated(c.clone(), pid, outcome(r)))
            .collect();
        child_records.extend(
            children
                .iter()
                .zip(&reference)
                .map(|((pid, c), e)| ScenarioRecord::mutated(c.clone(), pid, reference_outcome(&e.result))),
        );
        library.insert_batch(&child_records)?;

        // Children the reference driver does not survive carry no learning signal (no known
        // way through); they stay in the library but are not trained on.
        let unsolved: BTreeSet<String> =
            child_specs.iter().zip(&reference).filter(|(_, e)| failed(&e.result)).map(|(c, _)| content_id(c)).collect();
        let mut next: Vec<ScenarioSpec> = Vec::new();
        if let Some(f) = frontier.as_ref().filter(|f| !f.is_empty()) {
            next.extend(f.iter().map(|&i| candidates[i].clone()));
        } else {
            for r in library.rank_for_policy(label, None, None)? {
                if next.len() == plan.replay_top {
                    break;
                }
                if !unsolved.contains(&r.id)
                    && let Some(s) = library.get(&r.id)?
                {
                    next.push(s.spec);
                }
            }
            next.extend(failures.iter().map(|&i| candidates[i].clone()));
        }
        let solvable_children: Vec<ScenarioSpec> =
            child_specs.iter().filter(|c| !unsolved.contains(&content_id(c))).cloned().collect();
        next.extend(solvable_children.iter().cloned());
        next.extend(self.background(library, plan)?);
        let next = dedup(next, held_out);
        held_out.check_disjoint(&next)?;
        if next.is_empty() {
            return Err(TrainerError::EmptyLibrary);
        }
        let report = Refresh {
            phase,
            policy: label.to_string(),
            evaluated: candidates.len(),
            failures: failures.len(),
            children: child_specs.len(),
            child_failures: child_results.iter().filter(|r| failed(r)).count(),
            training_set: next.len(),
            policy_mean_risk: results.iter().map(|r| r.risk.score).sum::<f64>() / results.len().max(1) as f64,
            frontier: frontier.map(|f| f.len()),
        };
        self.children = solvable_children;
        Ok((next, report))
    }

    /// The frontier among `candidates` after [`FRONTIER_DRIVES`] noisy drives of each
    /// ([`frontier_order`]).
    fn frontier(
        &mut self,
        policy: &PolicyNet,
        candidates: &[ScenarioSpec],
        results: &[risktwin_common::episode::EpisodeResult],
        plan: &TrainingPlan,
        threads: usize,
    ) -> Result<Vec<usize>, TrainerError> {
        let seed = self.rng.next_u64();
        let shares = success_shares(policy, candidates, FRONTIER_DRIVES, seed, threads)
            .ok_or_else(|| TrainerError::BadPlan("the frontier replay rule needs a policy with PPO's σ".into()))?;
        let risks: Vec<f64> = results.iter().map(|r| r.risk.score).collect();
        let ids: Vec<String> = candidates.iter().map(content_id).collect();
        Ok(frontier_order(&shares, &risks, &ids, plan.replay_top))
    }
}

/// The frontier by success shares `shares` (indices, at most `top`): shares strictly between 0
/// and 1, ordered by the learning potential p·(1 − p), then by `risks` (highest first), then by
/// `ids`.
pub fn frontier_order(shares: &[f64], risks: &[f64], ids: &[String], top: usize) -> Vec<usize> {
    let potential = |i: usize| shares[i] * (1.0 - shares[i]);
    let mut frontier: Vec<usize> = (0..shares.len()).filter(|&i| potential(i) > 0.0).collect();
    frontier.sort_by(|&a, &b| {
        potential(b).total_cmp(&potential(a)).then(risks[b].total_cmp(&risks[a])).then_with(|| ids[a].cmp(&ids[b]))
    });
    frontier.truncate(top);
    frontier
}
