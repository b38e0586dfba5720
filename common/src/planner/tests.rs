use super::*;
use crate::env::benign_specs;
use crate::metrics::Ending;
use crate::road::Road;
use crate::scenario::ScenarioKind;
use crate::scenario::cast::{EGO, EGO_START_S_M, LANE_WIDTH_M, TRUCK};
use crate::sensor::{Sensor, SensorParams};
use crate::traffic::{IdmParams, Manoeuvre, Traffic, VehicleInit};
use crate::vehicle::{GRAVITY_MPS2, ModelKind, Vehicle, VehicleParams};
use crate::world::Route;

const SPEED_MPS: f64 = 30.0;

/// A two-lane straight road with a stopped truck in each lane, their rear bumpers `gap_m` ahead
/// of the ego's front bumper, and a route through them: the trucks leave 0.95 m per lane, less
/// than the ego's width, so nothing passes.
fn walled_world(gap_m: f64) -> World {
    let road = Road::straight(2, LANE_WIDTH_M, 600.0, 36.0);
    let mut traffic = Traffic::new();
    for lane in 0..2 {
        traffic.add(VehicleInit {
            lane,
            s_m: EGO_START_S_M + 0.5 * EGO.length_m + gap_m + 0.5 * TRUCK.length_m,
            d_m: 0.0,
            speed_mps: 0.0,
            footprint: TRUCK,
            idm: IdmParams::default(),
            lane_changes: false,
            manoeuvre: Manoeuvre::Parked,
        });
    }
    let start = road.lane(0).pose_at(EGO_START_S_M, 0.0);
    let ego = Vehicle::new(VehicleParams::bmw_320i(), ModelKind::SingleTrack, start, SPEED_MPS);
    let route = Route { lane: 0, start_s_m: EGO_START_S_M, length_m: 300.0 };
    let sensor = Sensor::new(SensorParams::default()).expect("default sensor parameters are valid");
    World::new(road, ego, traffic, Vec::new(), sensor, route, SPEED_MPS, 15.0, 1)
}

/// The shortest stop from `SPEED_MPS` on `world`'s road at full friction, m.
fn braking_distance_m(world: &World) -> f64 {
    SPEED_MPS * SPEED_MPS / (2.0 * world.road.friction_default * GRAVITY_MPS2)
}

#[test]
fn a_wall_closer_than_the_braking_distance_is_not_avoidable() {
    let world = walled_world(25.0);
    assert!(25.0 < braking_distance_m(&world), "the wall must lie inside the braking distance");
    let out = plan_world(&world, &PlannerParams::default());
    assert_eq!(out.verdict, Verdict::NotFound);
    assert_eq!(out.metrics.ending(), Ending::Collision);
    assert!(out.sim_steps > 0);
}

#[test]
fn a_wall_beyond_the_braking_distance_is_stopped_for_but_blocks_the_route() {
    let world = walled_world(90.0);
    assert!(90.0 > braking_distance_m(&world) + SPEED_MPS * 0.5, "the wall must lie beyond the braking distance");
    let out = plan_world(&world, &PlannerParams::default());
    // No collision-free way through, but a collision-free stop: the best attempt runs out of time.
    assert_eq!(out.verdict, Verdict::NotFound);
    assert_eq!(out.metrics.ending(), Ending::OutOfTime);
    assert!(out.metrics.min_distance_m > 0.0);
}

#[test]
fn a_clean_stop_seen_on_the_way_is_the_attempt_when_every_branch_dies() {
    // Only coasting primitives: every branch of the beam drives into the wall, but the braking
    // checks of the early nodes stop short of it; that stop is reported, not a collision.
    let world = walled_world(150.0);
    let params = PlannerParams { accels_mps2: vec![0.0], beam_width: 1, ..PlannerParams::default() };
    let out = plan_world(&world, &params);
    assert_eq!(out.verdict, Verdict::NotFound);
    assert_eq!(out.metrics.ending(), Ending::OutOfTime, "{:?}", out.metrics);
    assert!(out.metrics.min_distance_m >= params.clearance_m, "{:?}", out.metrics);
    assert_eq!(out.controls.len() as u64, out.metrics.steps);
}

#[test]
fn of_two_failed_searches_the_better_attempt_is_reported() {
    let outcome = |ending: Ending, route_completion: f64, sim_steps: u64| {
        let metrics = EpisodeMetrics {
            collision: ending == Ending::Collision,
            offroad: ending == Ending::Offroad,
            success: ending == Ending::Success,
            route_completion,
            ..EpisodeMetrics::default()
        };
        let verdict = if metrics.success { Verdict::Avoidable } else { Verdict::NotFound };
        PlanOutcome { verdict, metrics, sim_steps, controls: Vec::new() }
    };
    let pick = |a: PlanOutcome, b: PlanOutcome| {
        let best = better_of(a, b);
        (best.metrics.ending(), best.metrics.route_completion, best.sim_steps)
    };
    // Out of time beats contact, whichever search it came from and however far the contact got.
    let stopped = (Ending::OutOfTime, 0.3, 30);
    assert_eq!(pick(outcome(Ending::OutOfTime, 0.3, 10), outcome(Ending::Collision, 0.9, 20)), stopped);
    assert_eq!(pick(outcome(Ending::Offroad, 0.9, 10), outcome(Ending::OutOfTime, 0.3, 20)), stopped);
    // Then further progress; on a tie the first search's, which kept the margin.
    assert_eq!(
        pick(outcome(Ending::Collision, 0.6, 10), outcome(Ending::Offroad, 0.4, 20)),
        (Ending::Collision, 0.6, 30)
    );
    assert_eq!(
        pick(outcome(Ending::OutOfTime, 0.5, 10), outcome(Ending::OutOfTime, 0.5, 20)),
        (Ending::OutOfTime, 0.5, 30)
    );
    // A clean drive of the second search wins.
    assert_eq!(
        pick(outcome(Ending::OutOfTime, 0.9, 10), outcome(Ending::Success, 1.0, 20)),
        (Ending::Success, 1.0, 30)
    );
}

#[test]
fn finds_a_clean_drive_where_the_reference_driver_succeeds() {
    let spec = benign_specs(1, 5).into_iter().find(|s| s.kind == ScenarioKind::CutIn).expect("a benign cut-in");
    assert!(episode::evaluate(&spec).metrics.success, "the reference driver completes it");
    let out = plan(&spec);
    assert_eq!(out.verdict, Verdict::Avoidable, "{:?}", out.metrics);
    assert!(out.metrics.success && !out.metrics.collision && !out.metrics.offroad);
    assert_eq!(out.metrics.route_completion, 1.0);
    assert!(out.metrics.min_distance_m >= PlannerParams::default().clearance_m, "{:?}", out.metrics);
    // The controls are the drive: one per step of the replayed episode.
    assert_eq!(out.controls.len() as u64, out.metrics.steps);
}

#[test]
fn the_search_is_deterministic() {
    let spec = benign_specs(2, 2).into_iter().nth(1).expect("a benign spec");
    let (a, b) = (plan(&spec), plan(&spec));
    assert_eq!(a, b);
}
