//! Closed-loop re-simulation of a recorded scenario: the recorded traffic plays back, the ego
//! is replayed or driven by the reference driver from its recorded initial state, and the run
//! is measured like any twin episode (metrics, S_risk).

use super::super::Scenario;
use super::TwinError;
use super::ego::ego_sensor;
use super::scene::TwinScene;
use super::stepper::{EgoMode, ResimStepper, Resimulation, check_step};
use risktwin_common::driver::{DriverView, Policy};
use risktwin_common::vehicle::Controls;

/// Re-runs `scenario` at `step_s` from the ego's first to its last recorded state. The run stops
/// at the first collision when the reference driver drives (as a twin episode does); a replay
/// runs to the end, so its min distance covers the whole recording. Offroad means the ego's
/// centre is in no lanelet (see [`ResimStepper`]).
pub fn resimulate(
    scenario: &Scenario,
    ego_id: Option<u64>,
    mode: EgoMode,
    step_s: f64,
) -> Result<Resimulation, TwinError> {
    check_step(step_s)?;
    let scene = TwinScene::new(scenario, ego_id)?;
    let mut driver = scene.ego_driver();
    let footprint = scene.ego.footprint;
    let (mut sensor, mut rng) = ego_sensor();
    let mut perceived = Vec::new();
    let mut run = ResimStepper::new(&scenario.lanelets, scene, mode, step_s)?;
    while !run.finished() {
        let controls = match mode {
            EgoMode::Replay => Controls::default(),
            EgoMode::ReferenceDriver => {
                let vehicle = run.vehicle();
                let pose = vehicle.pose();
                sensor.perceive(pose, run.objects(), &mut rng, &mut perceived);
                driver.act(&DriverView {
                    road: run.road(),
                    time_s: run.time_s(),
                    ego_pose: pose,
                    ego_speed_mps: vehicle.state.speed_mps,
                    ego_accel_mps2: vehicle.state.accel_mps2,
                    ego_footprint: footprint,
                    perceived: &perceived,
                    warned: &[],
                })
            }
        };
        run.advance(controls);
    }
    Ok(run.finish())
}
