//! Writing scenarios: batch inserts in one transaction (validated first, all or nothing) and
//! rejection counts.

use super::connection::ScenarioLibrary;
use super::error::{LibraryError, RecordError};
use super::query::decode_kind;
use super::record::{InsertSummary, Outcome, Rejection, ScenarioRecord, content_id, ttc_for_storage, validate_record};
use super::stored::OUTCOME_COLUMNS;
use rusqlite::{OptionalExtension, Statement, TransactionBehavior, params};

impl ScenarioLibrary {
    /// Stores a batch of scenarios and their outcomes in one transaction: all or nothing.
    ///
    /// Every record is validated before anything is written. A scenario whose content is
    /// already stored keeps its first row (lineage included); its new outcome is still added.
    /// Outcomes with a collision mark their scenario as a regression case.
    pub fn insert_batch(&mut self, records: &[ScenarioRecord]) -> Result<InsertSummary, LibraryError> {
        self.insert_with_rejections(records, &[])
    }

    /// [`ScenarioLibrary::insert_batch`] and [`ScenarioLibrary::record_rejections`] in one
    /// transaction: a generator that commits the candidates it rejected together with the
    /// scenarios sampled beside them never leaves counts for scenarios a killed run did not store.
    pub fn insert_with_rejections(
        &mut self,
        records: &[ScenarioRecord],
        rejections: &[Rejection],
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
        let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        {
            let mut created_seq: i64 =
                tx.query_row("SELECT COALESCE(MAX(created_seq), 0) FROM scenarios", [], |r| r.get(0))?;
            let mut marked_seq: i64 =
                tx.query_row("SELECT COALESCE(MAX(marked_seq), 0) FROM regression", [], |r| r.get(0))?;
            let mut parent_stmt = tx.prepare_cached("SELECT kind, generation FROM scenarios WHERE id = ?1")?;
            let mut scenario_stmt = tx.prepare_cached(
                "INSERT INTO scenarios (id, kind, seed, params, parent_id, generation, origin, created_seq) \
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8) ON CONFLICT (id) DO NOTHING",
            )?;
            let mut outcome_stmt = tx.prepare_cached(&outcome_insert_sql("outcomes", "scenario_id"))?;
            let mut regression_stmt = tx.prepare_cached(
                "INSERT INTO regression (scenario_id, reason, marked_seq) VALUES (?1, 'collision', ?2) \
                 ON CONFLICT (scenario_id) DO NOTHING",
            )?;
            for (rec, id) in records.iter().zip(&ids) {
                let invalid = |source| LibraryError::InvalidRecord { id: id.clone(), source };
                let generation: i64 = match &rec.parent_id {
                    None => 0,
                    Some(parent) => {
                        let row: Option<(String, i64)> =
                            parent_stmt.query_row([parent], |r| Ok((r.get(0)?, r.get(1)?))).optional()?;
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
                let params_json = serde_json::to_string(&rec.spec.params).expect("validated params are finite numbers");
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
                    insert_outcome(&mut outcome_stmt, id, o)?;
                    summary.outcomes += 1;
                    if o.metrics.collision && regression_stmt.execute(params![id, marked_seq + 1])? == 1 {
                        marked_seq += 1;
                    }
                }
            }
            let mut rejected_stmt = tx.prepare_cached(
                "INSERT INTO rejected (kind, reason, count) VALUES (?1, ?2, ?3) \
                 ON CONFLICT (kind, reason) DO UPDATE SET count = count + excluded.count",
            )?;
            for r in rejections {
                rejected_stmt.execute(params![r.kind.name(), r.reason, r.count as i64])?;
            }
        }
        tx.commit()?;
        Ok(summary)
    }

    /// Adds rejected-candidate counts (by kind and `Infeasible::code`) in one transaction.
    pub fn record_rejections(&mut self, rejections: &[Rejection]) -> Result<(), LibraryError> {
        self.insert_with_rejections(&[], rejections).map(|_| ())
    }

    /// Every rejection count, by kind then reason.
    pub fn rejected_counts(&self) -> Result<Vec<Rejection>, LibraryError> {
        let mut stmt = self.conn.prepare_cached("SELECT kind, reason, count FROM rejected ORDER BY kind, reason")?;
        let rows = stmt.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?, r.get::<_, i64>(2)?)))?;
        let mut out = Vec::new();
        for row in rows {
            let (kind, reason, count) = row?;
            let kind = decode_kind(&format!("rejected/{reason}"), &kind)?;
            out.push(Rejection { kind, reason, count: count.max(0) as u64 });
        }
        out.sort_by(|a, b| (a.kind, &a.reason).cmp(&(b.kind, &b.reason)));
        Ok(out)
    }
}

/// `INSERT` of one outcome row into `table`, owned by the row `owner_column` names.
pub(super) fn outcome_insert_sql(table: &str, owner_column: &str) -> String {
    format!(
        "INSERT INTO {table} ({owner_column}, {OUTCOME_COLUMNS}) VALUES \
         (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20)"
    )
}

