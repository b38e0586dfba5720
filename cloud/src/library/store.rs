//! Writing and reading scenarios: batch inserts in one transaction, rejection counts, lookup by
//! id, lineage, per-kind counts and the regression set.

use super::ScenarioLibrary;
use super::error::{LibraryError, RecordError};
use super::record::{
    DEFAULT_POLICY, InsertSummary, KindCounts, Origin, Outcome, Rejection, ScenarioRecord,
    StoredScenario, content_id, ttc_for_storage, validate_record,
};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};
use rusqlite::{OptionalExtension, Row, TransactionBehavior, params};
use std::collections::BTreeMap;

/// Why a scenario is kept as a regression case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RegressionReason {
    /// Marked automatically: some policy collided in it.
    Collision,
    /// Marked by `mark_regression`.
    Manual,
}

/// A scenario kept for regression runs.
#[derive(Debug, Clone, PartialEq)]
pub struct RegressionCase {
    pub id: String,
    pub spec: ScenarioSpec,
    pub reason: RegressionReason,
}

/// The outcome columns, in the order `outcome_from_row` reads them.
pub(super) const OUTCOME_COLUMNS: &str = "policy, collision, offroad, success, route_completion, avg_speed_mps, \
     steering_smoothness, longitudinal_smoothness, min_ttc_s, min_distance_m, episode_risk_score, reward, steps, \
     risk_score, risk_ttc, risk_dist, risk_lane, risk_jerk, risk_collision";

fn outcome_from_row(r: &Row<'_>) -> rusqlite::Result<Outcome> {
    let steps: i64 = r.get(12)?;
    Ok(Outcome {
        policy: r.get(0)?,
        metrics: EpisodeMetrics {
            collision: r.get(1)?,
            offroad: r.get(2)?,
            success: r.get(3)?,
            route_completion: r.get(4)?,
            avg_speed_mps: r.get(5)?,
            steering_smoothness: r.get(6)?,
            longitudinal_smoothness: r.get(7)?,
            min_ttc_s: r.get(8)?,
            min_distance_m: r.get(9)?,
            risk_score: r.get(10)?,
            reward: r.get(11)?,
            // The column CHECK keeps steps non-negative.
            steps: steps.max(0) as u64,
        },
        risk: RiskTerms {
            score: r.get(13)?,
            ttc: r.get(14)?,
            dist: r.get(15)?,
            lane: r.get(16)?,
            jerk: r.get(17)?,
            collision: r.get(18)?,
        },
    })
}

/// Rebuilds and re-validates a spec from its columns; a row that fails is reported as corrupt.
/// Seeds are u64 stored bit for bit in SQLite's signed 64-bit integers.
pub(super) fn decode_spec(
    id: &str,
    kind: &str,
    seed: i64,
    params: &str,
) -> Result<ScenarioSpec, LibraryError> {
    let corrupt = |reason: String| LibraryError::Corrupt {
        id: id.to_string(),
        reason,
    };
    let kind: ScenarioKind = kind.parse().map_err(|e| corrupt(format!("{e}")))?;
    let params: BTreeMap<String, f64> = serde_json::from_str(params)
        .map_err(|e| corrupt(format!("params are not a JSON object of numbers: {e}")))?;
    ScenarioSpec::new(kind, seed as u64, params).map_err(|e| corrupt(e.to_string()))
}

