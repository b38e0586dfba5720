//! The messages that flow between edges and the cloud, as domain types.
//!
//! These are what the rest of the code speaks: the edge builds them from its simulation, the
//! cloud ingests and records them. Their protobuf encoding lives in `risktwin-protos` (package
//! `risktwin.v1`), which converts to and from these types and rejects invalid wire values; nothing
//! here knows about the wire. Every stream message starts with a [`Header`]: who sent it, its
//! number in that source's stream and the source's own capture and publish times (the source's
//! clock may be offset and drift; the cloud estimates that per source).

mod can;

pub use can::{CAN_DLC, CAN_ID_DRIVER, CAN_ID_MOTION, CanError, CanSignals, Signal, signals};

use crate::geometry::{Footprint, Pose, Vec2};
use crate::metrics::EpisodeMetrics;
use crate::risk::{RiskGrid, RiskTerms};
use crate::road::Road;
use crate::scenario::ScenarioSpec;
use crate::sensor::ObjectKind;
use crate::vehicle::Controls;

/// Coordinate frame of a message's geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Frame {
    /// The shared world frame (x east, y north, heading counter-clockwise from +x).
    World,
    /// The publishing vehicle's body frame (x forward, y left, origin at the footprint centre).
    Vehicle,
}

/// Envelope of every stream message.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Header {
    /// Stable id of the publishing source, e.g. `vehicle-3`.
    pub source: String,
    /// Per-source, per-stream sequence number, +1 per message.
    pub seq: u64,
    /// Capture time by the source's own clock, ns since the Unix epoch.
    pub capture_time_ns: i64,
    /// Publish time by the source's own clock, ns since the Unix epoch.
    pub publish_time_ns: i64,
    /// Frame of the message's geometry.
    pub frame: Frame,
}

/// Kinematic state of one vehicle (50 Hz from a vehicle edge).
#[derive(Debug, Clone, PartialEq)]
pub struct VehicleStateSample {
    pub header: Header,
    pub pose: Pose,
    /// Velocity of the footprint centre, m/s.
    pub velocity: Vec2,
    /// Signed speed along the heading, m/s.
    pub speed_mps: f64,
    pub accel_mps2: f64,
    pub yaw_rate_radps: f64,
    /// Front-wheel steering angle, rad.
    pub steer_rad: f64,
    pub footprint: Footprint,
}

/// One classic CAN frame (100 Hz from a vehicle edge); signal layout in [`signals`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CanFrame {
    pub header: Header,
    /// 11-bit or 29-bit identifier.
    pub can_id: u32,
    /// Payload; bytes at and beyond `dlc` are zero.
    pub data: [u8; 8],
    /// Data length code, 0 to 8.
    pub dlc: u8,
}

/// One object as a sensor (vehicle or RSU) reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectedObject {
    /// Track id, stable across frames of one source.
    pub id: u32,
    pub kind: ObjectKind,
    pub pose: Pose,
    pub footprint: Footprint,
    /// Velocity, m/s.
    pub velocity: Vec2,
    /// Acceleration along the heading, m/s²; 0 where the source does not estimate it.
    pub accel_mps2: f64,
}

/// Every object a vehicle perceived at the capture time (10 Hz).
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectList {
    pub header: Header,
    pub objects: Vec<DetectedObject>,
}

/// The objects a roadside unit perceives within its range (10 Hz).
#[derive(Debug, Clone, PartialEq)]
pub struct RsuObservation {
    pub header: Header,
    pub rsu_pose: Pose,
    pub range_m: f64,
    pub objects: Vec<DetectedObject>,
}

/// Signal aspect of a traffic light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Phase {
    Red,
    Amber,
    Green,
}

/// The current phase of one signal head.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalPhase {
    pub header: Header,
    pub signal_id: u32,
    pub phase: Phase,
    /// Time until the phase changes, s (≥ 0).
    pub time_to_change_s: f64,
}

/// The road network a source drives on.
#[derive(Debug, Clone)]
pub struct RoadMap {
    pub header: Header,
    pub road: Road,
    /// The CommonRoad lanelets `road` was converted from (empty for the twin's own roads):
    /// criticality needs their polygons and links, which the twin lanes simplify away.
    pub lanelets: crate::road::LaneletNetwork,
}

