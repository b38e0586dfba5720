//! Samples lost for good between an edge and the ingest: what the edge-stream subscriber could
//! neither receive nor recover from the publisher's cache (`risktwin_transport::StreamLoss`),
//! counted per source and stream so that no loss is silent.

use risktwin_transport::StreamLoss;
use risktwin_transport::keyexpr::{parse_edge_key, parse_edge_map_key};
use std::collections::BTreeMap;

/// The source (and stream) a loss is counted under when its key is not an edge stream, or
/// unknown; not a valid source id, so it never mixes with an edge's count.
pub const UNKNOWN: &str = "(unknown)";

/// The stream name a road map's losses are counted under.
const MAP: &str = "map";

/// Lost samples per source, per stream.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LossCounts {
    by_source: BTreeMap<String, BTreeMap<String, u64>>,
    total: u64,
}

impl LossCounts {
    /// Counts `loss` under its edge stream's source and stream (a road map under its source and
    /// `map`); a publisher of another key under `(unknown)` and its key; one whose key was
    /// forgotten under `(unknown)` twice.
    pub fn record(&mut self, loss: &StreamLoss) {
        let (source, stream) = match loss.key.as_deref() {
            Some(key) => match (parse_edge_key(key), parse_edge_map_key(key)) {
                (Some(parsed), _) => (parsed.source, parsed.stream.as_str()),
                (None, Some((_, source))) => (source, MAP),
                (None, None) => (UNKNOWN, key),
            },
            None => (UNKNOWN, UNKNOWN),
        };
        let samples = u64::from(loss.samples);
        *self.by_source.entry(source.to_owned()).or_default().entry(stream.to_owned()).or_default() += samples;
        self.total += samples;
        tracing::warn!("ingest: {samples} samples of {source}/{stream} lost (not recoverable from its cache)");
    }

    /// Lost samples per source, per stream.
    pub fn by_source(&self) -> &BTreeMap<String, BTreeMap<String, u64>> {
        &self.by_source
    }

    /// All lost samples.
    pub fn total(&self) -> u64 {
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn losses_are_counted_by_source_and_stream_and_never_dropped() {
        let mut counts = LossCounts::default();
        let loss = |key: Option<&str>, samples| StreamLoss { key: key.map(str::to_owned), samples };
        counts.record(&loss(Some("risktwin/v1/track/veh-1/can"), 3));
        counts.record(&loss(Some("risktwin/v1/track/veh-1/can"), 2));
        counts.record(&loss(Some("risktwin/v1/track/veh-1/state"), 1));
        counts.record(&loss(Some("risktwin/v1/track/veh-1/map"), 4));
        counts.record(&loss(Some("risktwin/v1/track/veh-1/other"), 6));
        counts.record(&loss(None, u32::MAX));
        let by = counts.by_source();
        assert_eq!(by["veh-1"]["can"], 5);
        assert_eq!(by["veh-1"]["state"], 1);
        assert_eq!(by["veh-1"]["map"], 4);
        assert_eq!(by[UNKNOWN]["risktwin/v1/track/veh-1/other"], 6);
        assert_eq!(by[UNKNOWN][UNKNOWN], u64::from(u32::MAX));
        assert_eq!(counts.total(), 16 + u64::from(u32::MAX));
    }
}
