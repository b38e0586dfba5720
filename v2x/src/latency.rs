//! How long a V2X message takes, sampled per message: the sidelink's semi-persistent scheduling
//! (a message waits for its reserved resource within the selection window) and a shifted Gamma
//! for a cellular uplink and backhaul to the cloud (the family measured vehicle-to-cloud latencies
//! are fitted with; [`Latency::CELLULAR_LTE_ROUND_TRIP`] is fitted to a published drive trace,
//! other parameters are the user's).

use risktwin_common::rng::Rng;
use serde::{Deserialize, Serialize};

/// A latency distribution, in ms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Latency {
    /// Sidelink mode 4 / mode 2 semi-persistent scheduling: the resource is chosen uniformly in
    /// the selection window [n + T1, n + T2] after the message is made (LTE, 3GPP TS 36.213
    /// §14.1.1.6: T1 ≤ 4 ms, 20 ms ≤ T2 ≤ 100 ms, T2 within the message's latency budget; other
    /// windows, e.g. NR's, are accepted up to 1 s). Drawn per message: a real reservation repeats
    /// every interval, so consecutive periodic messages see the same latency until the resource
    /// is reselected; this keeps the distribution, not that correlation.
    Sidelink { t1_ms: f64, t2_ms: f64 },
    /// `offset_ms` + Gamma(`shape`, `scale_ms`): a cellular path's fixed part and its queueing.
    Gamma { offset_ms: f64, shape: f64, scale_ms: f64 },
}

/// The command-line form [`Latency::parse`] reads: `sidelink:4:100`, `gamma:10:2:5`.
impl std::fmt::Display for Latency {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Latency::Sidelink { t1_ms, t2_ms } => write!(f, "sidelink:{t1_ms}:{t2_ms}"),
            Latency::Gamma { offset_ms, shape, scale_ms } => write!(f, "gamma:{offset_ms}:{shape}:{scale_ms}"),
        }
    }
}

/// The longest sidelink selection window accepted, ms.
const MAX_WINDOW_MS: f64 = 1000.0;
/// The gamma shapes accepted: beyond, the sampler's boost underflows (small) or the distribution
/// function's series needs more terms than it takes (large); latencies need neither.
const MIN_SHAPE: f64 = 0.01;
const MAX_SHAPE: f64 = 1000.0;

impl Latency {
    /// The widest sidelink window: T1 = 4 ms, T2 = 100 ms (a CAM's 100 ms budget).
    pub const SIDELINK: Latency = Latency::Sidelink { t1_ms: 4.0, t2_ms: 100.0 };

    /// A vehicle's round trip to a cloud server over commercial LTE, moving: fitted to the
    /// drive traces of Lee, Flinn and Tonshal, "RAVEN: Improving Interactive Latency for the
    /// Connected Car", ACM MobiCom 2018 (github.com/forkjoseph/vnperf, `traces/public.d1–d4`:
    /// Ann Arbor downtown, highway, rural and suburban, October 2017, a 10-byte TCP echo each
    /// second; the Verizon LTE column, 12,241 samples). Quantiles fitted by least squares with
    /// the offset just below the smallest sample; the body within 10 % (p1–p95), the tail
    /// beyond p99 (outages: 0.5 % over 1 s) not at all. For a warning that goes through the
    /// cloud: the report up and the warning down.
    pub const CELLULAR_LTE_ROUND_TRIP: Latency = Latency::Gamma { offset_ms: 44.0, shape: 4.45, scale_ms: 9.16 };

    /// Why this cannot be sampled, if it cannot.
    pub fn check(&self) -> Result<(), String> {
        match *self {
            Latency::Sidelink { t1_ms, t2_ms } => {
                if !(0.0 <= t1_ms && t1_ms <= t2_ms && t2_ms <= MAX_WINDOW_MS) {
                    return Err(format!("sidelink window [{t1_ms}, {t2_ms}] ms: need 0 ≤ t1_ms ≤ t2_ms ≤ 1000"));
                }
            }
            Latency::Gamma { offset_ms, shape, scale_ms } => {
                if !(offset_ms.is_finite() && offset_ms >= 0.0) {
                    return Err(format!("gamma offset {offset_ms} ms: need a finite number ≥ 0"));
                }
                if !((MIN_SHAPE..=MAX_SHAPE).contains(&shape) && scale_ms.is_finite() && scale_ms > 0.0) {
                    return Err(format!(
                        "gamma shape {shape}, scale {scale_ms} ms: need a shape in [{MIN_SHAPE}, {MAX_SHAPE}] and a positive scale"
                    ));
                }
            }
        }
        Ok(())
    }

