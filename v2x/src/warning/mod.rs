//! Cooperative hazard warnings in virtual time. A roadside unit (RSU) on a mast at the scene's
//! point of conflict perceives the scene with its own sensor; while it sees a hazard — a
//! pedestrian on the road, a vehicle standing in a lane — it broadcasts a DENM-like warning
//! (ETSI EN 302 637-3: the event's position and motion, repeated while it lasts) whose payload is
//! the perceived object, as a CPM (ETSI TS 103 324) would carry it. Each copy crosses the V2X
//! channel ([`super::link`]) to the ego from the distance between the mast and the ego.
//!
//! The ego fuses what it hears into what its own sensor perceives, as collective perception
//! does: a warned object it does not see itself becomes one more perceived object, moved on from
//! the moment the RSU saw it at the velocity it was seen with. Every policy — the reference
//! driver, a learned one — reads it from its [`DriverView`], so the observation's layout (and the
//! policy file's format) does not change, and a policy trained without warnings reacts to a
//! warned pedestrian as to one it sees. [`Heard`] keeps what was heard and fuses it; an edge
//! vehicle feeds it the cloud's hazard warnings ([`Warning::from_hazard`]) the same way.

use super::link::V2xChannel;
use super::loss::BurstState;
use risktwin_common::driver::{DriverView, Policy};
use risktwin_common::geometry::{Obb, Pose, Vec2};
use risktwin_common::rng::Rng;
use risktwin_common::sensor::{ObjectKind, PerceivedObject, SceneObject, Sensor, SensorParams};
use risktwin_common::telemetry::HazardWarning;
use risktwin_common::vehicle::Controls;
use risktwin_common::world::{DECISION_RATE_HZ, EGO_OBJECT_ID, World};

/// A vehicle slower than this is standing, m/s (above the RSU sensor's velocity noise, 0.3 m/s).
pub const STANDING_SPEED_MPS: f64 = 1.0;
/// How long the ego keeps a warned object after it last heard of it, s (its own tracks' memory).
pub const HEARD_MEMORY_S: f64 = 1.0;
/// The RSU's sensor range, m: a mast camera or radar over an intersection.
pub const RSU_RANGE_M: f64 = 150.0;
/// Where the RSU stands with no crosswalk and no standing vehicle in the scene: this far along
/// the ego's lane from its start, m.
pub const DEFAULT_SITE_AHEAD_M: f64 = 100.0;
/// Stream ids of the RSU sensor's and the channel's random numbers under the episode's seed.
const RSU_SENSOR_STREAM: u64 = 0x5253_5553;
const CHANNEL_STREAM: u64 = 0xDE_4E;

/// How warnings are made and sent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarningSetup {
    pub channel: V2xChannel,
    /// The mast's distance to the left of the ego lane's centre line, level with the point of
    /// conflict, m (how far the RSU stands from the hazard).
    pub rsu_offset_m: f64,
    /// DENM repetitions per second while a hazard lasts, Hz.
    pub repeat_hz: f64,
}

impl WarningSetup {
    pub fn check(&self) -> Result<(), String> {
        self.channel.check()?;
        if !(self.rsu_offset_m.is_finite() && self.rsu_offset_m >= 0.0) {
            return Err(format!("RSU offset {} m: need a finite distance ≥ 0", self.rsu_offset_m));
        }
        if !(self.repeat_hz.is_finite() && (0.1..=DECISION_RATE_HZ).contains(&self.repeat_hz)) {
            return Err(format!(
                "warning rate {} Hz: need 0.1 to {DECISION_RATE_HZ} Hz (one per step)",
                self.repeat_hz
            ));
        }
        Ok(())
    }
}

/// A warning: a hazard as the RSU perceived it, and when.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Warning {
    pub made_s: f64,
    pub object: PerceivedObject,
}

impl Warning {
    /// A cloud hazard warning as an edge vehicle hears it at `now_s` (its scene's time): the
    /// hazard vehicle, numbered `id` among the objects its ego perceives, at the pose, velocity
    /// and footprint the warning gives, taken as made at `now_s`: the path's few milliseconds
    /// are not moved on (the cloud's clock is not the scene's).
    pub fn from_hazard(w: &HazardWarning, id: u32, now_s: f64) -> Warning {
        let object = PerceivedObject {
            id,
            kind: ObjectKind::Vehicle,
            obb: Obb::new(w.hazard_pose, w.hazard_footprint),
            velocity: w.hazard_velocity,
            visible_fraction: 1.0,
        };
        Warning { made_s: now_s, object }
    }
}

