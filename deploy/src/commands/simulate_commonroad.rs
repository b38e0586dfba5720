//! `risktwin simulate --commonroad FILE [--ego ID] [--policy idm|replay]`: a recorded scenario
//! re-run in the twin — recorded traffic played back, the ego replayed or driven closed-loop by
//! the reference driver from its recorded initial state — measured like any episode.

use super::criticality::read_commonroad;
use crate::cli::SimulateArgs;
use crate::error::{CliError, CliResult};
use risktwin_common::commonroad::twin::{EgoMode, Resimulation, resimulate};
use risktwin_common::world::STEP_S;
use std::path::Path;

/// Re-runs the scenario at `path` with the ego driven by `policy` (`idm` or `replay`).
pub fn resimulate_file(path: &Path, ego: Option<u64>, policy: &str) -> CliResult<Resimulation> {
    let mode = match policy {
        "idm" => EgoMode::ReferenceDriver,
        "replay" => EgoMode::Replay,
        other => {
            return Err(CliError::input(format!(
                "unknown policy '{other}' for a CommonRoad scenario (available: idm, replay)"
            )));
        }
    };
    let scenario = read_commonroad(path)?;
    let ego = ego.or_else(|| scenario.default_ego_id());
    resimulate(&scenario, ego, mode, STEP_S).map_err(|e| CliError::input(format!("{}: {e}", path.display())))
}

pub fn simulate(args: &SimulateArgs, path: &Path) -> CliResult<Resimulation> {
    if args.trace.is_some() || args.record.is_some() {
        return Err(CliError::input("--trace and --record are not available with --commonroad"));
    }
    resimulate_file(path, args.source.ego, &args.policy)
}
