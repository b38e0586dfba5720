//! Behaviour of whole traffic steps: car following, stopping, manoeuvres, MOBIL, collisions,
//! ring wrap and thread-count independence.

use super::*;
use crate::road::Road;

const CAR: Footprint = Footprint::new(4.5, 1.8);

fn car(lane: LaneId, s_m: f64, speed_mps: f64, desired_mps: f64) -> VehicleInit {
    VehicleInit {
        lane,
        s_m,
        d_m: 0.0,
        speed_mps,
        footprint: CAR,
        idm: IdmParams::treiber2000(desired_mps),
        lane_changes: false,
        manoeuvre: Manoeuvre::None,
    }
}

fn parked(lane: LaneId, s_m: f64) -> VehicleInit {
    VehicleInit { manoeuvre: Manoeuvre::Parked, ..car(lane, s_m, 0.0, 0.0) }
}

/// Runs `steps` steps of `dt` from t = 0 with external agents given per time.
fn run(road: &Road, t: &mut Traffic, dt: f64, steps: usize, ext: impl Fn(f64) -> Vec<ExternalAgent>) -> usize {
    let mut contacts = 0;
    for k in 0..steps {
        let time = k as f64 * dt;
        t.step(road, time, dt, &ext(time));
        contacts += t.collisions().len();
    }
    contacts
}

#[test]
fn idm_settles_at_the_published_equilibrium_gap() {
    // Leader: an external agent at constant v = 20 m/s. Treiber et al. (2000), Table I
    // parameters with v0 = 120 km/h: s_e(20) = (2 + 20·1.6)/√(1 − (20/33.3)⁴) = 36.44 m.
    let road = Road::straight(1, 3.5, 12_000.0, 40.0);
    let mut t = Traffic::new();
    t.add(car(0, 0.0, 15.0, 120.0 / 3.6));
    let v = 20.0;
    let leader = |time: f64| {
        vec![ExternalAgent { pose: Pose::new(80.0 + v * time, 0.0, 0.0), velocity: Vec2::new(v, 0.0), footprint: CAR }]
    };
    let dt = 0.05;
    let steps = 6000; // 300 s
    assert_eq!(run(&road, &mut t, dt, steps, leader), 0);
    let end = steps as f64 * dt;
    let gap = (80.0 + v * end) - t.pose(0).x_m - CAR.length_m;
    let expected = IdmParams::default().equilibrium_gap_m(v);
    assert!((expected - 36.44).abs() < 0.01, "s_e {expected}");
    assert!((gap - expected).abs() < 0.05, "gap {gap} vs s_e {expected}");
    assert!((t.speed_mps(0) - v).abs() < 1e-3);
}

#[test]
fn stops_before_a_stopped_obstacle_from_highway_speeds() {
    for v0 in [10.0, 20.0, 30.0, 36.0] {
        let road = Road::straight(1, 3.5, 2_000.0, 40.0);
        let mut t = Traffic::new();
        t.add(car(0, 0.0, v0, v0));
        t.add(parked(0, 300.0));
        assert_eq!(run(&road, &mut t, 0.05, 1600, |_| vec![]), 0, "v0 {v0}");
        let gap = t.pose(1).x_m - t.pose(0).x_m - CAR.length_m;
        assert_eq!(t.speed_mps(0), 0.0, "v0 {v0}");
        // IDM comes to rest near its jam distance s0 = 2 m (the actuator lag costs a few cm).
        assert!(gap > 1.8 && gap < 2.05, "v0 {v0}: gap {gap}");
    }
}

#[test]
fn stops_for_a_pedestrian_on_the_crosswalk() {
    let road = Road::crossing(3.5, 300.0, 250.0, 120.0, 13.9);
    let mut t = Traffic::new();
    t.add(car(0, 40.0, 13.9, 13.9));
    // A pedestrian standing in lane 0 at the crosswalk.
    let ped = |_: f64| {
        vec![ExternalAgent {
            pose: Pose::new(120.0, 0.0, FRAC_PI_2),
            velocity: Vec2::zeros(),
            footprint: Footprint::new(0.6, 0.6),
        }]
    };
    run(&road, &mut t, 0.05, 800, ped);
    let front = t.pose(0).x_m + 0.5 * CAR.length_m;
    assert_eq!(t.speed_mps(0), 0.0);
    assert!(front < 120.0 - 0.3 - 1.5, "front {front}");
}

