//! Aligner behaviour at known times: interpolation, as-of, emission, late data, staleness.

use super::*;
use crate::interp::tests::TestPose;

const MS: i64 = 1_000_000;
const S0: SourceIndex = SourceIndex(0);
const S1: SourceIndex = SourceIndex(1);
const POSE: StreamIndex = StreamIndex(0);
const OBJECTS: StreamIndex = StreamIndex(1);

fn cfg() -> AlignConfig {
    AlignConfig { tick_ns: 50 * MS, lateness_ns: 100 * MS, stale_periods: 3, capacity: 16, ..AlignConfig::default() }
}

fn specs() -> [StreamSpec; 2] {
    [
        StreamSpec { mode: StreamMode::Interpolated, period_ns: 20 * MS },
        StreamSpec { mode: StreamMode::AsOf, period_ns: 100 * MS },
    ]
}

fn pose(x_m: f64, heading_rad: f64) -> TestPose {
    TestPose { x_m, y_m: 0.0, heading_rad }
}

/// Drives the aligner as the ingest does: advance to the receive time, then push.
fn feed<T: Clone + Interpolate>(
    a: &mut Aligner<T>,
    out: &mut Vec<Snapshot<T>>,
    receive_ns: i64,
    source: SourceIndex,
    stream: StreamIndex,
    t_ns: i64,
    value: T,
) -> PushOutcome {
    a.advance(receive_ns, |s| out.push(s.clone()));
    a.push(source, stream, t_ns, value).expect("known stream")
}

#[test]
fn continuous_streams_interpolate_and_discrete_ones_are_as_of() {
    let mut a: Aligner<TestPose> = Aligner::new(cfg(), &specs());
    let mut out = Vec::new();
    // Poses at 50 Hz from t = 1000 ms moving 1 m per 20 ms, heading crossing ±π; objects at 10 Hz.
    for k in 0..30 {
        let t = 1_000 * MS + k * 20 * MS;
        let heading = 3.1 + 0.01 * k as f64;
        feed(&mut a, &mut out, t + 5 * MS, S0, POSE, t, pose(k as f64, risktwin_common::geometry::wrap_angle(heading)));
        if k % 5 == 1 {
            feed(&mut a, &mut out, t + 7 * MS, S0, OBJECTS, t, pose(100.0 + k as f64, 0.0));
        }
    }
    // Receive times run 1005–1587 ms: the grid starts at 1050 ms, ticks up to 1485 ms are out.
    let ticks: Vec<i64> = out.iter().map(|s| s.tick_ns / MS).collect();
    assert_eq!(ticks, (0..9).map(|k| 1_050 + 50 * k).collect::<Vec<_>>());
    let s = &out[2]; // tick 1150 ms: between the poses at 1140 (k = 7) and 1160 (k = 8)
    assert_eq!(s.tick_ns, 1_150 * MS);
    let p = s.get(S0, POSE).expect("source 0");
    assert_eq!(p.status, ValueStatus::Interpolated);
    assert_eq!(p.age_ns, 10 * MS);
    let v = p.value.expect("value");
    assert!((v.x_m - 7.5).abs() < 1e-12, "x {}", v.x_m);
    let expected_heading = risktwin_common::geometry::wrap_angle(3.1 + 0.075);
    assert!((v.heading_rad - expected_heading).abs() < 1e-9, "heading {} vs {expected_heading}", v.heading_rad);
    assert!(v.heading_rad < 0.0, "3.175 rad wrapped past π");
    // Objects sampled at 1020, 1120, 1220 ms: at 1150 the one of 1120 ms, as of.
    let o = s.get(S0, OBJECTS).expect("source 0");
    assert_eq!(o.status, ValueStatus::AsOf);
    assert_eq!(o.age_ns, 30 * MS);
    assert_eq!(o.value.expect("value").x_m, 106.0);
    // Tick 1100 ms: exactly on a pose sample (k = 5).
    let on = out[1].get(S0, POSE).expect("pose");
    assert_eq!((on.value.map(|p| p.x_m), on.age_ns), (Some(5.0), 0));
    assert_eq!(a.counts().late, 0);
}

#[test]
fn a_tick_waits_for_the_lateness_and_holds_exactly_what_arrived_before_it() {
    let mut a: Aligner<f64> = Aligner::new(cfg(), &specs());
    let mut out = Vec::new();
    feed(&mut a, &mut out, 990 * MS, S0, POSE, 980 * MS, 1.0);
    feed(&mut a, &mut out, 1_095 * MS, S0, POSE, 1_000 * MS, 2.0);
    assert!(out.is_empty(), "tick 1000 needs receive time 1100 ms");
    // Receive 1100 ms: tick 1000 is emitted before this (late-ish) sample is pushed.
    feed(&mut a, &mut out, 1_100 * MS, S0, POSE, 1_010 * MS, 3.0);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].tick_ns, 1_000 * MS);
    let v = out[0].get(S0, POSE).expect("pose");
    assert_eq!((v.value, v.status, v.age_ns), (Some(2.0), ValueStatus::AsOf, 0));
    assert_eq!(a.watermark_ns(), Some(1_000 * MS));
    assert_eq!(a.last_emitted_ns(), Some(1_000 * MS));
}

