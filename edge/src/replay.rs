//! `risktwin edge replay`: fleet data from a recording. Every edge-stream and road-map message of
//! an MCAP file (a cloud `--record`ing, `risktwin import commonroad` output, or any file with the
//! same key scheme as topics) is republished on its recorded key, in file order, paced by its log time divided by `speed` (0: as fast as the transport takes it),
//! with its recorded receive time attached (see [`run`]).
//!
//! Like a live edge, a replay watches the cloud's delivery acknowledgements, for every source it
//! replays, and reports per source what no cloud accounted for ([`crate::delivery`]): the
//! numbers of a stream come from the recorded headers, so a number the recording lacks (lost on
//! the way to the recorder, or before it started) is counted as never sent, not as undelivered.

use crate::delivery::{DeliveryWatch, Numbering, StreamSent};
use crate::error::EdgeError;
use crate::summary::{DeliverySummary, ReplaySummary};
use risktwin_protos::header_seq;
use risktwin_protos::recording::{RecordingError, SpanCursor, encode_replay_time};
use risktwin_transport::keyexpr::{EDGE_MAP_MESSAGE, parse_edge_key, parse_edge_map_key};
use risktwin_transport::zenoh::Session;
use risktwin_transport::{
    Delivery, EdgeStream, Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, close, connect, retire,
};
use std::collections::BTreeMap;
use std::time::Duration;

/// How to replay.
#[derive(Debug, Clone)]
pub struct ReplayConfig {
    pub transport: TransportConfig,
    /// Replay speed relative to the recording; 0 means unpaced.
    pub speed: f64,
    /// How long to wait for a subscriber before publishing anyway.
    pub wait_for_cloud: Duration,
    /// Watch the cloud's delivery acknowledgements of every replayed source (`--no-ack` off).
    pub ack: bool,
}

/// A replayed channel: its publisher, and for an edge stream the source and stream whose
/// numbers it counts in.
struct Channel {
    publisher: StreamPublisher,
    counted: Option<(usize, EdgeStream)>,
}

/// One replayed source's watch on its acknowledgements and the numbers of its streams.
struct Source {
    name: String,
    watch: Option<DeliveryWatch>,
    streams: BTreeMap<EdgeStream, Numbering>,
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
    // By channel id: the channel's publisher, or None for a topic outside the scheme.
    let mut channels: Vec<Option<Option<Channel>>> = Vec::new();
    let mut sources: Vec<Source> = Vec::new();
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
        if channels.len() <= slot {
            channels.resize_with(slot + 1, || None);
        }
        if channels[slot].is_none() {
            channels[slot] = Some(declare(&session, m.topic, m.schema_name, config.ack, &mut sources).await?);
        }
        let Some(Some(Channel { publisher, counted })) = &channels[slot] else {
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
        let seq = counted.map(|_| header_seq(m.data));
        publisher.put_with_attachment(m.data.to_vec(), encode_replay_time(log_time_ns).to_vec())?;
        match (counted, seq) {
            (Some((source, stream)), Some(Some(seq))) => {
                sources[*source].streams.entry(*stream).or_default().sent(seq);
            }
            (Some(_), _) => summary.unnumbered += 1,
            (None, _) => {}
        }
        summary.published += 1;
        *summary.by_key.entry(topic).or_default() += 1;
    }
    summary.unfinished = cursor.unfinished().to_vec();
    summary.elapsed_s = start.elapsed().as_secs_f64();
    summary.msgs_per_s = summary.published as f64 / summary.elapsed_s.max(1e-9);
    // The publishers (and their caches) stay while the sources settle: the cloud may still fetch.
    summary.delivery = settle(sources).await?;
    crate::live_metrics::export_replay(&summary);
    retire(channels.into_iter().flatten().flatten().map(|c| c.publisher)).await?;
    close(session).await?;
    Ok(summary)
}

/// Waits (all at once) until every watched source's acknowledgements cover what it sent, or
/// its watch gives up; what became of each source's messages.
async fn settle(sources: Vec<Source>) -> Result<BTreeMap<String, DeliverySummary>, EdgeError> {
    let mut settling = Vec::new();
    for source in sources {
        let Some(watch) = source.watch else { continue };
        let sent: Vec<(EdgeStream, StreamSent)> = source.streams.iter().map(|(s, n)| (*s, n.stream_sent())).collect();
        settling.push((source.name, tokio::spawn(async move { watch.settle(&sent).await })));
    }
    let mut delivery = BTreeMap::new();
    for (name, task) in settling {
        let settled = task.await.map_err(|e| EdgeError::Shutdown { reason: format!("settling {name}: {e}") })?;
        delivery.insert(name, settled?);
    }
    Ok(delivery)
}

/// The channel of `topic`'s key, or `None` when the topic is neither an edge stream nor a road
/// map of the scheme. A channel whose schema is not the message its key carries (a recording of
/// another schema version) is refused by name: its messages would be tagged as what they are not.
/// An edge stream's source is watched (`ack`) from its first channel on.
async fn declare(
    session: &Session,
    topic: &str,
    schema: &str,
    ack: bool,
    sources: &mut Vec<Source>,
) -> Result<Option<Channel>, EdgeError> {
    let bad = |e: risktwin_transport::KeyError| EdgeError::Recording { reason: format!("{topic}: {e}") };
    let check = |message: &str| {
        let reason = format!("channel {topic} has schema {schema}, its key carries {message}");
        if schema == message { Ok(()) } else { Err(EdgeError::Recording { reason }) }
    };
    if let Some((site, source)) = parse_edge_map_key(topic) {
        check(EDGE_MAP_MESSAGE)?;
        let (site, source) = (SiteId::new(site).map_err(bad)?, SourceId::new(source).map_err(bad)?);
        let publisher = StreamPublisher::declare_map(session, &site, &source, replay_delivery())?;
        return Ok(Some(Channel { publisher, counted: None }));
    }
    let Some(key) = parse_edge_key(topic) else {
        return Ok(None);
    };
    check(key.stream.message())?;
    let site = SiteId::new(key.site).map_err(bad)?;
    let source = SourceId::new(key.source).map_err(bad)?;
    let publisher = StreamPublisher::declare(session, &site, &source, key.stream, replay_delivery())?;
    let name = format!("{site}/{source}");
    let index = match sources.iter().position(|s| s.name == name) {
        Some(index) => index,
        None => {
            let watch = if ack { Some(DeliveryWatch::start(session, &site, &source).await?) } else { None };
            sources.push(Source { name, watch, streams: BTreeMap::new() });
            sources.len() - 1
        }
    };
    Ok(Some(Channel { publisher, counted: Some((index, key.stream)) }))
}

/// Samples each replayed key keeps for recovery: 30 s of a 50 Hz state stream at speed 1.
const REPLAY_CACHE_SAMPLES: usize = 1500;

/// A replay is unpaced at `--speed 0`: the transport paces it (`Block`) rather than outrun the cache.
fn replay_delivery() -> Delivery {
    Delivery::paced_by_transport(REPLAY_CACHE_SAMPLES)
}
