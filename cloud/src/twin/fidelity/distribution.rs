//! A running distribution of non-negative errors in fixed memory: count, mean, max exactly, the
//! 95th percentile to a histogram bin.

use serde::Serialize;

/// Histogram bins of every distribution; errors beyond the last bin's edge land in it.
const BINS: usize = 2000;

/// What a distribution says, in the unit of the field that holds it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    pub n: u64,
    pub mean: f64,
    /// 95th percentile, to the histogram bin (its upper edge), never above `max`.
    pub p95: f64,
    pub max: f64,
}

#[derive(Debug, Clone)]
pub(crate) struct Distribution {
    bin: f64,
    n: u64,
    sum: f64,
    max: f64,
    histogram: Vec<u32>,
}

impl Distribution {
    /// An empty distribution with bins of width `bin` (so the p95 resolves to `bin` up to
    /// 2000 × `bin`).
    pub(crate) fn new(bin: f64) -> Self {
        Distribution { bin, n: 0, sum: 0.0, max: 0.0, histogram: vec![0; BINS] }
    }

    pub(crate) fn add(&mut self, x: f64) {
        self.n += 1;
        self.sum += x;
        self.max = self.max.max(x);
        self.histogram[((x / self.bin) as usize).min(BINS - 1)] += 1;
    }

    pub(crate) fn stats(&self) -> ErrorStats {
        let rank = (0.95 * self.n as f64).ceil() as u64;
        let mut seen = 0u64;
        let bin = self.histogram.iter().position(|&k| {
            seen += u64::from(k);
            seen >= rank
        });
        let p95 = bin.map_or(self.max, |b| ((b + 1) as f64 * self.bin).min(self.max));
        ErrorStats { n: self.n, mean: self.sum / self.n.max(1) as f64, p95, max: self.max }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_max_and_p95_to_the_bin() {
        let mut d = Distribution::new(0.005);
        for k in 0..100 {
            d.add(0.001 * f64::from(k));
        }
        let e = d.stats();
        assert_eq!(e.n, 100);
        assert!((e.mean - 0.0495).abs() < 1e-9 && (e.max - 0.099).abs() < 1e-12);
        assert!((e.p95 - 0.095).abs() < 1e-9, "{}", e.p95);
        d.add(1e9);
        assert_eq!(d.stats().max, 1e9, "beyond the last bin: counted, max exact");
    }
}
