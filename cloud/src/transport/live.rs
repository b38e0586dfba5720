//! The ingest role on the live Zenoh receive path: every sample goes through an
//! [`IngestWorker`] (decode → validate → exactly-once → clock mapping → alignment → recording),
//! stamped with the cloud's clock; per-source, per-stream acceptance counts and the snapshot
//! digest are kept for the summary.

use crate::ingest::{IngestStats, IngestWorker, SnapshotDigest, Stream};
use risktwin_common::align::IngestConfig;
use risktwin_protos::recording::{Recorder, RecordingError};
use risktwin_transport::EdgeStream;
use risktwin_transport::keyexpr::parse_edge_key;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::{Instant, SystemTime, UNIX_EPOCH};
use thiserror::Error;

const STREAMS: usize = EdgeStream::ALL.len();

/// Where a recording goes: buffered, since the recorder writes many small records.
pub type RecordingFile = BufWriter<File>;

/// What the ingest saw, as printed in the cloud's JSON summary.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
pub struct IngestSummary {
    /// Accepted messages per source, per stream (streams with none are left out).
    pub received: BTreeMap<String, BTreeMap<String, u64>>,
    /// Dropped messages per reason: the worker's codes, plus `bad_key` from the transport.
    pub dropped: BTreeMap<String, u64>,
    /// All accepted messages.
    pub total_received: u64,
    /// All dropped messages.
    pub total_dropped: u64,
    /// Messages written to the recording (equals `total_received` when recording).
    pub recorded: u64,
    /// Snapshots the aligner emitted.
    pub snapshots: u64,
    /// FNV-1a digest of every emitted snapshot (tick, statuses, pose bits), 16 hex digits.
    pub snapshot_digest: String,
}

/// Why the recording failed.
#[derive(Debug, Error)]
pub enum RecordError {
    #[error("creating the recording {path}: {source}")]
    Create { path: String, source: std::io::Error },
    #[error("recording: {0}")]
    Recording(#[from] RecordingError),
    #[error("flushing the recording: {0}")]
    Flush(std::io::Error),
}

/// The worker and the counts around it; lives behind a mutex shared with the Zenoh callback.
pub(crate) struct LiveIngest {
    worker: IngestWorker<RecordingFile>,
    received: HashMap<String, [u64; STREAMS]>,
    bad_key: u64,
    digest: SnapshotDigest,
    last_receive_ns: i64,
    last_sample: Option<Instant>,
    replay_time: bool,
    no_replay_time: u64,
}

impl LiveIngest {
    /// A worker recording into a new file at `record` when given.
    /// With `replay_time`, receive times come from the messages' replay-time attachments.
    pub(crate) fn new(record: Option<&Path>, replay_time: bool) -> Result<Self, RecordError> {
        let recorder = match record {
            Some(path) => {
                let file = File::create(path)
                    .map_err(|source| RecordError::Create { path: path.display().to_string(), source })?;
                Some(Recorder::new(BufWriter::new(file))?)
            }
            None => None,
        };
        Ok(LiveIngest {
            worker: IngestWorker::new(IngestConfig::default(), recorder),
            received: HashMap::new(),
            bad_key: 0,
            digest: SnapshotDigest::default(),
            last_receive_ns: i64::MIN,
            last_sample: None,
            replay_time,
            no_replay_time: 0,
        })
    }

    /// Handles one sample received on `key`; the receive time is read here, once, from the
    /// system clock and never goes backwards (the aligner needs non-decreasing receive times).
    /// `replay_ns` is the message's replay-time attachment, used instead of the clock in
    /// replay-time mode (and required there).
    pub(crate) fn handle(&mut self, key: &str, payload: &[u8], replay_ns: Option<i64>) -> Result<(), RecordingError> {
        let now = Instant::now();
        self.last_sample = Some(now);
        let wall_ns = match (self.replay_time, replay_ns) {
            (false, _) => SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as i64),
            (true, Some(t)) => t,
            (true, None) => {
                self.no_replay_time += 1;
                return Ok(());
            }
        };
        let receive_ns = wall_ns.max(self.last_receive_ns);
        self.last_receive_ns = receive_ns;
        let Some(parsed) = parse_edge_key(key) else {
            self.bad_key += 1;
            return Ok(());
        };
        let stream = match Stream::from_name(parsed.stream.as_str()) {
            Some(s) => s,
            None => {
                self.bad_key += 1;
                return Ok(());
            }
        };
        let accepted_before = self.worker.stats().accepted;
        let digest = &mut self.digest;
        self.worker.handle(parsed.source, stream, key, payload, receive_ns, |s| digest.add(s))?;
        if self.worker.stats().accepted > accepted_before {
            // Look up by &str first so that a known source costs no allocation.
            let counts = match self.received.get_mut(parsed.source) {
                Some(c) => c,
                None => self.received.entry(parsed.source.to_owned()).or_default(),
            };
            counts[parsed.stream.index()] += 1;
        }
        Ok(())
    }

    /// When the last sample (accepted or not) arrived.
    pub(crate) fn last_sample(&self) -> Option<Instant> {
        self.last_sample
    }

    /// Closes the recording (so the file is a valid MCAP) and returns the summary.
    pub(crate) fn finish(self) -> Result<IngestSummary, RecordError> {
        let (stats, writer) = self.worker.finish()?;
        if let Some(mut w) = writer {
            w.flush().map_err(RecordError::Flush)?;
        }
        let mut summary = summarize(&stats, &self.received, self.bad_key, &self.digest);
        if self.no_replay_time > 0 {
            summary.dropped.insert("no-replay-time".to_owned(), self.no_replay_time);
            summary.total_dropped += self.no_replay_time;
        }
        Ok(summary)
    }
}

fn summarize(
    stats: &IngestStats,
    received: &HashMap<String, [u64; STREAMS]>,
    bad_key: u64,
    digest: &SnapshotDigest,
) -> IngestSummary {
    let mut summary = IngestSummary {
        dropped: stats.dropped.clone(),
        total_received: stats.accepted,
        recorded: stats.recorded,
        snapshots: stats.snapshots,
        snapshot_digest: digest.hex(),
        ..IngestSummary::default()
    };
    if bad_key > 0 {
        *summary.dropped.entry("bad_key".to_owned()).or_default() += bad_key;
    }
    summary.total_dropped = summary.dropped.values().sum();
    for (source, counts) in received {
        let per_stream = EdgeStream::ALL
            .iter()
            .zip(counts)
            .filter(|(_, n)| **n > 0)
            .map(|(s, n)| (s.as_str().to_owned(), *n))
            .collect();
        summary.received.insert(source.clone(), per_stream);
    }
    summary
}
