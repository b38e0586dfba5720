//! The catalogue of a recordings folder: one SQLite file (`catalogue.db`) with the recordings
//! (how each was made), their segments (time range, counts, bytes, closed or not) and each
//! segment's messages per topic (source and stream where the topic is an edge key).

use super::error::CatalogueError;
use crate::sqlite_schema::schema_difference;
use risktwin_protos::recording::SegmentStats;
use risktwin_transport::keyexpr::parse_edge_key;
use rusqlite::{Connection, OpenFlags, OptionalExtension, Row, TransactionBehavior, params};
use serde::Serialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The catalogue's file name in its folder.
pub const CATALOGUE_FILE: &str = "catalogue.db";
/// `PRAGMA application_id` of a catalogue: "RTWC" in ASCII.
pub const APPLICATION_ID: i32 = 0x5254_5743;
/// `PRAGMA user_version`: bumped whenever the tables change.
pub const SCHEMA_VERSION: i64 = 1;
/// How long a connection waits for the other's lock (the cloud writes while the CLI reads).
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

const V1_DDL: &str = "
CREATE TABLE recordings (
    id INTEGER PRIMARY KEY,
    started_unix_ns INTEGER NOT NULL,
    risktwin_version TEXT NOT NULL,
    git_commit TEXT NOT NULL,
    config TEXT NOT NULL CHECK (json_valid(config))
) STRICT;
CREATE TABLE segments (
    seq INTEGER PRIMARY KEY CHECK (seq >= 1),
    recording_id INTEGER NOT NULL REFERENCES recordings(id),
    file TEXT NOT NULL UNIQUE,
    opened_unix_ns INTEGER NOT NULL,
    closed INTEGER NOT NULL DEFAULT 0 CHECK (closed IN (0, 1)),
    closed_unix_ns INTEGER,
    start_log_ns INTEGER CHECK (start_log_ns >= 0),
    end_log_ns INTEGER CHECK (end_log_ns >= start_log_ns),
    messages INTEGER CHECK (messages >= 0),
    bytes INTEGER CHECK (bytes >= 0),
    CHECK (closed = 0 OR (closed_unix_ns IS NOT NULL AND messages IS NOT NULL AND bytes IS NOT NULL)),
    CHECK ((start_log_ns IS NULL) = (end_log_ns IS NULL))
) STRICT;
CREATE TABLE segment_streams (
    seq INTEGER NOT NULL REFERENCES segments(seq) ON DELETE CASCADE,
    topic TEXT NOT NULL,
    schema TEXT NOT NULL,
    source TEXT,
    stream TEXT,
    messages INTEGER NOT NULL CHECK (messages >= 0),
    PRIMARY KEY (seq, topic)
) STRICT;
CREATE INDEX segment_streams_source ON segment_streams(source);
";

/// How a recording was made.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Provenance {
    pub risktwin_version: String,
    pub git_commit: String,
    /// The recorder's configuration as a JSON document (the cloud's flags).
    pub config: String,
}

/// One recording of the catalogue.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RecordingRow {
    pub id: i64,
    pub started_unix_ns: i64,
    #[serde(flatten)]
    pub provenance: Provenance,
}

/// One segment of the catalogue; counts, bytes and times are `None` until it is closed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SegmentRow {
    pub seq: u64,
    pub recording_id: i64,
    pub file: String,
    pub opened_unix_ns: i64,
    pub closed: bool,
    pub closed_unix_ns: Option<i64>,
    pub start_log_ns: Option<u64>,
    pub end_log_ns: Option<u64>,
    pub messages: Option<u64>,
    pub bytes: Option<u64>,
}

/// Messages on one topic of a segment.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct StreamRow {
    pub topic: String,
    pub schema: String,
    /// The edge source and stream when the topic is an edge key.
    pub source: Option<String>,
    pub stream: Option<String>,
    pub messages: u64,
}

/// An open catalogue.
#[derive(Debug)]
pub struct Catalogue {
    conn: Connection,
    path: PathBuf,
}