#[test]
fn a_car_parked_over_the_line_blocks_the_next_lane() {
    let road = Road::straight(2, 3.5, 2_000.0, 40.0);
    let mut t = Traffic::new();
    // Parked in lane 0 with its left side 0.45 m into lane 1 (1.3 + 0.9 − 1.75).
    t.add(VehicleInit { d_m: 1.3, ..parked(0, 300.0) });
    t.add(car(1, 0.0, 20.0, 20.0));
    assert_eq!(run(&road, &mut t, 0.05, 1200, |_| vec![]), 0);
    assert_eq!(t.speed_mps(1), 0.0, "stops behind the intruding car");
    assert!(t.pose(1).x_m < 300.0 - CAR.length_m - 1.5);
    // The same car parked inside its lane does not bother lane 1.
    let mut t = Traffic::new();
    t.add(VehicleInit { d_m: 0.5, ..parked(0, 300.0) });
    t.add(car(1, 0.0, 20.0, 20.0));
    assert_eq!(run(&road, &mut t, 0.05, 1200, |_| vec![]), 0);
    assert!(t.pose(1).x_m > 400.0);
}

#[test]
fn pedestrian_walk_stops_traffic_while_on_the_crosswalk() {
    let road = Road::crossing(3.5, 300.0, 250.0, 120.0, 13.9);
    let walk = PedestrianWalk {
        start: Vec2::new(120.0, -3.0),
        heading_rad: FRAC_PI_2,
        speed_mps: 0.5, // in lane 0 (|y| < 1.75 + 0.3) from 1.9 s to 10.1 s
        start_time_s: 0.0,
        path_length_m: 13.5,
        radius_m: 0.3,
    };
    let mut t = Traffic::new();
    t.add(car(0, 60.0, 13.9, 13.9));
    let (mut min_speed, mut min_clearance) = (f64::INFINITY, f64::INFINITY);
    for k in 0..600 {
        let time = k as f64 * 0.05;
        let agents: Vec<ExternalAgent> = walk.agent_at(time).into_iter().collect();
        t.step(&road, time, 0.05, &agents);
        if let Some(a) = agents.first() {
            min_clearance = min_clearance.min(t.obb(0).distance_to(&Obb::new(a.pose, a.footprint)));
        }
        if time < 10.1 {
            min_speed = min_speed.min(t.speed_mps(0));
        }
    }
    // It (all but) stopped while the pedestrian was in its lane — IDM approaches standstill
    // asymptotically — kept about s0 = 2 m away, then drove on.
    assert!(min_speed < 0.1, "min speed {min_speed}");
    assert!(min_clearance > 1.5, "clearance {min_clearance}");
    assert!(t.pose(0).x_m > 130.0 && t.speed_mps(0) > 5.0, "x {}", t.pose(0).x_m);
}

#[test]
fn cut_in_follows_its_timing() {
    let road = Road::straight(2, 3.5, 1_000.0, 30.0);
    let mut t = Traffic::new();
    let cut = Manoeuvre::CutIn { start_time_s: 2.0, duration_s: 4.0, target_lane: 0 };
    t.add(VehicleInit { manoeuvre: cut, ..car(1, 50.0, 20.0, 20.0) });
    let dt = 0.125; // exact in binary: the sample times are exact
    let mut y_at = Vec::new();
    for k in 0..64 {
        t.step(&road, k as f64 * dt, dt, &[]);
        let time = (k + 1) as f64 * dt;
        if [2.0, 4.0, 6.0, 8.0].contains(&time) {
            y_at.push((t.pose(0).y_m, t.pose(0).heading_rad, t.lane(0)));
        }
    }
    assert!((y_at[0].0 - 3.5).abs() < 1e-9 && y_at[0].2 == 1, "start {:?}", y_at[0]);
    assert!((y_at[1].0 - 1.75).abs() < 1e-9 && y_at[1].2 == 0, "mid {:?}", y_at[1]);
    // Mid-change heading = atan2(ḋ, v), ḋ = −3.5·(15/8)/4 m/s.
    let expected = (-3.5 * 1.875 / 4.0f64).atan2(20.0);
    assert!((y_at[1].1 - expected).abs() < 1e-9, "heading {} vs {expected}", y_at[1].1);
    assert!(y_at[2].0.abs() < 1e-9 && y_at[2].1.abs() < 1e-12, "end {:?}", y_at[2]);
    assert!(y_at[3].0.abs() < 1e-12 && !t.is_changing_lane(0));
}

