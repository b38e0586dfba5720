//! AdamW with global-norm gradient clipping.

use candle_core::{Result, Tensor, Var};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};

/// AdamW over a set of variables, clipping the global gradient norm before each step.
pub struct Adam {
    vars: Vec<Var>,
    opt: AdamW,
    max_grad_norm: f64,
}

impl Adam {
    /// Learning rate `lr`, no weight decay (the networks are small and the data non-stationary).
    pub fn new(vars: Vec<Var>, lr: f64, max_grad_norm: f64) -> Result<Self> {
        let opt = AdamW::new(vars.clone(), ParamsAdamW { lr, weight_decay: 0.0, ..ParamsAdamW::default() })?;
        Ok(Self { vars, opt, max_grad_norm })
    }

    /// Back-propagates `loss` and steps this optimiser's variables only.
    pub fn minimise(&mut self, loss: &Tensor) -> Result<()> {
        let mut grads = loss.backward()?;
        if self.max_grad_norm.is_finite() {
            let mut sq = 0.0f64;
            for v in &self.vars {
                if let Some(g) = grads.get(v.as_tensor()) {
                    sq += f64::from(g.sqr()?.sum_all()?.to_scalar::<f32>()?);
                }
            }
            let norm = sq.sqrt();
            if norm > self.max_grad_norm {
                let scale = self.max_grad_norm / (norm + 1e-6);
                for v in &self.vars {
                    if let Some(g) = grads.remove(v.as_tensor()) {
                        grads.insert(v.as_tensor(), (g * scale)?);
                    }
                }
            }
        }
        self.opt.step(&grads)
    }
}
