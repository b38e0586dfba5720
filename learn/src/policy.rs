//! Policies: what a trained agent is, how it acts, and how it is saved and loaded as
//! safetensors with a small metadata header (algo, dims, hidden sizes, format version).

use crate::LearnError;
use crate::gru::GruCell;
use crate::host::{HostMlp, Scratch};
use crate::nn::{HALF_LN_TAU, Mlp, Param, const_param, load_params, matrix};
use candle_core::{Device, Tensor};
use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::rng::Rng;
use std::collections::HashMap;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

/// Version of the policy file layout; bumped when tensor names or shapes change.
pub const POLICY_FORMAT_VERSION: u32 = 1;

/// Learning algorithm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Algo {
    /// PPO with a clipped Gaussian MLP policy.
    Ppo,
    /// PPO with a GRU policy: the recurrent (R2D2-style) baseline.
    PpoGru,
    /// SAC with a tanh-squashed Gaussian policy.
    Sac,
}

impl Algo {
    pub const ALL: [Algo; 3] = [Algo::Ppo, Algo::PpoGru, Algo::Sac];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Algo::Ppo => "ppo",
            Algo::PpoGru => "ppo-gru",
            Algo::Sac => "sac",
        }
    }
}

impl fmt::Display for Algo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Algo {
    type Err = LearnError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Algo::ALL.into_iter().find(|a| a.name() == s).ok_or_else(|| LearnError::UnknownAlgo(s.to_string()))
    }
}

/// The network of a policy.
#[derive(Debug, Clone)]
enum Body {
    /// Mean MLP and a state-independent log σ (PPO).
    Gaussian { mean: Mlp, log_std: Param },
    /// GRU over observations, then a mean MLP; log σ state-independent (recurrent PPO).
    Recurrent { cell: GruCell, mean: Mlp, log_std: Param },
    /// MLP giving mean and log σ of the pre-tanh Gaussian (SAC).
    Squashed { net: Mlp },
}

/// A policy network: observation (and recurrent state) → action distribution.
#[derive(Debug, Clone)]
pub struct PolicyNet {
    algo: Algo,
    hidden: Vec<usize>,
    body: Body,
}

/// Bounds on SAC's log σ, as in the SAC reference implementation.
pub const LOG_STD_MIN: f64 = -5.0;
pub const LOG_STD_MAX: f64 = 2.0;
/// Initial log σ of the PPO policies (σ ≈ 0.6).
const INITIAL_LOG_STD: f32 = -0.5;

impl PolicyNet {
    /// A freshly initialised policy for `algo` with hidden layer sizes `hidden` (for the GRU
    /// variant, `hidden[0]` is the GRU width and the rest the head's layers).
    pub fn new(algo: Algo, hidden: &[usize], rng: &mut Rng) -> Result<Self, LearnError> {
        if hidden.is_empty() || hidden.contains(&0) {
            return Err(LearnError::BadConfig(format!("hidden sizes {hidden:?} must be non-empty and positive")));
        }
        let sizes = |input: usize, rest: &[usize], out: usize| {
            let mut v = vec![input];
            v.extend_from_slice(rest);
            v.push(out);
            v
        };
        let log_std = || const_param("actor.log_std".into(), (1, ACT_DIM), INITIAL_LOG_STD);
        let body = match algo {
            Algo::Ppo => Body::Gaussian {
                mean: Mlp::new("actor.mean", &sizes(OBS_DIM, hidden, ACT_DIM), 0.01, rng)?,
                log_std: log_std()?,
            },
            Algo::PpoGru => Body::Recurrent {
                cell: GruCell::new("actor.gru", OBS_DIM, hidden[0], rng)?,
                mean: Mlp::new("actor.mean", &sizes(hidden[0], &hidden[1..], ACT_DIM), 0.01, rng)?,
                log_std: log_std()?,
            },
            Algo::Sac => {
                Body::Squashed { net: Mlp::new("actor.net", &sizes(OBS_DIM, hidden, 2 * ACT_DIM), 0.01, rng)? }
            }
        };
        Ok(Self { algo, hidden: hidden.to_vec(), body })
    }

    pub fn algo(&self) -> Algo {
        self.algo
    }

    /// Recurrent state width per environment (0 for feed-forward policies).
    pub fn state_dim(&self) -> usize {
        match &self.body {
            Body::Recurrent { cell, .. } => cell.hidden(),
            _ => 0,
        }
    }

