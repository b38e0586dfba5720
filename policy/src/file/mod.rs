//! Policy files: safetensors with a metadata header, the layout the `learn` crate saves and
//! loads (`learn::PolicyNet::save`), read here without a tensor library.
//!
//! Metadata: `algo` (`ppo`, `ppo-gru`, `sac`), `obs_dim`, `act_dim`, `hidden` (comma-separated
//! layer widths), `version` ([`POLICY_FORMAT_VERSION`]) and `decision_rate_hz`, the decisions
//! per second the policy was trained at ([`DECISION_RATE_HZ`]: one per physics step). A policy
//! acts on per-step observations, so a file of another rate is refused; a file without the
//! field predates it and was trained at the world's step of then and now, 20 Hz. The actor of a feed-forward
//! policy is an MLP `OBS_DIM → hidden… → out` stored as `<prefix>.<i>.weight` (in × out, F32)
//! and `<prefix>.<i>.bias` (1 × out, F32), with prefix `actor.mean` and out = ACT_DIM for PPO,
//! `actor.net` and out = 2·ACT_DIM (mean, log σ) for SAC. A recurrent policy (`ppo-gru`) has a
//! GRU of width h = hidden[0] first (`actor.gru.w_x` OBS_DIM × 3h, `actor.gru.w_h` h × 3h,
//! `actor.gru.b_x` and `actor.gru.b_h` 1 × 3h) and the mean MLP `h → hidden[1..] → ACT_DIM`
//! after it. Other tensors (PPO's `actor.log_std`, critics) may be present and are not read.

use super::{Dense, HostGru, HostMlp, HostPolicy, NetError, PolicyKind};
use risktwin_common::env::{ACT_DIM, OBS_DIM};
use risktwin_common::world::DECISION_RATE_HZ;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use std::collections::HashMap;

/// Version of the policy file layout; bumped when tensor names or shapes change.
pub const POLICY_FORMAT_VERSION: u32 = 1;

/// What a policy file's metadata says, once checked against this build.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PolicyMeta {
    /// Algorithm name as written (`ppo`, `ppo-gru`, `sac`).
    pub algo: String,
    /// Hidden layer widths.
    pub hidden: Vec<usize>,
}

/// The metadata a policy file of `algo` with `hidden` layers carries.
pub fn metadata(algo: &str, hidden: &[usize]) -> HashMap<String, String> {
    let hidden: Vec<String> = hidden.iter().map(|h| h.to_string()).collect();
    HashMap::from([
        ("algo".to_string(), algo.to_string()),
        ("obs_dim".to_string(), OBS_DIM.to_string()),
        ("act_dim".to_string(), ACT_DIM.to_string()),
        ("hidden".to_string(), hidden.join(",")),
        ("version".to_string(), POLICY_FORMAT_VERSION.to_string()),
        ("decision_rate_hz".to_string(), DECISION_RATE_HZ.to_string()),
    ])
}

/// safetensors writes its metadata map in `HashMap` order, which changes from one map to the
/// next, so the same policy gave different bytes from run to run. This rewrites a serialised
/// file's header with every object's keys sorted (serde_json's map is ordered): the same JSON
/// in another order, hence the same length, so the data offsets stay valid.
pub fn sort_header(mut bytes: Vec<u8>) -> Result<Vec<u8>, NetError> {
    let bad = |m: &str| NetError::Safetensors(format!("header: {m}"));
    let len = bytes.get(..8).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes"))).ok_or_else(|| bad("short"))?;
    let end = usize::try_from(len).ok().and_then(|n| n.checked_add(8)).filter(|&e| e <= bytes.len());
    let end = end.ok_or_else(|| bad("length beyond the file"))?;
    let value: serde_json::Value = serde_json::from_slice(&bytes[8..end]).map_err(|e| bad(&e.to_string()))?;
    let sorted = serde_json::to_vec(&value).map_err(|e| bad(&e.to_string()))?;
    let Some(pad) = (end - 8).checked_sub(sorted.len()) else { return Err(bad("grew when sorted")) };
    bytes[8..8 + sorted.len()].copy_from_slice(&sorted);
    bytes[end - pad..end].fill(b' ');
    Ok(bytes)
}

/// Reads a policy file's metadata and checks its format version, dimensions and decision rate.
pub fn read_meta(bytes: &[u8]) -> Result<PolicyMeta, NetError> {
    let (_, header) = SafeTensors::read_metadata(bytes).map_err(|e| NetError::Safetensors(e.to_string()))?;
    let meta = header.metadata().clone().unwrap_or_default();
    let get = |k: &'static str| meta.get(k).ok_or(NetError::MissingMetadata(k));
    let version = get("version")?;
    if *version != POLICY_FORMAT_VERSION.to_string() {
        return Err(NetError::FormatVersion { found: version.clone(), expected: POLICY_FORMAT_VERSION });
    }
    for (name, expected) in [("obs_dim", OBS_DIM), ("act_dim", ACT_DIM)] {
        let found = get(name)?;
        if *found != expected.to_string() {
            return Err(NetError::Dimension { name, found: found.clone(), expected });
        }
    }
    // Absent: a file from before the field, trained at 20 Hz like every policy since.
    if let Some(found) = meta.get("decision_rate_hz")
        && !found.parse::<f64>().is_ok_and(|hz| (hz - DECISION_RATE_HZ).abs() < 1e-9)
    {
        return Err(NetError::DecisionRate { found: found.clone(), expected_hz: DECISION_RATE_HZ });
    }
    let hidden_text = get("hidden")?;
    let hidden = hidden_text
        .split(',')
        .map(|s| s.parse::<usize>().ok().filter(|&h| h > 0))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| NetError::BadHidden(hidden_text.clone()))?;
    Ok(PolicyMeta { algo: get("algo")?.clone(), hidden })
}