    /// A latency from its command-line form: `sidelink:T1:T2` or `gamma:OFFSET:SHAPE:SCALE`
    /// (ms, the shape a number), checked.
    pub fn parse(text: &str) -> Result<Latency, String> {
        let mut parts = text.split(':');
        let model = parts.next().unwrap_or_default();
        let numbers: Result<Vec<f64>, _> = parts.map(str::parse::<f64>).collect();
        let numbers = numbers.map_err(|e| format!("latency {text:?}: {e}"))?;
        let latency = match (model, &numbers[..]) {
            ("sidelink", &[t1_ms, t2_ms]) => Latency::Sidelink { t1_ms, t2_ms },
            ("gamma", &[offset_ms, shape, scale_ms]) => Latency::Gamma { offset_ms, shape, scale_ms },
            _ => return Err(format!("latency {text:?}: expected sidelink:T1:T2 or gamma:OFFSET:SHAPE:SCALE (ms)")),
        };
        latency.check().map(|()| latency)
    }

    /// One latency, ms.
    pub fn sample_ms(&self, rng: &mut Rng) -> f64 {
        match *self {
            Latency::Sidelink { t1_ms, t2_ms } => rng.uniform(t1_ms, t2_ms),
            Latency::Gamma { offset_ms, shape, scale_ms } => offset_ms + scale_ms * standard_gamma(shape, rng),
        }
    }

    /// P(latency ≤ `x_ms`).
    pub fn cdf(&self, x_ms: f64) -> f64 {
        match *self {
            Latency::Sidelink { t1_ms, t2_ms } if t2_ms > t1_ms => ((x_ms - t1_ms) / (t2_ms - t1_ms)).clamp(0.0, 1.0),
            Latency::Sidelink { t1_ms, .. } => f64::from(u8::from(x_ms >= t1_ms)),
            Latency::Gamma { offset_ms, shape, scale_ms } => {
                if x_ms <= offset_ms {
                    0.0
                } else {
                    lower_regularized_gamma(shape, (x_ms - offset_ms) / scale_ms)
                }
            }
        }
    }

    pub fn mean_ms(&self) -> f64 {
        match *self {
            Latency::Sidelink { t1_ms, t2_ms } => 0.5 * (t1_ms + t2_ms),
            Latency::Gamma { offset_ms, shape, scale_ms } => offset_ms + shape * scale_ms,
        }
    }
}

/// Gamma(`shape`, 1) by Marsaglia and Tsang, "A Simple Method for Generating Gamma Variables"
/// (ACM TOMS 26(3), 2000), with their boost for shape < 1.
fn standard_gamma(shape: f64, rng: &mut Rng) -> f64 {
    if shape < 1.0 {
        let u = 1.0 - rng.unit(); // (0, 1]
        return standard_gamma(shape + 1.0, rng) * u.powf(1.0 / shape);
    }
    let d = shape - 1.0 / 3.0;
    let c = 1.0 / (9.0 * d).sqrt();
    loop {
        let x = rng.normal();
        let v = (1.0 + c * x).powi(3);
        if v <= 0.0 {
            continue;
        }
        let u = 1.0 - rng.unit();
        if u.ln() < 0.5 * x * x + d - d * v + d * v.ln() {
            return d * v;
        }
    }
}