impl ScenarioLibrary {
    /// Stores a batch of scenarios and their outcomes in one transaction: all or nothing.
    ///
    /// Every record is validated before anything is written. A scenario whose content is
    /// already stored keeps its first row (lineage included); its new outcome is still added.
    /// Outcomes with a collision mark their scenario as a regression case.
    pub fn insert_batch(
        &mut self,
        records: &[ScenarioRecord],
    ) -> Result<InsertSummary, LibraryError> {
        let ids = records
            .iter()
            .map(|rec| {
                let id = content_id(&rec.spec);
                match validate_record(rec) {
                    Ok(()) => Ok(id),
                    Err(source) => Err(LibraryError::InvalidRecord { id, source }),
                }
            })
            .collect::<Result<Vec<String>, LibraryError>>()?;
        let mut summary = InsertSummary::default();
        // IMMEDIATE takes the write lock first, so the sequence numbers read below stay ours.
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        {
            let mut created_seq: i64 = tx.query_row(
                "SELECT COALESCE(MAX(created_seq), 0) FROM scenarios",
                [],
                |r| r.get(0),
            )?;
            let mut marked_seq: i64 = tx.query_row(
                "SELECT COALESCE(MAX(marked_seq), 0) FROM regression",
                [],
                |r| r.get(0),
            )?;
            let mut parent_stmt =
                tx.prepare_cached("SELECT kind, generation FROM scenarios WHERE id = ?1")?;
            let mut scenario_stmt = tx.prepare_cached(
                "INSERT INTO scenarios (id, kind, seed, params, parent_id, generation, origin, created_seq) \
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8) ON CONFLICT (id) DO NOTHING",
            )?;
            let mut outcome_stmt = tx.prepare_cached(&format!(
                "INSERT INTO outcomes (scenario_id, {OUTCOME_COLUMNS}) VALUES \
                 (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20)"
            ))?;
            let mut regression_stmt = tx.prepare_cached(
                "INSERT INTO regression (scenario_id, reason, marked_seq) VALUES (?1, 'collision', ?2) \
                 ON CONFLICT (scenario_id) DO NOTHING",
            )?;
            for (rec, id) in records.iter().zip(&ids) {
                let invalid = |source| LibraryError::InvalidRecord {
                    id: id.clone(),
                    source,
                };
                let generation: i64 = match &rec.parent_id {
                    None => 0,
                    Some(parent) => {
                        let row: Option<(String, i64)> = parent_stmt
                            .query_row([parent], |r| Ok((r.get(0)?, r.get(1)?)))
                            .optional()?;
                        let (parent_kind, parent_generation) =
                            row.ok_or_else(|| invalid(RecordError::UnknownParent(parent.clone())))?;
                        if parent_kind != rec.spec.kind.name() {
                            let parent_kind = decode_kind(parent, &parent_kind)?;
                            return Err(invalid(RecordError::KindChanged {
                                parent: parent_kind,
                                child: rec.spec.kind,
                            }));
                        }
                        parent_generation + 1
                    }
                };
                let params_json = serde_json::to_string(&rec.spec.params)
                    .expect("validated params are finite numbers");
                let added = scenario_stmt.execute(params![
                    id,
                    rec.spec.kind.name(),
                    rec.spec.seed as i64,
                    params_json,
                    rec.parent_id,
                    generation,
                    rec.origin.as_str(),
                    created_seq + 1,
                ])?;
                if added == 1 {
                    created_seq += 1;
                    summary.inserted += 1;
                } else {
                    summary.duplicates += 1;
                }
                if let Some(o) = &rec.outcome {
                    let (m, r) = (&o.metrics, &o.risk);
                    let min_ttc_s = ttc_for_storage(m.min_ttc_s).map_err(invalid)?;
                    let steps = i64::try_from(m.steps)
                        .map_err(|_| invalid(RecordError::StepsTooLarge(m.steps)))?;
                    outcome_stmt.execute(params![
                        id,
                        o.policy,
                        m.collision,
                        m.offroad,
                        m.success,
                        m.route_completion,
                        m.avg_speed_mps,
                        m.steering_smoothness,
                        m.longitudinal_smoothness,
                        min_ttc_s,
                        m.min_distance_m,
                        m.risk_score,
                        m.reward,
                        steps,
                        r.score,
                        r.ttc,
                        r.dist,
                        r.lane,
                        r.jerk,
                        r.collision,
                    ])?;
                    summary.outcomes += 1;
                    if m.collision && regression_stmt.execute(params![id, marked_seq + 1])? == 1 {
                        marked_seq += 1;
                    }
                }
            }
        }
        tx.commit()?;
        Ok(summary)
    }