/// Runs a statement of [`outcome_insert_sql`] for outcome `o` of `owner_id`.
pub(super) fn insert_outcome(stmt: &mut Statement<'_>, owner_id: &str, o: &Outcome) -> Result<(), LibraryError> {
    let invalid = |source| LibraryError::InvalidRecord { id: owner_id.to_string(), source };
    let (m, r) = (&o.metrics, &o.risk);
    let min_ttc_s = ttc_for_storage(m.min_ttc_s).map_err(invalid)?;
    let steps = i64::try_from(m.steps).map_err(|_| invalid(RecordError::StepsTooLarge(m.steps)))?;
    stmt.execute(params![
        owner_id,
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, outcome, sampled, spec};
    use super::*;
    use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};

    fn count(lib: &ScenarioLibrary, table: &str) -> i64 {
        lib.conn.query_row(&format!("SELECT COUNT(*) FROM {table}"), [], |r| r.get(0)).expect("count")
    }

    #[test]
    fn invalid_values_are_refused_and_nothing_is_written() {
        let (_dir, mut lib) = file_library();
        let good = sampled(ScenarioKind::CutIn, 0, 0.5, false);
        let mut too_risky = sampled(ScenarioKind::CutIn, 1, 0.5, false);
        too_risky.outcome.as_mut().expect("has outcome").risk.score = 1.5;
        let err = lib.insert_batch(&[good.clone(), too_risky.clone()]).unwrap_err();
        match err {
            LibraryError::InvalidRecord { id, source: RecordError::OutOfRange { field: "risk.score", value, .. } } => {
                assert_eq!(id, content_id(&too_risky.spec));
                assert_eq!(value, 1.5);
            }
            other => panic!("expected risk.score out of range, got {other:?}"),
        }
        let mut nan = good.clone();
        nan.outcome.as_mut().expect("has outcome").metrics.route_completion = f64::NAN;
        let err = lib.insert_batch(&[nan]).unwrap_err();
        assert!(matches!(err, LibraryError::InvalidRecord { source: RecordError::NotFinite { .. }, .. }), "{err}");
        let mut negative_ttc = good.clone();
        negative_ttc.outcome.as_mut().expect("has outcome").metrics.min_ttc_s = Some(-1.0);
        assert!(lib.insert_batch(&[negative_ttc]).is_err());
        let mut out_of_range = good.clone();
        out_of_range.spec.params.insert("lateral_gap_m".into(), 99.0);
        let err = lib.insert_batch(&[out_of_range]).unwrap_err();
        assert!(matches!(err, LibraryError::InvalidRecord { source: RecordError::Spec(_), .. }), "{err}");
        let orphan =
            ScenarioRecord::mutated(spec(ScenarioKind::CutIn, 3), "feedfacefeedface", outcome(0.1, false, None));
        let err = lib.insert_batch(&[good.clone(), orphan]).unwrap_err();
        assert!(matches!(err, LibraryError::InvalidRecord { source: RecordError::UnknownParent(_), .. }), "{err}");
        // The failed batches were rolled back whole, including `good`, which came first.
        assert_eq!((count(&lib, "scenarios"), count(&lib, "outcomes")), (0, 0));
    }

    #[test]
    fn the_same_content_is_one_row() {
        let (_dir, mut lib) = file_library();
        let rec = sampled(ScenarioKind::EmergencyBraking, 4, 0.5, false);
        let first = lib.insert_batch(&[rec.clone(), rec.clone()]).expect("insert");
        assert_eq!(first, InsertSummary { inserted: 1, duplicates: 1, outcomes: 2 });
        let mut rebuilt = rec.clone();
        rebuilt.spec = ScenarioSpec::new(rec.spec.kind, rec.spec.seed, rec.spec.params.clone()).expect("valid");
        lib.insert_batch(&[rebuilt]).expect("insert again");
        assert_eq!(count(&lib, "scenarios"), 1);
        assert_eq!(count(&lib, "outcomes"), 3);
        let mut other_seed = rec.clone();
        other_seed.spec.seed += 1;
        lib.insert_batch(&[other_seed]).expect("insert");
        assert_eq!(count(&lib, "scenarios"), 2);
    }

    /// Run with `cargo test -p risktwin-store --release --lib library -- --ignored --nocapture`.
    #[test]
    #[ignore = "measurement, prints the insert rate"]
    fn insert_rate_of_ten_thousand_rows() {
        let (_dir, mut lib) = file_library();
        let records: Vec<ScenarioRecord> = (0..10_000u64)
            .map(|i| {
                let kind = ScenarioKind::ALL[(i % 5) as usize];
                ScenarioRecord::sampled(spec(kind, i), outcome((i % 1000) as f64 / 1000.0, i % 7 == 0, Some(1.5)))
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
        println!("rank top 100 of 10000: {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
        assert_eq!(top.len(), 100);
    }
}
