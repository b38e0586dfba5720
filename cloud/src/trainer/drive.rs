//! Driving a learned policy through `episode::run`, so its metrics and risk terms are exactly
//! those of `simulate` and of the library's reference-driver outcomes; [`Driver`] names any
//! driver an evaluation may hold (the reference driver, a trained policy, a user's model).

use crate::generate::parallel_map;
use risktwin_common::env::Variant;
use risktwin_common::episode::{self, EpisodeResult};
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_common::world::{StepReport, World};
use risktwin_learn::PolicyNet;
use risktwin_policy::model::DriverModel;

/// Every evaluation is scored with the full reward weights, so the reward column compares
/// variants on one scale (base trains without the risk term but is judged like the others).
pub const EVAL_VARIANT: Variant = Variant::Full;

/// Who drives a set of scenarios.
#[derive(Clone, Copy)]
pub enum Driver<'a> {
    /// The reference driver (IDM/MOBIL).
    Reference,
    /// A driver model: a trained policy on the host, or an ONNX model.
    Model(&'a DriverModel),
}

impl Driver<'_> {
    /// Each spec's episode on `threads` workers, in spec order.
    pub fn episodes(self, specs: &[ScenarioSpec], threads: usize) -> Vec<EpisodeResult> {
        match self {
            Driver::Reference => parallel_map(specs, threads, episode::evaluate),
            Driver::Model(model) => parallel_map(specs, threads, |spec| drive_model(model, &mut build(spec))),
        }
    }
}

/// Drives a built world with a driver model, scored with the evaluation weights: for a host
/// policy the same episode as [`drive`] of the policy it was taken from.
pub fn drive_model(model: &DriverModel, world: &mut World) -> EpisodeResult {
    let mut driver = model.driver(world.desired_speed_mps, world.dt_s);
    episode::run(world, &mut driver, &EVAL_VARIANT.weights())
}

/// Drives each spec with the policy's deterministic action on `threads` workers; results in
/// spec order.
pub fn drive_all(policy: &PolicyNet, specs: &[ScenarioSpec], threads: usize) -> Vec<EpisodeResult> {
    parallel_map(specs, threads, |spec| drive(policy, &mut build(spec), &mut |_, _| {}))
}

/// Drives a built world with the policy's deterministic action, scored with the evaluation
/// weights, calling `observe` after every step (for recordings).
pub fn drive(policy: &PolicyNet, world: &mut World, observe: &mut dyn FnMut(&World, &StepReport)) -> EpisodeResult {
    risktwin_learn::drive::drive(policy, world, &EVAL_VARIANT.weights(), observe)
}

/// Per spec, the share of `drives` drives with the policy's exploration noise that reach the
/// goal (success: no collision, on the road, route completed in time); the noise of spec `i`'s
/// drive `k` comes from stream `i · drives + k` of `seed`, so the shares do not depend on
/// `threads`. `None` for a policy without a state-independent σ (SAC).
pub fn success_shares(
    policy: &PolicyNet,
    specs: &[ScenarioSpec],
    drives: usize,
    seed: u64,
    threads: usize,
) -> Option<Vec<f64>> {
    policy.log_std().ok()??;
    let indexed: Vec<(usize, &ScenarioSpec)> = specs.iter().enumerate().collect();
    let weights = EVAL_VARIANT.weights();
    let shares = parallel_map(&indexed, threads, |&(i, spec)| {
        let wins = (0..drives)
            .filter(|&k| {
                let mut rng = Rng::derive(seed, (i * drives + k) as u64);
                risktwin_learn::drive::drive_sampled(policy, &mut build(spec), &weights, &mut rng)
                    .is_some_and(|r| r.metrics.success)
            })
            .count();
        wins as f64 / drives.max(1) as f64
    });
    Some(shares)
}
