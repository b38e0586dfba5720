//! A reproducible risk-field workload for `risktwin bench risk-field`: a four-lane road, dense
//! traffic around the ego and a pre-sized grid following it. The CLI owns the timing loop; this
//! module only builds the scene and evaluates one field per call.

use super::field::{EgoKinematics, FieldObject, RiskFieldParams};
use super::raster::{GridEvaluator, RiskGrid, RoadRaster};
use crate::geometry::{Footprint, Obb, Pose, Vec2};
use crate::rng::Rng;
use crate::road::Road;

/// Grid resolution of the benchmark (m): fine enough to resolve a 1.8 m wide car in 4 cells.
pub const BENCH_RESOLUTION_M: f64 = 0.5;
/// Largest grid side the scene builds (cells): keeps the grid and the raster (which must reach
/// half a grid beyond the road) within `raster::MAX_CELLS` whatever the CLI asks for.
pub const BENCH_MAX_SIDE: usize = 2048;
/// Time step by which agents move between evaluations (s).
const BENCH_DT_S: f64 = 0.05;
const LANES: usize = 4;
const LANE_WIDTH_M: f64 = 3.5;
const ROAD_LENGTH_M: f64 = 600.0;
/// The ego drives between these x; past the end everything shifts back by their difference.
const EGO_X_RANGE_M: (f64, f64) = (200.0, 400.0);

/// Everything one benchmark evaluation needs, built once.
#[derive(Debug, Clone)]
pub struct BenchScene {
    pub road: Road,
    pub raster: RoadRaster,
    pub evaluator: GridEvaluator,
    pub grid: RiskGrid,
    pub ego: EgoKinematics,
    pub objects: Vec<FieldObject>,
    /// Footprint of every object (the object list is rebuilt from it after each move).
    footprints: Vec<Footprint>,
    poses: Vec<Pose>,
}

/// A scene with `agents` cars within ±60 m of the ego on a four-lane road and a
/// `cols`×`rows` grid at [`BENCH_RESOLUTION_M`] centred on the ego. Each side is clamped to
/// [1, [`BENCH_MAX_SIDE`]].
pub fn bench_scene(agents: usize, cols: usize, rows: usize, seed: u64) -> BenchScene {
    let road = Road::straight(LANES, LANE_WIDTH_M, ROAD_LENGTH_M, 30.0);
    let params = RiskFieldParams::default();
    let (cols, rows) = (cols.clamp(1, BENCH_MAX_SIDE), rows.clamp(1, BENCH_MAX_SIDE));
    let half = 0.5 * BENCH_RESOLUTION_M * cols.max(rows) as f64;
    // The ego stays within EGO_X_RANGE_M (it wraps back) and the raster covers that range plus
    // the grid's reach, so the copy path is always taken.
    let raster = RoadRaster::new(&road, &params, BENCH_RESOLUTION_M, half + 2.0)
        .expect("bench raster: fixed, valid resolution and size");
    let mut rng = Rng::new(seed);
    let ego = EgoKinematics {
        pose: Pose::new(300.0, LANE_WIDTH_M, 0.0),
        velocity: Vec2::new(25.0, 0.0),
        lateral_accel_mps2: 0.5,
        jerk_mps3: 0.3,
        footprint: Footprint::new(4.6, 1.9),
    };
    let mut poses = Vec::with_capacity(agents);
    let mut footprints = Vec::with_capacity(agents);
    for _ in 0..agents {
        let lane = rng.below(LANES as u64) as f64;
        let x = 300.0 + rng.uniform(-60.0, 60.0);
        let y = lane * LANE_WIDTH_M + rng.uniform(-0.5, 0.5);
        poses.push(Pose::new(x, y, rng.uniform(-0.1, 0.1)));
        footprints.push(Footprint::new(rng.uniform(4.0, 5.5), rng.uniform(1.7, 2.0)));
    }
    let mut objects = Vec::with_capacity(agents);
    for (pose, fp) in poses.iter().zip(&footprints) {
        let speed = 20.0 + 10.0 * rng.unit();
        objects.push(FieldObject { obb: Obb::new(*pose, *fp), velocity: pose.forward() * speed });
    }
    let origin = raster.snap_origin(
        ego.pose.position() - Vec2::new(0.5 * BENCH_RESOLUTION_M * cols as f64, 0.5 * BENCH_RESOLUTION_M * rows as f64),
    );
    let grid = RiskGrid::new(origin, BENCH_RESOLUTION_M, cols, rows).expect("bench grid: valid shape");
    BenchScene { road, raster, evaluator: GridEvaluator::new(params), grid, ego, objects, footprints, poses }
}

