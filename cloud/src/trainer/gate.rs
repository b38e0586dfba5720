//! The regression gate: before a policy version is pushed to the fleet, it drives the
//! regression set (every library scenario some driver collided in) and the held-out set, and is
//! compared with the version deployed now (the reference driver before the first push) driving
//! the same scenarios. A candidate with more collisions than the deployed version on either set,
//! or a mean route completion lower by more than [`COMPLETION_TOLERANCE`], is held back, and the
//! report says which set and which figure. The rule is on the totals; the scenarios the
//! candidate newly collides in are listed beside them (a candidate may trade one collision for
//! another).

pub use super::drive::Driver;
use super::held_out::HeldOut;
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_store::library::{LibraryError, ScenarioLibrary, content_id};
use serde::Serialize;

/// How much lower the candidate's mean route completion may be than the deployed version's on a
/// set (a share of the route): 2 %, about one scenario in 50 stopping short.
pub const COMPLETION_TOLERANCE: f64 = 0.02;

/// One driver on one set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetSummary {
    pub collisions: usize,
    pub successes: usize,
    pub mean_route_completion: f64,
}

impl SetSummary {
    fn of(episodes: &[EpisodeMetrics]) -> Self {
        let n = episodes.len().max(1) as f64;
        SetSummary {
            collisions: episodes.iter().filter(|m| m.collision).count(),
            successes: episodes.iter().filter(|m| m.success).count(),
            mean_route_completion: episodes.iter().map(|m| m.route_completion).sum::<f64>() / n,
        }
    }
}

/// The candidate against the deployed version on one set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetComparison {
    pub scenarios: usize,
    pub candidate: SetSummary,
    pub deployed: SetSummary,
    /// Scenarios the candidate collides in and the deployed version does not (content ids).
    pub newly_colliding: Vec<String>,
}

impl SetComparison {
    fn of(specs: &[ScenarioSpec], candidate: Driver<'_>, deployed: Driver<'_>, threads: usize) -> Self {
        let metrics = |d: Driver<'_>| d.episodes(specs, threads).into_iter().map(|r| r.metrics).collect::<Vec<_>>();
        let (ours, theirs) = (metrics(candidate), metrics(deployed));
        let newly = specs.iter().zip(ours.iter().zip(&theirs)).filter(|(_, (c, d))| c.collision && !d.collision);
        SetComparison {
            scenarios: specs.len(),
            candidate: SetSummary::of(&ours),
            deployed: SetSummary::of(&theirs),
            newly_colliding: newly.map(|(s, _)| content_id(s)).collect(),
        }
    }

    /// Why this set holds the candidate back, if it does.
    fn regressions(&self, set: &str) -> Vec<String> {
        let (c, d) = (&self.candidate, &self.deployed);
        let mut why = Vec::new();
        if c.collisions > d.collisions {
            why.push(format!("{set}: {} collisions against {} of the deployed version", c.collisions, d.collisions));
        }
        if c.mean_route_completion < d.mean_route_completion - COMPLETION_TOLERANCE {
            why.push(format!(
                "{set}: mean route completion {:.3} against {:.3} of the deployed version (tolerance {COMPLETION_TOLERANCE})",
                c.mean_route_completion, d.mean_route_completion
            ));
        }
        why
    }
}

/// Push or hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Decision {
    Push,
    Hold,
}

/// The gate's verdict on one candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GateReport {
    pub decision: Decision,
    /// Why the candidate is held back (empty when it is pushed).
    pub reasons: Vec<String>,
    pub regression: SetComparison,
    pub held_out: SetComparison,
    pub completion_tolerance: f64,
}

/// Runs the gate: `candidate` against `deployed` on the library's regression set and on
/// `held_out`, on `threads` workers.
pub fn gate(
    library: &ScenarioLibrary,
    candidate: Driver<'_>,
    deployed: Driver<'_>,
    held_out: &HeldOut,
    threads: usize,
) -> Result<GateReport, LibraryError> {
    let regression: Vec<ScenarioSpec> = library.regression_set()?.into_iter().map(|case| case.spec).collect();
    let regression = SetComparison::of(&regression, candidate, deployed, threads);
    let held_out = SetComparison::of(&held_out.specs, candidate, deployed, threads);
    let reasons: Vec<String> =
        regression.regressions("regression set").into_iter().chain(held_out.regressions("held-out set")).collect();
    let decision = if reasons.is_empty() { Decision::Push } else { Decision::Hold };
    Ok(GateReport { decision, reasons, regression, held_out, completion_tolerance: COMPLETION_TOLERANCE })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comparison(candidate: (usize, f64), deployed: (usize, f64)) -> SetComparison {
        let summary =
            |(collisions, mean_route_completion)| SetSummary { collisions, successes: 0, mean_route_completion };
        SetComparison {
            scenarios: 10,
            candidate: summary(candidate),
            deployed: summary(deployed),
            newly_colliding: Vec::new(),
        }
    }

    #[test]
    fn more_collisions_or_completion_short_by_more_than_the_tolerance_hold_a_candidate_back() {
        assert!(comparison((2, 0.90), (2, 0.90)).regressions("set").is_empty(), "equal passes");
        assert!(comparison((1, 0.95), (2, 0.90)).regressions("set").is_empty(), "better passes");
        assert!(comparison((2, 0.89), (2, 0.90)).regressions("set").is_empty(), "within the tolerance");
        let more = comparison((3, 0.90), (2, 0.90)).regressions("regression set");
        assert_eq!(more, ["regression set: 3 collisions against 2 of the deployed version"]);
        let short = comparison((2, 0.85), (2, 0.90)).regressions("held-out set");
        assert_eq!(short.len(), 1);
        assert!(short[0].starts_with("held-out set: mean route completion 0.850 against 0.900"), "{short:?}");
        assert_eq!(comparison((3, 0.5), (2, 0.9)).regressions("set").len(), 2, "both reasons are given");
    }
}
