//! The vehicle role: a scenario world stepped at 50 Hz by the reference driver; per step the
//! ego's `VehicleStateSample` on `state`, the motion and driver CAN frames on `can` twice (every
//! 10 ms: 100 Hz per frame id, 200 frames/s on the stream), and every 5th step the perceived
//! `ObjectList` on `perception` (10 Hz).
//!
//! Cloud pushes ([`push`]): a valid scenario push replaces what the vehicle drives — the
//! pushed episode is executed (see `scene::Tape`) and played out on the same streams, then its
//! `ScenarioResult` goes back on `risktwin/v1/<site>/<id>/scenario_result` and the vehicle
//! returns to its own scenario. A valid policy update is kept and reported in the summary.

pub mod push;

use crate::publish::{EdgeConfig, Producer, Stamper, run_producer};
use crate::scene::{Scene, Tape, detected, feasible_spec};
use crate::{EdgeError, SentSummary};
use push::{PushSummary, ResultLine};
use risktwin_common::telemetry::{CanSignals, DetectedObject, ObjectList, ScenarioResult, VehicleStateSample};
use risktwin_protos::encode;
use risktwin_transport::keyexpr::{CloudToEdge, EdgeReport};
use risktwin_transport::{EdgeStream, Shutdown};
use serde::Serialize;

/// The state rate of a vehicle unless told otherwise, Hz.
pub const DEFAULT_STATE_RATE_HZ: f64 = 50.0;

const STREAMS: [EdgeStream; 3] = [EdgeStream::State, EdgeStream::Can, EdgeStream::Perception];
const PUSHES: [CloudToEdge; 2] = [CloudToEdge::Scenario, CloudToEdge::Policy];

/// A pushed scenario being played out.
struct Pushed {
    spec_id: String,
    tape: Tape,
}

/// A vehicle's scene and what it last did, ticked at twice the step rate.
pub struct Vehicle {
    scene: Scene,
    pushed: Option<Pushed>,
    signals: CanSignals,
    steps: u64,
    states: Vec<VehicleStateSample>,
    perceived: Vec<DetectedObject>,
    pushes: PushSummary,
    reports: Vec<(EdgeReport, Vec<u8>)>,
    results_sent: u64,
}

/// What a vehicle prints on exit: what it sent, and what the cloud pushed to it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VehicleSummary {
    #[serde(flatten)]
    pub sent: SentSummary,
    pub pushes: PushSummary,
}

impl Vehicle {
    /// The vehicle of `config`'s scenario.
    pub fn new(config: &EdgeConfig) -> Result<Self, EdgeError> {
        let scene = Scene::new(feasible_spec(config.scenario_seed, config.kind)?);
        Ok(Vehicle {
            scene,
            pushed: None,
            signals: CanSignals::default(),
            steps: 0,
            states: Vec::new(),
            perceived: Vec::new(),
            pushes: PushSummary::default(),
            reports: Vec::new(),
            results_sent: 0,
        })
    }

    /// The pushes received so far.
    pub fn pushes(&self) -> &PushSummary {
        &self.pushes
    }

    /// One simulation step: from the pushed episode while it lasts, else from the own scene.
    fn step(&mut self, stamper: &Stamper<'_>) {
        let from_tape = self.pushed.as_mut().and_then(|p| p.tape.next_step().cloned());
        let controls = match from_tape {
            Some(step) => {
                self.states.clear();
                self.states.push(step.state);
                self.perceived.clone_from(&step.perceived);
                step.controls
            }
            None => {
                if let Some(done) = self.pushed.take() {
                    self.finish_pushed(done, stamper);
                }
                let controls = self.scene.step();
                let world = &self.scene.world;
                world.state_samples(0, &mut self.states);
                self.perceived.clear();
                self.perceived.extend(world.perceived().iter().map(detected));
                controls
            }
        };
        if let Some(ego) = self.states.first() {
            self.signals = CanSignals {
                speed_mps: ego.speed_mps,
                accel_mps2: ego.accel_mps2,
                yaw_rate_radps: ego.yaw_rate_radps,
                throttle: controls.throttle,
                brake: controls.brake,
                steer_rad: ego.steer_rad,
            };
        }
    }

    /// Reports the outcome of a played-out pushed episode.
    fn finish_pushed(&mut self, done: Pushed, stamper: &Stamper<'_>) {
        let result = ScenarioResult {
            header: stamper.report_header(self.results_sent),
            spec_id: done.spec_id,
            metrics: done.tape.result.metrics.clone(),
            risk: done.tape.result.risk,
        };
        self.results_sent += 1;
        eprintln!(
            "edge {}: scenario {} done: collision {}, min TTC {:?} s",
            stamper.source(),
            result.spec_id,
            result.metrics.collision,
            result.metrics.min_ttc_s
        );
        self.pushes.results.push(ResultLine {
            spec_id: result.spec_id.clone(),
            collision: result.metrics.collision,
            min_ttc_s: result.metrics.min_ttc_s,
            risk_score: result.risk.score,
            steps: result.metrics.steps,
        });
        self.reports.push((EdgeReport::ScenarioResult, encode(&result)));
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
            self.step(stamper);
            if let Some(mut state) = self.states.first().cloned() {
                state.header = stamper.header(EdgeStream::State);
                out.push((EdgeStream::State, encode(&state)));
            }
            if self.steps.is_multiple_of(5) {
                let list =
                    ObjectList { header: stamper.header(EdgeStream::Perception), objects: self.perceived.clone() };
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

    fn pushes(&self) -> &[CloudToEdge] {
        &PUSHES
    }

    fn on_push(&mut self, push: CloudToEdge, payload: &[u8]) {
        match push {
            CloudToEdge::Scenario => {
                if let Some(p) = self.pushes.scenario(payload) {
                    eprintln!("edge: running pushed scenario {}", p.spec_id);
                    // A push while another one plays replaces it (its result is not reported).
                    self.pushed = Some(Pushed { spec_id: p.spec_id, tape: Tape::record(&p.spec) });
                }
            }
            CloudToEdge::Policy => {
                if let Some(u) = self.pushes.policy(payload) {
                    eprintln!("edge: holding policy {} version {} ({})", u.policy_id, u.version, u.algo);
                }
            }
            CloudToEdge::Control => {}
        }
    }

    fn reports(&mut self, out: &mut Vec<(EdgeReport, Vec<u8>)>) {
        out.append(&mut self.reports);
    }
}

/// Runs a vehicle until its count or duration is reached or `shutdown` fires.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<VehicleSummary, EdgeError> {
    let mut vehicle = Vehicle::new(config)?;
    let sent = run_producer(config, &mut vehicle, shutdown).await?;
    Ok(VehicleSummary { sent, pushes: vehicle.pushes })
}