    /// Adds rejected-candidate counts (by kind and `Infeasible::code`) in one transaction.
    pub fn record_rejections(&mut self, rejections: &[Rejection]) -> Result<(), LibraryError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        {
            let mut stmt = tx.prepare_cached(
                "INSERT INTO rejected (kind, reason, count) VALUES (?1, ?2, ?3) \
                 ON CONFLICT (kind, reason) DO UPDATE SET count = count + excluded.count",
            )?;
            for r in rejections {
                stmt.execute(params![r.kind.name(), r.reason, r.count as i64])?;
            }
        }
        tx.commit()?;
        Ok(())
    }

    /// Every rejection count, by kind then reason.
    pub fn rejected_counts(&self) -> Result<Vec<Rejection>, LibraryError> {
        let mut stmt = self
            .conn
            .prepare_cached("SELECT kind, reason, count FROM rejected ORDER BY kind, reason")?;
        let rows = stmt.query_map([], |r| {
            Ok((
                r.get::<_, String>(0)?,
                r.get::<_, String>(1)?,
                r.get::<_, i64>(2)?,
            ))
        })?;
        let mut out = Vec::new();
        for row in rows {
            let (kind, reason, count) = row?;
            let kind = decode_kind(&format!("rejected/{reason}"), &kind)?;
            out.push(Rejection {
                kind,
                reason,
                count: count.max(0) as u64,
            });
        }
        out.sort_by(|a, b| (a.kind, &a.reason).cmp(&(b.kind, &b.reason)));
        Ok(out)
    }

    /// The scenario stored under `id`, with all its outcomes (oldest first).
    pub fn get(&self, id: &str) -> Result<Option<StoredScenario>, LibraryError> {
        let row = self
            .conn
            .prepare_cached(
                "SELECT kind, seed, params, parent_id, generation, origin, created_seq FROM scenarios WHERE id = ?1",
            )?
            .query_row([id], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, String>(2)?,
                    r.get::<_, Option<String>>(3)?,
                    r.get::<_, i64>(4)?,
                    r.get::<_, String>(5)?,
                    r.get::<_, i64>(6)?,
                ))
            })
            .optional()?;
        let Some((kind, seed, params, parent_id, generation, origin, created_seq)) = row else {
            return Ok(None);
        };
        let spec = decode_spec(id, &kind, seed, &params)?;
        let origin = Origin::parse(&origin).ok_or_else(|| LibraryError::Corrupt {
            id: id.to_string(),
            reason: format!("unknown origin '{origin}'"),
        })?;
        let generation = u32::try_from(generation).map_err(|_| LibraryError::Corrupt {
            id: id.to_string(),
            reason: format!("generation {generation} out of range"),
        })?;
        let mut stmt = self.conn.prepare_cached(&format!(
            "SELECT {OUTCOME_COLUMNS} FROM outcomes WHERE scenario_id = ?1 ORDER BY seq"
        ))?;
        let outcomes = stmt
            .query_map([id], outcome_from_row)?
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Some(StoredScenario {
            id: id.to_string(),
            spec,
            origin,
            parent_id,
            generation,
            created_seq: created_seq.max(0) as u64,
            outcomes,
        }))
    }

    /// `id`, its parent, its grandparent, … back to the root (so `len() - 1` is the generation).
    pub fn lineage(&self, id: &str) -> Result<Vec<String>, LibraryError> {
        // The depth bound guards against a cycle in a hand-edited file.
        let mut stmt = self.conn.prepare_cached(
            "WITH RECURSIVE chain(id, parent_id, depth) AS ( \
                 SELECT id, parent_id, 0 FROM scenarios WHERE id = ?1 \
                 UNION ALL \
                 SELECT s.id, s.parent_id, c.depth + 1 FROM scenarios s JOIN chain c ON s.id = c.parent_id \
                 WHERE c.depth < 100000) \
             SELECT id FROM chain ORDER BY depth",
        )?;
        let chain = stmt
            .query_map([id], |r| r.get(0))?
            .collect::<Result<Vec<String>, _>>()?;
        if chain.is_empty() {
            return Err(LibraryError::UnknownScenario(id.to_string()));
        }
        Ok(chain)
    }

    /// Stored, rejected and colliding (latest default-policy outcome) counts for every kind.
    pub fn count_by_kind(&self) -> Result<BTreeMap<ScenarioKind, KindCounts>, LibraryError> {
        let mut counts: BTreeMap<ScenarioKind, KindCounts> = ScenarioKind::ALL
            .into_iter()
            .map(|k| (k, KindCounts::default()))
            .collect();
        let mut stmt = self.conn.prepare_cached(
            "SELECT k.kind, \
                 (SELECT COUNT(*) FROM scenarios s WHERE s.kind = k.kind), \
                 (SELECT COALESCE(SUM(count), 0) FROM rejected r WHERE r.kind = k.kind), \
                 (SELECT COUNT(*) FROM scenarios s JOIN outcomes o ON o.scenario_id = s.id \
                  WHERE s.kind = k.kind AND o.collision = 1 \
                    AND o.seq = (SELECT MAX(seq) FROM outcomes WHERE scenario_id = s.id AND policy = ?1)) \
             FROM (SELECT kind FROM scenarios UNION SELECT kind FROM rejected) k",
        )?;
        let rows = stmt
            .query_map([DEFAULT_POLICY], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, i64>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, i64>(3)?,
                ))
            })?
            .collect::<Result<Vec<_>, _>>()?;
        for (kind, stored, infeasible, collisions) in rows {
            let kind = decode_kind("count_by_kind", &kind)?;
            let as_count = |n: i64| n.max(0) as u64;
            counts.insert(
                kind,
                KindCounts {
                    stored: as_count(stored),
                    infeasible: as_count(infeasible),
                    collisions: as_count(collisions),
                },
            );
        }
        Ok(counts)
    }

    /// Keeps `id` as a regression case (an automatic collision mark stays as it is).
    pub fn mark_regression(&mut self, id: &str) -> Result<(), LibraryError> {
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let exists: bool = tx.query_row(
            "SELECT EXISTS (SELECT 1 FROM scenarios WHERE id = ?1)",
            [id],
            |r| r.get(0),
        )?;
        if !exists {
            return Err(LibraryError::UnknownScenario(id.to_string()));
        }
        tx.execute(
            "INSERT INTO regression (scenario_id, reason, marked_seq) \
             VALUES (?1, 'manual', (SELECT COALESCE(MAX(marked_seq), 0) + 1 FROM regression)) \
             ON CONFLICT (scenario_id) DO NOTHING",
            [id],
        )?;
        tx.commit()?;
        Ok(())
    }

    /// The regression cases, in the order they were marked.
    pub fn regression_set(&self) -> Result<Vec<RegressionCase>, LibraryError> {
        let mut stmt = self.conn.prepare_cached(
            "SELECT s.id, s.kind, s.seed, s.params, g.reason FROM regression g JOIN scenarios s ON s.id = g.scenario_id \
             ORDER BY g.marked_seq, s.id",
        )?;
        let rows = stmt
            .query_map([], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, i64>(2)?,
                    r.get::<_, String>(3)?,
                    r.get::<_, String>(4)?,
                ))
            })?
            .collect::<Result<Vec<_>, _>>()?;
        rows.into_iter()
            .map(|(id, kind, seed, params, reason)| {
                let spec = decode_spec(&id, &kind, seed, &params)?;
                let reason = match reason.as_str() {
                    "collision" => RegressionReason::Collision,
                    "manual" => RegressionReason::Manual,
                    other => {
                        return Err(LibraryError::Corrupt {
                            id,
                            reason: format!("unknown regression reason '{other}'"),
                        });
                    }
                };
                Ok(RegressionCase { id, spec, reason })
            })
            .collect()
    }
}

