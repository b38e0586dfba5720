//! Driving a policy's deterministic action through `episode::run_observed`: the one path behind
//! `risktwin train`'s evaluation and the run's held-out evaluation, re-scoring and recording,
//! so their metrics and risk terms are exactly those of `simulate`. [`drive_sampled`] drives
//! with the exploration noise instead (the frontier curriculum's success estimates).

use crate::PolicyNet;
use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy};
use risktwin_common::episode::{self, EpisodeResult};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::rng::Rng;
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

/// Drives a built world with the policy's Gaussian action, mean plus σ·N(0, 1) with its own
/// state-independent σ, the noise drawn from `rng` — how the policy acts in training. `None`
/// for a policy without such a σ (SAC's is state-dependent and squashed).
pub fn drive_sampled(
    policy: &PolicyNet,
    world: &mut World,
    weights: &RewardWeights,
    rng: &mut Rng,
) -> Option<EpisodeResult> {
    let std = policy.log_std().ok()??.map(f32::exp);
    let host = policy.host().ok()?;
    let mut memory = host.memory();
    let act = |o: &[f32; OBS_DIM]| {
        let mut a = host.act_deterministic(o, &mut memory);
        for (a, s) in a.iter_mut().zip(std) {
            *a = (*a + s * rng.normal() as f32).clamp(-1.0, 1.0);
        }
        a
    };
    let mut p = ObsPolicy::new(act, world.desired_speed_mps, world.dt_s);
    Some(episode::run_observed(world, &mut p, weights, &mut |_, _| {}))
}
