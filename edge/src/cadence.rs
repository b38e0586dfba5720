//! One tick of a vehicle, shared by the two roles that simulate one: `edge vehicle`
//! ([`crate::vehicle`], protobuf messages on Zenoh) and `edge sensor` ([`crate::sensor`],
//! plain-old-data samples into iceoryx2 for the vehicle's gateway). The role supplies the
//! simulation and the outlet ([`VehicleOutlet`]); [`vehicle_tick`] decides what is due when, so
//! that both publish the same streams at the same rates in the same order.
//!
//! One simulation, the world's: physics at `common::world::STEP_S` (50 ms, 20 Hz, one decision
//! per step). The streams are faster than that, so they carry *interpolated* samples of it: a
//! tick is [`TICK_S`] (10 ms) of simulated time, [`TICKS_PER_STEP`] per physics step. At the
//! first tick of each physics step the simulation advances one step, to the end of the
//! [`Segment`] the tick and the next ones sample, so it runs one step ahead of what goes out and
//! interpolation never extrapolates. Tick `k` of a step publishes the ego at fraction
//! (k + 1) / [`TICKS_PER_STEP`] of it: the state every [`TICKS_PER_STATE`] ticks (50 Hz), the
//! motion and driver CAN frames every tick (100 Hz per frame id), and every
//! [`TICKS_PER_PERCEPTION`] ticks (10 Hz, every 2nd physics step) the objects perceived at the
//! start of the step. Pose (heading on the shortest arc), speed, acceleration, yaw rate and
//! steering angle are linear between the step's two states; the pedals are the controls the
//! driver held over the step.

use risktwin_common::geometry::wrap_angle;
use risktwin_common::telemetry::{CAN_ID_DRIVER, CAN_ID_MOTION, CanSignals};
use risktwin_common::vehicle::{Controls, Vehicle, VehicleState};
use risktwin_common::world::STEP_S;
use risktwin_transport::EdgeStream;

/// Ticks per physics step.
pub const TICKS_PER_STEP: u32 = 5;

/// Simulated time per tick, s: 10 ms, the CAN period.
pub const TICK_S: f64 = STEP_S / TICKS_PER_STEP as f64;

/// Ticks per ego state message (50 Hz).
pub const TICKS_PER_STATE: u32 = 2;

/// Ticks per perception message (10 Hz: every 2nd physics step).
pub const TICKS_PER_PERCEPTION: u64 = 2 * TICKS_PER_STEP as u64;

/// CAN frames per tick (the motion and the driver frame).
pub const CAN_FRAMES_PER_TICK: u32 = 2;

/// Messages a vehicle publishes on `stream` per state message (none on a stream it lacks).
pub fn messages_per_state(stream: EdgeStream) -> f64 {
    match stream {
        EdgeStream::State => 1.0,
        EdgeStream::Can => f64::from(CAN_FRAMES_PER_TICK * TICKS_PER_STATE),
        EdgeStream::Perception => f64::from(TICKS_PER_STATE) / TICKS_PER_PERCEPTION as f64,
        EdgeStream::Rsu | EdgeStream::Signal => 0.0,
    }
}

/// The ego over one physics step, as the streams sample it.
#[derive(Debug, Clone)]
pub struct Segment {
    /// The ego at the end of the step (its parameters hold for every sample of the step).
    pub ego: Vehicle,
    /// The ego's state at the start of the step.
    pub from: VehicleState,
    /// The controls the driver held over the step.
    pub controls: Controls,
}

impl Segment {
    /// `ego` standing where it is: what a role holds before its first step.
    pub fn at_rest(ego: Vehicle) -> Self {
        Segment { from: ego.state, ego, controls: Controls::default() }
    }

