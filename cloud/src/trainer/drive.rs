//! Driving a learned policy through `episode::run`, so its metrics and risk terms are exactly
//! those of `simulate` and of the library's reference-driver outcomes.

use crate::generate::parallel_map;
use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy, Variant};
use risktwin_common::episode::{self, EpisodeResult};
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_common::world::{StepReport, World};
use risktwin_learn::PolicyNet;

/// Every evaluation is scored with the full reward weights, so the reward column compares
/// variants on one scale (base trains without the risk term but is judged like the others).
pub const EVAL_VARIANT: Variant = Variant::Full;

/// Drives each spec with the policy's deterministic action on `threads` workers; results in
/// spec order.
pub fn drive_all(policy: &PolicyNet, specs: &[ScenarioSpec], threads: usize) -> Vec<EpisodeResult> {
    parallel_map(specs, threads, |spec| drive(policy, &mut build(spec), &mut |_, _| {}))
}

/// Drives a built world with the policy's deterministic action, calling `observe` after every
/// step (for recordings).
pub fn drive(policy: &PolicyNet, world: &mut World, observe: &mut dyn FnMut(&World, &StepReport)) -> EpisodeResult {
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
    episode::run_observed(world, &mut p, &EVAL_VARIANT.weights(), observe)
}
