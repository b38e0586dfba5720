//! The scalar scenario risk score S_risk and its five normalised terms.

use serde::{Deserialize, Serialize};

/// S_risk and its terms, each in [0, 1]; `score` is their weighted sum.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RiskTerms {
    pub score: f64,
    pub ttc: f64,
    pub dist: f64,
    pub lane: f64,
    pub jerk: f64,
    pub collision: f64,
}
