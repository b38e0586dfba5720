//! What a heatmap of a [`CommonRoadField`] shows over the real lanelet map: cells inside a
//! lanelet in full colour (and setting the colour scale), lanelet bounds solid, centrelines
//! dashed. The figure itself is drawn by the report's figures (`risktwin-pipeline`).

use super::super::LaneletNetwork;
use super::snapshot::CommonRoadField;
use risktwin_common::risk::HeatmapLayers;

/// The layers of `field` over `network`.
pub fn lanelet_layers(field: &CommonRoadField, network: &LaneletNetwork) -> HeatmapLayers {
    let grid = &field.grid;
    let on_map = (0..grid.cols * grid.rows)
        .map(|k| network.containing(grid.cell_centre(k % grid.cols, k / grid.cols)).next().is_some())
        .collect();
    let mut edges = Vec::new();
    let mut centrelines = Vec::new();
    for l in &network.lanelets {
        edges.push(l.left_bound.clone());
        edges.push(l.right_bound.clone());
        centrelines.push(l.centreline.clone());
    }
    HeatmapLayers::new(grid, on_map, edges, centrelines)
}
