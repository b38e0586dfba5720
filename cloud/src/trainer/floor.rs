//! The achievable floor of a scenario set: the privileged planner (`common::planner`) on each
//! scenario, its drives averaged like any policy's, next to the reference driver's endings
//! (its episodes are passed in, computed once by [`reference_episodes`](super::ablation::reference_episodes)).
//!
//! The planner's success rate is the share of scenarios found avoidable — a lower bound of the
//! success any policy can reach — and its collision rate an upper bound of the collision floor
//! (a scenario the search found no clean drive for may still have one).

use crate::generate::parallel_map;
use risktwin_common::metrics::{Ending, EpisodeMetrics};
use risktwin_common::planner::{self, Verdict};
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};
use risktwin_store::library::content_id;
use serde::Serialize;

use super::ablation::PolicyEvaluation;

/// One scenario's floor.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FloorCase {
    /// Content id, as in the library.
    pub id: String,
    pub kind: ScenarioKind,
    pub seed: u64,
    pub verdict: Verdict,
    /// How the planner's drive ended (its best attempt when not found).
    pub ended: Ending,
    pub route_completion: f64,
    pub min_ttc_s: Option<f64>,
    pub min_distance_m: f64,
    pub avg_speed_mps: f64,
    /// Steps the search simulated.
    pub sim_steps: u64,
    /// How the reference driver's episode ended.
    pub reference_ended: Ending,
}

/// The planner on a set of scenarios (the reference driver's averages are the ablation's
/// `reference`, or `PolicyEvaluation::from_episodes` of the same episodes).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FloorEvaluation {
    /// The planner's drives averaged over all scenarios and per kind.
    pub planner: PolicyEvaluation,
    pub cases: Vec<FloorCase>,
}

/// Runs the planner on every spec, `threads` at a time, next to `reference` (the reference
/// driver's episodes of the same specs, in order); deterministic whatever the thread count.
pub fn evaluate_floor(specs: &[ScenarioSpec], reference: &[EpisodeMetrics], threads: usize) -> FloorEvaluation {
    assert_eq!(specs.len(), reference.len(), "one reference episode per spec");
    let indexed: Vec<(&ScenarioSpec, &EpisodeMetrics)> = specs.iter().zip(reference).collect();
    let runs: Vec<(EpisodeMetrics, FloorCase)> = parallel_map(&indexed, threads, |&(spec, reference)| {
        let out = planner::plan(spec);
        let m = &out.metrics;
        let case = FloorCase {
            id: content_id(spec),
            kind: spec.kind,
            seed: spec.seed,
            verdict: out.verdict,
            ended: m.ending(),
            route_completion: m.route_completion,
            min_ttc_s: m.min_ttc_s,
            min_distance_m: m.min_distance_m,
            avg_speed_mps: m.avg_speed_mps,
            sim_steps: out.sim_steps,
            reference_ended: reference.ending(),
        };
        (out.metrics, case)
    });
    let (planned, cases): (Vec<EpisodeMetrics>, Vec<FloorCase>) = runs.into_iter().unzip();
    FloorEvaluation { planner: PolicyEvaluation::from_episodes(specs, &planned), cases }
}

impl FloorEvaluation {
    /// Scenarios found avoidable, of `kind` or of all kinds.
    pub fn avoidable(&self, kind: Option<ScenarioKind>) -> u64 {
        let of_kind = |c: &&FloorCase| kind.is_none_or(|k| c.kind == k);
        self.cases.iter().filter(of_kind).filter(|c| c.verdict == Verdict::Avoidable).count() as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trainer::{HeldOut, reference_episodes};
    use risktwin_common::planner::PlannerParams;
    use risktwin_common::scenario::build;

    #[test]
    fn cut_ins_the_reference_driver_crashes_in_are_driven_with_clearance_whatever_the_threads() {
        let specs: Vec<ScenarioSpec> =
            HeldOut::new(1, 2).specs.into_iter().filter(|s| s.kind == ScenarioKind::CutIn).collect();
        let reference = reference_episodes(&specs, 1);
        let floor = evaluate_floor(&specs, &reference, 1);
        assert_eq!(floor.cases.len(), 2);
        // Held-out cut-ins of run seed 1: the reference driver collides in the first; with full
        // knowledge of the cutter's path the planner completes both.
        assert_eq!(floor.cases[0].reference_ended, Ending::Collision);
        assert_eq!(floor.avoidable(Some(ScenarioKind::CutIn)), 2);
        assert_eq!(floor.planner.by_kind[&ScenarioKind::CutIn].success_rate, 1.0);
        assert_ne!(floor.cases[1].reference_ended, Ending::Collision);
        assert_eq!(evaluate_floor(&specs, &reference, 2), floor);
        // Both drives keep the planner's clearance; without it the search passes the second
        // cutter within centimetres — clean for the twin, but no margin a policy could repeat.
        let clearance_m = PlannerParams::default().clearance_m;
        assert!(floor.cases.iter().all(|c| c.min_distance_m >= clearance_m), "{:?}", floor.cases);
        let tight = planner::plan_world(&build(&specs[1]), &PlannerParams { clearance_m: 0.0, ..Default::default() });
        assert_eq!(tight.verdict, Verdict::Avoidable);
        assert!(tight.metrics.min_distance_m < clearance_m, "{:?}", tight.metrics);
    }
}
