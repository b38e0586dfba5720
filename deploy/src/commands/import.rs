//! `risktwin import commonroad FILE.xml --out FILE.mcap`: a recorded CommonRoad scenario as fleet
//! data, replayable with `risktwin edge replay` (layout in [`crate::commonroad_recording`]).

use super::criticality::read_commonroad;
use crate::cli::ImportCommonRoadArgs;
use crate::commonroad_recording::{FleetRecordingError, ImportSummary, write_scenario};
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use std::fs::File;
use std::io::BufWriter;

pub fn commonroad(args: ImportCommonRoadArgs) -> CliResult {
    let scenario = read_commonroad(&args.scenario)?;
    let file =
        File::create(&args.out).map_err(|e| CliError::runtime(format!("cannot create {}: {e}", args.out.display())))?;
    let summary = write_scenario(&scenario, BufWriter::new(file)).map_err(|e| match e {
        FleetRecordingError::Recording(e) => CliError::runtime(format!("writing {}: {e}", args.out.display())),
        e => CliError::input(format!("{}: {e}", args.scenario.display())),
    })?;
    match args.format {
        Format::Json => print_json(&summary),
        _ => print_summary(&summary),
    }
}

fn print_summary(s: &ImportSummary) -> CliResult {
    let row = vec![
        s.site.clone(),
        s.lanelets.to_string(),
        s.dynamic_obstacles.to_string(),
        s.static_obstacles.to_string(),
        s.messages.to_string(),
        format!("{:.2}", s.duration_s),
    ];
    print_table(&["site", "lanelets", "dynamic", "static", "messages", "duration_s"], &[row])
}
