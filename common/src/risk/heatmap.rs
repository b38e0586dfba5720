//! What a heatmap of a [`RiskGrid`] shows, in world coordinates: which cells lie on the
//! drivable map (drawn in full colour and setting the top of the colour scale; off the map the
//! boundary term alone reaches an obstacle's peak, so those cells would swamp the scale), and
//! the lines drawn over the field (carriageway edges solid, lane centrelines dashed). Drawing
//! it is the caller's: the report's figures (`risktwin-pipeline`).

use super::raster::RiskGrid;
use crate::geometry::Vec2;
use crate::road::Road;

/// The layers of one heatmap.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatmapLayers {
    /// Per cell, in [`RiskGrid::cells`] order: whether its centre lies on the map.
    pub on_map: Vec<bool>,
    /// The top of the colour scale: the largest finite value on the map (the whole grid's when
    /// no cell is on it), at least 1e-9.
    pub scale_max: f32,
    /// Carriageway edges (lanelet bounds on a CommonRoad map): solid polylines.
    pub edges: Vec<Vec<Vec2>>,
    /// Lane centrelines: dashed polylines.
    pub centrelines: Vec<Vec<Vec2>>,
}

impl HeatmapLayers {
    /// The layers of `grid` given which cells are on the map and the lines over it.
    pub fn new(grid: &RiskGrid, on_map: Vec<bool>, edges: Vec<Vec<Vec2>>, centrelines: Vec<Vec<Vec2>>) -> Self {
        let any_on = on_map.iter().any(|&b| b);
        let scale_max = grid
            .cells
            .iter()
            .zip(on_map.iter().chain(std::iter::repeat(&true)))
            .filter(|(v, on)| v.is_finite() && (**on || !any_on))
            .fold(0.0f32, |m, (v, _)| m.max(*v))
            .max(1e-9);
        HeatmapLayers { on_map, scale_max, edges, centrelines }
    }

    /// Whether cell `k` is drawn in full colour (cells past `on_map` are).
    pub fn is_on_map(&self, k: usize) -> bool {
        self.on_map.get(k).copied().unwrap_or(true)
    }
}

/// The layers of `grid` over the twin's `road`: a cell is on the map when its centre is within
/// the carriageway; the lines are [`Road::lines`].
pub fn road_layers(grid: &RiskGrid, road: &Road) -> HeatmapLayers {
    let on_map =
        (0..grid.cols * grid.rows).map(|k| road.edge_distance_m(grid.cell_centre(k % grid.cols, k / grid.cols)) >= 0.0);
    let lines = road.lines();
    HeatmapLayers::new(grid, on_map.collect(), lines.edges, lines.centrelines)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn off_road_cells_are_marked_and_left_out_of_the_scale() {
        let road = Road::straight(1, 3.5, 100.0, 30.0);
        // Row 0 (centres at y = 0.5 m) is on the road, row 1 (y = 3.5 m) off it (edge at 1.75 m).
        let mut grid = RiskGrid::new(Vec2::new(0.0, -1.0), 3.0, 10, 2).expect("valid grid");
        grid.cells[3] = 0.5;
        grid.cells[13] = 2.0;
        let layers = road_layers(&grid, &road);
        assert!(layers.on_map[..10].iter().all(|&b| b) && layers.on_map[10..].iter().all(|&b| !b));
        assert_eq!(layers.scale_max, 0.5, "the on-road maximum is the top of the scale");
        // Off the road entirely: the whole grid sets the scale.
        let mut off = RiskGrid::new(Vec2::new(0.0, 5.0), 1.0, 10, 1).expect("valid grid");
        off.cells[3] = 2.0;
        assert_eq!(road_layers(&off, &road).scale_max, 2.0);
    }

    #[test]
    fn a_single_lane_has_both_edges_and_one_centreline() {
        let road = Road::straight(1, 3.5, 100.0, 30.0);
        let grid = RiskGrid::new(Vec2::new(0.0, -1.0), 1.0, 4, 4).expect("valid grid");
        let layers = road_layers(&grid, &road);
        assert_eq!((layers.edges.len(), layers.centrelines.len()), (2, 1));
        let ys: Vec<f64> = layers.edges.iter().map(|e| e[0].y).collect();
        assert!(ys.iter().any(|y| (y - 1.75).abs() < 1e-9) && ys.iter().any(|y| (y + 1.75).abs() < 1e-9), "{ys:?}");
        let centre = &layers.centrelines[0];
        assert!((centre.last().expect("points").x - centre[0].x - 100.0).abs() < 1e-6, "the whole lane");
    }
}
