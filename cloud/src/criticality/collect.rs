//! Rebuilding a CommonRoad [`Scenario`] from fleet messages: one road map (`RoadMap` with its
//! lanelets, on `risktwin/v1/<site>/<source>/map`) and every obstacle's `VehicleState`s (on
//! `risktwin/v1/<site>/dyn-<id>/state`, static obstacles on `static-<id>`), the layout
//! `risktwin import commonroad` writes. The one implementation behind `risktwin criticality
//! --mcap` (messages from a file) and the cloud's `criticality` role (messages off the wire).
//!
//! Every payload is decoded and validated as the ingest decodes it ([`risktwin_protos::decode`]);
//! a message that fails is rejected with the ingest's reason code and leaves the collector as it
//! was. The time step is not a field of any message: it is the smallest gap between two states
//! of one obstacle, and every state must lie on that grid with no step missing. Obstacles keep
//! the order in which they first appeared (the writer emits them per time step in file order,
//! so this is the file's order whenever it lists obstacles by first time step, as every
//! scenario of the data set does).
//!
//! What does not travel (no wire slot): obstacle type (read back as `car`), shapes other than
//! rectangles (their bounding rectangle), absent velocities and accelerations (0), planning
//! problems (so the default ego of a rebuilt scenario is its first dynamic obstacle).

use risktwin_align::DropReason;
use risktwin_common::geometry::Vec2;
use risktwin_common::telemetry::{RoadMap, VehicleStateSample};
use risktwin_commonroad::{DynamicObstacle, ObstacleState, Scenario, Shape, StaticObstacle};
use risktwin_protos::decode;
use risktwin_transport::EdgeStream;
use risktwin_transport::keyexpr::{parse_edge_key, parse_edge_map_key};
use std::collections::HashMap;
use thiserror::Error;

/// Why the collected messages do not make a scenario.
#[derive(Debug, Error)]
pub enum RebuildError {
    #[error("no road map arrived (risktwin/v1/<site>/<source>/map)")]
    NoMap,
    #[error("cannot infer the time step: no obstacle has two states")]
    NoTimeStep,
    #[error("obstacle id {id}: {reason}")]
    Obstacle { id: u64, reason: String },
    #[error(transparent)]
    Scenario(#[from] risktwin_commonroad::CommonRoadError),
}

/// A message from another site than the collector's (the first message fixed it).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("site '{site}' is not this collector's '{mine}'")]
pub struct OtherSite {
    /// The message's site.
    pub site: String,
    /// The collector's site.
    pub mine: String,
}

/// Why one message was not taken; the collector is unchanged.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{topic}: {detail}")]
pub struct Rejected {
    /// A short, stable code for counting: the ingest's [`DropReason`] codes of the decoder
    /// (`malformed`, `missing-field`, `invalid-field`) and `source-mismatch` (the payload names
    /// another source than its key), and this collector's own `bad-source` (not
    /// `dyn-<id>`/`static-<id>`), `other-site`, `stale-seq`.
    pub reason: &'static str,
    /// The key the message came on.
    pub topic: String,
    /// What was wrong, with the offending value.
    pub detail: String,
}

/// What [`ScenarioCollector::push`] did with a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pushed {
    /// The road map (a later one replaces an earlier one).
    Map,
    /// One obstacle state.
    State,
    /// A key outside the layout (another stream, a cloud output): ignored.
    Skipped,
}

/// One obstacle's states as received.
struct Track {
    id: u64,
    is_static: bool,
    shape: Shape,
    next_seq: u64,
    /// (capture time, state without its time step yet).
    states: Vec<(i64, ObstacleState)>,
}

/// The map and the obstacle states of one site, collected message by message.
#[derive(Default)]
pub struct ScenarioCollector {
    site: Option<String>,
    map: Option<RoadMap>,
    /// In order of first appearance.
    tracks: Vec<Track>,
    by_source: HashMap<String, usize>,
}

impl ScenarioCollector {
    /// An empty collector; the first message fixes its site.
    pub fn new() -> Self {
        Self::default()
    }

    /// The site of the messages taken so far.
    pub fn site(&self) -> Option<&str> {
        self.site.as_deref()
    }

    /// Whether a road map has arrived.
    pub fn has_map(&self) -> bool {
        self.map.is_some()
    }

