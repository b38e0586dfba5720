//! A synthetic fleet for tests and the throughput measurement: vehicles with their own clocks
//! (offset, drift), a 50 Hz pose stream and a 10 Hz object stream, sent over a network with
//! delay jitter, rare delay spikes, loss and duplication.

use super::aligner::{StreamMode, StreamSpec};
use super::ingest::Incoming;
use super::interp::tests::TestPose;
use super::snapshot::StreamIndex;
use super::source::SourceIndex;
use risktwin_common::rng::Rng;

pub const MS: i64 = 1_000_000;
pub const T0_NS: i64 = 1_700_000_000_000_000_000;
pub const POSE_PERIOD_NS: i64 = 20 * MS;
pub const OBJECTS_PERIOD_NS: i64 = 100 * MS;

/// The two streams: pose (continuous), objects (discrete).
pub fn fleet_streams() -> [StreamSpec; 2] {
    [
        StreamSpec { mode: StreamMode::Interpolated, period_ns: POSE_PERIOD_NS },
        StreamSpec { mode: StreamMode::AsOf, period_ns: OBJECTS_PERIOD_NS },
    ]
}

/// The network between the fleet and the cloud.
#[derive(Debug, Clone, Copy)]
pub struct Network {
    pub base_delay_ns: i64,
    pub jitter_mean_ns: f64,
    /// Probability of a 50–400 ms delay spike (makes late data around the lateness bound).
    pub spike: f64,
    pub loss: f64,
    pub duplicate: f64,
    /// Receive times rounded to this (1 ms makes many ties); 1 for none.
    pub receive_quantum_ns: i64,
}

/// One sent message and a random key for breaking receive-time ties "live".
pub struct Sent {
    pub msg: Incoming<TestPose>,
    pub tie_key: u64,
}

/// Every message the fleet sends over `seconds`, in no particular order; `sent` counts the
/// unique (source, stream, seq) numbers.
pub fn fleet(vehicles: u32, seconds: i64, seed: u64, net: Network) -> (Vec<Sent>, u64) {
    let mut out = Vec::new();
    let mut sent = 0;
    for v in 0..vehicles {
        let mut rng = Rng::derive(seed, u64::from(v));
        let offset_ns = rng.uniform(-2e9, 2e9) as i64;
        let drift = rng.uniform(-100e-6, 100e-6);
        let phase_ns = rng.uniform(0.0, 20e6) as i64;
        for (stream, period_ns) in [(0u16, POSE_PERIOD_NS), (1, OBJECTS_PERIOD_NS)] {
            let n = seconds * 1_000_000_000 / period_ns;
            for k in 0..n {
                sent += 1;
                let t = T0_NS + phase_ns + k * period_ns;
                let capture_ns = t + offset_ns + ((t - T0_NS) as f64 * drift) as i64;
                let heading = (v as f64 + 0.05 * k as f64) % std::f64::consts::TAU - std::f64::consts::PI;
                let payload =
                    TestPose { x_m: (t - T0_NS) as f64 * 1e-9 * 15.0, y_m: f64::from(v), heading_rad: heading };
                if rng.chance(net.loss) {
                    continue;
                }
                let copies = if rng.chance(net.duplicate) { 2 } else { 1 };
                for _ in 0..copies {
                    let mut delay = net.base_delay_ns + (-net.jitter_mean_ns * (1.0 - rng.unit()).ln()) as i64;
                    if rng.chance(net.spike) {
                        delay += rng.uniform(50e6, 400e6) as i64;
                    }
                    let q = net.receive_quantum_ns.max(1);
                    let receive_ns = (t + delay).div_euclid(q) * q;
                    let msg = Incoming {
                        source: SourceIndex(v),
                        stream: StreamIndex(stream),
                        seq: k as u64,
                        capture_ns,
                        receive_ns,
                        payload,
                    };
                    out.push(Sent { msg, tie_key: rng.next_u64() });
                }
            }
        }
    }
    (out, sent)
}
