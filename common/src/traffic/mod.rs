//! Surrounding traffic: IDM car following, MOBIL lane changes, scripted manoeuvres, pedestrians, parked vehicles.
//!
//! [`Traffic`] holds N vehicles as a structure of arrays in lane (Frenet) coordinates: lane,
//! arc length s, lateral offset d, speed, acceleration. One [`Traffic::step`]:
//! 1. computes every vehicle's next state from the current one only (leaders, IDM, the
//!    manoeuvre, MOBIL, first-order actuator lag, |a| ≤ μ·g, ballistic integration, the lateral
//!    lane-change profile, the world pose) into a scratch buffer — in parallel chunks with
//!    [`Traffic::step_threads`], bit-identical for any thread count;
//! 2. commits it, keeps the per-lane lists sorted by s (insertion sort on an almost sorted
//!    array: O(n)), and
//! 3. checks collisions between neighbours in those lists (broad phase) with [`Obb::overlaps`].
//!
//! Leaders and lanes: a vehicle belongs to its lane's list and, when its footprint reaches
//! over a lane boundary (a lane change, a parked car on the line), also to the neighbour
//! lane's list, so vehicles there see it as a leader and collisions across the line are found.
//! A lane change switches the vehicle's lane to the target at its start (its lateral offset is
//! then measured from the target lane) and blends the offset to 0 with the quintic profile of
//! [`manoeuvre`]; heading = lane heading + atan2(ḋ, max(v, 1 m/s)). External agents (the ego,
//! pedestrians) whose footprint overlaps a lane strip are leaders for that lane.
//!
//! Closed lanes ([`crate::road::Lane::is_closed`], e.g. [`crate::road::Road::ring`]) wrap s. On an open
//! lane a vehicle that passes the lane's end is deactivated: it keeps its last pose, is no
//! longer stepped, and is no longer a leader or collision partner. Lane s coordinates of
//! neighbouring lanes are related by the ratio of lane lengths (exact for straight roads and
//! rings, a metre-level approximation after a bend).

#[cfg(test)]
mod behaviour_tests;
mod bench;
mod collision;
mod crossing;
mod idm;
mod kernel;
mod lane_index;
mod manoeuvre;
mod mobil;
mod pedestrian;
mod signal;
mod sim;
mod state;
mod track;

pub use bench::bench_traffic;
pub use idm::{IdmParams, MIN_GAP_M, idm_accel};
pub use manoeuvre::{MOBIL_LANE_CHANGE_S, Manoeuvre};
pub use mobil::{MobilAccels, MobilParams, mobil_incentive, mobil_safe, mobil_should_change};
pub use pedestrian::PedestrianWalk;
pub use signal::FixedTimeSignal;

use crate::geometry::{Footprint, Obb, Pose, Vec2};
pub use crate::road::LaneId;
use idm::IdmCoeffs;
use kernel::ExtEntry;
use lane_index::{LaneIndex, LaneInfo};
use state::{Kinematics, Next};
use std::collections::HashMap;

/// Time constant τ of the first-order lag between commanded and actual acceleration
/// (ȧ = (a_cmd − a)/τ); 0.2 s is typical of a brake/throttle actuator.
pub const ACTUATOR_LAG_S: f64 = 0.2;

/// Standard gravity for the μ·g acceleration limit.
pub const GRAVITY_MPS2: f64 = 9.81;

/// How a vehicle enters the traffic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleInit {
    pub lane: LaneId,
    pub s_m: f64,
    /// Static lateral offset from the lane centre (positive left), e.g. a car parked on the line.
    pub d_m: f64,
    pub speed_mps: f64,
    pub footprint: Footprint,
    pub idm: IdmParams,
    /// MOBIL lane changes (only while the manoeuvre is [`Manoeuvre::None`]).
    pub lane_changes: bool,
    pub manoeuvre: Manoeuvre,
}

/// Something traffic must not hit that it does not move itself: the ego, pedestrians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExternalAgent {
    pub pose: Pose,
    pub velocity: Vec2,
    pub footprint: Footprint,
}

