//! Ego vehicle dynamics: parameters, kinematic and dynamic single-track models, actuators.

/// Standard gravity, m/s².
pub const GRAVITY_MPS2: f64 = 9.81;
