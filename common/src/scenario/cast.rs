//! The cast of every scenario: footprints and fixed layout constants, with their sources.

use crate::geometry::Footprint;

/// The ego: BMW 320i, CommonRoad vehicle parameter set 2 (4.508 m × 1.610 m).
pub const EGO: Footprint = Footprint::new(4.508, 1.610);
/// A mid-size passenger car.
pub const CAR: Footprint = Footprint::new(4.5, 1.8);
/// A rigid truck or bus (EU max width 2.55 m).
pub const TRUCK: Footprint = Footprint::new(12.0, 2.55);
/// Pedestrian body radius used for contact (shoulder half-width ≈ 0.3 m).
pub const PEDESTRIAN_RADIUS_M: f64 = 0.3;
/// Dry asphalt friction coefficient.
pub const DRY_MU: f64 = 0.9;
/// Standard lane width (German RAA/US AASHTO ≈ 3.5–3.7 m).
pub const LANE_WIDTH_M: f64 = 3.5;
/// Distance between parked cars' centres along the kerb.
pub const PARKED_SPACING_M: f64 = 5.5;
/// Where the ego starts along the reference lane: room behind it for followers.
pub const EGO_START_S_M: f64 = 30.0;

/// Number of parked cars for an occlusion level in [0, 1] (0 → none, 1 → three).
pub fn parked_count(occlusion_level: f64) -> usize {
    (occlusion_level * 3.0).round().clamp(0.0, 3.0) as usize
}
