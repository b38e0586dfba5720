//! `risktwin cloud`: run the cloud roles until SIGINT/SIGTERM, then print the JSON summary
//! (received per source and stream, drops by reason, snapshots and their digest, liveliness;
//! `--record FILE.mcap` records what was accepted). `ready` on stderr says the
//! subscriptions are in place. `--roles ingest,twin,risk` adds the live twin and risk on it,
//! `--roles library --db FILE` the library queryable, `--roles criticality --criticality-out
//! FILE.csv|json [--db FILE] [--ego ID]` the criticality of a replayed CommonRoad scenario,
//! written on exit (with `--db`, the drive stored as a recorded case of the library),
//! `--roles ingest,twin,loop[,trainer] --db FILE [--loop-report FILE.md]` the closed loop over
//! the fleet, with policy retraining and the regression gate; `--roles ingest,warning` a hazard
//! warning to both vehicles of a critical pair on every state message; `--roles
//! ingest,twin[,risk],viz [--viz-listen ADDR]` the live twin for the Foxglove app (`viz on
//! ws://ADDR` on stderr before `ready`).
//! Also `risktwin bench zenoh|latency|warning`.

use super::router::{transport_config, with_signals};
use crate::cli::{BenchLatencyArgs, BenchWarningArgs, BenchZenohArgs, CloudArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_align::IngestConfig;
use risktwin_bench::latency::{LatencyConfig, latency};
use risktwin_bench::secure_throughput::secure_throughput;
use risktwin_bench::warning::{WarningBenchConfig, warning};
use risktwin_bench::zenoh_throughput::{BenchConfig, throughput};
use risktwin_cloud::fleet_loop::trainer::TrainerConfig;
use risktwin_cloud::network::criticality::{CriticalityConfig, CriticalityRoleError};
use risktwin_cloud::network::{CloudConfig, CloudError, Role, run};
use risktwin_cloud::viz::VizConfig;
use risktwin_common::scenario::ScenarioKind;
use risktwin_pipeline::fidelity::write_fidelity_report;
use risktwin_transport::SiteId;
use std::time::Duration;

pub fn cloud(args: CloudArgs) -> CliResult {
    let roles =
        args.roles.iter().map(|r| r.trim().parse::<Role>()).collect::<Result<Vec<_>, _>>().map_err(CliError::input)?;
    let record_dir = super::recordings::rotation(&args.rotation)?;
    let mut config = CloudConfig::new(transport_config(args.zenoh)?);
    config.record_dir = record_dir;
    config.roles = roles;
    config.site = args.site.map(SiteId::new).transpose().map_err(CliError::input)?;
    config.record = args.record;
    config.replay_time = args.replay_time;
    if args.ego.is_some() && !config.roles.contains(&Role::Criticality) {
        return Err(CliError::input("--ego needs the criticality role (--roles ingest,criticality)"));
    }
    config.criticality = Some(CriticalityConfig { out: args.criticality_out, library: args.db.clone(), ego: args.ego });
    config.db = args.db;
    if args.fidelity_report.is_some() && !config.roles.contains(&Role::Twin) {
        return Err(CliError::input("--fidelity-report needs the twin role (--roles ingest,twin[,risk])"));
    }
    if !(args.push_timeout_s.is_finite() && (0.1..=86_400.0).contains(&args.push_timeout_s)) {
        return Err(CliError::input(format!("--push-timeout-s {} must lie in [0.1, 86400]", args.push_timeout_s)));
    }
    config.fleet_loop.result_timeout = Duration::from_secs_f64(args.push_timeout_s);
    if args.mutants_per_failure > 100 {
        return Err(CliError::input(format!(
            "--mutants-per-failure {} must lie in [0, 100]",
            args.mutants_per_failure
        )));
    }
    config.fleet_loop.mutants_per_failure = args.mutants_per_failure;
    if args.retrain_failures == 0 {
        return Err(CliError::input("--retrain-failures 0: must be positive"));
    }
    let every = match args.retrain_every_s {
        Some(s) if (1.0..=604_800.0).contains(&s) => Some(Duration::from_secs_f64(s)),
        Some(s) => return Err(CliError::input(format!("--retrain-every-s {s} must lie in [1, 604800]"))),
        None => None,
    };
    if !(1_000..=100_000_000).contains(&args.train_steps) {
        return Err(CliError::input(format!("--train-steps {} must lie in [1000, 100000000]", args.train_steps)));
    }
    if !(1..=1000).contains(&args.held_out_per_kind) {
        return Err(CliError::input(format!("--held-out-per-kind {} must lie in [1, 1000]", args.held_out_per_kind)));
    }
    config.trainer = TrainerConfig {
        retrain_failures: args.retrain_failures,
        every,
        steps: args.train_steps,
        held_out_per_kind: args.held_out_per_kind,
        seed: args.train_seed,
    };
    if args.signing_key.is_some() && !config.roles.contains(&Role::Loop) {
        return Err(CliError::input("--signing-key needs the loop role (it signs the policies the loop pushes)"));
    }
    config.signing_key = args.signing_key.as_deref().map(super::keys::read_signing_key).transpose()?;
    if config.signing_key.is_none() && config.roles.contains(&Role::Trainer) {
        tracing::warn!(
            "cloud: no --signing-key: the policies the trainer lets through are pushed unsigned, and every \
             vehicle refuses them (docs/signing.md)"
        );
    }
    if args.loop_report.is_some() && !config.roles.contains(&Role::Loop) {
        return Err(CliError::input("--loop-report needs the loop role (--roles ingest,twin,loop --db FILE)"));
    }
    if (args.warning_ttc_s.is_some() || args.warning_repeat_ms.is_some()) && !config.roles.contains(&Role::Warning) {
        return Err(CliError::input(
            "--warning-ttc-s and --warning-repeat-ms need the warning role (--roles ingest,warning)",
        ));
    }
    if let Some(ttc_s) = args.warning_ttc_s {
        if !(ttc_s > 0.0 && ttc_s <= 10.0) {
            return Err(CliError::input(format!("--warning-ttc-s {ttc_s} must lie in (0, 10]")));
        }
        config.warning.critical_ttc_s = ttc_s;
    }
    if let Some(repeat_ms) = args.warning_repeat_ms {
        if !(0.0..=60_000.0).contains(&repeat_ms) {
            return Err(CliError::input(format!("--warning-repeat-ms {repeat_ms} must lie in [0, 60000]")));
        }
        config.warning.repeat_ns = (repeat_ms * 1e6) as i64;
    }
    config.shard = args.shard;
    config.shed_after = match args.shed_after_ms {
        Some(ms) if (10.0..=60_000.0).contains(&ms) => Some(Duration::from_secs_f64(ms * 1e-3)),
        Some(ms) => return Err(CliError::input(format!("--shed-after-ms {ms} must lie in [10, 60000]"))),
        None => None,
    };
    let road_kind: ScenarioKind = args.road.parse().map_err(CliError::input)?;
    config.road = risktwin_cloud::twin::scenario_road(road_kind);
    if let Some(listen) = &args.viz_listen {
        config.viz = viz_config(listen, config.roles.contains(&Role::Viz))?;
    }
    let metrics = crate::metrics_endpoint::start(&args.metrics, "cloud")?;
    let summary = with_signals(|shutdown| async move {
        let on_ready = |ready: &risktwin_cloud::network::CloudReady| {
            if let Some(addr) = ready.viz {
                eprintln!("viz on ws://{addr}");
            }
            eprintln!("ready");
        };
        run(&config, shutdown, on_ready).await.map_err(|e| match e {
            CloudError::Transport(t) => CliError::runtime(t),
            CloudError::Viz(v) => CliError::runtime(v),
            CloudError::Record(r) => CliError::runtime(r),
            CloudError::Criticality(w @ CriticalityRoleError::Write { .. }) => CliError::runtime(w),
            CloudError::Criticality(s @ CriticalityRoleError::StoreCase { .. }) => CliError::runtime(s),
            other => CliError::input(other),
        })
    })?;
    if let (Some(dir), Some(twin)) = (&args.fidelity_report, &summary.twin) {
        write_fidelity_report(dir, twin).map_err(CliError::runtime)?;
    }
    if let (Some(path), Some(fleet)) = (&args.loop_report, &summary.fleet_loop) {
        std::fs::write(path, &fleet.fleet.report)
            .map_err(|e| CliError::runtime(format!("writing the loop report {}: {e}", path.display())))?;
    }
    print_json(&summary)?;
    if let Some(endpoint) = metrics {
        endpoint.last_scrape();
    }
    Ok(())
}

/// `--viz-listen`: an IP address and port, with the viz role; warned about once when it lets
/// other hosts in (the protocol has no authentication).
fn viz_config(listen: &str, with_role: bool) -> CliResult<VizConfig> {
    if !with_role {
        return Err(CliError::input("--viz-listen needs the viz role (--roles ingest,twin,viz)"));
    }
    let listen: std::net::SocketAddr = listen.parse().map_err(|_| {
        CliError::input(format!("--viz-listen {listen}: not an IP address and port (e.g. 127.0.0.1:8765)"))
    })?;
    if !listen.ip().is_loopback() {
        eprintln!(
            "warning: --viz-listen {listen} is reachable beyond this host: the Foxglove WebSocket protocol has no \
             authentication or encryption, so anyone who reaches the port sees the live twin (docs/viz.md)"
        );
    }
    Ok(VizConfig { listen })
}

pub fn bench_zenoh(args: BenchZenohArgs) -> CliResult {
    if args.messages == 0 || args.rounds == 0 {
        return Err(CliError::input("--messages and --rounds must be positive"));
    }
    let config = BenchConfig { messages: args.messages, payload_bytes: args.payload_bytes, rounds: args.rounds };
    if args.vs_tls {
        return bench_tls(config, args.format);
    }
    // The benchmark ends by itself; a signal still stops the process the usual way.
    let report = with_signals(|_shutdown| async move { throughput(config).await.map_err(CliError::runtime) })?;
    match args.format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["side", "msgs_per_s (median)", "all rounds"],
            &[
                vec![
                    "raw zenoh".into(),
                    format!("{:.0}", report.raw_median_msgs_per_s),
                    format!("{:.0?}", report.raw_msgs_per_s),
                ],
                vec![
                    "raw zenoh, wildcard sub".into(),
                    format!("{:.0}", report.raw_wildcard_median_msgs_per_s),
                    format!("{:.0?}", report.raw_wildcard_msgs_per_s),
                ],
                vec![
                    "risktwin".into(),
                    format!("{:.0}", report.ours_median_msgs_per_s),
                    format!("{:.0?}", report.ours_msgs_per_s),
                ],
                vec!["ratio ours/raw".into(), format!("{:.3}", report.ratio), String::new()],
                vec!["ratio ours/raw wildcard".into(), format!("{:.3}", report.ratio_vs_wildcard), String::new()],
            ],
        ),
    }
}

