//! Reading scenarios back: lookup by id with every outcome, lineage, per-kind counts, and the
//! decoding (with re-validation) of stored rows.

use super::connection::ScenarioLibrary;
use super::error::LibraryError;
use super::record::{DEFAULT_POLICY, KindCounts, Origin, StoredScenario};
use super::stored::{OUTCOME_COLUMNS, OutcomeRow};
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};
use rusqlite::OptionalExtension;
use std::collections::BTreeMap;

/// Rebuilds and re-validates a spec from its columns; a row that fails is reported as corrupt.
/// Seeds are u64 stored bit for bit in SQLite's signed 64-bit integers.
pub(super) fn decode_spec(id: &str, kind: &str, seed: i64, params: &str) -> Result<ScenarioSpec, LibraryError> {
    let corrupt = |reason: String| LibraryError::Corrupt { id: id.to_string(), reason };
    let kind: ScenarioKind = kind.parse().map_err(|e| corrupt(format!("{e}")))?;
    let params: BTreeMap<String, f64> =
        serde_json::from_str(params).map_err(|e| corrupt(format!("params are not a JSON object of numbers: {e}")))?;
    ScenarioSpec::new(kind, seed as u64, params).map_err(|e| corrupt(e.to_string()))
}

impl ScenarioLibrary {
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
            "SELECT seq, {OUTCOME_COLUMNS} FROM outcomes WHERE scenario_id = ?1 ORDER BY seq"
        ))?;
        let rows = stmt.query_map([id], |r| OutcomeRow::read_at(r, 0))?.collect::<Result<Vec<_>, _>>()?;
        let outcomes = rows.into_iter().map(|o| o.checked(&self.path, "outcomes")).collect::<Result<_, _>>()?;
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
        let chain = stmt.query_map([id], |r| r.get(0))?.collect::<Result<Vec<String>, _>>()?;
        if chain.is_empty() {
            return Err(LibraryError::UnknownScenario(id.to_string()));
        }
        Ok(chain)
    }

    /// The driver labels that outcomes of generated scenarios (or, with `recorded`, of
    /// recorded cases) are stored under and that end with `suffix` (a model file's `@` and
    /// digest: the same file evaluated under other paths), sorted.
    pub fn labels_ending_with(&self, suffix: &str, recorded: bool) -> Result<Vec<String>, LibraryError> {
        let table = if recorded { "recorded_outcomes" } else { "outcomes" };
        let sql = format!("SELECT DISTINCT policy FROM {table} WHERE substr(policy, -length(?1)) = ?1 ORDER BY policy");
        let mut stmt = self.conn.prepare_cached(&sql)?;
        let rows = stmt.query_map([suffix], |r| r.get::<_, String>(0))?;
        Ok(rows.collect::<Result<Vec<_>, _>>()?)
    }

    /// Stored, rejected and colliding (latest default-policy outcome) counts for every kind.
    pub fn count_by_kind(&self) -> Result<BTreeMap<ScenarioKind, KindCounts>, LibraryError> {
        let mut counts: BTreeMap<ScenarioKind, KindCounts> =
            ScenarioKind::ALL.into_iter().map(|k| (k, KindCounts::default())).collect();
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
                Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)?, r.get::<_, i64>(2)?, r.get::<_, i64>(3)?))
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
}

