//! Driving a learned policy through `episode::run`, so its metrics and risk terms are exactly
//! those of `simulate` and of the library's reference-driver outcomes.

use crate::generate::parallel_map;
use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy, Variant};
use risktwin_common::episode::{self, EpisodeResult};
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_learn::PolicyNet;

/// Every evaluation is scored with the full reward weights, so the reward column compares
/// variants on one scale (base trains without the risk term but is judged like the others).
pub const EVAL_VARIANT: Variant = Variant::Full;

/// Drives each spec with the policy's deterministic action on `threads` workers; results in
/// spec order.
pub fn drive_all(policy: &PolicyNet, specs: &[ScenarioSpec], threads: usize) -> Vec<EpisodeResult> {
    let weights = EVAL_VARIANT.weights();
    parallel_map(specs, threads, |spec| {
        let mut world = build(spec);
        let mut state = vec![0.0f32; policy.state_dim()];
        let act = |o: &[f32; OBS_DIM]| {
            let mut a = [0.0f32; ACT_DIM];
            // A failed forward pass (never expected for a well-formed net) coasts.
            if policy.act_deterministic(o, &mut state, &mut a).is_err() {
                a = [0.0; ACT_DIM];
            }
            a
        };
        let mut p = ObsPolicy::new(act, world.desired_speed_mps, world.dt_s);
        episode::run(&mut world, &mut p, &weights)
    })
}
