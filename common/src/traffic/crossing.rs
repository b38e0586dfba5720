//! Which lanes cross or touch lanes other than their neighbours (junctions, opposing lanes),
//! so the collision check can look across them: the per-lane lists only relate a lane to
//! itself and its same-direction neighbours.
//!
//! Found once per road by sweep-and-prune over all centreline segments (sorted by their
//! x extent inflated by the lane half-widths), then an exact segment–segment distance.

use super::lane_index::LaneInfo;
use super::track::Segment;
use crate::geometry::Vec2;

/// Extra distance at which two lane strips count as touching (opposing lanes share a line).
const TOUCH_MARGIN_M: f64 = 0.05;

/// One segment's inflated x/y extent for the sweep.
#[derive(Debug, Clone, Copy)]
struct Extent {
    min_x: f64,
    max_x: f64,
    min_y: f64,
    max_y: f64,
    lane: u32,
    seg: u32,
}

/// Per lane: true when its strip meets the strip of a lane that is neither itself nor a
/// same-direction neighbour.
pub(crate) fn crossing_lanes(lanes: &[LaneInfo], segments: &[Vec<Segment>], out: &mut Vec<bool>) {
    out.clear();
    out.resize(lanes.len(), false);
    let mut ext: Vec<Extent> = Vec::new();
    for (lane, segs) in segments.iter().enumerate() {
        let h = 0.5 * lanes[lane].width_m + 0.5 * TOUCH_MARGIN_M;
        for (k, g) in segs.iter().enumerate() {
            let b = g.start + g.dir * (g.s1_m - g.s0_m);
            ext.push(Extent {
                min_x: g.start.x.min(b.x) - h,
                max_x: g.start.x.max(b.x) + h,
                min_y: g.start.y.min(b.y) - h,
                max_y: g.start.y.max(b.y) + h,
                lane: lane as u32,
                seg: k as u32,
            });
        }
    }
    ext.sort_unstable_by(|a, b| a.min_x.total_cmp(&b.min_x));
    for i in 0..ext.len() {
        let a = ext[i];
        for b in ext[i + 1..].iter().take_while(|b| b.min_x <= a.max_x) {
            let (la, lb) = (a.lane as usize, b.lane as usize);
            let related = la == lb || lanes[la].left == b.lane || lanes[la].right == b.lane;
            if related || (out[la] && out[lb]) || b.min_y > a.max_y || a.min_y > b.max_y {
                continue;
            }
            let (ga, gb) = (&segments[la][a.seg as usize], &segments[lb][b.seg as usize]);
            let reach = 0.5 * (lanes[la].width_m + lanes[lb].width_m) + TOUCH_MARGIN_M;
            if segment_distance(ga, gb) <= reach {
                out[la] = true;
                out[lb] = true;
            }
        }
    }
}

fn end(g: &Segment) -> Vec2 {
    g.start + g.dir * (g.s1_m - g.s0_m)
}

fn point_segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-24)).clamp(0.0, 1.0);
    (a + ab * t - p).norm()
}

fn cross(a: Vec2, b: Vec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Distance between two segments (0 when they cross).
fn segment_distance(g: &Segment, h: &Segment) -> f64 {
    let (a, b, c, d) = (g.start, end(g), h.start, end(h));
    let (d1, d2) = (cross(b - a, c - a), cross(b - a, d - a));
    let (d3, d4) = (cross(d - c, a - c), cross(d - c, b - c));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    point_segment_distance(a, c, d)
        .min(point_segment_distance(b, c, d))
        .min(point_segment_distance(c, a, b))
        .min(point_segment_distance(d, a, b))
}

#[cfg(test)]
mod tests {
    use super::super::track::lane_segments;
    use super::*;
    use crate::road::Road;

    fn flags(road: &Road) -> Vec<bool> {
        let mut lanes = Vec::new();
        LaneInfo::of_road(road, &mut lanes);
        let segments: Vec<Vec<Segment>> = road
            .lanes
            .iter()
            .map(|l| {
                let mut s = Vec::new();
                lane_segments(l, &mut s);
                s
            })
            .collect();
        let mut out = Vec::new();
        crossing_lanes(&lanes, &segments, &mut out);
        out
    }

    #[test]
    fn junction_and_opposing_lanes_cross_parallel_ones_do_not() {
        // Main road 0, 1 eastbound, 2 westbound (touches 1), cross road 3, 4 crosses all.
        assert_eq!(flags(&Road::crossing(3.5, 200.0, 120.0, 100.0, 13.9)), vec![true; 5]);
        assert_eq!(flags(&Road::straight(3, 3.5, 500.0, 30.0)), vec![false; 3]);
        assert_eq!(flags(&Road::ring(4, 3.5, 2_000.0, 30.0)), vec![false; 4]);
    }
}
