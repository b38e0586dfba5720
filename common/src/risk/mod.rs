//! The driving risk field (mission.md §3), criticality measures and the scenario risk score.

mod score;

pub use score::RiskTerms;
