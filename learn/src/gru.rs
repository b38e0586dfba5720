//! A GRU cell (Cho et al. 2014) on candle, differentiable through time, weights from our Rng.

use crate::nn::{Param, const_param, uniform_param};
use candle_core::{Result, Tensor};
use risktwin_common::rng::Rng;

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
        let gx = x.matmul(self.w_x.var.as_tensor())?.broadcast_add(self.b_x.var.as_tensor())?;
        let gh = h.matmul(self.w_h.var.as_tensor())?.broadcast_add(self.b_h.var.as_tensor())?;
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
}
