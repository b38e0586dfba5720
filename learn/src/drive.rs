//! Driving a policy's deterministic action through `episode::run_observed`: the one path behind
//! `risktwin train`'s evaluation and the run's held-out evaluation, re-scoring and recording,
//! so their metrics and risk terms are exactly those of `simulate`.

use crate::PolicyNet;
use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy};
use risktwin_common::episode::{self, EpisodeResult};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::world::{StepReport, World};

/// Drives a built world with the policy's deterministic action, scoring with `weights` and
/// calling `observe` after every step.
pub fn drive(
    policy: &PolicyNet,
    world: &mut World,
    weights: &RewardWeights,
    observe: &mut dyn FnMut(&World, &StepReport),
) -> EpisodeResult {
    // Every policy acts through its host-side snapshot (no tensors per step), as at the edge.
    let Ok(host) = policy.host() else {
        // A snapshot fails only for a malformed net (never expected): it coasts.
        let mut p = ObsPolicy::new(|_: &[f32; OBS_DIM]| [0.0f32; ACT_DIM], world.desired_speed_mps, world.dt_s);
        return episode::run_observed(world, &mut p, weights, observe);
    };
    let mut memory = host.memory();
    let act = |o: &[f32; OBS_DIM]| host.act_deterministic(o, &mut memory);
    let mut p = ObsPolicy::new(act, world.desired_speed_mps, world.dt_s);
    episode::run_observed(world, &mut p, weights, observe)
}