    /// The ego at `fraction` (0 = start, 1 = end) of the step, interpolated linearly.
    pub fn at(&self, fraction: f64) -> Vehicle {
        let (a, b) = (&self.from, &self.ego.state);
        let lerp = |x: f64, y: f64| x + (y - x) * fraction;
        let mut ego = self.ego.clone();
        ego.state = VehicleState {
            x_m: lerp(a.x_m, b.x_m),
            y_m: lerp(a.y_m, b.y_m),
            heading_rad: a.heading_rad + wrap_angle(b.heading_rad - a.heading_rad) * fraction,
            speed_mps: lerp(a.speed_mps, b.speed_mps),
            yaw_rate_radps: lerp(a.yaw_rate_radps, b.yaw_rate_radps),
            slip_angle_rad: lerp(a.slip_angle_rad, b.slip_angle_rad),
            steer_rad: lerp(a.steer_rad, b.steer_rad),
            accel_mps2: lerp(a.accel_mps2, b.accel_mps2),
        };
        ego
    }
}

/// A vehicle role's simulation and where its messages go.
pub trait VehicleOutlet {
    /// Why publishing failed.
    type Error;
    /// Advances the simulation one physics step.
    fn step(&mut self) -> Result<(), Self::Error>;
    /// The last step, which the ticks until the next step sample.
    fn segment(&self) -> &Segment;
    /// Publishes `ego`, the ego as of this tick.
    fn publish_state(&mut self, ego: &Vehicle) -> Result<(), Self::Error>;
    /// Publishes the objects perceived at the start of the last step.
    fn publish_perception(&mut self) -> Result<(), Self::Error>;
    /// Publishes one CAN frame of `can_id` with its 8 payload bytes.
    fn publish_can(&mut self, can_id: u32, data: [u8; 8]) -> Result<(), Self::Error>;
}

/// Tick number `tick` (counted from 0 at the start of the run) of the vehicle behind `outlet`.
pub fn vehicle_tick<O: VehicleOutlet>(tick: u64, outlet: &mut O) -> Result<(), O::Error> {
    let in_step = tick % u64::from(TICKS_PER_STEP);
    if in_step == 0 {
        outlet.step()?;
    }
    let segment = outlet.segment();
    let ego = segment.at((in_step + 1) as f64 / f64::from(TICKS_PER_STEP));
    let signals = ego_signals(&ego, &segment.controls);
    if tick.is_multiple_of(u64::from(TICKS_PER_STATE)) {
        outlet.publish_state(&ego)?;
    }
    if tick.is_multiple_of(TICKS_PER_PERCEPTION) {
        outlet.publish_perception()?;
    }
    outlet.publish_can(CAN_ID_MOTION, signals.motion_payload())?;
    outlet.publish_can(CAN_ID_DRIVER, signals.driver_payload())
}

