//! A GRU cell on the host: the `learn` crate's candle cell (Cho et al. 2014) evaluated row by
//! row, so that a recurrent policy acts at the edge and in evaluation without a tensor library.
//!
//! r = σ(x·W_r + b_r + h·U_r + c_r), z = σ(x·W_z + b_z + h·U_z + c_z),
//! n = tanh(x·W_n + b_n + r⊙(h·U_n + c_n)), h′ = n + z⊙(h − n),
//! with the three gates side by side in one (in × 3h) and one (h × 3h) matrix, r first, as the
//! candle cell stores them (`<prefix>.w_x`, `.w_h`, `.b_x`, `.b_h`). The candle cell takes tanh
//! and σ from candle (libm's tanh, σ(x) = (tanh(x/2) + 1)/2), and so does this one: the fast
//! tanh of the MLPs would differ from it by a few ULP, compounding over an episode.

use super::{Dense, NetError};

/// A GRU cell: the input and the state maps, each to the three gates.
#[derive(Debug, Clone, PartialEq)]
pub struct HostGru {
    x: Dense,
    h: Dense,
}

/// Gate pre-activations of one step: input part and state part, 3·hidden each.
#[derive(Debug, Clone, Default)]
pub struct GruScratch {
    gx: Vec<f32>,
    gh: Vec<f32>,
}

fn sigmoid(v: f32) -> f32 {
    ((v * 0.5).tanh() + 1.0) * 0.5
}

impl HostGru {
    /// A cell of `x` (input → 3·hidden) and `h` (hidden → 3·hidden).
    pub fn new(x: Dense, h: Dense) -> Result<Self, NetError> {
        let hidden = h.n_in();
        if h.n_out() != 3 * hidden {
            return Err(NetError::Chain { layer: 1, n_in: h.n_out(), previous_out: 3 * hidden });
        }
        if x.n_out() != 3 * hidden {
            return Err(NetError::Chain { layer: 0, n_in: x.n_out(), previous_out: 3 * hidden });
        }
        Ok(Self { x, h })
    }

    /// Input width.
    pub fn input(&self) -> usize {
        self.x.n_in()
    }

    /// State width.
    pub fn hidden(&self) -> usize {
        self.h.n_in()
    }

    /// The input map and the state map.
    pub fn maps(&self) -> (&Dense, &Dense) {
        (&self.x, &self.h)
    }

    /// Scratch for [`HostGru::step`].
    pub fn scratch(&self) -> GruScratch {
        GruScratch { gx: vec![0.0; 3 * self.hidden()], gh: vec![0.0; 3 * self.hidden()] }
    }

    /// `h` ← the state after input `x` (one row), allocation-free.
    pub fn step(&self, x: &[f32], h: &mut [f32], scratch: &mut GruScratch) {
        let n = self.hidden();
        let GruScratch { gx, gh } = scratch;
        self.x.apply(x, gx);
        self.h.apply(h, gh);
        for j in 0..n {
            let r = sigmoid(gx[j] + gh[j]);
            let z = sigmoid(gx[n + j] + gh[n + j]);
            let cand = (gx[2 * n + j] + r * gh[2 * n + j]).tanh();
            h[j] = cand + z * (h[j] - cand);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_follows_the_gate_equations() {
        // One input, one state unit: every gate's weights written out.
        let x = Dense::new("x", vec![0.5, -1.0, 2.0], vec![0.1, 0.2, -0.3], 1, 3).expect("a layer");
        let h = Dense::new("h", vec![1.5, 0.25, -0.5], vec![0.0, -0.1, 0.4], 1, 3).expect("a layer");
        let cell = HostGru::new(x, h).expect("a cell");
        let (xv, hv) = (0.7f32, -0.4f32);
        let sig = |v: f32| 1.0 / (1.0 + (-v).exp());
        let r = sig(0.5 * xv + 0.1 + 1.5 * hv);
        let z = sig(-xv + 0.2 + 0.25 * hv - 0.1);
        let n = (2.0 * xv - 0.3 + r * (-0.5 * hv + 0.4)).tanh();
        let want = (1.0 - z) * n + z * hv;
        let mut state = [hv];
        cell.step(&[xv], &mut state, &mut cell.scratch());
        assert!((state[0] - want).abs() < 1e-6, "{} vs {want}", state[0]);
    }

    #[test]
    fn gate_widths_must_be_three_states() {
        let x = Dense::new("x", vec![0.0; 6], vec![0.0; 6], 1, 6).expect("a layer");
        let h = Dense::new("h", vec![0.0; 4], vec![0.0; 2], 2, 2).expect("a layer");
        assert!(matches!(HostGru::new(x, h), Err(NetError::Chain { .. })));
    }
}
