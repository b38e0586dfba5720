//! A GRU cell (Cho et al. 2014) on candle, differentiable through time, weights from our Rng.

use crate::LearnError;
use crate::bias::bias_add;
use crate::nn::{Param, const_param, uniform_param};
use candle_core::{Result, Tensor};
use risktwin_common::rng::Rng;
use risktwin_policy::{Dense, HostGru};

/// h' = (1 − z)⊙n + z⊙h, r = σ(x·W_r + h·U_r + b_r), z = σ(…), n = tanh(x·W_n + b_n + r⊙(h·U_n + c_n)).
#[derive(Debug, Clone)]
pub struct GruCell {
    w_x: Param,
    w_h: Param,
    b_x: Param,
    b_h: Param,
    hidden: usize,
}

/// Logistic sigmoid through tanh (σ(x) = (tanh(x/2) + 1)/2), whose gradient candle has.
fn sigmoid(x: &Tensor) -> Result<Tensor> {
    (x * 0.5)?.tanh()?.affine(0.5, 0.5)
}

impl GruCell {
    /// A cell from `input` features to `hidden` units; uniform ±1/√hidden as in PyTorch.
    pub fn new(prefix: &str, input: usize, hidden: usize, rng: &mut Rng) -> Result<Self> {
        let bound = 1.0 / (hidden as f64).sqrt();
        Ok(Self {
            w_x: uniform_param(format!("{prefix}.w_x"), (input, 3 * hidden), bound, rng)?,
            w_h: uniform_param(format!("{prefix}.w_h"), (hidden, 3 * hidden), bound, rng)?,
            b_x: const_param(format!("{prefix}.b_x"), (1, 3 * hidden), 0.0)?,
            b_h: const_param(format!("{prefix}.b_h"), (1, 3 * hidden), 0.0)?,
            hidden,
        })
    }

    /// Hidden units.
    pub fn hidden(&self) -> usize {
        self.hidden
    }

    /// One step: `x` (batch, input), `h` (batch, hidden) → h' (batch, hidden).
    pub fn step(&self, x: &Tensor, h: &Tensor) -> Result<Tensor> {
        let n = self.hidden;
        let gx = bias_add(&x.matmul(self.w_x.var.as_tensor())?, self.b_x.var.as_tensor())?;
        let gh = bias_add(&h.matmul(self.w_h.var.as_tensor())?, self.b_h.var.as_tensor())?;
        let r = sigmoid(&(gx.narrow(1, 0, n)? + gh.narrow(1, 0, n)?)?)?;
        let z = sigmoid(&(gx.narrow(1, n, n)? + gh.narrow(1, n, n)?)?)?;
        let cand = (gx.narrow(1, 2 * n, n)? + (r * gh.narrow(1, 2 * n, n)?)?)?.tanh()?;
        // (1 − z)⊙n + z⊙h = n + z⊙(h − n)
        &cand + (z * (h - &cand)?)?
    }

    /// Every parameter.
    pub fn params(&self) -> impl Iterator<Item = &Param> {
        [&self.w_x, &self.w_h, &self.b_x, &self.b_h].into_iter()
    }

    /// A host copy of the cell's current weights (acting without tensors: rollouts,
    /// evaluation, the edge).
    pub fn host(&self) -> std::result::Result<HostGru, LearnError> {
        let dense = |w: &Param, b: &Param| -> std::result::Result<Dense, LearnError> {
            let (n_in, n_out) = w.var.as_tensor().dims2()?;
            let values = |p: &Param| p.var.as_tensor().flatten_all().and_then(|t| t.to_vec1::<f32>());
            Ok(Dense::new(&w.name, values(w)?, values(b)?, n_in, n_out)?)
        };
        Ok(HostGru::new(dense(&self.w_x, &self.b_x)?, dense(&self.w_h, &self.b_h)?)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::matrix;

    /// The host cell steps as the candle cell does, state carried over ten steps.
    #[test]
    fn the_host_cell_steps_as_the_candle_cell() {
        let mut rng = Rng::new(9);
        let cell = GruCell::new("g", 5, 4, &mut rng).expect("a cell");
        // Non-zero biases, so that their places are checked too.
        for p in [&cell.b_x, &cell.b_h] {
            let v: Vec<f32> = (0..12).map(|_| rng.uniform(-0.5, 0.5) as f32).collect();
            p.var.set(&matrix(&v, 1, 12).expect("a row")).expect("set");
        }
        let host = cell.host().expect("a host cell");
        let (mut h, mut scratch) = (vec![0.0f32; 4], host.scratch());
        let mut h_candle = matrix(&[0.0; 4], 1, 4).expect("a row");
        for _ in 0..10 {
            let x: Vec<f32> = (0..5).map(|_| rng.uniform(-2.0, 2.0) as f32).collect();
            host.step(&x, &mut h, &mut scratch);
            h_candle = cell.step(&matrix(&x, 1, 5).expect("a row"), &h_candle).expect("a step");
            let want = h_candle.flatten_all().and_then(|t| t.to_vec1::<f32>()).expect("values");
            for (g, w) in h.iter().zip(&want) {
                assert!((g - w).abs() < 1e-5, "{h:?} vs {want:?}");
            }
        }
    }
}
