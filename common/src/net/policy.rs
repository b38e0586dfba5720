//! A feed-forward policy on the host: the network, how its output becomes an action, and the
//! driver that runs it in a world.

use super::{HostMlp, NetError, Scratch};
use crate::env::{ACT_DIM, OBS_DIM, ObsPolicy};
use std::sync::Arc;

/// How a policy network's output is read as an action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PolicyKind {
    /// PPO: the network gives the Gaussian mean (ACT_DIM outputs); the action is the mean
    /// clipped to [−1, 1].
    Gaussian,
    /// SAC: the network gives mean and log σ (2·ACT_DIM outputs); the action is tanh(mean).
    Squashed,
}

impl PolicyKind {
    /// The training algorithm's name in policy files and policy updates.
    pub fn algo(self) -> &'static str {
        match self {
            PolicyKind::Gaussian => "ppo",
            PolicyKind::Squashed => "sac",
        }
    }

    /// Outputs of the network.
    pub fn out_dim(self) -> usize {
        match self {
            PolicyKind::Gaussian => ACT_DIM,
            PolicyKind::Squashed => 2 * ACT_DIM,
        }
    }
}

/// A frozen feed-forward policy: deterministic actions without a tensor library.
#[derive(Debug, Clone, PartialEq)]
pub struct HostPolicy {
    kind: PolicyKind,
    net: HostMlp,
}

/// An observation → action function, boxed so that drivers of any policy share one type.
pub type BoxedActor = Box<dyn FnMut(&[f32; OBS_DIM]) -> [f32; ACT_DIM] + Send>;

/// A host policy driving through the training environment's observation and action mapping.
pub type HostDriver = ObsPolicy<BoxedActor>;

impl HostPolicy {
    /// `net` read as a `kind` policy; its input must be OBS_DIM wide and its output
    /// `kind.out_dim()`.
    pub fn new(kind: PolicyKind, net: HostMlp) -> Result<Self, NetError> {
        let (found_in, found_out) = (net.in_dim(), net.out_dim());
        if found_in != OBS_DIM || found_out != kind.out_dim() {
            return Err(NetError::PolicyShape {
                kind: kind.algo(),
                expected_in: OBS_DIM,
                expected_out: kind.out_dim(),
                found_in,
                found_out,
            });
        }
        Ok(Self { kind, net })
    }

    /// How the output is read.
    pub fn kind(&self) -> PolicyKind {
        self.kind
    }

    /// The network.
    pub fn net(&self) -> &HostMlp {
        &self.net
    }

    /// Scratch buffers for [`HostPolicy::act_deterministic`].
    pub fn scratch(&self) -> Scratch {
        self.net.scratch()
    }

    /// The mode of the action distribution for one observation, in [−1, 1].
    pub fn act_deterministic(&self, obs: &[f32; OBS_DIM], scratch: &mut Scratch) -> [f32; ACT_DIM] {
        let mut out = [0.0f32; 2 * ACT_DIM];
        self.net.forward(obs, scratch, &mut out[..self.kind.out_dim()]);
        let mut a = [0.0f32; ACT_DIM];
        for (a, m) in a.iter_mut().zip(out) {
            *a = match self.kind {
                PolicyKind::Squashed => m.tanh(),
                PolicyKind::Gaussian => m.clamp(-1.0, 1.0),
            };
        }
        a
    }

    /// A driver for a world with this desired speed and step (`world.desired_speed_mps`,
    /// `world.dt_s`): observation and action exactly as in training.
    pub fn driver(self: Arc<Self>, desired_speed_mps: f64, dt_s: f64) -> HostDriver {
        let mut scratch = self.scratch();
        let act: BoxedActor = Box::new(move |obs| self.act_deterministic(obs, &mut scratch));
        ObsPolicy::new(act, desired_speed_mps, dt_s)
    }
}