#[test]
fn braking_lead_decelerates_at_the_given_rate_and_caps_at_mu_g() {
    for (decel, mu, expected) in [(4.0, 0.9, 4.0), (12.0, 0.9, 0.9 * GRAVITY_MPS2), (6.0, 0.3, 0.3 * GRAVITY_MPS2)] {
        let road = Road::straight(1, 3.5, 2_000.0, 40.0).with_friction_patch(0.0, 2_000.0, mu);
        let mut t = Traffic::new();
        t.add(VehicleInit {
            manoeuvre: Manoeuvre::Brake { start_time_s: 1.0, decel_mps2: decel },
            ..car(0, 10.0, 30.0, 30.0)
        });
        let dt = 0.05;
        // 1.5 s after the start the actuator lag (τ = 0.2 s) has settled to e^−7.5.
        run(&road, &mut t, dt, 50, |_| vec![]);
        let a = t.accel_mps2(0);
        assert!((a + expected).abs() < 0.01 * expected, "decel {decel} μ {mu}: a {a}");
        assert!(a >= -mu * GRAVITY_MPS2 - 1e-12);
        run(&road, &mut t, dt, 400, |_| vec![]);
        assert_eq!(t.speed_mps(0), 0.0, "brakes to a standstill");
    }
}

#[test]
fn mobil_overtakes_a_slow_leader_only_when_the_lane_is_free() {
    let setup = |blocked: bool| {
        let road = Road::straight(2, 3.5, 3_000.0, 40.0);
        let mut t = Traffic::new();
        t.add(car(0, 100.0, 10.0, 10.0)); // slow leader
        t.add(VehicleInit { lane_changes: true, ..car(0, 60.0, 20.0, 30.0) });
        if blocked {
            // A dense platoon alongside, no gap anywhere near.
            for k in 0..16 {
                t.add(car(1, 0.0 + 7.0 * k as f64, 20.0, 20.0));
            }
        }
        (road, t)
    };
    let (road, mut free) = setup(false);
    run(&road, &mut free, 0.1, 25, |_| vec![]);
    assert_eq!(free.lane(1), 1, "overtakes into the free lane");
    let (road, mut blocked) = setup(true);
    run(&road, &mut blocked, 0.1, 25, |_| vec![]);
    assert_eq!(blocked.lane(1), 0, "stays behind when the lane is blocked");
    // The free overtaker completes the change without contact.
    assert_eq!(run(&road, &mut free, 0.1, 100, |_| vec![]), 0);
    assert!(!free.is_changing_lane(1) && free.pose(1).y_m == 3.5);
}

#[test]
fn swerve_reveals_a_stopped_car_without_hitting_it() {
    let road = Road::straight(2, 3.5, 2_000.0, 40.0);
    let mut t = Traffic::new();
    let swerve = Manoeuvre::Swerve { trigger_gap_m: 40.0, duration_s: 3.0, target_lane: 1 };
    t.add(VehicleInit { manoeuvre: swerve, footprint: Footprint::new(12.0, 2.5), ..car(0, 0.0, 20.0, 20.0) });
    t.add(parked(0, 400.0));
    assert_eq!(run(&road, &mut t, 0.05, 800, |_| vec![]), 0);
    assert_eq!(t.lane(0), 1);
    assert!(t.pose(0).x_m > 420.0, "drove past: {}", t.pose(0).x_m);
}

#[test]
fn collision_detection_finds_planted_overlaps_and_no_false_positives() {
    let road = Road::straight(3, 3.5, 3_000.0, 30.0);
    let mut t = Traffic::new();
    // Well separated: three lanes of parked cars every 10 m, trucks among them.
    for k in 0..300 {
        let mut v = parked(k % 3, 10.0 * (k / 3) as f64 + 5.0);
        if k % 7 == 0 {
            v.footprint = Footprint::new(5.4, 2.5);
        }
        t.add(v);
    }
    t.prepare(&road);
    assert!(t.collisions().is_empty(), "{:?}", t.collisions());
    // Planted: a car 3 m behind another in lane 0, and a car straddling the line next to one in lane 1.
    let a = t.add(parked(0, 2_000.0)) as u32;
    let b = t.add(parked(0, 2_003.0)) as u32;
    let c = t.add(VehicleInit { d_m: 2.0, ..parked(0, 2_100.0) }) as u32;
    let d = t.add(parked(1, 2_101.0)) as u32;
    t.step(&road, 0.0, 0.1, &[]);
    assert_eq!(t.collisions(), &[(a, b), (c, d)]);
}

