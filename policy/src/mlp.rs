//! A tanh MLP with a linear output layer, evaluated row by row in plain Rust: the host-side
//! form of the `learn` crate's candle networks, allocation-free per row once the scratch
//! buffers exist.

use super::NetError;
use super::tanh::tanh_in_place;

/// One dense layer: `w` is (in × out) row-major, as the candle parameter and the policy file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Dense {
    w: Vec<f32>,
    b: Vec<f32>,
    n_in: usize,
    n_out: usize,
}

impl Dense {
    /// A layer of `n_in` inputs and `n_out` outputs; `w` must hold n_in·n_out values, `b` n_out,
    /// all finite.
    pub fn new(name: &str, w: Vec<f32>, b: Vec<f32>, n_in: usize, n_out: usize) -> Result<Self, NetError> {
        let check = |what: &str, found: usize, expected: usize| {
            (found == expected).then_some(()).ok_or_else(|| NetError::LayerSize {
                layer: format!("{name}.{what}"),
                found,
                expected,
            })
        };
        check("weight", w.len(), n_in * n_out)?;
        check("bias", b.len(), n_out)?;
        if n_in == 0 || n_out == 0 {
            return Err(NetError::LayerSize { layer: name.to_owned(), found: 0, expected: 1 });
        }
        if let Some(index) = w.iter().chain(&b).position(|v| !v.is_finite()) {
            return Err(NetError::NonFinite { layer: name.to_owned(), index });
        }
        Ok(Self { w, b, n_in, n_out })
    }

    /// Inputs of the layer.
    pub fn n_in(&self) -> usize {
        self.n_in
    }

    /// Outputs of the layer.
    pub fn n_out(&self) -> usize {
        self.n_out
    }
}

/// A tanh MLP with a linear output layer.
#[derive(Debug, Clone, Default, PartialEq)]
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
    /// The network of `layers` in order; each layer's inputs must be the previous one's outputs.
    pub fn from_layers(layers: Vec<Dense>) -> Result<Self, NetError> {
        if layers.is_empty() {
            return Err(NetError::NoLayers);
        }
        for (i, pair) in layers.windows(2).enumerate() {
            if pair[1].n_in != pair[0].n_out {
                return Err(NetError::Chain { layer: i + 1, n_in: pair[1].n_in, previous_out: pair[0].n_out });
            }
        }
        Ok(Self { layers })
    }

    /// Input width (0 for the empty default network).
    pub fn in_dim(&self) -> usize {
        self.layers.first().map_or(0, |l| l.n_in)
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

    /// `out` (length `out_dim()`) ← network(`x`) for one row (`x` of length `in_dim()`,
    /// `scratch` from [`HostMlp::scratch`]).
    pub fn forward(&self, x: &[f32], scratch: &mut Scratch, out: &mut [f32]) {
        let last = self.layers.len().saturating_sub(1);
        let Scratch { a, b } = scratch;
        let (mut cur, mut next) = (a, b);
        for (i, l) in self.layers.iter().enumerate() {
            let input: &[f32] = if i == 0 { x } else { &cur[..l.n_in] };
            let dst: &mut [f32] = if i == last { &mut out[..l.n_out] } else { &mut next[..l.n_out] };
            l.apply(input, dst);
            if i != last {
                tanh_in_place(dst);
                std::mem::swap(&mut cur, &mut next);
            }
        }
    }

    /// The layers, input first.
    pub fn layers(&self) -> &[Dense] {
        &self.layers
    }
}

impl Dense {
    /// `out` (length `n_out`) ← `x`·W + b for one row `x` (length `n_in`).
    pub fn apply(&self, x: &[f32], out: &mut [f32]) {
        out.copy_from_slice(&self.b);
        // Row of x times (in × out) W: accumulate x_k · W[k, :], which vectorises over out.
        for (&xk, row) in x.iter().zip(self.w.chunks_exact(self.n_out)) {
            for (d, &w) in out.iter_mut().zip(row) {
                *d += xk * w;
            }
        }
    }

    /// Weights, (in × out) row-major.
    pub fn weight(&self) -> &[f32] {
        &self.w
    }

    /// Biases.
    pub fn bias(&self) -> &[f32] {
        &self.b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_is_tanh_of_the_affine_map_then_linear() {
        // 2 → 2 → 1: hidden = tanh(x·W0 + b0), out = hidden·W1 + b1.
        let l0 = Dense::new("l0", vec![1.0, 0.0, 0.0, 2.0], vec![0.5, -0.5], 2, 2).expect("a layer");
        let l1 = Dense::new("l1", vec![1.0, -1.0], vec![0.25], 2, 1).expect("a layer");
        let net = HostMlp::from_layers(vec![l0, l1]).expect("a chain");
        let mut scratch = net.scratch();
        let mut out = [0.0f32];
        net.forward(&[0.3, -0.2], &mut scratch, &mut out);
        let h = [(0.3f32 + 0.5).tanh(), (-0.4f32 - 0.5).tanh()];
        let want = h[0] - h[1] + 0.25;
        assert!((out[0] - want).abs() < 1e-5, "{} vs {want}", out[0]);
    }

    #[test]
    fn bad_layers_are_typed_errors() {
        assert!(matches!(Dense::new("x", vec![0.0; 5], vec![0.0; 2], 2, 3), Err(NetError::LayerSize { .. })));
        assert!(matches!(
            Dense::new("x", vec![f32::NAN, 0.0], vec![0.0], 2, 1),
            Err(NetError::NonFinite { index: 0, .. })
        ));
        let a = Dense::new("a", vec![0.0; 6], vec![0.0; 3], 2, 3).expect("a layer");
        let b = Dense::new("b", vec![0.0; 4], vec![0.0; 2], 2, 2).expect("a layer");
        assert!(matches!(
            HostMlp::from_layers(vec![a, b]),
            Err(NetError::Chain { layer: 1, n_in: 2, previous_out: 3 })
        ));
        assert!(matches!(HostMlp::from_layers(vec![]), Err(NetError::NoLayers)));
    }
}
