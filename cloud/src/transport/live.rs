//! The ingest role on the live Zenoh receive path: every sample goes through an
//! [`IngestWorker`] (decode → validate → exactly-once → clock mapping → alignment), stamped with
//! the cloud's clock; accepted messages are recorded byte for byte; per-source, per-stream
//! acceptance counts and the snapshot digest are kept for the summary. With the twin role on,
//! every snapshot updates the [`TwinOutputs`], whose risk and scene outputs go into the same
//! recording.
//!
//! The recorder is held here rather than inside the worker so that the twin's outputs can be
//! written into the same file; the worker is built without one. Its publish stamp is read from
//! the accepted payload's header alone (field 1 of every `risktwin.v1` stream message).

use super::outputs::TwinOutputs;
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
    /// Accepted messages that arrived after the snapshot of their time was emitted (beyond the
    /// allowed lateness); `late_dropped` of them were of no use to any later snapshot either.
    pub late: u64,
    /// Late messages the twin never saw (still received and recorded).
    pub late_dropped: u64,
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

/// The header of any `risktwin.v1` stream message, decoded alone (prost skips the rest).
#[derive(Clone, PartialEq, prost::Message)]
struct HeaderOnly {
    #[prost(message, optional, tag = "1")]
    header: Option<PublishStamp>,
}

/// The publish stamp of a `risktwin.v1.Header`.
#[derive(Clone, PartialEq, prost::Message)]
struct PublishStamp {
    #[prost(int64, tag = "4")]
    publish_time_ns: i64,
}

/// The worker and the counts around it; lives behind a mutex shared with the Zenoh callback.
pub(crate) struct LiveIngest {
    worker: IngestWorker<RecordingFile>,
    recorder: Option<Recorder<RecordingFile>>,
    recorded: u64,
    received: HashMap<String, [u64; STREAMS]>,
    /// Each source's site (from the key of its first accepted message).
    sites: HashMap<String, String>,
    named: usize,
    outputs: Option<TwinOutputs>,
    bad_key: u64,
    digest: SnapshotDigest,
    last_receive_ns: i64,
    last_sample: Option<Instant>,
    /// Replay-ingest mode: receive times come from the messages' replay-time attachments.
    replay_time: bool,
    no_replay_time: u64,
}

impl LiveIngest {
    /// A worker recording into a new file at `record` when given, feeding `outputs` (the twin
    /// and risk roles) when given.
    pub(crate) fn new(record: Option<&Path>, outputs: Option<TwinOutputs>) -> Result<Self, RecordError> {
        Self::with_config(record, outputs, IngestConfig::default())
    }

    /// [`LiveIngest::new`] with another ingest configuration (tick, lateness, …).
    pub(crate) fn with_config(
        record: Option<&Path>,
        outputs: Option<TwinOutputs>,
        config: IngestConfig,
    ) -> Result<Self, RecordError> {
        let recorder = match record {
            Some(path) => {
                let file = File::create(path)
                    .map_err(|source| RecordError::Create { path: path.display().to_string(), source })?;
                Some(Recorder::new(BufWriter::new(file))?)
            }
            None => None,
        };
        Ok(LiveIngest {
            worker: IngestWorker::new(config, None),
            recorder,
            recorded: 0,
            received: HashMap::new(),
            sites: HashMap::new(),
            named: 0,
            outputs,
            bad_key: 0,
            digest: SnapshotDigest::default(),
            last_receive_ns: i64::MIN,
            last_sample: None,
            replay_time: false,
            no_replay_time: 0,
        })
    }

    /// Switches replay-ingest mode on or off (see `CloudConfig::replay_time`).
    pub(crate) fn with_replay_time(mut self, on: bool) -> Self {
        self.replay_time = on;
        self
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
        let mut twin = self.outputs.as_mut().map(TwinOutputs::twin_mut);
        let mut ticked = false;
        self.worker.handle(parsed.source, stream, key, payload, receive_ns, |s| {
            digest.add(s);
            if let Some(twin) = twin.as_mut() {
                twin.update(s);
                ticked = true;
            }
        })?;
        if self.worker.stats().accepted > accepted_before {
            if let Some(recorder) = self.recorder.as_mut() {
                // Accepted means decoded, so the header is there; 0 only if that ever changed.
                let publish_ns = <HeaderOnly as prost::Message>::decode(payload)
                    .ok()
                    .and_then(|h| h.header)
                    .map_or(0, |h| h.publish_time_ns);
                let channel = recorder.channel(key, schema(stream))?;
                recorder.write(channel, receive_ns.max(0) as u64, publish_ns.max(0) as u64, payload)?;
                self.recorded += 1;
            }
            if !self.sites.contains_key(parsed.source) {
                self.sites.insert(parsed.source.to_owned(), parsed.site.to_owned());
            }
            // Look up by &str first so that a known source costs no allocation.
            let counts = match self.received.get_mut(parsed.source) {
                Some(c) => c,
                None => self.received.entry(parsed.source.to_owned()).or_default(),
            };
            counts[parsed.stream.index()] += 1;
        }
        if let Some(outputs) = self.outputs.as_mut() {
            // Sources the worker numbered since the last message get their names in the twin.
            while let Some(name) = self.worker.source_name(self.named) {
                if let Some(site) = self.sites.get(name) {
                    outputs.twin_mut().name_source(self.named, name, site);
                }
                self.named += 1;
            }
            if ticked {
                outputs.after_tick(receive_ns, self.recorder.as_mut())?;
            }
        }
        Ok(())
    }

    /// When the last sample (accepted or not) arrived.
    pub(crate) fn last_sample(&self) -> Option<Instant> {
        self.last_sample
    }

    /// The twin outputs, when the twin role runs.
    pub(crate) fn outputs_mut(&mut self) -> Option<&mut TwinOutputs> {
        self.outputs.as_mut()
    }

    /// Closes the recording (so the file is a valid MCAP) and returns the summary, with the
    /// twin outputs when they ran.
    pub(crate) fn finish(self) -> Result<(IngestSummary, Option<TwinOutputs>), RecordError> {
        let (mut stats, _) = self.worker.finish()?;
        if let Some(recorder) = self.recorder {
            recorder.finish_into_inner()?.flush().map_err(RecordError::Flush)?;
        }
        stats.recorded = self.recorded;
        let mut summary = summarize(&stats, &self.received, self.bad_key, &self.digest);
        if self.no_replay_time > 0 {
            summary.dropped.insert("no-replay-time".to_owned(), self.no_replay_time);
            summary.total_dropped += self.no_replay_time;
        }
        Ok((summary, self.outputs))
    }
}

/// The schema of a stream's messages in the recording.
fn schema(stream: Stream) -> &'static str {
    use risktwin_common::telemetry::{CanFrame, ObjectList, RsuObservation, SignalPhase, VehicleStateSample};
    use risktwin_protos::WireMessage;
    match stream {
        Stream::State => VehicleStateSample::PROTO_NAME,
        Stream::Can => CanFrame::PROTO_NAME,
        Stream::Perception => ObjectList::PROTO_NAME,
        Stream::Rsu => RsuObservation::PROTO_NAME,
        Stream::Signal => SignalPhase::PROTO_NAME,
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
        late: stats.late,
        late_dropped: stats.late_dropped,
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
