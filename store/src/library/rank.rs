//! Ranking by risk and selection for replay and mutation.
//!
//! A scenario's rank uses its latest outcome under one policy (the reference driver by
//! default): highest `risk.score` first, ties by id, so the order never depends on insertion
//! order or on SQLite's plan.

use super::connection::ScenarioLibrary;
use super::error::LibraryError;
use super::query::decode_spec;
use super::record::{DEFAULT_POLICY, Outcome};
use super::stored::{OUTCOME_COLUMNS, OutcomeRow, file_of};
use risktwin_common::digest::fnv1a64;
use risktwin_common::risk::RiskTerms;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::ScenarioKind;
use rusqlite::Connection;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One element of `scenarios rank --format json` (docs/cli.md), field for field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RankedScenario {
    pub id: String,
    pub kind: ScenarioKind,
    pub seed: u64,
    pub params: BTreeMap<String, f64>,
    pub risk: RiskTerms,
    pub outcome: RankOutcome,
}

/// The outcome part of a ranked scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RankOutcome {
    pub collision: bool,
    /// `null` when no vehicle pair ever closed in.
    pub min_ttc_s: Option<f64>,
    pub min_distance_m: f64,
}

impl RankOutcome {
    /// The ranking's part of a (checked) outcome.
    pub(super) fn of(o: &Outcome) -> Self {
        Self {
            collision: o.metrics.collision,
            min_ttc_s: o.metrics.min_ttc_s,
            min_distance_m: o.metrics.min_distance_m,
        }
    }
}

impl ScenarioLibrary {
    /// The `top` riskiest scenarios (all when `None`), of one kind or all, by the latest
    /// outcome of the reference driver.
    pub fn rank(&self, top: Option<usize>, kind: Option<ScenarioKind>) -> Result<Vec<RankedScenario>, LibraryError> {
        self.rank_for_policy(DEFAULT_POLICY, top, kind)
    }

    /// As `rank`, by the latest outcome of `policy`; scenarios it never drove are left out.
    pub fn rank_for_policy(
        &self,
        policy: &str,
        top: Option<usize>,
        kind: Option<ScenarioKind>,
    ) -> Result<Vec<RankedScenario>, LibraryError> {
        self.rank_where(policy, top, kind, false)
    }

    /// The riskiest scenario (by the reference driver's latest outcome) never pushed to an
    /// edge: what the loop sends next.
    pub fn riskiest_unpushed(&self) -> Result<Option<RankedScenario>, LibraryError> {
        Self::riskiest_unpushed_in(&self.conn)
    }

    /// [`Self::riskiest_unpushed`] on `conn` (a transaction of the library's connection).
    pub(super) fn riskiest_unpushed_in(conn: &Connection) -> Result<Option<RankedScenario>, LibraryError> {
        Ok(rank_on(conn, &file_of(conn), DEFAULT_POLICY, Some(1), None, true)?.pop())
    }

    fn rank_where(
        &self,
        policy: &str,
        top: Option<usize>,
        kind: Option<ScenarioKind>,
        unpushed: bool,
    ) -> Result<Vec<RankedScenario>, LibraryError> {
        rank_on(&self.conn, &self.path, policy, top, kind, unpushed)
    }

    /// The `k` riskiest scenarios, to replay through the pipeline.
    pub fn select_for_replay(&self, k: usize) -> Result<Vec<RankedScenario>, LibraryError> {
        self.rank(Some(k), None)
    }

    /// `k` parents for mutation: failures (collisions) first, then the highest risk.
    ///
    /// Equal candidates are ordered by a hash of their id salted from `rng`, so repeated rounds
    /// with a fresh rng spread over a plateau of equal scores instead of always mutating the
    /// lexicographically smallest ids; the same rng state gives the same choice.
    pub fn select_for_mutation(&self, k: usize, rng: &mut Rng) -> Result<Vec<RankedScenario>, LibraryError> {
        let salt = rng.next_u64();
        let mut all = self.rank(None, None)?;
        let tie_key = |id: &str| Rng::derive(salt, fnv1a64(id.bytes())).next_u64();
        all.sort_by(|a, b| {
            b.outcome
                .collision
                .cmp(&a.outcome.collision)
                .then(b.risk.score.total_cmp(&a.risk.score))
                .then_with(|| tie_key(&a.id).cmp(&tie_key(&b.id)))
                .then_with(|| a.id.cmp(&b.id))
        });
        all.truncate(k);
        Ok(all)
    }
}

