//! PPO-Lagrangian (Ray, Achiam & Amodei 2019, "Benchmarking Safe Exploration in Deep
//! Reinforcement Learning", the Safety Gym baseline; OmniSafe's `PPOLag`): a constraint on the
//! share of training episodes that end in a collision or off the road, held by a Lagrange
//! multiplier λ that grows while the share is above its limit and shrinks while below. The
//! policy ascends (Â_r − λ·Â_c)/(1 + λ), Â_c the standardised advantage of a second critic's
//! estimate of the discounted cost (1 at the step that ends an episode by a collision or a
//! road exit, 0 elsewhere); the reward is left as it is. Feed-forward PPO only.
//!
//! Unlike a penalty weight, λ is not tuned: the constraint's limit is the knob, and λ is what
//! it costs in return to hold it.

use crate::LearnError;
use crate::host::{HostMlp, Scratch, snapshot};
use crate::nn::Mlp;
use risktwin_common::env::OBS_DIM;
use risktwin_common::rng::Rng;

/// λ's step per rollout per unit by which the failure share exceeds its limit (gradient
/// ascent on the dual; Safety Gym's `penalty_lr` is 0.05 for its cost scale). At a share 0.25
/// above the limit λ reaches 1, equal weight to reward and cost, after 40 rollouts: 81,920
/// steps of `risktwin run`'s 589,824 (rollouts of 64 steps × 32 environments).
pub const LAMBDA_LR: f64 = 0.1;

/// The constraint: which share of training episodes may fail.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CostConstraint {
    /// Training episodes that may end in a collision or off the road, as a share of those
    /// finished, in [0, 1].
    pub limit: f64,
    /// λ's step per rollout per unit of excess share.
    pub lambda_lr: f64,
}

impl CostConstraint {
    /// A constraint with limit `limit` and the default step [`LAMBDA_LR`].
    pub fn new(limit: f64) -> Self {
        Self { limit, lambda_lr: LAMBDA_LR }
    }

    /// Refuses a limit outside [0, 1] or a step that is not a positive finite number.
    pub fn validate(&self) -> Result<(), String> {
        if !(0.0..=1.0).contains(&self.limit) {
            return Err(format!("cost_limit {} is out of range [0, 1]", self.limit));
        }
        if !(self.lambda_lr.is_finite() && self.lambda_lr > 0.0) {
            return Err(format!("the multiplier's step {} must be a positive number", self.lambda_lr));
        }
        Ok(())
    }
}

/// The cost side of a PPO learner: the cost critic, its rollout buffers and λ.
pub(crate) struct CostSide {
    pub constraint: CostConstraint,
    pub lambda: f64,
    pub critic: Mlp,
    host: HostMlp,
    /// Per rollout row `[t · n_envs + i]`: cost, V_c, advantage, return.
    pub costs: Vec<f32>,
    pub values: Vec<f32>,
    pub advantages: Vec<f32>,
    pub returns: Vec<f32>,
    /// V_c(s_T) after the rollout, per environment.
    pub last_value: Vec<f32>,
    /// Episodes finished and failed in the current rollout.
    episodes: u64,
    failures: u64,
}

impl CostSide {
    /// A cost critic of the reward critic's shape (`sizes`) for rollouts of `rows` rows.
    pub fn new(
        constraint: CostConstraint,
        sizes: &[usize],
        rows: usize,
        n_envs: usize,
        rng: &mut Rng,
    ) -> Result<Self, LearnError> {
        constraint.validate().map_err(LearnError::BadConfig)?;
        let critic = Mlp::new("cost_critic", sizes, 1.0, rng)?;
        Ok(Self {
            constraint,
            lambda: 0.0,
            host: snapshot(&critic)?,
            critic,
            costs: vec![0.0; rows],
            values: vec![0.0; rows],
            advantages: vec![0.0; rows],
            returns: vec![0.0; rows],
            last_value: vec![0.0; n_envs],
            episodes: 0,
            failures: 0,
        })
    }

    /// V_c of one observation.
    pub fn value(&self, obs: &[f32], scratch: &mut Scratch) -> f32 {
        debug_assert_eq!(obs.len(), OBS_DIM);
        let mut v = 0.0f32;
        self.host.forward(obs, scratch, std::slice::from_mut(&mut v));
        v
    }

    /// Records row `k`'s step: its cost (1 if it `failed`), and, if the episode was cut
    /// (`truncated`), γ·V_c of its final observation folded in as the reward's bootstrap is.
    pub fn record(&mut self, k: usize, failed: bool, done: bool, cut_bootstrap: Option<f32>) {
        self.costs[k] = f32::from(u8::from(failed)) + cut_bootstrap.unwrap_or(0.0);
        self.episodes += u64::from(done);
        self.failures += u64::from(failed);
    }

    /// The dual step after a rollout: λ ← max(0, λ + lr·(share − limit)) on the share of the
    /// rollout's finished episodes that failed (no step when none finished). Returns the share.
    pub fn update_lambda(&mut self) -> Option<f64> {
        let (episodes, failures) = (std::mem::take(&mut self.episodes), std::mem::take(&mut self.failures));
        if episodes == 0 {
            return None;
        }
        let share = failures as f64 / episodes as f64;
        self.lambda = (self.lambda + self.constraint.lambda_lr * (share - self.constraint.limit)).max(0.0);
        Some(share)
    }

    /// Copies the cost critic's weights into the host copy used while acting.
    pub fn refresh_host(&mut self) -> Result<(), LearnError> {
        self.host = snapshot(&self.critic)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambda_rises_above_the_limit_falls_below_it_and_stays_non_negative() {
        let mut rng = Rng::new(1);
        let mut side = CostSide::new(CostConstraint::new(0.1), &[OBS_DIM, 4, 1], 8, 2, &mut rng).unwrap();
        for k in 0..4 {
            side.record(k, k < 2, true, None);
        }
        assert_eq!(side.update_lambda(), Some(0.5));
        assert!((side.lambda - 0.04).abs() < 1e-12, "{}", side.lambda);
        assert_eq!(side.update_lambda(), None, "no episode finished: λ stays");
        assert!((side.lambda - 0.04).abs() < 1e-12);
        for k in 0..4 {
            side.record(k, false, true, None);
        }
        side.update_lambda();
        assert!((side.lambda - 0.03).abs() < 1e-12, "{}", side.lambda);
        for _ in 0..10 {
            side.record(0, false, true, None);
            side.update_lambda();
        }
        assert_eq!(side.lambda, 0.0);
    }

    #[test]
    fn limits_outside_a_share_are_refused() {
        for bad in [-0.1, 1.5, f64::NAN] {
            assert!(CostConstraint::new(bad).validate().is_err(), "{bad}");
        }
        assert!(CostConstraint { limit: 0.1, lambda_lr: 0.0 }.validate().is_err());
        assert!(CostConstraint::new(0.0).validate().is_ok());
    }
}
