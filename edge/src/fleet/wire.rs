//! The physics plane's messages: ground truth from the authority, joins and controls back.
//!
//! Encoded with postcard (serde; numbers as their exact IEEE-754 bits, −0.0 included), not
//! protobuf: lockstep promises byte-identical results to the embedded run, and proto3 turns
//! −0.0 into +0.0 (a default value is not sent), which changes `atan2` and so a heading. These
//! messages never leave a scene (the cloud's streams stay protobuf); [`SCHEMA_VERSION`] is in
//! every message and in the scene digest, and a mismatch is refused by name.

use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2};
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::risk::RiskTerms;
use risktwin_common::sensor::{ObjectKind, SceneObject};
use risktwin_common::telemetry::DetectedObject;
use risktwin_common::vehicle::Controls;
use risktwin_common::vehicle::Vehicle;
use risktwin_common::world::World;
use risktwin_commonroad::twin::ResimStepper;
use serde::{Deserialize, Serialize};

/// Version of the physics-plane messages; bump on any change to them.
pub const SCHEMA_VERSION: u32 = 2;

/// The ego's true state at the start of a step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EgoTruth {
    pub pose: [f64; 3],
    pub speed_mps: f64,
    pub accel_mps2: f64,
    pub yaw_rate_radps: f64,
    /// Front-wheel steering angle, rad.
    pub steer_rad: f64,
    pub velocity: [f64; 2],
    /// Length and width, m.
    pub footprint: [f64; 2],
}

/// One object other than the ego, exactly as the world holds it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TruthObject {
    pub id: u32,
    pub kind: ObjectKind,
    pub centre: [f64; 2],
    /// Unit vector along the length.
    pub axis: [f64; 2],
    pub half_length_m: f64,
    pub half_width_m: f64,
    pub velocity: [f64; 2],
    /// Acceleration along the heading, m/s² (0 for pedestrians).
    pub accel_mps2: f64,
}

/// How a scene ended, sent instead of a next step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SceneEnd {
    /// The episode is over (horizon, route done, collision or road departure): the ego's
    /// outcome as the authority measured it (the ego's process reports it to the cloud).
    Done { metrics: EpisodeMetrics, risk: RiskTerms },
    /// The authority gave up; the reason names who failed.
    Failed(String),
}

/// The ground truth of one step, from the authority to every participant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    pub schema: u32,
    /// The scene's digest ([`super::SceneSetup::digest`]).
    pub scene: u64,
    pub step: u64,
    pub time_s: f64,
    pub ego: EgoTruth,
    pub objects: Vec<TruthObject>,
    /// `Some` in the last message: no step follows.
    pub end: Option<SceneEnd>,
}

/// A participant's message to the authority.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    /// Repeated until the first truth arrives: who it is and which scene it runs.
    Join { schema: u32, participant: String, scene: u64, describe: String },
    /// The answer to step `step`: the ego's controls (steer, throttle, brake); `None` from
    /// participants that do not drive.
    Step { participant: String, step: u64, controls: Option<[f64; 3]> },
}

/// Why bytes are not a physics-plane message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    #[error("malformed physics-plane message: {0}")]
    Malformed(String),
    #[error("physics-plane schema version {theirs}, this process speaks {SCHEMA_VERSION}")]
    Schema { theirs: u32 },
    #[error("non-finite number in {0}")]
    NotFinite(&'static str),
}

fn finite(values: &[f64], what: &'static str) -> Result<(), WireError> {
    values.iter().all(|v| v.is_finite()).then_some(()).ok_or(WireError::NotFinite(what))
}

impl EgoTruth {
    /// The true state of the ego's `vehicle`.
    fn of(vehicle: &Vehicle) -> Self {
        let pose = vehicle.pose();
        let footprint = vehicle.params.footprint();
        let velocity = vehicle.velocity();
        EgoTruth {
            pose: [pose.x_m, pose.y_m, pose.heading_rad],
            speed_mps: vehicle.state.speed_mps,
            accel_mps2: vehicle.state.accel_mps2,
            yaw_rate_radps: vehicle.state.yaw_rate_radps,
            steer_rad: vehicle.state.steer_rad,
            velocity: [velocity.x, velocity.y],
            footprint: [footprint.length_m, footprint.width_m],
        }
    }
}

