//! The vehicle role: a scenario world stepped at the world's 20 Hz (`common::world::STEP_S`)
//! by its ego controller (the reference driver until the cloud pushes a policy), published as
//! interpolated samples of that one simulation ([`crate::cadence`]): the ego's
//! `VehicleStateSample` on `state` at 50 Hz, the motion and driver CAN frames on `can` every
//! 10 ms (100 Hz per frame id, 200 frames/s on the stream), and the perceived `ObjectList` on
//! `perception` every 2nd physics step (10 Hz).
//!
//! Cloud pushes ([`push`]): a valid scenario push replaces what the vehicle drives — the
//! pushed episode is executed (see `scene::Tape`) and played out on the same streams, then its
//! `ScenarioResult` goes back on `risktwin/v1/<site>/<id>/scenario_result` and the vehicle
//! returns to its own scenario. A valid policy update drives from then on: the vehicle's own
//! scene at once, and every pushed scenario executed after it (its `ScenarioResult` names the
//! policy version that drove). A hazard warning of the cloud's warning role
//! (`risktwin/v1/<site>/<id>/warning`) addressed to this vehicle puts the other vehicle it warns
//! of among the objects the driver of the own scene sees (as a V2X warning: `scene::Scene::hear`),
//! until 1 s after it was last heard of; warnings that arrive while a pushed episode plays (its
//! driving was recorded ahead of time) are only counted.

pub mod push;

use crate::cadence::{Segment, TICKS_PER_STATE, VehicleOutlet, messages_per_state, vehicle_tick};
use crate::error::EdgeError;
use crate::publish::{EdgeConfig, Producer, Stamper, run_producer};
use crate::scene::{ActivePolicy, Scene, Tape, detected, feasible_spec};
use crate::summary::SentSummary;
use push::{PolicyTrust, PushSummary, ResultLine};
use risktwin_common::telemetry::{CAN_DLC, CanFrame, DetectedObject, ObjectList, ScenarioResult};
use risktwin_policy::model::DriverModel;
use risktwin_protos::encode;
use risktwin_transport::keyexpr::{CloudToEdge, EdgeReport};
use risktwin_transport::{EdgeStream, Shutdown};
use serde::Serialize;
use std::convert::Infallible;

/// The state rate of a vehicle unless told otherwise, Hz.
pub const DEFAULT_STATE_RATE_HZ: f64 = 50.0;

const STREAMS: [EdgeStream; 3] = [EdgeStream::State, EdgeStream::Can, EdgeStream::Perception];
const PUSHES: [CloudToEdge; 3] = [CloudToEdge::Scenario, CloudToEdge::Policy, CloudToEdge::Warning];

/// A pushed scenario being played out.
struct Pushed {
    spec_id: String,
    tape: Tape,
    /// First and last sequence numbers of the `state` messages published from the tape.
    state_seqs: Option<(u64, u64)>,
}

/// The object ids the hazards warned of get among what the ego perceives: from here up, one per
/// hazard vehicle in order of first warning (scene objects are numbered from 0; the ego is
/// `u32::MAX`).
pub const HAZARD_ID_BASE: u32 = 0x4000_0000;