/// `bench zenoh --vs-tls`: the state path over plain TCP and over TLS with access rules.
fn bench_tls(config: BenchConfig, format: Format) -> CliResult {
    let report = with_signals(|_shutdown| async move { secure_throughput(config).await.map_err(CliError::runtime) })?;
    match format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["side", "msgs_per_s (median)", "all rounds"],
            &[
                vec![
                    "state path, plain TCP".into(),
                    format!("{:.0}", report.plain_median_msgs_per_s),
                    format!("{:.0?}", report.plain_msgs_per_s),
                ],
                vec![
                    "state path, TLS".into(),
                    format!("{:.0}", report.tls_median_msgs_per_s),
                    format!("{:.0?}", report.tls_msgs_per_s),
                ],
                vec![
                    "state path, TLS + ACL".into(),
                    format!("{:.0}", report.tls_acl_median_msgs_per_s),
                    format!("{:.0?}", report.tls_acl_msgs_per_s),
                ],
                vec!["ratio TLS+ACL/plain".into(), format!("{:.3}", report.ratio), String::new()],
                vec!["ratio TLS/plain".into(), format!("{:.3}", report.ratio_tls), String::new()],
                vec!["ratio TLS+ACL/TLS".into(), format!("{:.3}", report.ratio_acl), String::new()],
            ],
        ),
    }
}