#[test]
fn collisions_are_found_across_a_junction() {
    let road = Road::crossing(3.5, 300.0, 120.0, 100.0, 13.9);
    let mut t = Traffic::new();
    // Eastbound lane 0 and northbound lane 3 (x = 121.75) meet at (121.75, 0).
    let east = t.add(car(0, 121.0, 10.0, 10.0)) as u32;
    let north = t.add(car(3, 60.5, 10.0, 10.0)) as u32;
    t.add(car(1, 20.0, 10.0, 10.0)); // far away
    t.prepare(&road);
    assert_eq!(t.collisions(), &[(east, north)]);
}

#[test]
fn thread_count_does_not_change_a_bit() {
    let states: Vec<Vec<u64>> = [1usize, 2, 3]
        .iter()
        .map(|&threads| {
            let (road, mut t) = bench_traffic(2_001, 3);
            t.min_vehicles_per_task = 16; // really split 2,001 vehicles over the threads
            let mut collisions = 0;
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a thread pool");
            pool.install(|| {
                for k in 0..300 {
                    t.step_threads(&road, k as f64 * 0.1, 0.1, &[], threads);
                    collisions += t.collisions().len() as u64;
                }
            });
            let mut bits = vec![collisions];
            for i in 0..t.len() {
                let p = t.pose(i);
                bits.extend([p.x_m, p.y_m, p.heading_rad, t.speed_mps(i), t.accel_mps2(i), t.d_m(i)].map(f64::to_bits));
                bits.push(t.lane(i) as u64);
            }
            bits
        })
        .collect();
    assert_eq!(states[0], states[1]);
    assert_eq!(states[0], states[2]);
}

#[test]
fn ring_wrap_keeps_vehicles_on_the_road() {
    let (road, mut t) = bench_traffic(40, 11); // a ~300 m ring: every car laps it many times
    let circumference = road.lanes[0].length_m();
    let mut travelled = vec![0.0; t.len()];
    for k in 0..1200 {
        t.step(&road, k as f64 * 0.1, 0.1, &[]);
        for (i, d) in travelled.iter_mut().enumerate() {
            *d += t.speed_mps(i) * 0.1;
        }
        assert!(t.collisions().is_empty(), "step {k}: {:?}", t.collisions());
    }
    assert!(travelled.iter().all(|&d| d > 2.0 * circumference), "every car laps twice");
    for i in 0..t.len() {
        let lane = &road.lanes[t.lane(i)];
        assert!(t.is_active(i) && t.s_m(i) >= 0.0 && t.s_m(i) < lane.length_m());
        assert!(road.edge_distance_m(t.pose(i).position()) > 0.5, "vehicle {i} off the road");
    }
}

#[test]
fn bad_input_deactivates_instead_of_panicking() {
    let mut road = Road::straight(2, 3.5, 100.0, 30.0);
    road.lanes[1].centre.truncate(1); // a degenerate lane
    road.lanes[1].cum_s.truncate(1);
    let mut t = Traffic::new();
    t.add(car(7, 10.0, 10.0, 10.0)); // no such lane
    t.add(car(1, 10.0, 10.0, 10.0)); // degenerate lane
    let cut = Manoeuvre::CutIn { start_time_s: 0.0, duration_s: 2.0, target_lane: 9 };
    t.add(VehicleInit { manoeuvre: cut, ..car(0, 10.0, 10.0, 10.0) });
    let walker = ExternalAgent { pose: Pose::new(50.0, 0.0, 0.0), velocity: Vec2::zeros(), footprint: CAR };
    run(&road, &mut t, 0.1, 10, |_| vec![walker]);
    assert!(!t.is_active(0) && !t.is_active(1) && t.is_active(2));
    assert_eq!(t.lane(2), 0);
}

#[test]
fn leaving_an_open_lane_deactivates() {
    let road = Road::straight(1, 3.5, 100.0, 30.0);
    let mut t = Traffic::new();
    t.add(car(0, 90.0, 20.0, 20.0));
    run(&road, &mut t, 0.1, 10, |_| vec![]);
    assert!(!t.is_active(0));
}

use std::f64::consts::FRAC_PI_2;
