//! Can the cloud ingest hold a fleet (2,000 vehicles at 50 Hz: 100k msg/s) in reliable mode
//! without loss, and at what CPU cost? (`risktwin bench ingest`)
//!
//! [`cloud_side`] runs the cloud ingest role (the real [`risktwin_cloud::network::run`]: one
//! wildcard subscriber, decode, validate, exactly-once, clock estimation, alignment) as a Zenoh
//! peer listening on a free loopback port, and starts publisher child processes that emulate the
//! vehicles ([`publish_share`] in each): per vehicle a declared reliable, blocking publisher of
//! real `VehicleState` protobuf messages with its own sequence numbers and clock (offset and
//! drift, see [`SyntheticFleet`]), paced on a 10 ms timer. When the children have sent
//! everything the cloud drains and stops; its CPU use is this process's `getrusage` user +
//! system time over the wall time from the children's start to the cloud's stop (the children's
//! CPU is not in it).

use crate::BenchError;
use crate::synth::{FLEET_TICK_NS, FleetConfig, SyntheticFleet};
use risktwin_cloud::network::{CloudConfig, run};
use risktwin_transport::{
    Delivery, EdgeStream, Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, close, connect,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Samples each emulated vehicle keeps for recovery: 1 s at 50 Hz. A real edge keeps 30 s
/// (one vehicle per process); thousands of vehicles in one process would hold gigabytes.
const FLEET_CACHE_SAMPLES: usize = 50;

/// The fleet to emulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FleetBenchConfig {
    /// Vehicles in the fleet (split evenly over the publishers).
    pub vehicles: usize,
    /// State messages per vehicle per second; must divide 100.
    pub rate_hz: u64,
    /// Seconds of publishing.
    pub seconds: u64,
    /// Publisher processes (one Zenoh session each).
    pub publishers: usize,
}

/// One publisher process's share of the fleet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FleetShare {
    /// Where the cloud listens.
    pub locator: String,
    /// Index of the share's first vehicle.
    pub first_vehicle: usize,
    /// Vehicles in the share.
    pub vehicles: usize,
}

/// What one publisher process sent (its stdout, as JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FleetReport {
    pub sent: u64,
    pub wall_s: f64,
}

/// The figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IngestReport {
    pub vehicles: usize,
    pub rate_hz: u64,
    pub seconds: u64,
    pub publishers: usize,
    pub offered_msgs_per_s: u64,
    pub sent: u64,
    pub received: u64,
    pub dropped: BTreeMap<String, u64>,
    pub lost: i64,
    /// Received over the longest publisher's wall time.
    pub achieved_msgs_per_s: f64,
    pub snapshots: u64,
    pub cloud_cpu_s: f64,
    pub cloud_wall_s: f64,
    /// CPU seconds per wall second of the cloud process (1.0 = one core busy).
    pub cloud_cpu_cores: f64,
    pub cloud_cpu_us_per_msg: f64,
}

/// User + system CPU seconds of this process so far.
fn process_cpu_s() -> f64 {
    // SAFETY: getrusage only writes into the zeroed struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: a valid pointer to a rusage; RUSAGE_SELF is always valid.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return f64::NAN;
    }
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    secs(usage.ru_utime) + secs(usage.ru_stime)
}

fn free_port() -> Result<u16, BenchError> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").map_err(BenchError::runtime)?;
    Ok(listener.local_addr().map_err(BenchError::runtime)?.port())
}

