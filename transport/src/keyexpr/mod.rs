//! The one place where RiskTwin's Zenoh key expressions are spelled (see `docs/keyexpr.md`).
//!
//! Every key starts with `risktwin/v1/<site>/` and is named by direction:
//! - edge→cloud streams: `risktwin/v1/<site>/<source_id>/{state,can,perception,rsu,signal}`
//! - an edge's road map: `risktwin/v1/<site>/<source_id>/map` (not an ingest stream)
//! - cloud→edge pushes: `risktwin/v1/<site>/<source_id>/{scenario,policy,control,warning}`
//! - cloud outputs: `risktwin/v1/<site>/cloud/{risk_field,risk_report,snapshot}`
//! - library queryables: `risktwin/v1/<site>/cloud/library/**`
//! - liveliness tokens: `risktwin/v1/<site>/alive/<source_id>`
//! - sharded ingest: workers' tokens `risktwin/v1/<site>/cloud/workers/<worker>`, what they
//!   accepted, forwarded to the union: `risktwin/v1/<site>/cloud/ingested/<source>/<stream>`
//!
//! Ids are validated once, into [`SiteId`] and [`SourceId`], so that a key built from them is
//! always a valid, wildcard-free key expression.

use std::fmt;
use thiserror::Error;

/// The scheme's root and version: a breaking change of the payloads bumps `v1`.
pub const ROOT: &str = "risktwin/v1";
/// The id chunk under which the cloud publishes; reserved, no edge may use it.
pub const CLOUD_CHUNK: &str = "cloud";
/// The chunk under which liveliness tokens live; reserved, no edge may use it.
pub const ALIVE_CHUNK: &str = "alive";
/// The chunk of a scene's physics plane (ground truth out, controls back); reserved.
pub const SCENE_CHUNK: &str = "scene";
/// Longest accepted id, in bytes (keeps keys short on the wire).
pub const MAX_ID_LEN: usize = 64;

/// Why an id or a key expression was rejected.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum KeyError {
    #[error("{what} id is empty")]
    EmptyId { what: &'static str },
    #[error("{what} id {id:?} is {len} bytes long, at most {MAX_ID_LEN} allowed")]
    IdTooLong { what: &'static str, id: String, len: usize },
    #[error("{what} id {id:?} contains {ch:?}; allowed are ASCII letters, digits, '-', '_' and '.'")]
    ForbiddenChar { what: &'static str, id: String, ch: char },
    #[error("{what} id {id:?} is reserved by the key-expression scheme")]
    ReservedId { what: &'static str, id: String },
    #[error("key {key:?} is not a RiskTwin edge→cloud stream (risktwin/v1/<site>/<source>/<stream>)")]
    NotEdgeStream { key: String },
}

/// Checks one id chunk: non-empty, short, and made only of `[A-Za-z0-9_.-]`, which excludes
/// `/`, the wildcards `*` and `$`, and Zenoh's forbidden `?` and `#`.
fn validate_id(what: &'static str, id: &str) -> Result<(), KeyError> {
    if id.is_empty() {
        return Err(KeyError::EmptyId { what });
    }
    if id.len() > MAX_ID_LEN {
        return Err(KeyError::IdTooLong { what, id: id.to_owned(), len: id.len() });
    }
    if let Some(ch) = id.chars().find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))) {
        return Err(KeyError::ForbiddenChar { what, id: id.to_owned(), ch });
    }
    Ok(())
}

/// A deployment site (a test track, a city): the second level of every key.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SiteId(String);

impl SiteId {
    /// Validates `id` as a site id.
    pub fn new(id: impl Into<String>) -> Result<Self, KeyError> {
        let id = id.into();
        validate_id("site", &id)?;
        Ok(SiteId(id))
    }
    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

/// An edge source (a vehicle or an RSU); `cloud` and `alive` are reserved.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SourceId(String);

impl SourceId {
    /// Validates `id` as an edge source id.
    pub fn new(id: impl Into<String>) -> Result<Self, KeyError> {
        let id = id.into();
        validate_id("source", &id)?;
        if id == CLOUD_CHUNK || id == ALIVE_CHUNK || id == SCENE_CHUNK {
            return Err(KeyError::ReservedId { what: "source", id });
        }
        Ok(SourceId(id))
    }
    /// The id as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for SiteId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl fmt::Display for SourceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Streams an edge publishes towards the cloud.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EdgeStream {
    /// Vehicle state (pose, speed), 50 Hz.
    State,
    /// CAN-like signal frames, 100 Hz.
    Can,
    /// The vehicle's perceived object list, 10 Hz.
    Perception,
    /// An RSU's object list, 10 Hz.
    Rsu,
    /// Traffic-light phases, from an RSU.
    Signal,
}

impl EdgeStream {
    /// Every edge→cloud stream, in a fixed order (the index of [`EdgeStream::index`]).
    pub const ALL: [EdgeStream; 5] =
        [EdgeStream::State, EdgeStream::Can, EdgeStream::Perception, EdgeStream::Rsu, EdgeStream::Signal];

