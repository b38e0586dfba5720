//! The on-disk schema (documented in the `library` module doc) and the open-time checks that
//! tell a RiskTwin library from a foreign SQLite file or from a file that is not SQLite at all.

use super::error::LibraryError;
use crate::sqlite_schema::{not_a_database, schema_difference};
use rusqlite::{Connection, TransactionBehavior};
use std::path::Path;
use std::time::Duration;

/// `PRAGMA application_id` of a RiskTwin library: "RTWL" in ASCII.
pub const APPLICATION_ID: i32 = 0x5254_574C;
/// `PRAGMA user_version`: bumped whenever the tables change.
pub const SCHEMA_VERSION: i64 = 3;
/// How long a writer waits for another connection's lock (the cloud role and the CLI may share
/// a file) before reporting SQLITE_BUSY.
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// The column definitions of one outcome (every field of `EpisodeMetrics` and `RiskTerms`),
/// shared by the outcomes of generated scenarios and of recorded cases.
macro_rules! outcome_columns {
    () => {
        "
    policy                  TEXT NOT NULL CHECK (policy <> ''),
    collision               INTEGER NOT NULL CHECK (collision IN (0, 1)),
    offroad                 INTEGER NOT NULL CHECK (offroad IN (0, 1)),
    success                 INTEGER NOT NULL CHECK (success IN (0, 1)),
    route_completion        REAL NOT NULL,
    avg_speed_mps           REAL NOT NULL,
    steering_smoothness     REAL NOT NULL,
    longitudinal_smoothness REAL NOT NULL,
    min_ttc_s               REAL,
    min_distance_m          REAL NOT NULL,
    episode_risk_score      REAL NOT NULL,
    reward                  REAL NOT NULL,
    steps                   INTEGER NOT NULL CHECK (steps >= 0),
    risk_score              REAL NOT NULL CHECK (risk_score BETWEEN 0 AND 1),
    risk_ttc                REAL NOT NULL CHECK (risk_ttc BETWEEN 0 AND 1),
    risk_dist               REAL NOT NULL CHECK (risk_dist BETWEEN 0 AND 1),
    risk_lane               REAL NOT NULL CHECK (risk_lane BETWEEN 0 AND 1),
    risk_jerk               REAL NOT NULL CHECK (risk_jerk BETWEEN 0 AND 1),
    risk_collision          REAL NOT NULL CHECK (risk_collision BETWEEN 0 AND 1)
"
    };
}

