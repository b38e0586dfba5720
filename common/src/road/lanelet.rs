//! The lanelet network: lanelets from their left/right bounds, with centrelines, widths,
//! adjacency and predecessor/successor links, plus the point and polygon queries the measures
//! use.
//!
//! A lanelet's polygon is its right bound followed by its reversed left bound, as commonroad-io
//! builds it; its centreline is the mean of the two bounds vertex by vertex (commonroad-io
//! `Lanelet.center_vertices`), which needs bounds with the same number of points (checked on
//! import).

use crate::geometry::Vec2;
use std::collections::HashMap;

/// The neighbour beside a lanelet and whether it runs the same way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Adjacency {
    pub id: u64,
    pub same_direction: bool,
}

/// One lanelet.
#[derive(Debug, Clone, PartialEq)]
pub struct Lanelet {
    pub id: u64,
    pub left_bound: Vec<Vec2>,
    pub right_bound: Vec<Vec2>,
    /// Mean of the bounds, vertex by vertex.
    pub centreline: Vec<Vec2>,
    /// Distance between the bounds at each vertex, m.
    pub widths_m: Vec<f64>,
    pub predecessors: Vec<u64>,
    pub successors: Vec<u64>,
    pub adjacent_left: Option<Adjacency>,
    pub adjacent_right: Option<Adjacency>,
    /// `<laneletType>` values as written (`driveWay`, `intersection`, ...).
    pub lanelet_types: Vec<String>,
    /// Axis-aligned bounds of the polygon: min and max corner.
    pub bbox_min: Vec2,
    pub bbox_max: Vec2,
    /// Right bound then reversed left bound (closed implicitly).
    pub polygon: Vec<Vec2>,
    /// The polygon's edges in runs with their bounding boxes (see [`EdgeRun`]).
    edge_runs: Vec<EdgeRun>,
}

/// Edges per [`EdgeRun`].
const EDGE_RUN: usize = 8;
/// Slack of the run bounding boxes, m: far above the 1e-9 m boundary tolerance and the
/// rounding of the tests, so a run whose box misses a query by more contributes nothing.
const RUN_SLACK_M: f64 = 1e-6;

/// A run of consecutive polygon edges `first..end` (edge i joins vertex i to vertex i + 1,
/// wrapping) and the bounding box of their end points. The point and polygon queries skip the
/// runs whose box shows they cannot change the answer; the edges they do test are tested
/// exactly as before, so results are unchanged (profiled on USA_US101-5_1: the lanelet tests
/// of every state against every long highway lanelet were 57 % of `risktwin criticality`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct EdgeRun {
    lo: Vec2,
    hi: Vec2,
    first: usize,
    end: usize,
}

impl EdgeRun {
    fn of(polygon: &[Vec2]) -> Vec<Self> {
        let n = polygon.len();
        (0..n)
            .step_by(EDGE_RUN)
            .map(|first| {
                let end = (first + EDGE_RUN).min(n);
                let (mut lo, mut hi) = (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY));
                for k in first..=end {
                    let p = polygon[k % n];
                    lo = lo.inf(&p);
                    hi = hi.sup(&p);
                }
                Self { lo, hi, first, end }
            })
            .collect()
    }

    /// True when the box, grown by [`RUN_SLACK_M`], meets the box `lo`..`hi`.
    fn near(&self, lo: Vec2, hi: Vec2) -> bool {
        self.lo.x - RUN_SLACK_M <= hi.x
            && self.lo.y - RUN_SLACK_M <= hi.y
            && self.hi.x + RUN_SLACK_M >= lo.x
            && self.hi.y + RUN_SLACK_M >= lo.y
    }
}