    /// Every trainable parameter.
    pub fn params(&self) -> Vec<&Param> {
        match &self.body {
            Body::Gaussian { mean, log_std } => mean.params().chain([log_std]).collect(),
            Body::Recurrent { cell, mean, log_std } => cell.params().chain(mean.params()).chain([log_std]).collect(),
            Body::Squashed { net } => net.params().collect(),
        }
    }

    /// The mean MLP of the feed-forward Gaussian policy.
    pub(crate) fn mean_mlp(&self) -> Option<&Mlp> {
        match &self.body {
            Body::Gaussian { mean, .. } => Some(mean),
            _ => None,
        }
    }

    /// The recurrent cell, for training through time.
    pub(crate) fn gru(&self) -> Option<&GruCell> {
        match &self.body {
            Body::Recurrent { cell, .. } => Some(cell),
            _ => None,
        }
    }

    /// Pre-squash mean and log σ for `features` (observations, or GRU outputs for the
    /// recurrent policy): shapes (batch, ACT_DIM) and (batch or 1, ACT_DIM).
    pub(crate) fn head(&self, features: &Tensor) -> candle_core::Result<(Tensor, Tensor)> {
        match &self.body {
            Body::Gaussian { mean, log_std } | Body::Recurrent { mean, log_std, .. } => {
                Ok((mean.forward(features)?, log_std.var.as_tensor().clone()))
            }
            Body::Squashed { net } => {
                let out = net.forward(features)?;
                let mean = out.narrow(1, 0, ACT_DIM)?;
                let log_std = out.narrow(1, ACT_DIM, ACT_DIM)?.clamp(LOG_STD_MIN, LOG_STD_MAX)?;
                Ok((mean, log_std))
            }
        }
    }

    /// Mean and log σ for a batch of observations, advancing `state` (batch × state_dim,
    /// row-major) for the recurrent policy.
    pub fn distribution(&self, obs: &[f32], state: &mut [f32]) -> Result<(Vec<f32>, Vec<f32>), LearnError> {
        let batch = obs.len() / OBS_DIM;
        let x = matrix(obs, batch, OBS_DIM)?;
        let features = match &self.body {
            Body::Recurrent { cell, .. } => {
                let h = cell.step(&x, &matrix(state, batch, cell.hidden())?)?;
                state.copy_from_slice(&h.flatten_all()?.to_vec1::<f32>()?);
                h
            }
            _ => x,
        };
        let (mean, log_std) = self.head(&features)?;
        let log_std = log_std.broadcast_as((batch, ACT_DIM))?;
        Ok((mean.flatten_all()?.to_vec1()?, log_std.flatten_all()?.to_vec1()?))
    }

    /// The deterministic action (the distribution's mode, in [−1, 1]) for each observation.
    pub fn act_deterministic(&self, obs: &[f32], state: &mut [f32], out: &mut [f32]) -> Result<(), LearnError> {
        let (mean, _) = self.distribution(obs, state)?;
        for (o, m) in out.iter_mut().zip(mean) {
            *o = match self.algo {
                Algo::Sac => m.tanh(),
                Algo::Ppo | Algo::PpoGru => m.clamp(-1.0, 1.0),
            };
        }
        Ok(())
    }

    /// Sets the state-independent log σ of the Gaussian policies (no effect on SAC).
    pub(crate) fn set_log_std(&self, value: f32) -> candle_core::Result<()> {
        match &self.body {
            Body::Gaussian { log_std, .. } | Body::Recurrent { log_std, .. } => {
                log_std.var.set(&Tensor::full(value, (1, ACT_DIM), &Device::Cpu)?)
            }
            Body::Squashed { .. } => Ok(()),
        }
    }

    /// A host-side snapshot for fast acting (`None` for the recurrent policy, which acts
    /// through candle).
    pub fn host(&self) -> Result<Option<HostPolicy>, LearnError> {
        Ok(match &self.body {
            Body::Gaussian { mean, .. } => Some(HostPolicy { squashed: false, net: HostMlp::from_mlp(mean)? }),
            Body::Squashed { net } => Some(HostPolicy { squashed: true, net: HostMlp::from_mlp(net)? }),
            Body::Recurrent { .. } => None,
        })
    }

    /// The state-independent log σ of the Gaussian policies (`None` for SAC's state-dependent σ).
    pub fn log_std(&self) -> Result<Option<[f32; ACT_DIM]>, LearnError> {
        match &self.body {
            Body::Gaussian { log_std, .. } | Body::Recurrent { log_std, .. } => {
                let v = log_std.var.as_tensor().flatten_all()?.to_vec1::<f32>()?;
                let mut out = [0.0; ACT_DIM];
                out.copy_from_slice(&v[..ACT_DIM]);
                Ok(Some(out))
            }
            Body::Squashed { .. } => Ok(None),
        }
    }

