//! Visualisation messages for Foxglove: the risk field as a `foxglove.Grid`, vehicles as boxes
//! and the road as lines in a `foxglove.SceneUpdate`. One-way (the twin never reads these back).

use crate::foxglove as fg;
use risktwin_common::geometry::Vec2;
use risktwin_common::road::Road;
use risktwin_common::telemetry::{Frame, Header, RiskField, VehicleStateSample};

/// Full protobuf name of the grid message.
pub const FOXGLOVE_GRID: &str = "foxglove.Grid";
/// Full protobuf name of the scene-update message.
pub const FOXGLOVE_SCENE_UPDATE: &str = "foxglove.SceneUpdate";
/// Full protobuf name of the log-line message.
pub const FOXGLOVE_LOG: &str = "foxglove.Log";
/// Foxglove frame id of [`Frame::World`].
pub const WORLD_FRAME_ID: &str = "world";

/// Height of the boxes drawn for vehicles, m (the twin is planar).
const BOX_HEIGHT_M: f64 = 1.5;
/// Entity id of the road in a scene update.
pub const ROAD_ENTITY_ID: &str = "road";

/// A Unix time in ns as a protobuf timestamp (nanos always in [0, 1e9)).
pub fn timestamp(time_ns: i64) -> prost_types::Timestamp {
    prost_types::Timestamp {
        seconds: time_ns.div_euclid(1_000_000_000),
        nanos: time_ns.rem_euclid(1_000_000_000) as i32,
    }
}

/// The Foxglove frame id of a header: `world`, or the source's own id for its body frame.
pub fn frame_id(header: &Header) -> String {
    match header.frame {
        Frame::World => WORLD_FRAME_ID.to_string(),
        Frame::Vehicle => header.source.clone(),
    }
}

fn planar_pose(x_m: f64, y_m: f64, z_m: f64, heading_rad: f64) -> fg::Pose {
    let h = 0.5 * heading_rad;
    fg::Pose {
        position: Some(fg::Vector3 { x: x_m, y: y_m, z: z_m }),
        orientation: Some(fg::Quaternion { x: 0.0, y: 0.0, z: h.sin(), w: h.cos() }),
    }
}

/// The risk field as a `foxglove.Grid`: one little-endian FLOAT32 field `risk` per cell, rows from
/// the lowest y up, stamped with the header's capture time.
pub fn risk_grid(field: &RiskField) -> fg::Grid {
    let g = &field.grid;
    let mut data = Vec::with_capacity(g.cells.len() * 4);
    for v in &g.cells {
        data.extend_from_slice(&v.to_le_bytes());
    }
    fg::Grid {
        timestamp: Some(timestamp(field.header.capture_time_ns)),
        frame_id: frame_id(&field.header),
        pose: Some(planar_pose(g.origin_m.x, g.origin_m.y, 0.0, 0.0)),
        column_count: g.cols as u32,
        cell_size: Some(fg::Vector2 { x: g.resolution_m, y: g.resolution_m }),
        row_stride: (g.cols * 4) as u32,
        cell_stride: 4,
        fields: vec![fg::PackedElementField {
            name: "risk".into(),
            offset: 0,
            r#type: fg::packed_element_field::NumericType::Float32 as i32,
        }],
        data,
    }
}

/// Vehicles as boxes (entity id = source id, footprint × 1.5 m high, resting on z = 0), replacing
/// the previous boxes of the same sources; stamped `time_ns`.
pub fn vehicle_boxes(time_ns: i64, vehicles: &[VehicleStateSample]) -> fg::SceneUpdate {
    let entities = vehicles
        .iter()
        .map(|v| fg::SceneEntity {
            timestamp: Some(timestamp(time_ns)),
            frame_id: frame_id(&v.header),
            id: v.header.source.clone(),
            cubes: vec![fg::CubePrimitive {
                pose: Some(planar_pose(v.pose.x_m, v.pose.y_m, 0.5 * BOX_HEIGHT_M, v.pose.heading_rad)),
                size: Some(fg::Vector3 { x: v.footprint.length_m, y: v.footprint.width_m, z: BOX_HEIGHT_M }),
                color: Some(fg::Color { r: 0.2, g: 0.5, b: 0.9, a: 0.9 }),
            }],
            texts: vec![fg::TextPrimitive {
                pose: Some(planar_pose(v.pose.x_m, v.pose.y_m, BOX_HEIGHT_M + 0.5, 0.0)),
                billboard: true,
                font_size: 14.0,
                scale_invariant: true,
                color: Some(fg::Color { r: 1.0, g: 1.0, b: 1.0, a: 1.0 }),
                text: format!("{} {:.1} m/s", v.header.source, v.speed_mps),
            }],
            ..Default::default()
        })
        .collect();
    fg::SceneUpdate { deletions: Vec::new(), entities }
}