pub fn bench_latency(args: BenchLatencyArgs) -> CliResult {
    check_pacing(args.messages, args.rate_hz)?;
    let mut ingest = IngestConfig::default();
    let ms = |flag: &str, v: f64| {
        if (0.0..=10_000.0).contains(&v) {
            Ok((v * 1e6) as i64)
        } else {
            Err(CliError::input(format!("{flag} {v} must lie in [0, 10000] ms")))
        }
    };
    if let Some(t) = args.tick_ms {
        ingest.align.tick_ns = ms("--tick-ms", t)?.max(1_000_000);
    }
    if let Some(l) = args.lateness_ms {
        ingest.align.lateness_ns = ms("--lateness-ms", l)?;
    }
    let config = LatencyConfig { messages: args.messages, rate_hz: args.rate_hz, ingest };
    let report = with_signals(|_shutdown| async move { latency(config).await.map_err(CliError::runtime) })?;
    let rows = match args.format {
        Format::Json => Vec::new(),
        _ => vec![
            latency_row("raw zenoh one-way", report.raw_p50_ms, report.raw_p99_ms, Some(report.raw_samples)),
            latency_row(
                "edge publish → twin snapshot",
                report.ours_p50_ms,
                report.ours_p99_ms,
                Some(report.ours_samples),
            ),
            vec![
                format!("tick {} ms, lateness {} ms", report.tick_ms, report.lateness_ms),
                format!("ratio {:.3}", report.ratio),
                "ours_p50 / (raw_p50 + tick)".into(),
                String::new(),
            ],
        ],
    };
    print_latency(args.format, &report, &rows)
}

