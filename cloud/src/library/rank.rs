//! Ranking by risk and selection for replay and mutation.
//!
//! A scenario's rank uses its latest outcome under one policy (the reference driver by
//! default): highest `risk.score` first, ties by id, so the order never depends on insertion
//! order or on SQLite's plan.

use super::ScenarioLibrary;
use super::error::LibraryError;
use super::record::{DEFAULT_POLICY, fnv1a64};
use super::store::decode_spec;
use risktwin_common::risk::RiskTerms;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::ScenarioKind;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One element of `scenarios rank --format json` (cli.md), field for field.
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

type RankRow = (
    String,
    String,
    i64,
    String,
    [f64; 6],
    bool,
    Option<f64>,
    f64,
);

impl ScenarioLibrary {
    /// The `top` riskiest scenarios (all when `None`), of one kind or all, by the latest
    /// outcome of the reference driver.
    pub fn rank(
        &self,
        top: Option<usize>,
        kind: Option<ScenarioKind>,
    ) -> Result<Vec<RankedScenario>, LibraryError> {
        self.rank_for_policy(DEFAULT_POLICY, top, kind)
    }

    /// As `rank`, by the latest outcome of `policy`; scenarios it never drove are left out.
    pub fn rank_for_policy(
        &self,
        policy: &str,
        top: Option<usize>,
        kind: Option<ScenarioKind>,
    ) -> Result<Vec<RankedScenario>, LibraryError> {
        // SQLite reads a negative LIMIT as "no limit".
        let limit = top.map_or(-1, |k| i64::try_from(k).unwrap_or(i64::MAX));
        let mut stmt = self.conn.prepare_cached(
            "SELECT s.id, s.kind, s.seed, s.params, \
                    o.risk_score, o.risk_ttc, o.risk_dist, o.risk_lane, o.risk_jerk, o.risk_collision, \
                    o.collision, o.min_ttc_s, o.min_distance_m \
             FROM outcomes o JOIN scenarios s ON s.id = o.scenario_id \
             WHERE o.policy = ?1 \
               AND o.seq = (SELECT MAX(seq) FROM outcomes WHERE scenario_id = s.id AND policy = ?1) \
               AND (?2 IS NULL OR s.kind = ?2) \
             ORDER BY o.risk_score DESC, s.id ASC \
             LIMIT ?3",
        )?;
        let rows: Vec<RankRow> = stmt
            .query_map(
                rusqlite::params![policy, kind.map(ScenarioKind::name), limit],
                |r| {
                    Ok((
                        r.get(0)?,
                        r.get(1)?,
                        r.get(2)?,
                        r.get(3)?,
                        [
                            r.get(4)?,
                            r.get(5)?,
                            r.get(6)?,
                            r.get(7)?,
                            r.get(8)?,
                            r.get(9)?,
                        ],
                        r.get(10)?,
                        r.get(11)?,
                        r.get(12)?,
                    ))
                },
            )?
            .collect::<Result<_, _>>()?;
        rows.into_iter()
            .map(
                |(
                    id,
                    kind,
                    seed,
                    params,
                    [score, ttc, dist, lane, jerk, collision_term],
                    collision,
                    min_ttc_s,
                    min_distance_m,
                )| {
                    let spec = decode_spec(&id, &kind, seed, &params)?;
                    Ok(RankedScenario {
                        id,
                        kind: spec.kind,
                        seed: spec.seed,
                        params: spec.params,
                        risk: RiskTerms {
                            score,
                            ttc,
                            dist,
                            lane,
                            jerk,
                            collision: collision_term,
                        },
                        outcome: RankOutcome {
                            collision,
                            min_ttc_s,
                            min_distance_m,
                        },
                    })
                },
            )
            .collect()
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
    pub fn select_for_mutation(
        &self,
        k: usize,
        rng: &mut Rng,
    ) -> Result<Vec<RankedScenario>, LibraryError> {
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
