//! A CommonRoad scenario as fleet data, and back: the recording `risktwin import commonroad`
//! writes and `risktwin criticality --mcap` reads.
//!
//! Layout (the MCAP layout of `--record`, topics from `transport::keyexpr`, site = the benchmark
//! id): one `risktwin.v1.RoadMap` on `risktwin/v1/<site>/map/map` (twin lanes plus the lanelet
//! network), then per time step every obstacle present as a `risktwin.v1.VehicleState` on
//! `risktwin/v1/<site>/dyn-<id>/state` (static obstacles once, `static-<id>`), log and capture
//! time = time step × dt (scenario time from 0). Reading back is
//! [`crate::criticality::collect`]'s, the same code the cloud runs on the live stream;
//! its module doc says what does not travel.

use crate::criticality::{RebuildError, Rejected, ScenarioCollector};
use risktwin_common::geometry::Pose;
use risktwin_common::telemetry::{Frame, Header, RoadMap, VehicleStateSample};
use risktwin_commonroad::twin::{footprint_of, road_from_lanelets};
use risktwin_commonroad::{ObstacleState, Scenario, Shape};
use risktwin_protos::recording::{MessageCursor, Recorder, RecordingError, UnfinishedRecording};
use risktwin_protos::{WireMessage, encode};
use risktwin_transport::keyexpr::{EdgeStream, edge_map, edge_stream};
use risktwin_transport::{SiteId, SourceId};
use std::io::{Read, Seek, Write};

/// The source that publishes the map.
pub const MAP_SOURCE: &str = "map";
/// Site used when the benchmark id is not a valid site id.
const FALLBACK_SITE: &str = "commonroad";

/// Why a scenario could not be written as, or rebuilt from, a recording.
#[derive(Debug, thiserror::Error)]
pub enum FleetRecordingError {
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("the lanelet network cannot be converted to twin lanes: {0}")]
    Map(#[from] risktwin_commonroad::twin::TwinError),
    #[error("obstacle id {id}: {reason}")]
    Obstacle { id: u64, reason: String },
    #[error(transparent)]
    Message(#[from] Rejected),
    #[error(transparent)]
    Rebuild(#[from] RebuildError),
}

/// What [`write_scenario`] wrote.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ImportSummary {
    pub site: String,
    pub dt_s: f64,
    pub lanelets: usize,
    pub dynamic_obstacles: usize,
    pub static_obstacles: usize,
    /// Messages written, the map included.
    pub messages: u64,
    /// Scenario time of the last message, s.
    pub duration_s: f64,
}

fn source(prefix: &str, id: u64) -> Result<SourceId, FleetRecordingError> {
    SourceId::new(format!("{prefix}-{id}")).map_err(|e| FleetRecordingError::Obstacle { id, reason: e.to_string() })
}

fn state_sample(source: &str, seq: u64, time_ns: i64, shape: &Shape, s: &ObstacleState) -> VehicleStateSample {
    let pose = Pose::new(s.position.x, s.position.y, s.orientation_rad);
    let speed_mps = s.velocity_mps.unwrap_or(0.0);
    VehicleStateSample {
        header: Header {
            source: source.to_string(),
            seq,
            capture_time_ns: time_ns,
            publish_time_ns: time_ns,
            frame: Frame::World,
        },
        pose,
        velocity: pose.forward() * speed_mps,
        speed_mps,
        accel_mps2: s.acceleration_mps2.unwrap_or(0.0),
        yaw_rate_radps: 0.0,
        steer_rad: 0.0,
        footprint: footprint_of(shape),
    }
}

/// Writes `scenario` into `w` as described in the module doc.
pub fn write_scenario<W: Write + Seek>(scenario: &Scenario, w: W) -> Result<ImportSummary, FleetRecordingError> {
    let site = SiteId::new(scenario.benchmark_id.clone())
        .or_else(|_| SiteId::new(FALLBACK_SITE))
        .expect("the fallback site id is valid");
    let dt_ns = (scenario.dt_s * 1e9).round() as i64;
    let mut rec = Recorder::new(w)?;
    let map_source = SourceId::new(MAP_SOURCE).expect("the map source id is valid");
    let map_topic = edge_map(&site, &map_source);
    let map_channel = rec.channel(&map_topic, RoadMap::PROTO_NAME)?;
    // Channels in file order: dynamic obstacles, then static ones.
    let mut tracks = Vec::new();
    for o in &scenario.dynamic_obstacles {
        let src = source("dyn", o.id)?;
        let channel = rec.channel(&edge_stream(&site, &src, EdgeStream::State), VehicleStateSample::PROTO_NAME)?;
        tracks.push((src, channel, &o.shape, o.states().collect::<Vec<_>>()));
    }
    for o in &scenario.static_obstacles {
        let src = source("static", o.id)?;
        let channel = rec.channel(&edge_stream(&site, &src, EdgeStream::State), VehicleStateSample::PROTO_NAME)?;
        tracks.push((src, channel, &o.shape, vec![&o.initial_state]));
    }
    let first_step = tracks.iter().filter_map(|t| t.3.first()).map(|s| s.time_step).min().unwrap_or(0);
    let last_step = tracks.iter().filter_map(|t| t.3.last()).map(|s| s.time_step).max().unwrap_or(0);
    let stamp = |step: i64| (step.max(0) * dt_ns) as u64;

    let (road, _) = road_from_lanelets(&scenario.lanelets)?;
    let map_header = Header {
        source: MAP_SOURCE.to_string(),
        seq: 0,
        capture_time_ns: stamp(first_step) as i64,
        publish_time_ns: stamp(first_step) as i64,
        frame: Frame::World,
    };
    let map = RoadMap { header: map_header, road, lanelets: scenario.lanelets.clone() };
    rec.write(map_channel, stamp(first_step), stamp(first_step), &encode(&map))?;
    let mut messages = 1;
    // Time-ordered, file order within a step: a cursor per track.
    let mut next = vec![0usize; tracks.len()];
    for step in first_step..=last_step {
        for (k, (src, channel, shape, states)) in tracks.iter().enumerate() {
            let Some(s) = states.get(next[k]).filter(|s| s.time_step == step) else { continue };
            let sample = state_sample(src.as_str(), next[k] as u64, stamp(step) as i64, shape, s);
            rec.write(*channel, stamp(step), stamp(step), &encode(&sample))?;
            next[k] += 1;
            messages += 1;
        }
    }
    rec.finish()?;
    Ok(ImportSummary {
        site: site.as_str().to_string(),
        dt_s: scenario.dt_s,
        lanelets: scenario.lanelets.len(),
        dynamic_obstacles: scenario.dynamic_obstacles.len(),
        static_obstacles: scenario.static_obstacles.len(),
        messages,
        duration_s: stamp(last_step) as f64 * 1e-9,
    })
}

/// Rebuilds the scenario from a recording written by [`write_scenario`], with the collector the
/// cloud's `criticality` role uses on the live stream ([`ScenarioCollector`]): every state and
/// map message decoded and validated as the ingest decodes them; here a message that fails is an
/// error. Topics outside the layout are skipped. An unfinished recording gives the scenario of
/// its readable messages, and what could not be read.
pub fn read_scenario<R: Read>(
    mut cursor: MessageCursor<R>,
) -> Result<(Scenario, Option<UnfinishedRecording>), FleetRecordingError> {
    let mut collector = ScenarioCollector::new();
    while let Some(m) = cursor.next_message() {
        let m = m?;
        collector.push(m.topic, m.data)?;
    }
    Ok((collector.finish()?, cursor.unfinished()))
}
