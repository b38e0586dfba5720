//! A fast, vectorisable tanh for the hidden layers, shared by the candle networks (as a custom
//! op with its gradient) and their host-side copies, so learning and acting compute the same
//! function. libm's `tanhf` was the largest single cost of training (about 28 % of CPU time).
//!
//! The approximation is the clamped rational 13/6 fit used by Eigen's `ptanh` for f32: within
//! a few ULP of tanh on [−7.99, 7.99], ±1 beyond (where tanh is 1 to f32 precision).

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor, bail};

// The constants are Eigen's, kept to their published digits.
#[allow(clippy::excessive_precision)]
const CLAMP: f32 = 7.998_811_7;
#[allow(clippy::excessive_precision)]
const A1: f32 = 4.893_524_6e-3;
#[allow(clippy::excessive_precision)]
const A3: f32 = 6.372_619_3e-4;
#[allow(clippy::excessive_precision)]
const A5: f32 = 1.485_722_4e-5;
#[allow(clippy::excessive_precision)]
const A7: f32 = 5.122_297e-8;
#[allow(clippy::excessive_precision)]
const A9: f32 = -8.604_671_5e-11;
#[allow(clippy::excessive_precision)]
const A11: f32 = 2.000_187_9e-13;
#[allow(clippy::excessive_precision)]
const A13: f32 = -2.760_768_5e-16;
#[allow(clippy::excessive_precision)]
const B0: f32 = 4.893_525_2e-3;
#[allow(clippy::excessive_precision)]
const B2: f32 = 2.268_434_6e-3;
#[allow(clippy::excessive_precision)]
const B4: f32 = 1.185_347_1e-4;
#[allow(clippy::excessive_precision)]
const B6: f32 = 1.198_258_4e-6;

/// tanh(x) to a few ULP, branch-free apart from the clamp (NaN stays NaN).
#[inline]
pub fn tanh(x: f32) -> f32 {
    let x = x.clamp(-CLAMP, CLAMP);
    let x2 = x * x;
    let mut p = x2 * A13 + A11;
    p = x2 * p + A9;
    p = x2 * p + A7;
    p = x2 * p + A5;
    p = x2 * p + A3;
    p = x2 * p + A1;
    p *= x;
    let mut q = x2 * B6 + B4;
    q = x2 * q + B2;
    q = x2 * q + B0;
    p / q
}

/// Applies [`tanh`] in place.
pub fn tanh_in_place(xs: &mut [f32]) {
    xs.iter_mut().for_each(|v| *v = tanh(*v));
}

/// [`tanh`] as a candle op with the gradient 1 − tanh².
struct FastTanh;

impl CustomOp1 for FastTanh {
    fn name(&self) -> &'static str {
        "fast-tanh"
    }

    fn cpu_fwd(&self, storage: &CpuStorage, layout: &Layout) -> Result<(CpuStorage, Shape)> {
        let (CpuStorage::F32(data), Some((start, end))) = (storage, layout.contiguous_offsets()) else {
            bail!("fast-tanh needs a contiguous f32 tensor (layout {layout:?})");
        };
        let mut out = data[start..end].to_vec();
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
    fn matches_libm_tanh() {
        let mut worst = 0.0f32;
        for i in -20_000..=20_000 {
            let x = i as f32 * 1e-3;
            worst = worst.max((tanh(x) - x.tanh()).abs());
        }
        assert!(worst < 2e-6, "max error {worst}");
        assert_eq!(tanh(100.0), 1.0f32.min(tanh(100.0)));
        assert!((tanh(100.0) - 1.0).abs() < 1e-6 && (tanh(-100.0) + 1.0).abs() < 1e-6);
    }

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
