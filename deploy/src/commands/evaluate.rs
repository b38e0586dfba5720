//! `risktwin evaluate`: any driver on the held-out set of a run seed or on a library's
//! scenarios, per kind and overall, beside the reference driver and (with `--floor`) the
//! achievable floor; shares and means with 95 % intervals
//! ([`risktwin_cloud::trainer::outcomes`]). The document is a function of the flags and the
//! model file (same seed → same bytes); progress and wall time go to stderr.

use super::driver::{LoadedDriver, warn_faults};
use super::recorded::{CommonRoadInput, read_xml};
use super::scenarios::threads_flag;
use super::simulate_commonroad::{Recording, drive_model, resimulate_recording};
use super::source::open_existing_library;
use crate::cli::EvaluateArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_cloud::generate::parallel_map;
use risktwin_cloud::trainer::HeldOut;
use risktwin_cloud::trainer::evaluation::{
    self, Comparison, Driven, EvaluationDoc, MAX_PER_KIND, ScenarioSet, library_specs, reference_runs, store_outcomes,
};
use risktwin_cloud::trainer::outcomes::{OutcomeSummary, Share};
use risktwin_common::episode::EpisodeResult;
use risktwin_common::scenario::ScenarioSpec;
use risktwin_commonroad::twin::{EgoMode, Resimulation};
use risktwin_pipeline::figures::{ShareSeries, shares, write_png};
use risktwin_policy::model::ModelFile;
use risktwin_policy::spec::{self, DriverSpec};
use risktwin_store::library::{COMMONROAD_KIND, recorded_id};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Scenarios per progress line and worker batch: a few per thread.
const BATCH_PER_THREAD: usize = 4;

pub fn evaluate(args: EvaluateArgs) -> CliResult {
    if !(1..=MAX_PER_KIND).contains(&args.per_kind) {
        return Err(CliError::input(format!("--per-kind {} is out of range [1, {MAX_PER_KIND}]", args.per_kind)));
    }
    if args.format == Format::Csv {
        return Err(CliError::input("evaluate prints a table or JSON (--format table|json), not CSV"));
    }
    let threads = threads_flag(args.threads)?;
    let started = Instant::now();
    let (label, model, set, driven, avoidable) =
        if args.commonroad.is_empty() { generated(&args, threads)? } else { recorded(&args, threads)? };
    let faults = model.as_ref().map_or(0, |m| m.model.faults());
    if let Some(m) = &model {
        warn_faults(&label, &m.model);
    }
    let doc = EvaluationDoc::new(label, set, &driven, avoidable.as_deref(), faults);
    eprintln!("evaluate: {} scenarios in {:.1} s", driven.len(), started.elapsed().as_secs_f64());
    if let Some(out) = &args.out {
        write_report(out, &doc)?;
    }
    match args.format {
        Format::Json => print_json(&doc),
        Format::Table | Format::Csv => print_kinds(&doc),
    }
}

/// What an evaluation drove: the driver's label and model, the set, every scenario's two
/// episodes, and (with `--floor`) whether each is avoidable.
type Evaluation = (String, Option<ModelFile>, ScenarioSet, Vec<Driven>, Option<Vec<bool>>);

/// The held-out set or a library's scenarios; the library gets the driver's outcomes.
fn generated(args: &EvaluateArgs, threads: usize) -> CliResult<Evaluation> {
    let driver = LoadedDriver::load(&args.driver, "--driver")?;
    let mut library = args.db.as_deref().map(open_existing_library).transpose()?;
    let (specs, set) = match (&library, &args.db) {
        (Some(lib), Some(db)) => (library_specs(lib)?, ScenarioSet::Library { db: db.display().to_string() }),
        _ => (
            HeldOut::new(args.seed, args.per_kind as usize).specs,
            ScenarioSet::HeldOut { seed: args.seed, per_kind: args.per_kind },
        ),
    };
    if specs.is_empty() {
        return Err(CliError::input("the library holds no generated scenarios to evaluate on"));
    }
    let runs = with_progress(&specs, threads, "driver", |batch| driver.driver().episodes(batch, threads));
    let reference = with_progress(&specs, threads, "reference", |batch| reference_runs(batch, threads));
    let avoidable = args.floor.then(|| {
        eprintln!("evaluate: searching the floor of {} scenarios", specs.len());
        evaluation::avoidable(&specs, &reference, threads)
    });
    if let Some(lib) = library.as_mut() {
        store_outcomes(lib, &specs, &runs, &driver.label)?;
    }
    let driven = Driven::generated(&specs, runs, reference);
    Ok((driver.label, driver.model, set, driven, avoidable))
}

