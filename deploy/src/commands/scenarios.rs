//! `risktwin scenarios generate|rank|mutate`: the scenario library from the command line.

use super::driver::load_model;
use super::source::{open_existing_library, parse_kinds};
use crate::cli::{GenerateArgs, MutateArgs, RankArgs};
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_cloud::generate::{MutationError, all_cores, generate_into, mutate_stored};
use risktwin_common::risk::RiskTerms;
use risktwin_common::scenario::MutateError;
use risktwin_policy::model::ModelFile;
use risktwin_policy::spec::DriverSpec;
use risktwin_store::library::{
    COMMONROAD_KIND, DEFAULT_POLICY, REPLAY_POLICY, RankOutcome, RankedCase, RankedScenario, ScenarioLibrary,
};
use serde::Serialize;

/// A `--threads` flag: all cores when absent, else 1 to 1024.
pub fn threads_flag(threads: Option<u64>) -> CliResult<usize> {
    risktwin_cloud::generate::worker_threads(threads).map_err(|e| CliError::input(format!("--threads {e}")))
}

pub fn generate(args: GenerateArgs) -> CliResult {
    let kinds = parse_kinds(&args.kind)?;
    if args.count == 0 || args.count > 1_000_000 {
        return Err(CliError::input(format!("--count {} is out of range [1, 1000000]", args.count)));
    }
    let mut library = ScenarioLibrary::open(&args.db).map_err(CliError::input)?;
    let report = generate_into(&mut library, &kinds, args.count, args.seed, all_cores())?;
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

pub fn mutate(args: MutateArgs) -> CliResult {
    if args.count == 0 || args.count > 100_000 {
        return Err(CliError::input(format!("--count {} is out of range [1, 100000]", args.count)));
    }
    let radius = args.radius.unwrap_or(risktwin_pipeline::RunConfig::default().training.mutation_radius);
    let mut library = open_existing_library(&args.db)?;
    let report =
        mutate_stored(&mut library, &args.id, args.count, radius, args.seed, all_cores()).map_err(|e| match e {
            MutationError::Library(e) => CliError::runtime(e),
            MutationError::Mutate(e @ MutateError::InvalidRadius(_)) => {
                CliError::input(format!("--radius {radius}: {e}"))
            }
            MutationError::Mutate(e) => CliError::runtime(format!("stored scenario {}: {e}", args.id)),
            unknown => CliError::input(unknown),
        })?;
    match args.format {
        Format::Json => print_json(&report),
        _ => {
            let rows = report
                .children
                .iter()
                .map(|c| {
                    let ttc = c.min_ttc_s.map_or("-".into(), |t| format!("{t:.2}"));
                    vec![c.id.clone(), format!("{:.4}", c.risk), c.collision.to_string(), ttc]
                })
                .collect::<Vec<_>>();
            print_table(&["child", "risk", "collision", "min TTC s"], &rows)
        }
    }
}

pub fn rank(args: RankArgs) -> CliResult {
    let recorded = args.kind.as_deref() == Some(COMMONROAD_KIND);
    let kind = match args.kind.as_deref() {
        Some(COMMONROAD_KIND) | None | Some("all") => None,
        Some(k) => Some(parse_kinds(k)?[0]),
    };
    if args.driver == Some(DriverSpec::Replay) && !recorded {
        return Err(CliError::input(
            "--driver replay is a recording's ego: rank recorded cases with --kind commonroad",
        ));
    }
    let model = args.driver.as_ref().map(load_model).transpose()?.flatten();
    let library = open_existing_library(&args.db)?;
    let label = match (&model, &args.driver) {
        (Some(m), _) => stored_label(&library, m, recorded)?,
        (None, Some(spec)) => spec.to_string(),
        // Recorded cases by default by their replayed ego's outcome.
        (None, None) if recorded => REPLAY_POLICY.to_owned(),
        (None, None) => DEFAULT_POLICY.to_owned(),
    };
    if recorded {
        print_ranked(&library.rank_recorded(&label, args.top)?, args.format)
    } else {
        print_ranked(&library.rank_for_policy(&label, args.top, kind)?, args.format)
    }
}

/// The label a model file's outcomes are stored under in `library`: the label it has here, or
/// the one label of the same content under another path (evaluated from another folder).
fn stored_label(library: &ScenarioLibrary, model: &ModelFile, recorded: bool) -> CliResult<String> {
    let own = model.label();
    let stored = library.labels_ending_with(&model.label_suffix(), recorded)?;
    match stored.as_slice() {
        [] => Ok(own),
        [one] => Ok(one.clone()),
        _ if stored.contains(&own) => Ok(own),
        _ => Err(CliError::input(format!(
            "{} has outcomes under several labels ({}): name it by the path it was evaluated under",
            model.path.display(),
            stored.join(", ")
        ))),
    }
}

/// How one ranked item prints besides JSON: what names it, then its risk and outcome.
trait RankItem: Serialize {
    /// CSV and table columns that name the item.
    const NAME_COLUMNS: &'static [&'static str];
    /// CSV-only naming columns after `NAME_COLUMNS`.
    const CSV_EXTRA: &'static [&'static str];
    fn name_cells(&self) -> Vec<String>;
    fn csv_extra(&self) -> Vec<String>;
    fn risk(&self) -> &RiskTerms;
    fn outcome(&self) -> &RankOutcome;
}

