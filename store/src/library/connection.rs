//! The open library: one SQLite connection and the file it lives in.

use super::error::LibraryError;
use super::schema;
use rusqlite::Connection;
use std::path::{Path, PathBuf};

/// An open scenario library (one SQLite connection; open one per thread or process).
#[derive(Debug)]
pub struct ScenarioLibrary {
    pub(super) conn: Connection,
    pub(super) path: PathBuf,
}

impl ScenarioLibrary {
    /// Opens the library at `path`, creating the file and its schema if it does not exist.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, LibraryError> {
        let path = path.as_ref().to_path_buf();
        let mut conn = Connection::open(&path).map_err(|source| LibraryError::Open { path: path.clone(), source })?;
        schema::prepare(&mut conn, &path)?;
        Ok(Self { conn, path })
    }

    /// Opens the library at `path`, which must exist (reading never creates one).
    pub fn open_existing(path: impl AsRef<Path>) -> Result<Self, LibraryError> {
        let path = path.as_ref();
        if !path.is_file() {
            return Err(LibraryError::Missing { path: path.to_path_buf() });
        }
        Self::open(path)
    }

    /// A fresh library that lives in memory only (tests, dry runs).
    pub fn open_in_memory() -> Result<Self, LibraryError> {
        let path = PathBuf::from(":memory:");
        let mut conn =
            Connection::open_in_memory().map_err(|source| LibraryError::Open { path: path.clone(), source })?;
        schema::prepare(&mut conn, &path)?;
        Ok(Self { conn, path })
    }

    /// The file this library lives in (`:memory:` for in-memory ones).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The journal mode SQLite reports: `wal` for files, `memory` for in-memory libraries.
    pub fn journal_mode(&self) -> Result<String, LibraryError> {
        Ok(self.conn.pragma_query_value(None, "journal_mode", |r| r.get(0))?)
    }
}
