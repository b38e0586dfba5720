//! The training reward: eq. 7's weights, how its risk term is shaped, and the TTC term of the
//! `ttc` baseline (docs/method.md §7, "Risk shaping"). Evaluation never uses this: every
//! variant is scored with the same eq. 7 weights.

use crate::metrics::RewardWeights;
use serde::{Deserialize, Serialize};

/// The discount of the potential difference, equal to the learners' (PPO's and SAC's default
/// γ, checked by a test in `risktwin-learn`): shaping with another γ than the learner's is
/// no longer policy-invariant.
pub const SHAPING_GAMMA: f64 = 0.99;

/// Below this time to collision the `ttc` baseline's term is negative, s (Zhu et al. 2020).
pub const TTC_THRESHOLD_S: f64 = 4.0;
/// Time to collision at which the TTC term stops growing, s (ln(0.1/4) ≈ −3.7): a contact's
/// TTC of 0 would otherwise be −∞.
pub const TTC_FLOOR_S: f64 = 0.1;
/// Weight of the TTC term per second: the risk weight's default, so the baseline's penalty is
/// as large as the risk field's (−0.69 per second at a TTC of 1 s).
pub const TTC_WEIGHT: f64 = 0.5;

/// How the risk term R̄ (risk at the ego footprint) enters the training reward.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RiskShaping {
    /// −w_r·R̄_t per second of driving (paper eq. 7). Near traffic the step reward can stay
    /// negative for seconds, so ending the episode early can pay.
    PerStep,
    /// A potential difference γ·Φ(s′) − Φ(s) with Φ(s) = −k·w_r·R̄(s) (Ng, Harada & Russell
    /// 1999): it cannot change which policy is optimal, only how fast the learner finds it, and
    /// it cannot make an early ending pay. The terminal state keeps its potential (no bonus for
    /// crashing out of a risky state).
    Potential {
        /// k: the potential's scale.
        scale: f64,
    },
}

impl Default for RiskShaping {
    /// The paper's per-step term: potential shaping did not lower the collision rate on both
    /// run seeds (docs/results.md, "What was tried", 6), so the default stays eq. 7.
    fn default() -> Self {
        RiskShaping::PerStep
    }
}

impl RiskShaping {
    /// Refuses a scale that is not a finite positive number.
    pub fn validate(&self) -> Result<(), String> {
        match *self {
            RiskShaping::PerStep => Ok(()),
            RiskShaping::Potential { scale } if scale.is_finite() && scale > 0.0 && scale <= 100.0 => Ok(()),
            RiskShaping::Potential { scale } => Err(format!("risk potential scale {scale} is out of range (0, 100]")),
        }
    }
}

/// What a training environment rewards.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainingReward {
    /// Eq. 7's weights (terminal penalties already scaled for training where the caller wants).
    pub weights: RewardWeights,
    /// How `weights.risk` enters.
    pub risk: RiskShaping,
    /// Weight per second of the TTC term w·ln(TTC/4 s) below 4 s; 0 for none.
    pub ttc: f64,
}

impl TrainingReward {
    /// Eq. 7 as written: the risk term per step, no TTC term (what evaluation computes).
    pub fn eq7(weights: RewardWeights) -> Self {
        Self { weights, risk: RiskShaping::PerStep, ttc: 0.0 }
    }

    /// The weights [`crate::metrics::step_reward`] is called with: the risk weight moves into
    /// the potential when shaped that way.
    pub fn step_weights(&self) -> RewardWeights {
        match self.risk {
            RiskShaping::PerStep => self.weights,
            RiskShaping::Potential { .. } => RewardWeights { risk: 0.0, ..self.weights },
        }
    }

    /// Whether the risk field must be evaluated at all.
    pub fn needs_risk(&self) -> bool {
        self.weights.risk != 0.0
    }

    /// Whether the risk of the state before a step enters the reward (the potential form).
    pub fn needs_risk_before(&self) -> bool {
        self.needs_risk() && matches!(self.risk, RiskShaping::Potential { .. })
    }

    /// The shaping term of a step from a state of risk `risk_before` to one of `risk_after`:
    /// γ·Φ(s′) − Φ(s) = k·w_r·(R̄(s) − γ·R̄(s′)); 0 when the risk is per step.
    pub fn potential_term(&self, risk_before: f64, risk_after: f64) -> f64 {
        match self.risk {
            RiskShaping::PerStep => 0.0,
            RiskShaping::Potential { scale } => scale * self.weights.risk * (risk_before - SHAPING_GAMMA * risk_after),
        }
    }

    /// The TTC term of a step of `dt_s` at time to collision `ttc_s` (∞ when not closing):
    /// w·ln(TTC/4 s)·dt below 4 s, the TTC floored at [`TTC_FLOOR_S`].
    pub fn ttc_term(&self, ttc_s: f64, dt_s: f64) -> f64 {
        if self.ttc == 0.0 || ttc_s.is_nan() || ttc_s >= TTC_THRESHOLD_S {
            return 0.0;
        }
        self.ttc * (ttc_s.max(TTC_FLOOR_S) / TTC_THRESHOLD_S).ln() * dt_s
    }
}
