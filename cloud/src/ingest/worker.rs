//! The ingest worker: decode → validate → exactly-once → clock mapping → alignment, and the
//! recording of what was accepted. Transport-free: whoever receives a message calls
//! [`IngestWorker::handle`] with the source and stream its key expression names.
//!
//! Nothing that arrives stops the worker: a message that fails any check is counted under its
//! [`DropReason`] code and dropped. Accepted messages are recorded byte for byte as received,
//! so a recording replayed through a worker reproduces the live snapshots. The recorder is the
//! cloud's only one: the twin's outputs go into it too ([`IngestWorker::recorder_mut`]).

use super::sample::{ObservedKinematics, TwinSample};
use super::stream::{aligner_index, aligner_specs, proto_name};
use risktwin_align::{
    DropReason, Incoming, IngestConfig, IngestCore, PushOutcome, SeqProgress, SequenceScope, Snapshot, SourceIndex,
    SourceTable, StreamIndex,
};
use risktwin_common::telemetry::{CanFrame, Header, ObjectList, RsuObservation, SignalPhase, VehicleStateSample};
use risktwin_protos::recording::{Recorder, RecordingError, SegmentStats};
use risktwin_protos::{DecodeError, WireMessage, decode};
use risktwin_transport::EdgeStream;
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::sync::Arc;

/// Most sources one worker tracks (beyond: dropped as `too-many-sources`).
const MAX_SOURCES: usize = 100_000;

/// Counts of everything the worker saw; drops by reason code.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct IngestStats {
    pub received: u64,
    pub accepted: u64,
    pub recorded: u64,
    pub snapshots: u64,
    /// Accepted samples stamped at or before an already emitted tick (the aligner's late data).
    pub late: u64,
    /// Of those, the ones no coming tick could use, so the twin never saw them.
    pub late_dropped: u64,
    /// Drops by [`DropReason::code`].
    pub dropped: BTreeMap<String, u64>,
}

impl IngestStats {
    /// Messages dropped for any reason.
    pub fn dropped_total(&self) -> u64 {
        self.dropped.values().sum()
    }
}

/// A message the worker accepted: who sent it, when (its clock and the cloud's), and a
/// state's kinematics (what the warning path needs, without decoding twice).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AcceptedMessage {
    /// The source's index ([`IngestWorker::source_name`] names it).
    pub source: SourceIndex,
    pub seq: u64,
    /// The capture time as the source stamped it (its own clock), ns.
    pub capture_ns: i64,
    /// The capture time on the cloud's clock (the source's clock estimate), ns.
    pub cloud_ns: i64,
    /// The kinematics, for a `state` message.
    pub state: Option<ObservedKinematics>,
}

/// Decode, validate, align and record edge messages.
pub struct IngestWorker<W: Write + Seek> {
    core: IngestCore<TwinSample>,
    sources: SourceTable,
    recorder: Option<Recorder<W>>,
    stats: IngestStats,
    /// Why the last message handled was dropped (`None`: it was accepted).
    last_drop: Option<DropReason>,
}

fn decoded<T: WireMessage>(payload: &[u8]) -> Result<T, DropReason> {
    decode::<T>(payload).map_err(|e: DecodeError| e.drop_reason())
}

impl<W: Write + Seek> IngestWorker<W> {
    /// A worker that records accepted messages into `recorder` when one is given.
    pub fn new(config: IngestConfig, recorder: Option<Recorder<W>>) -> Self {
        Self {
            core: IngestCore::new(config, &aligner_specs()),
            sources: SourceTable::with_limit(MAX_SOURCES),
            recorder,
            stats: IngestStats::default(),
            last_drop: None,
        }
    }

    /// Handles one message from `source` on `stream`, received at `receive_ns` (cloud clock).
    /// `topic` names it in the recording. Snapshots that become due are passed to `on_snapshot`.
    /// `Ok(Some(_))` when the message was accepted (and recorded), `Ok(None)` when it was dropped.
    pub fn handle(
        &mut self,
        source: &str,
        stream: EdgeStream,
        topic: &str,
        payload: &[u8],
        receive_ns: i64,
        on_snapshot: impl FnMut(&Snapshot<TwinSample>),
    ) -> Result<Option<AcceptedMessage>, RecordingError> {
        self.handle_then(source, stream, topic, payload, receive_ns, |_| {}, on_snapshot)
    }