/// The road as lines on the ground (entity [`ROAD_ENTITY_ID`], world frame, stamped `time_ns`):
/// carriageway edges solid white, lane centrelines thin grey, crosswalks outlined in yellow; the
/// lines of [`Road::lines`], so Foxglove shows what the report's heatmaps show.
pub fn road_scene(time_ns: i64, road: &Road) -> fg::SceneUpdate {
    let line =
        |kind: fg::line_primitive::Type, points: &[Vec2], thickness_m: f64, color: fg::Color| fg::LinePrimitive {
            r#type: kind as i32,
            pose: Some(planar_pose(0.0, 0.0, 0.0, 0.0)),
            thickness: thickness_m,
            scale_invariant: false,
            points: points.iter().map(|p| fg::Point3 { x: p.x, y: p.y, z: 0.0 }).collect(),
            color: Some(color),
            ..Default::default()
        };
    let strip = fg::line_primitive::Type::LineStrip;
    let lines = road.lines();
    let edges = lines.edges.iter().map(|e| line(strip, e, 0.15, fg::Color { r: 0.9, g: 0.9, b: 0.9, a: 1.0 }));
    let centres = lines.centrelines.iter().map(|c| line(strip, c, 0.05, fg::Color { r: 0.6, g: 0.6, b: 0.6, a: 0.8 }));
    let crosswalks = road.crosswalks.iter().map(|w| {
        let along = Vec2::new(w.heading_rad.cos(), w.heading_rad.sin());
        let across = Vec2::new(-along.y, along.x) * (0.5 * w.width_m);
        let end = w.start + along * w.length_m;
        let corners = [w.start - across, end - across, end + across, w.start + across];
        line(fg::line_primitive::Type::LineLoop, &corners, 0.1, fg::Color { r: 1.0, g: 0.85, b: 0.2, a: 1.0 })
    });
    let entity = fg::SceneEntity {
        timestamp: Some(timestamp(time_ns)),
        frame_id: WORLD_FRAME_ID.to_owned(),
        id: ROAD_ENTITY_ID.to_owned(),
        lines: edges.chain(centres).chain(crosswalks).collect(),
        ..Default::default()
    };
    fg::SceneUpdate { deletions: Vec::new(), entities: vec![entity] }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::convert::tests::{hdr, vehicle_state};
    use prost::Message;
    use risktwin_common::geometry::{Pose, Vec2};
    use risktwin_common::risk::RiskGrid;

    #[test]
    fn grid_cells_land_where_foxglove_reads_them() {
        let grid = RiskGrid {
            origin_m: Vec2::new(-4.0, 2.0),
            resolution_m: 0.5,
            cols: 3,
            rows: 2,
            cells: vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.5],
        };
        let g = risk_grid(&RiskField { header: hdr(1), grid });
        let g = fg::Grid::decode(&*g.encode_to_vec()).expect("own encoding decodes");
        // Cell (col 2, row 1) starts at byte row·row_stride + col·cell_stride.
        let at = (g.row_stride + 2 * g.cell_stride) as usize;
        assert_eq!(f32::from_le_bytes([g.data[at], g.data[at + 1], g.data[at + 2], g.data[at + 3]]), 5.5);
        assert_eq!((g.column_count, g.data.len()), (3, 24));
        assert_eq!(g.pose.and_then(|p| p.position).map(|p| (p.x, p.y)), Some((-4.0, 2.0)));
        assert_eq!(g.timestamp, Some(prost_types::Timestamp { seconds: 1_700_000_000, nanos: 123_456_789 }));
    }

    #[test]
    fn boxes_follow_heading_and_footprint() {
        let v = VehicleStateSample { pose: Pose::new(10.0, 5.0, std::f64::consts::FRAC_PI_2), ..vehicle_state() };
        let update = vehicle_boxes(-1, &[v]);
        let e = &update.entities[0];
        assert_eq!((e.id.as_str(), e.frame_id.as_str()), ("vehicle-7", WORLD_FRAME_ID));
        assert_eq!(e.timestamp, Some(prost_types::Timestamp { seconds: -1, nanos: 999_999_999 }));
        let cube = &e.cubes[0];
        let q = cube.pose.and_then(|p| p.orientation).expect("orientation set");
        assert!((q.z - 0.5f64.sqrt()).abs() < 1e-12 && (q.w - 0.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(cube.size.map(|s| (s.x, s.y)), Some((4.5, 1.8)));
    }

    #[test]
    fn the_road_is_its_lines_on_the_ground() {
        let road = Road::crossing(3.5, 200.0, 100.0, 80.0, 13.9);
        let update = fg::SceneUpdate::decode(&*road_scene(5, &road).encode_to_vec()).expect("own encoding decodes");
        let entity = &update.entities[0];
        assert_eq!((entity.id.as_str(), entity.frame_id.as_str()), (ROAD_ENTITY_ID, WORLD_FRAME_ID));
        let lines = road.lines();
        let strips = lines.edges.len() + lines.centrelines.len();
        assert_eq!(entity.lines.len(), strips + road.crosswalks.len());
        assert!(!road.crosswalks.is_empty(), "the crossing has a crosswalk to draw");
        let first_edge = &entity.lines[0];
        assert_eq!(first_edge.points.len(), lines.edges[0].len());
        assert_eq!((first_edge.points[0].x, first_edge.points[0].y), (lines.edges[0][0].x, lines.edges[0][0].y));
        assert!(entity.lines.iter().flat_map(|l| &l.points).all(|p| p.z == 0.0));
        let crosswalk = entity.lines.last().expect("a crosswalk");
        assert_eq!(crosswalk.r#type, fg::line_primitive::Type::LineLoop as i32);
        assert_eq!(crosswalk.points.len(), 4);
    }
}
