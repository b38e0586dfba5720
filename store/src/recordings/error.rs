//! Why a recordings folder could not be opened, written or read.

use crate::sqlite_schema::blames_sqlite_file;
use risktwin_protos::recording::RecordingError;
use std::path::PathBuf;

/// Why the catalogue failed.
#[derive(Debug, thiserror::Error)]
pub enum CatalogueError {
    #[error("{}: not a folder", dir.display())]
    NotAFolder { dir: PathBuf },
    #[error("cannot create the recordings folder {}: {source}", dir.display())]
    Folder { dir: PathBuf, source: std::io::Error },
    #[error("{}: no recordings catalogue (catalogue.db) in this folder", dir.display())]
    Missing { dir: PathBuf },
    #[error("{} is not a SQLite database: {reason}", path.display())]
    NotSqlite { path: PathBuf, reason: String },
    #[error("{} is not a RiskTwin recordings catalogue: {reason}", path.display())]
    NotACatalogue { path: PathBuf, reason: String },
    #[error("{}: catalogue schema version {found} is not supported (this build reads version {expected})", path.display())]
    UnsupportedVersion { path: PathBuf, found: i64, expected: i64 },
    #[error("{} is a recordings catalogue with the wrong schema: {reason}", path.display())]
    WrongSchema { path: PathBuf, reason: String },
    #[error("{}: segment {seq}: {reason}", path.display())]
    BadRow { path: PathBuf, seq: i64, reason: String },
    #[error("{}: {value} does not fit a signed 64-bit SQLite integer", path.display())]
    OutOfRange { path: PathBuf, value: u64 },
    #[error("recordings catalogue {}: {source}", path.display())]
    Sqlite { path: PathBuf, source: rusqlite::Error },
}

impl CatalogueError {
    /// Segment `seq` is in the catalogue at `path` already.
    pub(super) fn already_catalogued(path: &std::path::Path, seq: u64) -> Self {
        let reason = format!("segment {seq} is already catalogued (another recorder in this folder?)");
        CatalogueError::BadRow { path: path.to_path_buf(), seq: seq as i64, reason }
    }

    pub(super) fn sqlite(path: &std::path::Path, source: rusqlite::Error) -> Self {
        if crate::sqlite_schema::not_a_database(&source) {
            return CatalogueError::NotSqlite { path: path.to_path_buf(), reason: source.to_string() };
        }
        CatalogueError::Sqlite { path: path.to_path_buf(), source }
    }

    /// Whether the error lies in the folder or the file given (exit 2) rather than in the run
    /// (a lock held too long, a full disk: exit 1).
    pub fn blames_the_input(&self) -> bool {
        match self {
            CatalogueError::Folder { .. } | CatalogueError::OutOfRange { .. } => false,
            CatalogueError::Sqlite { source, .. } => blames_sqlite_file(source),
            _ => true,
        }
    }
}

/// Why a rotating recording failed.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    #[error(transparent)]
    Catalogue(#[from] CatalogueError),
    #[error("recording: {0}")]
    Recording(#[from] RecordingError),
    #[error("segment {}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("recordings: the segment keeper thread stopped")]
    KeeperGone,
}
