//! The lines that show a road: carriageway edges and lane centrelines as polylines in the world
//! frame. One definition for every picture of the road (the report's heatmaps, the live view in
//! Foxglove).

use super::Road;
use crate::geometry::Vec2;

/// Spacing of the points of a lane's edge and centreline polylines, m.
const POLYLINE_STEP_M: f64 = 1.0;

/// A road drawn as lines.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RoadLines {
    /// Carriageway edges: the lane sides without a neighbour.
    pub edges: Vec<Vec<Vec2>>,
    /// Lane centrelines.
    pub centrelines: Vec<Vec<Vec2>>,
}

impl Road {
    /// Every lane's centreline and the sides of lanes without a neighbour there, a point every
    /// metre (at least the lane's two ends).
    pub fn lines(&self) -> RoadLines {
        let mut lines = RoadLines::default();
        for lane in &self.lanes {
            let len = lane.length_m();
            let n = (len / POLYLINE_STEP_M).ceil().clamp(1.0, 1e6) as usize;
            let along = |offset_m: f64| -> Vec<Vec2> {
                (0..=n).map(|k| lane.pose_at(len * k as f64 / n as f64, offset_m).position()).collect()
            };
            lines.centrelines.push(along(0.0));
            let half = 0.5 * lane.width_m;
            for (side, has_neighbour) in [(half, lane.left.is_some()), (-half, lane.right.is_some())] {
                if !has_neighbour {
                    lines.edges.push(along(side));
                }
            }
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_lanes_share_no_edge() {
        let lines = Road::straight(2, 3.5, 50.0, 30.0).lines();
        assert_eq!((lines.edges.len(), lines.centrelines.len()), (2, 2));
        // 50 m at a point a metre: 51 points, from one end of the lane to the other.
        assert!(lines.centrelines.iter().all(|c| c.len() == 51));
        let mut ys: Vec<f64> = lines.edges.iter().map(|e| e[0].y).collect();
        ys.sort_by(f64::total_cmp);
        let width = ys[1] - ys[0];
        assert!((width - 7.0).abs() < 1e-9, "the edges lie two lane widths apart: {ys:?}");
    }
}
