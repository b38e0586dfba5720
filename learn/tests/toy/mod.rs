//! A trivial 1-D control task: drive x to 0. x' = x + 0.1·a₀ (a₀ clipped to [−1, 1]),
//! reward −|x|, x₀ uniform in [−1, 1], episodes of 20 steps (truncated). A good policy
//! (a₀ ≈ −10x) earns about −0.6 per episode; doing nothing about −10.
//!
//! [`Toy::cliff`] is the constrained task: reward a₀ per step (pushing right pays), and the
//! episode fails (terminates) when x reaches 1. Failing costs nothing in reward, so the
//! unconstrained optimum pushes right and fails in almost every episode; a policy that never
//! fails must stop short of 1 and earns less.

use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::rng::Rng;
use risktwin_learn::LearnError;
use risktwin_learn::envs::Environment;

pub const EPISODE_STEPS: u32 = 20;

pub struct Toy {
    cliff: bool,
    x: Vec<f32>,
    t: Vec<u32>,
    ret: Vec<f32>,
    obs: Vec<f32>,
    rewards: Vec<f32>,
    terminated: Vec<u8>,
    truncated: Vec<u8>,
    final_obs: Vec<f32>,
    rng: Rng,
    /// Returns of finished episodes.
    pub returns: Vec<f32>,
    /// Whether each finished episode failed (the cliff task).
    pub failed: Vec<bool>,
}

impl Toy {
    pub fn new(n: usize, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let x: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0) as f32).collect();
        let mut toy = Self {
            cliff: false,
            x,
            t: vec![0; n],
            ret: vec![0.0; n],
            obs: vec![0.0; n * OBS_DIM],
            rewards: vec![0.0; n],
            terminated: vec![0; n],
            truncated: vec![0; n],
            final_obs: vec![0.0; n * OBS_DIM],
            rng,
            returns: Vec::new(),
            failed: Vec::new(),
        };
        for i in 0..n {
            toy.obs[i * OBS_DIM] = toy.x[i];
        }
        toy
    }

    /// The cliff task (module docs).
    pub fn cliff(n: usize, seed: u64) -> Self {
        Self { cliff: true, ..Self::new(n, seed) }
    }

    /// Share of the last `k` finished episodes that failed.
    pub fn recent_failures(&self, k: usize) -> f32 {
        let tail = &self.failed[self.failed.len().saturating_sub(k)..];
        tail.iter().filter(|&&f| f).count() as f32 / tail.len().max(1) as f32
    }

    /// Mean return of the last `k` finished episodes.
    pub fn recent_return(&self, k: usize) -> f32 {
        let tail = &self.returns[self.returns.len().saturating_sub(k)..];
        tail.iter().sum::<f32>() / tail.len().max(1) as f32
    }
}

impl Environment for Toy {
    fn n_envs(&self) -> usize {
        self.x.len()
    }
    fn obs(&self) -> &[f32] {
        &self.obs
    }
    fn step(&mut self, actions: &[f32]) -> Result<(), LearnError> {
        for i in 0..self.x.len() {
            let a = actions[i * ACT_DIM].clamp(-1.0, 1.0);
            self.x[i] += 0.1 * a;
            self.rewards[i] = if self.cliff { a } else { -self.x[i].abs() };
            self.ret[i] += self.rewards[i];
            self.t[i] += 1;
            self.obs[i * OBS_DIM] = self.x[i];
            self.terminated[i] = u8::from(self.cliff && self.x[i] >= 1.0);
            self.truncated[i] = u8::from(self.terminated[i] == 0 && self.t[i] >= EPISODE_STEPS);
            if self.terminated[i] != 0 || self.truncated[i] != 0 {
                self.final_obs[i * OBS_DIM] = self.x[i];
                self.returns.push(self.ret[i]);
                self.failed.push(self.terminated[i] != 0);
                self.ret[i] = 0.0;
                self.t[i] = 0;
                self.x[i] = self.rng.uniform(-1.0, 1.0) as f32;
                self.obs[i * OBS_DIM] = self.x[i];
            }
        }
        Ok(())
    }
    fn rewards(&self) -> &[f32] {
        &self.rewards
    }
    fn terminated(&self) -> &[u8] {
        &self.terminated
    }
    fn truncated(&self) -> &[u8] {
        &self.truncated
    }
    fn final_obs(&self) -> &[f32] {
        &self.final_obs
    }
}
