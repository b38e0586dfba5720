//! Policies: what a trained agent is, how it acts, and how it is saved and loaded as
//! safetensors with a small metadata header (algo, dims, hidden sizes, format version).

use crate::LearnError;
use crate::gru::GruCell;
use crate::host::snapshot;
use crate::nn::{HALF_LN_TAU, Mlp, Param, const_param, load_params, matrix};
use candle_core::{Device, Tensor};
use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::rng::Rng;
use safetensors::SafeTensors;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use risktwin_policy::PolicyKind;
use risktwin_policy::file::{metadata, read_meta, sort_header};
pub use risktwin_policy::{HostPolicy, POLICY_FORMAT_VERSION};

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
        let sizes = layer_sizes;
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

    /// A host-side snapshot for fast acting: the policy an edge reads from this policy's file.
    pub fn host(&self) -> Result<HostPolicy, LearnError> {
        Ok(match &self.body {
            Body::Gaussian { mean, .. } => HostPolicy::new(PolicyKind::Gaussian, snapshot(mean)?)?,
            Body::Squashed { net } => HostPolicy::new(PolicyKind::Squashed, snapshot(net)?)?,
            Body::Recurrent { cell, mean, .. } => HostPolicy::recurrent(cell.host()?, snapshot(mean)?)?,
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
        let meta = metadata(self.algo.name(), &self.hidden);
        let io = |e: String| LearnError::Io(path.display().to_string(), e);
        let bytes = safetensors::serialize(tensors.iter().map(|(n, t)| (n.as_str(), t)), Some(meta))
            .map_err(|e| io(e.to_string()))?;
        std::fs::write(path, sort_header(bytes)?).map_err(|e| io(e.to_string()))
    }

    /// Loads a policy saved by [`PolicyNet::save`], checking version and dimensions.
    pub fn load(path: &Path) -> Result<Self, LearnError> {
        let bytes = std::fs::read(path).map_err(|e| LearnError::Io(path.display().to_string(), e.to_string()))?;
        Self::from_bytes(&bytes).map_err(|e| match e {
            LearnError::BadPolicyFile(m) => LearnError::BadPolicyFile(format!("{}: {m}", path.display())),
            e => e,
        })
    }

    /// The policy of a policy file's bytes (what [`PolicyNet::load`] reads), checking version
    /// and dimensions.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, LearnError> {
        let meta = read_meta(bytes).map_err(|e| LearnError::BadPolicyFile(e.to_string()))?;
        let (algo, hidden): (Algo, _) = (meta.algo.parse()?, meta.hidden);
        // The net is built before its tensors are loaded into it, with the widths the file
        // names: a file must hold at least the values they imply, or a few bytes of metadata
        // would allocate without bound.
        let stored = stored_values(bytes)?;
        match param_count(algo, &hidden) {
            Some(needed) if needed <= stored => {}
            needed => {
                let needed = needed.map_or_else(|| "more than usize::MAX".to_string(), |n| n.to_string());
                return Err(LearnError::BadPolicyFile(format!(
                    "its metadata (hidden {hidden:?}) implies {needed} parameters, its tensors hold {stored} values"
                )));
            }
        }
        let net = PolicyNet::new(algo, &hidden, &mut Rng::new(0))?;
        let tensors = candle_core::safetensors::load_buffer(bytes, &Device::Cpu)?;
        load_params(net.params(), &tensors)?;
        Ok(net)
    }
}

/// `[input, rest…, out]`: the layer widths of an MLP.
fn layer_sizes(input: usize, rest: &[usize], out: usize) -> Vec<usize> {
    let mut v = vec![input];
    v.extend_from_slice(rest);
    v.push(out);
    v
}

