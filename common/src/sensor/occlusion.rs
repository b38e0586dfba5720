//! Line-of-sight tests for the sensor: which footprints block a ray from the sensor to a point.
//!
//! Every object's footprint is cached once per frame as a `parry2d` cuboid with its pose and
//! bounding circle. Two cheap broad phases run before `parry`'s exact ray–cuboid cast: per target,
//! only blockers whose bounding circle overlaps the target's in bearing (as seen from the sensor)
//! and starts nearer than the target ends are kept; per ray, only those whose circle touches
//! the ray's segment are cast against.

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
    cone: Cone,
    shape: Cuboid,
    pose: ParryPose,
}

/// The bearing interval a circle covers as seen from the sensor origin.
#[derive(Debug, Clone, Copy)]
struct Cone {
    /// Unit vector from the origin to the circle centre.
    dir: Vec2,
    /// Distance from the origin to the circle centre, m.
    dist_m: f64,
    radius_m: f64,
    /// Cosine and sine of the half-angle the circle subtends: sin a = r / d.
    cos_half: f64,
    sin_half: f64,
    /// The origin lies inside the circle: it covers every bearing.
    all_round: bool,
}

impl Cone {
    fn new(origin: Vec2, centre: Vec2, radius_m: f64) -> Self {
        let to = centre - origin;
        let dist_m = to.norm();
        let all_round = radius_m >= dist_m;
        let sin_half = if all_round { 1.0 } else { radius_m / dist_m };
        let dir = if dist_m > 0.0 { to / dist_m } else { Vec2::new(1.0, 0.0) };
        Self { dir, dist_m, radius_m, cos_half: (1.0 - sin_half * sin_half).sqrt(), sin_half, all_round }
    }

    /// True when some ray from the origin into `target`'s circle may cross this circle first:
    /// the bearing intervals overlap and this circle starts before the target's ends.
    fn may_hide(&self, target: &Cone) -> bool {
        if self.dist_m - self.radius_m > target.dist_m + target.radius_m {
            return false;
        }
        if self.all_round || target.all_round {
            return true;
        }
        // Angle between centres ≤ a_self + a_target, both half-angles < π/2, so compare cosines:
        // cos(a + b) = cos a cos b − sin a sin b. The slack keeps the test conservative.
        let cos_sum = self.cos_half * target.cos_half - self.sin_half * target.sin_half;
        self.dir.dot(&target.dir) >= cos_sum - 1e-9
    }
}

