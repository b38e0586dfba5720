//! Edge state publish → hazard warning received at the vehicle, against a raw Zenoh one-way hop,
//! in one run (`risktwin bench warning`).
//!
//! Both sides use two peer sessions in this process joined over TCP loopback (as `bench
//! latency`), the same message count and rate, and one clock (`Instant`):
//! - raw: `bench latency`'s raw side, a plain publisher → plain subscriber, one hop, sent with
//!   the warning puts' QoS (express, `InteractiveHigh`, `Drop`; `bench latency`'s raw side
//!   blocks at the default priority);
//! - ours: two vehicles on the edge session, `warn-0` driving at 10 m/s towards `warn-1`
//!   standing 15 m ahead (both keep that gap, so every message is critical: TTC ≈ 1.05 s). Each
//!   state goes through the cloud's own path on the other session (the edge-stream subscriber,
//!   [`LiveIngest`] with the twin and the warning role: decode, re-assess the pairs, put the
//!   warning from the callback through the publisher the role's task declared, then align, on
//!   the cloud's default road) and the warning comes back to a subscriber on `warn-0`'s warning
//!   key on the edge session: two hops (the edge stream's, then the warning's) where raw has one.
//!   Latency = the warning's arrival − the put of the state that raised it (its trigger seq);
//!   the repeat limit is off so that every message warns. Also reported: the time from the
//!   cloud callback's start (the sample handed over by Zenoh) to the return of the warning's
//!   put, recorded in the sink.
//!
//! The first [`WARMUP`] samples of each side are left out.
//!
//! Besides, [`assess_cost`] times the warning path alone (no transport) per state message with
//! N vehicles on one site: each state scans every live member of its site.

use crate::latency::{
    LatencyConfig, RawQos, SentAt, WARMUP, bench_ids, percentile, put_instant, raw_side, settle, state,
};
use crate::zenoh_throughput::peer_pair;
use risktwin_align::{IngestConfig, SourceIndex};
use risktwin_cloud::ingest::{AcceptedMessage, ObservedKinematics};
use risktwin_cloud::network::warning::{self as net_warning, NetworkSink, warning_sink};
use risktwin_cloud::network::{CloudError, LiveIngest, Origin};
use risktwin_cloud::twin::outputs::TwinOutputs;
use risktwin_cloud::twin::risk::{RiskAssessor, RiskConfig};
use risktwin_cloud::twin::scenario_road;
use risktwin_cloud::warning::{HazardWarner, WarningConfig, WarningSink, WarningSummary};
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::road::Road;
use risktwin_common::scenario::ScenarioKind;
use risktwin_common::telemetry::HazardWarning;
use risktwin_protos::{decode_tagged, encode};
use risktwin_transport::keyexpr::{CloudToEdge, cloud_to_edge};
use risktwin_transport::recovery::DEFAULT_OUTAGE;
use risktwin_transport::sync::LockExt;
use risktwin_transport::zenoh::Wait;
use risktwin_transport::zenoh::sample::Sample;
use risktwin_transport::{Delivery, EdgeStream, StreamLoss, StreamPublisher, TransportError, subscribe_edge_streams};
use serde::Serialize;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The warning path's target: a warning at the vehicle within 5 ms p50 of the state that raised
/// it (issue 16; 3GPP TS 22.185 gives pre-crash sensing 20 ms).
pub const TARGET_P50_MS: f64 = 5.0;
/// The measured vehicle's speed, m/s, and its gap to the standing one ahead (centres), m.
const SPEED_MPS: f64 = 10.0;
const GAP_M: f64 = 15.0;

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarningBenchConfig {
    /// Messages per side (the first [`WARMUP`] are not counted); ours sends as many of each vehicle.
    pub messages: u64,
    /// Publish rate, Hz.
    pub rate_hz: f64,
    /// Run the risk role (a risk field of every vehicle at 2 Hz) in the same callback too.
    pub risk: bool,
}

