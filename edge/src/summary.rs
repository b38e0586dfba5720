//! What an edge role reports on exit: plain data, built by the roles and exported by their
//! metrics.

use risktwin_protos::recording::UnfinishedRecording;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

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
    /// All undelivered messages.
    pub fn total_undelivered(&self) -> u64 {
        self.undelivered.values().sum()
    }

    /// All messages the cloud counts lost.
    pub fn total_lost(&self) -> u64 {
        self.lost.values().sum()
    }

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

/// A period when no cloud's liveliness token was seen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CloudGone {
    /// Seconds after the watch started (the edge's start) that the cloud went.
    pub at_s: f64,
    /// Seconds it stayed gone (until it came back, or the edge ended).
    pub for_s: f64,
}

/// What the edge says of the cloud in its summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CloudSeen {
    /// Whether a cloud's token or an acknowledgement was ever seen.
    pub seen: bool,
    /// Whether a cloud's token was there when the edge ended.
    pub alive_at_exit: bool,
    /// How many cloud sessions acknowledged this edge (two after a cloud restart).
    pub acknowledged_by: usize,
    /// The periods it was gone after it was first seen (at most 32 listed).
    pub gone: Vec<CloudGone>,
    /// All of them, seconds.
    pub gone_s: f64,
}

/// Per stream, what became of what the edge sent (flattened into the edge's summary).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DeliverySummary {
    /// Received by a cloud, per stream.
    pub acknowledged: BTreeMap<String, u64>,
    /// Counted lost by the cloud, per stream.
    pub lost: BTreeMap<String, u64>,
    /// Never accounted for by a cloud, per stream.
    pub undelivered: BTreeMap<String, u64>,
    /// Refused by the edge as larger than an edge stream may be, per stream (never sent).
    pub too_large: BTreeMap<String, u64>,
    pub cloud: CloudSeen,
}

/// What a replay published, per key, and what it skipped (topics that are neither an edge stream
/// nor a road map of the scheme).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ReplaySummary {
    pub published: u64,
    pub skipped: u64,
    pub by_key: BTreeMap<String, u64>,
    /// From the first message to the last one handed to Zenoh.
    pub elapsed_s: f64,
    /// Published messages per second over `elapsed_s`.
    pub msgs_per_s: f64,
    /// Edge-stream messages whose header could not be read (published, their delivery not
    /// tracked: the cloud drops them as malformed, counted).
    pub unnumbered: u64,
    /// What became of each replayed source's messages (`site/source`), when watched.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub delivery: BTreeMap<String, DeliverySummary>,
    /// What could not be read of each unfinished file (a recorder killed): the caller warns.
    #[serde(skip)]
    pub unfinished: Vec<(PathBuf, UnfinishedRecording)>,
}

impl ReplaySummary {
    /// Why this replay cannot count as a success, if it cannot: a source's messages that no
    /// cloud accounted for (see [`DeliverySummary::failure`]).
    pub fn failure(&self) -> Option<String> {
        let why: Vec<String> = self
            .delivery
            .iter()
            .filter_map(|(source, d)| {
                let sent = d.acknowledged.values().chain(d.lost.values()).chain(d.undelivered.values()).sum();
                d.failure(source, sent)
            })
            .collect();
        (!why.is_empty()).then(|| why.join("; "))
    }
}
