//! Traffic–traffic collision detection.
//!
//! Broad phase: two vehicles can only touch if they share a lane list (a footprint that
//! reaches over a lane line is listed in both lanes, see [`super::lane_index`]) and their arc
//! lengths differ by less than the sum of their bounding radii, so each vehicle is compared
//! with the few list neighbours ahead of it inside that window: O(n) for any traffic size.
//! Narrow phase: the separating-axis test [`crate::geometry::Obb::overlaps`].

use super::Traffic;

impl Traffic {
    /// Fills `self.collisions` with the sorted, de-duplicated pairs in contact.
    pub(crate) fn detect_collisions(&mut self) {
        self.collisions.clear();
        for (lane, list) in self.index.lists.iter().enumerate() {
            let info = &self.lanes[lane];
            let n = list.len();
            for k in 0..n {
                let a = list[k];
                let ia = a.id as usize;
                let reach = self.radius_m[ia] + self.max_radius_m;
                // On a closed lane the window may wrap past the end of the list.
                let limit = if info.closed { n - 1 } else { n - 1 - k };
                for step in 1..=limit {
                    let m = k + step;
                    let (b, off) = if m < n { (list[m], 0.0) } else { (list[m - n], info.length_m) };
                    if b.s_m + off - a.s_m > reach {
                        break;
                    }
                    let ib = b.id as usize;
                    if ib != ia && self.obb(ia).overlaps(&self.obb(ib)) {
                        self.collisions.push((a.id.min(b.id), a.id.max(b.id)));
                    }
                }
            }
        }
        if self.collisions.len() > 1 {
            self.collisions.sort_unstable();
            self.collisions.dedup();
        }
    }
}