/// The figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarningReport {
    pub messages: u64,
    pub rate_hz: f64,
    pub risk: bool,
    pub raw_p50_ms: f64,
    pub raw_p99_ms: f64,
    /// Edge publish → warning received at the vehicle: two hops.
    pub warning_p50_ms: f64,
    pub warning_p99_ms: f64,
    /// Of that, in the cloud: the callback's start (the sample handed over) → the warning's put
    /// returned.
    pub cloud_p50_ms: f64,
    pub cloud_p99_ms: f64,
    pub raw_samples: usize,
    pub warning_samples: usize,
    /// What the cloud's warning path counted: warnings sent (to both vehicles, for both
    /// vehicles' messages), held back, failed.
    pub warnings: WarningSummary,
    /// warning_p50 / raw_p50 (two hops against one).
    pub ratio: f64,
    pub target_p50_ms: f64,
    /// The warning path alone per state message, µs, with N vehicles on the site: (N, µs).
    pub assess_us_per_state: Vec<(usize, f64)>,
}

/// Runs both sides and reports.
pub async fn warning(config: WarningBenchConfig) -> Result<WarningReport, CloudError> {
    let raw_config =
        LatencyConfig { messages: config.messages, rate_hz: config.rate_hz, ingest: IngestConfig::default() };
    let warning_qos =
        RawQos { congestion: net_warning::CONGESTION, priority: net_warning::PRIORITY, express: net_warning::EXPRESS };
    let mut raw = raw_side(raw_config, warning_qos).await?;
    let (mut ours, mut cloud, warnings) = our_side(config).await?;
    let assess_us_per_state = ASSESS_SIZES.iter().map(|&n| (n, assess_cost(n, ASSESS_STATES))).collect();
    let (raw_p50, raw_p99) = (percentile(&mut raw, 0.5), percentile(&mut raw, 0.99));
    let (ours_p50, ours_p99) = (percentile(&mut ours, 0.5), percentile(&mut ours, 0.99));
    Ok(WarningReport {
        messages: config.messages,
        rate_hz: config.rate_hz,
        risk: config.risk,
        raw_p50_ms: raw_p50,
        raw_p99_ms: raw_p99,
        warning_p50_ms: ours_p50,
        warning_p99_ms: ours_p99,
        cloud_p50_ms: percentile(&mut cloud, 0.5),
        cloud_p99_ms: percentile(&mut cloud, 0.99),
        raw_samples: raw.len(),
        warning_samples: ours.len(),
        warnings,
        ratio: ours_p50 / raw_p50,
        target_p50_ms: TARGET_P50_MS,
        assess_us_per_state,
    })
}

/// Site sizes [`assess_cost`] is run with, and the state messages timed at each.
const ASSESS_SIZES: [usize; 3] = [10, 100, 1000];
const ASSESS_STATES: usize = 20_000;

