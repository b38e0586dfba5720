//! What goes into the library and what comes out: records, outcomes, lineage, content ids, and
//! the value checks done before anything is written.

use super::error::RecordError;
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
pub use risktwin_common::scenario::content_id;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};

/// The policy whose outcomes rank the library: the reference driver of docs/cli.md.
pub const DEFAULT_POLICY: &str = risktwin_common::driver::REFERENCE_LABEL;

/// How a scenario entered the library.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Origin {
    /// Drawn by the seeded sampler.
    Sampled,
    /// A child of a stored scenario (neighbourhood search around a failure).
    Mutated,
    /// From outside (a spec file, a recording).
    Imported,
    /// Re-entered from another library's regression set.
    Regression,
}

impl Origin {
    /// The spelling stored in the `origin` column.
    pub fn as_str(self) -> &'static str {
        match self {
            Origin::Sampled => "sampled",
            Origin::Mutated => "mutated",
            Origin::Imported => "imported",
            Origin::Regression => "regression",
        }
    }

    /// The origin stored as `s`, if any.
    pub fn parse(s: &str) -> Option<Self> {
        [Origin::Sampled, Origin::Mutated, Origin::Imported, Origin::Regression].into_iter().find(|o| o.as_str() == s)
    }
}

/// One evaluation of a scenario by one policy.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Who drove the ego: "idm" for the reference driver, or a policy file's name.
    pub policy: String,
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
}

/// A scenario offered to the library, with its lineage and (usually) its first outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioRecord {
    pub spec: ScenarioSpec,
    pub origin: Origin,
    /// The scenario this one was mutated from; required for `Mutated`, absent otherwise.
    pub parent_id: Option<String>,
    pub outcome: Option<Outcome>,
}

impl ScenarioRecord {
    /// A sampled scenario with its outcome.
    pub fn sampled(spec: ScenarioSpec, outcome: Outcome) -> Self {
        Self { spec, origin: Origin::Sampled, parent_id: None, outcome: Some(outcome) }
    }

    /// A child of `parent_id` with its outcome.
    pub fn mutated(spec: ScenarioSpec, parent_id: &str, outcome: Outcome) -> Self {
        Self { spec, origin: Origin::Mutated, parent_id: Some(parent_id.to_string()), outcome: Some(outcome) }
    }
}

/// A scenario as stored, with every outcome recorded for it (oldest first).
#[derive(Debug, Clone, PartialEq)]
pub struct StoredScenario {
    pub id: String,
    pub spec: ScenarioSpec,
    pub origin: Origin,
    pub parent_id: Option<String>,
    /// Mutation steps from the root: 0 for sampled or imported scenarios.
    pub generation: u32,
    /// Insertion order over the whole library, starting at 1.
    pub created_seq: u64,
    pub outcomes: Vec<Outcome>,
}

impl StoredScenario {
    /// The most recent outcome of `policy`, if it was ever evaluated.
    pub fn latest_outcome(&self, policy: &str) -> Option<&Outcome> {
        self.outcomes.iter().rev().find(|o| o.policy == policy)
    }
}

/// Rejected candidates of one kind for one infeasibility reason (`Infeasible::code`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rejection {
    pub kind: ScenarioKind,
    pub reason: String,
    pub count: u64,
}

/// Per-kind totals for reports (`scenarios generate`'s `by_kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KindCounts {
    /// Scenario rows of this kind.
    pub stored: u64,
    /// Candidates rejected as infeasible, all reasons.
    pub infeasible: u64,
    /// Scenarios whose latest default-policy outcome is a collision.
    pub collisions: u64,
}

/// What one batch insert did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct InsertSummary {
    /// New scenario rows.
    pub inserted: usize,
    /// Records whose content was already stored (their outcomes are still added).
    pub duplicates: usize,
    /// Outcome rows written.
    pub outcomes: usize,
}

fn finite(field: &'static str, value: f64) -> Result<(), RecordError> {
    if value.is_finite() { Ok(()) } else { Err(RecordError::NotFinite { field, value }) }
}

