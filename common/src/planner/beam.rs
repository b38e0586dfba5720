//! Beam search over segments of motion primitives, each candidate driven on its own clone of
//! the world: the episode's dynamics, traffic and contact checks, step by step.

use super::PlannerParams;
use super::primitive::{Primitive, controls};
use crate::road::LaneId;
use crate::vehicle::dynamics::MU_MIN;
use crate::vehicle::{Controls, GRAVITY_MPS2};
use crate::world::World;
use std::collections::BTreeSet;

/// Below this speed the ego counts as stopped, m/s.
const STILL_MPS: f64 = 0.05;

/// The braking continuation's time limit stretches the constant-deceleration stopping time
/// v/(μ·g) by this factor (grip shared with cornering on a bend, the brake's build-up).
const STOP_TIME_MARGIN: f64 = 1.25;

/// Clean stops kept as fallbacks (see `Search::stops`).
const STOPS_KEPT: usize = 3;

/// How a stretch of driving ended; the last three are the episode's own ends (`episode::run`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stop {
    /// The stretch's steps are used up and the episode goes on.
    Running,
    /// The stretch's own end condition held (for the braking continuation: the ego has stood
    /// still for the hold time) and the episode goes on.
    Held,
    Completed,
    OutOfTime,
    Contact,
}

/// One way of driving on: its world, the lane it follows and the controls that led there.
#[derive(Debug, Clone)]
struct Node {
    world: World,
    lane: LaneId,
    controls: Vec<Controls>,
}

impl Node {
    /// `world` at its start, on the lane the ego is in.
    fn start(world: &World) -> Self {
        let lane = world.road.locate_heading(world.ego.pose().position(), world.ego.pose().heading_rad).lane;
        Node { world: world.clone(), lane, controls: Vec::new() }
    }
}

/// How good a node is: first how many of its two continuations (the same primitive held on,
/// full braking to a stop) end without contact; then, for a safe node, the route progress of the
/// better safe continuation, m; for an unsafe one, the time its better continuation survived, s.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Score {
    safe_continuations: u8,
    value: f64,
}

impl Score {
    /// The ranking: more clean continuations first, then the higher value (a total order, so a
    /// NaN value cannot make the sort depend on the input order).
    fn rank(&self, other: &Score) -> std::cmp::Ordering {
        self.safe_continuations.cmp(&other.safe_continuations).then(self.value.total_cmp(&other.value))
    }
}

/// How a continuation driven on from a node ended.
#[derive(Debug, Clone, Copy)]
struct Continuation {
    clean: bool,
    progress_m: f64,
    end_time_s: f64,
}

impl Continuation {
    fn of(clean: bool, world: &World) -> Self {
        Continuation { clean, progress_m: world.progress_m(), end_time_s: world.time_s }
    }
}

/// What one segment of the search gave: a clean drive's controls, or the next beam.
enum Expansion {
    Completed(Vec<Controls>),
    Beam(Vec<Node>),
}

/// What the search found: the controls of a clean drive, or of its best attempt.
#[derive(Debug, Clone)]
pub struct Found {
    pub controls: Vec<Controls>,
    pub sim_steps: u64,
}

/// The search with its counters and its best attempt so far.
struct Search<'p> {
    params: &'p PlannerParams,
    primitives: Vec<Primitive>,
    speed_cap_mps: f64,
    segment_steps: usize,
    /// Closer than this to any object counts as contact in this search, m.
    clearance_m: f64,
    /// The lowest friction anywhere on the road (the braking continuation's time limit).
    brake_mu: f64,
    sim_steps: u64,
    /// The best failed drive: (out of time rather than contact, time survived s, progress m).
    best_attempt: Option<((bool, f64, f64), Vec<Controls>)>,
    /// The furthest clean stops the braking checks found, furthest first (at most
    /// [`STOPS_KEPT`], at least 1 m apart): each a node standing still after its hold, with
    /// the controls that led there. Where no drive completes, they are braked on to the
    /// episode's end and offered as attempts, so that a clean stop is not lost when every
    /// branch of the beam later dies.
    stops: Vec<(f64, Node)>,
}

