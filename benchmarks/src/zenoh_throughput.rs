//! Edge→cloud throughput, ours against raw Zenoh, in one run (`risktwin bench zenoh`).
//!
//! Both sides use two peer sessions in this process joined over TCP loopback (one listens on
//! `tcp/127.0.0.1:0`, the other connects to the port it got), reliable and blocking under
//! congestion, and push the same number of payloads of the same size:
//! - raw: a plain zenoh publisher puts a prebuilt payload (copied per put, as a real producer
//!   would hand over fresh data), a plain subscriber on the exact key counts samples;
//! - raw, wildcard: the same with the subscriber on `risktwin/bench/*`, the shape a cloud that
//!   listens to every source needs (Zenoh then matches every sample against the subscription
//!   again: its route cache does not help here, as profiling showed);
//! - ours: the edge's [`StreamPublisher`] (a zenoh-ext `AdvancedPublisher`: numbered samples, a
//!   vehicle state stream's 1 500-sample recovery cache, heartbeat; `Block` here, as any unpaced
//!   producer) puts a freshly encoded [`StandIn`] record; the cloud's edge-stream subscriber (an
//!   `AdvancedSubscriber` with recovery and a miss listener) hands it to the stand-in
//!   ingest ([`StandInCounters`]), which decodes, validates and counts it per source and stream.
//!
//! Throughput is messages delivered per second, from the first put until the subscriber has
//! seen the last message.

use crate::standin::StandIn;
use crate::standin_ingest::StandInCounters;
use risktwin_cloud::network::CloudError;
use risktwin_cloud::network::routes::declare_route_keys;
use risktwin_transport::recovery::{DEFAULT_OUTAGE, cache_samples};
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::zenoh::{Session, Wait};
use risktwin_transport::{
    Delivery, EdgeStream, Mode, Shutdown, SiteId, SourceId, StreamLoss, StreamPublisher, TransportConfig,
    TransportError, connect, listening_locators, subscribe_edge_streams,
};
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::Notify;

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BenchConfig {
    /// Messages per measurement.
    pub messages: u64,
    /// Payload size, bytes.
    pub payload_bytes: usize,
    /// Measurements per side (alternating raw, ours); the median is reported.
    pub rounds: usize,
}

/// The figures, messages per second.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchReport {
    /// Messages per measurement.
    pub messages: u64,
    /// Payload size, bytes.
    pub payload_bytes: usize,
    /// Every raw measurement.
    pub raw_msgs_per_s: Vec<f64>,
    /// Every raw measurement with a wildcard subscriber.
    pub raw_wildcard_msgs_per_s: Vec<f64>,
    /// Every measurement of ours.
    pub ours_msgs_per_s: Vec<f64>,
    /// Median raw.
    pub raw_median_msgs_per_s: f64,
    /// Median raw with a wildcard subscriber.
    pub raw_wildcard_median_msgs_per_s: f64,
    /// Median ours.
    pub ours_median_msgs_per_s: f64,
    /// ours / raw, medians.
    pub ratio: f64,
    /// ours / raw with a wildcard subscriber, medians.
    pub ratio_vs_wildcard: f64,
}

/// Runs the benchmark.
pub async fn throughput(config: BenchConfig) -> Result<BenchReport, CloudError> {
    let mut raw = Vec::with_capacity(config.rounds);
    let mut wild = Vec::with_capacity(config.rounds);
    let mut ours = Vec::with_capacity(config.rounds);
    for _ in 0..config.rounds {
        raw.push(raw_round(config, "risktwin/bench/raw").await?);
        wild.push(raw_round(config, "risktwin/bench/*").await?);
        ours.push(our_round(config).await?);
    }
    let (raw_median, wild_median, ours_median) = (median(&raw), median(&wild), median(&ours));
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    Ok(BenchReport {
        messages: config.messages,
        payload_bytes: config.payload_bytes,
        raw_msgs_per_s: raw,
        raw_wildcard_msgs_per_s: wild,
        ours_msgs_per_s: ours,
        raw_median_msgs_per_s: raw_median,
        raw_wildcard_median_msgs_per_s: wild_median,
        ours_median_msgs_per_s: ours_median,
        ratio: ratio(ours_median, raw_median),
        ratio_vs_wildcard: ratio(ours_median, wild_median),
    })
}

