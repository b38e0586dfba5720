//! The regression set: scenarios kept to re-run against every new policy. Any outcome with a
//! collision adds its scenario (in `insert_batch`); `mark_regression` adds others by hand.

use super::connection::ScenarioLibrary;
use super::error::LibraryError;
use super::query::decode_spec;
use risktwin_common::scenario::ScenarioSpec;
use rusqlite::TransactionBehavior;

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

impl ScenarioLibrary {
    /// Keeps `id` as a regression case (an automatic collision mark stays as it is).
    pub fn mark_regression(&mut self, id: &str) -> Result<(), LibraryError> {
        let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let exists: bool = tx.query_row("SELECT EXISTS (SELECT 1 FROM scenarios WHERE id = ?1)", [id], |r| r.get(0))?;
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

#[cfg(test)]
mod tests {
    use super::super::content_id;
    use super::super::fixtures::{file_library, sampled, spec};
    use super::*;
    use risktwin_common::scenario::ScenarioKind;

    #[test]
    fn collisions_and_marked_scenarios_are_regression_cases() {
        let (_dir, mut lib) = file_library();
        lib.insert_batch(&[
            sampled(ScenarioKind::CutIn, 0, 0.9, true),
            sampled(ScenarioKind::LowFriction, 0, 0.3, false),
        ])
        .expect("insert");
        // Collisions are regression cases by default; others only when marked.
        let crash = content_id(&spec(ScenarioKind::CutIn, 0));
        let calm = content_id(&spec(ScenarioKind::LowFriction, 0));
        lib.mark_regression(&calm).expect("mark");
        lib.mark_regression(&crash).expect("marking twice keeps the first reason");
        let set: Vec<(String, RegressionReason)> =
            lib.regression_set().expect("set").into_iter().map(|c| (c.id, c.reason)).collect();
        assert_eq!(set, vec![(crash, RegressionReason::Collision), (calm, RegressionReason::Manual)]);
        assert!(matches!(lib.mark_regression("nope"), Err(LibraryError::UnknownScenario(_))));
    }
}
