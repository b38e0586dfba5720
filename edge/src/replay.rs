//! `risktwin edge replay`: fleet data from a recording. Every edge-stream message of an MCAP file
//! (a cloud `--record`ing, or any file with the same key scheme as topics) is republished on its
//! recorded key, paced by its log time divided by `speed` (0: as fast as the transport takes it).

use crate::EdgeError;
use risktwin_protos::recording::read_messages;
use risktwin_transport::keyexpr::parse_edge_key;
use risktwin_transport::{Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, close, connect};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
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

/// What a replay published, per key, and what it skipped (topics outside the edge scheme).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct ReplaySummary {
    pub published: u64,
    pub skipped: u64,
    pub by_key: BTreeMap<String, u64>,
}

/// Republishes the edge streams of `recording` (the bytes of an MCAP file).
pub async fn run(recording: &[u8], config: &ReplayConfig, mut shutdown: Shutdown) -> Result<ReplaySummary, EdgeError> {
    let messages = read_messages(recording).map_err(|e| EdgeError::Recording { reason: e.to_string() })?;
    let session = connect(&config.transport).await?;
    let mut publishers: HashMap<&str, StreamPublisher> = HashMap::new();
    for m in &messages {
        if publishers.contains_key(m.topic.as_str()) {
            continue;
        }
        if let Some(key) = parse_edge_key(&m.topic) {
            let bad = |e: risktwin_transport::KeyError| EdgeError::Recording { reason: format!("{}: {e}", m.topic) };
            let site = SiteId::new(key.site).map_err(bad)?;
            let source = SourceId::new(key.source).map_err(bad)?;
            publishers.insert(&m.topic, StreamPublisher::declare(&session, &site, &source, key.stream).await?);
        }
    }
    if let Some(p) = publishers.values().next() {
        p.wait_for_subscriber(config.wait_for_cloud, shutdown.clone()).await?;
    }
    let mut summary = ReplaySummary::default();
    let t0 = messages.first().map_or(0, |m| m.log_time_ns);
    let start = tokio::time::Instant::now();
    for m in &messages {
        if shutdown.is_fired() {
            break;
        }
        let Some(publisher) = publishers.get(m.topic.as_str()) else {
            summary.skipped += 1;
            continue;
        };
        if config.speed > 0.0 {
            let offset = Duration::from_secs_f64(m.log_time_ns.saturating_sub(t0) as f64 * 1e-9 / config.speed);
            tokio::select! {
                () = tokio::time::sleep_until(start + offset) => {}
                () = shutdown.wait() => break,
            }
        }
        publisher.put(m.data.clone()).await?;
        summary.published += 1;
        *summary.by_key.entry(m.topic.clone()).or_default() += 1;
    }
    for (_, p) in publishers {
        p.undeclare().await?;
    }
    close(session).await?;
    Ok(summary)
}
