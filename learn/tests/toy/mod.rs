//! A trivial 1-D control task: drive x to 0. x' = x + 0.1·a₀ (a₀ clipped to [−1, 1]),
//! reward −|x|, x₀ uniform in [−1, 1], episodes of 20 steps (truncated). A good policy
//! (a₀ ≈ −10x) earns about −0.6 per episode; doing nothing about −10.

use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::rng::Rng;
use risktwin_learn::LearnError;
use risktwin_learn::envs::Environment;

pub const EPISODE_STEPS: u32 = 20;

pub struct Toy {
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
}

impl Toy {
    pub fn new(n: usize, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let x: Vec<f32> = (0..n).map(|_| rng.uniform(-1.0, 1.0) as f32).collect();
        let mut toy = Self {
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
        };
        for i in 0..n {
            toy.obs[i * OBS_DIM] = toy.x[i];
        }
        toy
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
            self.rewards[i] = -self.x[i].abs();
            self.ret[i] += self.rewards[i];
            self.t[i] += 1;
            self.obs[i * OBS_DIM] = self.x[i];
            self.truncated[i] = u8::from(self.t[i] >= EPISODE_STEPS);
            if self.truncated[i] != 0 {
                self.final_obs[i * OBS_DIM] = self.x[i];
                self.returns.push(self.ret[i]);
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
