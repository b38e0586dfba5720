//! Synthetic-clock tests of the estimator: known offset, drift and delay distributions.

use super::*;
use risktwin_common::rng::Rng;

/// A realistic epoch-scale start (2024), so precision at 1.7e18 ns is exercised.
const T0_NS: i64 = 1_700_000_000_000_000_000;
const MS: i64 = 1_000_000;

/// A source clock ahead of the cloud by `offset_ns` and running fast by `drift_ppm`.
fn source_clock(t_ns: i64, offset_ns: i64, drift_ppm: f64) -> i64 {
    t_ns + offset_ns + ((t_ns - T0_NS) as f64 * drift_ppm * 1e-6).round() as i64
}

enum Jitter {
    Exponential { mean_ns: f64 },
    Uniform { max_ns: f64 },
}

impl Jitter {
    fn sample(&self, rng: &mut Rng) -> i64 {
        match *self {
            Jitter::Exponential { mean_ns } => (-mean_ns * (1.0 - rng.unit()).ln()).round() as i64,
            Jitter::Uniform { max_ns } => rng.uniform(0.0, max_ns).round() as i64,
        }
    }
}

/// Feeds `seconds` of a `rate_hz` stream; returns the worst mapping error over the last 10 s
/// (estimate vs true capture time + base delay, mapped before each message is observed).
fn run(
    est: &mut ClockEstimator,
    offset_ns: i64,
    drift_ppm: f64,
    base_ns: i64,
    jitter: Jitter,
    rate_hz: i64,
    seconds: i64,
) -> i64 {
    let mut rng = Rng::new(11);
    let period_ns = 1_000_000_000 / rate_hz;
    let n = rate_hz * seconds;
    let mut worst = 0;
    for k in 0..n {
        let t = T0_NS + k * period_ns;
        let capture = source_clock(t, offset_ns, drift_ppm);
        let receive = t + base_ns + jitter.sample(&mut rng);
        est.roll_to(receive);
        if k >= n - 10 * rate_hz {
            let mapped = est.to_cloud_ns(capture).expect("warmed up");
            worst = worst.max((mapped - (t + base_ns)).abs());
        }
        est.observe(capture, receive);
    }
    worst
}

#[test]
fn offset_250ms_drift_50ppm_exponential_jitter() {
    // Documented tolerance: after 60 s at 50 Hz with 2 ms base delay and exponential jitter of
    // mean 3 ms, the mapping is within 0.3 ms of (true time + base delay) and the drift within
    // 5 ppm (the 1σ slope error of 32 bucket minima is ≈ 1 ppm here).
    let mut est = ClockEstimator::new(ClockConfig::default());
    let worst = run(&mut est, 250 * MS, 50.0, 2 * MS, Jitter::Exponential { mean_ns: 3e6 }, 50, 60);
    assert!(est.is_fitted());
    assert!(worst <= 300_000, "worst mapping error {worst} ns");
    assert!((est.drift_ppm() - 50.0).abs() <= 5.0, "drift {} ppm", est.drift_ppm());
    // θ at the last capture: −250 ms − 50 ppm · 60 s + 2 ms = −250.997 ms.
    let expected = -250 * MS - 3 * MS + 2 * MS;
    let got = est.offset_ns().expect("fitted");
    assert!((got - expected).abs() <= 300_000, "offset {got} vs {expected}");
    assert_eq!(est.samples(), 3000);
}

#[test]
fn negative_offset_negative_drift_uniform_jitter_at_10hz() {
    // 10 Hz, uniform 0–20 ms jitter: with 2 s buckets, 20 samples a bucket, each minimum lies
    // ≈ 1 ms above the floor (σ ≈ 1 ms), so over 32 buckets the slope's 1σ error is ≈ 9 ppm.
    // Tolerance: 2 ms on the mapping, 25 ppm on the drift after 120 s. Slow, jittery sources
    // want longer buckets; the mapping error, not the drift figure, is what alignment feels.
    let mut est = ClockEstimator::new(ClockConfig { bucket_ns: 2_000_000_000, ..ClockConfig::default() });
    let worst = run(&mut est, -1_500 * MS, -100.0, MS, Jitter::Uniform { max_ns: 20e6 }, 10, 120);
    assert!(worst <= 2 * MS, "worst mapping error {worst} ns");
    assert!((est.drift_ppm() + 100.0).abs() <= 25.0, "drift {} ppm", est.drift_ppm());
}

#[test]
fn without_drift_fitting_a_drifting_clock_would_be_off() {
    // A source running 50 ppm slow, mapped by the running minimum alone (no fit), drifts away by
    // milliseconds (the minimum holds on to old, lower values): the fit is what keeps it small.
    let mut est = ClockEstimator::new(ClockConfig { min_fit_buckets: 1000, buckets: 1000, ..ClockConfig::default() });
    let worst = run(&mut est, 250 * MS, -50.0, 2 * MS, Jitter::Exponential { mean_ns: 3e6 }, 50, 60);
    assert!(!est.is_fitted());
    assert!(worst >= 2 * MS, "worst {worst} ns");
}