/// Version 1: generated scenarios, their outcomes, rejection counts, the regression set.
const V1_DDL: &str = concat!(
    "
CREATE TABLE scenarios (
    id          TEXT PRIMARY KEY NOT NULL,
    kind        TEXT NOT NULL CHECK (kind IN ('cut-in', 'emergency-braking', 'pedestrian-crossing',
                                              'sensor-occlusion', 'low-friction')),
    seed        INTEGER NOT NULL,
    params      TEXT NOT NULL,
    parent_id   TEXT REFERENCES scenarios(id),
    generation  INTEGER NOT NULL CHECK (generation >= 0),
    origin      TEXT NOT NULL CHECK (origin IN ('sampled', 'mutated', 'imported', 'regression')),
    created_seq INTEGER NOT NULL UNIQUE
) STRICT;
CREATE INDEX scenarios_by_parent ON scenarios(parent_id);
CREATE INDEX scenarios_by_kind ON scenarios(kind);

CREATE TABLE outcomes (
    seq                     INTEGER PRIMARY KEY,
    scenario_id             TEXT NOT NULL REFERENCES scenarios(id),
",
    outcome_columns!(),
    ") STRICT;
CREATE INDEX outcomes_latest ON outcomes(scenario_id, policy, seq);

CREATE TABLE rejected (
    kind   TEXT NOT NULL,
    reason TEXT NOT NULL,
    count  INTEGER NOT NULL CHECK (count >= 0),
    PRIMARY KEY (kind, reason)
) STRICT;

CREATE TABLE regression (
    scenario_id TEXT PRIMARY KEY NOT NULL REFERENCES scenarios(id),
    reason      TEXT NOT NULL CHECK (reason IN ('collision', 'manual')),
    marked_seq  INTEGER NOT NULL
) STRICT;
"
);

/// Version 2: recorded validation cases (a CommonRoad XML scenario with its ego) and their
/// outcomes, one row per policy run; the reference outcome is the recorded ego replayed.
const V2_DDL: &str = concat!(
    "
CREATE TABLE recorded (
    id           TEXT PRIMARY KEY NOT NULL,
    kind         TEXT NOT NULL CHECK (kind = 'commonroad'),
    source_name  TEXT NOT NULL,
    benchmark_id TEXT NOT NULL,
    ego_id       INTEGER NOT NULL,
    xml          TEXT NOT NULL CHECK (xml <> ''),
    created_seq  INTEGER NOT NULL UNIQUE
) STRICT;

CREATE TABLE recorded_outcomes (
    seq                     INTEGER PRIMARY KEY,
    case_id                 TEXT NOT NULL REFERENCES recorded(id),
",
    outcome_columns!(),
    ") STRICT;
CREATE INDEX recorded_outcomes_latest ON recorded_outcomes(case_id, policy, seq);
"
);

/// Version 3: the closed loop's state. Scenarios pushed to fleet edges (one outstanding per
/// edge, enforced by a partial unique index), the episodes the fleet played with the edge's
/// own outcome (in `outcomes`) beside the twin's view of it, and the policy versions the
/// trainer produced with the gate's decision and where each went.
const V3_DDL: &str = concat!(
    "
CREATE TABLE pushes (
    seq         INTEGER PRIMARY KEY,
    scenario_id TEXT NOT NULL REFERENCES scenarios(id),
    site        TEXT NOT NULL CHECK (site <> ''),
    edge        TEXT NOT NULL CHECK (edge <> ''),
    attempts    INTEGER NOT NULL CHECK (attempts >= 1),
    state       TEXT NOT NULL CHECK (state IN ('outstanding', 'done', 'abandoned'))
) STRICT;
CREATE UNIQUE INDEX pushes_one_outstanding ON pushes(site, edge) WHERE state = 'outstanding';
CREATE INDEX pushes_by_scenario ON pushes(scenario_id);

CREATE TABLE twin_outcomes (
    seq                     INTEGER PRIMARY KEY,
    scenario_id             TEXT NOT NULL REFERENCES scenarios(id),
",
    outcome_columns!(),
    ") STRICT;

CREATE TABLE fleet_episodes (
    seq              INTEGER PRIMARY KEY,
    scenario_id      TEXT NOT NULL REFERENCES scenarios(id),
    site             TEXT NOT NULL CHECK (site <> ''),
    edge             TEXT NOT NULL CHECK (edge <> ''),
    policy_id        TEXT CHECK (policy_id <> ''),
    policy_version   INTEGER CHECK (policy_version >= 0),
    scene            TEXT,
    push_seq         INTEGER UNIQUE REFERENCES pushes(seq),
    edge_outcome_seq INTEGER NOT NULL UNIQUE REFERENCES outcomes(seq),
    twin_outcome_seq INTEGER UNIQUE REFERENCES twin_outcomes(seq),
    twin_ticks       INTEGER NOT NULL CHECK (twin_ticks >= 0),
    disagreement     TEXT CHECK (disagreement <> ''),
    CHECK ((policy_id IS NULL) = (policy_version IS NULL))
) STRICT;
CREATE INDEX fleet_episodes_by_scenario ON fleet_episodes(scenario_id);

CREATE TABLE policies (
    version     INTEGER PRIMARY KEY CHECK (version >= 1),
    policy_id   TEXT NOT NULL CHECK (policy_id <> ''),
    algo        TEXT NOT NULL CHECK (algo <> ''),
    weights     BLOB NOT NULL,
    decision    TEXT NOT NULL CHECK (decision IN ('pushed', 'held-back')),
    reasons     TEXT NOT NULL,
    failures    INTEGER NOT NULL CHECK (failures >= 0)
) STRICT;

CREATE TABLE policy_pushes (
    version INTEGER NOT NULL REFERENCES policies(version),
    site    TEXT NOT NULL,
    edge    TEXT NOT NULL,
    PRIMARY KEY (version, site, edge)
) STRICT;
"
);

/// `MIGRATIONS[v]` takes a file from version `v` to `v + 1`; a new file runs them all, so new
/// and upgraded files have the same schema. Frozen once released: add, never edit.
const MIGRATIONS: [&str; SCHEMA_VERSION as usize] = [V1_DDL, V2_DDL, V3_DDL];

/// Maps the first error that reading a file raises to "not SQLite" when SQLite says so.
fn read_error(path: &Path, err: rusqlite::Error) -> LibraryError {
    if not_a_database(&err) {
        LibraryError::NotSqlite { path: path.to_path_buf(), reason: err.to_string() }
    } else {
        LibraryError::Open { path: path.to_path_buf(), source: err }
    }
}

/// Checks what the file holds, creates the schema in an empty one (or upgrades an older one),
/// then sets the connection up.
///
/// Nothing is written before the file is known to be empty or ours, its tables and indexes
/// those of its version included, so opening a foreign or altered database by mistake leaves it
/// untouched.
pub fn prepare(conn: &mut Connection, path: &Path) -> Result<(), LibraryError> {
    // The first statement reads the header: garbage and text files fail here (SQLITE_NOTADB).
    let app_id: i32 = conn.pragma_query_value(None, "application_id", |r| r.get(0)).map_err(|e| read_error(path, e))?;
    let version: i64 = conn.pragma_query_value(None, "user_version", |r| r.get(0)).map_err(|e| read_error(path, e))?;
    let objects: Vec<String> = {
        let mut stmt = conn
            .prepare("SELECT name FROM sqlite_schema WHERE name NOT LIKE 'sqlite_%' ORDER BY name")
            .map_err(|e| read_error(path, e))?;
        let rows = stmt.query_map([], |r| r.get(0)).map_err(|e| read_error(path, e))?;
        rows.collect::<Result<_, _>>().map_err(|e| read_error(path, e))?
    };
    let unsupported =
        |found: i64| LibraryError::UnsupportedVersion { path: path.to_path_buf(), found, expected: SCHEMA_VERSION };
    if app_id == APPLICATION_ID {
        // Older versions are upgraded below; a newer one is another build's file.
        if !(1..=SCHEMA_VERSION).contains(&version) {
            return Err(unsupported(version));
        }
        check_schema(conn, path, version)?;
    } else if app_id != 0 || version != 0 || !objects.is_empty() {
        let shown: Vec<&str> = objects.iter().take(5).map(String::as_str).collect();
        return Err(LibraryError::NotALibrary {
            path: path.to_path_buf(),
            reason: format!(
                "application_id is {app_id:#x} (expected {APPLICATION_ID:#x}), user_version {version}, objects: [{}]",
                shown.join(", ")
            ),
        });
    }
    conn.busy_timeout(BUSY_TIMEOUT)?;
    // WAL: readers do not block the writer and a crash loses at most the last transactions;
    // NORMAL sync is durable across application crashes in WAL mode (sqlite.org/pragma.html).
    // In-memory databases answer "memory" and stay so.
    let _mode: String = conn.pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get(0))?;
    conn.pragma_update(None, "synchronous", "NORMAL")?;
    conn.pragma_update(None, "foreign_keys", true)?;
    if app_id == 0 || version < SCHEMA_VERSION {
        // IMMEDIATE plus a second look: two processes creating or upgrading the same file do
        // not both run the DDL. Upgrades only add tables, so an upgraded file reads as before.
        let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
        let app_id_now: i32 = tx.pragma_query_value(None, "application_id", |r| r.get(0))?;
        let version_now: i64 = tx.pragma_query_value(None, "user_version", |r| r.get(0))?;
        let from = if app_id_now == APPLICATION_ID { version_now } else { 0 };
        let pending = usize::try_from(from).ok().and_then(|v| MIGRATIONS.get(v..)).ok_or_else(|| unsupported(from))?;
        for ddl in pending {
            tx.execute_batch(ddl)?;
        }
        if app_id_now != APPLICATION_ID {
            tx.pragma_update(None, "application_id", APPLICATION_ID)?;
        }
        tx.pragma_update(None, "user_version", SCHEMA_VERSION)?;
        tx.commit()?;
        check_schema(conn, path, SCHEMA_VERSION)?;
    }
    Ok(())
}

/// Refuses a file whose tables and indexes are not those of schema `version`
/// ([`crate::sqlite_schema::schema_difference`]; new and upgraded files are the same).
fn check_schema(conn: &Connection, path: &Path, version: i64) -> Result<(), LibraryError> {
    let count = usize::try_from(version).unwrap_or(0).min(MIGRATIONS.len());
    match schema_difference(conn, &MIGRATIONS[..count], "a library").map_err(|e| read_error(path, e))? {
        Some(reason) => Err(LibraryError::WrongSchema { path: path.to_path_buf(), reason }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{file_library, sampled};
    use super::super::{LibraryError, ScenarioLibrary};
    use super::*;
    use risktwin_common::rng::Rng;
    use risktwin_common::scenario::ScenarioKind;

    #[test]
    fn files_are_in_wal_mode_and_marked_as_ours() {
        let (dir, lib) = file_library();
        assert_eq!(lib.journal_mode().expect("pragma"), "wal");
        // WAL is a property of the file: a second, plain connection sees it too.
        let raw = Connection::open(dir.path().join("library.db")).expect("raw open");
        let mode: String = raw.pragma_query_value(None, "journal_mode", |r| r.get(0)).expect("pragma");
        assert_eq!(mode, "wal");
        let app_id: i32 = raw.pragma_query_value(None, "application_id", |r| r.get(0)).expect("pragma");
        assert_eq!(app_id, APPLICATION_ID);
        let sync: i64 = lib.conn.pragma_query_value(None, "synchronous", |r| r.get(0)).expect("pragma");
        assert_eq!(sync, 1, "synchronous = NORMAL");
        let fk: bool = lib.conn.pragma_query_value(None, "foreign_keys", |r| r.get(0)).expect("pragma");
        assert!(fk);
        let mem = ScenarioLibrary::open_in_memory().expect("in memory");
        assert_eq!(mem.journal_mode().expect("pragma"), "memory");
    }

    #[test]
    fn data_survives_closing_and_reopening() {
        let (dir, mut lib) = file_library();
        let rec = sampled(ScenarioKind::LowFriction, 0, 0.625, true);
        lib.insert_batch(std::slice::from_ref(&rec)).expect("insert");
        let before = lib.rank(None, None).expect("rank");
        drop(lib);
        let lib = ScenarioLibrary::open(dir.path().join("library.db")).expect("reopen");
        assert_eq!(lib.rank(None, None).expect("rank"), before);
        assert_eq!(before.len(), 1);
        assert_eq!(lib.regression_set().expect("regression").len(), 1);
    }

    #[test]
    fn random_bytes_and_text_are_not_sqlite() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rng = Rng::new(99);
        let garbage: Vec<u8> = (0..8192).map(|_| rng.next_u64() as u8).collect();
        let text = b"kind,seed\ncut-in,1\n".repeat(200);
        for (name, bytes) in [("garbage.db", garbage), ("notes.db", text)] {
            let path = dir.path().join(name);
            std::fs::write(&path, &bytes).expect("write");
            match ScenarioLibrary::open(&path) {
                Err(LibraryError::NotSqlite { path: p, reason }) => {
                    assert_eq!(p, path);
                    assert!(reason.contains("not a database"), "{reason}");
                }
                other => panic!("{name}: expected NotSqlite, got {other:?}"),
            }
            assert_eq!(std::fs::read(&path).expect("read back"), bytes, "{name} must stay untouched");
        }
    }

    #[test]
    fn a_foreign_sqlite_database_is_refused_and_untouched() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("other.db");
        {
            let raw = Connection::open(&path).expect("raw");
            raw.execute_batch("CREATE TABLE invoices (n INTEGER); INSERT INTO invoices VALUES (1);").expect("ddl");
        }
        match ScenarioLibrary::open(&path) {
            Err(LibraryError::NotALibrary { path: p, reason }) => {
                assert_eq!(p, path);
                assert!(reason.contains("invoices"), "{reason}");
            }
            other => panic!("expected NotALibrary, got {other:?}"),
        }
        let raw = Connection::open(&path).expect("raw");
        let tables: i64 = raw.query_row("SELECT COUNT(*) FROM sqlite_schema", [], |r| r.get(0)).expect("count");
        assert_eq!(tables, 1, "no library table was created");
        let mode: String = raw.pragma_query_value(None, "journal_mode", |r| r.get(0)).expect("pragma");
        assert_eq!(mode, "delete", "journal mode left as it was");
    }

    /// Every object's SQL, by name: what makes two files the same schema.
    fn schema_of(conn: &Connection) -> Vec<(String, Option<String>)> {
        let mut stmt = conn.prepare("SELECT name, sql FROM sqlite_schema ORDER BY name").expect("schema");
        stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?))).expect("rows").collect::<Result<_, _>>().expect("read")
    }

    /// A version-1 file at `path` made of `ddl` (one batch) and that version's pragmas.
    fn version_1_file(path: &Path, ddl: &str) {
        let raw = Connection::open(path).expect("raw");
        raw.execute_batch(ddl).expect("the ddl");
        raw.pragma_update(None, "application_id", APPLICATION_ID).expect("app id");
        raw.pragma_update(None, "user_version", 1).expect("version");
    }

    #[test]
    fn a_version_1_file_is_upgraded_and_keeps_its_rows() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("v1.db");
        // A version-1 file as that build wrote it: its DDL, its pragmas, one scenario.
        version_1_file(&path, V1_DDL);
        let rec = sampled(ScenarioKind::CutIn, 0, 0.625, true);
        {
            // Write the row through a v1-shaped connection: the library would upgrade first.
            let raw = Connection::open(&path).expect("raw");
            raw.execute(
                "INSERT INTO scenarios VALUES (?1, 'cut-in', ?2, ?3, NULL, 0, 'sampled', 1)",
                rusqlite::params![
                    crate::library::content_id(&rec.spec),
                    rec.spec.seed as i64,
                    serde_json::to_string(&rec.spec.params).expect("params")
                ],
            )
            .expect("v1 row");
        }
        let lib = ScenarioLibrary::open(&path).expect("a version-1 file opens");
        let version: i64 = lib.conn.pragma_query_value(None, "user_version", |r| r.get(0)).expect("pragma");
        assert_eq!(version, SCHEMA_VERSION);
        let stored = lib.get(&crate::library::content_id(&rec.spec)).expect("get").expect("kept");
        assert_eq!(stored.spec, rec.spec);
        let (_fresh_dir, fresh) = file_library();
        assert_eq!(schema_of(&lib.conn), schema_of(&fresh.conn), "upgraded and new files have one schema");
        assert!(schema_of(&lib.conn).iter().any(|(name, _)| name == "recorded"));
        drop(lib);
        // Opening again runs nothing more.
        let again = ScenarioLibrary::open(&path).expect("reopen");
        assert_eq!(again.rank(None, None).expect("rank").len(), 0, "the v1 row has no outcome");
    }

    #[test]
    fn a_version_1_file_of_the_first_build_opens_and_is_upgraded() {
        // The first build's DDL laid the outcome columns out without the blank line that
        // `outcome_columns!` puts in front of them now: the same schema, other whitespace.
        let first_build = include_str!("testdata/v1_ddl_f57daa8.sql");
        assert!(!first_build.contains("REFERENCES scenarios(id),\n\n"), "the fixture is the old text");
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("v1-first.db");
        version_1_file(&path, first_build);
        let lib = ScenarioLibrary::open(&path).expect("a version-1 file of the first build opens");
        let version: i64 = lib.conn.pragma_query_value(None, "user_version", |r| r.get(0)).expect("pragma");
        assert_eq!(version, SCHEMA_VERSION);
        drop(lib);
        ScenarioLibrary::open(&path).expect("and opens again");
    }

    #[test]
    fn an_older_file_with_the_wrong_schema_is_refused_before_anything_is_written() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("v1-altered.db");
        // Version 1 by its pragmas, but `outcomes` rebuilt without its CHECKs.
        let altered = format!(
            "{V1_DDL} DROP TABLE outcomes; CREATE TABLE outcomes (seq INTEGER PRIMARY KEY, scenario_id TEXT);
             CREATE INDEX outcomes_latest ON outcomes(scenario_id, seq);"
        );
        version_1_file(&path, &altered);
        let before = std::fs::read(&path).expect("read");
        match ScenarioLibrary::open(&path) {
            Err(e @ LibraryError::WrongSchema { .. }) => assert!(e.to_string().contains("outcomes"), "{e}"),
            other => panic!("expected WrongSchema, got {other:?}"),
        }
        assert_eq!(std::fs::read(&path).expect("read back"), before, "no migration, no journal mode written");
        assert!(!dir.path().join("v1-altered.db-wal").exists());
    }

    #[test]
    fn a_version_2_file_is_upgraded_and_keeps_its_rows() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("v2.db");
        let rec = sampled(ScenarioKind::EmergencyBraking, 2, 0.5, true);
        let id = crate::library::content_id(&rec.spec);
        {
            // A version-2 file as that build wrote it: its DDL, its pragmas, a scenario with an
            // outcome, a regression mark and a recorded case.
            let raw = Connection::open(&path).expect("raw");
            raw.execute_batch(V1_DDL).expect("v1 ddl");
            raw.execute_batch(V2_DDL).expect("v2 ddl");
            raw.pragma_update(None, "application_id", APPLICATION_ID).expect("app id");
            raw.pragma_update(None, "user_version", 2).expect("version");
            raw.execute(
                "INSERT INTO scenarios VALUES (?1, 'emergency-braking', ?2, ?3, NULL, 0, 'sampled', 1)",
                rusqlite::params![id, rec.spec.seed as i64, serde_json::to_string(&rec.spec.params).expect("params")],
            )
            .expect("v2 scenario");
            raw.execute(
                "INSERT INTO outcomes VALUES (1, ?1, 'idm', 1, 0, 0, 0.5, 10.0, 0.1, 0.2, 0.4, 0.0, 0.9, -3.0, 80, \
                 0.5, 0.5, 0.25, 0.125, 0.0625, 1.0)",
                [&id],
            )
            .expect("v2 outcome");
            raw.execute("INSERT INTO regression VALUES (?1, 'collision', 1)", [&id]).expect("v2 mark");
            raw.execute("INSERT INTO recorded VALUES ('c1', 'commonroad', 'x.xml', 'X-1', 7, '<xml/>', 1)", [])
                .expect("v2 case");
        }
        let mut lib = ScenarioLibrary::open(&path).expect("a version-2 file opens");
        let version: i64 = lib.conn.pragma_query_value(None, "user_version", |r| r.get(0)).expect("pragma");
        assert_eq!(version, SCHEMA_VERSION);
        let (_fresh_dir, fresh) = file_library();
        assert_eq!(schema_of(&lib.conn), schema_of(&fresh.conn), "upgraded and new files have one schema");
        let ranked = lib.rank(None, None).expect("rank");
        assert_eq!((ranked.len(), ranked[0].id.as_str(), ranked[0].outcome.collision), (1, id.as_str(), true));
        assert_eq!(lib.regression_set().expect("regression").len(), 1);
        let cases: i64 = lib.conn.query_row("SELECT COUNT(*) FROM recorded", [], |r| r.get(0)).expect("count");
        assert_eq!(cases, 1);
        // The loop's tables work on the upgraded file.
        let (push, _) = lib.start_riskiest_push("s", "v1").expect("a push").expect("the one scenario");
        assert_eq!(lib.outstanding_pushes().expect("read"), [push]);
        assert_eq!(lib.riskiest_unpushed().expect("rank"), None);
    }

    #[test]
    fn a_newer_schema_is_refused() {
        let (dir, lib) = file_library();
        drop(lib);
        let path = dir.path().join("library.db");
        Connection::open(&path).expect("raw").pragma_update(None, "user_version", 99).expect("bump");
        match ScenarioLibrary::open(&path) {
            Err(LibraryError::UnsupportedVersion { found: 99, expected: SCHEMA_VERSION, .. }) => {}
            other => panic!("expected UnsupportedVersion, got {other:?}"),
        }
        let dir_as_file = ScenarioLibrary::open(dir.path());
        assert!(
            matches!(dir_as_file, Err(LibraryError::Open { .. } | LibraryError::NotSqlite { .. })),
            "{dir_as_file:?}"
        );
    }

    #[test]
    fn a_table_rebuilt_without_its_checks_or_an_extra_trigger_is_the_wrong_schema() {
        let cases = [
            (
                "CREATE TABLE o2 AS SELECT * FROM outcomes; DROP TABLE outcomes; ALTER TABLE o2 RENAME TO outcomes;",
                "outcomes",
            ),
            ("CREATE TRIGGER t AFTER INSERT ON outcomes BEGIN SELECT 1; END;", "trigger t"),
            ("DROP INDEX outcomes_latest;", "index outcomes_latest is missing"),
        ];
        for (sql, needle) in cases {
            let (dir, lib) = file_library();
            drop(lib);
            let path = dir.path().join("library.db");
            Connection::open(&path)
                .expect("raw")
                .execute_batch(&format!("PRAGMA foreign_keys = OFF; {sql}"))
                .expect("ddl");
            match ScenarioLibrary::open(&path) {
                Err(e @ LibraryError::WrongSchema { .. }) => {
                    assert!(e.to_string().contains(needle), "{sql}: {e}");
                    assert!(e.blames_the_file());
                }
                other => panic!("{sql}: expected WrongSchema, got {other:?}"),
            }
        }
    }
}