pub(crate) fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Two peers over TCP loopback: (listening subscriber side, connecting publisher side).
pub(crate) async fn peer_pair() -> Result<(Session, Session), CloudError> {
    let listen = TransportConfig { mode: Mode::Peer, listen: vec!["tcp/127.0.0.1:0".into()], ..Default::default() };
    let sub_side = connect(&listen).await?;
    let locators = listening_locators(&sub_side).await;
    let connect_to = TransportConfig {
        mode: Mode::Peer,
        connect: locators,
        listen: vec!["tcp/127.0.0.1:0".into()],
        ..Default::default()
    };
    let pub_side = connect(&connect_to).await?;
    Ok((sub_side, pub_side))
}

/// Counts deliveries and wakes the measuring task at the last one.
#[derive(Default)]
struct Finish {
    seen: AtomicU64,
    done: Notify,
}

impl Finish {
    fn hit(&self, target: u64) {
        if self.seen.fetch_add(1, Ordering::Relaxed) + 1 == target {
            self.done.notify_one();
        }
    }

    async fn wait(&self, target: u64) -> Result<(), CloudError> {
        let deadline = Duration::from_secs(120);
        let waited = tokio::time::timeout(deadline, async {
            while self.seen.load(Ordering::Relaxed) < target {
                self.done.notified().await;
            }
        })
        .await;
        waited.map_err(|_| {
            bench_error(format!(
                "only {} of {target} messages arrived in {deadline:?}",
                self.seen.load(Ordering::Relaxed)
            ))
        })
    }
}

pub(crate) fn bench_error(reason: String) -> CloudError {
    CloudError::Transport(TransportError::Put { key: "bench".into(), reason })
}

/// One raw measurement, the subscriber on `subscribe_key` (which must match the published key).
async fn raw_round(config: BenchConfig, subscribe_key: &str) -> Result<f64, CloudError> {
    let (sub_side, pub_side) = peer_pair().await?;
    let key = "risktwin/bench/raw";
    let finish = Arc::new(Finish::default());
    let hit = Arc::clone(&finish);
    let n = config.messages;
    let subscriber = sub_side
        .declare_subscriber(subscribe_key)
        .callback(move |sample| {
            std::hint::black_box(sample.payload().to_bytes().len());
            hit.hit(n);
        })
        .await
        .map_err(|e| bench_error(e.to_string()))?;
    let publisher = pub_side
        .declare_publisher(key)
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(|e| bench_error(e.to_string()))?;
    wait_matching(|| publisher.matching_status().wait().map(|s| s.matching()).unwrap_or(false)).await?;
    let payload = vec![0xA5u8; config.payload_bytes];
    let start = Instant::now();
    for _ in 0..n {
        publisher.put(payload.clone()).await.map_err(|e| bench_error(e.to_string()))?;
    }
    finish.wait(n).await?;
    let rate = n as f64 / start.elapsed().as_secs_f64();
    drop((subscriber, publisher));
    let _ = tokio::join!(pub_side.close(), sub_side.close());
    Ok(rate)
}

async fn our_round(config: BenchConfig) -> Result<f64, CloudError> {
    let (sub_side, pub_side) = peer_pair().await?;
    state_path_round(config, sub_side, pub_side).await
}

