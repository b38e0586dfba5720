//! Traffic–traffic collision detection.
//!
//! Broad phase: two vehicles can only touch if they share a lane list (a footprint that
//! reaches over a lane line is listed in both lanes, see [`super::lane_index`]) and their arc
//! lengths differ by less than the sum of their bounding radii, so each vehicle is compared
//! with the few list neighbours ahead of it inside that window: O(n) for any traffic size.
//! Lanes that cross or touch other lanes (junctions, opposing traffic; see
//! [`super::crossing`]) get a second broad phase: their vehicles sorted by x and swept with the
//! largest reach, O(m log m) in the number m of vehicles on such lanes (none on a ring or a
//! one-way road).
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
        self.sweep_crossing_lanes();
        if self.collisions.len() > 1 {
            self.collisions.sort_unstable();
            self.collisions.dedup();
        }
    }

    /// Sweep over the vehicles on crossing lanes, sorted by x.
    fn sweep_crossing_lanes(&mut self) {
        if !self.crossing.iter().any(|&c| c) {
            return;
        }
        let mut sweep = std::mem::take(&mut self.crossing_scratch);
        sweep.clear();
        for i in 0..self.len() {
            if self.cur.active[i] && self.crossing[self.cur.lane[i] as usize] {
                sweep.push((self.cur.x_m[i], i as u32));
            }
        }
        sweep.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for k in 0..sweep.len() {
            let (xa, a) = sweep[k];
            let ia = a as usize;
            let reach = self.radius_m[ia] + self.max_radius_m;
            for &(xb, b) in sweep[k + 1..].iter().take_while(|s| s.0 - xa <= reach) {
                let ib = b as usize;
                let (dx, dy) = (xb - xa, self.cur.y_m[ib] - self.cur.y_m[ia]);
                let r = self.radius_m[ia] + self.radius_m[ib];
                if dx * dx + dy * dy <= r * r && self.obb(ia).overlaps(&self.obb(ib)) {
                    self.collisions.push((a.min(b), a.max(b)));
                }
            }
        }
        self.crossing_scratch = sweep;
    }
}