/// A vehicle's scene and its last physics step, ticked at the CAN rate.
pub struct Vehicle {
    /// The vehicle's own id (the warnings addressed to it name it).
    id: String,
    /// The hazard vehicles warned of so far: object id `HAZARD_ID_BASE + index`.
    hazards: Vec<String>,
    scene: Scene,
    pushed: Option<Pushed>,
    /// Whether the current step came from the pushed tape.
    on_tape: bool,
    policy: Option<ActivePolicy>,
    /// The ego over the last step, which the ticks sample.
    segment: Segment,
    /// What the ego perceived at the start of the last step.
    perceived: Vec<DetectedObject>,
    pushes: PushSummary,
    /// Whose policy updates it takes.
    trust: PolicyTrust,
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
        let scene = Scene::with_policy(feasible_spec(config.scenario_seed, config.kind)?, config.driver.clone());
        let segment = Segment::at_rest(scene.world.ego.clone());
        Ok(Vehicle {
            id: config.id.as_str().to_owned(),
            hazards: Vec::new(),
            scene,
            pushed: None,
            on_tape: false,
            policy: config.driver.clone(),
            segment,
            perceived: Vec::new(),
            pushes: PushSummary::default(),
            trust: PolicyTrust {
                key: config.trust_key.clone(),
                target: format!("{}/{}", config.site.as_str(), config.id.as_str()),
            },
            reports: Vec::new(),
            results_sent: 0,
        })
    }

    /// The pushes received so far.
    pub fn pushes(&self) -> &PushSummary {
        &self.pushes
    }

    /// A hazard warning (`payload` tagged `encoding`): addressed to this vehicle, its hazard goes
    /// to the own scene's driver (not while a pushed episode plays).
    fn warning(&mut self, encoding: &str, payload: &[u8]) {
        let Some(warning) = self.pushes.warning(&self.id, encoding, payload) else { return };
        if self.pushed.is_some() {
            self.pushes.warnings_on_tape += 1;
            return;
        }
        let index = match self.hazards.iter().position(|h| *h == warning.hazard_source) {
            Some(i) => i,
            None => {
                self.hazards.push(warning.hazard_source.clone());
                self.hazards.len() - 1
            }
        };
        let id = HAZARD_ID_BASE.saturating_add(u32::try_from(index).unwrap_or(u32::MAX));
        self.scene.hear(&warning, id);
    }

    /// One physics step: from the pushed episode while it lasts, else from the own scene.
    fn step(&mut self, stamper: &Stamper<'_>) {
        if let Some((segment, perceived)) = self.pushed.as_mut().and_then(|p| p.tape.next_step()) {
            self.perceived.clear();
            self.perceived.extend_from_slice(perceived);
            self.segment = segment;
            self.on_tape = true;
            return;
        }
        self.on_tape = false;
        if let Some(done) = self.pushed.take() {
            self.finish_pushed(done, stamper);
        }
        self.segment = self.scene.step();
        self.perceived.clear();
        self.perceived.extend(self.scene.world.perceived().iter().map(detected));
    }

    /// Reports the outcome of a played-out pushed episode.
    fn finish_pushed(&mut self, done: Pushed, stamper: &Stamper<'_>) {
        let result = ScenarioResult {
            header: stamper.report_header(self.results_sent),
            spec_id: done.spec_id,
            metrics: done.tape.result.metrics.clone(),
            risk: done.tape.result.risk,
            policy: done.tape.driven_by.clone(),
            state_seqs: done.state_seqs,
            scene: None,
        };
        self.results_sent += 1;
        let driver = result
            .policy
            .as_ref()
            .map_or("reference driver".to_owned(), |p| format!("policy {} version {}", p.policy_id, p.version));
        tracing::info!(
            "edge {}: scenario {} done ({driver}): collision {}, min TTC {:?} s",
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
            policy: result.policy.clone(),
            state_seqs: done.state_seqs,
        });
        self.reports.push((EdgeReport::ScenarioResult, encode(&result)));
    }
}

impl Producer for Vehicle {
    fn streams(&self) -> &[EdgeStream] {
        &STREAMS
    }

    fn ticks_per_base(&self) -> u32 {
        TICKS_PER_STATE
    }

    fn messages_per_base(&self, stream: EdgeStream) -> f64 {
        messages_per_state(stream)
    }

    fn tick(&mut self, tick: u64, stamper: &mut Stamper<'_>, out: &mut Vec<(EdgeStream, Vec<u8>)>) {
        let Ok(()) = vehicle_tick(tick, &mut Encoding { vehicle: self, stamper, out });
    }

    fn pushes(&self) -> &[CloudToEdge] {
        &PUSHES
    }