/// CommonRoad recordings, each with its default ego, re-run closed-loop (or replayed, for
/// `--driver replay`) and with the reference driver.
fn recorded(args: &EvaluateArgs, threads: usize) -> CliResult<Evaluation> {
    let (label, model) = match &args.driver {
        DriverSpec::Replay => (spec::REPLAY.to_owned(), None),
        other => {
            let loaded = LoadedDriver::load(other, "--driver")?;
            (loaded.label, loaded.model)
        }
    };
    let inputs = args
        .commonroad
        .iter()
        .map(|path| {
            let text = read_xml(path)?;
            let input = CommonRoadInput::parse(&text, path.display().to_string(), None)?;
            let id = input.ego_id.map_or_else(|| input.shown.clone(), |ego| recorded_id(&text, ego));
            Ok((id, input.scenario, input.ego_id, input.shown))
        })
        .collect::<CliResult<Vec<_>>>()?;
    let result = |r: Resimulation| EpisodeResult { metrics: r.metrics, risk: r.risk };
    let runs = parallel_map(&inputs, threads, |(id, scenario, ego_id, shown)| {
        let recording = Recording { scenario, ego_id: *ego_id, shown };
        let driver = match (&args.driver, &model) {
            (DriverSpec::Replay, _) => resimulate_recording(&recording, EgoMode::Replay)?,
            (_, Some(file)) => drive_model(&recording, &file.model)?,
            (_, None) => resimulate_recording(&recording, EgoMode::ReferenceDriver)?,
        };
        let reference = resimulate_recording(&recording, EgoMode::ReferenceDriver)?;
        Ok(Driven {
            id: id.clone(),
            kind: COMMONROAD_KIND.to_owned(),
            seed: None,
            driver: result(driver),
            reference: result(reference),
        })
    })
    .into_iter()
    .collect::<CliResult<Vec<_>>>()?;
    let files = args.commonroad.iter().map(|p| p.display().to_string()).collect();
    Ok((label, model, ScenarioSet::CommonRoad { files }, runs, None))
}

/// `drive` over `specs` in batches, a progress line on stderr after each.
fn with_progress(
    specs: &[ScenarioSpec],
    threads: usize,
    who: &str,
    drive: impl Fn(&[ScenarioSpec]) -> Vec<EpisodeResult>,
) -> Vec<EpisodeResult> {
    let mut results = Vec::with_capacity(specs.len());
    for batch in specs.chunks(threads * BATCH_PER_THREAD) {
        results.extend(drive(batch));
        let _ = write!(std::io::stderr(), "\revaluate {who}: {}/{} scenarios", results.len(), specs.len());
    }
    let _ = writeln!(std::io::stderr());
    results
}

/// One row per kind and one for all.
fn print_kinds(doc: &EvaluationDoc) -> CliResult {
    let pct = |s: &Share| format!("{:.2} [{:.2}, {:.2}]", s.share, s.low, s.high);
    let row = |name: String, c: &Comparison| {
        let mut row = vec![
            name,
            c.driver.episodes.to_string(),
            pct(&c.driver.collision),
            pct(&c.reference.collision),
            pct(&c.driver.success),
            pct(&c.reference.success),
            format!("{:.3}", c.driver.route_completion.mean),
            format!("{:.3}", c.driver.risk_score.mean),
        ];
        row.extend(c.floor.as_ref().map(|f| pct(&f.avoidable)));
        row
    };
    let mut rows: Vec<Vec<String>> = doc.by_kind.iter().map(|(k, c)| row(k.clone(), c)).collect();
    rows.push(row("all".into(), &doc.overall));
    let mut header = vec![
        "kind",
        "scenarios",
        "collision",
        "reference collision",
        "success",
        "reference success",
        "completion",
        "S_risk",
    ];
    if doc.overall.floor.is_some() {
        header.push("avoidable (floor)");
    }
    println!("driver: {}", doc.driver);
    print_table(&header, &rows)?;
    println!("[low, high]: {:.0} % Wilson intervals", doc.confidence * 100.0);
    Ok(())
}

