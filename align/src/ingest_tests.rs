//! The ingest core end to end: accounting, bad timestamps, and replay determinism.

use super::*;
use crate::interp::tests::TestPose;
use crate::snapshot::ValueStatus;
use crate::test_fleet::{MS, Network, Sent, T0_NS, fleet, fleet_streams};

fn core() -> IngestCore<TestPose> {
    IngestCore::new(IngestConfig::default(), &fleet_streams())
}

fn net() -> Network {
    Network { base_delay_ns: MS, jitter_mean_ns: 2e6, spike: 0.01, loss: 0.02, duplicate: 0.02, receive_quantum_ns: MS }
}

fn pose(x_m: f64) -> TestPose {
    TestPose { x_m, y_m: 0.0, heading_rad: 0.0 }
}

fn msg(seq: u64, capture_ns: i64, receive_ns: i64) -> Incoming<TestPose> {
    Incoming { source: SourceIndex(0), stream: StreamIndex(0), seq, capture_ns, receive_ns, payload: pose(seq as f64) }
}

/// One aligned value as bits: status, age, and the pose's f64 bit patterns.
type ValueBits = (u8, i64, [u64; 3]);

/// Every bit of every snapshot, in order: equal fingerprints mean bit-for-bit equal snapshots.
fn fingerprint(snaps: &[Snapshot<TestPose>]) -> Vec<(i64, Vec<ValueBits>)> {
    snaps
        .iter()
        .map(|s| {
            let vals = s
                .values()
                .iter()
                .map(|a| {
                    let bits = a.value.map_or([0; 3], |p| [p.x_m.to_bits(), p.y_m.to_bits(), p.heading_rad.to_bits()]);
                    (a.status as u8, a.age_ns, bits)
                })
                .collect();
            (s.tick_ns, vals)
        })
        .collect()
}

#[test]
fn every_message_is_accounted_for() {
    let (mut sent_msgs, sent_unique) = fleet(20, 20, 3, net());
    sent_msgs.sort_by_key(|s| (s.msg.receive_ns, s.tie_key));
    let mut c = core();
    let received = sent_msgs.len() as u64;
    for s in sent_msgs {
        let _ = c.ingest(s.msg, |_| {});
    }
    let d = c.dedup().totals();
    let drops = c.drops();
    assert_eq!(c.accepted() + drops.total(), received, "each message ends accepted or dropped once");
    assert_eq!(d.fresh, c.accepted() + drops.get(DropReason::FutureTimestamp));
    // The tail of each stream may be lost unseen; count those from the known send counts.
    let highest_span: u64 = (0..40u32).map(|k| c.dedup().highest(SourceIndex(k)).map_or(0, |h| h + 1)).sum();
    assert_eq!(c.accepted() + drops.get(DropReason::FutureTimestamp) + d.presumed_lost, highest_span);
    assert!(highest_span <= sent_unique && sent_unique - highest_span < 40, "{highest_span} of {sent_unique}");
    assert!(drops.get(DropReason::Duplicate) > 100, "duplicates were injected: {:?}", drops);
    assert_eq!(drops.get(DropReason::FutureTimestamp), 0, "honest clocks never look future");
    assert!(d.presumed_lost > 100 && d.recovered > 10, "{d:?}");
    assert!(c.aligner().counts().late > 10, "delay spikes make late samples");
    // Per (source, stream), the counters sum to the totals.
    let streams = fleet_streams().len();
    let per_pair: u64 = (0..20u32)
        .flat_map(|src| (0..streams).map(move |st| (SourceIndex(src), StreamIndex(st as u16))))
        .map(|(src, st)| c.seq_counts(src, st).presumed_lost)
        .sum();
    assert_eq!(per_pair, d.presumed_lost);
}

#[test]
fn future_timestamps_are_counted_and_the_worker_keeps_going() {
    let mut c = core();
    let mut t = T0_NS;
    // 6 s at 50 Hz: the estimate is fitted.
    for seq in 0..300 {
        assert!(c.ingest(msg(seq, t - 400 * MS, t + 2 * MS), |_| {}).is_ok());
        t += 20 * MS;
    }
    assert!(c.clock(SourceIndex(0)).is_some_and(ClockEstimator::is_fitted));
    // One capture 5 s ahead of its source's clock: refused, and the estimate is untouched.
    let offset_before = c.clock(SourceIndex(0)).and_then(|k| k.offset_ns());
    assert_eq!(c.ingest(msg(300, t - 400 * MS + 5_000 * MS, t + 2 * MS), |_| {}), Err(DropReason::FutureTimestamp));
    assert_eq!(c.drops().get(DropReason::FutureTimestamp), 1);
    assert_eq!(c.ingest(msg(300, t - 400 * MS, t + 2 * MS), |_| {}), Err(DropReason::Duplicate), "300 was used");
    t += 20 * MS;
    let ok = c.ingest(msg(301, t - 400 * MS, t + 2 * MS), |_| {}).expect("normal message after a bad one");
    assert_eq!(c.clock(SourceIndex(0)).and_then(|k| k.offset_ns()), offset_before);
    assert!((ok.cloud_ns - (t + 2 * MS)).abs() <= MS, "mapped {} vs {}", ok.cloud_ns, t + 2 * MS);
    assert_eq!(c.warm_clamped(), 0);
}