/// The warning path alone ([`HazardWarner::on_state`], no transport, a sink that drops
/// everything) per state message, µs: `n` vehicles in dense traffic on a straight two-lane road
/// (pairs side by side, 30 m apart along it, 20 m/s, ±1 m/s), each sending a state in turn at
/// 50 Hz, `states` messages timed after one warm-up round.
pub fn assess_cost(n: usize, states: usize) -> f64 {
    const PERIOD_NS: i64 = 20_000_000;
    let rows = n.div_ceil(2);
    let road = Road::straight(2, 3.5, 30.0 * rows as f64 + 500.0, 30.0);
    let mut warner = HazardWarner::new(WarningConfig::default(), Some(road.clone()));
    let mut sink = |_: &str, _: &HazardWarning| true;
    let names: Vec<String> = (0..n).map(|i| format!("v{i}")).collect();
    let speeds: Vec<f64> = (0..n).map(|i| 20.0 + ((i * 7919) % 21) as f64 * 0.1 - 1.0).collect();
    let lane_y: Vec<f64> = (0..2).map(|l| -road.lane(l).project(Vec2::new(50.0, 0.0)).e_y_m).collect();
    let message = |i: usize, k: usize| {
        let t_ns = 1_000_000_000 + k as i64 * PERIOD_NS + (i as i64 * PERIOD_NS) / n as i64;
        let x_m = 50.0 + 30.0 * (i / 2) as f64 + speeds[i] * (t_ns as f64 * 1e-9);
        let state = ObservedKinematics {
            pose: Pose::new(x_m, lane_y[i % 2], 0.0),
            velocity: Vec2::new(speeds[i], 0.0),
            speed_mps: speeds[i],
            accel_mps2: 0.0,
            footprint: Footprint::new(4.5, 1.8),
            seqs: (k as u64, k as u64),
        };
        let source = SourceIndex(i as u32);
        (AcceptedMessage { source, seq: k as u64, capture_ns: t_ns, cloud_ns: t_ns, state: Some(state) }, t_ns)
    };
    for (i, name) in names.iter().enumerate() {
        let (msg, t_ns) = message(i, 0);
        warner.on_state("bench", name, &msg, t_ns, &mut sink);
    }
    let start = Instant::now();
    for j in 0..states {
        let (i, k) = (j % n, 1 + j / n);
        let (msg, t_ns) = message(i, k);
        warner.on_state("bench", &names[i], &msg, t_ns, &mut sink);
    }
    start.elapsed().as_secs_f64() * 1e6 / states.max(1) as f64
}

/// The network sink, noting when the put of each warning to the measured vehicle returned,
/// against the start of the callback that raised it.
struct TimedSink {
    inner: NetworkSink,
    measured_key: String,
    /// The running callback's start (set under the ingest's lock, read in the put).
    receipt: Arc<Mutex<Option<Instant>>>,
    held: Arc<Mutex<Vec<f64>>>,
}

impl WarningSink for TimedSink {
    fn joined(&mut self, key: &str) {
        self.inner.joined(key);
    }

    fn left(&mut self, key: &str) {
        self.inner.left(key);
    }

    fn put(&mut self, key: &str, warning: &HazardWarning) -> bool {
        let ok = self.inner.put(key, warning);
        let seq = usize::try_from(warning.trigger_seq).unwrap_or(usize::MAX);
        if key == self.measured_key && warning.trigger_source == "warn-0" && seq >= WARMUP {
            let put = Instant::now();
            if let Some(receipt) = *self.receipt.locked() {
                let ms = put.duration_since(receipt).as_secs_f64() * 1e3;
                self.held.locked().push(ms);
            }
        }
        ok
    }

    fn count(&self, summary: &mut WarningSummary) {
        self.inner.count(summary);
    }
}

