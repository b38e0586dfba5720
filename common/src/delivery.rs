//! Delivery acknowledgements: the cloud's word to an edge on how far each of its streams is
//! accounted for, and the edge's ledger that turns those words into what it reports on exit
//! (docs/keyexpr.md, "Delivery acknowledgements").
//!
//! The cloud's ingest acknowledges per stream the next sequence number it waits for (every
//! number below it was received or is counted lost), how many of the edge's numbers it received
//! and how many it counts lost, for the edge process (Zenoh session) whose sample it took last.
//! The edge keeps the latest acknowledgement of each cloud session it heard from, so that a
//! cloud restarted mid-run adds to what the first one received instead of replacing it.

use crate::telemetry::Header;
use std::ops::Range;

/// One stream's progress in a [`DeliveryAck`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StreamAck {
    /// The stream's name (`state`, `can`, …).
    pub stream: String,
    /// Every number below this one was received or is counted lost by the cloud.
    pub next_seq: u64,
    /// Numbers received.
    pub received: u64,
    /// Numbers the cloud counts lost (`presumed_lost`), those before its first one included.
    pub lost: u64,
}

/// The cloud to one edge: how far each of its streams is accounted for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeliveryAck {
    /// Source `cloud`; seq numbers this cloud's acknowledgements (all edges together).
    pub header: Header,
    /// The edge acknowledged.
    pub edge_source: String,
    /// The Zenoh session (process) of the edge whose sample the cloud took last: a new process
    /// under the same id ignores its predecessor's acknowledgements.
    pub edge_session: String,
    /// The cloud's own Zenoh session: acknowledgements of two clouds (a restart) add up.
    pub cloud_session: String,
    pub streams: Vec<StreamAck>,
    /// The streams the cloud sheds now (overloaded): the edge holds them back until an
    /// acknowledgement no longer names them.
    pub shed: Vec<String>,
}

/// Cloud sessions one edge keeps acknowledgements of; later ones are ignored (and said so).
pub const MAX_CLOUD_SESSIONS: usize = 16;

/// One stream's outcome as the edge reports it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StreamDelivery {
    /// Sent and received by a cloud.
    pub acknowledged: u64,
    /// Sent, and counted lost by the cloud (skipped numbers it accounts for).
    pub lost: u64,
    /// Sent and never accounted for by any cloud.
    pub undelivered: u64,
}

/// The latest acknowledgement of each cloud session, for one edge process.
#[derive(Debug, Clone, Default)]
pub struct DeliveryLedger {
    session: String,
    /// (cloud session, header seq of its latest acknowledgement, its streams).
    clouds: Vec<(String, u64, Vec<StreamAck>)>,
    /// Acknowledgements ignored: for another process, or from a cloud session beyond the limit.
    ignored: u64,
}

impl DeliveryLedger {
    /// The ledger of the edge process whose Zenoh session is `session`.
    pub fn new(session: impl Into<String>) -> Self {
        DeliveryLedger { session: session.into(), ..Default::default() }
    }

    /// Takes `ack` in; `false` when it is not for this process or comes from one cloud session
    /// too many.
    pub fn apply(&mut self, ack: DeliveryAck) -> bool {
        if ack.edge_session != self.session {
            self.ignored += 1;
            return false;
        }
        if let Some((_, seq, streams)) = self.clouds.iter_mut().find(|(cloud, _, _)| *cloud == ack.cloud_session) {
            if ack.header.seq >= *seq {
                *seq = ack.header.seq;
                *streams = ack.streams;
            }
        } else if self.clouds.len() < MAX_CLOUD_SESSIONS {
            self.clouds.push((ack.cloud_session, ack.header.seq, ack.streams));
        } else {
            self.ignored += 1;
            return false;
        }
        true
    }

    /// Whether any acknowledgement for this process came.
    pub fn heard(&self) -> bool {
        !self.clouds.is_empty()
    }

    /// Acknowledgements ignored so far.
    pub fn ignored(&self) -> u64 {
        self.ignored
    }

    /// How many cloud sessions acknowledged this process.
    pub fn clouds(&self) -> usize {
        self.clouds.len()
    }

