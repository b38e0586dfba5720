//! `risktwin edge replay`: fleet data from a recording. Every edge-stream and road-map message of
//! an MCAP file (a cloud `--record`ing, `risktwin import commonroad` output, or any file with the
//! same key scheme as topics) is republished on its recorded key, in file order, paced by its log time divided by `speed` (0: as fast as the transport takes it),
//! with its recorded receive time attached (see [`run`]).

use crate::error::EdgeError;
use risktwin_protos::recording::{RecordingError, SpanCursor, UnfinishedRecording, encode_replay_time};
use risktwin_transport::keyexpr::{EDGE_MAP_MESSAGE, parse_edge_key, parse_edge_map_key};
use risktwin_transport::zenoh::Session;
use risktwin_transport::{
    Delivery, Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, close, connect, retire,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

/// How to replay.
#[derive(Debug, Clone)]
pub struct ReplayConfig {
    pub transport: TransportConfig,
    /// Replay speed relative to the recording; 0 means unpaced.
    pub speed: f64,
    /// How long to wait for a subscriber before publishing anyway.
    pub wait_for_cloud: Duration,
}

/// What a replay published, per key, and what it skipped (topics that are neither an edge stream
/// nor a road map of the scheme).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ReplaySummary {
    pub published: u64,
    pub skipped: u64,
    pub by_key: BTreeMap<String, u64>,
    /// From the first message to the last one handed to Zenoh.
    pub elapsed_s: f64,
    /// Published messages per second over `elapsed_s`.
    pub msgs_per_s: f64,
    /// What could not be read of each unfinished file (a recorder killed): the caller warns.
    #[serde(skip)]
    pub unfinished: Vec<(PathBuf, UnfinishedRecording)>,
}

/// Republishes the edge streams of a recording read by `cursor` (MCAP files, or a span of the
/// segments of a rotating recording, streamed: the recording is never held in memory; an
/// unfinished file up to its last complete chunk). Each message carries its recorded receive time as a
/// replay-time attachment ([`encode_replay_time`]), which a cloud run with `--replay-time`
/// ingests at instead of its own clock, so that it rebuilds the live run's snapshots.
pub async fn run(
    mut cursor: SpanCursor,
    config: &ReplayConfig,
    mut shutdown: Shutdown,
) -> Result<ReplaySummary, EdgeError> {
    let bad_file = |e: RecordingError| EdgeError::Recording { reason: e.to_string() };
    let session = connect(&config.transport).await?;
    // By channel id: the publisher of the channel's key, or None for a topic outside the scheme.
    let mut publishers: Vec<Option<Option<StreamPublisher>>> = Vec::new();
    let mut waited = false;
    let mut summary = ReplaySummary::default();
    let mut first_log_ns = None;
    let start = tokio::time::Instant::now();
    while let Some(m) = cursor.next_message() {
        let m = m.map_err(bad_file)?;
        if shutdown.is_fired() {
            break;
        }
        let slot = usize::from(m.channel_id);
        if publishers.len() <= slot {
            publishers.resize_with(slot + 1, || None);
        }
        if publishers[slot].is_none() {
            publishers[slot] = Some(declare(&session, m.topic, m.schema_name).await?);
        }
        let Some(Some(publisher)) = &publishers[slot] else {
            summary.skipped += 1;
            continue;
        };
        if !waited {
            publisher.wait_for_subscriber(config.wait_for_cloud, shutdown.clone()).await?;
            waited = true;
        }
        let t0 = *first_log_ns.get_or_insert(m.log_time_ns);
        if config.speed > 0.0 {
            let offset = Duration::from_secs_f64(m.log_time_ns.saturating_sub(t0) as f64 * 1e-9 / config.speed);
            tokio::select! {
                () = tokio::time::sleep_until(start + offset) => {}
                () = shutdown.wait() => break,
            }
        }
        let Ok(log_time_ns) = i64::try_from(m.log_time_ns) else {
            summary.skipped += 1;
            continue;
        };
        let topic = m.topic.to_owned();
        publisher.put_with_attachment(m.data.to_vec(), encode_replay_time(log_time_ns).to_vec())?;
        summary.published += 1;
        *summary.by_key.entry(topic).or_default() += 1;
    }
    summary.unfinished = cursor.unfinished().to_vec();
    summary.elapsed_s = start.elapsed().as_secs_f64();
    summary.msgs_per_s = summary.published as f64 / summary.elapsed_s.max(1e-9);
    retire(publishers.into_iter().flatten().flatten()).await?;
    close(session).await?;
    Ok(summary)
}

/// The publisher of `topic`'s key, or `None` when the topic is neither an edge stream nor a road
/// map of the scheme. A channel whose schema is not the message its key carries (a recording of
/// another schema version) is refused by name: its messages would be tagged as what they are not.
async fn declare(session: &Session, topic: &str, schema: &str) -> Result<Option<StreamPublisher>, EdgeError> {
    let bad = |e: risktwin_transport::KeyError| EdgeError::Recording { reason: format!("{topic}: {e}") };
    let check = |message: &str| {
        let reason = format!("channel {topic} has schema {schema}, its key carries {message}");
        if schema == message { Ok(()) } else { Err(EdgeError::Recording { reason }) }
    };
    if let Some((site, source)) = parse_edge_map_key(topic) {
        check(EDGE_MAP_MESSAGE)?;
        let (site, source) = (SiteId::new(site).map_err(bad)?, SourceId::new(source).map_err(bad)?);
        return Ok(Some(StreamPublisher::declare_map(session, &site, &source, replay_delivery())?));
    }
    let Some(key) = parse_edge_key(topic) else {
        return Ok(None);
    };
    check(key.stream.message())?;
    let site = SiteId::new(key.site).map_err(bad)?;
    let source = SourceId::new(key.source).map_err(bad)?;
    Ok(Some(StreamPublisher::declare(session, &site, &source, key.stream, replay_delivery())?))
}

/// Samples each replayed key keeps for recovery: 30 s of a 50 Hz state stream at speed 1.
const REPLAY_CACHE_SAMPLES: usize = 1500;

/// A replay is unpaced at `--speed 0`: the transport paces it (`Block`) rather than outrun the cache.
fn replay_delivery() -> Delivery {
    Delivery::paced_by_transport(REPLAY_CACHE_SAMPLES)
}
