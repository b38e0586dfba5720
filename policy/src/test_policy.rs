//! Test policies: random weights of every kind, for the file and ONNX tests.

use crate::{Dense, HostGru, HostMlp, HostPolicy, PolicyKind};
use risktwin_common::env::OBS_DIM;
use risktwin_common::rng::Rng;

/// A `kind` policy with random weights and `out_bias` on the output layer: OBS_DIM → 8 → out,
/// or for the recurrent kind a GRU of 8 units and a linear head 8 → out (`hidden` = [8] both).
pub fn random_policy(kind: PolicyKind, seed: u64, out_bias: &[f32]) -> HostPolicy {
    let mut rng = Rng::new(seed);
    let mut values = |n: usize| (0..n).map(|_| rng.uniform(-0.5, 0.5) as f32).collect::<Vec<_>>();
    let out = kind.out_dim();
    let last = Dense::new("o", values(8 * out), out_bias.to_vec(), 8, out).expect("a layer");
    if kind == PolicyKind::Recurrent {
        let x = Dense::new("x", values(OBS_DIM * 24), values(24), OBS_DIM, 24).expect("a layer");
        let h = Dense::new("h", values(8 * 24), values(24), 8, 24).expect("a layer");
        let gru = HostGru::new(x, h).expect("a cell");
        return HostPolicy::recurrent(gru, HostMlp::from_layers(vec![last]).expect("a chain")).expect("a policy");
    }
    let hidden = Dense::new("h", values(OBS_DIM * 8), values(8), OBS_DIM, 8).expect("a layer");
    HostPolicy::new(kind, HostMlp::from_layers(vec![hidden, last]).expect("a chain")).expect("a policy")
}
