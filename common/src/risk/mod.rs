//! The driving risk field (docs/method.md §4), criticality measures and the scenario risk score.
//!
//! - [`field`]: R(p, t) = α_o·R_o + α_l·R_l + α_b·R_b + α_c·R_c, exact at a point, over the ego
//!   footprint and along a trajectory.
//! - [`raster`] (with the Gaussian table of `kernel`): the same field on a grid, fast.
//! - [`criticality`]: HW, THW, TTC, a_long,req per vehicle pair along the ego's lane.
//! - [`score`]: S_risk, its normalised terms and the per-episode accumulator.
//! - [`heatmap`]: what a heatmap of the field shows (cells on the map, colour scale, road lines).
//! - [`bench`]: the reproducible workload of `risktwin bench risk-field`.

pub mod bench;
pub mod criticality;
pub mod field;
pub mod heatmap;
mod kernel;
pub mod raster;
pub mod score;

pub use bench::{BenchScene, bench_scene};
pub use criticality::{
    EgoLaneFrame, LaneState, PairMeasures, VehicleState, pair_measures, ttc_constant_accel_s, ttc_jansson_s,
};
pub use field::{EgoKinematics, FieldError, FieldObject, RiskFieldParams};
pub use heatmap::{HeatmapLayers, road_layers};
pub use kernel::GaussTable;
pub use raster::{GridEvaluator, RiskGrid, RoadRaster};
pub use score::{
    PairExtremes, RiskAccumulator, RiskStep, RiskSummary, RiskTerms, RiskWeights, ScoreError, ScoreReferences,
};
