//! The ingest role on the live Zenoh receive path. A sample's key is parsed once into its site,
//! source and [`EdgeStream`], and its encoding must tag the stream's message (else it is counted
//! `wrong-schema`, see `risktwin_transport::stream`); the [`IngestWorker`] decodes the payload once (decode → validate →
//! exactly-once → clock mapping → alignment), stamped with the cloud's clock, and records what
//! it accepted byte for byte. With the twin role on, every snapshot updates the [`TwinOutputs`],
//! and what a tick produced (scene boxes, risk) is recorded into the worker's recording (the
//! cloud's only one) and handed to the publisher task.
//!
//! Publishing from inside a Zenoh callback could block it: outputs go to the publisher task
//! through a channel.

use super::ack::AckSources;
use super::id_conflicts::IdConflicts;
use super::loss::LossCounts;
use super::summary::STREAMS;
use crate::ingest::{AcceptedMessage, IngestWorker, ObservedKinematics, SnapshotDigest};
use crate::twin::fidelity::distribution::Distribution;
use crate::twin::outputs::TwinOutputs;
use crate::twin::risk::{RiskAssessor, RiskConfig};
use crate::twin::watch::{WatchCounts, WatchedEpisode};
use crate::viz::VizFeed;
use crate::warning::{HazardWarner, WarningSink, WarningSummary};
use load::LoadGauge;
use risktwin_align::{DropReason, IngestConfig, MAX_EDGE_PAYLOAD_BYTES, SeqProgress};
use risktwin_common::scenario::ScenarioSpec;
use risktwin_common::telemetry::{ObjectList, ScenarioResult, VehicleStateSample};
use risktwin_protos::convert::foxglove::{FOXGLOVE_GRID, FOXGLOVE_SCENE_UPDATE};
use risktwin_protos::recording::{Recorder, RecordingError};
use risktwin_store::recordings::{RotationConfig, SegmentError, Segments};
use risktwin_transport::keyexpr::{CloudOutput, cloud_output, parse_edge_key};
use risktwin_transport::recovery::is_recovered;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::bytes::Encoding;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::zenoh::session::ZenohId;
use risktwin_transport::{EdgeStream, SiteId, StreamLoss, protobuf};
use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::time::Instant;
use thiserror::Error;
use tokio::sync::mpsc::UnboundedSender;

mod acks;
#[cfg(test)]
mod departure_tests;
mod emit;
mod load;
mod report;

pub(super) use acks::spawn_acks;
use emit::emit;
pub(super) use report::watch_metrics;

/// Sources whose wrong-schema samples are logged; beyond, they are only counted.
const MAX_LOGGED: usize = 100;

/// The twin lag's histogram bin, s.
const LAG_BIN_S: f64 = 1e-3;

/// One message of a scene's ground truth.
#[derive(Debug, Clone, PartialEq)]
pub enum GroundTruth {
    /// A connected vehicle's true state (`scene/gt/<source>`).
    Vehicle { source: String, sample: VehicleStateSample },
    /// Every other object's true state (`scene/objects`).
    Objects(ObjectList),
}

/// Where a sample came from, as its Zenoh metadata tells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Origin {
    /// It came from an edge's cache (see [`is_recovered`]).
    pub recovered: bool,
    /// The session that published it (its source info), when the sample says.
    pub publisher: Option<ZenohId>,
}

impl Origin {
    /// The origin `sample` tells of.
    pub fn of(sample: &Sample) -> Origin {
        Origin { recovered: is_recovered(sample), publisher: sample.source_info().map(|i| i.source_id().zid()) }
    }
}

/// What became of one sample ([`LiveIngest::handle`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handled {
    Accepted,
    /// Refused, and counted under this reason.
    Dropped(DropReason),
}

impl Handled {
    /// Whether a sharded worker forwards it to the union: accepted, or refused only by this
    /// process's clock estimate (`future-timestamp`: a worker that took a source over anchors
    /// its estimate on samples from the edge's cache, which arrive late) or its load (`shed`);
    /// the union judges it again. Every other refusal holds wherever it is made.
    pub fn forwarded(self) -> bool {
        matches!(self, Handled::Accepted | Handled::Dropped(DropReason::FutureTimestamp | DropReason::Shed))
    }
}

