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
    match mode {
        EgoMode::Replay => run(scenario, ego_id, mode, step_s, |_| None),
        EgoMode::ReferenceDriver => run(scenario, ego_id, mode, step_s, |scene| Some(Box::new(scene.ego_driver()))),
    }
}

/// [`resimulate`] in closed loop with a driver of the caller's, made from the scene (its ego's
/// desired speed and parameters): a learned policy drives the recorded ego's vehicle, perceiving
/// through the same sensor as the reference driver, measured the same way.
pub fn resimulate_driven<'d>(
    scenario: &Scenario,
    ego_id: Option<u64>,
    step_s: f64,
    driver: impl FnOnce(&TwinScene) -> Box<dyn Policy + 'd>,
) -> Result<Resimulation, TwinError> {
    run(scenario, ego_id, EgoMode::ReferenceDriver, step_s, |scene| Some(driver(scene)))
}

/// The run: `driver` of the scene drives (closed loop), or none does (a replay).
fn run<'d>(
    scenario: &Scenario,
    ego_id: Option<u64>,
    mode: EgoMode,
    step_s: f64,
    driver: impl FnOnce(&TwinScene) -> Option<Box<dyn Policy + 'd>>,
) -> Result<Resimulation, TwinError> {
    check_step(step_s)?;
    let scene = TwinScene::new(scenario, ego_id)?;
    let mut driver = driver(&scene);
    let footprint = scene.ego.footprint;
    let (mut sensor, mut rng) = ego_sensor();
    let mut perceived = Vec::new();
    let mut run = ResimStepper::new(&scenario.lanelets, scene, mode, step_s)?;
    while !run.finished() {
        let controls = match driver.as_mut() {
            None => Controls::default(),
            Some(driver) => {
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
