//! The world as the telemetry an edge would publish: one state sample per moving thing,
//! stamped with the simulation clock. Sources are `ego`, `veh-<index>` and `ped-<index>`.

use super::World;
use crate::geometry::{Footprint, Pose};
use crate::telemetry::{Frame, Header, VehicleStateSample};

impl World {
    /// Replaces `out` with the state of the ego, every active traffic vehicle and every
    /// pedestrian on the road, each with sequence number `seq` and the world's time.
    pub fn state_samples(&self, seq: u64, out: &mut Vec<VehicleStateSample>) {
        out.clear();
        let time_ns = (self.time_s * 1e9).round() as i64;
        let header = |source: String| Header {
            source,
            seq,
            capture_time_ns: time_ns,
            publish_time_ns: time_ns,
            frame: Frame::World,
        };
        let ego = &self.ego;
        out.push(VehicleStateSample {
            header: header("ego".into()),
            pose: ego.pose(),
            velocity: ego.velocity(),
            speed_mps: ego.state.speed_mps,
            accel_mps2: ego.state.accel_mps2,
            yaw_rate_radps: ego.state.yaw_rate_radps,
            steer_rad: ego.state.steer_rad,
            footprint: ego.params.footprint(),
        });
        let t = &self.traffic;
        for i in (0..t.len()).filter(|&i| t.is_active(i)) {
            out.push(VehicleStateSample {
                header: header(format!("veh-{i}")),
                pose: t.pose(i),
                velocity: t.velocity(i),
                speed_mps: t.speed_mps(i),
                accel_mps2: t.accel_mps2(i),
                yaw_rate_radps: 0.0,
                steer_rad: 0.0,
                footprint: t.footprint(i),
            });
        }
        for (k, p) in self.pedestrians.iter().enumerate() {
            if let Some(pos) = p.position_at(self.time_s) {
                let velocity = p.velocity_at(self.time_s);
                let obb = World::pedestrian_obb(pos, velocity);
                out.push(VehicleStateSample {
                    header: header(format!("ped-{k}")),
                    pose: Pose::new(pos.x, pos.y, obb.axis.y.atan2(obb.axis.x)),
                    velocity,
                    speed_mps: velocity.norm(),
                    accel_mps2: 0.0,
                    yaw_rate_radps: 0.0,
                    steer_rad: 0.0,
                    footprint: Footprint::new(2.0 * obb.half_length_m, 2.0 * obb.half_width_m),
                });
            }
        }
    }
}
