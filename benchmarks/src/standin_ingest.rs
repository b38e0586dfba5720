//! The stand-in ingest of `bench zenoh`: every [`StandIn`](crate::standin::StandIn) sample is
//! either counted as received (per source and stream) or dropped with a named reason, with no
//! protobuf decoding or alignment, so that the figure stays comparable with raw Zenoh. The
//! cloud's real ingest is `risktwin_cloud::ingest::IngestWorker`.
//!
//! Sequence policy: per source and stream, a sequence number at or above the next expected one
//! is accepted (a jump is counted as a gap); one below it is a duplicate or a late reordering
//! and is dropped as `stale-seq`. Codes are the cloud's [`DropReason`] codes where they mean
//! the same.

use crate::standin::{self, StandInError};
use risktwin_align::DropReason;
use risktwin_transport::EdgeStream;
use risktwin_transport::keyexpr::parse_edge_key;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::time::Instant;

const STREAMS: usize = EdgeStream::ALL.len();

/// Why the stand-in ingest dropped a sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StandInDrop {
    /// The key does not parse as an edge stream of the scheme.
    BadKey,
    /// The payload did not decode.
    Payload(StandInError),
    /// The payload names another source than its key.
    SourceMismatch,
    /// The sequence number was already passed (duplicate or reordered).
    StaleSeq,
}

impl StandInDrop {
    /// A short, stable name for the summary.
    pub const fn name(&self) -> &'static str {
        match self {
            StandInDrop::BadKey => DropReason::BadKey.code(),
            StandInDrop::Payload(e) => e.reason(),
            StandInDrop::SourceMismatch => DropReason::SourceMismatch.code(),
            StandInDrop::StaleSeq => "stale-seq",
        }
    }
}

#[derive(Debug, Clone, Default)]
struct SourceCounters {
    received: [u64; STREAMS],
    next_seq: [u64; STREAMS],
    gaps: [u64; STREAMS],
}

/// Counters of the stand-in ingest.
#[derive(Debug, Default)]
pub struct StandInCounters {
    sources: HashMap<String, SourceCounters>,
    dropped: BTreeMap<&'static str, u64>,
    last_sample: Option<Instant>,
}

/// What the stand-in ingest saw.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Default)]
pub struct StandInSummary {
    /// Accepted messages per source, per stream (streams with none are left out).
    pub received: BTreeMap<String, BTreeMap<String, u64>>,
    /// Sequence numbers skipped per source, per stream (only non-zero entries).
    pub gaps: BTreeMap<String, BTreeMap<String, u64>>,
    /// Dropped messages per reason.
    pub dropped: BTreeMap<String, u64>,
    /// All accepted messages.
    pub total_received: u64,
    /// All dropped messages.
    pub total_dropped: u64,
}

impl StandInCounters {
    /// Accounts for one sample received on `key` at `now`; `Err` says why it was dropped (it
    /// has been counted either way).
    pub fn accept(&mut self, key: &str, payload: &[u8], now: Instant) -> Result<(), StandInDrop> {
        self.last_sample = Some(now);
        let result = self.check(key, payload);
        if let Err(reason) = &result {
            *self.dropped.entry(reason.name()).or_insert(0) += 1;
        }
        result
    }

    fn check(&mut self, key: &str, payload: &[u8]) -> Result<(), StandInDrop> {
        let parsed = parse_edge_key(key).ok_or(StandInDrop::BadKey)?;
        let record = standin::decode(payload).map_err(StandInDrop::Payload)?;
        if record.source != parsed.source {
            return Err(StandInDrop::SourceMismatch);
        }
        // Look up by &str first so that a known source costs no allocation.
        let counters = match self.sources.get_mut(parsed.source) {
            Some(c) => c,
            None => self.sources.entry(parsed.source.to_owned()).or_default(),
        };
        let i = parsed.stream.index();
        if record.seq < counters.next_seq[i] {
            return Err(StandInDrop::StaleSeq);
        }
        counters.gaps[i] += record.seq - counters.next_seq[i];
        counters.next_seq[i] = record.seq + 1;
        counters.received[i] += 1;
        Ok(())
    }

    /// When the last sample (accepted or not) arrived.
    pub fn last_sample(&self) -> Option<Instant> {
        self.last_sample
    }

    /// The counts so far.
    pub fn summary(&self) -> StandInSummary {
        let per_stream = |counts: &[u64; STREAMS]| -> BTreeMap<String, u64> {
            EdgeStream::ALL
                .iter()
                .zip(counts)
                .filter(|(_, n)| **n > 0)
                .map(|(s, n)| (s.as_str().to_owned(), *n))
                .collect()
        };
        let mut summary = StandInSummary::default();
        for (source, c) in &self.sources {
            summary.received.insert(source.clone(), per_stream(&c.received));
            let gaps = per_stream(&c.gaps);
            if !gaps.is_empty() {
                summary.gaps.insert(source.clone(), gaps);
            }
            summary.total_received += c.received.iter().sum::<u64>();
        }
        summary.dropped = self.dropped.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect();
        summary.total_dropped = self.dropped.values().sum();
        summary
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::standin::StandIn;

    fn rec(source: &str, seq: u64) -> Vec<u8> {
        StandIn { source, seq, capture_time_ns: 1, publish_time_ns: 2 }.encode(48).unwrap()
    }

    #[test]
    fn counts_by_source_and_stream_and_drops_by_reason() {
        let mut c = StandInCounters::default();
        let t = Instant::now();
        let state = "risktwin/v1/s/veh-1/state";
        assert_eq!(c.accept(state, &rec("veh-1", 0), t), Ok(()));
        assert_eq!(c.accept(state, &rec("veh-1", 1), t), Ok(()));
        assert_eq!(c.accept(state, &rec("veh-1", 1), t), Err(StandInDrop::StaleSeq));
        assert_eq!(c.accept(state, &rec("veh-1", 5), t), Ok(()));
        assert_eq!(c.accept("risktwin/v1/s/veh-1/can", &rec("veh-1", 0), t), Ok(()));
        assert_eq!(c.accept(state, &rec("veh-2", 9), t), Err(StandInDrop::SourceMismatch));
        assert_eq!(c.accept(state, b"garbage", t).map_err(|r| r.name()), Err("too-short"));
        assert_eq!(c.accept("risktwin/v1/s/cloud/snapshot", &rec("veh-1", 0), t), Err(StandInDrop::BadKey));
        let s = c.summary();
        assert_eq!(s.received["veh-1"], BTreeMap::from([("state".into(), 3), ("can".into(), 1)]));
        assert_eq!(s.gaps["veh-1"], BTreeMap::from([("state".into(), 3)]));
        assert_eq!(
            s.dropped,
            BTreeMap::from([
                ("stale-seq".into(), 1),
                ("source-mismatch".into(), 1),
                ("too-short".into(), 1),
                ("bad-key".into(), 1)
            ])
        );
        assert_eq!((s.total_received, s.total_dropped), (4, 4));
        assert_eq!(c.last_sample(), Some(t));
    }
}
