//! Small networks on candle (CPU, f32) whose weights are initialised from our own seeded
//! [`Rng`], so a training run is reproducible bit for bit for a seed.

use candle_core::{DType, Device, Result, Tensor, Var};
use risktwin_common::rng::Rng;
use std::collections::HashMap;

/// ln(2π)/2, the Gaussian log-density constant.
pub const HALF_LN_TAU: f32 = 0.918_938_5;

/// A named trainable tensor.
#[derive(Debug, Clone)]
pub struct Param {
    pub name: String,
    pub var: Var,
}

/// A parameter of `shape` with entries uniform in ±`bound`, drawn from `rng`.
pub fn uniform_param(name: String, shape: (usize, usize), bound: f64, rng: &mut Rng) -> Result<Param> {
    let data: Vec<f32> = (0..shape.0 * shape.1).map(|_| rng.uniform(-bound, bound) as f32).collect();
    Ok(Param { name, var: Var::from_tensor(&Tensor::from_vec(data, shape, &Device::Cpu)?)? })
}

/// A parameter of `shape` filled with `value`.
pub fn const_param(name: String, shape: (usize, usize), value: f32) -> Result<Param> {
    Ok(Param { name, var: Var::from_tensor(&Tensor::full(value, shape, &Device::Cpu)?)? })
}

/// A multilayer perceptron with tanh hidden activations ([`crate::activation::tanh`]) and a
/// linear output.
#[derive(Debug, Clone)]
pub struct Mlp {
    layers: Vec<(Param, Param)>,
}

impl Mlp {
    /// Layers `sizes[0] → sizes[1] → …`; Xavier-uniform weights (tanh gain 5/3), the output
    /// layer scaled by `out_gain` (small for a policy mean so the first actions are near 0).
    pub fn new(prefix: &str, sizes: &[usize], out_gain: f64, rng: &mut Rng) -> Result<Self> {
        let mut layers = Vec::with_capacity(sizes.len().saturating_sub(1));
        for (i, win) in sizes.windows(2).enumerate() {
            let (fan_in, fan_out) = (win[0], win[1]);
            let last = i + 2 == sizes.len();
            let gain = if last { out_gain } else { 5.0 / 3.0 };
            let bound = gain * (6.0 / (fan_in + fan_out) as f64).sqrt();
            let w = uniform_param(format!("{prefix}.{i}.weight"), (fan_in, fan_out), bound, rng)?;
            let b = const_param(format!("{prefix}.{i}.bias"), (1, fan_out), 0.0)?;
            layers.push((w, b));
        }
        Ok(Self { layers })
    }

    /// `x` of shape (batch, in) → (batch, out).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut h = x.clone();
        for (i, (w, b)) in self.layers.iter().enumerate() {
            h = h.matmul(w.var.as_tensor())?.broadcast_add(b.var.as_tensor())?;
            if i + 1 < self.layers.len() {
                h = crate::activation::tanh_tensor(&h)?;
            }
        }
        Ok(h)
    }

    /// Every parameter.
    pub fn params(&self) -> impl Iterator<Item = &Param> {
        self.layers.iter().flat_map(|(w, b)| [w, b])
    }

    /// Number of layers.
    pub fn layer_count(&self) -> usize {
        self.layers.len()
    }

    /// Weight (in × out) and bias (1 × out) of layer `i` (panics when out of range).
    pub fn layer(&self, i: usize) -> (&Param, &Param) {
        let (w, b) = &self.layers[i];
        (w, b)
    }
}

/// The trainable variables of `params`.
pub fn vars<'a>(params: impl IntoIterator<Item = &'a Param>) -> Vec<Var> {
    params.into_iter().map(|p| p.var.clone()).collect()
}

/// Copies `params`' values out of a loaded tensor map; errors name the missing or misshapen one.
pub fn load_params<'a>(
    params: impl IntoIterator<Item = &'a Param>,
    tensors: &HashMap<String, Tensor>,
) -> std::result::Result<(), crate::LearnError> {
    for p in params {
        let t = tensors.get(&p.name).ok_or_else(|| crate::LearnError::MissingTensor(p.name.clone()))?;
        if t.dims() != p.var.dims() {
            return Err(crate::LearnError::TensorShape {
                name: p.name.clone(),
                expected: p.var.dims().to_vec(),
                found: t.dims().to_vec(),
            });
        }
        p.var.set(&t.to_dtype(DType::F32)?)?;
    }
    Ok(())
}

/// `target ← τ·source + (1 − τ)·target` (Polyak averaging), parameter by parameter.
pub fn polyak<'a>(
    target: impl IntoIterator<Item = &'a Param>,
    source: impl IntoIterator<Item = &'a Param>,
    tau: f64,
) -> Result<()> {
    for (t, s) in target.into_iter().zip(source) {
        let mixed = ((s.var.as_tensor() * tau)? + (t.var.as_tensor() * (1.0 - tau))?)?;
        t.var.set(&mixed)?;
    }
    Ok(())
}

/// A (rows, cols) tensor from a row-major slice.
pub fn matrix(data: &[f32], rows: usize, cols: usize) -> Result<Tensor> {
    Tensor::from_slice(data, (rows, cols), &Device::Cpu)
}

/// `n` standard normal samples from `rng`.
pub fn normals(rng: &mut Rng, n: usize, out: &mut Vec<f32>) {
    out.clear();
    out.extend((0..n).map(|_| rng.normal() as f32));
}