#[test]
fn a_future_timestamp_while_warming_up_is_taken_at_its_receive_time_and_teaches_nothing() {
    let mut c = core();
    let mut t = T0_NS;
    for seq in 0..100 {
        assert!(c.ingest(msg(seq, t - 400 * MS, t + 2 * MS), |_| {}).is_ok());
        t += 20 * MS;
    }
    assert!(!c.clock(SourceIndex(0)).is_some_and(ClockEstimator::is_fitted), "2 s in: warming up");
    let offset_before = c.clock(SourceIndex(0)).and_then(|k| k.offset_ns());
    let a = c.ingest(msg(100, t - 400 * MS + 5_000 * MS, t + 2 * MS), |_| {}).expect("taken");
    assert_eq!(a.cloud_ns, t + 2 * MS, "at its receive time");
    assert_eq!((c.warm_clamped(), c.drops().total(), c.clock_resets()), (1, 0, 0));
    t += 20 * MS;
    let ok = c.ingest(msg(101, t - 400 * MS, t + 2 * MS), |_| {}).expect("the next, on its clock");
    assert_eq!(c.clock(SourceIndex(0)).and_then(|k| k.offset_ns()), offset_before, "the estimate is untouched");
    assert!((ok.cloud_ns - (t + 2 * MS)).abs() <= MS, "mapped {} vs {}", ok.cloud_ns, t + 2 * MS);
}

#[test]
fn a_clock_stepped_forward_is_re_anchored_after_a_run_of_future_timestamps() {
    let cfg = IngestConfig { clock_reset_after: 5, ..IngestConfig::default() };
    let mut c: IngestCore<TestPose> = IngestCore::new(cfg, &fleet_streams());
    let mut t = T0_NS;
    // 6 s: a fitted estimate.
    for seq in 0..300 {
        c.ingest(msg(seq, t, t + MS), |_| {}).expect("steady source");
        t += 20 * MS;
    }
    // The source's clock steps 10 s forward: 4 refusals, then the 5th resets and is accepted.
    let step = 10_000 * MS;
    for seq in 300..304 {
        assert_eq!(c.ingest(msg(seq, t + step, t + MS), |_| {}), Err(DropReason::FutureTimestamp));
        t += 20 * MS;
    }
    let a = c.ingest(msg(304, t + step, t + MS), |_| {}).expect("re-anchored");
    assert_eq!(a.cloud_ns, t + MS, "anchored at its receive time");
    assert_eq!(c.clock_resets(), 1);
    t += 20 * MS;
    let a = c.ingest(msg(305, t + step, t + MS), |_| {}).expect("follows the new clock");
    assert_eq!(a.cloud_ns, t + MS);
    assert_eq!(c.drops().get(DropReason::FutureTimestamp), 4);
}

#[test]
fn a_late_first_second_costs_a_warming_estimate_nothing() {
    // A cloud behind at start: a source's first 50 samples (1 s at 50 Hz) arrive 1 s late, then
    // on time. The estimate anchored on the late ones maps the on-time ones 1 s ahead; warming
    // up, they are taken at their receive times and it is reset after 5 of them in a row, not
    // refused (a run of 50 refusals, 2,000 vehicles: the 98,000 drops `bench ingest` once showed).
    let mut c = core();
    let mut t = T0_NS;
    for seq in 0..50 {
        c.ingest(msg(seq, t, t + 1_000 * MS), |_| {}).expect("late, but nothing to compare with");
        t += 20 * MS;
    }
    for seq in 50..150 {
        let a = c.ingest(msg(seq, t, t + 2 * MS), |_| {}).expect("nothing refused");
        assert!((a.cloud_ns - (t + 2 * MS)).abs() <= 2 * MS, "at (or re-anchored at) its receive time");
        t += 20 * MS;
    }
    assert_eq!((c.warm_clamped(), c.clock_resets(), c.drops().total()), (4, 1, 0));
    // A fitted estimate keeps the longer patience: a stepped clock is the likelier cause then.
    let fitted = c.clock(SourceIndex(0)).is_some_and(ClockEstimator::is_fitted);
    assert!(!fitted, "3 s in: still warming up (4 closed buckets are needed)");
}