impl Lanelet {
    /// Builds a lanelet from its bounds (same number of points, at least two each).
    pub fn new(id: u64, left_bound: Vec<Vec2>, right_bound: Vec<Vec2>) -> Self {
        let centreline = left_bound.iter().zip(&right_bound).map(|(l, r)| 0.5 * (l + r)).collect();
        let widths_m = left_bound.iter().zip(&right_bound).map(|(l, r)| (l - r).norm()).collect();
        let polygon: Vec<Vec2> = right_bound.iter().chain(left_bound.iter().rev()).copied().collect();
        let edge_runs = EdgeRun::of(&polygon);
        let (mut lo, mut hi) = (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY));
        for p in &polygon {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        Self {
            id,
            left_bound,
            right_bound,
            centreline,
            widths_m,
            predecessors: Vec::new(),
            successors: Vec::new(),
            adjacent_left: None,
            adjacent_right: None,
            lanelet_types: Vec::new(),
            bbox_min: lo,
            bbox_max: hi,
            polygon,
            edge_runs,
        }
    }

    /// True when `p` is inside the polygon or on its boundary (within 1e-9 m).
    pub fn contains(&self, p: Vec2) -> bool {
        if p.x < self.bbox_min.x - 1e-9
            || p.y < self.bbox_min.y - 1e-9
            || p.x > self.bbox_max.x + 1e-9
            || p.y > self.bbox_max.y + 1e-9
        {
            return false;
        }
        self.covers(p) || self.edges_near(p, p).any(|(a, b)| segment_distance_sq(p, a, b) < 1e-18)
    }

    /// True when the convex polygon `convex` (counter-clockwise or clockwise) meets this
    /// lanelet's polygon; touching counts (shapely `intersects`).
    pub fn intersects_convex(&self, convex: &[Vec2]) -> bool {
        let (mut lo, mut hi) = (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY));
        for p in convex {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        if hi.x < self.bbox_min.x || hi.y < self.bbox_min.y || lo.x > self.bbox_max.x || lo.y > self.bbox_max.y {
            return false;
        }
        if convex.iter().any(|&p| self.covers(p)) {
            return true;
        }
        if self.polygon.first().is_some_and(|&p| point_in_polygon(convex, p)) {
            return true;
        }
        let n = convex.len();
        self.edges_near(lo, hi).any(|(a, b)| (0..n).any(|i| segments_intersect(a, b, convex[i], convex[(i + 1) % n])))
    }

    /// The polygon's edges whose box is within [`RUN_SLACK_M`] of the box `lo`..`hi` (run boxes
    /// first, then each edge's).
    fn edges_near(&self, lo: Vec2, hi: Vec2) -> impl Iterator<Item = (Vec2, Vec2)> + '_ {
        let n = self.polygon.len();
        self.edge_runs
            .iter()
            .filter(move |r| r.near(lo, hi))
            .flat_map(move |r| (r.first..r.end).map(move |i| (self.polygon[i], self.polygon[(i + 1) % n])))
            .filter(move |&(a, b)| EdgeRun { lo: a.inf(&b), hi: a.sup(&b), first: 0, end: 0 }.near(lo, hi))
    }

    /// [`point_in_polygon`] on this lanelet's polygon, skipping the runs that no ray from `p`
    /// along +x can cross: all their vertices above `p`, none above it, or all left of it.
    fn covers(&self, p: Vec2) -> bool {
        let poly = &self.polygon;
        let n = poly.len();
        let mut inside = false;
        for r in &self.edge_runs {
            if r.lo.y > p.y || r.hi.y <= p.y || p.x > r.hi.x + RUN_SLACK_M * (1.0 + r.hi.x.abs()) {
                continue;
            }
            for i in r.first..r.end {
                // The same edge, with the same end as `a`, as `point_in_polygon`'s (i + 1, i).
                let (a, b) = (poly[(i + 1) % n], poly[i]);
                if crosses(a, b, p) {
                    inside = !inside;
                }
            }
        }
        inside
    }
}

/// The ray from `p` along +x crosses the edge from `b` to `a` (even-odd rule).
fn crosses(a: Vec2, b: Vec2, p: Vec2) -> bool {
    (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x
}

/// Even-odd ray casting.
fn point_in_polygon(poly: &[Vec2], p: Vec2) -> bool {
    let n = poly.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        if crosses(poly[i], poly[j], p) {
            inside = !inside;
        }
        j = i;
    }
    inside
}