/// N traffic vehicles as a structure of arrays (see the module docs for one step).
#[derive(Debug, Clone, Default)]
pub struct Traffic {
    /// Per-step state (lane, s, d, ḋ, v, a, world pose, segment hint, lane change, lane-line
    /// intrusion bits: 1 left, 2 right), and the buffer the next step is written to.
    cur: Kinematics,
    nxt: Kinematics,
    // Vehicle properties.
    half_length_m: Vec<f64>,
    half_width_m: Vec<f64>,
    radius_m: Vec<f64>,
    idm_idx: Vec<u32>,
    lane_changes: Vec<bool>,
    manoeuvre: Vec<Manoeuvre>,
    // Shared tables.
    idm_params: Vec<IdmParams>,
    idm_coeffs: Vec<IdmCoeffs>,
    idm_lookup: HashMap<[u64; 6], u32>,
    mobil: MobilParams,
    max_radius_m: f64,
    // Per-step machinery, reused so a step allocates nothing.
    lanes: Vec<LaneInfo>,
    lanes_check: Vec<LaneInfo>,
    /// Every lane's centreline segments, laid out for the pose update.
    segments: Vec<Vec<track::Segment>>,
    /// Per lane: it meets a lane other than itself and its neighbours (see [`crossing`]).
    crossing: Vec<bool>,
    /// Scratch for the crossing-lane collision sweep: (x, vehicle).
    crossing_scratch: Vec<(f64, u32)>,
    index: LaneIndex,
    changed: Vec<u32>,
    ext_lists: Vec<Vec<ExtEntry>>,
    collisions: Vec<(u32, u32)>,
    step_count: u64,
    lane_changes_started: u64,
    /// Override of the smallest per-thread chunk (0: the default); tests force threads on.
    min_vehicles_per_task: usize,
    /// False after `add`: the next step (or `prepare`) rebuilds poses and lane lists.
    ready: bool,
}

impl Traffic {
    /// Empty traffic with the default MOBIL parameters.
    pub fn new() -> Self {
        Self::default()
    }

    /// Empty traffic with room for `n` vehicles.
    pub fn with_capacity(n: usize) -> Self {
        let mut t = Self::new();
        t.reserve(n);
        t
    }

    fn reserve(&mut self, n: usize) {
        macro_rules! reserve_all { ($($v:ident),*) => { $(self.$v.reserve(n);)* } }
        reserve_all!(cur, nxt, half_length_m, half_width_m, radius_m, idm_idx, lane_changes, manoeuvre);
    }

    /// Sets the MOBIL parameters of every vehicle.
    pub fn set_mobil(&mut self, params: MobilParams) {
        self.mobil = params;
    }

    /// Adds a vehicle and returns its index. Its pose is valid after the next
    /// [`Traffic::step`] or [`Traffic::prepare`]; a vehicle on a lane the road lacks is inactive.
    pub fn add(&mut self, v: VehicleInit) -> usize {
        let key = [
            v.idm.desired_speed_mps.to_bits(),
            v.idm.time_headway_s.to_bits(),
            v.idm.min_gap_m.to_bits(),
            v.idm.max_accel_mps2.to_bits(),
            v.idm.comfort_decel_mps2.to_bits(),
            v.idm.exponent.to_bits(),
        ];
        let next_idx = self.idm_params.len() as u32;
        let idx = *self.idm_lookup.entry(key).or_insert(next_idx);
        if idx == next_idx {
            self.idm_params.push(v.idm);
            self.idm_coeffs.push(IdmCoeffs::new(&v.idm));
        }
        let parked = v.manoeuvre == Manoeuvre::Parked;
        let hl = 0.5 * v.footprint.length_m.max(0.0);
        let hw = 0.5 * v.footprint.width_m.max(0.0);
        self.cur.push(&Next {
            lane: u32::try_from(v.lane).unwrap_or(u32::MAX),
            s_m: if v.s_m.is_finite() { v.s_m } else { 0.0 },
            d_m: if v.d_m.is_finite() { v.d_m } else { 0.0 },
            speed_mps: if parked || !v.speed_mps.is_finite() { 0.0 } else { v.speed_mps.max(0.0) },
            active: true,
            cos_h: 1.0,
            ..Next::default()
        });
        self.half_length_m.push(hl);
        self.half_width_m.push(hw);
        self.radius_m.push(hl.hypot(hw));
        self.max_radius_m = self.max_radius_m.max(hl.hypot(hw));
        self.idm_idx.push(idx);
        self.lane_changes.push(v.lane_changes);
        self.manoeuvre.push(v.manoeuvre);
        self.ready = false;
        self.cur.s_m.len() - 1
    }