impl<'p> Search<'p> {
    /// A search from `world` (at its start) that keeps `clearance_m`.
    fn new(world: &World, params: &'p PlannerParams, clearance_m: f64) -> Self {
        let route_limit_mps = world.road.lane(world.route.lane).speed_limit_mps;
        let road = &world.road;
        Search {
            params,
            primitives: Primitive::lattice(&params.accels_mps2),
            speed_cap_mps: route_limit_mps.max(world.desired_speed_mps),
            segment_steps: ((params.segment_s / world.dt_s).round() as usize).max(1),
            clearance_m,
            brake_mu: road.friction_patches.iter().map(|p| p.mu).fold(road.friction_default, f64::min).max(MU_MIN),
            sim_steps: 0,
            best_attempt: None,
            stops: Vec::new(),
        }
    }

    /// Drives `world` at most `steps` steps on `lane` at `accel_mps2`, stopping at the episode's
    /// end or once `done` holds; records the controls when asked.
    fn drive(
        &mut self,
        world: &mut World,
        lane: LaneId,
        accel_mps2: f64,
        steps: usize,
        mut record: Option<&mut Vec<Controls>>,
        done: &mut dyn FnMut(&World) -> bool,
    ) -> Stop {
        for _ in 0..steps {
            let c = controls(world, lane, accel_mps2, self.speed_cap_mps);
            if let Some(r) = record.as_deref_mut() {
                r.push(c);
            }
            let contacts = world.advance(c).contacts;
            self.sim_steps += 1;
            if contacts.collision || contacts.offroad || contacts.min_distance_m < self.clearance_m {
                return Stop::Contact;
            }
            if world.finished() {
                return if world.progress_m() >= world.route.length_m { Stop::Completed } else { Stop::OutOfTime };
            }
            if done(world) {
                return Stop::Held;
            }
        }
        Stop::Running
    }

    /// The longest the braking continuation from `world` runs, s: the stop from the ego's speed
    /// at the road's lowest friction, v/(μ·g) stretched by [`STOP_TIME_MARGIN`], plus the brake's
    /// lag and the hold time, at most `stop_check_max_s`.
    fn stop_check_s(&self, world: &World) -> f64 {
        let ego = &world.ego;
        let decel_mps2 = (self.brake_mu * GRAVITY_MPS2).min(ego.params.brake_decel_max_mps2);
        let stopping_s = STOP_TIME_MARGIN * ego.state.speed_mps.max(0.0) / decel_mps2 + ego.params.accel_lag_s;
        (stopping_s + self.params.stop_hold_s).min(self.params.stop_check_max_s)
    }

    /// Full braking on the node's lane until the ego has stood still for the hold time. Clean
    /// only if that happened without contact (or the episode ended first without contact): a
    /// check whose time is up while the ego still moves, or has not stood still long enough,
    /// proves no safe stop.
    fn stop_check(&mut self, node: &Node) -> Continuation {
        let mut w = node.world.clone();
        let hold_steps = ((self.params.stop_hold_s / w.dt_s).round() as usize).max(1);
        let mut still = 0;
        let mut until_held = |w: &World| {
            still = if w.ego.state.speed_mps <= STILL_MPS { still + 1 } else { 0 };
            still >= hold_steps
        };
        let steps = (self.stop_check_s(&w) / w.dt_s).ceil() as usize;
        let brake = -node.world.ego.params.brake_decel_max_mps2;
        let mut braking = Vec::new();
        let stop = self.drive(&mut w, node.lane, brake, steps, Some(&mut braking), &mut until_held);
        let continuation = Continuation::of(matches!(stop, Stop::Held | Stop::OutOfTime | Stop::Completed), &w);
        if stop == Stop::Held {
            self.keep_stop(node, w, braking);
        }
        continuation
    }

    /// Keeps a clean stop (`world`, reached from `node` with `braking`) if it is among the
    /// furthest so far and not within 1 m of one kept.
    fn keep_stop(&mut self, node: &Node, world: World, braking: Vec<Controls>) {
        let progress_m = world.progress_m();
        let at = self.stops.iter().position(|(p, _)| progress_m > *p).unwrap_or(self.stops.len());
        if at >= STOPS_KEPT || self.stops.iter().any(|(p, _)| (p - progress_m).abs() < 1.0) {
            return;
        }
        let controls = [node.controls.as_slice(), braking.as_slice()].concat();
        self.stops.insert(at, (progress_m, Node { world, lane: node.lane, controls }));
        self.stops.truncate(STOPS_KEPT);
    }

