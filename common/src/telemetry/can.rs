//! The CAN signal layout of a vehicle edge, like a DBC file: which frame carries which signal,
//! where, and with what scale and offset (physical = raw · scale + offset).
//!
//! | id    | frame          | bytes | signal           | raw | scale  | physical range        |
//! |-------|----------------|-------|------------------|-----|--------|-----------------------|
//! | 0x100 | vehicle motion | 0–1   | `speed_mps`      | u16 | 0.01   | 0 … 655.35 m/s        |
//! | 0x100 | vehicle motion | 2–3   | `accel_mps2`     | i16 | 0.001  | −32.768 … 32.767 m/s² |
//! | 0x100 | vehicle motion | 4–5   | `yaw_rate_radps` | i16 | 0.0001 | −3.2768 … 3.2767 rad/s|
//! | 0x101 | driver input   | 0–1   | `throttle`       | u16 | 0.0001 | 0 … 1                 |
//! | 0x101 | driver input   | 2–3   | `brake`          | u16 | 0.0001 | 0 … 1                 |
//! | 0x101 | driver input   | 4–5   | `steer_rad`      | i16 | 0.0001 | −3.2768 … 3.2767 rad  |
//!
//! All raw values are little-endian (Intel byte order), offsets are 0, both frames have DLC 6.
//! Encoding saturates at the physical range, as an ECU's signal would, and sends NaN as 0.

use super::{CanFrame, Header};

/// Identifier of the vehicle-motion frame (speed, acceleration, yaw rate).
pub const CAN_ID_MOTION: u32 = 0x100;
/// Identifier of the driver-input frame (throttle, brake, steering angle).
pub const CAN_ID_DRIVER: u32 = 0x101;
/// Data length code of both frames.
pub const CAN_DLC: u8 = 6;

/// One 16-bit signal inside a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Signal {
    pub name: &'static str,
    pub can_id: u32,
    /// First (least significant) byte of the little-endian raw value.
    pub start_byte: usize,
    /// Raw value is i16 (true) or u16 (false).
    pub signed: bool,
    pub scale: f64,
    pub offset: f64,
    /// Physical range the encoder saturates to.
    pub min: f64,
    pub max: f64,
}

impl Signal {
    /// The physical value carried in `data`.
    pub fn decode(&self, data: &[u8; 8]) -> f64 {
        let bytes = [data[self.start_byte], data[self.start_byte + 1]];
        let raw = if self.signed { f64::from(i16::from_le_bytes(bytes)) } else { f64::from(u16::from_le_bytes(bytes)) };
        raw * self.scale + self.offset
    }

    /// Writes `value` into `data`, saturated to the signal's range (NaN as 0).
    pub fn encode(&self, value: f64, data: &mut [u8; 8]) {
        let v = if value.is_nan() { 0.0 } else { value.clamp(self.min, self.max) };
        let raw = ((v - self.offset) / self.scale).round();
        let bytes = if self.signed {
            (raw.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16).to_le_bytes()
        } else {
            (raw.clamp(0.0, f64::from(u16::MAX)) as u16).to_le_bytes()
        };
        data[self.start_byte..self.start_byte + 2].copy_from_slice(&bytes);
    }
}

const fn signal(
    name: &'static str,
    can_id: u32,
    start_byte: usize,
    signed: bool,
    scale: f64,
    min: f64,
    max: f64,
) -> Signal {
    Signal { name, can_id, start_byte, signed, scale, offset: 0.0, min, max }
}

/// The signal definitions (the "DBC"), one constant per signal.
pub mod signals {
    use super::{CAN_ID_DRIVER, CAN_ID_MOTION, Signal, signal};
    pub const SPEED_MPS: Signal = signal("speed_mps", CAN_ID_MOTION, 0, false, 0.01, 0.0, 655.35);
    pub const ACCEL_MPS2: Signal = signal("accel_mps2", CAN_ID_MOTION, 2, true, 0.001, -32.768, 32.767);
    pub const YAW_RATE_RADPS: Signal = signal("yaw_rate_radps", CAN_ID_MOTION, 4, true, 1e-4, -3.2768, 3.2767);
    pub const THROTTLE: Signal = signal("throttle", CAN_ID_DRIVER, 0, false, 1e-4, 0.0, 1.0);
    pub const BRAKE: Signal = signal("brake", CAN_ID_DRIVER, 2, false, 1e-4, 0.0, 1.0);
    pub const STEER_RAD: Signal = signal("steer_rad", CAN_ID_DRIVER, 4, true, 1e-4, -3.2768, 3.2767);
}

/// Why a CAN frame could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CanError {
    #[error("unknown CAN id {can_id:#x} (expected 0x100 or 0x101)")]
    UnknownId { can_id: u32 },
    #[error("CAN frame {can_id:#x} has DLC {dlc}, its signals need {need}")]
    ShortFrame { can_id: u32, dlc: u8, need: u8 },
}

/// The physical values of every signal of the layout.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CanSignals {
    pub speed_mps: f64,
    pub accel_mps2: f64,
    pub yaw_rate_radps: f64,
    pub throttle: f64,
    pub brake: f64,
    pub steer_rad: f64,
}