/// Latencies of warnings at the vehicle and the cloud's time per measured state, ms.
async fn our_side(config: WarningBenchConfig) -> Result<(Vec<f64>, Vec<f64>, WarningSummary), CloudError> {
    let (cloud_side, edge_side) = peer_pair().await?;
    let (site, measured) = bench_ids("bench", "warn-0")?;
    let (_, hazard) = bench_ids("bench", "warn-1")?;
    let n = usize::try_from(config.messages).unwrap_or(usize::MAX);
    let sent: SentAt = Arc::new(Mutex::new(vec![None; n]));
    let latencies = Arc::new(Mutex::new(Vec::with_capacity(n)));
    let held = Arc::new(Mutex::new(Vec::with_capacity(n)));

    // The cloud: ingest, twin (and risk), warning, on the cloud's default road.
    let road = scenario_road(ScenarioKind::CutIn);
    let risk = if config.risk { Some(RiskAssessor::new(road.clone(), RiskConfig::default())?) } else { None };
    let warner = HazardWarner::new(WarningConfig { repeat_ns: 0, ..WarningConfig::default() }, Some(road));
    let warning_key = cloud_to_edge(&site, &measured, CloudToEdge::Warning);
    let (inner, publishers) = warning_sink(&cloud_side);
    let receipt = Arc::new(Mutex::new(None));
    let sink =
        TimedSink { inner, measured_key: warning_key.clone(), receipt: Arc::clone(&receipt), held: Arc::clone(&held) };
    let ingest = LiveIngest::new(None, Some(TwinOutputs::new(risk)))?.with_warnings(Some((warner, Box::new(sink))));
    let ingest = Arc::new(Mutex::new(ingest));
    let (ingest_cb, loss_ingest) = (Arc::clone(&ingest), Arc::clone(&ingest));
    let on_sample = move |_, sample: &Sample| {
        let start = Instant::now();
        let payload = sample.payload().to_bytes();
        let key = sample.key_expr().as_str();
        let mut ingest = ingest_cb.locked();
        // Under the ingest's lock: no other callback's start can take its place.
        *receipt.locked() = Some(start);
        if let Err(e) = ingest.handle(key, sample.encoding(), &payload, None, Origin::of(sample)) {
            tracing::warn!("bench warning: ingest: {e}");
        }
    };
    let on_loss = move |loss: StreamLoss| loss_ingest.locked().record_loss(&loss);
    let subscriber = subscribe_edge_streams(&cloud_side, Some(&site), on_sample, on_loss).await?;

    // The vehicle: its warnings, timed against the put of the state that raised them.
    let (sent_cb, lat_cb) = (Arc::clone(&sent), Arc::clone(&latencies));
    let warnings = edge_side
        .declare_subscriber(warning_key.clone())
        .callback(move |sample| {
            let now = Instant::now();
            let bytes = sample.payload().to_bytes();
            let Ok(w) = decode_tagged::<HazardWarning>(&sample.encoding().to_string(), &bytes) else { return };
            let seq = usize::try_from(w.trigger_seq).unwrap_or(usize::MAX);
            if w.trigger_source != "warn-0" || seq < WARMUP {
                return;
            }
            if let Some(t) = put_instant(&sent_cb, seq) {
                lat_cb.locked().push(now.duration_since(t).as_secs_f64() * 1e3);
            }
        })
        .await
        .map_err(|e| TransportError::Declare { what: "subscriber", key: warning_key, reason: e.to_string() })?;

    let delivery = Delivery::live(config.rate_hz, DEFAULT_OUTAGE);
    let ahead = StreamPublisher::declare(&edge_side, &site, &hazard, EdgeStream::State, delivery)?;
    let publisher = StreamPublisher::declare(&edge_side, &site, &measured, EdgeStream::State, delivery)?;
    for p in [&ahead, &publisher] {
        let (_trigger, shutdown) = risktwin_transport::shutdown::channel();
        p.wait_for_subscriber(Duration::from_secs(5), shutdown).await?;
    }
    let spacing_m = SPEED_MPS / config.rate_hz;
    let period = Duration::from_secs_f64(1.0 / config.rate_hz);
    let start = Instant::now();
    for seq in 0..n {
        tokio::time::sleep_until((start + period * seq as u32).into()).await;
        let x_m = seq as f64 * spacing_m;
        ahead.put(encode(&state("warn-1", seq as u64, x_m + GAP_M, 0.0)))?;
        let payload = encode(&state("warn-0", seq as u64, x_m, SPEED_MPS));
        sent.locked()[seq] = Some(Instant::now());
        publisher.put(payload)?;
    }
    settle(&latencies, n.saturating_sub(WARMUP)).await;
    let _ = subscriber.undeclare().await;
    let _ = warnings.undeclare().await;
    publisher.undeclare()?;
    ahead.undeclare()?;
    publishers.task.abort();
    let _ = cloud_side.close().wait();
    let _ = edge_side.close().wait();
    let out = latencies.locked().clone();
    let held = held.locked().clone();
    let summary = ingest.locked().warning_summary().unwrap_or_default();
    Ok((out, held, summary))
}
