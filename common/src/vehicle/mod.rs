//! Ego vehicle dynamics: parameters, kinematic and dynamic single-track models, actuators.
//!
//! [`params`] holds a real car (CommonRoad vehicle 2, BMW 320i); [`actuator`] turns steering,
//! throttle and brake commands into the CommonRoad inputs; [`kinematic`] and [`single_track`]
//! are the CommonRoad KS and ST models over the state vector of [`cr_state`]; [`dynamics`]
//! ties them into one [`Vehicle`] stepped with RK4 on a road of given friction.

pub mod actuator;
pub mod cr_state;
pub mod dynamics;
pub mod kinematic;
pub mod params;
pub mod single_track;

pub use actuator::Controls;
pub use dynamics::{ModelKind, Vehicle, VehicleState};
pub use params::{GRAVITY_MPS2, VehicleParams};
