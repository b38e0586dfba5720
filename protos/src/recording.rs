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

mod read;
mod recover;
pub mod scan;

pub use read::{MessageCursor, MessageRef, RecordedMessage, UnfinishedRecording, read_messages, salvage_messages};
pub use recover::{Recovery, recover};
pub use scan::{CHUNK_UNCOMPRESSED_CAP, RECORD_LENGTH_CAP, RecordScanner, Tail};

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

/// Writes messages of known protobuf types to an MCAP file.
pub struct Recorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, (u16, &'static str)>,
    sequence: u32,
    /// When the open chunk got its first message (`None`: no chunk is open, or no wall bound).
    chunk_opened: Option<Instant>,
    /// How long a chunk may stay open by the wall clock; `None` for an offline recorder.
    wall_bound: Option<Duration>,
}

impl<W: Write + Seek> Recorder<W> {
    /// An offline recorder over `w`: chunks close at [`CHUNK_BYTES`] only, so the same messages
    /// give the same bytes however fast they come.
    pub fn new(w: W) -> Result<Self, RecordingError> {
        let options = mcap::WriteOptions::new()
            .profile("")
            .library(concat!("risktwin ", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_BYTES));
        Ok(Self {
            writer: options.create(w)?,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            sequence: 0,
            chunk_opened: None,
            wall_bound: None,
        })
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

    /// The channel id of `topic` carrying messages of `schema_name` (e.g. `risktwin.v1.VehicleState`).
    pub fn channel(&mut self, topic: &str, schema_name: &'static str) -> Result<u16, RecordingError> {
        if let Some(&(id, first)) = self.channels.get(topic) {
            if first != schema_name {
                return Err(RecordingError::SchemaChanged {
                    topic: topic.into(),
                    first: first.into(),
                    now: schema_name.into(),
                });
            }
            return Ok(id);
        }
        let schema = match self.schemas.get(schema_name) {
            Some(&id) => id,
            None => {
                let id = self.writer.add_schema(schema_name, "protobuf", crate::FILE_DESCRIPTOR_SET)?;
                self.schemas.insert(schema_name, id);
                id
            }
        };
        let id = self.writer.add_channel(schema, topic, "protobuf", &BTreeMap::new())?;
        self.channels.insert(topic.to_string(), (id, schema_name));
        Ok(id)
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
        self.sequence = self.sequence.wrapping_add(1);
        self.writer.write_to_known_channel(&header, data)?;
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
    pub fn finish_into_inner(mut self) -> Result<W, RecordingError> {
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
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
mod tests {
    use super::*;
    use crate::decode;
    use risktwin_common::geometry::{Footprint, Pose, Vec2};
    use risktwin_common::telemetry::{Frame, Header};

    fn state(seq: u64) -> VehicleStateSample {
        VehicleStateSample {
            header: Header {
                source: "veh-1".into(),
                seq,
                capture_time_ns: 1_000 * seq as i64,
                publish_time_ns: 1_001 * seq as i64,
                frame: Frame::World,
            },
            pose: Pose::new(seq as f64, 2.0, 0.1),
            velocity: Vec2::new(20.0, 0.0),
            speed_mps: 20.0,
            accel_mps2: -1.5,
            yaw_rate_radps: 0.01,
            steer_rad: 0.02,
            footprint: Footprint::new(4.5, 1.8),
        }
    }

    #[test]
    fn round_trip_through_a_file_and_schema_mismatch_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("r.mcap");
        let mut rec =
            Recorder::new(std::io::BufWriter::new(std::fs::File::create(&path).expect("create"))).expect("recorder");
        for seq in 0..100 {
            rec.record("risktwin/v1/site/veh-1/state", 10 * seq, &state(seq)).expect("record");
        }
        assert!(matches!(
            rec.channel("risktwin/v1/site/veh-1/state", "risktwin.v1.CanFrame"),
            Err(RecordingError::SchemaChanged { .. })
        ));
        rec.finish().expect("finish");
        let bytes = std::fs::read(&path).expect("read");
        let msgs = read_messages(&bytes).expect("valid recording");
        assert_eq!(msgs.len(), 100);
        for (seq, m) in msgs.iter().enumerate() {
            assert_eq!(m.schema_name, "risktwin.v1.VehicleState");
            assert_eq!(m.log_time_ns, 10 * seq as u64);
            let back: VehicleStateSample = decode(&m.data).expect("decodes");
            assert_eq!(format!("{back:?}"), format!("{:?}", state(seq as u64)));
        }
        // A truncated file is an error to the strict reader, not a panic.
        let truncated = read_messages(&bytes[..bytes.len() / 2]);
        assert!(truncated.is_err(), "a recording cut in half is refused: {:?}", truncated.map(|m| m.len()));
        let (kept, unfinished) = salvage_messages(&bytes[..bytes.len() / 2]).expect("salvaged");
        // The second half is the summary (it repeats the large schema): every message is kept.
        assert!(unfinished.is_some(), "a cut file is reported");
        assert_eq!(kept, msgs, "the messages before the cut");
        assert!(read_messages(b"not an mcap file").is_err());

        // The streaming cursor over the file itself agrees with the collected read.
        let mut cursor = MessageCursor::new(std::fs::File::open(&path).expect("open"));
        let mut n = 0;
        while let Some(m) = cursor.next_message() {
            let m = m.expect("a whole message");
            assert_eq!((m.topic, m.data), (msgs[n].topic.as_str(), msgs[n].data.as_slice()));
            assert_eq!(m.log_time_ns, msgs[n].log_time_ns);
            n += 1;
        }
        assert_eq!(n, 100);
        let mut cut = MessageCursor::new(&bytes[..bytes.len() / 2]);
        let mut read = 0;
        while let Some(m) = cut.next_message() {
            m.expect("the messages before the cut");
            read += 1;
        }
        assert_eq!(read, kept.len(), "the cursor keeps what the collected read keeps");
        assert!(cut.unfinished().is_some(), "the cursor reports a truncated file");
    }

    /// `n` state messages written by `rec`, its finished bytes.
    fn written(mut rec: Recorder<std::io::Cursor<Vec<u8>>>, n: u64) -> Vec<u8> {
        for seq in 0..n {
            rec.record("risktwin/v1/site/veh-1/state", 10 * seq, &state(seq)).expect("record");
        }
        rec.finish_into_inner().expect("finish").into_inner()
    }

    fn chunks(bytes: &[u8]) -> usize {
        mcap::Summary::read(bytes).expect("summary").expect("a summary").chunk_indexes.len()
    }

    #[test]
    fn an_offline_recording_has_no_wall_bound_and_its_bytes_follow_its_input() {
        let offline = || Recorder::new(std::io::Cursor::new(Vec::new())).expect("recorder");
        assert_eq!(offline().wall_bound(), None, "offline chunks close by size only");
        let live = Recorder::live(std::io::Cursor::new(Vec::new())).expect("recorder");
        assert_eq!(live.wall_bound(), Some(CHUNK_WALL));
        let (a, b) = (written(offline(), 200), written(offline(), 200));
        assert_eq!(a, b, "the same messages, the same bytes");
        assert_eq!(chunks(&a), 1, "200 small messages fit one 1 MiB chunk");
        // A bound that is always due closes a chunk at every second write (the first write after
        // the bound): what an offline recorder given a wall bound does once a slow machine
        // crosses it, other bytes for the same input.
        let bounded =
            Recorder::new(std::io::Cursor::new(Vec::new())).expect("recorder").with_wall_bound(Duration::ZERO);
        let bounded = written(bounded, 200);
        assert_eq!(chunks(&bounded), 100, "two messages a chunk");
        assert_eq!(read_messages(&bounded).expect("finished"), read_messages(&a).expect("finished"));
    }

    #[test]
    fn replay_time_attachments_round_trip_and_others_are_refused() {
        for t in [0, 1, -5, i64::MAX, 1_700_000_000_123_456_789] {
            assert_eq!(decode_replay_time(&encode_replay_time(t)), Some(t));
        }
        assert_eq!(decode_replay_time(b""), None);
        assert_eq!(decode_replay_time(b"rtlogt01short"), None);
        assert_eq!(decode_replay_time(b"somethingelse!!!"), None);
    }
}

#[cfg(test)]
mod salvage_tests;
