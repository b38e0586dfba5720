//! `risktwin scenarios floor`: the privileged planner on the held-out set of `risktwin run`,
//! per kind against the reference driver.

use super::driver::LoadedDriver;
use super::scenarios::threads_flag;
use super::source::parse_kinds;
use crate::cli::FloorArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_cloud::trainer::{EvalMetrics, FloorCase, HeldOut, PolicyEvaluation, evaluate_floor, reference_episodes};
use risktwin_common::metrics::Ending;
use risktwin_common::scenario::ScenarioKind;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

/// The floor of one kind (or of all): the planner's drives, the reference driver's episodes
/// and, with `--driver`, that driver's.
#[derive(Debug, Serialize)]
struct KindFloor {
    scenarios: u64,
    avoidable: u64,
    planner: EvalMetrics,
    reference: EvalMetrics,
    #[serde(skip_serializing_if = "Option::is_none")]
    driver: Option<EvalMetrics>,
}

/// One scenario's floor and, with `--driver`, how that driver's episode ended.
#[derive(Debug, Serialize)]
struct CaseRow {
    #[serde(flatten)]
    case: FloorCase,
    #[serde(skip_serializing_if = "Option::is_none")]
    driver_ended: Option<Ending>,
}

/// The JSON document (docs/cli.md).
#[derive(Debug, Serialize)]
struct FloorDoc {
    seed: u64,
    per_kind: u64,
    /// The `--driver`'s label.
    #[serde(skip_serializing_if = "Option::is_none")]
    driver: Option<String>,
    overall: KindFloor,
    by_kind: BTreeMap<ScenarioKind, KindFloor>,
    cases: Vec<CaseRow>,
    /// Wall time of the search, s (the one field that differs between runs).
    wall_s: f64,
}

pub fn floor(args: FloorArgs) -> CliResult {
    let kinds = parse_kinds(&args.kind)?;
    if !(1..=10_000).contains(&args.count) {
        return Err(CliError::input(format!("--count {} is out of range [1, 10000]", args.count)));
    }
    let threads = threads_flag(args.threads)?;
    let driver = args.driver.as_ref().map(|spec| LoadedDriver::load(spec, "--driver")).transpose()?;
    let started = Instant::now();
    let held_out = HeldOut::new(args.seed, args.count as usize);
    let specs: Vec<_> = held_out.specs.into_iter().filter(|s| kinds.contains(&s.kind)).collect();
    tracing::info!("searching {} held-out scenarios on {threads} threads", specs.len());
    // The reference driver's episodes, as `risktwin run`'s ablation evaluates them.
    let reference_runs = reference_episodes(&specs, threads);
    let floor = evaluate_floor(&specs, &reference_runs, threads);
    let reference = PolicyEvaluation::from_episodes(&specs, &reference_runs);
    let driver_runs: Option<Vec<_>> =
        driver.as_ref().map(|d| d.driver().episodes(&specs, threads).into_iter().map(|r| r.metrics).collect());
    let driven = driver_runs.as_ref().map(|runs| PolicyEvaluation::from_episodes(&specs, runs));
    let wall_s = started.elapsed().as_secs_f64();
    let pick = |e: &PolicyEvaluation, kind: Option<ScenarioKind>| kind.map_or(e.overall, |k| e.by_kind[&k]);
    let of = |kind: Option<ScenarioKind>| {
        let (planner, reference) = (pick(&floor.planner, kind), pick(&reference, kind));
        let driver = driven.as_ref().map(|e| pick(e, kind));
        KindFloor { scenarios: planner.episodes, avoidable: floor.avoidable(kind), planner, reference, driver }
    };
    let cases = floor.cases.iter().enumerate().map(|(i, case)| CaseRow {
        case: case.clone(),
        driver_ended: driver_runs.as_ref().map(|runs| runs[i].ending()),
    });
    let doc = FloorDoc {
        seed: args.seed,
        per_kind: args.count,
        driver: driver.as_ref().map(|d| d.label.clone()),
        overall: of(None),
        by_kind: kinds.iter().map(|&k| (k, of(Some(k)))).collect(),
        cases: cases.collect(),
        wall_s,
    };
    if let Some(d) = &driver {
        d.warn_faults();
    }
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
        .into_iter()
        .chain(k.driver.iter().flat_map(|d| [format!("{:.2}", d.collision_rate), format!("{:.2}", d.success_rate)]))
        .collect::<Vec<_>>()
    };
    let mut rows: Vec<Vec<String>> = doc.by_kind.iter().map(|(kind, k)| row(kind.to_string(), k)).collect();
    rows.push(row("all".into(), &doc.overall));
    let mut header = vec![
        "kind",
        "scenarios",
        "avoidable",
        "planner collision",
        "planner offroad",
        "planner out of time",
        "reference collision",
        "reference success",
    ];
    if doc.driver.is_some() {
        header.extend(["driver collision", "driver success"]);
    }
    print_table(&header, &rows)?;
    if let Some(label) = &doc.driver {
        eprintln!("driver: {label}");
    }
    eprintln!("{:.1} s wall", doc.wall_s);
    Ok(())
}

/// One row per scenario.
fn print_csv(cases: &[CaseRow]) -> CliResult {
    let driven = cases.first().is_some_and(|c| c.driver_ended.is_some());
    println!(
        "id,kind,seed,verdict,ended,route_completion,min_ttc_s,min_distance_m,avg_speed_mps,sim_steps,reference_ended{}",
        if driven { ",driver_ended" } else { "" }
    );
    for row in cases {
        let c = &row.case;
        let driver = match &row.driver_ended {
            Some(e) => format!(",{}", serde_name(e)?),
            None => String::new(),
        };
        println!(
            "{},{},{},{},{},{},{},{},{},{},{}{driver}",
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
