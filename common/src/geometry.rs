//! Planar geometry shared by every module: poses, rectangular footprints and their
//! oriented boxes, the separating-axis overlap test and point-to-box distance.
//!
//! These are the hot primitives of collision checking and the risk field, so they are plain
//! `f64` arithmetic on `Copy` values; `parry2d` is used where a general shape query pays off
//! (ray casts for sensor occlusion).

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

/// A point or vector in the world frame, metres.
pub type Vec2 = Vector2<f64>;

/// Position of a reference point (the centre of the footprint) and heading in the world frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Pose {
    pub x_m: f64,
    pub y_m: f64,
    pub heading_rad: f64,
}

impl Pose {
    pub fn new(x_m: f64, y_m: f64, heading_rad: f64) -> Self {
        Self { x_m, y_m, heading_rad }
    }
    pub fn position(&self) -> Vec2 {
        Vec2::new(self.x_m, self.y_m)
    }
    /// Unit vector along the heading.
    pub fn forward(&self) -> Vec2 {
        Vec2::new(self.heading_rad.cos(), self.heading_rad.sin())
    }
}

/// A rectangular footprint: length along the heading, width across it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Footprint {
    pub length_m: f64,
    pub width_m: f64,
}

impl Footprint {
    pub const fn new(length_m: f64, width_m: f64) -> Self {
        Self { length_m, width_m }
    }
    /// Radius of the circle that encloses the footprint (broad-phase bound).
    pub fn bounding_radius_m(&self) -> f64 {
        0.5 * self.length_m.hypot(self.width_m)
    }
}

/// An oriented bounding box: centre, unit axis along the length, half extents.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Obb {
    pub centre: Vec2,
    /// Unit vector along the length; the width axis is this rotated by +90°.
    pub axis: Vec2,
    pub half_length_m: f64,
    pub half_width_m: f64,
}

impl Obb {
    pub fn new(pose: Pose, footprint: Footprint) -> Self {
        Self {
            centre: pose.position(),
            axis: pose.forward(),
            half_length_m: 0.5 * footprint.length_m,
            half_width_m: 0.5 * footprint.width_m,
        }
    }

    fn normal(&self) -> Vec2 {
        Vec2::new(-self.axis.y, self.axis.x)
    }

    /// The four corners, counter-clockwise starting at front-left.
    pub fn corners(&self) -> [Vec2; 4] {
        let l = self.axis * self.half_length_m;
        let w = self.normal() * self.half_width_m;
        let c = self.centre;
        [c + l + w, c - l + w, c - l - w, c + l - w]
    }

    /// Half of the box's extent projected on the unit direction `d`.
    fn projected_radius(&self, d: &Vec2) -> f64 {
        self.half_length_m * self.axis.dot(d).abs() + self.half_width_m * self.normal().dot(d).abs()
    }

    /// Separating-axis test: true when the boxes overlap (touching counts).
    pub fn overlaps(&self, other: &Obb) -> bool {
        let t = other.centre - self.centre;
        for axis in [self.axis, self.normal(), other.axis, other.normal()] {
            if t.dot(&axis).abs() > self.projected_radius(&axis) + other.projected_radius(&axis) {
                return false;
            }
        }
        true
    }

    /// Euclidean distance from `p` to the box (0 inside).
    pub fn distance_to_point(&self, p: Vec2) -> f64 {
        self.distance_sq_to_point(p).sqrt()
    }

    /// Squared distance from `p` to the box (0 inside); avoids the square root in hot loops.
    pub fn distance_sq_to_point(&self, p: Vec2) -> f64 {
        let d = p - self.centre;
        let lx = (d.dot(&self.axis).abs() - self.half_length_m).max(0.0);
        let ly = (d.dot(&self.normal()).abs() - self.half_width_m).max(0.0);
        lx * lx + ly * ly
    }

    /// Minimum distance between two boxes (0 when they overlap). Exact for convex polygons:
    /// the closest pair always involves a corner of one box.
    pub fn distance_to(&self, other: &Obb) -> f64 {
        if self.overlaps(other) {
            return 0.0;
        }
        let a = self.corners().iter().map(|c| other.distance_sq_to_point(*c)).fold(f64::INFINITY, f64::min);
        let b = other.corners().iter().map(|c| self.distance_sq_to_point(*c)).fold(f64::INFINITY, f64::min);
        a.min(b).sqrt()
    }
}

/// Wraps an angle into (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let r = a.rem_euclid(t);
    if r > std::f64::consts::PI { r - t } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn car(x: f64, y: f64, h: f64) -> Obb {
        Obb::new(Pose::new(x, y, h), Footprint::new(4.0, 2.0))
    }

    #[test]
    fn overlap_and_separation() {
        assert!(car(0.0, 0.0, 0.0).overlaps(&car(3.9, 0.0, 0.0)));
        assert!(!car(0.0, 0.0, 0.0).overlaps(&car(4.1, 0.0, 0.0)));
        // Rotated 90°: the other car's half-width (1 m) faces us, so contact at x = 3.
        assert!(car(0.0, 0.0, 0.0).overlaps(&car(2.9, 0.0, FRAC_PI_2)));
        assert!(!car(0.0, 0.0, 0.0).overlaps(&car(3.1, 0.0, FRAC_PI_2)));
        // Diagonal boxes whose bounding circles overlap but which are separated.
        assert!(!car(0.0, 0.0, 0.785).overlaps(&car(2.6, -2.6, 0.785)));
    }

    #[test]
    fn distances() {
        let a = car(0.0, 0.0, 0.0);
        assert_eq!(a.distance_to_point(Vec2::new(1.0, 0.5)), 0.0);
        assert!((a.distance_to_point(Vec2::new(5.0, 0.0)) - 3.0).abs() < 1e-12);
        assert!((a.distance_to_point(Vec2::new(5.0, 4.0)) - (9.0f64 + 9.0).sqrt()).abs() < 1e-12);
        assert!((a.distance_to(&car(10.0, 0.0, 0.0)) - 6.0).abs() < 1e-12);
        assert!((a.distance_to(&car(0.0, 5.0, 0.0)) - 3.0).abs() < 1e-12);
    }

    #[test]
    fn wrap() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-12);
    }

    #[test]
    fn wrap_is_half_open() {
        use std::f64::consts::PI;
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(wrap_angle(PI), PI));
        assert!(close(wrap_angle(-PI), PI));
        assert!(close(wrap_angle(3.0 * PI + 0.5), -PI + 0.5));
        assert!(close(wrap_angle(-0.25), -0.25));
    }
}