/// The parameters (values) of a policy of `algo` with `hidden` layers as [`PolicyNet::new`]
/// builds it; `None` when they overflow `usize` or `hidden` is empty.
fn param_count(algo: Algo, hidden: &[usize]) -> Option<usize> {
    // Weights (in × out) and bias (1 × out) per layer.
    let mlp = |sizes: Vec<usize>| {
        sizes.windows(2).try_fold(0usize, |n, io| n.checked_add(io[0].checked_mul(io[1])?.checked_add(io[1])?))
    };
    match algo {
        Algo::Ppo => mlp(layer_sizes(OBS_DIM, hidden, ACT_DIM))?.checked_add(ACT_DIM),
        Algo::PpoGru => {
            let h = *hidden.first()?;
            // GruCell: w_x (in × 3h), w_h (h × 3h), b_x and b_h (1 × 3h).
            let cell = OBS_DIM.checked_add(h)?.checked_add(2)?.checked_mul(h.checked_mul(3)?)?;
            cell.checked_add(mlp(layer_sizes(h, &hidden[1..], ACT_DIM))?)?.checked_add(ACT_DIM)
        }
        Algo::Sac => mlp(layer_sizes(OBS_DIM, hidden, 2 * ACT_DIM)),
    }
}

/// The values a safetensors file's tensors hold (their shapes, which the parser checked
/// against the bytes they span).
fn stored_values(bytes: &[u8]) -> Result<usize, LearnError> {
    let (_, header) = SafeTensors::read_metadata(bytes).map_err(|e| LearnError::BadPolicyFile(e.to_string()))?;
    Ok(header.tensors().values().map(|t| t.shape.iter().product::<usize>()).sum())
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

#[cfg(test)]
mod tests {
    use super::*;

    fn policy_bytes(net: &PolicyNet, meta_hidden: &[usize]) -> Vec<u8> {
        let tensors: Vec<(String, Tensor)> =
            net.params().iter().map(|p| (p.name.clone(), p.var.as_tensor().clone())).collect();
        let meta = metadata(net.algo().name(), meta_hidden);
        safetensors::serialize(tensors.iter().map(|(n, t)| (n.as_str(), t)), Some(meta)).expect("serialises")
    }

    #[test]
    fn param_count_is_what_new_builds() {
        for algo in Algo::ALL {
            for hidden in [&[8][..], &[8, 4], &[5, 3, 2]] {
                let net = PolicyNet::new(algo, hidden, &mut Rng::new(1)).expect("a net");
                let built: usize = net.params().iter().map(|p| p.var.as_tensor().elem_count()).sum();
                assert_eq!(param_count(algo, hidden), Some(built), "{algo:?} {hidden:?}");
            }
        }
    }

    #[test]
    fn a_saved_policy_reads_back() {
        for algo in Algo::ALL {
            let net = PolicyNet::new(algo, &[8, 4], &mut Rng::new(3)).expect("a net");
            let back = PolicyNet::from_bytes(&policy_bytes(&net, &[8, 4])).expect("reads back");
            assert_eq!(back.hidden, net.hidden);
            let (a, b) = (net.params(), back.params());
            for (a, b) in a.iter().zip(&b) {
                let (a, b) = (a.var.as_tensor().flatten_all(), b.var.as_tensor().flatten_all());
                let (a, b) = (a.and_then(|t| t.to_vec1::<f32>()), b.and_then(|t| t.to_vec1::<f32>()));
                assert_eq!(a.expect("values"), b.expect("values"));
            }
        }
    }

    /// A file of a small net whose metadata names huge layers is refused before anything of
    /// their size is allocated (it used to be built first: a capacity-overflow panic, or tens
    /// of GB filled with random weights for widths in the hundreds of thousands).
    #[test]
    fn metadata_naming_layers_larger_than_the_file_is_refused() {
        for algo in Algo::ALL {
            let net = PolicyNet::new(algo, &[8], &mut Rng::new(4)).expect("a net");
            for claimed in [&[4_000_000_000, 4_000_000_000][..], &[200_000, 200_000], &[9], &[usize::MAX]] {
                match PolicyNet::from_bytes(&policy_bytes(&net, claimed)) {
                    Err(LearnError::BadPolicyFile(m)) => assert!(m.contains("implies"), "{algo:?} {claimed:?}: {m}"),
                    Err(e) => panic!("{algo:?} {claimed:?}: refused for another reason: {e}"),
                    Ok(_) => panic!("{algo:?} {claimed:?}: accepted"),
                }
            }
        }
    }
}
