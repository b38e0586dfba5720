//! A fast, vectorisable tanh for the hidden layers of the policy networks, shared by learning
//! (the `learn` crate's candle op) and acting on the host ([`super::HostMlp`]), so both compute
//! the same function. libm's `tanhf` was the largest single cost of training (about 28 % of CPU
//! time).
//!
//! The approximation is the clamped rational 13/6 fit used by Eigen's `ptanh` for f32: within
//! a few ULP of tanh on [−7.99, 7.99], ±1 beyond (where tanh is 1 to f32 precision).

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
        assert!((tanh(100.0) - 1.0).abs() < 1e-6 && (tanh(-100.0) + 1.0).abs() < 1e-6);
        assert!(tanh(f32::NAN).is_nan());
    }
}
