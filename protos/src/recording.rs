//! MCAP recordings of protobuf messages, as the Foxglove/MCAP convention wants them: message
//! encoding `protobuf`, schema encoding `protobuf`, schema data a FileDescriptorSet holding the
//! message's file and its imports (here: the whole [`crate::FILE_DESCRIPTOR_SET`], which is
//! valid and lets one schema blob serve every message type of a recording).
//!
//! The recorder stores bytes as they arrived (the cloud records what it accepted, unchanged);
//! [`Recorder::record`] encodes a domain message first.

use crate::WireMessage;
use crate::convert::foxglove::{FOXGLOVE_GRID, FOXGLOVE_SCENE_UPDATE, risk_grid, vehicle_boxes};
use risktwin_common::telemetry::{RiskField, VehicleStateSample};
use std::collections::BTreeMap;
use std::collections::HashMap;
use std::io::{Seek, Write};

/// Why a recording could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
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

/// All messages of a recording in file order; a truncated or corrupt file is an error.
pub fn read_messages(bytes: &[u8]) -> Result<Vec<RecordedMessage>, RecordingError> {
    let mut out = Vec::new();
    for m in mcap::MessageStream::new(bytes)? {
        let m = m?;
        out.push(RecordedMessage {
            topic: m.channel.topic.clone(),
            schema_name: m.channel.schema.as_ref().map_or_else(String::new, |s| s.name.clone()),
            log_time_ns: m.log_time,
            publish_time_ns: m.publish_time,
            data: m.data.into_owned(),
        });
    }
    Ok(out)
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
    }
}
