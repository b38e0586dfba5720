//! Host-side (plain Rust, no autograd) copies of the networks for acting: rollouts and
//! evaluation run the same weights as the candle networks without building tensors or a
//! gradient graph, allocation-free per row once the scratch buffers exist.
//!
//! A snapshot is taken after each update ([`HostMlp::refresh`]); the candle networks stay the
//! single source of truth for learning.

use crate::nn::Mlp;
use candle_core::Result;

/// One dense layer: `w` is (in × out) row-major, as the candle parameter.
#[derive(Debug, Clone, Default)]
struct Dense {
    w: Vec<f32>,
    b: Vec<f32>,
    n_in: usize,
    n_out: usize,
}

/// A tanh MLP with a linear output layer, evaluated row by row.
#[derive(Debug, Clone, Default)]
pub struct HostMlp {
    layers: Vec<Dense>,
}

/// Scratch for [`HostMlp::forward`]: two activation buffers of the widest layer.
#[derive(Debug, Clone, Default)]
pub struct Scratch {
    a: Vec<f32>,
    b: Vec<f32>,
}

impl Scratch {
    /// Scratch for networks whose layers are at most `width` wide.
    pub fn wide(width: usize) -> Self {
        Self { a: vec![0.0; width], b: vec![0.0; width] }
    }
}

impl HostMlp {
    /// A copy of `mlp`'s current weights.
    pub fn from_mlp(mlp: &Mlp) -> Result<Self> {
        let mut s = Self::default();
        s.refresh(mlp)?;
        Ok(s)
    }

    /// Copies `mlp`'s current weights in (reusing the buffers).
    pub fn refresh(&mut self, mlp: &Mlp) -> Result<()> {
        let n = mlp.layer_count();
        self.layers.resize_with(n, Dense::default);
        for (i, layer) in self.layers.iter_mut().enumerate() {
            let (w, b) = mlp.layer(i);
            let (n_in, n_out) = w.var.as_tensor().dims2()?;
            layer.w.clear();
            layer.w.extend(w.var.as_tensor().flatten_all()?.to_vec1::<f32>()?);
            layer.b.clear();
            layer.b.extend(b.var.as_tensor().flatten_all()?.to_vec1::<f32>()?);
            (layer.n_in, layer.n_out) = (n_in, n_out);
        }
        Ok(())
    }

    /// Output width.
    pub fn out_dim(&self) -> usize {
        self.layers.last().map_or(0, |l| l.n_out)
    }

    /// Widest layer output.
    pub fn max_width(&self) -> usize {
        self.layers.iter().map(|l| l.n_out).max().unwrap_or(0)
    }

    /// A scratch buffer wide enough for this network.
    pub fn scratch(&self) -> Scratch {
        Scratch::wide(self.max_width())
    }

    /// `out` (length `out_dim()`) ← network(`x`) for one row.
    pub fn forward(&self, x: &[f32], scratch: &mut Scratch, out: &mut [f32]) {
        let last = self.layers.len().saturating_sub(1);
        let Scratch { a, b } = scratch;
        let (mut cur, mut next) = (a, b);
        for (i, l) in self.layers.iter().enumerate() {
            let input: &[f32] = if i == 0 { x } else { &cur[..l.n_in] };
            let dst: &mut [f32] = if i == last { &mut out[..l.n_out] } else { &mut next[..l.n_out] };
            dst.copy_from_slice(&l.b);
            // Row of x times (in × out) W: accumulate x_k · W[k, :], which vectorises over out.
            for (k, &xk) in input.iter().enumerate() {
                let row = &l.w[k * l.n_out..(k + 1) * l.n_out];
                for (d, &w) in dst.iter_mut().zip(row) {
                    *d += xk * w;
                }
            }
            if i != last {
                crate::activation::tanh_in_place(dst);
                std::mem::swap(&mut cur, &mut next);
            }
        }
    }
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
        let host = HostMlp::from_mlp(&mlp).unwrap();
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