/// P(a, x), the regularized lower incomplete gamma function: its series for x < a + 1, else 1
/// minus Legendre's continued fraction (Lentz's method), as in Numerical Recipes §6.2.
fn lower_regularized_gamma(a: f64, x: f64) -> f64 {
    const EPS: f64 = 1e-15;
    const TINY: f64 = 1e-300;
    if x <= 0.0 {
        return 0.0;
    }
    if x.is_infinite() {
        return 1.0;
    }
    let log_prefix = a * x.ln() - x - libm::lgamma(a);
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * EPS {
                break;
            }
        }
        return (sum * log_prefix.exp()).clamp(0.0, 1.0);
    }
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..10_000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        d = if d.abs() < TINY { TINY } else { d };
        c = b + an / c;
        c = if c.abs() < TINY { TINY } else { c };
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < EPS {
            break;
        }
    }
    (1.0 - log_prefix.exp() * h).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_its_command_line_form_and_refuses_bad_values() {
        assert_eq!(Latency::parse("sidelink:4:100"), Ok(Latency::SIDELINK));
        let gamma = Latency::Gamma { offset_ms: 10.0, shape: 2.0, scale_ms: 5.0 };
        assert_eq!(Latency::parse("gamma:10:2:5"), Ok(gamma));
        for latency in [Latency::SIDELINK, gamma, Latency::Sidelink { t1_ms: 0.5, t2_ms: 20.25 }] {
            assert_eq!(Latency::parse(&latency.to_string()), Ok(latency), "{latency}");
        }
        for bad in ["sidelink:4", "sidelink:50:10", "gamma:1:0:5", "fixed:3", "sidelink:a:3", ""] {
            assert!(Latency::parse(bad).is_err(), "{bad}");
        }
    }

    /// The Kolmogorov–Smirnov statistic of `samples` against `cdf`: the largest gap between their
    /// empirical distribution and it.
    fn ks_statistic(samples: &mut [f64], cdf: impl Fn(f64) -> f64) -> f64 {
        samples.sort_by(f64::total_cmp);
        let n = samples.len() as f64;
        samples.iter().enumerate().fold(0.0, |worst: f64, (i, &x)| {
            let f = cdf(x);
            worst.max((f - i as f64 / n).abs()).max(((i + 1) as f64 / n - f).abs())
        })
    }

    /// 1.36 / √n: the Kolmogorov–Smirnov critical value at the 5 % level for large n.
    fn ks_critical(n: usize) -> f64 {
        1.36 / (n as f64).sqrt()
    }

    #[test]
    fn samplers_pass_a_kolmogorov_smirnov_test_against_their_distributions() {
        let models = [
            Latency::SIDELINK,
            Latency::Gamma { offset_ms: 10.0, shape: 2.5, scale_ms: 4.0 },
            Latency::Gamma { offset_ms: 0.0, shape: 0.6, scale_ms: 20.0 },
        ];
        let n = 20_000;
        for (k, model) in models.iter().enumerate() {
            let mut rng = Rng::new(0x5eed + k as u64);
            let mut samples: Vec<f64> = (0..n).map(|_| model.sample_ms(&mut rng)).collect();
            let mean = samples.iter().sum::<f64>() / n as f64;
            let d = ks_statistic(&mut samples, |x| model.cdf(x));
            assert!(d < ks_critical(n), "{model:?}: D = {d}");
            assert!((mean - model.mean_ms()).abs() < 0.03 * model.mean_ms(), "{model:?}: mean {mean}");
        }
        // And the test can fail: the same samples against another distribution.
        let mut rng = Rng::new(1);
        let wrong = Latency::Gamma { offset_ms: 10.0, shape: 3.0, scale_ms: 4.0 };
        let mut samples: Vec<f64> = (0..n).map(|_| models[1].sample_ms(&mut rng)).collect();
        assert!(ks_statistic(&mut samples, |x| wrong.cdf(x)) > ks_critical(n));
    }

    #[test]
    fn the_cellular_fit_reproduces_the_body_of_its_trace() {
        // Quantiles of the trace's 12,241 round trips, ms (see CELLULAR_LTE_ROUND_TRIP).
        let trace = [
            (0.01, 50.9),
            (0.05, 57.8),
            (0.10, 64.6),
            (0.25, 77.9),
            (0.50, 84.3),
            (0.75, 90.3),
            (0.90, 100.7),
            (0.95, 115.6),
        ];
        let model = Latency::CELLULAR_LTE_ROUND_TRIP;
        for (p, measured_ms) in trace {
            let (mut lo, mut hi) = (0.0, 1000.0);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if model.cdf(mid) < p { lo = mid } else { hi = mid }
            }
            assert!(
                (lo - measured_ms).abs() < 0.10 * measured_ms,
                "p{}: {lo:.1} ms against {measured_ms} ms",
                100.0 * p
            );
        }
    }

    #[test]
    fn the_gamma_cdf_matches_closed_forms() {
        // Shape 1 is the exponential: 1 − e^(−x/θ); shape 2: 1 − (1 + x/θ) e^(−x/θ).
        for x in [0.1, 1.0, 2.5, 7.0, 30.0] {
            let exp = Latency::Gamma { offset_ms: 0.0, shape: 1.0, scale_ms: 2.0 };
            assert!((exp.cdf(x) - (1.0 - (-x / 2.0f64).exp())).abs() < 1e-12, "{x}");
            let erlang = Latency::Gamma { offset_ms: 0.0, shape: 2.0, scale_ms: 1.0 };
            assert!((erlang.cdf(x) - (1.0 - (1.0 + x) * (-x).exp())).abs() < 1e-12, "{x}");
        }
        assert_eq!(Latency::Gamma { offset_ms: 5.0, shape: 2.0, scale_ms: 1.0 }.cdf(4.0), 0.0);
    }

    #[test]
    fn the_same_seed_gives_the_same_latencies_and_bad_parameters_are_named() {
        let draw = |seed| {
            let mut rng = Rng::new(seed);
            (0..100).map(|_| Latency::SIDELINK.sample_ms(&mut rng).to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(draw(7), draw(7));
        assert_ne!(draw(7), draw(8));
        assert!(Latency::Sidelink { t1_ms: 50.0, t2_ms: 20.0 }.check().is_err());
        assert!(Latency::Gamma { offset_ms: -1.0, shape: 1.0, scale_ms: 1.0 }.check().is_err());
        assert!(Latency::Gamma { offset_ms: 0.0, shape: 0.0, scale_ms: 1.0 }.check().is_err());
        assert_eq!(Latency::SIDELINK.check(), Ok(()));
    }
}
