//! Edge publish → twin snapshot containing it, against a raw Zenoh one-way hop, in one run
//! (`risktwin bench latency`).
//!
//! Both sides use two peer sessions in this process joined over TCP loopback (as
//! `bench zenoh`), and one clock (`Instant`) for send and arrival:
//! - raw: a plain publisher puts an 8-byte sequence number at the rate; a plain subscriber
//!   notes the arrival; latency = arrival − put;
//! - ours: the edge's [`StreamPublisher`] puts an encoded `VehicleState` at the rate (the car
//!   drives along x at a fixed speed, so the position tells which sample a value reflects); the
//!   cloud's live ingest path (the role's own [`LiveIngest`] with the twin) aligns it; after each
//!   message the twin's ego position says up to which sample the newest snapshot reflects, and
//!   every newly covered sample gets latency = now − its put.
//!
//! A snapshot at tick `t` is emitted once a message arrives with receive time ≥ `t + lateness`
//! (see `align::aligner`), so ours is about lateness + half a tick + the message
//! spacing above raw; the report gives the tick and lateness used next to the ratio.
//! The first [`WARMUP`] samples of each side (clock estimate and connection warm-up) are left out.

use crate::zenoh_throughput::peer_pair;
use risktwin_align::IngestConfig;
use risktwin_cloud::network::{CloudError, LiveIngest, Origin};
use risktwin_cloud::twin::outputs::TwinOutputs;
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::telemetry::{Frame, Header, VehicleStateSample};
use risktwin_protos::encode;
use risktwin_transport::recovery::DEFAULT_OUTAGE;
use risktwin_transport::sync::LockExt;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::Wait;
use risktwin_transport::zenoh::qos::{CongestionControl, Priority};
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{
    Delivery, EdgeStream, SiteId, SourceId, StreamLoss, StreamPublisher, TransportError, subscribe_edge_streams,
};
use serde::Serialize;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Samples of each side left out of the statistics.
pub const WARMUP: usize = 50;
/// Speed of the benchmark car, m/s, and so its spacing per sample at the rate.
const SPEED_MPS: f64 = 10.0;

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatencyConfig {
    /// Messages per side (the first [`WARMUP`] are not counted).
    pub messages: u64,
    /// Publish rate, Hz (a vehicle's state: 50).
    pub rate_hz: f64,
    /// The ingest configuration of ours (tick and lateness).
    pub ingest: IngestConfig,
}

/// The figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LatencyReport {
    pub messages: u64,
    pub rate_hz: f64,
    pub tick_ms: f64,
    pub lateness_ms: f64,
    pub raw_p50_ms: f64,
    pub raw_p99_ms: f64,
    pub ours_p50_ms: f64,
    pub ours_p99_ms: f64,
    /// Samples measured per side after the warm-up.
    pub raw_samples: usize,
    pub ours_samples: usize,
    /// ours_p50 / (raw_p50 + tick).
    pub ratio: f64,
}

/// Runs both sides and reports.
pub async fn latency(config: LatencyConfig) -> Result<LatencyReport, CloudError> {
    let mut raw = raw_side(config, RawQos::PLAIN).await?;
    let mut ours = our_side(config).await?;
    let tick_ms = config.ingest.align.tick_ns as f64 * 1e-6;
    let (raw_p50, raw_p99) = (percentile(&mut raw, 0.5), percentile(&mut raw, 0.99));
    let (ours_p50, ours_p99) = (percentile(&mut ours, 0.5), percentile(&mut ours, 0.99));
    Ok(LatencyReport {
        messages: config.messages,
        rate_hz: config.rate_hz,
        tick_ms,
        lateness_ms: config.ingest.align.lateness_ns as f64 * 1e-6,
        raw_p50_ms: raw_p50,
        raw_p99_ms: raw_p99,
        ours_p50_ms: ours_p50,
        ours_p99_ms: ours_p99,
        raw_samples: raw.len(),
        ours_samples: ours.len(),
        ratio: ours_p50 / (raw_p50 + tick_ms),
    })
}

/// The `q` quantile (nearest rank) of `values`, ms; NaN when empty.
pub(crate) fn percentile(values: &mut [f64], q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    if values.is_empty() {
        return f64::NAN;
    }
    let rank = ((q * values.len() as f64).ceil() as usize).clamp(1, values.len());
    values[rank - 1]
}

