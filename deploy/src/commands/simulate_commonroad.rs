//! `risktwin simulate --commonroad FILE [--ego ID] [--driver SPEC]` (or `--db FILE --id ID` of a
//! recorded case): a recorded scenario re-run in the twin — recorded traffic played back, the
//! ego replayed or driven closed-loop (by the reference driver or a model file) from its
//! recorded initial state — measured like any episode.

use super::driver::{load_model, warn_faults};
use super::recorded::CommonRoadInput;
use crate::cli::SimulateArgs;
use crate::error::{CliError, CliResult};
use risktwin_common::world::STEP_S;
use risktwin_commonroad::Scenario;
use risktwin_commonroad::twin::{EgoMode, Resimulation, resimulate, resimulate_driven};
use risktwin_policy::model::DriverModel;
use risktwin_policy::spec::{self, DriverSpec};
use risktwin_store::library::Outcome;

/// Re-runs `input` with the ego driven as `mode` says.
pub fn resimulate_input(input: &CommonRoadInput, mode: EgoMode) -> CliResult<Resimulation> {
    resimulate_recording(&Recording::of(input), mode)
}

/// A recording and its ego as the re-runs need them (shareable between threads, unlike a
/// [`CommonRoadInput`] holding its library).
pub struct Recording<'a> {
    pub scenario: &'a Scenario,
    pub ego_id: Option<u64>,
    /// How errors name it.
    pub shown: &'a str,
}

impl<'a> Recording<'a> {
    pub fn of(input: &'a CommonRoadInput) -> Self {
        Self { scenario: &input.scenario, ego_id: input.ego_id, shown: &input.shown }
    }
}

/// Re-runs a recording with the ego driven as `mode` says.
pub fn resimulate_recording(r: &Recording<'_>, mode: EgoMode) -> CliResult<Resimulation> {
    resimulate(r.scenario, r.ego_id, mode, STEP_S).map_err(|e| CliError::input(format!("{}: {e}", r.shown)))
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
    let (run, label) = drive(input, &args.driver)?;
    if let Some((library, id)) = &mut input.case {
        library.add_recorded_outcome(id, &outcome_of(&run, &label))?;
    }
    Ok(run)
}

/// Re-runs `input` with `driver` and returns the run and the driver's label: the recorded ego
/// for `replay`, else a closed loop (a model file checked in full first).
pub fn drive(input: &CommonRoadInput, driver: &DriverSpec) -> CliResult<(Resimulation, String)> {
    match driver {
        DriverSpec::Reference => Ok((resimulate_input(input, EgoMode::ReferenceDriver)?, spec::REFERENCE.to_owned())),
        DriverSpec::Replay => Ok((resimulate_input(input, EgoMode::Replay)?, spec::REPLAY.to_owned())),
        DriverSpec::PolicyFile(_) | DriverSpec::Onnx(_) => {
            let file = load_model(driver)?.ok_or_else(|| CliError::input("the driver has no model file"))?;
            let run = drive_model(&Recording::of(input), &file.model)?;
            warn_faults(&file.label(), &file.model);
            Ok((run, file.label()))
        }
    }
}

/// Re-runs a recording in closed loop with a driver model at the twin's step.
pub fn drive_model(r: &Recording<'_>, model: &DriverModel) -> CliResult<Resimulation> {
    resimulate_driven(r.scenario, r.ego_id, STEP_S, |scene| {
        Box::new(model.driver(scene.ego_desired_speed_mps(), STEP_S))
    })
    .map_err(|e| CliError::input(format!("{}: {e}", r.shown)))
}
