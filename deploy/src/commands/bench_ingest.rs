//! `risktwin bench ingest`: can the cloud ingest hold a fleet (2,000 vehicles at 50 Hz: 100k
//! msg/s) in reliable mode without loss, and at what CPU cost?
//!
//! This process runs the cloud ingest role (the real [`risktwin_cloud::transport::run`]: one
//! wildcard subscriber, decode, validate, exactly-once, clock estimation, alignment) as a Zenoh
//! peer listening on a free loopback port, and starts `--publishers` child processes of itself
//! that emulate the vehicles: per vehicle a declared reliable, blocking publisher of real
//! `VehicleState` protobuf messages with its own sequence numbers and clock (offset and drift,
//! see [`SyntheticFleet`]), paced on a 10 ms timer. When the children have sent everything the
//! cloud drains and stops; its CPU use is this process's `getrusage` user + system time over the
//! wall time from the children's start to the cloud's stop (the children's CPU is not in it).

use super::router::with_signals;
use crate::cli::BenchIngestArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_cloud::ingest::synth::{FLEET_TICK_NS, FleetConfig, SyntheticFleet};
use risktwin_cloud::transport::{CloudConfig, run};
use risktwin_transport::{EdgeStream, Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, close, connect};
use serde::Serialize;
use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What one publisher process sent.
#[derive(Debug, Serialize, serde::Deserialize)]
struct FleetReport {
    sent: u64,
    wall_s: f64,
}

#[derive(Serialize)]
struct IngestReport {
    vehicles: usize,
    rate_hz: u64,
    seconds: u64,
    publishers: usize,
    offered_msgs_per_s: u64,
    sent: u64,
    received: u64,
    dropped: BTreeMap<String, u64>,
    lost: i64,
    /// Received over the longest publisher's wall time.
    achieved_msgs_per_s: f64,
    snapshots: u64,
    cloud_cpu_s: f64,
    cloud_wall_s: f64,
    /// CPU seconds per wall second of the cloud process (1.0 = one core busy).
    cloud_cpu_cores: f64,
    cloud_cpu_us_per_msg: f64,
}

pub fn ingest(args: BenchIngestArgs) -> CliResult {
    if args.vehicles == 0 || args.seconds == 0 || args.publishers == 0 || args.publishers > args.vehicles {
        return Err(CliError::input("--vehicles, --seconds and --publishers must be positive, publishers ≤ vehicles"));
    }
    if args.rate_hz == 0 || 100 % args.rate_hz != 0 {
        return Err(CliError::input(format!("--rate-hz {} must divide 100 (the fleet's 10 ms tick)", args.rate_hz)));
    }
    if let Some(locator) = args.fleet_connect.clone() {
        let report = with_signals(|shutdown| async move { publish_fleet(&args, locator, shutdown).await })?;
        return print_json(&report);
    }
    let format = args.format;
    let report = with_signals(|_shutdown| async move { run_cloud(&args).await })?;
    match format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["sent", "received", "dropped", "lost", "msgs/s achieved", "offered", "cloud CPU cores", "µs CPU/msg"],
            &[vec![
                report.sent.to_string(),
                report.received.to_string(),
                format!("{:?}", report.dropped),
                report.lost.to_string(),
                format!("{:.0}", report.achieved_msgs_per_s),
                report.offered_msgs_per_s.to_string(),
                format!("{:.3}", report.cloud_cpu_cores),
                format!("{:.2}", report.cloud_cpu_us_per_msg),
            ]],
        ),
    }
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

fn free_port() -> CliResult<u16> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").map_err(CliError::runtime)?;
    Ok(listener.local_addr().map_err(CliError::runtime)?.port())
}