#[test]
fn a_burst_of_cached_samples_first_then_live_ones_loses_nothing() {
    // A worker that takes a source over asks its cache: 3.3 s of samples (110 ms apart: a
    // 10 Hz source's ticks, a little late) arrive in one burst, oldest first, each mapping
    // further ahead of the first's anchor (beyond the 100 ms tolerance); then live ones.
    let mut c = core();
    let now = T0_NS + 3_300 * MS;
    for seq in 0..30 {
        c.ingest(msg(seq, T0_NS + seq as i64 * 110 * MS, now + seq as i64 * 10_000), |_| {}).expect("the burst");
    }
    let mut t = now + 50 * MS;
    for seq in 30..60 {
        let a = c.ingest(msg(seq, t - MS, t), |_| {}).expect("live");
        assert!(a.cloud_ns <= t + 100 * MS, "mapped {} ms ahead", (a.cloud_ns - t) / MS);
        t += 100 * MS;
    }
    assert_eq!((c.accepted(), c.drops().total()), (60, 0), "{:?}", c.drops());
}

#[test]
fn a_source_back_from_an_outage_keeps_its_clock_and_a_restarted_one_gets_a_new_estimate() {
    let mut c = core();
    let mut t = T0_NS;
    let mut seq = 0;
    for _ in 0..100 {
        c.ingest(msg(seq, t, t + MS), |_| {}).expect("steady source");
        (seq, t) = (seq + 1, t + 20 * MS);
    }
    // The link goes for 2 s (the source's token with it): its cached samples come back late,
    // in one burst, then it goes on live. Nothing is mapped into the future.
    c.restart_source(SourceIndex(0));
    let back = t + 2_000 * MS;
    for k in 0..100 {
        c.ingest(msg(seq, t + k * 20 * MS, back + MS), |_| {}).expect("a late sample of the same process");
        seq += 1;
    }
    t = back + 20 * MS;
    for _ in 0..10 {
        let a = c.ingest(msg(seq, t, t + MS), |_| {}).expect("live again");
        assert!((a.cloud_ns - (t + MS)).abs() <= MS, "mapped {} for {}", a.cloud_ns, t + MS);
        (seq, t) = (seq + 1, t + 20 * MS);
    }
    // A new process under the name: numbers from 0, its clock 5 s ahead; re-anchored at once.
    c.restart_source(SourceIndex(0));
    let a = c.ingest(msg(0, t + 5_000 * MS, t + MS), |_| {}).expect("the new incarnation's first");
    assert_eq!(a.cloud_ns, t + MS, "anchored at its receive time");
    assert_eq!(c.drops().total(), 0, "{:?}", c.drops());
    assert_eq!(c.dedup().counts(SourceIndex(0)).restarts, 1);
}

#[test]
fn a_new_incarnation_drops_the_clock_estimate_once_not_once_per_stream() {
    let mut c = core();
    let mut t = T0_NS;
    for seq in 0..20 {
        c.ingest(msg(seq, t, t + MS), |_| {}).expect("steady source");
        t += 20 * MS;
    }
    c.restart_source(SourceIndex(0));
    // The new process numbers from 0 on every stream, its clock 5 s ahead.
    let ahead = 5_000 * MS;
    let first = c.ingest(msg(0, t + ahead, t + MS), |_| {}).expect("the new incarnation's first");
    assert_eq!(first.cloud_ns, t + MS, "anchored at its receive time");
    // Its second stream's first sample, 20 ms later on its clock, 30 ms slower on the way:
    // mapped through the new estimate, not anchored again at its own receive time.
    let other = Incoming { stream: StreamIndex(1), ..msg(0, t + ahead + 20 * MS, t + 51 * MS) };
    let second = c.ingest(other, |_| {}).expect("the second stream's first");
    assert_eq!(second.cloud_ns, t + 21 * MS, "one estimate for the whole source");
}

#[test]
fn unknown_streams_are_refused_before_sequence_accounting() {
    let mut c = core();
    let bad = Incoming { stream: StreamIndex(7), ..msg(0, T0_NS, T0_NS) };
    assert_eq!(c.ingest(bad, |_| {}), Err(DropReason::UnknownStream));
    assert_eq!(c.dedup().totals().fresh, 0);
    assert!(c.ingest(msg(0, T0_NS, T0_NS), |_| {}).is_ok());
}

