//! `risktwin criticality`: HW, THW, TTC and a_long,req of a CommonRoad scenario's ego against
//! every other dynamic obstacle (docs/cli.md), plus PET and minimum distance per pair in JSON.

use super::recorded::read_commonroad;
use super::recover::{open_recording, warn_unfinished};
use crate::cli::CriticalityArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_table};
use risktwin_cloud::commonroad_recording::read_scenario;
use risktwin_cloud::criticality::{ReportFormat, write_report};
use risktwin_commonroad::Scenario;
use risktwin_commonroad::criticality::{ScenarioCriticality, scenario_criticality};

pub fn criticality(args: CriticalityArgs) -> CliResult {
    let (path, scenario) = match (&args.commonroad, &args.mcap) {
        (Some(path), _) => (path, read_commonroad(path)?),
        (None, Some(path)) => (path, read_recording(path)?),
        (None, None) => return Err(CliError::input("give --commonroad FILE.xml or --mcap FILE.mcap")),
    };
    let measures =
        scenario_criticality(&scenario, args.ego).map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    let format = match args.format {
        Format::Csv => ReportFormat::Csv,
        Format::Json => ReportFormat::Json,
        Format::Table => return print_pairs(&measures),
    };
    let out = std::io::BufWriter::new(std::io::stdout().lock());
    write_report(out, format, &scenario.benchmark_id, &measures).map_err(CliError::runtime)
}

/// Rebuilds a scenario from a recording of `risktwin import commonroad`.
/// An unfinished recording gives the scenario of its readable part, with a warning.
fn read_recording(path: &std::path::Path) -> CliResult<Scenario> {
    let cursor = open_recording(path, 1 << 16)?;
    let (scenario, unfinished) =
        read_scenario(cursor).map_err(|e| CliError::input(format!("{}: {e}", path.display())))?;
    if let Some(unfinished) = unfinished {
        warn_unfinished(path, &unfinished);
    }
    Ok(scenario)
}

/// One line per other: the worst value of each measure over the scenario.
fn print_pairs(m: &ScenarioCriticality) -> CliResult {
    let rows = m
        .pairs
        .iter()
        .map(|p| {
            let cells = m.cells.iter().filter(|c| c.other_id == p.other_id);
            let min = |f: fn(&risktwin_commonroad::criticality::CellMeasures) -> f64| {
                cells.clone().map(f).filter(|x| !x.is_nan()).fold(f64::INFINITY, f64::min)
            };
            vec![
                p.other_id.to_string(),
                fmt2(min(|c| c.hw_m)),
                fmt2(min(|c| c.thw_s)),
                fmt2(min(|c| c.ttc_s)),
                fmt2(min(|c| c.a_long_req_mps2)),
                fmt2(p.pet_s),
                fmt2(p.min_distance_m),
            ]
        })
        .collect::<Vec<_>>();
    print_table(&["other_id", "min_hw_m", "min_thw_s", "min_ttc_s", "min_a_long_req", "pet_s", "min_distance_m"], &rows)
}

fn fmt2(x: f64) -> String {
    if x.is_finite() { format!("{x:.2}") } else { csv_float(x) }
}
