//! `risktwin scenarios generate|rank`: the scenario library from the command line.

use super::source::{open_existing_library, parse_kinds};
use crate::cli::{GenerateArgs, RankArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_cloud::generate::{generate as generate_batch, store};
use risktwin_cloud::library::{COMMONROAD_KIND, REPLAY_POLICY, RankedCase, RankedScenario, ScenarioLibrary};

/// Worker threads for episode batches: all cores.
pub fn worker_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

pub fn generate(args: GenerateArgs) -> CliResult {
    let kinds = parse_kinds(&args.kind)?;
    if args.count == 0 || args.count > 1_000_000 {
        return Err(CliError::input(format!("--count {} is out of range [1, 1000000]", args.count)));
    }
    let mut library = ScenarioLibrary::open(&args.db).map_err(CliError::input)?;
    let batch = generate_batch(&kinds, args.count, args.seed, worker_threads());
    let report = store(&mut library, &kinds, &batch).map_err(CliError::runtime)?;
    match args.format {
        Format::Json => print_json(&report),
        _ => {
            let mut rows: Vec<Vec<String>> = report
                .by_kind
                .iter()
                .map(|(k, r)| {
                    vec![k.to_string(), r.stored.to_string(), r.infeasible.to_string(), r.collisions.to_string()]
                })
                .collect();
            rows.push(vec![
                "total".into(),
                report.stored.to_string(),
                report.infeasible.to_string(),
                report.by_kind.values().map(|r| r.collisions).sum::<u64>().to_string(),
            ]);
            print_table(&["kind", "stored", "infeasible", "collisions"], &rows)
        }
    }
}

pub fn rank(args: RankArgs) -> CliResult {
    let kind = match args.kind.as_deref() {
        Some(COMMONROAD_KIND) => return rank_recorded(&args),
        None | Some("all") => None,
        Some(k) => Some(parse_kinds(k)?[0]),
    };
    let library = open_existing_library(&args.db)?;
    let ranked = library.rank(args.top, kind).map_err(CliError::runtime)?;
    match args.format {
        Format::Json => print_json(&ranked),
        Format::Csv => {
            println!("id,kind,seed,score,ttc,dist,lane,jerk,collision_term,collision,min_ttc_s,min_distance_m");
            for r in &ranked {
                println!("{}", csv_row(r));
            }
            Ok(())
        }
        Format::Table => print_table(
            &["rank", "id", "kind", "score", "collision", "min_ttc_s", "min_distance_m"],
            &ranked
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    vec![
                        (i + 1).to_string(),
                        r.id.clone(),
                        r.kind.to_string(),
                        format!("{:.3}", r.risk.score),
                        r.outcome.collision.to_string(),
                        r.outcome.min_ttc_s.map_or("inf".into(), |t| format!("{t:.2}")),
                        format!("{:.2}", r.outcome.min_distance_m),
                    ]
                })
                .collect::<Vec<_>>(),
        ),
    }
}

fn csv_row(r: &RankedScenario) -> String {
    let f = csv_float;
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{}",
        r.id,
        r.kind,
        r.seed,
        f(r.risk.score),
        f(r.risk.ttc),
        f(r.risk.dist),
        f(r.risk.lane),
        f(r.risk.jerk),
        f(r.risk.collision),
        r.outcome.collision,
        r.outcome.min_ttc_s.map_or("inf".into(), f),
        f(r.outcome.min_distance_m)
    )
}

/// `--kind commonroad`: the recorded cases by S_risk of their reference outcome (the replayed
/// ego), in the same formats.
fn rank_recorded(args: &RankArgs) -> CliResult {
    let library = open_existing_library(&args.db)?;
    let ranked = library.rank_recorded(REPLAY_POLICY, args.top).map_err(CliError::runtime)?;
    match args.format {
        Format::Json => print_json(&ranked),
        Format::Csv => {
            println!(
                "id,kind,benchmark_id,ego_id,score,ttc,dist,lane,jerk,collision_term,collision,min_ttc_s,min_distance_m"
            );
            for r in &ranked {
                println!("{}", recorded_csv_row(r));
            }
            Ok(())
        }
        Format::Table => print_table(
            &["rank", "id", "benchmark_id", "ego_id", "score", "collision", "min_ttc_s", "min_distance_m"],
            &ranked
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    vec![
                        (i + 1).to_string(),
                        r.id.clone(),
                        r.benchmark_id.clone(),
                        r.ego_id.to_string(),
                        format!("{:.3}", r.risk.score),
                        r.outcome.collision.to_string(),
                        r.outcome.min_ttc_s.map_or("inf".into(), |t| format!("{t:.2}")),
                        format!("{:.2}", r.outcome.min_distance_m),
                    ]
                })
                .collect::<Vec<_>>(),
        ),
    }
}

fn recorded_csv_row(r: &RankedCase) -> String {
    let f = csv_float;
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{}",
        r.id,
        r.kind,
        r.benchmark_id,
        r.ego_id,
        f(r.risk.score),
        f(r.risk.ttc),
        f(r.risk.dist),
        f(r.risk.lane),
        f(r.risk.jerk),
        f(r.risk.collision),
        r.outcome.collision,
        r.outcome.min_ttc_s.map_or("inf".into(), f),
        f(r.outcome.min_distance_m)
    )
}