    /// [`IngestWorker::handle`], handing an accepted message to `on_accepted` first: before the
    /// snapshots it makes due go to `on_snapshot` and before it is recorded
    /// (`IngestCore::ingest_then`; the snapshots and the recording are the same).
    #[allow(clippy::too_many_arguments)]
    pub fn handle_then(
        &mut self,
        source: &str,
        stream: EdgeStream,
        topic: &str,
        payload: &[u8],
        receive_ns: i64,
        on_accepted: impl FnOnce(&AcceptedMessage),
        on_snapshot: impl FnMut(&Snapshot<TwinSample>),
    ) -> Result<Option<AcceptedMessage>, RecordingError> {
        self.stats.received += 1;
        self.last_drop = None;
        let (header, sample) = match Self::decode(stream, payload) {
            Ok(v) => v,
            Err(reason) => {
                self.drop_for(reason);
                return Ok(None);
            }
        };
        if header.source != source {
            self.drop_for(DropReason::SourceMismatch);
            return Ok(None);
        }
        let Ok(src) = self.sources.index_of(source) else {
            self.drop_for(DropReason::TooManySources);
            return Ok(None);
        };
        let state = match &sample {
            TwinSample::State(k) => Some(*k),
            _ => None,
        };
        let incoming = Incoming {
            source: src,
            stream: aligner_index(stream),
            seq: header.seq,
            capture_ns: header.capture_time_ns,
            receive_ns,
            payload: sample,
        };
        let (seq, capture_ns) = (header.seq, header.capture_time_ns);
        let message = |cloud_ns| AcceptedMessage { source: src, seq, capture_ns, cloud_ns, state };
        let mut snapshots = 0;
        let mut on_snapshot = on_snapshot;
        let verdict = self.core.ingest_then(
            incoming,
            |cloud_ns| on_accepted(&message(cloud_ns)),
            |s| {
                snapshots += 1;
                on_snapshot(s);
            },
        );
        self.stats.snapshots += snapshots;
        match verdict {
            Err(reason) => {
                self.drop_for(reason);
                Ok(None)
            }
            Ok(accepted) => {
                self.stats.accepted += 1;
                match accepted.push {
                    PushOutcome::LateKept => self.stats.late += 1,
                    PushOutcome::LateDropped => {
                        self.stats.late += 1;
                        self.stats.late_dropped += 1;
                    }
                    PushOutcome::Buffered | PushOutcome::SameTime => {}
                }
                if let Some(rec) = self.recorder.as_mut() {
                    let channel = rec.channel(topic, proto_name(stream))?;
                    rec.write(channel, receive_ns.max(0) as u64, header.publish_time_ns.max(0) as u64, payload)?;
                    self.stats.recorded += 1;
                }
                Ok(Some(message(accepted.cloud_ns)))
            }
        }
    }

    /// `source` left (its liveliness token went away): a process that comes back under its name
    /// numbers its messages from the start again, and is taken as a new incarnation.
    pub fn restart_source(&mut self, source: &str) {
        if let Some(index) = self.sources.get(source) {
            self.core.restart_source(index);
        }
    }

    /// Sheds `streams` from now on (bit `i`: [`EdgeStream::index`] `i`; `0`: none).
    pub fn set_shed(&mut self, streams: u64) {
        self.core.set_shed(streams);
    }

    /// Why the last message handled was dropped; `None` when it was accepted.
    pub fn last_drop(&self) -> Option<DropReason> {
        self.last_drop
    }

    /// Counts a message dropped before it reached the worker (its key or its attachment was
    /// wrong), so that every drop is counted in one place.
    pub fn reject(&mut self, reason: DropReason) {
        self.stats.received += 1;
        self.drop_for(reason);
    }

    /// The recording, when the worker records: the twin's outputs are written into it too.
    pub fn recorder_mut(&mut self) -> Option<&mut Recorder<W>> {
        self.recorder.as_mut()
    }