/// Runs the cloud ingest role (recording into `record_dir` when given) and one publisher
/// process per share, each started by `publisher` (a command whose stdout is one
/// [`FleetReport`]), and reports.
pub async fn cloud_side(
    config: FleetBenchConfig,
    record_dir: Option<risktwin_store::recordings::RotationConfig>,
    publisher: impl Fn(&FleetShare) -> Command,
) -> Result<IngestReport, BenchError> {
    let locator = format!("tcp/127.0.0.1:{}", free_port()?);
    let transport = TransportConfig { listen: vec![locator.clone()], ..TransportConfig::default() };
    let mut cloud_config = CloudConfig::new(transport);
    cloud_config.drain_quiet = Duration::from_millis(300);
    cloud_config.drain_max = Duration::from_secs(10);
    cloud_config.record_dir = record_dir;
    let (trigger, shutdown) = risktwin_transport::shutdown::channel();
    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel();
    let cloud = tokio::spawn(async move {
        run(&cloud_config, shutdown, move |_| {
            let _ = ready_tx.send(());
        })
        .await
    });
    ready_rx.await.map_err(|_| BenchError::runtime("the cloud stopped before it was ready"))?;

    let per = config.vehicles.div_ceil(config.publishers);
    let cpu_start = process_cpu_s();
    let start = Instant::now();
    let mut children = Vec::new();
    for p in 0..config.publishers {
        let first_vehicle = p * per;
        let share =
            FleetShare { locator: locator.clone(), first_vehicle, vehicles: per.min(config.vehicles - first_vehicle) };
        let child =
            publisher(&share).stdout(Stdio::piped()).stdin(Stdio::null()).spawn().map_err(BenchError::runtime)?;
        children.push(child);
    }
    let outputs = tokio::task::spawn_blocking(move || {
        children.into_iter().map(std::process::Child::wait_with_output).collect::<Result<Vec<_>, _>>()
    })
    .await
    .map_err(BenchError::runtime)?
    .map_err(BenchError::runtime)?;
    trigger.fire();
    let summary = cloud.await.map_err(BenchError::runtime)?.map_err(BenchError::runtime)?;
    let cloud_wall_s = start.elapsed().as_secs_f64();
    let cloud_cpu_s = process_cpu_s() - cpu_start;

    let mut reports = Vec::new();
    for out in outputs {
        if !out.status.success() {
            return Err(BenchError::Runtime(format!("a fleet publisher failed: {}", out.status)));
        }
        let report: FleetReport = serde_json::from_slice(&out.stdout)
            .map_err(|e| BenchError::Runtime(format!("a fleet publisher's report: {e}")))?;
        reports.push(report);
    }
    let sent: u64 = reports.iter().map(|r| r.sent).sum();
    let publish_wall_s = reports.iter().map(|r| r.wall_s).fold(0.0, f64::max);
    let received = summary.ingest.total_received;
    Ok(IngestReport {
        vehicles: config.vehicles,
        rate_hz: config.rate_hz,
        seconds: config.seconds,
        publishers: config.publishers,
        offered_msgs_per_s: config.vehicles as u64 * config.rate_hz,
        sent,
        received,
        lost: sent as i64 - received as i64 - summary.ingest.total_dropped as i64,
        dropped: summary.ingest.dropped,
        achieved_msgs_per_s: received as f64 / publish_wall_s,
        snapshots: summary.ingest.snapshots,
        cloud_cpu_s,
        cloud_wall_s,
        cloud_cpu_cores: cloud_cpu_s / cloud_wall_s,
        cloud_cpu_us_per_msg: cloud_cpu_s * 1e6 / received.max(1) as f64,
    })
}

/// One publisher process: its share of the fleet at `rate_hz` for `seconds`, paced on the 10 ms
/// tick. With `tokens`, every vehicle holds its liveliness token and is waited on until a
/// subscriber matches it (sharded workers subscribe vehicle by vehicle, as they see the tokens);
/// without, the first vehicle's match is enough (one cloud subscribes to all at once).
pub async fn publish_share(
    share: &FleetShare,
    rate_hz: u64,
    seconds: u64,
    tokens: bool,
    shutdown: Shutdown,
) -> Result<FleetReport, BenchError> {
    let transport = TransportConfig { connect: vec![share.locator.clone()], ..TransportConfig::default() };
    let session = connect(&transport).await.map_err(BenchError::runtime)?;
    let site = SiteId::new("bench").map_err(BenchError::input)?;
    let config = FleetConfig {
        state_every_ticks: 100 / rate_hz,
        first_vehicle: share.first_vehicle,
        ..FleetConfig::states_only(share.vehicles)
    };
    let mut fleet = SyntheticFleet::new(config, site.as_str());
    let mut publishers = Vec::with_capacity(share.vehicles);
    let mut held_tokens = Vec::new();
    for i in 0..share.vehicles {
        let source = SourceId::new(format!("veh-{:05}", share.first_vehicle + i)).map_err(BenchError::input)?;
        let delivery = Delivery::paced_by_transport(FLEET_CACHE_SAMPLES);
        let publisher = StreamPublisher::declare(&session, &site, &source, EdgeStream::State, delivery);
        publishers.push(publisher.map_err(BenchError::runtime)?);
        if tokens {
            let key = risktwin_transport::keyexpr::liveliness_token(&site, &source);
            let token = session.liveliness().declare_token(key).await.map_err(BenchError::runtime)?;
            held_tokens.push(token);
        }
    }
    let waited_on = if tokens { &publishers[..] } else { &publishers[..publishers.len().min(1)] };
    for publisher in waited_on {
        if !publisher
            .wait_for_subscriber(Duration::from_secs(30), shutdown.clone())
            .await
            .map_err(BenchError::runtime)?
        {
            return Err(BenchError::runtime(format!("no cloud subscriber on {} within 30 s", publisher.key())));
        }
    }
    let mut timer = tokio::time::interval(Duration::from_nanos(FLEET_TICK_NS as u64));
    timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Burst);
    let mut batch: Vec<(usize, Vec<u8>)> = Vec::with_capacity(share.vehicles);
    let mut sent = 0u64;
    let start = Instant::now();
    for tick in 0..seconds * 100 {
        if shutdown.is_fired() {
            break;
        }
        timer.tick().await;
        fleet.tick(tick, |m| batch.push((m.vehicle, m.payload.to_vec())));
        for (vehicle, payload) in batch.drain(..) {
            publishers[vehicle].put(payload).map_err(BenchError::runtime)?;
            sent += 1;
        }
    }
    let wall_s = start.elapsed().as_secs_f64();
    drop(held_tokens);
    close(session).await.map_err(BenchError::runtime)?;
    Ok(FleetReport { sent, wall_s })
}