    fn on_push(&mut self, push: CloudToEdge, encoding: &str, payload: &[u8]) {
        match push {
            CloudToEdge::Scenario => {
                if let Some(p) = self.pushes.scenario(encoding, payload) {
                    tracing::info!("edge: running pushed scenario {}", p.spec_id);
                    // A push while another one plays replaces it (its result is not reported).
                    let tape = Tape::record(&p.spec, self.policy.as_ref());
                    self.pushed = Some(Pushed { spec_id: p.spec_id, tape, state_seqs: None });
                }
            }
            CloudToEdge::Policy => {
                if let Some(policy) = self.pushes.policy(encoding, payload, &self.trust) {
                    let kind = match &policy.model {
                        DriverModel::Native(net) => net.kind().algo(),
                        DriverModel::Onnx(_) => "onnx",
                    };
                    tracing::info!(
                        "edge: driving with policy {} version {} ({kind})",
                        policy.id.policy_id,
                        policy.id.version
                    );
                    // The own scene switches now; a pushed episode already recorded keeps its driver.
                    self.scene.set_policy(policy.clone());
                    self.policy = Some(policy);
                }
            }
            CloudToEdge::Warning => self.warning(encoding, payload),
            CloudToEdge::Control | CloudToEdge::Ack => {}
        }
    }

    fn reports(&mut self, out: &mut Vec<(EdgeReport, Vec<u8>)>) {
        out.append(&mut self.reports);
    }
}

/// A vehicle's tick encoded as protobuf messages for Zenoh.
struct Encoding<'v, 's> {
    vehicle: &'v mut Vehicle,
    stamper: &'v mut Stamper<'s>,
    out: &'v mut Vec<(EdgeStream, Vec<u8>)>,
}

impl VehicleOutlet for Encoding<'_, '_> {
    type Error = Infallible;

    fn step(&mut self) -> Result<(), Infallible> {
        self.vehicle.step(self.stamper);
        Ok(())
    }

    fn segment(&self) -> &Segment {
        &self.vehicle.segment
    }

    fn publish_state(&mut self, ego: &risktwin_common::vehicle::Vehicle) -> Result<(), Infallible> {
        let state = ego.state_sample(self.stamper.header(EdgeStream::State));
        let on_tape = self.vehicle.on_tape;
        if let Some(pushed) = self.vehicle.pushed.as_mut().filter(|_| on_tape) {
            let seq = state.header.seq;
            pushed.state_seqs = Some(pushed.state_seqs.map_or((seq, seq), |(first, _)| (first, seq)));
        }
        self.out.push((EdgeStream::State, encode(&state)));
        Ok(())
    }

    fn publish_perception(&mut self) -> Result<(), Infallible> {
        let header = self.stamper.header(EdgeStream::Perception);
        let list = ObjectList { header, objects: self.vehicle.perceived.clone() };
        self.out.push((EdgeStream::Perception, encode(&list)));
        Ok(())
    }

    fn publish_can(&mut self, can_id: u32, data: [u8; 8]) -> Result<(), Infallible> {
        let frame = CanFrame { header: self.stamper.header(EdgeStream::Can), can_id, data, dlc: CAN_DLC };
        self.out.push((EdgeStream::Can, encode(&frame)));
        Ok(())
    }
}

