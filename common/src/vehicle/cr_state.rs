//! The CommonRoad state vector that the kinematic ([`super::kinematic`]) and dynamic
//! ([`super::single_track`]) single-track models share, with its index names. Its own module so
//! that both models depend on it and not on each other.

/// CommonRoad single-track state `[x_m, y_m, δ_rad, v_mps, ψ_rad, ψ'_radps, β_rad]`.
pub type CrState = [f64; 7];
/// Index of the steering angle δ in [`CrState`].
pub const DELTA: usize = 2;
/// Index of the speed v in [`CrState`].
pub const V: usize = 3;
/// Index of the yaw angle ψ in [`CrState`].
pub const PSI: usize = 4;
/// Index of the yaw rate ψ' in [`CrState`].
pub const YAW_RATE: usize = 5;
/// Index of the slip angle β in [`CrState`].
pub const BETA: usize = 6;