    /// Brakes `node` in its lane to the episode's end: the drive's controls if that completes
    /// the route, else how it ended (and the drive is offered as an attempt).
    fn brake_to_end(&mut self, mut node: Node) -> Result<Vec<Controls>, Stop> {
        let brake = -node.world.ego.params.brake_decel_max_mps2;
        let steps = ((node.world.horizon_s - node.world.time_s) / node.world.dt_s).ceil() as usize + 1;
        let lane = node.lane;
        match self.drive(&mut node.world, lane, brake, steps, Some(&mut node.controls), &mut |_| false) {
            Stop::Completed => Ok(node.controls),
            stop => {
                self.offer_attempt(&node, stop);
                Err(stop)
            }
        }
    }

    /// The same primitive held on for the lookahead (a horizon, not a proof: still driving
    /// without contact when it is up counts as clean).
    fn hold_check(&mut self, node: &Node, accel_mps2: f64) -> Continuation {
        let mut w = node.world.clone();
        let steps = (self.params.lookahead_s / w.dt_s).round() as usize;
        let stop = self.drive(&mut w, node.lane, accel_mps2, steps, None, &mut |_| false);
        Continuation::of(stop != Stop::Contact, &w)
    }

    /// Scores a node reached with a primitive of `accel_mps2` (see [`Score`]).
    fn score(&mut self, node: &Node, accel_mps2: f64) -> Score {
        let both = [self.hold_check(node, accel_mps2), self.stop_check(node)];
        let clean: Vec<f64> = both.iter().filter(|c| c.clean).map(|c| c.progress_m).collect();
        match clean.iter().copied().reduce(f64::max) {
            Some(progress_m) => Score { safe_continuations: clean.len() as u8, value: progress_m },
            None => {
                let survived_s = both.iter().map(|c| c.end_time_s).fold(f64::NEG_INFINITY, f64::max);
                Score { safe_continuations: 0, value: survived_s - node.world.time_s }
            }
        }
    }

    /// Keeps `node` as the best failed drive if it got further than the best so far.
    fn offer_attempt(&mut self, node: &Node, stop: Stop) {
        let key = (stop == Stop::OutOfTime, node.world.time_s, node.world.progress_m());
        if self.best_attempt.as_ref().is_none_or(|(k, _)| key > *k) {
            self.best_attempt = Some((key, node.controls.clone()));
        }
    }

    /// Every primitive from every node for one segment: the first clean finish, else the next beam.
    fn expand(&mut self, beam: &[Node]) -> Expansion {
        let mut children: Vec<(Score, Node)> = Vec::new();
        for node in beam {
            for k in 0..self.primitives.len() {
                let prim = self.primitives[k];
                let Some(lane) = prim.lane_from(&node.world.road, node.lane) else { continue };
                let mut child = node.clone();
                child.lane = lane;
                let stop = self.drive(
                    &mut child.world,
                    lane,
                    prim.accel_mps2,
                    self.segment_steps,
                    Some(&mut child.controls),
                    &mut |_| false,
                );
                match stop {
                    Stop::Completed => return Expansion::Completed(child.controls),
                    Stop::Contact | Stop::OutOfTime => self.offer_attempt(&child, stop),
                    Stop::Running | Stop::Held => {
                        let score = self.score(&child, prim.accel_mps2);
                        children.push((score, child));
                    }
                }
            }
        }
        // Best first; the stable sort keeps the expansion order among equals (deterministic).
        children.sort_by(|a, b| b.0.rank(&a.0));
        // Near-duplicates (same lane, speed and progress rounded to the same 0.5 m/s and 0.5 m
        // bucket) waste the beam; the first (best) of each is kept.
        let mut seen = BTreeSet::new();
        children.retain(|(_, c)| {
            let w = &c.world;
            seen.insert((c.lane, (w.ego.state.speed_mps / 0.5).round() as i64, (w.progress_m() / 0.5).round() as i64))
        });
        // The best node of every lane first, so that the beam does not commit to one lane while
        // another is still open; then the best of the rest.
        let mut lanes = BTreeSet::new();
        let (mut next, rest): (Vec<_>, Vec<_>) = children.into_iter().partition(|(_, c)| lanes.insert(c.lane));
        next.truncate(self.params.beam_width);
        let room = self.params.beam_width - next.len();
        next.extend(rest.into_iter().take(room));
        Expansion::Beam(next.into_iter().map(|(_, c)| c).collect())
    }
}

