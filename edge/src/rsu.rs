//! The roadside-unit role: its own copy of the scenario world, seen by a 360° sensor on a mast
//! 12 m beside the ego's start, published as `RsuObservation` on `rsu`, and a fixed-time traffic
//! signal's `SignalPhase` on `signal`; both at the base rate (10 Hz, the usual SPaT rate).

use crate::error::EdgeError;
use crate::publish::{EdgeConfig, Producer, Stamper, run_producer};
use crate::scene::{Scene, detected, feasible_spec};
use crate::summary::SentSummary;
use risktwin_common::geometry::Pose;
use risktwin_common::rng::Rng;
use risktwin_common::sensor::{PerceivedObject, SceneObject, Sensor, SensorParams};
use risktwin_common::telemetry::{RsuObservation, SignalPhase};
use risktwin_common::traffic::FixedTimeSignal;
use risktwin_common::world::STEP_S;
use risktwin_protos::encode;
use risktwin_transport::{EdgeStream, Shutdown};

/// The rate of an RSU unless told otherwise, Hz.
pub const DEFAULT_RATE_HZ: f64 = 10.0;

/// Physics steps per observation: 10 Hz observations of the world's 20 Hz.
const STEPS_PER_TICK: u32 = 2;

const STREAMS: [EdgeStream; 2] = [EdgeStream::Rsu, EdgeStream::Signal];

/// A roadside unit's scene, sensor and signal.
pub struct Rsu {
    scene: Scene,
    sensor: Sensor,
    range_m: f64,
    mast: Pose,
    signal: FixedTimeSignal,
    rng: Rng,
    scratch: Vec<SceneObject>,
    seen: Vec<PerceivedObject>,
}

impl Rsu {
    /// The RSU of `config`'s scenario.
    pub fn new(config: &EdgeConfig) -> Result<Self, EdgeError> {
        let scene = Scene::new(feasible_spec(config.scenario_seed, config.kind)?);
        let ego = scene.world.ego.pose();
        let params = SensorParams { fov_rad: std::f64::consts::TAU, occlusion: false, ..SensorParams::default() };
        let sensor = Sensor::new(params).map_err(|e| EdgeError::Sensor { reason: e.to_string() })?;
        Ok(Rsu {
            scene,
            sensor,
            range_m: params.range_m,
            mast: Pose::new(ego.x_m, ego.y_m - 12.0, std::f64::consts::FRAC_PI_2),
            signal: FixedTimeSignal::default(),
            rng: Rng::new(config.scenario_seed),
            scratch: Vec::new(),
            seen: Vec::new(),
        })
    }
}

impl Producer for Rsu {
    fn streams(&self) -> &[EdgeStream] {
        &STREAMS
    }

    fn ticks_per_base(&self) -> u32 {
        1
    }

    fn messages_per_base(&self, _stream: EdgeStream) -> f64 {
        // One observation and one signal phase per tick.
        1.0
    }

    fn tick(&mut self, _tick: u64, stamper: &mut Stamper<'_>, out: &mut Vec<(EdgeStream, Vec<u8>)>) {
        for _ in 0..STEPS_PER_TICK {
            self.scene.step();
        }
        let world = &mut self.scene.world;
        world.roadside_view(&mut self.sensor, self.mast, &mut self.rng, &mut self.scratch, &mut self.seen);
        let observation = RsuObservation {
            header: stamper.header(EdgeStream::Rsu),
            rsu_pose: self.mast,
            range_m: self.range_m,
            objects: self.seen.iter().map(detected).collect(),
        };
        out.push((EdgeStream::Rsu, encode(&observation)));
        let (phase, time_to_change_s) = self.signal.phase_at(world.time_s);
        let signal = SignalPhase { header: stamper.header(EdgeStream::Signal), signal_id: 0, phase, time_to_change_s };
        out.push((EdgeStream::Signal, encode(&signal)));
    }
}

/// Runs an RSU until its count or duration is reached or `shutdown` fires.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<SentSummary, EdgeError> {
    debug_assert!((STEP_S * f64::from(STEPS_PER_TICK) - 0.1).abs() < 1e-12);
    let mut rsu = Rsu::new(config)?;
    run_producer(config, &mut rsu, shutdown).await
}