#[test]
fn late_samples_are_counted_and_kept_only_when_they_serve_the_next_tick() {
    let mut a: Aligner<f64> = Aligner::new(cfg(), &specs());
    let mut out = Vec::new();
    feed(&mut a, &mut out, 1_000 * MS, S0, POSE, 960 * MS, 0.0);
    feed(&mut a, &mut out, 1_000 * MS, S0, POSE, 980 * MS, 1.0);
    a.advance(1_100 * MS, |s| out.push(s.clone())); // emits tick 1000 ms
    assert_eq!(out.len(), 1);
    // 970 ms is older than 980 ms, the sample the next tick starts from: dropped.
    assert_eq!(a.push(S0, POSE, 970 * MS, 9.0), Ok(PushOutcome::LateDropped));
    // 990 ms is newer: it replaces 980 ms as the left bracket for tick 1050.
    assert_eq!(a.push(S0, POSE, 990 * MS, 2.0), Ok(PushOutcome::LateKept));
    assert_eq!(a.push(S0, POSE, 1_030 * MS, 6.0), Ok(PushOutcome::Buffered));
    assert_eq!(a.push(S0, POSE, 1_030 * MS, 7.0), Ok(PushOutcome::SameTime));
    a.advance(1_150 * MS, |s| out.push(s.clone()));
    let v = out[1].get(S0, POSE).expect("pose");
    // Tick 1050: held from 1030 ms (no later sample), age 20 ms ≤ 3 · 20 ms.
    assert_eq!((v.value, v.status, v.age_ns), (Some(6.0), ValueStatus::AsOf, 20 * MS));
    let c = a.counts();
    assert_eq!((c.late, c.late_dropped, c.same_time, c.pushed), (2, 1, 1, 6));
    // What tick 1000 showed was not revised: 980 ms held.
    assert_eq!(out[0].get(S0, POSE).expect("pose").value, Some(1.0));
}

#[test]
fn a_silent_source_goes_stale_and_long_gaps_are_not_interpolated() {
    let mut a: Aligner<f64> = Aligner::new(cfg(), &specs());
    let mut out = Vec::new();
    feed(&mut a, &mut out, 1_000 * MS, S0, POSE, 1_000 * MS, 10.0);
    feed(&mut a, &mut out, 1_001 * MS, S1, POSE, 1_000 * MS, 0.0);
    // Source 1 keeps sending; source 0 is silent until 1300 ms.
    for k in 1..=15 {
        let t = 1_000 * MS + k * 20 * MS;
        feed(&mut a, &mut out, t + MS, S1, POSE, t, k as f64);
    }
    feed(&mut a, &mut out, 1_301 * MS, S0, POSE, 1_300 * MS, 40.0);
    a.advance(1_450 * MS, |s| out.push(s.clone()));
    let at = |tick_ms: i64| out.iter().find(|s| s.tick_ns == tick_ms * MS).expect("tick emitted");
    // Tick 1050: source 0's gap 1000 → 1300 ms is 300 ms > 60 ms: held, age 50 ≤ 60 ms.
    let v = at(1_050).get(S0, POSE).expect("s0").clone();
    assert_eq!((v.value, v.status, v.age_ns), (Some(10.0), ValueStatus::AsOf, 50 * MS));
    // Tick 1100: age 100 ms > 60 ms: stale, not extrapolated, not interpolated.
    let v = at(1_100).get(S0, POSE).expect("s0").clone();
    assert_eq!((v.value, v.status, v.age_ns), (Some(10.0), ValueStatus::Stale, 100 * MS));
    // Source 1 at 1100 interpolates between 1100 ms samples exactly: value 5.
    assert_eq!(at(1_100).get(S1, POSE).expect("s1").value, Some(5.0));
    // Tick 1300: source 0 is back, fresh.
    assert_eq!(at(1_300).get(S0, POSE).expect("s0").status, ValueStatus::AsOf);
    assert_eq!(at(1_300).sources(), 2);
}

/// Found by the `ingest` fuzz target: a sample stamped near `i64::MIN` (a source may stamp
/// anything) made the age and the gap to the next sample overflow; in a release build they
/// wrapped negative, and an ancient value was served as fresh or interpolated from.
#[test]
fn a_sample_stamped_at_the_far_past_is_stale_not_fresh() {
    let mut a: Aligner<f64> = Aligner::new(cfg(), &specs());
    let mut out = Vec::new();
    feed(&mut a, &mut out, 1_000 * MS, S0, POSE, i64::MIN + 1, 1.0);
    feed(&mut a, &mut out, 1_001 * MS, S0, POSE, 1_100 * MS, 2.0);
    a.advance(1_450 * MS, |s| out.push(s.clone()));
    let at = |tick_ms: i64| out.iter().find(|s| s.tick_ns == tick_ms * MS).expect("tick emitted");
    // Tick 1050: the gap to the 1100 ms sample is beyond any bound: held, and stale.
    let v = at(1_050).get(S0, POSE).expect("s0").clone();
    assert_eq!((v.value, v.status, v.age_ns), (Some(1.0), ValueStatus::Stale, i64::MAX));
    assert_eq!(at(1_100).get(S0, POSE).expect("s0").status, ValueStatus::AsOf);
}

