//! MCAP recordings of protobuf messages, as the Foxglove/MCAP convention wants them: message
//! encoding `protobuf`, schema encoding `protobuf`, schema data a FileDescriptorSet holding the
//! message's file and its imports (here: the whole [`crate::FILE_DESCRIPTOR_SET`], which is
//! valid and lets one schema blob serve every message type of a recording).
//!
//! The recorder stores bytes as they arrived (the cloud records what it accepted, unchanged);
//! [`Recorder::record`] encodes a domain message first. It closes a chunk at [`CHUNK_BYTES`], so
//! a recorder killed without warning loses at most its open chunk ([`read`]: the readers keep
//! the rest). A recorder fed in real time ([`Recorder::live`]) also closes it [`CHUNK_WALL`]
//! after the chunk's first message; an offline one does not, so that its bytes depend on its
//! input alone (same seed, same bytes).
//!
//! A recording may be kept in several files: [`Recorder::rotate`] finishes one (footer and
//! summary) and goes on in the next with the same channel ids, and [`SpanCursor`] reads a time
//! span across such files ([`export`]: as one file).

mod read;
mod recover;
pub mod scan;
mod span;

pub use read::{MessageCursor, MessageRef, RecordedMessage, UnfinishedRecording, read_messages, salvage_messages};
pub use recover::{Recovery, recover};
pub use scan::{CHUNK_UNCOMPRESSED_CAP, RECORD_LENGTH_CAP, RecordScanner, Tail};
pub use span::{Exported, SpanCursor, TopicFilter, export};

use crate::WireMessage;
use crate::convert::foxglove::{
    FOXGLOVE_GRID, FOXGLOVE_LOG, FOXGLOVE_SCENE_UPDATE, risk_grid, timestamp, vehicle_boxes,
};
use risktwin_common::telemetry::{RiskField, VehicleStateSample};
use std::collections::BTreeMap;
use std::collections::HashMap;
use std::io::{Seek, Write};
use std::time::{Duration, Instant};

/// A chunk is closed once it holds this many uncompressed bytes: 1 MiB, the `mcap` crate's
/// default, where zstd compresses our messages about as well as it does larger chunks.
pub const CHUNK_BYTES: u64 = 1 << 20;
/// A live recorder's chunk is closed (and the file flushed) this long after its first message:
/// what a killed recorder can lose. 1 s costs a chunk header and a message index per channel a second (about
/// a hundred bytes each), against a second of data.
pub const CHUNK_WALL: Duration = Duration::from_secs(1);

/// Why a recording could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
    #[error("reading the recording: {0}")]
    Io(#[from] std::io::Error),
    #[error("corrupt recording: {reason}")]
    Corrupt { reason: String },
    #[error("topic '{topic}' was first recorded with schema {first}, now with {now}")]
    SchemaChanged { topic: String, first: String, now: String },
    #[error("not an MCAP file (it does not start with the MCAP magic)")]
    NotMcap,
    #[error(
        "record at byte {at_byte} claims {claimed} bytes, above the {RECORD_LENGTH_CAP}-byte cap{}",
        file_has(*at_byte, *claimed, *file_len)
    )]
    RecordTooLong { at_byte: u64, claimed: u64, file_len: Option<u64> },
    #[error(
        "chunk at byte {at_byte} claims {uncompressed} bytes decompressed, above the {CHUNK_UNCOMPRESSED_CAP}-byte cap"
    )]
    ChunkTooLarge { at_byte: u64, uncompressed: u64 },
    #[error("no complete message: {} at byte {} ({} bytes unreadable)", .0.reason, .0.at_byte, .0.unreadable_bytes)]
    NothingReadable(Tail),
    #[error("{0}")]
    Unfinished(Box<UnfinishedRecording>),
}

/// What a [`RecordingError::RecordTooLong`] adds about the file: its length, "only" when the
/// record would also run past its end.
fn file_has(at_byte: u64, claimed: u64, file_len: Option<u64>) -> String {
    match file_len {
        Some(len) if at_byte.saturating_add(scan::RECORD_HEAD_LEN as u64).saturating_add(claimed) > len => {
            format!(" (the file has only {len})")
        }
        Some(len) => format!(" (the file has {len})"),
        None => String::new(),
    }
}