/// Runs `msgs` in order; `timer` interleaves idle-timer advances between messages.
fn run(msgs: &[&Incoming<TestPose>], timer_seed: Option<u64>) -> (Vec<Snapshot<TestPose>>, IngestCore<TestPose>) {
    let mut c = core();
    let mut snaps = Vec::new();
    let mut rng = timer_seed.map(risktwin_common::rng::Rng::new);
    for (i, m) in msgs.iter().enumerate() {
        let _ = c.ingest((*m).clone(), |s| snaps.push(s.clone()));
        if let (Some(rng), Some(next)) = (rng.as_mut(), msgs.get(i + 1))
            && rng.chance(0.05)
        {
            // A timer firing somewhere before the next message arrives.
            let w = m.receive_ns + rng.below((next.receive_ns - m.receive_ns + 1) as u64) as i64;
            c.advance(w, |s| snaps.push(s.clone()));
        }
    }
    (snaps, c)
}

#[test]
fn replaying_a_recording_reproduces_the_live_snapshots_bit_for_bit() {
    // Receive times stamped per 5 ms batch (many ties) and 10 % delay spikes of 50–400 ms, so
    // samples land right at the lateness bound while ticks fall due inside a batch.
    let lossy = Network { spike: 0.1, receive_quantum_ns: 5 * MS, ..net() };
    let (mut sent, _) = fleet(30, 15, 9, lossy);
    // Live: arrival order by receive time, ties broken at random, plus idle-timer advances.
    sent.sort_by_key(|s: &Sent| (s.msg.receive_ns, s.tie_key));
    let live: Vec<&Incoming<TestPose>> = sent.iter().map(|s| &s.msg).collect();
    let ties = live.windows(2).filter(|w| w[0].receive_ns == w[1].receive_ns).count();
    assert!(ties > 1000, "the test needs many receive-time ties, got {ties}");
    let (live_snaps, live_core) = run(&live, Some(5));
    // Recording: the same messages with their receive times, read back in the recorder's order.
    let mut recorded = live.clone();
    recorded.sort_by_key(|m| (m.receive_ns, m.source, m.stream, m.seq));
    assert_ne!(
        live.iter().map(|m| (m.source, m.seq)).collect::<Vec<_>>(),
        recorded.iter().map(|m| (m.source, m.seq)).collect::<Vec<_>>(),
        "orders must differ for the test to mean something"
    );
    let (replay_snaps, replay_core) = run(&recorded, None);
    assert_eq!(live_snaps.len(), replay_snaps.len());
    assert!(live_snaps.len() >= 15 * 20 - 5, "{} snapshots", live_snaps.len());
    assert!(fingerprint(&live_snaps) == fingerprint(&replay_snaps), "replay differs from live");
    assert_eq!(live_core.aligner().counts().late, replay_core.aligner().counts().late);
    // The snapshots are real: mostly interpolated poses, as-of objects.
    let mid = &live_snaps[live_snaps.len() / 2];
    let interpolated = mid.values().iter().step_by(2).filter(|a| a.status == ValueStatus::Interpolated).count();
    let as_of = mid.values().iter().skip(1).step_by(2).filter(|a| a.status == ValueStatus::AsOf).count();
    assert!(interpolated >= 27 && as_of >= 27, "{interpolated} interpolated, {as_of} as-of of 30");
}

#[test]
fn admission_is_told_before_the_snapshots_and_changes_none_of_them() {
    let (mut sent, _) = fleet(20, 15, 4, Network { spike: 0.1, ..net() });
    sent.sort_by_key(|s: &Sent| (s.msg.receive_ns, s.tie_key));
    let (mut plain, mut then) = (core(), core());
    let (mut plain_snaps, mut then_snaps) = (Vec::new(), Vec::new());
    let mut admitted_first = 0;
    for s in &sent {
        let expected = plain.ingest(s.msg.clone(), |snap| plain_snaps.push(snap.clone()));
        // Every event in order: the admission (its cloud time), then the snapshots.
        let events = std::cell::RefCell::new(Vec::new());
        let got = then.ingest_then(
            s.msg.clone(),
            |cloud_ns| events.borrow_mut().push(Some(cloud_ns)),
            |snap| {
                then_snaps.push(snap.clone());
                events.borrow_mut().push(None);
            },
        );
        assert_eq!(got, expected, "the same verdict");
        let events = events.into_inner();
        let admissions: Vec<i64> = events.iter().flatten().copied().collect();
        assert_eq!(admissions, expected.iter().map(|a| a.cloud_ns).collect::<Vec<_>>(), "told once, when accepted");
        if admissions.len() == 1 && events.len() > 1 {
            assert_eq!(events[0], Some(admissions[0]), "before the snapshots it triggers");
            admitted_first += 1;
        }
    }
    assert!(admitted_first > 100, "accepted messages that made ticks due: {admitted_first}");
    assert!(fingerprint(&plain_snaps) == fingerprint(&then_snaps), "the snapshots are the same");
    assert_eq!((plain.accepted(), plain.drops().total()), (then.accepted(), then.drops().total()));
}