    /// The last chunk of the key.
    pub const fn as_str(self) -> &'static str {
        match self {
            EdgeStream::State => "state",
            EdgeStream::Can => "can",
            EdgeStream::Perception => "perception",
            EdgeStream::Rsu => "rsu",
            EdgeStream::Signal => "signal",
        }
    }

    /// The full name of the protobuf message the stream carries (package `risktwin.v1`, which
    /// is the schema version); every sample is tagged with it (see [`crate::stream`]).
    pub const fn message(self) -> &'static str {
        match self {
            EdgeStream::State => "risktwin.v1.VehicleState",
            EdgeStream::Can => "risktwin.v1.CanFrame",
            EdgeStream::Perception => "risktwin.v1.ObjectList",
            EdgeStream::Rsu => "risktwin.v1.RsuObservation",
            EdgeStream::Signal => "risktwin.v1.SignalPhase",
        }
    }

    /// Position in [`EdgeStream::ALL`], for per-stream counters held in arrays.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The stream named by a key's last chunk.
    pub fn from_chunk(chunk: &str) -> Option<Self> {
        EdgeStream::ALL.into_iter().find(|s| s.as_str() == chunk)
    }
}

/// Pushes the cloud sends to one edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CloudToEdge {
    /// A scenario for the edge to execute.
    Scenario,
    /// New policy weights.
    Policy,
    /// A control command.
    Control,
    /// A hazard warning (`HazardWarning`) about another vehicle, from the cloud's warning role.
    Warning,
    /// A delivery acknowledgement (`DeliveryAck`): how far the cloud's ingest has accounted for
    /// the edge's streams.
    Ack,
}

impl CloudToEdge {
    /// The last chunk of the key.
    pub const fn as_str(self) -> &'static str {
        match self {
            CloudToEdge::Scenario => "scenario",
            CloudToEdge::Policy => "policy",
            CloudToEdge::Control => "control",
            CloudToEdge::Warning => "warning",
            CloudToEdge::Ack => "ack",
        }
    }

    /// The full name of the protobuf message the push carries (its samples' schema tag).
    pub const fn message(self) -> &'static str {
        match self {
            CloudToEdge::Scenario => "risktwin.v1.ScenarioPush",
            CloudToEdge::Policy => "risktwin.v1.PolicyUpdate",
            CloudToEdge::Control => "risktwin.v1.ControlCommand",
            CloudToEdge::Warning => "risktwin.v1.HazardWarning",
            CloudToEdge::Ack => "risktwin.v1.DeliveryAck",
        }
    }
}

/// What the cloud publishes for everyone at a site.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CloudOutput {
    /// The risk field grid (`foxglove.Grid`).
    RiskField,
    /// The risk report.
    RiskReport,
    /// A twin snapshot.
    Snapshot,
    /// The twin's vehicles as boxes (`foxglove.SceneUpdate`).
    Scene,
    /// The closed loop's events (`risktwin.v1.LoopEvent`: pushes, retries, episodes stored).
    Loop,
    /// The road the site's twin runs on as lines (`foxglove.SceneUpdate`): a topic of the viz
    /// role's live view, not put on Zenoh.
    Road,
}

impl CloudOutput {
    /// The last chunk of the key.
    pub const fn as_str(self) -> &'static str {
        match self {
            CloudOutput::RiskField => "risk_field",
            CloudOutput::RiskReport => "risk_report",
            CloudOutput::Snapshot => "snapshot",
            CloudOutput::Scene => "scene",
            CloudOutput::Loop => "loop",
            CloudOutput::Road => "road",
        }
    }
}

