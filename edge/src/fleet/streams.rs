//! A participant's edge streams to the cloud, on the same keys and in the same messages as
//! `edge vehicle` and `edge rsu`: a connected vehicle's `state` every physics step (20 Hz) and
//! its `perception` every 2nd step (10 Hz); an RSU's `rsu` object list every 2nd step (10 Hz).
//! Stamped by the participant's own clock: the wall time at which it received step 0 plus the
//! scene's time, so in real time the stamps follow the wall clock, and in lockstep they advance
//! at the scene's pace. Reliable with blocking congestion control: a scene loses nothing.

use super::SceneError;
use super::onboard::Onboard;
use super::wire::Truth;
use crate::scene::detected;
use risktwin_common::telemetry::{Frame, Header, ObjectList, RsuObservation};
use risktwin_protos::encode;
use risktwin_transport::keyexpr::{edge_stream, liveliness_token};
use risktwin_transport::zenoh::Wait;
use risktwin_transport::zenoh::liveliness::LivelinessToken;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::{CongestionControl, Reliability};
use risktwin_transport::zenoh::{Session, bytes::ZBytes};
use risktwin_transport::{EdgeStream, SiteId, SourceId, protobuf};
use serde::Serialize;
use std::time::{SystemTime, UNIX_EPOCH};

/// Physics steps per perception or RSU message: 10 Hz from the 20 Hz simulation.
const STEPS_PER_OBJECT_LIST: u64 = 2;

/// Messages published per stream.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct StreamsSent {
    pub state: u64,
    pub perception: u64,
    pub rsu: u64,
}

/// A participant's publishers, sequence numbers and clock.
pub struct Streams {
    source: SourceId,
    is_rsu: bool,
    state: Publisher<'static>,
    objects: Publisher<'static>,
    _alive: LivelinessToken,
    /// Wall time at the scene's t = 0 by this participant's clock, ns since the Unix epoch.
    epoch_ns: Option<i64>,
    pub sent: StreamsSent,
}

/// The wall clock, ns since the Unix epoch.
pub(super) fn unix_ns() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as i64)
}

impl Streams {
    /// Declares the streams of `source` (an RSU's `rsu`, a vehicle's `state` and `perception`)
    /// and its liveliness token, so the cloud sees it join and leave like any edge.
    pub fn open(session: &Session, site: &SiteId, source: &SourceId, is_rsu: bool) -> Result<Streams, SceneError> {
        let declare = |stream: EdgeStream| {
            let key = edge_stream(site, source, stream);
            session
                .declare_publisher(key.clone())
                .encoding(protobuf(stream.message()))
                .congestion_control(CongestionControl::Block)
                .reliability(Reliability::Reliable)
                .wait()
                .map_err(|e| SceneError::Transport(format!("{key}: {e}")))
        };
        // An RSU has one stream; its `state` publisher is the same key and never used.
        let (state, objects) = if is_rsu {
            (declare(EdgeStream::Rsu)?, declare(EdgeStream::Rsu)?)
        } else {
            (declare(EdgeStream::State)?, declare(EdgeStream::Perception)?)
        };
        let key = liveliness_token(site, source);
        let alive = session
            .liveliness()
            .declare_token(key.clone())
            .wait()
            .map_err(|e| SceneError::Transport(format!("{key}: {e}")))?;
        let sent = StreamsSent::default();
        Ok(Streams { source: source.clone(), is_rsu, state, objects, _alive: alive, epoch_ns: None, sent })
    }

    fn header(&self, seq: u64, time_s: f64) -> Header {
        let capture = self.epoch_ns.unwrap_or_default() + (time_s * 1e9).round() as i64;
        Header {
            source: self.source.as_str().to_owned(),
            seq,
            capture_time_ns: capture,
            publish_time_ns: capture.max(unix_ns()),
            frame: Frame::World,
        }
    }

    /// Publishes what `stack` holds for `truth`'s step (after it responded to it).
    pub fn publish(&mut self, stack: &Onboard, truth: &Truth) -> Result<(), SceneError> {
        self.epoch_ns.get_or_insert_with(|| unix_ns() - (truth.time_s * 1e9).round() as i64);
        let put = |publisher: &Publisher<'static>, bytes: Vec<u8>| {
            publisher.put(ZBytes::from(bytes)).wait().map_err(|e| SceneError::Transport(format!("stream: {e}")))
        };
        if !self.is_rsu
            && let Some(state) = stack.own_state(truth, self.header(self.sent.state, truth.time_s))
        {
            put(&self.state, encode(&state))?;
            self.sent.state += 1;
        }
        if !truth.step.is_multiple_of(STEPS_PER_OBJECT_LIST) {
            return Ok(());
        }
        let objects = stack.perceived().iter().map(detected).collect();
        if self.is_rsu {
            let (rsu_pose, range_m) = stack.mast();
            let header = self.header(self.sent.rsu, truth.time_s);
            put(&self.objects, encode(&RsuObservation { header, rsu_pose, range_m, objects }))?;
            self.sent.rsu += 1;
        } else {
            let header = self.header(self.sent.perception, truth.time_s);
            put(&self.objects, encode(&ObjectList { header, objects }))?;
            self.sent.perception += 1;
        }
        Ok(())
    }
}