/// The frame's occluders; the buffers are reused across frames (no allocation after warm-up).
#[derive(Debug, Default, Clone)]
pub(crate) struct Blockers {
    items: Vec<Blocker>,
    /// Indices into `items` that may hide the current target (see [`Blockers::select`]).
    selected: Vec<usize>,
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
    pub(crate) fn rebuild<'a>(&mut self, obbs: impl Iterator<Item = &'a Obb>, origin: Vec2, reach_m: f64) {
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
                cone: Cone::new(origin, obb.centre, radius_m),
                shape: Cuboid::new(ParryVec::new(obb.half_length_m, obb.half_width_m)),
                pose: ParryPose::from_parts(
                    ParryVec::new(obb.centre.x, obb.centre.y),
                    Rot2::from_cos_sin_unchecked(axis.x, axis.y),
                ),
            });
        }
    }

    /// Selects every blocker but `target`: the reference the bearing filter must agree with.
    #[cfg(test)]
    fn select_all(&mut self, target: usize) {
        self.selected.clear();
        self.selected.extend((0..self.items.len()).filter(|&i| self.items[i].index != target));
    }

    /// Number of cached blockers and of those selected for the current target.
    #[cfg(test)]
    fn counts(&self) -> (usize, usize) {
        (self.items.len(), self.selected.len())
    }

    /// Keeps, for the rays to object `target` (circle `centre`, `radius_m`), only the blockers
    /// that may hide some of it; [`Blockers::is_blocked`] then tests only those.
    pub(crate) fn select(&mut self, origin: Vec2, centre: Vec2, radius_m: f64, target: usize) {
        let target_cone = Cone::new(origin, centre, radius_m);
        self.selected.clear();
        for (i, b) in self.items.iter().enumerate() {
            if b.index != target && b.cone.may_hide(&target_cone) {
                self.selected.push(i);
            }
        }
    }

    /// True when a selected footprint lies on the segment `origin → point`.
    pub(crate) fn is_blocked(&self, origin: Vec2, point: Vec2) -> bool {
        let d = point - origin;
        let len_sq = d.norm_squared();
        if len_sq == 0.0 {
            return false;
        }
        // The ray is parametrised on [0, 1] over the segment, so a time of impact < 1 is a hit
        // in front of the point.
        let ray = Ray::new(ParryVec::new(origin.x, origin.y), ParryVec::new(d.x, d.y));
        self.selected.iter().any(|&i| {
            let b = &self.items[i];
            // Closest point of the segment to the circle centre.
            let t = ((b.centre - origin).dot(&d) / len_sq).clamp(0.0, 1.0);
            let gap = origin + d * t - b.centre;
            if gap.norm_squared() > b.radius_m * b.radius_m {
                return false;
            }
            b.shape.cast_ray(&b.pose, &ray, 1.0 - END_TOLERANCE, true).is_some()
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

    /// Line of sight from `origin` to `point`, treating `point` as object `target`.
    fn blocked(obbs: &[Obb], origin: Vec2, point: Vec2, target: usize) -> bool {
        let mut b = Blockers::default();
        b.rebuild(obbs.iter(), origin, 100.0);
        b.select(origin, point, 0.0, target);
        b.is_blocked(origin, point)
    }

    #[test]
    fn exact_cast_after_broad_phase() {
        // A 45°-rotated 4×2 box at (10, 3): its lowest corner is at y = 3 − 3/√2 ≈ 0.879 and
        // its bounding circle (r = √5 ≈ 2.236) reaches down to y ≈ 0.764.
        let obbs = [boxed(10.0, 3.0, std::f64::consts::FRAC_PI_4, 4.0, 2.0)];
        let (none, ray_at) = (usize::MAX, |y: f64| (Vec2::new(0.0, y), Vec2::new(20.0, y)));
        let (o, p) = ray_at(0.0);
        assert!(!blocked(&obbs, o, p, none));
        let (o, p) = ray_at(1.5);
        assert!(blocked(&obbs, o, p, none));
        // At y = 0.8 both broad phases pass (circle reaches 0.764) but the exact cast misses.
        let (o, p) = ray_at(0.8);
        assert!(!blocked(&obbs, o, p, none));
        // The target never blocks itself, and a segment ending before the box is clear.
        let (o, p) = ray_at(1.5);
        assert!(!blocked(&obbs, o, p, 0));
        assert!(!blocked(&obbs, o, Vec2::new(5.0, 1.5), none));
    }

    #[test]
    fn selection_keeps_only_boxes_in_front_and_in_bearing() {
        let obbs = [
            boxed(20.0, 1.0, 0.0, 4.0, 2.0),  // in front, same bearing: kept
            boxed(20.0, 15.0, 0.0, 4.0, 2.0), // in front, 37° off: dropped
            boxed(60.0, 0.0, 0.0, 4.0, 2.0),  // same bearing but behind the target: dropped
            boxed(40.0, 0.0, 0.0, 4.0, 2.0),  // the target itself: dropped
            boxed(38.0, 4.0, 0.0, 4.0, 2.0),  // beside the target, bearings overlap: kept
            boxed(0.5, 0.0, 0.0, 4.0, 2.0),   // contains the origin: never cached
        ];
        let mut b = Blockers::default();
        b.rebuild(obbs.iter(), Vec2::zeros(), 150.0);
        b.select(Vec2::zeros(), obbs[3].centre, 5f64.sqrt(), 3);
        assert_eq!(b.counts(), (5, 2));
    }

    #[test]
    fn bearing_filter_never_changes_a_verdict() {
        let mut rng = crate::rng::Rng::new(17);
        let (mut blocked_rays, mut rays) = (0, 0);
        for _ in 0..50 {
            let obbs: Vec<Obb> = (0..40)
                .map(|_| {
                    let (l, w) = (rng.uniform(0.5, 12.0), rng.uniform(0.5, 2.5));
                    let (x, y) = (rng.uniform(-60.0, 60.0), rng.uniform(-60.0, 60.0));
                    boxed(x, y, rng.uniform(-3.2, 3.2), l, w)
                })
                .collect();
            let origin = Vec2::new(rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0));
            let mut b = Blockers::default();
            b.rebuild(obbs.iter(), origin, 200.0);
            for (target, obb) in obbs.iter().enumerate() {
                let c = obb.corners();
                let radius_m = obb.half_length_m.hypot(obb.half_width_m);
                for point in [c[0], c[1], c[2], c[3], obb.centre] {
                    b.select(origin, obb.centre, radius_m, target);
                    let filtered = b.is_blocked(origin, point);
                    b.select_all(target);
                    assert_eq!(filtered, b.is_blocked(origin, point), "target {target} point {point:?}");
                    blocked_rays += usize::from(filtered);
                    rays += 1;
                }
            }
        }
        // The scenes are dense enough that both verdicts occur often.
        assert!(blocked_rays > rays / 10 && blocked_rays < rays * 9 / 10, "{blocked_rays} of {rays}");
    }

    #[test]
    fn ego_footprint_and_far_or_invalid_boxes_are_not_cached() {
        let mut nan = boxed(5.0, 0.0, 0.0, 4.0, 2.0);
        nan.centre.x = f64::NAN;
        let obbs =
            [boxed(0.0, 0.0, 0.0, 4.0, 2.0), boxed(500.0, 0.0, 0.0, 4.0, 2.0), nan, boxed(20.0, 0.0, 0.0, 4.0, 2.0)];
        let mut b = Blockers::default();
        b.rebuild(obbs.iter(), Vec2::new(1.0, 0.0), 150.0);
        assert_eq!(b.counts().0, 1);
    }
}
