//! AdamW with global-norm gradient clipping, stepped on the host.
//!
//! candle_nn's `AdamW` spends about a dozen tensor ops (each a fresh buffer) per variable and
//! step, and the norm clipping three more: for these small networks that op overhead was a
//! larger share of a PPO update than the forward and backward passes. Here the moments live in
//! plain vectors, the gradients are read in place and each variable is written once per step.
//! The arithmetic is candle's AdamW (bias-corrected moments, ε outside the square root) with
//! no weight decay.

use crate::cpu::with_f32;
use candle_core::{Result, Tensor, Var};

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPS: f64 = 1e-8;

/// One variable with its moments and a staging buffer for its next value.
struct Slot {
    var: Var,
    m: Vec<f32>,
    v: Vec<f32>,
    next: Vec<f32>,
}

/// AdamW over a set of variables, clipping the global gradient norm before each step.
pub struct Adam {
    slots: Vec<Slot>,
    lr: f64,
    max_grad_norm: f64,
    step_t: i32,
}

impl Adam {
    /// Learning rate `lr`, no weight decay (the networks are small and the data non-stationary).
    pub fn new(vars: Vec<Var>, lr: f64, max_grad_norm: f64) -> Result<Self> {
        let slots = vars
            .into_iter()
            .map(|var| {
                let n = var.elem_count();
                Slot { var, m: vec![0.0; n], v: vec![0.0; n], next: vec![0.0; n] }
            })
            .collect();
        Ok(Self { slots, lr, max_grad_norm, step_t: 0 })
    }

    /// Back-propagates `loss` and steps this optimiser's variables only.
    pub fn minimise(&mut self, loss: &Tensor) -> Result<()> {
        let grads = loss.backward()?;
        let mut sq = 0.0f64;
        for slot in &self.slots {
            if let Some(g) = grads.get(slot.var.as_tensor()) {
                sq += with_f32(g, |g| g.iter().map(|&x| f64::from(x) * f64::from(x)).sum::<f64>())?;
            }
        }
        let norm = sq.sqrt();
        let clip = if self.max_grad_norm.is_finite() && norm > self.max_grad_norm {
            self.max_grad_norm / (norm + 1e-6)
        } else {
            1.0
        };
        self.step_t += 1;
        let scale_m = 1.0 / (1.0 - BETA1.powi(self.step_t));
        let scale_v = 1.0 / (1.0 - BETA2.powi(self.step_t));
        let (b1, b2, lr, eps) = (BETA1 as f32, BETA2 as f32, self.lr as f32, EPS as f32);
        let (scale_m, scale_v, clip) = (scale_m as f32, scale_v as f32, clip as f32);
        for slot in &mut self.slots {
            let Some(g) = grads.get(slot.var.as_tensor()) else { continue };
            let Slot { var, m, v, next } = slot;
            with_f32(var.as_tensor(), |theta| next.copy_from_slice(theta))?;
            with_f32(g, |g| {
                for (((&g, m), v), th) in g.iter().zip(m.iter_mut()).zip(v.iter_mut()).zip(next.iter_mut()) {
                    let g = g * clip;
                    *m = b1 * *m + (1.0 - b1) * g;
                    *v = b2 * *v + (1.0 - b2) * g * g;
                    *th -= lr * (*m * scale_m) / ((*v * scale_v).sqrt() + eps);
                }
            })?;
            var.set(&Tensor::from_slice(next, var.shape(), var.device())?)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;
    use candle_nn::{AdamW, Optimizer, ParamsAdamW};

    fn quadratic(x: &Var) -> Result<Tensor> {
        let target = Tensor::new(&[[1.0f32, -2.0], [0.5, 3.0]], &Device::Cpu)?;
        (x.as_tensor() - target)?.sqr()?.sum_all()
    }

    #[test]
    fn matches_candle_adamw_without_clipping() -> Result<()> {
        let start = Tensor::new(&[[0.0f32, 0.3], [-0.7, 2.0]], &Device::Cpu)?;
        let (ours_x, ref_x) = (Var::from_tensor(&start)?, Var::from_tensor(&start)?);
        let mut ours = Adam::new(vec![ours_x.clone()], 0.05, f64::INFINITY)?;
        let params = ParamsAdamW { lr: 0.05, weight_decay: 0.0, ..ParamsAdamW::default() };
        let mut reference = AdamW::new(vec![ref_x.clone()], params)?;
        for _ in 0..50 {
            ours.minimise(&quadratic(&ours_x)?)?;
            reference.backward_step(&quadratic(&ref_x)?)?;
        }
        let (a, b) = (ours_x.flatten_all()?.to_vec1::<f32>()?, ref_x.flatten_all()?.to_vec1::<f32>()?);
        for (a, b) in a.iter().zip(&b) {
            assert!((a - b).abs() < 1e-5, "ours {a:?} vs candle {b:?}");
        }
        assert!(a.iter().zip([1.0f32, -2.0, 0.5, 3.0]).any(|(x, t)| (x - t).abs() < 1.0), "it moved: {a:?}");
        Ok(())
    }

    #[test]
    fn clipping_bounds_the_first_step() -> Result<()> {
        // Adam's first step is lr·sign(g) whatever the scale, so clip via a huge gradient and
        // check the step is still lr per coordinate and finite.
        let x = Var::from_tensor(&Tensor::new(&[[1e4f32, -1e4], [0.0, 0.0]], &Device::Cpu)?)?;
        let mut opt = Adam::new(vec![x.clone()], 0.1, 0.5)?;
        opt.minimise(&quadratic(&x)?)?;
        let after = x.flatten_all()?.to_vec1::<f32>()?;
        assert!((after[0] - (1e4 - 0.1)).abs() < 1e-2 && (after[1] - (-1e4 + 0.1)).abs() < 1e-2, "{after:?}");
        assert!(after.iter().all(|v| v.is_finite()));
        Ok(())
    }
}
