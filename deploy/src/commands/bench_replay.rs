//! `risktwin bench replay`: unpaced MCAP replay into ingest, in-process, against the raw `mcap`
//! reader as the peer. The benchmark is [`risktwin_bench::replay`].

use crate::cli::BenchReplayArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_bench::replay::{ReplayConfig, replay as run_replay};

pub fn replay(args: BenchReplayArgs) -> CliResult {
    if args.rounds == 0 {
        return Err(CliError::input("--rounds must be positive"));
    }
    let config = ReplayConfig { file: args.file, vehicles: args.vehicles, seconds: args.seconds, rounds: args.rounds };
    let report = run_replay(&config)?;
    let (raw, cursor, ingest) = (report.raw_mcap_msgs_per_s, report.cursor_msgs_per_s, report.ingest_msgs_per_s);
    match args.format {
        Format::Json => print_json(&report),
        _ => print_table(
            &["side", "msgs_per_s (median)", "ratio to raw mcap"],
            &[
                vec!["raw mcap MessageStream (read only)".into(), format!("{raw:.0}"), "1.000".into()],
                vec!["our MessageCursor (read only)".into(), format!("{cursor:.0}"), format!("{:.3}", cursor / raw)],
                vec![
                    format!(
                        "cursor → IngestWorker ({} msgs, {} snapshots, {} dropped)",
                        report.messages, report.snapshots, report.dropped
                    ),
                    format!("{ingest:.0}"),
                    format!("{:.3}", ingest / raw),
                ],
            ],
        ),
    }
}
