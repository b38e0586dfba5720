//! `risktwin risk-field`: the risk field around the ego at a moment of a scenario.

use super::recorded::commonroad_input;
use super::risk_field_commonroad::commonroad_field;
use super::source;
use crate::cli::RiskFieldArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use crate::png_out::write_png;
use risktwin_common::episode::{FieldSnapshot, field_snapshot};
use risktwin_common::risk::render_heatmap;
use serde::Serialize;

#[derive(Serialize)]
pub(super) struct FieldSummary {
    pub cols: usize,
    pub rows: usize,
    pub resolution_m: f64,
    pub origin_m: [f64; 2],
    pub max: f64,
    pub mean: f64,
    pub argmax_m: [f64; 2],
    pub time_s: f64,
}

pub fn risk_field(args: RiskFieldArgs) -> CliResult {
    if !(args.resolution >= 0.05 && args.resolution <= 10.0) {
        return Err(CliError::input(format!("--resolution {} is out of range [0.05, 10] m", args.resolution)));
    }
    if !(args.cells >= 8 && args.cells <= 2048) {
        return Err(CliError::input(format!("--cells {} is out of range [8, 2048]", args.cells)));
    }
    if !(args.time >= 0.0 && args.time.is_finite()) {
        return Err(CliError::input(format!("--time {} must be a non-negative number of seconds", args.time)));
    }
    if let Some(input) = commonroad_input(&args.source)? {
        return commonroad_field(&args, &input);
    }
    let spec = source::load(&args.source)?;
    let snap: FieldSnapshot = field_snapshot(&spec, args.time, args.resolution, args.cells).map_err(CliError::input)?;
    if let Some(path) = &args.png {
        write_png(path, &render_heatmap(&snap.grid, &snap.road, &snap.others, &snap.ego, 4))?;
    }
    let (max, mean, argmax) = snap.stats();
    let summary = FieldSummary {
        cols: snap.grid.cols,
        rows: snap.grid.rows,
        resolution_m: snap.grid.resolution_m,
        origin_m: [snap.grid.origin_m.x, snap.grid.origin_m.y],
        max,
        mean,
        argmax_m: [argmax.x, argmax.y],
        time_s: snap.time_s,
    };
    print_summary(&summary, &summary, args.format)
}

/// `json` as JSON, or the summary as a table.
pub(super) fn print_summary(summary: &FieldSummary, json: &impl Serialize, format: Format) -> CliResult {
    match format {
        Format::Json => print_json(json),
        _ => print_table(
            &["cols", "rows", "resolution_m", "max", "mean", "argmax_m"],
            &[vec![
                summary.cols.to_string(),
                summary.rows.to_string(),
                csv_float(summary.resolution_m),
                format!("{:.4}", summary.max),
                format!("{:.4}", summary.mean),
                format!("({:.1}, {:.1})", summary.argmax_m[0], summary.argmax_m[1]),
            ]],
        ),
    }
}
