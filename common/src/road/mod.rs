//! Roads: lanes with Frenet frames, road edges, crosswalks and friction per segment.
//!
//! Three builders cover the scenario kinds: a multi-lane straight road, a multi-lane road with a
//! circular bend, and an urban crossing (two-way main road, a crossing road, a crosswalk).
//! Lanes of one driving direction that lie side by side form a carriageway; its outer edges are
//! road edges. Opposing carriageways are separate, so the centre line counts as an edge: leaving
//! one's carriageway towards oncoming traffic is a boundary risk as well.

mod builders;
mod lane;
pub mod lanelet;
mod lines;
mod ring;

pub use lane::{Frenet, Lane, LaneId};
pub use lanelet::{Adjacency, Lanelet, LaneletNetwork};
pub use lines::RoadLines;

use crate::geometry::{Obb, Vec2};
use serde::{Deserialize, Serialize};

/// A pedestrian crossing: a strip across the road that pedestrians walk along `heading_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Crosswalk {
    /// Where pedestrians step onto the road.
    pub start: Vec2,
    pub heading_rad: f64,
    pub length_m: f64,
    pub width_m: f64,
}

/// Friction coefficient μ over an interval of the reference lane's arc length.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrictionPatch {
    pub s_start_m: f64,
    pub s_end_m: f64,
    pub mu: f64,
}

/// A road network small enough to search linearly (tens of lanes).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Road {
    pub lanes: Vec<Lane>,
    pub crosswalks: Vec<Crosswalk>,
    /// μ outside every patch (dry asphalt ≈ 0.9–1.0).
    pub friction_default: f64,
    /// Patches along the arc length of lane `reference_lane`, applied across the carriageway.
    pub friction_patches: Vec<FrictionPatch>,
    pub reference_lane: LaneId,
}

/// Where a point lies on the road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LanePosition {
    pub lane: LaneId,
    pub frenet: Frenet,
}

impl Road {
    pub fn lane(&self, id: LaneId) -> &Lane {
        &self.lanes[id]
    }

    /// The lane whose centreline is laterally closest to `p` among lanes whose arc-length range
    /// covers it (falling back to all lanes), i.e. the lane a vehicle at `p` is driving in.
    pub fn locate(&self, p: Vec2) -> LanePosition {
        // Headings (atan2) only for the winner: this runs per cell and lane in the risk field.
        let mut best: Option<(bool, f64, LaneId)> = None;
        for (id, lane) in self.lanes.iter().enumerate() {
            let (s_m, e_y_m, _) = lane.project_offsets(p);
            let inside_s = s_m >= 0.0 && s_m <= lane.length_m();
            let key = (inside_s, e_y_m.abs());
            let better = match &best {
                None => true,
                Some((bs, be, _)) => (key.0 && !bs) || (key.0 == *bs && key.1 < *be),
            };
            if better {
                best = Some((key.0, key.1, id));
            }
        }
        let lane = best.map(|b| b.2).expect("a road has at least one lane (builders guarantee it)");
        LanePosition { lane, frenet: self.lanes[lane].project(p) }
    }

    /// Like [`Road::locate`] but restricted to lanes whose heading is within 90° of `heading_rad`,
    /// so a vehicle in an intersection is matched to the lane it drives along.
    pub fn locate_heading(&self, p: Vec2, heading_rad: f64) -> LanePosition {
        let mut best: Option<(f64, LanePosition)> = None;
        for (id, lane) in self.lanes.iter().enumerate() {
            let f = lane.project(p);
            if crate::geometry::wrap_angle(f.lane_heading_rad - heading_rad).abs() > std::f64::consts::FRAC_PI_2 {
                continue;
            }
            let outside_s = (-f.s_m).max(f.s_m - lane.length_m()).max(0.0);
            let cost = f.e_y_m.abs() + outside_s;
            if best.as_ref().is_none_or(|b| cost < b.0) {
                best = Some((cost, LanePosition { lane: id, frenet: f }));
            }
        }
        best.map(|b| b.1).unwrap_or_else(|| self.locate(p))
    }

    /// Distance from the lane edge to the carriageway edge on the left (sum of the widths of
    /// the left neighbours) and on the right.
    fn carriageway_margins(&self, id: LaneId) -> (f64, f64) {
        let (mut left, mut right) = (0.0, 0.0);
        let mut l = self.lanes[id].left;
        while let Some(n) = l {
            left += self.lanes[n].width_m;
            l = self.lanes[n].left;
        }
        let mut r = self.lanes[id].right;
        while let Some(n) = r {
            right += self.lanes[n].width_m;
            r = self.lanes[n].right;
        }
        (left, right)
    }

    /// Signed distance from `p` to the nearest road edge: positive on the road, negative off it.
    /// A point is on the road when it lies inside any lane's strip; the lane ends count as edges
    /// only where the lane has no continuation (every builder's lanes run to the map border).
    pub fn edge_distance_m(&self, p: Vec2) -> f64 {
        let mut best = f64::NEG_INFINITY;
        for (id, lane) in self.lanes.iter().enumerate() {
            let (s_m, e_y_m, _) = lane.project_offsets(p);
            let (ml, mr) = self.carriageway_margins(id);
            let half = 0.5 * lane.width_m;
            let lateral = (half + ml - e_y_m).min(half + mr + e_y_m);
            let along = s_m.min(lane.length_m() - s_m);
            let d = if lateral >= 0.0 && along >= 0.0 {
                lateral
            } else {
                -(lateral.min(0.0).powi(2) + along.min(0.0).powi(2)).sqrt()
            };
            best = best.max(d);
        }
        best
    }

    /// True when every corner of the footprint is on the road.
    pub fn contains_footprint(&self, obb: &Obb) -> bool {
        obb.corners().iter().all(|c| self.edge_distance_m(*c) >= 0.0)
    }

    /// Road friction coefficient μ at `p`.
    pub fn friction_at(&self, p: Vec2) -> f64 {
        if self.friction_patches.is_empty() {
            return self.friction_default;
        }
        let s = self.lanes[self.reference_lane].project(p).s_m;
        self.friction_patches.iter().find(|f| s >= f.s_start_m && s < f.s_end_m).map_or(self.friction_default, |f| f.mu)
    }

    /// Axis-aligned bounds of all lane strips: (min corner, max corner).
    pub fn bounds(&self) -> (Vec2, Vec2) {
        let mut lo = Vec2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = Vec2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        for lane in &self.lanes {
            for p in &lane.centre {
                let h = 0.5 * lane.width_m;
                lo = Vec2::new(lo.x.min(p.x - h), lo.y.min(p.y - h));
                hi = Vec2::new(hi.x.max(p.x + h), hi.y.max(p.y + h));
            }
        }
        (lo, hi)
    }
}
