//! Axis arithmetic shared by the charts: "nice" tick steps (1, 2 or 5 × 10^k) and compact tick
//! labels, plus the mapping from data to pixel coordinates.

/// Tick values covering [lo, hi] with about `target` ticks on 1/2/5 × 10^k steps.
pub fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo || target < 2 {
        return vec![lo];
    }
    let raw = (hi - lo) / (target - 1) as f64;
    let magnitude = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * magnitude).find(|s| *s >= raw).unwrap_or(10.0 * magnitude);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last).map(|i| i as f64 * step).collect()
}

/// A tick label: thousands as `k`, millions as `M`, otherwise as few decimals as the step needs.
pub fn label(value: f64, step: f64) -> String {
    let abs = value.abs();
    if abs >= 1e6 && step >= 1e5 {
        trim(format!("{:.1}", value / 1e6)) + "M"
    } else if abs >= 1e3 && step >= 100.0 {
        trim(format!("{:.1}", value / 1e3)) + "k"
    } else {
        let decimals = if step >= 1.0 { 0 } else { (-step.log10().floor()) as usize };
        format!("{value:.decimals$}")
    }
}

fn trim(s: String) -> String {
    s.strip_suffix(".0").map(str::to_owned).unwrap_or(s)
}

/// The data range of `values` widened so that a flat series still gets an axis; `None` if no
/// value is finite.
pub fn range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) =
        values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return None;
    }
    if hi - lo < 1e-12 {
        let pad = if lo.abs() > 1e-12 { lo.abs() * 0.1 } else { 1.0 };
        return Some((lo - pad, hi + pad));
    }
    Some((lo, hi))
}

/// Linear map from a data interval onto a pixel interval (which may run backwards, as y does).
#[derive(Debug, Clone, Copy)]
pub struct Scale {
    pub data: (f64, f64),
    pub pixels: (f64, f64),
}

impl Scale {
    pub fn map(&self, v: f64) -> f64 {
        let t = (v - self.data.0) / (self.data.1 - self.data.0);
        self.pixels.0 + t * (self.pixels.1 - self.pixels.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice_and_cover_the_range() {
        assert_eq!(ticks(0.0, 1.0, 6), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        assert_eq!(ticks(0.0, 200_000.0, 5), vec![0.0, 50_000.0, 100_000.0, 150_000.0, 200_000.0]);
        assert_eq!(ticks(-3.0, 7.0, 3), vec![0.0, 5.0]);
        assert_eq!(ticks(1.0, 1.0, 5), vec![1.0], "degenerate range");
    }

    #[test]
    fn labels_are_compact() {
        assert_eq!(label(150_000.0, 50_000.0), "150k");
        assert_eq!(label(2_500_000.0, 500_000.0), "2.5M");
        assert_eq!(label(0.6000000000000001, 0.2), "0.6");
        assert_eq!(label(-12.0, 5.0), "-12");
        assert_eq!(label(0.05, 0.05), "0.05");
    }

    #[test]
    fn flat_and_empty_ranges() {
        assert_eq!(range([2.0, 2.0].into_iter()), Some((1.8, 2.2)));
        assert_eq!(range([f64::NAN].into_iter()), None);
        let s = Scale { data: (0.0, 10.0), pixels: (100.0, 0.0) };
        assert_eq!(s.map(2.5), 75.0);
    }
}