/// Reports an edge sends back about a push it executed (not an ingest stream: the ingest
/// subscriber sees these keys but the key parser skips them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EdgeReport {
    /// The outcome of a pushed scenario (`ScenarioResult`).
    ScenarioResult,
}

impl EdgeReport {
    /// The last chunk of the key.
    pub const fn as_str(self) -> &'static str {
        match self {
            EdgeReport::ScenarioResult => "scenario_result",
        }
    }

    /// The full name of the protobuf message the report carries (its samples' schema tag).
    pub const fn message(self) -> &'static str {
        match self {
            EdgeReport::ScenarioResult => "risktwin.v1.ScenarioResult",
        }
    }
}

/// `risktwin/v1/<site>/<source>/<stream>`: where `source` publishes `stream`.
pub fn edge_stream(site: &SiteId, source: &SourceId, stream: EdgeStream) -> String {
    format!("{ROOT}/{site}/{source}/{}", stream.as_str())
}

/// `risktwin/v1/<site|*>/*/<stream>`: one stream from every source at one site (or every site).
pub fn edge_stream_all(site: Option<&SiteId>, stream: EdgeStream) -> String {
    format!("{ROOT}/{}/*/{}", site_or_star(site), stream.as_str())
}

/// `risktwin/v1/<site|*>/*/*`: every edge→cloud stream of every source (the subscriber also
/// sees other keys of that shape; [`parse_edge_key`] tells them apart).
pub fn edge_streams_all(site: Option<&SiteId>) -> String {
    format!("{ROOT}/{}/*/*", site_or_star(site))
}

/// `risktwin/v1/<site>/<source>/<push>`: what the cloud sends to one edge.
pub fn cloud_to_edge(site: &SiteId, source: &SourceId, push: CloudToEdge) -> String {
    format!("{ROOT}/{site}/{source}/{}", push.as_str())
}

/// `risktwin/v1/<site>/cloud/<output>`.
pub fn cloud_output(site: &SiteId, output: CloudOutput) -> String {
    format!("{ROOT}/{site}/{CLOUD_CHUNK}/{}", output.as_str())
}

/// The site of a cloud `output` key `risktwin/v1/<site>/cloud/<output>`; `None` otherwise.
pub fn parse_cloud_output_key(key: &str, output: CloudOutput) -> Option<&str> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let site = rest.strip_suffix(output.as_str())?.strip_suffix('/')?.strip_suffix(CLOUD_CHUNK)?.strip_suffix('/')?;
    (!site.is_empty() && !site.contains('/')).then_some(site)
}

/// The last chunk of an edge's road-map key.
pub const MAP_CHUNK: &str = "map";

/// The message an edge's road map carries (see [`edge_map`]).
pub const EDGE_MAP_MESSAGE: &str = "risktwin.v1.RoadMap";

/// `risktwin/v1/<site>/<source>/map`: the road map `source` drives on (a `RoadMap`, sent once;
/// an imported CommonRoad recording carries its lanelet map here).
pub fn edge_map(site: &SiteId, source: &SourceId) -> String {
    format!("{ROOT}/{site}/{source}/{MAP_CHUNK}")
}

/// The site and source of a road-map key `risktwin/v1/<site>/<source>/map`; `None` otherwise.
pub fn parse_edge_map_key(key: &str) -> Option<(&str, &str)> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let mut chunks = rest.split('/');
    let (site, source, last) = (chunks.next()?, chunks.next()?, chunks.next()?);
    let reserved = source == CLOUD_CHUNK || source == ALIVE_CHUNK || source == SCENE_CHUNK;
    (last == MAP_CHUNK && chunks.next().is_none() && !site.is_empty() && !source.is_empty() && !reserved)
        .then_some((site, source))
}

/// `risktwin/v1/<site>/<source>/<report>`: what one edge reports back about a push.
pub fn edge_report(site: &SiteId, source: &SourceId, report: EdgeReport) -> String {
    format!("{ROOT}/{site}/{source}/{}", report.as_str())
}

/// `risktwin/v1/<site|*>/*/<report>`: one report kind from every edge.
pub fn edge_report_all(site: Option<&SiteId>, report: EdgeReport) -> String {
    format!("{ROOT}/{}/*/{}", site_or_star(site), report.as_str())
}

