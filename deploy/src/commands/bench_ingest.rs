//! `risktwin bench ingest`: can the cloud ingest hold a fleet (2,000 vehicles at 50 Hz: 100k
//! msg/s) in reliable mode without loss, and at what CPU cost? The benchmark is
//! [`risktwin_bench::fleet_ingest`]; its publisher processes are children of this binary
//! (`bench ingest --fleet-connect …`, hidden flags).

use super::router::with_signals;
use crate::cli::BenchIngestArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_bench::fleet_ingest::{FleetBenchConfig, FleetShare, cloud_side, publish_share};
use std::process::Command;

pub fn ingest(args: BenchIngestArgs) -> CliResult {
    if args.vehicles == 0 || args.seconds == 0 || args.publishers == 0 || args.publishers > args.vehicles {
        return Err(CliError::input("--vehicles, --seconds and --publishers must be positive, publishers ≤ vehicles"));
    }
    if args.rate_hz == 0 || 100 % args.rate_hz != 0 {
        return Err(CliError::input(format!("--rate-hz {} must divide 100 (the fleet's 10 ms tick)", args.rate_hz)));
    }
    if let Some(locator) = args.fleet_connect.clone() {
        let share = FleetShare { locator, first_vehicle: args.first_vehicle, vehicles: args.vehicles };
        let report = with_signals(|shutdown| async move {
            publish_share(&share, args.rate_hz, args.seconds, args.fleet_tokens, shutdown).await.map_err(CliError::from)
        })?;
        return print_json(&report);
    }
    let _metrics = crate::metrics_endpoint::start(&args.metrics, "bench-ingest")?;
    let exe = std::env::current_exe().map_err(CliError::runtime)?;
    let config = FleetBenchConfig {
        vehicles: args.vehicles,
        rate_hz: args.rate_hz,
        seconds: args.seconds,
        publishers: args.publishers,
    };
    let record_dir = super::recordings::rotation(&args.rotation)?;
    let publisher = move |share: &FleetShare| {
        let mut command = Command::new(&exe);
        command
            .args(["bench", "ingest", "--fleet-connect", &share.locator])
            .args(["--vehicles", &share.vehicles.to_string(), "--first-vehicle", &share.first_vehicle.to_string()])
            .args(["--rate-hz", &config.rate_hz.to_string(), "--seconds", &config.seconds.to_string()]);
        command
    };
    let report =
        with_signals(
            |_shutdown| async move { cloud_side(config, record_dir, publisher).await.map_err(CliError::from) },
        )?;
    match args.format {
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
