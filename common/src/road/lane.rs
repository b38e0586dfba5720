//! A lane: a centreline polyline with a width, and the Frenet frame along it.

use crate::geometry::{Pose, Vec2, wrap_angle};
use serde::{Deserialize, Serialize};

/// Index of a lane in its [`super::Road`].
pub type LaneId = usize;

/// Coordinates of a point relative to a lane centreline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frenet {
    /// Arc length along the centreline (may be < 0 or > length beyond the ends).
    pub s_m: f64,
    /// Signed lateral offset, positive to the left of the driving direction.
    pub e_y_m: f64,
    /// Heading of the centreline at `s_m`.
    pub lane_heading_rad: f64,
}

/// One lane of a road. Neighbours are lanes of the same driving direction only.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Lane {
    pub centre: Vec<Vec2>,
    /// Cumulative arc length at each centreline vertex (`cum_s[0] == 0`).
    pub cum_s: Vec<f64>,
    pub width_m: f64,
    pub left: Option<LaneId>,
    pub right: Option<LaneId>,
    pub speed_limit_mps: f64,
}

impl Lane {
    /// A lane along `centre` (at least two distinct vertices, checked by the road builders).
    pub fn new(centre: Vec<Vec2>, width_m: f64, speed_limit_mps: f64) -> Self {
        let mut cum_s = Vec::with_capacity(centre.len());
        let mut s = 0.0;
        for (i, p) in centre.iter().enumerate() {
            if i > 0 {
                s += (p - centre[i - 1]).norm();
            }
            cum_s.push(s);
        }
        Self { centre, cum_s, width_m, left: None, right: None, speed_limit_mps }
    }

    pub fn length_m(&self) -> f64 {
        *self.cum_s.last().unwrap_or(&0.0)
    }

    fn segment_count(&self) -> usize {
        self.centre.len().saturating_sub(1)
    }

    /// Projects `p` on the centreline: the nearest segment wins; before the first and after the
    /// last vertex the end segments are extended, so `s_m` can leave [0, length].
    pub fn project(&self, p: Vec2) -> Frenet {
        let (s_m, e_y_m, i) = self.project_offsets(p);
        let ab = self.centre[i + 1] - self.centre[i];
        let dir = ab / ab.norm();
        Frenet { s_m, e_y_m, lane_heading_rad: dir.y.atan2(dir.x) }
    }

    /// [`Lane::project`] without the heading: `(s_m, e_y_m, segment)`. The risk field's static
    /// terms project every cell on every lane and need no heading, whose `atan2` cost as much as
    /// the projection itself.
    pub fn project_offsets(&self, p: Vec2) -> (f64, f64, usize) {
        let n = self.segment_count();
        let mut best = (f64::INFINITY, 0usize, 0.0f64);
        for i in 0..n {
            let a = self.centre[i];
            let ab = self.centre[i + 1] - a;
            let len_sq = ab.norm_squared();
            let mut t = (p - a).dot(&ab) / len_sq;
            let lo = if i == 0 { f64::NEG_INFINITY } else { 0.0 };
            let hi = if i + 1 == n { f64::INFINITY } else { 1.0 };
            t = t.clamp(lo, hi);
            let d_sq = (a + ab * t - p).norm_squared();
            if d_sq < best.0 {
                best = (d_sq, i, t);
            }
        }
        let (_, i, t) = best;
        let a = self.centre[i];
        let ab = self.centre[i + 1] - a;
        let len = ab.norm();
        let dir = ab / len;
        let rel = p - a;
        (self.cum_s[i] + t * len, dir.x * rel.y - dir.y * rel.x, i)
    }

    fn segment_at(&self, s_m: f64) -> usize {
        let n = self.segment_count();
        // Index of the last vertex with cum_s <= s, clamped to a valid segment.
        self.cum_s.partition_point(|&c| c <= s_m).saturating_sub(1).min(n - 1)
    }

    /// World pose of the Frenet point (s, e_y), heading along the lane.
    pub fn pose_at(&self, s_m: f64, e_y_m: f64) -> Pose {
        let mut i = self.segment_at(s_m);
        // A builder may leave a zero-length last segment (a bend with no exit): at the lane's
        // end, take the direction of the last segment that has one instead of 0/0.
        while i > 0 && self.cum_s[i + 1] <= self.cum_s[i] {
            i -= 1;
        }
        let a = self.centre[i];
        let ab = self.centre[i + 1] - a;
        let len = ab.norm();
        let dir = ab / len;
        let normal = Vec2::new(-dir.y, dir.x);
        let p = a + dir * (s_m - self.cum_s[i]) + normal * e_y_m;
        Pose::new(p.x, p.y, dir.y.atan2(dir.x))
    }

    /// Centreline heading at `s_m`.
    pub fn heading_at(&self, s_m: f64) -> f64 {
        self.pose_at(s_m, 0.0).heading_rad
    }

    /// Signed curvature at `s_m` (1/m, positive turning left), from the heading change across
    /// the neighbouring segments.
    pub fn curvature_at(&self, s_m: f64) -> f64 {
        let i = self.segment_at(s_m);
        if i == 0 || self.segment_count() < 2 {
            return 0.0;
        }
        let h0 = self.heading_at(self.cum_s[i] - 1e-9);
        let h1 = self.heading_at(self.cum_s[i] + 1e-9);
        let ds = 0.5 * (self.cum_s[(i + 1).min(self.cum_s.len() - 1)] - self.cum_s[i - 1]);
        if ds > 0.0 { wrap_angle(h1 - h0) / ds } else { 0.0 }
    }

    /// The sharpest signed curvature within `preview_m` ahead of `s_m`, sampled every 5 m: the
    /// bend a driver must slow down for (the reference driver's preview, and the policies').
    pub fn sharpest_curvature_ahead(&self, s_m: f64, preview_m: f64) -> f64 {
        let mut sharpest = 0.0f64;
        let mut d = 0.0;
        while d <= preview_m {
            let k = self.curvature_at(s_m + d);
            if k.abs() > sharpest.abs() {
                sharpest = k;
            }
            d += 5.0;
        }
        sharpest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_round_trip_on_a_bend() {
        let lane = Lane::new(vec![Vec2::new(0.0, 0.0), Vec2::new(10.0, 0.0), Vec2::new(10.0, 10.0)], 3.5, 20.0);
        assert_eq!(lane.length_m(), 20.0);
        let f = lane.project(Vec2::new(5.0, 1.0));
        assert!((f.s_m - 5.0).abs() < 1e-12 && (f.e_y_m - 1.0).abs() < 1e-12);
        let f = lane.project(Vec2::new(11.0, 5.0));
        assert!((f.s_m - 15.0).abs() < 1e-12 && (f.e_y_m + 1.0).abs() < 1e-12);
        let p = lane.pose_at(15.0, -1.0);
        assert!((p.x_m - 11.0).abs() < 1e-12 && (p.y_m - 5.0).abs() < 1e-12);
        // Beyond the start the first segment extends.
        assert!((lane.project(Vec2::new(-3.0, 0.0)).s_m + 3.0).abs() < 1e-12);
    }
}