/// Where a recording goes: buffered, since the recorder writes many small records.
pub type RecordingFile = BufWriter<File>;

/// Where the cloud records.
#[derive(Debug, Clone, Copy)]
pub enum RecordTo<'a> {
    /// One MCAP file.
    File(&'a Path),
    /// Rotating segments with a catalogue in a folder.
    Segments(&'a RotationConfig),
}

/// Why the recording failed.
#[derive(Debug, Error)]
pub enum RecordError {
    #[error(transparent)]
    Segments(#[from] SegmentError),
    #[error("creating the recording {path}: {source}")]
    Create { path: String, source: std::io::Error },
    #[error("recording: {0}")]
    Recording(#[from] RecordingError),
    #[error("flushing the recording: {0}")]
    Flush(std::io::Error),
}

/// Schema names of the cloud outputs, as recorded (for readers of a recording).
pub const OUTPUT_SCHEMAS: [(CloudOutput, &str); 4] = [
    (CloudOutput::RiskField, FOXGLOVE_GRID),
    (CloudOutput::RiskReport, "risktwin.v1.RiskReport"),
    (CloudOutput::Scene, FOXGLOVE_SCENE_UPDATE),
    (CloudOutput::Loop, LOOP_EVENT),
];

/// The schema of the loop's events in a recording.
const LOOP_EVENT: &str = "risktwin.v1.LoopEvent";

/// One message for the publisher task.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Publication {
    pub(crate) key: String,
    /// The full name of the message (its encoding's schema).
    pub(crate) message: &'static str,
    /// The cloud time it was produced at, ns (its log time in a recording).
    pub(crate) log_ns: u64,
    pub(crate) payload: Vec<u8>,
}

/// How long after its last road map a site is no longer taken to run a scene (the authority
/// republishes the map every second).
const SCENE_GONE: std::time::Duration = std::time::Duration::from_secs(3);

/// The worker, the twin and the counts around them; lives behind a mutex shared with the Zenoh
/// callback.
pub struct LiveIngest {
    worker: IngestWorker<RecordingFile>,
    received: HashMap<String, [u64; STREAMS]>,
    /// Of `received`, those recovered from an edge's cache.
    recovered: HashMap<String, [u64; STREAMS]>,
    /// Each source's site (from the key of its first accepted message).
    sites: HashMap<String, String>,
    /// Sites a scene's road map came from, and when the last one came.
    scene_sites: HashMap<String, Instant>,
    named: usize,
    outputs: Option<TwinOutputs>,
    publish: Option<UnboundedSender<Publication>>,
    /// Where finished episodes go (the loop role), when it runs.
    episodes: Option<UnboundedSender<WatchedEpisode>>,
    digest: SnapshotDigest,
    /// Each emitted snapshot's lag behind the cloud's clock, s.
    lag: Distribution,
    /// The same lags as a Prometheus histogram (a no-op without `--metrics-listen`): observed
    /// one by one, which a count copied at scrape time cannot give.
    lag_metric: metrics::Histogram,
    last_receive_ns: i64,
    last_sample: Option<Instant>,
    /// Replay-ingest mode: receive times come from the messages' replay-time attachments.
    replay_time: bool,
    /// The encoding each stream's samples must carry, by [`EdgeStream::index`].
    encodings: [Encoding; STREAMS],
    /// Sources whose wrong-schema samples were already logged (once each).
    wrong_schema_logged: HashSet<String>,
    /// Sources whose too-large samples were already logged (once each).
    too_large_logged: HashSet<String>,
    /// Samples the edge-stream subscriber reported lost for good.
    losses: LossCounts,
    /// Sources published by two live sessions at once.
    conflicts: IdConflicts,
    /// Sources whose edge left (its liveliness token went), with the session that published
    /// them last: their next sample decides whether a new process took the name (another
    /// session: its numbers start over) or the same one came back (a router restart: its
    /// numbers go on, and what its cache sends again is the old count's, not a new start).
    departed: HashMap<String, ZenohId>,
    /// How far behind the ingest runs, and what it sheds ([`load`]).
    load: LoadGauge,
    /// Where the key of each stream's first accepted sample goes, to be declared (see
    /// [`super::routes`]).
    route_keys: Option<UnboundedSender<String>>,
    /// The warning role: every accepted state re-assesses its pairs, and warnings go to the sink
    /// at once, before the tick work the message triggers and before it is recorded.
    warnings: Option<(HazardWarner, Box<dyn WarningSink>)>,
    /// The sources to acknowledge ([`super::ack`]).
    acks: AckSources,
    /// The segments and catalogue of a rotating recording (`--record-dir`).
    segments: Option<Segments>,
    /// The viz role's input: every accepted state goes there (copied only while a client is
    /// connected).
    viz: Option<VizFeed>,
}

impl LiveIngest {
    /// A worker recording to `record` when given, feeding `outputs` (the twin and risk roles)
    /// when given.
    pub fn new(record: Option<RecordTo<'_>>, outputs: Option<TwinOutputs>) -> Result<Self, RecordError> {
        Self::with_config(record, outputs, IngestConfig::default())
    }

    /// [`LiveIngest::new`] with another ingest configuration (tick, lateness, …).
    pub fn with_config(
        record: Option<RecordTo<'_>>,
        outputs: Option<TwinOutputs>,
        config: IngestConfig,
    ) -> Result<Self, RecordError> {
        let (file, segments) = match record {
            Some(RecordTo::File(path)) => {
                let file = File::create(path)
                    .map_err(|source| RecordError::Create { path: path.display().to_string(), source })?;
                (Some(BufWriter::new(file)), None)
            }
            Some(RecordTo::Segments(rotation)) => {
                let (segments, file) = Segments::start(rotation.clone())?;
                (Some(file), Some(segments))
            }
            None => (None, None),
        };
        // Fed in real time: a chunk closes a second after it opened (see
        // `flush_recording_if_due`), what a killed cloud can lose.
        let recorder = file.map(Recorder::live).transpose()?;
        Ok(LiveIngest {
            worker: IngestWorker::new(config, recorder),
            received: HashMap::new(),
            recovered: HashMap::new(),
            sites: HashMap::new(),
            scene_sites: HashMap::new(),
            named: 0,
            outputs,
            publish: None,
            episodes: None,
            digest: SnapshotDigest::default(),
            lag: Distribution::new(LAG_BIN_S),
            lag_metric: metrics::histogram!(super::live_metrics::SNAPSHOT_LAG),
            last_receive_ns: i64::MIN,
            last_sample: None,
            replay_time: false,
            encodings: EdgeStream::ALL.map(|s| protobuf(s.message())),
            wrong_schema_logged: HashSet::new(),
            too_large_logged: HashSet::new(),
            losses: LossCounts::default(),
            conflicts: IdConflicts::default(),
            departed: HashMap::new(),
            load: LoadGauge::default(),
            route_keys: None,
            warnings: None,
            acks: AckSources::default(),
            segments,
            viz: None,
        })
    }

    /// Switches replay-ingest mode on or off (see `CloudConfig::replay_time`).
    pub fn with_replay_time(mut self, on: bool) -> Self {
        self.replay_time = on;
        self
    }

    /// Sends the key of each stream's first accepted sample to `keys` (see [`super::routes`]).
    pub fn with_route_keys(mut self, keys: Option<UnboundedSender<String>>) -> Self {
        self.route_keys = keys;
        self
    }

    /// Runs the warning path ([`crate::warning`]) on every accepted state, handing each warning to
    /// the sink (which puts it), when given.
    pub fn with_warnings(mut self, path: Option<(HazardWarner, Box<dyn WarningSink>)>) -> Self {
        self.warnings = path;
        self
    }

    /// Hands every accepted vehicle state (and the scene maps' roads) to `viz` when given.
    pub fn with_viz(mut self, viz: Option<VizFeed>) -> Self {
        self.viz = viz;
        self
    }

    /// `site`'s scene published its road map: the viz role shows it as the site's road.
    pub fn set_viz_road(&mut self, site: &str, road: &risktwin_common::road::Road) {
        if let Some(viz) = &self.viz {
            viz.set_road(site, road);
        }
    }

    /// `site`'s scene published its road map: the warning path measures lane TTC on it.
    pub fn set_warning_road(&mut self, site: &str, road: &risktwin_common::road::Road) {
        if let Some((warner, _)) = self.warnings.as_mut() {
            warner.set_site_road(site, road.clone());
        }
    }

    /// What the warning path did, when it runs.
    pub fn warning_summary(&self) -> Option<WarningSummary> {
        self.warnings.as_ref().map(|(warner, sink)| {
            let mut summary = warner.summary();
            sink.count(&mut summary);
            summary
        })
    }

    /// Counts samples the edge-stream subscriber could neither receive nor recover.
    pub fn record_loss(&mut self, loss: &StreamLoss) {
        self.losses.record(loss);
    }

    /// Counts a message of the cloud's own subscriptions (a scene map) dropped for `reason`.
    pub fn reject(&mut self, reason: DropReason) {
        self.worker.reject(reason);
    }

    /// A message of a scene's ground truth, received on `key`: recorded there (its own
    /// topics, beside the twin's) and measured against by the twin.
    pub fn observe_truth(&mut self, key: &str, site: &str, truth: GroundTruth) -> Result<(), RecordingError> {
        let log_ns = unix_ns() as u64;
        if let Some(rec) = self.worker.recorder_mut() {
            match &truth {
                GroundTruth::Vehicle { sample, .. } => rec.record(key, log_ns, sample)?,
                GroundTruth::Objects(list) => rec.record(key, log_ns, list)?,
            }
        }
        if let Some(outputs) = self.outputs.as_mut() {
            match truth {
                GroundTruth::Vehicle { source, sample } => outputs.observe_truth_vehicle(site, &source, &sample),
                GroundTruth::Objects(list) => outputs.observe_truth_objects(site, list),
            }
        }
        Ok(())
    }

    /// How the risk role evaluates; `None` without it.
    pub fn risk_config(&self) -> Option<RiskConfig> {
        self.outputs.as_ref().and_then(TwinOutputs::risk_config)
    }

    /// `site`'s scene published its road map: the risk role assesses that site with
    /// `assessor` (built on it) from now on.
    pub fn set_site_risk(&mut self, site: &str, assessor: RiskAssessor) {
        if let Some(outputs) = self.outputs.as_mut() {
            outputs.set_site_risk(site, assessor);
        }
    }

    /// Sheds lower-priority streams once live states wait longer than `after` ([`load`]);
    /// `None` (the default): the wait is measured and reported, nothing is shed.
    pub(crate) fn with_shedding(mut self, after: Option<std::time::Duration>) -> Self {
        self.load = LoadGauge::new(after);
        self
    }

    /// Hands the twin's outputs to `publish` (the publisher task) when given.
    pub(crate) fn with_publisher(mut self, publish: Option<UnboundedSender<Publication>>) -> Self {
        self.publish = publish;
        self
    }

    /// Counts a sample whose key is no edge stream's (`bad-key`).
    pub fn reject_bad_key(&mut self) {
        self.worker.reject(DropReason::BadKey);
    }

    /// Handles one sample received on `key`; the receive time is read here, once, from the
    /// system clock and never goes backwards (the aligner needs non-decreasing receive times).
    /// `replay_ns` is the message's replay-time attachment, used instead of the clock in
    /// replay-time mode (and required there). `origin`: whether the sample came from the edge's
    /// cache, and which session published it. Tells whether the message was accepted.
    pub fn handle(
        &mut self,
        key: &str,
        encoding: &Encoding,
        payload: &[u8],
        replay_ns: Option<i64>,
        origin: Origin,
    ) -> Result<Handled, RecordingError> {
        let recovered = origin.recovered;
        let now = Instant::now();
        self.last_sample = Some(now);
        if let Some(level) = self.load.roll(now) {
            self.worker.set_shed(self.load.shed_mask());
            let delay_ms = self.load.summary().queue_delay_ms.unwrap_or(0);
            let shed: Vec<&str> = self.load.shed().iter().map(|s| s.as_str()).collect();
            tracing::warn!("ingest: live states wait {delay_ms} ms at least: shedding level {level} ({shed:?})");
        }
        let wall_ns = match (self.replay_time, replay_ns) {
            (false, _) => unix_ns(),
            (true, Some(t)) => t,
            (true, None) => {
                self.worker.reject(DropReason::NoReplayTime);
                return Ok(Handled::Dropped(DropReason::NoReplayTime));
            }
        };
        let receive_ns = wall_ns.max(self.last_receive_ns);
        self.last_receive_ns = receive_ns;
        let Some(parsed) = parse_edge_key(key) else {
            self.worker.reject(DropReason::BadKey);
            return Ok(Handled::Dropped(DropReason::BadKey));
        };
        // The first sample of a departed source: only another session starts its numbers over.
        if !self.departed.is_empty()
            && let Some(left) = self.departed.remove(parsed.source)
            && origin.publisher != Some(left)
        {
            self.worker.restart_source(parsed.source);
        }
        // Before any check: a second process under this id is told by its session, whatever
        // becomes of its samples (numbered like the first's, most are refused as duplicates).
        if let Some(publisher) = origin.publisher {
            self.conflicts.observe(parsed.source, publisher, now);
        }
        // Before anything reads it: no edge stream is that large (see MAX_EDGE_PAYLOAD_BYTES).
        if payload.len() > MAX_EDGE_PAYLOAD_BYTES {
            self.worker.reject(DropReason::TooLarge);
            if self.too_large_logged.len() < MAX_LOGGED && self.too_large_logged.insert(parsed.source.to_owned()) {
                tracing::warn!(
                    "ingest: refused {key}: {} bytes, more than {MAX_EDGE_PAYLOAD_BYTES} (counted too-large)",
                    payload.len()
                );
            }
            return Ok(Handled::Dropped(DropReason::TooLarge));
        }
        if encoding != &self.encodings[parsed.stream.index()] {
            self.worker.reject(DropReason::WrongSchema);
            if self.wrong_schema_logged.len() < MAX_LOGGED && self.wrong_schema_logged.insert(parsed.source.to_owned())
            {
                let expected = &self.encodings[parsed.stream.index()];
                tracing::warn!(
                    "ingest: refused {key}: encoding {encoding}, expected {expected} (counted wrong-schema)"
                );
            }
            return Ok(Handled::Dropped(DropReason::WrongSchema));
        }
        let digest = &mut self.digest;
        let lag = &mut self.lag;
        let lag_metric = &self.lag_metric;
        let mut outputs = self.outputs.as_mut();
        let mut ticked = false;
        let warnings = self.warnings.as_mut();
        let load = &mut self.load;
        // The warning path runs as soon as the message is accepted: before the snapshots it
        // makes due are applied and before it is recorded (`IngestWorker::handle_then`).
        let on_accepted = |msg: &AcceptedMessage| {
            // Only live states measure the load: a recovered sample waited in a cache, and the
            // other streams may be shed.
            if !recovered && parsed.stream == EdgeStream::State {
                load.observe(receive_ns - msg.cloud_ns);
            }
            if let Some((warner, sink)) = warnings {
                warner.on_state(parsed.site, parsed.source, msg, receive_ns, &mut **sink);
            }
        };
        let accepted =
            self.worker.handle_then(parsed.source, parsed.stream, key, payload, receive_ns, on_accepted, |s| {
                digest.add(s);
                let lag_s = receive_ns.saturating_sub(s.tick_ns).max(0) as f64 * 1e-9;
                lag.add(lag_s);
                lag_metric.record(lag_s);
                if let Some(outputs) = outputs.as_mut() {
                    outputs.apply(s);
                    ticked = true;
                }
            })?;
        let accepted = accepted.is_some();
        if accepted && parsed.stream == EdgeStream::State {
            self.watch_state(parsed.site, parsed.source, payload);
            if let Some(viz) = &self.viz {
                viz.offer(key, parsed.stream.message(), receive_ns.max(0) as u64, payload);
            }
        }
        if accepted {
            self.acks.touch(parsed.site, parsed.source, origin.publisher, now);
            if !self.sites.contains_key(parsed.source) {
                self.sites.insert(parsed.source.to_owned(), parsed.site.to_owned());
            }
            // Look up by &str first so that a known source costs no allocation.
            let counts = match self.received.get_mut(parsed.source) {
                Some(c) => c,
                None => self.received.entry(parsed.source.to_owned()).or_default(),
            };
            let count = &mut counts[parsed.stream.index()];
            if *count == 0
                && let Some(keys) = &self.route_keys
            {
                // A closed receiver means shutdown: nothing left to speed up.
                let _ = keys.send(key.to_owned());
            }
            *count += 1;
            if recovered {
                let counts = match self.recovered.get_mut(parsed.source) {
                    Some(c) => c,
                    None => self.recovered.entry(parsed.source.to_owned()).or_default(),
                };
                counts[parsed.stream.index()] += 1;
            }
        }
        if let Some(outputs) = self.outputs.as_mut() {
            // Sources the worker numbered since the last message get their names in the twin.
            while let Some(name) = self.worker.source_name(self.named) {
                if let Some(site) = self.sites.get(name) {
                    outputs.twin_mut().name_source(self.named, name, site);
                }
                self.named += 1;
            }
            if ticked && let Some(tick) = outputs.after_tick(|site| SiteId::new(site).is_ok()) {
                emit(tick, receive_ns, self.worker.recorder_mut(), self.publish.as_ref())?;
            }
        }
        self.forward_episodes();
        // A message not accepted was counted under its reason by the worker.
        Ok(self.worker.last_drop().map_or(Handled::Accepted, Handled::Dropped))
    }

    /// Hands the episodes the twin finished watching to `episodes` (the loop role).
    pub(crate) fn with_episodes(mut self, episodes: Option<UnboundedSender<WatchedEpisode>>) -> Self {
        self.episodes = episodes;
        self
    }

    /// Watches `site/edge` in the twin for the episode of `spec` the loop is pushing.
    pub(crate) fn watch_episode(
        &mut self,
        site: &str,
        edge: &str,
        spec_id: &str,
        spec: &ScenarioSpec,
        push_seq: Option<i64>,
    ) {
        if let Some(outputs) = self.outputs.as_mut() {
            outputs.watch_mut().begin(site, edge, spec_id, spec, push_seq);
        }
    }

    /// An edge's `ScenarioResult`: scored against the twin's watch, then on to the loop.
    pub(crate) fn episode_result(&mut self, site: &str, edge: &str, result: ScenarioResult) {
        if let Some(outputs) = self.outputs.as_mut() {
            outputs.episode_result(site, edge, result, Instant::now());
        }
        self.forward_episodes();
    }

    /// Edge `site/source` left: a next process starts its sequence numbers over. Whether the
    /// next sample is from one is known by its session when the last one's is known; otherwise
    /// the deduplicator decides on the next numbers ([`IngestWorker::restart_source`]).
    pub(crate) fn edge_left(&mut self, site: &str, source: &str) {
        if self.sites.get(source).is_some_and(|s| s == site) {
            match self.conflicts.last_publisher(source) {
                Some(publisher) => {
                    self.departed.insert(source.to_owned(), publisher);
                }
                None => self.worker.restart_source(source),
            }
            if let Some((warner, sink)) = self.warnings.as_mut() {
                warner.source_left(site, source, &mut **sink);
            }
        }
    }

    /// A scene's road map came from `site`: the twin watches the scene's episode, and the site's
    /// edges are scene participants from now on (the loop pushes them nothing).
    pub(crate) fn scene_seen(&mut self, site: &str) {
        let now = Instant::now();
        match self.scene_sites.get_mut(site) {
            Some(at) => *at = now,
            None => {
                self.scene_sites.insert(site.to_owned(), now);
            }
        }
        // Only the loop takes the episodes; without it a watch would never end.
        if let (Some(outputs), Some(_)) = (self.outputs.as_mut(), self.episodes.as_ref()) {
            outputs.watch_mut().begin_scene(site);
        }
    }

    /// Whether a scene runs at `site`: its road map (republished every second) came within the
    /// last [`SCENE_GONE`].
    pub(crate) fn is_scene_site(&self, site: &str) -> bool {
        self.scene_sites.get(site).is_some_and(|at| at.elapsed() < SCENE_GONE)
    }

    /// Hands on the watched episodes whose results are older than the watch waits
    /// ([`crate::twin::watch::SETTLE`]).
    pub(crate) fn expire_episodes(&mut self) {
        if let Some(outputs) = self.outputs.as_mut() {
            outputs.watch_mut().expire(Instant::now());
        }
        self.forward_episodes();
    }

    /// The number of state messages accepted from `source` of `site` so far (a vehicle has
    /// some, an RSU none).
    pub(crate) fn states_from(&self, site: &str, source: &str) -> u64 {
        if self.sites.get(source).is_none_or(|s| s != site) {
            return 0;
        }
        self.received.get(source).map_or(0, |c| c[EdgeStream::State.index()])
    }

    /// Records one event of the loop (when recording) on `site`'s loop topic, stamped now.
    pub(crate) fn record_loop_event(
        &mut self,
        site: &str,
        event: &risktwin_protos::v1::LoopEvent,
    ) -> Result<(), RecordingError> {
        let (Some(rec), Ok(site)) = (self.worker.recorder_mut(), SiteId::new(site)) else { return Ok(()) };
        let log_ns = unix_ns() as u64;
        let channel = rec.channel(&cloud_output(&site, CloudOutput::Loop), LOOP_EVENT)?;
        rec.write(channel, log_ns, log_ns, &prost::Message::encode_to_vec(event))
    }

    /// The twin's watch of pushed episodes, so far.
    pub(crate) fn watch_counts(&self) -> WatchCounts {
        self.outputs.as_ref().map(|o| o.watch().counts()).unwrap_or_default()
    }

    /// A state message of an edge the twin watches goes to the watch as well (decoded again:
    /// only a pushed episode's vehicle, 50 messages a second).
    fn watch_state(&mut self, site: &str, source: &str, payload: &[u8]) {
        let Some(outputs) = self.outputs.as_mut().filter(|o| o.watch().is_watching(site, source)) else { return };
        if let Ok(sample) = risktwin_protos::decode::<VehicleStateSample>(payload) {
            outputs.watch_mut().state(site, source, ObservedKinematics::from(&sample));
        }
    }

    fn forward_episodes(&mut self) {
        let (Some(outputs), Some(tx)) = (self.outputs.as_mut(), self.episodes.as_ref()) else { return };
        for episode in outputs.watch_mut().take_done() {
            // A closed channel means the loop has stopped: nothing more to hand over.
            let _ = tx.send(episode);
        }
    }

    /// Closes the recording's open chunk once it is a second old, so a cloud that goes quiet
    /// and is then killed keeps what it received (a chunk otherwise closes at the next message);
    /// of a rotating recording, closes the segment and opens the next once it is due.
    pub fn flush_recording_if_due(&mut self) -> Result<(), RecordError> {
        let Some(rec) = self.worker.recorder_mut() else { return Ok(()) };
        if let Some(segments) = self.segments.as_mut() {
            segments.check()?;
            if segments.due(rec.segment_messages()) {
                return Ok(segments.rotate(|next| Ok(rec.rotate(next)?))?);
            }
        }
        Ok(rec.flush_if_due()?)
    }

    /// The sources to acknowledge.
    pub(crate) fn acks_mut(&mut self) -> &mut AckSources {
        &mut self.acks
    }

    /// How far each stream of `source` is accounted for ([`IngestWorker::progress`]).
    pub(crate) fn progress(&self, source: &str) -> Vec<(EdgeStream, SeqProgress)> {
        self.worker.progress(source)
    }

    /// The streams shed now (an overloaded ingest; [`load`]).
    pub(crate) fn shed_streams(&self) -> &'static [EdgeStream] {
        self.load.shed()
    }

    /// When the last sample (accepted or not) arrived.
    pub(crate) fn last_sample(&self) -> Option<Instant> {
        self.last_sample
    }

    /// The twin, when the twin role runs.
    pub fn twin(&self) -> Option<&crate::twin::Twin> {
        self.outputs.as_ref().map(TwinOutputs::twin)
    }

    /// Stops publishing (the publisher task ends once the channel is empty).
    pub(crate) fn close_publisher(&mut self) {
        self.publish = None;
    }
}