/// Tensor-name prefix of the actor MLP of a `kind` policy.
pub fn actor_prefix(kind: PolicyKind) -> &'static str {
    match kind {
        PolicyKind::Gaussian | PolicyKind::Recurrent => "actor.mean",
        PolicyKind::Squashed => "actor.net",
    }
}

/// Tensor-name prefix of the recurrent policy's GRU.
const GRU_PREFIX: &str = "actor.gru";

/// The values of an F32 tensor of exactly `shape`.
fn f32_tensor(tensors: &SafeTensors<'_>, name: &str, shape: &[usize]) -> Result<Vec<f32>, NetError> {
    let view = tensors.tensor(name).map_err(|_| NetError::MissingTensor(name.to_owned()))?;
    if view.dtype() != Dtype::F32 {
        return Err(NetError::Dtype { name: name.to_owned(), found: view.dtype().to_string() });
    }
    if view.shape() != shape {
        return Err(NetError::TensorShape {
            name: name.to_owned(),
            expected: shape.to_vec(),
            found: view.shape().to_vec(),
        });
    }
    // The view's length is shape·4 bytes (checked by the safetensors parser).
    Ok(view.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect())
}

impl HostPolicy {
    /// The policy of a policy file (as `learn::PolicyNet::save` writes it): metadata checked,
    /// every actor tensor present, F32, of the shape the metadata implies, and finite.
    pub fn from_safetensors(bytes: &[u8]) -> Result<Self, NetError> {
        let meta = read_meta(bytes)?;
        let kind = match meta.algo.as_str() {
            "ppo" => PolicyKind::Gaussian,
            "sac" => PolicyKind::Squashed,
            "ppo-gru" => PolicyKind::Recurrent,
            _ => return Err(NetError::UnknownAlgo(meta.algo)),
        };
        let tensors = SafeTensors::deserialize(bytes).map_err(|e| NetError::Safetensors(e.to_string()))?;
        let dense = |name: &str, n_in: usize, n_out: usize, w: &str, b: &str| {
            let weight = f32_tensor(&tensors, &format!("{name}.{w}"), &[n_in, n_out])?;
            let bias = f32_tensor(&tensors, &format!("{name}.{b}"), &[1, n_out])?;
            Dense::new(name, weight, bias, n_in, n_out)
        };
        // The recurrent policy's MLP starts from the GRU's state, h = hidden[0].
        let (mlp_in, mlp_hidden) = match (kind, meta.hidden.split_first()) {
            (PolicyKind::Recurrent, Some((&h, rest))) => (h, rest),
            _ => (OBS_DIM, &meta.hidden[..]),
        };
        let mut sizes = vec![mlp_in];
        sizes.extend_from_slice(mlp_hidden);
        sizes.push(kind.out_dim());
        let prefix = actor_prefix(kind);
        let layers = sizes
            .windows(2)
            .enumerate()
            .map(|(i, io)| dense(&format!("{prefix}.{i}"), io[0], io[1], "weight", "bias"))
            .collect::<Result<Vec<_>, _>>()?;
        let net = HostMlp::from_layers(layers)?;
        if kind != PolicyKind::Recurrent {
            return HostPolicy::new(kind, net);
        }
        let h = mlp_in;
        let gates = h.checked_mul(3).ok_or_else(|| NetError::BadHidden(h.to_string()))?;
        let x = dense(GRU_PREFIX, OBS_DIM, gates, "w_x", "b_x")?;
        let state = dense(GRU_PREFIX, h, gates, "w_h", "b_h")?;
        HostPolicy::recurrent(HostGru::new(x, state)?, net)
    }

    /// The actor part of a policy file: what [`HostPolicy::from_safetensors`] reads back (the
    /// `learn` crate's files carry more, e.g. PPO's log σ, and are what training produces).
    pub fn to_safetensors(&self) -> Result<Vec<u8>, NetError> {
        let layers = self.net().layers();
        let mut hidden: Vec<usize> = self.gru().map(HostGru::hidden).into_iter().collect();
        hidden.extend(layers.iter().take(layers.len().saturating_sub(1)).map(|l| l.n_out()));
        let prefix = actor_prefix(self.kind());
        let le = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let tensors = |name: String, l: &Dense, w: &str, b: &str| {
            [
                (format!("{name}.{w}"), vec![l.n_in(), l.n_out()], le(l.weight())),
                (format!("{name}.{b}"), vec![1, l.n_out()], le(l.bias())),
            ]
        };
        let mut bytes: Vec<(String, Vec<usize>, Vec<u8>)> = layers
            .iter()
            .enumerate()
            .flat_map(|(i, l)| tensors(format!("{prefix}.{i}"), l, "weight", "bias"))
            .collect();
        if let Some((x, h)) = self.gru().map(HostGru::maps) {
            bytes.extend(tensors(GRU_PREFIX.to_owned(), x, "w_x", "b_x"));
            bytes.extend(tensors(GRU_PREFIX.to_owned(), h, "w_h", "b_h"));
        }
        let views = bytes
            .iter()
            .map(|(name, shape, data)| Ok((name.as_str(), TensorView::new(Dtype::F32, shape.clone(), data)?)))
            .collect::<Result<Vec<_>, safetensors::SafeTensorError>>()
            .map_err(|e| NetError::Safetensors(e.to_string()))?;
        let bytes = safetensors::serialize(views, Some(metadata(self.kind().algo(), &hidden)))
            .map_err(|e| NetError::Safetensors(e.to_string()))?;
        sort_header(bytes)
    }
}

#[cfg(test)]
mod tests;