/// A stored kind name, or a corruption error naming where it was found.
pub(super) fn decode_kind(id: &str, kind: &str) -> Result<ScenarioKind, LibraryError> {
    kind.parse().map_err(|e| LibraryError::Corrupt { id: id.to_string(), reason: format!("{e}") })
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, outcome, sampled, spec};
    use super::super::record::{InsertSummary, Rejection, ScenarioRecord, content_id};
    use super::super::{LibraryError, RecordError};
    use super::*;
    use risktwin_common::rng::Rng;
    use risktwin_common::scenario::mutate;

    #[test]
    fn store_then_get_gives_back_exact_values() {
        let (_dir, mut lib) = file_library();
        let mut with_ttc = outcome(0.8125, false, Some(1.234_567_890_123_456_7));
        with_ttc.metrics.steps = u64::from(u32::MAX) + 3;
        let mut big_seed = spec(ScenarioKind::CutIn, 0);
        big_seed.seed = u64::MAX - 5; // does not fit i64: stored bit for bit
        let records = [
            ScenarioRecord::sampled(big_seed.clone(), with_ttc.clone()),
            ScenarioRecord::sampled(spec(ScenarioKind::SensorOcclusion, 1), outcome(0.25, false, None)),
            ScenarioRecord::sampled(spec(ScenarioKind::LowFriction, 2), outcome(0.5, false, Some(f64::INFINITY))),
        ];
        let summary = lib.insert_batch(&records).expect("insert");
        assert_eq!(summary, InsertSummary { inserted: 3, duplicates: 0, outcomes: 3 });

        let got = lib.get(&content_id(&big_seed)).expect("get").expect("stored");
        assert_eq!(got.spec, big_seed);
        assert_eq!(got.outcomes, vec![with_ttc]);
        assert_eq!((got.origin, got.parent_id, got.generation, got.created_seq), (Origin::Sampled, None, 0, 1));

        let no_ttc = lib.get(&content_id(&records[1].spec)).expect("get").expect("stored");
        assert_eq!(no_ttc.outcomes[0].metrics.min_ttc_s, None);
        assert_eq!(no_ttc.created_seq, 2);
        // An infinite TTC ("never closing in") is stored as SQL NULL, not as a huge number.
        let inf_id = content_id(&records[2].spec);
        let is_null: bool = lib
            .conn
            .query_row("SELECT min_ttc_s IS NULL FROM outcomes WHERE scenario_id = ?1", [&inf_id], |r| r.get(0))
            .expect("row");
        assert!(is_null);
        assert_eq!(lib.get(&inf_id).expect("get").expect("stored").outcomes[0].metrics.min_ttc_s, None);
        assert_eq!(lib.get("0123456789abcdef").expect("get"), None);
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
            lib.insert_batch(&[ScenarioRecord::mutated(child.clone(), &parent_id, outcome(0.7, false, Some(1.0)))])
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
        assert!(matches!(lib.lineage("nope"), Err(LibraryError::UnknownScenario(_))));

        let other_kind = ScenarioRecord::mutated(spec(ScenarioKind::CutIn, 0), &parent_id, outcome(0.1, false, None));
        let err = lib.insert_batch(&[other_kind]).unwrap_err();
        assert!(matches!(err, LibraryError::InvalidRecord { source: RecordError::KindChanged { .. }, .. }), "{err}");
        let mut sampled_with_parent = sampled(ScenarioKind::CutIn, 1, 0.1, false);
        sampled_with_parent.parent_id = Some(parent_id.clone());
        assert!(matches!(
            lib.insert_batch(&[sampled_with_parent]),
            Err(LibraryError::InvalidRecord { source: RecordError::Lineage { .. }, .. })
        ));
    }

    #[test]
    fn counts_rejections_by_kind_and_reason() {
        let (_dir, mut lib) = file_library();
        lib.insert_batch(&[
            sampled(ScenarioKind::CutIn, 0, 0.9, true),
            sampled(ScenarioKind::CutIn, 1, 0.2, false),
            sampled(ScenarioKind::LowFriction, 0, 0.3, false),
        ])
        .expect("insert");
        let rej = |kind, reason: &str, count| Rejection { kind, reason: reason.to_string(), count };
        lib.record_rejections(&[rej(ScenarioKind::CutIn, "negative-speed", 2)]).expect("rejections");
        lib.record_rejections(&[
            rej(ScenarioKind::CutIn, "negative-speed", 3),
            rej(ScenarioKind::CutIn, "lateral-beyond-friction", 1),
        ])
        .expect("rejections");
        assert_eq!(
            lib.rejected_counts().expect("counts"),
            vec![rej(ScenarioKind::CutIn, "lateral-beyond-friction", 1), rej(ScenarioKind::CutIn, "negative-speed", 5)]
        );
        let counts = lib.count_by_kind().expect("counts");
        assert_eq!(counts[&ScenarioKind::CutIn], KindCounts { stored: 2, infeasible: 6, collisions: 1 });
        assert_eq!(counts[&ScenarioKind::LowFriction], KindCounts { stored: 1, infeasible: 0, collisions: 0 });
        assert_eq!(counts[&ScenarioKind::SensorOcclusion], KindCounts::default());
    }
}
