//! MCAP recordings of protobuf messages, as the Foxglove/MCAP convention wants them: message
//! encoding `protobuf`, schema encoding `protobuf`, schema data a FileDescriptorSet holding the
//! message's file and its imports (here: the whole [`crate::FILE_DESCRIPTOR_SET`], which is
//! valid and lets one schema blob serve every message type of a recording).
//!
//! The recorder stores bytes as they arrived (the cloud records what it accepted, unchanged);
//! [`Recorder::record`] encodes a domain message first.

use crate::WireMessage;
use crate::convert::foxglove::{
    FOXGLOVE_GRID, FOXGLOVE_LOG, FOXGLOVE_SCENE_UPDATE, risk_grid, timestamp, vehicle_boxes,
};
use risktwin_common::telemetry::{RiskField, VehicleStateSample};
use std::collections::BTreeMap;
use std::collections::HashMap;
use std::io::{Read, Seek, Write};

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
}

/// Writes messages of known protobuf types to an MCAP file.
pub struct Recorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, (u16, &'static str)>,
    sequence: u32,
}

impl<W: Write + Seek> Recorder<W> {
    /// A recorder over `w`.
    pub fn new(w: W) -> Result<Self, RecordingError> {
        let options = mcap::WriteOptions::new().profile("").library(concat!("risktwin ", env!("CARGO_PKG_VERSION")));
        Ok(Self { writer: options.create(w)?, schemas: HashMap::new(), channels: HashMap::new(), sequence: 0 })
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

/// One recorded message.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedMessage {
    pub topic: String,
    pub schema_name: String,
    pub log_time_ns: u64,
    pub publish_time_ns: u64,
    pub data: Vec<u8>,
}

/// All messages of a recording in file order; a truncated or corrupt file is an error. Collects
/// them: for large recordings iterate with a [`MessageCursor`] instead.
pub fn read_messages(bytes: &[u8]) -> Result<Vec<RecordedMessage>, RecordingError> {
    let mut out = Vec::new();
    let mut cursor = MessageCursor::new(bytes);
    while let Some(m) = cursor.next_message() {
        let m = m?;
        out.push(RecordedMessage {
            topic: m.topic.to_owned(),
            schema_name: m.schema_name.to_owned(),
            log_time_ns: m.log_time_ns,
            publish_time_ns: m.publish_time_ns,
            data: m.data.to_vec(),
        });
    }
    Ok(out)
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

/// One message lent by a [`MessageCursor`]: valid until the cursor moves on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageRef<'a> {
    pub topic: &'a str,
    pub schema_name: &'a str,
    pub channel_id: u16,
    pub log_time_ns: u64,
    pub publish_time_ns: u64,
    pub data: &'a [u8],
}

/// A channel as the cursor keeps it: what a message needs to be named.
#[derive(Debug)]
struct ChannelName {
    topic: String,
    schema_name: String,
}

/// Bytes of a message record before its data: channel id (2), sequence (4), log time (8),
/// publish time (8).
const MESSAGE_HEADER_LEN: usize = 22;

/// Streams the messages of an MCAP recording from any reader (a file, a memory map, a byte
/// slice) in file order, without collecting them and without an allocation per message: each
/// message is copied once, out of the decompressed chunk, into one reused buffer and lent out.
///
/// Like the `mcap` crate's own streaming reader it reads to the end magic, so a truncated file
/// is reported after its last whole message; the summary section (which repeats the channels) is
/// read but not re-checked.
pub struct MessageCursor<R: Read> {
    source: R,
    reader: mcap::sans_io::LinearReader,
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, ChannelName>,
    data: Vec<u8>,
    past_data_end: bool,
    done: bool,
}

/// Reads into `buf` until it is full or the source ends; the count read (0: end of file).
fn read_some<R: Read>(source: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match source.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

impl<R: Read> MessageCursor<R> {
    /// A cursor at the start of `source`.
    pub fn new(source: R) -> Self {
        Self {
            source,
            reader: mcap::sans_io::LinearReader::new(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            data: Vec::new(),
            past_data_end: false,
            done: false,
        }
    }

    /// The next message, `None` at the end of the file; after an error, `None` for ever.
    #[allow(clippy::should_implement_trait)] // a lending iterator: `Iterator` cannot lend
    pub fn next_message(&mut self) -> Option<Result<MessageRef<'_>, RecordingError>> {
        if self.done {
            return None;
        }
        match self.advance() {
            Ok(Some((channel_id, log_time_ns, publish_time_ns))) => {
                let Some(channel) = self.channels.get(&channel_id) else {
                    self.done = true;
                    return Some(Err(RecordingError::Corrupt {
                        reason: format!("a message on unknown channel {channel_id}"),
                    }));
                };
                Some(Ok(MessageRef {
                    topic: &channel.topic,
                    schema_name: &channel.schema_name,
                    channel_id,
                    log_time_ns,
                    publish_time_ns,
                    data: &self.data,
                }))
            }
            Ok(None) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }

    /// Reads up to the next message record, leaving its data in `self.data`.
    fn advance(&mut self) -> Result<Option<(u16, u64, u64)>, RecordingError> {
        use mcap::records::{Record, op};
        use mcap::sans_io::LinearReadEvent;
        loop {
            let event = match self.reader.next_event() {
                None => return Ok(None),
                Some(event) => event?,
            };
            match event {
                LinearReadEvent::ReadRequest(need) => {
                    let buf = self.reader.insert(need);
                    let n = read_some(&mut self.source, buf)?;
                    self.reader.notify_read(n);
                }
                LinearReadEvent::Record { opcode: op::DATA_END, .. } => self.past_data_end = true,
                LinearReadEvent::Record { .. } if self.past_data_end => {}
                LinearReadEvent::Record { opcode: op::MESSAGE, data } => {
                    let Some((head, body)) = data.split_at_checked(MESSAGE_HEADER_LEN) else {
                        return Err(RecordingError::Corrupt {
                            reason: format!("a message record of {} bytes (at least {MESSAGE_HEADER_LEN})", data.len()),
                        });
                    };
                    let channel_id = u16::from_le_bytes([head[0], head[1]]);
                    let word = |at: usize| {
                        let mut w = [0u8; 8];
                        w.copy_from_slice(&head[at..at + 8]);
                        u64::from_le_bytes(w)
                    };
                    let (log_time_ns, publish_time_ns) = (word(6), word(14));
                    self.data.clear();
                    self.data.extend_from_slice(body);
                    return Ok(Some((channel_id, log_time_ns, publish_time_ns)));
                }
                LinearReadEvent::Record { opcode, data } if opcode == op::SCHEMA || opcode == op::CHANNEL => {
                    match mcap::parse_record(opcode, data)? {
                        Record::Schema { header, .. } => {
                            self.schemas.insert(header.id, header.name);
                        }
                        Record::Channel(channel) => {
                            // Schema id 0 means "no schema".
                            let schema_name = match channel.schema_id {
                                0 => String::new(),
                                id => self.schemas.get(&id).cloned().ok_or_else(|| RecordingError::Corrupt {
                                    reason: format!("channel {} names unknown schema {id}", channel.id),
                                })?,
                            };
                            self.channels.insert(channel.id, ChannelName { topic: channel.topic, schema_name });
                        }
                        _ => {}
                    }
                }
                LinearReadEvent::Record { .. } => {}
            }
        }
    }
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
        // A truncated file is an error, not a panic.
        let truncated = read_messages(&bytes[..bytes.len() / 2]);
        assert!(truncated.is_err(), "a recording cut in half is refused: {:?}", truncated.map(|m| m.len()));
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
        let mut last = None;
        while let Some(m) = cut.next_message() {
            last = Some(m.map(|_| ()));
        }
        assert!(matches!(last, Some(Err(_))), "the cursor reports a truncated file");
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
