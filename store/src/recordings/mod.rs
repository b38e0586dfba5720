//! Rotating recordings with a catalogue (docs/recordings.md): a recording kept as MCAP segments
//! in one folder, each finished (footer, summary) when the next opens, closed by size or age;
//! a SQLite catalogue in the folder of the segments (time range, counts per source and stream,
//! bytes, closed or not) and of how each recording was made; retention by age or total size.
//!
//! # Catalogue (`catalogue.db`, schema version 1; tables `STRICT`)
//! Marked `PRAGMA application_id = 0x52545743` ("RTWC"), versioned by `PRAGMA user_version`.
//! - `recordings(id, started_unix_ns, risktwin_version, git_commit, config JSON)`.
//! - `segments(seq PK, recording_id, file UNIQUE, opened_unix_ns, closed 0/1, closed_unix_ns,
//!   start_log_ns, end_log_ns, messages, bytes)`: the last five are NULL until closed (times
//!   NULL too for a segment without messages).
//! - `segment_streams(seq, topic, schema, source, stream, messages)`, primary key (seq, topic):
//!   source and stream are those of an edge key, NULL for other topics (the twin's outputs).
//!
//! A file that is not SQLite, another database, another version or a schema altered in any way
//! is refused and never written to; so is a row naming a file outside the folder.

mod catalogue;
mod config;
mod error;
mod keeper;
mod rotation;

pub use catalogue::{
    APPLICATION_ID, CATALOGUE_FILE, Catalogue, Provenance, RecordingRow, SCHEMA_VERSION, SegmentRow, StreamRow,
    is_segment_name,
};
pub use config::{RotationConfig, SegmentsSummary};
pub use error::{CatalogueError, SegmentError};
pub use rotation::{Segments, segment_name, utc_stamp};

#[cfg(test)]
mod tests;