/// The site and source of a report key `risktwin/v1/<site>/<source>/<report>`; `None` otherwise.
pub fn parse_edge_report_key(key: &str, report: EdgeReport) -> Option<(&str, &str)> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let mut chunks = rest.split('/');
    let (site, source, last) = (chunks.next()?, chunks.next()?, chunks.next()?);
    let reserved = source == CLOUD_CHUNK || source == ALIVE_CHUNK || source == SCENE_CHUNK;
    (last == report.as_str() && chunks.next().is_none() && !site.is_empty() && !source.is_empty() && !reserved)
        .then_some((site, source))
}

/// `risktwin/v1/<site>/cloud/library/ranked`: the ranked-scenarios query of the library
/// (parameters in the selector, e.g. `?top=5;kind=cut-in`).
pub fn library_ranked(site: &SiteId) -> String {
    format!("{ROOT}/{site}/{CLOUD_CHUNK}/library/ranked")
}

/// `risktwin/v1/<site>/cloud/library/**`: what the library queryable answers.
pub fn library_queryable(site: &SiteId) -> String {
    format!("{ROOT}/{site}/{CLOUD_CHUNK}/library/**")
}

/// `risktwin/v1/<site|*>/cloud/library/**`: the library of one site, or of every site.
pub fn library_queryable_all(site: Option<&SiteId>) -> String {
    format!("{ROOT}/{}/{CLOUD_CHUNK}/library/**", site_or_star(site))
}

/// The site of a library query key `risktwin/v1/<site>/cloud/library/ranked`.
pub fn parse_library_ranked(key: &str) -> Option<&str> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let site = rest.strip_suffix("/cloud/library/ranked")?;
    (!site.is_empty() && !site.contains('/')).then_some(site)
}

/// `risktwin/v1/<site>/scene/truth`: a scene's ground truth, one message per physics step from
/// its authority to every participant (never an ingest stream).
pub fn scene_truth(site: &SiteId) -> String {
    format!("{ROOT}/{site}/{SCENE_CHUNK}/truth")
}

/// `risktwin/v1/<site>/scene/reply/<participant>`: a participant's join, then its controls per step.
pub fn scene_reply(site: &SiteId, participant: &SourceId) -> String {
    format!("{ROOT}/{site}/{SCENE_CHUNK}/reply/{participant}")
}

/// `risktwin/v1/<site>/scene/reply/*`: every participant's replies.
pub fn scene_replies(site: &SiteId) -> String {
    format!("{ROOT}/{site}/{SCENE_CHUNK}/reply/*")
}

/// `risktwin/v1/<site>/scene/v2x/<participant>`: a scene participant's V2X broadcasts (CAMs),
/// to every other participant's V2X layer (never an ingest stream).
pub fn scene_v2x(site: &SiteId, participant: &SourceId) -> String {
    format!("{ROOT}/{site}/{SCENE_CHUNK}/v2x/{participant}")
}

/// `risktwin/v1/<site>/scene/v2x/*`: every participant's V2X broadcasts.
pub fn scene_v2x_all(site: &SiteId) -> String {
    format!("{ROOT}/{site}/{SCENE_CHUNK}/v2x/*")
}

/// What a scene's authority publishes for the cloud on `risktwin/v1/<site>/scene/<topic>`
/// (protobuf; never an ingest stream).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneTopic {
    /// `map`: the scene's road (`RoadMap`), republished every second so late subscribers get it.
    Map,
    /// `objects`: every object of the scene's world but the ego, true state per physics step
    /// (`ObjectList`, truth ids, acceleration included).
    Objects,
    /// `truth_boxes`: a recording topic, not published: the truth at each twin tick as scene
    /// boxes (vehicles and objects), recorded by the cloud beside its twin's `cloud/scene`.
    TruthBoxes,
}

impl SceneTopic {
    fn leaf(self) -> &'static str {
        match self {
            SceneTopic::Map => "map",
            SceneTopic::Objects => "objects",
            SceneTopic::TruthBoxes => "truth_boxes",
        }
    }
}

/// `risktwin/v1/<site|*>/scene/<topic>`: `topic` of one site's scene, or of every site's.
pub fn scene_topic(site: Option<&SiteId>, topic: SceneTopic) -> String {
    format!("{ROOT}/{}/{SCENE_CHUNK}/{}", site_or_star(site), topic.leaf())
}

