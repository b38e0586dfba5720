//! The driving environment for reinforcement learning over the twin (docs/method.md §7).
//!
//! - [`observe`]: the observation s_t (table of features and their normalisation) and the
//!   action mapping [steering, throttle, brake] → actuator commands.
//! - [`DrivingEnv`]: one scenario's world stepped by actions, the reward of paper eq. 7
//!   ([`crate::metrics::step_reward`], computed exactly as `episode::run` does), termination on
//!   collision or leaving the road, truncation at the horizon or the route end.
//! - [`VecEnv`]: many environments stepped in parallel into flat buffers with auto-reset.
//! - [`ScenarioSource`]: seeded sampled specs of the five kinds, or a supplied list.
//! - [`ObsPolicy`]: any observation → action function as a [`crate::driver::Policy`], so a
//!   learned policy is evaluated by `episode::run` with the same metrics as `simulate`.
//!
//! Variants (docs/method.md §7) differ only in their training reward ([`Variant::training_reward`]:
//! eq. 7's weights with the terminal penalties scaled down, the risk term shaped as
//! [`RiskShaping`] says, and for `ttc` a time-to-collision term instead of the risk field);
//! `full` additionally draws half its training episodes from the scenario library, which the
//! trainer supplies as a [`ScenarioSource::Replay`]. The observation is the same for every
//! variant, so policies stay comparable and only the training signal differs.

mod demo;
mod driving;
pub mod observe;
mod policy;
mod reward;
mod source;
mod vec_env;

pub use demo::{DemoPlan, Demonstrations, controls_to_action, demonstrate};
pub use driving::{DrivingEnv, EpisodeSummary, StepOutcome};
pub use observe::{ACT_DIM, OBS_DIM, OBSERVATION_VERSION, Observer, action_to_controls};
pub use policy::ObsPolicy;
pub use reward::{RiskShaping, SHAPING_GAMMA, TTC_FLOOR_S, TTC_THRESHOLD_S, TTC_WEIGHT, TrainingReward};
pub use source::{BENIGN_MIN_TTC_S, DEFAULT_REPLAY_SHARE, ScenarioSource, SourceError, benign_specs};
pub use vec_env::VecEnv;

use crate::metrics::RewardWeights;
use std::fmt;
use std::str::FromStr;

/// Factor on the collision and off-road penalties during training only.
///
/// With the eq. 7 defaults (w_c = 200, w_o = 100) one crash costs as much as thirteen
/// perfectly driven 15 s episodes (the dense terms earn at most 1 per second), so PPO trades
/// route completion for speed and collapses to crawling: measured at 200k steps, held-out
/// success 0.08 at 11 m/s with the defaults, 0.44 at 16 m/s with the penalties scaled by 0.1
/// (a crash then costs about one episode's earnings, still the dominant single event).
pub const TRAIN_PENALTY_SCALE: f64 = 0.1;

/// The ablation variants of docs/method.md §7.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Variant {
    /// No risk terms: w_r = 0.
    Base,
    /// Risk reward (default w_r), scenarios sampled without risk guidance.
    RiskOnly,
    /// Risk reward and risk-ranked library scenarios.
    Full,
    /// The literature's usual safety term instead of the risk field: base plus a penalty
    /// ln(TTC/4 s) per second while the time to collision with the car ahead is under 4 s
    /// (Zhu et al. 2020, "Safe, efficient, and comfortable velocity control based on
    /// reinforcement learning for autonomous driving", Transp. Res. C 117).
    Ttc,
}

impl Variant {
    pub const ALL: [Variant; 4] = [Variant::Base, Variant::RiskOnly, Variant::Full, Variant::Ttc];

    /// The eq. 7 weights of this variant: the documented defaults of [`RewardWeights`], with
    /// the risk weight zeroed for `base` and `ttc`.
    pub fn weights(self) -> RewardWeights {
        let w = RewardWeights::default();
        match self {
            Variant::Base | Variant::Ttc => RewardWeights { risk: 0.0, ..w },
            Variant::RiskOnly | Variant::Full => w,
        }
    }

    /// What the learners train with: [`Variant::weights`] with the terminal penalties scaled
    /// by [`TRAIN_PENALTY_SCALE`], the risk term entering as `risk` says, and `ttc`'s TTC term.
    /// Evaluation scores every variant with `full`'s [`Variant::weights`].
    pub fn training_reward(self, risk: RiskShaping) -> TrainingReward {
        let w = self.weights();
        let weights = RewardWeights {
            collision: w.collision * TRAIN_PENALTY_SCALE,
            offroad: w.offroad * TRAIN_PENALTY_SCALE,
            ..w
        };
        let ttc = if self == Variant::Ttc { TTC_WEIGHT } else { 0.0 };
        TrainingReward { weights, risk, ttc }
    }

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Base => "base",
            Variant::RiskOnly => "risk-only",
            Variant::Full => "full",
            Variant::Ttc => "ttc",
        }
    }
}

impl fmt::Display for Variant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown variant name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown variant '{0}' (expected one of base, risk-only, full, ttc)")]
pub struct UnknownVariant(pub String);

impl FromStr for Variant {
    type Err = UnknownVariant;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Variant::ALL.into_iter().find(|v| v.name() == s).ok_or_else(|| UnknownVariant(s.to_string()))
    }
}

#[cfg(test)]
mod reward_tests;
#[cfg(test)]
mod tests;
