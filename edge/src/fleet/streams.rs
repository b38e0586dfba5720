//! A participant's edge streams to the cloud, on the same keys and in the same messages as
//! `edge vehicle` and `edge rsu`: a connected vehicle's `state` every physics step (20 Hz) and
//! its `perception` every 2nd step (10 Hz); an RSU's `rsu` object list every 2nd step (10 Hz).
//! Stamped by the participant's own clock: the wall time at which it received step 0 plus the
//! scene's time, so in real time the stamps follow the wall clock, and in lockstep they advance
//! at the scene's pace. Reliable with blocking congestion control: a scene loses nothing.
//! The ego of a generated scene reports its episode when the scene ends, as a `ScenarioResult`
//! on its `scenario_result` key (as `edge vehicle` reports a pushed scenario's), naming the
//! scene and its scenario, so that the cloud's loop keeps it.

use super::SceneError;
use super::onboard::Onboard;
use super::wire::Truth;
use crate::scene::detected;
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_common::scenario::{ScenarioSpec, content_id};
use risktwin_common::telemetry::{Frame, Header, ObjectList, RsuObservation, ScenarioResult, SceneRef};
use risktwin_protos::encode;
use risktwin_transport::keyexpr::{EdgeReport, edge_report, edge_stream, liveliness_token};
use risktwin_transport::recovery::LIVE_PRIORITY;
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
    /// The ego's result publisher, when it reports its episode.
    result: Option<Publisher<'static>>,
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
    /// Declares the streams of `source` (an RSU's `rsu`, a vehicle's `state` and `perception`,
    /// and with `reports` its `scenario_result`) and its liveliness token, so the cloud sees it
    /// join and leave like any edge.
    pub fn open(
        session: &Session,
        site: &SiteId,
        source: &SourceId,
        is_rsu: bool,
        reports: bool,
    ) -> Result<Streams, SceneError> {
        // `Drop`: a put runs in the truth callback, and a stalled data link must never hold the
        // physics step; what it drops, the cloud's `presumed_lost` counts.
        let declare_key = |key: String, message: &str| {
            session
                .declare_publisher(key.clone())
                .encoding(protobuf(message))
                .congestion_control(CongestionControl::Drop)
                .reliability(Reliability::Reliable)
                .priority(LIVE_PRIORITY)
                .wait()
                .map_err(|e| SceneError::Transport(format!("{key}: {e}")))
        };
        let declare = |stream: EdgeStream| declare_key(edge_stream(site, source, stream), stream.message());
        let report = EdgeReport::ScenarioResult;
        let result = reports.then(|| declare_key(edge_report(site, source, report), report.message())).transpose()?;
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
        Ok(Streams { source: source.clone(), is_rsu, state, objects, result, _alive: alive, epoch_ns: None, sent })
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
        self.publish_state(stack, truth)?;
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

    /// Publishes a vehicle's state in `truth` (nothing for an RSU): every step's, and the final
    /// one the scene ended in (no step follows it, so nothing is perceived in it).
    pub fn publish_state(&mut self, stack: &Onboard, truth: &Truth) -> Result<(), SceneError> {
        self.epoch_ns.get_or_insert_with(|| unix_ns() - (truth.time_s * 1e9).round() as i64);
        if !self.is_rsu
            && let Some(state) = stack.own_state(truth, self.header(self.sent.state, truth.time_s))
        {
            put(&self.state, encode(&state))?;
            self.sent.state += 1;
        }
        Ok(())
    }

    /// Reports the ego's episode of `spec` in scene `digest` (the authority's outcome), on the
    /// `state` messages this process published for it.
    pub fn report(
        &self,
        spec: &ScenarioSpec,
        digest: u64,
        metrics: EpisodeMetrics,
        risk: RiskTerms,
    ) -> Result<(), SceneError> {
        let Some(publisher) = &self.result else { return Ok(()) };
        let now_ns = unix_ns();
        let header = Header {
            source: self.source.as_str().to_owned(),
            seq: 0,
            capture_time_ns: now_ns,
            publish_time_ns: now_ns,
            frame: Frame::World,
        };
        let result = ScenarioResult {
            header,
            spec_id: content_id(spec),
            metrics,
            risk,
            policy: None,
            state_seqs: self.sent.state.checked_sub(1).map(|last| (0, last)),
            scene: Some(SceneRef { digest: format!("{digest:016x}"), spec: spec.clone() }),
        };
        publisher.put(ZBytes::from(encode(&result))).wait().map_err(|e| SceneError::Transport(format!("result: {e}")))
    }
}

fn put(publisher: &Publisher<'static>, bytes: Vec<u8>) -> Result<(), SceneError> {
    publisher.put(ZBytes::from(bytes)).wait().map_err(|e| SceneError::Transport(format!("stream: {e}")))
}