pub(crate) fn period(config: LatencyConfig) -> Duration {
    Duration::from_secs_f64(1.0 / config.rate_hz)
}

/// Put instants by sequence number, shared by the publishing loop and the receive callback.
pub(crate) type SentAt = Arc<Mutex<Vec<Option<Instant>>>>;

pub(crate) fn put_instant(sent: &SentAt, seq: usize) -> Option<Instant> {
    sent.locked().get(seq).copied().flatten()
}

/// How the raw side's publisher sends: `bench latency`'s plain publisher (default priority, not
/// express, blocking under congestion), or the warning puts' QoS (`bench warning`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RawQos {
    pub congestion: CongestionControl,
    pub priority: Priority,
    pub express: bool,
}

impl RawQos {
    /// A plain publisher's QoS, blocking under congestion.
    pub(crate) const PLAIN: RawQos =
        RawQos { congestion: CongestionControl::Block, priority: Priority::DEFAULT, express: false };
}

pub(crate) async fn raw_side(config: LatencyConfig, qos: RawQos) -> Result<Vec<f64>, CloudError> {
    let (sub_side, pub_side) = peer_pair().await?;
    let n = usize::try_from(config.messages).unwrap_or(usize::MAX);
    let sent: SentAt = Arc::new(Mutex::new(vec![None; n]));
    let latencies = Arc::new(Mutex::new(Vec::with_capacity(n)));
    let key = "risktwin/bench/latency";
    let (sent_cb, lat_cb) = (Arc::clone(&sent), Arc::clone(&latencies));
    let subscriber = sub_side
        .declare_subscriber(key)
        .callback(move |sample| {
            let now = Instant::now();
            let bytes = sample.payload().to_bytes();
            let Ok(seq) = <[u8; 8]>::try_from(&bytes[..]).map(u64::from_le_bytes) else { return };
            let seq = seq as usize;
            if let Some(t) = put_instant(&sent_cb, seq).filter(|_| seq >= WARMUP) {
                lat_cb.locked().push(now.duration_since(t).as_secs_f64() * 1e3);
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "subscriber", key: key.into(), reason: e.to_string() })?;
    let publisher = pub_side
        .declare_publisher(key)
        .congestion_control(qos.congestion)
        .priority(qos.priority)
        .express(qos.express)
        .await
        .map_err(|e| TransportError::Declare { what: "publisher", key: key.into(), reason: e.to_string() })?;
    wait_matching(&publisher).await;
    let start = Instant::now();
    for seq in 0..n {
        tokio::time::sleep_until((start + period(config) * seq as u32).into()).await;
        sent.locked()[seq] = Some(Instant::now());
        publisher
            .put((seq as u64).to_le_bytes().to_vec())
            .await
            .map_err(|e| TransportError::Put { key: key.into(), reason: e.to_string() })?;
    }
    settle(&latencies, n.saturating_sub(WARMUP)).await;
    let _ = subscriber.undeclare().await;
    let _ = publisher.undeclare().wait();
    let _ = sub_side.close().wait();
    let _ = pub_side.close().wait();
    let out = latencies.locked().clone();
    Ok(out)
}

/// Waits until a subscriber matches `publisher` (at most 5 s).
async fn wait_matching(publisher: &risktwin_transport::zenoh::pubsub::Publisher<'_>) {
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        if publisher.matching_status().await.is_ok_and(|s| s.matching()) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

/// Waits until `want` latencies are in, or nothing new came for 2 s.
pub(crate) async fn settle(latencies: &Mutex<Vec<f64>>, want: usize) {
    let mut last = (0, Instant::now());
    loop {
        let have = latencies.locked().len();
        if have >= want {
            return;
        }
        if have != last.0 {
            last = (have, Instant::now());
        } else if last.1.elapsed() > Duration::from_secs(2) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// `source`'s state number `seq`, stamped now, at `x_m` on the x axis driving at `speed_mps`.
pub(crate) fn state(source: &str, seq: u64, x_m: f64, speed_mps: f64) -> VehicleStateSample {
    let now_ns = unix_ns();
    VehicleStateSample {
        header: Header {
            source: source.into(),
            seq,
            capture_time_ns: now_ns,
            publish_time_ns: now_ns,
            frame: Frame::World,
        },
        pose: Pose::new(x_m, 0.0, 0.0),
        velocity: Vec2::new(speed_mps, 0.0),
        speed_mps,
        accel_mps2: 0.0,
        yaw_rate_radps: 0.0,
        steer_rad: 0.0,
        footprint: Footprint::new(4.5, 1.8),
    }
}

/// The benchmark's site and a source of it, as typed ids.
pub(crate) fn bench_ids(site: &str, source: &str) -> Result<(SiteId, SourceId), TransportError> {
    let config = |key: &'static str, value: &str, e: risktwin_transport::KeyError| TransportError::Config {
        key,
        value: value.into(),
        reason: e.to_string(),
    };
    let site_id = SiteId::new(site).map_err(|e| config("site", site, e))?;
    Ok((site_id, SourceId::new(source).map_err(|e| config("source", source, e))?))
}

async fn our_side(config: LatencyConfig) -> Result<Vec<f64>, CloudError> {
    let (sub_side, pub_side) = peer_pair().await?;
    let (site, source) = bench_ids("bench", "lat-0")?;
    let n = usize::try_from(config.messages).unwrap_or(usize::MAX);
    let spacing_m = SPEED_MPS / config.rate_hz;
    let sent: SentAt = Arc::new(Mutex::new(vec![None; n]));
    let latencies = Arc::new(Mutex::new(Vec::with_capacity(n)));
    let ingest = LiveIngest::with_config(None, Some(TwinOutputs::new(None)), config.ingest)?;
    let ingest = Arc::new(Mutex::new(ingest));
    let (sent_cb, lat_cb, ingest_cb) = (Arc::clone(&sent), Arc::clone(&latencies), Arc::clone(&ingest));
    // The next sample not yet seen in a snapshot.
    let covered = Arc::new(Mutex::new(0usize));
    let loss_ingest = Arc::clone(&ingest);
    let on_loss = move |loss: StreamLoss| loss_ingest.locked().record_loss(&loss);
    let on_sample = move |_, sample: &Sample| {
        let payload = sample.payload().to_bytes();
        let mut ingest = ingest_cb.locked();
        if ingest.handle(sample.key_expr().as_str(), sample.encoding(), &payload, None, Origin::of(sample)).is_err() {
            return;
        }
        let now = Instant::now();
        let Some(x_m) =
            ingest.twin().and_then(|t| t.site("bench")).and_then(|s| s.vehicles.first()).map(|v| v.kinematics.pose.x_m)
        else {
            return;
        };
        // Interpolated between samples k and k+1: the snapshot reflects every sample ≤ k.
        let reflected = (x_m / spacing_m + 1e-6).floor().max(-1.0) as i64;
        let mut next = covered.locked();
        while (*next as i64) <= reflected && *next < n {
            if let Some(t) = put_instant(&sent_cb, *next).filter(|_| *next >= WARMUP) {
                lat_cb.locked().push(now.duration_since(t).as_secs_f64() * 1e3);
            }
            *next += 1;
        }
    };
    let subscriber = subscribe_edge_streams(&sub_side, Some(&site), on_sample, on_loss).await?;
    // As a live edge's state stream: congestion drops, what the link dropped is recovered.
    let delivery = Delivery::live(config.rate_hz, DEFAULT_OUTAGE);
    let publisher = StreamPublisher::declare(&pub_side, &site, &source, EdgeStream::State, delivery)?;
    let (_trigger, shutdown) = risktwin_transport::shutdown::channel();
    publisher.wait_for_subscriber(Duration::from_secs(5), shutdown).await?;
    let start = Instant::now();
    for seq in 0..n {
        tokio::time::sleep_until((start + period(config) * seq as u32).into()).await;
        let payload = encode(&state("lat-0", seq as u64, seq as f64 * spacing_m, SPEED_MPS));
        sent.locked()[seq] = Some(Instant::now());
        publisher.put(payload)?;
    }
    // The last samples are only covered by snapshots after them: none come; count what came.
    settle(&latencies, n.saturating_sub(WARMUP + 20)).await;
    let _ = subscriber.undeclare().await;
    publisher.undeclare()?;
    let _ = sub_side.close().wait();
    let _ = pub_side.close().wait();
    let out = latencies.locked().clone();
    Ok(out)
}