impl Catalogue {
    /// The catalogue of `dir`, created (folder included) when missing: the recorder's.
    pub fn create(dir: &Path) -> Result<Self, CatalogueError> {
        if dir.exists() && !dir.is_dir() {
            return Err(CatalogueError::NotAFolder { dir: dir.to_path_buf() });
        }
        std::fs::create_dir_all(dir).map_err(|source| CatalogueError::Folder { dir: dir.to_path_buf(), source })?;
        Self::open_with(&dir.join(CATALOGUE_FILE), OpenFlags::default())
    }

    /// The existing catalogue of `dir`: the readers'.
    pub fn open(dir: &Path) -> Result<Self, CatalogueError> {
        if !dir.is_dir() {
            return Err(CatalogueError::NotAFolder { dir: dir.to_path_buf() });
        }
        let path = dir.join(CATALOGUE_FILE);
        if !path.is_file() {
            return Err(CatalogueError::Missing { dir: dir.to_path_buf() });
        }
        Self::open_with(&path, OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_NO_MUTEX)
    }

    fn open_with(path: &Path, flags: OpenFlags) -> Result<Self, CatalogueError> {
        let sqlite = |e| CatalogueError::sqlite(path, e);
        let conn = Connection::open_with_flags(path, flags).map_err(sqlite)?;
        let mut catalogue = Self { conn, path: path.to_path_buf() };
        catalogue.prepare()?;
        Ok(catalogue)
    }

    /// Checks that the file is empty or a catalogue of this version (nothing is written to any
    /// other), creates the schema in an empty one, and sets the connection up.
    fn prepare(&mut self) -> Result<(), CatalogueError> {
        let path = self.path.clone();
        let sqlite = |e| CatalogueError::sqlite(&path, e);
        let app_id: i32 = self.conn.pragma_query_value(None, "application_id", |r| r.get(0)).map_err(sqlite)?;
        let version: i64 = self.conn.pragma_query_value(None, "user_version", |r| r.get(0)).map_err(sqlite)?;
        let objects: i64 =
            self.conn.query_row("SELECT count(*) FROM sqlite_schema", [], |r| r.get(0)).map_err(sqlite)?;
        if app_id == APPLICATION_ID && version != SCHEMA_VERSION {
            return Err(CatalogueError::UnsupportedVersion { path, found: version, expected: SCHEMA_VERSION });
        }
        if app_id != APPLICATION_ID && (app_id != 0 || version != 0 || objects > 0) {
            let reason = format!("application_id is {app_id:#x} (expected {APPLICATION_ID:#x}), {objects} objects");
            return Err(CatalogueError::NotACatalogue { path, reason });
        }
        self.conn.busy_timeout(BUSY_TIMEOUT).map_err(sqlite)?;
        let _mode: String =
            self.conn.pragma_update_and_check(None, "journal_mode", "WAL", |r| r.get(0)).map_err(sqlite)?;
        self.conn.pragma_update(None, "synchronous", "NORMAL").map_err(sqlite)?;
        self.conn.pragma_update(None, "foreign_keys", true).map_err(sqlite)?;
        if app_id == 0 {
            let tx = self.conn.transaction_with_behavior(TransactionBehavior::Immediate).map_err(sqlite)?;
            // A second look under the lock: two recorders creating one catalogue run the DDL once.
            let now: i32 = tx.pragma_query_value(None, "application_id", |r| r.get(0)).map_err(sqlite)?;
            if now == 0 {
                tx.execute_batch(V1_DDL).map_err(sqlite)?;
                tx.pragma_update(None, "application_id", APPLICATION_ID).map_err(sqlite)?;
                tx.pragma_update(None, "user_version", SCHEMA_VERSION).map_err(sqlite)?;
            }
            tx.commit().map_err(sqlite)?;
        }
        if let Some(reason) = schema_difference(&self.conn, &[V1_DDL], "a catalogue").map_err(sqlite)? {
            return Err(CatalogueError::WrongSchema { path, reason });
        }
        Ok(())
    }

    /// Adds a recording; its id.
    pub fn add_recording(&self, started_unix_ns: i64, provenance: &Provenance) -> Result<i64, CatalogueError> {
        self.conn
            .execute(
                "INSERT INTO recordings (started_unix_ns, risktwin_version, git_commit, config) VALUES (?1, ?2, ?3, ?4)",
                params![started_unix_ns, provenance.risktwin_version, provenance.git_commit, provenance.config],
            )
            .map_err(|e| self.error(e))?;
        Ok(self.conn.last_insert_rowid())
    }