/// Writes messages of known protobuf types to an MCAP file, or to a series of them
/// ([`Recorder::rotate`]: segments of one recording).
///
/// Ids are the recorder's own, not the file's: a channel keeps its id in every segment, and a
/// segment declares a schema and a channel only once a message on it comes (a segment holds
/// what it needs and no more).
pub struct Recorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    /// Schema names, by id − 1.
    schemas: Vec<String>,
    /// Channel id and schema id by topic.
    channels: HashMap<String, (u16, u16)>,
    /// Each channel's topic and schema id, by id − 1: what a new segment declares again.
    channel_defs: Vec<(String, u16)>,
    /// Whether each schema / channel (by id − 1) is declared in the current file.
    schema_declared: Vec<bool>,
    channel_declared: Vec<bool>,
    /// Messages written to the current file.
    segment_messages: u64,
    sequence: u32,
    /// When the open chunk got its first message (`None`: no chunk is open, or no wall bound).
    chunk_opened: Option<Instant>,
    /// How long a chunk may stay open by the wall clock; `None` for an offline recorder.
    wall_bound: Option<Duration>,
}

/// What one closed file of a recording holds, from its statistics record.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SegmentStats {
    pub messages: u64,
    /// Least and greatest log time, ns; `None` without messages.
    pub log_time_ns: Option<(u64, u64)>,
    /// Messages per channel that has any, in channel order.
    pub topics: Vec<TopicCount>,
}

/// Messages on one topic of a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicCount {
    pub topic: String,
    pub schema_name: String,
    pub messages: u64,
}

impl<W: Write + Seek> Recorder<W> {
    /// An offline recorder over `w`: chunks close at [`CHUNK_BYTES`] only, so the same messages
    /// give the same bytes however fast they come.
    pub fn new(w: W) -> Result<Self, RecordingError> {
        Ok(Self {
            writer: Self::options().create(w)?,
            schemas: Vec::new(),
            channels: HashMap::new(),
            channel_defs: Vec::new(),
            schema_declared: Vec::new(),
            channel_declared: Vec::new(),
            segment_messages: 0,
            sequence: 0,
            chunk_opened: None,
            wall_bound: None,
        })
    }

    fn options() -> mcap::WriteOptions {
        mcap::WriteOptions::new()
            .profile("")
            .library(concat!("risktwin ", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_BYTES))
    }

    /// A recorder of messages as they arrive in real time over `w`: chunks close at
    /// [`CHUNK_BYTES`] or [`CHUNK_WALL`] after their first message, what a kill can lose.
    pub fn live(w: W) -> Result<Self, RecordingError> {
        Ok(Self::new(w)?.with_wall_bound(CHUNK_WALL))
    }

    /// Closes each chunk `bound` after its first message (at the next write or
    /// [`Recorder::flush_if_due`]).
    pub fn with_wall_bound(mut self, bound: Duration) -> Self {
        self.wall_bound = Some(bound);
        self
    }

    /// How long a chunk may stay open by the wall clock; `None` for an offline recorder.
    pub fn wall_bound(&self) -> Option<Duration> {
        self.wall_bound
    }

    /// Messages written to the current file (since the start or the last rotation).
    pub fn segment_messages(&self) -> u64 {
        self.segment_messages
    }

    /// Finishes the current file (summary and footer) and goes on in `next`, channel ids kept:
    /// the finished file's writer and what it holds.
    pub fn rotate(&mut self, next: W) -> Result<(W, SegmentStats), RecordingError> {
        let fresh = Self::options().create(next)?;
        let old = std::mem::replace(&mut self.writer, fresh);
        self.schema_declared.clear();
        self.channel_declared.clear();
        self.chunk_opened = None;
        self.segment_messages = 0;
        close(old, &self.channel_defs, &self.schemas)
    }

    /// Closes the open chunk and flushes the file when the chunk is as old as the wall bound;
    /// for a timer of a live recorder that may go quiet (a chunk otherwise closes at the next
    /// message). Does nothing for an offline recorder.
    pub fn flush_if_due(&mut self) -> Result<(), RecordingError> {
        if let (Some(opened), Some(bound)) = (self.chunk_opened, self.wall_bound)
            && opened.elapsed() >= bound
        {
            self.flush()?;
        }
        Ok(())
    }