impl Truth {
    /// The truth of `world` now (its scene as of the last refresh) for step `step`.
    pub fn of(world: &World, scene: u64, step: u64) -> Truth {
        let objects = world.scene().iter().map(|o| TruthObject::new(o, traffic_accel_mps2(o, world))).collect();
        Truth::new(scene, step, world.time_s, &world.ego, objects)
    }

    /// The truth of a re-simulated recording now, for step `step`; its time is the time since
    /// the ego's first recorded state (the driver's clock, as in `resimulate`).
    pub fn of_recording(run: &ResimStepper<'_>, scene: u64, step: u64) -> Truth {
        let objects = run.objects().iter().map(|o| TruthObject::new(o, run.accel_mps2(o.id))).collect();
        Truth::new(scene, step, run.time_s(), run.vehicle(), objects)
    }

    fn new(scene: u64, step: u64, time_s: f64, ego: &Vehicle, objects: Vec<TruthObject>) -> Truth {
        Truth { schema: SCHEMA_VERSION, scene, step, time_s, ego: EgoTruth::of(ego), objects, end: None }
    }

    /// The ego's pose.
    pub fn ego_pose(&self) -> Pose {
        let [x, y, h] = self.ego.pose;
        Pose::new(x, y, h)
    }

    /// The ego as a scene object (what other vehicles and RSUs perceive), with `id`.
    pub fn ego_object(&self, id: u32) -> SceneObject {
        let [length, width] = self.ego.footprint;
        SceneObject {
            id,
            obb: Obb::new(self.ego_pose(), Footprint::new(length, width)),
            velocity: Vec2::new(self.ego.velocity[0], self.ego.velocity[1]),
            kind: ObjectKind::Vehicle,
        }
    }

    /// Encodes into `out` (cleared first).
    pub fn encode_into(&self, out: &mut Vec<u8>) {
        out.clear();
        // Serialising plain data into a Vec cannot fail; the Vec keeps its capacity step to step.
        *out = postcard::to_extend(self, std::mem::take(out)).expect("a truth serialises");
    }

    /// Decodes and validates a truth message.
    pub fn decode(bytes: &[u8]) -> Result<Truth, WireError> {
        let truth: Truth = postcard::from_bytes(bytes).map_err(|e| WireError::Malformed(e.to_string()))?;
        if truth.schema != SCHEMA_VERSION {
            return Err(WireError::Schema { theirs: truth.schema });
        }
        let e = &truth.ego;
        finite(&[truth.time_s, e.speed_mps, e.accel_mps2, e.yaw_rate_radps, e.steer_rad], "truth.ego")?;
        finite(&e.pose, "truth.ego.pose")?;
        finite(&e.velocity, "truth.ego.velocity")?;
        finite(&e.footprint, "truth.ego.footprint")?;
        for o in &truth.objects {
            let [cx, cy] = o.centre;
            let [ax, ay] = o.axis;
            let [vx, vy] = o.velocity;
            finite(&[cx, cy, ax, ay, vx, vy, o.half_length_m, o.half_width_m, o.accel_mps2], "truth.objects")?;
        }
        Ok(truth)
    }
}

/// Acceleration of object `o` of `world`'s scene: its traffic vehicle's, 0 for a pedestrian.
fn traffic_accel_mps2(o: &SceneObject, world: &World) -> f64 {
    let traffic = o.kind != ObjectKind::Pedestrian && (o.id as usize) < world.traffic.len();
    if traffic { world.traffic.accel_mps2(o.id as usize) } else { 0.0 }
}

impl TruthObject {
    /// Scene object `o` with its acceleration along the heading.
    fn new(o: &SceneObject, accel_mps2: f64) -> Self {
        TruthObject {
            id: o.id,
            kind: o.kind,
            centre: [o.obb.centre.x, o.obb.centre.y],
            axis: [o.obb.axis.x, o.obb.axis.y],
            half_length_m: o.obb.half_length_m,
            half_width_m: o.obb.half_width_m,
            velocity: [o.velocity.x, o.velocity.y],
            accel_mps2,
        }
    }
}

