//! A policy on the host: the network (feed-forward, or a GRU before it), how its output becomes
//! an action, and the driver that runs it in a world.

use super::{GruScratch, HostGru, HostMlp, NetError, Scratch};
use risktwin_common::env::{ACT_DIM, OBS_DIM, ObsPolicy};
use std::sync::Arc;

/// How a policy network's output is read as an action.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PolicyKind {
    /// PPO: the network gives the Gaussian mean (ACT_DIM outputs); the action is the mean
    /// clipped to [−1, 1].
    Gaussian,
    /// SAC: the network gives mean and log σ (2·ACT_DIM outputs); the action is tanh(mean).
    Squashed,
    /// Recurrent PPO: a GRU over the observations, then a network giving the Gaussian mean
    /// from its state; the action is the mean clipped to [−1, 1].
    Recurrent,
}

impl PolicyKind {
    /// The training algorithm's name in policy files and policy updates.
    pub fn algo(self) -> &'static str {
        match self {
            PolicyKind::Gaussian => "ppo",
            PolicyKind::Squashed => "sac",
            PolicyKind::Recurrent => "ppo-gru",
        }
    }

    /// Outputs of the network.
    pub fn out_dim(self) -> usize {
        match self {
            PolicyKind::Gaussian | PolicyKind::Recurrent => ACT_DIM,
            PolicyKind::Squashed => 2 * ACT_DIM,
        }
    }
}

/// A frozen policy: deterministic actions without a tensor library.
#[derive(Debug, Clone, PartialEq)]
pub struct HostPolicy {
    kind: PolicyKind,
    /// The recurrent policy's cell (`None` for feed-forward kinds).
    gru: Option<HostGru>,
    net: HostMlp,
}

/// What one actor of a policy keeps between steps: scratch buffers and, for the recurrent
/// policy, the GRU's state (zero at the start: a fresh memory per episode).
#[derive(Debug, Clone, Default)]
pub struct Memory {
    scratch: Scratch,
    gru: GruScratch,
    state: Vec<f32>,
}

/// An observation → action function, boxed so that drivers of any policy share one type.
pub type BoxedActor = Box<dyn FnMut(&[f32; OBS_DIM]) -> [f32; ACT_DIM] + Send>;

/// A host policy driving through the training environment's observation and action mapping.
pub type HostDriver = ObsPolicy<BoxedActor>;

impl HostPolicy {
    /// `net` read as a feed-forward `kind` policy; its input must be OBS_DIM wide and its
    /// output `kind.out_dim()`.
    pub fn new(kind: PolicyKind, net: HostMlp) -> Result<Self, NetError> {
        if kind == PolicyKind::Recurrent {
            return Err(NetError::Recurrent(kind.algo().to_owned()));
        }
        check_shape(kind, OBS_DIM, net.in_dim(), net.out_dim())?;
        Ok(Self { kind, gru: None, net })
    }

    /// A recurrent policy: `gru` over OBS_DIM-wide observations, `net` from its state to the
    /// Gaussian mean (ACT_DIM).
    pub fn recurrent(gru: HostGru, net: HostMlp) -> Result<Self, NetError> {
        let kind = PolicyKind::Recurrent;
        check_shape(kind, OBS_DIM, gru.input(), net.out_dim())?;
        check_shape(kind, gru.hidden(), net.in_dim(), net.out_dim())?;
        Ok(Self { kind, gru: Some(gru), net })
    }

    /// How the output is read.
    pub fn kind(&self) -> PolicyKind {
        self.kind
    }

    /// The network after the GRU (the whole policy for feed-forward kinds).
    pub fn net(&self) -> &HostMlp {
        &self.net
    }

    /// The recurrent policy's GRU.
    pub fn gru(&self) -> Option<&HostGru> {
        self.gru.as_ref()
    }

    /// A fresh memory for [`HostPolicy::act_deterministic`]: one per actor and episode.
    pub fn memory(&self) -> Memory {
        let state = self.gru.as_ref().map_or(0, HostGru::hidden);
        Memory {
            scratch: self.net.scratch(),
            gru: self.gru.as_ref().map(HostGru::scratch).unwrap_or_default(),
            state: vec![0.0; state],
        }
    }

    /// The mode of the action distribution for one observation, in [−1, 1] (advancing the
    /// recurrent state in `memory`).
    pub fn act_deterministic(&self, obs: &[f32; OBS_DIM], memory: &mut Memory) -> [f32; ACT_DIM] {
        let mut out = [0.0f32; 2 * ACT_DIM];
        let Memory { scratch, gru, state } = memory;
        let input: &[f32] = match &self.gru {
            Some(cell) => {
                cell.step(obs, state, gru);
                state
            }
            None => obs,
        };
        self.net.forward(input, scratch, &mut out[..self.kind.out_dim()]);
        let mut a = [0.0f32; ACT_DIM];
        for (a, m) in a.iter_mut().zip(out) {
            *a = match self.kind {
                PolicyKind::Squashed => m.tanh(),
                PolicyKind::Gaussian | PolicyKind::Recurrent => m.clamp(-1.0, 1.0),
            };
        }
        a
    }

    /// The deterministic action as an observation → action function, memory from zero.
    pub fn actor(self: Arc<Self>) -> BoxedActor {
        let mut memory = self.memory();
        Box::new(move |obs| self.act_deterministic(obs, &mut memory))
    }
}

/// A `kind` network must map `expected_in` inputs to `kind.out_dim()` outputs.
fn check_shape(kind: PolicyKind, expected_in: usize, found_in: usize, found_out: usize) -> Result<(), NetError> {
    if found_in != expected_in || found_out != kind.out_dim() {
        return Err(NetError::PolicyShape {
            kind: kind.algo(),
            expected_in,
            expected_out: kind.out_dim(),
            found_in,
            found_out,
        });
    }
    Ok(())
}
