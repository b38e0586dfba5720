//! A CommonRoad scenario inside the twin: the lanelet map as a [`risktwin_common::road::Road`], the
//! recorded obstacles as kinematic playback, the ego replayed or driven closed-loop, and the
//! risk field over the real map.
//!
//! - [`road_from_lanelets`]: one twin lane per lanelet (its centreline, its mean width, its
//!   same-direction neighbours), so the lane and boundary terms of the risk field and the
//!   reference driver work on real maps.
//! - [`Playback`]: an obstacle's recorded states at any time, interpolated between the
//!   scenario's steps (linear in position, speed and acceleration; shortest-arc in heading).
//! - [`resimulate`]: the scenario re-run at the twin's step with the ego replayed or driven by
//!   the reference driver from its recorded initial state; episode metrics and S_risk. Its
//!   [`ResimStepper`] takes the ego's controls one step at a time, so a scene's authority
//!   (edge::fleet) runs the same episode with the driver in another process.
//! - [`field_at`]: the risk field around the ego at one moment, and [`lanelet_layers`] what a
//!   heatmap of it shows over the real lanelet bounds.

mod ego;
mod heatmap;
mod playback;
mod resim;
mod road;
mod scene;
mod snapshot;
mod stepper;
#[cfg(test)]
mod tests;

pub use ego::{RECORDING_SEED, ego_sensor};
pub use heatmap::lanelet_layers;
pub use playback::{Playback, PlaybackState, footprint_of, kind_of};
pub use resim::{resimulate, resimulate_driven};
pub use road::road_from_lanelets;
pub use scene::TwinScene;
pub use snapshot::{CommonRoadField, field_at};
pub use stepper::{EgoMode, ResimSample, ResimStepper, Resimulation};

/// What keeps a scenario from being put into the twin.
#[derive(Debug, thiserror::Error)]
pub enum TwinError {
    #[error("ego id {ego_id} is not a dynamic obstacle of the scenario (dynamic obstacles: {available})")]
    UnknownEgo { ego_id: u64, available: String },
    #[error("the scenario has no dynamic obstacle to take as the ego")]
    NoEgo,
    #[error("the lanelet network has no lanelet with a usable centreline (at least two distinct points)")]
    NoLanes,
    #[error("time {time_s} s is outside the ego's recording [{start_s}, {end_s}] s")]
    TimeOutOfRange { time_s: f64, start_s: f64, end_s: f64 },
    #[error("step {step_s} s is not a positive finite duration")]
    BadStep { step_s: f64 },
    #[error("risk field: {0}")]
    Field(#[from] risktwin_common::risk::FieldError),
}

/// The ego obstacle by id, or the scenario's default ego.
pub(crate) fn ego_of(scenario: &super::Scenario, ego_id: Option<u64>) -> Result<&super::DynamicObstacle, TwinError> {
    let id = match ego_id {
        Some(id) => id,
        None => scenario.default_ego_id().ok_or(TwinError::NoEgo)?,
    };
    scenario.dynamic_obstacle(id).ok_or_else(|| {
        let ids: Vec<String> = scenario.dynamic_obstacles.iter().map(|o| o.id.to_string()).collect();
        let available = if ids.is_empty() { "none".to_string() } else { ids.join(", ") };
        TwinError::UnknownEgo { ego_id: id, available }
    })
}