pub fn bench_warning(args: BenchWarningArgs) -> CliResult {
    check_pacing(args.messages, args.rate_hz)?;
    let config = WarningBenchConfig { messages: args.messages, rate_hz: args.rate_hz, risk: args.risk };
    let report = with_signals(|_shutdown| async move { warning(config).await.map_err(CliError::runtime) })?;
    let mut rows = match args.format {
        Format::Json => Vec::new(),
        _ => vec![
            latency_row(
                "raw zenoh one-way (warning QoS), 1 hop",
                report.raw_p50_ms,
                report.raw_p99_ms,
                Some(report.raw_samples),
            ),
            latency_row(
                "edge publish → warning at the vehicle, 2 hops",
                report.warning_p50_ms,
                report.warning_p99_ms,
                Some(report.warning_samples),
            ),
            latency_row(
                "  of which in the cloud (callback start → put returned)",
                report.cloud_p50_ms,
                report.cloud_p99_ms,
                None,
            ),
            vec![
                format!("ratio {:.2} (warning p50 / raw p50: 2 hops against 1)", report.ratio),
                format!("target ≤ {}", report.target_p50_ms),
                if report.risk { "with the risk role".into() } else { String::new() },
                format!(
                    "sent {} ({} via declared publishers), held back {}, failed {}",
                    report.warnings.sent,
                    report.warnings.via_publisher,
                    report.warnings.rate_limited,
                    report.warnings.failed
                ),
            ],
        ],
    };
    if args.format != Format::Json {
        for (n, us) in &report.assess_us_per_state {
            rows.push(vec![format!("warning path alone per state, {n} vehicles on the site"), format!("{us:.2} µs")]);
        }
    }
    print_latency(args.format, &report, &rows)
}

/// One row of a latency table: what, p50 and p99 in ms, and how many samples.
fn latency_row(what: &str, p50_ms: f64, p99_ms: f64, samples: Option<usize>) -> Vec<String> {
    let samples = samples.map(|n| n.to_string()).unwrap_or_default();
    vec![what.to_owned(), format!("{p50_ms:.3}"), format!("{p99_ms:.3}"), samples]
}

/// The pacing flags of the latency benchmarks: more messages than the warm-up, a sane rate.
fn check_pacing(messages: u64, rate_hz: f64) -> CliResult {
    if messages <= 50 || !(rate_hz > 0.0 && rate_hz <= 10_000.0) {
        return Err(CliError::input("--messages must exceed 50 and --rate-hz lie in (0, 10000]"));
    }
    Ok(())
}

/// A latency report as JSON, or as a table of `rows` (side, p50, p99, samples).
fn print_latency(format: Format, report: &impl serde::Serialize, rows: &[Vec<String>]) -> CliResult {
    match format {
        Format::Json => print_json(report),
        _ => print_table(&["side", "p50 ms", "p99 ms", "samples"], rows),
    }
}
