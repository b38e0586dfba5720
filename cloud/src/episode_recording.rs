//! Recording an embedded episode as MCAP: every vehicle's state on its own topic, the scene as
//! Foxglove boxes, and the risk field around the ego as a Foxglove grid at 2 Hz — the same
//! topics the distributed pipeline records, so Foxglove layouts work for both.

use risktwin_common::risk::{
    EgoKinematics, FieldError, FieldObject, GridEvaluator, RiskFieldParams, RiskGrid, RoadRaster,
};
use risktwin_common::telemetry::{Frame, Header, RiskField, VehicleStateSample};
use risktwin_common::world::World;
use risktwin_protos::recording::{Recorder, RecordingError};
use std::io::{Seek, Write};

/// Risk-field grid side (cells) and resolution (m) in recordings: 80 m around the ego.
const GRID_CELLS: usize = 160;
const GRID_RESOLUTION_M: f64 = 0.5;
/// Steps between two recorded risk grids (2 Hz at the twin's 20 Hz).
const GRID_EVERY_STEPS: u64 = 10;

/// Why an episode could not be recorded.
#[derive(Debug, thiserror::Error)]
pub enum EpisodeRecordingError {
    #[error(transparent)]
    Recording(#[from] RecordingError),
    #[error("risk field: {0}")]
    Field(#[from] FieldError),
}

/// Topic of one source's state stream in an embedded recording.
pub fn state_topic(source: &str) -> String {
    format!("/twin/{source}/state")
}

/// Records a [`World`] step by step.
pub struct EpisodeRecorder<W: Write + Seek> {
    recorder: Recorder<W>,
    raster: RoadRaster,
    evaluator: GridEvaluator,
    grid: RiskGrid,
    samples: Vec<VehicleStateSample>,
    objects: Vec<FieldObject>,
    steps: u64,
}

impl<W: Write + Seek> EpisodeRecorder<W> {
    /// A recorder for episodes on `world`'s road.
    pub fn new(w: W, world: &World) -> Result<Self, EpisodeRecordingError> {
        let params = RiskFieldParams::default();
        let half_m = 0.5 * GRID_RESOLUTION_M * GRID_CELLS as f64;
        let raster = RoadRaster::new(&world.road, &params, GRID_RESOLUTION_M, half_m + 10.0)?;
        let grid = RiskGrid::new(raster.grid().origin_m, GRID_RESOLUTION_M, GRID_CELLS, GRID_CELLS)?;
        Ok(Self {
            recorder: Recorder::new(w)?,
            raster,
            evaluator: GridEvaluator::new(params),
            grid,
            samples: Vec::new(),
            objects: Vec::new(),
            steps: 0,
        })
    }

    /// Records the world as it is now.
    pub fn record(&mut self, world: &World) -> Result<(), EpisodeRecordingError> {
        let time_ns = (world.time_s * 1e9).round().max(0.0) as u64;
        world.state_samples(self.steps, &mut self.samples);
        for s in &self.samples {
            self.recorder.record(&state_topic(&s.header.source), time_ns, s)?;
        }
        self.recorder.record_scene("/twin/scene", time_ns, &self.samples)?;
        if self.steps.is_multiple_of(GRID_EVERY_STEPS) {
            self.record_grid(world, time_ns)?;
        }
        self.steps += 1;
        Ok(())
    }

    fn record_grid(&mut self, world: &World, time_ns: u64) -> Result<(), EpisodeRecordingError> {
        let ego = EgoKinematics {
            pose: world.ego.pose(),
            velocity: world.ego.velocity(),
            lateral_accel_mps2: world.ego.lateral_accel_mps2(),
            jerk_mps3: 0.0,
            footprint: world.ego.params.footprint(),
        };
        self.objects.clear();
        self.objects.extend(self.samples.iter().skip(1).map(|s| FieldObject {
            obb: risktwin_common::geometry::Obb::new(s.pose, s.footprint),
            velocity: s.velocity,
        }));
        let half_m = 0.5 * GRID_RESOLUTION_M * GRID_CELLS as f64;
        let centre = ego.pose.position();
        self.grid.origin_m = self.raster.snap_origin(centre - risktwin_common::geometry::Vec2::new(half_m, half_m));
        self.evaluator.fill(&mut self.grid, &self.raster, &world.road, &self.objects, &ego);
        let header = Header {
            source: "ego".into(),
            seq: self.steps,
            capture_time_ns: time_ns as i64,
            publish_time_ns: time_ns as i64,
            frame: Frame::World,
        };
        let field = RiskField { header, grid: self.grid.clone() };
        self.recorder.record_risk_grid("/twin/risk_field", time_ns, &field)?;
        Ok(())
    }

    /// Completes the file (summary and footer).
    pub fn finish(self) -> Result<(), EpisodeRecordingError> {
        self.recorder.finish()?;
        Ok(())
    }
}
