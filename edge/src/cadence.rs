//! One tick of a vehicle, shared by the two roles that simulate one: `edge vehicle`
//! ([`crate::vehicle`], protobuf messages on Zenoh) and `edge sensor` ([`crate::sensor`],
//! plain-old-data samples into iceoryx2 for the vehicle's gateway). The role supplies the world
//! and the outlet ([`VehicleOutlet`]); [`vehicle_tick`] decides what is due when, so that both
//! publish the same streams at the same rates in the same order.
//!
//! A vehicle ticks [`TICKS_PER_STEP`] times per simulation step: each step (50 Hz at the default
//! rate) the world advances and the ego state goes out, every [`STEPS_PER_PERCEPTION`]th step
//! (10 Hz) the perceived objects, and every tick the motion and driver CAN frames (100 Hz per
//! frame id) with the signals of the last step.

use risktwin_common::telemetry::{CAN_ID_DRIVER, CAN_ID_MOTION, CanSignals};
use risktwin_common::vehicle::Controls;

/// Ticks per simulation step: CAN goes out every tick, state once per step.
pub const TICKS_PER_STEP: u32 = 2;

/// Simulation steps per perception message.
pub const STEPS_PER_PERCEPTION: u64 = 5;

/// A vehicle role's world and where its messages go.
pub trait VehicleOutlet {
    /// Why publishing failed.
    type Error;
    /// Advances the world one simulation step.
    fn step(&mut self) -> Result<(), Self::Error>;
    /// Publishes the ego state of the last step.
    fn publish_state(&mut self) -> Result<(), Self::Error>;
    /// Publishes the objects perceived at the last step.
    fn publish_perception(&mut self) -> Result<(), Self::Error>;
    /// The ego's CAN signals as of the last step.
    fn signals(&self) -> CanSignals;
    /// Publishes one CAN frame of `can_id` with its 8 payload bytes.
    fn publish_can(&mut self, can_id: u32, data: [u8; 8]) -> Result<(), Self::Error>;
}

/// Tick number `tick` (counted from 0 at the start of the run) of the vehicle behind `outlet`.
pub fn vehicle_tick<O: VehicleOutlet>(tick: u64, outlet: &mut O) -> Result<(), O::Error> {
    let ticks_per_step = u64::from(TICKS_PER_STEP);
    if tick.is_multiple_of(ticks_per_step) {
        outlet.step()?;
        outlet.publish_state()?;
        if (tick / ticks_per_step).is_multiple_of(STEPS_PER_PERCEPTION) {
            outlet.publish_perception()?;
        }
    }
    let signals = outlet.signals();
    outlet.publish_can(CAN_ID_MOTION, signals.motion_payload())?;
    outlet.publish_can(CAN_ID_DRIVER, signals.driver_payload())
}

/// The CAN signals of an ego moving at these values under `controls`.
pub fn ego_signals(
    speed_mps: f64,
    accel_mps2: f64,
    yaw_rate_radps: f64,
    steer_rad: f64,
    controls: &Controls,
) -> CanSignals {
    CanSignals { speed_mps, accel_mps2, yaw_rate_radps, throttle: controls.throttle, brake: controls.brake, steer_rad }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::Infallible;

    /// Records what was published, in order.
    #[derive(Default)]
    struct Log {
        steps: u64,
        published: Vec<String>,
    }

    impl VehicleOutlet for Log {
        type Error = Infallible;

        fn step(&mut self) -> Result<(), Infallible> {
            self.steps += 1;
            Ok(())
        }

        fn publish_state(&mut self) -> Result<(), Infallible> {
            self.published.push(format!("state{}", self.steps));
            Ok(())
        }

        fn publish_perception(&mut self) -> Result<(), Infallible> {
            self.published.push(format!("perception{}", self.steps));
            Ok(())
        }

        fn signals(&self) -> CanSignals {
            CanSignals { speed_mps: self.steps as f64, ..CanSignals::default() }
        }

        fn publish_can(&mut self, can_id: u32, data: [u8; 8]) -> Result<(), Infallible> {
            let expected = match can_id {
                CAN_ID_MOTION => self.signals().motion_payload(),
                _ => self.signals().driver_payload(),
            };
            assert_eq!(data, expected, "the frame carries the signals of the last step");
            self.published.push(format!("can{can_id:#x}"));
            Ok(())
        }
    }

    #[test]
    fn state_per_step_perception_every_fifth_can_every_tick() {
        let mut log = Log::default();
        for tick in 0..20 {
            let Ok(()) = vehicle_tick(tick, &mut log);
        }
        let count = |prefix: &str| log.published.iter().filter(|p| p.starts_with(prefix)).count();
        assert_eq!((log.steps, count("state"), count("perception"), count("can")), (10, 10, 2, 40));
        assert_eq!(log.published[..4], ["state1", "perception1", "can0x100", "can0x101"]);
        // The odd tick only repeats the CAN frames; the next step's state follows.
        assert_eq!(log.published[4..7], ["can0x100", "can0x101", "state2"]);
        assert!(log.published.contains(&"perception6".to_owned()), "{:?}", log.published);
    }

    #[test]
    fn signals_take_motion_from_the_ego_and_pedals_from_the_controls() {
        let controls = Controls { throttle: 0.25, brake: 0.5, ..Controls::default() };
        let s = ego_signals(10.0, -1.0, 0.1, 0.02, &controls);
        assert_eq!((s.speed_mps, s.accel_mps2, s.yaw_rate_radps, s.steer_rad), (10.0, -1.0, 0.1, 0.02));
        assert_eq!((s.throttle, s.brake), (0.25, 0.5));
    }
}