    /// Takes one message received on `topic`.
    pub fn push(&mut self, topic: &str, payload: &[u8]) -> Result<Pushed, Rejected> {
        let reject = |reason: &'static str, detail: String| Rejected { reason, topic: topic.to_owned(), detail };
        if let Some((site, _)) = parse_edge_map_key(topic) {
            self.check_site(site).map_err(|e| reject("other-site", e.to_string()))?;
            let map: RoadMap = decode(payload).map_err(|e| reject(e.reason(), e.to_string()))?;
            self.site.get_or_insert_with(|| site.to_owned());
            self.map = Some(map);
            return Ok(Pushed::Map);
        }
        let Some(key) = parse_edge_key(topic).filter(|k| k.stream == EdgeStream::State) else {
            return Ok(Pushed::Skipped);
        };
        self.check_site(key.site).map_err(|e| reject("other-site", e.to_string()))?;
        let s: VehicleStateSample = decode(payload).map_err(|e| reject(e.reason(), e.to_string()))?;
        if s.header.source != key.source {
            let detail = format!("the payload names source '{}'", s.header.source);
            return Err(reject(DropReason::SourceMismatch.code(), detail));
        }
        let index = match self.by_source.get(key.source) {
            Some(&i) => i,
            None => {
                let (is_static, id) = match key.source.split_once('-') {
                    Some(("dyn", id)) => (false, id.parse::<u64>().ok()),
                    Some(("static", id)) => (true, id.parse::<u64>().ok()),
                    _ => (false, None),
                };
                let id = id.ok_or_else(|| {
                    reject("bad-source", format!("source '{}' is not dyn-<id> or static-<id>", key.source))
                })?;
                let shape = Shape::Rectangle { length_m: s.footprint.length_m, width_m: s.footprint.width_m };
                self.tracks.push(Track { id, is_static, shape, next_seq: 0, states: Vec::new() });
                self.by_source.insert(key.source.to_owned(), self.tracks.len() - 1);
                self.tracks.len() - 1
            }
        };
        let track = &mut self.tracks[index];
        if s.header.seq < track.next_seq {
            let detail = format!("seq {} already passed (next {})", s.header.seq, track.next_seq);
            return Err(reject("stale-seq", detail));
        }
        track.next_seq = s.header.seq + 1;
        self.site.get_or_insert_with(|| key.site.to_owned());
        let state = ObstacleState {
            time_step: 0,
            position: Vec2::new(s.pose.x_m, s.pose.y_m),
            orientation_rad: s.pose.heading_rad,
            velocity_mps: Some(s.speed_mps),
            acceleration_mps2: Some(s.accel_mps2),
        };
        track.states.push((s.header.capture_time_ns, state));
        Ok(Pushed::State)
    }

    fn check_site(&self, site: &str) -> Result<(), OtherSite> {
        match &self.site {
            Some(mine) if mine != site => Err(OtherSite { site: site.to_owned(), mine: mine.clone() }),
            _ => Ok(()),
        }
    }

    /// The scenario the messages describe (benchmark id = the site).
    pub fn finish(self) -> Result<Scenario, RebuildError> {
        let map = self.map.ok_or(RebuildError::NoMap)?;
        let site = self.site.unwrap_or_default();
        let dt_ns = self
            .tracks
            .iter()
            .flat_map(|t| t.states.windows(2).map(|w| w[1].0 - w[0].0))
            .filter(|&d| d > 0)
            .min()
            .ok_or(RebuildError::NoTimeStep)?;
        let (mut dynamic, mut statics) = (Vec::new(), Vec::new());
        for t in self.tracks {
            let mut states = Vec::with_capacity(t.states.len());
            for (time_ns, mut s) in t.states {
                if time_ns % dt_ns != 0 {
                    let reason = format!("state at {time_ns} ns is not on the {dt_ns} ns time grid");
                    return Err(RebuildError::Obstacle { id: t.id, reason });
                }
                s.time_step = time_ns / dt_ns;
                if let Some(prev) = states.last().map(|p: &ObstacleState| p.time_step)
                    && s.time_step != prev + 1
                {
                    let reason = format!("time step {} follows {prev} (a state is missing)", s.time_step);
                    return Err(RebuildError::Obstacle { id: t.id, reason });
                }
                states.push(s);
            }
            let mut states = states.into_iter();
            let Some(initial_state) = states.next() else { continue };
            if t.is_static {
                statics.push(StaticObstacle {
                    id: t.id,
                    obstacle_type: "unknown".into(),
                    shape: t.shape,
                    initial_state,
                });
            } else {
                dynamic.push(DynamicObstacle {
                    id: t.id,
                    obstacle_type: "car".into(),
                    shape: t.shape,
                    initial_state,
                    trajectory: states.collect(),
                    occupancy_set: Vec::new(),
                });
            }
        }
        Ok(Scenario::from_parts(site, dt_ns as f64 / 1e9, map.lanelets, dynamic, statics)?)
    }
}
