//! The ego's reference path: one curvilinear frame per scenario, along which HW and THW are
//! measured and whose tangent gives "along the lane" for speeds and accelerations.
//!
//! Built as CommonRoad-CriMe 0.4.5 builds it (docs/criticality.md, "How CriMe 0.4.5 computes"
//! §2, `utility/general.generate_reference_path`): the centreline of the ego's initial lanelet, with
//! up to two predecessors before and two successors after (first listed link each time),
//! smoothed by one pass of Chaikin corner cutting (Chaikin 1974). Where we differ: the
//! projection is the plain orthogonal one onto that polyline (CriMe uses commonroad-clcs'
//! pseudo-projection on a 2 m resampling; they agree to ≲0.01 m on straight roads), and the
//! projection domain is approximated by its straight-road shape: ±20 m laterally, and ends
//! 0.03 m before the first and 0.02 m after the last vertex (commonroad-clcs' default
//! extension).

use risktwin_common::geometry::Vec2;
use risktwin_common::road::lanelet::LaneletNetwork;

/// Lateral half-width of the projection domain, m (commonroad-clcs default).
const DOMAIN_HALF_WIDTH_M: f64 = 20.0;
/// How far before the first / after the last vertex a point still projects, m.
const EXTENSION_START_M: f64 = 0.03;
const EXTENSION_END_M: f64 = 0.02;

/// A point projected on the path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// Arc length from the first vertex, m.
    pub s_m: f64,
    /// Signed lateral offset, m (+ left).
    pub lateral_m: f64,
    /// Direction of the path at the foot point, rad.
    pub heading_rad: f64,
}

/// A polyline with cumulative arc length.
#[derive(Debug, Clone)]
pub struct ReferencePath {
    points: Vec<Vec2>,
    cum_s_m: Vec<f64>,
}

impl ReferencePath {
    /// The path of CriMe §2 around lanelet `start_id`; `None` when the lanelet is unknown.
    pub fn around_lanelet(network: &LaneletNetwork, start_id: u64) -> Option<Self> {
        let start = network.get(start_id)?;
        let mut before = Vec::new();
        let mut cur = start;
        for _ in 0..2 {
            match cur.predecessors.first().and_then(|&id| network.get(id)) {
                Some(p) => {
                    before.push(p);
                    cur = p;
                }
                None => break,
            }
        }
        let mut raw: Vec<Vec2> = Vec::new();
        for l in before.iter().rev() {
            raw.extend(&l.centreline);
        }
        raw.extend(&start.centreline);
        let mut cur = start;
        for _ in 0..2 {
            match cur.successors.first().and_then(|&id| network.get(id)) {
                Some(s) => {
                    raw.extend(&s.centreline);
                    cur = s;
                }
                None => break,
            }
        }
        raw.dedup_by(|a, b| (*a - *b).norm() < 1e-9);
        Self::from_points(chaikin(&raw))
    }

    /// A path through `points` (at least two distinct ones).
    pub fn from_points(points: Vec<Vec2>) -> Option<Self> {
        if points.len() < 2 {
            return None;
        }
        let mut cum_s_m = Vec::with_capacity(points.len());
        let mut s = 0.0;
        cum_s_m.push(0.0);
        for w in points.windows(2) {
            s += (w[1] - w[0]).norm();
            cum_s_m.push(s);
        }
        (s > 0.0).then_some(Self { points, cum_s_m })
    }

    /// Total length, m.
    pub fn length_m(&self) -> f64 {
        self.cum_s_m.last().copied().unwrap_or(0.0)
    }

    /// Distance from `p` to the polyline and the polyline's direction at the nearest point
    /// (no domain limit).
    pub fn nearest(&self, p: Vec2) -> (f64, f64) {
        let mut best = (f64::INFINITY, 0.0);
        for w in self.points.windows(2) {
            let ab = w[1] - w[0];
            let d = risktwin_common::road::lanelet::segment_distance_sq(p, w[0], w[1]).sqrt();
            if d < best.0 && ab.norm_squared() > 0.0 {
                best = (d, ab.y.atan2(ab.x));
            }
        }
        best
    }

