//! `risktwin simulate --commonroad FILE [--ego ID] [--driver idm|replay]` (or `--db FILE --id ID`
//! of a recorded case): a recorded scenario re-run in the twin — recorded traffic played back,
//! the ego replayed or driven closed-loop by the reference driver from its recorded initial
//! state — measured like any episode.

use super::recorded::CommonRoadInput;
use crate::cli::SimulateArgs;
use crate::error::{CliError, CliResult};
use risktwin_common::world::STEP_S;
use risktwin_commonroad::twin::{EgoMode, Resimulation, resimulate};
use risktwin_policy::spec::DriverSpec;
use risktwin_store::library::Outcome;

/// Re-runs `input` with the ego driven as `mode` says.
pub fn resimulate_input(input: &CommonRoadInput, mode: EgoMode) -> CliResult<Resimulation> {
    resimulate(&input.scenario, input.ego_id, mode, STEP_S)
        .map_err(|e| CliError::input(format!("{}: {e}", input.shown)))
}

/// The run as a library outcome under its policy label.
pub fn outcome_of(run: &Resimulation, policy: &str) -> Outcome {
    Outcome { policy: policy.to_string(), metrics: run.metrics.clone(), risk: run.risk }
}

/// Runs `input`; a recorded case of a library gets the run's outcome under the policy's label.
pub fn simulate(args: &SimulateArgs, input: &mut CommonRoadInput) -> CliResult<Resimulation> {
    if args.trace.is_some() || args.record.is_some() {
        return Err(CliError::input("--trace and --record are not available with a CommonRoad scenario"));
    }
    let mode = match &args.driver {
        DriverSpec::Reference => EgoMode::ReferenceDriver,
        DriverSpec::Replay => EgoMode::Replay,
        DriverSpec::PolicyFile(path) => {
            return Err(CliError::input(format!(
                "driver {}: a policy file drives generated scenarios; a CommonRoad scenario's ego is driven by idm or replay",
                path.display()
            )));
        }
    };
    let run = resimulate_input(input, mode)?;
    if let Some((library, id)) = &mut input.case {
        library.add_recorded_outcome(id, &outcome_of(&run, &args.driver.label()))?;
    }
    Ok(run)
}