/// What the warnings of one episode did.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct WarningCounts {
    /// Warnings the RSU broadcast (one per hazard per repetition).
    pub made: u64,
    /// Copies that reached the ego.
    pub arrived: u64,
    /// When the RSU first saw a hazard, s.
    pub first_hazard_s: Option<f64>,
    /// When the ego first heard of one, s.
    pub first_heard_s: Option<f64>,
}

/// Whether the RSU warns of `o`: a pedestrian (on the road whenever it is in the scene), or a
/// vehicle standing, whether parked or stopped in a lane. Not the ego. One rule for the sweep's
/// RSU and a scene's RSU participants.
pub fn is_hazard(o: &PerceivedObject) -> bool {
    o.id != EGO_OBJECT_ID && (o.kind == ObjectKind::Pedestrian || o.velocity.norm() < STANDING_SPEED_MPS)
}

/// The scene's point of conflict: the middle of its first crosswalk, else its first parked
/// vehicle, else [`DEFAULT_SITE_AHEAD_M`] along the ego's lane.
fn conflict_point(world: &World) -> Vec2 {
    if let Some(cw) = world.road.crosswalks.first() {
        return cw.start + Vec2::new(cw.heading_rad.cos(), cw.heading_rad.sin()) * (0.5 * cw.length_m);
    }
    let t = &world.traffic;
    if let Some(i) = (0..t.len()).find(|&i| t.is_parked(i)) {
        return t.obb(i).centre;
    }
    world.road.lane(world.route.lane).pose_at(world.route.start_s_m + DEFAULT_SITE_AHEAD_M, 0.0).position()
}

/// The RSU's mast: `offset_m` to the left of the ego lane's centre level with the point of
/// conflict, facing the road. Its sensor sees all around and over parked cars (it is mounted
/// high), with the ego's sensor noise and no dropout.
fn rsu_mast(world: &World, offset_m: f64) -> (Pose, Sensor) {
    let lane = world.road.lane(world.route.lane);
    let s_m = lane.project(conflict_point(world)).s_m;
    let pose = lane.pose_at(s_m, offset_m);
    let params = SensorParams {
        range_m: RSU_RANGE_M + offset_m,
        fov_rad: std::f64::consts::TAU,
        dropout_rate: 0.0,
        occlusion: false,
        mount_forward_m: 0.0,
        ..SensorParams::default()
    };
    (pose, Sensor::new(params).expect("an all-round sensor without dropout is valid"))
}

/// When an RSU repeats its warnings: at `repeat_hz`, the phase accumulating, so a rate whose
/// period is not a whole number of steps keeps its mean (a step sends at most one warning per
/// hazard).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RepeatClock {
    repeat_hz: f64,
    next_due_s: f64,
}

impl RepeatClock {
    pub fn new(repeat_hz: f64) -> RepeatClock {
        RepeatClock { repeat_hz, next_due_s: 0.0 }
    }

    /// Whether a repetition is due at `now_s` (then the next one is scheduled).
    pub fn due(&mut self, now_s: f64) -> bool {
        if now_s + 1e-9 < self.next_due_s {
            return false;
        }
        while now_s + 1e-9 >= self.next_due_s {
            self.next_due_s += 1.0 / self.repeat_hz;
        }
        true
    }
}

/// What the ego has heard of, and what its policy sees of it: the newest warning per object,
/// kept [`HEARD_MEMORY_S`] after it was last heard, fused into the policy's [`DriverView`] as
/// warned objects (those the ego does not perceive itself, moved on to the view's time at the
/// velocity they were seen with). The RSU's warnings here and the cloud's hazard warnings at an
/// edge vehicle (`edge::scene`) both go through it.
#[derive(Debug, Clone, Default)]
pub struct Heard {
    /// The newest warning heard per object, and when it was heard.
    heard: Vec<(f64, Warning)>,
    /// What the ego heard of and does not see itself, moved on to now.
    warned: Vec<PerceivedObject>,
}

impl Heard {
    /// `w` heard at `now_s`: kept unless what is held of its object was made later (of two made
    /// at the same time, the one heard last; the RSU makes one per object per step, so for it
    /// that never happens).
    pub fn hear(&mut self, now_s: f64, w: Warning) {
        match self.heard.iter_mut().find(|(_, h)| h.object.id == w.object.id) {
            Some(h) if h.1.made_s <= w.made_s => *h = (now_s, w),
            Some(_) => {}
            None => self.heard.push((now_s, w)),
        }
    }

    /// Forgets the objects last heard of more than [`HEARD_MEMORY_S`] before `now_s`.
    pub fn forget_old(&mut self, now_s: f64) {
        self.heard.retain(|(heard_s, _)| now_s - heard_s <= HEARD_MEMORY_S);
    }

