//! `risktwin import commonroad FILE.xml (--out FILE.mcap | --db FILE.db [--ego ID])`: a recorded
//! CommonRoad scenario as fleet data, replayable with `risktwin edge replay` (layout in
//! [`risktwin_cloud::commonroad_recording`]), and/or as a recorded validation case in the scenario library
//! (the XML stored whole, the replayed ego's metrics as its reference outcome).

use super::recorded::{CommonRoadInput, read_xml};
use super::simulate_commonroad::{outcome_of, resimulate_input};
use crate::cli::ImportCommonRoadArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use risktwin_cloud::commonroad_recording::{FleetRecordingError, ImportSummary, write_scenario};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_commonroad::twin::EgoMode;
use risktwin_store::library::{REPLAY_POLICY, RecordedCase, ScenarioLibrary};
use serde::Serialize;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// What `--db` stored: the case and its reference outcome (the replayed ego).
#[derive(Serialize)]
struct CaseReport {
    id: String,
    benchmark_id: String,
    ego_id: u64,
    source: String,
    /// False when the same XML and ego were already in the library.
    inserted: bool,
    /// `simulate --policy replay`'s document: min TTC, min distance, S_risk (`risk_score`), ...
    #[serde(flatten)]
    metrics: EpisodeMetrics,
    risk: RiskTerms,
}

/// The JSON document: the recording summary (`--out`), the case (`--db`), or both in one object.
#[derive(Serialize)]
struct ImportReport {
    #[serde(flatten)]
    recording: Option<ImportSummary>,
    #[serde(flatten)]
    case: Option<CaseReport>,
}

pub fn commonroad(args: ImportCommonRoadArgs) -> CliResult {
    let xml = read_xml(&args.scenario)?;
    let input = CommonRoadInput::parse(&xml, args.scenario.display().to_string(), args.ego)?;
    // The replay runs and the library opens before anything is written, so an unusable ego or
    // a foreign `--db` file leaves no recording behind.
    let reference = match &args.db {
        Some(db) => {
            let run = resimulate_input(&input, EgoMode::Replay)?;
            Some((ScenarioLibrary::open(db).map_err(CliError::input)?, run))
        }
        None => None,
    };
    let recording = args.out.as_deref().map(|out| write_recording(&input, &args.scenario, out)).transpose()?;
    let case = match reference {
        Some((mut library, run)) => {
            let ego_id = input.ego_id.expect("the replay succeeded, so the scenario has an ego");
            let source = args
                .scenario
                .file_name()
                .map_or_else(|| args.scenario.display().to_string(), |name| name.to_string_lossy().into_owned());
            let case =
                RecordedCase { source_name: source, benchmark_id: input.scenario.benchmark_id.clone(), ego_id, xml };
            let stored = library.insert_recorded(&case, &outcome_of(&run, REPLAY_POLICY))?;
            Some(CaseReport {
                id: stored.id,
                benchmark_id: case.benchmark_id,
                ego_id,
                source: case.source_name,
                inserted: stored.inserted,
                metrics: run.metrics,
                risk: run.risk,
            })
        }
        None => None,
    };
    let report = ImportReport { recording, case };
    match args.format {
        Format::Json => print_json(&report),
        _ => print_tables(&report),
    }
}

fn write_recording(input: &CommonRoadInput, scenario: &Path, out: &Path) -> CliResult<ImportSummary> {
    let file = File::create(out).map_err(|e| CliError::runtime(format!("cannot create {}: {e}", out.display())))?;
    write_scenario(&input.scenario, BufWriter::new(file)).map_err(|e| match e {
        FleetRecordingError::Recording(e) => CliError::runtime(format!("writing {}: {e}", out.display())),
        e => CliError::input(format!("{}: {e}", scenario.display())),
    })
}

fn print_tables(report: &ImportReport) -> CliResult {
    if let Some(s) = &report.recording {
        let row = vec![
            s.site.clone(),
            s.lanelets.to_string(),
            s.dynamic_obstacles.to_string(),
            s.static_obstacles.to_string(),
            s.messages.to_string(),
            format!("{:.2}", s.duration_s),
        ];
        print_table(&["site", "lanelets", "dynamic", "static", "messages", "duration_s"], &[row])?;
    }
    if let Some(c) = &report.case {
        let m = &c.metrics;
        let row = vec![
            c.id.clone(),
            c.benchmark_id.clone(),
            c.ego_id.to_string(),
            c.inserted.to_string(),
            format!("{:.3}", m.risk_score),
            m.min_ttc_s.map_or("inf".into(), |t| format!("{t:.2}")),
            format!("{:.2}", m.min_distance_m),
            m.collision.to_string(),
        ];
        let header = ["id", "benchmark_id", "ego_id", "new", "risk_score", "min_ttc_s", "min_distance_m", "collision"];
        print_table(&header, &[row])?;
    }
    Ok(())
}
