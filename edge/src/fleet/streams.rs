//! A participant's edge streams to the cloud, on the same keys and in the same messages as
//! `edge vehicle` and `edge rsu`: a connected vehicle's `state` every physics step (20 Hz) and
//! its `perception` every 2nd step (10 Hz); an RSU's `rsu` object list every 2nd step (10 Hz).
//! Stamped by the participant's own clock: the wall time at which it received step 0 plus the
//! scene's time, so in real time the stamps follow the wall clock, and in lockstep they advance
//! at the scene's pace. The streams are the edges' own ([`StreamPublisher`]): numbered, cached
//! for [`DEFAULT_OUTAGE`] at their rates, so what a partition keeps from the cloud is fetched
//! after it; a full link queue drops rather than holds the physics step (congestion `Drop`).
//! (One wait remains, as for every edge: a put waits while its stream's cache sends an answer
//! to a recovery query, which a link that stalls at that moment can hold up.)
//!
//! Physics does not wait for the cloud as an `edge vehicle` does before its first message, so
//! until a subscriber first matches a stream its messages wait in the participant (as many as
//! the cache holds, the oldest dropped and counted `unsent` beyond) and go out in order when
//! one does, with the publish time of when they were made: a scene whose host starts cut off
//! loses nothing of its first seconds. Any subscriber counts (the cloud's ingest in a
//! deployment; a recorder or another cloud that matches first takes the flush, and an ingest
//! that subscribes later starts at the next message, the earlier ones `missing` in a report).
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
use risktwin_common::world::STEP_S;
use risktwin_protos::encode;
use risktwin_transport::keyexpr::{EdgeReport, edge_report, liveliness_token};
use risktwin_transport::recovery::{DEFAULT_OUTAGE, LIVE_PRIORITY};
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::Wait;
use risktwin_transport::zenoh::liveliness::LivelinessToken;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::{CongestionControl, Reliability};
use risktwin_transport::zenoh::{Session, bytes::ZBytes};
use risktwin_transport::{Delivery, EdgeStream, SiteId, SourceId, StreamPublisher, protobuf};
use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

/// Physics steps per perception or RSU message: 10 Hz from the 20 Hz simulation.
const STEPS_PER_OBJECT_LIST: u64 = 2;

/// One edge stream and how many messages it made (the next one's sequence number).
struct Counted {
    publisher: StreamPublisher,
    sent: u64,
    /// Until a subscriber first matches: the messages made so far, oldest first, at most
    /// `capacity`; `None` after.
    waiting: Option<VecDeque<Vec<u8>>>,
    capacity: usize,
    /// Made but dropped from a full `waiting`, oldest first: the first put is numbered this.
    dropped: u64,
}

impl Counted {
    fn declare(
        session: &Session,
        site: &SiteId,
        source: &SourceId,
        stream: EdgeStream,
        steps_per_message: u64,
    ) -> Result<Self, SceneError> {
        let rate_hz = 1.0 / (STEP_S * steps_per_message as f64);
        let delivery = Delivery::live(rate_hz, DEFAULT_OUTAGE);
        let publisher = StreamPublisher::declare(session, site, source, stream, delivery)
            .map_err(|e| SceneError::Transport(e.to_string()))?;
        let capacity = delivery.cache_samples;
        Ok(Counted { publisher, sent: 0, waiting: Some(VecDeque::new()), capacity, dropped: 0 })
    }

    /// Publishes the next message (numbered [`Counted::sent`]), after those waiting for the
    /// first subscriber; or adds it to them while none matches.
    fn put(&mut self, message: Vec<u8>) -> Result<(), SceneError> {
        self.sent += 1;
        self.flush()?;
        let Some(waiting) = &mut self.waiting else {
            return self.publisher.put(message).map_err(|e| SceneError::Transport(e.to_string()));
        };
        if waiting.len() == self.capacity {
            waiting.pop_front();
            self.dropped += 1;
        }
        waiting.push_back(message);
        Ok(())
    }

    /// Puts what waits for the first subscriber, in order, once one matches.
    fn flush(&mut self) -> Result<(), SceneError> {
        let Some(waiting) = &mut self.waiting else { return Ok(()) };
        if !self.publisher.matched() {
            return Ok(());
        }
        for earlier in waiting.drain(..) {
            self.publisher.put(earlier).map_err(|e| SceneError::Transport(e.to_string()))?;
        }
        self.waiting = None;
        Ok(())
    }