/// The risk field on a grid around an ego, as the cloud twin computed it.
#[derive(Debug, Clone, PartialEq)]
pub struct RiskField {
    pub header: Header,
    pub grid: RiskGrid,
}

/// The twin's current risk assessment of one ego vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct RiskReport {
    pub header: Header,
    /// Source id of the ego assessed.
    pub ego_source: String,
    pub terms: RiskTerms,
    /// `None` when no object is closing in.
    pub min_ttc_s: Option<f64>,
    /// `+inf` when no other object is present.
    pub min_distance_m: f64,
}

/// How a pair was found critical (see [`HazardWarning`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HazardKind {
    /// The footprints overlap at the triggering message's time.
    Contact,
    /// One follows the other in its lane, closing in below the TTC threshold.
    LaneTtc,
    /// The footprints, moved on at constant velocity, overlap within the TTC threshold.
    PredictedContact,
}

/// Cloud to one vehicle: a hazard is near (DENM-like). The header's source is the cloud, its
/// seq numbers the warnings to this vehicle, its capture time is the triggering message's time
/// on the cloud's clock.
#[derive(Debug, Clone, PartialEq)]
pub struct HazardWarning {
    pub header: Header,
    /// The vehicle warned.
    pub warned_source: String,
    /// The other vehicle of the pair.
    pub hazard_source: String,
    /// The hazard at the triggering message's time.
    pub hazard_pose: Pose,
    pub hazard_velocity: Vec2,
    pub hazard_footprint: Footprint,
    pub kind: HazardKind,
    /// Time to collision, s (0 on contact).
    pub ttc_s: f64,
    /// Footprint-to-footprint distance at the triggering message's time, m.
    pub distance_m: f64,
    /// The state message that raised it: source, seq, capture time (the source's clock).
    pub trigger_source: String,
    pub trigger_seq: u64,
    pub trigger_capture_time_ns: i64,
}

/// One actuator command for a vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlCommand {
    pub header: Header,
    pub controls: Controls,
}

/// A new version of a learned policy for the edges.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyUpdate {
    pub header: Header,
    pub policy_id: String,
    /// Monotonic per `policy_id`.
    pub version: u32,
    /// Training algorithm (`ppo`, `sac`, …): which network layout the weights fill.
    pub algo: String,
    /// The weights as safetensors bytes.
    pub weights: Vec<u8>,
    /// `SITE/ID` of the vehicle it is for: part of what is signed, so a copy sent to another
    /// vehicle does not verify there (empty: addressed to none).
    pub target: String,
    /// The cloud's ed25519 signature over the weights and the fields above
    /// (`risktwin_policy::signature`); empty: unsigned, and refused by every vehicle.
    pub signature: Vec<u8>,
}

/// Cloud to edge: run this scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioPush {
    pub header: Header,
    /// Library id, echoed in the [`ScenarioResult`].
    pub spec_id: String,
    pub spec: ScenarioSpec,
}

/// A version of a learned policy: what drove an episode.
#[derive(Debug, Clone, PartialEq, Eq, Hash, serde::Serialize)]
pub struct PolicyRef {
    pub policy_id: String,
    pub version: u32,
}

/// Edge to cloud: the outcome of a pushed scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioResult {
    pub header: Header,
    pub spec_id: String,
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
    /// The received policy that drove the ego; `None`: the scenario's reference driver.
    pub policy: Option<PolicyRef>,
    /// Sequence numbers of the first and last `state` message the episode was published on;
    /// `None`: none was.
    pub state_seqs: Option<(u64, u64)>,
    /// The distributed scene the episode was played in; `None`: a pushed scenario.
    pub scene: Option<SceneRef>,
}

/// A distributed scene (`risktwin scene`) an episode was played in.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneRef {
    /// The scene's digest, 16 hex digits (the authority's `scene`).
    pub digest: String,
    /// The generated scenario it ran; its content id is the result's `spec_id`.
    pub spec: ScenarioSpec,
}
