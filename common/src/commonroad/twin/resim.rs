//! Closed-loop re-simulation of a recorded scenario: the recorded traffic plays back, the ego
//! is replayed or driven by the reference driver from its recorded initial state, and the run
//! is measured like any twin episode (metrics, S_risk).

use super::super::Scenario;
use super::TwinError;
use super::ego::ego_sensor;
use super::scene::TwinScene;
use super::stepper::{ResimStepper, check_step};
use crate::driver::{DriverView, Policy};
use crate::geometry::Obb;
use crate::metrics::EpisodeMetrics;
use crate::risk::RiskTerms;
use crate::vehicle::Controls;

/// Who drives the ego.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EgoMode {
    /// The recorded ego trajectory, played back (open loop).
    Replay,
    /// The twin's reference driver (IDM + lane changes on what its sensor perceives) on the
    /// twin's single-track vehicle, from the recorded initial state (closed loop).
    ReferenceDriver,
}

/// The ego after one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResimSample {
    pub time_s: f64,
    pub ego: Obb,
    pub speed_mps: f64,
    /// Smallest footprint distance to any other object now, m (∞ when alone).
    pub min_distance_m: f64,
    pub collision: bool,
    pub offroad: bool,
}

/// What a re-simulation produced.
#[derive(Debug, Clone, PartialEq)]
pub struct Resimulation {
    /// As `risktwin simulate` reports them (route = the recorded ego path).
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
    /// The ego's initial sample, then one per step.
    pub trace: Vec<ResimSample>,
    pub start_s: f64,
    pub end_s: f64,
}

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
