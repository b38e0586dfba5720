//! The achievable floor: a privileged planner that tells, per scenario, whether a drive exists
//! that completes the route without collision or leaving the road.
//!
//! The planner knows everything — true states, and the other agents' future, which it obtains
//! by simulating them — and searches over the twin's own dynamics: candidate drives are run on
//! clones of the scenario's [`World`], advanced with ego controls at the episode's own step
//! ([`crate::world::STEP_S`]), so a drive it finds is a drive of the real episode. It is checked
//! as one: the found controls are replayed through [`episode::run`] (perception, dynamics,
//! traffic, contacts and metrics exactly as every evaluated policy is measured), and the verdict
//! is that episode's `success`.
//!
//! The search ([`beam`]) is a beam search over segments of motion primitives ([`primitive`]):
//! every `segment_s` each node of the beam is extended by every primitive (an acceleration held
//! on the current lane or a neighbour), and each extension is scored by two continuations driven
//! on: the same primitive held for `lookahead_s`, and full braking to a stop. Extensions rank
//! by how many of the two continuations stay clean (two before one before none), then by the
//! route progress the better clean one reaches (by the time survived when neither is clean).
//! It is deterministic: no random numbers, a stable order.
//!
//! `not found` is not a proof that no clean drive exists: a search can miss one (the primitives
//! are coarse, the beam narrow, the budget finite). Over a set of scenarios the avoidable share
//! is therefore a lower bound of what a policy can achieve, and the planner's collision rate an
//! upper bound of the collision floor.

mod beam;
mod primitive;

pub use primitive::{LaneShift, Primitive};

use crate::driver::{DriverView, Policy};
use crate::episode;
use crate::metrics::{Ending, EpisodeMetrics, RewardWeights};
use crate::scenario::{ScenarioSpec, build};
use crate::vehicle::Controls;
use crate::world::World;
use serde::{Deserialize, Serialize};

/// The knobs of the search.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerParams {
    /// Nodes kept after each segment.
    pub beam_width: usize,
    /// How long one primitive is held before the next choice, s.
    pub segment_s: f64,
    /// How long a primitive is held on to score it, s.
    pub lookahead_s: f64,
    /// The cap of the braking continuation's time limit, s. The limit itself is the stop from
    /// the ego's speed at the road's lowest friction (v/(μ·g) with a margin, plus the hold time):
    /// on the most slippery scenario roads (μ down to 0.1) a stop from 30 m/s takes about 30 s.
    /// The continuation also ends with the episode.
    pub stop_check_max_s: f64,
    /// How long the ego must then stand still for the stop to count, s (a pedestrian may
    /// still walk into a car that has stopped). A braking continuation counts as clean only
    /// once the ego has stood still that long without contact (or the episode ended first).
    pub stop_hold_s: f64,
    /// The accelerations of the primitives, m/s², each on the lane, its left and its right
    /// neighbour; the pedals coast above the route's speed limit (or the desired speed).
    pub accels_mps2: Vec<f64>,
    /// Simulated steps after which the search gives up (bounds its cost).
    pub max_sim_steps: u64,
    /// The gap to every object the first search keeps, m; a second search without it runs only
    /// where the first found no clean drive (with perfect knowledge, a drive that passes
    /// centimetres from a pedestrian is clean but no policy with a real sensor could repeat it).
    pub clearance_m: f64,
}

impl Default for PlannerParams {
    fn default() -> Self {
        Self {
            beam_width: 3,
            segment_s: 0.5,
            lookahead_s: 3.0,
            stop_check_max_s: 60.0,
            stop_hold_s: 1.0,
            accels_mps2: vec![-11.0, -5.0, -2.0, 0.0, 1.5, 3.0],
            max_sim_steps: 2_000_000,
            clearance_m: 1.0,
        }
    }
}

/// Whether a clean drive was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// A drive that completes the route without collision or leaving the road exists: the
    /// planner drove it.
    Avoidable,
    /// The planner found none; its best attempt is reported (not a proof that none exists).
    NotFound,
}

/// What the planner found for one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOutcome {
    pub verdict: Verdict,
    /// The planner's drive — the clean one, or its best attempt — as `episode::run` measures it.
    pub metrics: EpisodeMetrics,
    /// Steps simulated by the search (its cost; the replay not counted).
    pub sim_steps: u64,
    /// The ego controls of that drive, one per step.
    pub controls: Vec<Controls>,
}

/// Plays back a fixed control sequence, whatever it sees (coasting straight after its end).
struct Playback<'a> {
    controls: &'a [Controls],
    next: usize,
}

impl Policy for Playback<'_> {
    fn act(&mut self, _view: &DriverView) -> Controls {
        let c = self.controls.get(self.next).copied().unwrap_or_default();
        self.next += 1;
        c
    }
}

/// The planner on a scenario, with the default search.
pub fn plan(spec: &ScenarioSpec) -> PlanOutcome {
    plan_world(&build(spec), &PlannerParams::default())
}

/// The planner on a world at its start (a scenario's, or one built by hand).
pub fn plan_world(world: &World, params: &PlannerParams) -> PlanOutcome {
    let first = attempt(world, params, params.clearance_m);
    if first.verdict == Verdict::Avoidable || params.clearance_m <= 0.0 {
        return first;
    }
    better_of(first, attempt(world, params, 0.0))
}

/// The outcome of the second search (without the margin) where it found a clean drive; where
/// neither did, the better replayed attempt — out of time before contact, then further along
/// the route, the first (which kept the margin) on a tie. Its cost is that of both searches.
fn better_of(first: PlanOutcome, second: PlanOutcome) -> PlanOutcome {
    let sim_steps = first.sim_steps + second.sim_steps;
    let second_better = attempt_rank(&second.metrics) > attempt_rank(&first.metrics);
    let mut best = if second.verdict == Verdict::Avoidable || second_better { second } else { first };
    best.sim_steps = sim_steps;
    best
}

/// How good a failed drive is: ended out of time rather than in a collision or off the road,
/// then its route completion.
fn attempt_rank(m: &EpisodeMetrics) -> (bool, f64) {
    (m.ending() == Ending::OutOfTime, m.route_completion)
}

/// One search keeping `clearance_m`, its drive replayed and measured as an episode.
fn attempt(world: &World, params: &PlannerParams, clearance_m: f64) -> PlanOutcome {
    let found = beam::search(world, params, clearance_m);
    let mut replay = world.clone();
    let mut playback = Playback { controls: &found.controls, next: 0 };
    let metrics = episode::run(&mut replay, &mut playback, &RewardWeights::default()).metrics;
    let verdict = if metrics.success { Verdict::Avoidable } else { Verdict::NotFound };
    PlanOutcome { verdict, metrics, sim_steps: found.sim_steps, controls: found.controls }
}

#[cfg(test)]
mod tests;