    /// Number of vehicles (active or not).
    pub fn len(&self) -> usize {
        self.cur.s_m.len()
    }

    /// True when there are no vehicles.
    pub fn is_empty(&self) -> bool {
        self.cur.s_m.is_empty()
    }

    /// World pose of vehicle `i` (centre of its footprint).
    pub fn pose(&self, i: usize) -> Pose {
        Pose::new(self.cur.x_m[i], self.cur.y_m[i], self.cur.sin_h[i].atan2(self.cur.cos_h[i]))
    }

    /// World velocity of vehicle `i`: its speed along the heading plus the lateral rate.
    pub fn velocity(&self, i: usize) -> Vec2 {
        let v = self.cur.speed_mps[i];
        let w = self.cur.d_rate_mps[i];
        let speed = v.hypot(w);
        Vec2::new(self.cur.cos_h[i], self.cur.sin_h[i]) * speed
    }

    /// Longitudinal speed of vehicle `i`.
    pub fn speed_mps(&self, i: usize) -> f64 {
        self.cur.speed_mps[i]
    }

    /// Longitudinal acceleration of vehicle `i` after the last step.
    pub fn accel_mps2(&self, i: usize) -> f64 {
        self.cur.accel_mps2[i]
    }

    /// Footprint of vehicle `i`.
    pub fn footprint(&self, i: usize) -> Footprint {
        Footprint::new(2.0 * self.half_length_m[i], 2.0 * self.half_width_m[i])
    }

    /// Oriented box of vehicle `i`.
    pub fn obb(&self, i: usize) -> Obb {
        Obb {
            centre: Vec2::new(self.cur.x_m[i], self.cur.y_m[i]),
            axis: Vec2::new(self.cur.cos_h[i], self.cur.sin_h[i]),
            half_length_m: self.half_length_m[i],
            half_width_m: self.half_width_m[i],
        }
    }

    /// Lane of vehicle `i` (the target lane from the start of a lane change).
    pub fn lane(&self, i: usize) -> LaneId {
        self.cur.lane[i] as LaneId
    }

    /// Arc length of vehicle `i` along its lane.
    pub fn s_m(&self, i: usize) -> f64 {
        self.cur.s_m[i]
    }

    /// Lateral offset of vehicle `i` from its lane's centre (positive left).
    pub fn d_m(&self, i: usize) -> f64 {
        self.cur.d_m[i]
    }

    /// False once vehicle `i` has left the end of an open lane (or was put on a missing lane).
    pub fn is_active(&self, i: usize) -> bool {
        self.cur.active[i]
    }

    /// Takes vehicle `i` out of the run (a counterfactual: the same scene without it). Its index
    /// stays, so every other vehicle keeps its id; the lane lists are rebuilt by the next
    /// [`Traffic::prepare`] or step.
    pub fn withdraw(&mut self, i: usize) {
        self.cur.active[i] = false;
        self.ready = false;
    }

    /// True for a parked vehicle (a static obstacle).
    pub fn is_parked(&self, i: usize) -> bool {
        self.manoeuvre[i] == Manoeuvre::Parked
    }

    /// True while vehicle `i` is changing lanes.
    pub fn is_changing_lane(&self, i: usize) -> bool {
        self.cur.lane_change[i].active
    }

    /// Lane changes (MOBIL and scripted) started since the traffic was built.
    pub fn lane_changes_started(&self) -> u64 {
        self.lane_changes_started
    }

    /// Traffic–traffic pairs (lower index first, sorted) in contact after the last step.
    pub fn collisions(&self) -> &[(u32, u32)] {
        &self.collisions
    }
}
