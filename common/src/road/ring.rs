//! Ring roads: concentric closed lanes, so traffic can run for ever (benchmarks, density
//! studies), and the test for a closed lane.

use super::{Lane, Road};
use crate::geometry::Vec2;
use std::f64::consts::TAU;

/// Longest chord of a ring lane's polyline; short enough that the polygon's length is within
/// 1e-5 of the circle's for any radius above ~50 m.
const RING_SEGMENT_M: f64 = 2.0;

impl Lane {
    /// True when the centreline is a loop: its first and last vertex coincide, so arc length
    /// wraps at `length_m()`.
    pub fn is_closed(&self) -> bool {
        match (self.centre.first(), self.centre.last()) {
            (Some(a), Some(b)) => self.centre.len() > 2 && (a - b).norm() < 1e-6,
            _ => false,
        }
    }
}

impl Road {
    /// `n_lanes` concentric closed lanes driven counter-clockwise around the origin. Lane 0 is
    /// the outer (rightmost) lane with circumference `circumference_m`; lane `i + 1` lies
    /// `lane_width_m` inside lane `i`. Inner lanes keep a radius of at least one lane width.
    /// Each lane starts (s = 0) on the positive x axis.
    pub fn ring(n_lanes: usize, lane_width_m: f64, circumference_m: f64, speed_limit_mps: f64) -> Road {
        let n = n_lanes.max(1);
        let r0 = (circumference_m / TAU).max(n as f64 * lane_width_m);
        let segments = ((TAU * r0 / RING_SEGMENT_M).ceil() as usize).max(32);
        let mut lanes: Vec<Lane> = (0..n)
            .map(|i| {
                let r = r0 - i as f64 * lane_width_m;
                let mut pts: Vec<Vec2> = (0..segments)
                    .map(|k| {
                        let a = TAU * k as f64 / segments as f64;
                        Vec2::new(r * a.cos(), r * a.sin())
                    })
                    .collect();
                pts.push(pts[0]); // exact closure: is_closed() relies on it
                Lane::new(pts, lane_width_m, speed_limit_mps)
            })
            .collect();
        for i in 0..n.saturating_sub(1) {
            lanes[i].left = Some(i + 1);
            lanes[i + 1].right = Some(i);
        }
        Road {
            lanes,
            crosswalks: Vec::new(),
            friction_default: 0.9,
            friction_patches: Vec::new(),
            reference_lane: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_lanes_are_closed_circles() {
        let road = Road::ring(3, 3.5, 1000.0, 30.0);
        assert!(road.lanes.iter().all(Lane::is_closed));
        assert!(!Road::straight(2, 3.5, 100.0, 30.0).lanes[0].is_closed());
        // Polygon length within 1e-5 relative of the circle's.
        let r0 = 1000.0 / TAU;
        for (i, lane) in road.lanes.iter().enumerate() {
            let circle = TAU * (r0 - 3.5 * i as f64);
            assert!((lane.length_m() / circle - 1.0).abs() < 1e-5, "lane {i}");
        }
        // Counter-clockwise: heading at s = 0 (on +x) points along +y; lane 1 is to the left.
        assert!((road.lanes[0].heading_at(0.5) - std::f64::consts::FRAC_PI_2).abs() < 0.01);
        assert_eq!(road.locate(Vec2::new(r0 - 3.5, 0.5)).lane, 1);
        assert_eq!(road.lanes[0].left, Some(1));
    }
}
