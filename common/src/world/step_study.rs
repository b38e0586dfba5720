//! Evidence for the physics step (docs/method.md, "Physics step and decision rate"): the ego
//! model and the reference driver at world steps of 0.02, 0.05 and 0.1 s against a 5 ms
//! reference, over every scenario kind and three seeds. The driver decides once per step, so
//! the step is also the decision rate. Run with
//! `cargo test --release -p risktwin-common physics_step -- --nocapture` to see the table.

use super::STEP_S;
use crate::episode::{run_observed, with_reference_driver};
use crate::metrics::RewardWeights;
use crate::scenario::{ScenarioKind, check_feasible, sample};
use std::time::Instant;

/// The reference step, s: 10× finer than the world's.
const FINE_S: f64 = 0.005;
/// Steps compared against the reference, s.
const STEPS_S: [f64; 3] = [0.02, STEP_S, 0.1];
/// Seeds per scenario kind.
const SEEDS: u64 = 3;
/// Largest ego position error the chosen step may show against the reference over an episode,
/// m: well under a lane's half width, the scale at which outcomes could change. Not applied to
/// sensor-occlusion: its noisy, occluded sensor draws noise per frame, so another step is another
/// noise sequence and the driver's decisions (when to brake, where to go round) differ with it.
const MAX_POSITION_ERROR_M: f64 = 1.0;

/// One episode at one step: the ego's centre of gravity per step, the outcome and the wall time.
struct Trajectory {
    xy_m: Vec<(f64, f64)>,
    collision: bool,
    success: bool,
    wall_s: f64,
    simulated_s: f64,
}

fn drive(kind: ScenarioKind, seed: u64, step_s: f64) -> Trajectory {
    let spec = (0..1000).map(|i| sample(seed, kind, i)).find(|s| check_feasible(s).is_ok()).expect("a feasible spec");
    let (mut world, mut driver) = with_reference_driver(&spec);
    world.dt_s = step_s;
    let mut xy_m = vec![(world.ego.state.x_m, world.ego.state.y_m)];
    let started = Instant::now();
    let result = run_observed(&mut world, &mut driver, &RewardWeights::default(), &mut |w, _| {
        xy_m.push((w.ego.state.x_m, w.ego.state.y_m));
    });
    Trajectory {
        xy_m,
        collision: result.metrics.collision,
        success: result.metrics.success,
        wall_s: started.elapsed().as_secs_f64(),
        simulated_s: world.time_s,
    }
}

/// Max and mean distance of `coarse` from `fine` at the coarse step's times, m, over the time
/// both episodes ran.
fn position_error_m(coarse: &Trajectory, fine: &Trajectory, step_s: f64) -> (f64, f64) {
    let ratio = (step_s / FINE_S).round() as usize;
    let errors: Vec<f64> = coarse
        .xy_m
        .iter()
        .enumerate()
        .map_while(|(k, c)| fine.xy_m.get(k * ratio).map(|f| (c.0 - f.0).hypot(c.1 - f.1)))
        .collect();
    (errors.iter().copied().fold(0.0, f64::max), errors.iter().sum::<f64>() / errors.len() as f64)
}

#[test]
fn physics_step_error_against_a_fine_reference() {
    let cases: Vec<(ScenarioKind, u64)> =
        ScenarioKind::ALL.into_iter().flat_map(|k| (1..=SEEDS).map(move |s| (k, s))).collect();
    let fine: Vec<Trajectory> = cases.iter().map(|&(k, s)| drive(k, s, FINE_S)).collect();
    let cost =
        |t: &[Trajectory]| 1e3 * t.iter().map(|t| t.wall_s).sum::<f64>() / t.iter().map(|t| t.simulated_s).sum::<f64>();
    println!("{} episodes (5 kinds × {SEEDS} seeds, reference driver) against a {FINE_S} s step:", cases.len());
    println!(
        "| step s | max position error m | same, without sensor-occlusion | mean position error m | collision differs | success differs | ms per simulated s |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut chosen_max_m = f64::NAN;
    for step_s in STEPS_S {
        let coarse: Vec<Trajectory> = cases.iter().map(|&(k, s)| drive(k, s, step_s)).collect();
        let errors: Vec<(f64, f64)> = coarse.iter().zip(&fine).map(|(c, f)| position_error_m(c, f, step_s)).collect();
        let max_m = errors.iter().map(|e| e.0).fold(0.0, f64::max);
        let noiseless = cases.iter().zip(&errors).filter(|(c, _)| c.0 != ScenarioKind::SensorOcclusion);
        let max_noiseless_m = noiseless.map(|(_, e)| e.0).fold(0.0, f64::max);
        let mean_m = errors.iter().map(|e| e.1).sum::<f64>() / errors.len() as f64;
        let differs = |o: fn(&Trajectory) -> bool| coarse.iter().zip(&fine).filter(|(c, f)| o(c) != o(f)).count();
        println!(
            "| {step_s} | {max_m:.3} | {max_noiseless_m:.3} | {mean_m:.4} | {} | {} | {:.2} |",
            differs(|t| t.collision),
            differs(|t| t.success),
            cost(&coarse)
        );
        for ((c, f), (&(kind, seed), e)) in coarse.iter().zip(&fine).zip(cases.iter().zip(&errors)) {
            if c.collision != f.collision || c.success != f.success || e.0 > MAX_POSITION_ERROR_M {
                println!(
                    "  {kind} seed {seed}: max {:.3} m, collision {} (ref {}), success {} (ref {})",
                    e.0, c.collision, f.collision, c.success, f.success
                );
            }
        }
        if step_s == STEP_S {
            chosen_max_m = max_noiseless_m;
        }
    }
    println!("| {FINE_S} (reference) | 0 | 0 | 0 | 0 | 0 | {:.2} |", cost(&fine));
    assert!(chosen_max_m <= MAX_POSITION_ERROR_M, "the world's step is off by {chosen_max_m} m");
}