impl RankItem for RankedScenario {
    const NAME_COLUMNS: &'static [&'static str] = &["id", "kind"];
    const CSV_EXTRA: &'static [&'static str] = &["seed"];
    fn name_cells(&self) -> Vec<String> {
        vec![self.id.clone(), self.kind.to_string()]
    }
    fn csv_extra(&self) -> Vec<String> {
        vec![self.seed.to_string()]
    }
    fn risk(&self) -> &RiskTerms {
        &self.risk
    }
    fn outcome(&self) -> &RankOutcome {
        &self.outcome
    }
}

impl RankItem for RankedCase {
    const NAME_COLUMNS: &'static [&'static str] = &["id", "benchmark_id", "ego_id"];
    const CSV_EXTRA: &'static [&'static str] = &[];
    fn name_cells(&self) -> Vec<String> {
        vec![self.id.clone(), self.benchmark_id.clone(), self.ego_id.to_string()]
    }
    fn csv_extra(&self) -> Vec<String> {
        Vec::new()
    }
    fn risk(&self) -> &RiskTerms {
        &self.risk
    }
    fn outcome(&self) -> &RankOutcome {
        &self.outcome
    }
}

/// `ranked` in `format`: JSON as stored, CSV with every term, a table with the main ones.
fn print_ranked<T: RankItem>(ranked: &[T], format: Format) -> CliResult {
    match format {
        Format::Json => print_json(&ranked),
        Format::Csv => {
            let terms =
                ["score", "ttc", "dist", "lane", "jerk", "collision_term", "collision", "min_ttc_s", "min_distance_m"];
            let header: Vec<&str> = [T::NAME_COLUMNS, T::CSV_EXTRA, &terms].into_iter().flatten().copied().collect();
            println!("{}", header.join(","));
            for r in ranked {
                let (risk, outcome, f) = (r.risk(), r.outcome(), csv_float);
                let mut cells = r.name_cells();
                cells.extend(r.csv_extra());
                cells.extend([risk.score, risk.ttc, risk.dist, risk.lane, risk.jerk, risk.collision].map(f));
                cells.push(outcome.collision.to_string());
                cells.push(outcome.min_ttc_s.map_or("inf".into(), f));
                cells.push(f(outcome.min_distance_m));
                println!("{}", cells.join(","));
            }
            Ok(())
        }
        Format::Table => {
            let tail = ["score", "collision", "min_ttc_s", "min_distance_m"];
            let header: Vec<&str> = [&["rank"], T::NAME_COLUMNS, &tail].into_iter().flatten().copied().collect();
            let rows: Vec<Vec<String>> = ranked
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let outcome = r.outcome();
                    let mut row = vec![(i + 1).to_string()];
                    row.extend(r.name_cells());
                    row.extend([
                        format!("{:.3}", r.risk().score),
                        outcome.collision.to_string(),
                        outcome.min_ttc_s.map_or("inf".into(), |t| format!("{t:.2}")),
                        format!("{:.2}", outcome.min_distance_m),
                    ]);
                    row
                })
                .collect();
            print_table(&header, &rows)
        }
    }
}
