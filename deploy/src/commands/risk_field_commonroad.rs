//! `risktwin risk-field --commonroad FILE [--ego ID]` (or `--db FILE --id ID` of a recorded
//! case): the field around the recorded ego over the real lanelet map, and S_risk of the
//! recorded ego trajectory.

use super::recorded::CommonRoadInput;
use super::risk_field::{FieldSummary, print_summary};
use super::simulate_commonroad::resimulate_input;
use crate::cli::RiskFieldArgs;
use crate::error::{CliError, CliResult};
use crate::png_out::write_png;
use risktwin_common::commonroad::twin::{field_at, render_field};
use serde::Serialize;

/// cli.md's summary plus what only a recording has.
#[derive(Serialize)]
struct CommonRoadSummary<'a> {
    #[serde(flatten)]
    field: &'a FieldSummary,
    ego_id: u64,
    /// S_risk of the recorded ego trajectory replayed at the twin's step (score module).
    risk_score: f64,
}

pub fn commonroad_field(args: &RiskFieldArgs, input: &CommonRoadInput) -> CliResult {
    let (scenario, ego_id, shown) = (&input.scenario, input.ego_id, &input.shown);
    let field = field_at(scenario, ego_id, args.time, args.resolution, args.cells)
        .map_err(|e| CliError::input(format!("{shown}: {e}")))?;
    if let Some(png) = &args.png {
        write_png(png, &render_field(&field, &scenario.lanelets, 4))?;
    }
    let replay = resimulate_input(input, "replay")?;
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
