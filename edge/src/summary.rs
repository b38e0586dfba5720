//! What an edge role reports on exit.

use serde::Serialize;
use std::collections::BTreeMap;

/// What an edge sent, per stream: printed as JSON on exit so that tests can check
/// sent = received + counted drops.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SentSummary {
    /// The edge's site.
    pub site: String,
    /// The edge's id.
    pub source: String,
    /// Messages sent per stream name.
    pub sent: BTreeMap<String, u64>,
}