impl BenchScene {
    /// Moves the ego and every agent by one time step, re-snaps the grid to the ego and
    /// evaluates one full field into `self.grid`. Returns the grid's maximum (so a timing loop
    /// has a value to consume).
    pub fn evaluate(&mut self) -> f32 {
        let ego_step = self.ego.velocity * BENCH_DT_S;
        self.ego.pose.x_m += ego_step.x;
        self.ego.pose.y_m += ego_step.y;
        let wrap = if self.ego.pose.x_m > EGO_X_RANGE_M.1 { EGO_X_RANGE_M.1 - EGO_X_RANGE_M.0 } else { 0.0 };
        self.ego.pose.x_m -= wrap;
        for ((o, pose), fp) in self.objects.iter_mut().zip(&mut self.poses).zip(&self.footprints) {
            pose.x_m += o.velocity.x * BENCH_DT_S - wrap;
            pose.y_m += o.velocity.y * BENCH_DT_S;
            // Keep the traffic around the ego: an agent more than 60 m away re-enters opposite.
            let rel = pose.x_m - self.ego.pose.x_m;
            if rel.abs() > 60.0 {
                pose.x_m -= 120.0 * rel.signum();
            }
            o.obb = Obb::new(*pose, *fp);
        }
        let (cols, rows) = (self.grid.cols as f64, self.grid.rows as f64);
        let corner = self.ego.pose.position() - 0.5 * BENCH_RESOLUTION_M * Vec2::new(cols, rows);
        self.grid.origin_m = self.raster.snap_origin(corner);
        self.evaluator.fill(&mut self.grid, &self.raster, &self.road, &self.objects, &self.ego);
        self.grid.cells.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The brute-force field: the exact point evaluation at every cell centre.
    fn exact_grid(scene: &BenchScene) -> Vec<f64> {
        let p = scene.evaluator.params();
        let g = &scene.grid;
        let mut out = Vec::with_capacity(g.cols * g.rows);
        for r in 0..g.rows {
            for c in 0..g.cols {
                out.push(p.evaluate_point(&scene.road, &scene.objects, &scene.ego, g.cell_centre(c, r)));
            }
        }
        out
    }

    #[test]
    fn fast_field_matches_brute_force_within_the_bound() {
        let mut scene = bench_scene(24, 96, 64, 7);
        scene.evaluate();
        let exact = exact_grid(&scene);
        let max_value = exact.iter().copied().fold(0.0, f64::max);
        let bound = scene.evaluator.error_bound(&scene.objects, &scene.ego, max_value);
        let worst = scene.grid.cells.iter().zip(&exact).map(|(f, e)| (*f as f64 - e).abs()).fold(0.0, f64::max);
        assert!(worst <= bound, "max |fast − exact| = {worst} > bound {bound}");
        // The bound is tight enough to matter: a few thousandths of a field that peaks above 1.
        assert!(bound < 5e-3 && max_value > 1.0, "bound {bound}, max {max_value}");
    }

    #[test]
    fn grid_off_the_lattice_and_outside_the_raster_is_still_exact() {
        let mut scene = bench_scene(8, 40, 40, 3);
        scene.evaluate();
        // Off the lattice by a third of a cell, and partly beyond the raster's end (x < 0).
        scene.grid.origin_m = Vec2::new(-5.0 + BENCH_RESOLUTION_M / 3.0, -8.0);
        let (raster, road, objects, ego) = (&scene.raster, &scene.road, &scene.objects, &scene.ego);
        scene.evaluator.fill(&mut scene.grid, raster, road, objects, ego);
        let exact = exact_grid(&scene);
        let bound = scene.evaluator.error_bound(objects, ego, 10.0);
        let worst = scene.grid.cells.iter().zip(&exact).map(|(f, e)| (*f as f64 - e).abs()).fold(0.0, f64::max);
        assert!(worst <= bound, "{worst} > {bound}");
    }

    #[test]
    fn field_peaks_at_the_obstacle() {
        let road = Road::straight(3, 3.5, 300.0, 30.0);
        let params = RiskFieldParams::default();
        let raster = RoadRaster::new(&road, &params, 0.5, 10.0).expect("valid raster");
        let ego = EgoKinematics {
            pose: Pose::new(100.0, 3.5, 0.0),
            velocity: Vec2::new(20.0, 0.0),
            lateral_accel_mps2: 0.0,
            jerk_mps3: 0.0,
            footprint: Footprint::new(4.5, 1.8),
        };
        let obstacle = FieldObject {
            obb: Obb::new(Pose::new(130.0, 3.5, 0.3), Footprint::new(4.5, 1.8)),
            velocity: Vec2::zeros(),
        };
        let mut grid = RiskGrid::new(raster.snap_origin(Vec2::new(90.0, -4.0)), 0.5, 120, 30).expect("valid grid");
        let mut eval = GridEvaluator::new(params);
        eval.fill(&mut grid, &raster, &road, &[obstacle], &ego);
        let (c, r) = grid.argmax();
        let d = obstacle.obb.distance_to_point(grid.cell_centre(c, r));
        assert!(d <= 2.0 * 0.5, "argmax {d} m from the footprint");
        // Approaching raises the whole bump: the field in front of a car closing at 20 m/s.
        let before = grid.value_at(Vec2::new(125.0, 3.5)).expect("inside");
        let closing = FieldObject { velocity: Vec2::new(-20.0, 0.0), ..obstacle };
        eval.fill(&mut grid, &raster, &road, &[closing], &ego);
        let after = grid.value_at(Vec2::new(125.0, 3.5)).expect("inside");
        assert!(after > before + 0.1, "{after} vs {before}");
    }

    #[test]
    fn bench_grid_takes_the_raster_copy_path() {
        let mut scene = bench_scene(4, 256, 256, 9);
        for _ in 0..200 {
            scene.evaluate();
            let (ox, oy) = scene.raster.lattice_offset(&scene.grid, scene.evaluator.params()).expect("on the lattice");
            let r = scene.raster.grid();
            assert!(ox >= 0 && oy >= 0, "{ox} {oy}");
            assert!(ox as usize + scene.grid.cols <= r.cols && oy as usize + scene.grid.rows <= r.rows);
        }
    }

    #[test]
    fn raster_point_evaluation_matches_exact_away_from_lane_lines() {
        let scene = bench_scene(8, 32, 32, 2);
        let (p, road) = (scene.evaluator.params(), &scene.road);
        for k in 0..50 {
            // Lane centres ± 1 m, along the road: at least 0.75 m from any lane line.
            let at = Vec2::new(250.0 + 1.37 * k as f64, (k % 4) as f64 * LANE_WIDTH_M + (k % 3) as f64 - 1.0);
            let fast = scene.raster.evaluate_point(road, &scene.objects, &scene.ego, at);
            let exact = p.evaluate_point(road, &scene.objects, &scene.ego, at);
            // Bilinear error of the smooth static terms over a 0.5 m cell: curvature·h²/8.
            assert!((fast - exact).abs() < 0.02, "{at:?}: {fast} vs {exact}");
        }
        let poses = [scene.ego.pose, Pose::new(scene.ego.pose.x_m + 5.0, scene.ego.pose.y_m, 0.0)];
        let fast = scene.raster.evaluate_trajectory(road, &scene.objects, &scene.ego, &poses);
        let exact = p.evaluate_trajectory(road, &scene.objects, &scene.ego, &poses);
        assert!((fast - exact).abs() < 0.05, "{fast} vs {exact}");
    }

    #[test]
    fn repeated_fills_do_not_reallocate() {
        let mut scene = bench_scene(16, 64, 64, 1);
        scene.evaluate();
        let (cells, scratch) = (scene.grid.cells.as_ptr(), scene.grid.cells.capacity());
        for _ in 0..5 {
            scene.evaluate();
        }
        assert_eq!(scene.grid.cells.as_ptr(), cells);
        assert_eq!(scene.grid.cells.capacity(), scratch);
    }

    /// Throughput check, not a timed assertion: `cargo test --release -p risktwin-common --lib
    /// risk::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn print_fields_per_second() {
        let mut scene = bench_scene(64, 256, 256, 42);
        let mut acc = 0.0f32;
        for _ in 0..50 {
            acc += scene.evaluate();
        }
        let n = 2000;
        let start = std::time::Instant::now();
        for _ in 0..n {
            acc += scene.evaluate();
        }
        let secs = start.elapsed().as_secs_f64();
        println!(
            "risk field 64 agents 256x256: {:.0} fields/s ({:.1} µs/field) [{acc}]",
            n as f64 / secs,
            1e6 * secs / n as f64
        );
    }
}