/// The ranking on `conn` (a library in `file`): by `policy`'s latest outcome, highest risk first, ties by id; of one
/// kind or all; only scenarios never pushed when `unpushed`.
fn rank_on(
    conn: &Connection,
    file: &Path,
    policy: &str,
    top: Option<usize>,
    kind: Option<ScenarioKind>,
    unpushed: bool,
) -> Result<Vec<RankedScenario>, LibraryError> {
    // SQLite reads a negative LIMIT as "no limit".
    let limit = top.map_or(-1, |k| i64::try_from(k).unwrap_or(i64::MAX));
    let outcome_columns = OUTCOME_COLUMNS.split(", ").map(|c| format!("o.{c}")).collect::<Vec<_>>().join(", ");
    let mut stmt = conn.prepare_cached(&format!(
        "SELECT s.id, s.kind, s.seed, s.params, o.seq, {outcome_columns} \
             FROM outcomes o JOIN scenarios s ON s.id = o.scenario_id \
             WHERE o.policy = ?1 \
               AND o.seq = (SELECT MAX(seq) FROM outcomes WHERE scenario_id = s.id AND policy = ?1) \
               AND (?2 IS NULL OR s.kind = ?2) \
               AND (?4 = 0 OR NOT EXISTS (SELECT 1 FROM pushes p WHERE p.scenario_id = s.id)) \
             ORDER BY o.risk_score DESC, s.id ASC \
             LIMIT ?3"
    ))?;
    type Row = (String, String, i64, String, OutcomeRow);
    let rows: Vec<Row> = stmt
        .query_map(rusqlite::params![policy, kind.map(ScenarioKind::name), limit, unpushed], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, OutcomeRow::read_at(r, 4)?))
        })?
        .collect::<Result<_, _>>()?;
    rows.into_iter()
        .map(|(id, kind, seed, params, outcome)| {
            let outcome = outcome.checked(file, "outcomes")?;
            let spec = decode_spec(&id, &kind, seed, &params)?;
            let (risk, outcome) = (outcome.risk, RankOutcome::of(&outcome));
            Ok(RankedScenario { id, kind: spec.kind, seed: spec.seed, params: spec.params, risk, outcome })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, outcome, sampled, spec};
    use super::super::{ScenarioRecord, content_id};
    use super::*;

    fn ids(ranked: &[RankedScenario]) -> Vec<String> {
        ranked.iter().map(|r| r.id.clone()).collect()
    }

    #[test]
    fn rank_is_by_score_then_id_with_top_k_and_kind_filter() {
        let (_dir, mut lib) = file_library();
        let k = ScenarioKind::CutIn;
        lib.insert_batch(&[
            sampled(k, 0, 0.3, false),
            sampled(k, 1, 0.9, false),
            sampled(k, 2, 0.9, false),
            sampled(k, 3, 0.1, false),
            sampled(ScenarioKind::LowFriction, 0, 0.95, false),
        ])
        .expect("insert");
        let id = |kind, i| content_id(&spec(kind, i));
        let (tie_lo, tie_hi) = {
            let (a, b) = (id(k, 1), id(k, 2));
            if a < b { (a, b) } else { (b, a) }
        };
        let cut_in = lib.rank(None, Some(k)).expect("rank");
        assert_eq!(ids(&cut_in), vec![tie_lo.clone(), tie_hi, id(k, 0), id(k, 3)]);
        let all = lib.rank(None, None).expect("rank");
        assert_eq!(all.len(), 5);
        assert_eq!(all[0].id, id(ScenarioKind::LowFriction, 0));
        let scores: Vec<f64> = all.iter().map(|r| r.risk.score).collect();
        assert!(scores.windows(2).all(|w| w[0] >= w[1]), "{scores:?}");
        assert_eq!(ids(&lib.rank(Some(2), None).expect("rank")), ids(&all[..2]));
        assert_eq!(lib.rank(Some(0), None).expect("rank"), vec![]);
        assert_eq!(lib.select_for_replay(3).expect("replay"), all[..3].to_vec());
        assert_eq!(lib.rank(None, Some(ScenarioKind::SensorOcclusion)).expect("rank"), vec![]);
        assert_eq!(ids(&lib.rank(Some(1), Some(k)).expect("rank")), vec![tie_lo]);
    }

    #[test]
    fn the_latest_default_policy_outcome_counts() {
        let (_dir, mut lib) = file_library();
        let k = ScenarioKind::EmergencyBraking;
        lib.insert_batch(&[sampled(k, 0, 0.8, false), sampled(k, 1, 0.5, false)]).expect("insert");
        // A re-run of candidate 0 found it calmer; a learned policy's crash does not move the
        // reference ranking.
        let mut learned = outcome(1.0, true, Some(0.0));
        learned.policy = "ppo-full".into();
        lib.insert_batch(&[
            ScenarioRecord::sampled(spec(k, 0), outcome(0.2, false, None)),
            ScenarioRecord::sampled(spec(k, 1), learned),
        ])
        .expect("insert");
        let ranked = lib.rank(None, None).expect("rank");
        assert_eq!(ids(&ranked), vec![content_id(&spec(k, 1)), content_id(&spec(k, 0))]);
        assert_eq!(ranked[1].risk.score, 0.2);
        assert_eq!(ranked[1].outcome.min_ttc_s, None);
        let by_learned = lib.rank_for_policy("ppo-full", None, None).expect("rank");
        assert_eq!(ids(&by_learned), vec![content_id(&spec(k, 1))]);
    }

    #[test]
    fn ranked_json_is_the_cli_contract_object() {
        let (_dir, mut lib) = file_library();
        let s = spec(ScenarioKind::LowFriction, 0);
        lib.insert_batch(&[ScenarioRecord::sampled(s.clone(), outcome(0.75, false, None))]).expect("insert");
        let ranked = lib.rank(None, None).expect("rank");
        let params = serde_json::to_string(&s.params).expect("params json");
        let expected = format!(
            concat!(
                r#"{{"id":"{}","kind":"low-friction","seed":{},"params":{},"#,
                r#""risk":{{"score":0.75,"ttc":0.5,"dist":0.25,"lane":0.125,"jerk":0.0625,"collision":0.0}},"#,
                r#""outcome":{{"collision":false,"min_ttc_s":null,"min_distance_m":4.25}}}}"#
            ),
            content_id(&s),
            s.seed,
            params
        );
        assert_eq!(serde_json::to_string(&ranked[0]).expect("json"), expected);
        let back: RankedScenario = serde_json::from_str(&expected).expect("parse");
        assert_eq!(back, ranked[0]);
    }

    #[test]
    fn mutation_parents_are_failures_first_and_seeded() {
        let (_dir, mut lib) = file_library();
        let k = ScenarioKind::PedestrianCrossing;
        let mut records: Vec<ScenarioRecord> = (0..6).map(|i| sampled(k, i, 0.6, false)).collect();
        records.push(sampled(k, 6, 0.4, true)); // a collision with a lower score
        records.push(sampled(k, 7, 0.95, false));
        lib.insert_batch(&records).expect("insert");
        let pick = |seed| ids(&lib.select_for_mutation(4, &mut Rng::new(seed)).expect("select"));
        let a = pick(1);
        assert_eq!(a.len(), 4);
        assert_eq!(a[0], content_id(&spec(k, 6)), "the collision comes first");
        assert_eq!(a[1], content_id(&spec(k, 7)), "then the highest risk");
        let plateau: Vec<String> = (0..6).map(|i| content_id(&spec(k, i))).collect();
        assert!(a[2..].iter().all(|id| plateau.contains(id)));
        assert_eq!(a, pick(1), "same rng seed, same parents");
        // The plateau of equal scores is broken by the salted hash, not always the same way.
        let distinct: std::collections::BTreeSet<Vec<String>> = (0..16).map(pick).collect();
        assert!(distinct.len() > 1);
    }
}
