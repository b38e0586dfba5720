//! The vectorised-environment interface the learners train on, implemented for the twin's
//! [`VecEnv`] (and by toy tasks in tests).

use crate::LearnError;
use risktwin_common::env::VecEnv;

/// Many environments stepped together; layouts as in [`VecEnv`]: row-major, one row per
/// environment, `OBS_DIM` observation and `ACT_DIM` action columns, auto-reset.
pub trait Environment {
    fn n_envs(&self) -> usize;
    fn obs(&self) -> &[f32];
    fn step(&mut self, actions: &[f32]) -> Result<(), LearnError>;
    fn rewards(&self) -> &[f32];
    fn terminated(&self) -> &[u8];
    fn truncated(&self) -> &[u8];
    fn final_obs(&self) -> &[f32];
}

impl Environment for VecEnv {
    fn n_envs(&self) -> usize {
        self.len()
    }
    fn obs(&self) -> &[f32] {
        VecEnv::obs(self)
    }
    fn step(&mut self, actions: &[f32]) -> Result<(), LearnError> {
        Ok(VecEnv::step(self, actions)?)
    }
    fn rewards(&self) -> &[f32] {
        VecEnv::rewards(self)
    }
    fn terminated(&self) -> &[u8] {
        VecEnv::terminated(self)
    }
    fn truncated(&self) -> &[u8] {
        VecEnv::truncated(self)
    }
    fn final_obs(&self) -> &[f32] {
        VecEnv::final_obs(self)
    }
}
