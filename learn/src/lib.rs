//! RiskTwin's reinforcement learning on candle (CPU, f32): PPO with a clipped Gaussian MLP
//! policy, a recurrent GRU PPO (the R2D2-style baseline) and SAC with a tanh-squashed Gaussian,
//! twin critics, Polyak targets and a learned temperature — all trained on the twin's driving
//! environment ([`risktwin_common::env`]).
//!
//! Every random number (weights, exploration noise, minibatch order, replay sampling) comes
//! from our seeded [`risktwin_common::rng::Rng`], so a seed reproduces a run on the same
//! machine and thread count.
//!
//! - [`nn`], [`gru`]: networks; [`policy`]: the policy, saved/loaded as safetensors.
//! - [`gae`]: advantage estimation and reward scaling; [`ppo`], [`sac`]: the learners;
//!   [`lagrange`]: PPO's cost constraint (PPO-Lagrangian).
//! - [`train`]: the training driver behind `risktwin train` (curves, evaluation, report).

pub mod activation;
mod bias;
mod cpu;
pub mod drive;
pub mod envs;
pub mod gae;
pub mod gru;
pub mod host;
pub mod lagrange;
pub mod learner;
pub mod nn;
mod optim;
pub mod policy;
pub mod ppo;
pub mod sac;
pub mod train;
pub mod warm;

pub use policy::{Algo, PolicyNet};

/// Why learning failed.
#[derive(Debug, thiserror::Error)]
pub enum LearnError {
    #[error("unknown algorithm '{0}' (expected one of ppo, ppo-gru, sac)")]
    UnknownAlgo(String),
    #[error("bad configuration: {0}")]
    BadConfig(String),
    #[error("tensor error: {0}")]
    Tensor(#[from] candle_core::Error),
    #[error("policy file lacks tensor '{0}'")]
    MissingTensor(String),
    #[error("tensor '{name}' has shape {found:?}, expected {expected:?}")]
    TensorShape { name: String, expected: Vec<usize>, found: Vec<usize> },
    #[error("bad policy file: {0}")]
    BadPolicyFile(String),
    #[error("{0}: {1}")]
    Io(String, String),
    #[error("host network: {0}")]
    Net(#[from] risktwin_policy::NetError),
    #[error(transparent)]
    Source(#[from] risktwin_common::env::SourceError),
}
