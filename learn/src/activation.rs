//! The fast tanh of [`risktwin_policy::tanh`] as a differentiable candle op, so the
//! candle networks learn with exactly the function their host-side copies act with.

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor};
pub use risktwin_policy::tanh::{tanh, tanh_in_place};

/// [`tanh`] as a candle op with the gradient 1 − tanh².
struct FastTanh;

impl CustomOp1 for FastTanh {
    fn name(&self) -> &'static str {
        "fast-tanh"
    }

    fn cpu_fwd(&self, storage: &CpuStorage, layout: &Layout) -> Result<(CpuStorage, Shape)> {
        let mut out = crate::cpu::contiguous_f32(storage, layout)?.to_vec();
        tanh_in_place(&mut out);
        Ok((CpuStorage::F32(out), layout.shape().clone()))
    }

    fn bwd(&self, _arg: &Tensor, res: &Tensor, grad_res: &Tensor) -> Result<Option<Tensor>> {
        Ok(Some((grad_res * res.sqr()?.affine(-1.0, 1.0)?)?))
    }
}

/// tanh of a tensor through the fast approximation, differentiable.
pub fn tanh_tensor(x: &Tensor) -> Result<Tensor> {
    x.contiguous()?.apply_op1(FastTanh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_is_one_minus_square() {
        let x = candle_core::Var::new(&[[0.3f32, -1.2, 2.0]], &candle_core::Device::Cpu).unwrap();
        let y = tanh_tensor(x.as_tensor()).unwrap();
        let g = y.sum_all().unwrap().backward().unwrap();
        let got = g.get(x.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f32>().unwrap();
        for (g, x) in got.iter().zip([0.3f32, -1.2, 2.0]) {
            assert!((g - (1.0 - x.tanh().powi(2))).abs() < 1e-5, "{got:?}");
        }
    }
}
