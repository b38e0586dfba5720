//! The road map. Lanes travel as centreline vertices (a repeated vertex once); arc lengths are
//! recomputed on arrival, so a map cannot carry arc lengths inconsistent with its vertices. CommonRoad lanelets travel
//! as their two bounds and links; centrelines, widths and polygons are rebuilt on arrival
//! ([`Lanelet::new`]), exactly as the XML import builds them.

use super::geometry::{header, vec_from, vec_to};
use super::{ConvertError, finite, invalid, non_negative, positive};
use crate::v1;
use risktwin_common::road::{Adjacency, Lanelet, LaneletNetwork};
use risktwin_common::road::{Crosswalk, FrictionPatch, Lane, Road};
use risktwin_common::telemetry::RoadMap;
use std::collections::HashSet;

impl From<&RoadMap> for v1::RoadMap {
    fn from(m: &RoadMap) -> Self {
        let r = &m.road;
        Self {
            header: Some((&m.header).into()),
            lanes: r
                .lanes
                .iter()
                .map(|l| v1::Lane {
                    centre_m: without_repeats(&l.centre).map(vec_to).collect(),
                    width_m: l.width_m,
                    left: l.left.map(|i| i as u32),
                    right: l.right.map(|i| i as u32),
                    speed_limit_mps: l.speed_limit_mps,
                })
                .collect(),
            crosswalks: r
                .crosswalks
                .iter()
                .map(|c| v1::Crosswalk {
                    start_m: Some(vec_to(&c.start)),
                    heading_rad: c.heading_rad,
                    length_m: c.length_m,
                    width_m: c.width_m,
                })
                .collect(),
            friction_default: r.friction_default,
            friction_patches: r
                .friction_patches
                .iter()
                .map(|p| v1::FrictionPatch { s_start_m: p.s_start_m, s_end_m: p.s_end_m, mu: p.mu })
                .collect(),
            reference_lane: r.reference_lane as u32,
            lanelets: m.lanelets.lanelets.iter().map(lanelet_to).collect(),
        }
    }
}

/// A centreline without consecutive repeated vertices: a builder may leave a zero-length
/// segment (a bend with no exit), which carries no geometry and which a receiver refuses.
fn without_repeats(
    centre: &[risktwin_common::geometry::Vec2],
) -> impl Iterator<Item = &risktwin_common::geometry::Vec2> {
    centre.iter().enumerate().filter(|&(i, v)| i == 0 || centre[i - 1] != *v).map(|(_, v)| v)
}

fn lanelet_to(l: &Lanelet) -> v1::Lanelet {
    let adjacency =
        |a: Option<Adjacency>| a.map(|a| v1::LaneletAdjacency { id: a.id, same_direction: a.same_direction });
    v1::Lanelet {
        id: l.id,
        left_bound_m: l.left_bound.iter().map(vec_to).collect(),
        right_bound_m: l.right_bound.iter().map(vec_to).collect(),
        predecessors: l.predecessors.clone(),
        successors: l.successors.clone(),
        adjacent_left: adjacency(l.adjacent_left),
        adjacent_right: adjacency(l.adjacent_right),
        lanelet_types: l.lanelet_types.clone(),
    }
}

/// A lanelet with bounds of equal length (at least two finite vertices each). Links may name
/// lanelets absent from the map: CommonRoad files do (cut-outs of larger maps), and every
/// consumer looks ids up.
fn lanelet_from(l: v1::Lanelet) -> Result<Lanelet, ConvertError> {
    const M: &str = "Lanelet";
    let bound = |field: &'static str, vs: Vec<v1::Vector2>| -> Result<Vec<_>, ConvertError> {
        vs.into_iter().map(|v| vec_from(M, field, Some(v))).collect()
    };
    let left = bound("left_bound_m", l.left_bound_m)?;
    let right = bound("right_bound_m", l.right_bound_m)?;
    if left.len() < 2 || left.len() != right.len() {
        return Err(invalid(
            M,
            "right_bound_m",
            format!(
                "lanelet {}: bounds need the same number of vertices (at least 2), left has {}, right has {}",
                l.id,
                left.len(),
                right.len()
            ),
        ));
    }
    let mut out = Lanelet::new(l.id, left, right);
    out.predecessors = l.predecessors;
    out.successors = l.successors;
    let adjacency =
        |a: Option<v1::LaneletAdjacency>| a.map(|a| Adjacency { id: a.id, same_direction: a.same_direction });
    out.adjacent_left = adjacency(l.adjacent_left);
    out.adjacent_right = adjacency(l.adjacent_right);
    out.lanelet_types = l.lanelet_types;
    Ok(out)
}

