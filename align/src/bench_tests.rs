//! Throughput of the pure ingest core (an `#[ignore]`d measurement that prints, not a timed
//! test). Run: `cargo test -p risktwin-align --release bench_tests -- --ignored --nocapture`.

use super::ingest::{IngestConfig, IngestCore};
use super::interp::tests::TestPose;
use super::test_fleet::{MS, Network, fleet, fleet_streams};

#[test]
#[ignore = "measurement; run in release with --ignored --nocapture"]
fn bench_ingest_2000_vehicles() {
    let vehicles = 2_000;
    let seconds = 10;
    let net = Network {
        base_delay_ns: MS,
        jitter_mean_ns: 2e6,
        spike: 0.001,
        loss: 0.001,
        duplicate: 0.001,
        receive_quantum_ns: 1,
    };
    let (mut sent, _) = fleet(vehicles, seconds, 1, net);
    sent.sort_by_key(|s| (s.msg.receive_ns, s.tie_key));
    let msgs: Vec<_> = sent.into_iter().map(|s| s.msg).collect();
    let n = msgs.len();
    let mut core: IngestCore<TestPose> = IngestCore::new(IngestConfig::default(), &fleet_streams());
    let mut checksum = 0.0;
    let start = std::time::Instant::now();
    for m in msgs {
        let _ = core.ingest(m, |s| {
            checksum += s.values().first().and_then(|a| a.value).map_or(0.0, |p| p.x_m);
        });
    }
    let wall_s = start.elapsed().as_secs_f64();
    let c = core.aligner().counts();
    println!(
        "ingest core: {n} msgs from {vehicles} sources ({seconds} s of 50 Hz pose + 10 Hz objects) in {wall_s:.3} s \
         = {:.2} M msg/s on one core; {} snapshots at 20 Hz of {} values each; accepted {}, drops {}, late {} \
         (checksum {checksum:.1})",
        n as f64 / wall_s / 1e6,
        c.snapshots,
        vehicles * 2,
        core.accepted(),
        core.drops().total(),
        c.late,
    );
    assert!(c.snapshots >= (seconds as u64 - 1) * 20);
}