/// Searches for a clean drive from `world` (at its start) that keeps `clearance_m` from every
/// object; returns its controls, or those of the best attempt (out of time rather than
/// contact, then the longest and furthest drive).
pub fn search(world: &World, params: &PlannerParams, clearance_m: f64) -> Found {
    let mut s = Search::new(world, params, clearance_m);
    let mut beam = vec![Node::start(world)];
    while !beam.is_empty() && s.sim_steps < params.max_sim_steps {
        match s.expand(&beam) {
            Expansion::Beam(next) => beam = next,
            Expansion::Completed(controls) => return Found { controls, sim_steps: s.sim_steps },
        }
    }
    // Out of budget: the best node still on its way brakes in its lane to the episode's end.
    if let Some(node) = beam.into_iter().next()
        && let Ok(controls) = s.brake_to_end(node)
    {
        return Found { controls, sim_steps: s.sim_steps };
    }
    // The clean stops found on the way, furthest first, stand still to the episode's end; the
    // first that stays clean (out of time, not contact) is the best of them.
    for (_, node) in std::mem::take(&mut s.stops) {
        match s.brake_to_end(node) {
            Ok(controls) => return Found { controls, sim_steps: s.sim_steps },
            Err(Stop::OutOfTime) => break,
            Err(_) => {}
        }
    }
    let controls = s.best_attempt.map(|(_, c)| c).unwrap_or_default();
    Found { controls, sim_steps: s.sim_steps }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::road::Road;
    use crate::scenario::cast::{EGO_START_S_M, LANE_WIDTH_M};
    use crate::sensor::{Sensor, SensorParams};
    use crate::traffic::Traffic;
    use crate::vehicle::{ModelKind, Vehicle, VehicleParams};
    use crate::world::Route;

    /// An empty straight road of friction `mu`, the ego at 30 m/s, a long route and horizon.
    fn icy_world(mu: f64) -> World {
        let mut road = Road::straight(1, LANE_WIDTH_M, 3000.0, 36.0);
        road.friction_default = mu;
        let start = road.lane(0).pose_at(EGO_START_S_M, 0.0);
        let ego = Vehicle::new(VehicleParams::bmw_320i(), ModelKind::SingleTrack, start, 30.0);
        let route = Route { lane: 0, start_s_m: EGO_START_S_M, length_m: 2500.0 };
        let sensor = Sensor::new(SensorParams::default()).expect("default sensor parameters are valid");
        World::new(road, ego, Traffic::new(), Vec::new(), sensor, route, 30.0, 90.0, 1)
    }

    #[test]
    fn a_stop_counts_only_once_the_ego_has_stood_still_and_the_check_lasts_as_long_as_the_friction_needs() {
        let world = icy_world(0.1);
        let params = PlannerParams::default();
        let mut search = Search::new(&world, &params, 0.0);
        assert_eq!(search.brake_mu, 0.1);
        // 30 m/s at μ = 0.1: about 31 s to stop, far beyond a fixed 10 s.
        let limit_s = search.stop_check_s(&world);
        assert!(limit_s > 30.0 / (0.1 * GRAVITY_MPS2) + params.stop_hold_s && limit_s < 45.0, "{limit_s}");
        let stop = search.stop_check(&Node::start(&world));
        assert!(stop.clean, "{stop:?}");
        assert!(stop.end_time_s > 30.0 && stop.end_time_s < limit_s, "{stop:?}");
        // A check whose time runs out while the ego still moves proves no safe stop.
        let short = PlannerParams { stop_check_max_s: 10.0, ..PlannerParams::default() };
        let stop = Search::new(&world, &short, 0.0).stop_check(&Node::start(&world));
        assert!(!stop.clean, "{stop:?}");
        // On dry asphalt the limit is short and the stop clean.
        let dry = icy_world(0.9);
        let mut search = Search::new(&dry, &params, 0.0);
        assert!(search.stop_check_s(&dry) < 7.0);
        assert!(search.stop_check(&Node::start(&dry)).clean);
    }
}
