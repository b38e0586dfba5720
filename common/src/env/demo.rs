//! Demonstrations for a warm start: the reference driver's drives recorded as (observation,
//! action) pairs on the same observation a policy sees, so a learner can first imitate it and
//! then improve on it (docs/method.md §7, "Warm start").
//!
//! The driver's executed commands carry Gaussian noise while the recorded label is its clean
//! command (DART, Laskey et al. 2017, "DART: Noise injection for robust imitation learning"):
//! the data then covers the states a slightly imperfect imitator drifts into, and what the
//! driver would do there. Only episodes that end without a collision or leaving the road are
//! kept: a demonstration of a crash teaches the crash.

use super::driving::DrivingEnv;
use super::observe::{ACT_DIM, OBS_DIM, STEER_SCALE_RAD};
use super::reward::TrainingReward;
use super::source::{ScenarioSource, SourceError};
use crate::driver::{Policy, ReferenceDriver};
use crate::rng::Rng;
use crate::vehicle::Controls;
use rayon::prelude::*;

/// Recorded pairs, row-major: `obs` is n × OBS_DIM, `actions` n × ACT_DIM.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Demonstrations {
    pub obs: Vec<f32>,
    pub actions: Vec<f32>,
    /// Episodes driven and kept (clean endings).
    pub episodes: usize,
    pub kept: usize,
}

impl Demonstrations {
    /// Pairs recorded.
    pub fn len(&self) -> usize {
        self.actions.len() / ACT_DIM
    }

    pub fn is_empty(&self) -> bool {
        self.actions.is_empty()
    }
}

/// The action that commands `c`: the inverse of [`super::action_to_controls`] within its range.
/// The pedals are recorded as one signed demand u = throttle − brake, throttle at u and brake
/// at −u (the idle one below 0 by as much as the other is pressed; the reference driver never
/// presses both): a regression target continuous through coasting, where a fixed idle value
/// would make a light brake and none lie far apart, and the fit average them away.
pub fn controls_to_action(c: &Controls) -> [f32; ACT_DIM] {
    let u = (c.throttle.clamp(0.0, 1.0) - c.brake.clamp(0.0, 1.0)) as f32;
    [(c.steer_rad / STEER_SCALE_RAD).clamp(-1.0, 1.0) as f32, u, -u]
}

/// How demonstrations are collected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DemoPlan {
    /// Environments driven in parallel (each its own episode stream of the source).
    pub n_envs: usize,
    /// Steps driven per environment (the last, unfinished episode is dropped).
    pub steps_per_env: usize,
    /// Standard deviation of the noise on the executed action.
    pub noise_std: f64,
    pub seed: u64,
}

/// Drives `plan.n_envs` episode streams of `source` with the reference driver and returns the
/// pairs of the episodes that ended cleanly. Deterministic for the plan, whatever the thread
/// count. The episode streams are the source's environment indices offset past `n_envs`, so
/// they do not replay the first episodes a learner on the same source trains on.
pub fn demonstrate(
    source: &ScenarioSource,
    reward: TrainingReward,
    plan: &DemoPlan,
) -> Result<Demonstrations, SourceError> {
    source.validate()?;
    let per_env: Vec<Result<Demonstrations, SourceError>> =
        (0..plan.n_envs).into_par_iter().map(|i| drive_stream(source, reward, plan, plan.n_envs + i)).collect();
    let mut out = Demonstrations::default();
    for d in per_env {
        let d = d?;
        out.obs.extend_from_slice(&d.obs);
        out.actions.extend_from_slice(&d.actions);
        out.episodes += d.episodes;
        out.kept += d.kept;
    }
    Ok(out)
}

/// One environment's stream: episodes back to back until `steps_per_env` steps are driven.
fn drive_stream(
    source: &ScenarioSource,
    reward: TrainingReward,
    plan: &DemoPlan,
    stream: usize,
) -> Result<Demonstrations, SourceError> {
    let mut rng = Rng::derive(plan.seed, 0xDE30 ^ stream as u64);
    let mut out = Demonstrations::default();
    let (mut ep_obs, mut ep_act) = (Vec::new(), Vec::new());
    let mut obs = [0.0f32; OBS_DIM];
    let mut episode = 0u64;
    let mut env = DrivingEnv::new(&source.spec(stream, episode)?, reward, &mut obs);
    let mut driver = ReferenceDriver::new(env.world().desired_speed_mps, env.world().ego.params);
    for _ in 0..plan.steps_per_env {
        let label = controls_to_action(&driver.act(&env.world().view()));
        let mut executed = label;
        for a in &mut executed {
            *a = (*a + (plan.noise_std * rng.normal()) as f32).clamp(-1.0, 1.0);
        }
        ep_obs.extend_from_slice(&obs);
        ep_act.extend_from_slice(&label);
        let outcome = env.step(&executed, &mut obs);
        if !outcome.done() {
            continue;
        }
        out.episodes += 1;
        if !outcome.terminated {
            out.kept += 1;
            out.obs.append(&mut ep_obs);
            out.actions.append(&mut ep_act);
        }
        ep_obs.clear();
        ep_act.clear();
        episode += 1;
        env.reset(&source.spec(stream, episode)?, &mut obs);
        driver = ReferenceDriver::new(env.world().desired_speed_mps, env.world().ego.params);
    }
    Ok(out)
}