impl From<&TruthObject> for DetectedObject {
    /// The object as the ground-truth object list carries it: exact, with its truth id.
    fn from(o: &TruthObject) -> Self {
        let axis = Vec2::new(o.axis[0], o.axis[1]);
        DetectedObject {
            id: o.id,
            kind: o.kind,
            pose: Pose::new(o.centre[0], o.centre[1], axis.y.atan2(axis.x)),
            footprint: Footprint::new(2.0 * o.half_length_m, 2.0 * o.half_width_m),
            velocity: Vec2::new(o.velocity[0], o.velocity[1]),
            accel_mps2: o.accel_mps2,
        }
    }
}

impl From<&TruthObject> for SceneObject {
    fn from(o: &TruthObject) -> Self {
        SceneObject {
            id: o.id,
            obb: Obb {
                centre: Vec2::new(o.centre[0], o.centre[1]),
                axis: Vec2::new(o.axis[0], o.axis[1]),
                half_length_m: o.half_length_m,
                half_width_m: o.half_width_m,
            },
            velocity: Vec2::new(o.velocity[0], o.velocity[1]),
            kind: o.kind,
        }
    }
}

impl Reply {
    /// The answer to `step` with the controls of a driving participant.
    pub fn step(participant: &str, step: u64, controls: Option<Controls>) -> Reply {
        let controls = controls.map(|c| [c.steer_rad, c.throttle, c.brake]);
        Reply::Step { participant: participant.to_owned(), step, controls }
    }

    /// Encodes the reply.
    pub fn encode(&self) -> Vec<u8> {
        postcard::to_allocvec(self).expect("a reply serialises")
    }

    /// Decodes and validates a reply (controls finite and in range).
    pub fn decode(bytes: &[u8]) -> Result<Reply, WireError> {
        let reply: Reply = postcard::from_bytes(bytes).map_err(|e| WireError::Malformed(e.to_string()))?;
        match &reply {
            Reply::Join { schema, .. } if *schema != SCHEMA_VERSION => {
                return Err(WireError::Schema { theirs: *schema });
            }
            Reply::Step { controls: Some(c), .. } => finite(c, "reply.controls")?,
            _ => {}
        }
        Ok(reply)
    }
}

/// The controls of a step reply.
pub fn controls_of(values: [f64; 3]) -> Controls {
    let [steer_rad, throttle, brake] = values;
    Controls { steer_rad, throttle, brake }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::scenario::{ScenarioKind, build, sample};

    #[test]
    fn truth_round_trips_bit_for_bit_including_negative_zero() {
        let mut world = build(&sample(1, ScenarioKind::CutIn, 0));
        world.scene_objects();
        let mut truth = Truth::of(&world, 7, 3);
        truth.ego.accel_mps2 = -0.0;
        let mut bytes = Vec::new();
        truth.encode_into(&mut bytes);
        let back = Truth::decode(&bytes).expect("decodes");
        assert_eq!(back, truth);
        assert!(back.ego.accel_mps2.is_sign_negative(), "−0.0 stays −0.0");
        let objects: Vec<SceneObject> = back.objects.iter().map(SceneObject::from).collect();
        assert_eq!(objects, world.scene(), "the scene, exactly");
    }

    #[test]
    fn bad_messages_are_refused_by_reason() {
        assert!(matches!(Truth::decode(b"\xff\xff"), Err(WireError::Malformed(_))));
        let mut world = build(&sample(1, ScenarioKind::CutIn, 0));
        world.scene_objects();
        let mut truth = Truth::of(&world, 7, 0);
        truth.schema = SCHEMA_VERSION + 1;
        let mut bytes = Vec::new();
        truth.encode_into(&mut bytes);
        assert_eq!(Truth::decode(&bytes), Err(WireError::Schema { theirs: SCHEMA_VERSION + 1 }));
        truth.schema = SCHEMA_VERSION;
        truth.time_s = f64::NAN;
        truth.encode_into(&mut bytes);
        assert!(matches!(Truth::decode(&bytes), Err(WireError::NotFinite(_))));
        let reply = Reply::Step { participant: "v0".into(), step: 1, controls: Some([0.0, f64::INFINITY, 0.0]) };
        assert!(matches!(Reply::decode(&reply.encode()), Err(WireError::NotFinite(_))));
        let join = Reply::Join { schema: 0, participant: "v0".into(), scene: 1, describe: String::new() };
        assert_eq!(Reply::decode(&join.encode()), Err(WireError::Schema { theirs: 0 }));
    }
}
