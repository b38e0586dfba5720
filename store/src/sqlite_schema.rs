//! What the SQLite files of RiskTwin (the scenario library, the recordings catalogue) share when
//! they are opened: telling "not SQLite" from other errors, and comparing a file's tables and
//! indexes with those its migrations make.

use rusqlite::{Connection, ErrorCode};

/// Whether SQLite's error says the file is not a database (or a damaged one).
pub(crate) fn not_a_database(err: &rusqlite::Error) -> bool {
    matches!(err.sqlite_error_code(), Some(ErrorCode::NotADatabase | ErrorCode::DatabaseCorrupt))
}

/// Every table's and index's SQL, by name, as SQLite keeps it.
fn objects_of(conn: &Connection) -> rusqlite::Result<Vec<(String, String, Option<String>)>> {
    let mut stmt =
        conn.prepare("SELECT type, name, sql FROM sqlite_schema WHERE name NOT LIKE 'sqlite_%' ORDER BY type, name")?;
    let rows = stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?;
    rows.collect()
}

/// A statement's SQL with every run of whitespace made one space: SQLite keeps a `CREATE` as
/// it was written, and builds that laid the same DDL out differently wrote the same schema.
fn normalised(sql: &str) -> String {
    sql.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Whether `err` blames the file: not a database, or a value of a type or range it should not hold.
pub(crate) fn blames_sqlite_file(err: &rusqlite::Error) -> bool {
    not_a_database(err)
        || matches!(
            err,
            rusqlite::Error::InvalidColumnType(..)
                | rusqlite::Error::FromSqlConversionFailure(..)
                | rusqlite::Error::IntegralValueOutOfRange(..)
        )
}

/// How `conn`'s tables and indexes differ from those `migrations` make in an empty in-memory
/// database, to the letter (whitespace aside): `Ok(None)` when they are the same. The CHECKs
/// and NOT NULLs are what keep rows in range, so a table rebuilt without them (or an extra
/// trigger that rewrites rows) is not a file a RiskTwin build wrote. `what` names the file's
/// kind ("a library"). An error is the file's (reading it failed).
pub(crate) fn schema_difference(
    conn: &Connection,
    migrations: &[&str],
    what: &str,
) -> rusqlite::Result<Option<String>> {
    let expected = {
        let reference = Connection::open_in_memory()?;
        for ddl in migrations {
            reference.execute_batch(ddl)?;
        }
        objects_of(&reference)?
    };
    let found = objects_of(conn)?;
    for (kind, name, sql) in &expected {
        match found.iter().find(|(k, n, _)| k == kind && n == name) {
            None => return Ok(Some(format!("{kind} {name} is missing"))),
            Some((_, _, s)) if s.as_deref().map(normalised) != sql.as_deref().map(normalised) => {
                return Ok(Some(format!("{kind} {name} is not defined as this build defines it")));
            }
            Some(_) => {}
        }
    }
    let extra = found.iter().find(|(k, n, _)| !expected.iter().any(|(ek, en, _)| ek == k && en == n));
    Ok(extra.map(|(kind, name, _)| format!("{kind} {name} is not part of {what}")))
}