    /// Closes the open chunk and flushes the file: what is written so far survives a kill.
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.writer.flush()?;
        self.chunk_opened = None;
        Ok(())
    }

    /// The channel id of `topic` carrying messages of `schema_name` (e.g.
    /// `risktwin.v1.VehicleState`, a message of [`crate::FILE_DESCRIPTOR_SET`], which is the
    /// schema written for it). Declared in the file with its first message.
    pub fn channel(&mut self, topic: &str, schema_name: &str) -> Result<u16, RecordingError> {
        if let Some(&(id, schema)) = self.channels.get(topic) {
            let first = &self.schemas[usize::from(schema) - 1];
            if first != schema_name {
                return Err(RecordingError::SchemaChanged {
                    topic: topic.into(),
                    first: first.clone(),
                    now: schema_name.into(),
                });
            }
            return Ok(id);
        }
        let schema = match self.schemas.iter().position(|s| s == schema_name) {
            Some(i) => i + 1,
            None => {
                self.schemas.push(schema_name.to_owned());
                self.schemas.len()
            }
        };
        let schema = u16::try_from(schema).map_err(|_| mcap::McapError::TooManySchemas)?;
        let id = u16::try_from(self.channel_defs.len() + 1).map_err(|_| mcap::McapError::TooManyChannels)?;
        self.channel_defs.push((topic.to_owned(), schema));
        self.channels.insert(topic.to_owned(), (id, schema));
        Ok(id)
    }

    /// Declares `channel` (and its schema) in the current file.
    fn declare(&mut self, channel: u16) -> Result<(), RecordingError> {
        let index = usize::from(channel).wrapping_sub(1);
        let (topic, schema) = self.channel_defs.get(index).ok_or_else(|| RecordingError::Corrupt {
            reason: format!("a message on channel {channel}, which the recorder never made"),
        })?;
        let schema_index = usize::from(*schema) - 1;
        if !self.schema_declared.get(schema_index).copied().unwrap_or(false) {
            let name = &self.schemas[schema_index];
            self.writer.add_schema_with_id(*schema, name, "protobuf", crate::FILE_DESCRIPTOR_SET)?;
            grow(&mut self.schema_declared, schema_index);
        }
        self.writer.add_channel_with_id(channel, *schema, topic, "protobuf", &BTreeMap::new())?;
        grow(&mut self.channel_declared, index);
        Ok(())
    }

    /// Appends one encoded message. `log_time_ns` orders the recording (the cloud's receive
    /// time); `publish_time_ns` is the source's publish stamp.
    pub fn write(
        &mut self,
        channel: u16,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &[u8],
    ) -> Result<(), RecordingError> {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        if !self.channel_declared.get(usize::from(channel).wrapping_sub(1)).copied().unwrap_or(false) {
            self.declare(channel)?;
        }
        self.sequence = self.sequence.wrapping_add(1);
        self.writer.write_to_known_channel(&header, data)?;
        self.segment_messages += 1;
        // The writer closes a chunk at `CHUNK_BYTES` by itself (it does not say when, so this
        // clock may have started in an earlier chunk: it flushes early, never late).
        match self.chunk_opened {
            None if self.wall_bound.is_some() => self.chunk_opened = Some(Instant::now()),
            None => {}
            Some(_) => self.flush_if_due()?,
        }
        Ok(())
    }

    /// Encodes `message` and appends it on `topic`.
    pub fn record<T: WireMessage>(&mut self, topic: &str, log_time_ns: u64, message: &T) -> Result<(), RecordingError> {
        let channel = self.channel(topic, T::PROTO_NAME)?;
        let bytes = crate::encode(message);
        self.write(channel, log_time_ns, log_time_ns, &bytes)
    }

    /// Appends a `foxglove.SceneUpdate` with a box per vehicle (what Foxglove's 3D panel draws).
    pub fn record_scene(
        &mut self,
        topic: &str,
        time_ns: u64,
        vehicles: &[VehicleStateSample],
    ) -> Result<(), RecordingError> {
        let channel = self.channel(topic, FOXGLOVE_SCENE_UPDATE)?;
        let update = vehicle_boxes(time_ns as i64, vehicles);
        self.write(channel, time_ns, time_ns, &prost::Message::encode_to_vec(&update))
    }

    /// Appends a risk field as a `foxglove.Grid` (one FLOAT32 field `risk`).
    pub fn record_risk_grid(&mut self, topic: &str, time_ns: u64, field: &RiskField) -> Result<(), RecordingError> {
        let channel = self.channel(topic, FOXGLOVE_GRID)?;
        self.write(channel, time_ns, time_ns, &prost::Message::encode_to_vec(&risk_grid(field)))
    }

    /// Appends a generated message (`schema_name`: its full name in this crate's protos).
    pub fn record_proto<M: prost::Message>(
        &mut self,
        topic: &str,
        schema_name: &'static str,
        time_ns: u64,
        message: &M,
    ) -> Result<(), RecordingError> {
        let channel = self.channel(topic, schema_name)?;
        self.write(channel, time_ns, time_ns, &message.encode_to_vec())
    }

    /// Appends a `foxglove.Log` line from `name` (Foxglove's Log panel lists them).
    pub fn record_log(&mut self, topic: &str, time_ns: u64, name: &str, message: &str) -> Result<(), RecordingError> {
        let log = crate::foxglove::Log {
            timestamp: Some(timestamp(time_ns as i64)),
            level: crate::foxglove::log::Level::Info as i32,
            message: message.to_owned(),
            name: name.to_owned(),
            ..Default::default()
        };
        self.record_proto(topic, FOXGLOVE_LOG, time_ns, &log)
    }

    /// Writes the summary and footer: after this the file is complete and indexed.
    pub fn finish(self) -> Result<(), RecordingError> {
        self.finish_into_inner().map(|_| ())
    }

    /// [`Recorder::finish`], handing back the underlying writer.
    pub fn finish_into_inner(self) -> Result<W, RecordingError> {
        self.finish_segment().map(|(w, _)| w)
    }

    /// [`Recorder::finish`], handing back the underlying writer and what its file holds.
    pub fn finish_segment(self) -> Result<(W, SegmentStats), RecordingError> {
        close(self.writer, &self.channel_defs, &self.schemas)
    }
}