    /// The heard objects `perceived` lacks, each moved on from when it was seen to `time_s` at
    /// the velocity it was seen with: a [`DriverView::warned`].
    pub fn warned(&mut self, time_s: f64, perceived: &[PerceivedObject]) -> &[PerceivedObject] {
        self.warned.clear();
        for (_, h) in &self.heard {
            if perceived.iter().all(|o| o.id != h.object.id) {
                let mut o = h.object;
                o.obb.centre += o.velocity * (time_s - h.made_s);
                self.warned.push(o);
            }
        }
        &self.warned
    }

    /// The objects held now.
    pub fn len(&self) -> usize {
        self.heard.len()
    }

    pub fn is_empty(&self) -> bool {
        self.heard.is_empty()
    }

    /// Forgets everything (a new episode: its clock starts over).
    pub fn clear(&mut self) {
        self.heard.clear();
        self.warned.clear();
    }

    /// `policy` acting on `view` with the warned objects added (see the type's doc).
    pub fn act(&mut self, view: &DriverView, policy: &mut dyn Policy) -> Controls {
        let warned = self.warned(view.time_s, view.perceived);
        policy.act(&DriverView { warned, ..*view })
    }
}

/// The RSU, the channel to the ego, and what the ego has heard.
pub struct Warnings {
    setup: WarningSetup,
    mast: Pose,
    sensor: Sensor,
    sensor_rng: Rng,
    channel_rng: Rng,
    burst: BurstState,
    repeat: RepeatClock,
    seen: Vec<PerceivedObject>,
    scratch: Vec<SceneObject>,
    /// Copies on their way: (arrives, warning).
    in_flight: Vec<(f64, Warning)>,
    heard: Heard,
    counts: WarningCounts,
}

impl Warnings {
    /// The RSU of `world` (at t = 0), its randomness derived from `seed`.
    pub fn new(world: &World, setup: WarningSetup, seed: u64) -> Warnings {
        let (mast, sensor) = rsu_mast(world, setup.rsu_offset_m);
        Warnings {
            setup,
            mast,
            sensor,
            sensor_rng: Rng::derive(seed, RSU_SENSOR_STREAM),
            channel_rng: Rng::derive(seed, CHANNEL_STREAM),
            burst: BurstState::default(),
            repeat: RepeatClock::new(setup.repeat_hz),
            seen: Vec::new(),
            scratch: Vec::new(),
            in_flight: Vec::new(),
            heard: Heard::default(),
            counts: WarningCounts::default(),
        }
    }

    /// Where the RSU stands.
    pub fn mast(&self) -> Pose {
        self.mast
    }

    pub fn counts(&self) -> WarningCounts {
        self.counts
    }

    /// One step of `world` with `policy` driving the ego: the RSU warns if a repetition is due,
    /// copies that have arrived are heard, and the policy acts on its perception fused with
    /// what it heard. Consumes the world's randomness exactly as [`World::step`] does.
    pub fn step(&mut self, world: &mut World, policy: &mut dyn Policy) -> risktwin_common::world::StepReport {
        let now_s = world.time_s;
        if self.repeat.due(now_s) {
            self.broadcast(world, now_s);
        }
        self.deliver(now_s);
        world.perceive();
        let controls = self.heard.act(&world.view(), policy);
        world.advance(controls)
    }

    fn broadcast(&mut self, world: &mut World, now_s: f64) {
        world.roadside_view(&mut self.sensor, self.mast, &mut self.sensor_rng, &mut self.scratch, &mut self.seen);
        let ego = world.ego.pose().position();
        let distance_m = (ego - self.mast.position()).norm();
        for object in self.seen.iter().filter(|o| is_hazard(o)) {
            self.counts.made += 1;
            self.counts.first_hazard_s.get_or_insert(now_s);
            let latency_ms = self.setup.channel.latency_ms(&mut self.channel_rng);
            if self.setup.channel.receives(distance_m, &mut self.burst, &mut self.channel_rng) {
                self.in_flight.push((now_s + latency_ms / 1e3, Warning { made_s: now_s, object: *object }));
            }
        }
    }

    fn deliver(&mut self, now_s: f64) {
        let (heard, counts) = (&mut self.heard, &mut self.counts);
        self.in_flight.retain(|&(arrives_s, w)| {
            if arrives_s > now_s + 1e-9 {
                return true;
            }
            counts.arrived += 1;
            counts.first_heard_s.get_or_insert(now_s);
            heard.hear(now_s, w);
            false
        });
        heard.forget_old(now_s);
    }
}

#[cfg(test)]
mod tests;