/// The site of a `topic` key of a scene.
pub fn parse_scene_topic_key(key: &str, topic: SceneTopic) -> Option<&str> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let site = rest.strip_suffix(topic.leaf())?.strip_suffix("/scene/")?;
    (!site.is_empty() && !site.contains('/')).then_some(site)
}

/// `risktwin/v1/<site>/scene/gt/<source>`: a connected vehicle's true state per physics step,
/// from the scene's authority (`VehicleState`, protobuf): what the twin is measured against.
pub fn scene_ground_truth(site: &SiteId, source: &SourceId) -> String {
    format!("{ROOT}/{site}/{SCENE_CHUNK}/gt/{source}")
}

/// `risktwin/v1/<site|*>/scene/gt/*`: every connected vehicle's true state.
pub fn scene_ground_truth_all(site: Option<&SiteId>) -> String {
    format!("{ROOT}/{}/{SCENE_CHUNK}/gt/*", site_or_star(site))
}

/// The site and source of a ground-truth key.
pub fn parse_scene_ground_truth_key(key: &str) -> Option<(&str, &str)> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let (site, rest) = rest.split_once('/')?;
    let source = rest.strip_prefix("scene/gt/")?;
    (!site.is_empty() && !source.is_empty() && !source.contains('/')).then_some((site, source))
}

/// `risktwin/v1/<site>/alive/<source>`: the liveliness token of one edge.
pub fn liveliness_token(site: &SiteId, source: &SourceId) -> String {
    format!("{ROOT}/{site}/{ALIVE_CHUNK}/{source}")
}

/// `risktwin/v1/<site|*>/alive/*`: every edge's liveliness token.
pub fn liveliness_all(site: Option<&SiteId>) -> String {
    format!("{ROOT}/{}/{ALIVE_CHUNK}/*", site_or_star(site))
}

/// `risktwin/v1/<site|*>/alive/cloud`: the liveliness token of a cloud whose ingest serves
/// `site` (every site: `*`), which edges watch to know the cloud is there. `cloud` is never a
/// source id, so the token is no edge's.
pub fn cloud_liveliness(site: Option<&SiteId>) -> String {
    format!("{ROOT}/{}/{ALIVE_CHUNK}/{CLOUD_CHUNK}", site_or_star(site))
}

/// The chunk under `cloud/` of the sharded ingest workers' liveliness tokens.
pub const WORKERS_CHUNK: &str = "workers";
/// The chunk under `cloud/` where sharded ingest workers forward what they accepted.
pub const INGESTED_CHUNK: &str = "ingested";

/// `risktwin/v1/<site>/<source>/*`: every stream of one source (a sharded worker's share).
pub fn source_streams(site: &SiteId, source: &SourceId) -> String {
    format!("{ROOT}/{site}/{source}/*")
}

/// Characters at the end of a source id that name its shard group: the smallest share of a
/// site a sharded worker subscribes to (docs/sharding.md). Two give a numbered fleet 100 groups.
pub const SHARD_GROUP_CHARS: usize = 2;

/// The shard group of `source`: its last [`SHARD_GROUP_CHARS`] characters, or the whole id if
/// shorter.
pub fn shard_group(source: &str) -> &str {
    source.char_indices().rev().nth(SHARD_GROUP_CHARS - 1).map_or(source, |(at, _)| &source[at..])
}

/// `risktwin/v1/<site>/$*<group>/*`: every stream of every source whose id ends in `group` (a
/// group shorter than [`SHARD_GROUP_CHARS`] is a whole id, and only that id). The groups
/// partition the sources: an id of at least [`SHARD_GROUP_CHARS`] characters matches exactly
/// its own group's pattern.
pub fn shard_group_streams(site: &SiteId, group: &str) -> String {
    if group.chars().count() < SHARD_GROUP_CHARS {
        format!("{ROOT}/{site}/{group}/*")
    } else {
        format!("{ROOT}/{site}/$*{group}/*")
    }
}

/// `risktwin/v1/<site>/cloud/workers/<worker>`: the liveliness token of a sharded ingest worker.
pub fn worker_liveliness(site: &SiteId, worker: &str) -> String {
    format!("{ROOT}/{site}/{CLOUD_CHUNK}/{WORKERS_CHUNK}/{worker}")
}