#[test]
fn warm_up_uses_only_earlier_receive_times() {
    let mut est = ClockEstimator::new(ClockConfig::default());
    assert_eq!(est.to_cloud_ns(0), None);
    // Two messages at the same receive time map alike, whichever comes first.
    est.roll_to(1_000);
    assert_eq!(est.to_cloud_ns(100), None);
    est.observe(100, 1_000); // delta 900
    est.roll_to(1_000);
    assert_eq!(est.to_cloud_ns(500), None, "a tie does not see its partner");
    est.observe(500, 1_000); // delta 500
    est.roll_to(2_000);
    assert_eq!(est.offset_at_ns(0), Some(500), "the lowest earlier delta");
    assert_eq!(est.to_cloud_ns(1_600), Some(2_100));
    assert_eq!(est.drift_ppm(), 0.0);
    est.reset();
    assert_eq!(est.to_cloud_ns(0), None);
    assert_eq!(est.samples(), 0);
}

/// How a stalled cloud gets its samples back.
#[derive(Clone, Copy)]
enum Return {
    /// Those held back arrive within the catch-up, oldest first, the live ones waiting their
    /// turn behind them.
    Backlog,
    /// Those held back are gone; the live ones arrive this many ms late until caught up (a
    /// cloud running behind).
    Behind(i64),
}

/// 40 s of a 50 Hz stream, then the cloud stops receiving for 30 s (a stalled process) and
/// returns as `how` says for `catch_up_ms`; then the stream is live again. The worst mapping of
/// a live sample after its true time (+ base delay), in ns, over the 28 s after the catch-up.
fn stall_then_catch_up(cfg: ClockConfig, how: Return, catch_up_ms: i64) -> i64 {
    let mut est = ClockEstimator::new(cfg);
    let mut rng = Rng::new(5);
    let period_ns = 20 * MS;
    let (stall_from, stall_to) = (T0_NS + 40_000 * MS, T0_NS + 70_000 * MS);
    let caught_up = stall_to + catch_up_ms * MS;
    let mut worst_live = 0i64;
    for k in 0..(caught_up - T0_NS + 30_000 * MS) / period_ns {
        let t = T0_NS + k * period_ns;
        let capture = source_clock(t, 250 * MS, 20.0);
        let on_time = t + 2 * MS + Jitter::Exponential { mean_ns: 3e6 }.sample(&mut rng);
        let receive = match how {
            _ if on_time < stall_from || on_time >= caught_up => on_time,
            Return::Backlog => {
                let share = (t - stall_from) as f64 / (caught_up - stall_from) as f64;
                stall_to + ((caught_up - stall_to) as f64 * share) as i64
            }
            Return::Behind(_) if on_time < stall_to => continue,
            Return::Behind(late_ms) => on_time + late_ms * MS,
        };
        est.roll_to(receive);
        if t >= caught_up + 1_000 * MS {
            let mapped = est.to_cloud_ns(capture).expect("warmed up");
            worst_live = worst_live.max(mapped - (t + 2 * MS));
        }
        est.observe(capture, receive);
    }
    worst_live
}

#[test]
fn a_stalled_cloud_catching_up_keeps_mapping_live_samples_near_their_time() {
    // Late arrivals only raise the bucket minima: the lower envelope must stay where the network
    // put it, so a live sample never maps into the future (the ingest refuses those beyond
    // 100 ms as `future-timestamp`). A least-squares line mapped them 105.6 ms ahead after a 2 s
    // catch-up of the backlog; the lower hull keeps that within 0.02 ms.
    let quick = stall_then_catch_up(ClockConfig::default(), Return::Backlog, 2_000);
    assert!(quick <= 2 * MS, "2 s catch-up: a live sample mapped {} ms late", quick as f64 / 1e6);
    let slow = stall_then_catch_up(ClockConfig::default(), Return::Backlog, 10_000);
    assert!(slow <= 2 * MS, "10 s catch-up: a live sample mapped {} ms late", slow as f64 / 1e6);
    // A cloud that comes back 3 s behind for 10 s: ten raised minima a stall's length right of
    // the good ones, and the hull's edge across the gap climbs to them once their mean capture
    // time lies in it. The drift bound keeps the error within 500 ppm of the time since the last
    // good minimum (≈ 41 s: 21 ms); without it the edge's slope maps seconds ahead.
    let behind = stall_then_catch_up(ClockConfig::default(), Return::Behind(3_000), 10_000);
    assert!(behind <= 25 * MS, "3 s behind: a live sample mapped {} ms late", behind as f64 / 1e6);
    let unbounded = ClockConfig { max_drift_ppm: 1_000_000, ..ClockConfig::default() };
    let wild = stall_then_catch_up(unbounded, Return::Behind(3_000), 10_000);
    assert!(wild > 1_000 * MS, "without the bound: {} ms", wild as f64 / 1e6);
}
