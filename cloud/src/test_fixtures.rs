//! Test fixtures shared by the cloud crate's tests.

use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::telemetry::{Frame, Header, VehicleStateSample};

/// A car driving along +x at 20 m/s, sampled at `t_ns` (its position follows the time).
pub fn state(source: &str, seq: u64, t_ns: i64) -> VehicleStateSample {
    let x = 20.0 * t_ns as f64 * 1e-9;
    VehicleStateSample {
        header: Header {
            source: source.into(),
            seq,
            capture_time_ns: t_ns,
            publish_time_ns: t_ns,
            frame: Frame::World,
        },
        pose: Pose::new(x, 0.0, 0.0),
        velocity: Vec2::new(20.0, 0.0),
        speed_mps: 20.0,
        accel_mps2: 0.0,
        yaw_rate_radps: 0.0,
        steer_rad: 0.0,
        footprint: Footprint::new(4.5, 1.8),
    }
}