    /// Saves the policy as safetensors with metadata.
    pub fn save(&self, path: &Path) -> Result<(), LearnError> {
        let tensors: Vec<(String, Tensor)> =
            self.params().iter().map(|p| (p.name.clone(), p.var.as_tensor().clone())).collect();
        let hidden: Vec<String> = self.hidden.iter().map(|h| h.to_string()).collect();
        let meta = HashMap::from([
            ("algo".to_string(), self.algo.name().to_string()),
            ("obs_dim".to_string(), OBS_DIM.to_string()),
            ("act_dim".to_string(), ACT_DIM.to_string()),
            ("hidden".to_string(), hidden.join(",")),
            ("version".to_string(), POLICY_FORMAT_VERSION.to_string()),
        ]);
        safetensors::serialize_to_file(tensors.iter().map(|(n, t)| (n.as_str(), t)), Some(meta), path)
            .map_err(|e| LearnError::Io(path.display().to_string(), e.to_string()))
    }

    /// Loads a policy saved by [`PolicyNet::save`], checking version and dimensions.
    pub fn load(path: &Path) -> Result<Self, LearnError> {
        let bytes = std::fs::read(path).map_err(|e| LearnError::Io(path.display().to_string(), e.to_string()))?;
        let (_, header) = safetensors::SafeTensors::read_metadata(&bytes)
            .map_err(|e| LearnError::BadPolicyFile(format!("{}: {e}", path.display())))?;
        let meta = header.metadata().clone().unwrap_or_default();
        let get =
            |k: &str| meta.get(k).cloned().ok_or_else(|| LearnError::BadPolicyFile(format!("metadata lacks '{k}'")));
        let version = get("version")?;
        if version != POLICY_FORMAT_VERSION.to_string() {
            return Err(LearnError::BadPolicyFile(format!(
                "format version {version}, expected {POLICY_FORMAT_VERSION}"
            )));
        }
        for (k, want) in [("obs_dim", OBS_DIM), ("act_dim", ACT_DIM)] {
            let v = get(k)?;
            if v != want.to_string() {
                return Err(LearnError::BadPolicyFile(format!("{k} = {v}, this build uses {want}")));
            }
        }
        let algo: Algo = get("algo")?.parse()?;
        let hidden = get("hidden")?
            .split(',')
            .map(|s| s.parse::<usize>().map_err(|_| LearnError::BadPolicyFile(format!("bad hidden size '{s}'"))))
            .collect::<Result<Vec<_>, _>>()?;
        let net = PolicyNet::new(algo, &hidden, &mut Rng::new(0))?;
        let tensors = candle_core::safetensors::load_buffer(&bytes, &Device::Cpu)?;
        load_params(net.params(), &tensors)?;
        Ok(net)
    }
}

/// A frozen host-side copy of a feed-forward policy: deterministic actions without candle.
#[derive(Debug, Clone)]
pub struct HostPolicy {
    squashed: bool,
    net: HostMlp,
}

impl HostPolicy {
    /// Scratch buffers for [`HostPolicy::act_deterministic`].
    pub fn scratch(&self) -> Scratch {
        self.net.scratch()
    }

    /// The mode of the action distribution for one observation, in [−1, 1] (same as
    /// [`PolicyNet::act_deterministic`] up to float rounding).
    pub fn act_deterministic(&self, obs: &[f32; OBS_DIM], scratch: &mut Scratch) -> [f32; ACT_DIM] {
        let mut out = [0.0f32; 2 * ACT_DIM];
        let width = self.net.out_dim().min(2 * ACT_DIM);
        self.net.forward(obs, scratch, &mut out[..width]);
        let mut a = [0.0f32; ACT_DIM];
        for (a, m) in a.iter_mut().zip(out) {
            *a = if self.squashed { m.tanh() } else { m.clamp(-1.0, 1.0) };
        }
        a
    }
}

/// Log-density of `x` under N(mean, exp(log_std)²), summed over the action dimensions, per row
/// (host-side, for rollouts).
pub fn gaussian_log_prob(x: &[f32], mean: &[f32], log_std: &[f32]) -> f32 {
    x.iter()
        .zip(mean)
        .zip(log_std)
        .map(|((&x, &m), &ls)| {
            let z = (x - m) * (-ls).exp();
            -0.5 * z * z - ls - HALF_LN_TAU
        })
        .sum()
}
