//! `risktwin edge vehicle|rsu|sensor|gateway`: parse, run the role (a simulated `--kind`/`--seed` scenario
//! publishing real telemetry) until its count, duration or a signal, and print what it sent per
//! stream as JSON on stdout.

use super::driver::{LoadedDriver, warn_faults};
use super::recover::warn_unfinished;
use super::router::{transport_config, with_signals};
use crate::cli::{EdgeArgs, ReplayArgs};
use crate::error::{CliError, CliResult};
use crate::metrics_endpoint::{self, MetricsEndpoint};
use crate::output::print_json;
use risktwin_edge::replay::{self, ReplayConfig};
use risktwin_edge::{ClockModel, EdgeConfig, EdgeError, gateway, rsu, sensor, vehicle};
use risktwin_transport::{SiteId, SourceId};
use std::time::Duration;

/// The role name of `edge vehicle` (its metrics and the one role that takes `--driver`).
const VEHICLE_ROLE: &str = "edge-vehicle";

pub fn vehicle(args: EdgeArgs) -> CliResult {
    let (config, metrics) = edge_config(args, vehicle::DEFAULT_STATE_RATE_HZ, VEHICLE_ROLE)?;
    // The driver it started with (a policy push may replace it; its faults still count).
    let started_with = config.driver.as_ref().map(|d| (d.id.policy_id.clone(), d.model.clone()));
    let summary =
        with_signals(|shutdown| async move { vehicle::run(&config, shutdown).await.map_err(CliError::runtime) });
    if let Some((label, model)) = &started_with {
        warn_faults(label, model);
    }
    let summary = summary?;
    print_json(&summary)?;
    last_scrape(metrics);
    delivered(&summary.sent)
}

/// Lets a scraper take the role's final counts before the process exits.
fn last_scrape(metrics: Option<MetricsEndpoint>) {
    if let Some(endpoint) = metrics {
        endpoint.last_scrape();
    }
}

/// Exit 1 (after the summary) when messages sent were not all delivered or some were refused.
fn delivered(summary: &risktwin_edge::SentSummary) -> CliResult {
    summary.failure().map_or(Ok(()), |why| Err(CliError::runtime(why)))
}

pub fn sensor(args: EdgeArgs) -> CliResult {
    let (config, metrics) = edge_config(args, vehicle::DEFAULT_STATE_RATE_HZ, "edge-sensor")?;
    let summary =
        with_signals(|shutdown| async move { sensor::run(&config, shutdown).await.map_err(CliError::runtime) })?;
    print_json(&summary)?;
    last_scrape(metrics);
    Ok(())
}

pub fn gateway(args: EdgeArgs) -> CliResult {
    let (config, metrics) = edge_config(args, vehicle::DEFAULT_STATE_RATE_HZ, "edge-gateway")?;
    risktwin_edge::shm::validate_vehicle_id(config.id.as_str()).map_err(CliError::input)?;
    let summary =
        with_signals(|shutdown| async move { gateway::run(&config, shutdown).await.map_err(CliError::runtime) })?;
    print_json(&summary)?;
    last_scrape(metrics);
    summary.failure().map_or(Ok(()), |why| Err(CliError::runtime(why)))
}

pub fn rsu(args: EdgeArgs) -> CliResult {
    let (config, metrics) = edge_config(args, rsu::DEFAULT_RATE_HZ, "edge-rsu")?;
    let summary = with_signals(|shutdown| async move { rsu::run(&config, shutdown).await.map_err(CliError::runtime) })?;
    print_json(&summary)?;
    last_scrape(metrics);
    delivered(&summary)
}

pub fn replay(args: ReplayArgs) -> CliResult {
    if !(args.speed.is_finite() && args.speed >= 0.0) {
        return Err(CliError::input(format!("--speed {} must be a non-negative number (0: unpaced)", args.speed)));
    }
    let wait_for_cloud = Duration::try_from_secs_f64(args.wait_for_cloud_s)
        .map_err(|_| CliError::input(format!("--wait-for-cloud-s {} must be non-negative", args.wait_for_cloud_s)))?;
    let (cursor, _files) = super::recordings::span_cursor(&args.recording, &args.span)?;
    let config =
        ReplayConfig { transport: transport_config(args.zenoh)?, speed: args.speed, wait_for_cloud, ack: !args.no_ack };
    let path = args.recording.display().to_string();
    let metrics = metrics_endpoint::start(&args.metrics, "edge-replay")?;
    let summary = with_signals(|shutdown| async move {
        replay::run(cursor, &config, shutdown).await.map_err(|e| match e {
            EdgeError::Recording { .. } => CliError::input(format!("{path}: {e}")),
            other => CliError::runtime(other),
        })
    })?;
    for (file, unfinished) in &summary.unfinished {
        warn_unfinished(file, unfinished);
    }
    print_json(&summary)?;
    last_scrape(metrics);
    summary.failure().map_or(Ok(()), |why| Err(CliError::runtime(why)))
}

/// The config of an edge role, and its metrics endpoint once the config is valid.
fn edge_config(args: EdgeArgs, default_rate_hz: f64, role: &str) -> CliResult<(EdgeConfig, Option<MetricsEndpoint>)> {
    let site = SiteId::new(args.site).map_err(CliError::input)?;
    let id = SourceId::new(args.id).map_err(CliError::input)?;
    let rate_hz = args.rate_hz.unwrap_or(default_rate_hz);
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(CliError::input(format!("--rate-hz {rate_hz} must be a positive number")));
    }
    let seconds = |flag: &str, s: f64| {
        Duration::try_from_secs_f64(s)
            .map_err(|_| CliError::input(format!("{flag} {s} must be a non-negative number of seconds")))
    };
    let duration = args.duration.map(|s| seconds("--duration", s)).transpose()?;
    if !args.clock_drift_ppm.is_finite() {
        return Err(CliError::input(format!("--clock-drift-ppm {} must be finite", args.clock_drift_ppm)));
    }
    let mut config = EdgeConfig::new(site, id, rate_hz);
    config.transport = transport_config(args.zenoh)?;
    config.count = args.count;
    config.duration = duration;
    config.clock = ClockModel {
        offset_ns: args.clock_offset_ns,
        drift_ppm: args.clock_drift_ppm,
        jitter_ns: i64::from(args.clock_jitter_ns),
        seed: args.seed,
    };
    config.kind = args.kind.parse().map_err(CliError::input)?;
    config.scenario_seed = args.seed;
    config.wait_for_cloud = seconds("--wait-for-cloud-s", args.wait_for_cloud_s)?;
    config.cache_span = seconds("--cache-s", args.cache_s)?;
    config.clock_steps = args.clock_steps;
    config.ack = !args.no_ack;
    config.trust_key = args.trust_key.as_deref().map(super::keys::read_trust_key).transpose()?;
    config.driver = match &args.driver {
        Some(_) if role != VEHICLE_ROLE => {
            return Err(CliError::input("--driver names a vehicle's driver: edge vehicle only"));
        }
        Some(spec) => LoadedDriver::load(spec, "--driver")?.active(),
        None => None,
    };
    Ok((config, metrics_endpoint::start(&args.metrics, role)?))
}
