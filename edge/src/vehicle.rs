//! The vehicle role: a scenario world stepped at 50 Hz by the reference driver; per step the
//! ego's `VehicleStateSample` on `state`, the motion and driver CAN frames on `can` twice (every
//! 10 ms: 100 Hz per frame id, 200 frames/s on the stream), and every 5th step the perceived
//! `ObjectList` on `perception` (10 Hz).

use crate::publish::{EdgeConfig, Producer, Stamper, run_producer};
use crate::scene::{Scene, detected, feasible_spec};
use crate::{EdgeError, SentSummary};
use risktwin_common::telemetry::{CanSignals, ObjectList};
use risktwin_protos::encode;
use risktwin_transport::{EdgeStream, Shutdown};

/// The state rate of a vehicle unless told otherwise, Hz.
pub const DEFAULT_STATE_RATE_HZ: f64 = 50.0;

const STREAMS: [EdgeStream; 3] = [EdgeStream::State, EdgeStream::Can, EdgeStream::Perception];

/// A vehicle's scene and what it last did, ticked at twice the step rate.
pub struct Vehicle {
    scene: Scene,
    signals: CanSignals,
    steps: u64,
    states: Vec<risktwin_common::telemetry::VehicleStateSample>,
}

impl Vehicle {
    /// The vehicle of `config`'s scenario.
    pub fn new(config: &EdgeConfig) -> Result<Self, EdgeError> {
        let scene = Scene::new(feasible_spec(config.scenario_seed, config.kind)?);
        Ok(Vehicle { scene, signals: CanSignals::default(), steps: 0, states: Vec::new() })
    }
}

impl Producer for Vehicle {
    fn streams(&self) -> &[EdgeStream] {
        &STREAMS
    }

    fn ticks_per_base(&self) -> u32 {
        2
    }

    fn tick(&mut self, tick: u64, stamper: &mut Stamper<'_>, out: &mut Vec<(EdgeStream, Vec<u8>)>) {
        if tick.is_multiple_of(2) {
            let controls = self.scene.step();
            let world = &self.scene.world;
            world.state_samples(0, &mut self.states);
            let ego = &world.ego.state;
            self.signals = CanSignals {
                speed_mps: ego.speed_mps,
                accel_mps2: ego.accel_mps2,
                yaw_rate_radps: ego.yaw_rate_radps,
                throttle: controls.throttle,
                brake: controls.brake,
                steer_rad: ego.steer_rad,
            };
            if let Some(mut state) = self.states.first().cloned() {
                state.header = stamper.header(EdgeStream::State);
                out.push((EdgeStream::State, encode(&state)));
            }
            if self.steps.is_multiple_of(5) {
                let list = ObjectList {
                    header: stamper.header(EdgeStream::Perception),
                    objects: world.perceived().iter().map(detected).collect(),
                };
                out.push((EdgeStream::Perception, encode(&list)));
            }
            self.steps += 1;
        }
        let motion = stamper.header(EdgeStream::Can);
        let driver = stamper.header(EdgeStream::Can);
        for frame in self.signals.to_frames(motion, driver) {
            out.push((EdgeStream::Can, encode(&frame)));
        }
    }
}

/// Runs a vehicle until its count or duration is reached or `shutdown` fires.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<SentSummary, EdgeError> {
    let mut vehicle = Vehicle::new(config)?;
    run_producer(config, &mut vehicle, shutdown).await
}