fn cross(a: Vec2, b: Vec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Closed segments [a, b] and [c, d] share a point.
fn segments_intersect(a: Vec2, b: Vec2, c: Vec2, d: Vec2) -> bool {
    let (d1, d2) = (cross(b - a, c - a), cross(b - a, d - a));
    let (d3, d4) = (cross(d - c, a - c), cross(d - c, b - c));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0)) {
        return true;
    }
    let on = |p: Vec2, q: Vec2, r: Vec2| segment_distance_sq(r, p, q) < 1e-18;
    on(a, b, c) || on(a, b, d) || on(c, d, a) || on(c, d, b)
}

/// Squared distance from `p` to the segment [a, b].
pub fn segment_distance_sq(p: Vec2, a: Vec2, b: Vec2) -> f64 {
    let ab = b - a;
    let len_sq = ab.norm_squared();
    let t = if len_sq > 0.0 { ((p - a).dot(&ab) / len_sq).clamp(0.0, 1.0) } else { 0.0 };
    (a + ab * t - p).norm_squared()
}

/// All lanelets of a scenario, in file order, with an id index.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LaneletNetwork {
    pub lanelets: Vec<Lanelet>,
    index: HashMap<u64, usize>,
}

impl LaneletNetwork {
    /// Indexes `lanelets` by id (ids unique, checked on import).
    pub fn new(lanelets: Vec<Lanelet>) -> Self {
        let index = lanelets.iter().enumerate().map(|(i, l)| (l.id, i)).collect();
        Self { lanelets, index }
    }

    /// The lanelet with this id.
    pub fn get(&self, id: u64) -> Option<&Lanelet> {
        self.index.get(&id).map(|&i| &self.lanelets[i])
    }

    /// Position of the lanelet with this id in `lanelets`.
    pub fn index_of(&self, id: u64) -> Option<usize> {
        self.index.get(&id).copied()
    }

    /// Indices of the lanelets whose polygon contains `p`, in file order.
    pub fn containing(&self, p: Vec2) -> impl Iterator<Item = usize> + '_ {
        self.lanelets.iter().enumerate().filter(move |(_, l)| l.contains(p)).map(|(i, _)| i)
    }

    /// Number of lanelets.
    pub fn len(&self) -> usize {
        self.lanelets.len()
    }

    /// True when there is no lanelet.
    pub fn is_empty(&self) -> bool {
        self.lanelets.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight() -> Lanelet {
        let left = vec![Vec2::new(0.0, 3.0), Vec2::new(10.0, 3.0)];
        let right = vec![Vec2::new(0.0, 0.0), Vec2::new(10.0, 0.0)];
        Lanelet::new(1, left, right)
    }

    #[test]
    fn centreline_width_and_containment() {
        let l = straight();
        assert_eq!(l.centreline, vec![Vec2::new(0.0, 1.5), Vec2::new(10.0, 1.5)]);
        assert_eq!(l.widths_m, vec![3.0, 3.0]);
        assert!(l.contains(Vec2::new(5.0, 1.0)));
        assert!(l.contains(Vec2::new(5.0, 3.0)), "the boundary counts");
        assert!(!l.contains(Vec2::new(5.0, 3.1)));
        assert!(!l.contains(Vec2::new(-0.1, 1.0)));
    }

    #[test]
    fn convex_intersection_counts_touching() {
        let l = straight();
        let square = |x: f64, y: f64| {
            vec![Vec2::new(x, y), Vec2::new(x + 1.0, y), Vec2::new(x + 1.0, y + 1.0), Vec2::new(x, y + 1.0)]
        };
        assert!(l.intersects_convex(&square(4.0, 2.5)), "straddles the left bound");
        assert!(l.intersects_convex(&square(4.0, 3.0)), "touches the left bound");
        assert!(!l.intersects_convex(&square(4.0, 3.01)));
        // A box around the whole lanelet: no vertex inside it, but it contains the lanelet.
        let big = vec![Vec2::new(-1.0, -1.0), Vec2::new(11.0, -1.0), Vec2::new(11.0, 4.0), Vec2::new(-1.0, 4.0)];
        assert!(l.intersects_convex(&big));
    }
}