async fn run_cloud(args: &BenchIngestArgs) -> CliResult<IngestReport> {
    let locator = format!("tcp/127.0.0.1:{}", free_port()?);
    let transport = TransportConfig { listen: vec![locator.clone()], ..TransportConfig::default() };
    let mut config = CloudConfig::new(transport);
    config.drain_quiet = Duration::from_millis(300);
    config.drain_max = Duration::from_secs(10);
    let (trigger, shutdown) = risktwin_transport::shutdown::channel();
    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel();
    let cloud = tokio::spawn(async move {
        run(&config, shutdown, move || {
            let _ = ready_tx.send(());
        })
        .await
    });
    ready_rx.await.map_err(|_| CliError::runtime("the cloud stopped before it was ready"))?;

    let exe = std::env::current_exe().map_err(CliError::runtime)?;
    let per = args.vehicles.div_ceil(args.publishers);
    let cpu_start = process_cpu_s();
    let start = Instant::now();
    let mut children = Vec::new();
    for p in 0..args.publishers {
        let first = p * per;
        let vehicles = per.min(args.vehicles - first);
        let child = Command::new(&exe)
            .args(["bench", "ingest", "--fleet-connect", &locator])
            .args(["--vehicles", &vehicles.to_string(), "--first-vehicle", &first.to_string()])
            .args(["--rate-hz", &args.rate_hz.to_string(), "--seconds", &args.seconds.to_string()])
            .stdout(Stdio::piped())
            .stdin(Stdio::null())
            .spawn()
            .map_err(CliError::runtime)?;
        children.push(child);
    }
    let outputs = tokio::task::spawn_blocking(move || {
        children.into_iter().map(std::process::Child::wait_with_output).collect::<Result<Vec<_>, _>>()
    })
    .await
    .map_err(CliError::runtime)?
    .map_err(CliError::runtime)?;
    trigger.fire();
    let summary = cloud.await.map_err(CliError::runtime)?.map_err(CliError::runtime)?;
    let cloud_wall_s = start.elapsed().as_secs_f64();
    let cloud_cpu_s = process_cpu_s() - cpu_start;

    let mut reports = Vec::new();
    for out in outputs {
        if !out.status.success() {
            return Err(CliError::runtime(format!("a fleet publisher failed: {}", out.status)));
        }
        let report: FleetReport = serde_json::from_slice(&out.stdout)
            .map_err(|e| CliError::runtime(format!("a fleet publisher's report: {e}")))?;
        reports.push(report);
    }
    let sent: u64 = reports.iter().map(|r| r.sent).sum();
    let publish_wall_s = reports.iter().map(|r| r.wall_s).fold(0.0, f64::max);
    let received = summary.ingest.total_received;
    Ok(IngestReport {
        vehicles: args.vehicles,
        rate_hz: args.rate_hz,
        seconds: args.seconds,
        publishers: args.publishers,
        offered_msgs_per_s: args.vehicles as u64 * args.rate_hz,
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

/// One publisher process: its share of the fleet, paced on the 10 ms tick.
async fn publish_fleet(args: &BenchIngestArgs, locator: String, shutdown: Shutdown) -> CliResult<FleetReport> {
    let transport = TransportConfig { connect: vec![locator], ..TransportConfig::default() };
    let session = connect(&transport).await.map_err(CliError::runtime)?;
    let site = SiteId::new("bench").map_err(CliError::input)?;
    let config = FleetConfig {
        state_every_ticks: 100 / args.rate_hz,
        first_vehicle: args.first_vehicle,
        ..FleetConfig::states_only(args.vehicles)
    };
    let mut fleet = SyntheticFleet::new(config, site.as_str());
    let mut publishers = Vec::with_capacity(args.vehicles);
    for i in 0..args.vehicles {
        let source = SourceId::new(format!("veh-{:05}", args.first_vehicle + i)).map_err(CliError::input)?;
        publishers.push(
            StreamPublisher::declare(&session, &site, &source, EdgeStream::State).await.map_err(CliError::runtime)?,
        );
    }
    if let Some(first) = publishers.first()
        && !first.wait_for_subscriber(Duration::from_secs(30), shutdown.clone()).await.map_err(CliError::runtime)?
    {
        return Err(CliError::runtime("no cloud subscriber within 30 s"));
    }
    let mut timer = tokio::time::interval(Duration::from_nanos(FLEET_TICK_NS as u64));
    timer.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Burst);
    let mut batch: Vec<(usize, Vec<u8>)> = Vec::with_capacity(args.vehicles);
    let mut sent = 0u64;
    let start = Instant::now();
    for tick in 0..args.seconds * 100 {
        if shutdown.is_fired() {
            break;
        }
        timer.tick().await;
        fleet.tick(tick, |m| batch.push((m.vehicle, m.payload.to_vec())));
        for (vehicle, payload) in batch.drain(..) {
            publishers[vehicle].put(payload).await.map_err(CliError::runtime)?;
            sent += 1;
        }
    }
    let wall_s = start.elapsed().as_secs_f64();
    close(session).await.map_err(CliError::runtime)?;
    Ok(FleetReport { sent, wall_s })
}