fn within(field: &'static str, value: f64, min: f64, max: f64) -> Result<(), RecordError> {
    finite(field, value)?;
    if (min..=max).contains(&value) { Ok(()) } else { Err(RecordError::OutOfRange { field, value, min, max }) }
}

/// `min_ttc_s` as stored: an infinite or undefined TTC means "never closing in", which the
/// contract writes as null, so both become NULL; a negative TTC is an error, not a value.
pub fn ttc_for_storage(min_ttc_s: Option<f64>) -> Result<Option<f64>, RecordError> {
    match min_ttc_s {
        Some(t) if t.is_finite() => within("min_ttc_s", t, 0.0, f64::INFINITY).map(|()| Some(t)),
        Some(t) if t == f64::INFINITY || t.is_nan() => Ok(None),
        Some(t) => Err(RecordError::OutOfRange { field: "min_ttc_s", value: t, min: 0.0, max: f64::INFINITY }),
        None => Ok(None),
    }
}

/// Checks every value of an outcome before it is written.
pub fn validate_outcome(o: &Outcome) -> Result<(), RecordError> {
    if o.policy.is_empty() {
        return Err(RecordError::EmptyPolicy);
    }
    let r = &o.risk;
    for (field, value) in [
        ("risk.score", r.score),
        ("risk.ttc", r.ttc),
        ("risk.dist", r.dist),
        ("risk.lane", r.lane),
        ("risk.jerk", r.jerk),
        ("risk.collision", r.collision),
    ] {
        within(field, value, 0.0, 1.0)?;
    }
    let m = &o.metrics;
    within("route_completion", m.route_completion, 0.0, 1.0)?;
    within("avg_speed_mps", m.avg_speed_mps, 0.0, f64::INFINITY)?;
    within("min_distance_m", m.min_distance_m, 0.0, f64::INFINITY)?;
    finite("steering_smoothness", m.steering_smoothness)?;
    finite("longitudinal_smoothness", m.longitudinal_smoothness)?;
    finite("risk_score", m.risk_score)?;
    finite("reward", m.reward)?;
    ttc_for_storage(m.min_ttc_s)?;
    i64::try_from(m.steps).map_err(|_| RecordError::StepsTooLarge(m.steps))?;
    Ok(())
}

/// Checks the spec and the lineage fields of a record (the parent's existence is checked by the
/// store, inside the insert transaction).
pub fn validate_record(rec: &ScenarioRecord) -> Result<(), RecordError> {
    ScenarioSpec::new(rec.spec.kind, rec.spec.seed, rec.spec.params.clone())?;
    match (rec.origin, &rec.parent_id) {
        (Origin::Mutated, None) => {
            return Err(RecordError::Lineage { origin: "mutated", expectation: "needs a parent id" });
        }
        (Origin::Mutated, Some(_)) | (_, None) => {}
        (origin, Some(_)) => {
            return Err(RecordError::Lineage { origin: origin.as_str(), expectation: "has no parent" });
        }
    }
    if let Some(o) = &rec.outcome {
        validate_outcome(o)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn content_id_depends_on_content_only() {
        let a = risktwin_common::scenario::sample(1, ScenarioKind::CutIn, 0);
        let id = content_id(&a);
        assert_eq!(id.len(), 16);
        assert_eq!(id, content_id(&a.clone()));
        let mut b = a.clone();
        b.seed ^= 1;
        assert_ne!(id, content_id(&b));
        let mut c = a.clone();
        *c.params.get_mut("lateral_gap_m").expect("cut-in param") += 1e-12;
        assert_ne!(id, content_id(&c));
    }

    #[test]
    fn ttc_storage_maps_undefined_to_null_and_refuses_negative() {
        assert_eq!(ttc_for_storage(Some(1.25)), Ok(Some(1.25)));
        assert_eq!(ttc_for_storage(Some(f64::INFINITY)), Ok(None));
        assert_eq!(ttc_for_storage(Some(f64::NAN)), Ok(None));
        assert_eq!(ttc_for_storage(None), Ok(None));
        assert!(ttc_for_storage(Some(-0.5)).is_err());
        assert!(ttc_for_storage(Some(f64::NEG_INFINITY)).is_err());
    }
}