/// report.md, metrics.json, and the collision and success figures.
fn write_report(out: &Path, doc: &EvaluationDoc) -> CliResult {
    std::fs::create_dir_all(out).map_err(|e| CliError::input(format!("cannot create {}: {e}", out.display())))?;
    let json = serde_json::to_string_pretty(doc).map_err(CliError::runtime)?;
    let write = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| CliError::input(format!("cannot write {}: {e}", path.display())))
    };
    write("metrics.json", json + "\n")?;
    let groups: Vec<String> = doc.by_kind.keys().cloned().collect();
    for (file, measure, pick) in [
        ("collision.png", "collision share", (|s: &OutcomeSummary| s.collision) as fn(&OutcomeSummary) -> Share),
        ("success.png", "success share", |s: &OutcomeSummary| s.success),
    ] {
        let series = [
            ShareSeries { label: &doc.driver, shares: doc.by_kind.values().map(|c| pick(&c.driver)).collect() },
            ShareSeries { label: doc.reference, shares: doc.by_kind.values().map(|c| pick(&c.reference)).collect() },
        ];
        let title = format!("{measure} per kind, {} scenarios", doc.overall.driver.episodes);
        let image = shares(&title, measure, &groups, &series).map_err(CliError::runtime)?;
        write_png(&out.join(file), &image).map_err(CliError::runtime)?;
    }
    write("report.md", report_md(doc))
}

fn report_md(doc: &EvaluationDoc) -> String {
    use std::fmt::Write;
    let s = |x: &Share| format!("{:.2} [{:.2}, {:.2}]", x.share, x.low, x.high);
    let mut md = format!(
        "# Evaluation of {}\n\nScenarios: {}. Every share and mean with its {:.0} % interval \
         (Wilson for shares, Student t for means), the episodes taken as independent draws of the set's \
         scenario distribution. The reference driver ({}) drives the same scenarios.\n\n",
        doc.driver,
        match &doc.set {
            ScenarioSet::HeldOut { seed, per_kind } => format!("the held-out set of seed {seed}, {per_kind} per kind"),
            ScenarioSet::Library { db } => format!("every generated scenario of the library {db}"),
            ScenarioSet::CommonRoad { files } => format!("the CommonRoad recordings {}", files.join(", ")),
        },
        doc.confidence * 100.0,
        doc.reference
    );
    md.push_str("| kind | scenarios | collision | reference collision | success | reference success | off-road | out of time | completion | S_risk | avoidable (floor) |\n");
    md.push_str("|---|---|---|---|---|---|---|---|---|---|---|\n");
    let rows = doc.by_kind.iter().map(|(k, c)| (k.clone(), c)).chain([("all".to_owned(), &doc.overall)]);
    for (name, c) in rows {
        let d = &c.driver;
        let _ = writeln!(
            md,
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.3} | {} |",
            d.episodes,
            s(&d.collision),
            s(&c.reference.collision),
            s(&d.success),
            s(&c.reference.success),
            s(&d.offroad),
            s(&d.out_of_time),
            d.route_completion.mean,
            d.risk_score.mean,
            c.floor.as_ref().map_or("—".to_owned(), |f| s(&f.avoidable)),
        );
    }
    let _ = writeln!(
        md,
        "\n![collision share per kind](collision.png)\n\n![success share per kind](success.png)\n\n\
         Decisions the model failed to give (driven as the zero action): {}.",
        doc.model_faults
    );
    md
}