/// The CAN signals of `ego` under `controls`.
pub fn ego_signals(ego: &Vehicle, controls: &Controls) -> CanSignals {
    let s = &ego.state;
    CanSignals {
        speed_mps: s.speed_mps,
        accel_mps2: s.accel_mps2,
        yaw_rate_radps: s.yaw_rate_radps,
        throttle: controls.throttle,
        brake: controls.brake,
        steer_rad: s.steer_rad,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::geometry::Pose;
    use risktwin_common::vehicle::{ModelKind, VehicleParams};
    use std::convert::Infallible;

    /// An ego whose state is `x_m` along x at `x_m` m/s.
    fn ego_at(x_m: f64) -> Vehicle {
        let mut ego = Vehicle::new(VehicleParams::default(), ModelKind::SingleTrack, Pose::new(0.0, 0.0, 0.0), 0.0);
        ego.state = VehicleState { x_m, speed_mps: x_m, ..VehicleState::default() };
        ego
    }

    /// A simulation whose ego moves 1 m per step, and what was published, in order.
    struct Log {
        steps: u32,
        segment: Segment,
        published: Vec<String>,
    }

    impl VehicleOutlet for Log {
        type Error = Infallible;

        fn step(&mut self) -> Result<(), Infallible> {
            self.steps += 1;
            let from = self.segment.ego.state;
            let controls = Controls { brake: f64::from(self.steps) / 10.0, ..Controls::default() };
            self.segment = Segment { ego: ego_at(f64::from(self.steps)), from, controls };
            Ok(())
        }

        fn segment(&self) -> &Segment {
            &self.segment
        }

        fn publish_state(&mut self, ego: &Vehicle) -> Result<(), Infallible> {
            self.published.push(format!("state{:.1}", ego.state.x_m));
            Ok(())
        }

        fn publish_perception(&mut self) -> Result<(), Infallible> {
            self.published.push(format!("perception{}", self.steps));
            Ok(())
        }

        fn publish_can(&mut self, can_id: u32, data: [u8; 8]) -> Result<(), Infallible> {
            if can_id == CAN_ID_DRIVER {
                let held = ego_signals(&ego_at(0.0), &self.segment.controls).driver_payload();
                assert_eq!(data, held, "the pedals held over the step");
            }
            self.published.push(format!("can{can_id:#x}"));
            Ok(())
        }
    }

    #[test]
    fn ticks_sample_the_physics_step_ahead_at_50_100_and_10_hz() {
        assert!((TICK_S - 0.01).abs() < 1e-15, "CAN every 10 ms: {TICK_S}");
        let mut log = Log { steps: 0, segment: Segment::at_rest(ego_at(0.0)), published: Vec::new() };
        for tick in 0..20 {
            let Ok(()) = vehicle_tick(tick, &mut log);
        }
        let count = |prefix: &str| log.published.iter().filter(|p| p.starts_with(prefix)).count();
        // 200 ms: 4 physics steps, 10 states, 2 object lists, 2 × 20 CAN frames.
        assert_eq!((log.steps, count("state"), count("perception"), count("can")), (4, 10, 2, 40));
        // What sizes each stream's recovery cache agrees with what goes out.
        for (stream, prefix) in
            [(EdgeStream::State, "state"), (EdgeStream::Can, "can"), (EdgeStream::Perception, "perc")]
        {
            assert_eq!(messages_per_state(stream) * 10.0, count(prefix) as f64, "{stream:?}");
        }
        // Tick k of a step samples (k + 1)/5 of it: 10, 30, 50, 70 ms … of 1 m per 50 ms.
        let states: Vec<&str> = log.published.iter().filter(|p| p.starts_with("state")).map(String::as_str).collect();
        assert_eq!(
            states,
            [
                "state0.2", "state0.6", "state1.0", "state1.4", "state1.8", "state2.2", "state2.6", "state3.0",
                "state3.4", "state3.8"
            ]
        );
        assert_eq!(log.published[..4], ["state0.2", "perception1", "can0x100", "can0x101"]);
        assert_eq!(log.published[4..7], ["can0x100", "can0x101", "state0.6"]);
        assert!(log.published.contains(&"perception3".to_owned()), "every 2nd step: {:?}", log.published);
    }

    #[test]
    fn a_segment_interpolates_linearly_and_the_heading_on_the_shortest_arc() {
        let mut segment = Segment::at_rest(ego_at(0.0));
        segment.from.heading_rad = 3.1;
        segment.from.steer_rad = 0.1;
        segment.ego.state = VehicleState { x_m: 2.0, heading_rad: -3.1, speed_mps: 4.0, ..VehicleState::default() };
        assert_eq!(segment.at(0.0).state, segment.from);
        let end = segment.at(1.0).state;
        assert!((end.x_m, end.speed_mps, end.steer_rad) == (2.0, 4.0, 0.0));
        assert!((wrap_angle(end.heading_rad) + 3.1).abs() < 1e-12, "{}", end.heading_rad);
        let mid = segment.at(0.5).state;
        assert_eq!((mid.x_m, mid.speed_mps, mid.steer_rad), (1.0, 2.0, 0.05));
        // Through ±π, not through 0.
        assert!((wrap_angle(mid.heading_rad).abs() - std::f64::consts::PI).abs() < 1e-12, "{}", mid.heading_rad);
    }
}
