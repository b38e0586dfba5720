//! The world as the telemetry an edge would publish: one state sample per moving thing,
//! stamped with the simulation clock. Sources are `ego`, `veh-<index>` and `ped-<index>`.

use super::World;
use crate::geometry::{Footprint, Pose};
use crate::telemetry::{Frame, Header, VehicleStateSample};
use crate::vehicle::Vehicle;

impl Vehicle {
    /// The vehicle's state as a telemetry sample under `header` (pose and velocity of the
    /// footprint centre).
    pub fn state_sample(&self, header: Header) -> VehicleStateSample {
        VehicleStateSample {
            header,
            pose: self.pose(),
            velocity: self.velocity(),
            speed_mps: self.state.speed_mps,
            accel_mps2: self.state.accel_mps2,
            yaw_rate_radps: self.state.yaw_rate_radps,
            steer_rad: self.state.steer_rad,
            footprint: self.params.footprint(),
        }
    }
}

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
        out.push(self.ego.state_sample(header("ego".into())));
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