    /// Emits snapshots that are due by `now_ns` even when no message arrives (an idle timer).
    pub fn advance(&mut self, now_ns: i64, mut on_snapshot: impl FnMut(&Snapshot<TwinSample>)) {
        let mut n = 0;
        self.core.advance(now_ns, |s| {
            n += 1;
            on_snapshot(s);
        });
        self.stats.snapshots += n;
    }

    /// The name behind a snapshot's source index.
    pub fn source_name(&self, index: usize) -> Option<&str> {
        self.sources.name(risktwin_align::SourceIndex(index as u32))
    }

    pub fn stats(&self) -> &IngestStats {
        &self.stats
    }

    /// Sequence numbers skipped and not (yet) seen, per source, per stream (streams with none
    /// left out): the deduplicator's `presumed_lost` ([`risktwin_align::dedupe`]). With
    /// one sequence per source (`SequenceScope::PerSource`) it is reported under `(all)`.
    pub fn presumed_lost(&self) -> BTreeMap<String, BTreeMap<String, u64>> {
        let mut lost = BTreeMap::new();
        let per_source = self.core.sequence_scope() == SequenceScope::PerSource;
        for index in 0..self.sources.len() {
            let source = SourceIndex(index as u32);
            let Some(name) = self.sources.name(source) else { continue };
            let streams: Vec<(&str, u64)> = if per_source {
                vec![("(all)", self.core.seq_counts(source, StreamIndex(0)).presumed_lost)]
            } else {
                EdgeStream::ALL
                    .iter()
                    .map(|s| (s.as_str(), self.core.seq_counts(source, aligner_index(*s)).presumed_lost))
                    .collect()
            };
            let streams: BTreeMap<String, u64> =
                streams.into_iter().filter(|(_, n)| *n > 0).map(|(s, n)| (s.to_owned(), n)).collect();
            if !streams.is_empty() {
                lost.insert(name.to_owned(), streams);
            }
        }
        lost
    }

    /// How far each stream of `source`'s current incarnation is accounted for (streams with no
    /// accepted number left out); nothing with one sequence per source.
    pub fn progress(&self, source: &str) -> Vec<(EdgeStream, SeqProgress)> {
        let Some(index) = self.sources.get(source) else { return Vec::new() };
        if self.core.sequence_scope() == SequenceScope::PerSource {
            return Vec::new();
        }
        EdgeStream::ALL.iter().filter_map(|s| Some((*s, self.core.progress(index, aligner_index(*s))?))).collect()
    }

    /// Closes the recording (summary and footer written) and returns the final counts, and the
    /// recording's writer with what its (last) file holds.
    pub fn finish(self) -> Result<(IngestStats, Option<(W, SegmentStats)>), RecordingError> {
        let writer = self.recorder.map(Recorder::finish_segment).transpose()?;
        Ok((self.stats, writer))
    }

    fn drop_for(&mut self, reason: DropReason) {
        self.last_drop = Some(reason);
        // Look up by &str first so that a known reason costs no allocation.
        match self.stats.dropped.get_mut(reason.code()) {
            Some(n) => *n += 1,
            None => {
                self.stats.dropped.insert(reason.code().to_owned(), 1);
            }
        }
    }

    fn decode(stream: EdgeStream, payload: &[u8]) -> Result<(Header, TwinSample), DropReason> {
        Ok(match stream {
            EdgeStream::State => {
                let s: VehicleStateSample = decoded(payload)?;
                let k = ObservedKinematics::from(&s);
                (s.header, TwinSample::State(k))
            }
            EdgeStream::Can => {
                let f: CanFrame = decoded(payload)?;
                (f.header, TwinSample::Can { can_id: f.can_id, data: f.data })
            }
            EdgeStream::Perception => {
                let l: ObjectList = decoded(payload)?;
                (l.header, TwinSample::Objects(Arc::from(l.objects)))
            }
            EdgeStream::Rsu => {
                let o: RsuObservation = decoded(payload)?;
                (o.header, TwinSample::Objects(Arc::from(o.objects)))
            }
            EdgeStream::Signal => {
                let p: SignalPhase = decoded(payload)?;
                (p.header, TwinSample::Signal { signal_id: p.signal_id, phase: p.phase })
            }
        })
    }
}