    /// The outcome of `stream`, of which the edge numbered `numbered` messages (0..numbered),
    /// sent `sent` and never sent those in `unsent` (disjoint ranges of numbers: refused, or
    /// skipped; the cloud counts them lost).
    ///
    /// Covered are the numbers below the highest `next_seq` of any cloud. The received counts
    /// of several clouds are summed, capped at what is covered: a restarted cloud receives
    /// what came after the first one stopped (or, asking an edge's cache, a suffix of the
    /// stream), so the sum overstates only where both received the same numbers, which the
    /// cap removes as long as the first cloud's numbers come before the second's.
    pub fn stream(&self, stream: &str, numbered: u64, sent: u64, unsent: &[Range<u64>]) -> StreamDelivery {
        let acks = self.clouds.iter().filter_map(|(_, _, streams)| streams.iter().find(|s| s.stream == stream));
        let (covered, received) =
            acks.fold((0u64, 0u64), |(c, r), a| (c.max(a.next_seq), r.saturating_add(a.received)));
        let covered = covered.min(numbered);
        let unsent_covered: u64 = unsent.iter().map(|r| r.end.min(covered).saturating_sub(r.start)).sum();
        let sent_covered = covered.saturating_sub(unsent_covered).min(sent);
        let acknowledged = received.min(sent_covered);
        let lost = sent_covered - acknowledged;
        StreamDelivery { acknowledged, lost, undelivered: sent - sent_covered }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::telemetry::Frame;

    fn ack(edge: &str, cloud: &str, seq: u64, streams: &[(&str, u64, u64, u64)]) -> DeliveryAck {
        DeliveryAck {
            header: Header { source: "cloud".into(), seq, capture_time_ns: 0, publish_time_ns: 0, frame: Frame::World },
            edge_source: "veh".into(),
            edge_session: edge.into(),
            cloud_session: cloud.into(),
            shed: Vec::new(),
            streams: streams
                .iter()
                .map(|(s, next_seq, received, lost)| StreamAck {
                    stream: (*s).into(),
                    next_seq: *next_seq,
                    received: *received,
                    lost: *lost,
                })
                .collect(),
        }
    }

    #[test]
    fn one_cloud_acknowledges_what_it_received_and_says_what_it_lost() {
        let mut ledger = DeliveryLedger::new("e1");
        assert_eq!(ledger.stream("state", 10, 10, &[]), StreamDelivery { undelivered: 10, ..Default::default() });
        assert!(ledger.apply(ack("e1", "c1", 0, &[("state", 6, 6, 0)])));
        assert!(ledger.apply(ack("e1", "c1", 1, &[("state", 9, 8, 1)])));
        assert!(!ledger.apply(ack("e0", "c1", 2, &[("state", 100, 100, 0)])), "a predecessor's");
        assert!(ledger.apply(ack("e1", "c1", 0, &[("state", 1, 1, 0)])), "an older one of the same cloud");
        assert_eq!(ledger.stream("state", 10, 10, &[]), StreamDelivery { acknowledged: 8, lost: 1, undelivered: 1 });
        assert_eq!(ledger.stream("can", 4, 4, &[]), StreamDelivery { undelivered: 4, ..Default::default() });
        assert_eq!(ledger.ignored(), 1);
    }

    #[test]
    fn a_restarted_cloud_adds_to_what_the_first_received() {
        let mut ledger = DeliveryLedger::new("e1");
        // The first cloud took 0..40 and died; the second started at 55 and counts 0..55 lost.
        ledger.apply(ack("e1", "c1", 7, &[("state", 40, 40, 0)]));
        ledger.apply(ack("e1", "c2", 0, &[("state", 100, 45, 55)]));
        let d = ledger.stream("state", 100, 100, &[]);
        assert_eq!(d, StreamDelivery { acknowledged: 85, lost: 15, undelivered: 0 });
        // The second cloud fetched the edge's cache from 20 on: the overlap is capped.
        ledger.apply(ack("e1", "c2", 1, &[("state", 100, 80, 20)]));
        assert_eq!(ledger.stream("state", 100, 100, &[]).acknowledged, 100);
        assert_eq!(ledger.clouds(), 2);
    }

    #[test]
    fn refused_numbers_are_neither_sent_nor_lost() {
        let mut ledger = DeliveryLedger::new("e1");
        // Number 3 was refused (too large): the cloud skipped it and counts it lost.
        ledger.apply(ack("e1", "c1", 0, &[("rsu", 6, 5, 1)]));
        let unsent = std::slice::from_ref(&(3..4));
        let d = ledger.stream("rsu", 8, 7, unsent);
        assert_eq!(d, StreamDelivery { acknowledged: 5, lost: 0, undelivered: 2 });
    }

    #[test]
    fn a_stream_that_starts_late_has_its_first_numbers_unsent() {
        let mut ledger = DeliveryLedger::new("e1");
        // A replay of a recording that begins at number 1000 and skips 1500..1600.
        ledger.apply(ack("e1", "c1", 0, &[("state", 1800, 700, 1100)]));
        let d = ledger.stream("state", 2000, 900, &[0..1000, 1500..1600]);
        assert_eq!(d, StreamDelivery { acknowledged: 700, lost: 0, undelivered: 200 });
    }
}
