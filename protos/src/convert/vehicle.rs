//! Vehicle state, CAN frames and control commands.

use super::geometry::{footprint_from, footprint_to, header, pose_from, pose_to, vec_from, vec_to};
use super::{ConvertError, finite, in_range, invalid};
use crate::v1;
use risktwin_common::telemetry::{CanFrame, ControlCommand, VehicleStateSample};
use risktwin_common::vehicle::Controls;

/// Largest CAN identifier (29-bit extended).
const CAN_ID_MAX: u32 = 0x1FFF_FFFF;

impl From<&VehicleStateSample> for v1::VehicleState {
    fn from(s: &VehicleStateSample) -> Self {
        Self {
            header: Some((&s.header).into()),
            pose: Some(pose_to(&s.pose)),
            velocity_mps: Some(vec_to(&s.velocity)),
            speed_mps: s.speed_mps,
            accel_mps2: s.accel_mps2,
            yaw_rate_radps: s.yaw_rate_radps,
            steer_rad: s.steer_rad,
            footprint: Some(footprint_to(&s.footprint)),
        }
    }
}

impl TryFrom<v1::VehicleState> for VehicleStateSample {
    type Error = ConvertError;
    fn try_from(s: v1::VehicleState) -> Result<Self, ConvertError> {
        const M: &str = "VehicleState";
        Ok(Self {
            header: header(M, s.header)?,
            pose: pose_from(M, "pose", s.pose)?,
            velocity: vec_from(M, "velocity_mps", s.velocity_mps)?,
            speed_mps: finite(M, "speed_mps", s.speed_mps)?,
            accel_mps2: finite(M, "accel_mps2", s.accel_mps2)?,
            yaw_rate_radps: finite(M, "yaw_rate_radps", s.yaw_rate_radps)?,
            steer_rad: finite(M, "steer_rad", s.steer_rad)?,
            footprint: footprint_from(M, "footprint", s.footprint)?,
        })
    }
}

impl From<&CanFrame> for v1::CanFrame {
    fn from(f: &CanFrame) -> Self {
        // A DLC above 8 cannot be built through the validated path; clamp rather than panic.
        let len = usize::from(f.dlc).min(8);
        Self { header: Some((&f.header).into()), can_id: f.can_id, data: f.data[..len].to_vec() }
    }
}

impl TryFrom<v1::CanFrame> for CanFrame {
    type Error = ConvertError;
    fn try_from(f: v1::CanFrame) -> Result<Self, ConvertError> {
        const M: &str = "CanFrame";
        if f.can_id > CAN_ID_MAX {
            return Err(invalid(M, "can_id", format!("{:#x} exceeds the 29-bit maximum {CAN_ID_MAX:#x}", f.can_id)));
        }
        if f.data.len() > 8 {
            return Err(invalid(M, "data", format!("{} bytes, a CAN frame carries at most 8", f.data.len())));
        }
        let mut data = [0u8; 8];
        data[..f.data.len()].copy_from_slice(&f.data);
        Ok(Self { header: header(M, f.header)?, can_id: f.can_id, data, dlc: f.data.len() as u8 })
    }
}

impl From<&ControlCommand> for v1::ControlCommand {
    fn from(c: &ControlCommand) -> Self {
        Self {
            header: Some((&c.header).into()),
            steer_rad: c.controls.steer_rad,
            throttle: c.controls.throttle,
            brake: c.controls.brake,
        }
    }
}

impl TryFrom<v1::ControlCommand> for ControlCommand {
    type Error = ConvertError;
    fn try_from(c: v1::ControlCommand) -> Result<Self, ConvertError> {
        const M: &str = "ControlCommand";
        Ok(Self {
            header: header(M, c.header)?,
            controls: Controls::new(
                finite(M, "steer_rad", c.steer_rad)?,
                in_range(M, "throttle", c.throttle, 0.0, 1.0)?,
                in_range(M, "brake", c.brake, 0.0, 1.0)?,
            ),
        })
    }
}
