//! Episode metrics (paper table 1) and the reward.

use serde::{Deserialize, Serialize};

/// What one episode measured; field names and units follow cli.md (`simulate`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EpisodeMetrics {
    pub collision: bool,
    pub offroad: bool,
    pub success: bool,
    pub route_completion: f64,
    pub avg_speed_mps: f64,
    pub steering_smoothness: f64,
    pub longitudinal_smoothness: f64,
    /// `None` when no vehicle pair ever closed in.
    pub min_ttc_s: Option<f64>,
    pub min_distance_m: f64,
    pub risk_score: f64,
    pub reward: f64,
    pub steps: u64,
}
