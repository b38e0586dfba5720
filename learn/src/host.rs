//! Host-side (plain Rust, no autograd) copies of the candle networks for acting: rollouts and
//! evaluation run the same weights without building tensors or a gradient graph. The host
//! network itself ([`HostMlp`]) lives in `risktwin_policy`, so that processes without
//! candle (edge vehicles) act with the very same code.
//!
//! A snapshot is taken after each update ([`snapshot`]); the candle networks stay the single
//! source of truth for learning.

use crate::LearnError;
use crate::nn::Mlp;
use risktwin_policy::Dense;
pub use risktwin_policy::{HostMlp, Scratch};

/// A host copy of `mlp`'s current weights.
pub fn snapshot(mlp: &Mlp) -> Result<HostMlp, LearnError> {
    let layers = (0..mlp.layer_count())
        .map(|i| {
            let (w, b) = mlp.layer(i);
            let (n_in, n_out) = w.var.as_tensor().dims2()?;
            let w_values = w.var.as_tensor().flatten_all()?.to_vec1::<f32>()?;
            let b_values = b.var.as_tensor().flatten_all()?.to_vec1::<f32>()?;
            Ok(Dense::new(&w.name, w_values, b_values, n_in, n_out)?)
        })
        .collect::<Result<Vec<_>, LearnError>>()?;
    Ok(HostMlp::from_layers(layers)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::matrix;
    use risktwin_common::rng::Rng;

    #[test]
    fn host_forward_matches_candle() {
        let mut rng = Rng::new(5);
        let mlp = Mlp::new("m", &[7, 16, 9, 3], 1.0, &mut rng).unwrap();
        let x: Vec<f32> = (0..4 * 7).map(|_| rng.uniform(-2.0, 2.0) as f32).collect();
        let want = mlp.forward(&matrix(&x, 4, 7).unwrap()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        let host = snapshot(&mlp).unwrap();
        let mut scratch = host.scratch();
        let mut got = vec![0.0; 12];
        for r in 0..4 {
            host.forward(&x[r * 7..(r + 1) * 7], &mut scratch, &mut got[r * 3..(r + 1) * 3]);
        }
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() < 1e-5, "{got:?} vs {want:?}");
        }
    }
}
