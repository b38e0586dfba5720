//! Ego contact checks: collision with any object's footprint, and leaving the road.

use crate::geometry::Obb;
use crate::road::Road;
use crate::sensor::SceneObject;

/// Contacts of the ego after a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Contacts {
    pub collision: bool,
    pub offroad: bool,
    /// Smallest footprint-to-footprint distance to any object, m (∞ when alone).
    pub min_distance_m: f64,
}

impl Contacts {
    /// Broad phase by bounding circles, narrow phase by the separating-axis test; the distance
    /// is computed exactly only for objects within the current best distance.
    pub fn detect(ego: &Obb, objects: &[SceneObject], road: &Road) -> Contacts {
        let ego_r = ego.half_length_m.hypot(ego.half_width_m);
        let mut collision = false;
        let mut min_distance_m = f64::INFINITY;
        for o in objects {
            let r = o.obb.half_length_m.hypot(o.obb.half_width_m);
            let centre_gap = (o.obb.centre - ego.centre).norm() - ego_r - r;
            if centre_gap > min_distance_m {
                continue;
            }
            let d = ego.distance_to(&o.obb);
            min_distance_m = min_distance_m.min(d);
            collision |= d == 0.0;
        }
        Contacts { collision, offroad: !road.contains_footprint(ego), min_distance_m }
    }
}