/// A stored kind name, or a corruption error naming where it was found.
pub(super) fn decode_kind(id: &str, kind: &str) -> Result<ScenarioKind, LibraryError> {
    kind.parse().map_err(|e| LibraryError::Corrupt {
        id: id.to_string(),
        reason: format!("{e}"),
    })
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, outcome, sampled, spec};
    use super::*;
    use risktwin_common::rng::Rng;
    use risktwin_common::scenario::mutate;

    fn count(lib: &ScenarioLibrary, table: &str) -> i64 {
        lib.conn
            .query_row(&format!("SELECT COUNT(*) FROM {table}"), [], |r| r.get(0))
            .expect("count")
    }

    #[test]
    fn store_then_get_gives_back_exact_values() {
        let (_dir, mut lib) = file_library();
        let mut with_ttc = outcome(0.8125, false, Some(1.234_567_890_123_456_7));
        with_ttc.metrics.steps = u64::from(u32::MAX) + 3;
        let mut big_seed = spec(ScenarioKind::CutIn, 0);
        big_seed.seed = u64::MAX - 5; // does not fit i64: stored bit for bit
        let records = [
            ScenarioRecord::sampled(big_seed.clone(), with_ttc.clone()),
            ScenarioRecord::sampled(
                spec(ScenarioKind::SensorOcclusion, 1),
                outcome(0.25, false, None),
            ),
            ScenarioRecord::sampled(
                spec(ScenarioKind::LowFriction, 2),
                outcome(0.5, false, Some(f64::INFINITY)),
            ),
        ];
        let summary = lib.insert_batch(&records).expect("insert");
        assert_eq!(
            summary,
            InsertSummary {
                inserted: 3,
                duplicates: 0,
                outcomes: 3
            }
        );

        let got = lib
            .get(&content_id(&big_seed))
            .expect("get")
            .expect("stored");
        assert_eq!(got.spec, big_seed);
        assert_eq!(got.outcomes, vec![with_ttc]);
        assert_eq!(
            (got.origin, got.parent_id, got.generation, got.created_seq),
            (Origin::Sampled, None, 0, 1)
        );

        let no_ttc = lib
            .get(&content_id(&records[1].spec))
            .expect("get")
            .expect("stored");
        assert_eq!(no_ttc.outcomes[0].metrics.min_ttc_s, None);
        assert_eq!(no_ttc.created_seq, 2);
        // An infinite TTC ("never closing in") is stored as SQL NULL, not as a huge number.
        let inf_id = content_id(&records[2].spec);
        let is_null: bool = lib
            .conn
            .query_row(
                "SELECT min_ttc_s IS NULL FROM outcomes WHERE scenario_id = ?1",
                [&inf_id],
                |r| r.get(0),
            )
            .expect("row");
        assert!(is_null);
        assert_eq!(
            lib.get(&inf_id).expect("get").expect("stored").outcomes[0]
                .metrics
                .min_ttc_s,
            None
        );
        assert_eq!(lib.get("0123456789abcdef").expect("get"), None);
    }

    #[test]
    fn invalid_values_are_refused_and_nothing_is_written() {
        let (_dir, mut lib) = file_library();
        let good = sampled(ScenarioKind::CutIn, 0, 0.5, false);
        let mut too_risky = sampled(ScenarioKind::CutIn, 1, 0.5, false);
        too_risky.outcome.as_mut().expect("has outcome").risk.score = 1.5;
        let err = lib
            .insert_batch(&[good.clone(), too_risky.clone()])
            .unwrap_err();
        match err {
            LibraryError::InvalidRecord {
                id,
                source:
                    RecordError::OutOfRange {
                        field: "risk.score",
                        value,
                        ..
                    },
            } => {
                assert_eq!(id, content_id(&too_risky.spec));
                assert_eq!(value, 1.5);
            }
            other => panic!("expected risk.score out of range, got {other:?}"),
        }
        let mut nan = good.clone();
        nan.outcome
            .as_mut()
            .expect("has outcome")
            .metrics
            .route_completion = f64::NAN;
        let err = lib.insert_batch(&[nan]).unwrap_err();
        assert!(
            matches!(
                err,
                LibraryError::InvalidRecord {
                    source: RecordError::NotFinite { .. },
                    ..
                }
            ),
            "{err}"
        );
        let mut negative_ttc = good.clone();
        negative_ttc
            .outcome
            .as_mut()
            .expect("has outcome")
            .metrics
            .min_ttc_s = Some(-1.0);
        assert!(lib.insert_batch(&[negative_ttc]).is_err());
        let mut out_of_range = good.clone();
        out_of_range
            .spec
            .params
            .insert("lateral_gap_m".into(), 99.0);
        let err = lib.insert_batch(&[out_of_range]).unwrap_err();
        assert!(
            matches!(
                err,
                LibraryError::InvalidRecord {
                    source: RecordError::Spec(_),
                    ..
                }
            ),
            "{err}"
        );
        let orphan = ScenarioRecord::mutated(
            spec(ScenarioKind::CutIn, 3),
            "feedfacefeedface",
            outcome(0.1, false, None),
        );
        let err = lib.insert_batch(&[good.clone(), orphan]).unwrap_err();
        assert!(
            matches!(
                err,
                LibraryError::InvalidRecord {
                    source: RecordError::UnknownParent(_),
                    ..
                }
            ),
            "{err}"
        );
        // The failed batches were rolled back whole, including `good`, which came first.
        assert_eq!((count(&lib, "scenarios"), count(&lib, "outcomes")), (0, 0));
    }

    #[test]
    fn the_same_content_is_one_row() {
        let (_dir, mut lib) = file_library();
        let rec = sampled(ScenarioKind::EmergencyBraking, 4, 0.5, false);
        let first = lib
            .insert_batch(&[rec.clone(), rec.clone()])
            .expect("insert");
        assert_eq!(
            first,
            InsertSummary {
                inserted: 1,
                duplicates: 1,
                outcomes: 2
            }
        );
        let mut rebuilt = rec.clone();
        rebuilt.spec = ScenarioSpec::new(rec.spec.kind, rec.spec.seed, rec.spec.params.clone())
            .expect("valid");
        lib.insert_batch(&[rebuilt]).expect("insert again");
        assert_eq!(count(&lib, "scenarios"), 1);
        assert_eq!(count(&lib, "outcomes"), 3);
        let mut other_seed = rec.clone();
        other_seed.spec.seed += 1;
        lib.insert_batch(&[other_seed]).expect("insert");
        assert_eq!(count(&lib, "scenarios"), 2);
    }

    #[test]
    fn three_mutations_make_a_lineage_of_depth_three() {
        let (_dir, mut lib) = file_library();
        let root = sampled(ScenarioKind::EmergencyBraking, 0, 0.9, true);
        lib.insert_batch(std::slice::from_ref(&root)).expect("root");
        let mut rng = Rng::new(3);
        let (mut parent_id, mut parent_spec) = (content_id(&root.spec), root.spec.clone());
        let mut ids = vec![parent_id.clone()];
        for _ in 0..3 {
            let child = mutate(&parent_spec, 0.05, &mut rng).expect("feasible child");
            lib.insert_batch(&[ScenarioRecord::mutated(
                child.clone(),
                &parent_id,
                outcome(0.7, false, Some(1.0)),
            )])
            .expect("child");
            parent_id = content_id(&child);
            parent_spec = child;
            ids.push(parent_id.clone());
        }
        let leaf = lib.get(&parent_id).expect("get").expect("stored");
        assert_eq!((leaf.generation, leaf.origin), (3, Origin::Mutated));
        let lineage = lib.lineage(&parent_id).expect("lineage");
        ids.reverse();
        assert_eq!(lineage, ids);
        assert_eq!(lineage.len() - 1, 3);
        assert!(matches!(
            lib.lineage("nope"),
            Err(LibraryError::UnknownScenario(_))
        ));

        let other_kind = ScenarioRecord::mutated(
            spec(ScenarioKind::CutIn, 0),
            &parent_id,
            outcome(0.1, false, None),
        );
        let err = lib.insert_batch(&[other_kind]).unwrap_err();
        assert!(
            matches!(
                err,
                LibraryError::InvalidRecord {
                    source: RecordError::KindChanged { .. },
                    ..
                }
            ),
            "{err}"
        );
        let mut sampled_with_parent = sampled(ScenarioKind::CutIn, 1, 0.1, false);
        sampled_with_parent.parent_id = Some(parent_id.clone());
        assert!(matches!(
            lib.insert_batch(&[sampled_with_parent]),
            Err(LibraryError::InvalidRecord {
                source: RecordError::Lineage { .. },
                ..
            })
        ));
    }

    #[test]
    fn counts_rejections_and_regression_cases() {
        let (_dir, mut lib) = file_library();
        lib.insert_batch(&[
            sampled(ScenarioKind::CutIn, 0, 0.9, true),
            sampled(ScenarioKind::CutIn, 1, 0.2, false),
            sampled(ScenarioKind::LowFriction, 0, 0.3, false),
        ])
        .expect("insert");
        let rej = |kind, reason: &str, count| Rejection {
            kind,
            reason: reason.to_string(),
            count,
        };
        lib.record_rejections(&[rej(ScenarioKind::CutIn, "negative-speed", 2)])
            .expect("rejections");
        lib.record_rejections(&[
            rej(ScenarioKind::CutIn, "negative-speed", 3),
            rej(ScenarioKind::CutIn, "lateral-beyond-friction", 1),
        ])
        .expect("rejections");
        assert_eq!(
            lib.rejected_counts().expect("counts"),
            vec![
                rej(ScenarioKind::CutIn, "lateral-beyond-friction", 1),
                rej(ScenarioKind::CutIn, "negative-speed", 5)
            ]
        );
        let counts = lib.count_by_kind().expect("counts");
        assert_eq!(
            counts[&ScenarioKind::CutIn],
            KindCounts {
                stored: 2,
                infeasible: 6,
                collisions: 1
            }
        );
        assert_eq!(
            counts[&ScenarioKind::LowFriction],
            KindCounts {
                stored: 1,
                infeasible: 0,
                collisions: 0
            }
        );
        assert_eq!(
            counts[&ScenarioKind::SensorOcclusion],
            KindCounts::default()
        );

        // Collisions are regression cases by default; others only when marked.
        let crash = content_id(&spec(ScenarioKind::CutIn, 0));
        let calm = content_id(&spec(ScenarioKind::LowFriction, 0));
        lib.mark_regression(&calm).expect("mark");
        lib.mark_regression(&crash)
            .expect("marking twice keeps the first reason");
        let set: Vec<(String, RegressionReason)> = lib
            .regression_set()
            .expect("set")
            .into_iter()
            .map(|c| (c.id, c.reason))
            .collect();
        assert_eq!(
            set,
            vec![
                (crash, RegressionReason::Collision),
                (calm, RegressionReason::Manual)
            ]
        );
        assert!(matches!(
            lib.mark_regression("nope"),
            Err(LibraryError::UnknownScenario(_))
        ));
    }

    /// Run with `cargo test -p risktwin-cloud --release --lib library -- --ignored --nocapture`.
    #[test]
    #[ignore = "measurement, prints the insert rate"]
    fn insert_rate_of_ten_thousand_rows() {
        let (_dir, mut lib) = file_library();
        let records: Vec<ScenarioRecord> = (0..10_000u64)
            .map(|i| {
                let kind = ScenarioKind::ALL[(i % 5) as usize];
                ScenarioRecord::sampled(
                    spec(kind, i),
                    outcome((i % 1000) as f64 / 1000.0, i % 7 == 0, Some(1.5)),
                )
            })
            .collect();
        let start = std::time::Instant::now();
        let summary = lib.insert_batch(&records).expect("insert");
        let elapsed_s = start.elapsed().as_secs_f64();
        assert_eq!(summary.inserted, 10_000);
        println!(
            "inserted {} scenario + outcome rows in {elapsed_s:.3} s: {:.0} rows/s",
            summary.inserted,
            summary.inserted as f64 / elapsed_s
        );
        let start = std::time::Instant::now();
        let top = lib.rank(Some(100), None).expect("rank");
        println!(
            "rank top 100 of 10000: {:.1} ms",
            start.elapsed().as_secs_f64() * 1e3
        );
        assert_eq!(top.len(), 100);
    }
}
