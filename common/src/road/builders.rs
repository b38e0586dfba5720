//! Road builders for the scenario kinds. Lane 0 is the rightmost lane of the main carriageway
//! and the reference lane; lane `i + 1` lies to the left of lane `i` (right-hand traffic).

use super::{Crosswalk, FrictionPatch, Lane, Road};
use crate::geometry::Vec2;

/// Centreline vertices of a straight lead-in, a left bend of `radius_m` through `angle_rad`
/// (arc sampled every metre) and a straight exit, offset `offset_m` to the left.
fn bend_centreline(lead_in_m: f64, radius_m: f64, angle_rad: f64, exit_m: f64, offset_m: f64) -> Vec<Vec2> {
    let mut pts = vec![Vec2::new(0.0, offset_m), Vec2::new(lead_in_m, offset_m)];
    if angle_rad > 0.0 {
        let r = radius_m - offset_m; // left lanes run on the inside of a left bend
        let centre = Vec2::new(lead_in_m, radius_m);
        let steps = ((r * angle_rad).ceil() as usize).max(2);
        for k in 1..=steps {
            let a = angle_rad * k as f64 / steps as f64;
            pts.push(centre + Vec2::new(r * a.sin(), -r * a.cos()));
        }
    }
    let last = pts[pts.len() - 1];
    let dir = Vec2::new(angle_rad.cos(), angle_rad.sin());
    pts.push(last + dir * exit_m);
    pts
}

fn link_neighbours(lanes: &mut [Lane], ids: &[usize]) {
    for w in ids.windows(2) {
        lanes[w[0]].left = Some(w[1]);
        lanes[w[1]].right = Some(w[0]);
    }
}

impl Road {
    /// `n_lanes` parallel lanes along +x from x = 0 to `length_m`; lane 0 centred on y = 0.
    pub fn straight(n_lanes: usize, lane_width_m: f64, length_m: f64, speed_limit_mps: f64) -> Road {
        Self::curved(n_lanes, lane_width_m, length_m, f64::INFINITY, 0.0, 0.0, speed_limit_mps)
    }

    /// A straight lead-in, a left bend (radius of lane 0, turning `angle_rad`) and a straight
    /// exit. An infinite radius or zero angle gives a straight road of `lead_in_m + exit_m`.
    pub fn curved(
        n_lanes: usize,
        lane_width_m: f64,
        lead_in_m: f64,
        radius_m: f64,
        angle_rad: f64,
        exit_m: f64,
        speed_limit_mps: f64,
    ) -> Road {
        let n = n_lanes.max(1);
        let angle = if radius_m.is_finite() { angle_rad } else { 0.0 };
        let mut lanes: Vec<Lane> = (0..n)
            .map(|i| {
                let pts = bend_centreline(lead_in_m, radius_m, angle, exit_m, i as f64 * lane_width_m);
                Lane::new(pts, lane_width_m, speed_limit_mps)
            })
            .collect();
        let ids: Vec<usize> = (0..n).collect();
        link_neighbours(&mut lanes, &ids);
        Road { lanes, crosswalks: Vec::new(), friction_default: 0.9, friction_patches: Vec::new(), reference_lane: 0 }
    }

