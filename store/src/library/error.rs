//! Errors of the scenario library: opening a file, validating a record, reading rows back.

use risktwin_common::scenario::{ScenarioKind, SpecError};
use std::path::PathBuf;

/// Why a library operation failed.
#[derive(Debug, thiserror::Error)]
pub enum LibraryError {
    #[error("no scenario library at {}", path.display())]
    Missing { path: PathBuf },
    #[error("cannot open scenario library {}: {source}", path.display())]
    Open { path: PathBuf, source: rusqlite::Error },
    #[error("{} is not a SQLite database: {reason}", path.display())]
    NotSqlite { path: PathBuf, reason: String },
    #[error("{} is not a RiskTwin scenario library: {reason}", path.display())]
    NotALibrary { path: PathBuf, reason: String },
    #[error("{}: scenario library schema version {found} is not supported (this build reads version {expected})", path.display())]
    UnsupportedVersion { path: PathBuf, found: i64, expected: i64 },
    #[error("invalid record for scenario {id}: {source}")]
    InvalidRecord { id: String, source: RecordError },
    #[error("unknown scenario '{0}'")]
    UnknownScenario(String),
    #[error("stored scenario {id} is corrupt: {reason}")]
    Corrupt { id: String, reason: String },
    #[error("library {}: row id {row}: {table}: {reason}", path.display())]
    BadRow { path: PathBuf, table: &'static str, row: String, reason: String },
    #[error("{} is a RiskTwin scenario library with the wrong schema: {reason}", path.display())]
    WrongSchema { path: PathBuf, reason: String },
    #[error("scenario library database error: {0}")]
    Sqlite(#[from] rusqlite::Error),
}

impl LibraryError {
    /// Whether the error lies in the file (not SQLite, not a library, a schema or a row that
    /// this build never writes, a damaged page, a stored value of the wrong type) rather than in
    /// the run (I/O, a lock held too long): the CLI's bad input (exit 2) against a runtime
    /// failure (exit 1).
    pub fn blames_the_file(&self) -> bool {
        match self {
            LibraryError::Missing { .. }
            | LibraryError::NotSqlite { .. }
            | LibraryError::NotALibrary { .. }
            | LibraryError::UnsupportedVersion { .. }
            | LibraryError::Corrupt { .. }
            | LibraryError::BadRow { .. }
            | LibraryError::WrongSchema { .. } => true,
            LibraryError::Open { source: e, .. } | LibraryError::Sqlite(e) => {
                crate::sqlite_schema::blames_sqlite_file(e)
            }
            LibraryError::InvalidRecord { .. } | LibraryError::UnknownScenario(_) => false,
        }
    }
}

/// What is wrong with a record offered to the library (checked before anything is written).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RecordError {
    #[error(transparent)]
    Spec(#[from] SpecError),
    #[error("{field} = {value} is not a finite number")]
    NotFinite { field: &'static str, value: f64 },
    #[error("{field} = {value} is out of range [{min}, {max}]")]
    OutOfRange { field: &'static str, value: f64, min: f64, max: f64 },
    #[error("steps = {0} does not fit a signed 64-bit SQLite integer")]
    StepsTooLarge(u64),
    #[error("policy name is empty")]
    EmptyPolicy,
    #[error("a {origin} scenario {expectation}")]
    Lineage { origin: &'static str, expectation: &'static str },
    #[error("recorded case from '{0}' has no scenario text")]
    EmptyScenario(String),
    #[error("parent '{0}' is not in the library")]
    UnknownParent(String),
    #[error("parent is a {parent} scenario, the child a {child} one: mutation keeps the kind")]
    KindChanged { parent: ScenarioKind, child: ScenarioKind },
}