    /// Orthogonal projection of `p`, or `None` outside the projection domain.
    pub fn project(&self, p: Vec2) -> Option<PathPoint> {
        let n = self.points.len();
        let mut best: Option<(f64, usize, f64)> = None; // (distance², segment, unclamped t)
        for i in 0..n - 1 {
            let (a, b) = (self.points[i], self.points[i + 1]);
            let ab = b - a;
            let len_sq = ab.norm_squared();
            if len_sq == 0.0 {
                continue;
            }
            let t = (p - a).dot(&ab) / len_sq;
            let d_sq = (a + ab * t.clamp(0.0, 1.0) - p).norm_squared();
            if best.is_none_or(|(bd, _, _)| d_sq < bd) {
                best = Some((d_sq, i, t));
            }
        }
        let (_, i, t) = best?;
        let (a, b) = (self.points[i], self.points[i + 1]);
        let seg_len = self.cum_s_m[i + 1] - self.cum_s_m[i];
        let along = t * seg_len;
        // Before the start or past the end of the extended path: outside the domain.
        if (i == 0 && along < -EXTENSION_START_M) || (i == n - 2 && along > seg_len + EXTENSION_END_M) {
            return None;
        }
        let t = if (i == 0 && t < 0.0) || (i == n - 2 && t > 1.0) { t } else { t.clamp(0.0, 1.0) };
        let dir = (b - a) / seg_len;
        let lateral_m = dir.x * (p.y - a.y) - dir.y * (p.x - a.x);
        if lateral_m.abs() > DOMAIN_HALF_WIDTH_M {
            return None;
        }
        Some(PathPoint { s_m: self.cum_s_m[i] + t * seg_len, lateral_m, heading_rad: dir.y.atan2(dir.x) })
    }
}

/// One pass of Chaikin corner cutting that keeps the end points.
fn chaikin(points: &[Vec2]) -> Vec<Vec2> {
    if points.len() < 3 {
        return points.to_vec();
    }
    let mut out = Vec::with_capacity(2 * points.len());
    out.push(points[0]);
    for w in points.windows(2) {
        out.push(0.75 * w[0] + 0.25 * w[1]);
        out.push(0.25 * w[0] + 0.75 * w[1]);
    }
    out.push(points[points.len() - 1]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_path_projection_and_domain() {
        let path = ReferencePath::from_points(vec![Vec2::new(0.0, 0.0), Vec2::new(100.0, 0.0)]).unwrap();
        let p = path.project(Vec2::new(30.0, 2.0)).unwrap();
        assert!((p.s_m - 30.0).abs() < 1e-12 && (p.lateral_m - 2.0).abs() < 1e-12 && p.heading_rad == 0.0);
        assert!(path.project(Vec2::new(30.0, -20.5)).is_none(), "beyond the ±20 m band");
        assert!(path.project(Vec2::new(-0.5, 0.0)).is_none(), "before the start");
        assert!(path.project(Vec2::new(100.5, 0.0)).is_none(), "past the end");
        assert!((path.project(Vec2::new(-0.02, 0.0)).unwrap().s_m + 0.02).abs() < 1e-12, "inside the extension");
    }

    #[test]
    fn chaikin_keeps_ends_and_cuts_corners() {
        let c = chaikin(&[Vec2::new(0.0, 0.0), Vec2::new(4.0, 0.0), Vec2::new(4.0, 4.0)]);
        assert_eq!(c.first(), Some(&Vec2::new(0.0, 0.0)));
        assert_eq!(c.last(), Some(&Vec2::new(4.0, 4.0)));
        assert!(c.contains(&Vec2::new(3.0, 0.0)) && c.contains(&Vec2::new(4.0, 1.0)));
    }
}