    /// An urban crossing: a main road along +x of `length_m` with two eastbound lanes (0, 1)
    /// and one westbound lane (2); a two-lane cross road along y at `junction_x_m` (lane 3
    /// northbound, lane 4 southbound); and a crosswalk across the main road at `crosswalk_x_m`.
    pub fn crossing(
        lane_width_m: f64,
        length_m: f64,
        junction_x_m: f64,
        crosswalk_x_m: f64,
        speed_limit_mps: f64,
    ) -> Road {
        let w = lane_width_m;
        let east = |y: f64| Lane::new(vec![Vec2::new(0.0, y), Vec2::new(length_m, y)], w, speed_limit_mps);
        let west = Lane::new(vec![Vec2::new(length_m, 2.0 * w), Vec2::new(0.0, 2.0 * w)], w, speed_limit_mps);
        let (y_lo, y_hi) = (-60.0, 60.0 + 2.0 * w);
        let north = Lane::new(
            vec![Vec2::new(junction_x_m + 0.5 * w, y_lo), Vec2::new(junction_x_m + 0.5 * w, y_hi)],
            w,
            speed_limit_mps,
        );
        let south = Lane::new(
            vec![Vec2::new(junction_x_m - 0.5 * w, y_hi), Vec2::new(junction_x_m - 0.5 * w, y_lo)],
            w,
            speed_limit_mps,
        );
        let mut lanes = vec![east(0.0), east(w), west, north, south];
        link_neighbours(&mut lanes, &[0, 1]);
        Road {
            lanes,
            crosswalks: vec![Crosswalk {
                start: Vec2::new(crosswalk_x_m, -0.5 * w - 1.0),
                heading_rad: std::f64::consts::FRAC_PI_2,
                length_m: 3.0 * w + 2.0,
                width_m: 4.0,
            }],
            friction_default: 0.9,
            friction_patches: Vec::new(),
            reference_lane: 0,
        }
    }

    /// The same road with μ = `mu` on [s_start, s_end) of the reference lane.
    pub fn with_friction_patch(mut self, s_start_m: f64, s_end_m: f64, mu: f64) -> Road {
        self.friction_patches.push(FrictionPatch { s_start_m, s_end_m, mu });
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn straight_edges_and_lanes() {
        let road = Road::straight(3, 3.5, 200.0, 30.0);
        // Centre of the middle lane: 3.5 + 1.75 m to either edge.
        assert!((road.edge_distance_m(Vec2::new(50.0, 3.5)) - 5.25).abs() < 1e-9);
        // Just outside the right edge.
        assert!((road.edge_distance_m(Vec2::new(50.0, -2.75)) + 1.0).abs() < 1e-9);
        assert_eq!(road.locate(Vec2::new(50.0, 6.0)).lane, 2);
        assert_eq!(road.lanes[1].left, Some(2));
        assert_eq!(road.lanes[1].right, Some(0));
    }

    #[test]
    fn bend_is_a_circle_and_inner_lanes_are_shorter() {
        let road = Road::curved(2, 3.5, 50.0, 100.0, FRAC_PI_2, 50.0, 20.0);
        let outer = road.lanes[0].length_m();
        let inner = road.lanes[1].length_m();
        assert!((outer - (100.0 + 100.0 * FRAC_PI_2)).abs() < 0.1, "outer {outer}");
        assert!((inner - (100.0 + 96.5 * FRAC_PI_2)).abs() < 0.1, "inner {inner}");
        let k = road.lanes[0].curvature_at(50.0 + 0.5 * 100.0 * FRAC_PI_2);
        assert!((k - 0.01).abs() < 1e-3, "curvature {k}");
        // The bend's exit heads north.
        assert!((road.lanes[0].heading_at(outer - 1.0) - FRAC_PI_2).abs() < 1e-9);
    }

    #[test]
    fn crossing_has_a_crosswalk_and_drivable_junction() {
        let road = Road::crossing(3.5, 200.0, 120.0, 100.0, 13.9);
        assert_eq!(road.crosswalks.len(), 1);
        assert!(road.edge_distance_m(Vec2::new(121.0, 30.0)) > 0.0, "cross road is drivable");
        assert!(road.edge_distance_m(Vec2::new(60.0, 30.0)) < -20.0, "a field is not");
    }

    #[test]
    fn friction_patch_applies_across_the_road() {
        let road = Road::straight(2, 3.5, 200.0, 30.0).with_friction_patch(80.0, 120.0, 0.3);
        assert_eq!(road.friction_at(Vec2::new(100.0, 3.5)), 0.3);
        assert_eq!(road.friction_at(Vec2::new(130.0, 0.0)), 0.9);
    }
}
