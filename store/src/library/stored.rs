//! Outcome rows read back as values of their documented domains.
//!
//! A library file is input like any other: a hand, another tool or a flipped bit can put a
//! NULL, a text or an out-of-range number where this build only ever writes a checked value
//! (the column CHECKs do not hold against `PRAGMA ignore_check_constraints` or a damaged page).
//! Every outcome read back goes through [`validate_outcome`], the check that guards writes, and
//! a row that fails is reported as [`LibraryError::BadRow`] with its file and `seq`, never
//! passed through to a ranking or a report.

use super::error::LibraryError;
use super::record::{Outcome, validate_outcome};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use rusqlite::types::Value;
use rusqlite::{Connection, Row};
use std::path::{Path, PathBuf};

/// The outcome columns, in the order [`OutcomeRow::read_at`] reads them after `seq` (and the
/// order writes give them).
pub(super) const OUTCOME_COLUMNS: &str = "policy, collision, offroad, success, route_completion, avg_speed_mps, \
     steering_smoothness, longitudinal_smoothness, min_ttc_s, min_distance_m, episode_risk_score, reward, steps, \
     risk_score, risk_ttc, risk_dist, risk_lane, risk_jerk, risk_collision";

/// How many columns [`OUTCOME_COLUMNS`] names.
pub(super) const OUTCOME_COLUMN_COUNT: usize = 19;

/// One outcome row as SQLite holds it, before its values are checked.
#[derive(Debug, Clone)]
pub(super) struct OutcomeRow {
    seq: Value,
    values: Vec<Value>,
}

impl OutcomeRow {
    /// `seq` at column `first` of `r` and the [`OUTCOME_COLUMNS`] after it, whatever their types.
    pub fn read_at(r: &Row<'_>, first: usize) -> rusqlite::Result<Self> {
        let values = (1..=OUTCOME_COLUMN_COUNT).map(|k| r.get::<_, Value>(first + k)).collect::<Result<_, _>>()?;
        Ok(Self { seq: r.get(first)?, values })
    }

    /// The outcome, checked as a write is checked; a bad value names the file and the row of
    /// `table` it is in.
    pub fn checked(self, file: &Path, table: &'static str) -> Result<Outcome, LibraryError> {
        let row = match &self.seq {
            Value::Integer(seq) => seq.to_string(),
            other => format!("{other:?}"),
        };
        self.decode().map_err(|reason| LibraryError::BadRow { path: file.to_path_buf(), table, row, reason })
    }

    fn decode(&self) -> Result<Outcome, String> {
        let v = &self.values;
        let steps = int(v, 12)?;
        let outcome = Outcome {
            policy: match &v[0] {
                Value::Text(s) => s.clone(),
                other => return Err(not(0, other, "a text")),
            },
            metrics: EpisodeMetrics {
                collision: flag(v, 1)?,
                offroad: flag(v, 2)?,
                success: flag(v, 3)?,
                route_completion: real(v, 4)?,
                avg_speed_mps: real(v, 5)?,
                steering_smoothness: real(v, 6)?,
                longitudinal_smoothness: real(v, 7)?,
                min_ttc_s: match &v[8] {
                    Value::Null => None,
                    _ => Some(real(v, 8)?),
                },
                min_distance_m: real(v, 9)?,
                risk_score: real(v, 10)?,
                reward: real(v, 11)?,
                steps: u64::try_from(steps).map_err(|_| format!("steps = {steps} is negative"))?,
            },
            risk: RiskTerms {
                score: real(v, 13)?,
                ttc: real(v, 14)?,
                dist: real(v, 15)?,
                lane: real(v, 16)?,
                jerk: real(v, 17)?,
                collision: real(v, 18)?,
            },
        };
        validate_outcome(&outcome).map_err(|e| e.to_string())?;
        Ok(outcome)
    }
}

/// The file `conn` has open (empty for an in-memory library), for error messages.
pub(super) fn file_of(conn: &Connection) -> PathBuf {
    conn.path().map(PathBuf::from).unwrap_or_default()
}

/// The name of value `k` (column `k` of [`OUTCOME_COLUMNS`]).
fn name(k: usize) -> &'static str {
    OUTCOME_COLUMNS.split(", ").nth(k).unwrap_or("?")
}

fn not(k: usize, value: &Value, expected: &str) -> String {
    let found = match value {
        Value::Null => "NULL".to_string(),
        Value::Integer(i) => i.to_string(),
        Value::Real(x) => x.to_string(),
        Value::Text(t) => format!("text '{}'", t.chars().take(40).collect::<String>()),
        Value::Blob(b) => format!("a blob of {} bytes", b.len()),
    };
    format!("{} = {found} is not {expected}", name(k))
}

fn real(v: &[Value], k: usize) -> Result<f64, String> {
    match &v[k] {
        Value::Real(x) => Ok(*x),
        // SQLite may hand a whole REAL back as an integer.
        Value::Integer(i) => Ok(*i as f64),
        other => Err(not(k, other, "a number")),
    }
}

fn int(v: &[Value], k: usize) -> Result<i64, String> {
    match &v[k] {
        Value::Integer(i) => Ok(*i),
        other => Err(not(k, other, "an integer")),
    }
}

fn flag(v: &[Value], k: usize) -> Result<bool, String> {
    match &v[k] {
        Value::Integer(0) => Ok(false),
        Value::Integer(1) => Ok(true),
        other => Err(not(k, other, "0 or 1")),
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, sampled};
    use super::*;
    use risktwin_common::scenario::ScenarioKind;

    fn lib_with_one_outcome() -> (tempfile::TempDir, super::super::ScenarioLibrary) {
        let (dir, mut lib) = file_library();
        lib.insert_batch(&[sampled(ScenarioKind::CutIn, 0, 0.5, false)]).expect("insert");
        (dir, lib)
    }

    /// Sets `column` of the one outcome to `value` past the CHECKs, then ranks.
    fn rank_after(set: &str) -> String {
        let (_dir, lib) = lib_with_one_outcome();
        lib.conn
            .execute_batch(&format!("PRAGMA ignore_check_constraints = ON; UPDATE outcomes SET {set};"))
            .expect("update");
        match lib.rank(None, None) {
            Err(e @ LibraryError::BadRow { .. }) => {
                assert!(e.blames_the_file(), "{e}");
                e.to_string()
            }
            other => panic!("{set}: expected BadRow, got {other:?}"),
        }
    }

    #[test]
    fn every_out_of_range_or_mistyped_value_names_its_row_and_column() {
        let cases = [
            ("risk_score = 5.0", "risk.score = 5 is out of range [0, 1]"),
            ("risk_collision = -0.5", "risk.collision = -0.5 is out of range [0, 1]"),
            ("min_ttc_s = -3", "min_ttc_s = -3 is out of range"),
            ("min_distance_m = -1", "min_distance_m = -1 is out of range"),
            ("route_completion = 1.5", "route_completion = 1.5 is out of range [0, 1]"),
            ("collision = 7", "collision = 7 is not 0 or 1"),
            ("steps = -4", "steps = -4 is negative"),
        ];
        for (set, needle) in cases {
            let msg = rank_after(set);
            assert!(msg.contains("row id 1: outcomes: "), "{set}: {msg}");
            assert!(msg.contains(needle), "{set}: {msg}");
            assert!(msg.starts_with("library "), "{msg}");
        }
    }

    #[test]
    fn a_stored_outcome_reads_back_as_written() {
        let (_dir, lib) = lib_with_one_outcome();
        let ranked = lib.rank(None, None).expect("rank");
        assert_eq!(ranked[0].risk.score, 0.5);
    }
}