impl CanSignals {
    /// Payload of the vehicle-motion frame (0x100).
    pub fn motion_payload(&self) -> [u8; 8] {
        let mut data = [0; 8];
        signals::SPEED_MPS.encode(self.speed_mps, &mut data);
        signals::ACCEL_MPS2.encode(self.accel_mps2, &mut data);
        signals::YAW_RATE_RADPS.encode(self.yaw_rate_radps, &mut data);
        data
    }

    /// Payload of the driver-input frame (0x101).
    pub fn driver_payload(&self) -> [u8; 8] {
        let mut data = [0; 8];
        signals::THROTTLE.encode(self.throttle, &mut data);
        signals::BRAKE.encode(self.brake, &mut data);
        signals::STEER_RAD.encode(self.steer_rad, &mut data);
        data
    }

    /// Both frames, the motion frame stamped with `motion` and the driver frame with `driver`.
    pub fn to_frames(&self, motion: Header, driver: Header) -> [CanFrame; 2] {
        [
            CanFrame { header: motion, can_id: CAN_ID_MOTION, data: self.motion_payload(), dlc: CAN_DLC },
            CanFrame { header: driver, can_id: CAN_ID_DRIVER, data: self.driver_payload(), dlc: CAN_DLC },
        ]
    }

    /// Updates the signals `frame` carries; the others keep their values.
    pub fn apply(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        if frame.can_id != CAN_ID_MOTION && frame.can_id != CAN_ID_DRIVER {
            return Err(CanError::UnknownId { can_id: frame.can_id });
        }
        if frame.dlc < CAN_DLC {
            return Err(CanError::ShortFrame { can_id: frame.can_id, dlc: frame.dlc, need: CAN_DLC });
        }
        let d = &frame.data;
        if frame.can_id == CAN_ID_MOTION {
            self.speed_mps = signals::SPEED_MPS.decode(d);
            self.accel_mps2 = signals::ACCEL_MPS2.decode(d);
            self.yaw_rate_radps = signals::YAW_RATE_RADPS.decode(d);
        } else {
            self.throttle = signals::THROTTLE.decode(d);
            self.brake = signals::BRAKE.decode(d);
            self.steer_rad = signals::STEER_RAD.decode(d);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::telemetry::Frame;

    fn header(seq: u64) -> Header {
        Header { source: "vehicle-1".into(), seq, capture_time_ns: 5, publish_time_ns: 6, frame: Frame::Vehicle }
    }

    #[test]
    fn frames_round_trip_within_half_a_step() {
        let s = CanSignals {
            speed_mps: 27.777,
            accel_mps2: -6.4321,
            yaw_rate_radps: 0.12345,
            throttle: 0.33333,
            brake: 0.0,
            steer_rad: -0.05432,
        };
        let mut back = CanSignals::default();
        for f in s.to_frames(header(1), header(2)) {
            back.apply(&f).expect("layout frames decode");
        }
        for (sig, a, b) in [
            (signals::SPEED_MPS, s.speed_mps, back.speed_mps),
            (signals::ACCEL_MPS2, s.accel_mps2, back.accel_mps2),
            (signals::YAW_RATE_RADPS, s.yaw_rate_radps, back.yaw_rate_radps),
            (signals::THROTTLE, s.throttle, back.throttle),
            (signals::BRAKE, s.brake, back.brake),
            (signals::STEER_RAD, s.steer_rad, back.steer_rad),
        ] {
            assert!((a - b).abs() <= 0.5 * sig.scale + 1e-12, "{}: {a} vs {b}", sig.name);
        }
    }

    #[test]
    fn raw_bytes_follow_the_documented_layout() {
        let s = CanSignals { speed_mps: 10.0, accel_mps2: -1.0, yaw_rate_radps: 0.0, ..Default::default() };
        let d = s.motion_payload();
        assert_eq!(&d[0..2], &1000u16.to_le_bytes());
        assert_eq!(&d[2..4], &(-1000i16).to_le_bytes());
        assert_eq!(&d[6..8], &[0, 0]);
    }

    #[test]
    fn encoding_saturates_and_sends_nan_as_zero() {
        let s = CanSignals { speed_mps: -3.0, accel_mps2: 1e9, throttle: 2.0, brake: f64::NAN, ..Default::default() };
        let mut back = CanSignals::default();
        back.apply(&s.to_frames(header(1), header(2))[0]).expect("motion frame");
        back.apply(&s.to_frames(header(1), header(2))[1]).expect("driver frame");
        assert_eq!(back.speed_mps, 0.0);
        assert!((back.accel_mps2 - 32.767).abs() < 1e-9);
        assert_eq!(back.throttle, 1.0);
        assert_eq!(back.brake, 0.0);
    }

    #[test]
    fn unknown_and_short_frames_are_rejected() {
        let mut s = CanSignals::default();
        let mut f = CanFrame { header: header(1), can_id: 0x7ff, data: [0; 8], dlc: 8 };
        assert_eq!(s.apply(&f), Err(CanError::UnknownId { can_id: 0x7ff }));
        f.can_id = CAN_ID_MOTION;
        f.dlc = 4;
        assert_eq!(s.apply(&f), Err(CanError::ShortFrame { can_id: CAN_ID_MOTION, dlc: 4, need: 6 }));
    }
}
