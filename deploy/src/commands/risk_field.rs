//! `risktwin risk-field`: the risk field around the ego at a moment of a scenario. With
//! `--commonroad FILE [--ego ID]` (or `--db FILE --id ID` of a recorded case): the field around
//! the recorded ego over the real lanelet map, and S_risk of the recorded ego trajectory.

use super::recorded::{CommonRoadInput, commonroad_input};
use super::simulate_commonroad::resimulate_input;
use super::source;
use crate::cli::RiskFieldArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Format, csv_float, print_json, print_table};
use risktwin_common::episode::{FieldSnapshot, field_snapshot};
use risktwin_commonroad::twin::EgoMode;
use risktwin_commonroad::twin::field_at;
use risktwin_pipeline::figures::heatmap::heatmap;
use risktwin_pipeline::figures::{Bitmap, FigureError, HeatmapScene, write_png};
use serde::Serialize;
use std::path::Path;

#[derive(Serialize)]
struct FieldSummary {
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
        let title = format!("Risk field at t = {:.1} s ({})", snap.time_s, spec.kind);
        draw(path, heatmap(&HeatmapScene::of_snapshot(&snap, title)))?;
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

/// docs/cli.md's summary plus what only a recording has.
#[derive(Serialize)]
struct CommonRoadSummary<'a> {
    #[serde(flatten)]
    field: &'a FieldSummary,
    ego_id: u64,
    /// S_risk of the recorded ego trajectory replayed at the twin's step (score module).
    risk_score: f64,
}

fn commonroad_field(args: &RiskFieldArgs, input: &CommonRoadInput) -> CliResult {
    let (scenario, ego_id, shown) = (&input.scenario, input.ego_id, &input.shown);
    let field = field_at(scenario, ego_id, args.time, args.resolution, args.cells)
        .map_err(|e| CliError::input(format!("{shown}: {e}")))?;
    if let Some(png) = &args.png {
        let title = format!(
            "Risk field of {} around obstacle {} at t = {:.1} s",
            scenario.benchmark_id,
            ego_id.unwrap_or_default(),
            field.time_s
        );
        draw(png, heatmap(&HeatmapScene::of_commonroad(&field, &scenario.lanelets, title)))?;
    }
    let replay = resimulate_input(input, EgoMode::Replay)?;
    let (max, mean, argmax) = field.stats();
    let g = &field.grid;
    let summary = FieldSummary {
        cols: g.cols,
        rows: g.rows,
        resolution_m: g.resolution_m,
        origin_m: [g.origin_m.x, g.origin_m.y],
        max,
        mean,
        argmax_m: [argmax.x, argmax.y],
        time_s: field.time_s,
    };
    let doc = CommonRoadSummary {
        field: &summary,
        ego_id: ego_id.expect("field_at succeeded, so the scenario has an ego"),
        risk_score: replay.metrics.risk_score,
    };
    print_summary(&summary, &doc, args.format)
}

/// `json` as JSON, or the summary as a table.
fn print_summary(summary: &FieldSummary, json: &impl Serialize, format: Format) -> CliResult {
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

/// Writes a drawn heatmap; a file that cannot be created is the caller's input, as docs/cli.md says.
fn draw(path: &Path, figure: Result<Bitmap, FigureError>) -> CliResult {
    let error = |e: FigureError| match e {
        FigureError::Create { .. } => CliError::input(e),
        e => CliError::runtime(e),
    };
    write_png(path, &figure.map_err(error)?).map_err(error)
}
