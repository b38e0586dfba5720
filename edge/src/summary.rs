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
    /// Messages held back per stream name because the cloud shed the stream (overloaded; never
    /// numbered, never sent; streams with none left out).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub shed: BTreeMap<String, u64>,
    /// What became of it, when the edge watched the cloud's acknowledgements.
    #[serde(flatten)]
    pub delivery: Option<DeliverySummary>,
}

impl SentSummary {
    /// Why this run cannot count as a success, if it cannot: messages sent that no cloud
    /// accounted for, or messages refused as too large (docs/keyexpr.md, "Delivery
    /// acknowledgements").
    pub fn failure(&self) -> Option<String> {
        self.delivery.as_ref()?.failure(&self.source, self.sent.values().sum())
    }
}

impl DeliverySummary {
    /// Why an edge (`source`, which sent `sent` messages) cannot count its run a success, if it
    /// cannot: messages sent that no cloud accounted for, or messages refused as too large.
    pub fn failure(&self, source: &str, sent: u64) -> Option<String> {
        let per_stream = |counts: &BTreeMap<String, u64>| {
            let streams: Vec<String> =
                counts.iter().filter(|(_, n)| **n > 0).map(|(s, n)| format!("{s} {n}")).collect();
            streams.join(", ")
        };
        let undelivered = self.total_undelivered();
        let too_large: u64 = self.too_large.values().sum();
        let mut why = Vec::new();
        if undelivered > 0 {
            let cloud = if !self.cloud.seen {
                "no cloud seen (--no-ack publishes without one)".to_owned()
            } else if self.cloud.gone_s > 0.0 {
                let at_exit = if self.cloud.alive_at_exit { "" } else { ", and gone at the end" };
                format!("the cloud was gone for {:.1} s{at_exit}", self.cloud.gone_s)
            } else {
                "not acknowledged in time".to_owned()
            };
            why.push(format!(
                "{undelivered} of {sent} messages undelivered ({}): {cloud}",
                per_stream(&self.undelivered)
            ));
        }
        if too_large > 0 {
            why.push(format!("{too_large} messages refused as too large ({})", per_stream(&self.too_large)));
        }
        (!why.is_empty()).then(|| format!("edge {source}: {}", why.join("; ")))
    }
}
