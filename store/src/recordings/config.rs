//! What a rotating recording is told and what it tells: plain data shared by the writer
//! ([`super::Segments`]) and its keeper thread.

use super::catalogue::Provenance;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Duration;

/// How a rotating recording is kept.
#[derive(Debug, Clone, PartialEq)]
pub struct RotationConfig {
    pub dir: PathBuf,
    /// A segment closes once its file reaches this size...
    pub segment_bytes: u64,
    /// ...or this age.
    pub segment_age: Duration,
    /// Closed segments closed longer ago than this are deleted.
    pub retain_age: Option<Duration>,
    /// The oldest closed segments are deleted while the folder's segments hold more than this.
    pub retain_bytes: Option<u64>,
    pub provenance: Provenance,
}

/// What a rotating recording did, as the cloud's summary reports it.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct SegmentsSummary {
    pub dir: String,
    pub recording_id: i64,
    pub segments_opened: u64,
    pub segments_closed: u64,
    /// Segments deleted by retention (of this recording or older ones in the folder).
    pub segments_deleted: u64,
    /// Messages in the segments this recording closed.
    pub messages: u64,
    /// Bytes of the segments this recording closed.
    pub bytes_written: u64,
    pub bytes_deleted: u64,
}
