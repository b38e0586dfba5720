//! The traffic benchmark world: dense multi-lane ring traffic that can run for ever.

use super::{IdmParams, Manoeuvre, Traffic, VehicleInit};
use crate::geometry::Footprint;
use crate::rng::Rng;
use crate::road::Road;

const BENCH_LANES: usize = 4;
const LANE_WIDTH_M: f64 = 3.5;
/// Road length per vehicle per lane: 25 veh/km/lane, dense but flowing highway traffic
/// (≈ 20 m/s on average with these IDM parameters, with MOBIL lane changes going on).
const SPACING_M: f64 = 40.0;

/// A 4-lane ring sized to 40 m per vehicle per lane with `vehicles` vehicles (10 % trucks),
/// desired speeds uniform in 22–36 m/s, MOBIL on; the same seed gives the same world.
pub fn bench_traffic(vehicles: usize, seed: u64) -> (Road, Traffic) {
    let per_lane = vehicles.div_ceil(BENCH_LANES).max(1);
    let min_circ = std::f64::consts::TAU * (BENCH_LANES as f64 * LANE_WIDTH_M + 30.0);
    let circumference_m = (per_lane as f64 * SPACING_M).max(min_circ);
    let road = Road::ring(BENCH_LANES, LANE_WIDTH_M, circumference_m, 36.0);
    let mut rng = Rng::new(seed);
    let mut traffic = Traffic::with_capacity(vehicles);
    for k in 0..vehicles {
        let lane = k % BENCH_LANES;
        let slot = k / BENCH_LANES;
        let lane_len = road.lanes[lane].length_m();
        let spacing = lane_len / per_lane as f64;
        let truck = rng.chance(0.1);
        let footprint = if truck { Footprint::new(12.0, 2.5) } else { Footprint::new(4.5, 1.8) };
        let desired = if truck { rng.uniform(22.0, 25.0) } else { rng.uniform(25.0, 36.0) };
        // Jitter within a quarter of the spacing keeps the initial gaps above a truck's length.
        let s_m = (slot as f64 + 0.5) * spacing + rng.uniform(-0.1, 0.1) * spacing;
        traffic.add(VehicleInit {
            lane,
            s_m,
            d_m: 0.0,
            speed_mps: 0.7 * desired,
            footprint,
            idm: IdmParams::treiber2000(desired),
            lane_changes: true,
            manoeuvre: Manoeuvre::None,
        });
    }
    traffic.prepare(&road);
    (road, traffic)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Release-mode throughput measurement (not a timed assertion):
    /// `cargo test --release -p risktwin-common --lib traffic::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn measure_vehicle_steps_per_second() {
        for vehicles in [1_000usize, 10_000] {
            for threads in [1usize, 2] {
                let setup = std::time::Instant::now();
                let (road, mut traffic) = bench_traffic(vehicles, 1);
                let setup_ms = setup.elapsed().as_secs_f64() * 1e3;
                let steps = if vehicles >= 10_000 { 300 } else { 1_000 };
                let dt = 0.1;
                for k in 0..50 {
                    traffic.step_threads(&road, k as f64 * dt, dt, &[], threads);
                }
                let start = std::time::Instant::now();
                let mut contacts = 0;
                for k in 50..50 + steps {
                    traffic.step_threads(&road, k as f64 * dt, dt, &[], threads);
                    contacts += traffic.collisions().len();
                }
                let secs = start.elapsed().as_secs_f64();
                let rate = (vehicles * steps) as f64 / secs;
                let mean_speed = (0..vehicles).map(|i| traffic.speed_mps(i)).sum::<f64>() / vehicles as f64;
                println!(
                    "vehicles {vehicles} threads {threads}: {:.1} M vehicle-steps/s ({:.1} ns/vehicle-step), \
                     contacts {contacts}, lane changes {}, mean speed {mean_speed:.1} m/s, setup {setup_ms:.1} ms",
                    rate / 1e6,
                    1e9 / rate,
                    traffic.lane_changes_started()
                );
            }
        }
    }

    #[test]
    fn bench_world_runs_without_crashes_and_stays_on_the_ring() {
        let (road, mut traffic) = bench_traffic(400, 7);
        let mut contacts = 0;
        for k in 0..600 {
            traffic.step(&road, k as f64 * 0.1, 0.1, &[]);
            contacts += traffic.collisions().len();
        }
        assert_eq!(contacts, 0, "IDM/MOBIL traffic must not crash");
        let changes = traffic.lane_changes_started();
        assert!(changes >= 10, "MOBIL should change some lanes: {changes}");
        for i in 0..traffic.len() {
            assert!(traffic.is_active(i));
            assert!(road.edge_distance_m(traffic.pose(i).position()) > 0.0, "vehicle {i} off the road");
        }
    }
}
