//! Libraries that open but hold what no build of RiskTwin writes: stored values outside their
//! documented ranges, a schema that is not the library's, pages that are not SQLite's. Each is
//! an input error naming the file (and the row where there is one), exit 2; a value is never
//! passed through to the output.

use crate::support::{assert_input_error, generate};
use rusqlite::Connection;
use std::path::Path;
use tempfile::tempdir;

/// A generated library, then `sql` run on it the way a hand (or a bit flip) could.
fn tampered(dir: &Path, sql: &str) {
    generate(dir, "lib.db", 2, 1);
    let conn = Connection::open(dir.join("lib.db")).unwrap();
    conn.execute_batch(sql).unwrap();
}

/// The outcome row whose value was changed: the riskiest (first ranked) one.
const FIRST_OUTCOME: &str = "(SELECT MIN(seq) FROM outcomes)";

fn rank_refuses_row(dir: &Path, needle: &str) {
    let seq: i64 = Connection::open(dir.join("lib.db"))
        .unwrap()
        .query_row(&format!("SELECT {FIRST_OUTCOME}"), [], |r| r.get(0))
        .unwrap();
    let line = assert_input_error(dir, &["scenarios", "rank", "--db", "lib.db", "--format", "json"], needle);
    assert!(line.contains(&format!("library lib.db: row id {seq}")), "{line}");
}

#[test]
fn a_risk_score_above_one_is_refused() {
    let dir = tempdir().unwrap();
    tampered(
        dir.path(),
        &format!(
            "PRAGMA ignore_check_constraints = ON; UPDATE outcomes SET risk_score = 5.0 WHERE seq = {FIRST_OUTCOME};"
        ),
    );
    rank_refuses_row(dir.path(), "risk.score = 5 is out of range [0, 1]");
}

#[test]
fn a_negative_time_to_collision_is_refused() {
    let dir = tempdir().unwrap();
    tampered(dir.path(), &format!("UPDATE outcomes SET min_ttc_s = -3.0 WHERE seq = {FIRST_OUTCOME};"));
    rank_refuses_row(dir.path(), "min_ttc_s = -3");
    // `simulate --db` reads the same rows through another query.
    let id: String = Connection::open(dir.path().join("lib.db"))
        .unwrap()
        .query_row(&format!("SELECT scenario_id FROM outcomes WHERE seq = {FIRST_OUTCOME}"), [], |r| r.get(0))
        .unwrap();
    assert_input_error(dir.path(), &["simulate", "--db", "lib.db", "--id", &id, "--format", "json"], "min_ttc_s = -3");
}

#[test]
fn a_table_without_its_constraints_is_the_wrong_schema() {
    let dir = tempdir().unwrap();
    // The outcomes table rebuilt without NOT NULL and CHECKs, one score set to NULL.
    tampered(
        dir.path(),
        "PRAGMA foreign_keys = OFF; \
         CREATE TABLE o2 AS SELECT * FROM outcomes; DROP TABLE outcomes; ALTER TABLE o2 RENAME TO outcomes; \
         UPDATE outcomes SET risk_score = NULL;",
    );
    assert_input_error(dir.path(), &["scenarios", "rank", "--db", "lib.db", "--format", "json"], "schema");
}

#[test]
fn overwritten_pages_are_a_bad_file_not_a_runtime_failure() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 4, 1);
    let path = dir.path().join("lib.db");
    let mut bytes = std::fs::read(&path).unwrap();
    let page = u16::from_be_bytes([bytes[16], bytes[17]]) as usize;
    // Every page after the first (the schema) overwritten with a repeating pattern.
    for (i, b) in bytes.iter_mut().enumerate().skip(page) {
        *b = (i % 251) as u8;
    }
    std::fs::write(&path, &bytes).unwrap();
    for args in [
        &["scenarios", "rank", "--db", "lib.db", "--format", "json"][..],
        &["scenarios", "rank", "--db", "lib.db", "--kind", "commonroad", "--format", "json"][..],
    ] {
        assert_input_error(dir.path(), args, "lib.db");
    }
}