/// Finishes `writer` and reads what its file holds from the statistics it wrote; `channel_defs`
/// and `schemas` name its channels (see [`Recorder`]).
fn close<W: Write + Seek>(
    mut writer: mcap::Writer<W>,
    channel_defs: &[(String, u16)],
    schemas: &[String],
) -> Result<(W, SegmentStats), RecordingError> {
    let summary = writer.finish()?;
    let mut stats = SegmentStats::default();
    if let Some(s) = summary.stats.filter(|s| s.message_count > 0) {
        stats.messages = s.message_count;
        stats.log_time_ns = Some((s.message_start_time, s.message_end_time));
        for (&id, &messages) in &s.channel_message_counts {
            let Some((topic, schema)) = channel_defs.get(usize::from(id).wrapping_sub(1)) else { continue };
            let schema_name = schemas[usize::from(*schema) - 1].clone();
            stats.topics.push(TopicCount { topic: topic.clone(), schema_name, messages });
        }
    }
    Ok((writer.into_inner(), stats))
}

/// Sets `flags[index]`, growing `flags` as needed.
fn grow(flags: &mut Vec<bool>, index: usize) {
    if flags.len() <= index {
        flags.resize(index + 1, false);
    }
    flags[index] = true;
}

/// Length of a replay-time attachment: an 8-byte tag and the time as little-endian `i64` ns.
pub const REPLAY_TIME_ATTACHMENT_LEN: usize = 16;
const REPLAY_TIME_TAG: &[u8; 8] = b"rtlogt01";

/// The attachment `risktwin edge replay` puts on each message: its recorded receive (log) time,
/// which a cloud in replay-time mode uses instead of its own receive clock.
pub fn encode_replay_time(log_time_ns: i64) -> [u8; REPLAY_TIME_ATTACHMENT_LEN] {
    let mut out = [0u8; REPLAY_TIME_ATTACHMENT_LEN];
    out[..8].copy_from_slice(REPLAY_TIME_TAG);
    out[8..].copy_from_slice(&log_time_ns.to_le_bytes());
    out
}

/// The recorded receive time in a replay-time attachment; `None` for anything else.
pub fn decode_replay_time(attachment: &[u8]) -> Option<i64> {
    let (tag, time) = attachment.split_at_checked(8)?;
    if tag != REPLAY_TIME_TAG {
        return None;
    }
    Some(i64::from_le_bytes(time.try_into().ok()?))
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod salvage_tests;
