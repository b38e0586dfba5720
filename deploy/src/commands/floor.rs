//! `risktwin scenarios floor`: the privileged planner on the held-out set of `risktwin run`,
//! per kind against the reference driver.

use super::scenarios::worker_threads;
use super::source::parse_kinds;
use crate::cli::FloorArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_cloud::trainer::{EvalMetrics, FloorCase, HeldOut, PolicyEvaluation, evaluate_floor, reference_episodes};
use risktwin_common::scenario::ScenarioKind;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

/// The floor of one kind (or of all): the planner's drives and the reference driver's episodes.
#[derive(Debug, Serialize)]
struct KindFloor {
    scenarios: u64,
    avoidable: u64,
    planner: EvalMetrics,
    reference: EvalMetrics,
}

/// The JSON document (docs/cli.md).
#[derive(Debug, Serialize)]
struct FloorDoc {
    seed: u64,
    per_kind: u64,
    overall: KindFloor,
    by_kind: BTreeMap<ScenarioKind, KindFloor>,
    cases: Vec<FloorCase>,
    /// Wall time of the search, s (the one field that differs between runs).
    wall_s: f64,
}

pub fn floor(args: FloorArgs) -> CliResult {
    let kinds = parse_kinds(&args.kind)?;
    if !(1..=10_000).contains(&args.count) {
        return Err(CliError::input(format!("--count {} is out of range [1, 10000]", args.count)));
    }
    let threads = match args.threads {
        None => worker_threads(),
        Some(t @ 1..=1024) => t as usize,
        Some(t) => return Err(CliError::input(format!("--threads {t} is out of range [1, 1024]"))),
    };
    let started = Instant::now();
    let held_out = HeldOut::new(args.seed, args.count as usize);
    let specs: Vec<_> = held_out.specs.into_iter().filter(|s| kinds.contains(&s.kind)).collect();
    tracing::info!("searching {} held-out scenarios on {threads} threads", specs.len());
    // The reference driver's episodes, as `risktwin run`'s ablation evaluates them.
    let reference_runs = reference_episodes(&specs, threads);
    let floor = evaluate_floor(&specs, &reference_runs, threads);
    let reference = PolicyEvaluation::from_episodes(&specs, &reference_runs);
    let wall_s = started.elapsed().as_secs_f64();
    let of = |kind: Option<ScenarioKind>| {
        let (planner, reference) = match kind {
            None => (floor.planner.overall, reference.overall),
            Some(k) => (floor.planner.by_kind[&k], reference.by_kind[&k]),
        };
        KindFloor { scenarios: planner.episodes, avoidable: floor.avoidable(kind), planner, reference }
    };
    let doc = FloorDoc {
        seed: args.seed,
        per_kind: args.count,
        overall: of(None),
        by_kind: kinds.iter().map(|&k| (k, of(Some(k)))).collect(),
        cases: floor.cases.clone(),
        wall_s,
    };
    match args.format {
        Format::Json => print_json(&doc),
        Format::Csv => print_csv(&doc.cases),
        Format::Table => print_kinds(&doc),
    }
}

/// One row per kind and one for all: avoidable share, how the planner's drives ended, and the
/// reference driver's collision and success rates.
fn print_kinds(doc: &FloorDoc) -> CliResult {
    let row = |name: String, k: &KindFloor| {
        let p = &k.planner;
        vec![
            name,
            k.scenarios.to_string(),
            format!("{} ({:.2})", k.avoidable, p.success_rate),
            format!("{:.2}", p.collision_rate),
            format!("{:.2}", p.offroad_rate),
            format!("{:.2}", p.timeout_rate),
            format!("{:.2}", k.reference.collision_rate),
            format!("{:.2}", k.reference.success_rate),
        ]
    };
    let mut rows: Vec<Vec<String>> = doc.by_kind.iter().map(|(kind, k)| row(kind.to_string(), k)).collect();
    rows.push(row("all".into(), &doc.overall));
    print_table(
        &[
            "kind",
            "scenarios",
            "avoidable",
            "planner collision",
            "planner offroad",
            "planner out of time",
            "reference collision",
            "reference success",
        ],
        &rows,
    )?;
    eprintln!("{:.1} s wall", doc.wall_s);
    Ok(())
}

/// One row per scenario.
fn print_csv(cases: &[FloorCase]) -> CliResult {
    println!(
        "id,kind,seed,verdict,ended,route_completion,min_ttc_s,min_distance_m,avg_speed_mps,sim_steps,reference_ended"
    );
    for c in cases {
        println!(
            "{},{},{},{},{},{},{},{},{},{},{}",
            c.id,
            c.kind,
            c.seed,
            serde_name(&c.verdict)?,
            serde_name(&c.ended)?,
            csv_float(c.route_completion),
            c.min_ttc_s.map_or("inf".into(), csv_float),
            csv_float(c.min_distance_m),
            csv_float(c.avg_speed_mps),
            c.sim_steps,
            serde_name(&c.reference_ended)?
        );
    }
    Ok(())
}

/// The name serde gives a unit variant (`avoidable`, `out-of-time`, …).
fn serde_name<T: Serialize>(value: &T) -> CliResult<String> {
    match serde_json::to_value(value).map_err(CliError::runtime)? {
        serde_json::Value::String(s) => Ok(s),
        other => Err(CliError::runtime(format!("not a unit variant: {other}"))),
    }
}
