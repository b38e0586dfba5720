//! Lanelets → twin lanes.

use super::super::LaneletNetwork;
use super::TwinError;
use risktwin_common::geometry::Vec2;
use risktwin_common::road::{Lane, Road};

/// Speed limit given to every converted lane, m/s (130 km/h): the 2020a files here carry no
/// speed-limit signs the twin reads; drivers take their desired speed from the recording.
const DEFAULT_SPEED_LIMIT_MPS: f64 = 36.0;
/// Dry asphalt, as the twin's own road builders use.
const FRICTION: f64 = 0.9;

/// One twin lane per lanelet with a usable centreline, in file order: the centreline (repeated
/// vertices dropped), the mean of the lanelet's widths (a twin lane has one width), and the left
/// and right neighbours that run the same way. Lanelets with fewer than two distinct centreline
/// points are left out (their neighbours lose the link). Returns the road and, per lane, the
/// lanelet id it came from.
pub fn road_from_lanelets(network: &LaneletNetwork) -> Result<(Road, Vec<u64>), TwinError> {
    let mut lanes = Vec::with_capacity(network.len());
    let mut ids = Vec::with_capacity(network.len());
    let mut lane_of = vec![None; network.len()];
    for (i, l) in network.lanelets.iter().enumerate() {
        let mut centre: Vec<Vec2> = Vec::with_capacity(l.centreline.len());
        for &p in &l.centreline {
            if centre.last().is_none_or(|q: &Vec2| (p - q).norm() > 1e-6) && p.x.is_finite() && p.y.is_finite() {
                centre.push(p);
            }
        }
        if centre.len() < 2 {
            continue;
        }
        let width_m = l.widths_m.iter().sum::<f64>() / l.widths_m.len().max(1) as f64;
        lane_of[i] = Some(lanes.len());
        lanes.push(Lane::new(centre, width_m, DEFAULT_SPEED_LIMIT_MPS));
        ids.push(l.id);
    }
    if lanes.is_empty() {
        return Err(TwinError::NoLanes);
    }
    let twin_lane = |adj: Option<super::super::Adjacency>| {
        adj.filter(|a| a.same_direction).and_then(|a| network.index_of(a.id)).and_then(|k| lane_of[k])
    };
    for (i, l) in network.lanelets.iter().enumerate() {
        if let Some(k) = lane_of[i] {
            lanes[k].left = twin_lane(l.adjacent_left);
            lanes[k].right = twin_lane(l.adjacent_right);
        }
    }
    // A self-link or a left/right cycle would make the carriageway walk loop forever.
    break_neighbour_cycles(&mut lanes);
    let road = Road {
        lanes,
        crosswalks: Vec::new(),
        friction_default: FRICTION,
        friction_patches: Vec::new(),
        reference_lane: 0,
    };
    Ok((road, ids))
}

/// Cuts neighbour chains that revisit a lane (inconsistent adjacency in a file).
fn break_neighbour_cycles(lanes: &mut [Lane]) {
    let n = lanes.len();
    for start in 0..n {
        for left in [true, false] {
            let mut seen = vec![false; n];
            seen[start] = true;
            let mut cur = start;
            loop {
                let next = if left { lanes[cur].left } else { lanes[cur].right };
                let Some(next) = next else { break };
                if seen[next] {
                    if left {
                        lanes[cur].left = None;
                    } else {
                        lanes[cur].right = None;
                    }
                    break;
                }
                seen[next] = true;
                cur = next;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Adjacency, Lanelet};

    #[test]
    fn lanes_keep_centrelines_widths_and_same_direction_neighbours() {
        let a = |y0: f64, y1: f64| {
            (vec![Vec2::new(0.0, y1), Vec2::new(50.0, y1)], vec![Vec2::new(0.0, y0), Vec2::new(50.0, y0)])
        };
        let (l1, r1) = a(0.0, 3.0);
        let (l2, r2) = a(3.0, 7.0);
        let (l3, r3) = a(7.0, 10.0);
        let mut one = Lanelet::new(1, l1, r1);
        let mut two = Lanelet::new(2, l2, r2);
        // Lanelet 3 runs the other way: reversed bounds.
        let three = Lanelet::new(3, r3.into_iter().rev().collect(), l3.into_iter().rev().collect());
        one.adjacent_left = Some(Adjacency { id: 2, same_direction: true });
        two.adjacent_right = Some(Adjacency { id: 1, same_direction: true });
        two.adjacent_left = Some(Adjacency { id: 3, same_direction: false });
        let (road, ids) = road_from_lanelets(&LaneletNetwork::new(vec![one, two, three])).expect("three lanes");
        assert_eq!(ids, vec![1, 2, 3]);
        assert_eq!((road.lanes[0].left, road.lanes[0].right), (Some(1), None));
        assert_eq!((road.lanes[1].left, road.lanes[1].right), (None, Some(0)), "opposite lanes are no neighbours");
        assert!((road.lanes[1].width_m - 4.0).abs() < 1e-12);
        assert!((road.lanes[0].centre[0].y - 1.5).abs() < 1e-12);
        // The lane term sees lane 1 at y = 5, the boundary term the carriageway edge at y = 7.
        let at = road.locate(Vec2::new(25.0, 5.0));
        assert_eq!(at.lane, 1);
        assert!((road.edge_distance_m(Vec2::new(25.0, 6.0)) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn degenerate_network_is_an_error() {
        let p = vec![Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.0)];
        let l = Lanelet::new(1, p.clone(), p);
        assert!(matches!(road_from_lanelets(&LaneletNetwork::new(vec![l])), Err(TwinError::NoLanes)));
    }
}