    /// The number the next segment takes: one above every segment ever catalogued here.
    pub fn next_seq(&self) -> Result<u64, CatalogueError> {
        let last: Option<i64> =
            self.conn.query_row("SELECT max(seq) FROM segments", [], |r| r.get(0)).map_err(|e| self.error(e))?;
        Ok(last.map_or(1, |s| s as u64 + 1))
    }

    /// Catalogues a segment as it is opened (not closed: a crash leaves it so).
    pub fn open_segment(
        &self,
        recording_id: i64,
        seq: u64,
        file: &str,
        opened_unix_ns: i64,
    ) -> Result<(), CatalogueError> {
        self.conn
            .execute(
                "INSERT INTO segments (seq, recording_id, file, opened_unix_ns) VALUES (?1, ?2, ?3, ?4)",
                params![seq as i64, recording_id, file, opened_unix_ns],
            )
            .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// Marks segment `seq` closed with what its file holds, in one transaction.
    pub fn close_segment(
        &mut self,
        seq: u64,
        stats: &SegmentStats,
        bytes: u64,
        closed_unix_ns: i64,
    ) -> Result<(), CatalogueError> {
        let path = self.path.clone();
        let sqlite = |e| CatalogueError::sqlite(&path, e);
        let signed = |v: u64| i64::try_from(v).map_err(|_| CatalogueError::OutOfRange { path: path.clone(), value: v });
        let (start, end) = match stats.log_time_ns {
            Some((start, end)) => (Some(signed(start)?), Some(signed(end)?)),
            None => (None, None),
        };
        let tx = self.conn.transaction().map_err(sqlite)?;
        tx.execute(
            "UPDATE segments SET closed = 1, closed_unix_ns = ?2, start_log_ns = ?3, end_log_ns = ?4, messages = ?5,
             bytes = ?6 WHERE seq = ?1",
            params![seq as i64, closed_unix_ns, start, end, signed(stats.messages)?, signed(bytes)?],
        )
        .map_err(sqlite)?;
        for t in &stats.topics {
            let key = parse_edge_key(&t.topic);
            tx.execute(
                "INSERT INTO segment_streams (seq, topic, schema, source, stream, messages) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                params![
                    seq as i64,
                    t.topic,
                    t.schema_name,
                    key.as_ref().map(|k| k.source),
                    key.as_ref().map(|k| k.stream.as_str()),
                    signed(t.messages)?
                ],
            )
            .map_err(sqlite)?;
        }
        tx.commit().map_err(sqlite)
    }

    /// Every recording, oldest first.
    pub fn recordings(&self) -> Result<Vec<RecordingRow>, CatalogueError> {
        let sql = "SELECT id, started_unix_ns, risktwin_version, git_commit, config FROM recordings ORDER BY id";
        let mut stmt = self.conn.prepare(sql).map_err(|e| self.error(e))?;
        let rows = stmt.query_map([], |r| {
            let provenance = Provenance { risktwin_version: r.get(2)?, git_commit: r.get(3)?, config: r.get(4)? };
            Ok(RecordingRow { id: r.get(0)?, started_unix_ns: r.get(1)?, provenance })
        });
        rows.and_then(Iterator::collect).map_err(|e| self.error(e))
    }

