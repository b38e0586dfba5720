//! A learned policy (any observation → action function) as a [`Policy`] of the twin.

use super::observe::{ACT_DIM, OBS_DIM, Observer, action_to_controls};
use crate::driver::{DriverView, Policy};
use crate::vehicle::Controls;

/// Drives the ego with `act(s_t) → a_t`, observing exactly as the training environment does.
pub struct ObsPolicy<F: FnMut(&[f32; OBS_DIM]) -> [f32; ACT_DIM]> {
    act: F,
    observer: Observer,
    desired_speed_mps: f64,
    dt_s: f64,
    obs: [f32; OBS_DIM],
}

impl<F: FnMut(&[f32; OBS_DIM]) -> [f32; ACT_DIM]> ObsPolicy<F> {
    /// A policy for a world with this desired speed and step (`world.desired_speed_mps`,
    /// `world.dt_s`).
    pub fn new(act: F, desired_speed_mps: f64, dt_s: f64) -> Self {
        Self { act, observer: Observer::default(), desired_speed_mps, dt_s, obs: [0.0; OBS_DIM] }
    }
}

impl<F: FnMut(&[f32; OBS_DIM]) -> [f32; ACT_DIM]> Policy for ObsPolicy<F> {
    fn act(&mut self, view: &DriverView) -> Controls {
        self.observer.observe(view, self.desired_speed_mps, self.dt_s, &mut self.obs);
        action_to_controls(&(self.act)(&self.obs))
    }
}
