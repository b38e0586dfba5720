//! Test fixtures: libraries in temporary files and outcomes with chosen risk.

use super::{DEFAULT_POLICY, Outcome, ScenarioLibrary, ScenarioRecord};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, sample};
use tempfile::TempDir;

/// A library in a fresh file `library.db` of a temporary directory (removed on drop).
pub fn file_library() -> (TempDir, ScenarioLibrary) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let lib = ScenarioLibrary::open(dir.path().join("library.db")).expect("a new file opens as a library");
    (dir, lib)
}

/// Candidate `index` of `kind` under run seed 7.
pub fn spec(kind: ScenarioKind, index: u64) -> ScenarioSpec {
    sample(7, kind, index)
}

/// A reference-driver outcome with the given risk score and distinct, exactly representable
/// values in every other field.
pub fn outcome(score: f64, collision: bool, min_ttc_s: Option<f64>) -> Outcome {
    Outcome {
        policy: DEFAULT_POLICY.to_string(),
        metrics: EpisodeMetrics {
            collision,
            offroad: false,
            success: !collision,
            route_completion: 0.75,
            avg_speed_mps: 13.5,
            steering_smoothness: 0.125,
            longitudinal_smoothness: 0.0625,
            min_ttc_s,
            min_distance_m: if collision { 0.0 } else { 4.25 },
            risk_score: score,
            reward: -12.5,
            steps: 400,
        },
        risk: RiskTerms {
            score,
            ttc: 0.5,
            dist: 0.25,
            lane: 0.125,
            jerk: 0.0625,
            collision: f64::from(u8::from(collision)),
        },
    }
}

/// A sampled record of `kind` candidate `index` with the given score.
pub fn sampled(kind: ScenarioKind, index: u64, score: f64, collision: bool) -> ScenarioRecord {
    ScenarioRecord::sampled(spec(kind, index), outcome(score, collision, Some(2.5)))
}