/// The lanelets of a map, ids unique.
fn lanelets_from(ls: Vec<v1::Lanelet>) -> Result<LaneletNetwork, ConvertError> {
    let mut seen = HashSet::with_capacity(ls.len());
    if let Some(dup) = ls.iter().map(|l| l.id).find(|id| !seen.insert(*id)) {
        return Err(invalid("RoadMap", "lanelets", format!("lanelet id {dup} appears twice")));
    }
    Ok(LaneletNetwork::new(ls.into_iter().map(lanelet_from).collect::<Result<_, _>>()?))
}

/// A lane index that names another lane of the map.
fn lane_ref(field: &'static str, own: usize, index: Option<u32>, lanes: usize) -> Result<Option<usize>, ConvertError> {
    match index.map(|i| i as usize) {
        Some(i) if i >= lanes || i == own => {
            Err(invalid("Lane", field, format!("lane {own} names neighbour {i}, the map has {lanes} lanes")))
        }
        other => Ok(other),
    }
}

fn lane(own: usize, l: v1::Lane, lanes: usize) -> Result<Lane, ConvertError> {
    const M: &str = "Lane";
    if l.centre_m.len() < 2 {
        return Err(invalid(M, "centre_m", format!("lane {own} has {} vertices, needs at least 2", l.centre_m.len())));
    }
    let centre = l.centre_m.into_iter().map(|v| vec_from(M, "centre_m", Some(v))).collect::<Result<Vec<_>, _>>()?;
    if let Some(i) = centre.windows(2).position(|w| w[0] == w[1]) {
        return Err(invalid(M, "centre_m", format!("lane {own} repeats vertex {} (zero-length segment)", i + 1)));
    }
    let mut lane =
        Lane::new(centre, positive(M, "width_m", l.width_m)?, non_negative(M, "speed_limit_mps", l.speed_limit_mps)?);
    lane.left = lane_ref("left", own, l.left, lanes)?;
    lane.right = lane_ref("right", own, l.right, lanes)?;
    Ok(lane)
}

impl TryFrom<v1::RoadMap> for RoadMap {
    type Error = ConvertError;
    fn try_from(m: v1::RoadMap) -> Result<Self, ConvertError> {
        const M: &str = "RoadMap";
        let n = m.lanes.len();
        if n == 0 {
            return Err(ConvertError::MissingField { message: M, field: "lanes" });
        }
        let reference_lane = m.reference_lane as usize;
        if reference_lane >= n {
            return Err(invalid(M, "reference_lane", format!("{reference_lane}, the map has {n} lanes")));
        }
        let lanes = m.lanes.into_iter().enumerate().map(|(i, l)| lane(i, l, n)).collect::<Result<Vec<_>, _>>()?;
        let crosswalks = m
            .crosswalks
            .into_iter()
            .map(|c| {
                const C: &str = "Crosswalk";
                Ok(Crosswalk {
                    start: vec_from(C, "start_m", c.start_m)?,
                    heading_rad: finite(C, "heading_rad", c.heading_rad)?,
                    length_m: positive(C, "length_m", c.length_m)?,
                    width_m: positive(C, "width_m", c.width_m)?,
                })
            })
            .collect::<Result<Vec<_>, ConvertError>>()?;
        let friction_patches = m
            .friction_patches
            .into_iter()
            .map(|p| {
                const P: &str = "FrictionPatch";
                let s_start_m = finite(P, "s_start_m", p.s_start_m)?;
                let s_end_m = finite(P, "s_end_m", p.s_end_m)?;
                if s_end_m < s_start_m {
                    return Err(invalid(P, "s_end_m", format!("{s_end_m} is before s_start_m {s_start_m}")));
                }
                Ok(FrictionPatch { s_start_m, s_end_m, mu: positive(P, "mu", p.mu)? })
            })
            .collect::<Result<Vec<_>, ConvertError>>()?;
        let lanelets = lanelets_from(m.lanelets)?;
        Ok(Self {
            header: header(M, m.header)?,
            lanelets,
            road: Road {
                lanes,
                crosswalks,
                friction_default: positive(M, "friction_default", m.friction_default)?,
                friction_patches,
                reference_lane,
            },
        })
    }
}