    /// Made but never put: dropped from a full `waiting`, or still waiting.
    fn unsent(&self) -> u64 {
        self.dropped + self.waiting.as_ref().map_or(0, |w| w.len() as u64)
    }
}

/// A participant's publishers, sequence numbers and clock.
pub struct Streams {
    source: SourceId,
    /// A vehicle's `state`; `None` for an RSU.
    state: Option<Counted>,
    /// A vehicle's `perception` or an RSU's `rsu`.
    objects: Counted,
    /// The ego's result publisher, when it reports its episode.
    result: Option<Publisher<'static>>,
    _alive: LivelinessToken,
    /// Wall time at the scene's t = 0 by this participant's clock, ns since the Unix epoch.
    epoch_ns: Option<i64>,
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
        let report = EdgeReport::ScenarioResult;
        let result = reports
            .then(|| {
                let key = edge_report(site, source, report);
                session
                    .declare_publisher(key.clone())
                    .encoding(protobuf(report.message()))
                    .congestion_control(CongestionControl::Drop)
                    .reliability(Reliability::Reliable)
                    .priority(LIVE_PRIORITY)
                    .wait()
                    .map_err(|e| SceneError::Transport(format!("{key}: {e}")))
            })
            .transpose()?;
        let declare = |stream, steps| Counted::declare(session, site, source, stream, steps);
        let (state, objects) = if is_rsu {
            (None, declare(EdgeStream::Rsu, STEPS_PER_OBJECT_LIST)?)
        } else {
            (Some(declare(EdgeStream::State, 1)?), declare(EdgeStream::Perception, STEPS_PER_OBJECT_LIST)?)
        };
        let key = liveliness_token(site, source);
        let alive = session
            .liveliness()
            .declare_token(key.clone())
            .wait()
            .map_err(|e| SceneError::Transport(format!("{key}: {e}")))?;
        Ok(Streams { source: source.clone(), state, objects, result, _alive: alive, epoch_ns: None })
    }

    /// Messages made per stream name.
    pub fn sent(&self) -> BTreeMap<String, u64> {
        self.per_stream(|c| c.sent)
    }

    /// Of [`Streams::sent`], those never put because no subscriber matched in time.
    pub fn unsent(&self) -> BTreeMap<String, u64> {
        self.per_stream(Counted::unsent)
    }

    fn per_stream(&self, count: impl Fn(&Counted) -> u64) -> BTreeMap<String, u64> {
        let streams = self.state.iter().chain([&self.objects]);
        streams.map(|c| (c.publisher.stream().map_or("map", EdgeStream::as_str).to_owned(), count(c))).collect()
    }

    /// Puts what waits for a first subscriber, if one matches now (at the scene's end: no later
    /// put would).
    pub fn flush(&mut self) -> Result<(), SceneError> {
        self.state.iter_mut().try_for_each(Counted::flush)?;
        self.objects.flush()
    }

    /// How long the participant keeps its streams after its last put (see
    /// [`risktwin_transport::linger`]).
    pub fn linger(&self) -> Duration {
        risktwin_transport::linger(self.state.iter().chain([&self.objects]).map(|c| &c.publisher))
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
        let header = self.header(self.objects.sent, truth.time_s);
        let message = if self.state.is_none() {
            let (rsu_pose, range_m) = stack.mast();
            encode(&RsuObservation { header, rsu_pose, range_m, objects })
        } else {
            encode(&ObjectList { header, objects })
        };
        self.objects.put(message)
    }

    /// Publishes a vehicle's state in `truth` (nothing for an RSU): every step's, and the final
    /// one the scene ended in (no step follows it, so nothing is perceived in it).
    pub fn publish_state(&mut self, stack: &Onboard, truth: &Truth) -> Result<(), SceneError> {
        self.epoch_ns.get_or_insert_with(|| unix_ns() - (truth.time_s * 1e9).round() as i64);
        let Some(seq) = self.state.as_ref().map(|s| s.sent) else { return Ok(()) };
        let header = self.header(seq, truth.time_s);
        match (stack.own_state(truth, header), &mut self.state) {
            (Some(state), Some(stream)) => stream.put(encode(&state)),
            _ => Ok(()),
        }
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
            // The states put: those dropped while no subscriber matched were never published.
            state_seqs: self.state.as_ref().and_then(|s| Some((s.dropped, s.sent.checked_sub(1)?))),
            scene: Some(SceneRef { digest: format!("{digest:016x}"), spec: spec.clone() }),
        };
        publisher.put(ZBytes::from(encode(&result))).wait().map_err(|e| SceneError::Transport(format!("result: {e}")))
    }
}
