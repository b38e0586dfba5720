//! What an edge role reports on exit.

use crate::delivery::DeliverySummary;
use serde::Serialize;
use std::collections::BTreeMap;

/// What an edge sent, per stream: printed as JSON on exit so that tests can check
/// sent = received + counted drops.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SentSummary {
    /// The edge's site.
    pub site: String,
    /// The edge's id.
    pub source: String,
    /// Messages sent per stream name.
    pub sent: BTreeMap<String, u64>,
    /// What became of it, when the edge watched the cloud's acknowledgements.
    #[serde(flatten)]
    pub delivery: Option<DeliverySummary>,
}

impl SentSummary {
    /// Why this run cannot count as a success, if it cannot: messages sent that no cloud
    /// accounted for, or messages refused as too large (docs/keyexpr.md, "Delivery
    /// acknowledgements").
    pub fn failure(&self) -> Option<String> {
        let d = self.delivery.as_ref()?;
        let per_stream = |counts: &BTreeMap<String, u64>| {
            let streams: Vec<String> =
                counts.iter().filter(|(_, n)| **n > 0).map(|(s, n)| format!("{s} {n}")).collect();
            streams.join(", ")
        };
        let sent: u64 = self.sent.values().sum();
        let undelivered = d.total_undelivered();
        let too_large: u64 = d.too_large.values().sum();
        let mut why = Vec::new();
        if undelivered > 0 {
            let cloud = if !d.cloud.seen {
                "no cloud seen (--no-ack publishes without one)".to_owned()
            } else if d.cloud.gone_s > 0.0 {
                let at_exit = if d.cloud.alive_at_exit { "" } else { ", and gone at the end" };
                format!("the cloud was gone for {:.1} s{at_exit}", d.cloud.gone_s)
            } else {
                "not acknowledged in time".to_owned()
            };
            why.push(format!("{undelivered} of {sent} messages undelivered ({}): {cloud}", per_stream(&d.undelivered)));
        }
        if too_large > 0 {
            why.push(format!("{too_large} messages refused as too large ({})", per_stream(&d.too_large)));
        }
        (!why.is_empty()).then(|| format!("edge {}: {}", self.source, why.join("; ")))
    }
}
