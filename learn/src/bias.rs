//! `x + b` for a (rows, n) activation and a (1, n) bias as one candle op whose gradient for
//! the bias is a contiguous column sum.
//!
//! With `broadcast_add`, candle back-propagates the bias by a generic reduction over dim 0
//! that walks strided indices element by element: it was the largest single cost of a PPO
//! update (about a fifth of the CPU time).

use crate::cpu::{contiguous_f32, with_f32};
use candle_core::{CpuStorage, CustomOp2, Layout, Result, Shape, Tensor, bail};

struct BiasAdd;

impl CustomOp2 for BiasAdd {
    fn name(&self) -> &'static str {
        "bias-add"
    }

    fn cpu_fwd(&self, s1: &CpuStorage, l1: &Layout, s2: &CpuStorage, l2: &Layout) -> Result<(CpuStorage, Shape)> {
        let (x, b) = (contiguous_f32(s1, l1)?, contiguous_f32(s2, l2)?);
        let (Ok((_, n)), Ok((1, bn))) = (l1.shape().dims2(), l2.shape().dims2()) else {
            bail!("bias-add needs (rows, n) + (1, n), got {:?} + {:?}", l1.shape(), l2.shape());
        };
        if n != bn {
            bail!("bias-add width mismatch: {:?} + {:?}", l1.shape(), l2.shape());
        }
        let mut out = x.to_vec();
        if n > 0 {
            for row in out.chunks_exact_mut(n) {
                row.iter_mut().zip(b).for_each(|(o, b)| *o += b);
            }
        }
        Ok((CpuStorage::F32(out), l1.shape().clone()))
    }

    fn bwd(&self, _x: &Tensor, b: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let grad = grad.contiguous()?;
        let n = b.dim(1)?;
        let mut sums = vec![0.0f32; n];
        if n > 0 {
            with_f32(&grad, |g| {
                for row in g.chunks_exact(n) {
                    sums.iter_mut().zip(row).for_each(|(s, g)| *s += g);
                }
            })?;
        }
        let grad_b = Tensor::from_vec(sums, (1, n), b.device())?;
        Ok((Some(grad), Some(grad_b)))
    }
}

/// `x + b` row by row, differentiable in both.
pub fn bias_add(x: &Tensor, b: &Tensor) -> Result<Tensor> {
    x.contiguous()?.apply_op2(&b.contiguous()?, BiasAdd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    #[test]
    fn matches_broadcast_add_and_its_gradients() -> Result<()> {
        let x = Var::new(&[[1.0f32, 2.0, 3.0], [-4.0, 0.5, 6.0]], &Device::Cpu)?;
        let b = Var::new(&[[0.1f32, -0.2, 0.3]], &Device::Cpu)?;
        let w = Tensor::new(&[[1.0f32, 2.0, 3.0], [4.0, 5.0, 6.0]], &Device::Cpu)?;
        let ours = bias_add(x.as_tensor(), b.as_tensor())?;
        let reference = x.as_tensor().broadcast_add(b.as_tensor())?;
        assert_eq!(ours.to_vec2::<f32>()?, reference.to_vec2::<f32>()?);
        let g1 = (ours * &w)?.sum_all()?.backward()?;
        let g2 = (reference * &w)?.sum_all()?.backward()?;
        for v in [&x, &b] {
            let (a, r) = (g1.get(v.as_tensor()), g2.get(v.as_tensor()));
            let (Some(a), Some(r)) = (a, r) else { panic!("missing gradient") };
            assert_eq!(a.to_vec2::<f32>()?, r.to_vec2::<f32>()?);
        }
        assert_eq!(g1.get(b.as_tensor()).map(|g| g.to_vec2::<f32>()).transpose()?, Some(vec![vec![5.0, 7.0, 9.0]]));
        Ok(())
    }

    #[test]
    fn rejects_mismatched_widths() -> Result<()> {
        let x = Tensor::zeros((2, 3), candle_core::DType::F32, &Device::Cpu)?;
        let b = Tensor::zeros((1, 2), candle_core::DType::F32, &Device::Cpu)?;
        assert!(bias_add(&x, &b).is_err());
        Ok(())
    }
}
