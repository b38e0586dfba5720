//! `risktwin cloud`: run the cloud roles until SIGINT/SIGTERM, then print the JSON summary
//! (received per source and stream, drops by reason, snapshots and their digest, liveliness;
//! `--record FILE.mcap` records what was accepted). `ready` on stderr says the
//! subscriptions are in place. Also `risktwin bench zenoh`.

use super::router::{transport_config, with_signals};
use crate::cli::{BenchZenohArgs, CloudArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_cloud::transport::bench::{BenchConfig, throughput};
use risktwin_cloud::transport::{CloudConfig, Role, run};
use risktwin_transport::SiteId;

pub fn cloud(args: CloudArgs) -> CliResult {
    let roles =
        args.roles.iter().map(|r| r.trim().parse::<Role>()).collect::<Result<Vec<_>, _>>().map_err(CliError::input)?;
    let mut config = CloudConfig::new(transport_config(args.zenoh)?);
    config.roles = roles;
    config.site = args.site.map(SiteId::new).transpose().map_err(CliError::input)?;
    config.record = args.record;
    config.replay_time = args.replay_time;
    let summary = with_signals(|shutdown| async move {
        run(&config, shutdown, || eprintln!("ready")).await.map_err(|e| match e {
            risktwin_cloud::transport::CloudError::Transport(t) => CliError::runtime(t),
            risktwin_cloud::transport::CloudError::Record(r) => CliError::runtime(r),
            other => CliError::input(other),
        })
    })?;
    print_json(&summary)
}

pub fn bench_zenoh(args: BenchZenohArgs) -> CliResult {
    if args.messages == 0 || args.rounds == 0 {
        return Err(CliError::input("--messages and --rounds must be positive"));
    }
    let config = BenchConfig { messages: args.messages, payload_bytes: args.payload_bytes, rounds: args.rounds };
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
