//! Scripted pedestrians: a straight walk at constant speed (e.g. across a crosswalk).
//!
//! Pure functions of time; the world turns a walking pedestrian into an
//! [`super::ExternalAgent`] so traffic yields to it.

use super::ExternalAgent;
use crate::geometry::{Footprint, Pose, Vec2};
use serde::{Deserialize, Serialize};

/// A pedestrian walking from `start` along `heading_rad` for `path_length_m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PedestrianWalk {
    pub start: Vec2,
    pub heading_rad: f64,
    pub speed_mps: f64,
    pub start_time_s: f64,
    pub path_length_m: f64,
    /// Body radius (collision and perception extent).
    pub radius_m: f64,
}

impl PedestrianWalk {
    /// Seconds the walk lasts (infinite for a pedestrian standing still on its path).
    fn duration_s(&self) -> f64 {
        if self.speed_mps > 0.0 { self.path_length_m / self.speed_mps } else { f64::INFINITY }
    }

    fn is_walking(&self, time_s: f64) -> bool {
        time_s >= self.start_time_s && time_s <= self.start_time_s + self.duration_s()
    }

    /// Position at `time_s`; `None` before the start and after the end of the path.
    pub fn position_at(&self, time_s: f64) -> Option<Vec2> {
        if !self.is_walking(time_s) {
            return None;
        }
        let dir = Vec2::new(self.heading_rad.cos(), self.heading_rad.sin());
        let travelled_m = (self.speed_mps.max(0.0) * (time_s - self.start_time_s)).min(self.path_length_m);
        Some(self.start + dir * travelled_m)
    }

    /// The pedestrian as an agent traffic yields to (a square of side 2r), while on its path.
    pub fn agent_at(&self, time_s: f64) -> Option<ExternalAgent> {
        let p = self.position_at(time_s)?;
        let side = 2.0 * self.radius_m.max(0.0);
        Some(ExternalAgent {
            pose: Pose::new(p.x, p.y, self.heading_rad),
            velocity: self.velocity_at(time_s),
            footprint: Footprint::new(side, side),
        })
    }

    /// Velocity at `time_s` (zero when not on the path).
    pub fn velocity_at(&self, time_s: f64) -> Vec2 {
        if !self.is_walking(time_s) {
            return Vec2::zeros();
        }
        Vec2::new(self.heading_rad.cos(), self.heading_rad.sin()) * self.speed_mps.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn walks_across_and_leaves() {
        let w = PedestrianWalk {
            start: Vec2::new(100.0, -3.0),
            heading_rad: FRAC_PI_2,
            speed_mps: 1.4,
            start_time_s: 2.0,
            path_length_m: 14.0,
            radius_m: 0.3,
        };
        assert_eq!(w.position_at(1.9), None);
        assert_eq!(w.velocity_at(1.9), Vec2::zeros());
        let p = w.position_at(7.0).expect("walking at 7 s");
        assert!((p - Vec2::new(100.0, 4.0)).norm() < 1e-9, "{p:?}");
        assert!((w.velocity_at(7.0) - Vec2::new(0.0, 1.4)).norm() < 1e-9);
        // 14 m at 1.4 m/s: done at 12 s.
        assert!(w.position_at(12.0).is_some());
        assert_eq!(w.position_at(12.01), None);
        let agent = w.agent_at(7.0).expect("walking");
        assert_eq!(agent.footprint, Footprint::new(0.6, 0.6));
        assert_eq!(agent.pose.position(), p);
        assert!(w.agent_at(1.0).is_none());
    }
}