/// Found by the `ingest` fuzz target: a first receive time near `i64::MAX` (a replay-time
/// attachment claims it) overflowed the next tick; wrapped, the aligner stepped from the far
/// past, past any catch-up limit.
#[test]
fn a_receive_time_at_the_end_of_i64_emits_nothing_and_does_not_overflow() {
    let mut a: Aligner<f64> = Aligner::new(cfg(), &specs());
    let limit = u64::from(cfg().max_catch_up_ticks);
    let mut emitted = 0u64;
    for now_ns in [i64::MAX - 1, i64::MAX, i64::MIN] {
        a.advance(now_ns, |_| {
            emitted += 1;
            assert!(emitted <= limit, "more ticks than the catch-up limit");
        });
    }
    assert_eq!(emitted, 0);
}

#[test]
fn rings_stay_bounded_and_evict_the_oldest_when_flooded() {
    let mut a: Aligner<f64> = Aligner::new(AlignConfig { capacity: 4, ..cfg() }, &specs());
    assert_eq!(a.advance(0, |_| {}), 0, "starts the tick grid at 0; nothing due yet");
    for k in 0..10 {
        assert_eq!(a.push(S0, POSE, k * MS, k as f64), Ok(PushOutcome::Buffered));
    }
    assert_eq!(a.counts().overflow, 6);
    let mut snap = Snapshot::new(2);
    a.snapshot_at(6 * MS, &mut snap);
    assert_eq!(snap.get(S0, POSE).expect("s0").value, Some(6.0));
    a.snapshot_at(5 * MS, &mut snap);
    assert_eq!(snap.get(S0, POSE).expect("s0").status, ValueStatus::NoData, "5 ms was evicted");
    // An older sample than everything in a full ring is not taken.
    assert_eq!(a.push(S0, POSE, 0, 0.0), Ok(PushOutcome::Buffered));
    assert_eq!(a.counts().overflow, 7);
    // Emitting ticks 0, 50, 100 ms prunes the ring to the one sample later ticks start from.
    assert_eq!(a.advance(200 * MS, |_| {}), 3);
    a.snapshot_at(8 * MS, &mut snap);
    assert_eq!(snap.get(S0, POSE).expect("s0").status, ValueStatus::NoData, "pruned below 9 ms");
    a.snapshot_at(9 * MS, &mut snap);
    assert_eq!(snap.get(S0, POSE).expect("s0").value, Some(9.0));
}

#[test]
fn unknown_streams_and_sources_beyond_the_limit_are_refused() {
    let mut a: Aligner<f64> = Aligner::new(AlignConfig { max_sources: 2, ..cfg() }, &specs());
    assert_eq!(a.push(S0, StreamIndex(2), 0, 0.0), Err(DropReason::UnknownStream));
    assert_eq!(a.push(SourceIndex(2), POSE, 0, 0.0), Err(DropReason::TooManySources));
    assert_eq!(a.counts().pushed, 0);
}

#[test]
fn a_long_silence_emits_at_most_the_catch_up_limit() {
    let mut a: Aligner<f64> = Aligner::new(AlignConfig { max_catch_up_ticks: 10, ..cfg() }, &specs());
    let mut ticks = Vec::new();
    a.advance(0, |s| ticks.push(s.tick_ns));
    a.advance(3_600_000 * MS, |s| ticks.push(s.tick_ns));
    assert_eq!(ticks.len(), 10);
    assert_eq!(*ticks.last().expect("ten"), 3_600_000 * MS - 100 * MS);
    assert_eq!(a.counts().skipped_ticks, 72_000 - 2 + 1 - 10);
}

#[test]
fn as_of_only_aligner_needs_no_interpolation() {
    #[derive(Debug, Clone, PartialEq)]
    struct Phase(u8);
    let mut a: Aligner<Phase> = Aligner::as_of(cfg(), &[100 * MS]);
    a.push(S0, StreamIndex(0), 10 * MS, Phase(1)).expect("stream 0");
    a.push(S0, StreamIndex(0), 60 * MS, Phase(2)).expect("stream 0");
    let mut snap = Snapshot::new(1);
    a.snapshot_at(50 * MS, &mut snap);
    assert_eq!(snap.get(S0, StreamIndex(0)).expect("s0").value, Some(Phase(1)));
    a.snapshot_at(400 * MS, &mut snap);
    assert_eq!(snap.get(S0, StreamIndex(0)).expect("s0").status, ValueStatus::Stale);
}
