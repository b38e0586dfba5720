//! Line-of-sight tests for the sensor: which footprints block a ray from the sensor to a point.
//!
//! Every object's footprint is cached once per frame as a `parry2d` cuboid with its pose and
//! bounding circle. A ray first meets the cheap broad phase (does the blocker's bounding circle
//! touch the ray's segment?) and only survivors go to `parry`'s exact ray–cuboid cast.

use parry2d_f64::math::{Pose as ParryPose, Rot2, Vector as ParryVec};
use parry2d_f64::query::{Ray, RayCast};
use parry2d_f64::shape::Cuboid;

use crate::geometry::{Obb, Vec2};

/// A hit this close to the end of the segment is the target point itself touching the blocker
/// (e.g. two parked cars bumper to bumper), not a blocker in front of it.
const END_TOLERANCE: f64 = 1e-9;

/// One potential occluder, cached for the frame.
#[derive(Debug, Clone, Copy)]
struct Blocker {
    /// Index of the object in the frame's input slice, so a target never blocks itself.
    index: usize,
    centre: Vec2,
    radius_m: f64,
    shape: Cuboid,
    pose: ParryPose,
}

/// The frame's occluders; the buffer is reused across frames (no allocation after warm-up).
#[derive(Debug, Default, Clone)]
pub(crate) struct Blockers {
    items: Vec<Blocker>,
}

/// True when every number describing the box is finite and its size non-negative.
pub(crate) fn obb_is_valid(obb: &Obb) -> bool {
    obb.centre.iter().all(|v| v.is_finite())
        && obb.axis.iter().all(|v| v.is_finite())
        && obb.axis.norm_squared() > 0.0
        && obb.half_length_m.is_finite()
        && obb.half_width_m.is_finite()
        && obb.half_length_m >= 0.0
        && obb.half_width_m >= 0.0
}

impl Blockers {
    /// Clears the cache and fills it with the valid footprints among `obbs` that could cut a ray
    /// from `origin` of length at most `reach_m`. A footprint containing `origin` is left out:
    /// it is the ego itself (or something the sensor sits inside), which sees out, not through.
    pub(crate) fn rebuild<'a>(
        &mut self,
        obbs: impl Iterator<Item = &'a Obb>,
        origin: Vec2,
        reach_m: f64,
    ) {
        self.items.clear();
        for (index, obb) in obbs.enumerate() {
            if !obb_is_valid(obb) || obb.distance_sq_to_point(origin) == 0.0 {
                continue;
            }
            let radius_m = obb.half_length_m.hypot(obb.half_width_m);
            if (obb.centre - origin).norm() - radius_m > reach_m {
                continue;
            }
            let axis = obb.axis.normalize();
            self.items.push(Blocker {
                index,
                centre: obb.centre,
                radius_m,
                shape: Cuboid::new(ParryVec::new(obb.half_length_m, obb.half_width_m)),
                pose: ParryPose::from_parts(
                    ParryVec::new(obb.centre.x, obb.centre.y),
                    Rot2::from_cos_sin_unchecked(axis.x, axis.y),
                ),
            });
        }
    }

    /// Number of cached blockers.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.items.len()
    }

    /// True when a footprint other than object `target` lies on the segment `origin → point`.
    pub(crate) fn is_blocked(&self, origin: Vec2, point: Vec2, target: usize) -> bool {
        let d = point - origin;
        let len_sq = d.norm_squared();
        if len_sq == 0.0 {
            return false;
        }
        // The ray is parametrised on [0, 1] over the segment, so a time of impact < 1 is a hit
        // in front of the point.
        let ray = Ray::new(ParryVec::new(origin.x, origin.y), ParryVec::new(d.x, d.y));
        self.items.iter().any(|b| {
            if b.index == target {
                return false;
            }
            // Broad phase: closest point of the segment to the circle centre.
            let t = ((b.centre - origin).dot(&d) / len_sq).clamp(0.0, 1.0);
            let gap = origin + d * t - b.centre;
            if gap.norm_squared() > b.radius_m * b.radius_m {
                return false;
            }
            b.shape
                .cast_ray(&b.pose, &ray, 1.0 - END_TOLERANCE, true)
                .is_some()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Footprint, Pose};

    fn boxed(x: f64, y: f64, h: f64, l: f64, w: f64) -> Obb {
        Obb::new(Pose::new(x, y, h), Footprint::new(l, w))
    }

    #[test]
    fn exact_cast_after_broad_phase() {
        // A 45°-rotated 4×2 box at (10, 3): its lowest corner is at y = 3 − 3/√2 ≈ 0.879 and
        // its bounding circle (r = √5 ≈ 2.236) reaches down to y ≈ 0.764.
        let obbs = [boxed(10.0, 3.0, std::f64::consts::FRAC_PI_4, 4.0, 2.0)];
        let mut b = Blockers::default();
        b.rebuild(obbs.iter(), Vec2::zeros(), 100.0);
        assert!(!b.is_blocked(Vec2::zeros(), Vec2::new(20.0, 0.0), usize::MAX));
        // A ray at y = 1.5 crosses the box.
        assert!(b.is_blocked(Vec2::new(0.0, 1.5), Vec2::new(20.0, 1.5), usize::MAX));
        // At y = 0.8 the broad phase passes (circle reaches 0.764) but the exact cast misses.
        assert!(!b.is_blocked(Vec2::new(0.0, 0.8), Vec2::new(20.0, 0.8), usize::MAX));
        // The target never blocks itself, and a segment ending before the box is clear.
        assert!(!b.is_blocked(Vec2::new(0.0, 1.5), Vec2::new(20.0, 1.5), 0));
        assert!(!b.is_blocked(Vec2::new(0.0, 1.5), Vec2::new(5.0, 1.5), usize::MAX));
    }

    #[test]
    fn ego_footprint_and_far_or_invalid_boxes_are_not_cached() {
        let mut nan = boxed(5.0, 0.0, 0.0, 4.0, 2.0);
        nan.centre.x = f64::NAN;
        let obbs = [
            boxed(0.0, 0.0, 0.0, 4.0, 2.0),
            boxed(500.0, 0.0, 0.0, 4.0, 2.0),
            nan,
            boxed(20.0, 0.0, 0.0, 4.0, 2.0),
        ];
        let mut b = Blockers::default();
        b.rebuild(obbs.iter(), Vec2::new(1.0, 0.0), 150.0);
        assert_eq!(b.len(), 1);
    }
}