    /// The segments, in order, that may hold messages of `source` (every source when `None`)
    /// with a log time in `log_time_ns`: closed ones by their time range and streams,
    /// unfinished ones always (what they hold is known only by reading them).
    pub fn segments(&self, source: Option<&str>, log_time_ns: Range<u64>) -> Result<Vec<SegmentRow>, CatalogueError> {
        let clamp = |v: u64| i64::try_from(v).unwrap_or(i64::MAX);
        let filter = "WHERE closed = 0 OR (start_log_ns < ?2 AND end_log_ns >= ?1 AND (?3 IS NULL OR EXISTS
                      (SELECT 1 FROM segment_streams AS t WHERE t.seq = s.seq AND t.source = ?3)))";
        self.select(filter, params![clamp(log_time_ns.start), clamp(log_time_ns.end), source])
    }

    /// Every segment, in order.
    pub fn all_segments(&self) -> Result<Vec<SegmentRow>, CatalogueError> {
        self.select("", params![])
    }

    fn select(&self, filter: &str, values: &[&dyn rusqlite::ToSql]) -> Result<Vec<SegmentRow>, CatalogueError> {
        let sql = format!(
            "SELECT seq, recording_id, file, opened_unix_ns, closed, closed_unix_ns, start_log_ns, end_log_ns,
             messages, bytes FROM segments AS s {filter} ORDER BY seq"
        );
        let mut stmt = self.conn.prepare(&sql).map_err(|e| self.error(e))?;
        let rows = stmt
            .query_map(values, segment_row)
            .and_then(Iterator::collect::<Result<Vec<_>, _>>)
            .map_err(|e| self.error(e))?;
        rows.into_iter().map(|row| row.map_err(|reason| self.bad_row(reason))).collect()
    }

    /// What segment `seq` holds per topic (nothing until it is closed).
    pub fn streams(&self, seq: u64) -> Result<Vec<StreamRow>, CatalogueError> {
        let sql = "SELECT topic, schema, source, stream, messages FROM segment_streams WHERE seq = ?1 ORDER BY topic";
        let mut stmt = self.conn.prepare(sql).map_err(|e| self.error(e))?;
        let rows = stmt.query_map([seq as i64], |r| {
            let messages: i64 = r.get(4)?;
            Ok(StreamRow {
                topic: r.get(0)?,
                schema: r.get(1)?,
                source: r.get(2)?,
                stream: r.get(3)?,
                messages: messages.max(0) as u64,
            })
        });
        rows.and_then(Iterator::collect).map_err(|e| self.error(e))
    }

    /// Removes segment `seq`'s rows (its file is the caller's).
    pub fn delete_segment(&self, seq: u64) -> Result<(), CatalogueError> {
        self.conn.execute("DELETE FROM segments WHERE seq = ?1", [seq as i64]).map_err(|e| self.error(e))?;
        Ok(())
    }

    /// Whether segment `seq` is catalogued.
    pub fn has_segment(&self, seq: u64) -> Result<bool, CatalogueError> {
        let found = self
            .conn
            .query_row("SELECT 1 FROM segments WHERE seq = ?1", [seq as i64], |_| Ok(()))
            .optional()
            .map_err(|e| self.error(e))?;
        Ok(found.is_some())
    }

    /// The file the catalogue lives in.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn error(&self, e: rusqlite::Error) -> CatalogueError {
        CatalogueError::sqlite(&self.path, e)
    }

    fn bad_row(&self, (seq, reason): (i64, String)) -> CatalogueError {
        CatalogueError::BadRow { path: self.path.clone(), seq, reason }
    }
}

/// A segment's row, or why it is not one this build writes (its number and the reason).
fn segment_row(r: &Row<'_>) -> rusqlite::Result<Result<SegmentRow, (i64, String)>> {
    let seq: i64 = r.get(0)?;
    let file: String = r.get(2)?;
    let unsigned = |v: Option<i64>| v.map(|v| v.max(0) as u64);
    // The file is joined to the folder and may be deleted by retention: a plain segment name only.
    if !is_segment_name(&file) {
        return Ok(Err((seq, format!("file {file:?} is not a segment file name (seg-NNNNNN-….mcap)"))));
    }
    Ok(Ok(SegmentRow {
        seq: seq.max(0) as u64,
        recording_id: r.get(1)?,
        file,
        opened_unix_ns: r.get(3)?,
        closed: r.get::<_, i64>(4)? == 1,
        closed_unix_ns: r.get(5)?,
        start_log_ns: unsigned(r.get(6)?),
        end_log_ns: unsigned(r.get(7)?),
        messages: unsigned(r.get(8)?),
        bytes: unsigned(r.get(9)?),
    }))
}

/// Whether `name` is a segment file's name: `seg-`, digits, `-`, a stamp, `.mcap`, nothing that
/// leaves the folder.
pub fn is_segment_name(name: &str) -> bool {
    name.starts_with("seg-")
        && name.ends_with(".mcap")
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'.')
        && !name.contains("..")
}
