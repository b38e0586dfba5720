//! Is the driving task learnable through the policy's interface? Drives the held-out and benign
//! scenarios with (a) the reference driver and (b) a scripted controller that sees only the
//! observation vector and acts through `action_to_controls`, and prints their metrics.
//!
//! `cargo run --release -p risktwin-learn --example env_check`

use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy, Variant, benign_specs};
use risktwin_common::episode;
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_learn::train::{FinalMetrics, held_out_specs};

/// Lane keeping on e_y/e_ψ with a curvature feed-forward, speed tracking v_ref, braking when
/// the time to collision gets short.
fn scripted(o: &[f32; OBS_DIM]) -> [f32; ACT_DIM] {
    let (v, e_y, e_psi, d_f, dv_f, ttc_risk, v_ref, kappa) = (o[0], o[3], o[4], o[5], o[6], o[9], o[10], o[11]);
    // δ ≈ L·κ (wheelbase ≈ 2.8 m, κ scaled by 25 m, δ scaled by 0.25 rad) minus feedback.
    let steer = (2.8 * kappa / 25.0) / 0.25 - 0.6 * e_y - 1.5 * e_psi;
    let gap_m = d_f * 100.0;
    let closing = dv_f * 10.0;
    let want = if gap_m < 100.0 {
        (v_ref * 20.0).min(((gap_m - 8.0) / 1.5).max(0.0) + (v * 20.0 - closing))
    } else {
        v_ref * 20.0
    };
    let err = want - v * 20.0;
    let (throttle, brake) = if ttc_risk > 0.5 || err < -1.0 {
        (0.0, (0.3 * -err).clamp(0.2, 1.0))
    } else {
        ((0.3 * err).clamp(0.0, 1.0), 0.0)
    };
    [steer.clamp(-1.0, 1.0), throttle, brake]
}

fn report(name: &str, specs: &[ScenarioSpec]) {
    let reference: Vec<_> = specs.iter().map(|s| episode::evaluate(s).metrics).collect();
    let weights = Variant::Base.weights();
    let script: Vec<_> = specs
        .iter()
        .map(|s| {
            let mut world = build(s);
            let mut p = ObsPolicy::new(scripted, world.desired_speed_mps, world.dt_s);
            episode::run(&mut world, &mut p, &weights).metrics
        })
        .collect();
    for (who, m) in [("reference", reference), ("scripted", script)] {
        let f = FinalMetrics::average(&m);
        println!(
            "{name:9} {who:9}: success {:.2} collision {:.2} offroad {:.2} completion {:.2} speed {:.1} reward {:.1}",
            f.success_rate, f.collision_rate, f.offroad_rate, f.route_completion, f.avg_speed_mps, f.reward
        );
    }
}

fn main() {
    report("benign", &benign_specs(1 ^ 0xBE91_6000, 20));
    report("held-out", &held_out_specs(1, 10));
}
