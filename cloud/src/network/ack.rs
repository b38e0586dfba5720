//! Delivery acknowledgements from the ingest to the edges (docs/keyexpr.md, "Delivery
//! acknowledgements"): every [`ACK_PERIOD`], each source whose accounting moved within the last
//! [`ACK_REPEAT`] gets one `DeliveryAck` on `risktwin/v1/<site>/<source>/ack` telling, per stream,
//! the next sequence number the cloud waits for, what it received and what it counts lost.
//!
//! One message per active source and period, never one per sample; a source quiet for longer
//! than [`ACK_REPEAT`] costs nothing (its last state went out four times), and at most
//! [`MAX_ACKS_PER_PERIOD`] go out per period, the longest-unacknowledged first. The acks are made
//! under the ingest's lock (a few hash lookups per source) and put outside it, by a task, never
//! from the receive callback.

use risktwin_transport::zenoh::session::ZenohId;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// How often the ingest acknowledges.
pub const ACK_PERIOD: Duration = Duration::from_millis(500);

/// How long after its accounting last moved a source is still acknowledged (each period): a
/// lost acknowledgement is made good by the next ones, and an edge waiting at its exit hears
/// the final state more than once.
pub const ACK_REPEAT: Duration = Duration::from_secs(2);

/// The most acknowledgements per period (40 000 a second): a cloud facing more active sources
/// acknowledges each less often, never more.
pub const MAX_ACKS_PER_PERIOD: usize = 20_000;

/// One acknowledged source.
#[derive(Debug, Clone)]
struct AckSource {
    site: String,
    /// The session of the last sample accepted (its publisher's process).
    publisher: Option<ZenohId>,
    changed: Instant,
    acked: Option<Instant>,
}

/// The sources whose accounting moved lately (bounded by the ingest's source limit: only
/// accepted samples enter, and quiet ones leave).
#[derive(Debug, Default)]
pub struct AckSources {
    sources: HashMap<String, AckSource>,
    /// This cloud's acknowledgements so far (the header seq of the next one).
    seq: u64,
}

impl AckSources {
    /// A sample of `source` (at `site`, published by session `publisher`) was accepted at `now`.
    pub fn touch(&mut self, site: &str, source: &str, publisher: Option<ZenohId>, now: Instant) {
        // Look up by &str first so that a known source costs no allocation.
        match self.sources.get_mut(source) {
            Some(s) => {
                s.changed = now;
                if publisher.is_some() {
                    s.publisher = publisher;
                }
                if s.site != site {
                    site.clone_into(&mut s.site);
                }
            }
            None => {
                let entry = AckSource { site: site.to_owned(), publisher, changed: now, acked: None };
                self.sources.insert(source.to_owned(), entry);
            }
        }
    }

    /// The sources to acknowledge at `now` (site, source, publisher), at most `max`, the longest
    /// unacknowledged first; they count as acknowledged from now on. Sources quiet for longer
    /// than [`ACK_REPEAT`] are forgotten.
    pub(super) fn due(&mut self, now: Instant, max: usize) -> Vec<(String, String, Option<ZenohId>)> {
        self.sources.retain(|_, s| now.duration_since(s.changed) <= ACK_REPEAT);
        let mut due: Vec<(&String, &mut AckSource)> = self.sources.iter_mut().collect();
        if due.len() > max {
            // `None` (never acknowledged) sorts first.
            due.select_nth_unstable_by_key(max, |(_, s)| s.acked);
            due.truncate(max);
        }
        due.into_iter()
            .map(|(source, s)| {
                s.acked = Some(now);
                (s.site.clone(), source.clone(), s.publisher)
            })
            .collect()
    }

    pub(super) fn next_seq(&mut self) -> u64 {
        let seq = self.seq;
        self.seq += 1;
        seq
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quiet_sources_are_forgotten_and_the_longest_unacknowledged_go_first() {
        let mut acks = AckSources::default();
        let t0 = Instant::now();
        for source in ["a", "b", "c"] {
            acks.touch("site", source, None, t0);
        }
        let first: Vec<String> = acks.due(t0, 2).into_iter().map(|(_, s, _)| s).collect();
        assert_eq!(first.len(), 2, "at most the budget");
        let second: Vec<String> = acks.due(t0 + ACK_PERIOD, 2).into_iter().map(|(_, s, _)| s).collect();
        let missed = ["a", "b", "c"].into_iter().find(|s| !first.iter().any(|f| f == s)).unwrap();
        assert!(second.iter().any(|s| s == missed), "the one left out goes next: {first:?} then {second:?}");
        acks.touch("site", "a", None, t0 + ACK_REPEAT);
        let later = acks.due(t0 + ACK_REPEAT + ACK_PERIOD, 10);
        assert_eq!(later.len(), 1, "only a is still moving: {later:?}");
        assert_eq!(acks.sources.len(), 1, "the quiet ones are forgotten");
    }
}
