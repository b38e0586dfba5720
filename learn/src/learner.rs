//! The learner behind an algorithm: PPO (feed-forward or GRU) or SAC, stepped the same way by
//! `risktwin train` and by the cloud's trainer.

use crate::envs::Environment;
use crate::ppo::{Ppo, PpoConfig, PpoTimings};
use crate::sac::{Sac, SacConfig};
use crate::{Algo, LearnError, PolicyNet};

/// A PPO or SAC learner.
pub enum Learner {
    Ppo(Box<Ppo>),
    Sac(Box<Sac>),
}

impl Learner {
    /// A learner for `algo` (`ppo-gru` is PPO with `recurrent` set) on `n_envs` environments.
    pub fn new(algo: Algo, ppo: &PpoConfig, sac: &SacConfig, n_envs: usize, seed: u64) -> Result<Self, LearnError> {
        Ok(match algo {
            Algo::Ppo | Algo::PpoGru => {
                let pc = PpoConfig { recurrent: algo == Algo::PpoGru, ..ppo.clone() };
                Learner::Ppo(Box::new(Ppo::new(pc, n_envs, seed)?))
            }
            Algo::Sac => Learner::Sac(Box::new(Sac::new(sac.clone(), n_envs, seed)?)),
        })
    }

    /// One learner iteration (a PPO rollout and update, or SAC's steps); the environment steps taken.
    pub fn step(&mut self, env: &mut dyn Environment) -> Result<u64, LearnError> {
        Ok(match self {
            Learner::Ppo(p) => {
                p.learn_rollout(env)?;
                p.rollout_steps() as u64
            }
            Learner::Sac(s) => s.learn_steps(env)?,
        })
    }

    /// The current policy.
    pub fn policy(&self) -> &PolicyNet {
        match self {
            Learner::Ppo(p) => p.policy(),
            Learner::Sac(s) => s.policy(),
        }
    }

    /// The Lagrange multiplier λ of a constrained PPO learner.
    pub fn lagrange_multiplier(&self) -> Option<f64> {
        match self {
            Learner::Ppo(p) => p.lagrange_multiplier(),
            Learner::Sac(_) => None,
        }
    }

    /// PPO's time per phase (zero for SAC, which does not split it).
    pub fn timings(&self) -> PpoTimings {
        match self {
            Learner::Ppo(p) => p.timings(),
            Learner::Sac(_) => PpoTimings::default(),
        }
    }
}