/// One measurement of our state path between two sessions (closed at the end): the edge's
/// stream publisher on `pub_side` as source `bench/veh-0`, the cloud's edge-stream subscriber
/// and stand-in ingest on `sub_side`.
pub(crate) async fn state_path_round(
    config: BenchConfig,
    sub_side: Session,
    pub_side: Session,
) -> Result<f64, CloudError> {
    let site = SiteId::new("bench").map_err(|e| bench_error(e.to_string()))?;
    let source = SourceId::new("veh-0").map_err(|e| bench_error(e.to_string()))?;
    let counters = Arc::new(Mutex::new(StandInCounters::default()));
    // The bench measures the transport with the stand-in counters (no decoding or alignment),
    // so that its figure stays comparable with raw Zenoh.
    let sink_counters = Arc::clone(&counters);
    let sink = move |_: EdgeStream, sample: &Sample| {
        let payload = sample.payload().to_bytes();
        let mut counters = sink_counters.locked();
        let _ = counters.accept(sample.key_expr().as_str(), &payload, std::time::Instant::now());
    };
    let finish = Arc::new(Finish::default());
    let hit = Arc::clone(&finish);
    let n = config.messages;
    let lost = Arc::new(AtomicU64::new(0));
    let lost_cb = Arc::clone(&lost);
    let on_loss = move |loss: StreamLoss| {
        lost_cb.fetch_add(u64::from(loss.samples), Ordering::Relaxed);
    };
    let on_sample = move |stream, sample: &Sample| {
        sink(stream, sample);
        hit.hit(n);
    };
    let subscriber = subscribe_edge_streams(&sub_side, Some(&site), on_sample, on_loss).await?;
    // As in the cloud: the stream's key is declared on the cloud's session (there, on its first
    // accepted sample; see risktwin_cloud::network::routes).
    let (mut route_keys, keys) = declare_route_keys(&sub_side);
    // A vehicle state stream's cache; unpaced, so paced by the transport (`Block`).
    let delivery = Delivery::paced_by_transport(cache_samples(50.0, DEFAULT_OUTAGE));
    let publisher = StreamPublisher::declare(&pub_side, &site, &source, EdgeStream::State, delivery)?;
    let _ = keys.send(publisher.key().to_owned());
    tokio::time::timeout(Duration::from_secs(10), route_keys.declared.wait_for(|n| *n >= 1))
        .await
        .map_err(|_| bench_error("the stream's key was not declared in 10 s".into()))?
        .map_err(|e| bench_error(e.to_string()))?;
    let (_never_fired, shutdown): (_, Shutdown) = risktwin_transport::shutdown::channel();
    if !publisher.wait_for_subscriber(Duration::from_secs(10), shutdown).await? {
        return Err(bench_error("no subscriber matched in 10 s".into()));
    }
    let start = Instant::now();
    for seq in 0..n {
        let record = StandIn { source: source.as_str(), seq, capture_time_ns: seq as i64, publish_time_ns: seq as i64 };
        let payload = record.encode(config.payload_bytes).map_err(|e| bench_error(e.to_string()))?;
        publisher.put(payload)?;
    }
    finish.wait(n).await?;
    let rate = n as f64 / start.elapsed().as_secs_f64();
    let summary = counters.lock().map(|c| c.summary()).unwrap_or_default();
    if summary.total_received != n || lost.load(Ordering::Relaxed) != 0 {
        return Err(bench_error(format!(
            "ingest accepted {} of {n} ({:?} dropped, {} lost)",
            summary.total_received,
            summary.dropped,
            lost.load(Ordering::Relaxed)
        )));
    }
    drop((subscriber, publisher, keys));
    let _ = route_keys.task.await;
    let _ = tokio::join!(pub_side.close(), sub_side.close());
    Ok(rate)
}

/// Polls `matching` until true, waking on a short timer (bench setup only, never measured).
async fn wait_matching(matching: impl Fn() -> bool) -> Result<(), CloudError> {
    let deadline = Instant::now() + Duration::from_secs(10);
    while !matching() {
        if Instant::now() > deadline {
            return Err(bench_error("no subscriber matched in 10 s".into()));
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    Ok(())
}
