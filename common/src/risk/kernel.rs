//! A lookup table of the Gaussian factor exp(−d²/(2σ²)) indexed by d², cut off at ε, so the
//! grid fill's inner loop needs neither `sqrt` nor `exp`.
//!
//! The table covers u = d²/(2σ²) ∈ [0, ln(1/ε)) in `GAUSS_TABLE_LEN` equal bins of width
//! h = ln(1/ε)/N, each holding exp(−u) at its bin centre, plus a trailing 0 that every u beyond
//! the cut-off maps to (branch-free lookup). Since |d/du exp(−u)| ≤ 1, a bin's value is within
//! h/2 of the exact factor (≈ 4.2e-4 for ε = 1e-3, N = 8192); beyond the cut-off the exact
//! factor is below ε. So the table's absolute error is at most max(ε, h/2).

/// Number of bins (32 KiB of `f32`: stays in L1/L2 while an object's window is filled).
pub const GAUSS_TABLE_LEN: usize = 8192;

/// exp(−d²/(2σ²)) tabulated over d², zero beyond the cut-off.
#[derive(Debug, Clone)]
pub struct GaussTable {
    values: Vec<f32>,
    /// Multiplies d² (m²) into a bin index.
    index_per_m2: f64,
    /// Largest absolute error of a lookup against the exact factor.
    max_error: f64,
}

impl GaussTable {
    /// The table for standard deviation `sigma_m` and cut-off `eps` ∈ (0, 1).
    pub fn new(sigma_m: f64, eps: f64) -> Self {
        let eps = if eps > 0.0 && eps < 1.0 { eps } else { 1e-3 };
        let u_max = (1.0 / eps).ln();
        let h = u_max / GAUSS_TABLE_LEN as f64;
        let mut values: Vec<f32> = (0..GAUSS_TABLE_LEN).map(|k| (-(k as f64 + 0.5) * h).exp() as f32).collect();
        values.push(0.0);
        let two_sigma_sq = 2.0 * sigma_m * sigma_m;
        Self { values, index_per_m2: 1.0 / (two_sigma_sq * h), max_error: eps.max(0.5 * h) }
    }

    /// The factor for a squared distance `d_sq_m2` ≥ 0.
    #[inline(always)]
    pub fn lookup(&self, d_sq_m2: f64) -> f32 {
        // `as usize` saturates (NaN → 0), and `min` sends everything past the cut-off to the 0.
        let idx = ((d_sq_m2 * self.index_per_m2) as usize).min(GAUSS_TABLE_LEN);
        self.values[idx]
    }

    /// Largest absolute error of [`GaussTable::lookup`] against exp(−d²/(2σ²)).
    pub fn max_error(&self) -> f64 {
        self.max_error
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_error_is_within_the_stated_bound() {
        let sigma = 2.0;
        let t = GaussTable::new(sigma, 1e-3);
        assert!((t.max_error() - 1e-3).abs() < 1e-15);
        let mut worst: f64 = 0.0;
        for k in 0..20_000 {
            let d = k as f64 * 0.001;
            let exact = (-d * d / (2.0 * sigma * sigma)).exp();
            worst = worst.max((t.lookup(d * d) as f64 - exact).abs());
        }
        assert!(worst <= t.max_error() + 1e-7, "worst {worst}");
        // Inside the cut-off the error is the bin's, well below ε.
        assert!((t.lookup(0.0) as f64 - 1.0).abs() < 4.3e-4);
        assert_eq!(t.lookup(1e9), 0.0);
        assert_eq!(t.lookup(f64::INFINITY), 0.0);
    }
}