/// `risktwin/v1/<site>/cloud/workers/*`: every sharded ingest worker's token at `site`.
pub fn worker_liveliness_all(site: &SiteId) -> String {
    format!("{ROOT}/{site}/{CLOUD_CHUNK}/{WORKERS_CHUNK}/*")
}

/// The worker id of a [`worker_liveliness`] key; `None` for any other key.
pub fn parse_worker_liveliness_key(key: &str) -> Option<&str> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let mut chunks = rest.split('/');
    let (_site, cloud, workers, worker) = (chunks.next()?, chunks.next()?, chunks.next()?, chunks.next()?);
    let ok = cloud == CLOUD_CHUNK && workers == WORKERS_CHUNK && !worker.is_empty() && chunks.next().is_none();
    ok.then_some(worker)
}

/// `risktwin/v1/<site>/cloud/ingested/<source>/<stream>`: where a sharded worker forwards a
/// message it accepted on the edge key `edge` (under `cloud/`, so that only clouds may put it).
pub fn ingested(edge: &EdgeKey<'_>) -> String {
    format!("{ROOT}/{}/{CLOUD_CHUNK}/{INGESTED_CHUNK}/{}/{}", edge.site, edge.source, edge.stream.as_str())
}

/// `risktwin/v1/<site|*>/cloud/ingested/*/*`: everything the sharded workers of `site` (every
/// site: `*`) forward.
pub fn ingested_all(site: Option<&SiteId>) -> String {
    format!("{ROOT}/{}/{CLOUD_CHUNK}/{INGESTED_CHUNK}/*/*", site_or_star(site))
}

/// The edge key an [`ingested`] key was forwarded from, written into `buf` (reused: no
/// allocation once it is long enough); `None` for any other key.
pub fn edge_key_of_ingested<'b>(key: &str, buf: &'b mut String) -> Option<&'b str> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let mut chunks = rest.split('/');
    let (site, cloud, ingested) = (chunks.next()?, chunks.next()?, chunks.next()?);
    let (source, stream) = (chunks.next()?, chunks.next()?);
    if cloud != CLOUD_CHUNK || ingested != INGESTED_CHUNK || chunks.next().is_some() {
        return None;
    }
    buf.clear();
    for part in [ROOT, "/", site, "/", source, "/", stream] {
        buf.push_str(part);
    }
    parse_edge_key(buf).is_some().then_some(buf.as_str())
}

fn site_or_star(site: Option<&SiteId>) -> &str {
    site.map_or("*", SiteId::as_str)
}

/// A parsed edge→cloud key, borrowing from the key text (parsing allocates nothing).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EdgeKey<'a> {
    /// The site chunk.
    pub site: &'a str,
    /// The source chunk.
    pub source: &'a str,
    /// The stream.
    pub stream: EdgeStream,
}

/// Splits `risktwin/v1/<site>/<source>/<stream>`; `None` for anything else.
pub fn parse_edge_key(key: &str) -> Option<EdgeKey<'_>> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let mut chunks = rest.split('/');
    let (site, source, stream) = (chunks.next()?, chunks.next()?, chunks.next()?);
    if chunks.next().is_some() || site.is_empty() || source.is_empty() {
        return None;
    }
    if source == CLOUD_CHUNK || source == ALIVE_CHUNK || source == SCENE_CHUNK {
        return None;
    }
    Some(EdgeKey { site, source, stream: EdgeStream::from_chunk(stream)? })
}

/// Like [`parse_edge_key`], with a typed error naming the key.
pub fn try_parse_edge_key(key: &str) -> Result<EdgeKey<'_>, KeyError> {
    parse_edge_key(key).ok_or_else(|| KeyError::NotEdgeStream { key: key.to_owned() })
}

/// The site and source id of an edge's liveliness token key `risktwin/v1/<site>/alive/<source>`
/// (`None` for the cloud's, [`cloud_liveliness`]).
pub fn parse_liveliness_key(key: &str) -> Option<(&str, &str)> {
    let rest = key.strip_prefix(ROOT)?.strip_prefix('/')?;
    let mut chunks = rest.split('/');
    let (site, alive, source) = (chunks.next()?, chunks.next()?, chunks.next()?);
    let edge = !source.is_empty() && source != CLOUD_CHUNK;
    (alive == ALIVE_CHUNK && chunks.next().is_none() && edge).then_some((site, source))
}

#[cfg(test)]
mod tests;