/// Runs a vehicle until its count or duration is reached or `shutdown` fires.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<VehicleSummary, EdgeError> {
    let mut vehicle = Vehicle::new(config)?;
    let sent = run_producer(config, &mut vehicle, shutdown).await?;
    Ok(VehicleSummary { sent, pushes: vehicle.pushes })
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::geometry::{Footprint, Vec2};
    use risktwin_common::telemetry::{Frame, HazardKind, HazardWarning, Header, PolicyRef};
    use risktwin_protos::encoding_of;
    use risktwin_transport::{SiteId, SourceId};

    fn vehicle(id: &str) -> Vehicle {
        let config = EdgeConfig::new(SiteId::new("site").unwrap(), SourceId::new(id).unwrap(), 50.0);
        Vehicle::new(&config).expect("a feasible scenario")
    }

    /// A warning to `warned` of a vehicle standing `ahead_m` ahead of `v`'s ego in its lane.
    fn standing_ahead(v: &Vehicle, warned: &str, ahead_m: f64) -> HazardWarning {
        let world = &v.scene.world;
        let lane = world.road.lane(world.route.lane);
        let s_m = lane.project(world.ego.pose().position()).s_m;
        HazardWarning {
            header: Header {
                source: "cloud".into(),
                seq: 0,
                capture_time_ns: 1,
                publish_time_ns: 1,
                frame: Frame::World,
            },
            warned_source: warned.into(),
            hazard_source: "veh-9".into(),
            hazard_pose: lane.pose_at(s_m + ahead_m, 0.0),
            hazard_velocity: Vec2::zeros(),
            hazard_footprint: Footprint::new(4.5, 1.8),
            kind: HazardKind::LaneTtc,
            ttc_s: 1.5,
            distance_m: ahead_m - 4.5,
            trigger_source: warned.into(),
            trigger_seq: 1,
            trigger_capture_time_ns: 1,
        }
    }

    #[test]
    fn a_vehicle_starts_with_the_driver_it_is_given_an_onnx_model_too() {
        // The braking policy of the scene tests, exported and read back as ONNX.
        let braking = crate::scene::tests::policy_net(risktwin_policy::PolicyKind::Gaussian, &[0.0, 0.0, 1.0]);
        let onnx = risktwin_policy::onnx::OnnxPolicy::from_bytes(&braking.to_onnx()).expect("the export loads");
        let id = PolicyRef { policy_id: "brake.onnx@000000000000".into(), version: 0 };
        let mut config = EdgeConfig::new(SiteId::new("site").unwrap(), SourceId::new("veh-1").unwrap(), 50.0);
        config.driver = Some(ActivePolicy { id: id.clone(), model: DriverModel::Onnx(std::sync::Arc::new(onnx)) });
        let mut v = Vehicle::new(&config).expect("a feasible scenario");
        assert_eq!(v.scene.driven_by(), Some(&id));
        for _ in 0..5 {
            let step = v.scene.step();
            assert_eq!((step.controls.brake, step.controls.throttle), (1.0, 0.0), "the model brakes");
        }
        assert_eq!(vehicle("veh-1").scene.driven_by(), None, "without one: the reference driver");
    }

    #[test]
    fn a_warning_to_this_vehicle_slows_its_driver_for_the_hazard_in_its_lane_until_forgotten() {
        let (mut plain, mut warned) = (vehicle("veh-1"), vehicle("veh-1"));
        for _ in 0..10 {
            plain.scene.step();
            warned.scene.step();
        }
        let speed = |v: &Vehicle| v.scene.world.ego.state.speed_mps;
        assert_eq!(speed(&plain), speed(&warned), "nothing heard: the same drive");
        assert!(speed(&plain) > 5.0, "the ego drives: {} m/s", speed(&plain));
        let tag = encoding_of("risktwin.v1.HazardWarning");
        // Addressed to another vehicle: refused, not heard.
        plain.on_push(CloudToEdge::Warning, &tag, &encode(&standing_ahead(&plain, "veh-2", 30.0)));
        assert!(plain.scene.heard().is_empty());
        assert_eq!(plain.pushes().warnings_refused.get("wrong-vehicle"), Some(&1));
        // The warning again every 500 ms (the cloud's repeat limit) for 1.5 s, of the same spot:
        // the driver brakes for it after its reaction time (0.75 s); the other drives on.
        let warning = standing_ahead(&warned, "veh-1", 40.0);
        let (mut free_brake, mut warned_brake) = (0.0f64, 0.0f64);
        for step in 0..30 {
            if step % 10 == 0 {
                warned.on_push(CloudToEdge::Warning, &tag, &encode(&warning));
                assert_eq!(warned.scene.heard().len(), 1, "one hazard, heard again");
            }
            free_brake = free_brake.max(plain.scene.step().controls.brake);
            warned_brake = warned_brake.max(warned.scene.step().controls.brake);
        }
        assert_eq!(warned.pushes().warnings_received, 3);
        assert!(warned_brake > free_brake + 0.1, "brake {warned_brake} vs {free_brake}");
        assert!(speed(&warned) < speed(&plain) - 1.0, "{} vs {} m/s", speed(&warned), speed(&plain));
        // Not heard of again: forgotten 1 s after it was last heard (at step 20).
        assert_eq!(warned.scene.heard().len(), 1, "0.5 s after");
        // A step forgets at its start: the one that starts 1.05 s after.
        for _ in 0..12 {
            warned.scene.step();
        }
        assert!(warned.scene.heard().is_empty(), "1.05 s after");
    }
}
