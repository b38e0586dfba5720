//! Ring roads: concentric closed lanes, so traffic can run for ever (benchmarks, density
//! studies), and the test for a closed lane.

use super::{Lane, Road};
use crate::geometry::Vec2;
use std::f64::consts::TAU;

/// Largest distance between a ring lane's polyline and its circle (the sagitta L²/(8R) of a
/// chord L): 1 cm, so chords grow with the radius (≈ 10 m at R = 1.2 km) and a long ring stays
/// a small polyline. The polygon's length is then short of the circle's by θ²/24 ≤ 5e-5.
const RING_SAGITTA_M: f64 = 0.01;
/// Longest chord, whatever the radius.
const RING_MAX_CHORD_M: f64 = 50.0;

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
        let r_min = (r0 - (n - 1) as f64 * lane_width_m).max(lane_width_m);
        let chord = (8.0 * r_min * RING_SAGITTA_M).sqrt().min(RING_MAX_CHORD_M);
        let segments = ((TAU * r0 / chord).ceil() as usize).max(32);
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
        Road { lanes, crosswalks: Vec::new(), friction_default: 0.9, friction_patches: Vec::new(), reference_lane: 0 }
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
        // The polyline stays within the 1 cm sagitta of its circle, its length within 5e-5.
        let r0 = 1000.0 / TAU;
        for (i, lane) in road.lanes.iter().enumerate() {
            let r = r0 - 3.5 * i as f64;
            assert!((lane.length_m() / (TAU * r) - 1.0).abs() < 5e-5, "lane {i}");
            let mid = 0.5 * (lane.centre[0] + lane.centre[1]);
            assert!(r - mid.norm() <= RING_SAGITTA_M + 1e-12 && r - mid.norm() > 0.0, "lane {i}");
        }
        // Counter-clockwise: heading at s = 0 (on +x) points along +y; lane 1 is to the left.
        assert!((road.lanes[0].heading_at(0.5) - std::f64::consts::FRAC_PI_2).abs() < 0.02);
        assert_eq!(road.locate(Vec2::new(r0 - 3.5, 0.5)).lane, 1);
        assert_eq!(road.lanes[0].left, Some(1));
    }
}
